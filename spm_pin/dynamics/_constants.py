"""Constants of the constrained dynamics: gravity, time step, solver settings, guards.

The tolerances of the loop-closure projection and the thresholds that refuse a time
step, the settings of Pinocchio's proximal constraint solver and of MuJoCo's welds,
and the array types shared by the modules of :mod:`spm_pin.dynamics`.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

__all__ = [
    "CLOSURE_TOL",
    "DEFAULT_DT",
    "DRIFT_TOL",
    "GRAVITY",
    "INTEGRATORS",
    "JUMP_RATIO",
    "MAX_STEP_ANGLE",
    "MUJOCO_INTEGRATORS",
    "MUJOCO_SOLIMP",
    "NEWTON_MAX_ITERATIONS",
    "PROXIMAL_ACCURACY",
    "PROXIMAL_MAX_ITERATIONS",
    "PROXIMAL_MU",
    "RPM",
    "SINGULAR_NEAR",
    "SINGULAR_RCOND",
    "ZERO3",
    "FloatArray",
    "IntArray",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Gravity of an upright robot (z up, base below the platform) [m/s^2].
GRAVITY = (0.0, 0.0, -9.81)
#: Default time step of the simulator [s] (1 kHz).
DEFAULT_DT = 1e-3
#: Integrators of :class:`Simulator`.
INTEGRATORS = ("rk4", "euler")
#: Proximal regularisation mu of ``pin.constraintDynamics``: any value in
#: [1e-12, 1e-4] is exact with the redundant weld rows (mu = 0 gives NaN); at 1e-10 the
#: iterations stop after 2 (sometimes 3) with accelerations exact to ~1e-15 relative.
PROXIMAL_MU = 1e-10
#: Absolute accuracy and iteration cap of the proximal iterations.
PROXIMAL_ACCURACY = 1e-14
PROXIMAL_MAX_ITERATIONS = 20
#: Target of the position projection: Euclidean norm of the stacked weld errors [rad].
CLOSURE_TOL = 1e-12
#: Largest closure residual a simulation may ever carry [rad]; exceeding it raises.
DRIFT_TOL = 1e-10
#: Newton steps of the lean projection before falling back on ClosedLoop.project.
NEWTON_MAX_ITERATIONS = 6
#: Reciprocal condition number of J_p below which a configuration is treated as a
#: parallel (type II) singularity: the passive joints no longer follow the inputs.
SINGULAR_RCOND = 1e-8
#: A Newton projection that moves the passive joints by more than this fraction of the
#: step's own motion is refused (it may have jumped to another assembly mode).
JUMP_RATIO = 0.5
#: Largest joint motion of one rk4 step [rad]; beyond it the step is refused (a motion
#: that fast for the time step is not integrated accurately).
MAX_STEP_ANGLE = 0.1
#: A failed projection after a step that ended with an rcond below this is reported as
#: the motion reaching a parallel singularity (input angles cannot continue it).
SINGULAR_NEAR = 1e-2
#: Default softness of MuJoCo's weld constraints in :func:`simulate_mujoco`:
#: solimp (dmin, dmax, width, midpoint, power).
MUJOCO_SOLIMP = (0.999, 0.9999, 0.001, 0.5, 2.0)
#: Integrators of MuJoCo that :func:`simulate_mujoco` accepts.
MUJOCO_INTEGRATORS = ("euler", "rk4", "implicit", "implicitfast")
#: One revolution per minute [rad/s].
RPM = 2.0 * math.pi / 60.0
#: Three zeros (a torque row without feedforward).
ZERO3 = (0.0, 0.0, 0.0)
