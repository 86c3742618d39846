"""Gap coordinates of a coaxial SPM and tilt-and-torsion angles of the platform.

The gaps D12, D23, D31 between neighbouring proximal links [deg] are the plane a
workspace map samples (see :mod:`spm_pin.workspace`); :func:`gap_inputs` and
:func:`gaps_from_theta` convert between gaps and input angles, and
:func:`tilt_torsion` splits a platform rotation into tilt, azimuth and torsion.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .._checks import FloatArray
from ..design import SPMDesign
from ..errors import InputError
from ..kinematics._common import check_design

__all__ = ["coaxial", "gap_inputs", "gaps_from_theta", "tilt_torsion"]


def coaxial(design: SPMDesign | str | None) -> SPMDesign:
    design = check_design(design)
    if not design.is_coaxial:
        raise InputError(
            f"workspace maps over the proximal-link gaps need a coaxial design (all u_i "
            f"equal); design {design.name!r} is not coaxial",
            argument="design",
            value=design.name,
        )
    return design


def gap_inputs(
    d12_deg: npt.ArrayLike, d23_deg: npt.ArrayLike, design: SPMDesign | str | None = None
) -> FloatArray:
    """Input angles [rad] with theta_1 = 0 and the given gaps [deg] (broadcast).

    theta_2 = eta_2 - eta_1 - D12, theta_3 = eta_3 - eta_1 - D12 - D23.

    Raises:
        InputError: a non-coaxial design; gaps that are not finite numbers.
    """
    design = coaxial(design)
    try:
        d12 = np.asarray(d12_deg, dtype=float)
        d23 = np.asarray(d23_deg, dtype=float)
        d12, d23 = np.broadcast_arrays(d12, d23)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(
            f"gaps must be numbers [deg] of broadcastable shapes, got {d12_deg!r}, {d23_deg!r}",
            argument="gaps",
            value=(d12_deg, d23_deg),
        ) from exc
    if not (np.all(np.isfinite(d12)) and np.all(np.isfinite(d23))):
        raise InputError("gaps must be finite [deg]", argument="gaps", value=(d12_deg, d23_deg))
    eta = np.degrees(np.asarray(design.eta, dtype=float))
    theta2 = eta[1] - eta[0] - d12
    theta3 = eta[2] - eta[0] - d12 - d23
    result: FloatArray = np.radians(np.stack([np.zeros_like(d12), theta2, theta3], axis=-1))
    return result


def gaps_from_theta(theta: npt.ArrayLike, design: SPMDesign | str | None = None) -> FloatArray:
    """Gaps (D12, D23, D31) [deg] of input angles theta [rad], (..., 3); they sum to 360.

    D12 and D23 are wrapped into (-180, 540] around the home gaps so that small
    motions never jump; D31 = 360 - D12 - D23.
    """
    design = coaxial(design)
    from ..kinematics._common import as_theta

    angles = np.degrees(as_theta(theta))
    eta = np.degrees(np.asarray(design.eta, dtype=float))
    azimuth = eta - angles  # of w_i [deg]
    home = np.array([eta[1] - eta[0], eta[2] - eta[1]])
    raw = np.stack([azimuth[..., 1] - azimuth[..., 0], azimuth[..., 2] - azimuth[..., 1]], -1)
    wrapped = home + np.mod(raw - home + 180.0, 360.0) - 180.0
    return np.concatenate([wrapped, 360.0 - wrapped.sum(axis=-1, keepdims=True)], axis=-1)


def tilt_torsion(R: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    r"""Tilt-and-torsion angles of platform rotations [rad].

    R = Rz(phi) Ry(tilt) Rz(-phi) Rz(torsion): the platform normal n = R e_z has
    tilt = arccos(n_z) (computed as atan2(|n_xy|, n_z)) and azimuth
    phi = atan2(n_y, n_x) (0 where tilt = 0), and
    Rz(torsion) = (Rz(phi) Ry(tilt) Rz(-phi))^T R.

    Args:
        R: Rotations (..., 3, 3).

    Returns:
        (tilt in [0, pi], azimuth in (-pi, pi], torsion in (-pi, pi]), each (...).
    """
    M = np.asarray(R, dtype=float)
    n = M[..., :, 2]
    horizontal = np.hypot(n[..., 0], n[..., 1])
    tilt = np.arctan2(horizontal, n[..., 2])  # arccos(n_z), accurate near 0 and pi
    azimuth = np.where(horizontal > 1e-12, np.arctan2(n[..., 1], n[..., 0]), 0.0)
    c, s = np.cos(azimuth), np.sin(azimuth)
    ct, st = np.cos(tilt), np.sin(tilt)
    # T = Rz(phi) Ry(tilt) Rz(-phi); torsion from the first column of T^T R.
    T = np.empty(M.shape)
    T[..., 0, 0] = c * c * ct + s * s
    T[..., 0, 1] = c * s * (ct - 1.0)
    T[..., 0, 2] = c * st
    T[..., 1, 0] = c * s * (ct - 1.0)
    T[..., 1, 1] = s * s * ct + c * c
    T[..., 1, 2] = s * st
    T[..., 2, 0] = -c * st
    T[..., 2, 1] = -s * st
    T[..., 2, 2] = ct
    Z = np.swapaxes(T, -1, -2) @ M
    torsion = np.arctan2(Z[..., 1, 0], Z[..., 0, 0])
    return tilt, azimuth, torsion
