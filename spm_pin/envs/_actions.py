"""The check of the environments' actions: numbers of the expected shape, finite.

Values outside [-1, 1] are not refused: the step clips them. A single environment's
three numbers are checked with the least work (:func:`fill_action`), since that check
runs at every step of a policy's rollout.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ..errors import InputError

__all__ = ["check_actions", "fill_action"]

#: Actions checked in Python rather than by numpy (a single environment's three).
_FEW = 8


def _finite(values: npt.NDArray[np.float64]) -> bool:
    """Every value finite (a few: in Python, faster than numpy's call for them)."""
    if values.size <= _FEW:
        return all(map(math.isfinite, values.flat))
    return bool(np.isfinite(values).all())


def check_actions(actions: npt.ArrayLike, shape: tuple[int, ...]) -> npt.NDArray[np.float64]:
    """Actions as floats of ``shape``, finite; InputError otherwise (values outside
    [-1, 1] are clipped by the step)."""
    try:
        values = np.asarray(actions, dtype=float)
    except (TypeError, ValueError):
        raise InputError(
            f"action must be numbers of shape {shape}, got {actions!r}",
            argument="action",
            value=actions,
        ) from None
    if values.shape != shape or not _finite(values):
        raise InputError(
            f"action must be finite numbers of shape {shape}, got shape {values.shape}",
            argument="action",
            value=actions,
        )
    return values


def fill_action(row: npt.NDArray[np.float64], action: npt.ArrayLike) -> None:
    """Write one robot's action (3,) into ``row`` (3,) as :func:`check_actions` checks
    it (InputError, ``row`` left as it was, for a wrong shape or a value that is not
    finite): a float array of shape (3,) is copied at once, anything else checked
    first."""
    if type(action) is np.ndarray and action.shape == (3,) and action.dtype.kind == "f":
        x, y, z = action.tolist()
        if math.isfinite(x) and math.isfinite(y) and math.isfinite(z):
            row[0], row[1], row[2] = x, y, z
            return
    row[:] = check_actions(action, (3,))
