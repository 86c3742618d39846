"""Design optimization of spherical parallel manipulators.

Not imported by ``import spm_pin``: ``import spm_pin.optimize``. This first part
scores a design quickly and exactly: :func:`safe_workspace_score` gives the figures of
the safe orientation workspace that ``spm workspace`` reports (see
:mod:`spm_pin.optimize.scoring`), with the base installation alone.
:mod:`spm_pin.optimize.objectives` holds the variables of a study
(:class:`DesignSpace`) and the objectives beyond the workspace's size (the global
conditioning index, the worst dexterity over a required cone of tilts).
"""

from .objectives import (
    ConeDexterity,
    DesignSpace,
    Envelope,
    Variable,
    cone_dexterity,
    envelope,
    global_conditioning_index,
    home_clearance,
)
from .scoring import WorkspaceScore, safe_workspace_score

__all__ = [
    "ConeDexterity",
    "DesignSpace",
    "Envelope",
    "Variable",
    "WorkspaceScore",
    "cone_dexterity",
    "envelope",
    "global_conditioning_index",
    "home_clearance",
    "safe_workspace_score",
]
