"""Conversions between rotation matrices, quaternions and roll/pitch/yaw angles.

Conventions: quaternions are (w, x, y, z), scalar first, unit norm;
roll/pitch/yaw are the fixed-axis X-Y-Z angles, R = Rz(yaw) Ry(pitch) Rx(roll).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ._checks import as_rotation
from .errors import InputError

__all__ = ["matrix_from_quaternion", "matrix_from_rpy", "quaternion_from_matrix", "rpy_from_matrix"]

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
    m = as_rotation(R)
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
