"""Input checks of the dynamics: speeds, torques and accelerations within physical bounds.

Every array the dynamics is given passes here once: finite, of the expected shape and
within :data:`LIMITS` for its unit, or an :class:`~spm_pin.InputError` that names the
argument, the value and what is allowed.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .._checks import ANGLE_LIMIT, float_array, require_bounded, require_finite
from ..errors import InputError
from ._constants import FloatArray

__all__ = [
    "LIMITS",
    "array3",
    "bounded",
    "broadcast",
    "nonnegative_vector",
    "positive",
    "values",
    "vector",
]


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


def bounded(array: FloatArray, name: str, value: Any, unit: str) -> None:
    """InputError for NaN, inf or a value beyond LIMITS[unit] (finite only if no limit)."""
    limit = LIMITS.get(unit)
    if limit is None:
        require_finite(array, name, value, unit)
    else:
        require_bounded(array, name, value, limit, unit)


def values(value: Any, name: str, unit: str) -> FloatArray:
    """Numbers of any shape, finite and within LIMITS[unit], or InputError."""
    if isinstance(value, (str, bytes)):
        raise InputError(
            f"{name} must be numbers {unit}, got {value!r}", argument=name, value=value
        )
    array = float_array(value, name, f"{name} must be numbers {unit}, got {value!r}")
    bounded(array, name, value, unit)
    return array


def broadcast(*arrays: FloatArray, names: str) -> None:
    """InputError unless the arrays' shapes broadcast together."""
    try:
        np.broadcast_shapes(*(a.shape for a in arrays))
    except ValueError as exc:
        raise InputError(
            f"{names} must have shapes that broadcast, got {[a.shape for a in arrays]}",
            argument=names.split(",")[0],
            value=None,
        ) from exc


def vector(value: Any, size: int, name: str, unit: str) -> FloatArray:
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
    bounded(array, name, value, unit)
    return array


def array3(value: Any, name: str, unit: str) -> FloatArray:
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
    bounded(array, name, value, unit)
    return array


def positive(value: Any, name: str, unit: str, *, allow_zero: bool = False) -> float:
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


def nonnegative_vector(value: Any, size: int, name: str, unit: str) -> FloatArray:
    """A vector as :func:`vector` with every entry >= 0, or InputError."""
    array = vector(value, size, name, unit)
    if np.any(array < 0.0):
        raise InputError(
            f"{name} must be >= 0 {unit}, got {array.tolist()}", argument=name, value=value
        )
    return array
