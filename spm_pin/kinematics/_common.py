"""Shared helpers of the analytic kinematics: input checks and leg geometry."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..errors import InputError

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Largest |R^T R - I| accepted for a rotation matrix given by the user.
ROTATION_TOL = 1e-6


def check_design(design: SPMDesign | None) -> SPMDesign:
    """Return ``design`` or the prototype; reject anything that is not an SPMDesign."""
    if design is None:
        return SPMDesign.prototype()
    if not isinstance(design, SPMDesign):
        raise InputError(
            f"design must be an SPMDesign, got {type(design).__name__}",
            argument="design",
            value=design,
        )
    return design


def float_array(value: object, name: str, message: str) -> FloatArray:
    """``value`` as a new float array, or InputError(``message``) if it is not numbers."""
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(message, argument=name, value=value) from exc


def require_finite(array: FloatArray, name: str, value: object, unit: str = "") -> None:
    """InputError naming the first NaN or inf entry of ``array`` (given as ``value``)."""
    finite = np.isfinite(array)
    if not np.all(finite):
        bad = tuple(int(i) for i in np.argwhere(~finite)[0])
        raise InputError(
            f"{name} must be finite{' ' + unit if unit else ''}, got {array[bad]} at index {bad}",
            argument=name,
            value=value,
        )


def check_count(value: object, name: str, minimum: int) -> int:
    """An integer (not bool) >= ``minimum``, or InputError."""
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < minimum:
        raise InputError(
            f"{name} must be an integer >= {minimum}, got {value!r}", argument=name, value=value
        )
    return int(value)


def as_theta(theta: npt.ArrayLike, name: str = "theta") -> FloatArray:
    """Input angles as a float array of shape (..., 3), finite, or InputError."""
    try:
        array = np.asarray(theta, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"{name} must be numbers [rad] of shape (3,) or (..., 3), got {theta!r}",
            argument=name,
            value=theta,
        ) from exc
    if array.ndim == 0 or array.shape[-1] != 3:
        raise InputError(
            f"{name} must have shape (3,) or (..., 3) [rad], got shape {array.shape}",
            argument=name,
            value=theta,
        )
    require_finite(array, name, theta)
    return array


def as_rotation(rotation: npt.ArrayLike, name: str = "R") -> FloatArray:
    """Rotation matrices of shape (..., 3, 3), orthonormal with det +1, or InputError."""
    try:
        array = np.asarray(rotation, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"{name} must be rotation matrices of shape (3, 3) or (..., 3, 3), got {rotation!r}",
            argument=name,
            value=rotation,
        ) from exc
    if array.ndim < 2 or array.shape[-2:] != (3, 3):
        raise InputError(
            f"{name} must have shape (3, 3) or (..., 3, 3), got shape {array.shape}",
            argument=name,
            value=rotation,
        )
    if not np.all(np.isfinite(array)):
        raise InputError(f"{name} must be finite, got NaN or inf", argument=name, value=rotation)
    error = np.abs(np.swapaxes(array, -1, -2) @ array - np.eye(3)).max(axis=(-2, -1))
    det = np.linalg.det(array)
    bad = (error > ROTATION_TOL) | (det < 0)
    if np.any(bad):
        index = tuple(int(i) for i in np.argwhere(np.atleast_1d(bad))[0])
        flat_error = np.atleast_1d(error)[index]
        flat_det = np.atleast_1d(det)[index]
        raise InputError(
            f"{name} is not a rotation matrix (|R^T R - I| = {flat_error:.3g}, det = "
            f"{flat_det:.6g}{', at batch index ' + str(index) if array.ndim > 2 else ''}); "
            f"allowed: orthonormal within {ROTATION_TOL:g} with det +1",
            argument=name,
            value=rotation,
        )
    return array


def cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross product over the last axis (length 3), with broadcasting.

    The same as ``np.cross`` written out by components: several times faster on
    large batches of 3-vectors.
    """
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def rotate_about(axes: FloatArray, angles: FloatArray, vectors: FloatArray) -> FloatArray:
    """Rodrigues: turn ``vectors`` about unit ``axes`` by ``angles`` (right-handed).

    Shapes broadcast: axes (..., 3), angles (...), vectors (..., 3).
    """
    c = np.cos(angles)[..., None]
    s = np.sin(angles)[..., None]
    along = np.sum(axes * vectors, axis=-1, keepdims=True) * axes
    result: FloatArray = along + c * (vectors - along) + s * cross(axes, vectors)
    return result


def proximal_axes(theta: FloatArray, design: SPMDesign) -> FloatArray:
    """w_i(theta_i) = rotation of w_i0 about u_i by theta_i; rows, shape (..., 3, 3)."""
    return rotate_about(design.u, theta, design.w0)


def rotation_about(axis: FloatArray, angles: FloatArray) -> FloatArray:
    """Rotation matrices (..., 3, 3) about one unit ``axis`` by ``angles`` (...)."""
    c = np.cos(angles)[..., None, None]
    s = np.sin(angles)[..., None, None]
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    outer = np.outer(axis, axis)
    result: FloatArray = c * np.eye(3) + s * k + (1.0 - c) * outer
    return result


def mode_label(signs: npt.ArrayLike) -> str:
    """'+-+' style label from three signs (b_ii > 0 is '+')."""
    return "".join("+" if s > 0 else "-" for s in np.asarray(signs).ravel())
