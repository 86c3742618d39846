"""Safe motion planning of coaxial SPMs (:func:`plan`, ``spm plan``).

* :class:`SafeSet`: the safe set in the gap plane (home assembly mode, singularity
  margin, dexterity, clearance margin: the static checks of the servos' guard), with
  the Lipschitz bounds that certify a path between its samples
  (:mod:`spm_pin.planning.safe_set`).
* :func:`plan`: a safe, near-shortest path between input angles or orientations,
  the mechanism turned the shortest way about its axis (or whole turns more)
  (:mod:`spm_pin.planning.planner`).
"""

from __future__ import annotations

from .planner import PlannedPath, gap_length, plan
from .safe_set import (
    LIPSCHITZ_FACTOR,
    YAW_TOLERANCE_M,
    Evaluation,
    Lipschitz,
    PlanSettings,
    SafeSet,
    safe_set,
)

__all__ = [
    "LIPSCHITZ_FACTOR",
    "YAW_TOLERANCE_M",
    "Evaluation",
    "Lipschitz",
    "PlanSettings",
    "PlannedPath",
    "SafeSet",
    "gap_length",
    "plan",
    "safe_set",
]
