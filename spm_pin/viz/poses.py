"""What the viewer shows for what it is given: input angles or configurations.

:func:`configuration` turns a pose, input angles theta (3,) in an assembly mode or a
joint configuration q (9,), into the configuration q drawn and the label of its
assembly mode; :func:`path_configurations` does the same for a path, following input
angles continuously in one assembly mode (:func:`~spm_pin.track`). Both check their
arguments and raise :class:`~spm_pin.errors.InputError` with the argument's name.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..errors import InputError, UnreachableError
from ..kinematics import track
from ..kinematics.assembly import home_mode_label, select_assembly
from ..model.robot import SPMRobot

__all__ = ["configuration", "path_configurations"]

FloatArray = npt.NDArray[np.float64]


def configuration(
    robot: SPMRobot, x: npt.ArrayLike, mode: str
) -> tuple[FloatArray, str | None, bool]:
    """q of ``x``, the label of its assembly mode (None for a given q) and whether
    that is the home mode.

    Args:
        robot: The robot.
        x: Input angles theta (3,) or a configuration q (9,) [rad].
        mode: ``"nearest"`` (:func:`~spm_pin.select_assembly`), ``"home"`` or an
            assembly-mode label (theta only).

    Raises:
        InputError: x is neither (3,) nor (9,), not finite, or a bad mode.
        UnreachableError: no assembly of theta in that mode.
    """
    try:
        array = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"x must be input angles theta (3,) or a configuration q (9,) [rad], got {x!r}",
            argument="x",
            value=x,
        ) from exc
    if array.shape == (3,):
        if mode == "nearest":
            chosen = select_assembly(array, robot.design)
            if not bool(chosen.exists):
                raise UnreachableError(
                    f"theta = {np.degrees(array).round(6).tolist()} deg has no real "
                    "assembly mode: the platform cannot be placed",
                    value=array,
                )
            q = robot._closed_configuration(chosen.theta, chosen.R)
            return q, str(chosen.label), bool(chosen.home)
        q = robot.configuration(array, mode)
        if mode == "home":
            return q, home_mode_label(robot.design), True
        return q, mode, False
    if array.shape == (robot.model.nq,):
        if mode not in ("home", "nearest"):
            raise InputError(
                f"mode applies to input angles theta (3,), not to a configuration q; "
                f"got mode={mode!r} with q",
                argument="mode",
                value=mode,
            )
        if not np.all(np.isfinite(array)):
            raise InputError("q must be finite, got NaN or inf", argument="x", value=x)
        return array, None, False
    raise InputError(
        f"x must be input angles theta (3,) or a configuration q (9,) [rad], "
        f"got shape {array.shape}",
        argument="x",
        value=x,
    )


def path_configurations(
    robot: SPMRobot, path: npt.ArrayLike, start: npt.ArrayLike | None
) -> tuple[FloatArray, list[str | None]]:
    """The configurations (N, 9) of a path and the assembly-mode label of each sample
    (None for a path of configurations).

    Args:
        robot: The robot.
        path: Input angles (N, 3) or configurations (N, 9) [rad].
        start: Platform rotation (3, 3) near the mode to follow at the first sample
            (default: the mode of :func:`~spm_pin.select_assembly` there).

    Raises:
        InputError: bad shapes or values.
        UnreachableError: the path leaves the workspace of the followed mode.
    """
    try:
        array = np.asarray(path, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"path must be numbers of shape (N, 3) or (N, 9) [rad], got {path!r}",
            argument="path",
            value=path,
        ) from exc
    nq = robot.model.nq
    if array.ndim != 2 or array.shape[0] < 1 or array.shape[1] not in (3, nq):
        raise InputError(
            f"path must have shape (N, 3) (input angles) or (N, {nq}) (configurations) "
            f"with N >= 1 [rad], got shape {array.shape}",
            argument="path",
            value=path,
        )
    if not np.all(np.isfinite(array)):
        raise InputError("path must be finite, got NaN or inf", argument="path", value=path)
    if array.shape[1] == nq:
        if start is not None:
            raise InputError(
                "start applies to a path of input angles (N, 3), not to configurations",
                argument="start",
                value=start,
            )
        return array, [None] * array.shape[0]
    if start is None:  # the library's rule at the first sample
        first = select_assembly(array[0], robot.design)
        if bool(first.exists) and not bool(first.home):
            start = first.R
    followed = track(array, robot.design, start=start)
    if np.any(followed.lost):
        k = int(np.argmax(followed.lost))
        raise UnreachableError(
            f"the path loses its assembly mode at sample {k}, theta = "
            f"{np.degrees(array[k]).round(6).tolist()} deg (the edge of the workspace)",
            value=array[k],
        )
    qs = np.stack(
        [
            robot.configuration(theta, followed.labels[k], reference=followed.R[k])
            for k, theta in enumerate(array)
        ]
    )
    return qs, list(followed.labels)
