"""Design optimization of spherical parallel manipulators.

Not imported by ``import spm_pin``: ``import spm_pin.optimize``. This first part
scores a design quickly and exactly: :func:`safe_workspace_score` gives the figures of
the safe orientation workspace that ``spm workspace`` reports (see
:mod:`spm_pin.optimize.scoring`), with the base installation alone.
:mod:`spm_pin.optimize.objectives` holds the variables of a study
(:class:`DesignSpace`) and the objectives beyond the workspace's size (the global
conditioning index, the worst dexterity over a required cone of tilts).
:mod:`spm_pin.optimize.torque` gives the peak motor torque along a required motion
with a payload, and :mod:`spm_pin.optimize.study` runs resumable studies on Optuna
(the ``optimize`` extra), as ``spm optimize`` does; :mod:`spm_pin.optimize.results`
writes what a study found (the Pareto front's plot, the best designs as design files, a
page showing them and a JSON report), as ``spm optimize --out DIR`` does.
:mod:`spm_pin.optimize.validation` holds problems with known answers (the dexterity
at home in closed form, and the designs that make it isotropic; the published
isotropic design of the spherical 3-RRR, the Agile Eye's, at its reference
configuration).
"""

from ._engines import ClusterError
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
from .results import ResultFiles, best_trials, load_study_result, pareto_figure, write_results
from .scoring import WorkspaceScore, safe_workspace_score
from .study import OBJECTIVES, StudyResult, StudySettings, TrialRecord, evaluate, run_study
from .torque import Motion, Payload, PeakTorque, cone_motion, motion_inputs, peak_torque
from .validation import (
    find_orthogonal_optimum,
    home_dexterity,
    home_dexterity_right_angle,
    isotropic_alpha2,
    orthogonal_design,
    orthogonal_reference_dexterity,
    reference_dexterity,
    reference_orientation,
)

__all__ = [
    "OBJECTIVES",
    "ClusterError",
    "ConeDexterity",
    "DesignSpace",
    "Envelope",
    "Motion",
    "Payload",
    "PeakTorque",
    "ResultFiles",
    "StudyResult",
    "StudySettings",
    "TrialRecord",
    "Variable",
    "WorkspaceScore",
    "best_trials",
    "cone_dexterity",
    "cone_motion",
    "envelope",
    "evaluate",
    "find_orthogonal_optimum",
    "global_conditioning_index",
    "home_clearance",
    "home_dexterity",
    "home_dexterity_right_angle",
    "isotropic_alpha2",
    "load_study_result",
    "motion_inputs",
    "orthogonal_design",
    "orthogonal_reference_dexterity",
    "pareto_figure",
    "peak_torque",
    "reference_dexterity",
    "reference_orientation",
    "run_study",
    "safe_workspace_score",
    "write_results",
]
