"""Twins that move in time: a thread advances them one period at a time.

:class:`MotionTwin` is what the simulated twin (:class:`~spm_pin.remote.DynamicBackend`)
and the servo twin (:class:`~spm_pin.remote.ServoBackend`) share: a loop thread that
sends the twin, every ``period`` seconds, the next goal of a path checked whole before
its first goal, and reads back where the twin is. A goal from ``PUT /joints`` becomes
a straight line in joint space with a trapezoidal speed profile (the servos' speed and
acceleration limits of the guard), checked whole by the guard
(:meth:`~spm_pin.hardware.guard.SafetyGuard.check_path`: every state of the line, with
the speed and acceleration between goals); a streamed goal (with ``previous`` and
``period``) is checked alone, with its speed and acceleration, and replaces the path.

The derived state (orientation, dexterity, colliding pairs) is computed when read, for
the input angles the twin has then; the exact smallest link distance, the costly part
(about 20 ms), is computed again at most every ``distance_interval`` seconds while the
angles change (also while a twin that counts as at rest still creeps onto its goal),
and kept where they stay: within :data:`REST_ANGLE` of the angles where it was
computed (a simulation at rest still moves them by rounding). So at rest the distance
is exact, from at most ``distance_interval`` seconds after the twin stopped.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import threading
import time
from types import TracebackType

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..errors import InputError, UnsafeCommandError
from ..hardware.config import SafetyLimits
from ..hardware.sync import plan_linear
from ..model.robot import SPMRobot
from .backend import CheckOutcome, GuardedTwin, TwinState, _goal_arguments

__all__ = ["PATH_CHECK", "MotionTwin"]

FloatArray = npt.NDArray[np.float64]

#: The check of the straight line from where the twin heads to an HTTP goal.
PATH_CHECK = "path"
#: A twin within this of its goal [rad] and slower than SETTLED_SPEED is at rest.
SETTLED_ANGLE = math.radians(0.5)
#: [rad/s], see SETTLED_ANGLE.
SETTLED_SPEED = math.radians(2.0)
#: [rad]: at rest, angles within this of those where the smallest link distance was
#: computed keep it (a simulation at rest moves them by rounding, about 1e-19 rad a
#: period: the links move by some 1e-13 m at most, far below the distance's
#: tolerance); beyond it the distance is computed again.
REST_ANGLE = 1e-12


class MotionTwin(GuardedTwin):
    """A twin advanced by a loop thread, one ``period`` at a time (see the module).

    Subclasses set ``self._theta``, ``self._goal`` (and ``self._theta_dot``) before
    calling :meth:`_start_loop`, and provide :meth:`_advance`.

    Args:
        design: The SPM (default: the prototype); ignored when ``robot`` is given.
        robot: The robot with its collision checker.
        limits: The guard's limits (its ``max_speed`` and ``max_acceleration`` shape
            the paths to HTTP goals).
        period: Seconds between two goals sent to the twin (> 0).
        distance_interval: While moving, the smallest link distance is computed
            again at most this often [s].

    Attributes:
        period: Seconds between goals.
        cycles: Loop cycles run.
        late_cycles: Cycles that started late (the loop could not keep its period).
        fault: Why the twin stopped by itself, or None.
    """

    name = "motion"

    def __init__(
        self,
        design: SPMDesign | None = None,
        *,
        robot: SPMRobot | None = None,
        limits: SafetyLimits | None = None,
        period: float,
        distance_interval: float = 0.1,
    ) -> None:
        for key, value in (("period", period), ("distance_interval", distance_interval)):
            if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
                raise InputError(
                    f"{key} must be a positive number of seconds, got {value!r}",
                    argument=key,
                    value=value,
                )
            if not math.isfinite(value):
                raise InputError(f"{key} must be finite, got {value!r}", argument=key)
        super().__init__(design, robot=robot, limits=limits)
        self.period = float(period)
        self.distance_interval = float(distance_interval)
        self._motion = threading.Lock()  # path, goal, theta, theta_dot, fault, torque
        self._path: collections.deque[FloatArray] = collections.deque()
        self._theta: FloatArray = np.zeros(3)
        self._theta_dot: FloatArray = np.zeros(3)
        self._goal: FloatArray = np.zeros(3)
        self._torque = True
        self.fault: str | None = None
        self.cycles = 0
        self.late_cycles = 0
        self._closing = threading.Event()
        self._thread: threading.Thread | None = None
        self._derived: tuple[bytes, TwinState] | None = None
        # (monotonic time, distance, the angles [rad]) of the last exact distance
        self._distance: tuple[float, float, FloatArray] | None = None

    # ---------------------------------------------------------------- the loop
    def _start_loop(self) -> None:
        self._thread = threading.Thread(
            target=self._loop, name=f"spm-{self.name}-twin", daemon=True
        )
        self._thread.start()

    def _advance(self, goal: FloatArray) -> tuple[FloatArray, FloatArray]:
        """One period of the twin heading for ``goal`` [rad]; returns (theta,
        theta_dot) [rad], [rad/s] at its end. Raise SPMError on a fault."""
        raise NotImplementedError

    def _on_fault(self, exc: Exception) -> None:
        """Called in the loop thread after a fault (the servo twin turns torque off)."""

    def _cycle(self) -> None:
        with self._motion:
            if self._path:
                self._goal = self._path.popleft()
            goal = self._goal
        theta, theta_dot = self._advance(goal)
        with self._motion:
            self._theta, self._theta_dot = theta, theta_dot

    def _loop(self) -> None:
        period = self.period
        next_time = time.perf_counter()
        while not self._closing.is_set():
            if self.fault is None:
                try:
                    self._cycle()
                except Exception as exc:  # a fault ends the motion, never the server
                    with self._motion:
                        self.fault = f"{type(exc).__name__}: {exc}"
                        self._path.clear()
                    self._on_fault(exc)
            self.cycles += 1
            next_time += period
            delay = next_time - time.perf_counter()
            if delay > 0:
                self._closing.wait(delay)
            else:
                self.late_cycles += 1
                if delay < -10 * period:  # far behind: start counting afresh
                    next_time = time.perf_counter()

    def close(self) -> None:
        """End the loop thread (the twin holds where it is)."""
        self._closing.set()
        if self._thread is not None:
            self._thread.join(timeout=10.0)

    def __enter__(self) -> MotionTwin:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # ---------------------------------------------------------------- reading
    def joints(self) -> FloatArray:
        """Where the twin is now: its input angles [rad], (3,)."""
        with self._motion:
            theta: FloatArray = self._theta.copy()
        return theta

    def state(self) -> TwinState:
        """The present state (its ``time`` is now); see the module for the distance."""
        with self._motion:
            theta = self._theta.copy()
            theta_dot = self._theta_dot.copy()
            goal = (self._path[-1] if self._path else self._goal).copy()
            pending = bool(self._path)
            fault, torque = self.fault, self._torque
        moving = fault is None and (
            pending
            or float(np.max(np.abs(goal - theta))) > SETTLED_ANGLE
            or float(np.max(np.abs(theta_dot))) > SETTLED_SPEED
        )
        key = theta.tobytes()
        with self._lock:
            if self._derived is not None and self._derived[0] == key:
                derived = self._derived[1]
            else:
                now = time.monotonic()
                known = None
                recent = self._distance
                if recent is not None and (
                    now - recent[0] < self.distance_interval
                    or float(np.max(np.abs(theta - recent[2]))) <= REST_ANGLE
                ):
                    known = recent[1]
                derived = self._compute_state(theta, known)
                if known is None:
                    self._distance = (now, derived.min_distance, theta)
                self._derived = (key, derived)
        return dataclasses.replace(
            derived,
            time=time.time(),
            moving=moving,
            stops=self.stops,
            theta_dot=theta_dot,
            goal=goal,
            fault=fault,
            torque=torque,
        )

    # ---------------------------------------------------------------- moving
    def _path_to(self, start: FloatArray, goal: FloatArray) -> list[FloatArray]:
        """The straight line from ``start`` to ``goal``, one goal per period, checked
        whole by the guard (call with the model lock held)."""
        limits = self.guard.limits
        path = plan_linear(
            start,
            goal,
            max_speed=limits.max_speed,
            max_acceleration=limits.max_acceleration,
            period=self.period,
        )
        verdict = self.guard.check_path(path, period=self.period, start=start)
        if not verdict.safe:
            where = np.degrees(start).round(3).tolist()
            reason = f"the straight line from {where} deg: " + "; ".join(verdict.reasons)
            report = self._report(goal)
            dataclasses.replace(
                report,
                safe=False,
                reasons=(*report.reasons, reason),
                checks=(*report.checks, CheckOutcome(PATH_CHECK, False, reason)),
            ).require()
        return list(path)

    def _start_of_path(self) -> FloatArray:
        """Where a new path starts: the goal the twin heads for now."""
        start: FloatArray = self._goal.copy()
        return start

    def move(
        self,
        theta: npt.ArrayLike,
        *,
        previous: npt.ArrayLike | None = None,
        before_previous: npt.ArrayLike | None = None,
        period: float | None = None,
        previous_period: float | None = None,
    ) -> TwinState:
        """Head for a goal [rad], (3,), if it and the way there are safe.

        Without ``period`` (an HTTP goal) the twin follows the straight line from the
        goal it heads for now, at the guard's speed and acceleration limits, after
        the guard checked the whole line; with ``previous`` and ``period`` (a stream
        of goals) the goal is checked alone, with its speed (and, with
        ``before_previous``, acceleration, over ``previous_period`` and ``period``
        when the goals are not evenly spaced), and the twin heads for it at once.

        Returns:
            The state right after the goal was accepted (``moving`` is True until
            the twin settles; poll :meth:`state`).

        Raises:
            InputError: not 3 finite numbers.
            GoalRefusedError: the goal or the way there is unsafe (the ``path``
                check names the sample); nothing changes.
            UnsafeCommandError: the twin stopped after a fault; it takes no goals.
        """
        goal, last, before = _goal_arguments(theta, previous, before_previous)
        if self.fault is not None:
            raise UnsafeCommandError(
                f"the {self.name} twin stopped after a fault and takes no goals: {self.fault}",
                reasons=(self.fault,),
                goal=goal,
            )
        with self._lock:
            self._accept(goal, last, before, period, previous_period)
            if period is None:
                with self._motion:
                    start = self._start_of_path()
                path = self._path_to(start, goal)
            else:
                path = [goal]
        with self._motion:
            self._path.clear()
            self._path.extend(path)
        return self.state()

    def stop(self, reason: str | None = None) -> TwinState:
        """Hold where the twin is now: the path is dropped and the goal becomes the
        present input angles. Counts the stop (``stops``, ``last_stop_reason``)."""
        with self._motion:
            self._path.clear()
            self._goal = self._theta.copy()
        self.stops += 1
        self.last_stop_reason = reason
        return self.state()
