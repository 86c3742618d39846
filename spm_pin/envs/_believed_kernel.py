"""The platform rotations that miscalibrated controllers believe, row by row, in a
form that numba compiles (:func:`spm_pin._jit.kernels` of :data:`KERNELS`): each
row's own model, by the reduced dynamics' warm-started Newton and home sign rule
(:func:`~spm_pin.dynamics._reduced_kernel.home_rotation_of`), so a row's numbers do
not depend on the rows beside it. Nothing here checks its arguments.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..dynamics._reduced_kernel import KERNELS as REDUCED_KERNELS
from ..dynamics._reduced_kernel import home_rotation_of
from ..dynamics._tuple_kernel import _mat_of, _put_mat, _vec_of

__all__ = ["KERNELS", "believed_rows"]

FloatArray = npt.NDArray[np.float64]


def believed_rows(
    theta: FloatArray,
    start: FloatArray,
    u: FloatArray,
    w0: FloatArray,
    v0: FloatArray,
    cos_a2: FloatArray,
    home_sign: FloatArray,
    sign_tol: float,
    tol: float,
    iterations: int,
    out: FloatArray,
    settled: npt.NDArray[np.bool_],
) -> None:
    """The home-mode rotation of each row's model at its input angles, by Newton's
    method from ``start``, into ``out`` (n, 3, 3); ``settled`` (n,): whether Newton's
    residual came within ``tol`` and the home sign rule holds.

    Args:
        theta: Input angles [rad] (n, 3).
        start: Where Newton starts (n, 3, 3).
        u, w0, v0: Each row's base axes, proximal axes at home and platform axes
            (n, 3, 3), rows per leg.
        cos_a2: cos alpha2 of each row's model (n,).
        home_sign: The sign of det A at home of each row's model (n,).
        sign_tol, tol, iterations: The home sign rule's tolerance, the closure
            tolerance and Newton's iterations.
    """
    for m in range(theta.shape[0]):
        ok, R = home_rotation_of(
            _vec_of(theta[m]), _mat_of(start[m]), _mat_of(u[m]), _mat_of(w0[m]),
            _mat_of(v0[m]), cos_a2[m], home_sign[m], sign_tol, tol, iterations,
        )  # fmt: skip
        _put_mat(out[m], R)
        settled[m] = ok


#: The kernels, callees first: what :func:`spm_pin._jit.kernels` compiles.
KERNELS = (*REDUCED_KERNELS, believed_rows)
