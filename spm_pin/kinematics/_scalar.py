"""Single-input kinematics in plain Python floats, bit-identical to the batch code.

A control loop solves one orientation or one input at a time, and there the batch
functions spend nearly all of their time on numpy's per-call overhead. This module
repeats their arithmetic for one input, operation for operation and in the same
order, in Python floats:

* :func:`ik_home`: ``inverse_kinematics(R)`` in the home working mode;
* :func:`fk_home`: ``forward_kinematics(theta).R`` and ``.reachable``;
* :func:`measures`: ``jacobian(theta, R=R)``'s ``singularity_margin`` and
  ``dexterity``;
* :func:`quaternion_of` and :func:`rpy_of`: ``quaternion_from_matrix(R)`` and
  ``rpy_from_matrix(R)`` of one rotation (what a state read at 1 kHz converts).

Two kinds of operations are left to numpy because Python's ``math`` module does not
round them the same way: ``arctan2`` (numpy's vectorised version may differ from the C
library in the last bit) and the LAPACK factorisations (the singular values and the
solve of the Jacobian). They are called once per input on tiny arrays. Inputs that
the float path does not settle (a forward solve that Newton does not certify) take
the batch path, so every answer is the batch path's answer; ``tests/test_fast_path``
compares them bit for bit.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

try:  # the gufuncs behind np.linalg.svd and np.linalg.solve, without their wrappers
    from numpy.linalg import _umath_linalg

    _lapack: Any = _umath_linalg
except ImportError:  # pragma: no cover
    _lapack = None

from ..design import SPMDesign
from ._common import cross
from ._fk_single import Mat, Vec

__all__ = [
    "ScalarConstants",
    "constants",
    "fk_home",
    "ik_home",
    "measures",
    "quaternion_of",
    "rpy_of",
]

_TWO_PI = 2 * math.pi
FloatArray = npt.NDArray[np.float64]


class ScalarConstants(NamedTuple):
    """Per-design constants of the float paths (computed with numpy, as the batch
    code computes them)."""

    design: SPMDesign
    coaxial: bool
    v0: Mat
    u: Mat
    ik_a: Mat  # a_i = w0_i - (u_i . w0_i) u_i
    ik_uxw0: Mat  # u_i x w0_i
    ik_uw0: Vec  # u_i . w0_i
    cos_a2: float
    w_along: Mat  # (u_i . w0_i) u_i, as proximal_axes computes it
    w_rest: Mat  # w0_i - along_i
    w_cross: Mat  # u_i x w0_i, as proximal_axes computes it
    turn_axis: Vec  # u_1, the axis of the common turn of coaxial designs
    turn_outer: Mat  # outer(u_1, u_1)


def _vec(values: Sequence[float]) -> Vec:
    return (float(values[0]), float(values[1]), float(values[2]))


def _mat(array: FloatArray) -> Mat:
    rows = array.tolist()
    return (_vec(rows[0]), _vec(rows[1]), _vec(rows[2]))


@functools.lru_cache(maxsize=32)
def constants(design: SPMDesign) -> ScalarConstants:
    """The float paths' constants of a design (cached: designs are frozen)."""
    u, w0 = design.u, design.w0
    uw0 = np.sum(u * w0, axis=1)
    along = np.sum(u * w0, axis=-1, keepdims=True) * u
    axis = design.u[0]
    return ScalarConstants(
        design=design,
        coaxial=bool(design.is_coaxial),
        v0=_mat(design.v0),
        u=_mat(u),
        ik_a=_mat(w0 - uw0[:, None] * u),
        ik_uxw0=_mat(np.cross(u, w0)),
        ik_uw0=_vec(uw0.tolist()),
        cos_a2=float(np.cos(design.alpha2)),
        w_along=_mat(along),
        w_rest=_mat(w0 - along),
        w_cross=_mat(cross(u, w0)),
        turn_axis=_vec(axis.tolist()),
        turn_outer=_mat(np.outer(axis, axis)),
    )


def _sum3(a0: float, a1: float, a2: float) -> float:
    """``np.sum`` of three numbers along an axis (in order)."""
    return (a0 + a1) + a2


def _platform_axes(R: Sequence[Sequence[float]], v0: Mat) -> Mat:
    """Rows v_i = R v_i0, as ``np.einsum("...jk,ik->...ij", R, v0)`` computes them
    (its sum of products adds the first and last terms first)."""
    rows = []
    for v in v0:
        rows.append(
            (
                (R[0][0] * v[0] + R[0][2] * v[2]) + R[0][1] * v[1],
                (R[1][0] * v[0] + R[1][2] * v[2]) + R[1][1] * v[1],
                (R[2][0] * v[0] + R[2][2] * v[2]) + R[2][1] * v[1],
            )
        )
    return (rows[0], rows[1], rows[2])


def _wrap(angle: float) -> float:
    """``np.pi - np.mod(np.pi - angle, 2 pi)`` (Python's % rounds as np.mod does)."""
    return math.pi - (math.pi - angle) % _TWO_PI


# ------------------------------------------------------------------ inverse
class HomeIK(NamedTuple):
    """Inverse kinematics of one rotation in the home working mode."""

    theta: Vec  # [rad], NaN on legs that do not close
    b: Vec  # b_ii (NaN on legs that do not close)
    leg_reachable: tuple[bool, bool, bool]
    p: Vec
    q: Vec
    s: Vec


#: As ``spm_pin.kinematics.ik._REACH_TOL``.
_REACH_TOL = 1e-12


def ik_parts(
    R: Sequence[Sequence[float]],
    v0: Mat,
    ik_a: Mat,
    ik_uxw0: Mat,
    ik_uw0: Vec,
    u: Mat,
    cos_a2: float,
) -> tuple[Vec, Vec, Vec, Vec, tuple[bool, bool, bool]]:
    """The float part of :func:`ik_home` (a kernel: floats and tuples only): each
    leg's P, Q, S, the root of P^2 + Q^2 - S^2 (NaN where the leg cannot close) and
    whether it closes."""
    v = _platform_axes(R, v0)
    p = []
    q = []
    s = []
    ok = []
    root = []
    for i in range(3):
        a, c, w = ik_a[i], ik_uxw0[i], u[i]
        p.append(_sum3(v[i][0] * a[0], v[i][1] * a[1], v[i][2] * a[2]))
        q.append(_sum3(v[i][0] * c[0], v[i][1] * c[1], v[i][2] * c[2]))
        s.append(ik_uw0[i] * _sum3(v[i][0] * w[0], v[i][1] * w[1], v[i][2] * w[2]) - cos_a2)
        pp, qq, ss = p[i] * p[i], q[i] * q[i], s[i] * s[i]
        scale = pp + qq + ss
        disc = pp + qq - ss
        good = disc >= -_REACH_TOL * max(scale, 1.0)
        ok.append(good)
        root.append(math.sqrt(max(disc, 0.0)) if good else math.nan)
    return (
        (p[0], p[1], p[2]),
        (q[0], q[1], q[2]),
        (s[0], s[1], s[2]),
        (root[0], root[1], root[2]),
        (ok[0], ok[1], ok[2]),
    )


def ik_home(
    R: Sequence[Sequence[float]],
    k: ScalarConstants,
    parts: Callable[..., tuple[Vec, Vec, Vec, Vec, tuple[bool, bool, bool]]] | None = None,
) -> HomeIK:
    """``inverse_kinematics(R)`` (mode 0, no ``theta_near``) of one checked rotation
    (rows), bit for bit. ``parts`` is :func:`ik_parts` (default) or its compiled
    twin."""
    p, q, s, root, ok = (parts or ik_parts)(R, k.v0, k.ik_a, k.ik_uxw0, k.ik_uw0, k.u, k.cos_a2)
    angles = np.arctan2([*q, *root], [*p, -s[0], -s[1], -s[2]]).tolist()
    theta = (
        _wrap(angles[0] - angles[3]),
        _wrap(angles[1] - angles[4]),
        _wrap(angles[2] - angles[5]),
    )
    return HomeIK(theta, root, ok, p, q, s)


# ------------------------------------------------------------------ forward
def reduce_input(t0: float, t1: float, t2: float) -> tuple[Vec, float, float]:
    """A coaxial input split as the batch code splits it: the reduced input (the
    common turn removed, each input first brought within half a turn of the first)
    and the cosine and sine of the common turn (numpy's, as ``rotation_about``)."""
    rep1 = t0 + _wrap(t1 - t0)
    rep2 = t0 + _wrap(t2 - t0)
    common = _sum3(t0, rep1, rep2) / 3.0
    reduced = (t0 - common, rep1 - common, rep2 - common)
    return reduced, float(np.cos(common)), float(np.sin(common))


def fk_home(
    theta: Sequence[float],
    k: ScalarConstants,
    kernels: Mapping[str, Callable[..., Mat | None]] | None = None,
) -> Mat | None:
    """``forward_kinematics(theta)``'s R (rows) of one input (3 finite floats), or
    None where it is not ``reachable``; bit for bit. ``kernels``: the functions
    ``home_rotation`` and ``home_turned`` of :mod:`._fk_single` (default) or their
    compiled twins (:func:`spm_pin._jit.kernels` of its ``KERNELS``)."""
    from . import _fk_single
    from . import fk as batch

    t0, t1, t2 = float(theta[0]), float(theta[1]), float(theta[2])
    args = (
        batch._single_constants(k.design),
        batch._NEWTON_STEPS_FAST,
        batch._POLISH_EXTRA,
        batch._POLISHED,
        batch.RESIDUAL_TOL,
        batch._SIGN_TOL,
    )
    if k.coaxial:
        reduced, c, s = reduce_input(t0, t1, t2)
        solve = _fk_single.home_turned if kernels is None else kernels["home_turned"]
        single = solve(reduced, *args, c, s, k.turn_axis, k.turn_outer)
    else:
        solve = _fk_single.home_rotation if kernels is None else kernels["home_rotation"]
        single = solve((t0, t1, t2), *args)
    if single is None:  # not settled here: the batch path decides
        fk = batch.forward_kinematics(np.array([t0, t1, t2]), k.design)
        return _mat(fk.R) if bool(fk.reachable) else None
    return single


# ------------------------------------------------------------------ measures
def _cross(a: Sequence[float], b: Sequence[float]) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _norm(a: Vec) -> float:
    return math.sqrt(_sum3(a[0] * a[0], a[1] * a[1], a[2] * a[2]))


def proximal_axes_of(theta: Sequence[float], k: ScalarConstants) -> Mat:
    """Rows w_i(theta_i), as :func:`~spm_pin.kinematics._common.proximal_axes`."""
    return _proximal(theta, k.w_along, k.w_rest, k.w_cross)


def _proximal(theta: Sequence[float], w_along: Mat, w_rest: Mat, w_cross: Mat) -> Mat:
    rows = []
    for i in range(3):
        c, s = math.cos(theta[i]), math.sin(theta[i])
        along, rest, cross = w_along[i], w_rest[i], w_cross[i]
        rows.append(
            (
                along[0] + c * rest[0] + s * cross[0],
                along[1] + c * rest[1] + s * cross[1],
                along[2] + c * rest[2] + s * cross[2],
            )
        )
    return (rows[0], rows[1], rows[2])


def jacobian_parts(
    theta: Sequence[float],
    R: Sequence[Sequence[float]],
    u: Mat,
    v0: Mat,
    w_along: Mat,
    w_rest: Mat,
    w_cross: Mat,
) -> tuple[float, Mat, Mat, Vec]:
    """The float part of :func:`measures` (a kernel: floats and tuples only): the
    legs' singularity margin, the rows of A normalised, the rows of A, and b_ii."""
    w = _proximal(theta, w_along, w_rest, w_cross)
    v = _platform_axes(R, v0)
    legs = []
    b = []
    A = []
    unit = []
    for i in range(3):
        uxw = _cross(u[i], w[i])
        b.append(_sum3(uxw[0] * v[i][0], uxw[1] * v[i][1], uxw[2] * v[i][2]))
        legs.append(abs(b[i]) / _norm(uxw))
        row = _cross(w[i], v[i])
        A.append(row)
        n = _norm(row)
        d = n if n > 0 else 1.0
        unit.append((row[0] / d, row[1] / d, row[2] / d))
    leg_margin = min(legs[0], legs[1], legs[2])
    return leg_margin, (unit[0], unit[1], unit[2]), (A[0], A[1], A[2]), (b[0], b[1], b[2])


def measures(
    theta: Sequence[float],
    R: Sequence[Sequence[float]],
    k: ScalarConstants,
    tol: float,
    parts: Callable[..., tuple[float, Mat, Mat, Vec]] | None = None,
) -> tuple[float, float]:
    """``(singularity_margin, dexterity)`` of ``jacobian(theta, R=R, tol=tol)`` at
    one input with its (reachable) platform rotation, bit for bit. ``parts`` is
    :func:`jacobian_parts` (default) or its compiled twin."""
    leg_margin, unit, A, b = (parts or jacobian_parts)(
        (theta[0], theta[1], theta[2]), R, k.u, k.v0, k.w_along, k.w_rest, k.w_cross
    )
    return measures_of_parts(leg_margin, unit, A, b, tol)


def measures_of_parts(
    leg_margin: float, unit: Mat, A: Mat, b: Vec, tol: float
) -> tuple[float, float]:
    """:func:`measures` from the output of :func:`jacobian_parts` (the LAPACK part)."""
    a_margin = _singular_values(np.array(unit))[-1]
    margin = min(leg_margin, a_margin)
    if leg_margin <= tol or a_margin <= tol:  # type I or II: dexterity 0
        return margin, 0.0
    diagonal = [[b[i] * (1.0 if i == j else 0.0) for j in range(3)] for i in range(3)]
    sigma = _singular_values(_solve(np.array(A), np.array(diagonal)))
    return margin, (sigma[-1] / sigma[0] if sigma[0] > 0 else 0.0)


#: :func:`jacobian_parts`, :func:`ik_parts` and the functions they call, callees first: what
#: :func:`spm_pin._jit.kernels` compiles.
KERNELS = (_sum3, _cross, _norm, _platform_axes, _proximal, jacobian_parts, ik_parts)


def _singular_values(matrix: FloatArray) -> list[float]:
    """Singular values of a 3 x 3 matrix, largest first, as ``np.linalg.svd`` gives
    them (its LAPACK routine, without the wrapper's checks)."""
    if _lapack is None:  # pragma: no cover - numpy without the private module
        values: list[float] = np.linalg.svd(matrix, compute_uv=False).tolist()
        return values
    result: list[float] = _lapack.svd(matrix, signature="d->d").tolist()
    return result


def _solve(a: FloatArray, b: FloatArray) -> FloatArray:
    """``np.linalg.solve(a, b)`` of a regular 3 x 3 system (its LAPACK routine)."""
    if _lapack is None:  # pragma: no cover - numpy without the private module
        solved: FloatArray = np.linalg.solve(a, b).astype(np.float64)
        return solved
    result: FloatArray = _lapack.solve(a, b, signature="dd->d")
    return result


# ------------------------------------------------------------------ rotations
def quaternion_of(R: Sequence[Sequence[float]]) -> list[float]:
    """``quaternion_from_matrix(R)`` (w, x, y, z; w >= 0) of one checked rotation
    (rows), bit for bit: the same arithmetic in the same order (``sqrt`` is
    correctly rounded in both)."""
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = R
    # Row k equals 4 q_k q; use the row with the largest diagonal entry 4 q_k^2.
    rows = (
        (1 + m00 + m11 + m22, m21 - m12, m02 - m20, m10 - m01),
        (m21 - m12, 1 + m00 - m11 - m22, m01 + m10, m02 + m20),
        (m02 - m20, m01 + m10, 1 - m00 + m11 - m22, m12 + m21),
        (m10 - m01, m02 + m20, m12 + m21, 1 - m00 - m11 + m22),
    )
    k = 0  # the first of the largest, as np.argmax
    for i in (1, 2, 3):
        if rows[i][i] > rows[k][k]:
            k = i
    scale = 2.0 * math.sqrt(rows[k][k])
    q = [x / scale for x in rows[k]]
    return [-x for x in q] if q[0] < 0 else q


def rpy_of(R: Sequence[Sequence[float]]) -> list[float]:
    """``rpy_from_matrix(R)`` (roll, pitch, yaw) [rad] of one checked rotation (rows),
    bit for bit; ``arctan2`` and ``hypot`` are numpy's (``math`` may round them
    differently)."""
    (m00, _, _), (m10, _, _), (m20, m21, m22) = R
    hypot = float(np.hypot(m21, m22))
    angles: list[float] = np.arctan2((m21, -m20, m10), (m22, hypot, m00)).tolist()
    return angles
