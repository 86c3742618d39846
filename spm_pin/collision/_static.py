"""The static piece model of a robot's links, built once per robot: every convex piece
as a coal shape with its rotation-invariant bounds, the link pairs' piece pairs with
their static distance bounds, the parts symmetric about a link's axis, and the
culling BVHs of groups of parts."""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Any

import coal
import numpy as np
import pinocchio as pin

from ..model.geometry import LINK_NAMES, LinkPart, link_parts
from ._shapes import (
    AXIS_LENGTH,
    AXIS_TOL,
    axis_frame,
    bvh,
    capsule,
    concatenate,
    convex_shape,
    revolution_order,
    symmetry_order,
)
from .pairs import LINK_PAIRS, BoolArray, FloatArray, IntArray, LinkPair
from .pieces import ConvexPiece, convex_pieces

if TYPE_CHECKING:
    from ..design import SPMDesign
    from ..model.robot import SPMRobot

__all__ = ["LinkModel", "LinkPairGeometry", "Piece"]


@dataclasses.dataclass
class Piece:
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
class LinkPairGeometry:
    """Piece pairs of one link pair that a margin can reach."""

    pair: LinkPair
    a: IntArray  # piece indices
    b: IntArray
    static_bound: FloatArray  # rotation-invariant lower bounds of their distance [m]
    fixed: BoolArray  # the pair's distance does not depend on the configuration


class LinkModel:
    """The links of one robot as convex pieces, with what never changes as it moves.

    Attributes:
        robot: The robot.
        design: Its design.
        model: Its Pinocchio model.
        data: Pinocchio work data of the model (shared by the checks of one checker).
        convex: Every convex piece, in link order (:func:`convex_pieces`).
        pieces: The same pieces as coal shapes with their bounds (:class:`Piece`).
        orders: Symmetry order of each part symmetric about its link's axis, by
            (link index, part name).
        piece_group: Per piece, 1 if its part is symmetric about its link's axis,
            else 0.
        all: Per link pair of :data:`LINK_PAIRS`, its piece pairs
            (:class:`LinkPairGeometry`).
        fixed_clearance: Smallest static bound of the piece pairs whose distance does
            not depend on the configuration [m] (``inf`` when there are none).
    """

    def __init__(self, robot: SPMRobot) -> None:
        self.robot: SPMRobot = robot
        self.design: SPMDesign = robot.design
        self.model = robot.model
        self.data = robot.model.createData()
        self.link_frames = [robot.link_frames[name] for name in LINK_NAMES]
        self.parts: dict[str, tuple[LinkPart, ...]] = {
            name: tuple(parts) for name, parts in link_parts(self.design).items()
        }
        self.turning_axes = self._common_axes()
        self.pieces: list[Piece] = []
        self.convex: tuple[ConvexPiece, ...] = tuple(
            piece for name in LINK_NAMES for piece in convex_pieces(self.design)[name]
        )
        revolved = self._revolved_parts()
        for piece in self.convex:
            self.pieces.append(self._piece(piece, revolved))
        # Parts symmetric about their link's axis (group 1: a proximal link's drive
        # tube and gear, the base hub and plate) and their orders; group 0 is the rest.
        self.symmetry_axes = self._link_axes()
        self.orders: dict[tuple[int, str], int] = {}
        for index, name in enumerate(LINK_NAMES):
            axis = self.symmetry_axes[index]
            if axis is None:
                continue
            for part in self.parts[name]:
                order = symmetry_order(np.asarray(part.mesh.vertices, dtype=float), axis)
                if order:
                    self.orders[(index, part.name)] = order
        self.piece_group = np.array(
            [int((p.link, p.part) in self.orders) for p in self.pieces], dtype=np.int64
        )
        self.piece_link = np.array([p.link for p in self.pieces], dtype=np.int64)
        self.centers = np.array([p.center for p in self.pieces])
        self.radii = np.array([p.radius for p in self.pieces])
        self.anchors = np.array([p.anchor for p in self.pieces])
        self.all = [self._link_pair_geometry(pair) for pair in LINK_PAIRS]
        fixed = [g.static_bound[g.fixed] for g in self.all if np.any(g.fixed)]
        self.fixed_clearance: float = float(min(np.min(f) for f in fixed)) if fixed else math.inf
        self.bodies: dict[tuple[str, tuple[str, ...]], Any] = {}

    # ------------------------------------------------------------------ pieces
    def _common_axes(self) -> list[FloatArray | None]:
        """Per link, the fixed axis it turns about if another checked link turns about
        the same one (the coaxial proximal links), else None."""
        u = self.design.u
        axes: list[FloatArray | None] = [None] * len(LINK_NAMES)
        for leg in range(3):
            same = [k for k in range(3) if np.linalg.norm(u[k] - u[leg]) <= AXIS_TOL]
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
        if np.allclose(u, u[0], rtol=0.0, atol=AXIS_TOL):
            axes[LINK_NAMES.index("base")] = np.array(u[0], dtype=float)
        return axes

    def _revolved_parts(self) -> set[tuple[str, str]]:
        revolved = set()
        for index, name in enumerate(LINK_NAMES):
            axis = self.turning_axes[index]
            if axis is None:
                continue
            for part in self.parts[name]:
                if revolution_order(np.asarray(part.mesh.vertices, dtype=float), axis):
                    revolved.add((name, part.name))
        return revolved

    def _piece(self, piece: ConvexPiece, revolved: set[tuple[str, str]]) -> Piece:
        vertices = piece.vertices
        shape = convex_shape(vertices)
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
        axis = self.turning_axes[link]
        band = ring = None
        if axis is not None:
            height = vertices @ axis
            band = (float(height.min()), float(height.max()))
            # The axis as a long capsule of zero radius, centred at O.
            line = coal.Capsule(1e-12, AXIS_LENGTH)
            e1, e2 = axis_frame(axis)
            frame = coal.Transform3s(np.column_stack([e1, e2, axis]), np.zeros(3))
            near = coal.distance(
                shape, identity, line, frame, coal.DistanceRequest(), coal.DistanceResult()
            )
            radial = np.linalg.norm(vertices - height[:, None] * axis, axis=1)
            ring = (max(float(near), 0.0), float(radial.max()))
        return Piece(
            link=link,
            part=piece.part,
            index=piece.index,
            shape=shape,
            center=center,
            radius=radius,
            capsule=capsule(vertices),
            anchor=vertices[int(np.argmin(np.linalg.norm(vertices - center, axis=1)))],
            shell=(max(float(inner), 0.0), float(norms.max())),
            band=band,
            ring=ring,
            revolved=(piece.link, piece.part) in revolved,
        )

    def _link_pair_geometry(self, pair: LinkPair) -> LinkPairGeometry:
        """Every piece pair of a link pair with its rotation-invariant lower bound."""
        link_a, link_b = (LINK_NAMES.index(name) for name in pair)
        ia = np.flatnonzero(self.piece_link == link_a)
        ib = np.flatnonzero(self.piece_link == link_b)
        a, b = np.repeat(ia, ib.size), np.tile(ib, ia.size)
        shells = np.array([p.shell for p in self.pieces])
        bound = np.maximum(shells[a, 0] - shells[b, 1], shells[b, 0] - shells[a, 1])
        fixed = np.zeros(a.size, dtype=bool)
        axis_a, axis_b = self.turning_axes[link_a], self.turning_axes[link_b]
        if axis_a is not None and axis_b is not None and np.allclose(axis_a, axis_b):
            band = np.array([p.band if p.band else (0.0, 0.0) for p in self.pieces])
            ring = np.array([p.ring if p.ring else (0.0, 0.0) for p in self.pieces])
            along = np.maximum(band[a, 0] - band[b, 1], band[b, 0] - band[a, 1])
            across = np.maximum(ring[a, 0] - ring[b, 1], ring[b, 0] - ring[a, 1])
            # Both links turn about the same axis: heights along it and distances from
            # it are invariant, and so is the gap they leave (Pythagoras).
            bound = np.maximum(
                bound,
                np.hypot(np.maximum(along, 0.0), np.maximum(across, 0.0)),
            )
            revolved = np.array([p.revolved for p in self.pieces])
            fixed = revolved[a] | revolved[b]
        return LinkPairGeometry(pair, a, b, bound, fixed)

    # ------------------------------------------------------------ units, bodies
    def unit_parts(
        self, geometry: LinkPairGeometry, margin: float, include_fixed: bool
    ) -> list[tuple[int, int, set[str], set[str]]]:
        """The units of a link pair at ``margin``: per pair of piece groups that has
        pieces within reach, the groups and the parts of either link in reach."""
        near = geometry.static_bound <= margin
        if not include_fixed:
            near &= ~geometry.fixed
        group_a, group_b = self.piece_group[geometry.a], self.piece_group[geometry.b]
        units = []
        for first in (0, 1):
            for second in (0, 1):
                keep = near & (group_a == first) & (group_b == second)
                if np.any(keep):
                    parts_a = {self.pieces[i].part for i in geometry.a[keep]}
                    parts_b = {self.pieces[j].part for j in geometry.b[keep]}
                    units.append((first, second, parts_a, parts_b))
        return units

    def body(self, key: tuple[str, tuple[str, ...]]) -> Any:
        """The culling BVH of some parts of a link (made once, shared by the engines)."""
        shape = self.bodies.get(key)
        if shape is None:
            link, names = key
            shape = bvh(concatenate([p.mesh for p in self.parts[link] if p.name in names]))
            self.bodies[key] = shape
        return shape

    # ------------------------------------------------------------------ joints
    def joint_q(self, link: str, up: int = 0) -> int:
        """Index in q of the joint that carries ``link`` (``up`` joints towards the base)."""
        model = self.model
        joint = model.frames[self.link_frames[LINK_NAMES.index(link)]].parentJoint
        for _ in range(up):
            joint = model.parents[joint]
        return int(model.idx_qs[joint])

    def link_rotations(self, q: FloatArray) -> FloatArray:
        """World rotations of the links at q, (8, 3, 3) in LINK_NAMES order."""
        model, data = self.model, self.data
        pin.framesForwardKinematics(model, data, q)
        return np.array([data.oMf[frame].rotation for frame in self.link_frames])
