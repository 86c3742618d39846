"""What a check of input angles found: :class:`Evaluation` (shared by the safe set's
samples and the certified cells of :mod:`spm_pin.planning.cover`), and
:func:`sample_checks`, the kinematic checks of one input that both make."""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from ..collision._configuration import Legs
    from ..design import SPMDesign
    from ..model.robot import SPMRobot
    from .safe_set import PlanSettings

__all__ = ["YAW_TOLERANCE_M", "Evaluation", "nearest_phrase", "sample_checks"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Largest change of a link distance when the whole mechanism turns about the axis
#: [m] (the base's tessellation; measured: 35 um), added to the clearance margin.
YAW_TOLERANCE_M = 5e-5


def nearest_phrase(design: SPMDesign, nearest: FloatArray | None, what: str) -> str:
    """ "; the nearest safe input <what> [..] deg (orientation rpy [..] deg)" for a
    refusal's message, or "" without a nearest input."""
    if nearest is None:
        return ""
    from ..kinematics import forward_kinematics
    from ..rotations import rpy_from_matrix

    R = np.asarray(forward_kinematics(nearest, design).R, dtype=float)
    rpy = np.degrees(rpy_from_matrix(R)).round(2).tolist()
    return (
        f"; the nearest safe input {what} {np.degrees(nearest).round(2).tolist()} deg "
        f"(orientation rpy {rpy} deg)"
    )


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """The checks at input angles (n, 3), with thresholds raised by a buffer.

    Attributes:
        reachable: The home assembly mode exists, (n,).
        singularity_margin: (n,) (NaN where unreachable).
        dexterity: (n,) (NaN where unreachable).
        colliding: Two links nearer than the raised margin, (n,).
        safe: Every check passes, (n,).
        radius: Gap distance [deg] around each sample within which every check is
            certified to pass (negative where the sample fails), (n,).
    """

    reachable: BoolArray
    singularity_margin: FloatArray
    dexterity: FloatArray
    colliding: BoolArray
    safe: BoolArray
    radius: FloatArray

    def reason(self, k: int, settings: PlanSettings) -> str:
        """Why sample k is not safe (one sentence)."""
        if not self.reachable[k]:
            return "no home-mode assembly (unreachable)"
        if self.singularity_margin[k] < settings.min_singularity_margin:
            return (
                f"too near a singularity (margin {self.singularity_margin[k]:.3f} < "
                f"{settings.min_singularity_margin:g})"
            )
        if self.dexterity[k] < settings.min_dexterity:
            return f"dexterity {self.dexterity[k]:.3f} < {settings.min_dexterity:g}"
        if self.colliding[k]:
            return f"links nearer than the margin {settings.margin * 1e3:g} mm (collision)"
        return "too near the boundary of the safe set to certify"


def sample_checks(robot: SPMRobot, theta: list[float]) -> tuple[bool, float, float, FloatArray]:
    """(reachable, singularity margin, dexterity, closed q) of one finite input on
    the single-input float path (the batch values to rounding, 1e-13); NaN measures
    and zeros where it does not assemble in the home mode."""
    from ..collision._configuration import rotation_configuration
    from ..kinematics import _scalar
    from ..kinematics.jacobian import SINGULAR_TOL

    k = _scalar.constants(robot.design)
    rows = _scalar.fk_home(theta, k)
    if rows is None:
        return False, math.nan, math.nan, np.zeros(robot.model.nq)
    sing, dex = _scalar.measures(theta, rows, k, SINGULAR_TOL)
    return True, sing, dex, rotation_configuration(theta, rows, _legs(robot.design))


@functools.lru_cache(maxsize=32)
def _legs(design: SPMDesign) -> Legs:
    from ..collision._configuration import leg_axes

    return leg_axes(design)
