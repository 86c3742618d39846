"""The simulator's time step: its state, the kernel of bound closures, and its guards.

:class:`SimState` is the state a :class:`~spm_pin.dynamics.Simulator` advances:
(q, theta_dot), the velocity map and the counters. :class:`Kernel` binds everything a
step needs once, as closures over local names (Python call overhead dominates a step),
and advances that state in place. The guard functions refuse a step: a projection that
fails (:func:`lost`), a jump to another assembly mode (:func:`check_jump`), a motion too
fast for the time step (:func:`too_fast`), a parallel singularity (:func:`singular`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any, NoReturn

import eigenpy
import numpy as np
import pinocchio as pin

from ..closure import CLOSED_TOL
from ..errors import ConvergenceError, SingularityError
from ._constants import (
    CLOSURE_TOL,
    JUMP_RATIO,
    MAX_STEP_ANGLE,
    NEWTON_MAX_ITERATIONS,
    PROXIMAL_ACCURACY,
    PROXIMAL_MAX_ITERATIONS,
    PROXIMAL_MU,
    SINGULAR_NEAR,
    SINGULAR_RCOND,
    FloatArray,
    IntArray,
)
from .closed_loop import ClosedLoopDynamics

__all__ = ["Kernel", "SimState", "check_jump", "lost", "singular", "too_fast"]


@dataclasses.dataclass(slots=True)
class SimState:
    """The state of a simulation, advanced in place by :class:`Kernel`.

    Attributes:
        q: Closed joint configuration, (9,).
        theta_dot: Input speeds [rad/s], (3,).
        S: Velocity map at q, (9, 3): v = S theta_dot.
        time: Simulated time [s].
        steps: Steps taken since the last reset.
        work: Work done by the actuators since the last reset [J].
        loss: Energy dissipated by joint friction since the last reset [J].
        r2: Squared closure residual at q [rad^2].
        max_r2: Largest squared closure residual since the last reset [rad^2].
        rcond: Reciprocal condition number of J_p at the last check.
    """

    q: FloatArray
    theta_dot: FloatArray
    S: FloatArray
    time: float
    steps: int
    work: float
    loss: float
    r2: float
    max_r2: float
    rcond: float


# ------------------------------------------------------------------------ guards
def lost(
    state: SimState, q: FloatArray, error: ConvergenceError, lu: Any, actuated_idx: IntArray
) -> NoReturn:
    """The projection failed: near a parallel singularity (the motion would have to
    cross it) a SingularityError, otherwise the ConvergenceError with the time.

    ``lu`` is the LU of J_p of the failed attempt.
    """
    theta = np.degrees(q[actuated_idx]).round(4).tolist()
    # the last accepted state's conditioning, or that of the failed attempt
    state.rcond = min(state.rcond, float(lu.rcond()))
    if state.rcond < SINGULAR_NEAR:
        raise SingularityError(
            f"the motion reached a parallel (type II) singularity at t = "
            f"{state.time:.6g} s: the passive joints cannot follow the inputs through "
            f"it (rcond of the passive constraint Jacobian fell to {state.rcond:.2g}; "
            f"theta = {theta} deg); input angles cannot describe the motion beyond",
            kind="type II",
            value=q.copy(),
        ) from error
    raise ConvergenceError(
        f"the step from t = {state.time:.6g} s does not close the loops (theta = "
        f"{theta} deg): {error}",
        data={"time": state.time, **error.data},
    ) from error


def check_jump(
    state: SimState, q: FloatArray, predicted: FloatArray, projected: FloatArray, dt: float
) -> None:
    """A closed configuration further than JUMP_RATIO of the step's own motion from
    the integrator's prediction (its Taylor part, for euler) may be on another
    assembly mode: refuse it."""
    jump = float(np.abs(projected - predicted).max())
    motion = float(np.abs(predicted - q).max())
    if jump > JUMP_RATIO * motion + CLOSED_TOL:
        raise ConvergenceError(
            f"the step from t = {state.time:.6g} s is too large for the motion: closing "
            f"the loops moved the passive joints by {jump:.3g} rad, more than "
            f"{JUMP_RATIO:g} of the step's own motion ({motion:.3g} rad), so it may "
            f"have jumped to another assembly mode; use a smaller time step than "
            f"dt = {dt:g} s",
            data={"time": state.time, "q": q.copy(), "jump": jump, "motion": motion},
        )


def too_fast(state: SimState, q: FloatArray, predicted: FloatArray, dt: float) -> NoReturn:
    """Refuse a step that moves a joint by more than MAX_STEP_ANGLE."""
    motion = float(np.abs(predicted - q).max())
    raise ConvergenceError(
        f"the step from t = {state.time:.6g} s moves a joint by {motion:.3g} rad, more "
        f"than {MAX_STEP_ANGLE:g} rad: the motion is too fast for dt = {dt:g} s "
        "(the integration would not be accurate); use a smaller time step",
        data={"time": state.time, "q": q.copy(), "motion": motion},
    )


def singular(state: SimState, q: FloatArray, rcond: float, actuated_idx: IntArray) -> NoReturn:
    """Refuse a state whose rcond of J_p is below SINGULAR_RCOND (type II singularity)."""
    raise SingularityError(
        f"parallel (type II) singularity at t = {state.time:.6g} s: the passive joints "
        f"no longer follow the inputs (rcond of the passive constraint Jacobian "
        f"{rcond:.2g} < {SINGULAR_RCOND:g}) near theta = "
        f"{np.degrees(q[actuated_idx]).round(4).tolist()} deg",
        kind="type II",
        value=q.copy(),
    )


# ------------------------------------------------------------------------ kernel
class Kernel:
    """The simulator's hot loop: a private workspace and closures with bound locals.

    Python call overhead dominates a time step (each Pinocchio or numpy call costs
    about a microsecond), so everything a step needs is bound once, here. The
    workspace (``pin.Data``, constraint datas, LU) is the kernel's own, so other uses
    of the same :class:`ClosedLoopDynamics` between steps cannot disturb it.

    Args:
        dynamics: The dynamics whose model, welds, friction and armature are used.
        dt: Time step [s].
        integrator: ``"rk4"`` or ``"euler"``: the integrator of ``step``.
        state: The state that ``step`` advances in place.

    Attributes (callables):
        kinematics(q) -> (J, r2): joint Jacobians, weld residuals, the selected
            constraint Jacobian J (passive columns first) and the LU of J_p at q;
            r2 = ||e||^2.
        tangent(J) -> S: the velocity map S = [I; G] (9, 3), v = S theta_dot, with the
            LU of the last ``kinematics`` call.
        accelerate(q, v, tau3) -> (ddq, friction torque): ``pin.constraintDynamics``.
        project(q) -> (J, r2, moved, e): Newton projection of q's passive joints in
            place; e is the residual of the used rows at the result.
        step(tau3) -> theta_ddot: one step of the chosen integrator on ``state``;
            returns the input accelerations at the state it started from.
        energy(q, v) -> (kinetic, potential).
        forget(): clear the Euler predictor's history (after a reset).
    """

    def __init__(
        self, dynamics: ClosedLoopDynamics, dt: float, integrator: str, state: SimState
    ) -> None:
        dyn = dynamics
        model = dyn.model
        data = model.createData()
        cms = dyn._cms
        cds = pin.StdVec_ConstraintData()
        for constraint in cms:
            cds.append(constraint.createData())
        bare = [d.extract() for d in cds]
        self._keep = (cds, bare)
        calc_errors = tuple(
            (c.extract().calc, d, d.constraint_position_error)
            for c, d in zip(cms, bare, strict=True)
        )
        errors = tuple(d.constraint_position_error for d in bare)
        rigid = dyn._rigid
        rigid_datas = pin.StdVec_RigidConstraintData([r.createData() for r in rigid])
        pin.initConstraintDynamics(model, data, rigid, rigid_datas)
        prox = pin.ProximalSettings(PROXIMAL_ACCURACY, PROXIMAL_MU, PROXIMAL_MAX_ITERATIONS)
        self._keep_rigid = rigid_datas
        lu = eigenpy.PartialPivLU(np.eye(dyn.passive_idx.shape[0]))
        self.lu = lu
        lu_compute, lu_solve, lu_rcond = lu.compute, lu.solve, lu.rcond
        joint_jacobians = pin.computeJointJacobians
        constraints_jacobian = pin.getConstraintsJacobian
        constraint_dynamics = pin.constraintDynamics
        kinetic_energy = pin.computeKineticEnergy
        potential_energy = pin.computePotentialEnergy
        concatenate, tanh = np.concatenate, np.tanh
        flat, rows = dyn._flat, dyn.constraint_rows
        a_idx, p_idx = dyn.actuated_idx, dyn.passive_idx
        nv, n_p = model.nv, int(p_idx.shape[0])
        scatter = np.zeros((nv, n_p))
        scatter[p_idx, np.arange(n_p)] = 1.0
        # S = [I; G] in q order: the actuated rows are fixed, the passive rows change.
        identity = np.zeros((nv, 3))
        identity[a_idx, np.arange(3)] = 1.0
        minus_scatter = -scatter
        armature = dyn.armature
        friction = dyn.friction
        viscous = None if friction is None else friction.viscous
        coulomb = None if friction is None or not friction.has_coulomb else friction.coulomb
        smoothing = 1.0 if friction is None else friction.smoothing_speed
        tau = np.zeros(nv)
        no_friction = np.zeros(nv)
        tol2 = CLOSURE_TOL * CLOSURE_TOL
        half, sixth, half_dt2 = 0.5 * dt, dt / 6.0, 0.5 * dt * dt

        def kinematics(q: FloatArray) -> tuple[FloatArray, float]:
            joint_jacobians(model, data, q)
            r2 = 0.0
            for calc, cdata, error in calc_errors:
                calc(model, data, cdata)
                r2 += error.dot(error)
            J = constraints_jacobian(model, data, cms, cds).take(flat)
            lu_compute(J[:, :n_p])
            return J, r2

        if len(calc_errors) == 2:  # the SPM: two welds, unrolled (saves a microsecond)
            (calc_a, cdata_a, error_a), (calc_b, cdata_b, error_b) = calc_errors

            def kinematics(q: FloatArray) -> tuple[FloatArray, float]:
                joint_jacobians(model, data, q)
                calc_a(model, data, cdata_a)
                calc_b(model, data, cdata_b)
                J = constraints_jacobian(model, data, cms, cds).take(flat)
                lu_compute(J[:, :n_p])
                return J, error_a.dot(error_a) + error_b.dot(error_b)

        def tangent(J: FloatArray) -> FloatArray:
            S: FloatArray = identity + minus_scatter.dot(lu_solve(J[:, n_p:]))
            return S

        def accelerate(
            q: FloatArray, v: FloatArray, tau3: FloatArray
        ) -> tuple[FloatArray, FloatArray]:
            if viscous is None:
                f = no_friction
                tau.put(a_idx, tau3)
            else:
                f = -viscous * v
                if coulomb is not None:
                    f -= coulomb * tanh(v / smoothing)
                tau[:] = f
                tau[a_idx] += tau3
            ddq = constraint_dynamics(model, data, q, v, tau, rigid, rigid_datas, prox)
            return ddq, f

        def selected_error() -> FloatArray:
            """The residual rows used (the angular ones) at the last evaluation."""
            result: FloatArray = concatenate(errors).take(rows)
            return result

        def project(q: FloatArray) -> tuple[FloatArray, float, bool, FloatArray]:
            """(J, r2, moved, e): Newton projection of q's passive joints, in place; e
            is the residual of the used rows at the projected q."""
            for iteration in range(NEWTON_MAX_ITERATIONS):
                J, r2 = kinematics(q)
                e = selected_error()
                if r2 <= tol2:
                    return J, r2, iteration > 0, e
                if not math.isfinite(r2):
                    break
                q -= scatter.dot(lu_solve(e))
            dyn._project(q)  # the generic solver, or ConvergenceError
            J, r2 = kinematics(q)
            return J, r2, True, selected_error()

        if len(calc_errors) == 2:  # the SPM, inlined: this runs once or twice a step
            sizes = [int(error.shape[0]) for error in errors]
            part_a = rows[rows < sizes[0]]
            part_b = rows[rows >= sizes[0]] - sizes[0]
            if all(
                part.size and np.array_equal(part, np.arange(part[0], part[-1] + 1))
                for part in (part_a, part_b)
            ):  # contiguous rows in each weld: views into the live residuals
                view_a = error_a[part_a[0] : part_a[-1] + 1]
                view_b = error_b[part_b[0] : part_b[-1] + 1]

                def selected_error() -> FloatArray:
                    result: FloatArray = concatenate((view_a, view_b))
                    return result

                if dyn._dropped_rows_vanish:  # the whole residual is in the used rows

                    def project(q: FloatArray) -> tuple[FloatArray, float, bool, FloatArray]:
                        for iteration in range(NEWTON_MAX_ITERATIONS):
                            joint_jacobians(model, data, q)
                            calc_a(model, data, cdata_a)
                            calc_b(model, data, cdata_b)
                            J = constraints_jacobian(model, data, cms, cds).take(flat)
                            lu_compute(J[:, :n_p])
                            e = concatenate((view_a, view_b))
                            r2 = e.dot(e)
                            if r2 <= tol2:
                                return J, r2, iteration > 0, e
                            if not math.isfinite(r2):
                                break
                            q -= scatter.dot(lu_solve(e))
                        dyn._project(q)  # the generic solver, or ConvergenceError
                        J, r2 = kinematics(q)
                        return J, r2, True, concatenate((view_a, view_b))

        def commit(
            q_next: FloatArray,
            theta_dot: FloatArray,
            work: float,
            loss: float,
        ) -> bool:
            """Project q_next, check it, make it the state; returns whether Newton moved it."""
            predicted = q_next.copy()
            if float(np.abs(predicted - state.q).max()) > MAX_STEP_ANGLE:
                too_fast(state, state.q, predicted, dt)
            try:
                J, r2, moved, _ = project(q_next)
            except ConvergenceError as exc:
                lost(state, q_next, exc, lu, a_idx)
            if moved:  # a Newton step was needed: check it stayed on the branch
                check_jump(state, state.q, predicted, q_next, dt)
            rcond = lu_rcond()
            if rcond < SINGULAR_RCOND:
                singular(state, q_next, rcond, a_idx)
            state.rcond = rcond
            state.q = q_next
            state.theta_dot = theta_dot
            state.S = tangent(J)
            state.work += work
            state.loss += loss
            state.steps += 1
            state.time += dt
            if r2 > state.max_r2:
                state.max_r2 = r2
            state.r2 = r2
            return moved

        # The history of the Euler predictor, on the passive joints: the smooth part D of
        # the projection's corrections of the last three steps (h0, h1, h2), and the
        # Newton step still left at the accepted state (its residual is below
        # CLOSURE_TOL, not zero; q - left would be the exact closed state).
        zero = np.zeros(n_p)
        h0 = h1 = h2 = left = zero

        def forget() -> None:
            """Clear the history (after a reset: the motion starts anew)."""
            nonlocal h0, h1, h2, left
            h0 = h1 = h2 = left = zero

        def euler(tau3: FloatArray) -> FloatArray:
            # The hot path of the simulator: written out (no helper calls) because each
            # Python-level call costs a fraction of a microsecond.
            q, S, w = state.q, state.S, state.theta_dot
            v = S.dot(w)
            if viscous is None:
                f = no_friction
                tau.put(a_idx, tau3)
            else:
                f = -viscous * v
                if coulomb is not None:
                    f -= coulomb * tanh(v / smoothing)
                tau[:] = f
                tau[a_idx] += tau3
            ddq = constraint_dynamics(model, data, q, v, tau, rigid, rigid_datas, prox)
            theta_ddot: FloatArray = ddq.take(a_idx)
            # theta_next = theta + dt theta_dot_next (semi-implicit Euler). The passive
            # joints are predicted on the loops: q + dt v + dt^2/2 (ddq + S theta_ddot) is
            # exact to O(dt^3); the remainder D (the correction the projection makes)
            # varies smoothly from step to step, so the last three extrapolate it
            # quadratically (P), and the Newton step r left at q is added. The projection
            # then finds the loops closed at its first evaluation in most steps; a
            # Newton step follows only when not.
            base = q + dt * v + half_dt2 * (ddq + S.dot(theta_ddot))
            nonlocal h0, h1, h2, left
            smooth = 3.0 * (h0 - h1) + h2
            q_next = base + scatter.dot(smooth - left)
            theta_dot = w + dt * theta_ddot
            work = dt * float(tau3.dot(theta_dot))
            loss = 0.0 if viscous is None else -dt * float(f.dot(v + dt * ddq))
            try:
                J, r2, moved, e = project(q_next)
            except ConvergenceError as exc:
                lost(state, q_next, exc, lu, a_idx)
            if moved:  # a Newton step was needed: check it stayed on the branch
                check_jump(state, q, base, q_next, dt)
            if moved or not state.steps & 7:
                # The distance to a parallel singularity, every 8 steps and whenever
                # the prediction needed Newton (near a singularity it does).
                rcond = lu_rcond()
                if rcond < SINGULAR_RCOND:
                    singular(state, q_next, rcond, a_idx)
                state.rcond = rcond
            S_next = identity + minus_scatter.dot(lu_solve(J[:, n_p:]))
            state.q, state.theta_dot, state.S, state.r2 = q_next, theta_dot, S_next, r2
            state.work += work
            state.loss += loss
            state.steps += 1
            state.time += dt
            if r2 > state.max_r2:
                state.max_r2 = r2
            # The state stays where it was checked; the step r left there enters the
            # next prediction and is taken out of this step's correction.
            remaining = lu_solve(e)
            if moved:
                smooth = (q_next - base).take(p_idx) + left
            h0, h1, h2, left = smooth - remaining, h0, h1, remaining
            return theta_ddot

        def stage(
            q: FloatArray, theta_dot: FloatArray, tau3: FloatArray
        ) -> tuple[FloatArray, FloatArray, float]:
            J, _ = kinematics(q)
            v = tangent(J).dot(theta_dot)
            ddq, f = accelerate(q, v, tau3)
            power = 0.0 if viscous is None else -float(f.dot(v))
            return v, ddq.take(a_idx), power

        def rk4(tau3: FloatArray) -> FloatArray:
            q, w = state.q, state.theta_dot
            v1 = state.S.dot(w)
            ddq, f = accelerate(q, v1, tau3)
            a1 = ddq.take(a_idx)
            p1 = 0.0 if viscous is None else -float(f.dot(v1))
            v2, a2, p2 = stage(q + half * v1, w + half * a1, tau3)
            v3, a3, p3 = stage(q + half * v2, w + half * a2, tau3)
            v4, a4, p4 = stage(q + dt * v3, w + dt * a3, tau3)
            q_next = q + sixth * (v1 + 2.0 * (v2 + v3) + v4)
            theta_dot = w + sixth * (a1 + 2.0 * (a2 + a3) + a4)
            work = float(tau3.dot(q_next.take(a_idx) - q.take(a_idx)))
            loss = sixth * (p1 + 2.0 * (p2 + p3) + p4)
            commit(q_next, theta_dot, work, loss)
            return a1

        def energy(q: FloatArray, v: FloatArray) -> tuple[float, float]:
            rate = v.take(a_idx)
            kinetic = float(kinetic_energy(model, data, q, v))
            kinetic += 0.5 * float(armature.dot(rate * rate))
            return kinetic, float(potential_energy(model, data, q))

        self.kinematics = kinematics
        self.tangent = tangent
        self.accelerate = accelerate
        self.project = project
        self.energy = energy
        self.forget = forget
        self.step: Callable[[FloatArray], FloatArray] = rk4 if integrator == "rk4" else euler
