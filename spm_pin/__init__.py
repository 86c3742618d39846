"""spm-pin: exact kinematics and models of spherical parallel manipulators."""

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
    "SingularityError",
    "TrackResult",
    "UnreachableError",
    "__version__",
    "forward_kinematics",
    "forward_kinematics_all",
    "inverse_kinematics",
    "inverse_kinematics_all",
    "jacobian",
    "track",
]
