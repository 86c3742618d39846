"""The prototype's kinematics written out from DESIGN.md section 1, in plain numpy:
an independent truth for the tests (nothing here comes from spm_pin)."""

from __future__ import annotations

import numpy as np

# The prototype: a1 = 45, a2 = 90, b = 90 deg, coaxial u = -z.
A1, A2, BETA = np.radians(45.0), np.radians(90.0), np.radians(90.0)
ETA = np.radians([0.0, 120.0, 240.0])
U = np.array([0.0, 0.0, -1.0])
V0 = np.stack(
    [
        np.sin(BETA) * np.cos(ETA - np.pi / 2),
        np.sin(BETA) * np.sin(ETA - np.pi / 2),
        np.full(3, np.cos(BETA)),
    ],
    axis=1,
)


def w_axes(theta: np.ndarray) -> np.ndarray:
    """Rows w_i = [sin a1 cos(eta_i - theta_i), sin a1 sin(eta_i - theta_i), -cos a1]."""
    phi = ETA - np.asarray(theta, dtype=float)
    return np.stack(
        [np.sin(A1) * np.cos(phi), np.sin(A1) * np.sin(phi), np.full(3, -np.cos(A1))], axis=1
    )


def rot(vec: np.ndarray) -> np.ndarray:
    """Rodrigues: the rotation by |vec| about vec."""
    vec = np.asarray(vec, dtype=float)
    angle = float(np.linalg.norm(vec))
    if angle == 0.0:
        return np.eye(3)
    k = vec / angle
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * K @ K
