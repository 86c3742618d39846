"""What a workspace map computes: :class:`WorkspaceSettings`, the clearance ladder and
the checks of the numbers and counts given to a map."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..errors import InputError

__all__ = [
    "CLEARANCE_LADDER",
    "MAX_COUNT",
    "WorkspaceSettings",
    "check_count",
    "check_number",
]

#: Margins at which the clearance is bracketed [m]: the clearance field reads the
#: largest level at which no link pair collides (a lower bound of the distance).
#: (Larger margins make each check slower: the BVHs then have more to look at.)
CLEARANCE_LADDER: tuple[float, ...] = (
    0.0,
    0.00025,
    0.0005,
    0.00075,
    0.001,
    0.0015,
    0.002,
    0.003,
    0.004,
    0.005,
)


@dataclasses.dataclass(frozen=True)
class WorkspaceSettings:
    """What a map computes (picklable: it travels to the workers).

    Attributes:
        margin: Safety margin of the safe set [m].
        min_dexterity: Smallest dexterity (1/kappa_2(J)) of the safe set.
        clearance: Compute the clearance field (several collision checks per point).
        ladder: Margins of the clearance field [m], increasing from 0.
    """

    margin: float = 0.0
    min_dexterity: float = 0.2
    clearance: bool = True
    ladder: tuple[float, ...] = CLEARANCE_LADDER

    def __post_init__(self) -> None:
        check_number("margin", self.margin, 0.0, 1.0)
        check_number("min_dexterity", self.min_dexterity, 0.0, 1.0)
        if not isinstance(self.clearance, (bool, np.bool_)):
            raise InputError(
                f"clearance must be True or False, got {self.clearance!r}",
                argument="clearance",
                value=self.clearance,
            )


def check_number(name: str, value: object, low: float, high: float = math.inf) -> float:
    """``value`` as a float, or InputError naming ``name`` unless it is a finite number
    in [low, high] (bools refused)."""
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not -1e308 <= value <= 1e308  # NaN, inf and ints too large for a float
        or not math.isfinite(float(value))
        or not low <= float(value) <= high
    ):
        raise InputError(
            f"{name} must be a finite number in [{low:g}, {high:g}], got {value!r}",
            argument=name,
            value=value,
        )
    return float(value)


#: Largest count accepted (samples, seed, workers, chunk size).
MAX_COUNT = 2**32


def check_count(name: str, value: object, low: int = 1) -> int:
    """``value`` as an int, or InputError naming ``name`` unless it is an integer in
    [low, :data:`MAX_COUNT`] (bools refused)."""
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, np.integer))
        or not low <= value <= MAX_COUNT
    ):
        raise InputError(
            f"{name} must be an integer in [{low}, {MAX_COUNT}], got {value!r}",
            argument=name,
            value=value,
        )
    return int(value)
