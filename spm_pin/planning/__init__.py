"""Safe motion planning of SPMs (:func:`plan`, ``spm plan``): coaxial designs in
their gap plane with a free yaw, other designs in their 3-D input space.

* :class:`SafeSet`: the safe set in the gap plane (home assembly mode, singularity
  margin, dexterity, clearance margin: the static checks of the servos' guard), with
  the Lipschitz bounds that certify a path between its samples
  (:mod:`spm_pin.planning.safe_set`).
* :class:`SafeCover`: cells of the gap plane certified safe at every point, a
  quadtree grown as paths cross it (:mod:`spm_pin.planning.cover`).
* :class:`InputSafeSet`, :func:`plan_inputs`: the same checks and certificate in the
  3-D input space of a design that is not coaxial (the Agile Eye), searched with
  OMPL where the straight line is not safe (:mod:`spm_pin.planning.input_space`).
* :func:`plan`: a safe, near-shortest path between input angles or orientations,
  the mechanism turned the shortest way about its axis (or whole turns more)
  (:mod:`spm_pin.planning.planner`).
* :meth:`PlannedPath.timed`, :func:`time_path`: the fastest motion along a path
  under the servos' speed and acceleration limits, sampled at any rate (TOPP-RA, the
  ``planning`` extra) (:mod:`spm_pin.planning.timing`).
* :func:`path_figure`: planned paths drawn on the safe set in the gap plane
  (matplotlib, the ``plot`` extra) (:mod:`spm_pin.planning.plots`).
"""

from __future__ import annotations

from .cover import SafeCover
from .input_space import InputSafeSet, plan_inputs
from .planner import PlannedPath, gap_length, plan
from .plots import path_figure, save_path_figure
from .safe_set import (
    LIPSCHITZ_FACTOR,
    YAW_TOLERANCE_M,
    Evaluation,
    Lipschitz,
    PlanSettings,
    SafeSet,
    safe_set_of,
)
from .timing import (
    MotionLimits,
    TimingLimits,
    Trajectory,
    certify_curve,
    time_path,
    trapezoid_duration,
)

__all__ = [
    "LIPSCHITZ_FACTOR",
    "YAW_TOLERANCE_M",
    "Evaluation",
    "InputSafeSet",
    "Lipschitz",
    "MotionLimits",
    "PlanSettings",
    "PlannedPath",
    "SafeCover",
    "SafeSet",
    "TimingLimits",
    "Trajectory",
    "certify_curve",
    "gap_length",
    "path_figure",
    "plan",
    "plan_inputs",
    "safe_set_of",
    "save_path_figure",
    "time_path",
    "trapezoid_duration",
]
