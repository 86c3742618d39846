"""The library's one boundary for numbers: input checks shared by every layer.

Angles, rotations, counts and designs given by the user are checked here once and
handed on as checked float arrays; every message names the argument, the value and
what is allowed (see the conventions page, "Bad numbers: one boundary").
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from .design import SPMDesign
from .errors import InputError

__all__ = [
    "ANGLE_LIMIT",
    "ROTATION_TOL",
    "BoolArray",
    "FloatArray",
    "as_rotation",
    "as_theta",
    "check_count",
    "check_design",
    "float_array",
    "require_angles",
    "require_bounded",
    "require_finite",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Largest |R^T R - I| accepted for a rotation matrix given by the user.
ROTATION_TOL = 1e-6

#: Largest |angle| accepted for an input or joint angle [rad]: 2**11 = 2048 rad
#: (326 turns). Angles keep their turns (multi-turn inputs, unwrapped yaw), so the
#: kinematics do angle arithmetic (the common-turn split of a coaxial SPM, joint
#: offsets) on the caller's value before sin/cos. Each rounding moves the angle by up
#: to half the spacing of doubles at |angle|, which is 2**-42 = 2.3e-13 rad below
#: 2048 rad and doubles with every power of two above: up to 2048 rad the closure
#: residual of a solution stays below the solver tolerance 1e-12 (measured worst
#: 4.5e-13; from 4096 rad on it reaches 1e-12, at 2**22 rad 1.6e-10), so a result is
#: never reported as closed with a residual above the tolerance. The limit covers
#: the multi-turn range of the servos (extended position mode, +-256 turns =
#: +-1608 rad). Larger values, NaN and inf are refused before they reach math or
#: numpy.
ANGLE_LIMIT = 2048.0


def check_design(design: SPMDesign | str | None) -> SPMDesign:
    """Return ``design``, the preset it names, or the prototype for None.

    A string is a preset name or a design file (:meth:`SPMDesign.from_spec`); anything
    else that is not an SPMDesign is rejected.

    Raises:
        InputError: ``design`` is neither an SPMDesign, a string nor None.
        DesignError: a string that names neither a preset nor a file (it lists the
            presets).
        FileFormatError: a design file that cannot be read.
    """
    if design is None:
        return SPMDesign.prototype()
    if isinstance(design, SPMDesign):
        return design
    if isinstance(design, str):
        return SPMDesign.from_spec(design)
    raise InputError(
        "design must be an SPMDesign, a preset name "
        f"({', '.join(SPMDesign.preset_names())}) or a design file, got {type(design).__name__}",
        argument="design",
        value=design,
    )


def float_array(value: object, name: str, message: str) -> FloatArray:
    """``value`` as a new float array, or InputError(``message``) if it is not numbers."""
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
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


def require_angles(array: FloatArray, name: str, value: object) -> None:
    """InputError unless every entry of ``array`` is finite with |angle| <= ANGLE_LIMIT.

    The one rule for angles [rad] given by the user; the message names the allowed
    range (see :data:`ANGLE_LIMIT` for why it lies there).
    """
    require_bounded(
        array,
        name,
        value,
        ANGLE_LIMIT,
        "rad (326 turns, the range where float64 keeps angles within the 1e-12 closure tolerance)",
    )


def require_bounded(
    array: FloatArray, name: str, value: object, limit: float, unit: str = ""
) -> None:
    """InputError unless every entry of ``array`` is finite with |entry| <= ``limit``."""
    ok = np.isfinite(array) & (np.abs(array) <= limit)
    if not np.all(ok):
        bad = tuple(int(i) for i in np.argwhere(~ok)[0])
        raise InputError(
            f"{name} must be finite with |{name}| <= {limit:g}{' ' + unit if unit else ''}, "
            f"got {array[bad]}{' at index ' + str(bad) if bad else ''}",
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
    """Input angles as a float array of shape (..., 3), or InputError.

    The one boundary for input angles: numbers (not strings, None or objects), shape
    (3,) or (..., 3) (an empty batch (0, 3) is allowed and gives empty results),
    finite and |theta| <= :data:`ANGLE_LIMIT`. The value keeps its turns; code
    reduces angles only where it needs sin and cos.
    """

    def not_numbers() -> InputError:  # the message only when it is needed
        return InputError(
            f"{name} must be numbers [rad] of shape (3,) or (..., 3), got {theta!r}",
            argument=name,
            value=theta,
        )

    if isinstance(theta, (str, bytes)):  # numpy would read "1e3" as a number
        raise not_numbers()
    try:
        array = np.asarray(theta, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise not_numbers() from exc
    if array.ndim == 0 or array.shape[-1] != 3:
        raise InputError(
            f"{name} must have shape (3,) or (..., 3) [rad], got shape {array.shape}",
            argument=name,
            value=theta,
        )
    require_angles(array, name, theta)
    return array


def _plainly_rotation(rows: list[list[float]]) -> bool:
    """Whether one 3 x 3 matrix (rows) is a rotation with a wide berth: |R^T R - I| at
    most half of ``ROTATION_TOL`` and det above 1/2 (a near-orthonormal matrix has det
    near +1 or -1), in Python floats. Anything else (NaN, inf, near the tolerance) is
    left to the array check, so the answer never differs from it."""
    (a, b, c), (d, e, f), (g, h, i) = rows
    if not math.isfinite(a + b + c + d + e + f + g + h + i):
        return False
    error = max(
        abs(a * a + d * d + g * g - 1.0),
        abs(b * b + e * e + h * h - 1.0),
        abs(c * c + f * f + i * i - 1.0),
        abs(a * b + d * e + g * h),
        abs(a * c + d * f + g * i),
        abs(b * c + e * f + h * i),
    )
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    return error <= 0.5 * ROTATION_TOL and det > 0.5


def as_rotation(rotation: npt.ArrayLike, name: str = "R") -> FloatArray:
    """Rotation matrices of shape (..., 3, 3), orthonormal with det +1, or InputError."""
    try:
        array = np.asarray(rotation, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
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
    if array.shape == (3, 3) and _plainly_rotation(array.tolist()):
        return array  # one rotation far inside the tolerance (a control loop's case)
    if not np.all(np.isfinite(array)):
        raise InputError(f"{name} must be finite, got NaN or inf", argument=name, value=rotation)
    with np.errstate(over="ignore", invalid="ignore"):  # huge entries: error inf, refused
        error = np.abs(np.swapaxes(array, -1, -2) @ array - np.eye(3)).max(axis=(-2, -1))
        det = np.linalg.det(array)
    bad = ~(error <= ROTATION_TOL) | ~(det >= 0)  # NaN (inf - inf) is refused too
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
