"""Servos and joint friction: the torque a position-controlled DC servo can give.

:class:`ServoModel` is a PD position loop whose torque is clipped to the DC-motor
envelope (the torque-speed line and the current limit); :data:`XM540_W150` is the
prototype's servo. :func:`check_servo` holds a motion's torques and speeds against that
envelope (:class:`ServoCheck`). :class:`JointFriction` is the viscous and smoothed
Coulomb friction of the nine joints.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..model.robot import JOINT_NAMES
from ._checks import array3, broadcast, nonnegative_vector, positive, values
from ._constants import RPM, FloatArray

__all__ = ["XM540_W150", "JointFriction", "ServoCheck", "ServoModel", "check_servo"]


@dataclasses.dataclass(frozen=True)
class JointFriction:
    """Viscous and (smoothed) Coulomb friction in the nine joints.

    The friction torque on joint j is

        tau_f,j = -(viscous_j v_j + coulomb_j tanh(v_j / smoothing_speed)),

    a smooth stand-in for dry friction (it cannot stick; below ``smoothing_speed``
    it acts like a viscous term of coefficient coulomb / smoothing_speed, which an
    explicit integrator must resolve: keep coulomb * dt / (smoothing_speed * inertia)
    well below 1).

    Args:
        viscous: Viscous coefficients [N m s/rad], a scalar (every joint) or (9,) in q
            order (u_1, w_1, v_1, u_2, ...).
        coulomb: Coulomb torques [N m], a scalar or (9,).
        smoothing_speed: Speed scale of the tanh [rad/s], > 0.

    Raises:
        InputError: negative, non-finite or wrongly shaped coefficients.
    """

    viscous: FloatArray = dataclasses.field(default_factory=lambda: np.zeros(9))
    coulomb: FloatArray = dataclasses.field(default_factory=lambda: np.zeros(9))
    smoothing_speed: float = 0.05

    def __post_init__(self) -> None:
        unit = "[N m s/rad]"
        object.__setattr__(self, "viscous", nonnegative_vector(self.viscous, 9, "viscous", unit))
        object.__setattr__(self, "coulomb", nonnegative_vector(self.coulomb, 9, "coulomb", "[N m]"))
        object.__setattr__(
            self,
            "smoothing_speed",
            positive(self.smoothing_speed, "smoothing_speed", "[rad/s]"),
        )

    @classmethod
    def actuators(
        cls, viscous: float = 0.0, coulomb: float = 0.0, *, smoothing_speed: float = 0.05
    ) -> JointFriction:
        """Friction in the three actuated joints only (servo gears), none in the others.

        Args:
            viscous: Viscous coefficient of each input shaft [N m s/rad].
            coulomb: Coulomb torque of each input shaft [N m].
            smoothing_speed: Speed scale of the tanh [rad/s].
        """
        mask = np.array([name.startswith("u_") for name in JOINT_NAMES], dtype=float)
        v = positive(viscous, "viscous", "[N m s/rad]", allow_zero=True)
        c = positive(coulomb, "coulomb", "[N m]", allow_zero=True)
        return cls(mask * v, mask * c, smoothing_speed)

    @property
    def has_coulomb(self) -> bool:
        """Whether any Coulomb term is nonzero."""
        return bool(np.any(self.coulomb > 0.0))

    def torque(self, v: npt.ArrayLike) -> FloatArray:
        """Friction torques [N m] at joint velocities v [rad/s], shape (..., 9)."""
        velocity = np.asarray(v, dtype=float)
        result: FloatArray = -self.viscous * velocity
        if self.has_coulomb:
            result -= self.coulomb * np.tanh(velocity / self.smoothing_speed)
        return result


# -------------------------------------------------------------------------- servos
@dataclasses.dataclass(frozen=True)
class ServoModel:
    """A position-controlled DC servo: PD loop, torque-speed line, current limit.

    At output speed omega the servo can deliver torques in [lower, upper]:

        upper(omega) = min(stall, stall (1 - omega / no_load)),
        lower(omega) = max(-stall, -stall (1 + omega / no_load)),

    the voltage limit (the torque-speed line through the stall torque at rest and
    zero torque at the no-load speed) and the current limit (at most the stall torque,
    also when braking). The position loop commands
    ``clip(kp (goal - theta) + kd (goal_velocity - theta_dot) + feedforward, lower, upper)``.

    Attributes:
        name: Servo name for reports.
        stall_torque: Stall torque [N m] (> 0).
        no_load_speed: No-load speed [rad/s] (> 0).
        kp: Position gain [N m/rad] (>= 0).
        kd: Velocity gain [N m s/rad] (>= 0).
        voltage: Supply voltage of the ratings [V] (for reports only).
    """

    name: str = "XM540-W150"
    stall_torque: float = 7.3
    no_load_speed: float = 53.0 * RPM
    kp: float = 20.0
    kd: float = 0.5
    voltage: float = 12.0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise InputError(f"name must be a string, got {self.name!r}", argument="name")
        object.__setattr__(
            self, "stall_torque", positive(self.stall_torque, "stall_torque", "[N m]")
        )
        object.__setattr__(
            self, "no_load_speed", positive(self.no_load_speed, "no_load_speed", "[rad/s]")
        )
        object.__setattr__(self, "kp", positive(self.kp, "kp", "[N m/rad]", allow_zero=True))
        object.__setattr__(self, "kd", positive(self.kd, "kd", "[N m s/rad]", allow_zero=True))
        object.__setattr__(self, "voltage", positive(self.voltage, "voltage", "[V]"))

    @property
    def no_load_rpm(self) -> float:
        """No-load speed [rev/min]."""
        return self.no_load_speed / RPM

    def with_gains(self, kp: float, kd: float) -> ServoModel:
        """The same servo with other position-loop gains [N m/rad], [N m s/rad]."""
        return dataclasses.replace(self, kp=kp, kd=kd)

    def torque_limits(self, speed: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(lower, upper) available torque [N m] at output speed(s) [rad/s]."""
        omega = values(speed, "speed", "[rad/s]")
        stall = self.stall_torque
        slope = omega / self.no_load_speed
        upper: FloatArray = np.minimum(stall, stall * (1.0 - slope))
        lower: FloatArray = np.maximum(-stall, -stall * (1.0 + slope))
        return lower, upper

    def saturate(self, torque: npt.ArrayLike, speed: npt.ArrayLike) -> FloatArray:
        """Torques clipped to the envelope at the given speeds [N m]."""
        lower, upper = self.torque_limits(speed)
        tau = values(torque, "torque", "[N m]")
        broadcast(tau, lower, names="torque, speed")
        result: FloatArray = np.clip(tau, lower, upper)
        return result

    def command(
        self,
        theta: npt.ArrayLike,
        theta_dot: npt.ArrayLike,
        goal: npt.ArrayLike,
        goal_velocity: npt.ArrayLike | None = None,
        feedforward: npt.ArrayLike | None = None,
    ) -> FloatArray:
        """Servo torques [N m] of the PD position loop, clipped to the envelope.

        Args:
            theta: Present positions [rad], (3,).
            theta_dot: Present speeds [rad/s], (3,).
            goal: Goal positions [rad], (3,).
            goal_velocity: Goal speeds [rad/s] (default 0).
            feedforward: Torque added before clipping [N m] (default 0).
        """
        position = values(theta, "theta", "[rad]")
        speed = values(theta_dot, "theta_dot", "[rad/s]")
        target = values(goal, "goal", "[rad]")
        broadcast(position, speed, target, names="theta, theta_dot, goal")
        torque = self.kp * (target - position) - self.kd * speed
        if goal_velocity is not None:
            rate = values(goal_velocity, "goal_velocity", "[rad/s]")
            broadcast(torque, rate, names="goal_velocity, theta")
            torque = torque + self.kd * rate
        if feedforward is not None:
            extra = values(feedforward, "feedforward", "[N m]")
            broadcast(torque, extra, names="feedforward, theta")
            torque = torque + extra
        return self.saturate(torque, speed)

    def utilisation(self, torque: npt.ArrayLike, speed: npt.ArrayLike) -> FloatArray:
        """Load of the servo: the larger of the PWM duty and the current it needs.

        A DC motor gives tau = stall (d - omega / no_load) at duty d in [-1, 1] and its
        current is proportional to tau, so a torque at a speed needs the duty
        d = tau / stall + omega / no_load and the current fraction |tau| / stall. The
        load max(|d|, |tau| / stall) is 0 at rest without torque and at most 1 exactly
        inside the envelope of :meth:`torque_limits`; above 1 the servo cannot do it
        (too much torque, or a speed beyond what its voltage allows).
        """
        tau_in = values(torque, "torque", "[N m]")
        omega = values(speed, "speed", "[rad/s]")
        broadcast(tau_in, omega, names="torque, speed")
        tau = tau_in / self.stall_torque
        duty = tau + omega / self.no_load_speed
        result: FloatArray = np.maximum(np.abs(duty), np.abs(tau))
        return result


#: The Dynamixel XM540-W150 at 12 V: stall torque 7.3 N m, no-load speed 53 rev/min.
#: The PD gains are a soft default for simulation, not the servo's control table.
XM540_W150 = ServoModel()


@dataclasses.dataclass(frozen=True)
class ServoCheck:
    """Whether a motion stays inside a servo's torque-speed envelope.

    Attributes:
        servo: The servo checked against.
        within_limits: Every sample of every joint inside the envelope.
        max_utilisation: Largest load (:meth:`ServoModel.utilisation`; 1 = on the
            envelope, above 1 = beyond it).
        worst_sample: Index of the sample of ``max_utilisation``.
        worst_joint: 0-based joint (input) index of ``max_utilisation``.
        peak_torque: Largest |torque| per joint [N m], (3,).
        peak_speed: Largest |speed| per joint [rad/s], (3,).
        rms_torque: Root mean square torque per joint [N m], (3,).
        utilisation: Load per sample and joint, (N, 3).
        message: One sentence: the verdict.
        limit: What sets ``max_utilisation``: ``"speed"`` when the worst sample's
            speed is the larger share of the no-load speed than its torque is of the
            stall torque (the supply voltage limits), else ``"torque"``.
    """

    servo: ServoModel
    within_limits: bool
    max_utilisation: float
    worst_sample: int
    worst_joint: int
    peak_torque: FloatArray
    peak_speed: FloatArray
    rms_torque: FloatArray
    utilisation: FloatArray
    message: str
    limit: Literal["speed", "torque"]


def check_servo(
    torque: npt.ArrayLike,
    speed: npt.ArrayLike,
    servo: ServoModel = XM540_W150,
    *,
    time: npt.ArrayLike | None = None,
) -> ServoCheck:
    """Check actuator torques and speeds against a servo's torque-speed envelope.

    Args:
        torque: Actuator torques [N m], (N, 3) or (3,).
        speed: Actuator speeds [rad/s], the same shape.
        servo: The servo (default :data:`XM540_W150`).
        time: Sample times [s], (N,), used in the message only.

    Returns:
        :class:`ServoCheck`.

    Raises:
        InputError: shapes differ or are not (N, 3), NaN or inf.
    """
    tau = np.atleast_2d(array3(torque, "torque", "[N m]"))
    omega = np.atleast_2d(array3(speed, "speed", "[rad/s]"))
    if tau.shape != omega.shape:
        raise InputError(
            f"torque and speed must have the same shape, got {tau.shape} and {omega.shape}",
            argument="speed",
            value=speed,
        )
    when: FloatArray | None = None
    if time is not None:
        when = np.asarray(time, dtype=float).reshape(-1)
        if when.shape != (tau.shape[0],):
            raise InputError(
                f"time must have shape ({tau.shape[0]},), got {when.shape}",
                argument="time",
                value=time,
            )
    use = servo.utilisation(tau, omega)
    flat = int(np.argmax(use))
    sample, joint = divmod(flat, 3)
    worst = float(use[sample, joint])
    within = bool(worst <= 1.0)
    speed_share = abs(float(omega[sample, joint])) / servo.no_load_speed
    torque_share = abs(float(tau[sample, joint])) / servo.stall_torque
    limit: Literal["speed", "torque"] = "speed" if speed_share > torque_share else "torque"
    at = f"t = {when[sample]:.3f} s" if when is not None else f"sample {sample}"
    needs = f"{tau[sample, joint]:+.3g} N m at {omega[sample, joint] / RPM:+.3g} rpm ({at})"
    if within:
        message = (
            f"OK: within the {servo.name} torque-speed envelope; peak load "
            f"{100.0 * worst:.1f}%, set by {limit} (joint u_{joint + 1}: {needs})"
        )
    else:
        message = (
            f"EXCEEDS the {servo.name} torque-speed envelope: joint u_{joint + 1} needs "
            f"{needs}, {100.0 * worst:.0f}% of what the servo can give, limited by {limit} "
            f"(stall "
            f"{servo.stall_torque:g} N m, no-load speed {servo.no_load_rpm:g} rpm)"
        )
    return ServoCheck(
        servo=servo,
        within_limits=within,
        max_utilisation=worst,
        worst_sample=sample,
        worst_joint=joint,
        peak_torque=np.abs(tau).max(axis=0),
        peak_speed=np.abs(omega).max(axis=0),
        rms_torque=np.sqrt(np.mean(tau**2, axis=0)),
        utilisation=use,
        message=message,
        limit=limit,
    )
