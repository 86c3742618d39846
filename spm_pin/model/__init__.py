"""The SPM as a robot: link shapes and mass properties, the Pinocchio model, robot files.

* :mod:`.geometry`: link meshes and mass properties from an :class:`~spm_pin.SPMDesign`.
* :mod:`.robot`: the Pinocchio model (open tree plus loop closures) and its geometry.
* :mod:`.export`: URDF, MJCF and STL files (``spm export``).
"""

from .export import export, mjcf_text, urdf_text
from .geometry import (
    LINK_NAMES,
    LinkInertia,
    LinkPart,
    link_inertias,
    link_meshes,
    link_parts,
)
from .robot import SPMRobot, build_robot

__all__ = [
    "LINK_NAMES",
    "LinkInertia",
    "LinkPart",
    "SPMRobot",
    "build_robot",
    "export",
    "link_inertias",
    "link_meshes",
    "link_parts",
    "mjcf_text",
    "urdf_text",
]
