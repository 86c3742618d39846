"""Design optimization of spherical parallel manipulators.

Not imported by ``import spm_pin``: ``import spm_pin.optimize``. This first part
scores a design quickly and exactly: :func:`safe_workspace_score` gives the figures of
the safe orientation workspace that ``spm workspace`` reports (see
:mod:`spm_pin.optimize.scoring`), with the base installation alone.
"""

from .scoring import WorkspaceScore, safe_workspace_score

__all__ = ["WorkspaceScore", "safe_workspace_score"]
