r"""Fast scoring of a design: its safe orientation workspace, as ``spm workspace``
reports it, in a fraction of the time of a full map.

:func:`safe_workspace_score` samples the gap plane (D12, D23) on the grid of
:func:`~spm_pin.workspace.workspace_map` and returns the figures of the safe set that
:meth:`WorkspaceMap.summary <spm_pin.workspace.WorkspaceMap.summary>` reports: the
safe fraction of the gap plane, the largest safe tilt, and the safe tilt in every
direction (with free, endless yaw: the safe set of a coaxial design is a region of the
gap plane times a free turn about the axis). They are the same numbers, point by point,
because every point is decided by the same computations; the score only leaves out what
the figures do not read:

* the kinematic checks (home-mode assembly, dexterity, tilt and torsion) run on the
  whole grid, vectorised, in the same chunks and with the same calls as a map, so
  their values are the map's to the bit;
* the self-collision check runs only where those checks pass (about half of the
  prototype's gap plane), and asks only *whether* some link pair comes nearer than
  the margin, not *which* pairs do nor how near they come (a map asks both: every
  colliding pair and a clearance ladder per point);
* that check is set up for a new design without the full checker's probes and
  certified tables (see :mod:`spm_pin.optimize._margin_check`), which only settle
  early what its culling BVHs decide; it stops at the first colliding link pair.

A point is safe exactly where the map calls it safe: home-mode assembly, dexterity
1/kappa_2(J) >= ``min_dexterity`` and no two links nearer than ``margin``.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np
import numpy.typing as npt

from .._checks import BoolArray, FloatArray
from ..design import SPMDesign
from ..kinematics import forward_kinematics, jacobian
from ..workspace.compute import DEFAULT_CHUNK, _grid_points
from ..workspace.gaps import coaxial, gap_inputs, tilt_torsion
from ..workspace.result import safe_tilt_figures
from ..workspace.settings import check_number
from ._margin_check import margin_check_of

__all__ = ["WorkspaceScore", "safe_workspace_score"]

#: Defaults of a score: those of ``spm workspace``.
DEFAULT_STEP_DEG = 2.0
DEFAULT_MARGIN_M = 0.0
DEFAULT_MIN_DEXTERITY = 0.2


@dataclasses.dataclass(frozen=True)
class WorkspaceScore:
    """The safe orientation workspace of a design on a grid of the gap plane.

    Attributes:
        design: The SPM.
        step_deg: Grid step [deg].
        margin: Safety margin [m]: links nearer than this count as colliding.
        min_dexterity: Smallest dexterity 1/kappa_2(J) of a safe point.
        points: Grid points in the gap triangle (all three gaps in [0, 360] deg).
        safe_fraction: Share of the points that are safe.
        max_safe_tilt_deg: Largest tilt of the platform over the safe points [deg]
            (None if no point is safe).
        safe_tilt_every_direction_deg: Tilt reachable safely in every direction
            [deg]: over 5-degree sectors of azimuth - torsion, the smallest of the
            largest safe tilts (None if a sector has no safe point).
        d12_deg, d23_deg: Gaps of the points [deg], in the order of a map's points.
        reachable: Per point, a home-mode assembly exists.
        dexterity: Per point, 1/kappa_2(J) (NaN where unreachable).
        safe: Per point, safe.
        tilt_deg, azimuth_deg, torsion_deg: Tilt-and-torsion angles of the platform
            per point [deg] (NaN where unreachable).
        collision_checks: Points that needed a collision check.
        seconds: Time the score took [s].
    """

    design: SPMDesign
    step_deg: float
    margin: float
    min_dexterity: float
    points: int
    safe_fraction: float
    max_safe_tilt_deg: float | None
    safe_tilt_every_direction_deg: float | None
    d12_deg: FloatArray
    d23_deg: FloatArray
    reachable: BoolArray
    dexterity: FloatArray
    safe: BoolArray
    tilt_deg: FloatArray
    azimuth_deg: FloatArray
    torsion_deg: FloatArray
    collision_checks: int
    seconds: float

    def summary(self) -> dict[str, Any]:
        """The figures as plain data, under the keys of
        :meth:`WorkspaceMap.summary <spm_pin.workspace.WorkspaceMap.summary>`."""
        n = max(self.points, 1)
        return {
            "points": self.points,
            "reachable_fraction": int(np.count_nonzero(self.reachable)) / n,
            "safe_fraction": self.safe_fraction,
            "max_safe_tilt_deg": self.max_safe_tilt_deg,
            "safe_tilt_every_direction_deg": self.safe_tilt_every_direction_deg,
            "margin_m": self.margin,
            "min_dexterity": self.min_dexterity,
        }


def safe_workspace_score(
    design: SPMDesign | str | None = None,
    *,
    step_deg: float = DEFAULT_STEP_DEG,
    margin: float = DEFAULT_MARGIN_M,
    min_dexterity: float = DEFAULT_MIN_DEXTERITY,
) -> WorkspaceScore:
    """Score the safe orientation workspace of a coaxial design (see the module).

    The figures equal those of ``workspace_map(design, step_deg=step_deg,
    settings=WorkspaceSettings(margin=margin, min_dexterity=min_dexterity))``
    (``spm workspace --step STEP --margin MM --min-dexterity X``), computed many times
    faster: about 0.3 s for the prototype at 2 degrees on one core, its collision
    model included.

    Args:
        design: A coaxial SPM (default: the prototype).
        step_deg: Grid step over the gaps [deg], in [0.05, 60].
        margin: Safety margin [m], in [0, 0.1].
        min_dexterity: Smallest dexterity of a safe point, in [0, 1].

    Returns:
        The score.

    Raises:
        InputError: a non-coaxial design, or a number out of its range.
    """
    start = time.perf_counter()
    design = coaxial(design)
    step = check_number("step_deg", step_deg, 0.05, 60.0)
    margin = check_number("margin", margin, 0.0, 0.1) + 0.0
    min_dexterity = check_number("min_dexterity", min_dexterity, 0.0, 1.0)
    _, _, d12, d23, _ = _grid_points(step, 0.0, 360.0)
    theta = gap_inputs(d12, d23, design)
    n = theta.shape[0]
    reachable = np.zeros(n, dtype=bool)
    dexterity = np.full(n, np.nan)
    angles = np.full((n, 3), np.nan)
    R = np.empty((n, 3, 3))
    for s in range(0, n, DEFAULT_CHUNK):
        # The chunks of a map (spm_pin.workspace._evaluate): the same values.
        part = slice(s, s + DEFAULT_CHUNK)
        fk = forward_kinematics(theta[part], design)
        ok = np.asarray(fk.reachable, dtype=bool)
        reachable[part] = ok
        if np.any(ok):  # the dexterity of the reachable points (a map's values)
            jac = jacobian(theta[part][ok], design, R=fk.R[ok])
            dexterity[s + np.flatnonzero(ok)] = jac.dexterity
        tilt, azimuth, torsion = tilt_torsion(np.where(ok[:, None, None], fk.R, np.nan))
        angles[part] = np.degrees(np.stack([tilt, azimuth, torsion], axis=-1))
        R[part] = fk.R
    candidates = np.flatnonzero(reachable & (np.where(reachable, dexterity, -1.0) >= min_dexterity))
    safe = np.zeros(n, dtype=bool)
    if candidates.size:
        check = margin_check_of(design)
        robot = check.robot
        q = robot._configuration_from_rotation(theta[candidates], R[candidates])
        free = _free(check, q, margin)
        safe[candidates[free]] = True
    tilt_deg, azimuth_deg, torsion_deg = angles.T.copy()
    largest, every = safe_tilt_figures(safe, tilt_deg, azimuth_deg - torsion_deg)
    return WorkspaceScore(
        design=design,
        step_deg=step,
        margin=margin,
        min_dexterity=min_dexterity,
        points=n,
        safe_fraction=int(np.count_nonzero(safe)) / max(n, 1),
        max_safe_tilt_deg=largest,
        safe_tilt_every_direction_deg=every,
        d12_deg=np.asarray(d12, dtype=float),
        d23_deg=np.asarray(d23, dtype=float),
        reachable=reachable,
        dexterity=dexterity,
        safe=safe,
        tilt_deg=tilt_deg,
        azimuth_deg=azimuth_deg,
        torsion_deg=torsion_deg,
        collision_checks=int(candidates.size),
        seconds=time.perf_counter() - start,
    )


def _free(check: Any, q: FloatArray, margin: float) -> npt.NDArray[np.bool_]:
    """Per configuration, no collision at 0 and none at ``margin`` (a map's rule)."""
    free = np.ones(q.shape[0], dtype=bool)
    for k, item in enumerate(q):
        if check.collides(item, 0.0) or (margin > 0.0 and check.collides(item, margin)):
            free[k] = False
    return free
