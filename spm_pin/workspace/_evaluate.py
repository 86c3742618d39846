"""The evaluation of workspace-map points: kinematics, singularities, dexterity and
self-collision through a collision checker built once per thread and design.

:func:`chunk_task` is the module-level (picklable) function an executor runs on each
chunk of points, in this process, in threads or in worker processes.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from .._checks import FloatArray
from ..design import SPMDesign
from ..kinematics import forward_kinematics, jacobian, select_assembly
from .gaps import tilt_torsion
from .settings import WorkspaceSettings

__all__ = ["chunk_task"]

_LOCAL = threading.local()
#: Links placed by theta alone (no loop closure needed).
_THETA_LINKS = frozenset({"base", "proximal_1", "proximal_2", "proximal_3"})


def _checker(design: SPMDesign) -> Any:
    """This thread's robot checker for ``design`` (built once per thread and design)."""
    cache: dict[SPMDesign, Any] | None = getattr(_LOCAL, "checkers", None)
    if cache is None:
        cache = {}
        _LOCAL.checkers = cache
    if design not in cache:
        from ..collision import CollisionChecker
        from ..model.robot import build_robot

        cache[design] = CollisionChecker(build_robot(design))
    return cache[design]


def _evaluate(
    design: SPMDesign, theta: FloatArray, settings: WorkspaceSettings
) -> dict[str, npt.NDArray[Any]]:
    """Every field but the gaps at inputs theta (n, 3): the work of one chunk."""
    from ..collision import LINK_PAIRS

    checker = _checker(design)
    robot = checker.robot
    n = theta.shape[0]
    fk = forward_kinematics(theta, design)
    reachable = np.asarray(fk.reachable, dtype=bool)
    jac = jacobian(theta, design, R=np.where(reachable[:, None, None], fk.R, np.eye(3)))
    out: dict[str, npt.NDArray[Any]] = {
        "reachable": reachable,
        "type_i": jac.type_i & reachable,
        "type_ii": jac.type_ii & reachable,
        "singularity_margin": np.where(reachable, jac.singularity_margin, np.nan),
        "det_a": np.where(reachable, jac.det_a, np.nan),
        "dexterity": np.where(reachable, jac.dexterity, np.nan),
        "dexterity_ga": np.where(reachable, jac.dexterity_ga, np.nan),
    }
    tilt, azimuth, torsion = tilt_torsion(np.where(reachable[:, None, None], fk.R, np.nan))
    out["tilt_deg"] = np.degrees(tilt)
    out["azimuth_deg"] = np.degrees(azimuth)
    out["torsion_deg"] = np.degrees(torsion)

    pair_mask = np.zeros(n, dtype=np.int64)
    collision = np.zeros(n, dtype=bool)
    unsafe_margin = np.zeros(n, dtype=bool)
    clearance = np.full(n, np.nan)
    bit = {pair: 1 << k for k, pair in enumerate(LINK_PAIRS)}
    plan0 = checker._plan(0.0)
    plan_m = checker._plan(settings.margin)
    # The library's rule (spm.select_assembly): without a home-mode assembly the real
    # mode nearest to it is checked; with no real assembly, only the links theta places.
    placed = [p for p in LINK_PAIRS if p[0] in _THETA_LINKS and p[1] in _THETA_LINKS]
    plan_placed = checker._plan(0.0, pairs=placed)
    ladder = settings.ladder
    q = np.zeros((n, robot.model.nq))
    q[:, robot.actuated_q_idx] = theta
    R = fk.R.copy()
    assembled = reachable.copy()
    if not np.all(reachable):
        rest = np.nonzero(~reachable)[0]
        other = select_assembly(theta[rest], design)
        R[rest] = other.R
        assembled[rest] = other.exists
    if np.any(assembled):
        # q from the platform rotations just solved (checked against each leg).
        q[assembled] = robot._configuration_from_rotation(theta[assembled], R[assembled])
    for k in range(n):
        pairs = checker._check(q[k], plan0 if assembled[k] else plan_placed, False)
        mask = 0
        for pair in pairs:
            mask |= bit[pair]
        pair_mask[k] = mask
        collision[k] = bool(pairs)
        if not reachable[k]:
            continue
        if collision[k]:
            unsafe_margin[k] = True
            clearance[k] = 0.0
            continue
        if settings.margin > 0.0:
            unsafe_margin[k] = bool(checker._check(q[k], plan_m, True))
        if settings.clearance:
            clearance[k] = _ladder_level(checker, q[k], ladder)
    out["collision"] = collision
    out["pair_mask"] = pair_mask
    out["clearance"] = clearance
    dexterity_ok = np.where(reachable, out["dexterity"], -1.0) >= settings.min_dexterity
    out["safe"] = reachable & dexterity_ok & ~unsafe_margin
    return out


def _ladder_level(checker: Any, q: FloatArray, ladder: Sequence[float]) -> float:
    """Largest ladder margin at which nothing collides (configuration-dependent parts
    only); free at ladder[0] is known. Bisection over the levels."""
    low, high = 0, len(ladder)  # free at ladder[low]; collides at ladder[high] (or beyond)
    while high - low > 1:
        middle = (low + high) // 2
        if checker._check(q, checker._plan(ladder[middle], False), True):
            high = middle
        else:
            low = middle
    return float(ladder[low])


def chunk_task(
    design: SPMDesign, theta: FloatArray, settings: WorkspaceSettings
) -> dict[str, npt.NDArray[Any]]:
    """Module-level (picklable) entry point of one chunk."""
    return _evaluate(design, theta, settings)
