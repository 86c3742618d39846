r"""The peak motor torque of a design along a required motion with a payload.

The required motion is a motion of the platform: rotations R(t), angular velocities
omega(t) and angular accelerations alpha(t) in the world frame (:class:`Motion`; by
default :func:`cone_motion`, the platform tilted by a fixed angle whose tilt
direction turns once about the axis in a given time). The inputs follow from the
exact kinematics, sample by sample:

* theta: :func:`~spm_pin.inverse_kinematics` (home working mode);
* theta_dot from A omega = B theta_dot, row by row: theta_dot_i = a_i . omega / b_ii
  (a_i = w_i x v_i, b_ii = (u_i x w_i) . v_i);
* theta_ddot from its time derivative,
  a_i . alpha + a_dot_i . omega = b_ii theta_ddot_i + b_dot_i theta_dot_i, with
  w_dot_i = theta_dot_i (u_i x w_i), v_dot_i = omega x v_i.

The torques are those of the reduced closed-loop dynamics
(:class:`~spm_pin.dynamics.ReducedDynamics`, exact on the three inputs) plus the
payload's share. The payload is a rigid body fixed to the platform (a point mass, or
a mass with an inertia about its centre of mass, :class:`Payload`): it turns about O
with the platform, so its share is the virtual power of its inertia and weight
torques about O mapped to the inputs by the platform Jacobian J (omega = J theta_dot):

    tau = M theta_ddot + c + g - tau_f
          + J^T (I_O alpha + omega x I_O omega - h x gravity),

with I_O = R I_O,platform R^T the payload's inertia about O and h = R m p its first
moment of mass (p its centre of mass in the platform frame). The design's own model
is left untouched: the payload is added here, in the same equations.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from .._checks import FloatArray
from ..design import SPMDesign
from ..dynamics import ReducedDynamics
from ..errors import InputError, SingularityError, UnreachableError
from ..kinematics import inverse_kinematics
from .objectives import tilt_rotations

__all__ = ["Motion", "Payload", "PeakTorque", "cone_motion", "motion_inputs", "peak_torque"]

#: |b_ii| at or below which a sample of a motion is a serial (type I) singularity.
_SERIAL_SINGULAR = 1e-9


def _finite_array(value: Any, name: str, shape: tuple[int, ...]) -> FloatArray:
    """``value`` as a finite float array of ``shape`` (-1: any size), else InputError."""
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be numbers of shape {shape}", argument=name) from None
    if array.ndim != len(shape) or any(
        want not in (-1, got) for want, got in zip(shape, array.shape, strict=True)
    ):
        raise InputError(
            f"{name} must have shape {shape} (-1: any), got {array.shape}", argument=name
        )
    if not np.all(np.isfinite(array)):
        raise InputError(f"{name} must be finite, got NaN or inf", argument=name)
    return array


@dataclasses.dataclass(frozen=True)
class Payload:
    """A rigid payload fixed to the platform.

    Attributes:
        mass: Mass [kg] (>= 0; 0: no payload).
        com: Its centre of mass in the platform frame [m] (the platform frame is the
            world frame at home, origin at the centre O).
        inertia: Its inertia about its centre of mass in the platform frame [kg m^2],
            (3, 3) symmetric positive semi-definite (default 0: a point mass).

    Raises:
        InputError: a negative or non-finite mass, a bad centre of mass or inertia.
    """

    mass: float = 0.0
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[tuple[float, float, float], ...] = ((0.0,) * 3,) * 3

    def __post_init__(self) -> None:
        mass = self.mass
        if isinstance(mass, bool) or not isinstance(mass, int | float) or not mass >= 0.0:
            raise InputError(f"mass must be a number >= 0 [kg], got {mass!r}", argument="mass")
        if not math.isfinite(mass):
            raise InputError(f"mass must be finite [kg], got {mass!r}", argument="mass")
        com = _finite_array(self.com, "com", (3,))
        inertia = _finite_array(self.inertia, "inertia", (3, 3))
        if not np.allclose(inertia, inertia.T, atol=1e-12) or np.min(
            np.linalg.eigvalsh(0.5 * (inertia + inertia.T))
        ) < -1e-12 * max(1.0, float(np.abs(inertia).max())):
            raise InputError(
                "inertia must be symmetric positive semi-definite [kg m^2]", argument="inertia"
            )
        object.__setattr__(self, "mass", float(mass))
        object.__setattr__(self, "com", tuple(float(x) for x in com))
        object.__setattr__(self, "inertia", tuple(tuple(float(x) for x in row) for row in inertia))

    def inertia_about_o(self) -> FloatArray:
        """Inertia about O in the platform frame [kg m^2]: I_c + m (|p|^2 E - p p^T)."""
        p = np.asarray(self.com)
        result: FloatArray = np.asarray(self.inertia) + self.mass * (
            float(p @ p) * np.eye(3) - np.outer(p, p)
        )
        return result

    def first_moment(self) -> FloatArray:
        """m p in the platform frame [kg m]."""
        result: FloatArray = self.mass * np.asarray(self.com)
        return result


@dataclasses.dataclass(frozen=True)
class Motion:
    """A required motion of the platform, sampled in time (world frame).

    Attributes:
        time_s: Sample times [s], (N,), increasing.
        R: Platform rotations, (N, 3, 3).
        omega: Platform angular velocities [rad/s], (N, 3).
        alpha: Platform angular accelerations [rad/s^2], (N, 3).

    Raises:
        InputError: mismatched shapes, non-finite values, rotations that are not
            rotations, times that do not increase.
    """

    time_s: FloatArray
    R: FloatArray
    omega: FloatArray
    alpha: FloatArray

    def __post_init__(self) -> None:
        time_s = _finite_array(self.time_s, "time_s", (-1,))
        n = time_s.shape[0]
        if n == 0 or np.any(np.diff(time_s) <= 0.0):
            raise InputError("time_s must be one or more increasing times [s]", argument="time_s")
        R = _finite_array(self.R, "R", (n, 3, 3))
        should_be_eye = np.matmul(R, R.swapaxes(-1, -2)) - np.eye(3)
        if np.abs(should_be_eye).max() > 1e-9 or np.any(np.linalg.det(R) <= 0.0):
            raise InputError("R must hold rotation matrices (orthonormal, det +1)", argument="R")
        object.__setattr__(self, "time_s", time_s)
        object.__setattr__(self, "R", R)
        object.__setattr__(self, "omega", _finite_array(self.omega, "omega", (n, 3)))
        object.__setattr__(self, "alpha", _finite_array(self.alpha, "alpha", (n, 3)))


def cone_motion(tilt_deg: float = 20.0, period_s: float = 2.0, samples: int = 72) -> Motion:
    r"""The platform tilted by ``tilt_deg``, its tilt direction turning once about the
    axis at a steady rate in ``period_s`` (a cone traversed; no torsion):

        R(t) = Rz(phi) Ry(tilt) Rz(-phi),  phi = 2 pi t / T,
        omega = Omega (e_z - R e_z),  alpha = -Omega omega x (R e_z),  Omega = 2 pi / T.

    Args:
        tilt_deg: Tilt of the platform [deg], in [0, 90).
        period_s: Time of one turn [s], > 0.
        samples: Samples over the turn (the last one before the start again), >= 4.

    Raises:
        InputError: an argument out of its range.
    """
    for name, value, low, high in (
        ("tilt_deg", tilt_deg, 0.0, 90.0),
        ("period_s", period_s, 0.0, math.inf),
    ):
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not (low <= value < high and (name == "tilt_deg" or value > 0.0))
        ):
            raise InputError(f"{name} is out of range, got {value!r}", argument=name)
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 4:
        raise InputError(f"samples must be an integer >= 4, got {samples!r}", argument="samples")
    time_s: FloatArray = np.arange(samples, dtype=float) * (period_s / samples)
    phi_deg = (360.0 * time_s / period_s).tolist()
    R = tilt_rotations([float(tilt_deg)] * samples, phi_deg)
    rate = 2.0 * math.pi / period_s
    normal = R[:, :, 2]  # R e_z
    omega = rate * (np.array([0.0, 0.0, 1.0]) - normal)
    alpha = -rate * np.cross(omega, normal)
    return Motion(time_s=time_s, R=R, omega=omega, alpha=alpha)


def _rotate(axes: FloatArray, angles: FloatArray, vectors: FloatArray) -> FloatArray:
    """Rodrigues: turn ``vectors`` (..., 3) about unit ``axes`` by ``angles`` (...)."""
    c = np.cos(angles)[..., None]
    s = np.sin(angles)[..., None]
    along = np.sum(axes * vectors, axis=-1)[..., None] * axes
    result: FloatArray = along + c * (vectors - along) + s * np.cross(axes, vectors)
    return result


def motion_inputs(
    design: SPMDesign | str | None, motion: Motion
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The input angles, speeds and accelerations (theta, theta_dot, theta_ddot) of a
    platform motion, each (N, 3) [rad, rad/s, rad/s^2] (home working mode; see the
    module for the equations).

    Raises:
        UnreachableError: a sample without an inverse kinematics solution.
        SingularityError: a sample at a serial (type I) singularity (some b_ii = 0).
    """
    spm_design = SPMDesign.from_spec(design)
    ik = inverse_kinematics(motion.R, spm_design)
    reachable = np.asarray(ik.reachable, dtype=bool)
    if not np.all(reachable):
        bad = np.flatnonzero(~reachable)
        raise UnreachableError(
            f"the motion is out of reach of design {spm_design.name!r} at {bad.size} of "
            f"{reachable.size} samples (first at t = {float(motion.time_s[bad[0]]):g} s)",
            value=bad,
        )
    theta = np.asarray(ik.theta, dtype=float)
    u = np.asarray(spm_design.u, dtype=float)
    w = _rotate(u, theta, np.asarray(spm_design.w0, dtype=float))  # rows w_i, (N, 3, 3)
    v = np.matmul(motion.R, np.asarray(spm_design.v0, dtype=float).T).swapaxes(-1, -2)
    a = np.cross(w, v)
    uxw = np.cross(u, w)
    b = np.sum(uxw * v, axis=-1)
    if np.any(np.abs(b) <= _SERIAL_SINGULAR):
        first = int(np.flatnonzero(np.any(np.abs(b) <= _SERIAL_SINGULAR, axis=-1))[0])
        raise SingularityError(
            f"the motion meets a serial (type I) singularity of design {spm_design.name!r} "
            f"at t = {float(motion.time_s[first]):g} s",
            kind="type I",
            value=theta[first],
        )
    omega, alpha = motion.omega[:, None, :], motion.alpha[:, None, :]
    theta_dot = np.sum(a * omega, axis=-1) / b
    w_dot = theta_dot[..., None] * uxw
    v_dot = np.cross(omega, v)
    a_dot = np.cross(w_dot, v) + np.cross(w, v_dot)
    b_dot = np.sum(np.cross(u, w_dot) * v, axis=-1) + np.sum(uxw * v_dot, axis=-1)
    theta_ddot = (
        np.sum(a * alpha, axis=-1) + np.sum(a_dot * omega, axis=-1) - b_dot * theta_dot
    ) / b
    return theta, theta_dot, theta_ddot


@dataclasses.dataclass(frozen=True)
class PeakTorque:
    """The motor torques of a design along a motion.

    Attributes:
        peak_nm: Largest |torque| of any motor at any sample [N m].
        motor: Which motor (0, 1, 2) and ``time_s`` when.
        time_s: Time of the peak [s].
        torque: Motor torques [N m], (N, 3).
        theta, theta_dot, theta_ddot: The inputs of the motion, (N, 3) each.
    """

    peak_nm: float
    motor: int
    time_s: float
    torque: FloatArray
    theta: FloatArray
    theta_dot: FloatArray
    theta_ddot: FloatArray


def peak_torque(
    design: SPMDesign | str | None = None,
    motion: Motion | None = None,
    payload: Payload | None = None,
    *,
    dynamics: ReducedDynamics | None = None,
) -> PeakTorque:
    """The largest motor torque of a design along a required motion carrying a payload.

    Args:
        design: The SPM (default: the prototype).
        motion: The platform's motion (default: :func:`cone_motion`, a 20-degree tilt
            turned once in 2 s).
        payload: What the platform carries (default: nothing).
        dynamics: The reduced dynamics to use (gravity, armature and friction:
            default ``ReducedDynamics(design)``, upright gravity, no armature or
            friction); its design must be ``design``.

    Returns:
        :class:`PeakTorque`.

    Raises:
        InputError: bad arguments.
        UnreachableError, SingularityError: the motion leaves the design's workspace.
    """
    spm_design = SPMDesign.from_spec(design)
    motion = cone_motion() if motion is None else motion
    payload = Payload() if payload is None else payload
    if not isinstance(motion, Motion):
        raise InputError(f"motion must be a Motion, got {type(motion).__name__}", argument="motion")
    if not isinstance(payload, Payload):
        raise InputError(
            f"payload must be a Payload, got {type(payload).__name__}", argument="payload"
        )
    if dynamics is None:
        dynamics = ReducedDynamics(spm_design)
    elif not isinstance(dynamics, ReducedDynamics) or dynamics.design != spm_design:
        raise InputError("dynamics must be a ReducedDynamics of the design", argument="dynamics")
    theta, theta_dot, theta_ddot = motion_inputs(spm_design, motion)
    terms = dynamics.terms(theta, theta_dot, reference=motion.R)
    torque = np.einsum("nij,nj->ni", terms.M, theta_ddot) + terms.c + terms.g - terms.friction
    if payload.mass > 0.0 or np.any(np.asarray(payload.inertia) != 0.0):
        R = motion.R
        inertia = np.matmul(np.matmul(R, payload.inertia_about_o()), R.swapaxes(-1, -2))
        moment = np.matmul(R, payload.first_moment())
        gravity = np.asarray(dynamics.gravity, dtype=float)
        omega, alpha = motion.omega, motion.alpha
        wrench = (
            np.einsum("nij,nj->ni", inertia, alpha)
            + np.cross(omega, np.einsum("nij,nj->ni", inertia, omega))
            - np.cross(moment, gravity)
        )
        torque = torque + np.einsum("nji,nj->ni", terms.J, wrench)
    magnitude = np.abs(torque)
    sample, motor = np.unravel_index(int(np.argmax(magnitude)), magnitude.shape)
    return PeakTorque(
        peak_nm=float(magnitude[sample, motor]),
        motor=int(motor),
        time_s=float(motion.time_s[sample]),
        torque=torque,
        theta=theta,
        theta_dot=theta_dot,
        theta_ddot=theta_ddot,
    )
