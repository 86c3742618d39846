r"""Generic loop-closure solver for any Pinocchio model with loop constraints.

Pinocchio 4 models a closed-loop robot as an open kinematic tree plus constraint
models that close the loops. It uses them in the dynamics, but it has no routine that
puts the robot into a configuration that satisfies them (closed-loop forward
kinematics) and none for closed-loop velocities. :class:`ClosedLoop` adds both, for
any ``pin.Model``, any set of loop closures and any choice of actuated joints:

* the constraint residual e(q) and its Jacobian J = de/dv split into the columns of
  the actuated joints (J_a) and of the passive ones (J_p);
* :meth:`ClosedLoop.project`: given the actuated joint values, solve the passive
  joints by Newton projection (rank-aware damped least squares) to a residual
  ``||e|| <= 1e-12``, from a cold or a warm start;
* :meth:`ClosedLoop.follow`: a path of actuated values, each solve warm-started from
  the previous one with a first-order predictor, steps halved where the corrector
  has to work hard (near singularities);
* closed-loop velocities (:meth:`ClosedLoop.velocity`,
  :meth:`ClosedLoop.velocity_map`), the closed-loop Jacobian of any frame with respect
  to the actuated joints (:meth:`ClosedLoop.frame_jacobian`) and inverse kinematics of
  a frame target through the loops (:meth:`ClosedLoop.solve_frame_target`).

Accepted loop closures: Pinocchio 4 ``FrameAnchorConstraintModel`` (6D weld) and
``PointAnchorConstraintModel`` (3D point coincidence), bare or wrapped in
``pin.ConstraintModel``, and legacy ``RigidConstraintModel`` (``CONTACT_6D`` and
``CONTACT_3D``, any reference frame; converted to the new kinds, which have the same
closed configurations).

The maths. Let q split into actuated joints (values theta, velocities v_a) and passive
joints (velocities v_p). Pinocchio's residual of each closure is
e = log6(c1Mc2) [linear; angular] for a weld and the position of c2 in c1 for a point
anchor; stacked, e(q) has m rows and J = [J_a J_p] satisfies de = J v to first order
on the closed set (the weld Jacobian is exact there). The closed set is
{q : e(q) = 0}, and with theta fixed each Newton step solves

    min_dx ||J_p dx + e||^2 + lambda ||dx||^2,   lambda = mu ||e||^2,

(Levenberg-Marquardt with the damping of Yamashita and Fukushima, quadratic
convergence even with redundant rows) through a complete orthogonal decomposition
of the stacked matrix [J_p; sqrt(lambda) I] (rank-revealing QR: redundant and
dependent rows are the rule, the SPM has 12 rows of rank 6). A step that does not
reduce ||e|| is retried with ten times the damping. On the closed set the loops stay
closed to first order when J_a v_a + J_p v_p = 0, so

    v_p = G v_a,   G = -J_p^+ J_a,

(minimum norm when J_p has idle directions, such as the spin of a rod between two
ball joints) and a frame with Jacobian J_f = [J_fa J_fp] moves with the closed-loop
Jacobian J_f,closed = J_fa + J_fp G. Where J_p loses rank below its generic value
(:attr:`ClosedLoop.nominal_rank`) the passive joints are not determined by the
actuated ones (a parallel, type II singularity): velocities raise
:class:`~spm_pin.SingularityError`, and results carry ``singular=True``.

A :class:`ClosedLoop` keeps one private ``pin.Data``: use one object per thread.
Joint limits are not enforced (check ``model.lowerPositionLimit`` yourself).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, TypeAlias

import eigenpy
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .errors import ConvergenceError, FileFormatError, InputError, SingularityError
from .kinematics._common import (
    ANGLE_LIMIT,
    check_count,
    float_array,
    require_angles,
    require_bounded,
)

#: ``actuated.dot(actuated)`` at most this bounds every entry by ANGLE_LIMIT.
_LIMIT_SQUARED = ANGLE_LIMIT**2
#: Largest |entry| of a frame target (positions [m], matrix entries): generous for a
#: mechanism metres in size, and small enough that the least-squares steps stay finite.
TARGET_LIMIT = 1e6

__all__ = [
    "CLOSED_TOL",
    "CONTINUATION_MODES",
    "CONTINUATION_STEP",
    "CORRECTOR_RATIO",
    "DEFAULT_DAMPING",
    "DEFAULT_MAX_HALVINGS",
    "DEFAULT_MAX_ITERATIONS",
    "DEFAULT_TOL",
    "EUCLIDEAN_JOINTS",
    "FOLLOW_MAX_ITERATIONS",
    "RANK_TOL",
    "ClosedLoop",
    "FrameTargetResult",
    "PathResult",
    "ProjectionResult",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Closure tolerance of :meth:`ClosedLoop.project`: Euclidean norm of the stacked
#: constraint residual [m and rad]; it bounds every component (max-abs).
DEFAULT_TOL = 1e-12
#: Newton iterations (accepted and retried steps) before :meth:`ClosedLoop.project`
#: gives up.
DEFAULT_MAX_ITERATIONS = 50
#: Newton iterations per sub-step in :meth:`ClosedLoop.follow` before the step is halved.
FOLLOW_MAX_ITERATIONS = 12
#: Damping factor mu of the Newton steps, lambda = mu ||e||^2 (lambda in the units of
#: J_p^T J_p; 1 suits joints in rad and lengths in m).
DEFAULT_DAMPING = 1.0
#: Relative rank threshold: a pivot of the rank-revealing QR counts as zero below
#: RANK_TOL times the largest one.
RANK_TOL = 1e-9
#: A configuration counts as closed (velocity maps accept it) when ||e|| <= CLOSED_TOL.
CLOSED_TOL = 1e-9
#: Default number of halvings of a path step in :meth:`ClosedLoop.follow`.
DEFAULT_MAX_HALVINGS = 12
#: Largest path step tried by the continuation fallback of :meth:`ClosedLoop.project`
#: (max-abs over the actuated values) [rad or m].
CONTINUATION_STEP = 0.1
#: A path sub-step is accepted when the corrector moved the passive joints by at most
#: this fraction of the predicted change (plus :data:`CLOSED_TOL`).
CORRECTOR_RATIO = 0.5
#: Values of the ``continuation`` argument of :meth:`ClosedLoop.project`.
CONTINUATION_MODES = ("never", "fallback", "always")
#: Consecutive rejected Newton steps (damping x 10 each) that mean a stall.
_MAX_REJECTIONS = 8
_FLOAT64 = np.dtype(np.float64)
#: Seed of the random configurations that estimate the generic ranks.
_RANK_SEED = 20_240_611

#: Joint kinds whose configuration is a vector of coordinates with q_dot = v (the
#: actuated joints must be of these kinds; when every joint is, q is updated in place).
EUCLIDEAN_JOINTS = frozenset(
    {
        "JointModelRX",
        "JointModelRY",
        "JointModelRZ",
        "JointModelRevoluteUnaligned",
        "JointModelPX",
        "JointModelPY",
        "JointModelPZ",
        "JointModelPrismaticUnaligned",
        "JointModelHX",
        "JointModelHY",
        "JointModelHZ",
        "JointModelHelicalUnaligned",
        "JointModelTranslation",
        "JointModelUniversal",
    }
)

_CONSTRAINT_KINDS = (
    "pin.FrameAnchorConstraintModel, pin.PointAnchorConstraintModel (bare or in "
    "pin.ConstraintModel) or pin.RigidConstraintModel (CONTACT_6D or CONTACT_3D)"
)


# ------------------------------------------------------------------------- results
class ProjectionResult:
    """A closed configuration found by :meth:`ClosedLoop.project`.

    Pass it back as ``start`` of the next call: the solve then starts from a
    first-order prediction instead of from ``q``. ``rank``, ``singular`` and
    ``velocity_map`` are computed exactly at ``q`` when first read (one Jacobian and
    one small factorisation), so a control loop that never reads them does not pay
    for them.

    Attributes:
        q: Closed joint configuration, shape (nq,).
        actuated: The actuated joint values that were imposed, shape (n_actuated,)
            [rad or m].
        iterations: Newton steps taken (0 when the start was already closed).
        residual: ||e(q)||, Euclidean norm of the stacked constraint residual [m, rad].
        continuation: True when the answer came from path following (the
            ``continuation`` argument of :meth:`ClosedLoop.project`).
    """

    __slots__ = (
        "_loop",
        "_map",
        "_predictor",
        "_rank",
        "actuated",
        "continuation",
        "iterations",
        "q",
        "residual",
    )

    def __init__(
        self,
        loop: ClosedLoop,
        q: FloatArray,
        actuated: FloatArray,
        iterations: int,
        residual: float,
        predictor: FloatArray | None,
    ) -> None:
        self._loop = loop
        self.q = q
        self.actuated = actuated
        self.iterations = iterations
        self.residual = residual
        self.continuation = False
        self._predictor = predictor
        self._rank: int | None = None
        self._map: FloatArray | None = None

    def __repr__(self) -> str:
        return (
            f"ProjectionResult(q={self.q!r}, iterations={self.iterations}, "
            f"residual={self.residual:.3g}, continuation={self.continuation})"
        )

    def _analyse(self) -> tuple[int, FloatArray]:
        if self._rank is None or self._map is None:
            self._rank, self._map = self._loop._analysis(self.q)
        return self._rank, self._map

    @property
    def rank(self) -> int:
        """Numerical rank of the passive constraint Jacobian J_p at ``q`` (the matrix
        the Newton steps invert; relative threshold :data:`RANK_TOL`)."""
        return self._analyse()[0]

    @property
    def singular(self) -> bool:
        """True when ``rank`` is below the generic rank (:attr:`ClosedLoop.nominal_rank`):
        the passive joints are not determined by the actuated ones here."""
        return self._analyse()[0] < self._loop.nominal_rank

    @property
    def velocity_map(self) -> FloatArray:
        """G = -J_p^+ J_a at ``q``, shape (n_passive_v, n_actuated): passive joint
        velocities per unit actuated velocity (minimum norm, rank-revealing)."""
        return self._analyse()[1]


@dataclasses.dataclass
class PathResult:
    """A path of closed configurations found by :meth:`ClosedLoop.follow`.

    Attributes:
        q: Closed configurations, shape (N, nq).
        actuated: The actuated values of the path, shape (N, n_actuated).
        iterations: Newton steps spent on each point, sub-steps included, (N,).
        residual: ||e|| at each point [m, rad], (N,).
        rank: Rank of J_p at each point, (N,).
        substeps: Projections used to reach each point from the previous one, (N,);
            more than 1 where the step was halved.
        results: The :class:`ProjectionResult` of each point.
    """

    q: FloatArray
    actuated: FloatArray
    iterations: IntArray
    residual: FloatArray
    rank: IntArray
    substeps: IntArray
    results: list[ProjectionResult]

    @property
    def total_iterations(self) -> int:
        """Newton steps over the whole path."""
        return int(np.sum(self.iterations))


@dataclasses.dataclass
class FrameTargetResult:
    """Actuated values that bring a frame to a target (:meth:`ClosedLoop.solve_frame_target`).

    Attributes:
        actuated: The actuated joint values found, shape (n_actuated,) [rad or m].
        q: The closed configuration there, shape (nq,).
        iterations: Outer Newton steps on the actuated values.
        residual: Norm of the task error at the answer: ||log3|| [rad] for an
            orientation, ||log6|| [m, rad] for a placement, distance [m] for a position.
        kind: ``"orientation"``, ``"placement"`` or ``"position"``.
        projection: The closed configuration as a :class:`ProjectionResult` (closure
            residual, rank, velocity map).
    """

    actuated: FloatArray
    q: FloatArray
    iterations: int
    residual: float
    kind: str
    projection: ProjectionResult


#: What a solve may start from: None (a cold start at ``pin.neutral(model)``), a
#: configuration q (nq,), or a previous result (a warm start with a predictor).
Start: TypeAlias = "ProjectionResult | FrameTargetResult | npt.ArrayLike | None"


class _LocalFailure(Exception):
    """Internal: the local Newton solve did not converge (data kept for the report)."""

    def __init__(self, reason: str, q: FloatArray, residual: float, iterations: int) -> None:
        super().__init__(reason)
        self.reason = reason
        self.q = q
        self.residual = residual
        self.iterations = iterations


# ----------------------------------------------------------------------- the solver
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
        self.model: pin.Model = model
        self._data: pin.Data = model.createData()
        self.constraint_models: pin.StdVec_ConstraintModel = _loop_constraints(
            model, constraint_models
        )
        self._constraint_datas = pin.StdVec_ConstraintData()
        for constraint in self.constraint_models:
            self._constraint_datas.append(constraint.createData())
        bare = [
            (constraint.extract(), data.extract())
            for constraint, data in zip(self.constraint_models, self._constraint_datas, strict=True)
        ]
        self._calcs = [(constraint.calc, data) for constraint, data in bare]
        self._errors = [data.constraint_position_error for _, data in bare]
        self.n_constraints: int = int(sum(error.shape[0] for error in self._errors))

        joint_ids = _actuated_ids(model, actuated)
        self.actuated_joints: tuple[str, ...] = tuple(model.names[j] for j in joint_ids)
        passive_ids = [j for j in range(1, model.njoints) if j not in joint_ids]
        self.passive_joints: tuple[str, ...] = tuple(model.names[j] for j in passive_ids)
        self.actuated_q_idx: IntArray = _indices(model.idx_qs, model.nqs, joint_ids)
        self.actuated_v_idx: IntArray = _indices(model.idx_vs, model.nvs, joint_ids)
        self.passive_q_idx: IntArray = _indices(model.idx_qs, model.nqs, passive_ids)
        self.passive_v_idx: IntArray = _indices(model.idx_vs, model.nvs, passive_ids)
        self._euclidean = all(
            model.joints[j].shortname() in EUCLIDEAN_JOINTS for j in range(1, model.njoints)
        )
        self._setup_workspace()
        self.nominal_rank: int
        self.mobility: int
        self.idle_dof: int
        self._nominal_ranks()

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
        result: FloatArray = np.array(pin.neutral(self.model), dtype=float)
        return result

    # ---------------------------------------------------------------- internals
    def _setup_workspace(self) -> None:
        m, nv = self.n_constraints, self.model.nv
        n_p = self.passive_v_idx.shape[0]
        n_a = self.actuated_v_idx.shape[0]
        # [J_p; sqrt(lambda) I] and [e; 0]: the damped Newton system, preallocated.
        self._aug = np.zeros((m + n_p, n_p))
        self._aug_top = self._aug[:m]
        self._rhs = np.zeros(m + n_p)
        self._ebuf = self._rhs[:m]
        # the diagonal of the damping block, a writable strided view
        self._aug_diag = self._aug[m:].reshape(-1)[:: n_p + 1]
        self._select_p = np.zeros((nv, n_p))
        self._select_p[self.passive_v_idx, np.arange(n_p)] = 1.0
        self._select_a = np.zeros((nv, n_a))
        self._select_a[self.actuated_v_idx, np.arange(n_a)] = 1.0
        self._cod = eigenpy.CompleteOrthogonalDecomposition(np.eye(max(m + n_p, 1), max(n_p, 1)))
        self._cod_p = eigenpy.CompleteOrthogonalDecomposition(np.eye(max(m, 1), max(n_p, 1)))
        self._cod_p.setThreshold(RANK_TOL)
        self._neg_select_a = -self._select_a
        # [-J_a; 0] for the predictor map, solved with the last step's factorisation
        self._rhs_a = np.zeros((m + n_p, n_a))
        self._rhs_a_top = self._rhs_a[:m]
        self._jp = np.zeros((m, n_p))
        self._ja = np.zeros((m, n_a))
        self._e_old = np.zeros(m)
        self._v = np.zeros(nv)
        self._q_shape = (int(self.model.nq),)
        self._a_shape = (n_a,)
        self._g_shape = (n_p, n_a)
        # (rows of e, error view) of every closure, to gather e without a temporary
        self._copies = []
        row = 0
        for error in self._errors:
            size = int(error.shape[0])
            self._copies.append((slice(row, row + size), error))
            row += size

    def _nominal_ranks(self) -> None:
        """Generic ranks of J and J_p from random configurations; independence check."""
        rng = np.random.default_rng(_RANK_SEED)
        rank = rank_p = 0
        neutral = pin.neutral(self.model)
        for _ in range(3):
            q = pin.integrate(self.model, neutral, rng.normal(size=self.model.nv))
            J = self._jacobian_at(q)
            rank = max(rank, _rank(J))
            rank_p = max(rank_p, _rank(J[:, self.passive_v_idx]))
        if rank_p < rank:
            raise InputError(
                f"the actuated joints {list(self.actuated_joints)} are not independent: "
                f"the loop closures have rank {rank}, but with the actuated joints fixed "
                f"the passive joints {list(self.passive_joints)} can satisfy only "
                f"{rank_p} of those directions; actuate fewer joints (the mechanism has "
                f"{self.model.nv - rank} degrees of freedom)",
                argument="actuated",
                value=list(self.actuated_joints),
            )
        self.nominal_rank = rank
        self.mobility = self.model.nv - rank
        self.idle_dof = int(self.passive_v_idx.shape[0]) - rank_p

    def _evaluate(self, q: FloatArray) -> float:
        """Kinematics and constraint residual at q into the workspace; returns ||e||^2."""
        model, data, ebuf = self.model, self._data, self._ebuf
        pin.computeJointJacobians(model, data, q)
        for calc, constraint_data in self._calcs:
            calc(model, data, constraint_data)
        for rows, error in self._copies:
            ebuf[rows] = error
        r2: float = ebuf.dot(ebuf)
        return r2

    def _jacobian_at(self, q: FloatArray) -> FloatArray:
        self._evaluate(q)
        return self._jacobian()

    def _jacobian(self) -> FloatArray:
        """Constraint Jacobian (m, nv) at the configuration last evaluated."""
        if not self._errors:
            return np.zeros((0, self.model.nv))
        J: FloatArray = pin.getConstraintsJacobian(
            self.model, self._data, self.constraint_models, self._constraint_datas
        )
        return J

    def _step(self, q: FloatArray, dx: FloatArray) -> FloatArray:
        """q moved by -dx on the passive joints (in place when q is Euclidean)."""
        if self._euclidean:
            q[self.passive_q_idx] -= dx
            return q
        v = self._v
        v[:] = 0.0
        v[self.passive_v_idx] = -dx
        result: FloatArray = pin.integrate(self.model, q, v)
        return result

    def _check_actuated(self, actuated: Any, name: str = "actuated") -> FloatArray:
        if (
            type(actuated) is np.ndarray
            and actuated.dtype is _FLOAT64
            and actuated.shape == self._a_shape
        ):
            array: FloatArray = actuated
        else:
            n = self.n_actuated
            array = float_array(
                actuated,
                name,
                f"{name} must be {n} numbers (values of {list(self.actuated_joints)}) "
                f"[rad or m], got {actuated!r}",
            )
            if array.shape != (n,):
                raise InputError(
                    f"{name} must have shape ({n},) (values of {list(self.actuated_joints)}) "
                    f"[rad or m], got shape {array.shape}",
                    argument=name,
                    value=actuated,
                )
        # Cheap test first (a NaN spreads; a sum of squares <= limit**2 bounds every
        # entry; Python floats overflow to inf without numpy's warning machinery, which
        # costs more than the test), then the one rule for joint values: finite,
        # |value| <= ANGLE_LIMIT.
        if not sum(v * v for v in array.tolist()) <= _LIMIT_SQUARED:
            require_angles(array, name, actuated)
        return array

    def _check_q(self, q: Any, name: str = "q") -> FloatArray:
        nq = self.model.nq
        array = float_array(q, name, f"{name} must be a configuration of {nq} numbers, got {q!r}")
        if array.shape != (nq,):
            raise InputError(
                f"{name} must have shape ({nq},) (model {self.model.name!r}), "
                f"got shape {array.shape}",
                argument=name,
                value=q,
            )
        require_angles(array, name, q)
        return array

    def _start(self, start: Any, theta: FloatArray) -> tuple[FloatArray, bool]:
        """The initial iterate (a fresh array) and whether a predictor was applied."""
        if start is None:
            q = self.neutral()
            q[self.actuated_q_idx] = theta
            return q, False
        if isinstance(start, ProjectionResult):
            given = start.q
            if (
                type(given) is np.ndarray
                and given.dtype is _FLOAT64
                and given.shape == self._q_shape
            ):
                q = given.copy()
            else:
                q = self._check_q(given, "start.q")
            q[self.actuated_q_idx] = theta
            G = start._map if start._map is not None else start._predictor
            if G is None or G.shape != self._g_shape:
                return q, False
            if self._euclidean:
                q[self.passive_q_idx] += G @ (theta - start.actuated)
                return q, True
            return self._step(q, G @ (start.actuated - theta)), True
        q = self._check_q(start, "start")
        q[self.actuated_q_idx] = theta
        return q, False

    # ------------------------------------------------------------ public: residual
    def residual(self, q: npt.ArrayLike) -> FloatArray:
        """The stacked constraint residual e(q), shape (m,) [m and rad].

        Rows follow :attr:`constraint_models`: a weld gives log6 of the placement of
        its second frame in its first, [linear; angular]; a point anchor the position
        of its second point in its first frame.
        """
        array = self._check_q(q)
        self._evaluate(array)
        result: FloatArray = self._ebuf.copy()
        return result

    def constraint_jacobian(self, q: npt.ArrayLike) -> FloatArray:
        """J = de/dv at q, shape (m, nv) (exact on the closed set)."""
        array = self._check_q(q)
        result: FloatArray = self._jacobian_at(array).copy()
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
        theta = self._check_actuated(actuated)
        if isinstance(start, FrameTargetResult):
            start = start.projection
        if (
            tol != DEFAULT_TOL
            or max_iterations != DEFAULT_MAX_ITERATIONS
            or damping != DEFAULT_DAMPING
        ):
            _check_solver_options(tol, max_iterations, damping)
        if continuation is True or continuation is False:
            continuation = "fallback" if continuation else "never"
        elif continuation != "fallback" and continuation not in CONTINUATION_MODES:
            raise InputError(
                f"continuation must be one of {CONTINUATION_MODES}, got {continuation!r}",
                argument="continuation",
                value=continuation,
            )
        local: _LocalFailure | None = None
        if continuation != "always":
            q, _ = self._start(start, theta)
            try:
                return self._project(theta, q, tol, max_iterations, damping)
            except _LocalFailure as failure:
                local = failure
            if continuation == "never":
                raise self._failure(theta, local)
        return self._continue(theta, start, tol, max_iterations, damping, local)

    def _continue(
        self,
        theta: FloatArray,
        start: Any,
        tol: float,
        max_iterations: int,
        damping: float,
        local: _LocalFailure | None,
    ) -> ProjectionResult:
        """Path following from the start's actuated values to theta (straight line)."""
        if start is None:
            begin = self.neutral()
        elif isinstance(start, ProjectionResult):
            begin = self._check_q(start.q, "start.q")
        else:
            begin = self._check_q(start, "start")
        begin_theta = begin[self.actuated_q_idx].copy()
        span = float(np.max(np.abs(theta - begin_theta), initial=0.0))
        count = max(2, math.ceil(span / CONTINUATION_STEP))
        path = begin_theta + np.linspace(0.0, 1.0, count + 1)[:, None] * (theta - begin_theta)
        path[-1] = theta
        try:
            first = self._project(begin_theta, begin, tol, max_iterations, damping)
        except _LocalFailure as failure:
            why = (
                f"the start does not close at its own actuated values {begin_theta.tolist()} "
                f"({failure.reason} at residual {failure.residual:.3g})"
            )
            raise self._failure(theta, local or failure, why) from None
        try:
            followed = self._follow(path, first, tol, DEFAULT_MAX_HALVINGS, damping)
        except ConvergenceError as exc:
            data = exc.data
            best = _LocalFailure("path", data["q"], data["residual"], 0)
            raise self._failure(theta, local or best, str(exc)) from None
        final = followed.results[-1]
        final.iterations = followed.total_iterations + (local.iterations if local else 0)
        final.continuation = True
        return final

    def _project(
        self, theta: FloatArray, q: FloatArray, tol: float, max_iterations: int, damping: float
    ) -> ProjectionResult:
        """The local damped Newton solve from q (modified); raises _LocalFailure.

        The hot loop of the library: one kinematics call, one calc per closure and,
        when another step is needed, one Jacobian call and one small factorisation.
        """
        model, data, ebuf, e_old = self.model, self._data, self._ebuf, self._e_old
        kinematics, jacobian = pin.computeJointJacobians, pin.getConstraintsJacobian
        constraints, datas = self.constraint_models, self._constraint_datas
        calcs, copies = self._calcs, self._copies
        aug, aug_top, diag, rhs = self._aug, self._aug_top, self._aug_diag, self._rhs
        cod, select_p, passive = self._cod, self._select_p, self.passive_q_idx
        euclidean, n_passive = self._euclidean, self._g_shape[0]
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
                    raise _LocalFailure(reason, q, math.sqrt(r2), iterations)
                J = jacobian(model, data, constraints, datas)
                np.dot(J, select_p, out=aug_top)
                e_old[:] = ebuf
                q_old = q.copy()
                r2_old = r2
                rejections = 0
                lam_scale = damping
            else:
                if r2_old == math.inf:
                    self._non_finite(theta, q)
                # rejected: retry from the last accepted iterate with more damping
                rejections += 1
                if rejections > _MAX_REJECTIONS:
                    raise _LocalFailure("stalled", q_old, math.sqrt(r2_old), iterations)
                if iterations >= max_iterations:
                    raise _LocalFailure("max_iterations", q_old, math.sqrt(r2_old), iterations)
                lam_scale = max(lam_scale, 1e-6) * 10.0
                ebuf[:] = e_old
                q = q_old.copy()
            diag[:] = math.sqrt(lam_scale * r2_old)
            cod.compute(aug)
            if euclidean:
                q[passive] -= cod.solve(rhs)
            else:
                q = self._step(q, cod.solve(rhs))
            iterations += 1
        return self._result(theta, q, iterations, r2, J)

    def _result(
        self, theta: FloatArray, q: FloatArray, iterations: int, r2: float, J: Any
    ) -> ProjectionResult:
        """The result at q (the configuration last evaluated).

        The predictor map comes from the last Newton step's factorisation (J from that
        step, damping about ||e||^2 there: exact to first order in the last step),
        or, after no step, from the exact analysis.
        """
        result = ProjectionResult(self, q, theta.copy(), iterations, math.sqrt(r2), None)
        n_p, n_a = self._g_shape
        if J is None or not n_a:
            result._rank, result._map = self._passive_map(self._jacobian())
            result._predictor = result._map
        else:
            np.dot(J, self._neg_select_a, out=self._rhs_a_top)
            result._predictor = self._cod.solve(self._rhs_a).reshape(n_p, n_a)
        return result

    def _analysis(self, q: FloatArray) -> tuple[int, FloatArray]:
        """Exact rank of J_p and velocity map G at q (leaves J_p in ``self._jp``)."""
        self._evaluate(q)
        return self._passive_map(self._jacobian())

    def _non_finite(self, theta: FloatArray, q: FloatArray) -> None:
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

    def _failure(
        self, theta: FloatArray, local: _LocalFailure, continued: str | None = None
    ) -> ConvergenceError:
        """A ConvergenceError that says why (with the diagnosis at the best iterate)."""
        q = local.q
        J = self._jacobian_at(q)
        residual = math.sqrt(float(self._ebuf.dot(self._ebuf)))
        Jp = J[:, self.passive_v_idx]
        rank = _rank(Jp)
        gradient = float(np.linalg.norm(Jp.T @ self._ebuf))
        stationary = gradient <= 1e-6 * float(np.linalg.norm(Jp)) * residual
        singular = f"the passive Jacobian has rank {rank} < {self.nominal_rank} there"
        if stationary:
            diagnosis = (
                "the residual reached a local minimum of ||e|| above zero: the input is "
                "most likely unreachable (no closed configuration)"
            )
            if rank < self.nominal_rank:
                diagnosis += f"; {singular} (the closest configuration is singular)"
        elif rank < self.nominal_rank:
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
            f"({', '.join(self.actuated_joints)}): {what} at residual {residual:.3g}; "
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
                "rank": rank,
                "nominal_rank": self.nominal_rank,
                "stationary": stationary,
                "reason": local.reason,
                "continuation": continued,
            },
        )

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
        points = self._check_path(path)
        if isinstance(start, FrameTargetResult):
            start = start.projection
        _check_solver_options(tol, FOLLOW_MAX_ITERATIONS, damping)
        halvings = check_count(max_halvings, "max_halvings", 0)
        first = self.project(points[0], start, tol=tol, damping=damping)
        return self._follow(points, first, tol, halvings, damping)

    def _check_path(self, path: Any) -> FloatArray:
        n = self.n_actuated
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
                f"{list(self.actuated_joints)}), got shape {points.shape}",
                argument="path",
                value=path,
            )
        require_angles(points, "path", path)
        return points

    def _follow(
        self,
        points: FloatArray,
        first: ProjectionResult,
        tol: float,
        max_halvings: int,
        damping: float,
    ) -> PathResult:
        results = [first]
        iterations = [first.iterations]
        substeps = [1]
        previous = first
        # Orientation of J_p on its range, tracked to catch a singularity crossed between
        # two path points (the sign of det(Q^T J_p) flips; only with no idle motions).
        tracking = self.idle_dof == 0 and self.passive_v_idx.shape[0] > 0
        basis, sign = np.zeros((0, 0)), 0.0
        if tracking:
            basis, sign = _orientation(self._jacobian_at(first.q) @ self._select_p)
        for index in range(1, points.shape[0]):
            target = points[index]
            base = previous.actuated
            done, h, halvings, used, spent = 0.0, 1.0, 0, 0, 0
            while done < 1.0:
                h = min(h, 1.0 - done)
                final = done + h >= 1.0
                theta = target.copy() if final else base + (done + h) * (target - base)
                q, predicted = self._start(previous, theta)
                q_predicted = q.copy()
                try:
                    result = self._project(theta, q, tol, FOLLOW_MAX_ITERATIONS, damping)
                    spent += result.iterations
                    if tracking:
                        singular = result.singular  # the exact analysis leaves J_p in _jp
                        passive = self._jp
                        if singular or np.sign(np.linalg.det(basis.T @ passive)) != sign:
                            raise _LocalFailure(
                                "singularity", result.q, result.residual, result.iterations
                            )
                        new_basis, new_sign = _orientation(passive)
                    if predicted and not self._continuous(previous, q_predicted, theta, result):
                        raise _LocalFailure("jumped", result.q, result.residual, result.iterations)
                except _LocalFailure as failure:
                    if failure.reason in ("max_iterations", "stalled"):
                        spent += failure.iterations
                    halvings += 1
                    if halvings > max_halvings:
                        raise self._path_failure(
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

    def _path_failure(
        self,
        index: int,
        previous: ProjectionResult,
        target: FloatArray,
        failure: _LocalFailure,
        results: list[ProjectionResult],
        max_halvings: int,
    ) -> ConvergenceError:
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

    def _continuous(
        self,
        previous: ProjectionResult,
        q_predicted: FloatArray,
        theta: FloatArray,
        result: ProjectionResult,
    ) -> bool:
        """Whether the corrector stayed close to the predictor (no branch jump)."""
        G = previous._predictor if previous._predictor is not None else previous.velocity_map
        change = G @ (theta - previous.actuated)
        corrector = pin.difference(self.model, q_predicted, result.q)[self.passive_v_idx]
        size = max(
            float(np.max(np.abs(change), initial=0.0)),
            float(np.max(np.abs(theta - previous.actuated), initial=0.0)),
        )
        moved = float(np.max(np.abs(corrector), initial=0.0))
        return moved <= CORRECTOR_RATIO * size + CLOSED_TOL

    # ---------------------------------------------------------- public: velocities
    def _closed(self, q: Any) -> tuple[FloatArray, FloatArray]:
        """(q checked, J at q); raises when q does not close the loops."""
        array = self._check_q(q)
        J = self._jacobian_at(array)
        residual = math.sqrt(float(self._ebuf.dot(self._ebuf)))
        if residual > CLOSED_TOL:
            raise InputError(
                f"q does not close the loops: residual {residual:.3g} > {CLOSED_TOL:g}; "
                "project it first (ClosedLoop.project)",
                argument="q",
                value=q,
            )
        return array, J

    def _passive_map(self, J: FloatArray) -> tuple[int, FloatArray]:
        """Rank of J_p and G = -J_p^+ J_a (minimum norm, rank-revealing) from J (m, nv).

        Leaves J_p in ``self._jp``.
        """
        n_p, n_a = self._g_shape
        if n_p == 0:
            return 0, np.zeros((0, n_a))
        cod = self._cod_p
        cod.compute(np.dot(J, self._select_p, out=self._jp))
        rank = int(cod.rank())
        if n_a == 0:
            return rank, np.zeros((n_p, 0))
        G: FloatArray = cod.solve(np.dot(J, self._neg_select_a, out=self._ja))
        if G.ndim != 2:  # a single column comes back as a vector
            G = G.reshape(n_p, n_a)
        return rank, G

    def _velocity_map(self, J: FloatArray) -> FloatArray:
        rank, G = self._passive_map(J)
        if rank < self.nominal_rank:
            raise SingularityError(
                f"the passive joints are not determined by the actuated ones here: the "
                f"passive constraint Jacobian has rank {rank} < {self.nominal_rank} (a "
                "parallel, type II singularity)",
                kind="type II",
                value=rank,
            )
        return G

    def velocity_map(self, q: npt.ArrayLike) -> FloatArray:
        """G = dv_p/dv_a = -J_p^+ J_a at a closed q, shape (n_passive_v, n_actuated).

        Raises:
            InputError: q has a bad shape or does not close the loops (residual above
                :data:`CLOSED_TOL`).
            SingularityError: J_p has lost rank (kind ``"type II"``).
        """
        _, J = self._closed(q)
        return self._velocity_map(J)

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
        rate = self._check_actuated(actuated_velocity, "actuated_velocity")
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
        frame_id = self._frame_id(frame)
        reference = _reference_frame(reference_frame)
        _, J = self._closed(q)
        G = self._velocity_map(J)
        return self._closed_frame_jacobian(frame_id, reference, G)

    def _closed_frame_jacobian(
        self, frame_id: int, reference: pin.ReferenceFrame, G: FloatArray
    ) -> FloatArray:
        """J_fa + J_fp G at the configuration last evaluated."""
        Jf = pin.getFrameJacobian(self.model, self._data, frame_id, reference)
        result: FloatArray = Jf @ self._select_a + (Jf @ self._select_p) @ G
        return result

    def _frame_id(self, frame: Any) -> int:
        model = self.model
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
        frame_id = self._frame_id(frame)
        kind, goal = _frame_target(target)
        if isinstance(start, FrameTargetResult):
            start = start.projection
        _check_solver_options(tol, max_iterations, damping)
        if start is None:
            begin: ProjectionResult | FloatArray = self.neutral()
        elif isinstance(start, ProjectionResult):
            begin = start
        else:
            begin = self._check_q(start, "start")
        theta0 = (
            begin.actuated if isinstance(begin, ProjectionResult) else begin[self.actuated_q_idx]
        )
        current = self.project(theta0, begin, tol=DEFAULT_TOL)
        error, jac = self._task(frame_id, kind, goal, current)
        residual = float(np.linalg.norm(error))
        iterations = 0
        while residual > tol:
            if iterations >= max_iterations:
                raise self._task_failure(current, residual, iterations, "max_iterations", frame)
            n = self.n_actuated
            stacked = np.vstack([jac, math.sqrt(damping) * residual * np.eye(n)])
            rhs = np.concatenate([error, np.zeros(n)])
            step = -np.linalg.lstsq(stacked, rhs, rcond=None)[0]
            iterations += 1
            scale = 1.0
            for _ in range(_MAX_REJECTIONS + 4):
                theta = current.actuated + scale * step
                try:
                    trial = self.project(theta, current, tol=DEFAULT_TOL, continuation="never")
                except ConvergenceError:
                    scale *= 0.5
                    continue
                trial_error, trial_jac = self._task(frame_id, kind, goal, trial)
                trial_residual = float(np.linalg.norm(trial_error))
                if trial_residual < residual:
                    current, error, jac, residual = trial, trial_error, trial_jac, trial_residual
                    break
                scale *= 0.5
            else:
                raise self._task_failure(current, residual, iterations, "stalled", frame)
        return FrameTargetResult(
            actuated=current.actuated.copy(),
            q=current.q.copy(),
            iterations=iterations,
            residual=residual,
            kind=kind,
            projection=current,
        )

    def _task(
        self, frame_id: int, kind: str, goal: Any, result: ProjectionResult
    ) -> tuple[FloatArray, FloatArray]:
        """Task error and its Jacobian wrt the actuated values at a projection result.

        Leaves the workspace at ``result.q``.
        """
        G = result.velocity_map
        self._evaluate(result.q)
        placement = pin.updateFramePlacement(self.model, self._data, frame_id)
        if kind == "position":
            J = self._closed_frame_jacobian(frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED, G)
            error: FloatArray = np.array(placement.translation) - goal
            return error, J[:3]
        J = self._closed_frame_jacobian(frame_id, pin.ReferenceFrame.LOCAL, G)
        if kind == "orientation":
            relative = goal.T @ placement.rotation
            error = np.array(pin.log3(relative))
            return error, pin.Jlog3(relative) @ J[3:]
        difference = goal.actInv(placement)
        error = np.array(pin.log6(difference).vector)
        return error, pin.Jlog6(difference) @ J

    def _task_failure(
        self, current: ProjectionResult, residual: float, iterations: int, reason: str, frame: Any
    ) -> ConvergenceError:
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


# ------------------------------------------------------------------------ helpers
def _rank(matrix: FloatArray) -> int:
    """Numerical rank: singular values above RANK_TOL times the largest."""
    if matrix.size == 0:
        return 0
    s = np.linalg.svd(matrix, compute_uv=False)
    if s[0] == 0.0:
        return 0
    return int(np.sum(s > RANK_TOL * s[0]))


def _orientation(passive: FloatArray) -> tuple[FloatArray, float]:
    """An orthonormal basis Q of the range of J_p (full column rank) and sign det(Q^T J_p)."""
    basis, triangle = np.linalg.qr(passive)
    return basis, float(np.sign(np.prod(np.diag(triangle))))


def _indices(starts: Any, sizes: Any, joints: Sequence[int]) -> IntArray:
    return np.array(
        [k for j in joints for k in range(starts[j], starts[j] + sizes[j])], dtype=np.int64
    )


def _actuated_ids(model: pin.Model, actuated: Any) -> list[int]:
    names = [model.names[j] for j in range(1, model.njoints)]
    if isinstance(actuated, (str, bytes)) or not isinstance(actuated, Iterable):
        raise InputError(
            f"actuated must be a sequence of joint names or ids, got {actuated!r}; joints: {names}",
            argument="actuated",
            value=actuated,
        )
    ids: list[int] = []
    for item in actuated:
        if isinstance(item, str):
            if not model.existJointName(item):
                raise InputError(
                    f"actuated joint {item!r} is not a joint of model {model.name!r}; "
                    f"joints: {names}",
                    argument="actuated",
                    value=actuated,
                )
            joint = int(model.getJointId(item))
        elif isinstance(item, (int, np.integer)) and not isinstance(item, bool):
            joint = int(item)
            if not 1 <= joint < model.njoints:
                raise InputError(
                    f"actuated joint id must lie in [1, {model.njoints - 1}] (0 is the "
                    f"universe), got {joint}",
                    argument="actuated",
                    value=actuated,
                )
        else:
            raise InputError(
                f"actuated joints are names (str) or ids (int), got {item!r}",
                argument="actuated",
                value=actuated,
            )
        if joint in ids:
            raise InputError(
                f"actuated joint {model.names[joint]!r} is listed twice",
                argument="actuated",
                value=actuated,
            )
        kind = model.joints[joint].shortname()
        if kind not in EUCLIDEAN_JOINTS:
            raise InputError(
                f"actuated joint {model.names[joint]!r} is a {kind}; actuated joints must "
                f"have plain coordinates ({', '.join(sorted(EUCLIDEAN_JOINTS))})",
                argument="actuated",
                value=actuated,
            )
        ids.append(joint)
    return ids


def _loop_constraints(model: pin.Model, constraint_models: Any) -> pin.StdVec_ConstraintModel:
    """The closures as new-style models in a StdVec (legacy ones converted)."""
    if not isinstance(constraint_models, Iterable) or isinstance(constraint_models, (str, bytes)):
        raise InputError(
            f"constraint_models must be an iterable of {_CONSTRAINT_KINDS}, "
            f"got {type(constraint_models).__name__}",
            argument="constraint_models",
            value=constraint_models,
        )
    result = pin.StdVec_ConstraintModel()
    items = list(constraint_models)
    if not items:
        raise InputError(
            f"constraint_models is empty: give at least one loop closure ({_CONSTRAINT_KINDS})",
            argument="constraint_models",
            value=constraint_models,
        )
    for k, item in enumerate(items):
        inner = item.extract() if isinstance(item, pin.ConstraintModel) else item
        if isinstance(inner, pin.RigidConstraintModel):
            inner = _from_rigid(model, inner, k)
        elif not isinstance(
            inner, (pin.FrameAnchorConstraintModel, pin.PointAnchorConstraintModel)
        ):
            raise InputError(
                f"constraint_models[{k}] is a {type(inner).__name__}, not a loop closure; "
                f"allowed: {_CONSTRAINT_KINDS}",
                argument="constraint_models",
                value=item,
            )
        for joint in (inner.joint1_id, inner.joint2_id):
            if not 0 <= joint < model.njoints:
                raise InputError(
                    f"constraint_models[{k}] ({inner.name!r}) refers to joint {joint}, but "
                    f"model {model.name!r} has joints 0..{model.njoints - 1}: it was built "
                    "for another model",
                    argument="constraint_models",
                    value=item,
                )
        if getattr(inner, "nv", model.nv) != model.nv:
            raise InputError(
                f"constraint_models[{k}] ({inner.name!r}) was built for a model with "
                f"nv = {inner.nv}, this model has nv = {model.nv}",
                argument="constraint_models",
                value=item,
            )
        wrapped = pin.ConstraintModel(inner)
        wrapped.name = inner.name
        result.append(wrapped)
    return result


def _from_rigid(model: pin.Model, rigid: Any, k: int) -> Any:
    """A legacy RigidConstraintModel as the new kind with the same closed set."""
    desired = rigid.desired_contact_placement
    if not desired.isIdentity(1e-14):
        raise InputError(
            f"constraint_models[{k}] ({rigid.name!r}) has a desired_contact_placement other "
            "than the identity; fold it into joint1_placement (joint1_placement * desired)",
            argument="constraint_models",
            value=rigid,
        )
    args = (model, rigid.joint1_id, rigid.joint1_placement, rigid.joint2_id, rigid.joint2_placement)
    if rigid.type == pin.ContactType.CONTACT_6D:
        converted = pin.FrameAnchorConstraintModel(*args)
    elif rigid.type == pin.ContactType.CONTACT_3D:
        converted = pin.PointAnchorConstraintModel(*args)
    else:
        raise InputError(
            f"constraint_models[{k}] ({rigid.name!r}) is a RigidConstraintModel of type "
            f"{rigid.type}; allowed: CONTACT_6D, CONTACT_3D",
            argument="constraint_models",
            value=rigid,
        )
    converted.name = rigid.name
    return converted


def _check_solver_options(tol: Any, max_iterations: Any, damping: Any) -> None:
    if not isinstance(tol, (int, float, np.floating)) or not (0.0 < float(tol) < math.inf):
        raise InputError(
            f"tol must be a number > 0 [m, rad], got {tol!r}", argument="tol", value=tol
        )
    check_count(max_iterations, "max_iterations", 0)
    if not isinstance(damping, (int, float, np.floating)) or not (0.0 <= float(damping) < math.inf):
        raise InputError(
            f"damping must be a finite number >= 0, got {damping!r}",
            argument="damping",
            value=damping,
        )


def _reference_frame(reference_frame: Any) -> pin.ReferenceFrame:
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


def _frame_target(target: Any) -> tuple[str, Any]:
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
        _check_rotation(array[:3, :3])
        return "placement", pin.SE3(array)
    if array.shape == (3, 3):
        _check_rotation(array)
        return "orientation", array
    raise InputError(
        f"target must be a pin.SE3, a (4, 4) or (3, 3) matrix or a point (3,), got shape "
        f"{array.shape}",
        argument="target",
        value=target,
    )


def _check_rotation(R: FloatArray) -> None:
    error = float(np.abs(R.T @ R - np.eye(3)).max())
    if error > 1e-9 or np.linalg.det(R) <= 0.0:
        raise InputError(
            f"target rotation must be orthonormal with det +1 (to 1e-9), got |R^T R - I| = "
            f"{error:.3g}, det = {np.linalg.det(R):.6g}",
            argument="target",
            value=R,
        )
