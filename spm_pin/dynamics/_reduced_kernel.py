r"""The reduced dynamics of :mod:`spm_pin.dynamics.reduced`, row by row in floats.

:class:`~spm_pin.dynamics.ReducedDynamics` evaluates its equations in numpy over a
batch axis; for one robot, or for the substeps of an environment, numpy's per-call
overhead on (N, 3, 3) arrays is nearly all of the time. This module repeats the same
equations for one row at a time in Python floats and tuples, in a form that numba
compiles unchanged (:func:`spm_pin._jit.kernels` of :data:`KERNELS`), with loops over
the rows of the batch:

* :func:`rotations`: the warm-started Newton solve of the platform rotation on the
  closures w_i . R v_i0 = cos a2 and the home sign rule (a per-row flag: rows that
  fail it are solved by :func:`~spm_pin.forward_kinematics` in Python, as before);
* :func:`terms`: M, c, g, the friction torques, J and S (a per-row singularity flag);
* :func:`accelerations`: theta_ddot = M^-1 (tau + tau_f - c - g);
* :func:`step`: rotation, accelerations and the integrator (semi-implicit Euler or
  rk4) of a whole time step in one call (a per-row status; rows that are not
  settled there take the Python path).

The constants (:data:`Constants`, built by ``ReducedDynamics``) travel as one tuple
of arrays and floats; each kernel turns them once into floats and tuples
(:func:`flat`), which the hot callees take, inlined into the compiled callers
(:func:`spm_pin._jit.inline`): a loop over robots reads no array of constants (as the
vectorised loops of :mod:`spm_pin.envs._block_kernel` need). The 3-vector algebra is
:mod:`spm_pin.dynamics._tuple_kernel`. Per state, cos and sin of the input angles,
the proximal axes and the distal axes (from Newton's last check) are computed once
and shared by the rotation, the terms and gravity. The mass and bias terms of a
distal link use its two axes in its own frame (x = D^T u_i, y = D^T w_i) rather than
its whole rotation D: W^T D I D^T W is a sum of three scalars times outer products.

The results agree with the numpy path to rounding (the sums are taken in another
order; ``tests/test_reduced_kernel`` compares them), not bit for bit. Nothing here
checks inputs: the callers pass checked, C-contiguous float arrays.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from .. import _jit
from ._tuple_kernel import KERNELS as TUPLE_KERNELS
from ._tuple_kernel import (
    Mat,
    Vec,
    _angle_cos_sin,
    _cos_sin,
    _cross,
    _dot,
    _mat_mul,
    _mat_of,
    _mat_t_mul,
    _mat_t_vec,
    _mat_vec,
    _mat_vecs,
    _put_mat,
    _rotate,
    _scale,
    _solve3,
    _unit,
    _vec_of,
)

__all__ = [
    "KERNELS",
    "STATUS_OK",
    "STATUS_ROTATION",
    "STATUS_SINGULAR",
    "accelerations",
    "flat",
    "home_rotation_of",
    "rotations",
    "step",
    "terms",
]

FloatArray = npt.NDArray[np.float64]

#: Row status of :func:`step`: settled.
STATUS_OK = 0
#: Row status: the warm-started rotation failed (residual or home sign rule) at a
#: stage; the Python path solves it by forward kinematics.
STATUS_ROTATION = 1
#: Row status: a parallel (type II) singularity at a stage.
STATUS_SINGULAR = 2

#: The constants of the kernels, in this order (see ``ReducedDynamics._constants``):
#: u, w0, v0 (3, 3) rows; frame_inv (3, 3, 3); dist_inertia (3, 3, 3); plat_inertia
#: (3, 3); prox_inertia (3,) (u_i^T I_O u_i of the proximal links); prox_moment
#: (3, 3); dist_moment (3, 3); plat_moment (3,); gravity (3,); viscous (9,); coulomb
#: (9,); then cos_a2, smoothing_speed, friction (0.0 none, 1.0 joint friction),
#: home_sign (sign of det A at home), sign_tol, singular_det, closure_tol,
#: newton_iterations (int); armature (3,).
Constants = tuple[Any, ...]
#: The constants as floats and tuples (:func:`flat`, made once per kernel call): what
#: the hot callees take, so that a loop over robots reads no array and takes no view
#: of one (see :func:`flat` for the order).
Flat = tuple[Any, ...]


def flat(k: Constants) -> Flat:
    """The constants ``k`` as floats and tuples, in the order of :data:`Constants`
    (u, w0, v0 and the plat_inertia as rows; frame_inv and dist_inertia as three
    matrices; prox_moment and dist_moment as three rows; viscous and coulomb as nine
    floats) except at 6: the proximal links' inertia plus the armature (3,); and
    without the armature at the end."""
    fi, di, pm, dm = k[3], k[4], k[7], k[8]
    viscous, coulomb, prox, armature = k[11], k[12], k[6], k[21]
    return (
        _mat_of(k[0]), _mat_of(k[1]), _mat_of(k[2]),
        (_mat_of(fi[0]), _mat_of(fi[1]), _mat_of(fi[2])),
        (_mat_of(di[0]), _mat_of(di[1]), _mat_of(di[2])),
        _mat_of(k[5]),
        (prox[0] + armature[0], prox[1] + armature[1], prox[2] + armature[2]),
        (_vec_of(pm[0]), _vec_of(pm[1]), _vec_of(pm[2])),
        (_vec_of(dm[0]), _vec_of(dm[1]), _vec_of(dm[2])),
        _vec_of(k[9]), _vec_of(k[10]),
        (viscous[0], viscous[1], viscous[2], viscous[3], viscous[4], viscous[5],
         viscous[6], viscous[7], viscous[8]),
        (coulomb[0], coulomb[1], coulomb[2], coulomb[3], coulomb[4], coulomb[5],
         coulomb[6], coulomb[7], coulomb[8]),
        float(k[13]), float(k[14]), float(k[15]), float(k[16]), float(k[17]), float(k[18]),
        float(k[19]), int(k[20]),
    )  # fmt: skip


def _leg_row(vJ: Vec, vu: float, vw: float, e: Vec, p: Vec) -> Vec:
    """Row i of Chi: (v_i^T J)_j - (v_i . u_i) e_ij - (v_i . w_i) Psi_ij."""
    return (
        vJ[0] - vu * e[0] - vw * p[0],
        vJ[1] - vu * e[1] - vw * p[1],
        vJ[2] - vu * e[2] - vw * p[2],
    )


def _pair(e: Vec, p: Vec, xx: float, xy: float, yy: float, j: int, m: int) -> float:
    """Entry (j, m) of xx e e^T + xy (e p^T + p e^T) + yy p p^T."""
    return xx * e[j] * e[m] + xy * (e[j] * p[m] + p[j] * e[m]) + yy * p[j] * p[m]


def _rate_rhs(
    u: Vec, w: Vec, v: Vec, uxw: Vec, w_dot: Vec, v_dot: Vec, rate: float, omega_p: Vec
) -> float:
    """Row i of B_dot theta_dot - A_dot omega_p (a_dot = w_dot x v + w x v_dot,
    b_dot = (u x w_dot) . v + (u x w) . v_dot)."""
    p = _cross(w_dot, v)
    q = _cross(w, v_dot)
    a_dot = (p[0] + q[0], p[1] + q[1], p[2] + q[2])
    b_dot = _dot(_cross(u, w_dot), v) + _dot(uxw, v_dot)
    return b_dot * rate - _dot(a_dot, omega_p)


# ------------------------------------------------------------------ kinematics
def _trig(theta: Vec) -> tuple[Vec, Vec]:
    """(cos theta_i, sin theta_i) (:func:`_angle_cos_sin`): computed once per state,
    shared by the rotation, the proximal axes and the proximal links' gravity."""
    a, b, c = _angle_cos_sin(theta[0]), _angle_cos_sin(theta[1]), _angle_cos_sin(theta[2])
    return (a[0], b[0], c[0]), (a[1], b[1], c[1])


def _proximal(cos: Vec, sin: Vec, u: Mat, w0: Mat) -> Mat:
    """Rows w_i(theta_i): w0_i turned about u_i by theta_i (given its cos and sin)."""
    return (
        _rotate(u[0], cos[0], sin[0], w0[0]),
        _rotate(u[1], cos[1], sin[1], w0[1]),
        _rotate(u[2], cos[2], sin[2], w0[2]),
    )


def _cofactors(a: Mat) -> Mat:
    """Rows a_1 x a_2, a_2 x a_0, a_0 x a_1 (the columns of det(A) A^-1)."""
    return (_cross(a[1], a[2]), _cross(a[2], a[0]), _cross(a[0], a[1]))


def _closure(R: Mat, w: Mat, v0: Mat, cos_a2: float) -> tuple[Mat, Vec, float]:
    """(v, r, residual) of the rotation R: the distal axes v_i = R v_i0, the closures
    r_i = w_i . v_i - cos a2 and max |r_i| (NaN when an r_i is NaN)."""
    v = _mat_vecs(R, v0)
    r = (_dot(w[0], v[0]) - cos_a2, _dot(w[1], v[1]) - cos_a2, _dot(w[2], v[2]) - cos_a2)
    residual = max(abs(r[0]), abs(r[1]), abs(r[2]))
    if math.isnan(r[0]) or math.isnan(r[1]) or math.isnan(r[2]):
        residual = math.nan
    return v, r, residual


def _newton_step(w: Mat, v: Mat, r: Vec) -> tuple[Vec, float]:
    """(axis, angle) of Newton's turn of the platform from the closures r: delta =
    A^-1 r with the rows a_i = w_i x v_i (|det A| at least 1e-300)."""
    a = (_cross(w[0], v[0]), _cross(w[1], v[1]), _cross(w[2], v[2]))
    cof = _cofactors(a)
    det = _dot(a[0], cof[0])
    if not abs(det) > 1e-300:
        det = 1e-300
    delta = (
        (r[0] * cof[0][0] + r[1] * cof[1][0] + r[2] * cof[2][0]) / det,
        (r[0] * cof[0][1] + r[1] * cof[1][1] + r[2] * cof[2][1]) / det,
        (r[0] * cof[0][2] + r[1] * cof[1][2] + r[2] * cof[2][2]) / det,
    )
    angle = math.sqrt(_dot(delta, delta))
    safe = angle if angle > 0.0 else 1.0
    return (delta[0] / safe, delta[1] / safe, delta[2] / safe), angle


def _turned(R: Mat, axis: Vec, c: float, s: float) -> Mat:
    """R with each column turned about the axis by the angle of cos c and sin s."""
    k0 = _rotate(axis, c, s, (R[0][0], R[1][0], R[2][0]))
    k1 = _rotate(axis, c, s, (R[0][1], R[1][1], R[2][1]))
    k2 = _rotate(axis, c, s, (R[0][2], R[1][2], R[2][2]))
    return ((k0[0], k1[0], k2[0]), (k0[1], k1[1], k2[1]), (k0[2], k1[2], k2[2]))


def _newton(R: Mat, w: Mat, v0: Mat, cos_a2: float, stop: float, iterations: int) -> Any:
    """The warm-started Newton of ``ReducedDynamics._rotation`` on one row:
    (R, the residual max |w_i . R v_i0 - cos a2| of the last iterate checked, the
    distal axes v_i = R v_i0 of R: the last check's, else computed)."""
    residual, checked, zero = math.inf, False, (0.0, 0.0, 0.0)
    v = (zero, zero, zero)
    for _ in range(iterations):
        v, r, residual = _closure(R, w, v0, cos_a2)
        checked = residual <= stop
        if checked:
            break
        axis, angle = _newton_step(w, v, r)
        R = _turned(R, axis, *_cos_sin(angle))
    return R, residual, v if checked else _mat_vecs(R, v0)


@_jit.inline
def _home_of(b: Vec, det_a: float, home_sign: float, sign_tol: float) -> bool:
    """The home sign rule of b_ii = (u_i x w_i) . v_i and det A (rows w_i x v_i):
    every b_ii > sign_tol, and det A of the sign it has at home (``home_sign``) and
    larger than sign_tol in size (:func:`_row_terms` gives both)."""
    same_sign = (det_a > 0.0 and home_sign > 0.0) or (det_a < 0.0 and home_sign < 0.0)
    home = b[0] > sign_tol and b[1] > sign_tol and b[2] > sign_tol and same_sign
    return home and abs(det_a) > sign_tol


def _home_rule(R: Mat, w: Mat, u: Mat, v0: Mat, home_sign: float, sign_tol: float) -> bool:
    """The home sign rule (:func:`_home_of`) of the rotation R, b and det A computed
    as :func:`_row_terms` computes them (the same operations: the same bits)."""
    v = _mat_vecs(R, v0)
    b0 = _dot(_cross(u[0], w[0]), v[0])
    b1 = _dot(_cross(u[1], w[1]), v[1])
    b2 = _dot(_cross(u[2], w[2]), v[2])
    a = (_cross(w[0], v[0]), _cross(w[1], v[1]), _cross(w[2], v[2]))
    det_a = _dot(a[0], _cross(a[1], a[2]))
    return _home_of((b0, b1, b2), det_a, home_sign, sign_tol)


@_jit.inline
def _home_rotation(w: Mat, R: Mat, f: Flat) -> tuple[bool, Mat]:
    """(settled, R) for the proximal axes w: Newton from R, accepted when the residual
    is within the closure tolerance and the home sign rule holds (every b_ii >
    sign_tol, det A of the sign it has at home and larger than sign_tol in size)."""
    return _settle(w, R, f[0], f[2], f[13], f[16], f[17], f[19], f[20])


def home_rotation_of(
    theta: Vec,
    R: Mat,
    u: Mat,
    w0: Mat,
    v0: Mat,
    cos_a2: float,
    home_sign: float,
    sign_tol: float,
    tol: float,
    iterations: int,
) -> tuple[bool, Mat]:
    """:func:`_home_rotation` of the input angles theta, with its constants given one
    by one: the design's rows u, w0, v0, cos a2, the sign of det A at home, the sign
    tolerance, the closure tolerance and the Newton iterations."""
    cos, sin = _trig(theta)
    w = _proximal(cos, sin, u, w0)
    return _settle(w, R, u, v0, cos_a2, home_sign, sign_tol, tol, iterations)


def _settle(
    w: Mat,
    R: Mat,
    u: Mat,
    v0: Mat,
    cos_a2: float,
    home_sign: float,
    sign_tol: float,
    tol: float,
    iterations: int,
) -> tuple[bool, Mat]:
    """:func:`home_rotation_of` from the proximal axes w."""
    R, residual, _ = _newton(R, w, v0, cos_a2, 0.1 * tol, int(iterations))
    home = _home_rule(R, w, u, v0, home_sign, sign_tol)
    ok = math.isfinite(residual) and residual <= tol and home
    return ok, R


@_jit.inline
def _leg_terms(
    ui: Vec,
    wi: Vec,
    vi: Vec,
    ai: Vec,
    e: Vec,
    P: Vec,
    Fi: Mat,
    I_d: Mat,
    dist_moment: Vec,
    prox_moment: Vec,
    cos_i: float,
    sin_i: float,
    grav: Vec,
    bias: bool,
    alpha_p: Vec,
    psi_dot: float,
    chi_dot: float,
    w_dot: Vec,
    v_dot: Vec,
    s_i: Vec,
    uw: Vec,
    ri: float,
) -> Any:
    """What leg i adds to M (its entries 00, 01, 02, 11, 12, 22), to g and to c (zero
    without ``bias``): its distal link and its proximal link's weight. e = e_i,
    P = Psi_i; the rest are leg i's elements of :func:`_row_terms`' quantities."""
    # The distal link turns with D_i = [w_i v_i a_i] F_i^-1 and at
    # omega_d,i = W theta_dot, W = u_i e_i^T + w_i Psi_i^T: in its frame the axes
    # u_i, w_i are x = D^T u_i, y = D^T w_i (D^T = F_i^-T [w_i v_i a_i]^T), so
    # W^T D I_d D^T W = xx e e^T + xy (e Psi_i^T + Psi_i e^T) + yy Psi_i Psi_i^T.
    x = _mat_t_vec(Fi, (_dot(wi, ui), _dot(vi, ui), _dot(ai, ui)))
    y = _mat_t_vec(Fi, (_dot(wi, wi), _dot(vi, wi), _dot(ai, wi)))
    Ix = _mat_vec(I_d, x)
    Iy = _mat_vec(I_d, y)
    xx, xy, yy = _dot(x, Ix), _dot(y, Ix), _dot(y, Iy)
    m = (
        _pair(e, P, xx, xy, yy, 0, 0),
        _pair(e, P, xx, xy, yy, 0, 1),
        _pair(e, P, xx, xy, yy, 0, 2),
        _pair(e, P, xx, xy, yy, 1, 1),
        _pair(e, P, xx, xy, yy, 1, 2),
        _pair(e, P, xx, xy, yy, 2, 2),
    )
    # gravity: the distal link's weight (first moment D h = [w v a] F^-1 h), and the
    # proximal link's
    p = _mat_vec(Fi, dist_moment)
    dist_h = (
        wi[0] * p[0] + vi[0] * p[1] + ai[0] * p[2],
        wi[1] * p[0] + vi[1] * p[1] + ai[1] * p[2],
        wi[2] * p[0] + vi[2] * p[1] + ai[2] * p[2],
    )
    weight = _cross(dist_h, grav)
    gu, gw = _dot(ui, weight), _dot(wi, weight)  # W^T z = e (u.z) + Psi_i (w.z)
    prox_h = _rotate(ui, cos_i, sin_i, prox_moment)
    gi = -_dot(ui, _cross(prox_h, grav))
    g = (
        gi * e[0] - (gu * e[0] + gw * P[0]),
        gi * e[1] - (gu * e[1] + gw * P[1]),
        gi * e[2] - (gu * e[2] + gw * P[2]),
    )
    c = (0.0, 0.0, 0.0)
    if bias:
        psi_ddot = _dot(
            (
                alpha_p[0] - psi_dot * w_dot[0] - chi_dot * v_dot[0],
                alpha_p[1] - psi_dot * w_dot[1] - chi_dot * v_dot[1],
                alpha_p[2] - psi_dot * w_dot[2] - chi_dot * v_dot[2],
            ),
            s_i,
        )
        # in the link's frame: omega_d = x rate_i + y psi_dot_i, and
        # alpha_d = psi_ddot y + psi_dot_i rate_i z, z = D^T (u_i x w_i)
        z = _mat_t_vec(Fi, (_dot(wi, uw), _dot(vi, uw), _dot(ai, uw)))
        Iz = _mat_vec(I_d, z)
        spin = psi_dot * ri
        od = (x[0] * ri + y[0] * psi_dot, x[1] * ri + y[1] * psi_dot, x[2] * ri + y[2] * psi_dot)
        Iod = (
            Ix[0] * ri + Iy[0] * psi_dot,
            Ix[1] * ri + Iy[1] * psi_dot,
            Ix[2] * ri + Iy[2] * psi_dot,
        )
        gyro = _cross(od, Iod)
        q = (
            Iy[0] * psi_ddot + Iz[0] * spin + gyro[0],
            Iy[1] * psi_ddot + Iz[1] * spin + gyro[1],
            Iy[2] * psi_ddot + Iz[2] * spin + gyro[2],
        )
        cu, cw = _dot(x, q), _dot(y, q)  # W^T D q = e (x.q) + Psi_i (y.q)
        c = (cu * e[0] + cw * P[0], cu * e[1] + cw * P[1], cu * e[2] + cw * P[2])
    return m, g, c


# ------------------------------------------------------------------ dynamics
@_jit.inline
def _row_terms(cos: Vec, sin: Vec, w: Mat, v: Mat, rate: Vec, R: Mat, f: Flat, bias: bool) -> Any:
    """Every term of one state (the cos and sin of its input angles, its proximal axes
    w, its distal axes v_i = R v_i0) but friction, as ``ReducedDynamics._terms`` and
    ``_bias``: (singular, det A, M, c, g, J, Psi, Chi, Psi theta_dot, Chi theta_dot,
    b), b_ii = (u_i x w_i) . v_i the diagonal of B (det A and b: what the home sign
    rule :func:`_home_of` takes)."""
    u = f[0]
    frame_inv, dist_inertia, I_p, prox_diag = f[3], f[4], f[5], f[6]
    prox_moment, dist_moment, plat_moment, grav = f[7], f[8], f[9], f[10]
    singular_det = f[18]
    a = (_cross(w[0], v[0]), _cross(w[1], v[1]), _cross(w[2], v[2]))
    uxw = (_cross(u[0], w[0]), _cross(u[1], w[1]), _cross(u[2], w[2]))
    b = (_dot(uxw[0], v[0]), _dot(uxw[1], v[1]), _dot(uxw[2], v[2]))
    cof = _cofactors(a)
    det = _dot(a[0], cof[0])
    aa = (_dot(a[0], a[0]), _dot(a[1], a[1]), _dot(a[2], a[2]))
    scale = math.sqrt(aa[0]) * math.sqrt(aa[1]) * math.sqrt(aa[2])
    zero: Mat = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    zero3: Vec = (0.0, 0.0, 0.0)
    if not abs(det) > singular_det * scale:
        return True, det, zero, zero3, zero3, zero, zero, zero, zero3, zero3, b
    # J = A^-1 B: J[k][j] = cof[j][k] b_j / det
    q = (b[0] / det, b[1] / det, b[2] / det)
    J: Mat = (
        (cof[0][0] * q[0], cof[1][0] * q[1], cof[2][0] * q[2]),
        (cof[0][1] * q[0], cof[1][1] * q[1], cof[2][1] * q[2]),
        (cof[0][2] * q[0], cof[1][2] * q[1], cof[2][2] * q[2]),
    )
    s0 = _cross(v[0], a[0])
    s1 = _cross(v[1], a[1])
    s2 = _cross(v[2], a[2])
    s = (
        (s0[0] / aa[0], s0[1] / aa[0], s0[2] / aa[0]),
        (s1[0] / aa[1], s1[1] / aa[1], s1[2] / aa[1]),
        (s2[0] / aa[2], s2[1] / aa[2], s2[2] / aa[2]),
    )
    sJ = (_mat_t_vec(J, s[0]), _mat_t_vec(J, s[1]), _mat_t_vec(J, s[2]))
    su = (_dot(s[0], u[0]), _dot(s[1], u[1]), _dot(s[2], u[2]))
    Psi: Mat = (
        (sJ[0][0] - su[0], sJ[0][1], sJ[0][2]),
        (sJ[1][0], sJ[1][1] - su[1], sJ[1][2]),
        (sJ[2][0], sJ[2][1], sJ[2][2] - su[2]),
    )
    vJ = (_mat_t_vec(J, v[0]), _mat_t_vec(J, v[1]), _mat_t_vec(J, v[2]))
    vu = (_dot(v[0], u[0]), _dot(v[1], u[1]), _dot(v[2], u[2]))
    vw = (_dot(v[0], w[0]), _dot(v[1], w[1]), _dot(v[2], w[2]))
    Chi: Mat = (
        _leg_row(vJ[0], vu[0], vw[0], _unit(0), Psi[0]),
        _leg_row(vJ[1], vu[1], vw[1], _unit(1), Psi[1]),
        _leg_row(vJ[2], vu[2], vw[2], _unit(2), Psi[2]),
    )
    # omega_d,i = W_d,i theta_dot, W_d,i[m][j] = u_i[m] e_ij + w_i[m] Psi_i[j]
    omega_p = _mat_vec(J, rate)
    psi_dot = _mat_vec(Psi, rate)
    chi_dot = _mat_vec(Chi, rate)
    w_dot = (
        _scale(rate[0], uxw[0]),
        _scale(rate[1], uxw[1]),
        _scale(rate[2], uxw[2]),
    )  # the proximal links turn w_i about u_i
    v_dot = (_cross(omega_p, v[0]), _cross(omega_p, v[1]), _cross(omega_p, v[2]))
    alpha_p = zero3
    if bias:
        # A alpha_p = B_dot theta_dot - A_dot omega_p  (theta_ddot = 0)
        rhs = (
            _rate_rhs(u[0], w[0], v[0], uxw[0], w_dot[0], v_dot[0], rate[0], omega_p),
            _rate_rhs(u[1], w[1], v[1], uxw[1], w_dot[1], v_dot[1], rate[1], omega_p),
            _rate_rhs(u[2], w[2], v[2], uxw[2], w_dot[2], v_dot[2], rate[2], omega_p),
        )
        alpha_p = _mat_t_vec(cof, rhs)
        alpha_p = (alpha_p[0] / det, alpha_p[1] / det, alpha_p[2] / det)
    # leg by leg, each with its own elements (an unrolled loop: tuples indexed by a
    # constant stay in registers)
    legs = (
        _leg_terms(u[0], w[0], v[0], a[0], _unit(0), Psi[0], frame_inv[0], dist_inertia[0],
                   dist_moment[0], prox_moment[0], cos[0], sin[0], grav, bias, alpha_p,
                   psi_dot[0], chi_dot[0], w_dot[0], v_dot[0], s[0], uxw[0], rate[0]),
        _leg_terms(u[1], w[1], v[1], a[1], _unit(1), Psi[1], frame_inv[1], dist_inertia[1],
                   dist_moment[1], prox_moment[1], cos[1], sin[1], grav, bias, alpha_p,
                   psi_dot[1], chi_dot[1], w_dot[1], v_dot[1], s[1], uxw[1], rate[1]),
        _leg_terms(u[2], w[2], v[2], a[2], _unit(2), Psi[2], frame_inv[2], dist_inertia[2],
                   dist_moment[2], prox_moment[2], cos[2], sin[2], grav, bias, alpha_p,
                   psi_dot[2], chi_dot[2], w_dot[2], v_dot[2], s[2], uxw[2], rate[2]),
    )  # fmt: skip
    (m0, h0, q0), (m1, h1, q1), (m2, h2, q2) = legs
    M00 = 0.0 + m0[0] + m1[0] + m2[0]
    M01 = 0.0 + m0[1] + m1[1] + m2[1]
    M02 = 0.0 + m0[2] + m1[2] + m2[2]
    M11 = 0.0 + m0[3] + m1[3] + m2[3]
    M12 = 0.0 + m0[4] + m1[4] + m2[4]
    M22 = 0.0 + m0[5] + m1[5] + m2[5]
    g0 = 0.0 + h0[0] + h1[0] + h2[0]
    g1 = 0.0 + h0[1] + h1[1] + h2[1]
    g2 = 0.0 + h0[2] + h1[2] + h2[2]
    c0 = 0.0 + q0[0] + q1[0] + q2[0]
    c1 = 0.0 + q0[1] + q1[1] + q2[1]
    c2 = 0.0 + q0[2] + q1[2] + q2[2]
    # the platform
    Jp = _mat_t_mul(R, J)  # R^T J
    part = _mat_t_mul(Jp, _mat_mul(I_p, Jp))
    M00 += part[0][0] + prox_diag[0]
    M01 += part[0][1]
    M02 += part[0][2]
    M11 += part[1][1] + prox_diag[1]
    M12 += part[1][2]
    M22 += part[2][2] + prox_diag[2]
    M: Mat = ((M00, M01, M02), (M01, M11, M12), (M02, M12, M22))
    plat_h = _mat_vec(R, plat_moment)
    torque = _mat_t_vec(J, _cross(plat_h, grav))
    g: Vec = (g0 - torque[0], g1 - torque[1], g2 - torque[2])
    c: Vec = (c0, c1, c2)
    if bias:
        op = _mat_t_vec(R, omega_p)
        ap = _mat_t_vec(R, alpha_p)
        t1 = _mat_vec(I_p, ap)
        t2 = _cross(op, _mat_vec(I_p, op))
        world = _mat_vec(R, (t1[0] + t2[0], t1[1] + t2[1], t1[2] + t2[2]))
        cp = _mat_t_vec(J, world)
        c = (c0 + cp[0], c1 + cp[1], c2 + cp[2])
    return False, det, M, c, g, J, Psi, Chi, psi_dot, chi_dot, b


@_jit.inline
def _friction(rate: Vec, Psi: Mat, Chi: Mat, psi_dot: Vec, chi_dot: Vec, f: Flat) -> Vec:
    """The joints' friction torques on the inputs (zero without friction), from the
    terms of :func:`_row_terms`."""
    if not f[15] > 0.0:
        return (0.0, 0.0, 0.0)
    viscous, coulomb, smoothing = f[11], f[12], f[14]
    f0 = f1 = f2 = 0.0
    for i in range(3):
        # joints u_i, w_i, v_i of leg i: rates theta_dot_i, psi_dot_i, chi_dot_i
        rows = (_unit(i), Psi[i], Chi[i])
        joint_rates = (rate[i], psi_dot[i], chi_dot[i])
        for m in range(3):
            jr = joint_rates[m]
            q = -viscous[3 * i + m] * jr
            if coulomb[3 * i + m] != 0.0:  # as numpy: zero adds nothing
                q -= coulomb[3 * i + m] * math.tanh(jr / smoothing)
            f0 += rows[m][0] * q
            f1 += rows[m][1] * q
            f2 += rows[m][2] * q
    return (f0, f1, f2)


def _solve_acceleration(M: Mat, c: Vec, g: Vec, friction: Vec, tau: Vec) -> Vec:
    """theta_ddot = M^-1 (tau + friction - c - g)."""
    rhs = (
        tau[0] + friction[0] - c[0] - g[0],
        tau[1] + friction[1] - c[1] - g[1],
        tau[2] + friction[2] - c[2] - g[2],
    )
    return _solve3(M, rhs)


@_jit.inline
def _row_acceleration(
    cos: Vec, sin: Vec, w: Mat, v: Mat, rate: Vec, tau: Vec, R: Mat, f: Flat
) -> Any:
    """(singular, det A, theta_ddot, b) of one state (as :func:`_row_terms` takes it;
    det A and b as it gives them)."""
    singular, det, M, c, g, _, Psi, Chi, psi_dot, chi_dot, b = _row_terms(
        cos, sin, w, v, rate, R, f, True
    )
    if singular:
        return True, det, (0.0, 0.0, 0.0), b
    friction = _friction(rate, Psi, Chi, psi_dot, chi_dot, f)
    return False, det, _solve_acceleration(M, c, g, friction, tau), b


# ------------------------------------------------------------------ batches
def rotations(theta: FloatArray, reference: FloatArray, k: Constants, R: FloatArray) -> Any:
    """Warm-started rotations of rows (N, 3) from ``reference`` (N, 3, 3) into ``R``
    (N, 3, 3); returns the settled flags (N,) (False: solve by forward kinematics)."""
    n = theta.shape[0]
    ok = np.zeros(n, dtype=np.bool_)
    for row in range(n):
        done, rotation = home_rotation_of(
            _vec_of(theta[row]),
            _mat_of(reference[row]),
            _mat_of(k[0]),
            _mat_of(k[1]),
            _mat_of(k[2]),
            k[13],
            k[16],
            k[17],
            k[19],
            int(k[20]),
        )
        ok[row] = done
        _put_mat(R[row], rotation)
    return ok


def terms(
    theta: FloatArray,
    rate: FloatArray,
    R: FloatArray,
    k: Constants,
    bias: bool,
    M: FloatArray,
    c: FloatArray,
    g: FloatArray,
    friction: FloatArray,
    J: FloatArray,
    S: FloatArray,
    det: FloatArray,
) -> Any:
    """M, c (zero without ``bias``), g, friction, J, S and det A of rows into the given
    arrays; returns the singular flags (N,) (their rows left unwritten)."""
    n = theta.shape[0]
    singular = np.zeros(n, dtype=np.bool_)
    f = flat(k)
    for row in range(n):
        cos, sin = _trig(_vec_of(theta[row]))
        w = _proximal(cos, sin, f[0], f[1])
        r, rotation = _vec_of(rate[row]), _mat_of(R[row])
        out = _row_terms(cos, sin, w, _mat_vecs(rotation, f[2]), r, rotation, f, bias)
        singular[row] = out[0]
        det[row] = out[1]
        if out[0]:
            continue
        Psi, Chi = out[6], out[7]
        tau_f = _friction(r, Psi, Chi, out[8], out[9], f)
        _put_mat(M[row], out[2])
        for j in range(3):
            c[row, j] = out[3][j]
            g[row, j] = out[4][j]
            friction[row, j] = tau_f[j]
        _put_mat(J[row], out[5])
        for i in range(3):
            for j in range(3):
                S[row, 3 * i, j] = 1.0 if i == j else 0.0
                S[row, 3 * i + 1, j] = Psi[i][j]
                S[row, 3 * i + 2, j] = Chi[i][j]
    return singular


def accelerations(
    theta: FloatArray,
    rate: FloatArray,
    tau: FloatArray,
    R: FloatArray,
    k: Constants,
    out: FloatArray,
    det: FloatArray,
) -> Any:
    """theta_ddot of rows into ``out`` (N, 3), det A into ``det``; returns the singular
    flags (N,)."""
    n = theta.shape[0]
    singular = np.zeros(n, dtype=np.bool_)
    f = flat(k)
    for row in range(n):
        cos, sin = _trig(_vec_of(theta[row]))
        w = _proximal(cos, sin, f[0], f[1])
        r, rotation = _vec_of(rate[row]), _mat_of(R[row])
        bad, d, acc, _ = _row_acceleration(
            cos, sin, w, _mat_vecs(rotation, f[2]), r, _vec_of(tau[row]), rotation, f
        )
        singular[row] = bad
        det[row] = d
        out[row, 0], out[row, 1], out[row, 2] = acc
    return singular


def _rk4_stage(
    theta: Vec, rate: Vec, r: Vec, a: Vec, step: float, tau: Vec, R: Mat, f: Flat
) -> Any:
    """One intermediate RK4 stage of one robot, at theta + step r with the rate
    rate + step a, its rotation warm-started from R: (status, the stage's rate, its
    theta_ddot)."""
    t = (theta[0] + step * r[0], theta[1] + step * r[1], theta[2] + step * r[2])
    rs = (rate[0] + step * a[0], rate[1] + step * a[1], rate[2] + step * a[2])
    cos, sin = _trig(t)
    w = _proximal(cos, sin, f[0], f[1])
    ok, Rs = _home_rotation(w, R, f)
    if not ok:
        return STATUS_ROTATION, rs, rs
    bad, _, acc, _ = _row_acceleration(cos, sin, w, _mat_vecs(Rs, f[2]), rs, tau, Rs, f)
    if bad:
        return STATUS_SINGULAR, rs, acc
    return STATUS_OK, rs, acc


@_jit.inline
def _row_step(
    theta: Vec,
    cos: Vec,
    sin: Vec,
    w: Mat,
    v: Mat,
    rate: Vec,
    tau: Vec,
    R: Mat,
    h: float,
    rk4: bool,
    f: Flat,
) -> Any:
    """One time step of one robot from a rotation R (cos, sin: of theta; w, v: its
    proximal and distal axes, v_i = R v_i0): (status, theta', rate', theta_ddot, b,
    det A), the last two at R (the home sign rule's, :func:`_home_of`: R is settled
    where it holds)."""
    zero = (0.0, 0.0, 0.0)
    bad, det, a1, b = _row_acceleration(cos, sin, w, v, rate, tau, R, f)
    if bad:
        return STATUS_SINGULAR, zero, zero, zero, b, det
    if not rk4:
        r = (rate[0] + h * a1[0], rate[1] + h * a1[1], rate[2] + h * a1[2])
        t = (theta[0] + h * r[0], theta[1] + h * r[1], theta[2] + h * r[2])
        return STATUS_OK, t, r, a1, b, det
    half = 0.5 * h
    status, r2, a2 = _rk4_stage(theta, rate, rate, a1, half, tau, R, f)
    if status != STATUS_OK:
        return status, zero, zero, zero, b, det
    status, r3, a3 = _rk4_stage(theta, rate, r2, a2, half, tau, R, f)
    if status != STATUS_OK:
        return status, zero, zero, zero, b, det
    status, r4, a4 = _rk4_stage(theta, rate, r3, a3, h, tau, R, f)
    if status != STATUS_OK:
        return status, zero, zero, zero, b, det
    sixth = h / 6.0
    t = (
        theta[0] + sixth * (rate[0] + 2.0 * (r2[0] + r3[0]) + r4[0]),
        theta[1] + sixth * (rate[1] + 2.0 * (r2[1] + r3[1]) + r4[1]),
        theta[2] + sixth * (rate[2] + 2.0 * (r2[2] + r3[2]) + r4[2]),
    )
    r = (
        rate[0] + sixth * (a1[0] + 2.0 * (a2[0] + a3[0]) + a4[0]),
        rate[1] + sixth * (a1[1] + 2.0 * (a2[1] + a3[1]) + a4[1]),
        rate[2] + sixth * (a1[2] + 2.0 * (a2[2] + a3[2]) + a4[2]),
    )
    return STATUS_OK, t, r, a1, b, det


def step(
    theta: FloatArray,
    rate: FloatArray,
    tau: FloatArray,
    reference: FloatArray,
    h: float,
    rk4: bool,
    k: Constants,
    theta_out: FloatArray,
    rate_out: FloatArray,
    acc_out: FloatArray,
    R_out: FloatArray,
) -> int:
    """One time step of rows (N, 3) warm-started from ``reference`` (N, 3, 3), into the
    output arrays (R_out: the rotations at the start). Stops at the first row that is
    not settled (a failed warm-started rotation at any stage, or a singularity) and
    returns its status (:data:`STATUS_ROTATION` or :data:`STATUS_SINGULAR`): the
    caller takes the Python path for the whole batch. :data:`STATUS_OK` otherwise."""
    n = theta.shape[0]
    f = flat(k)
    for row in range(n):
        th = _vec_of(theta[row])
        cos, sin = _trig(th)
        w = _proximal(cos, sin, f[0], f[1])
        ok, R = _home_rotation(w, _mat_of(reference[row]), f)
        if not ok:
            return STATUS_ROTATION
        status, t, r, acc, _, _ = _row_step(
            th, cos, sin, w, _mat_vecs(R, f[2]), _vec_of(rate[row]), _vec_of(tau[row]), R, h,
            rk4, f,
        )  # fmt: skip
        if status != STATUS_OK:
            return int(status)
        _put_mat(R_out[row], R)
        for j in range(3):
            theta_out[row, j] = t[j]
            rate_out[row, j] = r[j]
            acc_out[row, j] = acc[j]
    return STATUS_OK


#: The kernels, callees first: what :func:`spm_pin._jit.kernels` compiles.
KERNELS = (
    *TUPLE_KERNELS,
    flat,
    _leg_row,
    _pair,
    _rate_rhs,
    _leg_terms,
    _trig,
    _proximal,
    _cofactors,
    _closure,
    _newton_step,
    _turned,
    _newton,
    _home_of,
    _home_rule,
    _settle,
    home_rotation_of,
    _home_rotation,
    _row_terms,
    _friction,
    _solve_acceleration,
    _row_acceleration,
    rotations,
    terms,
    accelerations,
    _rk4_stage,
    _row_step,
    step,
)
