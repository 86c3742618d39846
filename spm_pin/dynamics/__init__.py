r"""Constrained dynamics of the closed-loop SPM: forward, inverse, simulation, servos.

The robot is an open Pinocchio tree of nine revolute joints, q = (u_1, w_1, v_1, ...,
v_3), plus two welds that close legs 2 and 3 on the platform
(:class:`~spm_pin.SPMRobot`). On the tree

    M(q) qdd + h(q, v) = tau + tau_f(v) + J(q)^T lambda,        J(q) v = 0,

with M the mass matrix (armature of the actuated joints included), h the Coriolis,
centrifugal and gravity terms, tau the actuator torques (zero on passive joints),
tau_f the joint friction and lambda the weld multipliers. J has 12 rows of rank 6:
all axes meet at O, so the linear rows of both welds are identically zero and the
closing forces at O are statically indeterminate. Only the six angular rows J_s are
used (chosen once, at construction, as the rows that are not identically zero; they
are independent away from parallel singularities), split into the columns of the
actuated joints (J_a) and of the passive joints (J_p, 6 x 6, invertible away from
type II singularities).

Null-space (reduced) form on the input angles theta. The passive velocities follow
from the actuated ones,

    v = S theta_dot,  S = [I; G] (rows in q order),  G = -J_p^-1 J_a,

and qdd = S theta_ddot + a_b with the bias a_b = [0; -J_p^-1 gamma], gamma = Jdot v
(the constraint acceleration at zero joint acceleration). Multiplying the tree
equation by S^T removes the multipliers (S^T J^T = 0):

    M_r theta_ddot = S^T (tau + tau_f - b),  M_r = S^T M S,  b = rnea(q, v, a_b).

Which formulation, and why:

* Forward dynamics in the simulator and :meth:`ClosedLoopDynamics.forward` (default
  ``method="pinocchio"``): Pinocchio's ``constraintDynamics`` on the two welds
  (legacy 6D models) with proximal settings mu = :data:`PROXIMAL_MU` and zero
  Baumgarte gains, fed with velocities projected so that J v = 0 exactly. With the
  redundant rows the plain KKT system is singular (mu = 0 gives NaN); the proximal
  iterations converge to the minimum-norm multipliers in 2-3 iterations and the
  accelerations agree with the null-space form to about 1e-15 relative (tested). It
  is one C++ call (about 5 us) against a dozen calls for the null-space form from
  Python, which is what a 1 kHz simulator at 50 times real time can afford.
* ``method="nullspace"``: the reduced equations above, exact by construction
  (redundant rows never enter); the reference that the tests hold the other to.
* Inverse dynamics (:meth:`ClosedLoopDynamics.inverse`): the same null-space
  quantities: qdd = S theta_ddot + a_b, tau_tree = rnea(q, v, qdd) - tau_f; the
  passive rows give the weld torques, J_p^T lambda_s = tau_tree,p; the actuated rows
  the actuator torques, tau = tau_tree,a - J_a^T lambda_s (= S^T tau_tree).

Time stepping (:class:`Simulator`): the state is (q, theta_dot) with q closed. Each
step integrates q (with v = S(q) theta_dot) and theta_dot, then projects: the
passive joints are moved by Newton steps on the angular weld rows with theta held
until the closure residual is <= :data:`CLOSURE_TOL` (evaluated at the state that is
kept, every step; a simulation never carries more than :data:`DRIFT_TOL`), and the
velocities are rebuilt from theta_dot with the Jacobian of that state, so J v = 0
again. Integrators:

* ``"rk4"``: classic fourth order on (q, theta_dot), the stages evaluated with the
  projected-velocity vector field; its steps land within 1e-12 of the loops, and a
  frictionless passive motion keeps its energy to about 1e-10 (relative) over 10 s
  at 1 kHz.
* ``"euler"``: semi-implicit Euler (MuJoCo's default scheme), one dynamics evaluation
  per step, first order. The passive joints are predicted on the loops to O(dt^3)
  (q + dt v + dt^2/2 (ddq + S theta_ddot)) plus an extrapolation of the previous
  steps' corrections, so that the projection usually finds the loops closed at its
  first evaluation: one kinematics evaluation and one ``constraintDynamics`` call
  per step.

A step is refused (:class:`~spm_pin.ConvergenceError`, "use a smaller time step")
when closing the loops lands further than :data:`JUMP_RATIO` of the step's motion
from the prediction (it may be another assembly mode) or an rk4 step moves a joint
by more than :data:`MAX_STEP_ANGLE`; a motion that runs into a parallel (type II)
singularity, where input angles stop describing the configuration, ends with
:class:`~spm_pin.SingularityError`. Actuator torques are held constant over a step
(a zero-order hold, like a digital servo loop at the step rate).

Servos (:class:`ServoModel`, :data:`XM540_W150`): a PD position loop whose torque is
clipped to the DC-motor envelope: the torque-speed line between the stall torque at
rest and zero torque at the no-load speed (voltage limit), and the stall torque as a
current limit (braking included).
"""

from __future__ import annotations

from ._checks import LIMITS as LIMITS
from ._constants import (
    CLOSURE_TOL,
    DEFAULT_DT,
    DRIFT_TOL,
    GRAVITY,
    INTEGRATORS,
    PROXIMAL_MU,
)
from ._constants import JUMP_RATIO as JUMP_RATIO
from ._constants import MAX_STEP_ANGLE as MAX_STEP_ANGLE
from ._constants import MUJOCO_SOLIMP as MUJOCO_SOLIMP
from ._constants import NEWTON_MAX_ITERATIONS as NEWTON_MAX_ITERATIONS
from ._constants import PROXIMAL_ACCURACY as PROXIMAL_ACCURACY
from ._constants import PROXIMAL_MAX_ITERATIONS as PROXIMAL_MAX_ITERATIONS
from ._constants import SINGULAR_NEAR as SINGULAR_NEAR
from ._constants import SINGULAR_RCOND as SINGULAR_RCOND
from ._constants import FloatArray as FloatArray
from ._constants import IntArray as IntArray
from .closed_loop import (
    ClosedLoopDynamics,
    ForwardDynamicsResult,
    InverseDynamicsResult,
    forward_dynamics,
    holding_torques,
    inverse_dynamics,
)
from .mujoco import simulate_mujoco
from .plots import plot_torques
from .reduced import REDUCED_CLOSURE_TOL, ReducedDynamics, ReducedStep, ReducedTerms
from .servo import XM540_W150, JointFriction, ServoCheck, ServoModel, check_servo
from .simulator import Controller as Controller
from .simulator import SimulationResult, Simulator
from .tracking import TrackingResult, track_goals
from .trajectory import ServoController, Trajectory

__all__ = [
    "CLOSURE_TOL",
    "DEFAULT_DT",
    "DRIFT_TOL",
    "GRAVITY",
    "INTEGRATORS",
    "PROXIMAL_MU",
    "REDUCED_CLOSURE_TOL",
    "XM540_W150",
    "ClosedLoopDynamics",
    "ForwardDynamicsResult",
    "InverseDynamicsResult",
    "JointFriction",
    "ReducedDynamics",
    "ReducedStep",
    "ReducedTerms",
    "ServoCheck",
    "ServoController",
    "ServoModel",
    "SimulationResult",
    "Simulator",
    "TrackingResult",
    "Trajectory",
    "check_servo",
    "forward_dynamics",
    "holding_torques",
    "inverse_dynamics",
    "plot_torques",
    "simulate_mujoco",
    "track_goals",
]
