"""Closing the loops: the Newton projection, path following, and the failure reports.

Plain functions of a :class:`~spm_pin.closure._core.LoopCore`:

* :func:`newton`, the hot loop of the library: damped Newton steps on the passive
  joints with the actuated values fixed (see the :mod:`spm_pin.closure` docstring);
* :func:`first_iterate`, its start (with the first-order predictor after a result);
* :func:`follow_path` and :func:`continue_path`, continuation along a straight path
  of actuated values, steps halved near singularities;
* :func:`convergence_error` and :func:`path_failure`, the ConvergenceErrors that say
  why a solve failed.

Inputs are checked by the caller (:class:`~spm_pin.closure.ClosedLoop`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from ..errors import ConvergenceError, InputError
from ..kinematics._common import require_angles
from ._constants import (
    CLOSED_TOL,
    CONTINUATION_STEP,
    CORRECTOR_RATIO,
    DEFAULT_DAMPING,
    DEFAULT_MAX_HALVINGS,
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_TOL,
    FLOAT64,
    FOLLOW_MAX_ITERATIONS,
    MAX_REJECTIONS,
    FloatArray,
    orientation,
    rank,
)
from ._core import LoopCore
from .results import LocalFailure, PathResult, ProjectionResult


def first_iterate(core: LoopCore, start: Any, theta: FloatArray) -> tuple[FloatArray, bool]:
    """The initial iterate (a fresh array) and whether a predictor was applied."""
    if start is None:
        q = core.neutral()
        q[core.actuated_q_idx] = theta
        return q, False
    if isinstance(start, ProjectionResult):
        given = start.q
        if type(given) is np.ndarray and given.dtype is FLOAT64 and given.shape == core.q_shape:
            q = given.copy()
        else:
            q = core.check_q(given, "start.q")
        q[core.actuated_q_idx] = theta
        G = start._map if start._map is not None else start._predictor
        if G is None or G.shape != core.g_shape:
            return q, False
        if core.euclidean:
            q[core.passive_q_idx] += G @ (theta - start.actuated)
            return q, True
        return core.step(q, G @ (start.actuated - theta)), True
    q = core.check_q(start, "start")
    q[core.actuated_q_idx] = theta
    return q, False


def newton(
    core: LoopCore,
    theta: FloatArray,
    q: FloatArray,
    tol: float,
    max_iterations: int,
    damping: float,
) -> ProjectionResult:
    """The local damped Newton solve from q (modified); raises LocalFailure.

    The hot loop of the library: one kinematics call, one calc per closure and,
    when another step is needed, one Jacobian call and one small factorisation.
    """
    model, data, ebuf, e_old = core.model, core.data, core.ebuf, core.e_old
    kinematics, jacobian = pin.computeJointJacobians, pin.getConstraintsJacobian
    constraints, datas = core.constraint_models, core.constraint_datas
    calcs, copies = core.calcs, core.copies
    aug, aug_top, diag, rhs = core.aug, core.aug_top, core.aug_diag, core.rhs
    cod, select_p, passive = core.cod, core.select_p, core.passive_q_idx
    euclidean, n_passive = core.euclidean, core.g_shape[0]
    tol2 = tol * tol
    iterations = rejections = 0
    r2_old = math.inf
    lam_scale = damping
    q_old = q
    J = None
    while True:
        kinematics(model, data, q)
        for calc, constraint_data in calcs:
            calc(model, data, constraint_data)
        for rows, error in copies:
            ebuf[rows] = error
        r2 = float(ebuf.dot(ebuf))
        if r2 <= tol2:
            break
        if r2 < r2_old:
            # accepted: linearise at the new iterate
            if iterations >= max_iterations or not n_passive:
                reason = "max_iterations" if n_passive else "stalled"
                raise LocalFailure(reason, q, math.sqrt(r2), iterations)
            J = jacobian(model, data, constraints, datas)
            np.dot(J, select_p, out=aug_top)
            e_old[:] = ebuf
            q_old = q.copy()
            r2_old = r2
            rejections = 0
            lam_scale = damping
        else:
            if r2_old == math.inf:
                raise_non_finite(theta, q)
            # rejected: retry from the last accepted iterate with more damping
            rejections += 1
            if rejections > MAX_REJECTIONS:
                raise LocalFailure("stalled", q_old, math.sqrt(r2_old), iterations)
            if iterations >= max_iterations:
                raise LocalFailure("max_iterations", q_old, math.sqrt(r2_old), iterations)
            lam_scale = max(lam_scale, 1e-6) * 10.0
            ebuf[:] = e_old
            q = q_old.copy()
        diag[:] = math.sqrt(lam_scale * r2_old)
        cod.compute(aug)
        if euclidean:
            q[passive] -= cod.solve(rhs)
        else:
            q = core.step(q, cod.solve(rhs))
        iterations += 1
    return closed_result(core, theta, q, iterations, r2, J)


def closed_result(
    core: LoopCore, theta: FloatArray, q: FloatArray, iterations: int, r2: float, J: Any
) -> ProjectionResult:
    """The result at q (the configuration last evaluated).

    The predictor map comes from the last Newton step's factorisation (J from that
    step, damping about ||e||^2 there: exact to first order in the last step),
    or, after no step, from the exact analysis.
    """
    result = ProjectionResult(core, q, theta.copy(), iterations, math.sqrt(r2), None)
    n_p, n_a = core.g_shape
    if J is None or not n_a:
        result._rank, result._map = core.passive_map(core.jacobian())
        result._predictor = result._map
    else:
        np.dot(J, core.neg_select_a, out=core.rhs_a_top)
        result._predictor = core.cod.solve(core.rhs_a).reshape(n_p, n_a)
    return result


def raise_non_finite(theta: FloatArray, q: FloatArray) -> None:
    """Raise for a residual that is not finite: bad input, or a model that yields NaN."""
    if not np.all(np.isfinite(theta)):
        raise InputError(
            f"actuated must be finite, got {theta.tolist()}", argument="actuated", value=theta
        )
    if not np.all(np.isfinite(q)):
        raise InputError("start must be finite, got NaN or inf", argument="start", value=q)
    raise ConvergenceError(
        "the constraint residual is not finite at a finite configuration "
        "(the model or its constraints produce NaN)",
        data={"q": q, "actuated": theta, "reason": "non_finite"},
    )


def convergence_error(
    core: LoopCore, theta: FloatArray, local: LocalFailure, continued: str | None = None
) -> ConvergenceError:
    """A ConvergenceError that says why (with the diagnosis at the best iterate)."""
    q = local.q
    J = core.jacobian_at(q)
    residual = math.sqrt(float(core.ebuf.dot(core.ebuf)))
    Jp = J[:, core.passive_v_idx]
    rank_p = rank(Jp)
    gradient = float(np.linalg.norm(Jp.T @ core.ebuf))
    stationary = gradient <= 1e-6 * float(np.linalg.norm(Jp)) * residual
    singular = f"the passive Jacobian has rank {rank_p} < {core.nominal_rank} there"
    if stationary:
        diagnosis = (
            "the residual reached a local minimum of ||e|| above zero: the input is "
            "most likely unreachable (no closed configuration)"
        )
        if rank_p < core.nominal_rank:
            diagnosis += f"; {singular} (the closest configuration is singular)"
    elif rank_p < core.nominal_rank:
        diagnosis = f"{singular} (a singular configuration)"
    else:
        diagnosis = "more iterations or a start closer to the solution may help"
    if local.reason == "path":
        what = "path following from the start stopped"
    else:
        verb = "stalled" if local.reason == "stalled" else "ran out of iterations"
        what = f"the Newton projection {verb} after {local.iterations} iterations"
    message = (
        f"no closed configuration at actuated = {theta.tolist()} "
        f"({', '.join(core.actuated_joints)}): {what} at residual {residual:.3g}; "
        f"{diagnosis}"
    )
    if continued is not None:
        message += f" [path following: {continued}]"
    return ConvergenceError(
        message,
        data={
            "actuated": theta.copy(),
            "q": q.copy(),
            "residual": residual,
            "iterations": local.iterations,
            "rank": rank_p,
            "nominal_rank": core.nominal_rank,
            "stationary": stationary,
            "reason": local.reason,
            "continuation": continued,
        },
    )


def project_near(core: LoopCore, actuated: Any, start: ProjectionResult) -> ProjectionResult:
    """``ClosedLoop.project(actuated, start, continuation="never")`` with the default
    tolerance, iterations and damping: Newton only, a ConvergenceError on failure."""
    theta = core.check_actuated(actuated)
    local: LocalFailure | None = None
    q, _ = first_iterate(core, start, theta)
    try:
        return newton(core, theta, q, DEFAULT_TOL, DEFAULT_MAX_ITERATIONS, DEFAULT_DAMPING)
    except LocalFailure as failure:
        local = failure
    raise convergence_error(core, theta, local)


def continue_path(
    core: LoopCore,
    theta: FloatArray,
    start: Any,
    tol: float,
    max_iterations: int,
    damping: float,
    local: LocalFailure | None,
) -> ProjectionResult:
    """Path following from the start's actuated values to theta (straight line)."""
    if start is None:
        begin = core.neutral()
    elif isinstance(start, ProjectionResult):
        begin = core.check_q(start.q, "start.q")
    else:
        begin = core.check_q(start, "start")
    begin_theta = begin[core.actuated_q_idx].copy()
    span = float(np.max(np.abs(theta - begin_theta), initial=0.0))
    count = max(2, math.ceil(span / CONTINUATION_STEP))
    path = begin_theta + np.linspace(0.0, 1.0, count + 1)[:, None] * (theta - begin_theta)
    path[-1] = theta
    try:
        first = newton(core, begin_theta, begin, tol, max_iterations, damping)
    except LocalFailure as failure:
        why = (
            f"the start does not close at its own actuated values {begin_theta.tolist()} "
            f"({failure.reason} at residual {failure.residual:.3g})"
        )
        raise convergence_error(core, theta, local or failure, why) from None
    try:
        followed = follow_path(core, path, first, tol, DEFAULT_MAX_HALVINGS, damping)
    except ConvergenceError as exc:
        data = exc.data
        best = LocalFailure("path", data["q"], data["residual"], 0)
        raise convergence_error(core, theta, local or best, str(exc)) from None
    final = followed.results[-1]
    final.iterations = followed.total_iterations + (local.iterations if local else 0)
    final.continuation = True
    return final


def check_path(core: LoopCore, path: Any) -> FloatArray:
    """A path of actuated values as a float array (N, n_actuated), checked."""
    n = core.n_actuated
    try:
        points = np.array(path, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(
            f"path must be numbers of shape (N, {n}) [rad or m], got {path!r}",
            argument="path",
            value=path,
        ) from exc
    if points.ndim != 2 or points.shape[1] != n or points.shape[0] < 1:
        raise InputError(
            f"path must have shape (N, {n}) with N >= 1 (values of "
            f"{list(core.actuated_joints)}), got shape {points.shape}",
            argument="path",
            value=path,
        )
    require_angles(points, "path", path)
    return points


def follow_path(
    core: LoopCore,
    points: FloatArray,
    first: ProjectionResult,
    tol: float,
    max_halvings: int,
    damping: float,
) -> PathResult:
    """Continuation from ``first`` (closed at ``points[0]``) through the other points."""
    results = [first]
    iterations = [first.iterations]
    substeps = [1]
    previous = first
    # Orientation of J_p on its range, tracked to catch a singularity crossed between
    # two path points (the sign of det(Q^T J_p) flips; only with no idle motions).
    tracking = core.idle_dof == 0 and core.passive_v_idx.shape[0] > 0
    basis, sign = np.zeros((0, 0)), 0.0
    if tracking:
        basis, sign = orientation(core.jacobian_at(first.q) @ core.select_p)
    for index in range(1, points.shape[0]):
        target = points[index]
        base = previous.actuated
        done, h, halvings, used, spent = 0.0, 1.0, 0, 0, 0
        while done < 1.0:
            h = min(h, 1.0 - done)
            final = done + h >= 1.0
            theta = target.copy() if final else base + (done + h) * (target - base)
            q, predicted = first_iterate(core, previous, theta)
            q_predicted = q.copy()
            try:
                result = newton(core, theta, q, tol, FOLLOW_MAX_ITERATIONS, damping)
                spent += result.iterations
                if tracking:
                    singular = result.singular  # the exact analysis leaves J_p in jp
                    passive = core.jp
                    if singular or np.sign(np.linalg.det(basis.T @ passive)) != sign:
                        raise LocalFailure(
                            "singularity", result.q, result.residual, result.iterations
                        )
                    new_basis, new_sign = orientation(passive)
                if predicted and not continuous(core, previous, q_predicted, theta, result):
                    raise LocalFailure("jumped", result.q, result.residual, result.iterations)
            except LocalFailure as failure:
                if failure.reason in ("max_iterations", "stalled"):
                    spent += failure.iterations
                halvings += 1
                if halvings > max_halvings:
                    raise path_failure(
                        index, previous, target, failure, results, max_halvings
                    ) from None
                h *= 0.5
                continue
            if tracking:
                basis, sign = new_basis, new_sign
            previous = result
            used += 1
            done = 1.0 if final else done + h
            h *= 2.0
        results.append(previous)
        iterations.append(spent)
        substeps.append(used)
    return PathResult(
        q=np.array([r.q for r in results]),
        actuated=np.array([r.actuated for r in results]),
        iterations=np.array(iterations, dtype=np.int64),
        residual=np.array([r.residual for r in results]),
        rank=np.array([r.rank for r in results], dtype=np.int64),
        substeps=np.array(substeps, dtype=np.int64),
        results=results,
    )


def path_failure(
    index: int,
    previous: ProjectionResult,
    target: FloatArray,
    failure: LocalFailure,
    results: list[ProjectionResult],
    max_halvings: int,
) -> ConvergenceError:
    """The ConvergenceError of a path point that no halved step reaches."""
    if failure.reason == "singularity":
        why = (
            "a singularity lies on the path: the passive Jacobian loses rank or its "
            "orientation flips (the robot would change assembly mode)"
        )
    elif failure.reason == "jumped":
        why = "the corrector keeps landing far from the predicted branch"
    else:
        why = (
            f"the Newton corrector {failure.reason} at residual {failure.residual:.3g} "
            "(the workspace boundary or a singularity lies on the path)"
        )
    return ConvergenceError(
        f"path following stopped at point {index}: from actuated = "
        f"{previous.actuated.tolist()}, no step down to 1/2^{max_halvings} of the "
        f"way to {target.tolist()} succeeds; {why}",
        data={
            "index": index,
            "actuated": previous.actuated.copy(),
            "target": target.copy(),
            "q": previous.q.copy(),
            "residual": previous.residual,
            "reason": failure.reason,
            "results": results,
        },
    )


def continuous(
    core: LoopCore,
    previous: ProjectionResult,
    q_predicted: FloatArray,
    theta: FloatArray,
    result: ProjectionResult,
) -> bool:
    """Whether the corrector stayed close to the predictor (no branch jump)."""
    G = previous._predictor if previous._predictor is not None else previous.velocity_map
    change = G @ (theta - previous.actuated)
    corrector = pin.difference(core.model, q_predicted, result.q)[core.passive_v_idx]
    size = max(
        float(np.max(np.abs(change), initial=0.0)),
        float(np.max(np.abs(theta - previous.actuated), initial=0.0)),
    )
    moved = float(np.max(np.abs(corrector), initial=0.0))
    return moved <= CORRECTOR_RATIO * size + CLOSED_TOL
