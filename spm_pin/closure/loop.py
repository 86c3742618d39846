"""The public face of the loop-closure solver: :class:`ClosedLoop`.

It checks its inputs once, at the public boundary, and hands the checked values to
the solver's functions (``_solve``: projection and path following; ``_frames``:
velocities, frame Jacobians and frame targets), which work on its
:class:`~spm_pin.closure._core.LoopCore`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import FileFormatError, InputError
from ..kinematics._common import check_count
from ._constants import (
    CONTINUATION_MODES,
    DEFAULT_DAMPING,
    DEFAULT_MAX_HALVINGS,
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_TOL,
    FOLLOW_MAX_ITERATIONS,
    FloatArray,
    IntArray,
    check_solver_options,
)
from ._constraints import actuated_ids, loop_constraints
from ._core import LoopCore
from ._frames import (
    check_frame,
    check_reference_frame,
    check_target,
    closed,
    closed_frame_jacobian,
    reach_target,
    velocity_map_of,
)
from ._solve import (
    check_path,
    continue_path,
    convergence_error,
    first_iterate,
    follow_path,
    newton,
)
from .results import FrameTargetResult, LocalFailure, PathResult, ProjectionResult, Start


class ClosedLoop:
    """A closed-loop mechanism: a Pinocchio tree, its loop closures, its actuated joints.

    Args:
        model: The open kinematic tree, ``pin.Model`` (any joint kinds; the model is
            not modified).
        constraint_models: The loop closures, an iterable (list,
            ``pin.StdVec_ConstraintModel``, ``pin.StdVec_RigidConstraintModel``, ...)
            of ``pin.FrameAnchorConstraintModel``, ``pin.PointAnchorConstraintModel``
            (bare or wrapped in ``pin.ConstraintModel``) or legacy
            ``pin.RigidConstraintModel`` of type ``CONTACT_6D`` or ``CONTACT_3D``.
        actuated: The actuated joints, by name (``str``) or Pinocchio joint id
            (``int`` >= 1), in the order of the actuated values. Each must be a
            joint whose configuration is plain coordinates (:data:`EUCLIDEAN_JOINTS`:
            revolute, prismatic, helical, translation, universal). Every other joint
            is passive.

    Raises:
        InputError: a constraint of another kind or of another model, an unknown,
            repeated or non-Euclidean actuated joint, or actuated joints that are not
            independent (with them fixed, the passive joints cannot close every
            constraint direction).

    Attributes:
        model: The ``pin.Model``.
        constraint_models: The closures as ``pin.StdVec_ConstraintModel`` (new kinds;
            legacy models converted), in the given order.
        n_constraints: m, rows of the stacked residual.
        actuated_joints: Names of the actuated joints.
        passive_joints: Names of the passive joints, in tree order.
        actuated_q_idx: Indices of the actuated values in q, (n_actuated,).
        actuated_v_idx: Their indices in v (the same count: Euclidean joints).
        passive_q_idx: Indices of the passive joints' coordinates in q.
        passive_v_idx: Indices of the passive joints' velocities in v, (n_passive_v,).
        nominal_rank: Generic rank of the constraint Jacobian J (and of J_p), from
            random configurations.
        mobility: Degrees of freedom of the closed mechanism, nv - nominal_rank.
        idle_dof: Passive motions that leave every closure unchanged
            (n_passive_v - nominal_rank; e.g. the spin of a rod between two ball
            joints), chosen by minimum norm.
    """

    def __init__(
        self,
        model: pin.Model,
        constraint_models: Iterable[Any],
        actuated: Sequence[str | int],
    ) -> None:
        if not isinstance(model, pin.Model):
            raise InputError(
                f"model must be a pinocchio.Model, got {type(model).__name__}",
                argument="model",
                value=model,
            )
        constraints = loop_constraints(model, constraint_models)
        core = LoopCore(model, constraints, actuated_ids(model, actuated))
        self._core = core
        self.model: pin.Model = core.model
        self.constraint_models: pin.StdVec_ConstraintModel = core.constraint_models
        self.n_constraints: int = core.n_constraints
        self.actuated_joints: tuple[str, ...] = core.actuated_joints
        self.passive_joints: tuple[str, ...] = core.passive_joints
        self.actuated_q_idx: IntArray = core.actuated_q_idx
        self.actuated_v_idx: IntArray = core.actuated_v_idx
        self.passive_q_idx: IntArray = core.passive_q_idx
        self.passive_v_idx: IntArray = core.passive_v_idx
        self.nominal_rank: int = core.nominal_rank
        self.mobility: int = core.mobility
        self.idle_dof: int = core.idle_dof

    # ------------------------------------------------------------------ builders
    @classmethod
    def from_mjcf(cls, path: str | Path, actuated: Sequence[str | int]) -> ClosedLoop:
        """Load a model and its ``<equality>`` welds and connects from an MJCF file.

        Uses ``pin.buildModelAndConstraintsFromMJCF`` (welds become frame anchors,
        connects point anchors). Pinocchio parses only the first body directly under
        ``<worldbody>``: put the whole mechanism under one root body.

        Args:
            path: The MJCF file.
            actuated: Actuated joint names or ids (see :class:`ClosedLoop`).

        Raises:
            InputError: the file does not exist, or the actuated joints are bad.
            FileFormatError: Pinocchio cannot parse the file.
        """
        file = Path(path)
        if not file.is_file():
            raise InputError(f"MJCF file {str(file)!r} does not exist", argument="path", value=path)
        try:
            model, points, frames = pin.buildModelAndConstraintsFromMJCF(str(file))
        except (RuntimeError, ValueError) as exc:
            raise FileFormatError(f"Pinocchio cannot load it: {exc}", path=str(file)) from exc
        if len(points) + len(frames) == 0:
            raise InputError(
                f"MJCF file {str(file)!r} has no <equality> weld or connect: no loop to close",
                argument="path",
                value=path,
            )
        return cls(model, [*points, *frames], actuated)

    @classmethod
    def from_robot(cls, robot: Any) -> ClosedLoop:
        """The closed loop of a robot object with ``model``, ``constraint_models`` and
        ``actuated_joints`` attributes, such as :class:`~spm_pin.SPMRobot`.

        Example:
            >>> import spm_pin as spm
            >>> loop = spm.ClosedLoop.from_robot(spm.build_robot())
            >>> loop.actuated_joints, loop.mobility
            (('u_1', 'u_2', 'u_3'), 3)
        """
        for name in ("model", "constraint_models", "actuated_joints"):
            if not hasattr(robot, name):
                raise InputError(
                    f"robot must have model, constraint_models and actuated_joints "
                    f"(e.g. spm.build_robot()), got {type(robot).__name__} without {name!r}",
                    argument="robot",
                    value=robot,
                )
        return cls(robot.model, robot.constraint_models, robot.actuated_joints)

    def __repr__(self) -> str:
        return (
            f"ClosedLoop(model={self.model.name!r}, nq={self.model.nq}, "
            f"constraints={len(self.constraint_models)} ({self.n_constraints} rows, "
            f"rank {self.nominal_rank}), actuated={list(self.actuated_joints)}, "
            f"mobility={self.mobility})"
        )

    @property
    def n_actuated(self) -> int:
        """Number of actuated values (= actuated velocities)."""
        return int(self.actuated_q_idx.shape[0])

    def neutral(self) -> FloatArray:
        """``pin.neutral(model)``: the default cold start, shape (nq,)."""
        return self._core.neutral()

    # ------------------------------------------------------------ public: residual
    def residual(self, q: npt.ArrayLike) -> FloatArray:
        """The stacked constraint residual e(q), shape (m,) [m and rad].

        Rows follow :attr:`constraint_models`: a weld gives log6 of the placement of
        its second frame in its first, [linear; angular]; a point anchor the position
        of its second point in its first frame.
        """
        core = self._core
        core.evaluate(core.check_q(q))
        result: FloatArray = core.ebuf.copy()
        return result

    def constraint_jacobian(self, q: npt.ArrayLike) -> FloatArray:
        """J = de/dv at q, shape (m, nv) (exact on the closed set)."""
        core = self._core
        result: FloatArray = core.jacobian_at(core.check_q(q)).copy()
        return result

    def constraint_jacobians(self, q: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(J_a, J_p): the actuated (m, n_actuated) and passive (m, n_passive_v) columns."""
        J = self.constraint_jacobian(q)
        return J[:, self.actuated_v_idx], J[:, self.passive_v_idx]

    # ------------------------------------------------------------- public: project
    def project(
        self,
        actuated: npt.ArrayLike,
        start: Start = None,
        *,
        tol: float = DEFAULT_TOL,
        max_iterations: int = DEFAULT_MAX_ITERATIONS,
        damping: float = DEFAULT_DAMPING,
        continuation: str | bool = "fallback",
    ) -> ProjectionResult:
        """Closed configuration at the given actuated values (Newton projection).

        The passive joints start from ``start`` and are moved by damped Newton steps
        (see the module docstring) until ||e|| <= ``tol``. Newton converges to a
        closed configuration near the start, which for a far cold start need not be
        in the start's assembly mode (a four-bar may flip to its crossed form).
        Path following (:meth:`follow`, from the start's actuated values to the
        target along a straight line) keeps the start's assembly mode by
        continuity; ``continuation`` chooses when to use it.

        Args:
            actuated: Values of the actuated joints, shape (n_actuated,) [rad or m].
            start: Where to start: None (``pin.neutral(model)``, a cold start), a
                configuration q (nq,), or a previous :class:`ProjectionResult` or
                :class:`FrameTargetResult` (a warm start with the first-order
                predictor q_p + G dtheta, the fastest).
            tol: Closure tolerance on ||e|| [m, rad].
            max_iterations: Newton steps allowed (rejected steps count).
            damping: mu >= 0 in lambda = mu ||e||^2.
            continuation: ``"fallback"`` (default): Newton from the start, path
                following if that fails; ``"never"``: Newton only; ``"always"``:
                path following only (keeps the start's assembly mode; the start must
                close at its own actuated values). ``True`` and ``False`` mean
                ``"fallback"`` and ``"never"``.

        Returns:
            :class:`ProjectionResult` with ``q``, ``iterations``, ``residual``,
            ``rank``, ``singular`` and ``velocity_map``.

        Raises:
            InputError: bad shape, NaN or inf in ``actuated`` or ``start``; bad
                ``tol``, ``max_iterations``, ``damping`` or ``continuation``.
            ConvergenceError: no closed configuration found (unreachable input,
                singularity on the way); ``error.data`` holds ``q`` (the best
                iterate), ``residual``, ``iterations``, ``rank``, ``actuated``,
                ``stationary`` (a local minimum of ||e|| above zero) and ``reason``
                (``"stalled"``, ``"max_iterations"``, ``"path"``).

        Example:
            >>> import numpy as np, spm_pin as spm
            >>> loop = spm.ClosedLoop.from_robot(spm.build_robot())
            >>> first = loop.project(np.radians([60.0, 90.0, 120.0]))
            >>> bool(first.residual <= 1e-12), first.rank
            (True, 6)
            >>> warm = loop.project(np.radians([61.0, 90.0, 120.0]), first)
            >>> warm.iterations <= 2
            True
        """
        core = self._core
        theta = core.check_actuated(actuated)
        if isinstance(start, FrameTargetResult):
            start = start.projection
        if (
            tol != DEFAULT_TOL
            or max_iterations != DEFAULT_MAX_ITERATIONS
            or damping != DEFAULT_DAMPING
        ):
            check_solver_options(tol, max_iterations, damping)
        if continuation is True or continuation is False:
            continuation = "fallback" if continuation else "never"
        elif continuation != "fallback" and continuation not in CONTINUATION_MODES:
            raise InputError(
                f"continuation must be one of {CONTINUATION_MODES}, got {continuation!r}",
                argument="continuation",
                value=continuation,
            )
        local: LocalFailure | None = None
        if continuation != "always":
            q, _ = first_iterate(core, start, theta)
            try:
                return newton(core, theta, q, tol, max_iterations, damping)
            except LocalFailure as failure:
                local = failure
            if continuation == "never":
                raise convergence_error(core, theta, local)
        return continue_path(core, theta, start, tol, max_iterations, damping, local)

    # -------------------------------------------------------------- public: follow
    def follow(
        self,
        path: npt.ArrayLike,
        start: Start = None,
        *,
        tol: float = DEFAULT_TOL,
        max_halvings: int = DEFAULT_MAX_HALVINGS,
        damping: float = DEFAULT_DAMPING,
    ) -> PathResult:
        """Closed configurations along a path of actuated values, by continuation.

        The first point is solved by :meth:`project` from ``start``; each next one is
        warm-started from the previous answer with the first-order predictor
        ``q_p + G dtheta``. A step is halved (up to ``max_halvings`` times) when the
        corrector fails, needs more than :data:`FOLLOW_MAX_ITERATIONS` iterations,
        moves the passive joints by more than :data:`CORRECTOR_RATIO` of the
        predicted change, or (mechanisms without idle motions) when J_p loses rank or
        the sign of det(Q^T J_p) flips between two points, Q an orthonormal basis of
        the range of J_p at the previous point: a singularity lies between them. Near
        singularities the path is walked in smaller steps; across one, following
        stops with an error, so the robot never changes assembly mode silently.

        Args:
            path: Actuated values, shape (N, n_actuated) [rad or m].
            start: Start of the first solve (see :meth:`project`).
            tol: Closure tolerance on ||e|| [m, rad].
            max_halvings: Halvings allowed per path step.
            damping: mu of the Newton steps.

        Returns:
            :class:`PathResult`.

        Raises:
            InputError: bad shape, NaN or inf in ``path``; bad options.
            ConvergenceError: a point cannot be reached even with the smallest step
                (a singularity or the workspace boundary on the path); ``data`` holds
                ``index`` (the path point), ``actuated`` (the last value reached),
                ``q`` and the partial ``results``.
        """
        points = check_path(self._core, path)
        if isinstance(start, FrameTargetResult):
            start = start.projection
        check_solver_options(tol, FOLLOW_MAX_ITERATIONS, damping)
        halvings = check_count(max_halvings, "max_halvings", 0)
        first = self.project(points[0], start, tol=tol, damping=damping)
        return follow_path(self._core, points, first, tol, halvings, damping)

    def velocity_map(self, q: npt.ArrayLike) -> FloatArray:
        """G = dv_p/dv_a = -J_p^+ J_a at a closed q, shape (n_passive_v, n_actuated).

        Raises:
            InputError: q has a bad shape or does not close the loops (residual above
                :data:`CLOSED_TOL`).
            SingularityError: J_p has lost rank (kind ``"type II"``).
        """
        core = self._core
        _, J = closed(core, q)
        return velocity_map_of(core, J)

    def velocity(self, q: npt.ArrayLike, actuated_velocity: npt.ArrayLike) -> FloatArray:
        """Joint velocity v (nv,) that keeps the loops closed, from the actuated velocities.

        v[actuated_v_idx] = actuated_velocity and v[passive_v_idx] = G actuated_velocity,
        so J v = 0.

        Args:
            q: A closed configuration (nq,).
            actuated_velocity: Velocities of the actuated joints (n_actuated,)
                [rad/s or m/s].

        Raises:
            InputError, SingularityError: as :meth:`velocity_map`.
        """
        rate = self._core.check_actuated(actuated_velocity, "actuated_velocity")
        G = self.velocity_map(q)
        v = np.zeros(self.model.nv)
        v[self.actuated_v_idx] = rate
        v[self.passive_v_idx] = G @ rate
        return v

    def frame_jacobian(
        self,
        q: npt.ArrayLike,
        frame: str | int,
        reference_frame: pin.ReferenceFrame = pin.ReferenceFrame.LOCAL,
    ) -> FloatArray:
        """Closed-loop Jacobian of a frame with respect to the actuated joints, (6, n_actuated).

        J_closed = J_f[:, actuated] + J_f[:, passive] G: the frame's spatial velocity
        [linear; angular] per unit actuated velocity, with the passive joints moving
        as the loops require.

        Args:
            q: A closed configuration (nq,).
            frame: Frame name or id of ``model``.
            reference_frame: ``pin.ReferenceFrame.LOCAL`` (Pinocchio's default),
                ``WORLD`` or ``LOCAL_WORLD_ALIGNED``, as in ``pin.getFrameJacobian``.

        Raises:
            InputError: bad q (see :meth:`velocity_map`), unknown frame.
            SingularityError: J_p has lost rank.
        """
        core = self._core
        frame_id = check_frame(core.model, frame)
        reference = check_reference_frame(reference_frame)
        _, J = closed(core, q)
        G = velocity_map_of(core, J)
        return closed_frame_jacobian(core, frame_id, reference, G)

    # --------------------------------------------------------- public: frame target
    def solve_frame_target(
        self,
        frame: str | int,
        target: pin.SE3 | npt.ArrayLike,
        start: Start = None,
        *,
        tol: float = DEFAULT_TOL,
        max_iterations: int = DEFAULT_MAX_ITERATIONS,
        damping: float = DEFAULT_DAMPING,
    ) -> FrameTargetResult:
        """Actuated values that bring a frame to a target orientation, placement or position.

        Newton's method on the actuated values with the closed-loop frame Jacobian;
        every iterate is a closed configuration (:meth:`project`, warm-started). The
        task error and its exact Jacobian:

        * orientation R* (3, 3): e = log3(R*^T R), J = Jlog3(R*^T R) J_closed,angular
          (LOCAL);
        * placement M* (``pin.SE3`` or 4x4): e = log6(M*^-1 M), J = Jlog6 J_closed
          (LOCAL);
        * position p* (3,): e = p - p*, J = J_closed,linear (LOCAL_WORLD_ALIGNED).

        Steps are damped least squares (lambda = mu ||e||^2) and halved when they do
        not reduce ||e|| or leave the workspace.

        Args:
            frame: Frame name or id.
            target: ``pin.SE3`` or (4, 4) homogeneous matrix (placement), rotation
                matrix (3, 3) (orientation) or point (3,) [m] (position), in the world.
            start: Start (see :meth:`project`); its actuated values are the initial guess.
            tol: Tolerance on the task error norm (see :attr:`FrameTargetResult.residual`).
            max_iterations: Outer Newton steps allowed.
            damping: mu of the steps.

        Returns:
            :class:`FrameTargetResult`.

        Raises:
            InputError: unknown frame, malformed target (a rotation must be orthonormal
                with det +1 to 1e-9).
            ConvergenceError: the task error stalls above ``tol`` (the target is out
                of reach of this frame, or the start lies across a singularity);
                ``data`` has the best ``actuated``, ``q``, ``residual``.
        """
        core = self._core
        frame_id = check_frame(core.model, frame)
        kind, goal = check_target(target)
        if isinstance(start, FrameTargetResult):
            start = start.projection
        check_solver_options(tol, max_iterations, damping)
        if start is None:
            begin: ProjectionResult | FloatArray = self.neutral()
        elif isinstance(start, ProjectionResult):
            begin = start
        else:
            begin = core.check_q(start, "start")
        theta0 = (
            begin.actuated if isinstance(begin, ProjectionResult) else begin[self.actuated_q_idx]
        )
        current = self.project(theta0, begin, tol=DEFAULT_TOL)
        return reach_target(
            core, frame_id, kind, goal, current, tol, max_iterations, damping, frame
        )
