r"""Inverse kinematics: platform orientation R -> input angles theta, all 8 working modes.

For leg i, with v = R v_i0, w_i0 the home proximal axis and u_i the base axis,
rotating w_i0 about u_i by theta gives
w_i(theta) = (u.w0) u + cos(theta) a + sin(theta) (u x w0), a = w0 - (u.w0) u,
so the loop closure w_i . v = cos a2 reads

    P cos(theta) + Q sin(theta) + S = 0,
    P = a . v,  Q = (u x w0) . v,  S = (u.w0)(u.v) - cos a2.

It has real roots iff P^2 + Q^2 - S^2 >= 0. The two roots are
theta = atan2(Q, P) -+ atan2(sqrt(P^2 + Q^2 - S^2), -S); the first ("+") has
b_ii = (u x w_i) . v = +sqrt(P^2 + Q^2 - S^2) > 0 and belongs to the home working
mode. A working mode is three signs, one per leg; index m in 0..7 has bit i set when
leg i takes the "-" root, so mode 0 ("+++") is the home working mode.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from .. import _jit
from ..design import SPMDesign
from ..errors import InputError, UnreachableError
from . import _scalar
from ._common import BoolArray, FloatArray, as_rotation, as_theta, check_design, mode_label

__all__ = [
    "WORKING_MODE_LABELS",
    "IKAllResult",
    "IKResult",
    "inverse_kinematics",
    "inverse_kinematics_all",
]

#: Labels of the 8 working modes, index m: bit i set = leg i+1 on the "-" root.
WORKING_MODE_LABELS: tuple[str, ...] = tuple(
    mode_label([-1 if (m >> i) & 1 else 1 for i in range(3)]) for m in range(8)
)

#: Relative slack on P^2 + Q^2 - S^2 that still counts as reachable (a type I boundary).
_REACH_TOL = 1e-12


@dataclasses.dataclass(frozen=True)
class IKResult:
    """Inverse kinematics in one working mode.

    Attributes:
        theta: Input angles [rad], shape (..., 3); NaN where unreachable.
        reachable: (...,) True where every leg closes.
        leg_reachable: (..., 3) per leg.
        b: (..., 3) b_ii = (u_i x w_i) . v_i; its signs are the working mode.
        mode: Working-mode label, e.g. ``"+++"`` (home).
    """

    theta: FloatArray
    reachable: BoolArray
    leg_reachable: BoolArray
    b: FloatArray
    mode: str


@dataclasses.dataclass(frozen=True)
class IKAllResult:
    """All 8 working modes.

    Attributes:
        theta: (..., 8, 3) input angles [rad], mode m along axis -2; NaN where unreachable.
        reachable: (...,) True where every leg closes (then all 8 modes exist, some
            coinciding on type I singularities).
        labels: the 8 labels, ``WORKING_MODE_LABELS``.
    """

    theta: FloatArray
    reachable: BoolArray
    labels: tuple[str, ...]


def _leg_coefficients(
    rotation: FloatArray, design: SPMDesign
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """P, Q, S of each leg, shapes (..., 3)."""
    u, w0 = design.u, design.w0
    v = np.einsum("...jk,ik->...ij", rotation, design.v0)  # rows v_i = R v_i0
    uw0 = np.sum(u * w0, axis=1)
    a = w0 - uw0[:, None] * u
    uxw0 = np.cross(u, w0)
    p = np.sum(v * a, axis=-1)
    q = np.sum(v * uxw0, axis=-1)
    s = uw0 * np.sum(v * u, axis=-1) - np.cos(design.alpha2)
    return p, q, s


def _wrap(angle: FloatArray) -> FloatArray:
    """Angles into (-pi, pi]."""
    return np.pi - np.mod(np.pi - angle, 2 * np.pi)


def _near(theta: FloatArray, theta_near: FloatArray) -> FloatArray:
    """The 2 pi k shift of each angle nearest to ``theta_near``."""
    try:
        np.broadcast_shapes(theta.shape, theta_near.shape)
    except ValueError as exc:
        raise InputError(
            f"theta_near must broadcast to the shape {theta.shape} of the solutions, got "
            f"shape {theta_near.shape}",
            argument="theta_near",
            value=theta_near,
        ) from exc
    return theta_near + _wrap(theta - theta_near)


def _solve_legs(
    rotation: FloatArray, design: SPMDesign
) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
    p, q, s = _leg_coefficients(rotation, design)
    scale = p * p + q * q + s * s
    disc = p * p + q * q - s * s
    leg_ok = disc >= -_REACH_TOL * np.maximum(scale, 1.0)
    root = np.sqrt(np.where(leg_ok, np.maximum(disc, 0.0), np.nan))
    base = np.arctan2(q, p)
    half = np.arctan2(root, -s)
    return base, half, root, leg_ok


def inverse_kinematics(
    R: npt.ArrayLike,
    design: SPMDesign | str | None = None,
    *,
    mode: int | str = 0,
    theta_near: npt.ArrayLike | None = None,
) -> IKResult:
    """Input angles that put the platform at orientation ``R``.

    Args:
        R: Platform rotation(s), shape (3, 3) or (..., 3, 3).
        design: The SPM (default: the prototype).
        mode: Working mode, an index 0..7 or a label such as ``"+-+"``; 0 (``"+++"``,
            every b_ii > 0) is the home working mode.
        theta_near: Optional angles [rad], shape broadcastable to (..., 3): each result
            is shifted by whole turns to lie nearest to it (multi-turn inputs).
            Default: angles in (-pi, pi].

    Returns:
        IKResult; for a batch, unreachable items are flagged in ``reachable`` and
        their angles are NaN.

    Raises:
        UnreachableError: a single orientation (shape (3, 3)) that some leg cannot
            reach; ``error.leg`` names the (first) failing leg.
        InputError: R is not a rotation matrix, or mode is unknown.
    """
    design = check_design(design)
    rotation = as_rotation(R)
    index = _mode_index(mode)
    if rotation.ndim == 2 and index == 0 and theta_near is None:
        return _home_one(rotation, design, R)  # the float path, same bits
    base, half, root, leg_ok = _solve_legs(rotation, design)
    signs = np.array([-1.0 if (index >> i) & 1 else 1.0 for i in range(3)])
    theta = _wrap(base - signs * half)
    if theta_near is not None:
        theta = _near(theta, as_theta(theta_near, "theta_near"))
    reachable = np.all(leg_ok, axis=-1)
    if rotation.ndim == 2 and not reachable:
        leg = int(np.argmin(leg_ok)) + 1
        p, q, s = _leg_coefficients(rotation, design)
        gap = float((s * s - p * p - q * q)[leg - 1])
        raise UnreachableError(
            f"orientation unreachable: leg {leg} cannot close (P^2 + Q^2 - S^2 = {-gap:.3g} < 0)",
            leg=leg,
            value=np.asarray(R),
        )
    return IKResult(
        theta=theta,
        reachable=reachable,
        leg_reachable=leg_ok,
        b=signs * root,
        mode=WORKING_MODE_LABELS[index],
    )


def _home_one(rotation: FloatArray, design: SPMDesign, given: npt.ArrayLike) -> IKResult:
    """``inverse_kinematics`` of one rotation in the home working mode, in floats."""
    rows = rotation.tolist()
    compiled = _jit.ready(_scalar.KERNELS)  # where a control loop compiled them
    solved = _scalar.ik_home(
        (tuple(rows[0]), tuple(rows[1]), tuple(rows[2])),
        _scalar.constants(design),
        None if compiled is None else compiled["ik_parts"],
    )
    if not all(solved.leg_reachable):
        leg = solved.leg_reachable.index(False) + 1
        p, q, s = solved.p[leg - 1], solved.q[leg - 1], solved.s[leg - 1]
        gap = s * s - p * p - q * q
        raise UnreachableError(
            f"orientation unreachable: leg {leg} cannot close (P^2 + Q^2 - S^2 = {-gap:.3g} < 0)",
            leg=leg,
            value=np.asarray(given),
        )
    return IKResult(
        theta=np.array(solved.theta),
        reachable=np.bool_(True),  # type: ignore[arg-type]
        leg_reachable=np.ones(3, dtype=bool),
        b=np.array(solved.b),
        mode=WORKING_MODE_LABELS[0],
    )


def inverse_kinematics_all(
    R: npt.ArrayLike,
    design: SPMDesign | str | None = None,
    *,
    theta_near: npt.ArrayLike | None = None,
) -> IKAllResult:
    """All 8 working modes at orientation ``R`` (never raises for unreachable poses).

    Returns:
        IKAllResult with ``theta`` of shape (..., 8, 3); mode m uses, for leg i, the
        "-" root when bit i of m is set (labels in ``WORKING_MODE_LABELS``).
    """
    design = check_design(design)
    rotation = as_rotation(R)
    base, half, _, leg_ok = _solve_legs(rotation, design)
    signs = np.array([[-1.0 if (m >> i) & 1 else 1.0 for i in range(3)] for m in range(8)])
    theta = _wrap(base[..., None, :] - signs * half[..., None, :])
    if theta_near is not None:
        theta = _near(theta, as_theta(theta_near, "theta_near")[..., None, :])
    return IKAllResult(theta=theta, reachable=np.all(leg_ok, axis=-1), labels=WORKING_MODE_LABELS)


def _mode_index(mode: int | str) -> int:
    if isinstance(mode, str):
        if mode not in WORKING_MODE_LABELS:
            raise InputError(
                f"mode {mode!r} is not a working mode; use one of {list(WORKING_MODE_LABELS)}",
                argument="mode",
                value=mode,
            )
        return WORKING_MODE_LABELS.index(mode)
    if isinstance(mode, (int, np.integer)) and not isinstance(mode, bool) and 0 <= mode < 8:
        return int(mode)
    raise InputError(
        f"mode must be an index 0..7 or a label like '+-+', got {mode!r}",
        argument="mode",
        value=mode,
    )
