"""Forward and inverse dynamics of the closed loop, one state or a path at a time.

:class:`ClosedLoopDynamics` holds a private copy of the robot's Pinocchio model (with
the chosen gravity and armature), the two welds that close legs 2 and 3, and the
workspace of both formulations of :mod:`spm_pin.dynamics` (``pin.constraintDynamics``
and the null-space equations). :func:`forward_dynamics`, :func:`inverse_dynamics`
and :func:`holding_torques` are its plain-function forms; their results are
:class:`ForwardDynamicsResult` and :class:`InverseDynamicsResult`.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, NoReturn

import eigenpy
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .._checks import float_array, require_angles
from ..closure import CLOSED_TOL, ClosedLoop
from ..errors import ConvergenceError, InputError, SingularityError
from ..model.robot import SPMRobot, build_robot
from ._checks import array3, nonnegative_vector, vector
from ._constants import (
    CLOSURE_TOL,
    GRAVITY,
    PROXIMAL_ACCURACY,
    PROXIMAL_MAX_ITERATIONS,
    PROXIMAL_MU,
    SINGULAR_RCOND,
    FloatArray,
    IntArray,
)
from .servo import JointFriction
from .trajectory import Trajectory

__all__ = [
    "ClosedLoopDynamics",
    "ForwardDynamicsResult",
    "InverseDynamicsResult",
    "forward_dynamics",
    "holding_torques",
    "inverse_dynamics",
]


@dataclasses.dataclass(frozen=True)
class ForwardDynamicsResult:
    """Accelerations of the closed loop under given torques (one state).

    Attributes:
        theta_ddot: Input accelerations [rad/s^2], (3,).
        ddq: Joint accelerations [rad/s^2], (9,), q order.
        q: The closed configuration, (9,).
        v: Joint velocities [rad/s], (9,) (J v = 0).
        torque: Actuator torques applied [N m], (3,).
        friction_torque: Joint friction torques [N m], (9,).
        constraint_torque: Torque that legs 2 and 3 exert on the platform through
            their closures, world frame [N m], (2, 3). The forces at O are statically
            indeterminate (all axes meet there) and are not reported.
        method: ``"pinocchio"`` or ``"nullspace"``.
    """

    theta_ddot: FloatArray
    ddq: FloatArray
    q: FloatArray
    v: FloatArray
    torque: FloatArray
    friction_torque: FloatArray
    constraint_torque: FloatArray
    method: str


@dataclasses.dataclass(frozen=True)
class InverseDynamicsResult:
    """Actuator torques and closure torques that produce a motion.

    Arrays have a leading sample axis when the input was a path (N, 3), none for a
    single state (3,).

    Attributes:
        torque: Actuator torques [N m], (..., 3).
        constraint_torque: Torque that legs 2 and 3 exert on the platform through
            their closures, world frame [N m], (..., 2, 3).
        theta: Input angles [rad], (..., 3).
        theta_dot: Input speeds [rad/s], (..., 3).
        theta_ddot: Input accelerations [rad/s^2], (..., 3).
        q: Closed configurations, (..., 9).
        v: Joint velocities [rad/s], (..., 9).
        ddq: Joint accelerations [rad/s^2], (..., 9).
        friction_torque: Joint friction torques [N m], (..., 9) (already compensated
            in ``torque``).
        time: Sample times [s], (N,), when the input was a :class:`Trajectory`.
    """

    torque: FloatArray
    constraint_torque: FloatArray
    theta: FloatArray
    theta_dot: FloatArray
    theta_ddot: FloatArray
    q: FloatArray
    v: FloatArray
    ddq: FloatArray
    friction_torque: FloatArray
    time: FloatArray | None = None

    @property
    def power(self) -> FloatArray:
        """Mechanical power of each actuator, torque * theta_dot [W], (..., 3)."""
        result: FloatArray = self.torque * self.theta_dot
        return result


# --------------------------------------------------------------------- dynamics
class ClosedLoopDynamics:
    """Forward and inverse dynamics of the closed-loop SPM (see :mod:`spm_pin.dynamics`).

    Holds a private copy of the robot's Pinocchio model (with the chosen gravity and
    armature), its data and the loop-closure workspace; one object per thread.

    Args:
        robot: The robot (default: ``build_robot()``, the prototype).
        gravity: Gravity vector in the world frame [m/s^2] (default :data:`GRAVITY`,
            upright; ``(0, 0, 9.81)`` is the robot hanging upside down).
        friction: Joint friction (default: none).
        armature: Reflected rotor inertia of each actuator [kg m^2], scalar or (3,),
            added to the input joints (the servos' gear trains; default 0).

    Raises:
        InputError: bad arguments; closures whose nonzero rows are not independent.

    Attributes:
        robot: The :class:`~spm_pin.SPMRobot`.
        model: The private ``pin.Model`` (gravity and armature set).
        loop: :class:`~spm_pin.closure.ClosedLoop` of ``model`` (position projection
            of single states and paths).
        gravity: (3,) [m/s^2].
        friction: :class:`JointFriction` or None.
        armature: (3,) [kg m^2].
        actuated_idx: Indices of the inputs in q and v, (3,).
        passive_idx: Indices of the passive joints, (6,).
        constraint_rows: Rows of the stacked weld residual that are used (the angular
            ones), (6,).
    """

    def __init__(
        self,
        robot: SPMRobot | None = None,
        *,
        gravity: npt.ArrayLike = GRAVITY,
        friction: JointFriction | None = None,
        armature: npt.ArrayLike = 0.0,
    ) -> None:
        if robot is None:
            robot = build_robot()
        if not isinstance(robot, SPMRobot):
            raise InputError(
                f"robot must be an SPMRobot (spm.build_robot()), got {type(robot).__name__}",
                argument="robot",
                value=robot,
            )
        if friction is not None and not isinstance(friction, JointFriction):
            raise InputError(
                f"friction must be a JointFriction or None, got {type(friction).__name__}",
                argument="friction",
                value=friction,
            )
        self.robot = robot
        self.gravity: FloatArray = vector(gravity, 3, "gravity", "[m/s^2]")
        self.friction: JointFriction | None = friction
        self.armature: FloatArray = nonnegative_vector(armature, 3, "armature", "[kg m^2]")
        self.actuated_idx: IntArray = np.array(robot.actuated_q_idx, dtype=np.int64)
        self.passive_idx: IntArray = np.array(robot.passive_q_idx, dtype=np.int64)

        model = pin.Model(robot.model)
        model.gravity = pin.Motion(np.concatenate([self.gravity, np.zeros(3)]))
        armature_full = np.zeros(model.nv)
        armature_full[self.actuated_idx] = self.armature
        model.armature = armature_full
        self.model: pin.Model = model
        self._data: pin.Data = model.createData()
        self.loop = ClosedLoop(model, robot.constraint_models, robot.actuated_joints)

        # New-style welds: residuals, Jacobians, acceleration bias.
        self._cms = pin.StdVec_ConstraintModel()
        self._cds = pin.StdVec_ConstraintData()
        for constraint in robot.constraint_models:
            self._cms.append(constraint)
            self._cds.append(constraint.createData())
        bare = [(c.extract(), d.extract()) for c, d in zip(self._cms, self._cds, strict=True)]
        self._bare = bare  # keeps the references alive
        self._calcs = [(c.calc, d) for c, d in bare]
        self._position_errors = [d.constraint_position_error for _, d in bare]
        self._acceleration_errors = [d.constraint_acceleration_error for _, d in bare]
        self._weld_rows = [int(e.shape[0]) for e in self._position_errors]
        # Legacy welds for pin.constraintDynamics (Baumgarte gains zero).
        self._rigid = robot.rigid_constraint_models()
        for rigid in self._rigid:
            rigid.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(0.0, 0.0))
        self._rigid_datas = pin.StdVec_RigidConstraintData(
            [rigid.createData() for rigid in self._rigid]
        )
        pin.initConstraintDynamics(model, self._data, self._rigid, self._rigid_datas)
        self._prox = pin.ProximalSettings(PROXIMAL_ACCURACY, PROXIMAL_MU, PROXIMAL_MAX_ITERATIONS)

        self.constraint_rows: IntArray = self._select_rows()
        n_rows = self.constraint_rows.shape[0]
        n_passive = self.passive_idx.shape[0]
        if n_rows != n_passive:
            raise InputError(
                f"the closures have {n_rows} independent rows but {n_passive} passive "
                "joints: the dynamics needs the passive joints to be determined by the inputs",
                argument="robot",
                value=robot,
            )
        perm = np.concatenate([self.passive_idx, self.actuated_idx])
        # Flat indices into the (m, nv) constraint Jacobian: selected rows, passive
        # columns first, then actuated ones.
        self._flat: IntArray = (self.constraint_rows[:, None] * model.nv + perm[None, :]).astype(
            np.int64
        )
        self._lu = eigenpy.PartialPivLU(np.eye(n_passive))
        self._lu_t = eigenpy.PartialPivLU(np.eye(n_passive))  # of J_p^T
        self._J = np.zeros((n_rows, model.nv))
        self._zero_v = np.zeros(model.nv)

    def __repr__(self) -> str:
        return (
            f"ClosedLoopDynamics(design={self.robot.design.name!r}, gravity="
            f"{self.gravity.tolist()}, armature={self.armature.tolist()}, friction="
            f"{'yes' if self.friction is not None else 'none'})"
        )

    # -------------------------------------------------------------- internals
    def _select_rows(self) -> IntArray:
        """The weld rows that are not identically zero (checked on random configurations).

        Also sets ``_dropped_rows_vanish``: the other rows, residual and Jacobian, were
        exactly zero on every configuration tried (all axes through O: the linear rows
        of a weld at O), so the residual of the used rows is the whole residual.
        """
        rng = np.random.default_rng(7)
        model = self.model
        m = sum(self._weld_rows)
        size = np.zeros(m)
        residual = np.zeros(m)
        for _ in range(4):
            q = pin.integrate(model, pin.neutral(model), rng.uniform(-np.pi, np.pi, model.nv))
            pin.computeJointJacobians(model, self._data, q)
            for calc, data in self._calcs:
                calc(model, self._data, data)
            J = pin.getConstraintsJacobian(model, self._data, self._cms, self._cds)
            size = np.maximum(size, np.abs(J).max(axis=1))
            residual = np.maximum(residual, np.abs(np.concatenate(self._position_errors)))
        rows = np.flatnonzero(size > 1e-12).astype(np.int64)
        dropped = np.setdiff1d(np.arange(m), rows)
        self._dropped_rows_vanish = bool(
            np.all(size[dropped] == 0.0) and np.all(residual[dropped] == 0.0)
        )
        return rows

    def _kinematics(self, q: FloatArray) -> float:
        """Joint Jacobians, weld residuals and the LU of J_p at q; returns ||e||^2."""
        model, data = self.model, self._data
        pin.computeJointJacobians(model, data, q)
        r2 = 0.0
        for (calc, cdata), error in zip(self._calcs, self._position_errors, strict=True):
            calc(model, data, cdata)
            r2 += float(error.dot(error))
        J = pin.getConstraintsJacobian(model, data, self._cms, self._cds).take(self._flat)
        self._J = J
        self._lu.compute(J[:, : self.passive_idx.shape[0]])
        return r2

    def _passive_velocity(self, theta_dot: FloatArray) -> FloatArray:
        """v_p = G theta_dot at the configuration of the last _kinematics call."""
        n_p = self.passive_idx.shape[0]
        result: FloatArray = -self._lu.solve(self._J[:, n_p:].dot(theta_dot))
        return result

    def _velocity(self, theta_dot: FloatArray) -> FloatArray:
        v = np.empty(self.model.nv)
        v.put(self.actuated_idx, theta_dot)
        v.put(self.passive_idx, self._passive_velocity(theta_dot))
        return v

    def _velocity_map(self) -> FloatArray:
        n_p = self.passive_idx.shape[0]
        G: FloatArray = -self._lu.solve(self._J[:, n_p:])
        return G

    def _singular(self) -> bool:
        return bool(self._lu.rcond() < SINGULAR_RCOND)

    def _raise_singular(self, q: FloatArray, when: str = "") -> NoReturn:
        raise SingularityError(
            f"parallel (type II) singularity{when}: the passive joints no longer follow "
            f"the inputs (rcond of the passive constraint Jacobian {self._lu.rcond():.2g} < "
            f"{SINGULAR_RCOND:g}) at theta = {np.degrees(q[self.actuated_idx]).round(4).tolist()}"
            " deg",
            kind="type II",
            value=q.copy(),
        )

    def _project(self, q: FloatArray) -> None:
        """Close the loops at q (in place, theta held) with the generic solver.

        :meth:`ClosedLoop.project` (damped Newton with line search, rank revealing):
        the fallback of the simulator's lean Newton steps.

        Raises:
            ConvergenceError: no closed configuration near q.
        """
        theta = q[self.actuated_idx].copy()
        try:
            result = self.loop.project(theta, q, tol=CLOSURE_TOL, continuation=False)
        except ConvergenceError as exc:
            raise ConvergenceError(
                f"the loops cannot be closed at theta = {np.degrees(theta).round(4).tolist()} "
                f"deg: {exc}",
                data={"q": q.copy(), **exc.data},
            ) from exc
        q[:] = result.q

    def _gamma(self, q: FloatArray, v: FloatArray) -> FloatArray:
        """Constraint acceleration at zero joint acceleration (selected rows)."""
        model, data = self.model, self._data
        pin.forwardKinematics(model, data, q, v, self._zero_v)
        for calc, cdata in self._calcs:
            calc(model, data, cdata)
        gamma: FloatArray = np.concatenate(self._acceleration_errors).take(self.constraint_rows)
        return gamma

    def _friction(self, v: FloatArray) -> FloatArray:
        if self.friction is None:
            return np.zeros(self.model.nv)
        return self.friction.torque(v)

    def _state(self, state: Any) -> FloatArray:
        """A closed configuration (9,) from theta (3,) or q (9,)."""
        array = float_array(
            state,
            "state",
            f"state must be input angles theta (3,) [rad] or a closed configuration "
            f"q (9,), got {state!r}",
        )
        if array.shape == (3,):
            require_angles(array, "theta", state)
            q: FloatArray = self.robot.configuration(array)
            return q
        if array.shape != (self.model.nq,):
            raise InputError(
                f"state must be theta (3,) [rad] or a closed configuration q (9,), got "
                f"shape {array.shape}",
                argument="state",
                value=state,
            )
        require_angles(array, "q", state)
        residual = math.sqrt(self._kinematics(array))
        if residual > CLOSED_TOL:
            raise InputError(
                f"q does not close the loops: residual {residual:.3g} > {CLOSED_TOL:g} rad; "
                "start from theta, robot.configuration(theta) or dynamics.loop.project",
                argument="q",
                value=state,
            )
        return array

    def _evaluate(self, q: FloatArray) -> None:
        """Kinematics at a closed q, with the type II check."""
        self._kinematics(q)
        if self._singular():
            self._raise_singular(q)

    def _split(self, tau_tree: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Actuator torques and weld torques from tau_tree = M qdd + h - tau_f.

        The passive rows give the multipliers, J_p^T lambda_s = tau_tree,p; the actuated
        rows the actuator torques, tau = tau_tree,a - J_a^T lambda_s. Each weld's angular
        multiplier, in the frame of its first body (the leg end), is rotated to the world:
        the torque leg k exerts on the platform. Needs the kinematics at q.
        """
        n_p = self.passive_idx.shape[0]
        Jp, Ja = self._J[:, :n_p], self._J[:, n_p:]
        self._lu_t.compute(Jp.T)
        lam = self._lu_t.solve(tau_tree[self.passive_idx])
        torque: FloatArray = tau_tree[self.actuated_idx] - Ja.T @ lam
        full = np.zeros(sum(self._weld_rows))
        full[self.constraint_rows] = lam
        welds = np.zeros((len(self._weld_rows), 3))
        start = 0
        for k, ((_, cdata), rows) in enumerate(zip(self._bare, self._weld_rows, strict=True)):
            if rows == 6:  # a weld: [linear; angular]
                welds[k] = np.asarray(cdata.oMc1.rotation) @ full[start + 3 : start + 6]
            start += rows
        return torque, welds

    # -------------------------------------------------------------- public
    def configuration(self, state: npt.ArrayLike) -> FloatArray:
        """The closed configuration q (9,) of input angles theta (3,) [rad] (home
        assembly mode) or of a q (9,) that closes the loops (checked, copied)."""
        result: FloatArray = self._state(state).copy()
        return result

    def velocity(self, state: npt.ArrayLike, theta_dot: npt.ArrayLike) -> FloatArray:
        """Joint velocities v (9,) [rad/s] that keep the loops closed: v = S theta_dot.

        Raises:
            SingularityError: a parallel (type II) singularity at the state.
        """
        q = self._state(state)
        rate = vector(theta_dot, 3, "theta_dot", "[rad/s]")
        self._evaluate(q)
        return self._velocity(rate)

    def velocity_map(self, state: npt.ArrayLike) -> FloatArray:
        """S (9, 3): joint velocities per unit input speed, rows in q order."""
        q = self._state(state)
        self._evaluate(q)
        S = np.zeros((self.model.nv, 3))
        S[self.actuated_idx] = np.eye(3)
        S[self.passive_idx] = self._velocity_map()
        return S

    def mass_matrix(self, state: npt.ArrayLike) -> FloatArray:
        """Reduced mass matrix M_r = S^T M S (3, 3) [kg m^2] (armature included)."""
        q = self._state(state)
        S = self.velocity_map(q)
        M = pin.crba(self.model, self._data, q, pin.Convention.WORLD)
        result: FloatArray = S.T @ M @ S
        return result

    def energy(self, state: npt.ArrayLike, theta_dot: npt.ArrayLike) -> tuple[float, float]:
        """(kinetic, potential) energy [J]; potential is -sum m g . c (zero with every
        centre of mass at O)."""
        q = self._state(state)
        v = self.velocity(q, theta_dot)
        return self._energy(q, v)

    def _energy(self, q: FloatArray, v: FloatArray) -> tuple[float, float]:
        model, data = self.model, self._data
        rate = v[self.actuated_idx]
        kinetic = float(pin.computeKineticEnergy(model, data, q, v)) + 0.5 * float(
            np.dot(self.armature, rate * rate)
        )
        potential = float(pin.computePotentialEnergy(model, data, q))
        return kinetic, potential

    def holding_torques(self, state: npt.ArrayLike) -> FloatArray:
        """Actuator torques that hold the robot still against gravity [N m], (3,).

        tau = S^T g(q), g the generalised gravity of the tree: the torques the servos
        must apply so that the robot stays at rest (minus the gradient of the potential
        energy along the closed mechanism).
        """
        q = self._state(state)
        S = self.velocity_map(q)
        g = pin.computeGeneralizedGravity(self.model, self._data, q)
        result: FloatArray = S.T @ g
        return result

    def forward(
        self,
        state: npt.ArrayLike,
        theta_dot: npt.ArrayLike,
        torque: npt.ArrayLike | None = None,
        *,
        method: str = "pinocchio",
    ) -> ForwardDynamicsResult:
        """Accelerations of the closed loop under actuator torques, gravity and friction.

        Args:
            state: Input angles theta (3,) [rad] (home assembly mode) or a closed q (9,).
            theta_dot: Input speeds [rad/s], (3,).
            torque: Actuator torques [N m], (3,) (default 0).
            method: ``"pinocchio"`` (``pin.constraintDynamics``, proximal) or
                ``"nullspace"`` (the reduced equations); see :mod:`spm_pin.dynamics`.

        Returns:
            :class:`ForwardDynamicsResult`.

        Raises:
            InputError: bad shapes, NaN or inf, unknown method, a q that does not close.
            SingularityError: a parallel (type II) singularity at the state.
        """
        if method not in ("pinocchio", "nullspace"):
            raise InputError(
                f"method must be 'pinocchio' or 'nullspace', got {method!r}",
                argument="method",
                value=method,
            )
        q = self._state(state)
        rate = vector(theta_dot, 3, "theta_dot", "[rad/s]")
        tau3 = np.zeros(3) if torque is None else vector(torque, 3, "torque", "[N m]")
        self._evaluate(q)
        v = self._velocity(rate)
        friction = self._friction(v)
        tau = friction.copy()
        tau[self.actuated_idx] += tau3
        model, data = self.model, self._data
        if method == "pinocchio":
            ddq = np.array(
                pin.constraintDynamics(
                    model, data, q, v, tau, self._rigid, self._rigid_datas, self._prox
                )
            )
        else:
            ddq = self._nullspace_acceleration(q, v, tau)
        # the kinematics workspace still holds q (neither call above changes it)
        _, welds = self._split(np.array(pin.rnea(model, data, q, v, ddq)) - friction)
        return ForwardDynamicsResult(
            theta_ddot=ddq[self.actuated_idx].copy(),
            ddq=ddq,
            q=q.copy(),
            v=v,
            torque=tau3,
            friction_torque=friction,
            constraint_torque=welds,
            method=method,
        )

    def _nullspace_acceleration(self, q: FloatArray, v: FloatArray, tau: FloatArray) -> FloatArray:
        """qdd from M_r theta_ddot = S^T (tau - b); kinematics at q required."""
        model, data = self.model, self._data
        G = self._velocity_map()
        S = np.zeros((model.nv, 3))
        S[self.actuated_idx] = np.eye(3)
        S[self.passive_idx] = G
        bias = np.zeros(model.nv)
        bias[self.passive_idx] = -self._lu.solve(self._gamma(q, v))
        b = np.array(pin.rnea(model, data, q, v, bias))
        M = np.array(pin.crba(model, data, q, pin.Convention.WORLD))
        theta_ddot = np.linalg.solve(S.T @ M @ S, S.T @ (tau - b))
        result: FloatArray = S @ theta_ddot + bias
        return result

    def inverse(
        self,
        theta: npt.ArrayLike,
        theta_dot: npt.ArrayLike,
        theta_ddot: npt.ArrayLike,
        *,
        start: npt.ArrayLike | None = None,
    ) -> InverseDynamicsResult:
        """Actuator torques and closure torques for a motion (closed-loop inverse dynamics).

        Args:
            theta: Input angles [rad], (3,) or a path (N, 3) (consecutive samples of a
                continuous motion: the closed configurations are followed by
                continuation, so the assembly mode never jumps).
            theta_dot: Input speeds [rad/s], the same shape.
            theta_ddot: Input accelerations [rad/s^2], the same shape.
            start: Closed configuration q (9,) of the first sample (default: the home
                assembly mode at theta[0]).

        Returns:
            :class:`InverseDynamicsResult` (arrays (3,) or (N, 3), ...).

        Raises:
            InputError: bad shapes, NaN or inf.
            UnreachableError, ConvergenceError: no closed configuration along the path.
            SingularityError: a parallel (type II) singularity on the path.
        """
        angles = array3(theta, "theta", "[rad]")
        speed = array3(theta_dot, "theta_dot", "[rad/s]")
        acceleration = array3(theta_ddot, "theta_ddot", "[rad/s^2]")
        for name, array in (("theta_dot", speed), ("theta_ddot", acceleration)):
            if array.shape != angles.shape:
                raise InputError(
                    f"{name} must have the shape of theta {angles.shape}, got {array.shape}",
                    argument=name,
                    value=array,
                )
        single = angles.ndim == 1
        path = angles[None] if single else angles
        if start is None:
            first = self.robot.configuration(path[0])
        else:
            first = self._state(start)
            if not np.allclose(first[self.actuated_idx], path[0], atol=1e-9, rtol=0.0):
                raise InputError(
                    "start must be a closed configuration at theta[0]",
                    argument="start",
                    value=start,
                )
        configurations = first[None] if path.shape[0] == 1 else self.loop.follow(path, first).q
        n = path.shape[0]
        torque = np.zeros((n, 3))
        welds = np.zeros((n, len(self._weld_rows), 3))
        v_all = np.zeros((n, self.model.nv))
        ddq_all = np.zeros((n, self.model.nv))
        friction_all = np.zeros((n, self.model.nv))
        rates = np.atleast_2d(speed)
        accelerations = np.atleast_2d(acceleration)
        for k in range(n):
            (
                torque[k],
                welds[k],
                v_all[k],
                ddq_all[k],
                friction_all[k],
            ) = self._inverse_one(configurations[k], rates[k], accelerations[k])
        if single:
            return InverseDynamicsResult(
                torque=torque[0],
                constraint_torque=welds[0],
                theta=angles.copy(),
                theta_dot=speed.copy(),
                theta_ddot=acceleration.copy(),
                q=configurations[0].copy(),
                v=v_all[0],
                ddq=ddq_all[0],
                friction_torque=friction_all[0],
            )
        return InverseDynamicsResult(
            torque=torque,
            constraint_torque=welds,
            theta=angles.copy(),
            theta_dot=speed.copy(),
            theta_ddot=acceleration.copy(),
            q=np.array(configurations),
            v=v_all,
            ddq=ddq_all,
            friction_torque=friction_all,
        )

    def _inverse_one(
        self, q: FloatArray, theta_dot: FloatArray, theta_ddot: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        model, data = self.model, self._data
        self._evaluate(q)
        v = self._velocity(theta_dot)
        n_p = self.passive_idx.shape[0]
        J_a_theta_ddot = self._J[:, n_p:].dot(theta_ddot)
        gamma = self._gamma(q, v)
        ddq = np.empty(model.nv)
        ddq[self.actuated_idx] = theta_ddot
        ddq[self.passive_idx] = -self._lu.solve(J_a_theta_ddot + gamma)
        friction = self._friction(v)
        torque, welds = self._split(np.array(pin.rnea(model, data, q, v, ddq)) - friction)
        return torque, welds, v, ddq, friction


def _dynamics(dynamics: ClosedLoopDynamics | SPMRobot | None) -> ClosedLoopDynamics:
    if isinstance(dynamics, ClosedLoopDynamics):
        return dynamics
    if dynamics is None or isinstance(dynamics, SPMRobot):
        return ClosedLoopDynamics(dynamics)
    raise InputError(
        "expected a ClosedLoopDynamics or an SPMRobot, got " + type(dynamics).__name__,
        argument="dynamics",
        value=dynamics,
    )


def forward_dynamics(
    dynamics: ClosedLoopDynamics | SPMRobot | None,
    state: npt.ArrayLike,
    theta_dot: npt.ArrayLike,
    torque: npt.ArrayLike | None = None,
    *,
    method: str = "pinocchio",
) -> ForwardDynamicsResult:
    """Input accelerations under actuator torques (see :meth:`ClosedLoopDynamics.forward`).

    Args:
        dynamics: A :class:`ClosedLoopDynamics` (gravity, friction, armature), or an
            SPMRobot / None for the defaults (upright, frictionless).
        state: theta (3,) [rad] or a closed q (9,).
        theta_dot: Input speeds [rad/s], (3,).
        torque: Actuator torques [N m], (3,) (default 0).
        method: ``"pinocchio"`` or ``"nullspace"``.

    Example:
        >>> import numpy as np, spm_pin as spm
        >>> result = spm.forward_dynamics(None, np.zeros(3), np.zeros(3), [0.1, 0, 0])
        >>> result.theta_ddot.shape
        (3,)
    """
    return _dynamics(dynamics).forward(state, theta_dot, torque, method=method)


def inverse_dynamics(
    dynamics: ClosedLoopDynamics | SPMRobot | None,
    motion: Trajectory | npt.ArrayLike,
    theta_dot: npt.ArrayLike | None = None,
    theta_ddot: npt.ArrayLike | None = None,
) -> InverseDynamicsResult:
    """Actuator torques and closure torques for a motion.

    Args:
        dynamics: A :class:`ClosedLoopDynamics`, or an SPMRobot / None (defaults).
        motion: A :class:`Trajectory`, or input angles theta [rad] (3,) or (N, 3)
            with ``theta_dot`` and ``theta_ddot`` of the same shape.
        theta_dot: Input speeds [rad/s] (with theta).
        theta_ddot: Input accelerations [rad/s^2] (with theta).

    Returns:
        :class:`InverseDynamicsResult` (with ``time`` for a trajectory).

    Example:
        >>> import spm_pin as spm
        >>> motion = spm.Trajectory.minimum_jerk([0, 0, 0], [0.5, 0.2, -0.3], 1.0, 100)
        >>> spm.inverse_dynamics(None, motion).torque.shape
        (101, 3)
    """
    model = _dynamics(dynamics)
    if isinstance(motion, Trajectory):
        if theta_dot is not None or theta_ddot is not None:
            raise InputError(
                "give either a Trajectory or theta, theta_dot and theta_ddot",
                argument="theta_dot",
            )
        result = model.inverse(motion.theta, motion.theta_dot, motion.theta_ddot)
        return dataclasses.replace(result, time=motion.time.copy())
    if theta_dot is None or theta_ddot is None:
        raise InputError("theta_dot and theta_ddot are required with theta", argument="theta_dot")
    return model.inverse(motion, theta_dot, theta_ddot)


def holding_torques(
    dynamics: ClosedLoopDynamics | SPMRobot | None, state: npt.ArrayLike
) -> FloatArray:
    """Static actuator torques [N m] that hold the robot at a state against gravity.

    See :meth:`ClosedLoopDynamics.holding_torques`.
    """
    return _dynamics(dynamics).holding_torques(state)
