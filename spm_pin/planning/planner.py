"""Safe, near-shortest paths of a coaxial SPM: :func:`plan`.

The safe set is a region of the gap plane (D12, D23) times a free, endless turn of
the whole mechanism about its axis (see :mod:`spm_pin.planning.safe_set`). Writing
the input angles as theta = c (1, 1, 1) + P(D12, D23), with c the mean input and P
the part with zero mean, splits the length of a motion in input space exactly:
|d theta|^2 = 3 dc^2 + |dP|^2, and |dP|^2 = 2/3 (a^2 + a b + b^2) for gap changes a,
b. So the shortest motion is the shortest path in the gap plane in that metric, with
the mean input changed in proportion to its length: a straight line in input space
wherever the gap path is straight.

The search: the straight line from start to goal when it is safe; otherwise A* on the
grid of safe vertices (8 neighbours, the metric above), then the path is pulled
straight (each vertex skipped when the straight line past it is safe) and every
segment is certified as a continuous path (:meth:`SafeSet.certify`); a grid edge that
fails the certificate is removed and the search runs again.
"""

from __future__ import annotations

import dataclasses
import heapq
import itertools
import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .._checks import as_rotation
from ..design import SPMDesign
from ..errors import InputError, PlanningError
from ..kinematics import inverse_kinematics
from ._evaluation import nearest_phrase
from .safe_set import PlanSettings, SafeSet, safe_set_of

if TYPE_CHECKING:
    from .input_space import InputSafeSet
from .timing import MotionLimits, Trajectory, time_path

__all__ = ["PlannedPath", "gap_length", "plan"]

FloatArray = npt.NDArray[np.float64]

#: Searches after a grid edge failed its certificate, at most.
MAX_REPAIRS = 50


def gap_length(d12: npt.ArrayLike, d23: npt.ArrayLike) -> float:
    """Length [deg] of a polyline in the gap plane in the metric |dP| (see the module)."""
    a = np.diff(np.asarray(d12, dtype=float))
    b = np.diff(np.asarray(d23, dtype=float))
    return float(np.sum(np.sqrt(2.0 / 3.0 * (a * a + a * b + b * b))))


@dataclasses.dataclass(frozen=True)
class PlannedPath:
    """A safe path, certified along its whole length.

    Attributes:
        theta: Waypoints [rad], (n, 3), from the start to the goal; the path is the
            straight lines between them.
        length_deg: Its length in input space [deg] (Euclidean).
        straight_length_deg: Length of the straight line from start to goal [deg].
        grid_length_deg: Length of the grid search's path in input space [deg] (the
            same as ``length_deg`` when the straight line was safe; for a design that
            is not coaxial, the length of OMPL's path before its simplification).
        samples: Samples checked to certify it.
        min_singularity_margin: Smallest singularity margin at the samples.
        min_dexterity: Smallest dexterity at the samples.
        turns: Whole turns of the mechanism about its axis added to the shortest
            turn.
        planning_time_ms: Time to plan [ms] (the safe set's build not included).
        settings: The thresholds used.
        safe: The safe set it was planned in (certifies a smoothed timing).
    """

    theta: FloatArray
    length_deg: float
    straight_length_deg: float
    grid_length_deg: float
    samples: int
    min_singularity_margin: float
    min_dexterity: float
    turns: int
    planning_time_ms: float
    settings: PlanSettings
    safe: SafeSet | InputSafeSet | None = dataclasses.field(default=None, repr=False, compare=False)

    @property
    def start(self) -> FloatArray:
        """The start [rad], (3,)."""
        result: FloatArray = self.theta[0].copy()
        return result

    @property
    def goal(self) -> FloatArray:
        """The goal [rad], (3,)."""
        result: FloatArray = self.theta[-1].copy()
        return result

    def timed(
        self,
        limits: MotionLimits | None = None,
        *,
        smooth: bool = True,
        safe: SafeSet | InputSafeSet | None = None,
    ) -> Trajectory:
        """The fastest motion along this path under joint speed and acceleration
        limits, from rest to rest (:func:`~spm_pin.planning.timing.time_path`; needs
        toppra, ``pip install 'spm-pin[planning]'``).

        Args:
            limits: Joint limits with ``max_speed`` [rad/s] and ``max_acceleration``
                [rad/s^2] (default: the servos' guard's).
            smooth: Round the corners with a spline when it is certified safe
                (otherwise the motion stops at every corner).
            safe: The safe set that certifies the rounded corners (default: the one
                the path was planned in).
        """
        return time_path(
            self.theta, limits, safe=self.safe if safe is None else safe, smooth=smooth
        )


def _length_deg(theta: FloatArray) -> float:
    return float(np.sum(np.linalg.norm(np.degrees(np.diff(theta, axis=0)), axis=1)))


def _angles_or_rotation(value: Any, name: str) -> FloatArray:
    """An end point as given: finite input angles (3,) [rad] (a copy), or an array of
    shape (3, 3) to be checked as a rotation; else InputError."""
    array = np.asarray(value, dtype=float) if not isinstance(value, str) else np.empty(0)
    if array.shape == (3,):
        if not np.all(np.isfinite(array)):
            raise InputError(f"{name} must be finite angles [rad], got {value!r}", argument=name)
        result: FloatArray = array.copy()
        return result
    if array.shape != (3, 3):
        raise InputError(
            f"{name} must be input angles (3,) [rad] or a rotation matrix (3, 3), got "
            f"shape {array.shape}",
            argument=name,
            value=value,
        )
    return array


def _end(
    value: Any, name: str, safe: SafeSet, reference_yaw: float | None, turns: int
) -> FloatArray:
    """Input angles of an end point: theta (3,) as given, or a rotation (3, 3) solved
    in the home working mode with the mean input nearest ``reference_yaw`` plus
    ``turns`` whole turns."""
    array = _angles_or_rotation(value, name)
    if array.shape == (3,):
        return array
    solved = _solve_home(array, name, safe.design)
    d12, d23, _ = (float(x) for x in safe.gaps_of(solved))
    if d12 + d23 >= 360.0:
        raise PlanningError(
            f"the {name} orientation needs the proximal links in another order",
            reasons=("proximal links out of order",),
            check=name,
        )
    # The mean input of the inputs with these gaps whose first is the solved one:
    # each solved input is wrapped on its own, so their plain mean may be a third
    # of a turn off (and the platform turned by 120 degrees).
    yaw = float(solved[0] - safe.theta_of(d12, d23, 0.0)[0])
    if reference_yaw is not None:
        yaw += 2.0 * math.pi * round((reference_yaw - yaw) / (2.0 * math.pi))
    else:
        yaw = math.remainder(yaw, 2.0 * math.pi)
    return safe.theta_of(d12, d23, yaw + 2.0 * math.pi * turns)


def _nearest_safe(safe: SafeSet, theta: FloatArray) -> FloatArray | None:
    """The safe grid vertex nearest theta in the gap metric, at theta's mean input."""
    d12, d23, yaw = safe.gaps_of(theta)
    rows, cols = np.nonzero(safe.safe)
    if rows.size == 0:
        return None
    a = safe.d12[rows] - d12
    b = safe.d23[cols] - d23
    k = int(np.argmin(a * a + a * b + b * b))
    return safe.theta_of(safe.d12[rows[k]], safe.d23[cols[k]], yaw)


def _require_safe(safe: SafeSet, theta: FloatArray, name: str) -> None:
    if safe.cover.contains(theta):  # in a certified cell: safe
        return
    evaluation = safe.evaluate(theta[None])
    if not evaluation.safe[0]:
        reason = evaluation.reason(0, safe.settings)
        nearest = _nearest_safe(safe, theta)
        where = nearest_phrase(safe.design, nearest, "is")
        raise PlanningError(
            f"the {name} {np.degrees(theta).round(3).tolist()} deg is unsafe: {reason}{where}",
            reasons=(reason,),
            check=name,
            nearest=nearest,
        )


class _Grid:
    """A* over the safe vertices of the gap grid, edges removable."""

    MOVES = ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, -1), (1, -1), (-1, 1))

    def __init__(self, safe: SafeSet) -> None:
        self.safe = safe
        self.h = safe.settings.grid_step_deg
        self.blocked: set[tuple[tuple[int, int], tuple[int, int]]] = set()

    def cost(self, a: tuple[int, int], b: tuple[int, int]) -> float:
        x, y = (b[0] - a[0]) * self.h, (b[1] - a[1]) * self.h
        return math.sqrt(2.0 / 3.0 * (x * x + x * y + y * y))

    def search(self, start: tuple[int, int], goal: tuple[int, int]) -> list[tuple[int, int]]:
        mask = self.safe.safe
        n, m = mask.shape
        frontier = [(self.cost(start, goal), 0.0, start)]
        came: dict[tuple[int, int], tuple[int, int] | None] = {start: None}
        best = {start: 0.0}
        while frontier:
            _, g, node = heapq.heappop(frontier)
            if node == goal:
                path = [node]
                while (prev := came[path[-1]]) is not None:
                    path.append(prev)
                return path[::-1]
            if g > best[node]:
                continue
            for di, dj in self.MOVES:
                nxt = (node[0] + di, node[1] + dj)
                if not (0 <= nxt[0] < n and 0 <= nxt[1] < m) or not mask[nxt]:
                    continue
                if di and dj and not (mask[node[0] + di, node[1]] and mask[node[0], node[1] + dj]):
                    continue  # a diagonal only across a cell whose corners are all safe
                if (node, nxt) in self.blocked:
                    continue
                cost = g + self.cost(node, nxt)
                if cost < best.get(nxt, math.inf):
                    best[nxt] = cost
                    came[nxt] = node
                    heapq.heappush(frontier, (cost + self.cost(nxt, goal), cost, nxt))
        return []


def _attach(safe: SafeSet, theta: FloatArray) -> list[tuple[int, int]]:
    """Safe grid vertices near theta, nearest first (in the gap metric)."""
    d12, d23, _ = (float(x) for x in safe.gaps_of(theta))
    h = safe.settings.grid_step_deg
    i0 = round(d12 / h) - 1
    j0 = round(d23 / h) - 1
    out = []
    for i in range(i0 - 3, i0 + 4):
        for j in range(j0 - 3, j0 + 4):
            if 0 <= i < safe.safe.shape[0] and 0 <= j < safe.safe.shape[1] and safe.safe[i, j]:
                a, b = safe.d12[i] - d12, safe.d23[j] - d23
                out.append((a * a + a * b + b * b, (i, j)))
    return [node for _, node in sorted(out)]


def plan(
    start: npt.ArrayLike,
    goal: npt.ArrayLike,
    design: SPMDesign | None = None,
    *,
    settings: PlanSettings | None = None,
    turns: int = 0,
    safe: SafeSet | None = None,
) -> PlannedPath:
    """A safe, near-shortest path from ``start`` to ``goal`` (see the module).

    Args:
        start: Input angles (3,) [rad], or a platform rotation (3, 3).
        goal: Input angles (3,) [rad], or a platform rotation (3, 3): solved in the
            home working mode, the mechanism turned the shortest way (plus ``turns``).
        design: The SPM (default: the prototype). A design that is not coaxial (the
            Agile Eye) is planned in its 3-D input space
            (:func:`~spm_pin.planning.input_space.plan_inputs`: OMPL's RRTConnect
            where the straight line is not safe, the same continuity certificate).
        settings: The thresholds (default: the servos' guard's).
        turns: Whole turns about the axis added to the shortest one (orientation
            goals of coaxial designs only; the platform can spin endlessly).
        safe: The safe set to plan in (default: built once per design and settings).

    Returns:
        The path, certified as a continuous motion.

    Raises:
        InputError: malformed start, goal or turns.
        PlanningError: the start or goal is unsafe (with the nearest safe input), or
            the goal cannot be reached from the start within the safe set.
    """
    if isinstance(turns, bool) or not isinstance(turns, int | np.integer):
        raise InputError(f"turns must be a whole number, got {turns!r}", argument="turns")
    if safe is None and design is not None and not design.is_coaxial:
        return _plan_inputs(start, goal, design, settings, int(turns))
    if safe is None:
        safe = safe_set_of(design or SPMDesign.prototype(), settings or PlanSettings())
    begin = time.perf_counter()
    theta0 = _end(start, "start", safe, None, 0)
    theta1 = _end(goal, "goal", safe, float(np.mean(theta0)), int(turns))
    _require_safe(safe, theta0, "start")
    _require_safe(safe, theta1, "goal")
    straight = np.vstack([theta0, theta1])
    ok, _, evaluation = safe.certify(straight)
    path, grid_length = straight, _length_deg(straight)
    if not ok:
        path, grid_length, evaluation = _search(safe, theta0, theta1)
    return PlannedPath(
        theta=path,
        length_deg=_length_deg(path),
        straight_length_deg=_length_deg(straight),
        grid_length_deg=grid_length,
        samples=int(evaluation.safe.size),
        min_singularity_margin=float(np.nanmin(evaluation.singularity_margin)),
        min_dexterity=float(np.nanmin(evaluation.dexterity)),
        turns=int(turns),
        planning_time_ms=1e3 * (time.perf_counter() - begin),
        settings=safe.settings,
        safe=safe,
    )


def _plan_inputs(
    start: npt.ArrayLike,
    goal: npt.ArrayLike,
    design: SPMDesign,
    settings: PlanSettings | None,
    turns: int,
) -> PlannedPath:
    """:func:`plan` for a design that is not coaxial: in its 3-D input space."""
    from .input_space import plan_inputs

    if turns:
        raise InputError(
            f"turns: {design.name!r} is not coaxial, its platform cannot spin endlessly",
            argument="turns",
            value=turns,
        )
    ends = [_input_end(value, name, design) for value, name in ((start, "start"), (goal, "goal"))]
    path, facts = plan_inputs(ends[0], ends[1], design, settings=settings)
    evaluation_settings = facts["safe"].settings
    return PlannedPath(
        theta=path,
        length_deg=_length_deg(path),
        straight_length_deg=facts["straight_length_deg"],
        grid_length_deg=facts["raw_length_deg"],
        samples=facts["samples"],
        min_singularity_margin=facts["min_singularity_margin"],
        min_dexterity=facts["min_dexterity"],
        turns=0,
        planning_time_ms=facts["planning_time_ms"],
        settings=evaluation_settings,
        safe=facts["safe"],
    )


def _input_end(value: Any, name: str, design: SPMDesign) -> FloatArray:
    """Input angles of an end point of a design that is not coaxial: theta (3,) as
    given, or a rotation (3, 3) solved in the home working mode."""
    array = _angles_or_rotation(value, name)
    if array.shape == (3,):
        return array
    return _solve_home(array, name, design)


def _solve_home(array: FloatArray, name: str, design: SPMDesign) -> FloatArray:
    """Input angles [rad] of a rotation (3, 3) (checked) in the home working mode,
    each wrapped on its own; PlanningError naming the legs that cannot close."""
    ik = inverse_kinematics(as_rotation(array, name)[None], design)
    legs = [int(i) + 1 for i in np.flatnonzero(~np.asarray(ik.leg_reachable[0]))]
    if legs:
        raise PlanningError(
            f"the {name} orientation is out of reach: leg(s) {legs} cannot close",
            reasons=(f"leg(s) {legs} cannot close",),
            check=name,
        )
    solved: FloatArray = np.asarray(ik.theta[0], dtype=float)
    return solved


def _with_yaw(safe: SafeSet, d12: FloatArray, d23: FloatArray, y0: float, y1: float) -> FloatArray:
    """Input angles along a gap polyline, the mean input moved in proportion to the
    gap-metric length (the shortest motion in input space along it)."""
    a, b = np.diff(d12), np.diff(d23)
    steps = np.sqrt(2.0 / 3.0 * (a * a + a * b + b * b))
    total = float(steps.sum())
    fraction = (
        np.concatenate([[0.0], np.cumsum(steps)]) / total
        if total > 0
        else np.linspace(0.0, 1.0, d12.size)
    )
    return safe.theta_of(d12, d23, y0 + fraction * (y1 - y0))


def _search(safe: SafeSet, theta0: FloatArray, theta1: FloatArray) -> tuple[FloatArray, float, Any]:
    grid = _Grid(safe)
    g0, g1 = safe.gaps_of(theta0), safe.gaps_of(theta1)
    y0, y1 = float(g0[2]), float(g1[2])

    def line(points: list[tuple[float, float]]) -> FloatArray:
        d12 = np.array([p[0] for p in points])
        d23 = np.array([p[1] for p in points])
        path = _with_yaw(safe, d12, d23, y0, y1)
        path[0], path[-1] = theta0, theta1
        return path

    def certified(p: tuple[float, float], q: tuple[float, float]) -> bool:
        # The checks do not depend on the mean input: the gap segment at one.
        segment = safe.theta_of(np.array([p[0], q[0]]), np.array([p[1], q[1]]), y0)
        return safe.certify(segment)[0]

    def point(node: tuple[int, int]) -> tuple[float, float]:
        return (float(safe.d12[node[0]]), float(safe.d23[node[1]]))

    p0 = (float(g0[0]), float(g0[1]))
    p1 = (float(g1[0]), float(g1[1]))
    # The nearest grid vertex reached safely (no further candidate is checked).
    starts = list(
        itertools.islice((n for n in _attach(safe, theta0) if certified(p0, point(n))), 1)
    )
    goals = list(itertools.islice((n for n in _attach(safe, theta1) if certified(point(n), p1)), 1))
    if not starts or not goals:
        raise PlanningError(
            "no safe way onto the search grid from the "
            + ("start" if not starts else "goal")
            + ": it lies in a sliver of the safe set narrower than the grid",
            reasons=("end point too near the boundary of the safe set",),
            check="connected",
        )
    for _ in range(MAX_REPAIRS):
        nodes = grid.search(starts[0], goals[0])
        if not nodes:
            raise PlanningError(
                "the goal lies in a part of the safe set that the start cannot reach "
                "(no safe path between them)",
                reasons=("start and goal in different parts of the safe set",),
                check="connected",
            )
        points = [p0, *(point(n) for n in nodes), p1]
        grid_length = _length_deg(line(points))
        # Pull the path straight: from each kept point, the furthest point seen safely.
        kept = [0]
        failed_edge = None
        while kept[-1] < len(points) - 1:
            i = kept[-1]
            for j in range(len(points) - 1, i, -1):
                if j == i + 1 or (
                    _free(safe, points[i], points[j]) and certified(points[i], points[j])
                ):
                    break
            if j == i + 1 and not certified(points[i], points[j]):
                failed_edge = (i, j)
                break
            kept.append(j)
        if failed_edge is None:
            path = line([points[k] for k in kept])
            ok, _, evaluation = safe.certify(path)
            if ok:
                return path, grid_length, evaluation
            failed_edge = (0, len(points) - 1)
        i, j = failed_edge
        if i >= 1 and j <= len(nodes):
            grid.blocked.add((nodes[i - 1], nodes[j - 1]))
        else:
            raise PlanningError(
                "no certified way onto the search grid",
                reasons=("end point too near the boundary of the safe set",),
                check="connected",
            )
    raise PlanningError(
        f"no certified path after {MAX_REPAIRS} repairs of the search grid",
        reasons=("the safe set is too narrow there for the grid",),
        check="connected",
    )


def _free(safe: SafeSet, p: tuple[float, float], q: tuple[float, float]) -> bool:
    """Cheap test on the grid: every cell the segment p-q passes has safe corners."""
    h = safe.settings.grid_step_deg
    length = math.hypot(q[0] - p[0], q[1] - p[1])
    n = max(2, math.ceil(4.0 * length / h) + 1)
    t = np.linspace(0.0, 1.0, n)
    a = p[0] + t * (q[0] - p[0])
    b = p[1] + t * (q[1] - p[1])
    i = np.floor(a / h).astype(int) - 1
    j = np.floor(b / h).astype(int) - 1
    mask = safe.safe
    shape = mask.shape
    for di in (0, 1):
        for dj in (0, 1):
            ii, jj = i + di, j + dj
            if np.any((ii < 0) | (jj < 0) | (ii >= shape[0]) | (jj >= shape[1])):
                return False
            if not np.all(mask[ii, jj]):
                return False
    return True
