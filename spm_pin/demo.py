"""The published study of the prototype, reproduced (what ``spm demo`` runs): the
names of :mod:`spm_pin.study`, importable from ``spm_pin.demo`` as well."""

from __future__ import annotations

from .study import (
    DEMO_COLLIDING_THETA_DEG,
    DEMO_SAMPLES,
    DEMO_SECTIONS,
    DEMO_THETA_DEG,
    INSTALL_DEMO,
    MUJOCO_SETTLE_STEPS,
    MUJOCO_TIMESTEP,
    MUJOCO_TOLERANCE,
    OPTIONAL_DEPENDENCIES,
    PROJECTION_TOLERANCE,
    STUDY_AGREEMENT,
    DemoContext,
    DemoResult,
    DemoSection,
    MujocoAxes,
    ReportItem,
    Skipped,
    demo_record,
    mujoco_platform_axes,
    run_demo,
)
from .study import MUJOCO_PASSIVE_DAMPING as MUJOCO_PASSIVE_DAMPING
from .study import ProgressMode as ProgressMode

__all__ = [
    "DEMO_COLLIDING_THETA_DEG",
    "DEMO_SAMPLES",
    "DEMO_SECTIONS",
    "DEMO_THETA_DEG",
    "INSTALL_DEMO",
    "MUJOCO_SETTLE_STEPS",
    "MUJOCO_TIMESTEP",
    "MUJOCO_TOLERANCE",
    "OPTIONAL_DEPENDENCIES",
    "PROJECTION_TOLERANCE",
    "STUDY_AGREEMENT",
    "DemoContext",
    "DemoResult",
    "DemoSection",
    "MujocoAxes",
    "ReportItem",
    "Skipped",
    "demo_record",
    "mujoco_platform_axes",
    "run_demo",
]
