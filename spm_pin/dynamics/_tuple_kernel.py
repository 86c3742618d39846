"""3-vectors and 3 x 3 matrices as tuples of floats (matrices by rows), in a form that
numba compiles unchanged (:func:`spm_pin._jit.kernels` of :data:`KERNELS`): the small
algebra of the compiled kernels (:mod:`spm_pin.dynamics._reduced_kernel`, the
environments' kernels). Tuples stay in registers; each function is the plain
formula, so a kernel's bits are those of its Python twin.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from .. import _jit

__all__ = [
    "KERNELS",
    "SMALL_ANGLE",
    "Mat",
    "Vec",
    "_cos_sin",
    "_cross",
    "_dot",
    "_mat_mul",
    "_mat_of",
    "_mat_t_mul",
    "_mat_t_vec",
    "_mat_vec",
    "_mat_vecs",
    "_put_mat",
    "_rotate",
    "_scale",
    "_small_cos_sin",
    "_solve3",
    "_unit",
    "_vec_of",
]

FloatArray = npt.NDArray[np.float64]
Vec = tuple[float, float, float]
Mat = tuple[Vec, Vec, Vec]  # rows


def _dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _rotate(axis: Vec, c: float, s: float, x: Vec) -> Vec:
    """Rodrigues, as ``reduced._rotate``: along + c (x - along) + s (axis x x)."""
    d = _dot(axis, x)
    t = _cross(axis, x)
    return (
        d * axis[0] + c * (x[0] - d * axis[0]) + s * t[0],
        d * axis[1] + c * (x[1] - d * axis[1]) + s * t[1],
        d * axis[2] + c * (x[2] - d * axis[2]) + s * t[2],
    )


def _mat_vec(m: Mat, x: Vec) -> Vec:
    """m x."""
    return (_dot(m[0], x), _dot(m[1], x), _dot(m[2], x))


def _mat_vecs(m: Mat, rows: Mat) -> Mat:
    """Rows m x_i of the rows x_i."""
    return (_mat_vec(m, rows[0]), _mat_vec(m, rows[1]), _mat_vec(m, rows[2]))


def _mat_t_vec(m: Mat, x: Vec) -> Vec:
    """m^T x."""
    return (
        m[0][0] * x[0] + m[1][0] * x[1] + m[2][0] * x[2],
        m[0][1] * x[0] + m[1][1] * x[1] + m[2][1] * x[2],
        m[0][2] * x[0] + m[1][2] * x[1] + m[2][2] * x[2],
    )


def _mat_mul(a: Mat, b: Mat) -> Mat:
    """a b."""
    return (_mat_t_vec(b, a[0]), _mat_t_vec(b, a[1]), _mat_t_vec(b, a[2]))


def _mat_t_mul(a: Mat, b: Mat) -> Mat:
    """a^T b."""
    c0 = (a[0][0], a[1][0], a[2][0])
    c1 = (a[0][1], a[1][1], a[2][1])
    c2 = (a[0][2], a[1][2], a[2][2])
    return (_mat_t_vec(b, c0), _mat_t_vec(b, c1), _mat_t_vec(b, c2))


def _vec_of(array: FloatArray) -> Vec:
    """A (3,) array as a tuple."""
    return (array[0], array[1], array[2])


def _mat_of(array: FloatArray) -> Mat:
    """A (3, 3) array as rows."""
    return (
        (array[0, 0], array[0, 1], array[0, 2]),
        (array[1, 0], array[1, 1], array[1, 2]),
        (array[2, 0], array[2, 1], array[2, 2]),
    )


def _put_mat(out: FloatArray, m: Mat) -> None:
    """Write rows m into a (3, 3) array."""
    for i in range(3):
        for j in range(3):
            out[i, j] = m[i][j]


def _solve3(m: Mat, b: Vec) -> Vec:
    """m^-1 b by Gaussian elimination with partial pivoting (LAPACK's LU)."""
    r0, r1, r2 = m
    b0, b1, b2 = b
    if abs(r1[0]) > abs(r0[0]) and abs(r1[0]) >= abs(r2[0]):
        r0, r1, b0, b1 = r1, r0, b1, b0
    elif abs(r2[0]) > abs(r0[0]):
        r0, r2, b0, b2 = r2, r0, b2, b0
    f1 = r1[0] / r0[0]
    f2 = r2[0] / r0[0]
    a11, a12, c1 = r1[1] - f1 * r0[1], r1[2] - f1 * r0[2], b1 - f1 * b0
    a21, a22, c2 = r2[1] - f2 * r0[1], r2[2] - f2 * r0[2], b2 - f2 * b0
    if abs(a21) > abs(a11):
        a11, a12, c1, a21, a22, c2 = a21, a22, c2, a11, a12, c1
    f = a21 / a11
    x2 = (c2 - f * c1) / (a22 - f * a12)
    x1 = (c1 - a12 * x2) / a11
    x0 = (b0 - r0[1] * x1 - r0[2] * x2) / r0[0]
    return (x0, x1, x2)


def _unit(i: int) -> Vec:
    """e_i."""
    return (1.0 if i == 0 else 0.0, 1.0 if i == 1 else 0.0, 1.0 if i == 2 else 0.0)


def _scale(f: float, x: Vec) -> Vec:
    return (f * x[0], f * x[1], f * x[2])


#: Below this angle [rad], :func:`_cos_sin` sums the Taylor series: its first left-out
#: terms, x^8 / 8! and x^9 / 9!, are below 3e-21 of the result, far under half a unit
#: in the last place (1.1e-16), so the sums are libm's values to rounding.
SMALL_ANGLE = 1e-2


@_jit.inline
def _small_cos_sin(x: float) -> tuple[float, float]:
    """(cos x, sin x) by their Taylor series to x^6 and x^7 (Horner): for |x| below
    :data:`SMALL_ANGLE`; no call, so a loop over lanes vectorises."""
    x2 = x * x
    c = 1.0 - x2 * (0.5 - x2 * (1.0 / 24.0 - x2 * (1.0 / 720.0)))
    s = x * (1.0 - x2 * (1.0 / 6.0 - x2 * (1.0 / 120.0 - x2 * (1.0 / 5040.0))))
    return c, s


@_jit.inline
def _cos_sin(x: float) -> tuple[float, float]:
    """(cos x, sin x): :func:`_small_cos_sin` below :data:`SMALL_ANGLE` (Newton's turns
    of a warm-started rotation, 1e-4 rad and less), else libm's (NaN: libm's)."""
    if abs(x) < SMALL_ANGLE:
        return _small_cos_sin(x)
    return math.cos(x), math.sin(x)


#: The kernels, callees first: what :func:`spm_pin._jit.kernels` compiles.
KERNELS = (
    _dot,
    _cross,
    _rotate,
    _mat_vec,
    _mat_vecs,
    _mat_t_vec,
    _mat_mul,
    _mat_t_mul,
    _vec_of,
    _mat_of,
    _put_mat,
    _solve3,
    _unit,
    _scale,
    _small_cos_sin,
    _cos_sin,
)
