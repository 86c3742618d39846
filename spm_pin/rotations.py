"""Rotations: conversions between matrices, quaternions and roll/pitch/yaw angles, and
the exponential, logarithm and Jacobians of SO(3).

Conventions: quaternions are (w, x, y, z), scalar first, unit norm;
roll/pitch/yaw are the fixed-axis X-Y-Z angles, R = Rz(yaw) Ry(pitch) Rx(roll);
a rotation vector r [rad] is the axis times the angle, R = exp([r]), where [r] is the
cross-product matrix of r (:func:`skew`).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ._checks import as_rotation
from .errors import InputError

__all__ = [
    "exp_so3",
    "left_jacobian_so3",
    "log_so3",
    "matrix_from_quaternion",
    "matrix_from_rpy",
    "quaternion_from_matrix",
    "right_jacobian_so3",
    "rpy_from_matrix",
    "skew",
]

FloatArray = npt.NDArray[np.float64]


def _finite(value: npt.ArrayLike, name: str, size: int) -> FloatArray:
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(f"{name} must be numbers, got {value!r}", argument=name) from exc
    if array.ndim == 0 or array.shape[-1] != size:
        raise InputError(
            f"{name} must have shape ({size},) or (..., {size}), got {array.shape}",
            argument=name,
            value=value,
        )
    if not np.all(np.isfinite(array)):
        raise InputError(f"{name} must be finite, got {value!r}", argument=name, value=value)
    return array


def matrix_from_quaternion(quaternion: npt.ArrayLike) -> FloatArray:
    """Rotation matrices (..., 3, 3) from quaternions (..., 4) = (w, x, y, z).

    The quaternion is normalised; a (near) zero quaternion raises InputError.
    """
    q = _finite(quaternion, "quaternion", 4)
    largest = np.max(np.abs(q), axis=-1, keepdims=True)
    if np.any(largest < 1e-9):
        raise InputError("quaternion must be non-zero", argument="quaternion", value=quaternion)
    q = q / largest  # no overflow in the norm of huge quaternions
    w, x, y, z = np.moveaxis(q / np.linalg.norm(q, axis=-1, keepdims=True), -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def matrix_from_rpy(rpy: npt.ArrayLike) -> FloatArray:
    """Rotation matrices (..., 3, 3) = Rz(yaw) Ry(pitch) Rx(roll) from (..., 3) [rad]."""
    angles = _finite(rpy, "rpy", 3)
    cr, cp, cy = np.moveaxis(np.cos(angles), -1, 0)
    sr, sp, sy = np.moveaxis(np.sin(angles), -1, 0)
    return np.stack(
        [
            np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
            np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
            np.stack([-sp, cp * sr, cp * cr], -1),
        ],
        axis=-2,
    )


def rpy_from_matrix(R: npt.ArrayLike) -> FloatArray:
    """Roll, pitch, yaw [rad], (..., 3), of rotation matrices (..., 3, 3).

    Raises:
        InputError: R is not (a batch of) rotation matrices.
    """
    m = as_rotation(R)
    yaw = np.arctan2(m[..., 1, 0], m[..., 0, 0])
    pitch = np.arctan2(-m[..., 2, 0], np.hypot(m[..., 2, 1], m[..., 2, 2]))
    roll = np.arctan2(m[..., 2, 1], m[..., 2, 2])
    return np.stack([roll, pitch, yaw], axis=-1)


def quaternion_from_matrix(R: npt.ArrayLike) -> FloatArray:
    """Unit quaternions (..., 4) = (w, x, y, z) with w >= 0 of rotation matrices.

    Raises:
        InputError: R is not (a batch of) rotation matrices.
    """
    return _quaternion(as_rotation(R))


def _quaternion(m: FloatArray) -> FloatArray:
    """:func:`quaternion_from_matrix` of checked rotation matrices ``m`` (..., 3, 3)."""
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    # Row k equals 4 q_k q; use the row with the largest diagonal entry 4 q_k^2.
    rows = np.stack(
        [
            np.stack([1 + m00 + m11 + m22, m21 - m12, m02 - m20, m10 - m01], -1),
            np.stack([m21 - m12, 1 + m00 - m11 - m22, m01 + m10, m02 + m20], -1),
            np.stack([m02 - m20, m01 + m10, 1 - m00 + m11 - m22, m12 + m21], -1),
            np.stack([m10 - m01, m02 + m20, m12 + m21, 1 - m00 - m11 + m22], -1),
        ],
        axis=-2,
    )
    diagonal = np.diagonal(rows, axis1=-2, axis2=-1)
    k = np.argmax(diagonal, axis=-1)
    row = np.take_along_axis(rows, k[..., None, None], axis=-2)[..., 0, :]
    q = row / (2.0 * np.sqrt(np.take_along_axis(diagonal, k[..., None], axis=-1)))
    result: FloatArray = np.where(q[..., :1] < 0, -q, q)
    return result


# ---------------------------------------------------------------------------- SO(3)
def skew(vectors: npt.ArrayLike) -> FloatArray:
    """Cross-product matrices [v] (..., 3, 3) of vectors v (..., 3): [v] u = v x u.

    [v] = ((0, -z, y), (z, 0, -x), (-y, x, 0)) for v = (x, y, z).

    Raises:
        InputError: vectors are not finite numbers of shape (3,) or (..., 3).
    """
    v = _finite(vectors, "vectors", 3)
    out = np.zeros((*v.shape, 3))
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    out[..., 0, 1], out[..., 0, 2] = -z, y
    out[..., 1, 0], out[..., 1, 2] = z, -x
    out[..., 2, 0], out[..., 2, 1] = -y, x
    return out


def exp_so3(rotvec: npt.ArrayLike) -> FloatArray:
    """Rotation matrix (3, 3) exp([r]) of one rotation vector r (3,) [rad] (Rodrigues).

    exp([r]) = I + (sin t / t) [r] + ((1 - cos t) / t^2) [r]^2 with t = |r|; below
    t = 1e-4 the coefficients are their Taylor series (exact to rounding).

    Raises:
        InputError: rotvec is not 3 finite numbers.
    """
    K, a, b, _ = _so3_terms(_rotation_vector(rotvec))
    result: FloatArray = np.eye(3) + a * K + b * (K @ K)
    return result


def log_so3(R: npt.ArrayLike) -> FloatArray:
    """Rotation vector r (3,) [rad], |r| <= pi, of one rotation matrix: exp([r]) = R.

    From the quaternion (w, q) of R with w >= 0: r = 2 atan2(|q|, w) q / |q|, which is
    precise at every angle (r = 2 q when |q| < 1e-12).

    Raises:
        InputError: R is not one rotation matrix (3, 3).
    """
    m = as_rotation(R)
    if m.shape != (3, 3):
        raise InputError(f"R must be one rotation matrix (3, 3), got shape {m.shape}", argument="R")
    q = _quaternion(m)
    w, v = float(q[0]), q[1:]
    s = float(np.linalg.norm(v))
    if s < 1e-12:
        result: FloatArray = 2.0 * v
        return result
    return 2.0 * math.atan2(s, w) * v / s


def left_jacobian_so3(rotvec: npt.ArrayLike) -> FloatArray:
    """Left Jacobian J_l (3, 3) of SO(3) at rotation vector r (3,) [rad].

    exp([r + dr]) = exp([J_l dr]) exp([r]) to first order, and
    J_l = I + ((1 - cos t) / t^2) [r] + ((t - sin t) / t^3) [r]^2 with t = |r|
    (Taylor series below t = 1e-4). J_l(r) = R J_r(r) with R = exp([r]).

    Raises:
        InputError: rotvec is not 3 finite numbers.
    """
    return _left_jacobian(_rotation_vector(rotvec))


def right_jacobian_so3(rotvec: npt.ArrayLike) -> FloatArray:
    """Right Jacobian J_r (3, 3) of SO(3) at rotation vector r (3,) [rad].

    exp([r + dr]) = exp([r]) exp([J_r dr]) to first order; J_r(r) = J_l(-r)
    (:func:`left_jacobian_so3`). This is Pinocchio's ``Jexp3``.

    Raises:
        InputError: rotvec is not 3 finite numbers.
    """
    return _left_jacobian(-_rotation_vector(rotvec))


def _rotation_vector(rotvec: npt.ArrayLike) -> FloatArray:
    r = _finite(rotvec, "rotvec", 3)
    if r.shape != (3,):
        raise InputError(
            f"rotvec must be one rotation vector of shape (3,), got {r.shape}",
            argument="rotvec",
            value=rotvec,
        )
    return r


def _so3_terms(rotvec: FloatArray) -> tuple[FloatArray, float, float, float]:
    """K = [rotvec], sin t / t, (1 - cos t) / t^2, (t - sin t) / t^3 (series near 0)."""
    t = float(np.linalg.norm(rotvec))
    K = skew(rotvec)
    if t < 1e-4:
        t2 = t * t
        return K, 1.0 - t2 / 6.0, 0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0
    return K, math.sin(t) / t, (1.0 - math.cos(t)) / t**2, (t - math.sin(t)) / t**3


def _left_jacobian(rotvec: FloatArray) -> FloatArray:
    """:func:`left_jacobian_so3` of a checked rotation vector."""
    K, _, b, c = _so3_terms(rotvec)
    result: FloatArray = np.eye(3) + b * K + c * (K @ K)
    return result
