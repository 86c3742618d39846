"""Constants of the calibration (parameter names and groups, losses, tolerances), its
warning class, and the small argument checks and number formats its modules share."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import FileFormatError, InputError

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]


#: Encoder counts per turn of the Dynamixel XM540 (0.088 deg per count): the pulses
#: per servo turn of :mod:`spm_pin.hardware`.
TICKS_PER_TURN = 4096

#: Every parameter that can be identified, in the order in which they are kept free
#: when the readings cannot separate some of them.
PARAMETER_NAMES: tuple[str, ...] = (
    "offset_1",
    "offset_2",
    "offset_3",
    "alpha1",
    "alpha2",
    "beta",
    "mount_x",
    "mount_y",
    "mount_z",
    "ref_x",
    "ref_y",
    "ref_z",
)

#: Group names accepted wherever parameter names are.
PARAMETER_GROUPS: dict[str, tuple[str, ...]] = {
    "offsets": PARAMETER_NAMES[0:3],
    "links": PARAMETER_NAMES[3:6],
    "mount": PARAMETER_NAMES[6:9],
    "ref": PARAMETER_NAMES[9:12],
}

#: Parameters identified by default, per kind of orientation reading.
DEFAULT_PARAMETERS: dict[str, tuple[str, ...]] = {
    "quaternion": PARAMETER_NAMES[0:9],
    "axes": PARAMETER_NAMES[0:6],
}

#: Residual components per reading, per kind.
COMPONENTS = {"quaternion": 3, "axes": 6}

#: Robust losses of scipy.optimize.least_squares and their IRLS weights rho'(z), z = (r/f)^2.
LOSS_WEIGHTS: dict[str, Callable[[FloatArray], FloatArray]] = {
    "linear": lambda z: np.ones_like(z),
    "soft_l1": lambda z: 1.0 / np.sqrt(1.0 + z),
    "huber": lambda z: np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1.0))),
    "cauchy": lambda z: 1.0 / (1.0 + z),
    "arctan": lambda z: 1.0 / (1.0 + z * z),
}

#: Their psi'(r) = d(r rho'(z))/dr = rho'(z) + 2 z rho''(z), for the covariance.
LOSS_SLOPES: dict[str, Callable[[FloatArray], FloatArray]] = {
    "linear": lambda z: np.ones_like(z),
    "soft_l1": lambda z: (1.0 + z) ** -1.5,
    "huber": lambda z: np.where(z <= 1.0, 1.0, 0.0),
    "cauchy": lambda z: (1.0 - z) / (1.0 + z) ** 2,
    "arctan": lambda z: (1.0 - 3.0 * z * z) / (1.0 + z * z) ** 2,
}

#: Relative singular value (column-normalised Jacobian) at or below which a direction
#: of the parameter space is not identifiable.
RANK_TOL = 1e-6
#: Condition number (column-normalised Jacobian) above which the identification is
#: reported as poorly conditioned.
MAX_CONDITION = 1000.0
#: |correlation| at or above which two estimates are reported as not separated.
MAX_CORRELATION = 0.99
#: Robust loss scale in units of the noise level.
LOSS_SCALE = 3.0
#: Residual [rad] given to a reading the candidate model cannot assemble.
UNREACHABLE_RESIDUAL = 1.0
#: A measured quaternion or axis may differ from unit length by this much.
UNIT_TOL = 0.01
#: Probability of a reading flagged as an outlier by chance.
OUTLIER_P = 1e-3
#: Parameters whose column of the Jacobian is this small (relative) have no effect.
NO_EFFECT = 1e-10

SERVO_UNITS = ("ticks", "deg", "rad")
ANGLE_UNITS = ("deg", "rad")


class IdentifiabilityWarning(UserWarning):
    """The readings cannot separate some parameters (or only poorly).

    The identified values of the other parameters are real estimates; the ones named
    in the warning keep their starting values and have infinite intervals.
    """


def as_triple(value: Any, name: str) -> tuple[float, float, float]:
    """Three finite floats from 3 numbers or 1 (repeated), or InputError naming ``name``."""
    try:
        array = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(
            f"{name} must be 3 numbers, got {value!r}", argument=name, value=value
        ) from exc
    if array.size == 1:
        array = np.repeat(array, 3)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise InputError(
            f"{name} must be 3 finite numbers, got {value!r}", argument=name, value=value
        )
    return (float(array[0]), float(array[1]), float(array[2]))


def format_float(value: float) -> str:
    """A float with 12 significant digits (round-trips what the readings hold)."""
    return f"{float(value) + 0.0:.12g}"


def parse_number(field: str, column: str, line: int, source: str | None) -> float:
    """The finite number in a field of a CSV file, or FileFormatError at its line."""
    if field == "":
        raise FileFormatError(f"column {column}: missing value", path=source, line=line)
    try:
        value = float(field)
    except ValueError:
        raise FileFormatError(
            f"column {column}: {field!r} is not a number", path=source, line=line
        ) from None
    if not math.isfinite(value):
        raise FileFormatError(
            f"column {column}: {field!r} is not allowed; values must be finite numbers",
            path=source,
            line=line,
        )
    return value


def check_positive(value: Any, name: str) -> float:
    """A positive finite number (not a bool), or InputError naming ``name``."""
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.floating))
        or not math.isfinite(value)
        or value <= 0
    ):
        raise InputError(
            f"{name} must be a positive finite number, got {value!r}", argument=name, value=value
        )
    return float(value)


def check_count(value: Any, name: str) -> int:
    """A positive integer (not a bool), or InputError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise InputError(
            f"{name} must be a positive integer, got {value!r}", argument=name, value=value
        )
    return int(value)
