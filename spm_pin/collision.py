r"""Self-collision of an SPM's links with coal: colliding link pairs, distances, clearance.

Every link is checked against every other link except the pairs that share a joint,
which touch by construction: ``base``-``proximal_i`` (joint u_i),
``proximal_i``-``distal_i`` (w_i) and ``distal_i``-``platform`` (v_i, the loop
closures). That leaves 19 link pairs (:data:`LINK_PAIRS`).

The shapes are the link shapes that are drawn (:func:`spm_pin.model.link_parts`):
every part is cut into exact convex pieces (:func:`convex_pieces`): convex parts
stay whole; curved plates, tubes and gears are swept shapes, cut along their sweep
into cells between consecutive cross-sections. Each cell is the convex hull of two
neighbouring sections, and that hull *is* the cell (its faces are planar), so the
pieces and the drawn triangles bound the same volume; the cut is checked by volume
when it is made.

How one check runs (choices measured by ``benchmarks/bench_collision.py``):

* **Static culling.** Every joint axis passes through O, so each link moves by a
  rotation about O and every piece keeps its distance range from O: two pieces whose
  shells are further apart than the margin can never meet. Links that turn about one
  common axis (the coaxial proximal links) also keep each piece's height along that
  axis and its distance from it, which removes the nested drive tubes and gears from
  each other's checks as long as the margin is below their clearance
  (:attr:`CollisionChecker.fixed_clearance`: a bound of 0.94 mm for the prototype,
  whose tubes are 1 mm apart).
* **Culling bodies.** What remains of each link against each other link is one or two
  triangle-mesh BVHs (coal OBBRSS) of the parts that can reach it: a BVH proves a
  pair apart in well under a microsecond, but it is slow to confirm a contact (its
  triangles are thin).
* **Probes.** So each link pair first tries a few convex piece pairs that, in a
  seeded sample of the workspace, caught most of its collisions (GJK confirms a
  contact in about a microsecond). A probe that collides settles the link pair and
  its BVH is skipped.
* **Ordering.** The link pairs are blocks of one list; ``pin.computeCollisions``
  stops at the first colliding pair, the block is recorded, and the next call starts
  after it (one ``GeometryData`` per starting block, made once): one pass over the
  list, in C++, whatever collides.
* **Relative-angle tables.** Two coaxial proximal links are placed relative to each
  other by the difference of their inputs alone. A table over that angle, made once
  per margin, marks the cells where the pair is certainly apart (a check at a larger
  margin at the cell's middle plus a Lipschitz bound); there the pair is skipped.

A probe only changes the speed, never the answer: each probe is a piece of both
links, and the BVH decides whenever no probe collides.

Distances (:meth:`CollisionChecker.distances`) are exact minima over the convex
pieces (GJK), pruned with bounding spheres; negative values are penetration depths
of the deepest-overlapping pieces (a lower bound of the links' penetration).
"""

from __future__ import annotations

import collections
import dataclasses
import functools
import math
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any

import coal
import numpy as np
import numpy.typing as npt
import pinocchio as pin
import trimesh

from .design import SPMDesign
from .errors import InputError, SPMError, UnreachableError
from .kinematics import forward_kinematics, forward_kinematics_all, jacobian
from .kinematics._common import as_theta, check_design, mode_label
from .model.geometry import LINK_NAMES, link_parts

if TYPE_CHECKING:
    from .model.robot import SPMRobot

__all__ = [
    "ADJACENT_PAIRS",
    "DEFAULT_PROBES",
    "LINK_PAIRS",
    "CollisionChecker",
    "CollisionReport",
    "ConvexPiece",
    "LinkPair",
    "check_input",
    "convex_pieces",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

#: A pair of link names, in the order of :data:`~spm_pin.model.geometry.LINK_NAMES`.
LinkPair = tuple[str, str]

#: Link pairs that share a joint (never checked): u_i, w_i and v_i.
ADJACENT_PAIRS: tuple[LinkPair, ...] = tuple(
    pair
    for leg in (1, 2, 3)
    for pair in (
        ("base", f"proximal_{leg}"),
        (f"proximal_{leg}", f"distal_{leg}"),
        (f"distal_{leg}", "platform"),
    )
)

#: The 19 checked link pairs, in the order of ``LINK_NAMES`` (first name first).
LINK_PAIRS: tuple[LinkPair, ...] = tuple(
    (a, b)
    for i, a in enumerate(LINK_NAMES)
    for b in LINK_NAMES[i + 1 :]
    if (a, b) not in ADJACENT_PAIRS
)

#: Default largest number of probe piece pairs tried per link pair before its BVH.
DEFAULT_PROBES = 4
#: Seeded inputs sampled to choose the probes.
PROBE_SAMPLES = 256
#: A probe is kept only if it catches a collision of its link pair, missed by the
#: earlier probes, in at least this fraction of the samples.
PROBE_MIN_SHARE = 0.02
#: Largest number of margins whose check set-up is kept (least recently used first out).
ENGINE_CACHE = 24

#: Parts of a proximal link that turn about the input axis as solids of revolution
#: (culling body "drive"); everything else of a link is its main body.
_DRIVE_PARTS = frozenset({"tube", "gear"})
#: Relative tolerance of the volume check of a convex cut.
_VOLUME_RTOL = 1e-9
#: Two section angles closer than this are one section [rad].
_ANGLE_TOL = 1e-7
#: Axes closer than this are the same axis.
_AXIS_TOL = 1e-12
#: Length of the segment that stands for a rotation axis in distance queries [m].
_AXIS_LENGTH = 10.0
#: EPA iterations in collision requests: the contact itself comes from GJK; EPA
#: would only refine a penetration depth that is not used.
_EPA_ITERATIONS = 0


# ------------------------------------------------------------------ convex pieces
@dataclasses.dataclass(frozen=True)
class ConvexPiece:
    """One exact convex piece of a link part.

    Attributes:
        link: Link name.
        part: Part name (:attr:`spm_pin.model.LinkPart.name`).
        index: Index of the piece within its part (0 for a convex part).
        vertices: Vertices of the piece, link frame (= world frame at home) [m],
            shape (k, 3); the piece is their convex hull.
    """

    link: str
    part: str
    index: int
    vertices: FloatArray


def _convex_shape(points: FloatArray) -> Any:
    """coal.Convex hull of points (qhull), with triangles for fast support queries."""
    vector = coal.StdVec_Vec3s()
    for point in np.ascontiguousarray(points, dtype=np.float64):
        vector.append(point)
    return coal.Convex.convexHull(vector, True, None)


def _bvh(mesh: trimesh.Trimesh) -> Any:
    points = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    triangles = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    model = coal.BVHModelOBBRSS()
    model.beginModel(int(triangles.shape[0]), int(points.shape[0]))
    model.addVertices(points)
    model.addTriangles(triangles)
    model.endModel()
    return model


def _concatenate(meshes: Sequence[trimesh.Trimesh]) -> trimesh.Trimesh:
    vertices, faces, offset = [], [], 0
    for mesh in meshes:
        vertices.append(np.asarray(mesh.vertices, dtype=np.float64))
        faces.append(np.asarray(mesh.faces, dtype=np.int64) + offset)
        offset += len(mesh.vertices)
    return trimesh.Trimesh(np.vstack(vertices), np.vstack(faces), process=False)


def _axis_frame(axis: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit vectors completing ``axis`` to a right-handed frame."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = helper - (helper @ axis) * axis
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def _section_angles(vertices: FloatArray, axis: FloatArray) -> tuple[FloatArray, IntArray]:
    """Distinct angles of the vertices about ``axis`` (sorted) and each vertex's index
    among them."""
    e1, e2 = _axis_frame(axis)
    angle = np.arctan2(vertices @ e2, vertices @ e1)
    order = np.sort(angle)
    groups = [float(order[0])]
    for value in order[1:]:
        if value - groups[-1] > _ANGLE_TOL:
            groups.append(float(value))
    if len(groups) > 1 and groups[0] + 2.0 * math.pi - groups[-1] <= _ANGLE_TOL:
        groups.pop()
    sections = np.array(groups)
    gap = np.abs(np.angle(np.exp(1j * (angle[:, None] - sections[None, :]))))
    return sections, np.argmin(gap, axis=1).astype(np.int64)


def _sweep_cells(vertices: FloatArray, axis: FloatArray) -> list[FloatArray] | None:
    """Vertex sets of the cells between consecutive sections of a shape swept about
    ``axis`` (a plate bent along an arc, a tube), or None if it is not swept."""
    sections, label = _section_angles(vertices, axis)
    count = sections.size
    if count < 3:
        return None
    steps = np.diff(np.concatenate([sections, [sections[0] + 2.0 * math.pi]]))
    closed = bool(steps.max() < 3.0 * np.median(steps))
    start = 0 if closed else (int(np.argmax(steps)) + 1) % count
    cells = []
    for k in range(count if closed else count - 1):
        a, b = (start + k) % count, (start + k + 1) % count
        cells.append(vertices[(label == a) | (label == b)])
    return cells


def _solid(points: FloatArray) -> bool:
    """At least 4 points spanning 3 dimensions (qhull needs that)."""
    if points.shape[0] < 4:
        return False
    spread = np.linalg.svd(points - points.mean(axis=0), compute_uv=False)
    return bool(spread[-1] > 1e-9 * max(float(spread[0]), 1e-300))


def _hull_volume(points: FloatArray) -> float:
    return float(_convex_shape(points).computeVolume())


def _candidate_axes(design: SPMDesign) -> list[FloatArray]:
    """Axes about which the link parts are swept: joint axes and arc normals."""
    u, w0, v0 = design.u, design.w0, design.v0
    axes: list[FloatArray] = [np.array([0.0, 0.0, 1.0])]
    mean = u.mean(axis=0)
    if np.linalg.norm(mean) > 1e-6:
        axes.append(mean / np.linalg.norm(mean))
    for leg in range(3):
        axes += [u[leg], w0[leg], v0[leg]]
        for a, b in ((u[leg], w0[leg]), (w0[leg], v0[leg])):
            normal = np.cross(a, b)
            if np.linalg.norm(normal) > 1e-9:
                axes.append(normal / np.linalg.norm(normal))
    return axes


def _cut(mesh: trimesh.Trimesh, axes: Sequence[FloatArray]) -> list[FloatArray]:
    """Exact convex pieces of one closed part mesh (see :func:`convex_pieces`)."""
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    volume = float(mesh.volume)
    if mesh.is_convex:
        return [vertices]
    for axis in axes:
        cells = _sweep_cells(vertices, axis)
        if cells is None or not all(_solid(cell) for cell in cells):
            continue
        total = sum(_hull_volume(cell) for cell in cells)
        if abs(total - volume) <= _VOLUME_RTOL * abs(volume) + 1e-15:
            return cells
    raise SPMError(  # pragma: no cover - a geometry module change the cut cannot follow
        f"a part with {len(vertices)} vertices is neither convex nor swept about a joint "
        "axis; the collision model cannot cut it into exact convex pieces"
    )


@functools.lru_cache(maxsize=8)
def _pieces(design: SPMDesign) -> dict[str, tuple[ConvexPiece, ...]]:
    axes = _candidate_axes(design)
    result: dict[str, tuple[ConvexPiece, ...]] = {}
    for link, parts in link_parts(design).items():
        pieces: list[ConvexPiece] = []
        for part in parts:
            for index, cell in enumerate(_cut(part.mesh, axes)):
                cell.setflags(write=False)
                pieces.append(ConvexPiece(link, part.name, index, cell))
        result[link] = tuple(pieces)
    return result


def convex_pieces(design: SPMDesign | None = None) -> dict[str, tuple[ConvexPiece, ...]]:
    """Exact convex pieces of every link (keys :data:`LINK_NAMES`), link frame [m].

    Convex parts (cylinders, boxes, hulls) are one piece each. Curved plates, tubes
    and gears are cut along their sweep (about a joint axis or the normal of their
    arc) into the cells between consecutive cross-sections; each cell is the convex
    hull of its two sections. The cut is accepted only if the cells' volumes add up
    to the part's volume (relative 1e-9), so the pieces are the drawn shape.

    Args:
        design: The SPM (default: the prototype).
    """
    return _pieces(check_design(design))


# ---------------------------------------------------------------- the static model
def _revolution_order(vertices: FloatArray, axis: FloatArray) -> int:
    """n if the vertex set is invariant under turns of 2 pi / n about ``axis`` through
    O (a faceted solid of revolution), else 0."""
    sections, label = _section_angles(vertices, axis)
    n = sections.size
    if n < 8:
        return 0
    steps = np.diff(np.concatenate([sections, [sections[0] + 2.0 * math.pi]]))
    if np.ptp(steps) > 1e-6:
        return 0
    height = vertices @ axis
    radius = np.linalg.norm(vertices - height[:, None] * axis, axis=1)
    profile = {
        (round(float(h), 9), round(float(r), 9)) for h, r in zip(height, radius, strict=True)
    }
    counts = np.bincount(label, minlength=n)
    if counts.min() != counts.max() or len(profile) * n != len(vertices):
        return 0
    return int(n)


def _capsule(points: FloatArray) -> tuple[FloatArray, FloatArray, float]:
    """A capsule (segment p0-p1, radius) containing the points: the segment along
    their principal direction, the radius their largest distance from it [m]."""
    middle = points.mean(axis=0)
    spread = points - middle
    direction = np.linalg.svd(spread, full_matrices=False)[2][0]
    along = spread @ direction
    p0 = middle + along.min() * direction
    p1 = middle + along.max() * direction
    t = np.clip((points - p0) @ direction / max(float(along.max() - along.min()), 1e-300), 0, 1)
    nearest = p0 + t[:, None] * (p1 - p0)
    return p0, p1, float(np.linalg.norm(points - nearest, axis=1).max())


def _segment_distances(
    p0: FloatArray, p1: FloatArray, q0: FloatArray, q1: FloatArray
) -> FloatArray:
    """Distances between segments p0-p1 and q0-q1, row by row (closest points of two
    segments, clamped closed form; C. Ericson, Real-Time Collision Detection, 5.1.9)."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    tiny = 1e-30
    a_ok, e_ok = a > tiny, e > tiny
    safe_a, safe_e = np.where(a_ok, a, 1.0), np.where(e_ok, e, 1.0)
    denom = a * e - b * b
    s = np.where(
        denom > tiny, np.clip((b * f - c * e) / np.where(denom > tiny, denom, 1.0), 0, 1), 0
    )
    s = np.where(a_ok, s, 0.0)
    t = np.where(e_ok, (b * s + f) / safe_e, 0.0)
    s_low = np.where(a_ok, np.clip(-c / safe_a, 0, 1), 0.0)
    s_high = np.where(a_ok, np.clip((b - c) / safe_a, 0, 1), 0.0)
    s = np.where(t < 0, s_low, np.where(t > 1, s_high, s))
    t = np.clip(t, 0.0, 1.0)
    # With a degenerate p-segment the nearest point of q follows from t alone.
    t = np.where(a_ok, t, np.where(e_ok, np.clip(f / safe_e, 0, 1), 0.0))
    gap = (p0 + s[:, None] * d1) - (q0 + t[:, None] * d2)
    result: FloatArray = np.linalg.norm(gap, axis=1)
    return result


@dataclasses.dataclass
class _Piece:
    """A convex piece with its coal shape and rotation-invariant bounds."""

    link: int  # index into LINK_NAMES
    part: str
    index: int
    shape: Any
    center: FloatArray  # bounding-sphere centre, link frame [m]
    radius: float  # bounding-sphere radius [m]
    capsule: tuple[FloatArray, FloatArray, float]  # bounding capsule, link frame [m]
    anchor: FloatArray  # a point of the piece (a vertex), link frame [m]
    shell: tuple[float, float]  # distance range from O [m]
    band: tuple[float, float] | None  # height along the common turning axis [m]
    ring: tuple[float, float] | None  # distance range from that axis [m]
    revolved: bool  # the part is a faceted solid of revolution about that axis


@dataclasses.dataclass(frozen=True)
class _LinkPairGeometry:
    """Piece pairs of one link pair that a margin can reach."""

    pair: LinkPair
    a: IntArray  # piece indices
    b: IntArray
    static_bound: FloatArray  # rotation-invariant lower bounds of their distance [m]
    fixed: BoolArray  # the pair's distance does not depend on the configuration


class _Engine:
    """The collision check at one margin: geometry, pair blocks, one GeometryData per
    starting block (see the module docstring)."""

    def __init__(
        self,
        checker: CollisionChecker,
        margin: float,
        include_fixed: bool,
        pairs: frozenset[LinkPair] | None,
    ) -> None:
        robot = checker.robot
        model = robot.model
        gm = pin.GeometryModel()
        objects: dict[tuple[str, tuple[str, ...]] | int, int] = {}

        def add(key: tuple[str, tuple[str, ...]] | int, link: str, shape: Any) -> int:
            if key not in objects:
                frame = robot.link_frames[link]
                name = f"{link}/{'+'.join(key[1])}" if isinstance(key, tuple) else f"piece{key}"
                geometry = pin.GeometryObject(
                    name, model.frames[frame].parentJoint, frame, pin.SE3.Identity(), shape
                )
                objects[key] = gm.addGeometryObject(geometry)
            return objects[key]

        def body(link: str, parts: Iterable[str]) -> int:
            names = tuple(sorted(set(parts)))
            key = (link, names)
            if key not in objects:
                shape = checker._bodies.get(key)
                if shape is None:
                    meshes = [p.mesh for p in checker._parts[link] if p.name in names]
                    shape = _bvh(_concatenate(meshes))
                    checker._bodies[key] = shape
                add(key, link, shape)
            return objects[key]

        blocks: list[list[tuple[int, int]]] = []
        block_pairs: list[LinkPair] = []
        # Frequent colliders first: a pass then stops, and is read back, early.
        for geometry in (checker._all[k] for k in checker._block_order):
            if pairs is not None and geometry.pair not in pairs:
                continue
            near = geometry.static_bound <= margin
            if not include_fixed:
                near &= ~geometry.fixed
            if not np.any(near):
                continue
            a_idx, b_idx = geometry.a[near], geometry.b[near]
            link_a, link_b = geometry.pair
            block: list[tuple[int, int]] = []
            for i, j in checker._probes.get(geometry.pair, ()):
                block.append(
                    (
                        add(i, link_a, checker._pieces[i].shape),
                        add(j, link_b, checker._pieces[j].shape),
                    )
                )
            for group_a in _groups(checker._pieces, a_idx):
                for group_b in _groups(checker._pieces, b_idx):
                    keep = np.isin(a_idx, group_a) & np.isin(b_idx, group_b)
                    if not np.any(keep):
                        continue
                    parts_a = {checker._pieces[i].part for i in a_idx[keep]}
                    parts_b = {checker._pieces[j].part for j in b_idx[keep]}
                    block.append((body(link_a, parts_a), body(link_b, parts_b)))
            blocks.append(block)
            block_pairs.append(geometry.pair)

        pair_block: list[int] = []
        block_start: list[int] = []
        for number, block in enumerate(blocks):
            block_start.append(len(pair_block))
            for first, second in block:
                gm.addCollisionPair(pin.CollisionPair(first, second))
                pair_block.append(number)
        datas = []
        for start in range(len(blocks)):
            gd = pin.GeometryData(gm)
            for k, request in enumerate(gd.collisionRequests):
                request.security_margin = margin
                request.break_distance = 0.0
                request.epa_max_iterations = _EPA_ITERATIONS
                if pair_block[k] < start:
                    gd.deactivateCollisionPair(k)
            datas.append(gd)
        self.margin = margin
        self.include_fixed = include_fixed
        self.geometry_model = gm
        self.datas = datas
        # The results' isCollision methods, bound once (the references follow the C++
        # objects; indexing the vector proxy at each look-up costs about 4x more).
        self.results = [
            [gd.collisionResults[k].isCollision for k in range(len(pair_block))] for gd in datas
        ]
        self.block_pairs = block_pairs
        self.block_start = block_start
        self.pair_block = pair_block


_TWO_PI = 2.0 * math.pi
#: Largest distance error allowed to the relative-angle tables [m] (see _Plan).
_SWEEP_BUDGET = 0.0005
#: Most cells of a relative-angle table.
_SWEEP_CELLS = 8192


@dataclasses.dataclass(frozen=True)
class _Sweep:
    """Relative-angle table of two links turning about one axis (input joints ``a``,
    ``b`` in q): ``free[k]`` certifies that the pair is apart by more than the margin
    for every relative angle q_b - q_a in cell k (width 2 pi / len(free))."""

    pair: LinkPair
    a: int
    b: int
    free: list[bool]
    scale: float  # cells per radian


class _Plan:
    """How to check at one margin: relative-angle tables for the links that turn about
    one common axis, and an engine for each set of such pairs the tables cannot clear.

    Two coaxial proximal links are placed relative to each other by the difference
    of their inputs alone, Delta. Their distance d(Delta) changes by at most r |dDelta|
    with r the largest distance of their pieces from the axis, so a check at margin
    m + r h / 2 at the middle of a cell of width h that finds nothing proves the pair
    apart by more than m over the whole cell. Such cells need no check at run time;
    elsewhere the pair is checked as any other.
    """

    def __init__(
        self,
        checker: CollisionChecker,
        margin: float,
        include_fixed: bool,
        pairs: frozenset[LinkPair] | None,
    ) -> None:
        self.checker = checker
        self.margin = margin
        self.include_fixed = include_fixed
        chosen = [p for p in LINK_PAIRS if pairs is None or p in pairs]
        self.sweeps: list[_Sweep] = []
        for pair in chosen:
            sweep = checker._sweep(pair, margin, include_fixed)
            if sweep is not None:
                self.sweeps.append(sweep)
        swept = {s.pair for s in self.sweeps}
        self.others = [p for p in chosen if p not in swept]
        self.engines: dict[int, _Engine] = {}

    def engine(self, uncleared: int) -> _Engine:
        """The engine for the other pairs plus the swept pairs of bit mask ``uncleared``."""
        engine = self.engines.get(uncleared)
        if engine is None:
            extra = {s.pair for bit, s in enumerate(self.sweeps) if uncleared >> bit & 1}
            engine = _Engine(
                self.checker,
                self.margin,
                self.include_fixed,
                frozenset(self.others) | frozenset(extra),
            )
            self.engines[uncleared] = engine
        return engine


def _groups(pieces: Sequence[_Piece], indices: IntArray) -> list[IntArray]:
    """The piece indices split into culling bodies: a proximal link's drive (tube and
    gear) and the rest."""
    drive = np.array([pieces[i].part in _DRIVE_PARTS for i in indices], dtype=bool)
    groups = [np.unique(indices[~drive]), np.unique(indices[drive])]
    return [g for g in groups if g.size]


def _check_margin(margin: object) -> float:
    if (
        isinstance(margin, bool)
        or not isinstance(margin, (int, float, np.integer, np.floating))
        or not math.isfinite(float(margin))
        or float(margin) < 0.0
    ):
        raise InputError(
            f"margin must be a finite distance >= 0 [m], got {margin!r}",
            argument="margin",
            value=margin,
        )
    return float(margin) + 0.0


class _DistanceIndex:
    """Bounding capsules of the parts and pieces, for exact distances by pruning.

    The distance of a link pair is the minimum over its pieces' pairs. Part pairs
    whose capsules are further apart than an upper bound of the link pair's distance
    (two points of its parts) are dropped; the pieces of the others are tried in order
    of their capsule lower bounds (and the rotation-invariant static bound) with GJK,
    until the next lower bound is no smaller than the best distance found.
    """

    def __init__(self, checker: CollisionChecker) -> None:
        pieces = checker._pieces
        self.checker = checker
        part_key: dict[tuple[int, str], int] = {}
        part_of_piece = np.empty(len(pieces), dtype=np.int64)
        for k, piece in enumerate(pieces):
            part_of_piece[k] = part_key.setdefault((piece.link, piece.part), len(part_key))
        part_link = np.empty(len(part_key), dtype=np.int64)
        part_capsules: list[tuple[FloatArray, FloatArray, float]] = []
        part_anchor = np.empty((len(part_key), 3))
        for (link, _), number in part_key.items():
            part_link[number] = link
            vertices = np.vstack(
                [checker.pieces[k].vertices for k in np.flatnonzero(part_of_piece == number)]
            )
            p0, p1, radius = _capsule(vertices)
            part_capsules.append((p0, p1, radius))
            middle = 0.5 * (p0 + p1)
            part_anchor[number] = vertices[np.argmin(np.linalg.norm(vertices - middle, axis=1))]
        self.piece_link = checker._piece_link
        self.part_link = part_link
        self.piece_caps = np.array([[p.capsule[0], p.capsule[1]] for p in pieces])  # (n, 2, 3)
        self.piece_radius = np.array([p.capsule[2] for p in pieces])
        self.part_caps = np.array([[c[0], c[1]] for c in part_capsules])
        self.part_radius = np.array([c[2] for c in part_capsules])
        self.part_anchor = part_anchor
        # Per link pair and per choice of include_fixed: its part pairs, and for each
        # the rows of its piece pairs.
        self.groups: dict[bool, list[tuple[IntArray, IntArray, list[IntArray]]]] = {
            True: [],
            False: [],
        }
        count = len(part_key)
        for geometry in checker._all:
            for include_fixed in (True, False):
                keep = np.ones(geometry.a.size, dtype=bool) if include_fixed else ~geometry.fixed
                kept = np.flatnonzero(keep)
                keys = part_of_piece[geometry.a[kept]] * count + part_of_piece[geometry.b[kept]]
                unique, inverse = np.unique(keys, return_inverse=True)
                order = np.argsort(inverse, kind="stable")
                bounds = np.searchsorted(inverse[order], np.arange(unique.size + 1))
                rows = [kept[order[bounds[k] : bounds[k + 1]]] for k in range(unique.size)]
                self.groups[include_fixed].append((unique // count, unique % count, rows))

    def world(self, rotations: FloatArray) -> dict[str, FloatArray]:
        """Capsule end points and anchors in the world frame."""
        piece_r = rotations[self.piece_link]
        part_r = rotations[self.part_link]
        return {
            "pieces": np.einsum("pij,pkj->pki", piece_r, self.piece_caps),
            "parts": np.einsum("pij,pkj->pki", part_r, self.part_caps),
            "anchors": np.einsum("pij,pj->pi", part_r, self.part_anchor),
        }

    def link_pair_distance(
        self,
        number: int,
        world: dict[str, FloatArray],
        transforms: Sequence[Any],
        include_fixed: bool,
        cap: float,
    ) -> float:
        checker = self.checker
        geometry = checker._all[number]
        part_a, part_b, rows = self.groups[include_fixed][number]
        if part_a.size == 0:
            return math.inf
        parts, radius = world["parts"], self.part_radius
        lower = (
            _segment_distances(
                parts[part_a, 0], parts[part_a, 1], parts[part_b, 0], parts[part_b, 1]
            )
            - radius[part_a]
            - radius[part_b]
        )
        upper = np.linalg.norm(world["anchors"][part_a] - world["anchors"][part_b], axis=1)
        best = float(np.min(upper))
        caps, piece_radius = world["pieces"], self.piece_radius
        # Branch and bound: part pairs in order of their lower bounds; within each,
        # pieces in order of theirs. Overlapping capsules bound nothing (-inf).
        part_lower = np.where(lower > 0.0, lower, -math.inf)
        for k in np.argsort(part_lower, kind="stable"):
            if part_lower[k] >= best or part_lower[k] > cap:
                break
            picked = rows[k]
            a, b = geometry.a[picked], geometry.b[picked]
            gap = (
                _segment_distances(caps[a, 0], caps[a, 1], caps[b, 0], caps[b, 1])
                - piece_radius[a]
                - piece_radius[b]
            )
            bound = geometry.static_bound[picked]
            piece_lower = np.maximum(
                np.where(gap > 0.0, gap, -math.inf), np.where(bound > 0.0, bound, -math.inf)
            )
            for m in np.argsort(piece_lower, kind="stable"):
                if piece_lower[m] >= best or piece_lower[m] > cap:
                    break
                best = min(best, checker._distance(int(a[m]), int(b[m]), transforms))
        return best if best <= cap else cap


# ------------------------------------------------------------------------ checker
class CollisionChecker:
    """Self-collision checks and distances of an :class:`~spm_pin.SPMRobot`'s links.

    Build one with ``CollisionChecker(robot)`` or use ``robot.collisions``,
    ``robot.distances`` and ``robot.min_clearance``, which share one checker per
    robot. A checker is not thread-safe (it keeps Pinocchio and coal work data): give
    each thread its own.

    Attributes:
        robot: The robot whose links are checked.
        design: Its design.
        pairs: The checked link pairs (:data:`LINK_PAIRS`).
        excluded_pairs: The link pairs that share a joint (:data:`ADJACENT_PAIRS`).
        fixed_clearance: Smallest distance between parts whose distance does not
            depend on the configuration (solids of revolution on links that turn
            about one axis: the prototype's nested drive tubes), a lower bound [m];
            ``inf`` when there are none. A margin at or above it may make those links
            collide everywhere.
        probes: Probe piece pairs per link pair (piece indices into :attr:`pieces`).
        pieces: Every convex piece, in link order (:func:`convex_pieces`).
    """

    def __init__(
        self,
        robot: SPMRobot,
        *,
        probes: int = DEFAULT_PROBES,
        probe_samples: int = PROBE_SAMPLES,
        seed: int = 0,
    ) -> None:
        """Cut the links into convex pieces and choose the probes.

        Args:
            robot: The robot (:func:`spm_pin.build_robot`).
            probes: Largest number of probe piece pairs per link pair (0 disables
                probes: the BVHs decide alone, slower where links collide).
            probe_samples: Seeded random inputs used to choose the probes.
            seed: Seed of those inputs (the choice of probes is reproducible; the
                answers never depend on it).

        Raises:
            InputError: ``robot`` is not an SPMRobot; bad ``probes``,
                ``probe_samples`` or ``seed``.
        """
        from .model.robot import SPMRobot

        if not isinstance(robot, SPMRobot):
            raise InputError(
                f"robot must be an SPMRobot (spm_pin.build_robot), got {type(robot).__name__}",
                argument="robot",
                value=robot,
            )
        for name, value, low in (("probes", probes, 0), ("probe_samples", probe_samples, 0)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise InputError(
                    f"{name} must be an integer >= {low}, got {value!r}",
                    argument=name,
                    value=value,
                )
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise InputError(
                f"seed must be an integer >= 0, got {seed!r}", argument="seed", value=seed
            )
        self.robot: SPMRobot = robot
        self.design: SPMDesign = robot.design
        self.pairs: tuple[LinkPair, ...] = LINK_PAIRS
        self.excluded_pairs: tuple[LinkPair, ...] = ADJACENT_PAIRS
        self._model = robot.model
        self._data = robot.model.createData()
        self._link_frames = [robot.link_frames[name] for name in LINK_NAMES]
        self._parts = {name: tuple(parts) for name, parts in link_parts(self.design).items()}
        self._turning_axes = self._common_axes()
        self._pieces: list[_Piece] = []
        self.pieces: tuple[ConvexPiece, ...] = tuple(
            piece for name in LINK_NAMES for piece in convex_pieces(self.design)[name]
        )
        revolved = self._revolved_parts()
        for piece in self.pieces:
            self._pieces.append(self._piece(piece, revolved))
        self._piece_link = np.array([p.link for p in self._pieces], dtype=np.int64)
        self._centers = np.array([p.center for p in self._pieces])
        self._radii = np.array([p.radius for p in self._pieces])
        self._anchors = np.array([p.anchor for p in self._pieces])
        self._all = [self._link_pair_geometry(pair) for pair in LINK_PAIRS]
        self._index = _DistanceIndex(self)
        fixed = [g.static_bound[g.fixed] for g in self._all if np.any(g.fixed)]
        self.fixed_clearance: float = float(min(np.min(f) for f in fixed)) if fixed else math.inf
        self._probes: dict[LinkPair, tuple[tuple[int, int], ...]] = {}
        # How often each link pair collided in the sample: the blocks go in that order.
        self._frequency: dict[LinkPair, float] = {}
        if probes and probe_samples:
            self._probes = self._choose_probes(int(probes), int(probe_samples), int(seed))
        self.probes: dict[LinkPair, tuple[tuple[int, int], ...]] = dict(self._probes)
        self._rank = {pair: k for k, pair in enumerate(LINK_PAIRS)}
        self._block_order = sorted(
            range(len(LINK_PAIRS)), key=lambda k: -self._frequency.get(LINK_PAIRS[k], 0.0)
        )
        self._engines: collections.OrderedDict[
            tuple[float, bool, frozenset[LinkPair] | None], _Engine
        ] = collections.OrderedDict()
        self._plans: collections.OrderedDict[
            tuple[float, bool, frozenset[LinkPair] | None], _Plan
        ] = collections.OrderedDict()
        self._bodies: dict[tuple[str, tuple[str, ...]], Any] = {}
        self._distance_functors: dict[tuple[int, int], Any] = {}
        self._distance_request = coal.DistanceRequest()
        self._distance_result = coal.DistanceResult()

    def __repr__(self) -> str:
        return (
            f"CollisionChecker(design={self.design.name!r}, pairs={len(self.pairs)}, "
            f"pieces={len(self.pieces)})"
        )

    # ------------------------------------------------------------- static model
    def _common_axes(self) -> list[FloatArray | None]:
        """Per link, the fixed axis it turns about if another checked link turns about
        the same one (the coaxial proximal links), else None."""
        u = self.design.u
        axes: list[FloatArray | None] = [None] * len(LINK_NAMES)
        for leg in range(3):
            same = [k for k in range(3) if np.linalg.norm(u[k] - u[leg]) <= _AXIS_TOL]
            if len(same) > 1:
                axes[LINK_NAMES.index(f"proximal_{leg + 1}")] = np.array(u[leg], dtype=float)
        return axes

    def _revolved_parts(self) -> set[tuple[str, str]]:
        revolved = set()
        for index, name in enumerate(LINK_NAMES):
            axis = self._turning_axes[index]
            if axis is None:
                continue
            for part in self._parts[name]:
                if _revolution_order(np.asarray(part.mesh.vertices, dtype=float), axis):
                    revolved.add((name, part.name))
        return revolved

    def _piece(self, piece: ConvexPiece, revolved: set[tuple[str, str]]) -> _Piece:
        vertices = piece.vertices
        shape = _convex_shape(vertices)
        identity = coal.Transform3s()
        low, high = vertices.min(axis=0), vertices.max(axis=0)
        center = 0.5 * (low + high)
        radius = float(np.linalg.norm(vertices - center, axis=1).max())
        norms = np.linalg.norm(vertices, axis=1)
        inner = coal.distance(
            shape,
            identity,
            coal.Sphere(1e-12),
            identity,
            coal.DistanceRequest(),
            coal.DistanceResult(),
        )
        link = LINK_NAMES.index(piece.link)
        axis = self._turning_axes[link]
        band = ring = None
        if axis is not None:
            height = vertices @ axis
            band = (float(height.min()), float(height.max()))
            # The axis as a long capsule of zero radius, centred at O.
            line = coal.Capsule(1e-12, _AXIS_LENGTH)
            e1, e2 = _axis_frame(axis)
            frame = coal.Transform3s(np.column_stack([e1, e2, axis]), np.zeros(3))
            near = coal.distance(
                shape, identity, line, frame, coal.DistanceRequest(), coal.DistanceResult()
            )
            radial = np.linalg.norm(vertices - height[:, None] * axis, axis=1)
            ring = (max(float(near), 0.0), float(radial.max()))
        return _Piece(
            link=link,
            part=piece.part,
            index=piece.index,
            shape=shape,
            center=center,
            radius=radius,
            capsule=_capsule(vertices),
            anchor=vertices[int(np.argmin(np.linalg.norm(vertices - center, axis=1)))],
            shell=(max(float(inner), 0.0), float(norms.max())),
            band=band,
            ring=ring,
            revolved=(piece.link, piece.part) in revolved,
        )

    def _link_pair_geometry(self, pair: LinkPair) -> _LinkPairGeometry:
        """Every piece pair of a link pair with its rotation-invariant lower bound."""
        link_a, link_b = (LINK_NAMES.index(name) for name in pair)
        ia = np.flatnonzero(self._piece_link == link_a)
        ib = np.flatnonzero(self._piece_link == link_b)
        a, b = np.repeat(ia, ib.size), np.tile(ib, ia.size)
        shells = np.array([p.shell for p in self._pieces])
        bound = np.maximum(shells[a, 0] - shells[b, 1], shells[b, 0] - shells[a, 1])
        fixed = np.zeros(a.size, dtype=bool)
        axis_a, axis_b = self._turning_axes[link_a], self._turning_axes[link_b]
        if axis_a is not None and axis_b is not None and np.allclose(axis_a, axis_b):
            band = np.array([p.band if p.band else (0.0, 0.0) for p in self._pieces])
            ring = np.array([p.ring if p.ring else (0.0, 0.0) for p in self._pieces])
            along = np.maximum(band[a, 0] - band[b, 1], band[b, 0] - band[a, 1])
            across = np.maximum(ring[a, 0] - ring[b, 1], ring[b, 0] - ring[a, 1])
            # Both links turn about the same axis: heights along it and distances from
            # it are invariant, and so is the gap they leave (Pythagoras).
            bound = np.maximum(
                bound,
                np.hypot(np.maximum(along, 0.0), np.maximum(across, 0.0)),
            )
            revolved = np.array([p.revolved for p in self._pieces])
            fixed = revolved[a] | revolved[b]
        return _LinkPairGeometry(pair, a, b, bound, fixed)

    # ------------------------------------------------------------------ probes
    def _choose_probes(
        self, count: int, samples: int, seed: int
    ) -> dict[LinkPair, tuple[tuple[int, int], ...]]:
        """For each link pair, up to ``count`` piece pairs that catch its collisions in
        seeded random reachable inputs (greedy cover). A probe is kept if it catches
        at least :data:`PROBE_MIN_SHARE` of the samples that the earlier probes
        missed: a probe costs a fraction of a microsecond where it misses, a contact
        left to the BVH costs tens."""
        rng = np.random.default_rng(seed)
        theta = rng.uniform(-math.pi, math.pi, size=(8 * samples, 3))
        theta = theta[forward_kinematics(theta, self.design).reachable][:samples]
        if theta.shape[0] == 0:  # pragma: no cover - a design with no reachable input
            return {}
        q = self.robot.configuration(theta)
        near = [g.static_bound <= 0.0 for g in self._all]
        a = np.concatenate([g.a[m] for g, m in zip(self._all, near, strict=True)])
        b = np.concatenate([g.b[m] for g, m in zip(self._all, near, strict=True)])
        owner = np.concatenate([np.full(int(m.sum()), k) for k, m in enumerate(near)]).astype(
            np.int64
        )
        reach = self._radii[a] + self._radii[b]
        request = coal.CollisionRequest()
        request.break_distance = 0.0
        request.epa_max_iterations = _EPA_ITERATIONS
        result = coal.CollisionResult()
        hits: dict[int, list[set[tuple[int, int]]]] = collections.defaultdict(list)
        for item in q:
            rotations = self._link_rotations(item)
            transforms = [coal.Transform3s(R, np.zeros(3)) for R in rotations]
            centers = np.einsum("pij,pj->pi", rotations[self._piece_link], self._centers)
            close = np.flatnonzero(np.linalg.norm(centers[a] - centers[b], axis=1) <= reach)
            found: dict[int, set[tuple[int, int]]] = collections.defaultdict(set)
            for k in close:
                i, j = int(a[k]), int(b[k])
                result.clear()
                first, second = self._pieces[i], self._pieces[j]
                if coal.collide(
                    first.shape,
                    transforms[first.link],
                    second.shape,
                    transforms[second.link],
                    request,
                    result,
                ):
                    found[int(owner[k])].add((i, j))
            for pair_index, pieces in found.items():
                hits[pair_index].append(pieces)
        total = q.shape[0]
        self._frequency = {self._all[k].pair: len(v) / total for k, v in hits.items()}
        chosen: dict[LinkPair, tuple[tuple[int, int], ...]] = {}
        for pair_index in sorted(hits):
            remaining = hits[pair_index]
            picked: list[tuple[int, int]] = []
            while remaining and len(picked) < count:
                tally = collections.Counter(p for s in remaining for p in sorted(s))
                best, caught = tally.most_common(1)[0]
                if caught < PROBE_MIN_SHARE * total:
                    break
                picked.append(best)
                remaining = [s for s in remaining if best not in s]
            if picked:
                chosen[self._all[pair_index].pair] = tuple(picked)
        return chosen

    # ------------------------------------------------------------------ inputs
    def _link_rotations(self, q: FloatArray) -> FloatArray:
        """World rotations of the links at q, (8, 3, 3) in LINK_NAMES order."""
        model, data = self._model, self._data
        pin.framesForwardKinematics(model, data, q)
        return np.array([data.oMf[frame].rotation for frame in self._link_frames])

    def configuration(self, x: npt.ArrayLike) -> FloatArray:
        """q (9,) from input angles theta (3,) (home assembly mode) or a q (9,).

        Raises:
            InputError: not shape (3,) or (9,), or not finite.
            UnreachableError: theta without a home-mode assembly.
        """
        if (
            type(x) is np.ndarray
            and x.dtype == np.float64
            and x.shape == (self._model.nq,)
            and np.isfinite(x).all()
        ):
            return x  # the common case, kept short
        try:
            array = np.asarray(x, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"x must be input angles theta (3,) or a joint configuration q (9,) [rad], "
                f"got {x!r}",
                argument="x",
                value=x,
            ) from exc
        if array.shape == (3,):
            q: FloatArray = self.robot.configuration(array)
            return q
        if array.shape != (self._model.nq,):
            raise InputError(
                "x must be input angles theta of shape (3,) or a joint configuration q "
                f"of shape ({self._model.nq},) [rad], got shape {array.shape}",
                argument="x",
                value=x,
            )
        if not np.all(np.isfinite(array)):
            raise InputError(f"x must be finite, got {array.tolist()}", argument="x", value=x)
        return array

    def _engine(
        self,
        margin: float = 0.0,
        include_fixed: bool = True,
        pairs: Iterable[LinkPair] | None = None,
    ) -> _Engine:
        """The check set-up at one margin, optionally for some link pairs only (made
        on first use, then kept)."""
        subset = None if pairs is None else frozenset(self._check_pairs(pairs))
        key = (_check_margin(margin), bool(include_fixed), subset)
        engine = self._engines.get(key)
        if engine is None:
            engine = _Engine(self, *key)
            self._engines[key] = engine
            while len(self._engines) > ENGINE_CACHE:
                self._engines.popitem(last=False)
        else:
            self._engines.move_to_end(key)
        return engine

    def _plan(
        self,
        margin: float = 0.0,
        include_fixed: bool = True,
        pairs: Iterable[LinkPair] | None = None,
    ) -> _Plan:
        """The check at one margin: relative-angle tables and engines (made on first
        use, then kept)."""
        subset = None if pairs is None else frozenset(self._check_pairs(pairs))
        key = (_check_margin(margin), bool(include_fixed), subset)
        plan = self._plans.get(key)
        if plan is None:
            plan = _Plan(self, *key)
            self._plans[key] = plan
            while len(self._plans) > ENGINE_CACHE:
                self._plans.popitem(last=False)
        return plan

    def _sweep(self, pair: LinkPair, margin: float, include_fixed: bool) -> _Sweep | None:
        """The relative-angle table of a pair of links turning about one axis (None for
        other pairs, or when the margin leaves no room below a fixed clearance)."""
        a, b = (LINK_NAMES.index(name) for name in pair)
        axis_a, axis_b = self._turning_axes[a], self._turning_axes[b]
        if axis_a is None or axis_b is None or not np.allclose(axis_a, axis_b):
            return None
        geometry = self._all[LINK_PAIRS.index(pair)]
        budget = _SWEEP_BUDGET
        if include_fixed and np.any(geometry.fixed):
            budget = min(
                budget, 0.5 * (float(np.min(geometry.static_bound[geometry.fixed])) - margin)
            )
        reach = max(p.ring[1] for p in self._pieces if p.link in (a, b) and p.ring is not None)
        cells = math.ceil(_TWO_PI * reach / (2.0 * budget)) if budget > 0 else _SWEEP_CELLS + 1
        if cells > _SWEEP_CELLS:
            return None
        width = _TWO_PI / cells
        model = self._model
        joint_a = model.idx_qs[model.frames[self._link_frames[a]].parentJoint]
        joint_b = model.idx_qs[model.frames[self._link_frames[b]].parentJoint]
        engine = _Engine(self, margin + 0.5 * reach * width, include_fixed, frozenset({pair}))
        q = np.zeros(model.nq)
        free = []
        for k in range(cells):
            q[joint_b] = (k + 0.5) * width
            free.append(not self._collisions_q(q, engine, True))
        return _Sweep(pair, int(joint_a), int(joint_b), free, cells / _TWO_PI)

    def _check(self, q: FloatArray, plan: _Plan, first_only: bool) -> list[LinkPair]:
        """Colliding pairs at q: the relative-angle tables, then one engine."""
        uncleared = 0
        for bit, sweep in enumerate(plan.sweeps):
            cell = int(((q[sweep.b] - q[sweep.a]) % _TWO_PI) * sweep.scale)
            if not sweep.free[min(cell, len(sweep.free) - 1)]:
                uncleared |= 1 << bit
        return self._collisions_q(q, plan.engine(uncleared), first_only)

    def geometry_model(self, margin: float = 0.0, include_fixed: bool = True) -> pin.GeometryModel:
        """The Pinocchio GeometryModel that the check at ``margin`` runs (probe pieces
        and culling BVHs, with its collision pairs), for inspection."""
        return self._engine(margin, include_fixed).geometry_model

    # ------------------------------------------------------------------ checks
    def _collisions_q(self, q: FloatArray, engine: _Engine, first_only: bool) -> list[LinkPair]:
        model, data, gm = self._model, self._data, engine.geometry_model
        datas, blocks = engine.datas, len(engine.block_pairs)
        found: list[LinkPair] = []
        if not blocks or not pin.computeCollisions(model, data, gm, datas[0], q, True):
            return found  # (kinematics, placements and the first pass in one call)
        start = 0
        while True:
            results = engine.results[start]
            k = engine.block_start[start]
            while not results[k]():
                k += 1
            block = engine.pair_block[k]
            found.append(engine.block_pairs[block])
            start = block + 1
            if first_only or start >= blocks:
                break
            gd = datas[start]
            pin.updateGeometryPlacements(model, data, gm, gd)
            if not pin.computeCollisions(gm, gd, True):
                break
        if len(found) > 1:
            found.sort(key=self._rank.__getitem__)
        return found

    def collisions(
        self, x: npt.ArrayLike, *, margin: float = 0.0, include_fixed: bool = True
    ) -> list[LinkPair]:
        """The link pairs that collide (or come nearer than ``margin``) at x.

        Args:
            x: Input angles theta (3,) [rad] (home assembly mode) or a joint
                configuration q (9,) [rad].
            margin: Safety margin [m]: links nearer than this count as colliding.
                Keep it below :attr:`fixed_clearance` (the nested drive tubes of the
                prototype are about 1 mm apart in every configuration), or leave those
                parts out with ``include_fixed=False``.
            include_fixed: Check the parts whose distance does not depend on the
                configuration (see :attr:`fixed_clearance`).

        Returns:
            Colliding link pairs in the order of :attr:`pairs`; never a pair that
            shares a joint. Empty if nothing collides.

        Raises:
            InputError: bad ``x`` or ``margin``.
            UnreachableError: theta without a home-mode assembly.
        """
        plan = self._plan(margin, include_fixed)
        return self._check(self.configuration(x), plan, False)

    def in_collision(
        self, x: npt.ArrayLike, *, margin: float = 0.0, include_fixed: bool = True
    ) -> bool:
        """Whether any link pair collides at x (stops at the first; see :meth:`collisions`)."""
        plan = self._plan(margin, include_fixed)
        return bool(self._check(self.configuration(x), plan, True))

    def collision_matrix(
        self, q: npt.ArrayLike, *, margin: float = 0.0, include_fixed: bool = True
    ) -> BoolArray:
        """Colliding link pairs of many configurations.

        Args:
            q: Joint configurations, shape (N, 9) [rad].
            margin: Safety margin [m].
            include_fixed: See :meth:`collisions`.

        Returns:
            (N, 19) bool, column k for :attr:`pairs` [k].
        """
        plan = self._plan(margin, include_fixed)
        array = self._as_q_batch(q)
        column = {pair: k for k, pair in enumerate(self.pairs)}
        out = np.zeros((array.shape[0], len(self.pairs)), dtype=bool)
        for row, item in enumerate(array):
            for pair in self._check(item, plan, False):
                out[row, column[pair]] = True
        return out

    def _as_q_batch(self, q: npt.ArrayLike) -> FloatArray:
        try:
            array = np.asarray(q, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(
                f"q must be numbers of shape (N, 9) [rad], got {q!r}", argument="q", value=q
            ) from exc
        if array.ndim != 2 or array.shape[1] != self._model.nq:
            raise InputError(
                f"q must have shape (N, {self._model.nq}) [rad], got shape {array.shape}",
                argument="q",
                value=q,
            )
        if not np.all(np.isfinite(array)):
            raise InputError("q must be finite, got NaN or inf", argument="q", value=q)
        return array

    # --------------------------------------------------------------- distances
    def _distance(self, i: int, j: int, transforms: Sequence[Any]) -> float:
        functor = self._distance_functors.get((i, j))
        if functor is None:
            functor = coal.ComputeDistance(self._pieces[i].shape, self._pieces[j].shape)
            self._distance_functors[(i, j)] = functor
        result = self._distance_result
        result.clear()
        return float(
            functor(
                transforms[self._pieces[i].link],
                transforms[self._pieces[j].link],
                self._distance_request,
                result,
            )
        )

    def _distances_q(
        self,
        q: FloatArray,
        pairs: Sequence[LinkPair],
        include_fixed: bool,
        cap: float,
    ) -> dict[LinkPair, float]:
        rotations = self._link_rotations(q)
        transforms = [coal.Transform3s(R, np.zeros(3)) for R in rotations]
        index = self._index
        world = index.world(rotations)
        out: dict[LinkPair, float] = {}
        for number, geometry in enumerate(self._all):
            if geometry.pair not in pairs:
                continue
            out[geometry.pair] = index.link_pair_distance(
                number, world, transforms, include_fixed, cap
            )
        return out

    def _check_pairs(self, pairs: Iterable[LinkPair] | None) -> list[LinkPair]:
        if pairs is None:
            return list(self.pairs)
        chosen = []
        for pair in pairs:
            item = tuple(pair) if isinstance(pair, (tuple, list)) else None
            if item is None or len(item) != 2:
                raise InputError(
                    f"pairs must hold link pairs like ('proximal_1', 'proximal_2'), got {pair!r}",
                    argument="pairs",
                    value=pair,
                )
            a, b = (str(item[0]), str(item[1]))
            key = (a, b) if (a, b) in self.pairs else (b, a)
            if key not in self.pairs:
                raise InputError(
                    f"pairs: {pair!r} is not a checked link pair; allowed: {list(self.pairs)}",
                    argument="pairs",
                    value=pair,
                )
            chosen.append(key)
        return chosen

    def distances(
        self,
        x: npt.ArrayLike,
        *,
        pairs: Iterable[LinkPair] | None = None,
        include_fixed: bool = True,
    ) -> dict[LinkPair, float]:
        """Exact distance of every checked link pair at x [m].

        The minimum over the pairs' convex pieces (GJK), pruned with bounding capsules
        (milliseconds per call: use :meth:`collisions` with a margin to test for a
        clearance). Negative where the links overlap: minus the penetration depth of
        the deepest overlapping pair of pieces (the links' own penetration depth is at
        least that).

        Args:
            x: Input angles theta (3,) [rad] (home mode) or a joint configuration q (9,).
            pairs: Link pairs to measure (default: all of :attr:`pairs`).
            include_fixed: Include the parts whose distance does not depend on the
                configuration (see :attr:`fixed_clearance`); without them a pair with
                nothing else left reads ``inf``.

        Returns:
            Link pair -> distance [m], in the order of :attr:`pairs`.

        Raises:
            InputError: bad ``x`` or ``pairs``.
            UnreachableError: theta without a home-mode assembly.
        """
        chosen = self._check_pairs(pairs)
        return self._distances_q(self.configuration(x), chosen, bool(include_fixed), math.inf)

    def min_clearance(self, x: npt.ArrayLike, *, include_fixed: bool = True) -> float:
        """Smallest distance between two checked links at x [m] (negative if they
        overlap; see :meth:`distances`)."""
        values = self.distances(x, include_fixed=include_fixed).values()
        return float(min(values))

    def clearances(
        self,
        q: npt.ArrayLike,
        *,
        include_fixed: bool = False,
        cap: float = math.inf,
    ) -> FloatArray:
        """Smallest link distance of many configurations [m].

        Args:
            q: Joint configurations, shape (N, 9) [rad].
            include_fixed: Include the configuration-independent parts (off by
                default: a map of them would be flat).
            cap: Distances above this are reported as ``cap`` (faster) [m].

        Returns:
            (N,) clearances [m] (``inf`` where nothing is left to measure).
        """
        array = self._as_q_batch(q)
        if isinstance(cap, bool) or not isinstance(cap, (int, float)) or not cap > 0:
            raise InputError(
                f"cap must be a distance > 0 [m], got {cap!r}", argument="cap", value=cap
            )
        out = np.empty(array.shape[0])
        for row, item in enumerate(array):
            values = self._distances_q(item, list(self.pairs), bool(include_fixed), float(cap))
            out[row] = min(values.values())
        return out


# ------------------------------------------------------------------ input report
@dataclasses.dataclass(frozen=True)
class CollisionReport:
    """Self-collision at one input, whichever assembly mode exists.

    Attributes:
        theta: Input angles [rad], (3,).
        reachable: A home-mode assembly exists.
        mode: Assembly-mode label that was checked (``"+++/-"`` style), or None when
            no assembly exists and only the links that theta alone places were checked.
        home: The checked mode is the home assembly mode.
        checked_pairs: The link pairs that were checked.
        pairs: The colliding link pairs (with ``margin``).
        distances: Distance of every checked pair [m] (negative where they overlap).
        margin: The safety margin used [m].
    """

    theta: FloatArray
    reachable: bool
    mode: str | None
    home: bool
    checked_pairs: tuple[LinkPair, ...]
    pairs: tuple[LinkPair, ...]
    distances: dict[LinkPair, float]
    margin: float

    @property
    def collision(self) -> bool:
        """Any checked pair collides."""
        return bool(self.pairs)

    @property
    def min_distance(self) -> float:
        """Smallest distance over the checked pairs [m] (``inf`` if none)."""
        return float(min(self.distances.values(), default=math.inf))


#: Links whose placement follows from theta alone (no loop closure needed).
_THETA_LINKS = frozenset({"base", "proximal_1", "proximal_2", "proximal_3"})


def _label(b: FloatArray, det_a: float) -> str:
    """Assembly-mode label: signs of b_11, b_22, b_33, then of det A (``"+++/-"``)."""
    return mode_label(b) + ("/+" if det_a > 0 else "/-")


def _home_label(design: SPMDesign) -> str:
    jac = jacobian(np.zeros((1, 3)), design)
    return _label(jac.b[0], float(jac.det_a[0]))


def _mode_order(labels: Sequence[str], home: str) -> list[int]:
    """Indices of assembly-mode labels, nearest to the home label first (fewest
    differing signs, then the given order)."""
    return sorted(
        range(len(labels)),
        key=lambda k: (sum(x != y for x, y in zip(labels[k], home, strict=True)), k),
    )


def check_input(
    theta: npt.ArrayLike,
    robot: SPMRobot | None = None,
    *,
    margin: float = 0.0,
) -> CollisionReport:
    """Self-collision at input angles, even where the home assembly mode does not exist.

    The home assembly mode is checked when it exists. Otherwise the real assembly mode
    nearest to it (fewest signs of b_11, b_22, b_33, det A that differ from
    ``+++/-``) is checked, and the report names it. With no real assembly at all, only
    the links that theta alone places (base and proximal links) are checked.

    Args:
        theta: Input angles [rad], (3,).
        robot: The robot (default: the prototype).
        margin: Safety margin [m].

    Raises:
        InputError: bad ``theta``, ``robot`` or ``margin``.
    """
    from .model.robot import SPMRobot, build_robot

    angles = as_theta(theta)
    if angles.shape != (3,):
        raise InputError(
            f"theta must have shape (3,) [rad], got shape {angles.shape}",
            argument="theta",
            value=theta,
        )
    margin = _check_margin(margin)
    if robot is None:
        robot = build_robot()
    elif not isinstance(robot, SPMRobot):
        raise InputError(
            f"robot must be an SPMRobot, got {type(robot).__name__}", argument="robot", value=robot
        )
    checker = robot.collision_checker
    fk = forward_kinematics(angles, robot.design)
    reachable = bool(fk.reachable)
    mode: str | None
    home_label = _home_label(robot.design)
    q: FloatArray | None
    if reachable:
        q = robot.configuration(angles)
        jac = jacobian(angles[None], robot.design, R=fk.R[None])
        mode, home = _label(jac.b[0], float(jac.det_a[0])), True
    else:
        every = forward_kinematics_all(angles, robot.design)
        labels = [str(label) for label in every.labels[: int(every.count)]]
        mode, home, q = None, False, None
        for k in _mode_order(labels, home_label):
            try:
                q = robot.configuration(angles, mode=labels[k])
            except (UnreachableError, SPMError):  # pragma: no cover - a mode that fails to close
                continue
            mode = labels[k]
            break
    if q is not None:
        checked = checker.pairs
    else:
        checked = tuple(p for p in checker.pairs if p[0] in _THETA_LINKS and p[1] in _THETA_LINKS)
        # Base and proximal links are placed by theta alone: any q with these inputs
        # places them (the passive joints, left at zero, only move the other links).
        q = np.zeros(robot.model.nq)
        q[robot.actuated_q_idx] = angles
    found = checker._check(q, checker._plan(margin), False)
    pairs = tuple(p for p in found if p in checked)
    distances = checker._distances_q(q, list(checked), True, math.inf)
    return CollisionReport(
        theta=angles,
        reachable=reachable,
        mode=mode,
        home=home,
        checked_pairs=tuple(checked),
        pairs=pairs,
        distances=distances,
        margin=margin,
    )
