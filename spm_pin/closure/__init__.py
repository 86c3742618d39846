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

from ._constants import (
    CLOSED_TOL,
    CONTINUATION_MODES,
    CONTINUATION_STEP,
    CORRECTOR_RATIO,
    DEFAULT_DAMPING,
    DEFAULT_MAX_HALVINGS,
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_TOL,
    FOLLOW_MAX_ITERATIONS,
    RANK_TOL,
)
from ._constants import TARGET_LIMIT as TARGET_LIMIT
from ._constraints import EUCLIDEAN_JOINTS
from .loop import ClosedLoop
from .results import FrameTargetResult, PathResult, ProjectionResult
from .results import Start as Start

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
