"""spm-pin: exact kinematics and models of spherical parallel manipulators."""

from ._version import __version__
from .design import LinkDimensions, SPMDesign
from .errors import SPMError
from .kinematics import forward_kinematics, forward_kinematics_all, inverse_kinematics

__all__ = [
    "LinkDimensions",
    "SPMDesign",
    "SPMError",
    "__version__",
    "forward_kinematics",
    "forward_kinematics_all",
    "inverse_kinematics",
]
