r"""Constrained dynamics of the closed-loop SPM: forward, inverse, simulation, servos.

The robot is an open Pinocchio tree of nine revolute joints, q = (u_1, w_1, v_1, ...,
v_3), plus two welds that close legs 2 and 3 on the platform
(:class:`~spm_pin.SPMRobot`). On the tree

    M(q) qdd + h(q, v) = tau + tau_f(v) + J(q)^T lambda,        J(q) v = 0,

with M the mass matrix (armature of the actuated joints included), h the Coriolis,
centrifugal and gravity terms, tau the actuator torques (zero on passive joints),
tau_f the joint friction and lambda the weld multipliers. J has 12 rows of rank 6:
all axes meet at O, so the linear rows of both welds are identically zero and the
closing forces at O are statically indeterminate. Only the six angular rows J_s are
used (chosen once, at construction, as the rows that are not identically zero; they
are independent away from parallel singularities), split into the columns of the
actuated joints (J_a) and of the passive joints (J_p, 6 x 6, invertible away from
type II singularities).

Null-space (reduced) form on the input angles theta. The passive velocities follow
from the actuated ones,

    v = S theta_dot,  S = [I; G] (rows in q order),  G = -J_p^-1 J_a,

and qdd = S theta_ddot + a_b with the bias a_b = [0; -J_p^-1 gamma], gamma = Jdot v
(the constraint acceleration at zero joint acceleration). Multiplying the tree
equation by S^T removes the multipliers (S^T J^T = 0):

    M_r theta_ddot = S^T (tau + tau_f - b),  M_r = S^T M S,  b = rnea(q, v, a_b).

Which formulation, and why:

* Forward dynamics in the simulator and :meth:`ClosedLoopDynamics.forward` (default
  ``method="pinocchio"``): Pinocchio's ``constraintDynamics`` on the two welds
  (legacy 6D models) with proximal settings mu = :data:`PROXIMAL_MU` and zero
  Baumgarte gains, fed with velocities projected so that J v = 0 exactly. With the
  redundant rows the plain KKT system is singular (mu = 0 gives NaN); the proximal
  iterations converge to the minimum-norm multipliers in 2-3 iterations and the
  accelerations agree with the null-space form to about 1e-15 relative (tested). It
  is one C++ call (about 5 us) against a dozen calls for the null-space form from
  Python, which is what a 1 kHz simulator at 50 times real time can afford.
* ``method="nullspace"``: the reduced equations above, exact by construction
  (redundant rows never enter); the reference that the tests hold the other to.
* Inverse dynamics (:meth:`ClosedLoopDynamics.inverse`): the same null-space
  quantities: qdd = S theta_ddot + a_b, tau_tree = rnea(q, v, qdd) - tau_f; the
  passive rows give the weld torques, J_p^T lambda_s = tau_tree,p; the actuated rows
  the actuator torques, tau = tau_tree,a - J_a^T lambda_s (= S^T tau_tree).

Time stepping (:class:`Simulator`): the state is (q, theta_dot) with q closed. Each
step integrates q (with v = S(q) theta_dot) and theta_dot, then projects: the
passive joints are moved by Newton steps on the angular weld rows with theta held
until the closure residual is <= :data:`CLOSURE_TOL` (evaluated at the state that is
kept, every step; a simulation never carries more than :data:`DRIFT_TOL`), and the
velocities are rebuilt from theta_dot with the Jacobian of that state, so J v = 0
again. Integrators:

* ``"rk4"``: classic fourth order on (q, theta_dot), the stages evaluated with the
  projected-velocity vector field; its steps land within 1e-12 of the loops, and a
  frictionless passive motion keeps its energy to about 1e-10 (relative) over 10 s
  at 1 kHz.
* ``"euler"``: semi-implicit Euler (MuJoCo's default scheme), one dynamics evaluation
  per step, first order. The passive joints are predicted on the loops to O(dt^3)
  (q + dt v + dt^2/2 (ddq + S theta_ddot)) plus an extrapolation of the previous
  steps' corrections, so that the projection usually finds the loops closed at its
  first evaluation: one kinematics evaluation and one ``constraintDynamics`` call
  per step.

A step is refused (:class:`~spm_pin.ConvergenceError`, "use a smaller time step")
when closing the loops lands further than :data:`JUMP_RATIO` of the step's motion
from the prediction (it may be another assembly mode) or an rk4 step moves a joint
by more than :data:`MAX_STEP_ANGLE`; a motion that runs into a parallel (type II)
singularity, where input angles stop describing the configuration, ends with
:class:`~spm_pin.SingularityError`. Actuator torques are held constant over a step
(a zero-order hold, like a digital servo loop at the step rate).

Servos (:class:`ServoModel`, :data:`XM540_W150`): a PD position loop whose torque is
clipped to the DC-motor envelope: the torque-speed line between the stall torque at
rest and zero torque at the no-load speed (voltage limit), and the stall torque as a
current limit (braking included).
"""

from __future__ import annotations

import bisect
import csv
import dataclasses
import math
import textwrap
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

import eigenpy
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .closure import CLOSED_TOL, ClosedLoop
from .errors import ConvergenceError, FileFormatError, InputError, SingularityError
from .kinematics._common import (
    ANGLE_LIMIT,
    check_count,
    float_array,
    require_angles,
    require_bounded,
    require_finite,
)
from .model.robot import JOINT_NAMES, SPMRobot, build_robot

__all__ = [
    "CLOSURE_TOL",
    "DEFAULT_DT",
    "DRIFT_TOL",
    "GRAVITY",
    "INTEGRATORS",
    "PROXIMAL_MU",
    "XM540_W150",
    "ClosedLoopDynamics",
    "ForwardDynamicsResult",
    "InverseDynamicsResult",
    "JointFriction",
    "ServoCheck",
    "ServoController",
    "ServoModel",
    "SimulationResult",
    "Simulator",
    "Trajectory",
    "check_servo",
    "forward_dynamics",
    "holding_torques",
    "inverse_dynamics",
    "plot_torques",
    "simulate_mujoco",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Gravity of an upright robot (z up, base below the platform) [m/s^2].
GRAVITY = (0.0, 0.0, -9.81)
#: Default time step of the simulator [s] (1 kHz).
DEFAULT_DT = 1e-3
#: Integrators of :class:`Simulator`.
INTEGRATORS = ("rk4", "euler")
#: Proximal regularisation mu of ``pin.constraintDynamics``: any value in
#: [1e-12, 1e-4] is exact with the redundant weld rows (mu = 0 gives NaN); at 1e-10 the
#: iterations stop after 2 (sometimes 3) with accelerations exact to ~1e-15 relative.
PROXIMAL_MU = 1e-10
#: Absolute accuracy and iteration cap of the proximal iterations.
PROXIMAL_ACCURACY = 1e-14
PROXIMAL_MAX_ITERATIONS = 20
#: Target of the position projection: Euclidean norm of the stacked weld errors [rad].
CLOSURE_TOL = 1e-12
#: Largest closure residual a simulation may ever carry [rad]; exceeding it raises.
DRIFT_TOL = 1e-10
#: Newton steps of the lean projection before falling back on ClosedLoop.project.
NEWTON_MAX_ITERATIONS = 6
#: Reciprocal condition number of J_p below which a configuration is treated as a
#: parallel (type II) singularity: the passive joints no longer follow the inputs.
SINGULAR_RCOND = 1e-8
#: A Newton projection that moves the passive joints by more than this fraction of the
#: step's own motion is refused (it may have jumped to another assembly mode).
JUMP_RATIO = 0.5
#: Largest joint motion of one rk4 step [rad]; beyond it the step is refused (a motion
#: that fast for the time step is not integrated accurately).
MAX_STEP_ANGLE = 0.1
#: A failed projection after a step that ended with an rcond below this is reported as
#: the motion reaching a parallel singularity (input angles cannot continue it).
SINGULAR_NEAR = 1e-2
#: Default softness of MuJoCo's weld constraints in :func:`simulate_mujoco`:
#: solimp (dmin, dmax, width, midpoint, power).
MUJOCO_SOLIMP = (0.999, 0.9999, 0.001, 0.5, 2.0)
_MUJOCO_INTEGRATORS = ("euler", "rk4", "implicit", "implicitfast")
_RPM = 2.0 * math.pi / 60.0
_ZERO3 = (0.0, 0.0, 0.0)


# ------------------------------------------------------------------------- checks
#: Largest |value| accepted for the speeds [rad/s], torques [N m] and accelerations
#: [rad/s^2] given to the dynamics, by unit. Generous physical bounds: 1e4 rad/s is
#: ~95,000 rev/min (the XM540 turns at 5.5 rad/s), 1e4 N m is >1000 times its stall
#: torque, 1e7 rad/s^2 is a servo reaching 1e4 rad/s in a millisecond. Beyond them the
#: quadratic terms of the dynamics (speed**2 * inertia) and the constraint solve would
#: overflow to inf or NaN; such inputs are refused instead. Angles [rad] follow the
#: one rule of the kinematics (ANGLE_LIMIT).
LIMITS: dict[str, float] = {
    "[rad/s]": 1e4,
    "[N m]": 1e4,
    "[rad/s^2]": 1e7,
    "[rad]": ANGLE_LIMIT,
}


def _bounded(array: FloatArray, name: str, value: Any, unit: str) -> None:
    """InputError for NaN, inf or a value beyond LIMITS[unit] (finite only if no limit)."""
    limit = LIMITS.get(unit)
    if limit is None:
        require_finite(array, name, value, unit)
    else:
        require_bounded(array, name, value, limit, unit)


def _values(value: Any, name: str, unit: str) -> FloatArray:
    """Numbers of any shape, finite and within LIMITS[unit], or InputError."""
    if isinstance(value, (str, bytes)):
        raise InputError(
            f"{name} must be numbers {unit}, got {value!r}", argument=name, value=value
        )
    array = float_array(value, name, f"{name} must be numbers {unit}, got {value!r}")
    _bounded(array, name, value, unit)
    return array


def _broadcast(*arrays: FloatArray, names: str) -> None:
    try:
        np.broadcast_shapes(*(a.shape for a in arrays))
    except ValueError as exc:
        raise InputError(
            f"{names} must have shapes that broadcast, got {[a.shape for a in arrays]}",
            argument=names.split(",")[0],
            value=None,
        ) from exc


def _vector(value: Any, size: int, name: str, unit: str) -> FloatArray:
    """A finite float vector of shape (size,) (a scalar broadcasts), or InputError."""
    array = float_array(value, name, f"{name} must be {size} numbers {unit}, got {value!r}")
    if array.ndim == 0:
        array = np.full(size, float(array))
    if array.shape != (size,):
        raise InputError(
            f"{name} must have shape ({size},) {unit}, got shape {array.shape}",
            argument=name,
            value=value,
        )
    _bounded(array, name, value, unit)
    return array


def _array3(value: Any, name: str, unit: str) -> FloatArray:
    """A finite float array of shape (3,) or (N, 3), or InputError (no broadcasting)."""
    array = float_array(
        value, name, f"{name} must be numbers of shape (3,) or (N, 3) {unit}, got {value!r}"
    )
    if array.ndim not in (1, 2) or array.shape[-1] != 3 or array.shape[0] == 0:
        raise InputError(
            f"{name} must have shape (3,) or (N, 3) {unit} (one value per input "
            f"u_1, u_2, u_3), got shape {array.shape}",
            argument=name,
            value=value,
        )
    _bounded(array, name, value, unit)
    return array


def _positive(value: Any, name: str, unit: str, *, allow_zero: bool = False) -> float:
    """A finite number > 0 (or >= 0), or InputError."""
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    try:
        number = float(value) if ok else math.nan
    except OverflowError:  # an int too large for a float
        number = math.nan
    if not (math.isfinite(number) and (number >= 0.0 if allow_zero else number > 0.0)):
        relation = ">= 0" if allow_zero else "> 0"
        raise InputError(
            f"{name} must be a finite number {relation} {unit}, got {value!r}",
            argument=name,
            value=value,
        )
    return number


def _nonnegative_vector(value: Any, size: int, name: str, unit: str) -> FloatArray:
    array = _vector(value, size, name, unit)
    if np.any(array < 0.0):
        raise InputError(
            f"{name} must be >= 0 {unit}, got {array.tolist()}", argument=name, value=value
        )
    return array


# ----------------------------------------------------------------------- friction
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
        object.__setattr__(self, "viscous", _nonnegative_vector(self.viscous, 9, "viscous", unit))
        object.__setattr__(
            self, "coulomb", _nonnegative_vector(self.coulomb, 9, "coulomb", "[N m]")
        )
        object.__setattr__(
            self,
            "smoothing_speed",
            _positive(self.smoothing_speed, "smoothing_speed", "[rad/s]"),
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
        v = _positive(viscous, "viscous", "[N m s/rad]", allow_zero=True)
        c = _positive(coulomb, "coulomb", "[N m]", allow_zero=True)
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
    no_load_speed: float = 53.0 * _RPM
    kp: float = 20.0
    kd: float = 0.5
    voltage: float = 12.0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str):
            raise InputError(f"name must be a string, got {self.name!r}", argument="name")
        object.__setattr__(
            self, "stall_torque", _positive(self.stall_torque, "stall_torque", "[N m]")
        )
        object.__setattr__(
            self, "no_load_speed", _positive(self.no_load_speed, "no_load_speed", "[rad/s]")
        )
        object.__setattr__(self, "kp", _positive(self.kp, "kp", "[N m/rad]", allow_zero=True))
        object.__setattr__(self, "kd", _positive(self.kd, "kd", "[N m s/rad]", allow_zero=True))
        object.__setattr__(self, "voltage", _positive(self.voltage, "voltage", "[V]"))

    @property
    def no_load_rpm(self) -> float:
        """No-load speed [rev/min]."""
        return self.no_load_speed / _RPM

    def with_gains(self, kp: float, kd: float) -> ServoModel:
        """The same servo with other position-loop gains [N m/rad], [N m s/rad]."""
        return dataclasses.replace(self, kp=kp, kd=kd)

    def torque_limits(self, speed: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(lower, upper) available torque [N m] at output speed(s) [rad/s]."""
        omega = _values(speed, "speed", "[rad/s]")
        stall = self.stall_torque
        slope = omega / self.no_load_speed
        upper: FloatArray = np.minimum(stall, stall * (1.0 - slope))
        lower: FloatArray = np.maximum(-stall, -stall * (1.0 + slope))
        return lower, upper

    def saturate(self, torque: npt.ArrayLike, speed: npt.ArrayLike) -> FloatArray:
        """Torques clipped to the envelope at the given speeds [N m]."""
        lower, upper = self.torque_limits(speed)
        tau = _values(torque, "torque", "[N m]")
        _broadcast(tau, lower, names="torque, speed")
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
        position = _values(theta, "theta", "[rad]")
        speed = _values(theta_dot, "theta_dot", "[rad/s]")
        target = _values(goal, "goal", "[rad]")
        _broadcast(position, speed, target, names="theta, theta_dot, goal")
        torque = self.kp * (target - position) - self.kd * speed
        if goal_velocity is not None:
            rate = _values(goal_velocity, "goal_velocity", "[rad/s]")
            _broadcast(torque, rate, names="goal_velocity, theta")
            torque = torque + self.kd * rate
        if feedforward is not None:
            extra = _values(feedforward, "feedforward", "[N m]")
            _broadcast(torque, extra, names="feedforward, theta")
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
        tau_in = _values(torque, "torque", "[N m]")
        omega = _values(speed, "speed", "[rad/s]")
        _broadcast(tau_in, omega, names="torque, speed")
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
    tau = np.atleast_2d(_array3(torque, "torque", "[N m]"))
    omega = np.atleast_2d(_array3(speed, "speed", "[rad/s]"))
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
    at = f"t = {when[sample]:.3f} s" if when is not None else f"sample {sample}"
    needs = f"{tau[sample, joint]:+.3g} N m at {omega[sample, joint] / _RPM:+.3g} rpm ({at})"
    if within:
        message = (
            f"OK: within the {servo.name} torque-speed envelope; peak load "
            f"{100.0 * worst:.1f}% (joint u_{joint + 1}: {needs})"
        )
    else:
        message = (
            f"EXCEEDS the {servo.name} torque-speed envelope: joint u_{joint + 1} needs "
            f"{needs}, {100.0 * worst:.0f}% of what the servo can give (stall "
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
    )


# --------------------------------------------------------------------- trajectory
@dataclasses.dataclass(frozen=True)
class Trajectory:
    """A motion of the three inputs: theta(t), theta_dot(t), theta_ddot(t).

    Build one with :meth:`minimum_jerk`, :meth:`from_samples` or :meth:`load`.

    Attributes:
        time: Sample times [s], (N,), strictly increasing, N >= 2.
        theta: Input angles [rad], (N, 3).
        theta_dot: Input speeds [rad/s], (N, 3).
        theta_ddot: Input accelerations [rad/s^2], (N, 3).
    """

    time: FloatArray
    theta: FloatArray
    theta_dot: FloatArray
    theta_ddot: FloatArray

    def __post_init__(self) -> None:
        time = np.array(self.time, dtype=float).reshape(-1)
        if time.shape[0] < 2 or not np.all(np.isfinite(time)) or np.any(np.diff(time) <= 0.0):
            raise InputError(
                "time must hold at least 2 finite, strictly increasing sample times [s]",
                argument="time",
                value=self.time,
            )
        object.__setattr__(self, "time", time)
        n = time.shape[0]
        for name, unit in (
            ("theta", "[rad]"),
            ("theta_dot", "[rad/s]"),
            ("theta_ddot", "[rad/s^2]"),
        ):
            array = _array3(getattr(self, name), name, unit)
            if array.shape != (n, 3):
                raise InputError(
                    f"{name} must have shape ({n}, 3) (one row per sample time), got {array.shape}",
                    argument=name,
                    value=getattr(self, name),
                )
            object.__setattr__(self, name, array)

    @classmethod
    def minimum_jerk(
        cls,
        start: npt.ArrayLike,
        goal: npt.ArrayLike,
        duration: float,
        rate: float = 1000.0,
    ) -> Trajectory:
        """Rest-to-rest minimum-jerk motion (quintic) from ``start`` to ``goal``.

        theta(t) = start + (goal - start) s(t / T), s(x) = 10 x^3 - 15 x^4 + 6 x^5, with
        exact derivatives; speed, acceleration are zero at both ends.

        Args:
            start: Input angles at t = 0 [rad], (3,).
            goal: Input angles at t = duration [rad], (3,).
            duration: T [s], > 0.
            rate: Samples per second [Hz], > 0 (at least 2 samples are made).
        """
        begin = _vector(start, 3, "start", "[rad]")
        end = _vector(goal, 3, "goal", "[rad]")
        total = _positive(duration, "duration", "[s]")
        hz = _positive(rate, "rate", "[Hz]")
        count = max(2, math.ceil(total * hz) + 1)
        t = np.linspace(0.0, total, count)
        x = t / total
        s = x**3 * (10.0 + x * (-15.0 + 6.0 * x))
        ds = x**2 * (30.0 + x * (-60.0 + 30.0 * x)) / total
        dds = x * (60.0 + x * (-180.0 + 120.0 * x)) / total**2
        span = end - begin
        theta = begin + s[:, None] * span
        theta[-1] = end  # exactly, not begin + (end - begin)
        return cls(
            time=t,
            theta=theta,
            theta_dot=ds[:, None] * span,
            theta_ddot=dds[:, None] * span,
        )

    @classmethod
    def from_samples(cls, time: npt.ArrayLike, theta: npt.ArrayLike) -> Trajectory:
        """A trajectory from sampled angles; speeds and accelerations by finite differences.

        Second-order central differences (one-sided at the ends), on any strictly
        increasing time grid: errors scale with the square of the sample spacing, so
        sample smooth motions densely (1 kHz is plenty).

        Args:
            time: Sample times [s], (N,), N >= 3.
            theta: Input angles [rad], (N, 3).
        """
        t = np.array(time, dtype=float).reshape(-1)
        angles = _array3(theta, "theta", "[rad]")
        if t.shape[0] < 3 or angles.shape != (t.shape[0], 3):
            raise InputError(
                f"from_samples needs N >= 3 times and theta of shape (N, 3), got "
                f"{t.shape[0]} times and theta of shape {angles.shape}",
                argument="theta",
                value=theta,
            )
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
            raise InputError(
                "time must be finite and strictly increasing [s]", argument="time", value=time
            )
        speed = np.gradient(angles, t, axis=0, edge_order=2)
        acceleration = np.gradient(speed, t, axis=0, edge_order=2)
        return cls(time=t, theta=angles, theta_dot=speed, theta_ddot=acceleration)

    @classmethod
    def load(cls, path: str | Path) -> Trajectory:
        """Read a CSV trajectory: a header, then one sample per line.

        Columns: time, then the three input angles, named with their unit:
        ``time_s,theta_1_deg,theta_2_deg,theta_3_deg`` (or ``..._rad``). Speeds and
        accelerations come from :meth:`from_samples`.

        Raises:
            FileFormatError: missing file, bad header, a line without 4 numbers,
                non-increasing times (the message names the line).
        """
        file = Path(path)
        try:
            text = file.read_text(encoding="utf-8")
        except OSError as exc:
            raise FileFormatError(f"cannot read the trajectory: {exc}", path=str(file)) from exc
        rows = list(csv.reader(text.splitlines()))
        lines = [(number, row) for number, row in enumerate(rows, start=1) if any(row)]
        if not lines:
            raise FileFormatError("the trajectory file is empty", path=str(file))
        head_line, header = lines[0]
        names = [cell.strip().lower() for cell in header]
        units = {name.rsplit("_", 1)[-1] for name in names[1:]}
        if (
            len(names) != 4
            or names[0] not in ("time_s", "t_s")
            or len(units) != 1
            or units - {"deg", "rad"}
        ):
            raise FileFormatError(
                "the header must be 'time_s,theta_1_deg,theta_2_deg,theta_3_deg' "
                f"(or _rad), got {','.join(header)!r}",
                path=str(file),
                line=head_line,
            )
        scale = math.pi / 180.0 if units == {"deg"} else 1.0
        values: list[list[float]] = []
        for number, row in lines[1:]:
            try:
                numbers = [float(cell) for cell in row]
            except ValueError:
                numbers = []
            if len(numbers) != 4 or not all(math.isfinite(x) for x in numbers):
                raise FileFormatError(
                    f"expected 4 finite numbers (time, three angles), got {','.join(row)!r}",
                    path=str(file),
                    line=number,
                )
            if values and numbers[0] <= values[-1][0]:
                raise FileFormatError(
                    f"times must increase: {numbers[0]:g} s after {values[-1][0]:g} s",
                    path=str(file),
                    line=number,
                )
            values.append(numbers)
        if len(values) < 3:
            raise FileFormatError(
                f"a trajectory needs at least 3 samples, got {len(values)}", path=str(file)
            )
        data = np.array(values)
        return cls.from_samples(data[:, 0], data[:, 1:] * scale)

    def save(self, path: str | Path, *, degrees: bool = True) -> Path:
        """Write the time and angles as CSV (see :meth:`load`); returns the path."""
        file = Path(path)
        unit = "deg" if degrees else "rad"
        angles = np.degrees(self.theta) if degrees else self.theta
        lines = [f"time_s,theta_1_{unit},theta_2_{unit},theta_3_{unit}"]
        lines += [
            ",".join(repr(float(x)) for x in (t, *row))
            for t, row in zip(self.time, angles, strict=True)
        ]
        file.write_text("\n".join(lines) + "\n", encoding="utf-8")
        return file

    @property
    def duration(self) -> float:
        """Last time minus first time [s]."""
        return float(self.time[-1] - self.time[0])

    def sample(self, t: float) -> tuple[FloatArray, FloatArray]:
        """(theta, theta_dot) at time t [s] by linear interpolation; held beyond the ends."""
        time = self.time
        if t <= time[0]:
            return self.theta[0].copy(), self.theta_dot[0].copy()
        if t >= time[-1]:
            return self.theta[-1].copy(), self.theta_dot[-1].copy()
        k = int(np.searchsorted(time, t, side="right")) - 1
        w = (t - time[k]) / (time[k + 1] - time[k])
        theta, speed = self.theta, self.theta_dot
        return theta[k] + w * (theta[k + 1] - theta[k]), speed[k] + w * (speed[k + 1] - speed[k])


@dataclasses.dataclass(frozen=True)
class ServoController:
    """Servos that follow a goal: a fixed goal (3,) or a :class:`Trajectory`.

    Call it as ``controller(t, theta, theta_dot)`` to get the servo torques [N m];
    :class:`Simulator` and :func:`simulate_mujoco` do so once per step.

    Attributes:
        servo: The servo model (gains and torque-speed envelope).
        goal: Goal angles [rad] (3,), or a trajectory (positions and speeds).
        feedforward: Optional torques [N m] added before clipping: (3,), or (N, 3) at
            the trajectory's sample times (interpolated), e.g. from
            :func:`inverse_dynamics`.
    """

    servo: ServoModel
    goal: Trajectory | FloatArray
    feedforward: FloatArray | None = None
    _constants: tuple[float, float, float, float] = dataclasses.field(
        init=False, repr=False, compare=False, default=(0.0, 0.0, 0.0, 0.0)
    )
    _table: Any = dataclasses.field(init=False, repr=False, compare=False, default=None)
    _goal_rows: Any = dataclasses.field(init=False, repr=False, compare=False, default=None)

    def __post_init__(self) -> None:
        if not isinstance(self.servo, ServoModel):
            raise InputError(
                f"servo must be a ServoModel, got {type(self.servo).__name__}",
                argument="servo",
                value=self.servo,
            )
        if not isinstance(self.goal, Trajectory):
            object.__setattr__(self, "goal", _vector(self.goal, 3, "goal", "[rad]"))
        if self.feedforward is not None:
            ff = _array3(self.feedforward, "feedforward", "[N m]")
            if ff.ndim == 2:
                n = self.goal.time.shape[0] if isinstance(self.goal, Trajectory) else -1
                if ff.shape[0] != n:
                    raise InputError(
                        "a feedforward of shape (N, 3) needs a trajectory goal with N "
                        f"samples, got {ff.shape[0]} rows",
                        argument="feedforward",
                        value=self.feedforward,
                    )
            object.__setattr__(self, "feedforward", ff)
        # Plain-float tables for __call__ (not dataclass fields).
        servo = self.servo
        object.__setattr__(
            self,
            "_constants",
            (servo.kp, servo.kd, servo.stall_torque, 1.0 / servo.no_load_speed),
        )
        ff_now = self.feedforward
        goal = self.goal
        if isinstance(goal, Trajectory):
            n = goal.time.shape[0]
            if ff_now is None:
                ff_rows = np.zeros((n, 3))
            elif ff_now.ndim == 1:
                ff_rows = np.broadcast_to(ff_now, (n, 3))
            else:
                ff_rows = ff_now
            table = (
                goal.time.tolist(),
                goal.theta.tolist(),
                goal.theta_dot.tolist(),
                np.asarray(ff_rows).tolist(),
                ff_now is not None and ff_now.ndim == 2,
            )
            object.__setattr__(self, "_table", table)
            object.__setattr__(self, "_goal_rows", None)
        else:
            ff_row = [0.0, 0.0, 0.0] if ff_now is None else ff_now.tolist()
            object.__setattr__(self, "_table", None)
            object.__setattr__(self, "_goal_rows", (goal.tolist(), [0.0, 0.0, 0.0], ff_row))

    def __call__(self, t: float, theta: FloatArray, theta_dot: FloatArray) -> FloatArray:
        """Servo torques [N m] at time t [s] and the present state (theta [rad],
        theta_dot [rad/s], (3,) each).

        The same as ``servo.command(theta, theta_dot, goal(t), goal_velocity(t),
        feedforward(t))``, written with plain floats: it runs once per simulated step.
        """
        table = self._table
        x = theta.tolist()
        xd = theta_dot.tolist()
        if table is None:
            g, gd, ff = self._goal_rows
        else:
            times = table[0]
            k = bisect.bisect_right(times, t) - 1
            angles, speeds, torques = table[1], table[2], table[3]
            if k < 0:
                g, gd, ff = angles[0], speeds[0], torques[0]
            elif k >= len(times) - 1:
                g, gd, ff = angles[-1], speeds[-1], torques[-1]
            else:
                w = (t - times[k]) / (times[k + 1] - times[k])
                a, b = angles[k], angles[k + 1]
                g = [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1]), a[2] + w * (b[2] - a[2])]
                a, b = speeds[k], speeds[k + 1]
                gd = [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1]), a[2] + w * (b[2] - a[2])]
                if table[4]:
                    a, b = torques[k], torques[k + 1]
                    ff = [
                        a[0] + w * (b[0] - a[0]),
                        a[1] + w * (b[1] - a[1]),
                        a[2] + w * (b[2] - a[2]),
                    ]
                else:
                    ff = _ZERO3
        kp, kd, stall, scale = self._constants
        out = [0.0, 0.0, 0.0]
        for i in range(3):
            torque = kp * (g[i] - x[i]) + kd * (gd[i] - xd[i]) + ff[i]
            slope = xd[i] * scale
            upper = stall * (1.0 - slope)
            lower = -stall * (1.0 + slope)
            upper = stall if upper > stall else upper
            lower = -stall if lower < -stall else lower
            torque = lower if torque < lower else torque  # as np.clip: upper wins
            out[i] = upper if torque > upper else torque
        return np.array(out)


# ----------------------------------------------------------------------- results
@dataclasses.dataclass(frozen=True)
class ForwardDynamicsResult:
    """Accelerations of the closed loop under given torques (one state).

    Attributes:
        theta_ddot: Input accelerations [rad/s^2], (3,).
        ddq: Joint accelerations [rad/s^2], (9,), q order.
        q: The closed configuration, (9,).
        v: Joint velocities [rad/s], (9,) (J v = 0).
        torque: Actuator torques applied [N m], (3,).
        friction_torque: Joint friction torques [N m], (9,).
        constraint_torque: Torque that legs 2 and 3 exert on the platform through
            their closures, world frame [N m], (2, 3). The forces at O are statically
            indeterminate (all axes meet there) and are not reported.
        method: ``"pinocchio"`` or ``"nullspace"``.
    """

    theta_ddot: FloatArray
    ddq: FloatArray
    q: FloatArray
    v: FloatArray
    torque: FloatArray
    friction_torque: FloatArray
    constraint_torque: FloatArray
    method: str


@dataclasses.dataclass(frozen=True)
class InverseDynamicsResult:
    """Actuator torques and closure torques that produce a motion.

    Arrays have a leading sample axis when the input was a path (N, 3), none for a
    single state (3,).

    Attributes:
        torque: Actuator torques [N m], (..., 3).
        constraint_torque: Torque that legs 2 and 3 exert on the platform through
            their closures, world frame [N m], (..., 2, 3).
        theta: Input angles [rad], (..., 3).
        theta_dot: Input speeds [rad/s], (..., 3).
        theta_ddot: Input accelerations [rad/s^2], (..., 3).
        q: Closed configurations, (..., 9).
        v: Joint velocities [rad/s], (..., 9).
        ddq: Joint accelerations [rad/s^2], (..., 9).
        friction_torque: Joint friction torques [N m], (..., 9) (already compensated
            in ``torque``).
        time: Sample times [s], (N,), when the input was a :class:`Trajectory`.
    """

    torque: FloatArray
    constraint_torque: FloatArray
    theta: FloatArray
    theta_dot: FloatArray
    theta_ddot: FloatArray
    q: FloatArray
    v: FloatArray
    ddq: FloatArray
    friction_torque: FloatArray
    time: FloatArray | None = None

    @property
    def power(self) -> FloatArray:
        """Mechanical power of each actuator, torque * theta_dot [W], (..., 3)."""
        result: FloatArray = self.torque * self.theta_dot
        return result


# --------------------------------------------------------------------- dynamics
class ClosedLoopDynamics:
    """Forward and inverse dynamics of the closed-loop SPM (see the module docstring).

    Holds a private copy of the robot's Pinocchio model (with the chosen gravity and
    armature), its data and the loop-closure workspace; one object per thread.

    Args:
        robot: The robot (default: ``build_robot()``, the prototype).
        gravity: Gravity vector in the world frame [m/s^2] (default :data:`GRAVITY`,
            upright; ``(0, 0, 9.81)`` is the robot hanging upside down).
        friction: Joint friction (default: none).
        armature: Reflected rotor inertia of each actuator [kg m^2], scalar or (3,),
            added to the input joints (the servos' gear trains; default 0).

    Raises:
        InputError: bad arguments; closures whose nonzero rows are not independent.

    Attributes:
        robot: The :class:`~spm_pin.SPMRobot`.
        model: The private ``pin.Model`` (gravity and armature set).
        loop: :class:`~spm_pin.closure.ClosedLoop` of ``model`` (position projection
            of single states and paths).
        gravity: (3,) [m/s^2].
        friction: :class:`JointFriction` or None.
        armature: (3,) [kg m^2].
        actuated_idx: Indices of the inputs in q and v, (3,).
        passive_idx: Indices of the passive joints, (6,).
        constraint_rows: Rows of the stacked weld residual that are used (the angular
            ones), (6,).
    """

    def __init__(
        self,
        robot: SPMRobot | None = None,
        *,
        gravity: npt.ArrayLike = GRAVITY,
        friction: JointFriction | None = None,
        armature: npt.ArrayLike = 0.0,
    ) -> None:
        if robot is None:
            robot = build_robot()
        if not isinstance(robot, SPMRobot):
            raise InputError(
                f"robot must be an SPMRobot (spm.build_robot()), got {type(robot).__name__}",
                argument="robot",
                value=robot,
            )
        if friction is not None and not isinstance(friction, JointFriction):
            raise InputError(
                f"friction must be a JointFriction or None, got {type(friction).__name__}",
                argument="friction",
                value=friction,
            )
        self.robot = robot
        self.gravity: FloatArray = _vector(gravity, 3, "gravity", "[m/s^2]")
        self.friction: JointFriction | None = friction
        self.armature: FloatArray = _nonnegative_vector(armature, 3, "armature", "[kg m^2]")
        self.actuated_idx: IntArray = np.array(robot.actuated_q_idx, dtype=np.int64)
        self.passive_idx: IntArray = np.array(robot.passive_q_idx, dtype=np.int64)

        model = pin.Model(robot.model)
        model.gravity = pin.Motion(np.concatenate([self.gravity, np.zeros(3)]))
        armature_full = np.zeros(model.nv)
        armature_full[self.actuated_idx] = self.armature
        model.armature = armature_full
        self.model: pin.Model = model
        self._data: pin.Data = model.createData()
        self.loop = ClosedLoop(model, robot.constraint_models, robot.actuated_joints)

        # New-style welds: residuals, Jacobians, acceleration bias.
        self._cms = pin.StdVec_ConstraintModel()
        self._cds = pin.StdVec_ConstraintData()
        for constraint in robot.constraint_models:
            self._cms.append(constraint)
            self._cds.append(constraint.createData())
        bare = [(c.extract(), d.extract()) for c, d in zip(self._cms, self._cds, strict=True)]
        self._bare = bare  # keeps the references alive
        self._calcs = [(c.calc, d) for c, d in bare]
        self._position_errors = [d.constraint_position_error for _, d in bare]
        self._acceleration_errors = [d.constraint_acceleration_error for _, d in bare]
        self._weld_rows = [int(e.shape[0]) for e in self._position_errors]
        # Legacy welds for pin.constraintDynamics (Baumgarte gains zero).
        self._rigid = robot.rigid_constraint_models()
        for rigid in self._rigid:
            rigid.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(0.0, 0.0))
        self._rigid_datas = pin.StdVec_RigidConstraintData(
            [rigid.createData() for rigid in self._rigid]
        )
        pin.initConstraintDynamics(model, self._data, self._rigid, self._rigid_datas)
        self._prox = pin.ProximalSettings(PROXIMAL_ACCURACY, PROXIMAL_MU, PROXIMAL_MAX_ITERATIONS)

        self.constraint_rows: IntArray = self._select_rows()
        n_rows = self.constraint_rows.shape[0]
        n_passive = self.passive_idx.shape[0]
        if n_rows != n_passive:
            raise InputError(
                f"the closures have {n_rows} independent rows but {n_passive} passive "
                "joints: the dynamics needs the passive joints to be determined by the inputs",
                argument="robot",
                value=robot,
            )
        perm = np.concatenate([self.passive_idx, self.actuated_idx])
        # Flat indices into the (m, nv) constraint Jacobian: selected rows, passive
        # columns first, then actuated ones.
        self._flat: IntArray = (self.constraint_rows[:, None] * model.nv + perm[None, :]).astype(
            np.int64
        )
        self._lu = eigenpy.PartialPivLU(np.eye(n_passive))
        self._lu_t = eigenpy.PartialPivLU(np.eye(n_passive))  # of J_p^T
        self._J = np.zeros((n_rows, model.nv))
        self._zero_v = np.zeros(model.nv)

    def __repr__(self) -> str:
        return (
            f"ClosedLoopDynamics(design={self.robot.design.name!r}, gravity="
            f"{self.gravity.tolist()}, armature={self.armature.tolist()}, friction="
            f"{'yes' if self.friction is not None else 'none'})"
        )

    # -------------------------------------------------------------- internals
    def _select_rows(self) -> IntArray:
        """The weld rows that are not identically zero (checked on random configurations).

        Also sets ``_dropped_rows_vanish``: the other rows, residual and Jacobian, were
        exactly zero on every configuration tried (all axes through O: the linear rows
        of a weld at O), so the residual of the used rows is the whole residual.
        """
        rng = np.random.default_rng(7)
        model = self.model
        m = sum(self._weld_rows)
        size = np.zeros(m)
        residual = np.zeros(m)
        for _ in range(4):
            q = pin.integrate(model, pin.neutral(model), rng.uniform(-np.pi, np.pi, model.nv))
            pin.computeJointJacobians(model, self._data, q)
            for calc, data in self._calcs:
                calc(model, self._data, data)
            J = pin.getConstraintsJacobian(model, self._data, self._cms, self._cds)
            size = np.maximum(size, np.abs(J).max(axis=1))
            residual = np.maximum(residual, np.abs(np.concatenate(self._position_errors)))
        rows = np.flatnonzero(size > 1e-12).astype(np.int64)
        dropped = np.setdiff1d(np.arange(m), rows)
        self._dropped_rows_vanish = bool(
            np.all(size[dropped] == 0.0) and np.all(residual[dropped] == 0.0)
        )
        return rows

    def _kinematics(self, q: FloatArray) -> float:
        """Joint Jacobians, weld residuals and the LU of J_p at q; returns ||e||^2."""
        model, data = self.model, self._data
        pin.computeJointJacobians(model, data, q)
        r2 = 0.0
        for (calc, cdata), error in zip(self._calcs, self._position_errors, strict=True):
            calc(model, data, cdata)
            r2 += float(error.dot(error))
        J = pin.getConstraintsJacobian(model, data, self._cms, self._cds).take(self._flat)
        self._J = J
        self._lu.compute(J[:, : self.passive_idx.shape[0]])
        return r2

    def _passive_velocity(self, theta_dot: FloatArray) -> FloatArray:
        """v_p = G theta_dot at the configuration of the last _kinematics call."""
        n_p = self.passive_idx.shape[0]
        result: FloatArray = -self._lu.solve(self._J[:, n_p:].dot(theta_dot))
        return result

    def _velocity(self, theta_dot: FloatArray) -> FloatArray:
        v = np.empty(self.model.nv)
        v.put(self.actuated_idx, theta_dot)
        v.put(self.passive_idx, self._passive_velocity(theta_dot))
        return v

    def _velocity_map(self) -> FloatArray:
        n_p = self.passive_idx.shape[0]
        G: FloatArray = -self._lu.solve(self._J[:, n_p:])
        return G

    def _singular(self) -> bool:
        return bool(self._lu.rcond() < SINGULAR_RCOND)

    def _raise_singular(self, q: FloatArray, when: str = "") -> NoReturn:
        raise SingularityError(
            f"parallel (type II) singularity{when}: the passive joints no longer follow "
            f"the inputs (rcond of the passive constraint Jacobian {self._lu.rcond():.2g} < "
            f"{SINGULAR_RCOND:g}) at theta = {np.degrees(q[self.actuated_idx]).round(4).tolist()}"
            " deg",
            kind="type II",
            value=q.copy(),
        )

    def _project(self, q: FloatArray) -> None:
        """Close the loops at q (in place, theta held) with the generic solver.

        :meth:`ClosedLoop.project` (damped Newton with line search, rank revealing):
        the fallback of the simulator's lean Newton steps.

        Raises:
            ConvergenceError: no closed configuration near q.
        """
        theta = q[self.actuated_idx].copy()
        try:
            result = self.loop.project(theta, q, tol=CLOSURE_TOL, continuation=False)
        except ConvergenceError as exc:
            raise ConvergenceError(
                f"the loops cannot be closed at theta = {np.degrees(theta).round(4).tolist()} "
                f"deg: {exc}",
                data={"q": q.copy(), **exc.data},
            ) from exc
        q[:] = result.q

    def _gamma(self, q: FloatArray, v: FloatArray) -> FloatArray:
        """Constraint acceleration at zero joint acceleration (selected rows)."""
        model, data = self.model, self._data
        pin.forwardKinematics(model, data, q, v, self._zero_v)
        for calc, cdata in self._calcs:
            calc(model, data, cdata)
        gamma: FloatArray = np.concatenate(self._acceleration_errors).take(self.constraint_rows)
        return gamma

    def _friction(self, v: FloatArray) -> FloatArray:
        if self.friction is None:
            return np.zeros(self.model.nv)
        return self.friction.torque(v)

    def _state(self, state: Any) -> FloatArray:
        """A closed configuration (9,) from theta (3,) or q (9,)."""
        array = float_array(
            state,
            "state",
            f"state must be input angles theta (3,) [rad] or a closed configuration "
            f"q (9,), got {state!r}",
        )
        if array.shape == (3,):
            require_angles(array, "theta", state)
            q: FloatArray = self.robot.configuration(array)
            return q
        if array.shape != (self.model.nq,):
            raise InputError(
                f"state must be theta (3,) [rad] or a closed configuration q (9,), got "
                f"shape {array.shape}",
                argument="state",
                value=state,
            )
        require_angles(array, "q", state)
        residual = math.sqrt(self._kinematics(array))
        if residual > CLOSED_TOL:
            raise InputError(
                f"q does not close the loops: residual {residual:.3g} > {CLOSED_TOL:g} rad; "
                "start from theta, robot.configuration(theta) or dynamics.loop.project",
                argument="q",
                value=state,
            )
        return array

    def _evaluate(self, q: FloatArray) -> None:
        """Kinematics at a closed q, with the type II check."""
        self._kinematics(q)
        if self._singular():
            self._raise_singular(q)

    def _split(self, tau_tree: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Actuator torques and weld torques from tau_tree = M qdd + h - tau_f.

        The passive rows give the multipliers, J_p^T lambda_s = tau_tree,p; the actuated
        rows the actuator torques, tau = tau_tree,a - J_a^T lambda_s. Each weld's angular
        multiplier, in the frame of its first body (the leg end), is rotated to the world:
        the torque leg k exerts on the platform. Needs the kinematics at q.
        """
        n_p = self.passive_idx.shape[0]
        Jp, Ja = self._J[:, :n_p], self._J[:, n_p:]
        self._lu_t.compute(Jp.T)
        lam = self._lu_t.solve(tau_tree[self.passive_idx])
        torque: FloatArray = tau_tree[self.actuated_idx] - Ja.T @ lam
        full = np.zeros(sum(self._weld_rows))
        full[self.constraint_rows] = lam
        welds = np.zeros((len(self._weld_rows), 3))
        start = 0
        for k, ((_, cdata), rows) in enumerate(zip(self._bare, self._weld_rows, strict=True)):
            if rows == 6:  # a weld: [linear; angular]
                welds[k] = np.asarray(cdata.oMc1.rotation) @ full[start + 3 : start + 6]
            start += rows
        return torque, welds

    # -------------------------------------------------------------- public
    def configuration(self, state: npt.ArrayLike) -> FloatArray:
        """The closed configuration q (9,) of input angles theta (3,) [rad] (home
        assembly mode) or of a q (9,) that closes the loops (checked, copied)."""
        result: FloatArray = self._state(state).copy()
        return result

    def velocity(self, state: npt.ArrayLike, theta_dot: npt.ArrayLike) -> FloatArray:
        """Joint velocities v (9,) [rad/s] that keep the loops closed: v = S theta_dot.

        Raises:
            SingularityError: a parallel (type II) singularity at the state.
        """
        q = self._state(state)
        rate = _vector(theta_dot, 3, "theta_dot", "[rad/s]")
        self._evaluate(q)
        return self._velocity(rate)

    def velocity_map(self, state: npt.ArrayLike) -> FloatArray:
        """S (9, 3): joint velocities per unit input speed, rows in q order."""
        q = self._state(state)
        self._evaluate(q)
        S = np.zeros((self.model.nv, 3))
        S[self.actuated_idx] = np.eye(3)
        S[self.passive_idx] = self._velocity_map()
        return S

    def mass_matrix(self, state: npt.ArrayLike) -> FloatArray:
        """Reduced mass matrix M_r = S^T M S (3, 3) [kg m^2] (armature included)."""
        q = self._state(state)
        S = self.velocity_map(q)
        M = pin.crba(self.model, self._data, q, pin.Convention.WORLD)
        result: FloatArray = S.T @ M @ S
        return result

    def energy(self, state: npt.ArrayLike, theta_dot: npt.ArrayLike) -> tuple[float, float]:
        """(kinetic, potential) energy [J]; potential is -sum m g . c (zero with every
        centre of mass at O)."""
        q = self._state(state)
        v = self.velocity(q, theta_dot)
        return self._energy(q, v)

    def _energy(self, q: FloatArray, v: FloatArray) -> tuple[float, float]:
        model, data = self.model, self._data
        rate = v[self.actuated_idx]
        kinetic = float(pin.computeKineticEnergy(model, data, q, v)) + 0.5 * float(
            np.dot(self.armature, rate * rate)
        )
        potential = float(pin.computePotentialEnergy(model, data, q))
        return kinetic, potential

    def holding_torques(self, state: npt.ArrayLike) -> FloatArray:
        """Actuator torques that hold the robot still against gravity [N m], (3,).

        tau = S^T g(q), g the generalised gravity of the tree: the torques the servos
        must apply so that the robot stays at rest (minus the gradient of the potential
        energy along the closed mechanism).
        """
        q = self._state(state)
        S = self.velocity_map(q)
        g = pin.computeGeneralizedGravity(self.model, self._data, q)
        result: FloatArray = S.T @ g
        return result

    def forward(
        self,
        state: npt.ArrayLike,
        theta_dot: npt.ArrayLike,
        torque: npt.ArrayLike | None = None,
        *,
        method: str = "pinocchio",
    ) -> ForwardDynamicsResult:
        """Accelerations of the closed loop under actuator torques, gravity and friction.

        Args:
            state: Input angles theta (3,) [rad] (home assembly mode) or a closed q (9,).
            theta_dot: Input speeds [rad/s], (3,).
            torque: Actuator torques [N m], (3,) (default 0).
            method: ``"pinocchio"`` (``pin.constraintDynamics``, proximal) or
                ``"nullspace"`` (the reduced equations); see the module docstring.

        Returns:
            :class:`ForwardDynamicsResult`.

        Raises:
            InputError: bad shapes, NaN or inf, unknown method, a q that does not close.
            SingularityError: a parallel (type II) singularity at the state.
        """
        if method not in ("pinocchio", "nullspace"):
            raise InputError(
                f"method must be 'pinocchio' or 'nullspace', got {method!r}",
                argument="method",
                value=method,
            )
        q = self._state(state)
        rate = _vector(theta_dot, 3, "theta_dot", "[rad/s]")
        tau3 = np.zeros(3) if torque is None else _vector(torque, 3, "torque", "[N m]")
        self._evaluate(q)
        v = self._velocity(rate)
        friction = self._friction(v)
        tau = friction.copy()
        tau[self.actuated_idx] += tau3
        model, data = self.model, self._data
        if method == "pinocchio":
            ddq = np.array(
                pin.constraintDynamics(
                    model, data, q, v, tau, self._rigid, self._rigid_datas, self._prox
                )
            )
        else:
            ddq = self._nullspace_acceleration(q, v, tau)
        # the kinematics workspace still holds q (neither call above changes it)
        _, welds = self._split(np.array(pin.rnea(model, data, q, v, ddq)) - friction)
        return ForwardDynamicsResult(
            theta_ddot=ddq[self.actuated_idx].copy(),
            ddq=ddq,
            q=q.copy(),
            v=v,
            torque=tau3,
            friction_torque=friction,
            constraint_torque=welds,
            method=method,
        )

    def _nullspace_acceleration(self, q: FloatArray, v: FloatArray, tau: FloatArray) -> FloatArray:
        """qdd from M_r theta_ddot = S^T (tau - b); kinematics at q required."""
        model, data = self.model, self._data
        G = self._velocity_map()
        S = np.zeros((model.nv, 3))
        S[self.actuated_idx] = np.eye(3)
        S[self.passive_idx] = G
        bias = np.zeros(model.nv)
        bias[self.passive_idx] = -self._lu.solve(self._gamma(q, v))
        b = np.array(pin.rnea(model, data, q, v, bias))
        M = np.array(pin.crba(model, data, q, pin.Convention.WORLD))
        theta_ddot = np.linalg.solve(S.T @ M @ S, S.T @ (tau - b))
        result: FloatArray = S @ theta_ddot + bias
        return result

    def inverse(
        self,
        theta: npt.ArrayLike,
        theta_dot: npt.ArrayLike,
        theta_ddot: npt.ArrayLike,
        *,
        start: npt.ArrayLike | None = None,
    ) -> InverseDynamicsResult:
        """Actuator torques and closure torques for a motion (closed-loop inverse dynamics).

        Args:
            theta: Input angles [rad], (3,) or a path (N, 3) (consecutive samples of a
                continuous motion: the closed configurations are followed by
                continuation, so the assembly mode never jumps).
            theta_dot: Input speeds [rad/s], the same shape.
            theta_ddot: Input accelerations [rad/s^2], the same shape.
            start: Closed configuration q (9,) of the first sample (default: the home
                assembly mode at theta[0]).

        Returns:
            :class:`InverseDynamicsResult` (arrays (3,) or (N, 3), ...).

        Raises:
            InputError: bad shapes, NaN or inf.
            UnreachableError, ConvergenceError: no closed configuration along the path.
            SingularityError: a parallel (type II) singularity on the path.
        """
        angles = _array3(theta, "theta", "[rad]")
        speed = _array3(theta_dot, "theta_dot", "[rad/s]")
        acceleration = _array3(theta_ddot, "theta_ddot", "[rad/s^2]")
        for name, array in (("theta_dot", speed), ("theta_ddot", acceleration)):
            if array.shape != angles.shape:
                raise InputError(
                    f"{name} must have the shape of theta {angles.shape}, got {array.shape}",
                    argument=name,
                    value=array,
                )
        single = angles.ndim == 1
        path = angles[None] if single else angles
        if start is None:
            first = self.robot.configuration(path[0])
        else:
            first = self._state(start)
            if not np.allclose(first[self.actuated_idx], path[0], atol=1e-9, rtol=0.0):
                raise InputError(
                    "start must be a closed configuration at theta[0]",
                    argument="start",
                    value=start,
                )
        configurations = first[None] if path.shape[0] == 1 else self.loop.follow(path, first).q
        n = path.shape[0]
        torque = np.zeros((n, 3))
        welds = np.zeros((n, len(self._weld_rows), 3))
        v_all = np.zeros((n, self.model.nv))
        ddq_all = np.zeros((n, self.model.nv))
        friction_all = np.zeros((n, self.model.nv))
        rates = np.atleast_2d(speed)
        accelerations = np.atleast_2d(acceleration)
        for k in range(n):
            (
                torque[k],
                welds[k],
                v_all[k],
                ddq_all[k],
                friction_all[k],
            ) = self._inverse_one(configurations[k], rates[k], accelerations[k])
        if single:
            return InverseDynamicsResult(
                torque=torque[0],
                constraint_torque=welds[0],
                theta=angles.copy(),
                theta_dot=speed.copy(),
                theta_ddot=acceleration.copy(),
                q=configurations[0].copy(),
                v=v_all[0],
                ddq=ddq_all[0],
                friction_torque=friction_all[0],
            )
        return InverseDynamicsResult(
            torque=torque,
            constraint_torque=welds,
            theta=angles.copy(),
            theta_dot=speed.copy(),
            theta_ddot=acceleration.copy(),
            q=np.array(configurations),
            v=v_all,
            ddq=ddq_all,
            friction_torque=friction_all,
        )

    def _inverse_one(
        self, q: FloatArray, theta_dot: FloatArray, theta_ddot: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        model, data = self.model, self._data
        self._evaluate(q)
        v = self._velocity(theta_dot)
        n_p = self.passive_idx.shape[0]
        J_a_theta_ddot = self._J[:, n_p:].dot(theta_ddot)
        gamma = self._gamma(q, v)
        ddq = np.empty(model.nv)
        ddq[self.actuated_idx] = theta_ddot
        ddq[self.passive_idx] = -self._lu.solve(J_a_theta_ddot + gamma)
        friction = self._friction(v)
        torque, welds = self._split(np.array(pin.rnea(model, data, q, v, ddq)) - friction)
        return torque, welds, v, ddq, friction


def _dynamics(dynamics: ClosedLoopDynamics | SPMRobot | None) -> ClosedLoopDynamics:
    if isinstance(dynamics, ClosedLoopDynamics):
        return dynamics
    if dynamics is None or isinstance(dynamics, SPMRobot):
        return ClosedLoopDynamics(dynamics)
    raise InputError(
        "expected a ClosedLoopDynamics or an SPMRobot, got " + type(dynamics).__name__,
        argument="dynamics",
        value=dynamics,
    )


def forward_dynamics(
    dynamics: ClosedLoopDynamics | SPMRobot | None,
    state: npt.ArrayLike,
    theta_dot: npt.ArrayLike,
    torque: npt.ArrayLike | None = None,
    *,
    method: str = "pinocchio",
) -> ForwardDynamicsResult:
    """Input accelerations under actuator torques (see :meth:`ClosedLoopDynamics.forward`).

    Args:
        dynamics: A :class:`ClosedLoopDynamics` (gravity, friction, armature), or an
            SPMRobot / None for the defaults (upright, frictionless).
        state: theta (3,) [rad] or a closed q (9,).
        theta_dot: Input speeds [rad/s], (3,).
        torque: Actuator torques [N m], (3,) (default 0).
        method: ``"pinocchio"`` or ``"nullspace"``.

    Example:
        >>> import numpy as np, spm_pin as spm
        >>> result = spm.forward_dynamics(None, np.zeros(3), np.zeros(3), [0.1, 0, 0])
        >>> result.theta_ddot.shape
        (3,)
    """
    return _dynamics(dynamics).forward(state, theta_dot, torque, method=method)


def inverse_dynamics(
    dynamics: ClosedLoopDynamics | SPMRobot | None,
    motion: Trajectory | npt.ArrayLike,
    theta_dot: npt.ArrayLike | None = None,
    theta_ddot: npt.ArrayLike | None = None,
) -> InverseDynamicsResult:
    """Actuator torques and closure torques for a motion.

    Args:
        dynamics: A :class:`ClosedLoopDynamics`, or an SPMRobot / None (defaults).
        motion: A :class:`Trajectory`, or input angles theta [rad] (3,) or (N, 3)
            with ``theta_dot`` and ``theta_ddot`` of the same shape.
        theta_dot: Input speeds [rad/s] (with theta).
        theta_ddot: Input accelerations [rad/s^2] (with theta).

    Returns:
        :class:`InverseDynamicsResult` (with ``time`` for a trajectory).

    Example:
        >>> import spm_pin as spm
        >>> motion = spm.Trajectory.minimum_jerk([0, 0, 0], [0.5, 0.2, -0.3], 1.0, 100)
        >>> spm.inverse_dynamics(None, motion).torque.shape
        (101, 3)
    """
    model = _dynamics(dynamics)
    if isinstance(motion, Trajectory):
        if theta_dot is not None or theta_ddot is not None:
            raise InputError(
                "give either a Trajectory or theta, theta_dot and theta_ddot",
                argument="theta_dot",
            )
        result = model.inverse(motion.theta, motion.theta_dot, motion.theta_ddot)
        return dataclasses.replace(result, time=motion.time.copy())
    if theta_dot is None or theta_ddot is None:
        raise InputError("theta_dot and theta_ddot are required with theta", argument="theta_dot")
    return model.inverse(motion, theta_dot, theta_ddot)


def holding_torques(
    dynamics: ClosedLoopDynamics | SPMRobot | None, state: npt.ArrayLike
) -> FloatArray:
    """Static actuator torques [N m] that hold the robot at a state against gravity.

    See :meth:`ClosedLoopDynamics.holding_torques`.
    """
    return _dynamics(dynamics).holding_torques(state)


# -------------------------------------------------------------------- simulation
@dataclasses.dataclass(frozen=True)
class SimulationResult:
    """A simulated motion, sampled every ``record_every`` steps.

    Attributes:
        time: Sample times [s], (N,).
        theta: Input angles [rad], (N, 3).
        theta_dot: Input speeds [rad/s], (N, 3).
        theta_ddot: Input accelerations [rad/s^2] at the samples, (N, 3).
        torque: Actuator torques applied from each sample on [N m], (N, 3).
        q: Joint configurations, (N, 9).
        kinetic: Kinetic energy [J], (N,) (armature included).
        potential: Potential energy [J], (N,).
        actuator_work: Work done by the actuators since the start [J], (N,).
        friction_loss: Energy dissipated by joint friction since the start [J], (N,).
        closure_residual: Closure residual at each sample [rad], (N,).
        max_closure_residual: Largest closure residual over every step [rad].
        steps: Number of time steps.
        dt: Time step [s].
        integrator: Integrator name.
    """

    time: FloatArray
    theta: FloatArray
    theta_dot: FloatArray
    theta_ddot: FloatArray
    torque: FloatArray
    q: FloatArray
    kinetic: FloatArray
    potential: FloatArray
    actuator_work: FloatArray
    friction_loss: FloatArray
    closure_residual: FloatArray
    max_closure_residual: float
    steps: int
    dt: float
    integrator: str

    @property
    def energy(self) -> FloatArray:
        """Mechanical energy kinetic + potential [J], (N,)."""
        result: FloatArray = self.kinetic + self.potential
        return result

    @property
    def energy_error(self) -> FloatArray:
        """Energy balance error E - E_0 - W_actuators + D_friction [J], (N,): zero for an
        exact integration."""
        result: FloatArray = self.energy - self.energy[0] - self.actuator_work + self.friction_loss
        return result

    def check_servo(self, servo: ServoModel = XM540_W150) -> ServoCheck:
        """The recorded torques and speeds against a servo's envelope."""
        return check_servo(self.torque, self.theta_dot, servo, time=self.time)


Controller = Callable[[float, FloatArray, FloatArray], Any]


class _Kernel:
    """The simulator's hot loop: a private workspace and closures with bound locals.

    Python call overhead dominates a time step (each Pinocchio or numpy call costs
    about a microsecond), so everything a step needs is bound once, here. The
    workspace (``pin.Data``, constraint datas, LU) is the kernel's own, so other uses
    of the same :class:`ClosedLoopDynamics` between steps cannot disturb it.

    Attributes (callables):
        kinematics(q) -> (J, r2): joint Jacobians, weld residuals, the selected
            constraint Jacobian J (passive columns first) and the LU of J_p at q;
            r2 = ||e||^2.
        tangent(J) -> S: the velocity map S = [I; G] (9, 3), v = S theta_dot, with the
            LU of the last ``kinematics`` call.
        accelerate(q, v, tau3) -> (ddq, friction torque): ``pin.constraintDynamics``.
        project(q) -> (J, r2, moved, e): Newton projection of q's passive joints in
            place; e is the residual of the used rows at the result.
        step(tau3) -> theta_ddot: one step of the chosen integrator on the simulator's
            state; returns the input accelerations at the state it started from.
        energy(q, v) -> (kinetic, potential).
        forget(): clear the Euler predictor's history (after a reset).
    """

    def __init__(self, sim: Simulator) -> None:
        dyn = sim.dynamics
        model = dyn.model
        data = model.createData()
        cms = dyn._cms
        cds = pin.StdVec_ConstraintData()
        for constraint in cms:
            cds.append(constraint.createData())
        bare = [d.extract() for d in cds]
        self._keep = (cds, bare)
        calc_errors = tuple(
            (c.extract().calc, d, d.constraint_position_error)
            for c, d in zip(cms, bare, strict=True)
        )
        errors = tuple(d.constraint_position_error for d in bare)
        rigid = dyn._rigid
        rigid_datas = pin.StdVec_RigidConstraintData([r.createData() for r in rigid])
        pin.initConstraintDynamics(model, data, rigid, rigid_datas)
        prox = pin.ProximalSettings(PROXIMAL_ACCURACY, PROXIMAL_MU, PROXIMAL_MAX_ITERATIONS)
        self._keep_rigid = rigid_datas
        lu = eigenpy.PartialPivLU(np.eye(dyn.passive_idx.shape[0]))
        self.lu = lu
        lu_compute, lu_solve, lu_rcond = lu.compute, lu.solve, lu.rcond
        joint_jacobians = pin.computeJointJacobians
        constraints_jacobian = pin.getConstraintsJacobian
        constraint_dynamics = pin.constraintDynamics
        kinetic_energy = pin.computeKineticEnergy
        potential_energy = pin.computePotentialEnergy
        concatenate, tanh = np.concatenate, np.tanh
        flat, rows = dyn._flat, dyn.constraint_rows
        a_idx, p_idx = dyn.actuated_idx, dyn.passive_idx
        nv, n_p = model.nv, int(p_idx.shape[0])
        scatter = np.zeros((nv, n_p))
        scatter[p_idx, np.arange(n_p)] = 1.0
        # S = [I; G] in q order: the actuated rows are fixed, the passive rows change.
        identity = np.zeros((nv, 3))
        identity[a_idx, np.arange(3)] = 1.0
        minus_scatter = -scatter
        armature = dyn.armature
        friction = dyn.friction
        viscous = None if friction is None else friction.viscous
        coulomb = None if friction is None or not friction.has_coulomb else friction.coulomb
        smoothing = 1.0 if friction is None else friction.smoothing_speed
        tau = np.zeros(nv)
        no_friction = np.zeros(nv)
        tol2 = CLOSURE_TOL * CLOSURE_TOL
        dt = sim.dt
        half, sixth, half_dt2 = 0.5 * dt, dt / 6.0, 0.5 * dt * dt

        def kinematics(q: FloatArray) -> tuple[FloatArray, float]:
            joint_jacobians(model, data, q)
            r2 = 0.0
            for calc, cdata, error in calc_errors:
                calc(model, data, cdata)
                r2 += error.dot(error)
            J = constraints_jacobian(model, data, cms, cds).take(flat)
            lu_compute(J[:, :n_p])
            return J, r2

        if len(calc_errors) == 2:  # the SPM: two welds, unrolled (saves a microsecond)
            (calc_a, cdata_a, error_a), (calc_b, cdata_b, error_b) = calc_errors

            def kinematics(q: FloatArray) -> tuple[FloatArray, float]:
                joint_jacobians(model, data, q)
                calc_a(model, data, cdata_a)
                calc_b(model, data, cdata_b)
                J = constraints_jacobian(model, data, cms, cds).take(flat)
                lu_compute(J[:, :n_p])
                return J, error_a.dot(error_a) + error_b.dot(error_b)

        def tangent(J: FloatArray) -> FloatArray:
            S: FloatArray = identity + minus_scatter.dot(lu_solve(J[:, n_p:]))
            return S

        def accelerate(
            q: FloatArray, v: FloatArray, tau3: FloatArray
        ) -> tuple[FloatArray, FloatArray]:
            if viscous is None:
                f = no_friction
                tau.put(a_idx, tau3)
            else:
                f = -viscous * v
                if coulomb is not None:
                    f -= coulomb * tanh(v / smoothing)
                tau[:] = f
                tau[a_idx] += tau3
            ddq = constraint_dynamics(model, data, q, v, tau, rigid, rigid_datas, prox)
            return ddq, f

        def selected_error() -> FloatArray:
            """The residual rows used (the angular ones) at the last evaluation."""
            result: FloatArray = concatenate(errors).take(rows)
            return result

        def project(q: FloatArray) -> tuple[FloatArray, float, bool, FloatArray]:
            """(J, r2, moved, e): Newton projection of q's passive joints, in place; e
            is the residual of the used rows at the projected q."""
            for iteration in range(NEWTON_MAX_ITERATIONS):
                J, r2 = kinematics(q)
                e = selected_error()
                if r2 <= tol2:
                    return J, r2, iteration > 0, e
                if not math.isfinite(r2):
                    break
                q -= scatter.dot(lu_solve(e))
            dyn._project(q)  # the generic solver, or ConvergenceError
            J, r2 = kinematics(q)
            return J, r2, True, selected_error()

        if len(calc_errors) == 2:  # the SPM, inlined: this runs once or twice a step
            sizes = [int(error.shape[0]) for error in errors]
            part_a = rows[rows < sizes[0]]
            part_b = rows[rows >= sizes[0]] - sizes[0]
            if all(
                part.size and np.array_equal(part, np.arange(part[0], part[-1] + 1))
                for part in (part_a, part_b)
            ):  # contiguous rows in each weld: views into the live residuals
                view_a = error_a[part_a[0] : part_a[-1] + 1]
                view_b = error_b[part_b[0] : part_b[-1] + 1]

                def selected_error() -> FloatArray:
                    result: FloatArray = concatenate((view_a, view_b))
                    return result

                if dyn._dropped_rows_vanish:  # the whole residual is in the used rows

                    def project(q: FloatArray) -> tuple[FloatArray, float, bool, FloatArray]:
                        for iteration in range(NEWTON_MAX_ITERATIONS):
                            joint_jacobians(model, data, q)
                            calc_a(model, data, cdata_a)
                            calc_b(model, data, cdata_b)
                            J = constraints_jacobian(model, data, cms, cds).take(flat)
                            lu_compute(J[:, :n_p])
                            e = concatenate((view_a, view_b))
                            r2 = e.dot(e)
                            if r2 <= tol2:
                                return J, r2, iteration > 0, e
                            if not math.isfinite(r2):
                                break
                            q -= scatter.dot(lu_solve(e))
                        dyn._project(q)  # the generic solver, or ConvergenceError
                        J, r2 = kinematics(q)
                        return J, r2, True, concatenate((view_a, view_b))

        def commit(
            q_next: FloatArray,
            theta_dot: FloatArray,
            work: float,
            loss: float,
        ) -> bool:
            """Project q_next, check it, make it the state; returns whether Newton moved it."""
            predicted = q_next.copy()
            if float(np.abs(predicted - sim._q).max()) > MAX_STEP_ANGLE:
                sim._too_fast(sim._q, predicted)
            try:
                J, r2, moved, _ = project(q_next)
            except ConvergenceError as exc:
                sim._lost(q_next, exc)
            if moved:  # a Newton step was needed: check it stayed on the branch
                sim._check_jump(sim._q, predicted, q_next)
            rcond = lu_rcond()
            if rcond < SINGULAR_RCOND:
                sim._singular(q_next, rcond)
            sim._rcond = rcond
            sim._q = q_next
            sim._theta_dot = theta_dot
            sim._S = tangent(J)
            sim._work += work
            sim._loss += loss
            sim._steps += 1
            sim._time += dt
            if r2 > sim._max_r2:
                sim._max_r2 = r2
            sim._r2 = r2
            return moved

        # The history of the Euler predictor, on the passive joints: the smooth part D of
        # the projection's corrections of the last three steps (h0, h1, h2), and the
        # Newton step still left at the accepted state (its residual is below
        # CLOSURE_TOL, not zero; q - left would be the exact closed state).
        zero = np.zeros(n_p)
        h0 = h1 = h2 = left = zero

        def forget() -> None:
            """Clear the history (after a reset: the motion starts anew)."""
            nonlocal h0, h1, h2, left
            h0 = h1 = h2 = left = zero

        def euler(tau3: FloatArray) -> FloatArray:
            # The hot path of the simulator: written out (no helper calls) because each
            # Python-level call costs a fraction of a microsecond.
            q, S, w = sim._q, sim._S, sim._theta_dot
            v = S.dot(w)
            if viscous is None:
                f = no_friction
                tau.put(a_idx, tau3)
            else:
                f = -viscous * v
                if coulomb is not None:
                    f -= coulomb * tanh(v / smoothing)
                tau[:] = f
                tau[a_idx] += tau3
            ddq = constraint_dynamics(model, data, q, v, tau, rigid, rigid_datas, prox)
            theta_ddot: FloatArray = ddq.take(a_idx)
            # theta_next = theta + dt theta_dot_next (semi-implicit Euler). The passive
            # joints are predicted on the loops: q + dt v + dt^2/2 (ddq + S theta_ddot) is
            # exact to O(dt^3); the remainder D (the correction the projection makes)
            # varies smoothly from step to step, so the last three extrapolate it
            # quadratically (P), and the Newton step r left at q is added. The projection
            # then finds the loops closed at its first evaluation in most steps; a
            # Newton step follows only when not.
            base = q + dt * v + half_dt2 * (ddq + S.dot(theta_ddot))
            nonlocal h0, h1, h2, left
            smooth = 3.0 * (h0 - h1) + h2
            q_next = base + scatter.dot(smooth - left)
            theta_dot = w + dt * theta_ddot
            work = dt * float(tau3.dot(theta_dot))
            loss = 0.0 if viscous is None else -dt * float(f.dot(v + dt * ddq))
            try:
                J, r2, moved, e = project(q_next)
            except ConvergenceError as exc:
                sim._lost(q_next, exc)
            if moved:  # a Newton step was needed: check it stayed on the branch
                sim._check_jump(q, base, q_next)
            if moved or not sim._steps & 7:
                # The distance to a parallel singularity, every 8 steps and whenever
                # the prediction needed Newton (near a singularity it does).
                rcond = lu_rcond()
                if rcond < SINGULAR_RCOND:
                    sim._singular(q_next, rcond)
                sim._rcond = rcond
            S_next = identity + minus_scatter.dot(lu_solve(J[:, n_p:]))
            sim._q, sim._theta_dot, sim._S, sim._r2 = q_next, theta_dot, S_next, r2
            sim._work += work
            sim._loss += loss
            sim._steps += 1
            sim._time += dt
            if r2 > sim._max_r2:
                sim._max_r2 = r2
            # The state stays where it was checked; the step r left there enters the
            # next prediction and is taken out of this step's correction.
            remaining = lu_solve(e)
            if moved:
                smooth = (q_next - base).take(p_idx) + left
            h0, h1, h2, left = smooth - remaining, h0, h1, remaining
            return theta_ddot

        def stage(
            q: FloatArray, theta_dot: FloatArray, tau3: FloatArray
        ) -> tuple[FloatArray, FloatArray, float]:
            J, _ = kinematics(q)
            v = tangent(J).dot(theta_dot)
            ddq, f = accelerate(q, v, tau3)
            power = 0.0 if viscous is None else -float(f.dot(v))
            return v, ddq.take(a_idx), power

        def rk4(tau3: FloatArray) -> FloatArray:
            q, w = sim._q, sim._theta_dot
            v1 = sim._S.dot(w)
            ddq, f = accelerate(q, v1, tau3)
            a1 = ddq.take(a_idx)
            p1 = 0.0 if viscous is None else -float(f.dot(v1))
            v2, a2, p2 = stage(q + half * v1, w + half * a1, tau3)
            v3, a3, p3 = stage(q + half * v2, w + half * a2, tau3)
            v4, a4, p4 = stage(q + dt * v3, w + dt * a3, tau3)
            q_next = q + sixth * (v1 + 2.0 * (v2 + v3) + v4)
            theta_dot = w + sixth * (a1 + 2.0 * (a2 + a3) + a4)
            work = float(tau3.dot(q_next.take(a_idx) - q.take(a_idx)))
            loss = sixth * (p1 + 2.0 * (p2 + p3) + p4)
            commit(q_next, theta_dot, work, loss)
            return a1

        def energy(q: FloatArray, v: FloatArray) -> tuple[float, float]:
            rate = v.take(a_idx)
            kinetic = float(kinetic_energy(model, data, q, v))
            kinetic += 0.5 * float(armature.dot(rate * rate))
            return kinetic, float(potential_energy(model, data, q))

        self.kinematics = kinematics
        self.tangent = tangent
        self.accelerate = accelerate
        self.project = project
        self.energy = energy
        self.forget = forget
        self.step: Callable[[FloatArray], FloatArray] = rk4 if sim.integrator == "rk4" else euler


class Simulator:
    """Time stepping of the closed loop with projection (see the module docstring).

    The state is (q, theta_dot) with q closed; each step integrates, projects the
    passive joints back onto the loops (Newton, theta held) and rebuilds the joint
    velocities from theta_dot, so both the positions and the velocities satisfy the
    closures after every step.

    Args:
        dynamics: A :class:`ClosedLoopDynamics` (gravity, friction, armature), or an
            SPMRobot / None for the defaults.
        dt: Time step [s] (default 1 ms).
        integrator: ``"rk4"`` (default, accurate) or ``"euler"`` (semi-implicit, fast).
        state: Initial theta (3,) [rad] or closed q (9,) (default home).
        theta_dot: Initial input speeds [rad/s] (default 0).

    Raises:
        InputError: non-positive or non-finite dt, unknown integrator, bad state.

    Example:
        >>> import spm_pin as spm
        >>> sim = spm.Simulator(dt=1e-3, state=[0.1, 0.0, 0.0])
        >>> result = sim.run(0.05)
        >>> bool(result.max_closure_residual <= spm.dynamics.DRIFT_TOL)
        True
    """

    def __init__(
        self,
        dynamics: ClosedLoopDynamics | SPMRobot | None = None,
        *,
        dt: float = DEFAULT_DT,
        integrator: str = "rk4",
        state: npt.ArrayLike | None = None,
        theta_dot: npt.ArrayLike | None = None,
    ) -> None:
        self.dynamics = _dynamics(dynamics)
        self.dt = _positive(dt, "dt", "[s]")
        if integrator not in INTEGRATORS:
            raise InputError(
                f"integrator must be one of {list(INTEGRATORS)}, got {integrator!r}",
                argument="integrator",
                value=integrator,
            )
        self.integrator = integrator
        self._q: FloatArray = np.zeros(self.dynamics.model.nq)
        self._theta_dot: FloatArray = np.zeros(3)
        self._S: FloatArray = np.zeros((0, 0))
        self._time = 0.0
        self._steps = 0
        self._work = 0.0
        self._loss = 0.0
        self._r2 = 0.0
        self._max_r2 = 0.0
        self._rcond = 1.0
        self._kernel = _Kernel(self)
        self.reset(state, theta_dot)

    def __repr__(self) -> str:
        return (
            f"Simulator(dt={self.dt:g}, integrator={self.integrator!r}, t={self._time:.6g}, "
            f"theta={self.theta.round(6).tolist()})"
        )

    # ------------------------------------------------------------------ state
    def reset(
        self,
        state: npt.ArrayLike | None = None,
        theta_dot: npt.ArrayLike | None = None,
        *,
        time: float = 0.0,
    ) -> None:
        """Put the robot at a state and clear the counters.

        Args:
            state: theta (3,) [rad] (home assembly mode) or a closed q (9,) (default
                home).
            theta_dot: Input speeds [rad/s] (default 0).
            time: Clock [s].

        Raises:
            InputError: bad state, speeds or time.
            SingularityError: the state is a parallel (type II) singularity.
        """
        q = self.dynamics.configuration(np.zeros(3) if state is None else state)
        rate = np.zeros(3) if theta_dot is None else _vector(theta_dot, 3, "theta_dot", "[rad/s]")
        if isinstance(time, bool) or not isinstance(time, (int, float, np.integer, np.floating)):
            raise InputError(f"time must be a number [s], got {time!r}", argument="time")
        clock = float(time)
        if not math.isfinite(clock):
            raise InputError(f"time must be finite [s], got {time!r}", argument="time")
        kernel = self._kernel
        J, r2, _, _ = kernel.project(q)
        rcond = kernel.lu.rcond()
        if rcond < SINGULAR_RCOND:
            self._singular(q, rcond)
        self._rcond = rcond
        self._q = q
        self._theta_dot = rate
        self._S = kernel.tangent(J)
        self._time = clock
        self._steps = 0
        self._work = 0.0
        self._loss = 0.0
        self._r2 = r2
        self._max_r2 = r2
        kernel.forget()

    def _lost(self, q: FloatArray, error: ConvergenceError) -> NoReturn:
        """The projection failed: near a parallel singularity (the motion would have to
        cross it) a SingularityError, otherwise the ConvergenceError with the time."""
        theta = np.degrees(q[self.dynamics.actuated_idx]).round(4).tolist()
        # the last accepted state's conditioning, or that of the failed attempt
        self._rcond = min(self._rcond, float(self._kernel.lu.rcond()))
        if self._rcond < SINGULAR_NEAR:
            raise SingularityError(
                f"the motion reached a parallel (type II) singularity at t = "
                f"{self._time:.6g} s: the passive joints cannot follow the inputs through "
                f"it (rcond of the passive constraint Jacobian fell to {self._rcond:.2g}; "
                f"theta = {theta} deg); input angles cannot describe the motion beyond",
                kind="type II",
                value=q.copy(),
            ) from error
        raise ConvergenceError(
            f"the step from t = {self._time:.6g} s does not close the loops (theta = "
            f"{theta} deg): {error}",
            data={"time": self._time, **error.data},
        ) from error

    def _check_jump(self, q: FloatArray, predicted: FloatArray, projected: FloatArray) -> None:
        """A closed configuration further than JUMP_RATIO of the step's own motion from
        the integrator's prediction (its Taylor part, for euler) may be on another
        assembly mode: refuse it."""
        jump = float(np.abs(projected - predicted).max())
        motion = float(np.abs(predicted - q).max())
        if jump > JUMP_RATIO * motion + CLOSED_TOL:
            raise ConvergenceError(
                f"the step from t = {self._time:.6g} s is too large for the motion: closing "
                f"the loops moved the passive joints by {jump:.3g} rad, more than "
                f"{JUMP_RATIO:g} of the step's own motion ({motion:.3g} rad), so it may "
                f"have jumped to another assembly mode; use a smaller time step than "
                f"dt = {self.dt:g} s",
                data={"time": self._time, "q": q.copy(), "jump": jump, "motion": motion},
            )

    def _too_fast(self, q: FloatArray, predicted: FloatArray) -> NoReturn:
        motion = float(np.abs(predicted - q).max())
        raise ConvergenceError(
            f"the step from t = {self._time:.6g} s moves a joint by {motion:.3g} rad, more "
            f"than {MAX_STEP_ANGLE:g} rad: the motion is too fast for dt = {self.dt:g} s "
            "(the integration would not be accurate); use a smaller time step",
            data={"time": self._time, "q": q.copy(), "motion": motion},
        )

    def _singular(self, q: FloatArray, rcond: float) -> NoReturn:
        raise SingularityError(
            f"parallel (type II) singularity at t = {self._time:.6g} s: the passive joints "
            f"no longer follow the inputs (rcond of the passive constraint Jacobian "
            f"{rcond:.2g} < {SINGULAR_RCOND:g}) near theta = "
            f"{np.degrees(q[self.dynamics.actuated_idx]).round(4).tolist()} deg",
            kind="type II",
            value=q.copy(),
        )

    @property
    def time(self) -> float:
        """Simulated time [s]."""
        return self._time

    @property
    def q(self) -> FloatArray:
        """Closed joint configuration (9,) (a copy)."""
        result: FloatArray = self._q.copy()
        return result

    @property
    def theta(self) -> FloatArray:
        """Input angles [rad] (3,)."""
        result: FloatArray = self._q.take(self.dynamics.actuated_idx)
        return result

    @property
    def theta_dot(self) -> FloatArray:
        """Input speeds [rad/s] (3,)."""
        result: FloatArray = self._theta_dot.copy()
        return result

    @property
    def v(self) -> FloatArray:
        """Joint velocities [rad/s] (9,), J v = 0."""
        result: FloatArray = self._S.dot(self._theta_dot)
        return result

    @property
    def closure_residual(self) -> float:
        """Closure residual of the present state [rad] (Euclidean norm of the welds)."""
        return math.sqrt(self._r2)

    @property
    def max_closure_residual(self) -> float:
        """Largest closure residual since the last reset [rad]."""
        return math.sqrt(self._max_r2)

    @property
    def steps(self) -> int:
        """Steps taken since the last reset."""
        return self._steps

    def energy(self) -> tuple[float, float]:
        """(kinetic, potential) energy at the present state [J]."""
        return self._kernel.energy(self._q, self.v)

    # ------------------------------------------------------------------ steps
    def step(self, torque: npt.ArrayLike | None = None) -> FloatArray:
        """Advance one time step with actuator torques [N m] (3,) held over it (default 0).

        Returns:
            The input accelerations at the state the step started from [rad/s^2], (3,).

        Raises:
            InputError: torque of a wrong shape, NaN or inf.
            SingularityError: the motion reached a parallel (type II) singularity.
            ConvergenceError: the loops could not be closed (never silently).
        """
        tau = np.zeros(3) if torque is None else _vector(torque, 3, "torque", "[N m]")
        return self._kernel.step(tau)

    # -------------------------------------------------------------------- run
    def run(
        self,
        duration: float,
        controller: Controller | npt.ArrayLike | None = None,
        *,
        record_every: int = 1,
    ) -> SimulationResult:
        """Simulate for ``duration`` seconds and return the sampled motion.

        Args:
            duration: Simulated time [s] (rounded to whole steps, at least one).
            controller: The actuator torques: None (zero: a passive motion), a constant
                (3,) [N m], or a callable ``controller(t, theta, theta_dot) -> (3,)``
                evaluated at the start of every step and held over it (e.g. a
                :class:`ServoController`).
            record_every: Record every k-th step (the first and last state always).

        Returns:
            :class:`SimulationResult`.

        Raises:
            InputError: bad duration, record_every, constant torque or controller
                output (NaN, inf, wrong shape: reported with the time).
            SingularityError: the motion reached a parallel (type II) singularity.
        """
        length = _positive(duration, "duration", "[s]")
        check_count(record_every, "record_every", 1)
        steps = max(1, round(length / self.dt))
        call: Controller | None = None
        constant = np.zeros(3)
        if callable(controller):
            call = controller
        elif controller is not None:
            constant = _vector(controller, 3, "controller", "[N m] (a constant torque)")
        recorder = _Recorder(self, steps // record_every + 2)
        step = self._kernel.step
        idx = self.dynamics.actuated_idx

        def torque_now() -> FloatArray:
            if call is None:
                return constant
            value: FloatArray = call(self._time, self._q.take(idx), self._theta_dot.copy())
            if (
                type(value) is not np.ndarray
                or value.shape != (3,)
                or value.dtype != np.float64
                or not math.isfinite(float(value.dot(value)))
            ):
                value = _vector(value, 3, "controller output", f"[N m] (at t = {self._time:.6g} s)")
            return value

        for k in range(steps):
            tau = torque_now()
            if k % record_every == 0:
                row = recorder.add(tau)
                recorder.theta_ddot[row] = step(tau)
            else:
                step(tau)
        tau = torque_now()
        row = recorder.add(tau)
        v = self._S.dot(self._theta_dot)
        recorder.theta_ddot[row] = self._kernel.accelerate(self._q, v, tau)[0].take(idx)
        return recorder.result()


class _Recorder:
    """Preallocated sample arrays of a run."""

    def __init__(self, sim: Simulator, n: int) -> None:
        self.sim = sim
        self.n = 0
        self.time = np.zeros(n)
        self.theta_dot = np.zeros((n, 3))
        self.theta_ddot = np.zeros((n, 3))
        self.torque = np.zeros((n, 3))
        self.q = np.zeros((n, 9))
        self.kinetic = np.zeros(n)
        self.potential = np.zeros(n)
        self.work = np.zeros(n)
        self.loss = np.zeros(n)
        self.residual = np.zeros(n)

    def add(self, tau: FloatArray) -> int:
        """Record the simulator's present state (the kinematics are evaluated there)."""
        sim = self.sim
        kernel = sim._kernel
        k = self.n
        q = sim._q
        v = sim._S.dot(sim._theta_dot)
        self.time[k] = sim._time
        self.theta_dot[k] = sim._theta_dot
        self.torque[k] = tau
        self.q[k] = q
        self.kinetic[k], self.potential[k] = kernel.energy(q, v)
        self.work[k] = sim._work
        self.loss[k] = sim._loss
        self.residual[k] = math.sqrt(sim._r2)
        self.n += 1
        return k

    def result(self) -> SimulationResult:
        sim = self.sim
        n = self.n
        idx = sim.dynamics.actuated_idx
        return SimulationResult(
            time=self.time[:n].copy(),
            theta=self.q[:n][:, idx].copy(),
            theta_dot=self.theta_dot[:n].copy(),
            theta_ddot=self.theta_ddot[:n].copy(),
            torque=self.torque[:n].copy(),
            q=self.q[:n].copy(),
            kinetic=self.kinetic[:n].copy(),
            potential=self.potential[:n].copy(),
            actuator_work=self.work[:n].copy(),
            friction_loss=self.loss[:n].copy(),
            closure_residual=self.residual[:n].copy(),
            max_closure_residual=sim.max_closure_residual,
            steps=sim._steps,
            dt=sim.dt,
            integrator=sim.integrator,
        )


# -------------------------------------------------------------------------- plots
def plot_torques(
    motion: InverseDynamicsResult | SimulationResult,
    path: str | Path,
    servo: ServoModel = XM540_W150,
    *,
    title: str | None = None,
) -> Path:
    """Write a PNG of the actuator torques against the servo's torque-speed envelope.

    Left: torque against time for each input, with the stall torque. Right: every
    sample in the torque-speed plane with the envelope of :meth:`ServoModel.torque_limits`
    (a sample outside it needs more than the servo can give). Needs matplotlib
    (``pip install 'spm-pin[plot]'``), imported here only; no global pyplot state is used.

    Args:
        motion: An :class:`InverseDynamicsResult` with ``time`` (from a
            :class:`Trajectory`) or a :class:`SimulationResult`.
        path: The PNG file to write.
        servo: The servo whose envelope is drawn.
        title: Figure title (default: a summary of the check).

    Returns:
        The path written.

    Raises:
        InputError: a motion without sample times.
        ImportError: matplotlib is missing.
    """
    if not isinstance(motion, (InverseDynamicsResult, SimulationResult)):
        raise InputError(
            "motion must be an InverseDynamicsResult or a SimulationResult, got "
            f"{type(motion).__name__}",
            argument="motion",
            value=motion,
        )
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:  # pragma: no cover - matplotlib is in the test extra
        raise ImportError("plot_torques needs matplotlib: pip install 'spm-pin[plot]'") from exc
    time = motion.time
    if time is None or np.ndim(motion.torque) != 2:
        raise InputError(
            "plot_torques needs a motion sampled in time (a Trajectory's inverse dynamics "
            "or a simulation)",
            argument="motion",
        )
    torque = np.asarray(motion.torque)
    speed = np.asarray(motion.theta_dot)
    check = check_servo(torque, speed, servo, time=time)
    figure = Figure(figsize=(11.0, 4.5), layout="constrained")
    FigureCanvasAgg(figure)
    left, right = figure.subplots(1, 2)
    colors = ("tab:blue", "tab:orange", "tab:green")
    for joint in range(3):
        left.plot(time, torque[:, joint], color=colors[joint], label=f"u_{joint + 1}")
        right.plot(speed[:, joint], torque[:, joint], ".", ms=2, color=colors[joint])
    stall = servo.stall_torque
    peak = float(np.abs(torque).max(initial=0.0))
    zoom = peak < 0.1 * stall  # the motion uses little of the servo: show the torques
    for sign in (1.0, -1.0):
        left.axhline(sign * stall, color="k", lw=0.8, ls="--", label=None)
    if zoom:
        left.set_ylim(-1.3 * peak - 1e-6, 1.3 * peak + 1e-6)
        left.set_title(f"stall torque +-{stall:g} N m: off scale", fontsize=8)
    left.set_xlabel("time [s]")
    left.set_ylabel("actuator torque [N m]")
    left.legend(loc="best")
    left.grid(True, alpha=0.3)
    reach = max(2.0 * servo.no_load_speed, 1.1 * float(np.abs(speed).max(initial=0.0)))
    omega = np.linspace(-reach, reach, 401)
    lower, upper = servo.torque_limits(omega)
    right.fill_between(omega, lower, upper, color="0.85", label=f"{servo.name} envelope")
    right.plot(omega, upper, "k", lw=0.8)
    right.plot(omega, lower, "k", lw=0.8)
    if zoom:
        right.set_ylim(-2.0 * peak - 1e-6, 2.0 * peak + 1e-6)
    right.set_xlabel("speed [rad/s]")
    right.set_ylabel("actuator torque [N m]")
    right.legend(loc="upper right")
    right.grid(True, alpha=0.3)
    heading = title if title is not None else check.message
    figure.suptitle(textwrap.fill(heading, 110), fontsize=9)
    out = Path(path)
    figure.savefig(out, format="png", dpi=110)
    return out


# ------------------------------------------------------------------------ MuJoCo
def simulate_mujoco(
    mjcf: str | Path,
    dynamics: ClosedLoopDynamics | SPMRobot | None,
    duration: float,
    controller: Controller | npt.ArrayLike | None = None,
    *,
    state: npt.ArrayLike | None = None,
    theta_dot: npt.ArrayLike | None = None,
    dt: float = DEFAULT_DT,
    substeps: int = 10,
    integrator: str = "rk4",
    solref: tuple[float, float] | None = None,
    solimp: Sequence[float] = MUJOCO_SOLIMP,
    record_every: int = 1,
) -> SimulationResult:
    """The same motion in MuJoCo, for cross-checking (needs the ``mujoco`` package).

    MuJoCo loads the exported MJCF (``spm export``: the same tree and welds), with the
    gravity, armature and viscous friction of ``dynamics``. The controller runs every
    ``dt`` (as in :class:`Simulator`) and its torque is held over ``substeps`` MuJoCo
    steps of ``dt / substeps``. MuJoCo's constraints are soft (a spring-damper with
    time constant solref[0]): the defaults stiffen them to twice the physics step
    with solimp close to 1, which brings MuJoCo within about 1e-7 rad of the rigid
    answer; MuJoCo's stock values (solref 0.02 s, solimp 0.9/0.95) and a 1 ms step
    leave errors near 1e-2 rad.

    Args:
        mjcf: Path of the MJCF file of ``dynamics.robot``'s design.
        dynamics: The physics to copy (gravity, armature, viscous friction; Coulomb
            friction is not supported).
        duration: Simulated time [s].
        controller: As in :meth:`Simulator.run`.
        state: Initial theta (3,) [rad] or closed q (9,) (default home).
        theta_dot: Initial input speeds [rad/s] (default 0).
        dt: Control period [s].
        substeps: MuJoCo steps per control period (>= 1).
        integrator: MuJoCo integrator: ``"rk4"``, ``"euler"``, ``"implicit"`` or
            ``"implicitfast"``.
        solref: (time constant [s], damping ratio) of the welds (default
            (2 dt / substeps, 1)).
        solimp: The welds' impedance (5 numbers).
        record_every: Record every k-th control period.

    Returns:
        :class:`SimulationResult` (``max_closure_residual``: the largest Pinocchio weld
        residual at the recorded samples; ``theta_ddot``: MuJoCo's accelerations).

    Raises:
        InputError: bad arguments, Coulomb friction, an MJCF of another robot.
        ImportError: MuJoCo is not installed (``pip install spm-pin[sim]``).
    """
    try:
        import mujoco
    except ImportError as exc:  # pragma: no cover - mujoco is in the test extra
        raise ImportError("simulate_mujoco needs MuJoCo: pip install 'spm-pin[sim]'") from exc
    dyn = _dynamics(dynamics)
    length = _positive(duration, "duration", "[s]")
    period = _positive(dt, "dt", "[s]")
    check_count(substeps, "substeps", 1)
    check_count(record_every, "record_every", 1)
    if integrator not in _MUJOCO_INTEGRATORS:
        raise InputError(
            f"integrator must be one of {list(_MUJOCO_INTEGRATORS)}, got {integrator!r}",
            argument="integrator",
            value=integrator,
        )
    if dyn.friction is not None and dyn.friction.has_coulomb:
        raise InputError(
            "simulate_mujoco supports viscous friction only (MuJoCo's frictionloss is "
            "not a smoothed Coulomb law)",
            argument="dynamics",
        )
    if not isinstance(mjcf, (str, Path)):
        raise InputError(
            f"mjcf must be the path of an MJCF file (str or Path), got {type(mjcf).__name__}",
            argument="mjcf",
            value=mjcf,
        )
    file = Path(mjcf)
    if not file.is_file():
        raise InputError(f"MJCF file {str(file)!r} does not exist", argument="mjcf", value=mjcf)
    model = mujoco.MjModel.from_xml_path(str(file))
    names = tuple(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt))
    mass = float(np.sum(model.body_mass))
    if names != JOINT_NAMES or not math.isclose(mass, dyn.robot.total_mass, rel_tol=1e-9):
        raise InputError(
            f"{file} is not the MJCF of this robot (joints {names}, total mass {mass:.6g} kg "
            f"vs {dyn.robot.total_mass:.6g} kg); export it with spm export",
            argument="mjcf",
            value=mjcf,
        )
    step = period / substeps
    model.opt.timestep = step
    model.opt.gravity[:] = dyn.gravity
    model.opt.integrator = {
        "euler": mujoco.mjtIntegrator.mjINT_EULER,
        "rk4": mujoco.mjtIntegrator.mjINT_RK4,
        "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
        "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    }[integrator]
    reference = (2.0 * step, 1.0) if solref is None else tuple(float(x) for x in solref)
    impedance = np.array(solimp, dtype=float)
    if len(reference) != 2 or impedance.shape != (5,):
        raise InputError("solref needs 2 numbers and solimp 5", argument="solref")
    model.eq_solref[:] = reference
    model.eq_solimp[:] = impedance
    model.dof_armature[:] = 0.0
    model.dof_armature[dyn.actuated_idx] = dyn.armature
    model.dof_damping[:] = 0.0 if dyn.friction is None else dyn.friction.viscous
    data = mujoco.MjData(model)
    q0 = dyn.configuration(np.zeros(3) if state is None else state)
    rate = np.zeros(3) if theta_dot is None else _vector(theta_dot, 3, "theta_dot", "[rad/s]")
    data.qpos[:] = q0
    data.qvel[:] = dyn.velocity(q0, rate)
    mujoco.mj_forward(model, data)

    steps = max(1, round(length / period))
    call: Controller | None = controller if callable(controller) else None
    constant = np.zeros(3)
    if controller is not None and call is None:
        constant = _vector(controller, 3, "controller", "[N m] (a constant torque)")
    idx = dyn.actuated_idx
    records: dict[str, list[Any]] = {
        key: []
        for key in ("time", "q", "v", "ddq", "torque", "work", "kinetic", "potential", "loss")
    }
    work = loss = 0.0
    damping = model.dof_damping.copy()

    def torque_now(t: float) -> FloatArray:
        if call is None:
            return constant
        return _vector(
            call(t, data.qpos[idx].copy(), data.qvel[idx].copy()), 3, "controller output", "[N m]"
        )

    def record(t: float, tau: FloatArray) -> None:
        q = data.qpos.copy()
        v = data.qvel.copy()
        records["time"].append(t)
        records["q"].append(q)
        records["v"].append(v)
        records["ddq"].append(data.qacc.copy())
        records["torque"].append(tau.copy())
        records["work"].append(work)
        records["loss"].append(loss)
        kinetic, potential = dyn._energy(q, v)
        records["kinetic"].append(kinetic)
        records["potential"].append(potential)

    tau = torque_now(0.0)
    data.qfrc_applied[:] = 0.0
    data.qfrc_applied[idx] = tau
    mujoco.mj_forward(model, data)
    record(0.0, tau)
    for k in range(1, steps + 1):
        theta_before = data.qpos[idx].copy()
        power_before = float(np.dot(damping * data.qvel, data.qvel))
        mujoco.mj_step(model, data, nstep=substeps)
        work += float(tau.dot(data.qpos[idx] - theta_before))
        power_after = float(np.dot(damping * data.qvel, data.qvel))
        loss += 0.5 * period * (power_before + power_after)
        t = k * period
        tau = torque_now(t)
        data.qfrc_applied[idx] = tau
        mujoco.mj_forward(model, data)
        if k % record_every == 0 or k == steps:
            record(t, tau)
    q_all = np.array(records["q"])
    residuals = np.array([float(dyn.robot.closure_residual(q)) for q in q_all])
    return SimulationResult(
        time=np.array(records["time"]),
        theta=q_all[:, idx],
        theta_dot=np.array(records["v"])[:, idx],
        theta_ddot=np.array(records["ddq"])[:, idx],
        torque=np.array(records["torque"]),
        q=q_all,
        kinetic=np.array(records["kinetic"]),
        potential=np.array(records["potential"]),
        actuator_work=np.array(records["work"]),
        friction_loss=np.array(records["loss"]),
        closure_residual=residuals,
        max_closure_residual=float(residuals.max()),
        steps=steps * substeps,
        dt=step,
        integrator=f"mujoco-{integrator}",
    )
