"""Design problems with known answers, to validate studies against.

The dexterity at home in closed form. For a coaxial design with three-fold symmetry
(the legs 120 degrees apart) the three legs at home are copies of leg 1 turned about
the axis z, so every b_ii = (u_i x w_i0) . v_i0 is the same b and the rows
a_i = w_i0 x v_i0 of A are a_1 turned by 0, 120 and 240 degrees. Then

    A^T A = diag(p, p, q),  p = 3/2 |a_perp|^2,  q = 3 a_par^2,

(a_par the component of a_1 along z, a_perp the rest), J = A^-1 B = b A^-1, and the
dexterity 1/kappa_2(J) is sqrt(min(p, q) / max(p, q)): one leg's geometry fixes it.
It is 1 (isotropic) where tan^2 phi = |a_perp|^2 / a_par^2 = 2, phi the angle of a_1
from the axis (54.74 degrees).

With beta = 90 degrees (each v_i0 square to the platform's axis), write
w_10 = cos(alpha2) v + w_t t - cos(alpha1) z with t = z x v; unit length gives
w_t^2 = sin^2(alpha1) - cos^2(alpha2), and a_1 = w_10 x v = -w_t z - cos(alpha1) t:

    tan^2 phi = cos^2(alpha1) / (sin^2(alpha1) - cos^2(alpha2)),

so the dexterity at home is sqrt(min(r, 1/r)) with r = tan^2 phi / 2, and the
isotropic designs have cos^2(alpha2) = (3 sin^2(alpha1) - 1) / 2 (alpha1 at least
35.26 degrees): for alpha1 = 45 degrees, alpha2 = 60 or 120 degrees.
"""

from __future__ import annotations

import math

import numpy as np

from ..design import SPMDesign
from ..errors import InputError

__all__ = [
    "ISOTROPIC_PHI",
    "home_dexterity",
    "home_dexterity_right_angle",
    "isotropic_alpha2",
]

#: The angle of a_1 = w_10 x v_10 from the axis at which the home pose is isotropic:
#: arctan(sqrt(2)) [rad].
ISOTROPIC_PHI = math.atan(math.sqrt(2.0))


def _symmetric(design: SPMDesign) -> None:
    eta = np.mod(np.asarray(design.eta, dtype=float) - design.eta[0], 2.0 * math.pi)
    spaced = np.allclose(np.sort(eta), np.radians([0.0, 120.0, 240.0]), atol=1e-12)
    if not design.is_coaxial or not spaced:
        raise InputError(
            "the closed form needs a coaxial design with its legs 120 deg apart "
            f"(got {design.name!r}: coaxial={design.is_coaxial}, "
            f"eta={np.degrees(design.eta).round(3).tolist()} deg)",
            argument="design",
        )


def home_dexterity(design: SPMDesign | str | None = None) -> float:
    """The dexterity 1/kappa_2(J) at home from leg 1's geometry alone (see the
    module): sqrt(min(p, q) / max(p, q)) with p = 3/2 |a_perp|^2, q = 3 a_par^2.

    Raises:
        InputError: a design that is not coaxial with its legs 120 deg apart.
    """
    spm_design = SPMDesign.from_spec(design)
    _symmetric(spm_design)
    axis = spm_design.u[0] / np.linalg.norm(spm_design.u[0])
    a = np.cross(spm_design.w0[0], spm_design.v0[0])
    along = float(a @ axis)
    across = float(a @ a) - along * along
    p, q = 1.5 * across, 3.0 * along * along
    return math.sqrt(min(p, q) / max(p, q))


def home_dexterity_right_angle(alpha1: float, alpha2: float) -> float:
    """The dexterity at home of a coaxial, symmetric design with beta = 90 deg, from
    its link angles [rad] alone (see the module).

    Raises:
        InputError: link angles with which leg 1 cannot be assembled at home.
    """
    rest = math.sin(alpha1) ** 2 - math.cos(alpha2) ** 2
    if not rest > 0.0 or not math.cos(alpha1) != 0.0:
        raise InputError(
            f"alpha1 = {math.degrees(alpha1):.3f} and alpha2 = {math.degrees(alpha2):.3f} deg "
            "cannot be assembled at home with beta = 90 deg (sin^2 alpha1 > cos^2 alpha2 "
            "is needed, and alpha1 != 90 deg)",
            argument="alpha2",
        )
    ratio = math.cos(alpha1) ** 2 / rest / 2.0
    return math.sqrt(min(ratio, 1.0 / ratio))


def isotropic_alpha2(alpha1: float) -> tuple[float, float]:
    """The two distal link angles alpha2 [rad] (below and above 90 deg) that make the
    home pose isotropic (dexterity 1) for a coaxial, symmetric design with beta = 90
    deg and proximal link angle ``alpha1`` [rad]: cos^2(alpha2) = (3 sin^2(alpha1) -
    1) / 2.

    Raises:
        InputError: alpha1 below arctan(1 / sqrt(2)) = 35.26 deg (no isotropic home) or
            not below 90 deg.
    """
    value = (3.0 * math.sin(alpha1) ** 2 - 1.0) / 2.0
    if not 0.0 <= value < 1.0 or not 0.0 < alpha1 < math.pi / 2:
        raise InputError(
            f"no isotropic home pose with alpha1 = {math.degrees(alpha1):.3f} deg: it needs "
            "35.26 <= alpha1 < 90 deg",
            argument="alpha1",
        )
    low = math.acos(math.sqrt(value))
    return low, math.pi - low
