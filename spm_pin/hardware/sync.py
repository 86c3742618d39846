"""Model-servo sync: read the servos, solve the model, send only what the guard approves.

One cycle of :meth:`ServoSync.step`::

    read (sync read of the three servos) -> forward kinematics (home assembly mode,
    continuous with the last cycle) -> model update (closed configuration q, and a
    meshcat view when one is attached) -> guard (reachable, singularity margin,
    collisions with margin, joint limits, speed and acceleration) -> write (sync write
    of the goal positions)

An unsafe goal is refused with the guard's reasons and never sent. A path is checked
whole before its first command (:meth:`ServoSync.run`, :meth:`ServoSync.move_to`).
Faults are handled so that the servos never receive an unchecked command:

* a failed read or write (after the driver's bounded retries), or a servo that does
  not hold the goal last sent: the cycle sends nothing (the servos keep the last safe
  goal); after ``max_failures`` consecutive failed cycles torque goes off and
  :class:`~spm_pin.errors.HardwareError` is raised;
* a hardware alert: the servo is rebooted when the :class:`RebootPolicy` allows it
  (its profile is written again, it holds its present position, torque comes back);
  otherwise torque goes off on every servo and
  :class:`~spm_pin.errors.ServoAlertError` is raised;
* leaving ``with ServoSync(...)`` (normally or by an exception) turns torque off.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import time
from collections.abc import Callable
from types import TracebackType
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import numpy.typing as npt

from ..errors import (
    CommunicationError,
    ConvergenceError,
    HardwareError,
    InputError,
    ServoAlertError,
    SPMError,
    UnreachableError,
    UnsafeCommandError,
)
from ..kinematics import forward_kinematics
from .config import HardwareConfig, RebootPolicy
from .control_table import HardwareErrorFlag
from .driver import ServoBus, ServoReadings
from .guard import SafetyGuard, Verdict
from .joints import JointMap

if TYPE_CHECKING:
    from ..model.robot import SPMRobot

__all__ = [
    "MoveResult",
    "ServoSync",
    "StepResult",
    "SyncState",
    "Viewer",
    "plan_linear",
]

FloatArray = npt.NDArray[np.float64]
_STAGES = ("read", "kinematics", "view", "guard", "write")


class Viewer(Protocol):
    """Anything that can show the robot at a configuration (e.g. spm_pin.viz.Visualizer)."""

    def display(self, x: npt.ArrayLike) -> object:
        """Show the robot at joint configuration q (9,) [rad]."""


@dataclasses.dataclass(frozen=True)
class SyncState:
    """The robot as the servos and the model see it at one instant.

    Attributes:
        time: :func:`time.perf_counter` at the read [s].
        theta: Joint angles [rad], (3,).
        theta_dot: Joint speeds [rad/s], (3,).
        current: Servo currents [A], (3,).
        goal: Goals the servos hold [rad], (3,).
        moving: Each servo's Moving flag.
        alert: Each servo's alert bit.
        reachable: The home assembly mode exists at theta.
        R: Platform rotation (3, 3) (NaN when unreachable).
        q: Closed joint configuration (9,) when the model is updated, else None.
        readings: The raw readings.
    """

    time: float
    theta: FloatArray
    theta_dot: FloatArray
    current: FloatArray
    goal: FloatArray
    moving: tuple[bool, ...]
    alert: tuple[bool, ...]
    reachable: bool
    R: FloatArray
    q: FloatArray | None
    readings: ServoReadings


@dataclasses.dataclass(frozen=True)
class StepResult:
    """What one cycle did.

    Attributes:
        state: The state read (None when the read failed).
        goal: The goal asked for [rad] (None for a read-only cycle).
        sent: The goal went to the servos.
        verdict: The guard's verdict (None when it was not reached).
        fault: What went wrong (read/write failure, recovery), or None.
        timings: Seconds spent per stage: read (sync read), kinematics (forward
            kinematics, and the closed configuration q when the model is updated),
            view (the viewer), guard, write (sync write).
    """

    state: SyncState | None
    goal: FloatArray | None
    sent: bool
    verdict: Verdict | None
    fault: str | None
    timings: dict[str, float]

    @property
    def refused(self) -> bool:
        """The guard refused the goal."""
        return self.verdict is not None and not self.verdict.safe


@dataclasses.dataclass(frozen=True)
class MoveResult:
    """A streamed motion.

    Attributes:
        path: The goals sent [rad], (n, 3).
        states: The state of every cycle (model following the servos).
        reached: The servos came to rest (at most 0.229 rev/min) within tolerance of
            the last goal.
        final: The last state read.
        duration: From the first command to the end [s].
        max_lag: Largest |theta - goal sent| over the cycles [rad].
        late_cycles: Cycles that started more than one period late.
    """

    path: FloatArray
    states: list[SyncState]
    reached: bool
    final: SyncState
    duration: float
    max_lag: float
    late_cycles: int

    @property
    def final_error(self) -> float:
        """Largest |theta - last goal| at the end [rad]."""
        return float(np.max(np.abs(self.final.theta - self.path[-1])))


def plan_linear(
    start: npt.ArrayLike,
    goal: npt.ArrayLike,
    *,
    max_speed: float,
    max_acceleration: float,
    period: float,
) -> FloatArray:
    """A straight line in joint space with a trapezoidal speed profile, sampled.

    All joints move together; the joint that moves furthest goes at most
    ``max_speed`` [rad/s] and accelerates at most ``max_acceleration`` [rad/s^2],
    starting and ending at rest.

    Returns:
        The goals at t = period, 2 period, ..., ending exactly on ``goal``, (n, 3).
    """
    try:
        a0 = np.asarray(start, dtype=float)
        a1 = np.asarray(goal, dtype=float)
    except (TypeError, ValueError):  # not numbers: refused by the shape check below
        a0 = a1 = np.empty(0)
    if a0.shape != (3,) or a1.shape != (3,) or not np.all(np.isfinite(np.r_[a0, a1])):
        raise InputError(
            f"start and goal must be 3 finite angles [rad], got {start!r} and {goal!r}",
            argument="goal",
            value=goal,
        )
    for name, value in (("max_speed", max_speed), ("max_acceleration", max_acceleration)):
        if not value > 0 or not math.isfinite(value):
            raise InputError(f"{name} must be > 0, got {value!r}", argument=name, value=value)
    if not period > 0:
        raise InputError(f"period must be > 0 s, got {period!r}", argument="period", value=period)
    distance = float(np.max(np.abs(a1 - a0)))
    if distance == 0.0:
        single: FloatArray = a1[None].copy()
        return single
    v, a = max_speed, max_acceleration
    if distance >= v * v / a:  # accelerate, cruise, brake
        t_acc = v / a
        total = distance / v + t_acc
    else:  # accelerate, brake
        t_acc = math.sqrt(distance / a)
        v = a * t_acc
        total = 2.0 * t_acc
    n = max(1, math.ceil(total / period - 1e-9))
    t = np.minimum(np.arange(1, n + 1) * period, total)
    s = np.where(
        t < t_acc,
        0.5 * a * t**2,
        np.where(
            t <= total - t_acc,
            0.5 * a * t_acc**2 + v * (t - t_acc),
            distance - 0.5 * a * (total - t) ** 2,
        ),
    )
    fraction = np.clip(s / distance, 0.0, 1.0)
    fraction[-1] = 1.0
    result: FloatArray = a0 + fraction[:, None] * (a1 - a0)
    return result


class ServoSync:
    """Keeps the model and the servos in sync; sends only guarded goals.

    Args:
        bus: An open :class:`ServoBus` whose ids are the joints' servo ids, in order.
        config: Joints, limits and rates (default: :class:`HardwareConfig` defaults).
        robot: The robot model (default: built from ``design`` or the prototype).
        guard: The safety guard (default: one on ``robot`` with ``config.safety``).
        viewer: Shown the closed configuration q every cycle (e.g.
            ``spm_pin.viz.Visualizer(robot)``).
        update_model: Compute the closed configuration q every cycle (always with a
            viewer).

    Attributes:
        goal: The last safe goal sent (what the servos hold) [rad], or None.
        torque: Torque is on (as far as this object commanded it).
        failures: Consecutive failed cycles.
        events: Faults and recoveries, oldest first (one sentence each).
        reboots: Reboots done per servo id.
    """

    def __init__(
        self,
        bus: ServoBus,
        config: HardwareConfig | None = None,
        *,
        robot: SPMRobot | None = None,
        guard: SafetyGuard | None = None,
        viewer: Viewer | None = None,
        update_model: bool = True,
        clock: Callable[[], float] = time.perf_counter,
    ) -> None:
        if not isinstance(bus, ServoBus):
            raise InputError(
                f"bus must be a ServoBus, got {type(bus).__name__}", argument="bus", value=bus
            )
        config = config or HardwareConfig(port=bus.port_name)
        if tuple(bus.ids) != config.ids:
            raise InputError(
                f"the bus has servo ids {list(bus.ids)} but the joints u_1, u_2, u_3 use "
                f"{list(config.ids)}: build the bus with ids=config.ids",
                argument="bus",
                value=bus.ids,
            )
        if robot is None:
            if guard is not None:
                robot = guard.robot
            else:
                from ..collision import build_robot

                robot = build_robot()
        self.bus = bus
        self.config = config
        self.robot: SPMRobot = robot
        self.design = robot.design
        self.guard = guard or SafetyGuard(robot, config.safety)
        self.viewer = viewer
        self.update_model = bool(update_model) or viewer is not None
        self.joints = JointMap(config.joints, coaxial=self.design.is_coaxial)
        self.clock = clock
        self.goal: FloatArray | None = None
        self._goal_before: FloatArray | None = None
        self._sent: dict[int, int] | None = None
        self.torque = False
        self.failures = 0
        self.events: list[str] = []
        self.reboots: dict[int, int] = dict.fromkeys(config.ids, 0)
        self.state: SyncState | None = None
        self._R: FloatArray | None = None

    def __repr__(self) -> str:
        return (
            f"ServoSync(port={self.bus.port_name!r}, ids={list(self.config.ids)}, "
            f"torque={'on' if self.torque else 'off'})"
        )

    def __enter__(self) -> ServoSync:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.release()

    # ------------------------------------------------------------------ state
    def _event(self, text: str) -> str:
        self.events.append(text)
        return text

    def _to_state(self, readings: ServoReadings) -> tuple[SyncState, dict[str, float]]:
        t0 = self.clock()
        theta = self.joints.to_theta(readings.position)
        q = None
        # The compiled single-input solve where it continues the last R (else the
        # solve from the last R decides).
        fast = self.guard._fast
        near = None if fast is None else fast.rotation_near(theta, self._R, self.design)
        if self.update_model:
            # The closed configuration (of that rotation, or the model's own home-mode
            # solve); R is the platform's placement in it.
            try:
                if fast is not None and near is not None:
                    q = fast.configuration(theta, near)
                else:
                    q = self.robot.configuration(theta, reference=self._R)
            except (UnreachableError, ConvergenceError):
                reachable, R = False, np.full((3, 3), math.nan)
            else:
                reachable = True
                R = np.array(self.robot.placement(q, "platform").rotation, dtype=float)
        elif near is not None:
            reachable, R = True, near
        else:
            fk = forward_kinematics(theta, self.design, reference=self._R)
            reachable = bool(fk.reachable)
            R = np.asarray(fk.R, dtype=float)
        if reachable:
            self._R = R
        t1 = self.clock()
        if self.viewer is not None and q is not None:
            self.viewer.display(q)
        t2 = self.clock()
        state = SyncState(
            time=readings.time,
            theta=theta,
            theta_dot=self.joints.to_theta_rate(readings.velocity),
            current=np.asarray(readings.current_a(), dtype=float),
            goal=self.joints.to_theta(readings.goal),
            moving=readings.moving,
            alert=readings.alert,
            reachable=reachable,
            R=R,
            q=q,
            readings=readings,
        )
        self.state = state
        return state, {"kinematics": t1 - t0, "view": t2 - t1}

    def read(self) -> SyncState:
        """Read the servos and update the model (no fault handling: errors raise)."""
        if not self.joints.unwrapped:
            raise HardwareError("call start() first (it fixes the servo turns)", operation="read")
        return self._to_state(self.bus.sync_read())[0]

    # ------------------------------------------------------------------ start/stop
    def start(self, *, torque: bool = True) -> SyncState:
        """Identify and configure the servos, read them, then hold where they are.

        A servo that reports a hardware error is rebooted first if the reboot policy
        allows it.

        Args:
            torque: Turn torque on, holding the present position (the goal is set to
                the present position first, so nothing moves). False leaves torque
                off (to follow the robot moved by hand).

        Raises:
            HardwareError: a servo is missing or of another model, or the reading
                has no assembly (check the zero offsets).
            ServoAlertError: a hardware error the reboot policy does not clear.
            UnsafeCommandError: the robot stands where the guard would refuse a goal
                (move it by hand, torque off, to a safe pose first).
        """
        self.bus.identify()
        alerted = [i for i in self.config.ids if self.bus.alerts.get(i)]
        if alerted:  # a shutdown latched earlier: clear it by the policy, or stop here
            summary = self._reboot_alerted(alerted)
            self._event(f"rebooted at start after a hardware error ({summary})")
        self.bus.configure(self.config.servo)
        self.torque = False
        readings = self.bus.sync_read()
        self.joints.unwrap(readings.position)
        state, _ = self._to_state(readings)
        if not state.reachable:
            raise HardwareError(
                f"the servos read theta = {np.degrees(state.theta).round(2).tolist()} deg, "
                "where the model has no assembly: check the zero offsets and directions in "
                "the configuration",
                operation="start",
            )
        self.goal = state.theta.copy()
        self._goal_before = None
        if torque:
            self.guard.check(state.theta).require()
            pulses = dict(zip(self.config.ids, readings.position, strict=True))
            self._sent = self.bus.sync_write_goals(pulses)
            self.bus.set_torque(True)
            self.torque = True
        self.failures = 0
        return state

    def release(self) -> list[str]:
        """Turn torque off on every servo (best effort; returns the servos that failed)."""
        problems: list[str] = []
        if not self.bus.is_open:
            return problems
        for servo_id in self.config.ids:
            try:
                self.bus.write(servo_id, "Torque Enable", 0)
            except SPMError as exc:
                problems.append(f"servo {servo_id}: {exc}")
        self.torque = False
        if problems:
            self._event("torque off failed on " + "; ".join(problems))
        return problems

    def _emergency(self, reason: str, cause: BaseException | None = None) -> HardwareError:
        problems = self.release()
        extra = f" (torque off failed: {'; '.join(problems)})" if problems else ""
        self._event(f"torque off: {reason}{extra}")
        return HardwareError(f"torque turned off: {reason}{extra}", operation="sync loop")

    def _fault(self, message: str, timings: dict[str, float], cause: BaseException) -> StepResult:
        self.failures += 1
        self._event(f"cycle failed ({self.failures}/{self.config.max_failures}): {message}")
        if self.failures >= self.config.max_failures:
            raise self._emergency(
                f"{self.failures} consecutive failed cycles, the last: {message}"
            ) from cause
        return StepResult(None, None, False, None, message, timings)

    # ------------------------------------------------------------------ alerts
    def _reboot_alerted(self, alerted: list[int]) -> str:
        """Reboot the alerted servos if the policy allows it, else torque off and raise.

        Returns:
            A summary of the errors, e.g. ``"servo 2: overload"``.
        """
        policy: RebootPolicy = self.config.reboot
        status = {i: int(self.bus.hardware_errors(i)) for i in alerted}
        names = {
            i: ", ".join(HardwareErrorFlag(bits).describe()) or "none reported"
            for i, bits in status.items()
        }
        summary = "; ".join(f"servo {i}: {names[i]}" for i in alerted)
        curable = all(
            bits and not bits & ~int(policy.reboot_on) and self.reboots[i] < policy.max_reboots
            for i, bits in status.items()
        )
        if not curable:
            problems = self.release()
            extra = f" (torque off failed: {'; '.join(problems)})" if problems else ""
            self._event(f"hardware error, torque off: {summary}{extra}")
            raise ServoAlertError(
                f"hardware error ({summary}); torque is off on every servo{extra}. Allowed "
                f"reboots: {policy.max_reboots} per servo for "
                f"{', '.join(policy.reboot_on.describe()) or 'nothing'}",
                servo_id=alerted[0] if len(alerted) == 1 else None,
                status=status,
            )
        for servo_id in alerted:
            self.bus.reboot(servo_id)
            self.reboots[servo_id] += 1
        return summary

    def _recover(self, readings: ServoReadings) -> str:
        """Reboot alerted servos when the policy allows; else torque off and raise."""
        alerted = [i for i, alert in zip(readings.ids, readings.alert, strict=True) if alert]
        summary = self._reboot_alerted(alerted)
        raw = self.config.servo.raw()
        for servo_id in alerted:
            # RAM is back to defaults: the profile (0 = unlimited!) first.
            for item in ("Profile Acceleration", "Profile Velocity"):
                self.bus.write(servo_id, item, raw[item])
        after = self.bus.sync_read()
        goal = self.goal if self.goal is not None else self.joints.to_theta(after.position)
        goal = goal.copy()
        for index, servo_id in enumerate(self.config.ids):
            if servo_id in alerted:
                # The multi-turn count restarted: the turn nearest the last goal.
                goal[index] = self.joints.unwrap_one(index, after.position[index], goal[index])
        held = self.joints.to_pulses(goal)
        self._sent = self.bus.sync_write_goals(held)
        if self.torque:
            self.bus.set_torque(True, alerted)
        self._goal_before, self.goal = None, goal
        return self._event(
            f"rebooted after a hardware error ({summary}); holding the present position"
        )

    def _restore(self, state: SyncState) -> None:
        """Send the last safe goal again, if the way there from where the servos are is
        safe; otherwise turn torque off (a goal the loop did not send is being held)."""
        if self.goal is None or self._sent is None:
            return
        way = self.guard.check_path(self.goal[None], start=state.theta)
        if not way.safe:
            raise self._emergency(
                "a servo holds a goal this loop did not send, and the way back to the last "
                f"safe goal is unsafe: {'; '.join(way.reasons)}"
            )
        try:
            self.bus.sync_write_goals(self._sent)
        except CommunicationError as exc:
            self._event(f"re-sending the last safe goal failed: {exc}")

    # ------------------------------------------------------------------ one cycle
    def step(self, goal: npt.ArrayLike | None = None) -> StepResult:
        """One cycle: read, model, then (if ``goal`` is given and safe) send it.

        Args:
            goal: Joint angles to send [rad], (3,), or None to only read (hold).

        Returns:
            What happened. A refused goal has ``sent`` False and the guard's reasons
            in ``verdict.reasons``; a failed cycle has ``fault`` set.

        Raises:
            HardwareError: ``max_failures`` consecutive failed cycles (torque is off).
            ServoAlertError: a hardware error the reboot policy cannot clear (torque
                is off).
            InputError: a malformed goal.
        """
        if self.goal is None:
            raise HardwareError("call start() first", operation="step")
        target = None
        if goal is not None:
            try:
                target = np.array(goal, dtype=float)
            except (TypeError, ValueError):
                raise InputError(
                    f"goal must be 3 joint angles [rad], got {goal!r}", argument="goal", value=goal
                ) from None
            if target.shape != (3,):
                raise InputError(
                    f"goal must be 3 joint angles [rad], got shape {target.shape}",
                    argument="goal",
                    value=goal,
                )
        timings = dict.fromkeys(_STAGES, 0.0)
        t0 = self.clock()
        try:
            readings = self.bus.sync_read()
        except CommunicationError as exc:
            timings["read"] = self.clock() - t0
            return self._fault(f"read failed: {exc}", timings, exc)
        timings["read"] = self.clock() - t0
        if any(readings.alert):
            try:
                message = self._recover(readings)
            except CommunicationError as exc:
                return self._fault(f"recovery failed: {exc}", timings, exc)
            state, stage = self._to_state(self.bus.sync_read())
            timings.update(stage)
            return StepResult(state, target, False, None, message, timings)
        state, stage = self._to_state(readings)
        timings.update(stage)
        if self._sent is not None and self.torque:
            held = dict(zip(readings.ids, readings.goal, strict=True))
            wrong = {i: (held[i], v) for i, v in self._sent.items() if held[i] != v}
            if wrong:
                text = ", ".join(
                    f"servo {i} holds {h}, expected {v}" for i, (h, v) in wrong.items()
                )
                result = self._fault(
                    f"goal mismatch ({text}): a lost packet or a servo that restarted; "
                    "the last safe goal is sent again",
                    timings,
                    HardwareError(text),
                )
                self._restore(state)
                return result
        if not state.reachable:
            return self._fault(
                f"the servos read theta = {np.degrees(state.theta).round(2).tolist()} deg where "
                "the model has no assembly",
                timings,
                HardwareError("unreachable reading"),
            )
        if target is None:
            self.failures = 0
            return StepResult(state, None, False, None, None, timings)
        if not self.torque:
            raise HardwareError("torque is off: start(torque=True) before sending goals")
        t1 = self.clock()
        verdict = self.guard.check(
            target,
            previous=self.goal,
            before_previous=self._goal_before,
            period=self.config.period,
        )
        timings["guard"] = self.clock() - t1
        if not verdict.safe:
            self._event(f"refused {np.degrees(target).round(3).tolist()} deg: {verdict.reasons}")
            self.failures = 0
            return StepResult(state, target, False, verdict, None, timings)
        t2 = self.clock()
        try:
            pulses = self.joints.to_pulses(target)
            self._sent = self.bus.sync_write_goals(pulses)
        except CommunicationError as exc:
            timings["write"] = self.clock() - t2
            return self._fault(f"write failed: {exc}", timings, exc)
        timings["write"] = self.clock() - t2
        self._goal_before, self.goal = self.goal, target
        self.failures = 0
        return StepResult(state, target, True, verdict, None, timings)

    # ------------------------------------------------------------------ motions
    def run(
        self,
        path: npt.ArrayLike,
        *,
        settle_timeout: float = 2.0,
        tolerance: float = math.radians(0.5),
        on_state: Callable[[SyncState], Any] | None = None,
    ) -> MoveResult:
        """Stream a path of goals, one per period, after checking it whole.

        Args:
            path: Goals [rad], (n, 3), one per ``config.period``, from the last goal.
            settle_timeout: How long to wait for the servos to reach the last goal [s].
            tolerance: Largest |theta - last goal| counted as reached [rad].
            on_state: Called with every state read.

        Raises:
            UnsafeCommandError: some sample is unsafe (nothing was sent).
            HardwareError: the motion was interrupted by faults (torque stays on,
                holding the last safe goal, unless the failures ran out).
        """
        if self.goal is None or not self.torque:
            raise HardwareError("call start() (torque on) before moving", operation="run")
        period = self.config.period
        # The guard validates the path's shape and numbers before numpy converts it here.
        self.guard.check_path(path, period=period, start=self.goal).require()
        goals = np.array(path, dtype=float)
        states: list[SyncState] = []
        late = 0
        max_lag = 0.0
        begin = next_time = self.clock()
        for k, goal in enumerate(goals):
            next_time += period
            delay = next_time - self.clock()
            if delay > 0:
                time.sleep(delay)
            elif -delay > period:
                late += 1
            previous_goal = self.goal
            result = self.step(goal)
            if result.state is not None:
                states.append(result.state)
                max_lag = max(max_lag, float(np.max(np.abs(result.state.theta - previous_goal))))
                if on_state is not None:
                    on_state(result.state)
            if not result.sent:
                why = result.fault or "; ".join(result.verdict.reasons if result.verdict else ())
                if result.refused:
                    raise UnsafeCommandError(
                        f"motion stopped at sample {k} (holding the last safe goal): {why}",
                        reasons=result.verdict.reasons if result.verdict else (),
                        goal=goal,
                        index=k,
                    )
                raise HardwareError(
                    f"motion stopped at sample {k} (holding the last safe goal): {why}",
                    operation="run",
                )
        target = goals[-1]
        reached = False
        deadline = self.clock() + settle_timeout
        final = states[-1] if states else self.read()
        while True:
            result = self.step()
            if result.state is not None:
                final = result.state
                states.append(final)
                if on_state is not None:
                    on_state(final)
                near = float(np.max(np.abs(final.theta - target))) <= tolerance
                # At rest: not moving, and at most one velocity unit (0.229 rev/min).
                still = not any(final.moving) and max(map(abs, final.readings.velocity)) <= 1
                if near and still:
                    reached = True
                    break
            if self.clock() > deadline:
                break
            time.sleep(period)
        return MoveResult(
            path=goals,
            states=states,
            reached=reached,
            final=final,
            duration=self.clock() - begin,
            max_lag=max_lag,
            late_cycles=late,
        )

    def move_to(
        self,
        theta: npt.ArrayLike,
        *,
        speed: float | None = None,
        acceleration: float | None = None,
        settle_timeout: float = 2.0,
        tolerance: float = math.radians(0.5),
        on_state: Callable[[SyncState], Any] | None = None,
    ) -> MoveResult:
        """Move along a straight line in joint space to ``theta`` [rad], checked first.

        Args:
            theta: The goal [rad], (3,).
            speed: Joint speed [rad/s] (default and at most ``safety.max_speed``).
            acceleration: [rad/s^2] (default and at most ``safety.max_acceleration``).
            settle_timeout: See :meth:`run` [s].
            tolerance: See :meth:`run` [rad].
            on_state: Called with every state read.

        Raises:
            UnsafeCommandError: the goal or the way to it is unsafe (nothing sent).
        """
        if self.goal is None:
            raise HardwareError("call start() first", operation="move_to")
        limits = self.config.safety
        path = plan_linear(
            self.goal,
            theta,
            max_speed=min(speed or limits.max_speed, limits.max_speed),
            max_acceleration=min(acceleration or limits.max_acceleration, limits.max_acceleration),
            period=self.config.period,
        )
        return self.run(path, settle_timeout=settle_timeout, tolerance=tolerance, on_state=on_state)

    def follow(
        self,
        duration: float,
        *,
        on_state: Callable[[SyncState], Any] | None = None,
        keep: int = 100_000,
    ) -> list[SyncState]:
        """Read the servos at the loop rate for ``duration`` seconds, sending nothing.

        The model (and viewer) follow the robot, e.g. moved by hand with torque off.

        Returns:
            The states read (the last ``keep``).
        """
        if not duration >= 0 or not math.isfinite(duration):
            raise InputError(
                f"duration must be a finite number of seconds >= 0, got {duration!r}",
                argument="duration",
                value=duration,
            )
        if self.goal is None:
            raise HardwareError("call start() first", operation="follow")
        period = self.config.period
        states: collections.deque[SyncState] = collections.deque(maxlen=max(int(keep), 0))
        end = self.clock() + duration
        next_time = self.clock()
        while True:
            result = self.step()
            if result.state is not None:
                states.append(result.state)
                if on_state is not None:
                    on_state(result.state)
            if self.clock() >= end:
                return list(states)
            next_time += period
            delay = next_time - self.clock()
            if delay > 0:
                time.sleep(min(delay, max(end - self.clock(), 0.0)))
