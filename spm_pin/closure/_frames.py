"""Closed-loop velocities, frame Jacobians and frame targets.

Plain functions of a :class:`~spm_pin.closure._core.LoopCore`: the velocity map
G = -J_p^+ J_a at a closed configuration (:func:`velocity_map_of`), the closed-loop
Jacobian J_fa + J_fp G of a frame (:func:`closed_frame_jacobian`), the frame and
target checks, and the Newton iteration on the actuated values that brings a frame
to a target (:func:`reach_target`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from ..errors import ConvergenceError, InputError, SingularityError
from ..kinematics._common import float_array, require_bounded
from ._constants import CLOSED_TOL, MAX_REJECTIONS, TARGET_LIMIT, FloatArray
from ._core import LoopCore
from ._solve import project_near
from .results import FrameTargetResult, ProjectionResult


# ------------------------------------------------------------------ velocities
def closed(core: LoopCore, q: Any) -> tuple[FloatArray, FloatArray]:
    """(q checked, J at q); raises when q does not close the loops."""
    array = core.check_q(q)
    J = core.jacobian_at(array)
    residual = math.sqrt(float(core.ebuf.dot(core.ebuf)))
    if residual > CLOSED_TOL:
        raise InputError(
            f"q does not close the loops: residual {residual:.3g} > {CLOSED_TOL:g}; "
            "project it first (ClosedLoop.project)",
            argument="q",
            value=q,
        )
    return array, J


def velocity_map_of(core: LoopCore, J: FloatArray) -> FloatArray:
    """G = -J_p^+ J_a from J (m, nv); raises SingularityError where J_p has lost rank."""
    rank, G = core.passive_map(J)
    if rank < core.nominal_rank:
        raise SingularityError(
            f"the passive joints are not determined by the actuated ones here: the "
            f"passive constraint Jacobian has rank {rank} < {core.nominal_rank} (a "
            "parallel, type II singularity)",
            kind="type II",
            value=rank,
        )
    return G


def closed_frame_jacobian(
    core: LoopCore, frame_id: int, reference: pin.ReferenceFrame, G: FloatArray
) -> FloatArray:
    """J_fa + J_fp G at the configuration last evaluated."""
    Jf = pin.getFrameJacobian(core.model, core.data, frame_id, reference)
    result: FloatArray = Jf @ core.select_a + (Jf @ core.select_p) @ G
    return result


# ---------------------------------------------------------------------- checks
def check_frame(model: pin.Model, frame: Any) -> int:
    """The id of a frame given by name or id, checked."""
    if isinstance(frame, str):
        if model.existFrame(frame):
            return int(model.getFrameId(frame))
        names = [f.name for f in model.frames]
        shown = ", ".join(names[:40]) + (", ..." if len(names) > 40 else "")
        raise InputError(
            f"frame {frame!r} is not a frame of model {model.name!r}; frames: {shown}",
            argument="frame",
            value=frame,
        )
    if isinstance(frame, (int, np.integer)) and not isinstance(frame, bool):
        if 0 <= int(frame) < model.nframes:
            return int(frame)
        raise InputError(
            f"frame id must lie in [0, {model.nframes - 1}], got {frame}",
            argument="frame",
            value=frame,
        )
    raise InputError(
        f"frame must be a frame name or id, got {type(frame).__name__}",
        argument="frame",
        value=frame,
    )


def check_reference_frame(reference_frame: Any) -> pin.ReferenceFrame:
    """``pin.ReferenceFrame.LOCAL``, ``WORLD`` or ``LOCAL_WORLD_ALIGNED``, checked."""
    allowed = (
        pin.ReferenceFrame.LOCAL,
        pin.ReferenceFrame.WORLD,
        pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
    )
    if reference_frame not in allowed:
        raise InputError(
            f"reference_frame must be pin.ReferenceFrame.LOCAL, WORLD or "
            f"LOCAL_WORLD_ALIGNED, got {reference_frame!r}",
            argument="reference_frame",
            value=reference_frame,
        )
    return reference_frame


def check_target(target: Any) -> tuple[str, Any]:
    """('placement', SE3) | ('orientation', R (3, 3)) | ('position', p (3,))."""
    if isinstance(target, pin.SE3):
        return "placement", pin.SE3(target)
    array = float_array(
        target,
        "target",
        f"target must be a pin.SE3, a 4x4 or 3x3 matrix or a point (3,), got {target!r}",
    )
    require_bounded(array, "target", target, TARGET_LIMIT, "[m] (entries of the target)")
    if array.shape == (3,):
        return "position", array
    if array.shape == (4, 4):
        if not np.allclose(array[3], [0.0, 0.0, 0.0, 1.0], atol=1e-12):
            raise InputError(
                f"a 4x4 target must be homogeneous (last row 0 0 0 1), got {array[3].tolist()}",
                argument="target",
                value=target,
            )
        check_rotation(array[:3, :3])
        return "placement", pin.SE3(array)
    if array.shape == (3, 3):
        check_rotation(array)
        return "orientation", array
    raise InputError(
        f"target must be a pin.SE3, a (4, 4) or (3, 3) matrix or a point (3,), got shape "
        f"{array.shape}",
        argument="target",
        value=target,
    )


def check_rotation(R: FloatArray) -> None:
    """Raise InputError unless R is orthonormal with det +1 (to 1e-9)."""
    error = float(np.abs(R.T @ R - np.eye(3)).max())
    if error > 1e-9 or np.linalg.det(R) <= 0.0:
        raise InputError(
            f"target rotation must be orthonormal with det +1 (to 1e-9), got |R^T R - I| = "
            f"{error:.3g}, det = {np.linalg.det(R):.6g}",
            argument="target",
            value=R,
        )


# ---------------------------------------------------------------- frame target
def reach_target(
    core: LoopCore,
    frame_id: int,
    kind: str,
    goal: Any,
    current: ProjectionResult,
    tol: float,
    max_iterations: int,
    damping: float,
    frame: Any,
) -> FrameTargetResult:
    """Newton on the actuated values from ``current`` until the task error <= tol.

    Every iterate is a closed configuration (:func:`~._solve.project_near`); steps are
    damped least squares, halved when they do not reduce the error or do not close.
    """
    error, jac = task(core, frame_id, kind, goal, current)
    residual = float(np.linalg.norm(error))
    iterations = 0
    while residual > tol:
        if iterations >= max_iterations:
            raise task_failure(current, residual, iterations, "max_iterations", frame)
        n = core.n_actuated
        stacked = np.vstack([jac, math.sqrt(damping) * residual * np.eye(n)])
        rhs = np.concatenate([error, np.zeros(n)])
        step = -np.linalg.lstsq(stacked, rhs, rcond=None)[0]
        iterations += 1
        scale = 1.0
        for _ in range(MAX_REJECTIONS + 4):
            theta = current.actuated + scale * step
            try:
                trial = project_near(core, theta, current)
            except ConvergenceError:
                scale *= 0.5
                continue
            trial_error, trial_jac = task(core, frame_id, kind, goal, trial)
            trial_residual = float(np.linalg.norm(trial_error))
            if trial_residual < residual:
                current, error, jac, residual = trial, trial_error, trial_jac, trial_residual
                break
            scale *= 0.5
        else:
            raise task_failure(current, residual, iterations, "stalled", frame)
    return FrameTargetResult(
        actuated=current.actuated.copy(),
        q=current.q.copy(),
        iterations=iterations,
        residual=residual,
        kind=kind,
        projection=current,
    )


def task(
    core: LoopCore, frame_id: int, kind: str, goal: Any, result: ProjectionResult
) -> tuple[FloatArray, FloatArray]:
    """Task error and its Jacobian wrt the actuated values at a projection result.

    Leaves the workspace at ``result.q``.
    """
    G = result.velocity_map
    core.evaluate(result.q)
    placement = pin.updateFramePlacement(core.model, core.data, frame_id)
    if kind == "position":
        J = closed_frame_jacobian(core, frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED, G)
        error: FloatArray = np.array(placement.translation) - goal
        return error, J[:3]
    J = closed_frame_jacobian(core, frame_id, pin.ReferenceFrame.LOCAL, G)
    if kind == "orientation":
        relative = goal.T @ placement.rotation
        error = np.array(pin.log3(relative))
        return error, pin.Jlog3(relative) @ J[3:]
    difference = goal.actInv(placement)
    error = np.array(pin.log6(difference).vector)
    return error, pin.Jlog6(difference) @ J


def task_failure(
    current: ProjectionResult, residual: float, iterations: int, reason: str, frame: Any
) -> ConvergenceError:
    """The ConvergenceError of a frame target that is not reached."""
    return ConvergenceError(
        f"frame {frame!r} does not reach the target: task error {residual:.3g} after "
        f"{iterations} iterations ({reason}) at actuated = {current.actuated.tolist()}; "
        "the target is most likely out of reach of this frame (or a singularity lies "
        "between it and the start)",
        data={
            "actuated": current.actuated.copy(),
            "q": current.q.copy(),
            "residual": residual,
            "iterations": iterations,
            "reason": reason,
        },
    )
