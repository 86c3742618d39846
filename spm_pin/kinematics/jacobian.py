r"""Velocity kinematics, singularities and dexterity.

Differentiating the loop closures w_i . v_i = cos a2 with dw_i/dtheta_i = u_i x w_i
and dv_i/dt = omega x v_i gives

    A omega = B theta_dot,   A rows a_i = w_i x v_i,   B = diag(b_ii),
    b_ii = (u_i x w_i) . v_i,

so J = A^-1 B maps input rates to the platform angular velocity (world frame).

* Type I (serial) singularity: some b_ii = 0 (u_i, w_i, v_i coplanar): J loses rank.
* Type II (parallel) singularity: det A = 0: J does not exist.
* Dexterity: 1/kappa(J) with the 2-norm (sigma_min / sigma_max) and with the
  Gosselin-Angeles norm ||J|| = sqrt(tr(J^T J) / 3), both in [0, 1].
* ``singularity_margin`` in [0, 1]: min over legs of |b_ii| / |u_i x w_i| (the sine
  of the angle of v_i out of the plane of u_i and w_i) and the smallest singular
  value of A with unit rows (how far the a_i are from coplanar). 0 on either kind of
  singularity; use it as a safety margin before sending a command.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..errors import InputError, SingularityError, UnreachableError
from ._common import BoolArray, FloatArray, as_rotation, as_theta, check_design, proximal_axes
from .fk import forward_kinematics

__all__ = ["JacobianResult", "jacobian"]

#: Default threshold on the normalised measures below which a configuration is singular.
#: At an exact type I pose, b_ii comes from the square root of a discriminant that is
#: zero up to rounding, so it reads about sqrt(eps) ~ 1e-8: the threshold sits above.
SINGULAR_TOL = 1e-7


@dataclasses.dataclass(frozen=True)
class JacobianResult:
    """Velocity kinematics at one or many configurations.

    Attributes:
        J: (..., 3, 3) omega = J theta_dot [rad/s per rad/s]; NaN where type II singular
            or unreachable (see the flags).
        A: (..., 3, 3) rows a_i = w_i x v_i.
        B: (..., 3, 3) diag(b_ii).
        b: (..., 3) b_ii.
        det_a: (...,) det A.
        R: (..., 3, 3) the platform rotation used.
        type_i: (...,) serial singularity (some normalised |b_ii| <= tol).
        type_ii: (...,) parallel singularity (normalised sigma_min(A) <= tol).
        dexterity: (...,) 1 / kappa_2(J) = sigma_min / sigma_max (0 when singular).
        dexterity_ga: (...,) 1 / kappa_F(J) with the Gosselin-Angeles norm.
        singularity_margin: (...,) distance to the nearest singularity in [0, 1].
        reachable: (...,) the configuration exists (home mode found, for theta input).
    """

    J: FloatArray
    A: FloatArray
    B: FloatArray
    b: FloatArray
    det_a: FloatArray
    R: FloatArray
    type_i: BoolArray
    type_ii: BoolArray
    dexterity: FloatArray
    dexterity_ga: FloatArray
    singularity_margin: FloatArray
    reachable: BoolArray

    @property
    def singular(self) -> BoolArray:
        """(...,) type I or type II."""
        result: BoolArray = self.type_i | self.type_ii
        return result


def jacobian(
    theta: npt.ArrayLike,
    design: SPMDesign | str | None = None,
    *,
    R: npt.ArrayLike | None = None,
    tol: float = SINGULAR_TOL,
) -> JacobianResult:
    """Jacobian omega = J theta_dot with singularity and dexterity measures.

    Args:
        theta: Input angles [rad], (3,) or (..., 3).
        design: The SPM (default: the prototype).
        R: Platform rotation(s) (..., 3, 3) of the assembly mode to use; default: the
            home mode from :func:`forward_kinematics`.
        tol: Threshold on the normalised singularity measures.

    Raises:
        UnreachableError: a single input (shape (3,)) without a home-mode assembly.
        SingularityError: a single input at a type II singularity (J does not exist).
        InputError: bad shapes or values.
    """
    design = check_design(design)
    theta_in = as_theta(theta)
    shape = theta_in.shape[:-1]
    if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not 0.0 <= tol < 1.0:
        raise InputError(f"tol must be a number in [0, 1), got {tol!r}", argument="tol", value=tol)
    if R is None:
        fk = forward_kinematics(theta_in, design)
        rotation, reachable = fk.R, fk.reachable
    else:
        given = as_rotation(R)
        try:
            rotation = np.broadcast_to(given, (*shape, 3, 3))
        except ValueError as exc:
            raise InputError(
                f"R of shape {given.shape} does not match theta of shape {theta_in.shape}; "
                f"R must broadcast to {(*shape, 3, 3)}",
                argument="R",
                value=R,
            ) from exc
        reachable = np.ones(shape, dtype=bool)
    if theta_in.ndim == 1 and not bool(reachable):
        raise UnreachableError(
            f"no home-mode assembly at theta = {np.degrees(theta_in).round(6).tolist()} deg",
            value=theta_in,
        )
    w = proximal_axes(theta_in, design)
    v = np.einsum("...jk,ik->...ij", rotation, design.v0)
    uxw = np.cross(design.u, w)
    b = np.sum(uxw * v, axis=-1)
    A = np.cross(w, v)
    det_a = np.linalg.det(np.where(np.isfinite(A), A, 0.0))
    det_a = np.where(reachable, det_a, np.nan)
    B = b[..., :, None] * np.eye(3)
    leg_margin = np.abs(b) / np.linalg.norm(uxw, axis=-1)
    rows = np.linalg.norm(A, axis=-1, keepdims=True)
    A_unit = np.where(np.isfinite(A), A / np.where(rows > 0, rows, 1.0), 0.0)
    sigma_a = np.linalg.svd(A_unit, compute_uv=False)
    a_margin = sigma_a[..., -1]
    type_i = np.min(leg_margin, axis=-1) <= tol
    type_ii = a_margin <= tol
    margin = np.minimum(np.min(leg_margin, axis=-1), a_margin)
    ok = reachable & ~type_ii
    A_safe = np.where(ok[..., None, None], A, np.eye(3))
    J = np.linalg.solve(A_safe, np.where(ok[..., None, None], B, 0.0))
    J = np.where(ok[..., None, None], J, np.nan)
    sigma = np.linalg.svd(np.where(ok[..., None, None], J, 0.0), compute_uv=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        dex = np.where(sigma[..., 0] > 0, sigma[..., -1] / sigma[..., 0], 0.0)
        inv_sq = np.where(sigma > 0, 1.0 / sigma**2, np.inf)
        ga = 3.0 / np.sqrt(np.sum(sigma**2, axis=-1) * np.sum(inv_sq, axis=-1))
    ga = np.where(np.isfinite(ga), ga, 0.0)
    dex = np.where(type_i, 0.0, dex)
    ga = np.where(type_i, 0.0, ga)
    nan_if_unreachable = np.where(reachable, 1.0, np.nan)
    if theta_in.ndim == 1 and bool(type_ii):
        raise SingularityError(
            f"type II (parallel) singularity at theta = "
            f"{np.degrees(theta_in).round(6).tolist()} deg: det A = {float(det_a):.3g}, "
            "the Jacobian does not exist",
            kind="type II",
            value=theta_in,
        )
    return JacobianResult(
        J=J,
        A=A,
        B=B,
        b=b,
        det_a=det_a,
        R=np.asarray(rotation),
        type_i=type_i & reachable,
        type_ii=type_ii & reachable,
        dexterity=dex * nan_if_unreachable,
        dexterity_ga=ga * nan_if_unreachable,
        singularity_margin=margin * nan_if_unreachable,
        reachable=np.asarray(reachable),
    )
