"""Shared helpers of the analytic kinematics: leg geometry, and the input checks of
:mod:`spm_pin._checks` under the names the library has always imported from here."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .._checks import ANGLE_LIMIT as ANGLE_LIMIT
from .._checks import ROTATION_TOL as ROTATION_TOL
from .._checks import BoolArray as BoolArray
from .._checks import FloatArray as FloatArray
from .._checks import as_rotation as as_rotation
from .._checks import as_theta as as_theta
from .._checks import check_count as check_count
from .._checks import check_design as check_design
from .._checks import float_array as float_array
from .._checks import require_angles as require_angles
from .._checks import require_bounded as require_bounded
from .._checks import require_finite as require_finite
from ..design import SPMDesign


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
