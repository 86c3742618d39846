r"""Calibration: identify the model of a real SPM from readings of the prototype.

A model matches the prototype only once it knows the encoders' zero offsets, the link
angles as printed and assembled, and how the orientation sensor sits on the platform.
This module identifies them from *readings*: at each of N poses, the three servo
positions and a measurement of the platform orientation.

Measurement model
-----------------
For reading k with servo angles r_k (the servo positions as input-shaft angles, see
:class:`JointConvention`), the model's input angles are

    theta_k = r_k - o,        o = (offset_1, offset_2, offset_3)  [rad]

so ``offset_i`` is what servo i reads when input i is at the model's zero (home).
The platform rotation is R(theta_k; alpha1, alpha2, beta), the home assembly mode of
:func:`spm_pin.forward_kinematics`. The sensor measures either

* its own orientation (``kind="quaternion"``: an IMU or a motion-capture rigid body):
  R_meas = R_ref R R_mount, where R_mount is the sensor frame in the platform frame
  (the mounting rotation) and R_ref the world (base) frame in the sensor's reference
  frame; or
* the platform joint axes v_1, v_2, v_3 (``kind="axes"``, unit vectors in the sensor's
  reference frame): v_i,meas = R_ref R v_i0(beta).

The parameters, all angles in radians, are

=============================  ==========================================================
``offset_1..3``                encoder zero offsets (absolute)
``alpha1, alpha2, beta``       link angles of :class:`~spm_pin.SPMDesign` (absolute)
``mount_x, mount_y, mount_z``  rotation vector of the mounting correction:
                               R_mount = R_mount,start exp([mount])
``ref_x, ref_y, ref_z``        rotation vector of the reference correction:
                               R_ref = exp([ref]) R_ref,start
=============================  ==========================================================

Residuals [rad]: for quaternion readings 2 vec(q(E)) with E = R_pred^T R_meas (the
rotation vector of the error for small errors, 3 per reading); for axis readings
the components of v_i,meas - v_i,pred across v_i,meas (in a fixed basis
perpendicular to it: 2 per axis, 6 per reading). Their Jacobian is analytic: differentiating the
loop closures w_i . v_i = cos alpha2 (with w_i0 a function of alpha1, alpha2, beta)
gives A dphi = K dp, with A the rows a_i = w_i x v_i of :func:`spm_pin.jacobian` and
dphi the world-frame rotation increment of the platform.

Identification is :func:`scipy.optimize.least_squares` (trust-region reflective) with
a robust loss; covariances are Huber's for M-estimates,
[sum psi(r)^2 / (m - n)] / mean(psi'(r))^2 (J^T J)^-1 with psi(r) = r rho'(r^2)
(s^2 (J^T J)^-1 for the linear loss), and intervals use Student's t. Before solving,
the parameters that the readings cannot separate are found from the column-normalised
Jacobian (its numerical rank, greedily in the order of :data:`PARAMETER_NAMES`); they
keep their starting values and an :class:`IdentifiabilityWarning` names them.

Readings file (CSV)
-------------------
Comma-separated, one reading per row, a header row of column names carrying units;
lines starting with ``#`` are comments, ``# key = value`` comments before the header
are settings (:class:`JointConvention`)::

    # spm-pin calibration readings
    # ticks_per_turn = 4096
    # direction = 1, 1, 1
    # zero_offset = 2048, 2048, 2048
    # gear_ratio = 1, 1, 1
    pose,servo1_ticks,servo2_ticks,servo3_ticks,qw,qx,qy,qz
    1,2071,2113,1993,0.99,0.01,-0.12,0.03

``direction``, ``zero_offset`` [counts] and ``gear_ratio`` are the keys, and the
convention, of the ``[[joints]]`` tables of a servo configuration
(:class:`spm_pin.hardware.HardwareConfig`); settings the file does not give come from
the ``joints`` argument of :func:`load_readings` (e.g.
:meth:`JointConvention.from_servo_config`), else the defaults of :class:`JointConvention`.
``zero_offset_ticks``, the older name of ``zero_offset``, is still read.

Columns (any order):

* servo positions, all three in one unit: ``servo1_ticks..servo3_ticks`` (raw
  encoder counts, whole numbers; converted with the settings), ``servo1_deg..`` or
  ``servo1_rad..`` (input-shaft angles);
* one orientation group: ``qw, qx, qy, qz`` (unit quaternion, scalar first, Hamilton,
  sensor frame to reference frame), ``roll_deg, pitch_deg, yaw_deg`` (or ``_rad``;
  R = Rz(yaw) Ry(pitch) Rx(roll)), or ``v1_x, v1_y, v1_z, v2_x, .., v3_z`` (measured
  joint axes, unit vectors);
* optional ``pose`` (a label), ``time_s``, and any ``x_*`` column (kept as text).
"""

from __future__ import annotations

from ._constants import (
    DEFAULT_PARAMETERS,
    PARAMETER_GROUPS,
    PARAMETER_NAMES,
    TICKS_PER_TURN,
    IdentifiabilityWarning,
)
from ._constants import MAX_CONDITION as MAX_CONDITION
from ._constants import MAX_CORRELATION as MAX_CORRELATION
from ._constants import RANK_TOL as RANK_TOL
from ._model import Model as _Model  # noqa: F401 (read by the tests)
from ._model import geometry as _geometry  # noqa: F401 (read by the tests)
from .convention import JointConvention
from .identifiability import Identifiability, Observability, observability
from .parameters import CalibrationParameters
from .poses import PosePlan, load_poses, plan_poses
from .readings import Readings, load_readings, parse_readings
from .result import CalibrationResult, ParameterEstimate
from .solve import calibrate
from .synthetic import SyntheticReadings, synthetic_readings

__all__ = [
    "DEFAULT_PARAMETERS",
    "PARAMETER_GROUPS",
    "PARAMETER_NAMES",
    "TICKS_PER_TURN",
    "CalibrationParameters",
    "CalibrationResult",
    "Identifiability",
    "IdentifiabilityWarning",
    "JointConvention",
    "Observability",
    "ParameterEstimate",
    "PosePlan",
    "Readings",
    "SyntheticReadings",
    "calibrate",
    "load_poses",
    "load_readings",
    "observability",
    "parse_readings",
    "plan_poses",
    "synthetic_readings",
]
