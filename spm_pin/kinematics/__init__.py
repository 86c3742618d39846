"""Analytic kinematics of 3-RRR spherical parallel manipulators (numpy only)."""

from .assembly import Assembly, select_assembly
from .fk import FKAllResult, FKResult, forward_kinematics, forward_kinematics_all
from .ik import (
    WORKING_MODE_LABELS,
    IKAllResult,
    IKResult,
    inverse_kinematics,
    inverse_kinematics_all,
)
from .jacobian import JacobianResult, jacobian
from .tracking import TrackResult, track

__all__ = [
    "WORKING_MODE_LABELS",
    "Assembly",
    "FKAllResult",
    "FKResult",
    "IKAllResult",
    "IKResult",
    "JacobianResult",
    "TrackResult",
    "forward_kinematics",
    "forward_kinematics_all",
    "inverse_kinematics",
    "inverse_kinematics_all",
    "jacobian",
    "select_assembly",
    "track",
]
