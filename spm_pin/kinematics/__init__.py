"""Analytic kinematics of 3-RRR spherical parallel manipulators (numpy only)."""

from .fk import FKAllResult, FKResult, forward_kinematics, forward_kinematics_all
from .ik import IKAllResult, IKResult, inverse_kinematics, inverse_kinematics_all

__all__ = [
    "FKAllResult",
    "FKResult",
    "IKAllResult",
    "IKResult",
    "forward_kinematics",
    "forward_kinematics_all",
    "inverse_kinematics",
    "inverse_kinematics_all",
]
