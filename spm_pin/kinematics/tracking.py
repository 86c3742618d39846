"""Following one assembly mode continuously along a path of inputs.

At every sample all assembly modes are solved (:func:`forward_kinematics_all`) and the
one nearest to the previous platform orientation is kept. When that choice is not
clear-cut (the nearest mode is not much nearer than the next one, or the platform
moved a lot), the step is halved and the midpoint solved first, recursively. Inputs
may turn any number of times; the platform yaw about z is unwrapped, so endless
rotation of a coaxial SPM is reported as a growing angle.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..errors import InputError, UnreachableError
from ._common import BoolArray, FloatArray, as_rotation, as_theta, check_design
from .fk import forward_kinematics_all

__all__ = ["TrackResult", "track"]

#: The nearest mode must be this many times nearer than the second nearest.
_CLEAR_RATIO = 3.0
#: Largest accepted change of R (Frobenius norm) in one accepted step.
_MAX_JUMP = 0.5


@dataclasses.dataclass(frozen=True)
class TrackResult:
    """A mode followed along a path.

    Attributes:
        theta: (N, 3) the inputs [rad].
        R: (N, 3, 3) platform rotations; NaN from the first sample where the mode was
            lost (it ceased to exist, e.g. past the edge of the workspace).
        v: (N, 3, 3) platform joint axes (rows).
        home: (N,) the followed mode satisfies the home sign rule at that sample.
        labels: (N,) mode labels such as ``"+++/-"`` ('' where lost).
        yaw: (N,) unwrapped platform yaw about z [rad] (continuous over many turns).
        lost: (N,) no continuous solution at or before this sample.
        subdivisions: number of extra midpoints solved to keep continuity.
    """

    theta: FloatArray
    R: FloatArray
    v: FloatArray
    home: BoolArray
    labels: list[str]
    yaw: FloatArray
    lost: BoolArray
    subdivisions: int


class _Follower:
    def __init__(self, design: SPMDesign, max_depth: int) -> None:
        self.design = design
        self.max_depth = max_depth
        self.subdivisions = 0

    def step(
        self, theta_prev: FloatArray, R_prev: FloatArray, theta: FloatArray, depth: int = 0
    ) -> tuple[FloatArray, bool, str, float] | None:
        """(R, home, label, yaw change) at ``theta``, continuing from ``R_prev``."""
        out = forward_kinematics_all(theta, self.design)
        valid = out.valid
        if not np.any(valid):
            return None
        dist = np.where(valid, np.linalg.norm(out.R - R_prev, axis=(-2, -1)), np.inf)
        order = np.argsort(dist)
        nearest, second = dist[order[0]], dist[order[1]]
        clear = nearest * _CLEAR_RATIO < second and nearest < _MAX_JUMP
        if not clear and depth < self.max_depth:
            self.subdivisions += 1
            middle = 0.5 * (theta_prev + theta)
            half = self.step(theta_prev, R_prev, middle, depth + 1)
            if half is not None:
                rest = self.step(middle, half[0], theta, depth + 1)
                if rest is not None:
                    return rest[0], rest[1], rest[2], half[3] + rest[3]
        if not np.isfinite(nearest) or nearest > 2 * _MAX_JUMP:
            return None
        k = int(order[0])
        change = _yaw(out.R[k]) - _yaw(R_prev)
        change = float(np.pi - np.mod(np.pi - change, 2 * np.pi))
        return out.R[k], bool(out.home[k]), str(out.labels[k]), change


def _yaw(R: FloatArray) -> float:
    return float(np.arctan2(R[1, 0], R[0, 0]))


def track(
    theta_path: npt.ArrayLike,
    design: SPMDesign | str | None = None,
    *,
    start: npt.ArrayLike | None = None,
    max_depth: int = 10,
) -> TrackResult:
    """Follow one assembly mode continuously along a path of inputs.

    Args:
        theta_path: Inputs [rad], shape (N, 3), N >= 1, in order; any number of turns.
        design: The SPM (default: the prototype).
        start: Platform rotation at the first sample (the mode nearest to it is
            followed); default: the home assembly mode at the first sample.
        max_depth: Largest number of successive step halvings.

    Raises:
        UnreachableError: no start mode exists at the first sample.
        InputError: bad shapes or values.
    """
    design = check_design(design)
    path = as_theta(theta_path, "theta_path")
    if path.ndim != 2 or path.shape[0] < 1:
        raise InputError(
            f"theta_path must have shape (N, 3) with N >= 1, got {path.shape}",
            argument="theta_path",
            value=theta_path,
        )
    if not isinstance(max_depth, int) or max_depth < 0:
        raise InputError(
            f"max_depth must be a non-negative integer, got {max_depth!r}",
            argument="max_depth",
            value=max_depth,
        )
    n = path.shape[0]
    first = forward_kinematics_all(path[0], design)
    if start is None:
        k = int(first.home_index)
        if k < 0:
            raise UnreachableError(
                "no home-mode assembly at the first sample, theta = "
                f"{np.degrees(path[0]).round(6).tolist()} deg; pass start= to follow another mode",
                value=path[0],
            )
    else:
        R_start = as_rotation(start, "start")
        if R_start.shape != (3, 3):
            raise InputError(
                f"start must be one rotation (3, 3), got {R_start.shape}", argument="start"
            )
        if not np.any(first.valid):
            raise UnreachableError(
                f"no assembly mode at all at theta = {np.degrees(path[0]).round(6).tolist()} deg",
                value=path[0],
            )
        dist = np.where(first.valid, np.linalg.norm(first.R - R_start, axis=(-2, -1)), np.inf)
        k = int(np.argmin(dist))
    R = np.full((n, 3, 3), np.nan)
    home = np.zeros(n, dtype=bool)
    labels = [""] * n
    lost = np.zeros(n, dtype=bool)
    R[0], home[0], labels[0] = first.R[k], bool(first.home[k]), str(first.labels[k])
    follower = _Follower(design, max_depth)
    yaw = np.full(n, np.nan)
    yaw[0] = _yaw(R[0])
    for i in range(1, n):
        result = follower.step(path[i - 1], R[i - 1], path[i])
        if result is None:
            lost[i:] = True
            break
        R[i], home[i], labels[i], change = result
        yaw[i] = yaw[i - 1] + change
    v = np.einsum("njk,ik->nij", R, design.v0)
    return TrackResult(
        theta=path,
        R=R,
        v=v,
        home=home,
        labels=labels,
        yaw=yaw,
        lost=lost,
        subdivisions=follower.subdivisions,
    )
