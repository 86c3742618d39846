"""The guard's one compiled call a cycle: forward kinematics, Jacobian parts and the
closed joint angles of one goal (see :mod:`spm_pin.hardware._fast`)."""

from __future__ import annotations

from ..collision import _configuration
from ..collision._configuration import Legs, closed_angles
from ..kinematics import _fk_single, _scalar
from ..kinematics._fk_single import Mat, SingleConstants, Vec, _home_solution, turned_rows
from ..kinematics._scalar import jacobian_parts

__all__ = ["KERNELS", "static_parts"]


def static_parts(
    theta: Vec,
    reduced: Vec,
    c: float,
    s: float,
    coaxial: bool,
    single: SingleConstants,
    newton_steps: int,
    polish_extra: int,
    polished: float,
    residual_tol: float,
    sign_tol: float,
    axis: Vec,
    outer: Mat,
    k: tuple[Mat, Mat, Mat, Mat, Mat],
    legs: Legs,
) -> tuple[bool, Mat, float, Mat, Mat, Vec, Vec, Vec, Vec, float]:
    """One goal's home-mode rotation, Jacobian parts and closed joint angles, in one
    kernel (compiled, one call a cycle): :func:`~spm_pin.kinematics._fk_single.
    home_rotation` at the reduced input (turned by the common turn of coaxial
    designs), :func:`~spm_pin.kinematics._scalar.jacobian_parts` and
    :func:`~spm_pin.collision._configuration.closed_angles`; ``k`` is (u, v0,
    w_along, w_rest, w_cross). Not certified: False and zeros."""
    ok, R = _home_solution(
        reduced, single, newton_steps, polish_extra, polished, residual_tol, sign_tol
    )
    if not ok:
        return False, R, 0.0, R, R, R[0], R[0], R[0], R[0], 0.0
    if coaxial:
        R = turned_rows(c, s, axis, outer, R)
    leg_margin, unit, A, b = jacobian_parts(theta, R, k[0], k[1], k[2], k[3], k[4])
    columns = (
        (R[0][0], R[1][0], R[2][0]),
        (R[0][1], R[1][1], R[2][1]),
        (R[0][2], R[1][2], R[2][2]),
    )
    first, second, third, worst = closed_angles(theta, columns, legs)
    return True, R, leg_margin, unit, A, b, first, second, third, worst


#: :func:`static_parts` and the functions it calls, callees first.
KERNELS = (*_fk_single.KERNELS, *_scalar.KERNELS, *_configuration.KERNELS, static_parts)
