"""An independent brute-force forward-kinematics solver, used only by the tests.

It shares nothing with ``spm_pin.kinematics`` except the design's public data
(``u``, ``w0``, ``v0``, ``alpha2``) and builds every equation from scratch:

* w_i(theta_i) is w_i0 turned about u_i by theta_i (Rodrigues, written out here).
* v_1 and v_2 run over their cones of half-angle alpha2 around w_1 and w_2,
  parameterised by phi_1, phi_2 in frames built from a fixed helper vector (not from
  u_i x w_i, as the library does).
* The platform rotation is R(phi_1, phi_2) = G(v_1, v_2) G(v_10, v_20)^T with G the
  Gram-Schmidt frame of two vectors, a proper rotation for every (phi_1, phi_2).
* The unknowns solve g_1 = v_1 . v_2 - v_10 . v_20 = 0 and
  g_2 = w_3 . (R v_30) - cos(alpha2) = 0.

A dense grid over the (phi_1, phi_2) torus is scanned; Newton (finite-difference
Jacobian, vectorised) starts from every cell where both g_1 and g_2 change sign and
from every local minimum of g_1^2 + g_2^2; converged points are checked on the three
original loop closures w_i . R v_i0 = cos(alpha2) and de-duplicated by R. The result
is every real assembly mode, found by exhaustion rather than by a resultant.
"""

from __future__ import annotations

import numpy as np

#: Grid points per torus direction.
GRID = 240
#: A Newton end point is a solution when every loop closure holds to this.
SOLUTION_TOL = 1e-11
#: Two solutions whose rotations differ by less than this (max abs entry) are one.
DUPLICATE_TOL = 1e-6
_NEWTON_STEPS = 40
_FD_STEP = 1e-7


def rodrigues(axis: np.ndarray, angle: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """Turn ``vector`` (3,) about unit ``axis`` (3,) by ``angle`` (...,), right-handed."""
    angle = np.asarray(angle, dtype=float)[..., None]
    k = np.asarray(axis, dtype=float)
    x = np.asarray(vector, dtype=float)
    return (
        x * np.cos(angle)
        + np.cross(k, x) * np.sin(angle)
        + k * float(k @ x) * (1.0 - np.cos(angle))
    )


def _perpendicular_frame(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors e, f with (w, e, f) right-handed orthonormal."""
    helper = np.zeros(3)
    helper[int(np.argmin(np.abs(w)))] = 1.0
    e = np.cross(w, helper)
    e /= np.linalg.norm(e)
    return e, np.cross(w, e)


def _gram_schmidt(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Columns (x, y, z): x along a, y in the plane of a and b; shapes (..., 3) -> (..., 3, 3)."""
    x = a / np.linalg.norm(a, axis=-1, keepdims=True)
    y = b - np.sum(b * x, axis=-1, keepdims=True) * x
    y = y / np.linalg.norm(y, axis=-1, keepdims=True)
    return np.stack([x, y, np.cross(x, y)], axis=-1)


class _System:
    """The two torus equations of one input theta."""

    def __init__(self, theta: np.ndarray, u: np.ndarray, w0: np.ndarray, v0: np.ndarray, alpha2):
        self.w = np.array([rodrigues(u[i], theta[i], w0[i]) for i in range(3)])
        self.v0 = np.asarray(v0, dtype=float)
        self.cos2 = float(np.cos(alpha2))
        self.sin2 = float(np.sin(alpha2))
        self.c12 = float(self.v0[0] @ self.v0[1])
        self.frames = [_perpendicular_frame(self.w[i]) for i in range(2)]
        self.body = _gram_schmidt(self.v0[0], self.v0[1])

    def cone(self, leg: int, phi: np.ndarray) -> np.ndarray:
        e, f = self.frames[leg]
        phi = np.asarray(phi, dtype=float)[..., None]
        return self.cos2 * self.w[leg] + self.sin2 * (np.cos(phi) * e + np.sin(phi) * f)

    def rotation(self, phi1: np.ndarray, phi2: np.ndarray) -> np.ndarray:
        world = _gram_schmidt(self.cone(0, phi1), self.cone(1, phi2))
        return world @ self.body.T

    def equations(self, phi1: np.ndarray, phi2: np.ndarray) -> np.ndarray:
        v1, v2 = self.cone(0, phi1), self.cone(1, phi2)
        g1 = np.sum(v1 * v2, axis=-1) - self.c12
        v3 = self.rotation(phi1, phi2) @ self.v0[2]
        g2 = v3 @ self.w[2] - self.cos2
        return np.stack([g1, g2], axis=-1)

    def loop_residual(self, R: np.ndarray) -> np.ndarray:
        """max_i |w_i . R v_i0 - cos a2| and |R^T R - I|, for R (..., 3, 3)."""
        v = np.einsum("...jk,ik->...ij", R, self.v0)
        loop = np.abs(np.sum(v * self.w, axis=-1) - self.cos2).max(axis=-1)
        ortho = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(-2, -1))
        return np.maximum(loop, ortho)


def _starts(system: _System, grid: int) -> tuple[np.ndarray, np.ndarray]:
    """Grid cells where both equations change sign, plus local minima of |g|^2."""
    phi = np.linspace(0.0, 2 * np.pi, grid, endpoint=False)
    p1, p2 = np.meshgrid(phi, phi, indexing="ij")
    g = system.equations(p1, p2)  # (grid, grid, 2)

    def corners(values: np.ndarray) -> np.ndarray:
        return np.stack(
            [
                values,
                np.roll(values, -1, axis=0),
                np.roll(values, -1, axis=1),
                np.roll(np.roll(values, -1, axis=0), -1, axis=1),
            ],
            axis=-1,
        )

    c1, c2 = corners(g[..., 0]), corners(g[..., 1])
    crossing = (c1.min(-1) <= 0) & (c1.max(-1) >= 0) & (c2.min(-1) <= 0) & (c2.max(-1) >= 0)
    step = phi[1]
    cross_1 = p1[crossing] + step / 2
    cross_2 = p2[crossing] + step / 2
    energy = np.sum(g * g, axis=-1)
    neighbours = np.stack(
        [np.roll(np.roll(energy, i, axis=0), j, axis=1) for i in (-1, 0, 1) for j in (-1, 0, 1)]
    )
    minimum = (energy <= neighbours.min(axis=0)) & (energy < 1e-2)
    return (
        np.concatenate([cross_1, p1[minimum]]),
        np.concatenate([cross_2, p2[minimum]]),
    )


def _newton(system: _System, phi1: np.ndarray, phi2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised Newton with a central-difference Jacobian and step limiting."""
    h = _FD_STEP
    for _ in range(_NEWTON_STEPS):
        f = system.equations(phi1, phi2)
        d1 = (system.equations(phi1 + h, phi2) - system.equations(phi1 - h, phi2)) / (2 * h)
        d2 = (system.equations(phi1, phi2 + h) - system.equations(phi1, phi2 - h)) / (2 * h)
        det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            s1 = (d2[:, 1] * f[:, 0] - d2[:, 0] * f[:, 1]) / det
            s2 = (d1[:, 0] * f[:, 1] - d1[:, 1] * f[:, 0]) / det
        ok = np.isfinite(s1) & np.isfinite(s2)
        size = np.maximum(np.abs(s1), np.abs(s2))
        scale = np.where(ok, 1.0 / np.maximum(size / 0.2, 1.0), 0.0)
        phi1 = phi1 - scale * np.where(ok, s1, 0.0)
        phi2 = phi2 - scale * np.where(ok, s2, 0.0)
    return phi1, phi2


def brute_force_fk(theta, u, w0, v0, alpha2, *, grid: int = GRID) -> np.ndarray:
    """Every real assembly mode at input ``theta`` (3,): rotations, shape (k, 3, 3).

    Args:
        theta: Input angles [rad], shape (3,).
        u, w0, v0: The design's base axes, home proximal axes and platform axes (rows).
        alpha2: Distal link angle [rad].
        grid: Grid points per torus direction.
    """
    system = _System(np.asarray(theta, dtype=float), np.asarray(u), np.asarray(w0), v0, alpha2)
    phi1, phi2 = _starts(system, grid)
    phi1, phi2 = _newton(system, phi1, phi2)
    R = system.rotation(phi1, phi2)
    good = system.loop_residual(R) <= SOLUTION_TOL
    solutions: list[np.ndarray] = []
    for candidate in R[good]:
        if all(np.abs(candidate - known).max() > DUPLICATE_TOL for known in solutions):
            solutions.append(candidate)
    return np.array(solutions).reshape(-1, 3, 3)
