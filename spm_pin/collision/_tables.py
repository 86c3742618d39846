"""Certified tables of a collision check and the plan that holds them: over one or
two joint angles, cells proved free or colliding once per margin, so that a check
settles their units by a lookup; and the making of those tables from checks at the
cells' middles with Lipschitz bounds."""

from __future__ import annotations

import collections
import dataclasses
import functools
import math
from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..model.geometry import LINK_NAMES
from ._engine import Engine, geometry_object
from ._shapes import AXIS_TOL, MIN_ORDER, TWO_PI
from ._static import LinkModel, LinkPairGeometry
from .pairs import (
    _EPA_CERTIFY_ITERATIONS,
    _EPA_ITERATIONS,
    LINK_PAIRS,
    BoolArray,
    FloatArray,
    LinkPair,
)

__all__ = [
    "CHECK",
    "FREE",
    "HIT",
    "Plan",
    "Table",
    "TableMaker",
]

#: Largest distance error allowed to a table per angle [m] (see Plan).
SWEEP_BUDGET = 0.0005
#: Most cells of a table.
SWEEP_CELLS = 8192
#: Tables of symmetric parts consider the parts within this distance of the other link
#: (a table's own distance error stays below it) [m].
TABLE_REACH = 0.002
#: States of a table cell: the pair is certainly apart by more than the margin,
#: certainly colliding, or has to be checked.
FREE, HIT, CHECK = 0, 1, 2
#: Added to the Lipschitz bounds of the tables: covers the rounding of an angle to its
#: cell and the tolerance of coal's penetration depths [m].
SWEEP_SLACK = 1e-6


@dataclasses.dataclass(frozen=True)
class Table:
    """Certified states of a link pair, or of one unit of it, over one or two angles.

    The angles are alpha = q[b] - q[a] (mod ``period``; index nq of the values reads
    0) and beta = q[c] (mod 2 pi; none for nq). ``state`` holds the cells row by row
    (alpha along the rows), each cell :data:`FREE`, :data:`HIT` or :data:`CHECK`
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


class Plan:
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
        maker: TableMaker,
        probes: dict[LinkPair, tuple[tuple[int, int], ...]],
        body_order: Sequence[int],
        margin: float,
        include_fixed: bool,
        pairs: frozenset[LinkPair] | None,
    ) -> None:
        self.margin = margin
        self.include_fixed = include_fixed
        chosen = [p for p in LINK_PAIRS if pairs is None or p in pairs]
        self.engine = Engine(
            maker.links, probes, body_order, margin, include_fixed, frozenset(chosen)
        )
        self.tables: list[Table] = []
        for pair in chosen:
            table = maker.link_table(pair, margin, include_fixed)
            if table is not None:
                self.tables.append(table)
        for pair, group_a, group_b in self.engine.units:
            if group_a == 1:
                unit = maker.unit_table(pair, group_b, margin, include_fixed)
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
                    (t.columns - 1) / TWO_PI,
                    t.columns,
                    t.state,
                    free,
                    masks,
                    t.pair,
                )
            )


class TableMaker:
    """Makes the certified tables of a robot's links (see :class:`Plan`), keeping the
    penetration results of their cells across margins.

    Args:
        links: The static piece model.
        piece_hits: How often each piece pair collided in the probes' sample
            (penetration checks try the pairs in that order).
    """

    def __init__(self, links: LinkModel, piece_hits: collections.Counter[tuple[int, int]]) -> None:
        self.links = links
        self.piece_hits = piece_hits
        self.deep_results: dict[
            tuple[object, ...], tuple[pin.GeometryModel, npt.NDArray[np.int8]]
        ] = {}

    def _body_model(
        self,
        geometry: LinkPairGeometry,
        margin: float,
        include_fixed: bool,
        groups: tuple[int, int] | None = None,
    ) -> pin.GeometryModel:
        """The culling BVH pairs of a link pair (or of one unit of it) at ``margin``, as
        one Pinocchio model (for the tables' checks)."""
        gm = pin.GeometryModel()
        link_a, link_b = geometry.pair
        for first, second, parts_a, parts_b in self.links.unit_parts(
            geometry, margin, include_fixed
        ):
            if groups is not None and (first, second) != groups:
                continue
            objects = []
            for link, parts in ((link_a, parts_a), (link_b, parts_b)):
                key = (link, tuple(sorted(parts)))
                body = geometry_object(
                    self.links.robot, f"{link}/{'+'.join(key[1])}", link, self.links.body(key)
                )
                objects.append(gm.addGeometryObject(body))
            gm.addCollisionPair(pin.CollisionPair(objects[0], objects[1]))
        return gm

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
        state = np.where(free, FREE, CHECK)
        if not np.all(free):
            model, known = deep()
            todo = np.flatnonzero(~free & (known < 0))
            if todo.size:
                known[todo] = self._batch(model, -bound, _EPA_CERTIFY_ITERATIONS, q[todo])
            state[~free & (known == 1)] = HIT
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
            entry = self.deep_results.get(key)
            if entry is None:
                entry = self.deep_results[key] = (make(), np.full(cells, -1, dtype=np.int8))
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
        pool = pin.GeometryPool(self.links.model, gm, 1)
        pool.update(gd)
        batch = np.asfortranarray(q.T)
        return np.asarray(pin.computeCollisionsInParallel(1, pool, batch, True), dtype=bool)

    def _deep_model(
        self,
        geometry: LinkPairGeometry,
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
            near &= self.links.piece_group[geometry.a] == groups[0]
            near &= self.links.piece_group[geometry.b] == groups[1]
        if sweep is not None:
            _, w, angle = sweep
            a, b = geometry.a, geometry.b
            centre_b = self.links.centers[b]
            along = centre_b @ w
            circle = np.linalg.norm(centre_b - np.outer(along, w), axis=1)
            offset = self.links.centers[a] - np.outer(along, w)
            height = offset @ w
            across = np.linalg.norm(offset - np.outer(height, w), axis=1)
            gap = np.hypot(height, across - circle)
            reach = (
                self.links.radii[a] + self.links.radii[b] + np.linalg.norm(centre_b, axis=1) * angle
            )
            near &= gap <= reach
        # The pairs that collided most often in the probes' sample first: a check
        # stops at the first deep overlap.
        hits = self.piece_hits
        candidates = sorted(
            zip(geometry.a[near].tolist(), geometry.b[near].tolist(), strict=True),
            key=lambda p: -hits[p],
        )
        gm = pin.GeometryModel()
        objects: dict[int, int] = {}
        for pieces in candidates:
            for index in pieces:
                if index not in objects:
                    piece = self.links.pieces[index]
                    objects[index] = gm.addGeometryObject(
                        geometry_object(
                            self.links.robot, f"piece{index}", LINK_NAMES[piece.link], piece.shape
                        )
                    )
            gm.addCollisionPair(pin.CollisionPair(objects[pieces[0]], objects[pieces[1]]))
        return gm

    def link_table(self, pair: LinkPair, margin: float, include_fixed: bool) -> Table | None:
        """The table of two links turning about one axis, over the difference of their
        inputs (None for other pairs, or when the margin leaves no room below a fixed
        clearance; see :class:`Plan`)."""
        a, b = (LINK_NAMES.index(name) for name in pair)
        axis_a, axis_b = self.links.turning_axes[a], self.links.turning_axes[b]
        if axis_a is None or axis_b is None or not np.allclose(axis_a, axis_b):
            return None
        geometry = self.links.all[LINK_PAIRS.index(pair)]
        budget = SWEEP_BUDGET
        if include_fixed and np.any(geometry.fixed):
            budget = min(
                budget, 0.5 * (float(np.min(geometry.static_bound[geometry.fixed])) - margin)
            )
        # Either link may be the one that turns: the one nearer to the axis.
        reach = min(
            max(p.ring[1] for p in self.links.pieces if p.link == link and p.ring is not None)
            for link in (a, b)
        )
        cells = math.ceil(TWO_PI * reach / (2.0 * budget)) if budget > 0 else SWEEP_CELLS + 1
        if cells > SWEEP_CELLS:
            return None
        width = TWO_PI / cells
        bound = 0.5 * reach * width + SWEEP_SLACK  # largest move of a point in a cell [m]
        joint_a, joint_b = self.links.joint_q(pair[0]), self.links.joint_q(pair[1])
        q = np.zeros((cells, self.links.model.nq))
        q[:, joint_b] = (np.arange(cells) + 0.5) * width
        free = self._body_model(geometry, margin + bound, include_fixed)
        deep = self._deep(
            (pair, include_fixed, cells),
            cells,
            lambda: self._deep_model(geometry, include_fixed),
        )
        state = self._certify(free, deep, margin, bound, q)
        nq = self.links.model.nq
        return Table(pair, None, joint_a, joint_b, TWO_PI, cells + 1, nq, 1, (*state, state[0]))

    def unit_table(
        self, pair: LinkPair, group_b: int, margin: float, include_fixed: bool
    ) -> Table | None:
        """The table of the symmetric parts of a link (base or proximal link) against
        a distal link, over the turn about the axis (modulo the parts' symmetry) and
        the distal link's joint w (None when the pair is not of that kind; see
        :class:`Plan`)."""
        a, b = (LINK_NAMES.index(name) for name in pair)
        axis = self.links.symmetry_axes[a]
        if axis is None or not pair[1].startswith("distal_") or pair[0] == "platform":
            return None
        leg = int(pair[1].split("_")[1]) - 1
        if not np.allclose(self.links.design.u[leg], axis, rtol=0.0, atol=AXIS_TOL):
            return None
        geometry = self.links.all[LINK_PAIRS.index(pair)]
        group = self.links.piece_group
        near = (
            (geometry.static_bound <= margin + TABLE_REACH)
            & (group[geometry.a] == 1)
            & (group[geometry.b] == group_b)
        )
        if not include_fixed:
            near &= ~geometry.fixed
        if not np.any(near):
            return None
        # The symmetric parts within reach: they turn onto themselves every 2 pi / n.
        parts = {self.links.pieces[i].part for i in geometry.a[near]}
        order = functools.reduce(math.gcd, (self.links.orders[(a, part)] for part in parts))
        if order < MIN_ORDER:
            return None
        period = TWO_PI / order
        vertices = np.vstack(
            [np.asarray(p.mesh.vertices) for p in self.links.parts[pair[0]] if p.name in parts]
        )
        radius_a = float(np.linalg.norm(vertices - np.outer(vertices @ axis, axis), axis=1).max())
        w = self.links.design.w0[leg]
        pieces_b = [p for p in self.links.convex if p.link == pair[1]]
        vertices = np.vstack(
            [
                p.vertices
                for p, g in zip(pieces_b, group[self.links.piece_link == b], strict=True)
                if g == group_b
            ]
        )
        radius_b = float(np.linalg.norm(vertices - np.outer(vertices @ w, w), axis=1).max())
        rows = max(1, math.ceil(period * radius_a / (2.0 * SWEEP_BUDGET)))
        columns = math.ceil(TWO_PI * radius_b / (2.0 * SWEEP_BUDGET))
        bound = 0.5 * (radius_a * period / rows + radius_b * TWO_PI / columns) + SWEEP_SLACK
        if bound > TABLE_REACH or rows * columns > SWEEP_CELLS:
            return None
        nq = self.links.model.nq
        joint_a = self.links.joint_q(pair[0]) if pair[0] != "base" else nq
        joint_b, joint_c = self.links.joint_q(pair[1], up=1), self.links.joint_q(pair[1])
        grid_a, grid_c = np.meshgrid(
            (np.arange(rows) + 0.5) * period / rows,
            (np.arange(columns) + 0.5) * TWO_PI / columns,
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
        return Table(
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
