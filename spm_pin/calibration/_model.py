"""The measurement model: predicted measurements, residuals and their analytic
Jacobian with respect to the parameters (:class:`Model`), and the home axes'
derivatives with respect to the link angles (:func:`geometry`)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..design import SPMDesign
from ..errors import DesignError
from ..kinematics import forward_kinematics
from ..kinematics._common import cross, rotate_about
from ..rotations import exp_so3, left_jacobian_so3, quaternion_from_matrix, right_jacobian_so3, skew
from ._constants import COMPONENTS, PARAMETER_NAMES, UNREACHABLE_RESIDUAL, BoolArray, FloatArray
from .parameters import CalibrationParameters


def tangent_basis(vectors: FloatArray) -> FloatArray:
    """Two unit vectors perpendicular to each unit vector (..., 3): shape (..., 2, 3)."""
    helper = np.where(
        (np.abs(vectors[..., 0]) < 0.9)[..., None], np.array([1.0, 0.0, 0.0]), [0.0, 1.0, 0.0]
    )
    e1 = cross(helper, vectors)
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    e2 = cross(vectors, e1)
    return np.stack([e1, e2], axis=-2)


@dataclasses.dataclass(frozen=True)
class Geometry:
    """Home axes and their derivatives with respect to (alpha1, alpha2, beta)."""

    w0: FloatArray  # (3 legs, 3)
    dw0: FloatArray  # (3 params, 3 legs, 3)
    v0: FloatArray
    dv0: FloatArray  # d v0 / d beta


def geometry(design: SPMDesign) -> Geometry:
    """w_i0 as in :class:`SPMDesign` (unit vector at alpha1 from u_i and alpha2 from
    v_i0): w0 = x u + y v0 + z (u x v0) with c = u . v0, D = 1 - c^2,
    x = (cos a1 - c cos a2)/D, y = (cos a2 - c cos a1)/D,
    z = -sqrt((1 - x^2 - y^2 - 2 x y c)/D); differentiated by the chain rule."""
    u = design.u
    eta = np.asarray(design.eta) - math.pi / 2
    sb, cb = math.sin(design.beta), math.cos(design.beta)
    v0 = np.stack([sb * np.cos(eta), sb * np.sin(eta), np.full(3, cb)], axis=1)
    dv0 = np.stack([cb * np.cos(eta), cb * np.sin(eta), np.full(3, -sb)], axis=1)
    c = np.sum(u * v0, axis=1)
    dc_db = np.sum(u * dv0, axis=1)
    C1, C2 = math.cos(design.alpha1), math.cos(design.alpha2)
    D = 1.0 - c * c
    x = (C1 - c * C2) / D
    y = (C2 - c * C1) / D
    z2 = (1.0 - x * x - y * y - 2.0 * x * y * c) / D
    z = -np.sqrt(z2)
    uxv = np.cross(u, v0)
    w0 = x[:, None] * u + y[:, None] * v0 + z[:, None] * uxv

    def partial(dx: FloatArray, dy: FloatArray, dc: FloatArray) -> FloatArray:
        """d(x, y, z) -> d w0 at fixed u, v0 (dc: derivative of c)."""
        dN = -2 * x * dx - 2 * y * dy - 2 * c * (y * dx + x * dy) - 2 * x * y * dc
        dz2 = dN / D + z2 * 2 * c * dc / D
        dz = dz2 / (2 * z)
        result: FloatArray = dx[:, None] * u + dy[:, None] * v0 + dz[:, None] * uxv
        return result

    zero = np.zeros(3)
    d_a1 = partial(np.full(3, 1.0) / D, -c / D, zero) * -math.sin(design.alpha1)
    d_a2 = partial(-c / D, np.full(3, 1.0) / D, zero) * -math.sin(design.alpha2)
    d_c = partial((-C2 + 2 * c * x) / D, (-C1 + 2 * c * y) / D, np.ones(3))
    d_b = dc_db[:, None] * d_c + y[:, None] * dv0 + z[:, None] * np.cross(u, dv0)
    return Geometry(w0=w0, dw0=np.stack([d_a1, d_a2, d_b]), v0=v0, dv0=dv0)


@dataclasses.dataclass
class Evaluation:
    """Residuals, their Jacobian and the predicted measurements at one parameter vector."""

    residual: FloatArray  # (N, k)
    jacobian: FloatArray | None  # (N, k, 12)
    reachable: BoolArray  # (N,)
    predicted: FloatArray  # (N, 3, 3) predicted measurement (NaN where unreachable)


class Model:
    """Predicted measurements, residuals and their Jacobian for fixed readings."""

    def __init__(
        self,
        theta: FloatArray,
        measured: FloatArray | None,
        kind: str,
        base: SPMDesign,
        start: CalibrationParameters,
    ) -> None:
        self.theta = theta
        self.measured = measured
        self.kind = kind
        self.base = base
        self.start = start
        self.k = COMPONENTS[kind]
        self.basis = None if measured is None or kind != "axes" else tangent_basis(measured)
        self._cache: tuple[bytes, bool, Evaluation] | None = None
        self.evaluations = 0

    def evaluate(self, x: FloatArray, jac: bool) -> Evaluation:
        key = np.asarray(x, dtype=float).tobytes()
        if self._cache is not None and self._cache[0] == key and (self._cache[1] or not jac):
            return self._cache[2]
        result = self._evaluate(np.asarray(x, dtype=float), jac)
        self._cache = (key, jac, result)
        self.evaluations += 1
        return result

    def _evaluate(self, x: FloatArray, jac: bool) -> Evaluation:
        n, k = self.theta.shape[0], self.k
        penalty = Evaluation(
            residual=np.full((n, k), UNREACHABLE_RESIDUAL),
            jacobian=np.zeros((n, k, len(PARAMETER_NAMES))) if jac else None,
            reachable=np.zeros(n, dtype=bool),
            predicted=np.full((n, 3, 3), np.nan),
        )
        try:
            design = dataclasses.replace(self.base, alpha1=x[3], alpha2=x[4], beta=x[5])
        except DesignError:
            return penalty
        mu, rho = x[6:9], x[9:12]
        R_mount = self.start.mount @ exp_so3(mu)
        R_ref = exp_so3(rho) @ self.start.reference
        theta = self.theta - x[0:3]
        fk = forward_kinematics(theta, design)
        ok = np.asarray(fk.reachable)
        if not np.any(ok):
            return penalty
        R, w, v, th = fk.R[ok], fk.w[ok], fk.v[ok], theta[ok]
        if self.kind == "quaternion":
            predicted = R_ref @ R @ R_mount
        else:
            predicted = np.einsum("jk,nik->nij", R_ref, v)
        residual = np.full((n, k), UNREACHABLE_RESIDUAL)
        full_pred = np.full((n, 3, 3), np.nan)
        full_pred[ok] = predicted
        q: FloatArray | None = None
        if self.measured is not None:
            meas = self.measured[ok]
            if self.kind == "quaternion":
                q = quaternion_from_matrix(np.swapaxes(predicted, -1, -2) @ meas)
                residual[ok] = 2.0 * q[:, 1:]
            else:
                assert self.basis is not None
                basis = self.basis[ok]
                residual[ok] = np.einsum("nicd,nid->nic", basis, meas - predicted).reshape(-1, 6)
        else:
            residual[ok] = 0.0
            basis = tangent_basis(predicted)
        jacobian = None
        if jac:
            D = self._prediction_derivative(design, th, R, w, v, predicted, R_mount, R_ref, mu, rho)
            if self.kind == "quaternion":
                if q is None:  # planning: measured = predicted, E = I
                    block = -D
                else:
                    w_q = q[:, 0][:, None, None] * np.eye(3)
                    block = -(w_q - skew(q[:, 1:])) @ D
            else:
                block = -np.einsum("nicd,nidp->nicp", basis, D).reshape(-1, 6, len(PARAMETER_NAMES))
            jacobian = np.zeros((n, k, len(PARAMETER_NAMES)))
            jacobian[ok] = block
        return Evaluation(residual=residual, jacobian=jacobian, reachable=ok, predicted=full_pred)

    def _prediction_derivative(
        self,
        design: SPMDesign,
        theta: FloatArray,
        R: FloatArray,
        w: FloatArray,
        v: FloatArray,
        predicted: FloatArray,
        R_mount: FloatArray,
        R_ref: FloatArray,
        mu: FloatArray,
        rho: FloatArray,
    ) -> FloatArray:
        """d(prediction)/d(parameters): quaternion kind (n, 3, 12) as right increments
        of R_pred in the sensor frame; axes kind (n, 3 legs, 3, 12)."""
        n = theta.shape[0]
        geo = geometry(design)
        u = design.u
        b = np.sum(cross(u, w) * v, axis=-1)  # (n, 3)
        dw = np.stack([rotate_about(u, theta, geo.dw0[p]) for p in range(3)], axis=-1)
        Rdv0 = np.einsum("njk,ik->nij", R, geo.dv0)  # rows R dv_i0/d beta
        K = np.zeros((n, 3, 6))
        K[:, [0, 1, 2], [0, 1, 2]] = -b  # offsets: d theta_i = -d offset_i
        K[:, :, 3:6] = np.einsum("nicp,nic->nip", dw, v)
        K[:, :, 4] += math.sin(design.alpha2)
        K[:, :, 5] += np.sum(w * Rdv0, axis=-1)
        A = cross(w, v)
        dphi = np.linalg.solve(A, K)  # (n, 3, 6): world-frame platform increments
        P = len(PARAMETER_NAMES)
        if self.kind == "quaternion":
            D = np.zeros((n, 3, P))
            M = R @ R_mount
            D[:, :, 0:6] = np.swapaxes(M, -1, -2) @ dphi
            D[:, :, 6:9] = right_jacobian_so3(mu)
            D[:, :, 9:12] = np.swapaxes(predicted, -1, -2) @ left_jacobian_so3(rho)
            return D
        D = np.zeros((n, 3, 3, P))
        # d v_i = dphi x v_i (+ R dv_i0 d beta), then R_ref in front.
        world = -skew(v) @ dphi[:, None]  # (n, 3 legs, 3, 6)
        world[..., 5] += Rdv0
        D[..., 0:6] = np.einsum("jk,nikp->nijp", R_ref, world)
        D[..., 9:12] = -skew(predicted) @ left_jacobian_so3(rho)
        return D
