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


def _row(a: float, b: float, c: float, m: Mat) -> Vec:
    """Row (a, b, c) @ m."""
    return (
        a * m[0][0] + b * m[1][0] + c * m[2][0],
        a * m[0][1] + b * m[1][1] + c * m[2][1],
        a * m[0][2] + b * m[1][2] + c * m[2][2],
    )


def _gram(V1: Mat, V2: Mat, c12: float) -> Mat:
    """M1[i][j] = V1_i . V2_j, less c12 at (0, 0): the closure of legs 1 and 2."""
    return (
        (_dot(V1[0], V2[0]) - c12, _dot(V1[0], V2[1]), _dot(V1[0], V2[2])),
        (_dot(V1[1], V2[0]), _dot(V1[1], V2[1]), _dot(V1[1], V2[2])),
        (_dot(V1[2], V2[0]), _dot(V1[2], V2[1]), _dot(V1[2], V2[2])),
    )


def _second(V1: Mat, V2: Mat, w3: Vec, pa: float, pb: float, pd: float, ca2: float) -> Mat:
    """M2: the closure of leg 3 (its platform axis as a combination of the others)."""
    x0, x1, x2 = _cross(V2[0], w3), _cross(V2[1], w3), _cross(V2[2], w3)
    rows = []
    for i in range(3):
        r0 = pd * _dot(V1[i], x0) + pa * _dot(w3, V1[i])
        r1 = pd * _dot(V1[i], x1)
        r2 = pd * _dot(V1[i], x2)
        if i == 0:
            r0 = r0 + pb * _dot(w3, V2[0]) - ca2
            r1 = r1 + pb * _dot(w3, V2[1])
            r2 = r2 + pb * _dot(w3, V2[2])
        rows.append((r0, r1, r2))
    return (rows[0], rows[1], rows[2])


def _half(m: Mat, c1: float, s1: float, c2: float, s2: float) -> Vec:
    """(f, d f / d phi1, d f / d phi2) of one closure equation."""
    r0 = m[0][0] + m[0][1] * c2 + m[0][2] * s2
    r1 = m[1][0] + m[1][1] * c2 + m[1][2] * s2
    r2 = m[2][0] + m[2][1] * c2 + m[2][2] * s2
    t0 = m[0][2] * c2 - m[0][1] * s2
    t1 = m[1][2] * c2 - m[1][1] * s2
    t2 = m[2][2] * c2 - m[2][1] * s2
    return r0 + c1 * r1 + s1 * r2, c1 * r2 - s1 * r1, t0 + c1 * t1 + s1 * t2


def _residual(
    M1: Mat, M2: Mat, phi1: float, phi2: float
) -> tuple[float, float, float, float, float, float]:
    """(f0, f1, d f0/d phi1, d f1/d phi1, d f0/d phi2, d f1/d phi2)."""
    c1, s1, c2, s2 = math.cos(phi1), math.sin(phi1), math.cos(phi2), math.sin(phi2)
    f0, a0, b0 = _half(M1, c1, s1, c2, s2)
    f1, a1, b1 = _half(M2, c1, s1, c2, s2)
    return f0, f1, a0, a1, b0, b1


def _step(M1: Mat, M2: Mat, phi1: float, phi2: float) -> tuple[float, float]:
    """One damped Newton step of the two closure equations."""
    f0, f1, j10, j11, j20, j21 = _residual(M1, M2, phi1, phi2)
    det = j10 * j21 - j11 * j20
    if det == 0.0:
        return phi1, phi2
    d1 = (j21 * f0 - j20 * f1) / det
    d2 = (j10 * f1 - j11 * f0) / det
    if not (math.isfinite(d1) and math.isfinite(d2)):
        return phi1, phi2
    scale = 1.0 / max(abs(d1), abs(d2), 1.0)  # steps beyond one radian are damped
    return phi1 - scale * d1, phi2 - scale * d2


def _home_solution(
    theta: Sequence[float],
    constants: SingleConstants,
    newton_steps: int,
    polish_extra: int,
    polished: float,
    residual_tol: float,
    sign_tol: float,
) -> tuple[bool, Mat]:
    """(certified, R) of :func:`home_rotation` (R is zeros where not certified)."""
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
    V1, V2 = cols[0], cols[1]  # V[c] is column c
    w3 = w[2]
    M1 = _gram(V1, V2, c12)
    M2 = _second(V1, V2, w3, pa, pb, pd, ca2)
    phi1 = _dot(theta, slope[0])
    phi2 = _dot(theta, slope[1])
    for _ in range(newton_steps + 1):
        phi1, phi2 = _step(M1, M2, phi1, phi2)
    r6 = _residual(M1, M2, phi1, phi2)
    res = max(abs(r6[0]), abs(r6[1]))
    for _ in range(polish_extra):
        if not res > polished:
            break
        phi1, phi2 = _step(M1, M2, phi1, phi2)
        r6 = _residual(M1, M2, phi1, phi2)
        res = max(abs(r6[0]), abs(r6[1]))
    zero = (0.0, 0.0, 0.0)
    if not res <= residual_tol:
        return False, (zero, zero, zero)
    c1, s1, c2, s2 = math.cos(phi1), math.sin(phi1), math.cos(phi2), math.sin(phi2)
    v1 = (
        V1[0][0] + V1[1][0] * c1 + V1[2][0] * s1,
        V1[0][1] + V1[1][1] * c1 + V1[2][1] * s1,
        V1[0][2] + V1[1][2] * c1 + V1[2][2] * s1,
    )
    v2 = (
        V2[0][0] + V2[1][0] * c2 + V2[2][0] * s2,
        V2[0][1] + V2[1][1] * c2 + V2[2][1] * s2,
        V2[0][2] + V2[1][2] * c2 + V2[2][2] * s2,
    )
    v12 = _cross(v1, v2)
    # R = world @ body^-1, world with columns v1, v2, v1 x v2.
    R = (
        _row(v1[0], v2[0], v12[0], body_inv),
        _row(v1[1], v2[1], v12[1], body_inv),
        _row(v1[2], v2[2], v12[2], body_inv),
    )
    # Home sign rule: every b_ii = (u_i x w_i) . v_i > 0 and det A of the home sign.
    A = []
    for i in range(3):
        v = (_dot(R[0], v0[i]), _dot(R[1], v0[i]), _dot(R[2], v0[i]))
        if not _dot(_cross(u[i], w[i]), v) > sign_tol:
            return False, (zero, zero, zero)
        A.append(_cross(w[i], v))
    det_a = _dot(A[0], _cross(A[1], A[2]))
    if not (abs(det_a) > sign_tol and math.copysign(1.0, det_a) == home_sign):
        return False, (zero, zero, zero)
    return True, R


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
    ok, R = _home_solution(
        theta, constants, newton_steps, polish_extra, polished, residual_tol, sign_tol
    )
    return R if ok else None


def turned_rows(c: float, s: float, axis: Vec, outer: Mat, R: Mat) -> Mat:
    """Rot(axis, angle) @ R for the angle of cosine ``c`` and sine ``s``, in the order
    of :func:`~spm_pin.kinematics._common.rotation_about` and
    :func:`~spm_pin.kinematics.fk.turned` (same bits)."""
    x, y, z = axis
    one_c = 1.0 - c
    # c I + s [axis]x + (1 - c) axis axis^T, entry by entry.
    t = (
        (
            c + s * 0.0 + one_c * outer[0][0],
            c * 0.0 + s * -z + one_c * outer[0][1],
            c * 0.0 + s * y + one_c * outer[0][2],
        ),
        (
            c * 0.0 + s * z + one_c * outer[1][0],
            c + s * 0.0 + one_c * outer[1][1],
            c * 0.0 + s * -x + one_c * outer[1][2],
        ),
        (
            c * 0.0 + s * -y + one_c * outer[2][0],
            c * 0.0 + s * x + one_c * outer[2][1],
            c + s * 0.0 + one_c * outer[2][2],
        ),
    )
    rows = []
    for i in range(3):
        rows.append(
            (
                (t[i][0] * R[0][0] + t[i][1] * R[1][0]) + t[i][2] * R[2][0],
                (t[i][0] * R[0][1] + t[i][1] * R[1][1]) + t[i][2] * R[2][1],
                (t[i][0] * R[0][2] + t[i][1] * R[1][2]) + t[i][2] * R[2][2],
            )
        )
    return (rows[0], rows[1], rows[2])


def home_turned(
    theta: Sequence[float],
    constants: SingleConstants,
    newton_steps: int,
    polish_extra: int,
    polished: float,
    residual_tol: float,
    sign_tol: float,
    c: float,
    s: float,
    axis: Vec,
    outer: Mat,
) -> Mat | None:
    """:func:`home_rotation` at the reduced input, turned by :func:`turned_rows`."""
    ok, R = _home_solution(
        theta, constants, newton_steps, polish_extra, polished, residual_tol, sign_tol
    )
    return turned_rows(c, s, axis, outer, R) if ok else None


#: :func:`home_rotation`, :func:`home_turned` and the functions they call, callees
#: first: what :func:`spm_pin._jit.kernels` compiles.
KERNELS = (
    _cross,
    _dot,
    _rotate,
    _row,
    _gram,
    _second,
    _half,
    _residual,
    _step,
    _home_solution,
    home_rotation,
    turned_rows,
    home_turned,
)
