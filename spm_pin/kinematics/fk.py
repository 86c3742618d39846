r"""Forward kinematics: input angles theta -> platform orientation R, every assembly mode.

Method (numpy, vectorised over any batch shape):

1. Legs 1 and 2: with p_i = (u_i x w_i)/|u_i x w_i| and q_i = w_i x p_i, the platform
   axis v_i lies on the cone v_i(phi_i) = cos a2 w_i + sin a2 (cos phi_i p_i +
   sin phi_i q_i), so b_ii = |u_i x w_i| sin a2 cos phi_i.
2. The platform is rigid: v_1 . v_2 = v_10 . v_20, and v_3 = a v_1 + b v_2 +
   d (v_1 x v_2) must close leg 3: w_3 . v_3 = cos a2. Both equations are bilinear
   in m(phi_1) = [1, cos phi_1, sin phi_1] and m(phi_2): m1^T M_k m2 = 0.
3. With x_i = tan((phi_i - sigma)/2) (an offset sigma keeps the symmetric roots
   phi = 0, pi at finite x), each equation is a quadratic in x_2 whose coefficients
   are quadratic in x_1; their Sylvester resultant is a polynomial of degree 8 in
   x_1, solved through its companion matrix. Each real root gives phi_1; phi_2
   follows in closed form from v_1 . v_2; both are polished by Newton steps on the
   two equations to machine precision and duplicates are merged.
4. R = [v1 v2 v1xv2] [v10 v20 v10xv20]^-1.

An assembly mode is labelled by the signs of b_11, b_22, b_33 and of det A
(A has rows a_i = w_i x v_i), e.g. ``"+++/-"``. The home assembly mode has every
b_ii > 0 and det A of the sign it has at home (negative for the prototype).

:func:`forward_kinematics` returns the home mode only. It first runs Newton on the
two equations from the home-like start (for coaxial designs after removing the
common turn of the inputs, which only turns the platform about the axis) and keeps a
solution that satisfies the sign rule; items where that fails go through the full
resultant solve. Where a design admits several sign-rule modes (never seen for the
prototype), pass ``reference`` to choose by continuity, or use
:func:`forward_kinematics_all` or :func:`spm_pin.kinematics.track`.

Unreachable inputs are detected early for coaxial designs (:mod:`._reach`): whether
an input has a home-mode assembly depends only on its gaps (d_1, d_2), and a table of
the gap torus marks the cells where no input can have one, proven by branch-and-bound
with Lipschitz bounds on the two closure equations, b_33 and det A (margin 1e-9, far
above the solver's 1e-12 acceptance). Inputs in those cells return unreachable at
once; the others take the path above, so answers do not change. Measured alternatives:
pairwise cone conditions (only the sign rule without det A: they leave agile-eye-like
designs, whose mirror modes keep every b_ii > 0, entirely undecided and reject 57 % of
the prototype's unreachable inputs) and a per-input branch-and-bound (over 100 us per
input, slower than the resultant); the table decides 92 % of the prototype's
unreachable uniform inputs for one lookup each. Non-coaxial designs keep the usual path.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..errors import InputError
from . import _reach
from ._common import (
    BoolArray,
    FloatArray,
    as_rotation,
    as_theta,
    check_design,
    cross,
    proximal_axes,
    rotation_about,
)
from ._fk_single import SingleConstants, home_rotation, make_constants

__all__ = [
    "MAX_ASSEMBLY_MODES",
    "FKAllResult",
    "FKResult",
    "forward_kinematics",
    "forward_kinematics_all",
    "satisfies_home_rule",
]

#: A 3-RRR SPM has at most 8 real assembly modes.
MAX_ASSEMBLY_MODES = 8

#: Closure residual below which a solution is accepted [unit-vector dot products].
RESIDUAL_TOL = 1e-12
#: |b_ii| and |det A| at or below this are on a singularity and carry no sign.
_SIGN_TOL = 1e-9
#: Offsets of the tan-half parameterisation (the second one is a fallback).
_SIGMAS = (0.7234, -1.9113)
#: Imaginary part (relative) below which a resultant root is treated as real.
_IMAG_TOL = 1e-4
#: Two solutions closer than this in (phi_1, phi_2) are the same [rad].
_DUPLICATE_TOL = 1e-7
_NEWTON_STEPS_POLISH = 6
_NEWTON_STEPS_SLOW = 40
_NEWTON_STEPS_FAST = 3
#: Residual of the two equations regarded as rounding level after polishing.
_POLISHED = 1e-14
_POLISH_EXTRA = 5
#: Batches at least this large build the unreachable-cell table of a coaxial design
#: (about a second, once per design and process); smaller ones use it once built.
_TABLE_MIN_BATCH = 4096


@dataclasses.dataclass(frozen=True)
class FKResult:
    """Home-mode forward kinematics.

    Attributes:
        theta: The input angles [rad], shape (..., 3).
        R: Platform rotation, (..., 3, 3); NaN where not reachable.
        v: Platform joint axes v_1..v_3 as rows, (..., 3, 3) (v_i = R v_i0).
        w: Proximal-distal joint axes w_1..w_3 as rows, (..., 3, 3).
        reachable: (...,) True where a home-mode assembly exists.
        residual: (...,) max_i |w_i . v_i - cos a2| and |R^T R - I| (NaN where not
            reachable).
    """

    theta: FloatArray
    R: FloatArray
    v: FloatArray
    w: FloatArray
    reachable: BoolArray
    residual: FloatArray


@dataclasses.dataclass(frozen=True)
class FKAllResult:
    """Every real assembly mode, padded to 8 slots along axis -3 (or -1 for flags).

    Slots are sorted: home-rule modes first, then by label (see :attr:`labels`).
    Unused slots have ``valid`` False and NaN arrays.

    Attributes:
        theta: (..., 3) input angles [rad].
        R: (..., 8, 3, 3) platform rotations.
        v: (..., 8, 3, 3) platform joint axes (rows).
        w: (..., 3, 3) proximal-distal axes (the same in every mode).
        valid: (..., 8) which slots hold a solution.
        count: (...,) number of real assembly modes.
        b: (..., 8, 3) b_ii = (u_i x w_i) . v_i.
        det_a: (..., 8) det A.
        home: (..., 8) the slot satisfies the home sign rule.
        residual: (..., 8) closure residual of each solution.
    """

    theta: FloatArray
    R: FloatArray
    v: FloatArray
    w: FloatArray
    valid: BoolArray
    count: npt.NDArray[np.int64]
    b: FloatArray
    det_a: FloatArray
    home: BoolArray
    residual: FloatArray

    @property
    def labels(self) -> list[object]:
        """Nested lists (batch shape, 8) of unique labels ('' for unused slots).

        A label is the signs of b_11, b_22, b_33 and det A, e.g. ``"+++/-"``. Where
        several modes of one input share these signs, the first keeps the bare label
        and the k-th is suffixed ``#k`` (``"-+-/-#2"``), in slot order: modes sharing
        their signs are ordered by the tilt of the platform (smallest first), then by
        the cone angles of v_1 and v_2, so the labels of an input are unique by
        construction."""
        return _labels(self.b, self.det_a, self.valid)

    @property
    def home_index(self) -> npt.NDArray[np.int64]:
        """(...,) slot of the first home-rule mode, -1 where there is none."""
        index = np.argmax(self.home, axis=-1)
        result: npt.NDArray[np.int64] = np.where(np.any(self.home, axis=-1), index, -1)
        return result

    @property
    def ambiguous(self) -> BoolArray:
        """(...,) more than one mode satisfies the home sign rule."""
        result: BoolArray = np.sum(self.home, axis=-1) > 1
        return result


# --------------------------------------------------------------------------- set-up
@dataclasses.dataclass
class _Legs:
    """Per-item data of the two-equation system, flattened batch of n items."""

    w: FloatArray  # (n, 3, 3)
    V1: FloatArray  # (n, 3, 3): v_1 = V1 @ m(phi_1)
    V2: FloatArray  # (n, 3, 3)
    M: FloatArray  # (n, 2, 3, 3): m1^T M_k m2 = 0


def _cone_frames(w: FloatArray, design: SPMDesign) -> FloatArray:
    """Columns [cos a2 w, sin a2 p, sin a2 q] of each leg, shape (n, 3, 3, 3).

    p = (u x w) / |u x w| with |u x w| = sin a1 (w stays at a1 from u), q = w x p.
    """
    p = cross(design.u, w) / math.sin(design.alpha1)
    q = cross(w, p)
    c2, s2 = math.cos(design.alpha2), math.sin(design.alpha2)
    return np.stack([c2 * w, s2 * p, s2 * q], axis=-1)


def _setup(theta: FloatArray, design: SPMDesign) -> _Legs:
    w = proximal_axes(theta, design)
    frames = _cone_frames(w, design)
    V1, V2 = frames[:, 0], frames[:, 1]
    a, b, d = design.platform_combination
    v0 = design.v0
    c12 = float(v0[0] @ v0[1])
    M1 = np.swapaxes(V1, -1, -2) @ V2
    M1[:, 0, 0] -= c12
    w3 = w[:, 2]
    t1 = np.einsum("nk,nkj->nj", w3, V1)  # w3 . V1 columns
    t2 = np.einsum("nk,nkj->nj", w3, V2)
    cross_cols = cross(np.swapaxes(V2, -1, -2), w3[:, None, :])  # (n, 3 cols, 3)
    M2 = d * (np.swapaxes(V1, -1, -2) @ np.swapaxes(cross_cols, -1, -2))
    M2[:, :, 0] += a * t1
    M2[:, 0, :] += b * t2
    M2[:, 0, 0] -= math.cos(design.alpha2)
    return _Legs(w=w, V1=V1, V2=V2, M=np.stack([M1, M2], axis=1))


def _m(phi: FloatArray) -> FloatArray:
    return np.stack([np.ones_like(phi), np.cos(phi), np.sin(phi)], axis=-1)


def _dm(phi: FloatArray) -> FloatArray:
    return np.stack([np.zeros_like(phi), -np.sin(phi), np.cos(phi)], axis=-1)


def _newton(
    M: FloatArray, phi1: FloatArray, phi2: FloatArray, steps: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Newton on f_k = m(phi1)^T M_k m(phi2) = 0, k = 1, 2.

    M has shape (n, 2, 3, 3) and phi1, phi2 shape (n,). Returns phi1, phi2 and max |f|
    after the last step. Written out component by component: on 3-vectors this is
    several times faster than generic contractions.
    """
    # Components as contiguous (n,) arrays: m[k][i][j].
    m = [
        [[np.ascontiguousarray(M[:, k, i, j]) for j in range(3)] for i in range(3)] for k in (0, 1)
    ]

    def evaluate(
        phi1: FloatArray, phi2: FloatArray, jacobian: bool
    ) -> tuple[list[FloatArray], list[FloatArray], list[FloatArray]]:
        c1, s1, c2, s2 = np.cos(phi1), np.sin(phi1), np.cos(phi2), np.sin(phi2)
        f, j1, j2 = [], [], []
        for mk in m:
            r = [mk[i][0] + mk[i][1] * c2 + mk[i][2] * s2 for i in range(3)]
            f.append(r[0] + c1 * r[1] + s1 * r[2])
            if jacobian:
                t = [mk[i][2] * c2 - mk[i][1] * s2 for i in range(3)]
                j1.append(c1 * r[2] - s1 * r[1])
                j2.append(t[0] + c1 * t[1] + s1 * t[2])
        return f, j1, j2

    for _ in range(steps):
        f, j1, j2 = evaluate(phi1, phi2, True)
        det = j1[0] * j2[1] - j1[1] * j2[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            step1 = (j2[1] * f[0] - j2[0] * f[1]) / det
            step2 = (j1[0] * f[1] - j1[1] * f[0]) / det
        ok = np.isfinite(step1) & np.isfinite(step2)
        # Damp huge steps: a Newton step beyond one radian is not trusted.
        size = np.maximum(np.abs(step1), np.abs(step2))
        scale = 1.0 / np.maximum(np.where(ok, size, 1.0), 1.0)
        phi1 = np.where(ok, phi1 - scale * step1, phi1)
        phi2 = np.where(ok, phi2 - scale * step2, phi2)
    f, _, _ = evaluate(phi1, phi2, False)
    return phi1, phi2, np.maximum(np.abs(f[0]), np.abs(f[1]))


def _platform(
    legs_V1: FloatArray, legs_V2: FloatArray, phi1: FloatArray, phi2: FloatArray, design: SPMDesign
) -> FloatArray:
    """R from phi_1, phi_2; V (..., 3, 3), phi (...). Returns (..., 3, 3)."""
    v1 = np.einsum("...ij,...j->...i", legs_V1, _m(phi1))
    v2 = np.einsum("...ij,...j->...i", legs_V2, _m(phi2))
    world = np.stack([v1, v2, cross(v1, v2)], axis=-1)
    v0 = design.v0
    body = np.stack([v0[0], v0[1], cross(v0[0], v0[1])], axis=-1)
    R: FloatArray = world @ np.linalg.inv(body)
    return R


def _platform_axes(R: FloatArray, design: SPMDesign) -> FloatArray:
    """Rows v_i = R v_i0, shape (..., 3, 3)."""
    return np.swapaxes(R @ design.v0.T, -1, -2)


def _closure(R: FloatArray, w: FloatArray, design: SPMDesign) -> tuple[FloatArray, FloatArray]:
    """v rows (..., 3, 3) and the residual (...)."""
    v = _platform_axes(R, design)
    loop = np.abs(np.sum(w * v, axis=-1) - math.cos(design.alpha2)).max(axis=-1)
    ortho = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(-2, -1))
    return v, np.maximum(loop, ortho)


def _signs(
    R: FloatArray, w: FloatArray, design: SPMDesign
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """v, b (..., 3) and det A (...) of solutions R (..., 3, 3) with axes w (..., 3, 3)."""
    v = _platform_axes(R, design)
    b = np.sum(cross(design.u, w) * v, axis=-1)
    A = cross(w, v)
    det_a = np.sum(A[..., 0, :] * cross(A[..., 1, :], A[..., 2, :]), axis=-1)
    return v, b, det_a


def satisfies_home_rule(b: FloatArray, det_a: FloatArray, design: SPMDesign) -> BoolArray:
    """The home sign rule on b (..., 3) and det A (...): every b_ii > 0 (strictly, not on
    a type I singularity) and det A non-zero with the sign it has at home."""
    result: BoolArray = (
        np.all(b > _SIGN_TOL, axis=-1)
        & (np.sign(det_a) == np.sign(design.home_det_a))
        & (np.abs(det_a) > _SIGN_TOL)
    )
    return result


# ------------------------------------------------------------------------ all modes
def _polymul(p: FloatArray, q: FloatArray) -> FloatArray:
    """Product of ascending coefficient arrays (n, a) x (n, b) -> (n, a + b - 1)."""
    out = np.zeros((p.shape[0], p.shape[1] + q.shape[1] - 1))
    for i in range(p.shape[1]):
        out[:, i : i + q.shape[1]] += p[:, i : i + 1] * q
    return out


_G = np.array([[1.0, 0.0, 1.0], [1.0, 0.0, -1.0], [0.0, 2.0, 0.0]])


def _resultant_roots(M: FloatArray, sigma: float) -> tuple[FloatArray, BoolArray, BoolArray]:
    """Real roots phi_1 of the degree-8 resultant: phi1 (n, 8), real mask, degenerate (n,).

    ``degenerate`` marks items whose leading coefficient vanishes (a root at
    phi_1 = sigma + pi, x_1 = infinity): solve those again with another sigma.
    """
    c, s = math.cos(sigma), math.sin(sigma)
    rot = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])  # m(sigma + psi) = rot m(psi)
    T = rot @ _G
    N = T.T @ M @ T  # (n, 2, 3, 3): coefficient of x1^i x2^j
    A1, B1, C1 = N[:, 0, :, 2], N[:, 0, :, 1], N[:, 0, :, 0]
    A2, B2, C2 = N[:, 1, :, 2], N[:, 1, :, 1], N[:, 1, :, 0]
    ac = _polymul(A1, C2) - _polymul(C1, A2)
    ab = _polymul(A1, B2) - _polymul(B1, A2)
    bc = _polymul(B1, C2) - _polymul(C1, B2)
    poly = _polymul(ac, ac) - _polymul(ab, bc)  # (n, 9), ascending
    scale = np.max(np.abs(poly), axis=1, keepdims=True)
    scale = np.where(scale > 0, scale, 1.0)
    poly = poly / scale
    lead = poly[:, 8]
    degenerate = np.abs(lead) < 1e-9
    safe_lead = np.where(degenerate, 1.0, lead)
    companion = np.zeros((poly.shape[0], 8, 8))
    companion[:, 0, :] = -poly[:, 7::-1] / safe_lead[:, None]
    companion[:, np.arange(1, 8), np.arange(7)] = 1.0
    roots = np.linalg.eigvals(companion)
    real = np.abs(roots.imag) <= _IMAG_TOL * (1.0 + np.abs(roots.real))
    real &= ~degenerate[:, None]
    phi1 = sigma + 2.0 * np.arctan(roots.real)
    return phi1, real, degenerate


def _phi2_candidates(legs: _Legs, phi1: FloatArray, design: SPMDesign) -> FloatArray:
    """phi_2 on the cone of leg 2 with v_1 . v_2 = c12 (two per phi_1): (n, k, 2)."""
    v1 = np.einsum("nij,nkj->nki", legs.V1, _m(phi1))
    coeff = np.einsum("nki,nij->nkj", v1, legs.V2)  # v1 . [c w2, s p2, s q2]
    c12 = float(design.v0[0] @ design.v0[1])
    amplitude = np.hypot(coeff[..., 1], coeff[..., 2])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = (c12 - coeff[..., 0]) / amplitude
    ratio = np.clip(np.nan_to_num(ratio), -1.0, 1.0)  # near-tangent cones: Newton decides
    base = np.arctan2(coeff[..., 2], coeff[..., 1])
    half = np.arccos(ratio)
    return np.stack([base + half, base - half], axis=-1)


def _equations(M: FloatArray, phi1: FloatArray, phi2: FloatArray) -> FloatArray:
    """|f| of both equations, M (..., 2, 3, 3), phi (...) -> (..., 2)."""
    Mm2 = np.einsum("...kij,...j->...ki", M, _m(phi2))
    result: FloatArray = np.abs(np.einsum("...i,...ki->...k", _m(phi1), Mm2))
    return result


def _candidates(
    legs: _Legs, design: SPMDesign, home_only: bool
) -> tuple[npt.NDArray[np.intp], FloatArray, FloatArray]:
    """Starting points (item, phi_1, phi_2) for the polish, from the resultant roots."""
    phi1, real, degenerate = _resultant_roots(legs.M, _SIGMAS[0])
    if np.any(degenerate):
        idx = np.nonzero(degenerate)[0]
        sub = _Legs(w=legs.w[idx], V1=legs.V1[idx], V2=legs.V2[idx], M=legs.M[idx])
        phi1_b, real_b, _ = _resultant_roots(sub.M, _SIGMAS[1])
        phi1[idx], real[idx] = phi1_b, real_b
    if home_only:  # the home mode has cos(phi_1) > 0; keep a margin for the polish
        real &= np.cos(phi1) > -0.05
    phi2 = _phi2_candidates(legs, phi1, design)  # (n, 8, 2)
    both = np.repeat(phi1[:, :, None], 2, axis=2)
    residual = np.max(_equations(legs.M[:, None, None], both, phi2), axis=-1)
    # Keep the better phi_2 of each root, and the other one too when it also nearly
    # closes (two modes sharing phi_1 at symmetric inputs).
    best = np.min(residual, axis=-1, keepdims=True)
    mask = real[:, :, None] & (residual <= np.maximum(1e3 * best, 1e-6))
    if home_only:
        mask &= np.cos(phi2) > -0.05
    item, root, which = np.nonzero(mask)
    return item, both[item, root, which], phi2[item, root, which]


@dataclasses.dataclass
class _Modes:
    """Solutions of a flat batch, padded to 8 slots per item."""

    R: FloatArray  # (n, 8, 3, 3)
    b: FloatArray  # (n, 8, 3)
    det_a: FloatArray  # (n, 8)
    residual: FloatArray  # (n, 8)
    home: BoolArray  # (n, 8)
    valid: BoolArray  # (n, 8)


def _solve_all_flat(theta: FloatArray, design: SPMDesign, *, home_only: bool = False) -> _Modes:
    """All assembly modes (or the home-rule ones only) for a flat batch theta (n, 3)."""
    n = theta.shape[0]
    legs = _setup(theta, design)
    item, phi1, phi2 = _candidates(legs, design, home_only)
    p1, p2, res = _newton(legs.M[item], phi1, phi2, _NEWTON_STEPS_POLISH)
    # Near a double root (a type II singularity) Newton converges only linearly:
    # give the candidates that are close but not done more steps.
    slow = np.nonzero((res > RESIDUAL_TOL) & (res < 1e-2))[0]
    if slow.size:
        p1[slow], p2[slow], res[slow] = _newton(
            legs.M[item[slow]], p1[slow], p2[slow], _NEWTON_STEPS_SLOW
        )
    ok = res <= RESIDUAL_TOL
    item, p1, p2 = item[ok], p1[ok], p2[ok]
    # Merge duplicates: sort candidates per item and drop near-equal neighbours.
    p1w = np.mod(p1, 2 * np.pi)
    p2w = np.mod(p2, 2 * np.pi)
    order = np.lexsort((p2w, p1w, item))
    item, p1, p2, p1w, p2w = item[order], p1[order], p2[order], p1w[order], p2w[order]
    keep = np.ones(item.shape[0], dtype=bool)
    counts = np.bincount(item, minlength=n) if item.size else np.zeros(n, dtype=int)
    width = int(counts.max()) if n else 0
    for lag in range(1, width):
        dup = np.zeros(item.shape[0], dtype=bool)
        dup[lag:] = (
            (item[lag:] == item[:-lag])
            & (_angle_diff(p1w[lag:], p1w[:-lag]) < _DUPLICATE_TOL)
            & (_angle_diff(p2w[lag:], p2w[:-lag]) < _DUPLICATE_TOL)
            & keep[:-lag]
        )
        keep &= ~dup
    item, p1, p2, p1w, p2w = item[keep], p1[keep], p2[keep], p1w[keep], p2w[keep]
    R = _platform(legs.V1[item], legs.V2[item], p1, p2, design)
    w_item = legs.w[item]
    _, b, det_a = _signs(R, w_item, design)
    _, residual = _closure(R, w_item, design)
    home = satisfies_home_rule(b, det_a, design)
    if home_only:
        item, R, b, det_a, residual = item[home], R[home], b[home], det_a[home], residual[home]
        p1w, p2w = p1w[home], p2w[home]
        home = home[home]
    # Order per item: home-rule modes first, then by the sign code of the label, then
    # (modes sharing their signs) by the tilt of the platform from its home normal,
    # then by (phi_1, phi_2): a strict order of distinct solutions.
    code = np.sum(~(b > 0) * np.array([1, 2, 4]), axis=-1) + 8 * (det_a > 0)  # as the labels
    normal_z = R[:, 2, 2]  # cos(tilt): the common turn of coaxial inputs was removed
    order = np.lexsort((p2w, p1w, -normal_z, code, ~home, item))
    item = item[order]
    slot_of = np.arange(item.shape[0]) - np.searchsorted(item, item)
    fits = slot_of < MAX_ASSEMBLY_MODES
    sel = order[fits]
    item, slot_of = item[fits], slot_of[fits]
    out_R = np.full((n, MAX_ASSEMBLY_MODES, 3, 3), np.nan)
    out_b = np.full((n, MAX_ASSEMBLY_MODES, 3), np.nan)
    out_det = np.full((n, MAX_ASSEMBLY_MODES), np.nan)
    out_res = np.full((n, MAX_ASSEMBLY_MODES), np.nan)
    out_home = np.zeros((n, MAX_ASSEMBLY_MODES), dtype=bool)
    out_valid = np.zeros((n, MAX_ASSEMBLY_MODES), dtype=bool)
    out_R[item, slot_of] = R[sel]
    out_b[item, slot_of] = b[sel]
    out_det[item, slot_of] = det_a[sel]
    out_res[item, slot_of] = residual[sel]
    out_home[item, slot_of] = home[sel]
    out_valid[item, slot_of] = True
    return _Modes(R=out_R, b=out_b, det_a=out_det, residual=out_res, home=out_home, valid=out_valid)


def _angle_diff(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.pi - np.abs(np.mod(a - b, 2 * np.pi) - np.pi)


def sign_label(b: npt.ArrayLike, det_a: float) -> str:
    """The sign part of an assembly-mode label: signs of b_11, b_22, b_33, then of
    det A, e.g. ``"+++/-"`` (a value > 0 is ``+``)."""
    signs = np.asarray(b, dtype=float).ravel()
    return "".join("+" if x > 0 else "-" for x in signs) + ("/+" if det_a > 0 else "/-")


#: Sign labels by sign code (bit i set: b_(i+1)(i+1) <= 0; bit 3 set: det A > 0).
_SIGN_LABELS = np.array(
    [
        "".join("-" if (code >> i) & 1 else "+" for i in range(3)) + ("/+" if code & 8 else "/-")
        for code in range(16)
    ],
    dtype=object,
)


def label_array(b: FloatArray, det_a: FloatArray, valid: BoolArray) -> npt.NDArray[np.object_]:
    """Unique labels of the slots, an object array of the shape of ``valid``: the sign
    label, and for the k-th (k >= 2) mode of an input whose signs repeat an earlier
    slot's, the suffix ``#k``; ``""`` for unused slots."""
    code = np.sum((~(b > 0)) * np.array([1, 2, 4]), axis=-1) + 8 * (det_a > 0)
    code = np.where(valid, code, -1)
    earlier = np.tril(np.ones((MAX_ASSEMBLY_MODES, MAX_ASSEMBLY_MODES), dtype=bool), -1)
    same = (code[..., :, None] == code[..., None, :]) & valid[..., None, :] & earlier
    ordinal = np.sum(same, axis=-1) + 1
    labels = np.where(valid, _SIGN_LABELS[np.clip(code, 0, 15)], "").astype(object)
    for index in zip(*np.nonzero(valid & (ordinal > 1)), strict=True):
        labels[index] = f"{labels[index]}#{ordinal[index]}"
    result: npt.NDArray[np.object_] = labels
    return result


def _labels(b: FloatArray, det_a: FloatArray, valid: BoolArray) -> list[object]:
    result: list[object] = label_array(b, det_a, valid).tolist()
    return result


def _torsion_split(theta: FloatArray, design: SPMDesign) -> tuple[FloatArray, FloatArray | None]:
    """For coaxial designs split theta = theta' + c (1, 1, 1) (+ whole turns per leg).

    Each theta_i is first replaced by the representative theta_1 + wrap(theta_i -
    theta_1) (the same mechanism: only whole turns differ), then the mean c is
    removed; the platform at theta is the one at theta' turned by c about the axis.
    """
    if not design.is_coaxial:
        return theta, None
    first = theta[..., :1]
    rep = first + np.concatenate([np.zeros_like(first), _wrap(theta[..., 1:] - first)], axis=-1)
    common = np.mean(rep, axis=-1)
    return rep - common[..., None], common


def _wrap(angle: FloatArray) -> FloatArray:
    return np.pi - np.mod(np.pi - angle, 2 * np.pi)


def forward_kinematics_all(theta: npt.ArrayLike, design: SPMDesign | None = None) -> FKAllResult:
    """Every real assembly mode of the platform at input angles ``theta``.

    Args:
        theta: Input angles [rad], shape (3,) or (..., 3).
        design: The SPM (default: the prototype).

    Returns:
        FKAllResult; modes fill slots 0..count-1 (home-rule modes first).
    """
    design = check_design(design)
    theta_in = as_theta(theta)
    shape = theta_in.shape[:-1]
    reduced, common = _torsion_split(theta_in, design)
    out = _solve_all_flat(reduced.reshape(-1, 3), design)
    R = out.R
    if common is not None:
        turn = rotation_about(design.u[0], common.reshape(-1))
        R = turned(turn[:, None], R)
    w = proximal_axes(theta_in, design)
    v = np.einsum("...jk,ik->...ij", R, design.v0)
    valid = out.valid.reshape(*shape, MAX_ASSEMBLY_MODES)
    b = out.b.reshape(*shape, MAX_ASSEMBLY_MODES, 3)
    det_a = out.det_a.reshape(*shape, MAX_ASSEMBLY_MODES)
    return FKAllResult(
        theta=theta_in,
        R=R.reshape(*shape, MAX_ASSEMBLY_MODES, 3, 3),
        v=v.reshape(*shape, MAX_ASSEMBLY_MODES, 3, 3),
        w=w,
        valid=valid,
        count=np.sum(valid, axis=-1),
        b=b,
        det_a=det_a,
        home=out.home.reshape(*shape, MAX_ASSEMBLY_MODES),
        residual=out.residual.reshape(*shape, MAX_ASSEMBLY_MODES),
    )


# ------------------------------------------------------------------------ home mode
def forward_kinematics(
    theta: npt.ArrayLike,
    design: SPMDesign | None = None,
    *,
    reference: npt.ArrayLike | None = None,
) -> FKResult:
    """The platform orientation in the home assembly mode at input angles ``theta``.

    Args:
        theta: Input angles [rad], shape (3,) or (..., 3); any number of turns.
        design: The SPM (default: the prototype).
        reference: Optional platform rotation(s) (..., 3, 3) near the wanted solution
            (e.g. the previous sample of a motion): Newton starts there, and where the
            sign rule admits several modes the one nearest to it is returned.

    Returns:
        FKResult. Where no home-mode assembly exists, ``reachable`` is False and
        ``R``, ``v`` and ``residual`` are NaN.
    """
    design = check_design(design)
    theta_in = as_theta(theta)
    shape = theta_in.shape[:-1]
    flat = theta_in.reshape(-1, 3)
    ref_flat: FloatArray | None = None
    if reference is not None:
        ref = as_rotation(reference, "reference")
        try:
            ref_flat = np.broadcast_to(ref, (*shape, 3, 3)).reshape(-1, 3, 3)
        except ValueError as exc:
            raise InputError(
                f"reference must broadcast to shape {(*shape, 3, 3)}, got {ref.shape}",
                argument="reference",
                value=reference,
            ) from exc
    reduced, common = _torsion_split(flat, design)
    turn = None if common is None else rotation_about(design.u[0], common)
    local_ref = None
    if ref_flat is not None:
        local_ref = ref_flat if turn is None else np.swapaxes(turn, -1, -2) @ ref_flat
    todo = _maybe_reachable(reduced, design)
    if todo is None:
        R, done = _home_solve(reduced, design, local_ref)
    else:  # inputs in certified-unreachable gap cells skip the solve
        R = np.full((reduced.shape[0], 3, 3), np.nan)
        done = np.zeros(reduced.shape[0], dtype=bool)
        if todo.size:
            sub_ref = None if local_ref is None else local_ref[todo]
            R[todo], done[todo] = _home_solve(reduced[todo], design, sub_ref)
    if turn is not None:
        R = turned(turn, R)
    w = proximal_axes(flat, design)
    v, residual = _closure(R, w, design)
    return FKResult(
        theta=theta_in,
        R=R.reshape(*shape, 3, 3),
        v=v.reshape(*shape, 3, 3),
        w=w.reshape(*shape, 3, 3),
        reachable=done.reshape(shape),
        residual=residual.reshape(shape),
    )


def turned(turn: FloatArray, R: FloatArray) -> FloatArray:
    """``turn @ R`` for stacks of 3 x 3 matrices, element by element: (i, j) is
    ``(t_i0 r_0j + t_i1 r_1j) + t_i2 r_2j``, without fused multiply-adds, so that the
    single-input float code (:func:`~._fk_single.turned_rows`) gives the same bits
    (a BLAS product rounds in an order of its own)."""
    result: FloatArray = (
        turn[..., :, 0, None] * R[..., None, 0, :] + turn[..., :, 1, None] * R[..., None, 1, :]
    ) + turn[..., :, 2, None] * R[..., None, 2, :]
    return result


@functools.lru_cache(maxsize=32)
def _home_slope(design: SPMDesign) -> FloatArray:
    """d(phi_1, phi_2)/d(theta) of the home mode at theta = 0, shape (2, 3).

    Central differences of the home solution; theta @ slope.T is a first-order
    guess of the home mode that Newton then finishes in a few steps.
    """
    h = 1e-6
    probes = np.concatenate([np.eye(3) * h, -np.eye(3) * h])
    legs = _setup(probes, design)
    zeros = np.zeros(6)
    phi1, phi2, _ = _newton(legs.M, zeros, zeros, _NEWTON_STEPS_FAST + 3)
    slope = np.stack([phi1[:3] - phi1[3:], phi2[:3] - phi2[3:]]) / (2 * h)
    slope.setflags(write=False)
    return slope


@functools.lru_cache(maxsize=32)
def _single_constants(design: SPMDesign) -> SingleConstants:
    """The float fast path's constants of a design (cached: designs are frozen)."""
    return make_constants(design, _home_slope(design).tolist())


def _home_newton(
    theta: FloatArray, design: SPMDesign, reference: FloatArray | None
) -> tuple[FloatArray, BoolArray]:
    """Newton towards the home mode; returns R (n, 3, 3) and which items it certifies.

    Newton starts from a first-order guess of the home mode (or from ``reference``).
    Items it does not certify are tried again by continuation from home: first at
    theta / 2, then at theta. An item is certified when it converged and satisfies
    the home sign rule.
    """
    legs = _setup(theta, design)
    if reference is None:
        slope = _home_slope(design)
        phi1, phi2 = theta @ slope[0], theta @ slope[1]
    else:
        v_ref = np.einsum("njk,ik->nij", reference, design.v0)
        phi1 = _cone_angle(legs.V1, v_ref[:, 0])
        phi2 = _cone_angle(legs.V2, v_ref[:, 1])
    phi1, phi2, _ = _newton(legs.M, phi1, phi2, _NEWTON_STEPS_FAST)
    R, done = _certify(legs, phi1, phi2, design)
    if reference is None and not np.all(done):
        rest = np.nonzero(~done)[0]
        half_theta = 0.5 * theta[rest]
        half = _setup(half_theta, design)
        p1, p2, _ = _newton(half.M, half_theta @ slope[0], half_theta @ slope[1], 3)
        sub = _Legs(w=legs.w[rest], V1=legs.V1[rest], V2=legs.V2[rest], M=legs.M[rest])
        p1, p2, _ = _newton(sub.M, p1, p2, _NEWTON_STEPS_FAST + 1)
        R[rest], done[rest] = _certify(sub, p1, p2, design)
    return R, done


def _certify(
    legs: _Legs, phi1: FloatArray, phi2: FloatArray, design: SPMDesign
) -> tuple[FloatArray, BoolArray]:
    """R of Newton's solutions after polishing, and which of them converged
    (residual <= RESIDUAL_TOL) into the home mode.

    One more Newton step for all, then up to ``_POLISH_EXTRA`` more for items still
    above rounding level, so accepted solutions end at machine precision.
    """
    phi1, phi2, res = _newton(legs.M, phi1, phi2, 1)
    for _ in range(_POLISH_EXTRA):
        again = np.nonzero(res > _POLISHED)[0]
        if again.size == 0:
            break
        phi1[again], phi2[again], res[again] = _newton(legs.M[again], phi1[again], phi2[again], 1)
    R = _platform(legs.V1, legs.V2, phi1, phi2, design)
    _, b, det_a = _signs(R, legs.w, design)
    return R, (res <= RESIDUAL_TOL) & satisfies_home_rule(b, det_a, design)


def _home_solve(
    reduced: FloatArray, design: SPMDesign, local_ref: FloatArray | None
) -> tuple[FloatArray, BoolArray]:
    """Home mode of reduced inputs (n, 3): R (n, 3, 3) (NaN where none) and which exist.

    One input: the float fast path; otherwise Newton (:func:`_home_newton`); items not
    certified there go through the home-only resultant solve.
    """
    single = None
    if local_ref is None and reduced.shape[0] == 1:  # one input: the float fast path
        single = home_rotation(
            reduced[0].tolist(),
            _single_constants(design),
            _NEWTON_STEPS_FAST,
            _POLISH_EXTRA,
            _POLISHED,
            RESIDUAL_TOL,
            _SIGN_TOL,
        )
    if single is not None:
        R, done = np.array(single)[None], np.ones(1, dtype=bool)
    else:
        R, done = _home_newton(reduced, design, local_ref)
    if not np.all(done):
        rest = np.nonzero(~done)[0]
        out = _solve_all_flat(reduced[rest], design, home_only=True)
        home = out.home
        if local_ref is None:
            pick = np.argmax(home, axis=1)
        else:
            dist = np.linalg.norm(out.R - local_ref[rest][:, None], axis=(-2, -1))
            pick = np.argmin(np.where(home, dist, np.inf), axis=1)
        found = np.any(home, axis=1)
        chosen = out.R[np.arange(rest.shape[0]), pick]
        R[rest] = np.where(found[:, None, None], chosen, np.nan)
        done[rest] = found
    return R, done


def _maybe_reachable(reduced: FloatArray, design: SPMDesign) -> npt.NDArray[np.intp] | None:
    """Indices of the reduced inputs not in a certified-unreachable gap cell, or None
    when the table does not apply (non-coaxial design, or a small batch before the
    table of this design is built); see :mod:`._reach`."""
    if not design.is_coaxial:
        return None
    table = _reach.cached_table(design)
    if table is None:
        if reduced.shape[0] < _TABLE_MIN_BATCH:
            return None
        table = _reach.unreachable_table(design, lambda theta: _home_solve(theta, design, None)[1])
    row, col = _reach.gap_index(reduced)
    result: npt.NDArray[np.intp] = np.nonzero(~table[row, col])[0]
    return result


def _cone_angle(V: FloatArray, v: FloatArray) -> FloatArray:
    """phi with V m(phi) closest to v."""
    coeff = np.einsum("ni,nij->nj", v, V)
    result: FloatArray = np.arctan2(coeff[:, 2], coeff[:, 1])
    return result
