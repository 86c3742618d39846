"""Joint configurations for the collision checker: the closed q of input angles theta
in the home assembly mode, in Python floats, and the check of a batch of q."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ..errors import ConvergenceError, InputError, UnreachableError
from ..kinematics import forward_kinematics
from ..kinematics._common import require_angles
from ..model.robot import CLOSURE_TOL
from ._shapes import cross, dot, turn
from .pairs import FloatArray

__all__ = [
    "KERNELS",
    "Legs",
    "as_q_batch",
    "closed_angles",
    "leg_axes",
    "rotation_configuration",
    "theta_configuration",
]

#: Per leg: u_i, w_i0, v_i0 as float tuples.
Legs = tuple[tuple[tuple[float, ...], ...], ...]
Vec = tuple[float, float, float]


def leg_axes(design: SPMDesign) -> Legs:
    """The axes u_i, w_i0 and v_i0 of the legs as float tuples (u, w0, v0 rows)."""
    return tuple(
        tuple(tuple(float(c) for c in row) for row in axes)
        for axes in (design.u, design.w0, design.v0)
    )


def theta_configuration(theta: FloatArray, design: SPMDesign, legs: Legs) -> FloatArray:
    """The closed q of one theta (3,) in the home assembly mode (``legs``: the axes of
    :func:`leg_axes`).

    The method of ``SPMRobot.configuration`` (see :mod:`spm_pin.model.robot`):
    q_ui = theta_i; q_wi = psi_i with Rot(w_i0, psi_i) v_i0 = P_i^T R v_i0; q_vi =
    chi_i with Rot(v_i0, chi_i) = D_i^T R, checked to :data:`CLOSURE_TOL
    <spm_pin.model.robot.CLOSURE_TOL>` (that check proves every leg ends at R,
    so the loops close).
    """
    fk = forward_kinematics(theta, design)
    if not bool(fk.reachable):
        raise UnreachableError(
            f"theta = {np.degrees(theta).round(6).tolist()} deg has no assembly in mode "
            "'home'; filter inputs with spm.forward_kinematics(theta, design).reachable",
            value=theta,
        )
    return rotation_configuration(theta.tolist(), fk.R.tolist(), legs)


def closed_angles(
    theta: Sequence[float], columns: Sequence[Sequence[float]], legs: Legs
) -> tuple[Vec, Vec, Vec, float]:
    """(theta_i, psi_i, chi_i) of each leg whose platform rotation has the
    ``columns``, and the largest residual of the fit (a kernel: floats and tuples
    only, compiled by :func:`spm_pin._jit.kernels` for the control loop)."""
    out = []
    worst = 0.0
    for i in range(3):
        angle, u, w0, v0 = theta[i], legs[0][i], legs[1][i], legs[2][i]
        # Columns of P^T R: R's columns turned by -theta about u.
        c, s = math.cos(angle), math.sin(angle)
        p0, p1, p2 = (
            turn(u, c, -s, columns[0]),
            turn(u, c, -s, columns[1]),
            turn(u, c, -s, columns[2]),
        )
        # psi from the components of v0 and P^T R v0 normal to w0.
        x, y, z = v0
        target = (
            p0[0] * x + p1[0] * y + p2[0] * z,
            p0[1] * x + p1[1] * y + p2[1] * z,
            p0[2] * x + p1[2] * y + p2[2] * z,
        )
        along_v, along_t = dot(w0, v0), dot(w0, target)
        a = (x - along_v * w0[0], y - along_v * w0[1], z - along_v * w0[2])
        b = (
            target[0] - along_t * w0[0],
            target[1] - along_t * w0[1],
            target[2] - along_t * w0[2],
        )
        psi = math.atan2(dot(w0, cross(a, b)), dot(a, b))
        # M = D^T R = Rot(w0, -psi) P^T R (columns m0, m1, m2); chi from its
        # axis-angle form, and M must be that turn about v0.
        c, s = math.cos(psi), math.sin(psi)
        m0, m1, m2 = turn(w0, c, -s, p0), turn(w0, c, -s, p1), turn(w0, c, -s, p2)
        sin_chi = 0.5 * (x * (m1[2] - m2[1]) + y * (m2[0] - m0[2]) + z * (m0[1] - m1[0]))
        chi = math.atan2(sin_chi, 0.5 * (m0[0] + m1[1] + m2[2] - 1.0))
        c, s = math.cos(chi), math.sin(chi)
        t = 1.0 - c
        worst = max(
            worst,
            abs(m0[0] - c - t * x * x),
            abs(m0[1] - t * x * y - s * z),
            abs(m0[2] - t * x * z + s * y),
            abs(m1[0] - t * x * y + s * z),
            abs(m1[1] - c - t * y * y),
            abs(m1[2] - t * y * z - s * x),
            abs(m2[0] - t * x * z - s * y),
            abs(m2[1] - t * y * z + s * x),
            abs(m2[2] - c - t * z * z),
        )
        out.append((angle, psi, chi))
    return out[0], out[1], out[2], worst


#: :func:`closed_angles` and the functions it calls, callees first: what
#: :func:`spm_pin._jit.kernels` compiles.
KERNELS = (dot, cross, turn, closed_angles)


def rotation_configuration(
    theta: Sequence[float],
    rotation: Sequence[Sequence[float]],
    legs: Legs,
    kernel: Callable[..., tuple[Vec, Vec, Vec, float]] = closed_angles,
) -> FloatArray:
    """The closed q of one theta (3 floats) whose home-mode platform rotation (rows)
    is known: what :func:`theta_configuration` computes after its forward kinematics.

    ``kernel`` is :func:`closed_angles` or its compiled twin (same bits).

    Raises:
        ConvergenceError: the rotation does not fit the legs at theta.
    """
    r = rotation
    columns = (
        (r[0][0], r[1][0], r[2][0]),
        (r[0][1], r[1][1], r[2][1]),
        (r[0][2], r[1][2], r[2][2]),
    )
    first, second, third, worst = kernel((theta[0], theta[1], theta[2]), columns, legs)
    if not worst <= CLOSURE_TOL:  # pragma: no cover - FK certifies its solutions
        raise ConvergenceError(
            f"the platform rotation does not fit leg geometry at theta = "
            f"{np.degrees(theta).tolist()} deg: residual {worst:.3g}",
            data={"theta": np.asarray(theta), "R": np.asarray(rotation), "residual": worst},
        )
    return np.array(first + second + third)


def as_q_batch(q: npt.ArrayLike, nq: int) -> FloatArray:
    """Checked joint configurations q of shape (N, nq) [rad]."""
    try:
        array = np.asarray(q, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(
            f"q must be numbers of shape (N, 9) [rad], got {q!r}", argument="q", value=q
        ) from exc
    if array.ndim != 2 or array.shape[1] != nq:
        raise InputError(
            f"q must have shape (N, {nq}) [rad], got shape {array.shape}",
            argument="q",
            value=q,
        )
    require_angles(array, "q", q)
    return array
