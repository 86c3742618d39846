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
* **Units.** Each link pair is split by piece groups: a link's parts that are
  symmetric about its axis (a proximal link's drive tube and gear, the base hub:
  faceted solids that turn onto themselves every 2 pi / 48) and the rest. Each unit
  has one culling body per side: a triangle-mesh BVH (coal OBBRSS) of the parts in
  reach, which proves a pair apart in well under a microsecond but is slow to confirm
  a contact (its triangles are thin). Against a distal link, a proximal link's joint
  boss has a BVH of its own, apart from its plate and spoke (near misses then cost
  less).
* **Tables.** Some units are placed relative to each other by one or two joint
  angles: two coaxial proximal links by the difference of their inputs; a symmetric
  part against a distal link by the turn about the axis (modulo its symmetry) and the
  distal link's joint w. A table over those angles, made once per margin, certifies
  each cell free (a check at a larger margin at the cell's middle and a Lipschitz
  bound), colliding (two convex pieces that overlap deeper than that bound) or
  undecided; a lookup in Python floats then settles the unit, and only undecided
  cells leave it to the passes below (about 1 % of them).
* **Probes.** Convex piece pairs that, in a seeded sample of the workspace, caught
  most collisions of their link pair (GJK confirms a contact in about a
  microsecond). All probes of the units left run in one ``pin.computeCollisions``
  call that does not stop; a probe that collides settles its link pair.
* **Bodies.** The culling bodies of the link pairs still open run in one call that
  stops at the first collision; that link pair is recorded and switched off, and the
  call repeats until nothing collides. Switching pairs on and off is done only where
  the set changed since the previous call.

Tables, probes and culling only decide what to skip, never the answer: each table
cell is proved for every angle in it, each probe is a piece of both links, and the
BVHs decide whenever no table or probe does.

Distances (:meth:`CollisionChecker.distances`) are exact minima over the convex
pieces (GJK), pruned with bounding spheres; negative values are penetration depths
of the deepest-overlapping pieces (a lower bound of the links' penetration).
"""

from __future__ import annotations

import collections
import dataclasses
import functools
import math
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING, Any

import coal
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..design import SPMDesign
from ..errors import ConvergenceError, InputError, UnreachableError
from ..kinematics import forward_kinematics, select_assembly
from ..kinematics._common import as_theta, require_angles
from ..model.geometry import LINK_NAMES, link_parts
from ..model.robot import CLOSURE_TOL
from ._shapes import ANGLE_TOL as _ANGLE_TOL
from ._shapes import axis_frame as _axis_frame
from ._shapes import bvh as _bvh
from ._shapes import concatenate as _concatenate
from ._shapes import convex_shape as _convex_shape
from ._shapes import cross as _cross
from ._shapes import dot as _dot
from ._shapes import section_angles as _section_angles
from ._shapes import turn as _turn
from .pieces import ConvexPiece, convex_pieces

if TYPE_CHECKING:
    from ..model.robot import SPMRobot

__all__ = [
    "ADJACENT_PAIRS",
    "DEFAULT_PROBES",
    "LINK_PAIRS",
    "CollisionChecker",
    "CollisionReport",
    "ConvexPiece",
    "LinkPair",
    "build_robot",
    "check_input",
    "checker_of",
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
#: Largest number of margins whose check set-up (tables and engine) is kept (the
#: oldest first out).
PLAN_CACHE = 24

#: Axes closer than this are the same axis.
_AXIS_TOL = 1e-12
#: Length of the segment that stands for a rotation axis in distance queries [m].
_AXIS_LENGTH = 10.0
#: EPA iterations in collision requests: the contact itself comes from GJK; EPA
#: would only refine a penetration depth that is not used.
_EPA_ITERATIONS = 0
#: EPA iterations where a penetration depth certifies a collision (tables only).
_EPA_CERTIFY_ITERATIONS = 128


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


def _geometry_object(robot: SPMRobot, name: str, link: str, shape: Any) -> Any:
    """A Pinocchio geometry object of ``shape`` fixed to the frame of ``link``."""
    frame = robot.link_frames[link]
    model = robot.model
    return pin.GeometryObject(
        name, model.frames[frame].parentJoint, frame, pin.SE3.Identity(), shape
    )


def _collision_data(gm: pin.GeometryModel, margin: float) -> pin.GeometryData:
    """GeometryData of ``gm`` whose requests test for a distance below ``margin``."""
    gd = pin.GeometryData(gm)
    for request in gd.collisionRequests:
        request.security_margin = margin
        request.break_distance = 0.0
        request.epa_max_iterations = _EPA_ITERATIONS
    return gd


class _Engine:
    """The collision check of some link pairs at one margin (see the module docstring).

    A link pair is split into units, one per pair of piece groups (a link's parts
    symmetric about its axis, and the rest), each with its culling BVH pair and the
    probes whose pieces it holds. Two Pinocchio geometry models, made once:

    * probes: the probe piece pairs of every unit, run in one ``pin.computeCollisions``
      call that does not stop (forward kinematics and placements included); a
      colliding probe settles its link pair;
    * bodies: the culling BVHs of every unit, run in one call that stops at the first
      collision; that link pair is recorded and switched off, and the call repeats
      until nothing collides.

    Units that a table settles (``skip``) and, in the body pass, the link pairs that a
    probe settled are switched off; only the changes since the previous call are
    made. Unit k of :attr:`units` is bit k of the masks.
    """

    def __init__(
        self,
        checker: CollisionChecker,
        margin: float,
        include_fixed: bool,
        pairs: frozenset[LinkPair] | None,
    ) -> None:
        robot = checker.robot
        probe_model, body_model = pin.GeometryModel(), pin.GeometryModel()
        probe_objects: dict[int, int] = {}
        body_objects: dict[tuple[str, tuple[str, ...]], int] = {}

        def probe(index: int) -> int:
            if index not in probe_objects:
                piece = checker._pieces[index]
                geometry = _geometry_object(
                    robot, f"piece{index}", LINK_NAMES[piece.link], piece.shape
                )
                probe_objects[index] = probe_model.addGeometryObject(geometry)
            return probe_objects[index]

        def body(link: str, parts: Iterable[str]) -> int:
            key = (link, tuple(sorted(set(parts))))
            if key not in body_objects:
                geometry = _geometry_object(
                    robot, f"{link}/{'+'.join(key[1])}", link, checker._body(key)
                )
                body_objects[key] = body_model.addGeometryObject(geometry)
            return body_objects[key]

        group = checker._piece_group
        #: The units: (link pair, group of the first link, group of the second).
        self.units: list[tuple[LinkPair, int, int]] = []
        self.link_pairs: list[LinkPair] = []
        self.pair_masks: dict[LinkPair, int] = {}
        probe_switches: list[list[int]] = []
        body_switches: list[list[int]] = []
        probe_owner: list[int] = []
        body_owner: list[int] = []
        # Link pairs whose bodies often have to confirm a contact go first: the body
        # pass then repeats over fewer pairs.
        for geometry in (checker._all[k] for k in checker._body_order):
            if pairs is not None and geometry.pair not in pairs:
                continue
            link_a, link_b = geometry.pair
            for group_a, group_b, parts_a, parts_b in checker._unit_parts(
                geometry, margin, include_fixed
            ):
                number = len(self.units)
                self.units.append((geometry.pair, group_a, group_b))
                if geometry.pair not in self.pair_masks:
                    self.link_pairs.append(geometry.pair)
                    self.pair_masks[geometry.pair] = 0
                self.pair_masks[geometry.pair] |= 1 << number
                indices = []
                for i, j in checker._probes.get(geometry.pair, ()):
                    if group[i] == group_a and group[j] == group_b:
                        indices.append(len(probe_owner))
                        probe_model.addCollisionPair(pin.CollisionPair(probe(i), probe(j)))
                        probe_owner.append(number)
                probe_switches.append(indices)
                chunks = [parts_a]
                if group_a == group_b == 0 and (link_a[:9], link_b[:7]) == ("proximal_", "distal_"):
                    # A proximal link's main parts against a distal link: the joint boss
                    # in a BVH of its own, apart from the plate and spoke; the tighter
                    # root volumes make near misses cheaper (measured: p95 -12 %,
                    # median +0.5 us).
                    bosses = {part for part in parts_a if part.startswith("boss")}
                    chunks = [chunk for chunk in (bosses, parts_a - bosses) if chunk]
                switches = []
                for chunk in chunks:
                    first, second = body(link_a, chunk), body(link_b, parts_b)
                    switches.append(len(body_owner))
                    body_model.addCollisionPair(pin.CollisionPair(first, second))
                    body_owner.append(number)
                body_switches.append(switches)
        self.margin = margin
        self.include_fixed = include_fixed
        self.bits = {key: 1 << k for k, key in enumerate(self.units)}
        self.every = (1 << len(self.units)) - 1
        self.probe_model, self.body_model = probe_model, body_model
        self.probe_data = _collision_data(probe_model, margin)
        self.body_data = _collision_data(body_model, margin)
        # Per collision pair: its unit's bit, the isCollision method of its result
        # (bound once: the reference follows the C++ object; indexing the vector
        # proxy at each look-up costs about 4x more), the mask of its link pair's
        # units and the link pair.
        results = self.probe_data.collisionResults
        self.probe_reads = [
            (1 << k, results[n].isCollision, self.pair_masks[self.units[k][0]], self.units[k][0])
            for n, k in enumerate(probe_owner)
        ]
        results = self.body_data.collisionResults
        self.body_reads = [
            (1 << k, results[n].isCollision, self.pair_masks[self.units[k][0]], self.units[k][0])
            for n, k in enumerate(body_owner)
        ]
        self.probe_switches = probe_switches
        self.body_switches = body_switches
        # Masks of the units whose probes, and bodies, are switched off.
        self.probe_off = 0
        self.body_off = 0

    @property
    def geometry_model(self) -> pin.GeometryModel:
        """Both passes in one model, for inspection: the probe pairs, then the bodies."""
        gm = pin.GeometryModel()
        for model in (self.probe_model, self.body_model):
            offset = gm.ngeoms
            for geometry in model.geometryObjects:
                gm.addGeometryObject(geometry)
            for pair in model.collisionPairs:
                gm.addCollisionPair(pin.CollisionPair(pair.first + offset, pair.second + offset))
        return gm

    @staticmethod
    def _switch(gd: pin.GeometryData, switches: list[list[int]], changed: int, off: int) -> None:
        """Switch the collision pairs of the units in mask ``changed`` off (if in mask
        ``off``) or on."""
        while changed:
            low = changed & -changed
            changed ^= low
            toggle = gd.deactivateCollisionPair if off & low else gd.activateCollisionPair
            for k in switches[low.bit_length() - 1]:
                toggle(k)

    def run(
        self, model: pin.Model, data: pin.Data, q: FloatArray, first_only: bool, skip: int
    ) -> list[LinkPair]:
        """The colliding link pairs at q, leaving out the units of mask ``skip`` (not
        sorted; with ``first_only``, at most one)."""
        if skip != self.probe_off:
            self._switch(self.probe_data, self.probe_switches, skip ^ self.probe_off, skip)
            self.probe_off = skip
        found = []
        off = skip
        if pin.computeCollisions(model, data, self.probe_model, self.probe_data, q, False):
            for bit, read, mask, pair in self.probe_reads:
                if not off & bit and read():  # (switched-off results are stale)
                    off |= mask
                    found.append(pair)
                    if first_only:
                        return found
        if off != self.body_off:
            self._switch(self.body_data, self.body_switches, off ^ self.body_off, off)
            self.body_off = off
        if off == self.every:
            return found
        gm, gd = self.body_model, self.body_data
        pin.updateGeometryPlacements(model, data, gm, gd)
        while pin.computeCollisions(gm, gd, True):
            # The first switched-on pair that collides (the pass stopped there).
            _, _, mask, pair = next(
                entry for entry in self.body_reads if not off & entry[0] and entry[1]()
            )
            found.append(pair)
            self._switch(gd, self.body_switches, mask & ~off, off | mask)
            off = self.body_off = off | mask
            if first_only or off == self.every:
                break
        return found


_TWO_PI = 2.0 * math.pi
#: Largest distance error allowed to a table per angle [m] (see _Plan).
_SWEEP_BUDGET = 0.0005
#: Most cells of a table.
_SWEEP_CELLS = 8192
#: Tables of symmetric parts consider the parts within this distance of the other link
#: (a table's own distance error stays below it) [m].
_TABLE_REACH = 0.002
#: Symmetric parts turn onto themselves by at most this angle [rad] (2 pi / 8).
_MIN_ORDER = 8
#: States of a table cell: the pair is certainly apart by more than the margin,
#: certainly colliding, or has to be checked.
_FREE, _HIT, _CHECK = 0, 1, 2
#: Added to the Lipschitz bounds of the tables: covers the rounding of an angle to its
#: cell and the tolerance of coal's penetration depths [m].
_SWEEP_SLACK = 1e-6


@dataclasses.dataclass(frozen=True)
class _Table:
    """Certified states of a link pair, or of one unit of it, over one or two angles.

    The angles are alpha = q[b] - q[a] (mod ``period``; index nq of the values reads
    0) and beta = q[c] (mod 2 pi; none for nq). ``state`` holds the cells row by row
    (alpha along the rows), each cell :data:`_FREE`, :data:`_HIT` or :data:`_CHECK`
    for every alpha and beta in it, with one more row (and column, for two angles)
    that repeats the first (an angle at the end of its period rounds onto it).
    """

    pair: LinkPair
    unit: tuple[int, int] | None  # (group of the first link, of the second); None: all
    a: int
    b: int
    period: float
    rows: int
    c: int
    columns: int
    state: tuple[int, ...]


class _Plan:
    """How to check at one margin: certified tables, and the engine for the rest.

    Tables map a few joint angles to cells whose states are proved once, at the cell's
    middle, with a Lipschitz bound: a relative turn of the two parts by e moves no
    point of them by more than r |e|, r the largest distance of the moving part from
    the turning axis. Over a cell where no point moves by more than b:

    * a check at margin m + b at the middle that finds nothing proves the pair apart
      by more than m in the whole cell;
    * two convex pieces that overlap at the middle by a penetration depth above b
      overlap in the whole cell (were a moved copy apart, a plane would separate them,
      and the pieces at the middle, no point more than b away, would come apart by a
      translation of b along its normal), so the pair collides at any margin. coal's
      depth (EPA) is that of a polytope inside the pieces' Minkowski difference,
      never above the true depth.

    Two kinds (coaxial designs):

    * two proximal links turn about one axis: their relative pose is the difference
      of their inputs, one angle over a turn (the whole link pair);
    * a part symmetric about the axis (a proximal link's drive tube, the base hub:
      faceted, they turn onto themselves every 2 pi / n) against a distal link j:
      the distal link is placed, relative to it, by a turn about the axis (the
      difference of the inputs, or theta_j for the base) and then by q_wj about
      w_j0. The first angle counts modulo 2 pi / n, the symmetric part being the one
      that turns (its radius is small); the second over a turn.

    Cells certified free or colliding need no check at run time; elsewhere the engine
    checks as everywhere else.
    """

    def __init__(
        self,
        checker: CollisionChecker,
        margin: float,
        include_fixed: bool,
        pairs: frozenset[LinkPair] | None,
    ) -> None:
        self.margin = margin
        self.include_fixed = include_fixed
        chosen = [p for p in LINK_PAIRS if pairs is None or p in pairs]
        self.engine = _Engine(checker, margin, include_fixed, frozenset(chosen))
        self.tables: list[_Table] = []
        for pair in chosen:
            table = checker._link_table(pair, margin, include_fixed)
            if table is not None:
                self.tables.append(table)
        for pair, group_a, group_b in self.engine.units:
            if group_a == 1:
                unit = checker._unit_table(pair, group_b, margin, include_fixed)
                if unit is not None:
                    self.tables.append(unit)
        # What a check reads per table (plain Python values): the joints, the scales,
        # the states, the units that a free cell settles, the link pair's units.
        self.lookups = []
        for t in self.tables:
            masks = self.engine.pair_masks.get(t.pair, 0)
            free = masks if t.unit is None else self.engine.bits.get((t.pair, *t.unit), 0)
            self.lookups.append(
                (
                    t.a,
                    t.b,
                    t.period,
                    (t.rows - 1) / t.period,
                    t.c,
                    (t.columns - 1) / _TWO_PI,
                    t.columns,
                    t.state,
                    free,
                    masks,
                    t.pair,
                )
            )


def _symmetry_order(vertices: FloatArray, axis: FloatArray) -> int:
    """The order n >= :data:`_MIN_ORDER` of a vertex set that turns onto itself by
    2 pi / n about ``axis`` through O (to 1e-9 of its size), else 0."""
    height = vertices @ axis
    radial = vertices - height[:, None] * axis
    size = float(np.abs(vertices).max())
    off = np.linalg.norm(radial, axis=1) > 1e-9 * size
    if np.count_nonzero(off) < _MIN_ORDER:
        return 0
    e1, e2 = _axis_frame(axis)
    angle = np.sort(np.mod(np.arctan2(radial[off] @ e2, radial[off] @ e1), _TWO_PI))
    steps = np.diff(np.concatenate([angle, [angle[0] + _TWO_PI]]))
    steps = steps[steps > _ANGLE_TOL]
    if steps.size == 0:
        return 0
    n = round(_TWO_PI / float(steps.min()))
    if n < _MIN_ORDER:
        return 0
    c, s = math.cos(_TWO_PI / n), math.sin(_TWO_PI / n)
    turned = vertices * c + np.cross(axis, vertices) * s + np.outer(vertices @ axis, axis) * (1 - c)
    gaps = np.linalg.norm(turned[:, None, :] - vertices[None, :, :], axis=2).min(axis=1)
    return n if float(gaps.max()) <= 1e-9 * size else 0


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
        from ..model.robot import SPMRobot

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
        # Per leg: u_i, w_i0, v_i0 as float tuples (q from theta, see configuration).
        self._legs = tuple(
            tuple(tuple(float(c) for c in row) for row in axes)
            for axes in (self.design.u, self.design.w0, self.design.v0)
        )
        self._parts = {name: tuple(parts) for name, parts in link_parts(self.design).items()}
        self._turning_axes = self._common_axes()
        self._pieces: list[_Piece] = []
        self.pieces: tuple[ConvexPiece, ...] = tuple(
            piece for name in LINK_NAMES for piece in convex_pieces(self.design)[name]
        )
        revolved = self._revolved_parts()
        for piece in self.pieces:
            self._pieces.append(self._piece(piece, revolved))
        # Parts symmetric about their link's axis (group 1: a proximal link's drive
        # tube and gear, the base hub and plate) and their orders; group 0 is the rest.
        self._symmetry_axes = self._link_axes()
        self._orders: dict[tuple[int, str], int] = {}
        for index, name in enumerate(LINK_NAMES):
            axis = self._symmetry_axes[index]
            if axis is None:
                continue
            for part in self._parts[name]:
                order = _symmetry_order(np.asarray(part.mesh.vertices, dtype=float), axis)
                if order:
                    self._orders[(index, part.name)] = order
        self._piece_group = np.array(
            [int((p.link, p.part) in self._orders) for p in self._pieces], dtype=np.int64
        )
        self._piece_link = np.array([p.link for p in self._pieces], dtype=np.int64)
        self._centers = np.array([p.center for p in self._pieces])
        self._radii = np.array([p.radius for p in self._pieces])
        self._anchors = np.array([p.anchor for p in self._pieces])
        self._all = [self._link_pair_geometry(pair) for pair in LINK_PAIRS]
        self._index = _DistanceIndex(self)
        fixed = [g.static_bound[g.fixed] for g in self._all if np.any(g.fixed)]
        self.fixed_clearance: float = float(min(np.min(f) for f in fixed)) if fixed else math.inf
        self._probes: dict[LinkPair, tuple[tuple[int, int], ...]] = {}
        # How often each link pair collided in the sample with no probe catching it:
        # the body pass takes the link pairs in that order.
        self._unprobed: dict[LinkPair, float] = {}
        # How often each piece pair collided in that sample (tables try them in order).
        self._piece_hits: collections.Counter[tuple[int, int]] = collections.Counter()
        if probe_samples:
            self._probes = self._choose_probes(int(probes), int(probe_samples), int(seed))
        self.probes: dict[LinkPair, tuple[tuple[int, int], ...]] = dict(self._probes)
        self._rank = {pair: k for k, pair in enumerate(LINK_PAIRS)}
        self._body_order = sorted(
            range(len(LINK_PAIRS)), key=lambda k: -self._unprobed.get(LINK_PAIRS[k], 0.0)
        )
        self._plans: collections.OrderedDict[
            tuple[float, bool, frozenset[LinkPair] | None], _Plan
        ] = collections.OrderedDict()
        self._bodies: dict[tuple[str, tuple[str, ...]], Any] = {}
        self._deep_results: dict[
            tuple[object, ...], tuple[pin.GeometryModel, npt.NDArray[np.int8]]
        ] = {}
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

    def _link_axes(self) -> list[FloatArray | None]:
        """Per link, the axis through O that its symmetric parts turn about: a
        proximal link's input axis, the base's when the design is coaxial."""
        u = self.design.u
        axes: list[FloatArray | None] = [None] * len(LINK_NAMES)
        for leg in range(3):
            axes[LINK_NAMES.index(f"proximal_{leg + 1}")] = np.array(u[leg], dtype=float)
        if np.allclose(u, u[0], rtol=0.0, atol=_AXIS_TOL):
            axes[LINK_NAMES.index("base")] = np.array(u[0], dtype=float)
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
        left to the BVH costs several microseconds, up to tens."""
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
        self._piece_hits = collections.Counter(p for v in hits.values() for s in v for p in s)
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
            self._unprobed[self._all[pair_index].pair] = len(remaining) / total
        return chosen

    # ------------------------------------------------------------------ inputs
    def _link_rotations(self, q: FloatArray) -> FloatArray:
        """World rotations of the links at q, (8, 3, 3) in LINK_NAMES order."""
        model, data = self._model, self._data
        pin.framesForwardKinematics(model, data, q)
        return np.array([data.oMf[frame].rotation for frame in self._link_frames])

    def configuration(self, x: npt.ArrayLike) -> FloatArray:
        """q (9,) from input angles theta (3,) (home assembly mode) or a q (9,).

        From theta, q is that of :meth:`SPMRobot.configuration
        <spm_pin.SPMRobot.configuration>` (the same formulas, in Python floats: one
        input costs a fraction of the numpy path).

        Raises:
            InputError: not shape (3,) or (9,), or not finite.
            UnreachableError: theta without a home-mode assembly.
            ConvergenceError: the configuration does not close (see
                :meth:`SPMRobot.configuration <spm_pin.SPMRobot.configuration>`).
        """
        if (
            type(x) is np.ndarray
            and x.shape == (self._model.nq,)
            and x.dtype == np.float64
            and math.isfinite(sum(x.tolist()))  # a non-finite sum takes the slow path
        ):
            return x  # the common case, kept short
        try:
            array = np.asarray(x, dtype=float)
        except (TypeError, ValueError, OverflowError) as exc:
            raise InputError(
                f"x must be input angles theta (3,) or a joint configuration q (9,) [rad], "
                f"got {x!r}",
                argument="x",
                value=x,
            ) from exc
        if array.shape == (3,):
            return self._theta_configuration(as_theta(array, "theta"))
        if array.shape != (self._model.nq,):
            raise InputError(
                "x must be input angles theta of shape (3,) or a joint configuration q "
                f"of shape ({self._model.nq},) [rad], got shape {array.shape}",
                argument="x",
                value=x,
            )
        require_angles(array, "x", x)
        return array

    def _theta_configuration(self, theta: FloatArray) -> FloatArray:
        """The closed q of one theta (3,) in the home assembly mode.

        The method of ``SPMRobot.configuration`` (see :mod:`spm_pin.model.robot`):
        q_ui = theta_i; q_wi = psi_i with Rot(w_i0, psi_i) v_i0 = P_i^T R v_i0; q_vi =
        chi_i with Rot(v_i0, chi_i) = D_i^T R, checked to :data:`CLOSURE_TOL
        <spm_pin.model.robot.CLOSURE_TOL>` (that check proves every leg ends at R,
        so the loops close).
        """
        fk = forward_kinematics(theta, self.design)
        if not bool(fk.reachable):
            raise UnreachableError(
                f"theta = {np.degrees(theta).round(6).tolist()} deg has no assembly in mode "
                "'home'; filter inputs with spm.forward_kinematics(theta, design).reachable",
                value=theta,
            )
        columns = tuple(zip(*fk.R.tolist(), strict=True))
        q: list[float] = []
        worst = 0.0
        for angle, u, w0, v0 in zip(theta.tolist(), *self._legs, strict=True):
            # Columns of P^T R: R's columns turned by -theta about u.
            c, s = math.cos(angle), math.sin(angle)
            p0, p1, p2 = (_turn(u, c, -s, column) for column in columns)
            # psi from the components of v0 and P^T R v0 normal to w0.
            x, y, z = v0
            target = (
                p0[0] * x + p1[0] * y + p2[0] * z,
                p0[1] * x + p1[1] * y + p2[1] * z,
                p0[2] * x + p1[2] * y + p2[2] * z,
            )
            along_v, along_t = _dot(w0, v0), _dot(w0, target)
            a = (x - along_v * w0[0], y - along_v * w0[1], z - along_v * w0[2])
            b = (
                target[0] - along_t * w0[0],
                target[1] - along_t * w0[1],
                target[2] - along_t * w0[2],
            )
            psi = math.atan2(_dot(w0, _cross(a, b)), _dot(a, b))
            # M = D^T R = Rot(w0, -psi) P^T R (columns m0, m1, m2); chi from its
            # axis-angle form, and M must be that turn about v0.
            c, s = math.cos(psi), math.sin(psi)
            m0, m1, m2 = _turn(w0, c, -s, p0), _turn(w0, c, -s, p1), _turn(w0, c, -s, p2)
            sin_chi = 0.5 * (x * (m1[2] - m2[1]) + y * (m2[0] - m0[2]) + z * (m0[1] - m1[0]))
            chi = math.atan2(sin_chi, 0.5 * (m0[0] + m1[1] + m2[2] - 1.0))
            c, s = math.cos(chi), math.sin(chi)
            t = 1.0 - c
            worst = max(
                worst,
                abs(m0[0] - c - t * x * x),
                abs(m0[1] - t * x * y - s * z),
                abs(m0[2] - t * x * z + s * y),
                abs(m1[0] - t * x * y + s * z),
                abs(m1[1] - c - t * y * y),
                abs(m1[2] - t * y * z - s * x),
                abs(m2[0] - t * x * z - s * y),
                abs(m2[1] - t * y * z + s * x),
                abs(m2[2] - c - t * z * z),
            )
            q += [angle, psi, chi]
        if not worst <= CLOSURE_TOL:  # pragma: no cover - FK certifies its solutions
            raise ConvergenceError(
                f"the platform rotation does not fit leg geometry at theta = "
                f"{np.degrees(theta).tolist()} deg: residual {worst:.3g}",
                data={"theta": theta, "R": fk.R, "residual": worst},
            )
        return np.array(q)

    def _plan(
        self,
        margin: float = 0.0,
        include_fixed: bool = True,
        pairs: Iterable[LinkPair] | None = None,
    ) -> _Plan:
        """The check at one margin: relative-angle tables and engines (made on first
        use, then kept)."""
        if pairs is None and type(margin) is float and type(include_fixed) is bool:
            # Only validated margins are keys: a float equal to one is valid too.
            known = self._plans.get((margin, include_fixed, None))
            if known is not None:
                return known
        subset = None if pairs is None else frozenset(self._check_pairs(pairs))
        key = (_check_margin(margin), bool(include_fixed), subset)
        plan = self._plans.get(key)
        if plan is None:
            plan = _Plan(self, *key)
            self._plans[key] = plan
            while len(self._plans) > PLAN_CACHE:
                self._plans.popitem(last=False)
        return plan

    def _unit_parts(
        self, geometry: _LinkPairGeometry, margin: float, include_fixed: bool
    ) -> list[tuple[int, int, set[str], set[str]]]:
        """The units of a link pair at ``margin``: per pair of piece groups that has
        pieces within reach, the groups and the parts of either link in reach."""
        near = geometry.static_bound <= margin
        if not include_fixed:
            near &= ~geometry.fixed
        group_a, group_b = self._piece_group[geometry.a], self._piece_group[geometry.b]
        units = []
        for first in (0, 1):
            for second in (0, 1):
                keep = near & (group_a == first) & (group_b == second)
                if np.any(keep):
                    parts_a = {self._pieces[i].part for i in geometry.a[keep]}
                    parts_b = {self._pieces[j].part for j in geometry.b[keep]}
                    units.append((first, second, parts_a, parts_b))
        return units

    def _body_model(
        self,
        geometry: _LinkPairGeometry,
        margin: float,
        include_fixed: bool,
        groups: tuple[int, int] | None = None,
    ) -> pin.GeometryModel:
        """The culling BVH pairs of a link pair (or of one unit of it) at ``margin``, as
        one Pinocchio model (for the tables' checks)."""
        gm = pin.GeometryModel()
        link_a, link_b = geometry.pair
        for first, second, parts_a, parts_b in self._unit_parts(geometry, margin, include_fixed):
            if groups is not None and (first, second) != groups:
                continue
            objects = []
            for link, parts in ((link_a, parts_a), (link_b, parts_b)):
                key = (link, tuple(sorted(parts)))
                geometry_object = _geometry_object(
                    self.robot, f"{link}/{'+'.join(key[1])}", link, self._body(key)
                )
                objects.append(gm.addGeometryObject(geometry_object))
            gm.addCollisionPair(pin.CollisionPair(objects[0], objects[1]))
        return gm

    def _body(self, key: tuple[str, tuple[str, ...]]) -> Any:
        """The culling BVH of some parts of a link (made once, shared by the engines)."""
        shape = self._bodies.get(key)
        if shape is None:
            link, names = key
            shape = _bvh(_concatenate([p.mesh for p in self._parts[link] if p.name in names]))
            self._bodies[key] = shape
        return shape

    def _joint_q(self, link: str, up: int = 0) -> int:
        """Index in q of the joint that carries ``link`` (``up`` joints towards the base)."""
        model = self._model
        joint = model.frames[self._link_frames[LINK_NAMES.index(link)]].parentJoint
        for _ in range(up):
            joint = model.parents[joint]
        return int(model.idx_qs[joint])

    def _certify(
        self,
        free_model: pin.GeometryModel,
        deep: Callable[[], tuple[pin.GeometryModel, npt.NDArray[np.int8]]],
        margin: float,
        bound: float,
        q: FloatArray,
    ) -> tuple[int, ...]:
        """Cell states from checks at the cells' middles q (N, nq): free where the
        ``free_model`` pairs are apart by more than ``margin + bound``, colliding where
        two pieces of the model that ``deep`` gives overlap by more than ``bound``.
        Penetrations do not depend on the margin: ``deep`` also gives the cells'
        known results (1, 0, or -1 for not checked yet), which are filled in."""
        free = ~self._batch(free_model, margin + bound, _EPA_ITERATIONS, q)
        state = np.where(free, _FREE, _CHECK)
        if not np.all(free):
            model, known = deep()
            todo = np.flatnonzero(~free & (known < 0))
            if todo.size:
                known[todo] = self._batch(model, -bound, _EPA_CERTIFY_ITERATIONS, q[todo])
            state[~free & (known == 1)] = _HIT
        return tuple(int(v) for v in state)

    def _deep(
        self,
        key: tuple[object, ...],
        cells: int,
        make: Callable[[], pin.GeometryModel],
    ) -> Callable[[], tuple[pin.GeometryModel, npt.NDArray[np.int8]]]:
        """The penetration model of a table (made by ``make`` on first use) and its
        cells' results, kept across margins under ``key``."""

        def get() -> tuple[pin.GeometryModel, npt.NDArray[np.int8]]:
            entry = self._deep_results.get(key)
            if entry is None:
                entry = self._deep_results[key] = (make(), np.full(cells, -1, dtype=np.int8))
            return entry

        return get

    def _batch(self, gm: pin.GeometryModel, margin: float, epa: int, q: FloatArray) -> BoolArray:
        """Whether any pair of ``gm`` comes nearer than ``margin`` [m] at each q (N, nq)
        (one Pinocchio call for the batch)."""
        if not len(gm.collisionPairs) or q.shape[0] == 0:
            return np.zeros(q.shape[0], dtype=bool)
        gd = pin.GeometryData(gm)
        for request in gd.collisionRequests:
            request.security_margin = margin
            request.break_distance = 0.0
            request.epa_max_iterations = epa
        pool = pin.GeometryPool(self._model, gm, 1)
        pool.update(gd)
        batch = np.asfortranarray(q.T)
        return np.asarray(pin.computeCollisionsInParallel(1, pool, batch, True), dtype=bool)

    def _deep_model(
        self,
        geometry: _LinkPairGeometry,
        include_fixed: bool,
        groups: tuple[int, int] | None = None,
        sweep: tuple[FloatArray, FloatArray, float] | None = None,
    ) -> pin.GeometryModel:
        """The piece pairs of a link pair (or of one unit of it) that can overlap, as
        one Pinocchio model (for penetration checks). With ``sweep`` (axis u, axis w,
        angle P): only the pairs that can overlap while the second link turns by up to
        P about u after any turn about w (its piece centres keep to circles about w,
        moved by at most |c| P)."""
        near = geometry.static_bound <= 0.0
        if not include_fixed:
            near &= ~geometry.fixed
        if groups is not None:
            near &= self._piece_group[geometry.a] == groups[0]
            near &= self._piece_group[geometry.b] == groups[1]
        if sweep is not None:
            _, w, angle = sweep
            a, b = geometry.a, geometry.b
            centre_b = self._centers[b]
            along = centre_b @ w
            circle = np.linalg.norm(centre_b - np.outer(along, w), axis=1)
            offset = self._centers[a] - np.outer(along, w)
            height = offset @ w
            across = np.linalg.norm(offset - np.outer(height, w), axis=1)
            gap = np.hypot(height, across - circle)
            reach = self._radii[a] + self._radii[b] + np.linalg.norm(centre_b, axis=1) * angle
            near &= gap <= reach
        # The pairs that collided most often in the probes' sample first: a check
        # stops at the first deep overlap.
        hits = self._piece_hits
        candidates = sorted(
            zip(geometry.a[near].tolist(), geometry.b[near].tolist(), strict=True),
            key=lambda p: -hits[p],
        )
        gm = pin.GeometryModel()
        objects: dict[int, int] = {}
        for pieces in candidates:
            for index in pieces:
                if index not in objects:
                    piece = self._pieces[index]
                    objects[index] = gm.addGeometryObject(
                        _geometry_object(
                            self.robot, f"piece{index}", LINK_NAMES[piece.link], piece.shape
                        )
                    )
            gm.addCollisionPair(pin.CollisionPair(objects[pieces[0]], objects[pieces[1]]))
        return gm

    def _link_table(self, pair: LinkPair, margin: float, include_fixed: bool) -> _Table | None:
        """The table of two links turning about one axis, over the difference of their
        inputs (None for other pairs, or when the margin leaves no room below a fixed
        clearance; see :class:`_Plan`)."""
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
        # Either link may be the one that turns: the one nearer to the axis.
        reach = min(
            max(p.ring[1] for p in self._pieces if p.link == link and p.ring is not None)
            for link in (a, b)
        )
        cells = math.ceil(_TWO_PI * reach / (2.0 * budget)) if budget > 0 else _SWEEP_CELLS + 1
        if cells > _SWEEP_CELLS:
            return None
        width = _TWO_PI / cells
        bound = 0.5 * reach * width + _SWEEP_SLACK  # largest move of a point in a cell [m]
        joint_a, joint_b = self._joint_q(pair[0]), self._joint_q(pair[1])
        q = np.zeros((cells, self._model.nq))
        q[:, joint_b] = (np.arange(cells) + 0.5) * width
        free = self._body_model(geometry, margin + bound, include_fixed)
        deep = self._deep(
            (pair, include_fixed, cells),
            cells,
            lambda: self._deep_model(geometry, include_fixed),
        )
        state = self._certify(free, deep, margin, bound, q)
        nq = self._model.nq
        return _Table(pair, None, joint_a, joint_b, _TWO_PI, cells + 1, nq, 1, (*state, state[0]))

    def _unit_table(
        self, pair: LinkPair, group_b: int, margin: float, include_fixed: bool
    ) -> _Table | None:
        """The table of the symmetric parts of a link (base or proximal link) against
        a distal link, over the turn about the axis (modulo the parts' symmetry) and
        the distal link's joint w (None when the pair is not of that kind; see
        :class:`_Plan`)."""
        a, b = (LINK_NAMES.index(name) for name in pair)
        axis = self._symmetry_axes[a]
        if axis is None or not pair[1].startswith("distal_") or pair[0] == "platform":
            return None
        leg = int(pair[1].split("_")[1]) - 1
        if not np.allclose(self.design.u[leg], axis, rtol=0.0, atol=_AXIS_TOL):
            return None
        geometry = self._all[LINK_PAIRS.index(pair)]
        group = self._piece_group
        near = (
            (geometry.static_bound <= margin + _TABLE_REACH)
            & (group[geometry.a] == 1)
            & (group[geometry.b] == group_b)
        )
        if not include_fixed:
            near &= ~geometry.fixed
        if not np.any(near):
            return None
        # The symmetric parts within reach: they turn onto themselves every 2 pi / n.
        parts = {self._pieces[i].part for i in geometry.a[near]}
        order = functools.reduce(math.gcd, (self._orders[(a, part)] for part in parts))
        if order < _MIN_ORDER:
            return None
        period = _TWO_PI / order
        vertices = np.vstack(
            [np.asarray(p.mesh.vertices) for p in self._parts[pair[0]] if p.name in parts]
        )
        radius_a = float(np.linalg.norm(vertices - np.outer(vertices @ axis, axis), axis=1).max())
        w = self.design.w0[leg]
        pieces_b = [p for p in self.pieces if p.link == pair[1]]
        vertices = np.vstack(
            [
                p.vertices
                for p, g in zip(pieces_b, group[self._piece_link == b], strict=True)
                if g == group_b
            ]
        )
        radius_b = float(np.linalg.norm(vertices - np.outer(vertices @ w, w), axis=1).max())
        rows = max(1, math.ceil(period * radius_a / (2.0 * _SWEEP_BUDGET)))
        columns = math.ceil(_TWO_PI * radius_b / (2.0 * _SWEEP_BUDGET))
        bound = 0.5 * (radius_a * period / rows + radius_b * _TWO_PI / columns) + _SWEEP_SLACK
        if bound > _TABLE_REACH or rows * columns > _SWEEP_CELLS:
            return None
        nq = self._model.nq
        joint_a = self._joint_q(pair[0]) if pair[0] != "base" else nq
        joint_b, joint_c = self._joint_q(pair[1], up=1), self._joint_q(pair[1])
        grid_a, grid_c = np.meshgrid(
            (np.arange(rows) + 0.5) * period / rows,
            (np.arange(columns) + 0.5) * _TWO_PI / columns,
            indexing="ij",
        )
        q = np.zeros((rows * columns, nq))
        q[:, joint_b] = grid_a.ravel()
        q[:, joint_c] = grid_c.ravel()
        free = self._body_model(geometry, margin + bound, include_fixed, (1, group_b))
        deep = self._deep(
            (pair, group_b, include_fixed, rows, columns, frozenset(parts)),
            rows * columns,
            lambda: self._deep_model(geometry, include_fixed, (1, group_b), (axis, w, period)),
        )
        cells = self._certify(free, deep, margin, bound, q)
        state: list[int] = []
        for row in (*range(rows), 0):  # the last row and column repeat the first
            state += cells[row * columns : (row + 1) * columns]
            state.append(cells[row * columns])
        return _Table(
            pair,
            (1, group_b),
            joint_a,
            joint_b,
            period,
            rows + 1,
            joint_c,
            columns + 1,
            tuple(state),
        )

    def _check(self, q: FloatArray, plan: _Plan, first_only: bool) -> list[LinkPair]:
        """Colliding pairs at q: the tables, then the engine for the units they leave
        (sorted in the order of :attr:`pairs`)."""
        found: list[LinkPair] = []
        skip = hit = 0
        if plan.lookups:
            values = q.tolist()
            values.append(0.0)
            for (
                a,
                b,
                period,
                scale_a,
                c,
                scale_c,
                columns,
                state,
                free,
                units,
                pair,
            ) in plan.lookups:
                cell = state[
                    int(((values[b] - values[a]) % period) * scale_a) * columns
                    + int((values[c] % _TWO_PI) * scale_c)
                ]
                if cell == _FREE:
                    skip |= free
                elif cell == _HIT:
                    if first_only:
                        return [pair]
                    if not hit & units:
                        found.append(pair)
                    hit |= units
        found += plan.engine.run(self._model, self._data, q, first_only, skip | hit)
        if len(found) > 1:
            found.sort(key=self._rank.__getitem__)
        return found

    def geometry_model(self, margin: float = 0.0, include_fixed: bool = True) -> pin.GeometryModel:
        """The collision pairs that the check at ``margin`` runs when no table settles a
        pair (probe pieces, then culling BVHs), in one Pinocchio GeometryModel, for
        inspection."""
        return self._plan(margin, include_fixed).engine.geometry_model

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
        except (TypeError, ValueError, OverflowError) as exc:
            raise InputError(
                f"q must be numbers of shape (N, 9) [rad], got {q!r}", argument="q", value=q
            ) from exc
        if array.ndim != 2 or array.shape[1] != self._model.nq:
            raise InputError(
                f"q must have shape (N, {self._model.nq}) [rad], got shape {array.shape}",
                argument="q",
                value=q,
            )
        require_angles(array, "q", q)
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


def build_robot(design: SPMDesign | str | None = None) -> SPMRobot:
    """The SPM as a Pinocchio model with geometry, loop closures and its self-collision
    checker: :func:`spm_pin.model.robot.build_robot` given
    :class:`CollisionChecker` as its checker factory. This is ``spm.build_robot``.

    Args:
        design: The SPM (default: the prototype).

    Returns:
        An :class:`~spm_pin.SPMRobot` whose ``collisions``, ``distances`` and
        ``min_clearance`` work.

    Example:
        >>> import spm_pin as spm
        >>> robot = spm.build_robot()
        >>> robot.collisions([0.0, 0.0, 0.0])
        []
    """
    from ..model.robot import build_robot as build_model

    return build_model(design, checker_factory=CollisionChecker)


def checker_of(robot: SPMRobot) -> CollisionChecker:
    """The robot's own :class:`CollisionChecker`, made and kept on the robot when it
    was built without one (by ``spm_pin.model.robot.build_robot``)."""
    checker = robot.__dict__.get("_collision_checker")
    if isinstance(checker, CollisionChecker):
        return checker
    try:
        own = robot.collision_checker
    except InputError:  # a robot built without a checker factory
        own = None
    if isinstance(own, CollisionChecker):
        return own
    made = CollisionChecker(robot)
    if own is None:
        robot.__dict__["_collision_checker"] = made
    return made


def check_input(
    theta: npt.ArrayLike,
    robot: SPMRobot | None = None,
    *,
    margin: float = 0.0,
) -> CollisionReport:
    """Self-collision at input angles, even where the home assembly mode does not exist.

    The assembly mode is chosen by the library's one rule
    (:func:`~spm_pin.select_assembly`): the home mode where it exists, else the real
    assembly mode nearest to it, named in the report. With no real assembly at all,
    only the links that theta alone places (base and proximal links) are checked.

    Args:
        theta: Input angles [rad], (3,).
        robot: The robot (default: the prototype).
        margin: Safety margin [m].

    Raises:
        InputError: bad ``theta``, ``robot`` or ``margin``.
    """
    from ..model.robot import SPMRobot

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
    checker = checker_of(robot)
    chosen = select_assembly(angles, robot.design)
    mode = str(chosen.label) if bool(chosen.exists) else None
    q: FloatArray | None = None
    if bool(chosen.exists):
        q = robot._closed_configuration(angles, chosen.R)
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
        reachable=bool(chosen.home),
        mode=mode,
        home=bool(chosen.home),
        checked_pairs=tuple(checked),
        pairs=pairs,
        distances=distances,
        margin=margin,
    )
