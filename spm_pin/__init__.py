"""spm-pin: exact kinematics and models of spherical parallel manipulators."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ._version import __version__
from .design import LinkDimensions, SPMDesign
from .errors import (
    ConvergenceError,
    DesignError,
    FileFormatError,
    InputError,
    SingularityError,
    SPMError,
    UnreachableError,
)
from .kinematics import (
    FKAllResult,
    FKResult,
    IKAllResult,
    IKResult,
    JacobianResult,
    TrackResult,
    forward_kinematics,
    forward_kinematics_all,
    inverse_kinematics,
    inverse_kinematics_all,
    jacobian,
    track,
)

if TYPE_CHECKING:
    from .model.robot import SPMRobot, build_robot

#: Names served lazily from submodules that import Pinocchio (``import spm_pin`` stays
#: light): name -> module.
_LAZY = {"SPMRobot": ".model.robot", "build_robot": ".model.robot"}


def __getattr__(name: str) -> Any:
    """Import Pinocchio-backed names on first use (PEP 562)."""
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(_LAZY[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


__all__ = [
    "ConvergenceError",
    "DesignError",
    "FKAllResult",
    "FKResult",
    "FileFormatError",
    "IKAllResult",
    "IKResult",
    "InputError",
    "JacobianResult",
    "LinkDimensions",
    "SPMDesign",
    "SPMError",
    "SPMRobot",
    "SingularityError",
    "TrackResult",
    "UnreachableError",
    "__version__",
    "build_robot",
    "forward_kinematics",
    "forward_kinematics_all",
    "inverse_kinematics",
    "inverse_kinematics_all",
    "jacobian",
    "track",
]
