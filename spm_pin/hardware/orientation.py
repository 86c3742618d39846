"""Orientation control of the servos: planned moves and streamed orientation targets.

* :func:`planned_goals` / :func:`move_planned`: a move to input angles or an
  orientation along a path of :func:`spm_pin.planning.plan` (safe along the whole
  motion; round the unsafe parts of the workspace instead of refusing), sampled one
  goal per loop period, each straight piece from rest to rest on the sync loop's
  trapezoid (``plan_linear``) at the guard's limits, then sent by
  :meth:`~spm_pin.hardware.sync.ServoSync.run` (which checks the goals whole again).
* :class:`OrientationStream`: orientation targets arriving at a rate (a head tracker,
  a joystick, a file). Each target is solved (home working mode, the turn about the
  axis nearest the present goal), rate-limited (speed and acceleration of the
  guard), and the step towards it checked as a continuous motion in the certified
  safe set before the sync loop's guard checks it again; an unsafe target never
  reaches the bus. With ``mode="slide"`` (default) a step that would leave the safe
  set slides along its boundary instead: the step's gap part turned by the smallest
  angle that is safe and still brings the goal nearer the target (the turn about the
  axis kept), else as far towards the target as is safe; the goal stops where the
  boundary comes nearest the target. With ``mode="stop"`` it holds the last safe
  goal. Every step says what it did and why.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError, UnreachableError
from ..kinematics import inverse_kinematics
from .sync import MoveResult, ServoSync, StepResult, plan_linear

if TYPE_CHECKING:
    from ..planning import PlannedPath, SafeSet

__all__ = [
    "STREAM_MODES",
    "OrientationStream",
    "StreamStep",
    "move_planned",
    "planned_goals",
]

FloatArray = npt.NDArray[np.float64]

#: What a stream does with a target it cannot reach safely.
STREAM_MODES = ("slide", "stop")
#: Bisections of the step towards an unsafe target (mode "slide").
SLIDE_BISECTIONS = 12
#: Turns of the blocked step's gap part tried to slide along the boundary [deg].
SLIDE_ANGLES_DEG = (15.0, 30.0, 45.0, 60.0, 75.0)
#: An orthonormal basis of the input changes that keep the mean input (the gaps).
_GAP_BASIS = np.array([[1.0, -1.0, 0.0], [1.0, 1.0, -2.0]]) / np.array(
    [[math.sqrt(2.0)], [math.sqrt(6.0)]]
)


def _safe_set(sync: ServoSync, safe: SafeSet | None) -> SafeSet:
    from ..planning import PlanSettings, safe_set_of

    if safe is not None:
        return safe
    limits = sync.guard.limits
    settings = PlanSettings(
        margin=limits.collision_margin,
        min_dexterity=limits.min_dexterity,
        min_singularity_margin=limits.min_singularity_margin,
    )
    return safe_set_of(sync.design, settings)


def planned_goals(
    path: FloatArray, *, max_speed: float, max_acceleration: float, period: float
) -> FloatArray:
    """A polyline of input angles (n, 3) [rad] sampled one goal per ``period`` [s]:
    each straight piece from rest to rest (a corner cannot be passed at speed without
    a jump of the joint speeds) on :func:`~spm_pin.hardware.sync.plan_linear`'s
    trapezoid, no joint faster than ``max_speed`` [rad/s] nor accelerating more than
    ``max_acceleration`` [rad/s^2]. The last goal is the polyline's end exactly.

    Raises:
        InputError: a path that is not (n, 3) finite angles, or limits or a period
            that are not positive (checked by ``plan_linear``).
    """
    try:
        theta = np.array(path, dtype=float)
    except (TypeError, ValueError):
        theta = np.empty(0)
    if theta.ndim != 2 or theta.shape[1:] != (3,) or theta.shape[0] < 1:
        raise InputError(f"path must have shape (n, 3), got {np.shape(path)}", argument="path")
    if not np.all(np.isfinite(theta)):
        raise InputError("path must hold finite angles [rad]", argument="path")
    pieces = [
        plan_linear(
            theta[k],
            theta[k + 1],
            max_speed=max_speed,
            max_acceleration=max_acceleration,
            period=period,
        )
        for k in range(theta.shape[0] - 1)
    ]
    if not pieces:
        single: FloatArray = theta[-1:].copy()
        return single
    goals: FloatArray = np.vstack(pieces)
    goals[-1] = theta[-1]
    return goals


def move_planned(
    sync: ServoSync,
    goal: npt.ArrayLike,
    *,
    turns: int = 0,
    safe: SafeSet | None = None,
    settle_timeout: float = 2.0,
) -> tuple[PlannedPath, MoveResult]:
    """Move the servos to input angles (3,) [rad] or a platform rotation (3, 3) along
    a planned path (see the module).

    Raises:
        PlanningError: the goal is unsafe or cannot be reached within the safe set
            (nothing is sent).
        UnsafeCommandError: the sync loop's guard refused a goal (holding the last
            safe one).
    """
    from ..planning import plan

    if sync.goal is None:
        raise InputError("call sync.start() before moving", argument="sync")
    path = plan(sync.goal, goal, sync.design, turns=turns, safe=_safe_set(sync, safe))
    limits = sync.guard.limits
    goals = planned_goals(
        path.theta,
        max_speed=limits.max_speed,
        max_acceleration=limits.max_acceleration,
        period=sync.config.period,
    )
    return path, sync.run(goals, settle_timeout=settle_timeout)


@dataclasses.dataclass(frozen=True)
class StreamStep:
    """What one target of a stream did.

    Attributes:
        target: The input angles the target asks for [rad], or None when it could
            not be solved.
        goal: The goal sent this cycle [rad] (the last safe goal when holding).
        action: ``"track"`` (towards the target within the rate limits), ``"slide"``
            (as far towards it as is safe), ``"hold"`` (nothing new sent).
        reason: Why not ``"track"`` (None when tracking).
        sync: The sync loop's result of the cycle.
    """

    target: FloatArray | None
    goal: FloatArray
    action: str
    reason: str | None
    sync: StepResult


class OrientationStream:
    """Streamed orientation targets to the servos, through the guard (see the module).

    Args:
        sync: A started :class:`~spm_pin.hardware.sync.ServoSync` (torque on).
        mode: ``"slide"`` or ``"stop"`` for targets that cannot be reached safely.
        safe: The certified safe set (default: the guard's limits).

    Attributes:
        velocity: The rate-limited goal velocity [rad/s], (3,).
        counts: Steps by action.
    """

    def __init__(self, sync: ServoSync, *, mode: str = "slide", safe: SafeSet | None = None):
        if mode not in STREAM_MODES:
            raise InputError(
                f"mode must be one of {list(STREAM_MODES)}, got {mode!r}",
                argument="mode",
                value=mode,
            )
        if sync.goal is None:
            raise InputError("call sync.start() before streaming", argument="sync")
        self.sync = sync
        self.mode = mode
        self.safe = _safe_set(sync, safe)
        # The goal's present velocity, as the guard sees it (its last two goals).
        before = sync._goal_before
        self.velocity = (
            np.zeros(3)
            if before is None
            else (np.asarray(sync.goal, dtype=float) - before) / sync.config.period
        )
        self.counts = dict.fromkeys(("track", "slide", "hold"), 0)

    def solve(self, R: npt.ArrayLike) -> FloatArray:
        """Input angles [rad] of a platform rotation: the home working mode, turned
        about the axis the way nearest the present goal.

        Raises:
            UnreachableError: some leg cannot close.
        """
        from .._checks import as_rotation

        rotation = as_rotation(R, "R")
        if rotation.ndim != 2:
            raise InputError(
                f"R must be one rotation matrix (3, 3), got shape {rotation.shape}",
                argument="R",
                value=R,
            )
        # One rotation: the single-input path (compiled where the guard compiled it).
        theta = inverse_kinematics(rotation, self.sync.design).theta
        goal = self.sync.goal if self.sync.goal is not None else np.zeros(3)
        # Each input modulo a turn, nearest the present goal (the gaps stay in order
        # when every input moves less than half a turn).
        nearest: FloatArray = theta + 2.0 * math.pi * np.round((goal - theta) / (2.0 * math.pi))
        return nearest

    def _limited(self, goal: FloatArray, target: FloatArray) -> FloatArray:
        """The next goal towards ``target`` within the speed and acceleration limits
        (per joint), from ``goal`` moving at :attr:`velocity`."""
        limits = self.sync.guard.limits
        period = self.sync.config.period
        v_max, a_max = limits.max_speed, limits.max_acceleration
        # Speed that can still stop at the target: v^2 <= 2 a d.
        distance = target - goal
        stop_speed = np.sqrt(2.0 * a_max * np.abs(distance))
        wanted = np.sign(distance) * np.minimum(
            np.minimum(v_max, stop_speed), np.abs(distance) / period
        )
        change = np.clip(wanted - self.velocity, -a_max * period, a_max * period)
        velocity = self.velocity + change
        result: FloatArray = goal + velocity * period
        return result

    def _along(self, goal: FloatArray, nxt: FloatArray, target: FloatArray) -> FloatArray | None:
        """A step from ``goal`` along the boundary of the safe set, when the step to
        ``nxt`` leaves it: the gap part of the step turned by the smallest of
        :data:`SLIDE_ANGLES_DEG` (either way) that is safe and brings the goal nearer
        the target, shortened to its projection (the turn about the axis kept), then
        rate-limited as the tracking step. None when no such step exists (the goal
        stops at the boundary)."""
        step = nxt - goal
        mean = np.full(3, step.mean())
        gap = step - mean  # the part that changes the gaps (zero mean)
        a, b = float(gap @ _GAP_BASIS[0]), float(gap @ _GAP_BASIS[1])
        if math.hypot(a, b) < 1e-12:
            return None
        now = float(np.linalg.norm(target - goal))
        best: tuple[float, FloatArray] | None = None
        for angle in SLIDE_ANGLES_DEG:
            for sign in (1.0, -1.0):
                phi = math.radians(sign * angle)
                c, s = math.cos(phi), math.sin(phi)
                turned = c * ((c * a - s * b) * _GAP_BASIS[0] + (s * a + c * b) * _GAP_BASIS[1])
                candidate = self._rate_limited(goal, goal + mean + turned)
                distance = float(np.linalg.norm(target - candidate))
                if distance >= now - 1e-12 or not self._safe_step(goal, candidate):
                    continue
                if best is None or distance < best[0]:
                    best = (distance, candidate)
            if best is not None:
                return best[1]
        return None

    def _rate_limited(self, goal: FloatArray, wanted: FloatArray) -> FloatArray:
        """``wanted`` pulled in so that the step from ``goal`` keeps the guard's joint
        speed and acceleration (from :attr:`velocity`)."""
        limits = self.sync.guard.limits
        period = self.sync.config.period
        velocity = (wanted - goal) / period
        dv = limits.max_acceleration * period
        velocity = np.clip(velocity, self.velocity - dv, self.velocity + dv)
        velocity = np.clip(velocity, -limits.max_speed, limits.max_speed)
        result: FloatArray = goal + velocity * period
        return result

    def _safe_step(self, goal: FloatArray, nxt: FloatArray) -> bool:
        return bool(self.safe.certify(np.vstack([goal, nxt]))[0])

    def step(self, R: npt.ArrayLike | None) -> StreamStep:
        """One cycle with a target orientation (None: hold)."""
        sync = self.sync
        goal = np.array(sync.goal, dtype=float)
        period = sync.config.period
        target: FloatArray | None = None
        reason: str | None = None
        if R is not None:
            try:
                target = self.solve(R)
            except (UnreachableError, InputError) as exc:
                reason = f"target not solved: {exc}"
        action = "hold" if target is None else "track"
        nxt = goal
        if target is not None:
            nxt = self._limited(goal, target)
            if not self._safe_step(goal, nxt):
                reason = "the way towards the target leaves the safe set"
                if self.mode == "slide":
                    low, high = 0.0, 1.0  # goal is safe; find the furthest safe fraction
                    for _ in range(SLIDE_BISECTIONS):
                        mid = 0.5 * (low + high)
                        if self._safe_step(goal, goal + mid * (nxt - goal)):
                            low = mid
                        else:
                            high = mid
                    along = self._along(goal, nxt, target)
                    nxt = goal + low * (nxt - goal) if along is None else along
                    action = "slide" if np.any(nxt != goal) else "hold"
                else:
                    nxt, action = goal, "hold"
        result = sync.step(None if action == "hold" else nxt)
        if action != "hold" and not result.sent:
            # The loop's own guard (speed, acceleration, its model) refused it.
            why = result.fault or "; ".join(result.verdict.reasons if result.verdict else ())
            reason = f"the guard refused the step: {why}"
            action = "hold"
        if action == "hold":
            # Holding: the goal is at rest (the guard's next speed and acceleration
            # checks start from rest, as the limiter does).
            sync._goal_before = None
        sent_goal = np.array(sync.goal, dtype=float)
        self.velocity = (sent_goal - goal) / period
        self.counts[action] += 1
        return StreamStep(target, sent_goal, action, reason, result)

    def run(self, targets: Iterable[Any]) -> list[StreamStep]:
        """Stream targets (rotations, or None to hold), one per loop period."""
        import time

        steps = []
        period = self.sync.config.period
        next_time = time.perf_counter()
        for R in targets:
            steps.append(self.step(R))
            next_time += period
            delay = next_time - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
        return steps
