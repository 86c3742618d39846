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
    "ANGLE_RANGE",
    "KERNELS",
    "SMALL_ANGLE",
    "Mat",
    "Vec",
    "_angle_cos_sin",
    "_cos_sin",
    "_cross",
    "_dot",
    "_first_round",
    "_first_suffices",
    "_last_rounds",
    "_mat_mul",
    "_mat_of",
    "_mat_t_mul",
    "_mat_t_vec",
    "_mat_vec",
    "_mat_vecs",
    "_put_mat",
    "_quadrant_cos_sin",
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


#: Below this magnitude [rad], :func:`_angle_cos_sin` reduces the angle modulo pi/2
#: itself (n, an integer below 2^19, times pi/2's 33-bit pieces is exact); beyond it,
#: and for inf and NaN, it takes libm's values. The input angles' bound
#: (:data:`spm_pin._checks.ANGLE_LIMIT`) is far inside.
ANGLE_RANGE = 2.0**19

_CANCELLED = 2.0**-20  # the first round's r - w relative to x below which it does not suffice
_QUARTER_PI = 0.25 * math.pi  # fdlibm's kernels alone serve below it
_ROUND = 6755399441055744.0  # 1.5 * 2^52: x + _ROUND - _ROUND is x to the nearest integer

# fdlibm's constants (e_rem_pio2.c, k_sin.c, k_cos.c):
# ====================================================
# Copyright (C) 1993 by Sun Microsystems, Inc. All rights reserved.
#
# Developed at SunSoft, a Sun Microsystems, Inc. business.
# Permission to use, copy, modify, and distribute this
# software is freely granted, provided that this notice
# is preserved.
# ====================================================
# 2 / pi; pi / 2 in 33-bit pieces (_PIO2_1, _PIO2_2, _PIO2_3) and their tails.
_INVPIO2 = 6.36619772367581382433e-01
_PIO2_1, _PIO2_1T = 1.57079632673412561417e00, 6.07710050650619224932e-11
_PIO2_2, _PIO2_2T = 6.07710050630396597660e-11, 2.02226624879595063154e-21
_PIO2_3, _PIO2_3T = 2.02226624871116645580e-21, 8.47842766036889956997e-32
# sin x = x + S1 x^3 + ... + S6 x^13 and cos x = 1 - x^2 / 2 + C1 x^4 + ... + C6 x^14 on
# [-pi/4, pi/4], each within 2^-58.
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


@_jit.inline
def _first_round(x: float) -> tuple[float, float, float]:
    """fdlibm's first round of the reduction: the nearest n to x / (pi/2) and x - n pi/2
    as r - w, good to 85 bits (:func:`_first_suffices`)."""
    n = (x * _INVPIO2 + _ROUND) - _ROUND
    return n, x - n * _PIO2_1, n * _PIO2_1T


@_jit.inline
def _first_suffices(x: float, r: float, w: float) -> bool:
    """Whether the first round is enough: |x| below :data:`ANGLE_RANGE` and fewer than
    20 of its bits cancelled (x is not within 2^-20 |x| of a multiple of pi/2)."""
    return abs(x) < ANGLE_RANGE and abs(r - w) >= abs(x) * _CANCELLED


@_jit.inline
def _last_rounds(n: float, r: float) -> tuple[float, float]:
    """fdlibm's second and third rounds, after the first's r: x - n pi/2 as r - w, good
    to 151 bits, which covers every x below :data:`ANGLE_RANGE`."""
    t = r
    w = n * _PIO2_2
    r = t - w
    w = n * _PIO2_2T - ((t - r) - w)
    t = r
    w = n * _PIO2_3
    r = t - w
    w = n * _PIO2_3T - ((t - r) - w)
    return r, w


@_jit.inline
def _quadrant_cos_sin(n: float, r: float, w: float) -> tuple[float, float]:
    """(cos x, sin x) from x - n pi/2 = r - w: fdlibm's kernels on [-pi/4, pi/4] of
    y0 + y1 = r - w, then the quadrant n mod 4. No branch or call."""
    y0 = r - w
    y1 = (r - y0) - w
    z = y0 * y0
    z2 = z * z
    p = _S2 + z * (_S3 + z * _S4) + z * z2 * (_S5 + z * _S6)
    v = z * y0
    s = y0 - ((z * (0.5 * y1 - v * p) - y1) - v * _S1)
    q = z * (_C1 + z * (_C2 + z * _C3)) + z2 * z2 * (_C4 + z * (_C5 + z * _C6))
    half = 0.5 * z
    one = 1.0 - half
    c = one + (((1.0 - one) - half) + (z * q - y0 * y1))
    k = n - 4.0 * ((n * 0.25 + _ROUND) - _ROUND)  # n mod 4, as -2, -1, 0, 1 or 2
    odd = k == 1.0 or k == -1.0
    sin, cos = (c, s) if odd else (s, c)
    if k == 2.0 or k == -2.0 or k == -1.0:  # quadrants 2 and 3: sin < 0
        sin = -sin
    if k == 1.0 or k == 2.0 or k == -2.0:  # quadrants 1 and 2: cos < 0
        cos = -cos
    return cos, sin


@_jit.inline
def _angle_cos_sin(x: float) -> tuple[float, float]:
    """(cos x, sin x) for the input angles, as fdlibm (FreeBSD's and musl's libm)
    computes them: x reduced modulo pi/2 by :func:`_first_round` (and, when it does not
    suffice, :func:`_last_rounds`), then :func:`_quadrant_cos_sin`; beyond
    :data:`ANGLE_RANGE` (inf, NaN), libm's. Within one unit in the last place of the
    true value, so of libm's (tested). A loop over lanes vectorises the first round
    and the kernels, and takes this function for the lanes :func:`_first_suffices`
    refuses (0.14% of angles drawn at random in +-2048 rad, fewer for smaller ones)."""
    n, r, w = _first_round(x)
    if not _first_suffices(x, r, w):
        if not abs(x) < ANGLE_RANGE:
            return math.cos(x), math.sin(x)
        r, w = _last_rounds(n, r)
    return _quadrant_cos_sin(n, r, w)


@_jit.inline
def _cos_sin(x: float) -> tuple[float, float]:
    """(cos x, sin x) of Newton's turns: :func:`_small_cos_sin` below
    :data:`SMALL_ANGLE` (the turns of the dynamics' warm start, 1e-4 rad and less),
    fdlibm's kernels (:func:`_quadrant_cos_sin`, no reduction) below pi/4 (the
    kinematic steps' turns, about 0.05 rad), else libm's (NaN: libm's)."""
    if abs(x) < SMALL_ANGLE:
        return _small_cos_sin(x)
    if abs(x) < _QUARTER_PI:
        return _quadrant_cos_sin(0.0, x, 0.0)
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
    _first_round,
    _first_suffices,
    _last_rounds,
    _quadrant_cos_sin,
    _cos_sin,
    _angle_cos_sin,
)
