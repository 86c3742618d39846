"""The observations of :class:`~spm_pin.envs._core.OrientCore`'s robots in one call, in
a form that numba compiles (:func:`spm_pin._jit.kernels` of :data:`KERNELS`).

:meth:`OrientCore.observe <spm_pin.envs._core.OrientCore.observe>` builds the 21
numbers of each robot (the 6-D forms of its rotation and of its goal, the sines and
cosines of its input angles, its speeds over the speed limit clipped to [-1, 1]) with
a dozen numpy calls, most of a single environment's step after the compiled physics.
Here they are written in place, the same operations (the float32 rounding of the
float64 values, as ``astype``), but for the sines and cosines: fdlibm's
(:func:`~spm_pin.dynamics._tuple_kernel._angle_cos_sin`, no libm call; within one
unit in the last place of libm's, so in float32 the same but where a float64 value
lies within that unit of a float32 rounding boundary: about one value in 2^28).
Nothing here checks its arguments.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..dynamics._tuple_kernel import KERNELS as TUPLE_KERNELS
from ..dynamics._tuple_kernel import _angle_cos_sin

__all__ = ["KERNELS", "observe_record", "observe_rows"]


def observe_rows(
    rows: npt.NDArray[np.int64],
    R: npt.NDArray[np.float64],
    goal: npt.NDArray[np.float64],
    theta: npt.NDArray[np.float64],
    speed: npt.NDArray[np.float64],
    max_speed: float,
    out: npt.NDArray[np.float32],
) -> None:
    """The observations (n, 21) of ``rows`` into ``out`` (float32): the first two
    columns of R and of the goal rotation, column after column, sin and cos of the
    input angles, the speeds over ``max_speed`` clipped to [-1, 1]."""
    for m in range(rows.shape[0]):
        r = rows[m]
        for i in range(3):
            out[m, i] = R[r, i, 0]
            out[m, 3 + i] = R[r, i, 1]
            out[m, 6 + i] = goal[r, i, 0]
            out[m, 9 + i] = goal[r, i, 1]
            cos, sin = _angle_cos_sin(theta[r, i])
            out[m, 12 + i] = sin
            out[m, 15 + i] = cos
            out[m, 18 + i] = min(max(speed[r, i] / max_speed, -1.0), 1.0)


def observe_record(
    rows: npt.NDArray[np.int64],
    R: npt.NDArray[np.float64],
    goal: npt.NDArray[np.float64],
    theta: npt.NDArray[np.float64],
    speed: npt.NDArray[np.float64],
    max_speed: float,
    out: npt.NDArray[np.float32],
    sources: tuple[npt.NDArray[np.float64], ...],
    record: npt.NDArray[np.float64],
) -> None:
    """:func:`observe_rows` of one robot (``rows`` (1,)), and its row of each of the
    ``sources`` (arrays (N, k), the k of each its own), one after the other, into
    ``record``: a single environment's observation and the numbers of its info in one
    call."""
    observe_rows(rows, R, goal, theta, speed, max_speed, out)
    r = rows[0]
    at = 0
    for source in sources:
        for j in range(source.shape[1]):
            record[at] = source[r, j]
            at += 1


#: The kernels, callees first: what :func:`spm_pin._jit.kernels` compiles.
KERNELS = (*TUPLE_KERNELS, observe_rows, observe_record)
