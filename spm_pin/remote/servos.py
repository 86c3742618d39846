"""The servo twin: the real robot through the hardware layer, the model in the loop
(``spm serve --device DEV [--config FILE]``).

:class:`ServoBackend` runs a :class:`~spm_pin.hardware.sync.ServoSync` loop at the
configuration's rate: every period it reads the three servos, solves the model, and
sends the next goal of the path (see :mod:`spm_pin.remote._motion`) only when the
sync loop's own guard accepts it too. So every goal passes the guard twice: once when
the server accepts it (goal, and the whole way there), once more on its way to the
bus (with the speed and acceleration between the goals actually sent). A goal the
loop's guard refuses is not sent: the path is dropped and the servos hold the last
safe goal; ``refusals`` counts them and ``events`` says why.

A stop turns the servos' torque off (the robot can then be moved by hand; the twin
follows it); the next accepted goal turns it on again, holding the present position
first, after the guard has accepted where the robot stands. A fault of the bus that
the sync loop cannot ride out (its bounded retries, then ``max_failures`` failed
cycles; a hardware alert its reboot policy does not clear) leaves torque off; the
twin reports it and takes no more goals. Closing the twin turns torque off.

The bus is used by the loop thread alone; the loop has its own copy of the robot
model, so requests served in other threads never share Pinocchio's data with it.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..errors import InputError, UnsafeCommandError
from ..hardware.config import HardwareConfig
from ..hardware.driver import ServoBus
from ..hardware.guard import SafetyGuard
from ..hardware.sync import ServoSync
from ..model.robot import SPMRobot
from ._motion import MotionTwin
from .backend import TwinState

__all__ = ["ServoBackend"]

FloatArray = npt.NDArray[np.float64]


class ServoBackend(MotionTwin):
    """The servos as a twin, through :class:`~spm_pin.hardware.sync.ServoSync`.

    Opening it identifies and configures the servos and turns torque on holding where
    they stand (the guard must accept that pose).

    Args:
        bus: An open :class:`~spm_pin.hardware.driver.ServoBus` of the three servos.
        config: Joints, limits and loop rate (default
            :class:`~spm_pin.hardware.config.HardwareConfig` on the bus's port).
        robot: The robot model (default: the prototype).
        distance_interval: See :class:`~spm_pin.remote.MotionTwin`.

    Attributes:
        name: ``"servos"``.
        sync: The sync loop (used by the twin's thread alone while it runs).
        config: The hardware configuration.
        refusals: Goals the loop's guard refused (not sent).
        events: What happened on the bus, oldest first (the sync loop's events and
            the twin's refusals and stops).

    Raises:
        HardwareError: a servo is missing or of another model; the reading has no
            assembly.
        UnsafeCommandError: the robot stands where the guard would refuse a goal.
    """

    name = "servos"

    def __init__(
        self,
        bus: ServoBus,
        config: HardwareConfig | None = None,
        *,
        robot: SPMRobot | None = None,
        distance_interval: float = 0.1,
    ) -> None:
        if not isinstance(bus, ServoBus):
            raise InputError(
                f"bus must be a ServoBus, got {type(bus).__name__}", argument="bus", value=bus
            )
        config = config or HardwareConfig(port=bus.port_name)
        super().__init__(
            robot=robot,
            limits=config.safety,
            period=config.period,
            distance_interval=distance_interval,
        )
        from ..collision import build_robot

        # The loop's own model and guard: no Pinocchio data shared across threads.
        loop_robot = build_robot(self.design)
        self.config = config
        self.sync = ServoSync(
            bus,
            config,
            robot=loop_robot,
            guard=SafetyGuard(loop_robot, config.safety),
            update_model=False,
        )
        self.refusals = 0
        self._resume = False
        self._halt = False
        self._twin_events: list[str] = []
        state = self.sync.start(torque=True)
        self._theta = state.theta.copy()
        self._theta_dot = np.asarray(state.theta_dot, dtype=float).copy()
        self._goal = state.theta.copy()
        self._torque = True
        self._start_loop()

    @property
    def events(self) -> list[str]:
        """The sync loop's events and the twin's, oldest first (a copy)."""
        return [*self.sync.events, *self._twin_events]

    # ---------------------------------------------------------------- the loop
    def _start_of_path(self) -> FloatArray:
        # With torque off the robot may have been moved by hand: start where it is,
        # and have the loop turn torque on (holding there) before the first goal.
        if not self._torque:
            self._resume = True
            start: FloatArray = self._theta.copy()
            return start
        return super()._start_of_path()

    def _advance(self, goal: FloatArray) -> tuple[FloatArray, FloatArray]:
        sync = self.sync
        if self._halt:
            self._halt = False
            problems = sync.release()
            with self._motion:
                self._torque = False
                self._resume = False
                self._path.clear()
            if problems:
                self._twin_events.append("torque off failed: " + "; ".join(problems))
        if not self._torque and self._resume:
            self._resume = False
            try:  # guard-checked: holds the present position
                held = sync.start(torque=True)
            except UnsafeCommandError as exc:  # moved by hand somewhere unsafe
                with self._motion:
                    self._path.clear()
                self._twin_events.append(f"torque stays off, the robot stands unsafe: {exc}")
            else:
                with self._motion:
                    self._torque = True
                self._twin_events.append(
                    f"torque on, holding {np.degrees(held.theta).round(2).tolist()} deg"
                )
        send = self._torque and sync.goal is not None and not np.array_equal(goal, sync.goal)
        result = sync.step(goal if send else None)
        if result.refused:
            reasons = "; ".join(result.verdict.reasons) if result.verdict else "refused"
            self.refusals += 1
            self._twin_events.append(
                f"not sent {np.degrees(goal).round(3).tolist()} deg: {reasons}; holding"
            )
            with self._motion:
                self._path.clear()
                self._goal = np.array(sync.goal, dtype=float)
        state = result.state
        if state is None:  # a failed cycle: nothing read; keep what was known
            return self._theta.copy(), self._theta_dot.copy()
        theta = np.asarray(state.theta, dtype=float).copy()
        if not self._torque:
            with self._motion:
                self._goal = theta.copy()  # torque off: the twin follows the robot
        speed = np.asarray(state.theta_dot, dtype=float).copy()
        return theta, speed

    def _on_fault(self, exc: Exception) -> None:
        problems = self.sync.release()
        with self._motion:
            self._torque = False
        if problems:
            self._twin_events.append("torque off failed: " + "; ".join(problems))

    # ---------------------------------------------------------------- public
    def stop(self, reason: str | None = None) -> TwinState:
        """Turn the servos' torque off (at the next cycle of the loop, within one
        period) and drop the path; counts the stop. The next accepted goal turns
        torque on again."""
        with self._motion:
            self._path.clear()
            self._goal = self._theta.copy()
            self._halt = True
            self._resume = False
        self.stops += 1
        self.last_stop_reason = reason
        self._twin_events.append(f"stop: {reason or 'asked'}; torque off")
        return self.state()

    def close(self) -> None:
        """End the loop thread and turn torque off (the bus stays open: its owner
        closes it)."""
        super().close()
        if self.sync.bus.is_open:
            self.sync.release()
