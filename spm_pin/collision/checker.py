"""The self-collision checker of an SPM's links: :class:`CollisionChecker`, which
validates the inputs and composes the static piece model, the probes, the certified
tables with their coal engine and the distance index; and :func:`build_robot` and
:func:`checker_of`, which give a robot its checker."""

from __future__ import annotations

import collections
import math
from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..design import SPMDesign
from ..errors import InputError
from ..kinematics._common import as_theta, require_angles
from ._configuration import as_q_batch, leg_axes, theta_configuration
from ._distance import DistanceIndex
from ._probes import choose_probes
from ._shapes import TWO_PI
from ._static import LinkModel, LinkPairGeometry, Piece
from ._tables import FREE, HIT, Plan, TableMaker
from .pairs import (
    ADJACENT_PAIRS,
    DEFAULT_PROBES,
    LINK_PAIRS,
    PLAN_CACHE,
    PROBE_SAMPLES,
    BoolArray,
    FloatArray,
    LinkPair,
    _check_margin,
)
from .pieces import ConvexPiece

if TYPE_CHECKING:
    from ..model.robot import SPMRobot

__all__ = ["CollisionChecker", "build_robot", "checker_of"]


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
        links = LinkModel(robot)
        self._links = links
        self._model = links.model
        self._data = links.data
        # Per leg: u_i, w_i0, v_i0 as float tuples (q from theta, see configuration).
        self._legs = leg_axes(self.design)
        # The static model's pieces, orders and link pair geometries, under the names
        # that the benchmarks and tests read.
        self._pieces: list[Piece] = links.pieces
        self.pieces: tuple[ConvexPiece, ...] = links.convex
        self._orders: dict[tuple[int, str], int] = links.orders
        self._all: list[LinkPairGeometry] = links.all
        self.fixed_clearance: float = links.fixed_clearance
        self._index = DistanceIndex(links)
        self._distances_q = self._index.distances_q
        self._probes: dict[LinkPair, tuple[tuple[int, int], ...]] = {}
        # How often each link pair collided in the sample with no probe catching it:
        # the body pass takes the link pairs in that order.
        self._unprobed: dict[LinkPair, float] = {}
        # How often each piece pair collided in that sample (tables try them in order).
        self._piece_hits: collections.Counter[tuple[int, int]] = collections.Counter()
        if probe_samples:
            self._probes, self._unprobed, self._piece_hits = choose_probes(
                links, int(probes), int(probe_samples), int(seed)
            )
        self.probes: dict[LinkPair, tuple[tuple[int, int], ...]] = dict(self._probes)
        self._rank = {pair: k for k, pair in enumerate(LINK_PAIRS)}
        self._body_order = sorted(
            range(len(LINK_PAIRS)), key=lambda k: -self._unprobed.get(LINK_PAIRS[k], 0.0)
        )
        self._plans: collections.OrderedDict[
            tuple[float, bool, frozenset[LinkPair] | None], Plan
        ] = collections.OrderedDict()
        self._tables = TableMaker(links, self._piece_hits)

    def __repr__(self) -> str:
        return (
            f"CollisionChecker(design={self.design.name!r}, pairs={len(self.pairs)}, "
            f"pieces={len(self.pieces)})"
        )

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
            return theta_configuration(as_theta(array, "theta"), self.design, self._legs)
        if array.shape != (self._model.nq,):
            raise InputError(
                "x must be input angles theta of shape (3,) or a joint configuration q "
                f"of shape ({self._model.nq},) [rad], got shape {array.shape}",
                argument="x",
                value=x,
            )
        require_angles(array, "x", x)
        return array

    def _plan(
        self,
        margin: float = 0.0,
        include_fixed: bool = True,
        pairs: Iterable[LinkPair] | None = None,
    ) -> Plan:
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
            plan = Plan(self._tables, self._probes, self._body_order, *key)
            self._plans[key] = plan
            while len(self._plans) > PLAN_CACHE:
                self._plans.popitem(last=False)
        return plan

    def _check(self, q: FloatArray, plan: Plan, first_only: bool) -> list[LinkPair]:
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
                    + int((values[c] % TWO_PI) * scale_c)
                ]
                if cell == FREE:
                    skip |= free
                elif cell == HIT:
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

    def prepare(self, margin: float = 0.0, include_fixed: bool = True) -> None:
        """Make the check at ``margin`` now (its relative-angle tables and engine,
        tens of milliseconds), so that no later check pays for it: what a loop with
        a time budget calls at start-up for each margin it uses. The checker keeps
        the set-ups of the last :data:`~spm_pin.collision.pairs.PLAN_CACHE` margins.

        Raises:
            InputError: a bad ``margin``.
        """
        self._plan(margin, include_fixed)

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
        array = as_q_batch(q, self._model.nq)
        column = {pair: k for k, pair in enumerate(self.pairs)}
        out = np.zeros((array.shape[0], len(self.pairs)), dtype=bool)
        for row, item in enumerate(array):
            for pair in self._check(item, plan, False):
                out[row, column[pair]] = True
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
        array = as_q_batch(q, self._model.nq)
        if isinstance(cap, bool) or not isinstance(cap, (int, float)) or not cap > 0:
            raise InputError(
                f"cap must be a distance > 0 [m], got {cap!r}", argument="cap", value=cap
            )
        out = np.empty(array.shape[0])
        for row, item in enumerate(array):
            values = self._distances_q(item, list(self.pairs), bool(include_fixed), float(cap))
            out[row] = min(values.values())
        return out


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
