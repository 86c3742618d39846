"""spm-pin: exact kinematics and models of spherical parallel manipulators."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ._version import __version__
from .design import LinkDimensions, SPMDesign
from .errors import (
    CommunicationError,
    ConvergenceError,
    DesignError,
    FileFormatError,
    HardwareError,
    InputError,
    ServoAlertError,
    ServoError,
    SingularityError,
    SPMError,
    UnreachableError,
    UnsafeCommandError,
)
from .kinematics import (
    Assembly,
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
    select_assembly,
    track,
)

if TYPE_CHECKING:
    from .calibration import (
        CalibrationResult,
        IdentifiabilityWarning,
        Readings,
        calibrate,
        load_readings,
        plan_poses,
        synthetic_readings,
    )
    from .closure import ClosedLoop, FrameTargetResult, PathResult, ProjectionResult
    from .collision import CollisionChecker, CollisionReport, build_robot
    from .dynamics import (
        XM540_W150,
        ClosedLoopDynamics,
        ForwardDynamicsResult,
        InverseDynamicsResult,
        JointFriction,
        ServoCheck,
        ServoController,
        ServoModel,
        SimulationResult,
        Simulator,
        Trajectory,
        check_servo,
        forward_dynamics,
        holding_torques,
        inverse_dynamics,
        plot_torques,
        simulate_mujoco,
    )
    from .model.robot import SPMRobot
    from .workspace import WorkspaceMap, WorkspaceSettings, workspace_map

#: Names served lazily from submodules that import Pinocchio (``import spm_pin`` stays
#: light), by module; each is also in that module's ``__all__`` (checked by the tests).
_LAZY_EXPORTS: dict[str, tuple[str, ...]] = {
    ".model.robot": ("SPMRobot",),
    # The generic loop-closure solver (Pinocchio).
    ".closure": ("ClosedLoop", "FrameTargetResult", "PathResult", "ProjectionResult"),
    # Constrained dynamics, simulation and servos (Pinocchio; MuJoCo and matplotlib only
    # inside the functions that need them).
    ".dynamics": (
        "ClosedLoopDynamics",
        "ForwardDynamicsResult",
        "InverseDynamicsResult",
        "JointFriction",
        "ServoCheck",
        "ServoController",
        "ServoModel",
        "SimulationResult",
        "Simulator",
        "Trajectory",
        "XM540_W150",
        "check_servo",
        "forward_dynamics",
        "holding_torques",
        "inverse_dynamics",
        "plot_torques",
        "simulate_mujoco",
    ),
    # Self-collision (Pinocchio, coal) and workspace maps; build_robot gives the robot
    # its collision checker.
    ".collision": ("CollisionChecker", "CollisionReport", "build_robot"),
    ".workspace": ("WorkspaceMap", "WorkspaceSettings", "workspace_map"),
    # Calibration (scipy is imported only when calibrating).
    ".calibration": (
        "CalibrationResult",
        "IdentifiabilityWarning",
        "Readings",
        "calibrate",
        "load_readings",
        "plan_poses",
        "synthetic_readings",
    ),
}
#: name -> module of the lazy names.
_LAZY = {name: module for module, names in _LAZY_EXPORTS.items() for name in names}


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
    "XM540_W150",
    "Assembly",
    "CalibrationResult",
    "ClosedLoop",
    "ClosedLoopDynamics",
    "CollisionChecker",
    "CollisionReport",
    "CommunicationError",
    "ConvergenceError",
    "DesignError",
    "FKAllResult",
    "FKResult",
    "FileFormatError",
    "ForwardDynamicsResult",
    "FrameTargetResult",
    "HardwareError",
    "IKAllResult",
    "IKResult",
    "IdentifiabilityWarning",
    "InputError",
    "InverseDynamicsResult",
    "JacobianResult",
    "JointFriction",
    "LinkDimensions",
    "PathResult",
    "ProjectionResult",
    "Readings",
    "SPMDesign",
    "SPMError",
    "SPMRobot",
    "ServoAlertError",
    "ServoCheck",
    "ServoController",
    "ServoError",
    "ServoModel",
    "SimulationResult",
    "Simulator",
    "SingularityError",
    "TrackResult",
    "Trajectory",
    "UnreachableError",
    "UnsafeCommandError",
    "WorkspaceMap",
    "WorkspaceSettings",
    "__version__",
    "build_robot",
    "calibrate",
    "check_servo",
    "forward_dynamics",
    "forward_kinematics",
    "forward_kinematics_all",
    "holding_torques",
    "inverse_dynamics",
    "inverse_kinematics",
    "inverse_kinematics_all",
    "jacobian",
    "load_readings",
    "plan_poses",
    "plot_torques",
    "select_assembly",
    "simulate_mujoco",
    "synthetic_readings",
    "track",
    "workspace_map",
]
