"""The kinematic twin: the model alone, its input angles jumping to each accepted goal.

What ``spm serve`` drives by default (``--sim kinematic``). The state is computed
when read and kept until the next goal; the costly part, the exact smallest link
distance, is computed on a robot of its own and, while goals stream in, at most every
:data:`DISTANCE_INTERVAL` seconds.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import threading
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ._distance import DistanceWorker, exact_min_distance
from .backend import FloatArray, GuardedTwin, LinkPair, TwinState, _goal_arguments, _theta

if TYPE_CHECKING:
    from ..design import SPMDesign
    from ..hardware.config import SafetyLimits
    from ..model.robot import SPMRobot

__all__ = ["DISTANCE_INTERVAL", "KinematicBackend"]

#: While goals stream in (``command``), the kinematic twin's exact smallest link
#: distance is computed again at most this often [s] (it costs ~15 ms).
DISTANCE_INTERVAL = 0.1


@contextlib.contextmanager
def _held(lock: threading.Lock, quick: bool) -> Iterator[bool]:
    """Hold ``lock`` for the block; ``quick``: only if it is free now (the block is
    told whether it holds it)."""
    held = lock.acquire(blocking=not quick)
    try:
        yield held
    finally:
        if held:
            lock.release()


class KinematicBackend(GuardedTwin):
    """The model alone: a twin whose input angles jump to each accepted goal.

    Its state is computed when it is read, not when a goal is accepted, and kept
    until the next goal: a stream of goals (:meth:`command`) pays for the guard's
    checks only, and the exact smallest link distance (``min_distance``, the costly
    part) is computed with the distance of the nearest pair of the previous state
    as a cap, which prunes the other pairs early and gives the same minimum. While
    goals stream in, it is computed again at most every :data:`DISTANCE_INTERVAL`
    seconds (in between, a read gives the last one computed); after :meth:`move` it
    is always exact.

    Args:
        design: The SPM (default: the prototype); ignored when ``robot`` is given.
        robot: The robot with its collision checker (default
            ``spm.build_robot(design)``).
        limits: The guard's limits (default
            :class:`~spm_pin.hardware.config.SafetyLimits`).
        theta: The starting input angles [rad] (default: home, [0, 0, 0]); must be
            safe.
        distance_process: While goals stream in, compute the exact distances in a
            child process (:class:`~spm_pin.remote._distance.DistanceWorker`, what
            ``spm serve`` does): they hold the interpreter lock for about 12 ms,
            which would stall a server's event loop. A read then gives the last
            distance computed while the child computes the next (its age: at most
            :data:`DISTANCE_INTERVAL` plus one computation). Stop the child with
            :meth:`close` (or use the twin as a context manager). Where no process
            can be started, the distances are computed in process.

    Attributes:
        name: ``"kinematic"``.
        design: The design of the robot.
        robot: The robot model.
        guard: The safety guard every goal passes.
        distance_process: Whether a child process computes the distances of a stream.
    """

    name = "kinematic"

    def __init__(
        self,
        design: SPMDesign | None = None,
        *,
        robot: SPMRobot | None = None,
        limits: SafetyLimits | None = None,
        theta: npt.ArrayLike | None = None,
        distance_process: bool = False,
    ) -> None:
        super().__init__(design, robot=robot, limits=limits)
        start: FloatArray = np.zeros(3) if theta is None else _theta(theta)
        report = self._report(start).require()
        self.distance_process = bool(distance_process)
        # Started now: a spawned process takes a while to start. Where no process
        # can be started, the distances are computed in process.
        self._worker: DistanceWorker | None = None
        if self.distance_process:
            try:
                self._worker = DistanceWorker(self.design)
            except (OSError, RuntimeError):
                self.distance_process = False
        self._theta: FloatArray = start
        self._state: TwinState | None = self._compute_state(start, report.min_distance)
        # The exact distances: a robot of their own (built at the first read after
        # a goal) and the link pair nearest at the last read, whose distance caps
        # the search of the next minimum.
        self._distance_lock = threading.Lock()
        self._streaming = False  # the last goal came by command() (a stream)
        # (monotonic time, m): the last exact distance. With a child process, the
        # one at the start stands until the child's first answer.
        self._last_distance: tuple[float, float] | None = (
            (time.monotonic(), report.min_distance) if self._worker is not None else None
        )
        self._distance_robot: SPMRobot | None = None
        self._nearest: LinkPair | None = None

    def _min_distance(self, theta: FloatArray) -> float:
        """The exact smallest link distance at an accepted goal [m] (home assembly
        mode, every checked pair, as :func:`~spm_pin.collision.check_input`).

        Computed on a robot of its own (under its own lock), so that the twin's lock
        is not held meanwhile and goals keep being accepted.
        """
        from ..collision import build_robot

        with self._distance_lock:
            if self._distance_robot is None:
                self._distance_robot = build_robot(self.design)
            distance, self._nearest = exact_min_distance(self._distance_robot, theta, self._nearest)
            return distance

    def _worker_takes(self, theta: FloatArray, quick: bool = False) -> bool:
        """Whether the child process computes the distance at ``theta`` (asked now,
        or a request under way); False without one (or before it is ready; or,
        ``quick``, while a distance is computed in process)."""
        if not self.distance_process:
            return False
        with _held(self._distance_lock, quick) as held:
            if not held:
                return False
            if self._worker is None:
                self._worker = DistanceWorker(self.design)
            worker = self._worker
        return worker.request(theta)

    def _worker_answer(self) -> None:
        """Take the child's newest distance, when newer than the last one."""
        worker = self._worker
        answer = None if worker is None else worker.latest()
        recent = self._last_distance
        if answer is not None and (recent is None or answer[0] > recent[0]):
            self._last_distance = (answer[0], answer[2])

    def close(self) -> None:
        """Stop the child process of the distances, if any (the twin stays usable:
        it computes them in process from then on)."""
        self.distance_process = False
        worker, self._worker = self._worker, None
        if worker is not None:
            worker.close()

    def __enter__(self) -> KinematicBackend:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def state(self) -> TwinState:
        """The current state (its ``time`` is now); computed at the first read after
        a goal, then kept until the next.

        The exact distances are computed without the twin's lock: a goal accepted
        meanwhile is not held up, and this read answers the state at the goal it
        started from (its own ``theta``, every value exact there).
        """
        with self._lock:
            theta = self._theta
        return self._exact_state(theta)

    def state_quick(self) -> TwinState | None:
        """:meth:`state` when it needs no exact distance computation: kept since the
        last read, or, while goals stream in, with the distance the child process
        computed or one at most :data:`DISTANCE_INTERVAL` old (what :meth:`state`
        then gives too). That costs a fraction of a millisecond, so a server may
        read it on its event loop. None where :meth:`state` would compute the
        distance (milliseconds): read that one with :meth:`state`.
        """
        with _held(self._lock, quick=True) as held:
            if not held:  # a goal is being checked (its report may take milliseconds)
                return None
            theta = self._theta
        return self._state_at(theta, quick=True)

    def _exact_state(self, theta: FloatArray) -> TwinState:
        """:meth:`_state_at` ``theta``, waiting and computing what it must."""
        state = self._state_at(theta, quick=False)
        assert state is not None  # only a quick read gives None
        return state

    def _state_at(self, theta: FloatArray, *, quick: bool) -> TwinState | None:
        """The state at ``theta``, an accepted goal (the current one, or one that a
        later goal has replaced meanwhile); kept when it is still the current one.
        ``quick``: None instead of computing the exact distance or waiting for a
        lock."""
        with _held(self._lock, quick) as held:
            if not held:
                return None
            if self._state is not None and self._theta is theta:
                return dataclasses.replace(self._state, time=time.time(), stops=self.stops)
        now = time.monotonic()
        if self._streaming:
            self._worker_answer()
        recent = self._last_distance
        if (
            self._streaming
            and recent is not None
            and (now - recent[0] < DISTANCE_INTERVAL or self._worker_takes(theta, quick))
        ):
            # Goals streaming in: at most DISTANCE_INTERVAL old, or the child
            # process computes the next one meanwhile.
            min_distance = recent[1]
        elif quick:
            return None
        else:
            min_distance = self._min_distance(theta)
            self._last_distance = (time.monotonic(), min_distance)  # its age counts from now
        with _held(self._lock, quick) as held:
            if not held:
                return None
            state = self._compute_state(theta, min_distance)
            if self._theta is theta:
                self._state = state
            return dataclasses.replace(state, time=time.time(), stops=self.stops)

    def joints(self) -> FloatArray:
        """The current input angles [rad], (3,)."""
        with self._lock:
            theta: FloatArray = self._theta.copy()
        return theta

    def command(
        self,
        theta: npt.ArrayLike,
        *,
        previous: npt.ArrayLike | None = None,
        before_previous: npt.ArrayLike | None = None,
        period: float | None = None,
        previous_period: float | None = None,
    ) -> None:
        """Jump to a goal [rad], (3,), if it is safe, without reading the state back
        (what a streamed goal needs; :meth:`move` answers the state too).

        Arguments and errors as :meth:`move`.
        """
        self._command(theta, previous, before_previous, period, previous_period, streamed=True)

    def command_quick(
        self,
        theta: npt.ArrayLike,
        *,
        previous: npt.ArrayLike | None = None,
        before_previous: npt.ArrayLike | None = None,
        period: float | None = None,
        previous_period: float | None = None,
    ) -> bool:
        """:meth:`command` without the costly report of a refusal: True when the goal
        was safe and taken, False when a static check of the guard refused it
        (nothing moved). Costs the guard's checks alone (a fraction of a
        millisecond), so a server may call it on its event loop and leave only those
        refusals, whose report costs milliseconds, to :meth:`command` in a worker
        thread.

        Raises:
            InputError: as :meth:`move`.
            GoalRefusedError: refused for its speed or acceleration alone (its report
                is as quick: the static checks passed, no distances are computed).
        """
        goal, last, before = _goal_arguments(theta, previous, before_previous)
        with self._lock:
            verdict = self.guard.check(
                goal,
                previous=last,
                before_previous=before,
                period=period,
                previous_period=previous_period,
            )
            if not verdict.safe:
                report = self._report(goal, last, before, period, verdict, previous_period)
                if report.assembly is not None and math.isinf(report.min_distance):
                    report.require()  # refused for its timing alone: a quick report
                return False
            self._theta = goal
            self._state = None
            self._streaming = True
        return True

    def _command(
        self,
        theta: npt.ArrayLike,
        previous: npt.ArrayLike | None,
        before_previous: npt.ArrayLike | None,
        period: float | None,
        previous_period: float | None = None,
        *,
        streamed: bool = False,
    ) -> FloatArray:
        goal, last, before = _goal_arguments(theta, previous, before_previous)
        with self._lock:
            self._accept(goal, last, before, period, previous_period)
            self._theta = goal
            self._state = None
            self._streaming = streamed
        return goal

    def move(
        self,
        theta: npt.ArrayLike,
        *,
        previous: npt.ArrayLike | None = None,
        before_previous: npt.ArrayLike | None = None,
        period: float | None = None,
        previous_period: float | None = None,
    ) -> TwinState:
        """Jump to a goal [rad], (3,), if it is safe.

        Args:
            theta: The goal [rad], (3,).
            previous: For a stream of goals: the goal commanded before [rad]; with
                ``period`` the guard checks the speed |theta - previous| / period.
            before_previous: The goal commanded before ``previous`` [rad]; the
                guard then checks the acceleration too.
            period: Time since ``previous`` was commanded [s].
            previous_period: Time between ``before_previous`` and ``previous`` [s]
                (default: ``period``).

        Returns:
            The state at the goal.

        Raises:
            InputError: not 3 finite numbers.
            GoalRefusedError: the goal is unsafe (an UnsafeCommandError; its
                ``report`` says why); the state is unchanged.
        """
        goal = self._command(theta, previous, before_previous, period, previous_period)
        return self._exact_state(goal)

    def stop(self, reason: str | None = None) -> TwinState:
        """Nothing is ever in motion in the kinematic twin: it holds still, counts
        the stop (``stops``, ``last_stop_reason``) and answers the state."""
        with self._lock:
            self.stops += 1
            self.last_stop_reason = reason
        return self.state()
