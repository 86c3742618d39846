"""Home-mode forward kinematics of one input in plain Python floats.

The batch code of :mod:`.fk` spends most of a single-input call on numpy's per-call
overhead (hundreds of operations on 3-vectors). This module runs the same method,
the same two-equation Newton from the home slope, certified by the same residual
and sign rule, component by component in Python floats, for the one-input calls of
control loops (model-servo sync, closed configurations, collision checks). An input
that it does not certify returns None and takes the batch path, so the answers are
the batch path's answers.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

from ..design import SPMDesign

Vec = tuple[float, float, float]
Mat = tuple[Vec, Vec, Vec]  # rows


def _cross(a: Sequence[float], b: Sequence[float]) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a: Sequence[float], b: Sequence[float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


class SingleConstants(NamedTuple):
    """Per-design constants as Python floats."""

    u: Mat
    w0: Mat
    v0: Mat
    body_inv: Mat  # inverse of the matrix with columns v_10, v_20, v_10 x v_20
    slope: tuple[Vec, Vec]  # d(phi_1, phi_2) / d(theta) at home
    combination: Vec  # (a, b, d): v_30 = a v_10 + b v_20 + d (v_10 x v_20)
    sin_a1: float
    cos_a2: float
    sin_a2: float
    c12: float  # v_10 . v_20
    home_sign: float  # sign of det A at home


def _vec(values: Sequence[float]) -> Vec:
    return (float(values[0]), float(values[1]), float(values[2]))


def _mat(rows: Sequence[Sequence[float]]) -> Mat:
    return (_vec(rows[0]), _vec(rows[1]), _vec(rows[2]))


def make_constants(design: SPMDesign, slope: Sequence[Sequence[float]]) -> SingleConstants:
    """The constants of a design for :func:`home_rotation`; ``slope`` is d(phi_1,
    phi_2)/d(theta) of the home mode at home, (2, 3), from the batch module (which
    caches the result per design)."""
    v0 = _mat(design.v0.tolist())
    return SingleConstants(
        u=_mat(design.u.tolist()),
        w0=_mat(design.w0.tolist()),
        v0=v0,
        body_inv=_inverse_columns(v0[0], v0[1], _cross(v0[0], v0[1])),
        slope=(_vec(slope[0]), _vec(slope[1])),
        combination=_vec(design.platform_combination),
        sin_a1=math.sin(design.alpha1),
        cos_a2=math.cos(design.alpha2),
        sin_a2=math.sin(design.alpha2),
        c12=_dot(v0[0], v0[1]),
        home_sign=math.copysign(1.0, float(design.home_det_a)),
    )


def _inverse_columns(c0: Vec, c1: Vec, c2: Vec) -> Mat:
    """Inverse of the matrix with columns c0, c1, c2 (rows of the inverse: cofactors)."""
    r0, r1, r2 = _cross(c1, c2), _cross(c2, c0), _cross(c0, c1)
    det = _dot(c0, r0)
    return (
        (r0[0] / det, r0[1] / det, r0[2] / det),
        (r1[0] / det, r1[1] / det, r1[2] / det),
        (r2[0] / det, r2[1] / det, r2[2] / det),
    )


def _rotate(axis: Vec, angle: float, x: Vec) -> Vec:
    """Rodrigues: x turned about the unit ``axis`` by ``angle``."""
    c, s = math.cos(angle), math.sin(angle)
    kx = _cross(axis, x)
    k = _dot(axis, x) * (1.0 - c)
    return (
        x[0] * c + kx[0] * s + axis[0] * k,
        x[1] * c + kx[1] * s + axis[1] * k,
        x[2] * c + kx[2] * s + axis[2] * k,
    )


def home_rotation(
    theta: Sequence[float],
    constants: SingleConstants,
    newton_steps: int,
    polish_extra: int,
    polished: float,
    residual_tol: float,
    sign_tol: float,
) -> Mat | None:
    """R (rows) of the home mode at one reduced input ``theta`` [rad], or None.

    The method and the tolerances are those of the batch path in :mod:`.fk`
    (``_setup``, ``_newton``, ``_certify``): None where Newton from the home slope
    does not certify a home-mode solution.
    """
    k = constants
    u, w0, v0, body_inv, slope = k.u, k.w0, k.v0, k.body_inv, k.slope
    pa, pb, pd = k.combination
    sa1, ca2, sa2, c12, home_sign = k.sin_a1, k.cos_a2, k.sin_a2, k.c12, k.home_sign
    w = [_rotate(u[i], theta[i], w0[i]) for i in range(3)]
    # Cone frames of legs 1 and 2: columns [cos a2 w, sin a2 p, sin a2 q].
    cols = []
    for i in (0, 1):
        p = _cross(u[i], w[i])
        p = (p[0] / sa1, p[1] / sa1, p[2] / sa1)
        q = _cross(w[i], p)
        cols.append(
            (
                (ca2 * w[i][0], ca2 * w[i][1], ca2 * w[i][2]),
                (sa2 * p[0], sa2 * p[1], sa2 * p[2]),
                (sa2 * q[0], sa2 * q[1], sa2 * q[2]),
            )
        )
    V1, V2 = cols  # V[c] is column c
    w3 = w[2]
    M1 = [[_dot(V1[i], V2[j]) for j in range(3)] for i in range(3)]
    M1[0][0] -= c12
    crossed = [_cross(V2[j], w3) for j in range(3)]
    M2 = [[pd * _dot(V1[i], crossed[j]) for j in range(3)] for i in range(3)]
    for i in range(3):
        M2[i][0] += pa * _dot(w3, V1[i])
    for j in range(3):
        M2[0][j] += pb * _dot(w3, V2[j])
    M2[0][0] -= ca2
    Ms = (M1, M2)

    def residual(phi1: float, phi2: float) -> tuple[float, float, float, float, float, float]:
        c1, s1, c2, s2 = math.cos(phi1), math.sin(phi1), math.cos(phi2), math.sin(phi2)
        out = []
        for m in Ms:
            r = [m[i][0] + m[i][1] * c2 + m[i][2] * s2 for i in range(3)]
            t = [m[i][2] * c2 - m[i][1] * s2 for i in range(3)]
            out += [
                r[0] + c1 * r[1] + s1 * r[2],  # f_k
                c1 * r[2] - s1 * r[1],  # d f_k / d phi1
                t[0] + c1 * t[1] + s1 * t[2],  # d f_k / d phi2
            ]
        f0, a0, b0, f1, a1, b1 = out
        return f0, f1, a0, a1, b0, b1

    def step(phi1: float, phi2: float) -> tuple[float, float]:
        f0, f1, j10, j11, j20, j21 = residual(phi1, phi2)
        det = j10 * j21 - j11 * j20
        if det == 0.0:
            return phi1, phi2
        d1 = (j21 * f0 - j20 * f1) / det
        d2 = (j10 * f1 - j11 * f0) / det
        if not (math.isfinite(d1) and math.isfinite(d2)):
            return phi1, phi2
        scale = 1.0 / max(abs(d1), abs(d2), 1.0)  # steps beyond one radian are damped
        return phi1 - scale * d1, phi2 - scale * d2

    phi1 = _dot(theta, slope[0])
    phi2 = _dot(theta, slope[1])
    for _ in range(newton_steps + 1):
        phi1, phi2 = step(phi1, phi2)
    f0, f1 = residual(phi1, phi2)[:2]
    res = max(abs(f0), abs(f1))
    for _ in range(polish_extra):
        if not res > polished:
            break
        phi1, phi2 = step(phi1, phi2)
        f0, f1 = residual(phi1, phi2)[:2]
        res = max(abs(f0), abs(f1))
    if not res <= residual_tol:
        return None
    c1, s1, c2, s2 = math.cos(phi1), math.sin(phi1), math.cos(phi2), math.sin(phi2)
    v1 = tuple(V1[0][k] + V1[1][k] * c1 + V1[2][k] * s1 for k in range(3))
    v2 = tuple(V2[0][k] + V2[1][k] * c2 + V2[2][k] * s2 for k in range(3))
    v12 = _cross(v1, v2)
    # R = world @ body^-1, world with columns v1, v2, v1 x v2.
    R = tuple(
        tuple(
            v1[r] * body_inv[0][c] + v2[r] * body_inv[1][c] + v12[r] * body_inv[2][c]
            for c in range(3)
        )
        for r in range(3)
    )
    # Home sign rule: every b_ii = (u_i x w_i) . v_i > 0 and det A of the home sign.
    A = []
    for i in range(3):
        v = tuple(_dot(R[r], v0[i]) for r in range(3))
        if not _dot(_cross(u[i], w[i]), v) > sign_tol:
            return None
        A.append(_cross(w[i], v))
    det_a = _dot(A[0], _cross(A[1], A[2]))
    if not (abs(det_a) > sign_tol and math.copysign(1.0, det_a) == home_sign):
        return None
    return R  # type: ignore[return-value]
