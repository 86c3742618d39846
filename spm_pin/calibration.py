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

import csv
import dataclasses
import io
import math
import os
import re
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .design import SPMDesign, _read_text
from .errors import ConvergenceError, DesignError, FileFormatError, InputError
from .kinematics import forward_kinematics, inverse_kinematics, jacobian
from .kinematics._common import as_rotation, check_design, cross, rotate_about
from .rotations import matrix_from_quaternion, matrix_from_rpy, quaternion_from_matrix

if TYPE_CHECKING:  # pragma: no cover
    from scipy.optimize import OptimizeResult

    from .hardware.config import HardwareConfig

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

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]

#: Encoder counts per turn of the Dynamixel XM540 (0.088 deg per count): the pulses
#: per servo turn of :mod:`spm_pin.hardware`.
TICKS_PER_TURN = 4096

#: Every parameter that can be identified, in the order in which they are kept free
#: when the readings cannot separate some of them.
PARAMETER_NAMES: tuple[str, ...] = (
    "offset_1",
    "offset_2",
    "offset_3",
    "alpha1",
    "alpha2",
    "beta",
    "mount_x",
    "mount_y",
    "mount_z",
    "ref_x",
    "ref_y",
    "ref_z",
)

#: Group names accepted wherever parameter names are.
PARAMETER_GROUPS: dict[str, tuple[str, ...]] = {
    "offsets": PARAMETER_NAMES[0:3],
    "links": PARAMETER_NAMES[3:6],
    "mount": PARAMETER_NAMES[6:9],
    "ref": PARAMETER_NAMES[9:12],
}

#: Parameters identified by default, per kind of orientation reading.
DEFAULT_PARAMETERS: dict[str, tuple[str, ...]] = {
    "quaternion": PARAMETER_NAMES[0:9],
    "axes": PARAMETER_NAMES[0:6],
}

#: Residual components per reading, per kind.
_COMPONENTS = {"quaternion": 3, "axes": 6}

#: Robust losses of scipy.optimize.least_squares and their IRLS weights rho'(z), z = (r/f)^2.
_LOSS_WEIGHTS: dict[str, Callable[[FloatArray], FloatArray]] = {
    "linear": lambda z: np.ones_like(z),
    "soft_l1": lambda z: 1.0 / np.sqrt(1.0 + z),
    "huber": lambda z: np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1.0))),
    "cauchy": lambda z: 1.0 / (1.0 + z),
    "arctan": lambda z: 1.0 / (1.0 + z * z),
}

#: Their psi'(r) = d(r rho'(z))/dr = rho'(z) + 2 z rho''(z), for the covariance.
_LOSS_SLOPES: dict[str, Callable[[FloatArray], FloatArray]] = {
    "linear": lambda z: np.ones_like(z),
    "soft_l1": lambda z: (1.0 + z) ** -1.5,
    "huber": lambda z: np.where(z <= 1.0, 1.0, 0.0),
    "cauchy": lambda z: (1.0 - z) / (1.0 + z) ** 2,
    "arctan": lambda z: (1.0 - 3.0 * z * z) / (1.0 + z * z) ** 2,
}

#: Relative singular value (column-normalised Jacobian) at or below which a direction
#: of the parameter space is not identifiable.
RANK_TOL = 1e-6
#: Condition number (column-normalised Jacobian) above which the identification is
#: reported as poorly conditioned.
MAX_CONDITION = 1000.0
#: |correlation| at or above which two estimates are reported as not separated.
MAX_CORRELATION = 0.99
#: Robust loss scale in units of the noise level.
_LOSS_SCALE = 3.0
#: Residual [rad] given to a reading the candidate model cannot assemble.
_UNREACHABLE_RESIDUAL = 1.0
#: A measured quaternion or axis may differ from unit length by this much.
_UNIT_TOL = 0.01
#: Probability of a reading flagged as an outlier by chance.
_OUTLIER_P = 1e-3
#: Parameters whose column of the Jacobian is this small (relative) have no effect.
_NO_EFFECT = 1e-10

_SERVO_UNITS = ("ticks", "deg", "rad")
_ANGLE_UNITS = ("deg", "rad")


class IdentifiabilityWarning(UserWarning):
    """The readings cannot separate some parameters (or only poorly).

    The identified values of the other parameters are real estimates; the ones named
    in the warning keep their starting values and have infinite intervals.
    """


# =============================================================================== joints
@dataclasses.dataclass(frozen=True)
class JointConvention:
    """How raw encoder counts become input-shaft angles (one entry per servo).

    ``reading_i [rad] = direction_i * (ticks_i - zero_offset_ticks_i) * 2 pi /
    (ticks_per_turn * gear_ratio_i)``. These are the per-joint settings of a servo
    configuration: direction +1 or -1, gear ratio (servo turns per input-shaft turn,
    1 for the prototype's 1:1 gears) and the zero offset in counts. It is the formula
    of :class:`spm_pin.hardware.JointConfig` (``theta_i = direction * (pulses -
    zero_offset - 4096 k_i) * 2 pi / 4096 / gear_ratio``) for ticks_per_turn = 4096,
    with the whole servo turns k_i left in the reading. With 1:1 gears they change
    nothing (a servo turn is a turn of the input, and the kinematics repeat every
    turn); with other gears, take all readings without the servos losing their turn
    count (no power cycle or reboot). In a readings file the zero offset is the
    setting ``zero_offset``, as in the servo configuration.

    Attributes:
        ticks_per_turn: Encoder counts per servo turn (4096 for the XM540).
        direction: +1 or -1 per servo.
        zero_offset_ticks: Counts at which the input angle reads zero (need not be
            whole: :meth:`with_offsets` gives the exact value).
        gear_ratio: Servo turns per input-shaft turn (> 0).
    """

    ticks_per_turn: int = TICKS_PER_TURN
    direction: tuple[int, int, int] = (1, 1, 1)
    zero_offset_ticks: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gear_ratio: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        tpt = self.ticks_per_turn
        if isinstance(tpt, bool) or not isinstance(tpt, (int, np.integer)) or tpt < 1:
            raise InputError(
                f"ticks_per_turn must be a positive whole number, got {tpt!r}",
                argument="ticks_per_turn",
                value=tpt,
            )
        object.__setattr__(self, "ticks_per_turn", int(tpt))
        direction = _triple(self.direction, "direction")
        if any(d not in (1.0, -1.0) for d in direction):
            raise InputError(
                f"direction must hold +1 or -1 per servo, got {self.direction!r}",
                argument="direction",
                value=self.direction,
            )
        object.__setattr__(self, "direction", tuple(int(d) for d in direction))
        object.__setattr__(
            self, "zero_offset_ticks", _triple(self.zero_offset_ticks, "zero_offset_ticks")
        )
        gear = _triple(self.gear_ratio, "gear_ratio")
        if any(g <= 0 for g in gear):
            raise InputError(
                f"gear_ratio must be positive, got {self.gear_ratio!r}",
                argument="gear_ratio",
                value=self.gear_ratio,
            )
        object.__setattr__(self, "gear_ratio", gear)

    @property
    def radians_per_tick(self) -> FloatArray:
        """Input-shaft angle per count [rad], per servo, with its sign (3,)."""
        result: FloatArray = (
            np.asarray(self.direction, dtype=float)
            * 2.0
            * math.pi
            / (self.ticks_per_turn * np.asarray(self.gear_ratio))
        )
        return result

    def ticks_to_angle(self, ticks: npt.ArrayLike) -> FloatArray:
        """Input-shaft angles [rad] (..., 3) from encoder counts (..., 3)."""
        counts = np.asarray(ticks, dtype=float)
        result: FloatArray = (counts - np.asarray(self.zero_offset_ticks)) * self.radians_per_tick
        return result

    def angle_to_ticks(self, angle: npt.ArrayLike) -> FloatArray:
        """Encoder counts (not rounded) (..., 3) at input-shaft angles [rad] (..., 3)."""
        result: FloatArray = (
            np.asarray(self.zero_offset_ticks)
            + np.asarray(angle, dtype=float) / self.radians_per_tick
        )
        return result

    def with_offsets(self, offsets: npt.ArrayLike) -> JointConvention:
        """The convention whose zero reads the model's zero, given identified offsets [rad].

        With ``offset_i`` the reading at the model's zero, the new zero offset is
        ``zero_offset_ticks_i + offset_i / radians_per_tick_i`` (exact, not rounded).
        """
        shift = np.asarray(offsets, dtype=float) / self.radians_per_tick
        zero = np.asarray(self.zero_offset_ticks) + shift
        return dataclasses.replace(
            self, zero_offset_ticks=(float(zero[0]), float(zero[1]), float(zero[2]))
        )

    @classmethod
    def from_servo_config(cls, config: HardwareConfig) -> JointConvention:
        """The convention of a servo configuration's joints (4096 pulses per turn).

        Readings of the servos' Present Position [pulses] convert to the very angles
        the hardware layer uses (up to whole turns); load them with
        ``load_readings(path, joints=JointConvention.from_servo_config(config))``.

        Args:
            config: A :class:`spm_pin.hardware.HardwareConfig`.
        """
        hardware_config = _hardware_config_class()
        if not isinstance(config, hardware_config):
            raise InputError(
                f"config must be a spm_pin.hardware.HardwareConfig, got {type(config).__name__}",
                argument="config",
                value=config,
            )
        u1, u2, u3 = config.joints
        return cls(
            ticks_per_turn=TICKS_PER_TURN,
            direction=(u1.direction, u2.direction, u3.direction),
            zero_offset_ticks=(float(u1.zero_offset), float(u2.zero_offset), float(u3.zero_offset)),
            gear_ratio=(float(u1.gear_ratio), float(u2.gear_ratio), float(u3.gear_ratio)),
        )


def _hardware_config_class() -> type[HardwareConfig]:
    """spm_pin.hardware.HardwareConfig, imported when first needed.

    The hardware package imports its SDK (dynamixel-sdk, the ``hardware`` extra) only
    when a port is opened, so the configuration works without it.
    """
    from .hardware.config import HardwareConfig

    return HardwareConfig


def _triple(value: Any, name: str) -> tuple[float, float, float]:
    try:
        array = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(
            f"{name} must be 3 numbers, got {value!r}", argument=name, value=value
        ) from exc
    if array.size == 1:
        array = np.repeat(array, 3)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise InputError(
            f"{name} must be 3 finite numbers, got {value!r}", argument=name, value=value
        )
    return (float(array[0]), float(array[1]), float(array[2]))


# ============================================================================= readings
@dataclasses.dataclass(frozen=True, eq=False)
class Readings:
    """Readings of the prototype, one per pose.

    Attributes:
        theta: Servo positions as input-shaft angles [rad], (N, 3), before the zero
            offsets (the model's input is ``theta - offsets``).
        orientation: (N, 3, 3): for ``kind="quaternion"`` the measured sensor rotation
            R_meas (sensor frame to reference frame); for ``kind="axes"`` the measured
            joint axes v_1..v_3 as rows.
        kind: ``"quaternion"`` or ``"axes"``.
        lines: (N,) line of each reading in its file (1-based), or 1..N.
        labels: The ``pose`` column (empty strings when absent).
        joints: Encoder conventions (used for tick columns and to express the
            identified offsets in counts).
        servo_unit: Unit of the servo columns in the file: ``"ticks"``, ``"deg"``, ``"rad"``.
        source: The file, when read from one.
        extra: ``time_s`` and ``x_*`` columns, as text, by column name.
    """

    theta: FloatArray
    orientation: FloatArray
    kind: str = "quaternion"
    lines: IntArray | None = None
    labels: tuple[str, ...] = ()
    joints: JointConvention = dataclasses.field(default_factory=JointConvention)
    servo_unit: str = "deg"
    source: str | None = None
    extra: Mapping[str, tuple[str, ...]] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in _COMPONENTS:
            raise InputError(
                f"kind must be one of {sorted(_COMPONENTS)}, got {self.kind!r}",
                argument="kind",
                value=self.kind,
            )
        try:
            theta = np.array(self.theta, dtype=float)
            orientation = np.array(self.orientation, dtype=float)
        except (TypeError, ValueError, OverflowError) as exc:
            raise InputError(
                "theta and orientation must be numeric arrays", argument="theta"
            ) from exc
        if theta.ndim != 2 or theta.shape[1] != 3 or theta.shape[0] < 1:
            raise InputError(
                f"theta must have shape (N, 3) with N >= 1, got {theta.shape}",
                argument="theta",
                value=self.theta,
            )
        n = theta.shape[0]
        if orientation.shape != (n, 3, 3):
            raise InputError(
                f"orientation must have shape ({n}, 3, 3), got {orientation.shape}",
                argument="orientation",
                value=self.orientation,
            )
        for name, array in (("theta", theta), ("orientation", orientation)):
            if not np.all(np.isfinite(array)):
                bad = int(np.argwhere(~np.isfinite(array.reshape(n, -1)))[0, 0])
                raise InputError(
                    f"{name} must be finite; reading {bad} is not",
                    argument=name,
                    value=array[bad],
                )
        if self.kind == "quaternion":
            as_rotation(orientation, "orientation")
        else:
            norm = np.linalg.norm(orientation, axis=-1)
            if np.any(np.abs(norm - 1.0) > _UNIT_TOL):
                bad = int(np.argwhere(np.abs(norm - 1.0) > _UNIT_TOL)[0, 0])
                raise InputError(
                    f"measured axes must be unit vectors; reading {bad} has norms "
                    f"{np.round(norm[bad], 6).tolist()}",
                    argument="orientation",
                    value=orientation[bad],
                )
            orientation = orientation / norm[..., None]
        lines = np.arange(1, n + 1) if self.lines is None else np.asarray(self.lines, dtype=int)
        if lines.shape != (n,):
            raise InputError(
                f"lines must have shape ({n},), got {lines.shape}", argument="lines", value=lines
            )
        labels = tuple(str(x) for x in self.labels) if self.labels else ("",) * n
        if len(labels) != n:
            raise InputError(f"labels must hold {n} entries, got {len(labels)}", argument="labels")
        if self.servo_unit not in _SERVO_UNITS:
            raise InputError(
                f"servo_unit must be one of {list(_SERVO_UNITS)}, got {self.servo_unit!r}",
                argument="servo_unit",
                value=self.servo_unit,
            )
        if not isinstance(self.joints, JointConvention):
            raise InputError("joints must be a JointConvention", argument="joints")
        for array in (theta, orientation, lines):
            array.setflags(write=False)
        object.__setattr__(self, "theta", theta)
        object.__setattr__(self, "orientation", orientation)
        object.__setattr__(self, "lines", lines)
        object.__setattr__(self, "labels", labels)
        object.__setattr__(self, "extra", dict(self.extra))

    def __len__(self) -> int:
        return int(self.theta.shape[0])

    @classmethod
    def from_quaternions(
        cls, theta: npt.ArrayLike, quaternions: npt.ArrayLike, **kwargs: Any
    ) -> Readings:
        """Readings from input-shaft angles [rad] (N, 3) and quaternions (N, 4) (w, x, y, z)."""
        q = np.asarray(quaternions, dtype=float)
        norm = np.linalg.norm(q, axis=-1) if q.ndim == 2 else np.array([np.nan])
        if q.ndim != 2 or q.shape[1] != 4 or np.any(~(np.abs(norm - 1.0) <= _UNIT_TOL)):
            raise InputError(
                "quaternions must be unit quaternions (w, x, y, z) of shape (N, 4)",
                argument="quaternions",
                value=quaternions,
            )
        return cls(theta=np.asarray(theta), orientation=matrix_from_quaternion(q), **kwargs)

    @property
    def quaternions(self) -> FloatArray:
        """Measured quaternions (N, 4), (w, x, y, z) with w >= 0 (quaternion readings)."""
        if self.kind != "quaternion":
            raise InputError("axis readings have no quaternion", argument="kind", value=self.kind)
        return quaternion_from_matrix(self.orientation)

    def subset(self, index: npt.ArrayLike) -> Readings:
        """The readings selected by ``index`` (indices or a boolean mask)."""
        pick = np.arange(len(self))[np.asarray(index)]
        return dataclasses.replace(
            self,
            theta=self.theta[pick],
            orientation=self.orientation[pick],
            lines=None if self.lines is None else self.lines[pick],
            labels=tuple(self.labels[i] for i in pick),
            extra={k: tuple(v[i] for i in pick) for k, v in self.extra.items()},
        )

    def to_csv(
        self,
        path: str | Path | None = None,
        *,
        unit: str | None = None,
        comments: Sequence[str] = (),
    ) -> str:
        """The readings as CSV text (see the module docstring); also written to ``path``.

        Args:
            path: File to write, or None.
            unit: Unit of the servo columns: ``"ticks"`` (rounded to whole counts),
                ``"deg"`` or ``"rad"``; default: the unit they were read in.
            comments: Lines of text for the top of the file (no ``key = value`` lines,
                which would read as settings).
        """
        unit = self.servo_unit if unit is None else unit
        if unit not in _SERVO_UNITS:
            raise InputError(
                f"unit must be one of {list(_SERVO_UNITS)}, got {unit!r}", argument="unit"
            )
        lines = [str(c) for c in comments]
        for line in lines:
            if "\n" in line or _SETTING.match("# " + line):
                raise InputError(
                    f"comment {line!r} would not read back as a comment (one line, no "
                    "'key = value')",
                    argument="comments",
                    value=line,
                )
        j = self.joints
        out = io.StringIO()
        out.write("# spm-pin calibration readings\n")
        for line in lines:
            out.write(f"# {line}\n")
        out.write(f"# ticks_per_turn = {j.ticks_per_turn}\n")
        out.write(f"# direction = {', '.join(str(d) for d in j.direction)}\n")
        out.write(f"# zero_offset = {', '.join(_fmt(z) for z in j.zero_offset_ticks)}\n")
        out.write(f"# gear_ratio = {', '.join(_fmt(g) for g in j.gear_ratio)}\n")
        servo = [f"servo{i}_{unit}" for i in (1, 2, 3)]
        if self.kind == "quaternion":
            orient = ["qw", "qx", "qy", "qz"]
            values = self.quaternions
        else:
            orient = [f"v{i}_{c}" for i in (1, 2, 3) for c in "xyz"]
            values = self.orientation.reshape(-1, 9)
        extra = list(self.extra)
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(["pose", *servo, *orient, *extra])
        if unit == "ticks":
            counts = np.rint(j.angle_to_ticks(self.theta)).astype(np.int64)
            servo_text = [[str(int(c)) for c in row] for row in counts]
        else:
            angles = np.degrees(self.theta) if unit == "deg" else self.theta
            servo_text = [[_fmt(a) for a in row] for row in angles]
        for k in range(len(self)):
            label = self.labels[k] or str(k + 1)
            row = [label, *servo_text[k], *(_fmt(x) for x in values[k])]
            row += [self.extra[name][k] for name in extra]
            writer.writerow(row)
        text = out.getvalue()
        if path is not None:
            Path(path).write_text(text, encoding="utf-8")
        return text


def _fmt(value: float) -> str:
    """A float with 12 significant digits (round-trips what the readings hold)."""
    return f"{float(value) + 0.0:.12g}"


# ----------------------------------------------------------------------- CSV parsing
_SETTING = re.compile(r"^#\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*(.*?)\s*$")
_SERVO_COLUMN = re.compile(r"^servo([123])_(.+)$")
_EULER_COLUMN = re.compile(r"^(roll|pitch|yaw)_(.+)$")
_QUATERNION = ("qw", "qx", "qy", "qz")
_AXES = tuple(f"v{i}_{c}" for i in (1, 2, 3) for c in "xyz")
_SETTINGS = ("ticks_per_turn", "direction", "zero_offset", "gear_ratio")
#: Older names of settings, still read.
_SETTING_ALIASES = {"zero_offset_ticks": "zero_offset"}
#: JointConvention field of each setting.
_SETTING_FIELDS = {
    "ticks_per_turn": "ticks_per_turn",
    "direction": "direction",
    "zero_offset": "zero_offset_ticks",
    "gear_ratio": "gear_ratio",
}


def _allowed_columns() -> str:
    return (
        "servo1_<unit>..servo3_<unit> with unit ticks, deg or rad; qw, qx, qy, qz | "
        "roll_<unit>, pitch_<unit>, yaw_<unit> with unit deg or rad | v1_x..v3_z; "
        "optional pose, time_s, x_*"
    )


def parse_readings(
    text: str, *, source: str | None = None, joints: JointConvention | None = None
) -> Readings:
    """Parse readings CSV text (format in the module docstring).

    Args:
        text: The file's content.
        source: Name used in error messages (the path).
        joints: The encoder convention for the settings the file does not give
            (``ticks_per_turn``, ``direction``, ``zero_offset``, ``gear_ratio``; each
            one the file gives wins), e.g. :meth:`JointConvention.from_servo_config`.
            Default: :class:`JointConvention` (4096 per turn, direction +1, zero at 0
            counts, gear ratio 1).

    Raises:
        FileFormatError: with ``error.line`` (1-based) and the column: unknown or
            missing columns, mixed or unknown units, non-numeric, NaN or infinite
            values, fractional ticks, non-unit quaternions or axes, bad settings.
    """
    settings: dict[str, str] = {}
    setting_lines: dict[str, int] = {}
    header: list[str] | None = None
    header_line = 0
    rows: list[tuple[int, list[str]]] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            match = _SETTING.match(line)
            if match is None:
                continue
            if header is not None:
                raise FileFormatError(
                    f"setting {match.group(1)!r} after the header row (line {header_line}); "
                    "settings go before the header",
                    path=source,
                    line=number,
                )
            key = _SETTING_ALIASES.get(match.group(1), match.group(1))
            if key not in _SETTINGS:
                raise FileFormatError(
                    f"unknown setting {key!r}; allowed: {list(_SETTINGS)}", path=source, line=number
                )
            if key in settings:
                raise FileFormatError(
                    f"setting {key!r} given twice (first on line {setting_lines[key]})",
                    path=source,
                    line=number,
                )
            settings[key] = match.group(2)
            setting_lines[key] = number
            continue
        fields = [f.strip() for f in next(csv.reader([line]))]
        if header is None:
            header, header_line = fields, number
        else:
            rows.append((number, fields))
    if header is None:
        raise FileFormatError("no header row: the file holds no columns", path=source)
    if joints is not None and not isinstance(joints, JointConvention):
        raise InputError(
            f"joints must be a JointConvention, got {type(joints).__name__}",
            argument="joints",
            value=joints,
        )
    convention = _parse_settings(settings, setting_lines, source, joints)
    columns = _parse_header(header, header_line, source)
    if not rows:
        raise FileFormatError(
            f"no readings: the header (line {header_line}) is followed by no data row",
            path=source,
        )
    n = len(rows)
    values: dict[str, FloatArray] = {}
    text_columns: dict[str, list[str]] = {name: [] for name in columns.text}
    for name in columns.numeric:
        values[name] = np.empty(n)
    for k, (number, fields) in enumerate(rows):
        if len(fields) != len(header):
            raise FileFormatError(
                f"{len(fields)} values, but the header (line {header_line}) has "
                f"{len(header)} columns",
                path=source,
                line=number,
            )
        for name, index in columns.index.items():
            field = fields[index]
            if name in text_columns:
                text_columns[name].append(field)
                continue
            values[name][k] = _number(field, name, number, source)
    servo = np.stack([values[c] for c in columns.servo], axis=1)
    lines = np.array([number for number, _ in rows])
    if columns.servo_unit == "ticks":
        fractional = np.nonzero(servo != np.round(servo))
        if fractional[0].size:
            k, i = int(fractional[0][0]), int(fractional[1][0])
            raise FileFormatError(
                f"column {columns.servo[i]}: {servo[k, i]!r} is not a whole number of "
                "encoder counts (angles go in servo<i>_deg or servo<i>_rad columns)",
                path=source,
                line=int(lines[k]),
            )
        theta = convention.ticks_to_angle(servo)
    elif columns.servo_unit == "deg":
        theta = np.radians(servo)
    else:
        theta = servo
    orientation = _orientation(values, columns, lines, source)
    labels = tuple(text_columns.get("pose", ()))
    extra = {k: tuple(v) for k, v in text_columns.items() if k != "pose"}
    return Readings(
        theta=theta,
        orientation=orientation,
        kind=columns.kind,
        lines=lines,
        labels=labels,
        joints=convention,
        servo_unit=columns.servo_unit,
        source=source,
        extra=extra,
    )


def load_readings(path: str | Path, *, joints: JointConvention | None = None) -> Readings:
    """Read a readings CSV file (see :func:`parse_readings`, also for ``joints``)."""
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(
            f"path must be a file path (str or Path), got {type(path).__name__}",
            argument="path",
            value=path,
        )
    text, source = _read_text(path, "readings file")
    return parse_readings(text, source=source, joints=joints)


def _number(field: str, column: str, line: int, source: str | None) -> float:
    if field == "":
        raise FileFormatError(f"column {column}: missing value", path=source, line=line)
    try:
        value = float(field)
    except ValueError:
        raise FileFormatError(
            f"column {column}: {field!r} is not a number", path=source, line=line
        ) from None
    if not math.isfinite(value):
        raise FileFormatError(
            f"column {column}: {field!r} is not allowed; values must be finite numbers",
            path=source,
            line=line,
        )
    return value


def _parse_settings(
    settings: Mapping[str, str],
    lines: Mapping[str, int],
    source: str | None,
    default: JointConvention | None = None,
) -> JointConvention:
    kwargs: dict[str, Any] = {}
    for key, text in settings.items():
        field = _SETTING_FIELDS[key]
        parts = [p for p in re.split(r"[,\s]+", text) if p]
        try:
            numbers = [float(p) for p in parts]
        except ValueError:
            raise FileFormatError(
                f"setting {key}: {text!r} is not a list of numbers", path=source, line=lines[key]
            ) from None
        if key == "ticks_per_turn":
            if len(numbers) != 1 or numbers[0] != int(numbers[0]) or numbers[0] < 1:
                raise FileFormatError(
                    f"setting ticks_per_turn must be one positive whole number, got {text!r}",
                    path=source,
                    line=lines[key],
                )
            kwargs[field] = int(numbers[0])
        else:
            if len(numbers) not in (1, 3):
                raise FileFormatError(
                    f"setting {key} needs 1 or 3 values (one per servo), got {len(numbers)}",
                    path=source,
                    line=lines[key],
                )
            kwargs[field] = tuple(numbers) if len(numbers) == 3 else (numbers[0],) * 3
    base = default or JointConvention()
    tpt = kwargs.get("ticks_per_turn", base.ticks_per_turn)
    if "zero_offset_ticks" not in kwargs and tpt != base.ticks_per_turn:
        # The default's zero offsets, in the file's counts.
        kwargs["zero_offset_ticks"] = tuple(
            z * tpt / base.ticks_per_turn for z in base.zero_offset_ticks
        )
    try:
        return dataclasses.replace(base, **kwargs)
    except InputError as exc:
        key = next((k for k, f in _SETTING_FIELDS.items() if f == exc.argument), "")
        message = str(exc).replace("zero_offset_ticks", "zero_offset")
        raise FileFormatError(f"setting {message}", path=source, line=lines.get(key)) from exc


@dataclasses.dataclass
class _Columns:
    index: dict[str, int]
    numeric: list[str]
    text: list[str]
    servo: list[str]
    servo_unit: str
    kind: str
    orientation: list[str]
    euler_unit: str | None


def _parse_header(header: Sequence[str], line: int, source: str | None) -> _Columns:
    def fail(message: str) -> FileFormatError:
        return FileFormatError(message, path=source, line=line)

    index: dict[str, int] = {}
    for k, name in enumerate(header):
        if name == "":
            raise fail(f"column {k + 1} of the header has no name")
        if name in index:
            raise fail(f"column {name!r} appears twice")
        index[name] = k
    servo_units: dict[int, str] = {}
    euler_units: dict[str, str] = {}
    text: list[str] = []
    for name in header:
        servo = _SERVO_COLUMN.match(name)
        euler = _EULER_COLUMN.match(name)
        if servo is not None:
            unit = servo.group(2)
            if unit not in _SERVO_UNITS:
                raise fail(
                    f"column {name!r}: unit {unit!r} is not allowed; servo positions are in "
                    f"{', '.join(_SERVO_UNITS)} (e.g. servo{servo.group(1)}_deg)"
                )
            servo_units[int(servo.group(1))] = unit
        elif euler is not None:
            unit = euler.group(2)
            if unit not in _ANGLE_UNITS:
                raise fail(
                    f"column {name!r}: unit {unit!r} is not allowed; angles are in deg or rad "
                    f"(e.g. {euler.group(1)}_deg)"
                )
            euler_units[euler.group(1)] = unit
        elif name in ("pose", "time_s") or name.startswith("x_"):
            text.append(name)
        elif name not in _QUATERNION and name not in _AXES:
            raise fail(
                f"unknown column {name!r}; allowed: {_allowed_columns()} "
                "(prefix a column with x_ to keep it unused)"
            )
    missing_servo = [i for i in (1, 2, 3) if i not in servo_units]
    if missing_servo:
        raise fail(
            "missing servo column(s) "
            + ", ".join(f"servo{i}_<unit>" for i in missing_servo)
            + f"; the header has {list(header)}"
        )
    units = set(servo_units.values())
    if len(units) > 1:
        raise fail(
            "servo columns mix units "
            + ", ".join(f"servo{i}_{servo_units[i]}" for i in (1, 2, 3))
            + "; use one unit for all three"
        )
    groups: dict[str, list[str]] = {
        "quaternion": [c for c in _QUATERNION if c in index],
        "euler": [c for c in ("roll", "pitch", "yaw") if c in euler_units],
        "axes": [c for c in _AXES if c in index],
    }
    present = [g for g, cols in groups.items() if cols]
    if not present:
        raise fail(
            "missing orientation columns: give qw, qx, qy, qz, or roll/pitch/yaw with a unit, "
            "or v1_x..v3_z"
        )
    if len(present) > 1:
        raise fail(f"more than one orientation given ({', '.join(present)}); keep one")
    group = present[0]
    if group == "quaternion" and len(groups[group]) < 4:
        missing = [c for c in _QUATERNION if c not in index]
        raise fail(f"missing quaternion column(s) {missing}")
    if group == "axes" and len(groups[group]) < 9:
        missing = [c for c in _AXES if c not in index]
        raise fail(f"missing axis column(s) {missing}")
    euler_unit: str | None = None
    if group == "euler":
        if len(groups["euler"]) < 3:
            missing = [c + "_<unit>" for c in ("roll", "pitch", "yaw") if c not in euler_units]
            raise fail(f"missing angle column(s) {missing}")
        if len(set(euler_units.values())) > 1:
            raise fail("roll, pitch and yaw columns mix units; use deg or rad for all three")
        euler_unit = euler_units["roll"]
    servo_unit = units.pop()
    servo_cols = [f"servo{i}_{servo_unit}" for i in (1, 2, 3)]
    if group == "euler":
        orientation = [f"{c}_{euler_unit}" for c in ("roll", "pitch", "yaw")]
    else:
        orientation = list(_QUATERNION) if group == "quaternion" else list(_AXES)
    numeric = servo_cols + orientation
    used = set(numeric) | set(text)
    return _Columns(
        index={name: k for name, k in index.items() if name in used},
        numeric=numeric,
        text=text,
        servo=servo_cols,
        servo_unit=servo_unit,
        kind="axes" if group == "axes" else "quaternion",
        orientation=orientation,
        euler_unit=euler_unit,
    )


def _orientation(
    values: Mapping[str, FloatArray], columns: _Columns, lines: IntArray, source: str | None
) -> FloatArray:
    if columns.kind == "axes":
        axes = np.stack([values[c] for c in columns.orientation], axis=1).reshape(-1, 3, 3)
        norm = np.linalg.norm(axes, axis=-1)
        bad = np.argwhere(np.abs(norm - 1.0) > _UNIT_TOL)
        if bad.size:
            k, i = int(bad[0, 0]), int(bad[0, 1])
            raise FileFormatError(
                f"columns v{i + 1}_x, v{i + 1}_y, v{i + 1}_z: the measured axis has length "
                f"{norm[k, i]:.6g}; axes must be unit vectors (within {_UNIT_TOL})",
                path=source,
                line=int(lines[k]),
            )
        result: FloatArray = axes / norm[..., None]
        return result
    if columns.euler_unit is not None:
        angles = np.stack([values[c] for c in columns.orientation], axis=1)
        if columns.euler_unit == "deg":
            angles = np.radians(angles)
        return matrix_from_rpy(angles)
    q = np.stack([values[c] for c in _QUATERNION], axis=1)
    norm = np.linalg.norm(q, axis=1)
    bad_q = np.nonzero(np.abs(norm - 1.0) > _UNIT_TOL)[0]
    if bad_q.size:
        k = int(bad_q[0])
        raise FileFormatError(
            f"columns qw, qx, qy, qz: the quaternion has norm {norm[k]:.6g}; it must be a unit "
            f"quaternion (within {_UNIT_TOL}) - angles belong in roll_deg, pitch_deg, yaw_deg",
            path=source,
            line=int(lines[k]),
        )
    return matrix_from_quaternion(q)


# ============================================================================ rotations
def _skew(vectors: FloatArray) -> FloatArray:
    """Cross-product matrices (..., 3, 3) of vectors (..., 3)."""
    out = np.zeros((*vectors.shape, 3))
    x, y, z = vectors[..., 0], vectors[..., 1], vectors[..., 2]
    out[..., 0, 1], out[..., 0, 2] = -z, y
    out[..., 1, 0], out[..., 1, 2] = z, -x
    out[..., 2, 0], out[..., 2, 1] = -y, x
    return out


def _so3_terms(rotvec: FloatArray) -> tuple[FloatArray, float, float, float]:
    """K = [rotvec], sin t / t, (1 - cos t) / t^2, (t - sin t) / t^3 (series near 0)."""
    t = float(np.linalg.norm(rotvec))
    K = _skew(rotvec)
    if t < 1e-4:
        t2 = t * t
        return K, 1.0 - t2 / 6.0, 0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0
    return K, math.sin(t) / t, (1.0 - math.cos(t)) / t**2, (t - math.sin(t)) / t**3


def _exp(rotvec: FloatArray) -> FloatArray:
    """Rotation matrix exp([rotvec]) (Rodrigues)."""
    K, a, b, _ = _so3_terms(rotvec)
    result: FloatArray = np.eye(3) + a * K + b * (K @ K)
    return result


def _log(R: FloatArray) -> FloatArray:
    """Rotation vector (3,) of a rotation matrix."""
    q = quaternion_from_matrix(R)
    w, v = float(q[0]), q[1:]
    s = float(np.linalg.norm(v))
    if s < 1e-12:
        result: FloatArray = 2.0 * v
        return result
    return 2.0 * math.atan2(s, w) * v / s


def _left_jacobian(rotvec: FloatArray) -> FloatArray:
    """J_l: exp([r + dr]) = exp([J_l dr]) exp([r]) to first order."""
    K, _, b, c = _so3_terms(rotvec)
    result: FloatArray = np.eye(3) + b * K + c * (K @ K)
    return result


def _right_jacobian(rotvec: FloatArray) -> FloatArray:
    """J_r: exp([r + dr]) = exp([r]) exp([J_r dr]) to first order."""
    return _left_jacobian(-rotvec)


def _tangent_basis(vectors: FloatArray) -> FloatArray:
    """Two unit vectors perpendicular to each unit vector (..., 3): shape (..., 2, 3)."""
    helper = np.where(
        (np.abs(vectors[..., 0]) < 0.9)[..., None], np.array([1.0, 0.0, 0.0]), [0.0, 1.0, 0.0]
    )
    e1 = cross(helper, vectors)
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    e2 = cross(vectors, e1)
    return np.stack([e1, e2], axis=-2)


def _error_angle(R_a: FloatArray, R_b: FloatArray) -> FloatArray:
    """Angle [rad] of E = R_a^T R_b, batched (...): atan2(sin, cos), precise near 0."""
    E = np.swapaxes(R_a, -1, -2) @ R_b
    sine = 0.5 * np.linalg.norm(
        np.stack(
            [E[..., 2, 1] - E[..., 1, 2], E[..., 0, 2] - E[..., 2, 0], E[..., 1, 0] - E[..., 0, 1]],
            -1,
        ),
        axis=-1,
    )
    cosine = 0.5 * (np.trace(E, axis1=-2, axis2=-1) - 1.0)
    result: FloatArray = np.arctan2(sine, cosine)
    return result


# =========================================================================== parameters
@dataclasses.dataclass(frozen=True, eq=False)
class CalibrationParameters:
    """A full set of model parameters (angles in radians).

    Attributes:
        offsets: Encoder zero offsets (3,): model input = reading - offset.
        alpha1: Proximal link angle.
        alpha2: Distal link angle.
        beta: Inclination of the platform joint axes.
        mount: Sensor frame in the platform frame, (3, 3).
        reference: World (base) frame in the sensor's reference frame, (3, 3).
    """

    offsets: FloatArray
    alpha1: float
    alpha2: float
    beta: float
    mount: FloatArray
    reference: FloatArray

    def __post_init__(self) -> None:
        offsets = np.array(_triple(self.offsets, "offsets"))
        offsets.setflags(write=False)
        object.__setattr__(self, "offsets", offsets)
        for name in ("alpha1", "alpha2", "beta"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)):
                raise InputError(f"{name} must be an angle [rad], got {value!r}", argument=name)
            object.__setattr__(self, name, float(value))
        for name in ("mount", "reference"):
            matrix = np.array(as_rotation(getattr(self, name), name))
            if matrix.shape != (3, 3):
                raise InputError(f"{name} must be one rotation matrix (3, 3)", argument=name)
            matrix.setflags(write=False)
            object.__setattr__(self, name, matrix)

    @classmethod
    def nominal(
        cls,
        design: SPMDesign | str | None = None,
        *,
        mount: npt.ArrayLike | None = None,
        reference: npt.ArrayLike | None = None,
    ) -> CalibrationParameters:
        """Zero offsets, the design's link angles and the given (default identity) rotations."""
        design = check_design(design)
        return cls(
            offsets=np.zeros(3),
            alpha1=design.alpha1,
            alpha2=design.alpha2,
            beta=design.beta,
            mount=np.eye(3) if mount is None else np.asarray(mount, dtype=float),
            reference=np.eye(3) if reference is None else np.asarray(reference, dtype=float),
        )

    def design(self, base: SPMDesign | str | None = None, *, name: str | None = None) -> SPMDesign:
        """``base`` (default: the prototype) with these link angles."""
        base = check_design(base)
        return dataclasses.replace(
            base,
            alpha1=self.alpha1,
            alpha2=self.alpha2,
            beta=self.beta,
            name=base.name if name is None else name,
        )

    def vector(self, start: CalibrationParameters | None = None) -> FloatArray:
        """Values in the order of :data:`PARAMETER_NAMES` [rad]; mount and ref as
        rotation vectors of the corrections relative to ``start`` (default identity)."""
        mount0 = np.eye(3) if start is None else start.mount
        ref0 = np.eye(3) if start is None else start.reference
        return np.concatenate(
            [
                self.offsets,
                [self.alpha1, self.alpha2, self.beta],
                _log(mount0.T @ self.mount),
                _log(self.reference @ ref0.T),
            ]
        )

    @classmethod
    def from_vector(
        cls, x: npt.ArrayLike, start: CalibrationParameters | None = None
    ) -> CalibrationParameters:
        """Inverse of :meth:`vector`."""
        x = np.asarray(x, dtype=float)
        mount0 = np.eye(3) if start is None else start.mount
        ref0 = np.eye(3) if start is None else start.reference
        return cls(
            offsets=x[0:3],
            alpha1=float(x[3]),
            alpha2=float(x[4]),
            beta=float(x[5]),
            mount=mount0 @ _exp(x[6:9]),
            reference=_exp(x[9:12]) @ ref0,
        )

    def as_dict(self) -> dict[str, Any]:
        """Degrees for JSON and reports: offsets, link angles, rotations as rotation vectors."""
        return {
            "offsets_deg": np.degrees(self.offsets).tolist(),
            "alpha1_deg": math.degrees(self.alpha1),
            "alpha2_deg": math.degrees(self.alpha2),
            "beta_deg": math.degrees(self.beta),
            "mount_rotvec_deg": np.degrees(_log(self.mount)).tolist(),
            "reference_rotvec_deg": np.degrees(_log(self.reference)).tolist(),
        }


def _expand(
    names: Sequence[str] | str | None, kind: str, argument: str = "parameters"
) -> list[str]:
    """Parameter names (groups expanded), unique, in the order of PARAMETER_NAMES."""
    if names is None:
        return list(DEFAULT_PARAMETERS[kind])
    if isinstance(names, str):
        names = [n for n in re.split(r"[,\s]+", names) if n]
    chosen: set[str] = set()
    for name in names:
        if name in PARAMETER_GROUPS:
            chosen.update(PARAMETER_GROUPS[name])
        elif name in PARAMETER_NAMES:
            chosen.add(name)
        else:
            raise InputError(
                f"unknown parameter {name!r}; allowed: {list(PARAMETER_NAMES)} or the groups "
                f"{list(PARAMETER_GROUPS)}",
                argument=argument,
                value=name,
            )
    if not chosen:
        raise InputError(f"{argument} must name at least one parameter", argument=argument)
    return [n for n in PARAMETER_NAMES if n in chosen]


# ================================================================================ model
@dataclasses.dataclass(frozen=True)
class _Geometry:
    """Home axes and their derivatives with respect to (alpha1, alpha2, beta)."""

    w0: FloatArray  # (3 legs, 3)
    dw0: FloatArray  # (3 params, 3 legs, 3)
    v0: FloatArray
    dv0: FloatArray  # d v0 / d beta


def _geometry(design: SPMDesign) -> _Geometry:
    """w_i0 as in :class:`SPMDesign` (unit vector at alpha1 from u_i and alpha2 from
    v_i0): w0 = x u + y v0 + z (u x v0) with c = u . v0, D = 1 - c^2,
    x = (cos a1 - c cos a2)/D, y = (cos a2 - c cos a1)/D,
    z = -sqrt((1 - x^2 - y^2 - 2 x y c)/D); differentiated by the chain rule."""
    u = design.u
    eta = np.asarray(design.eta) - math.pi / 2
    sb, cb = math.sin(design.beta), math.cos(design.beta)
    v0 = np.stack([sb * np.cos(eta), sb * np.sin(eta), np.full(3, cb)], axis=1)
    dv0 = np.stack([cb * np.cos(eta), cb * np.sin(eta), np.full(3, -sb)], axis=1)
    c = np.sum(u * v0, axis=1)
    dc_db = np.sum(u * dv0, axis=1)
    C1, C2 = math.cos(design.alpha1), math.cos(design.alpha2)
    D = 1.0 - c * c
    x = (C1 - c * C2) / D
    y = (C2 - c * C1) / D
    z2 = (1.0 - x * x - y * y - 2.0 * x * y * c) / D
    z = -np.sqrt(z2)
    uxv = np.cross(u, v0)
    w0 = x[:, None] * u + y[:, None] * v0 + z[:, None] * uxv

    def partial(dx: FloatArray, dy: FloatArray, dc: FloatArray) -> FloatArray:
        """d(x, y, z) -> d w0 at fixed u, v0 (dc: derivative of c)."""
        dN = -2 * x * dx - 2 * y * dy - 2 * c * (y * dx + x * dy) - 2 * x * y * dc
        dz2 = dN / D + z2 * 2 * c * dc / D
        dz = dz2 / (2 * z)
        result: FloatArray = dx[:, None] * u + dy[:, None] * v0 + dz[:, None] * uxv
        return result

    zero = np.zeros(3)
    d_a1 = partial(np.full(3, 1.0) / D, -c / D, zero) * -math.sin(design.alpha1)
    d_a2 = partial(-c / D, np.full(3, 1.0) / D, zero) * -math.sin(design.alpha2)
    d_c = partial((-C2 + 2 * c * x) / D, (-C1 + 2 * c * y) / D, np.ones(3))
    d_b = dc_db[:, None] * d_c + y[:, None] * dv0 + z[:, None] * np.cross(u, dv0)
    return _Geometry(w0=w0, dw0=np.stack([d_a1, d_a2, d_b]), v0=v0, dv0=dv0)


@dataclasses.dataclass
class _Evaluation:
    residual: FloatArray  # (N, k)
    jacobian: FloatArray | None  # (N, k, 12)
    reachable: BoolArray  # (N,)
    predicted: FloatArray  # (N, 3, 3) predicted measurement (NaN where unreachable)


class _Model:
    """Predicted measurements, residuals and their Jacobian for fixed readings."""

    def __init__(
        self,
        theta: FloatArray,
        measured: FloatArray | None,
        kind: str,
        base: SPMDesign,
        start: CalibrationParameters,
    ) -> None:
        self.theta = theta
        self.measured = measured
        self.kind = kind
        self.base = base
        self.start = start
        self.k = _COMPONENTS[kind]
        self.basis = None if measured is None or kind != "axes" else _tangent_basis(measured)
        self._cache: tuple[bytes, bool, _Evaluation] | None = None
        self.evaluations = 0

    def evaluate(self, x: FloatArray, jac: bool) -> _Evaluation:
        key = np.asarray(x, dtype=float).tobytes()
        if self._cache is not None and self._cache[0] == key and (self._cache[1] or not jac):
            return self._cache[2]
        result = self._evaluate(np.asarray(x, dtype=float), jac)
        self._cache = (key, jac, result)
        self.evaluations += 1
        return result

    def _evaluate(self, x: FloatArray, jac: bool) -> _Evaluation:
        n, k = self.theta.shape[0], self.k
        penalty = _Evaluation(
            residual=np.full((n, k), _UNREACHABLE_RESIDUAL),
            jacobian=np.zeros((n, k, len(PARAMETER_NAMES))) if jac else None,
            reachable=np.zeros(n, dtype=bool),
            predicted=np.full((n, 3, 3), np.nan),
        )
        try:
            design = dataclasses.replace(self.base, alpha1=x[3], alpha2=x[4], beta=x[5])
        except DesignError:
            return penalty
        mu, rho = x[6:9], x[9:12]
        R_mount = self.start.mount @ _exp(mu)
        R_ref = _exp(rho) @ self.start.reference
        theta = self.theta - x[0:3]
        fk = forward_kinematics(theta, design)
        ok = np.asarray(fk.reachable)
        if not np.any(ok):
            return penalty
        R, w, v, th = fk.R[ok], fk.w[ok], fk.v[ok], theta[ok]
        if self.kind == "quaternion":
            predicted = R_ref @ R @ R_mount
        else:
            predicted = np.einsum("jk,nik->nij", R_ref, v)
        residual = np.full((n, k), _UNREACHABLE_RESIDUAL)
        full_pred = np.full((n, 3, 3), np.nan)
        full_pred[ok] = predicted
        q: FloatArray | None = None
        if self.measured is not None:
            meas = self.measured[ok]
            if self.kind == "quaternion":
                q = quaternion_from_matrix(np.swapaxes(predicted, -1, -2) @ meas)
                residual[ok] = 2.0 * q[:, 1:]
            else:
                assert self.basis is not None
                basis = self.basis[ok]
                residual[ok] = np.einsum("nicd,nid->nic", basis, meas - predicted).reshape(-1, 6)
        else:
            residual[ok] = 0.0
            basis = _tangent_basis(predicted)
        jacobian = None
        if jac:
            D = self._prediction_derivative(design, th, R, w, v, predicted, R_mount, R_ref, mu, rho)
            if self.kind == "quaternion":
                if q is None:  # planning: measured = predicted, E = I
                    block = -D
                else:
                    w_q = q[:, 0][:, None, None] * np.eye(3)
                    block = -(w_q - _skew(q[:, 1:])) @ D
            else:
                block = -np.einsum("nicd,nidp->nicp", basis, D).reshape(-1, 6, len(PARAMETER_NAMES))
            jacobian = np.zeros((n, k, len(PARAMETER_NAMES)))
            jacobian[ok] = block
        return _Evaluation(residual=residual, jacobian=jacobian, reachable=ok, predicted=full_pred)

    def _prediction_derivative(
        self,
        design: SPMDesign,
        theta: FloatArray,
        R: FloatArray,
        w: FloatArray,
        v: FloatArray,
        predicted: FloatArray,
        R_mount: FloatArray,
        R_ref: FloatArray,
        mu: FloatArray,
        rho: FloatArray,
    ) -> FloatArray:
        """d(prediction)/d(parameters): quaternion kind (n, 3, 12) as right increments
        of R_pred in the sensor frame; axes kind (n, 3 legs, 3, 12)."""
        n = theta.shape[0]
        geo = _geometry(design)
        u = design.u
        b = np.sum(cross(u, w) * v, axis=-1)  # (n, 3)
        dw = np.stack([rotate_about(u, theta, geo.dw0[p]) for p in range(3)], axis=-1)
        Rdv0 = np.einsum("njk,ik->nij", R, geo.dv0)  # rows R dv_i0/d beta
        K = np.zeros((n, 3, 6))
        K[:, [0, 1, 2], [0, 1, 2]] = -b  # offsets: d theta_i = -d offset_i
        K[:, :, 3:6] = np.einsum("nicp,nic->nip", dw, v)
        K[:, :, 4] += math.sin(design.alpha2)
        K[:, :, 5] += np.sum(w * Rdv0, axis=-1)
        A = cross(w, v)
        dphi = np.linalg.solve(A, K)  # (n, 3, 6): world-frame platform increments
        P = len(PARAMETER_NAMES)
        if self.kind == "quaternion":
            D = np.zeros((n, 3, P))
            M = R @ R_mount
            D[:, :, 0:6] = np.swapaxes(M, -1, -2) @ dphi
            D[:, :, 6:9] = _right_jacobian(mu)
            D[:, :, 9:12] = np.swapaxes(predicted, -1, -2) @ _left_jacobian(rho)
            return D
        D = np.zeros((n, 3, 3, P))
        # d v_i = dphi x v_i (+ R dv_i0 d beta), then R_ref in front.
        world = -_skew(v) @ dphi[:, None]  # (n, 3 legs, 3, 6)
        world[..., 5] += Rdv0
        D[..., 0:6] = np.einsum("jk,nikp->nijp", R_ref, world)
        D[..., 9:12] = -_skew(predicted) @ _left_jacobian(rho)
        return D


# ======================================================================= identifiability
@dataclasses.dataclass(frozen=True)
class Identifiability:
    """What the readings can and cannot tell apart.

    Attributes:
        parameters: The parameters asked for.
        identified: Those the readings determine (estimated).
        unidentified: Those kept at their starting values.
        combinations: Parameter combinations the readings cannot see, e.g.
            ``"ref_z ~ - offset_1 - offset_2 - offset_3"``: on these readings a change of
            ref_z looks like that change of the identified parameters.
        singular_values: Of the column-normalised Jacobian of ``parameters``, descending.
        condition_number: Of the column-normalised Jacobian of ``identified``.
        correlated: Pairs ``(a, b, r)`` of identified parameters with |r| >= 0.99.
        redundancy: Residual components minus identified parameters (degrees of freedom).
        warnings: Human-readable warnings (empty when all is well).
    """

    parameters: tuple[str, ...]
    identified: tuple[str, ...]
    unidentified: tuple[str, ...]
    combinations: tuple[str, ...]
    singular_values: FloatArray
    condition_number: float
    correlated: tuple[tuple[str, str, float], ...]
    redundancy: int
    warnings: tuple[str, ...]

    @property
    def ok(self) -> bool:
        """Every parameter identified, well conditioned, with redundancy to spare."""
        return not self.warnings

    def as_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {
            "ok": self.ok,
            "parameters": list(self.parameters),
            "identified": list(self.identified),
            "unidentified": list(self.unidentified),
            "combinations": list(self.combinations),
            "singular_values": self.singular_values.tolist(),
            "condition_number": self.condition_number,
            "correlated": [list(p) for p in self.correlated],
            "redundancy": self.redundancy,
            "warnings": list(self.warnings),
        }


def _combination(coefficients: FloatArray, names: Sequence[str]) -> str:
    """``"- offset_1 - offset_2 + 0.50 beta"`` from coefficients (small ones left out)."""
    top = float(np.max(np.abs(coefficients))) if coefficients.size else 0.0
    terms = []
    for c, name in zip(coefficients, names, strict=True):
        if abs(c) < 0.05 * top or abs(c) < 5e-3:
            continue
        sign = "-" if c < 0 else "+"
        magnitude = "" if abs(abs(c) - 1.0) < 0.005 else f"{abs(c):.2f} "
        terms.append(f"{sign} {magnitude}{name}")
    text = " ".join(terms) or "0"
    return text[2:] if text.startswith("+ ") else text


def _select(J: FloatArray, names: Sequence[str]) -> tuple[list[int], list[int], list[str]]:
    """Greedy identifiable subset of the columns of J (order = priority).

    A column is kept when the column-normalised Jacobian of the kept columns plus
    this one has relative smallest singular value > RANK_TOL (and there are at least
    as many residuals as kept columns).

    Returns:
        Indices kept, indices dropped, and for each dropped parameter what the
        readings confuse it with: ``"ref_z ~ - offset_1 - offset_2 - offset_3"``
        (a change of ref_z looks like that change of the kept parameters).
    """
    norms = np.linalg.norm(J, axis=0)
    floor = _NO_EFFECT * max(float(np.max(norms)) if norms.size else 0.0, 1e-300)
    kept: list[int] = []
    dropped: list[int] = []
    for j in range(J.shape[1]):
        if norms[j] <= floor:
            dropped.append(j)
            continue
        trial = [*kept, j]
        s = np.linalg.svd(J[:, trial] / norms[trial], compute_uv=False)
        if J.shape[0] >= len(trial) and s[-1] > RANK_TOL * s[0]:
            kept.append(j)
        else:
            dropped.append(j)
    combos: list[str] = []
    for j in dropped:
        if norms[j] <= floor:
            combos.append(f"{names[j]} has no effect")
            continue
        if not kept:
            combos.append(f"{names[j]} ~ 0")
            continue
        coefficients = np.asarray(np.linalg.lstsq(J[:, kept], J[:, j], rcond=None)[0], dtype=float)
        combos.append(f"{names[j]} ~ " + _combination(coefficients, [names[k] for k in kept]))
    return kept, dropped, combos


def _identifiability(
    J: FloatArray,
    names: Sequence[str],
    kept: Sequence[int],
    dropped: Sequence[int],
    combos: Sequence[str],
    covariance: FloatArray | None,
) -> Identifiability:
    m = J.shape[0]
    norms = np.linalg.norm(J, axis=0)
    safe = np.where(norms > 0, norms, 1.0)
    singular = np.linalg.svd(J / safe, compute_uv=False) if J.size else np.zeros(0)
    if kept:
        s = np.linalg.svd(J[:, list(kept)] / safe[list(kept)], compute_uv=False)
        cond = float(s[0] / s[-1]) if s[-1] > 0 else math.inf
    else:
        cond = math.inf
    redundancy = m - len(kept)
    correlated: list[tuple[str, str, float]] = []
    if covariance is not None and np.all(np.isfinite(covariance)):
        std = np.sqrt(np.diag(covariance))
        corr = covariance / np.outer(std, std)
        for a in range(len(kept)):
            for b in range(a + 1, len(kept)):
                if abs(corr[a, b]) >= MAX_CORRELATION:
                    correlated.append((names[kept[a]], names[kept[b]], float(corr[a, b])))
    messages: list[str] = []
    if dropped:
        messages.append(
            "the readings cannot identify "
            + ", ".join(names[j] for j in dropped)
            + " (kept at the starting values; on these readings "
            + "; ".join(combos)
            + ")"
        )
    if redundancy <= 0:
        messages.append(
            f"{m} residuals for {len(kept)} parameters: no redundancy, so no noise estimate "
            "or confidence interval; add readings"
        )
    if kept and cond > MAX_CONDITION:
        messages.append(
            f"poorly conditioned (condition number {cond:.3g} > {MAX_CONDITION:g}): the "
            "readings barely separate the parameters; use more varied poses (spm plan-poses)"
        )
    if correlated:
        messages.append(
            "estimates nearly inseparable: "
            + ", ".join(f"{a}/{b} (r = {r:+.3f})" for a, b, r in correlated)
        )
    return Identifiability(
        parameters=tuple(names),
        identified=tuple(names[j] for j in kept),
        unidentified=tuple(names[j] for j in dropped),
        combinations=tuple(combos),
        singular_values=np.asarray(singular),
        condition_number=cond,
        correlated=tuple(correlated),
        redundancy=int(redundancy),
        warnings=tuple(messages),
    )


# ============================================================================ calibrate
@dataclasses.dataclass(frozen=True)
class ParameterEstimate:
    """One identified (or fixed) parameter [rad].

    Attributes:
        name: One of :data:`PARAMETER_NAMES`.
        start: Starting value as given (mount/ref: 0, the correction is estimated).
        value: Estimate (the start when not identified).
        std: Standard deviation (inf when not identified).
        low: Lower end of the confidence interval.
        high: Upper end of the confidence interval.
        identified: Whether the readings determine it.
    """

    name: str
    start: float
    value: float
    std: float
    low: float
    high: float
    identified: bool

    def as_dict(self) -> dict[str, Any]:
        """Degrees, for JSON and reports."""
        return {
            "name": self.name,
            "identified": self.identified,
            "start_deg": math.degrees(self.start),
            "value_deg": math.degrees(self.value),
            "change_deg": math.degrees(self.value - self.start),
            "std_deg": math.degrees(self.std) if math.isfinite(self.std) else None,
            "ci_deg": (
                [math.degrees(self.low), math.degrees(self.high)]
                if math.isfinite(self.std)
                else None
            ),
        }


@dataclasses.dataclass(frozen=True, eq=False)
class CalibrationResult:
    """Outcome of :func:`calibrate`.

    Attributes:
        design: The calibrated design (link angles identified; the rest as given).
        parameters: All parameters after calibration.
        start: The starting parameters (before the offsets are guessed from the
            readings, see ``initial_offsets`` of :func:`calibrate`).
        estimates: One entry per requested parameter, in the order of PARAMETER_NAMES.
        covariance: Covariance [rad^2] of the identified parameters, in the order of
            ``identifiability.identified``.
        identifiability: What the readings could tell apart.
        confidence: Level of the intervals (e.g. 0.95).
        readings: The readings given.
        used: (N,) readings used (the start model could assemble them).
        error_start_deg: (N,) orientation error per reading with the starting
            parameters [deg] (for axis readings the largest axis error); NaN where not
            used or not assembled.
        error_deg: (N,) the same after calibration.
        residuals: (N, k) residual components after calibration [rad].
        weights: (N,) mean robust-loss weight per reading (1 = full weight).
        outliers: (N,) readings whose error is improbably large for the noise level.
        sigma_deg: Estimated measurement noise per residual component [deg].
        loss: Robust loss used; ``f_scale`` its scale [rad].
        f_scale: Robust loss scale [rad].
        cost: Final cost 0.5 sum rho(r^2).
        nfev: Residual evaluations.
        njev: Jacobian evaluations.
        method: ``"analytic"`` or the finite-difference scheme used for the Jacobian.
        messages: Warnings (identifiability, excluded readings, outliers).
    """

    design: SPMDesign
    parameters: CalibrationParameters
    start: CalibrationParameters
    estimates: tuple[ParameterEstimate, ...]
    covariance: FloatArray
    identifiability: Identifiability
    confidence: float
    readings: Readings
    used: BoolArray
    error_start_deg: FloatArray
    error_deg: FloatArray
    residuals: FloatArray
    weights: FloatArray
    outliers: BoolArray
    sigma_deg: float
    loss: str
    f_scale: float
    cost: float
    nfev: int
    njev: int
    method: str
    messages: tuple[str, ...]

    @property
    def ok(self) -> bool:
        """Every requested parameter identified and well conditioned."""
        return self.identifiability.ok

    def estimate(self, name: str) -> ParameterEstimate:
        """The estimate of one parameter by name."""
        for entry in self.estimates:
            if entry.name == name:
                return entry
        raise InputError(
            f"{name!r} was not a calibrated parameter; these were: "
            f"{[e.name for e in self.estimates]}",
            argument="name",
            value=name,
        )

    @property
    def offsets_deg(self) -> FloatArray:
        """Identified encoder zero offsets [deg] (3,)."""
        return np.degrees(self.parameters.offsets)

    @property
    def joints(self) -> JointConvention:
        """The readings' encoder convention with the identified zero offsets."""
        return self.readings.joints.with_offsets(self.parameters.offsets)

    @property
    def zero_offsets(self) -> FloatArray:
        """Identified zero offsets [pulses, 4096 per turn] (3,), not rounded.

        The servos' Present Position at which each input is at the model's zero: the
        ``zero_offset`` of a servo configuration (:meth:`servo_config` rounds them). For
        readings of 4096 counts per turn these are ``joints.zero_offset_ticks``.
        """
        joints = self.joints
        result: FloatArray = (
            np.asarray(joints.zero_offset_ticks) * TICKS_PER_TURN / joints.ticks_per_turn
        )
        return result

    def servo_config(self, config: HardwareConfig | str | Path) -> HardwareConfig:
        """A servo configuration with the identified zero offsets (whole pulses).

        Everything else in ``config`` is kept, and the copy is validated like any
        :class:`spm_pin.hardware.HardwareConfig` (write it with ``.save(path)``). The
        readings' directions and gear ratios must be the configuration's: load them
        with ``joints=JointConvention.from_servo_config(config)``, or give the same
        settings in the file. Their zero offsets may be anything (the old
        configuration's, say): the identified ones are absolute. Check :attr:`ok`
        first: offsets the readings cannot identify keep their starting values.

        Needs only the core of :mod:`spm_pin.hardware` (not its SDK).

        Args:
            config: The configuration the readings were taken with, or its file.

        Raises:
            InputError: ``config`` is no configuration, or its directions or gear
                ratios differ from the readings'.
            FileFormatError: the configuration file is malformed.
        """
        hardware_config = _hardware_config_class()
        if isinstance(config, (str, Path)):
            config = hardware_config.load(config)
        if not isinstance(config, hardware_config):
            raise InputError(
                f"config must be a spm_pin.hardware.HardwareConfig or its file, got "
                f"{type(config).__name__}",
                argument="config",
                value=config,
            )
        readings = self.readings.joints
        for i, joint in enumerate(config.joints):
            direction, gear = readings.direction[i], readings.gear_ratio[i]
            if joint.direction != direction or not math.isclose(
                joint.gear_ratio, gear, rel_tol=1e-9
            ):
                raise InputError(
                    f"joint {joint.joint}: the readings were converted with direction "
                    f"{direction:+d} and gear ratio {_fmt(gear)}, the servo configuration has "
                    f"direction {joint.direction:+d} and gear ratio {_fmt(joint.gear_ratio)}; "
                    "the readings file must give the configuration's direction and "
                    "gear_ratio, or none (then the configuration's apply, by loading it with "
                    "joints=JointConvention.from_servo_config(config), as spm calibrate "
                    "--servo-config does)",
                    argument="config",
                    value=config,
                )
        zero = self.zero_offsets
        u1, u2, u3 = (
            dataclasses.replace(joint, zero_offset=round(float(zero[i])))
            for i, joint in enumerate(config.joints)
        )
        return config.replace(joints=(u1, u2, u3))

    def as_dict(self) -> dict[str, Any]:
        """Plain data (degrees) for JSON."""
        lines = self.readings.lines
        assert lines is not None
        return {
            "ok": self.ok,
            "design": self.design.to_dict(),
            "confidence": self.confidence,
            "readings": len(self.readings),
            "used": int(np.sum(self.used)),
            "excluded_lines": lines[~self.used].tolist(),
            "outlier_lines": lines[self.outliers].tolist(),
            "parameters": [e.as_dict() for e in self.estimates],
            "all_parameters": self.parameters.as_dict(),
            "identifiability": self.identifiability.as_dict(),
            "rms_error_start_deg": _rms(self.error_start_deg[self.used]),
            "rms_error_deg": _rms(self.error_deg[self.used]),
            "sigma_deg": self.sigma_deg,
            "loss": self.loss,
            "f_scale_deg": math.degrees(self.f_scale),
            "nfev": self.nfev,
            "njev": self.njev,
            "jacobian": self.method,
            "encoder": self._encoder_dict(),
            "messages": list(self.messages),
        }

    def _encoder_dict(self) -> dict[str, Any]:
        """The zero offsets in the servo configuration's terms (pulses, 4096 per turn)."""
        joints = self.joints
        zero = self.zero_offsets
        std = [self._offset_std(i) for i in range(3)]
        return {
            "ticks_per_turn": joints.ticks_per_turn,
            "joints": {
                f"u_{i + 1}": {
                    "direction": joints.direction[i],
                    "gear_ratio": joints.gear_ratio[i],
                    "zero_offset": round(float(zero[i])),
                    "zero_offset_exact": float(zero[i]),
                    "offset_deg": float(self.offsets_deg[i]),
                    "offset_std_deg": math.degrees(std[i]) if math.isfinite(std[i]) else None,
                }
                for i in range(3)
            },
        }

    def _offset_std(self, i: int) -> float:
        name = f"offset_{i + 1}"
        return next((e.std for e in self.estimates if e.name == name), math.inf)

    def offsets_toml(self) -> str:
        """The identified zero offsets as the ``[[joints]]`` tables of a servo configuration.

        The keys of :class:`spm_pin.hardware.HardwareConfig`: ``joint``, ``direction``,
        ``gear_ratio`` and ``zero_offset`` (whole pulses, 4096 per turn), for
        ``theta_i = direction * (pulses - zero_offset) * 360 / 4096 / gear_ratio`` [deg];
        only ``servo_id`` is missing. The exact value and the identified offset [deg]
        are comments. :meth:`servo_config` writes a whole configuration instead.
        """
        data = self._encoder_dict()
        source = self.readings.source or "readings"
        lines = [
            f"# Encoder zero offsets identified by spm-pin calibration from {source}:",
            "# [[joints]] tables of a servo configuration (spm_pin.hardware.HardwareConfig).",
            "# Copy each zero_offset into your configuration's table of the same joint, or",
            "# paste the tables and add servo_id; spm calibrate --servo-config CONFIG.toml",
            "# writes the whole configuration instead.",
            "# theta_i [deg] = direction * (pulses - zero_offset) * 360 / 4096 / gear_ratio",
            "# is the model's input angle (0 at home). Each comment gives the exact value",
            "# and the identified offset: the change from the readings' zero.",
        ]
        if data["ticks_per_turn"] != TICKS_PER_TURN:
            lines.append(
                f"# (the readings' {data['ticks_per_turn']} counts per turn are converted to "
                f"{TICKS_PER_TURN} pulses per turn)"
            )
        for name, joint in data["joints"].items():
            std = joint["offset_std_deg"]
            spread = "" if std is None else f" +- {std:.4f}"
            lines += [
                "",
                "[[joints]]",
                f'joint = "{name}"',
                f"direction = {joint['direction']}",
                f"gear_ratio = {float(joint['gear_ratio'])!r}",
                f"zero_offset = {joint['zero_offset']}  # pulses (exact "
                f"{joint['zero_offset_exact']:.2f}); offset {joint['offset_deg']:+.4f}{spread} deg",
            ]
        return "\n".join(lines) + "\n"

    def report(self) -> str:
        """A human-readable report: data, fit, parameters, identifiability, outliers."""
        r = self.readings
        lines_of = r.lines
        assert lines_of is not None
        level = f"{100 * self.confidence:g}%"
        out = [
            f"spm-pin calibration of {self.start_design_name} from "
            f"{r.source or 'readings'}: {len(r)} readings ({r.kind}, servo {r.servo_unit})",
            "",
            f"fit: {self.loss} loss (scale {math.degrees(self.f_scale):.3g} deg), "
            f"{self.nfev} evaluations, Jacobian {self.method}",
            f"rms orientation error: {_rms(self.error_start_deg[self.used]):.4g} deg before, "
            f"{_rms(self.error_deg[self.used]):.4g} deg after; noise estimate "
            f"{self.sigma_deg:.3g} deg per axis",
            "",
            f"{'parameter':<10} {'start':>11} {'estimate':>11} {'std':>9}  {level} interval [deg]",
        ]
        for e in self.estimates:
            d = e.as_dict()
            if d["ci_deg"] is not None:
                ci = f"[{d['ci_deg'][0]:.4f}, {d['ci_deg'][1]:.4f}]"
                std = f"{d['std_deg']:.4f}"
            elif e.identified:
                ci, std = "no interval (no redundancy)", "inf"
            else:
                ci, std = "not identified (kept at start)", "inf"
            out.append(
                f"{e.name:<10} {d['start_deg']:>11.4f} {d['value_deg']:>11.4f} {std:>9}  {ci}"
            )
        ident = self.identifiability
        out += [
            "",
            f"identifiability: condition number {ident.condition_number:.4g}, "
            f"redundancy {ident.redundancy}",
            "  normalised singular values: " + " ".join(f"{s:.3g}" for s in ident.singular_values),
        ]
        out += [f"  WARNING: {w}" for w in ident.warnings]
        if ident.ok:
            out.append("  every parameter is identified")
        enc = self._encoder_dict()
        out += ["", "encoder zero offsets (servo configuration, 4096 pulses per turn):"]
        for name, j in enc["joints"].items():
            std = "" if j["offset_std_deg"] is None else f" +- {j['offset_std_deg']:.4f}"
            out.append(
                f"  {name}: offset {j['offset_deg']:+.4f}{std} deg -> zero_offset "
                f"{j['zero_offset']} ({j['zero_offset_exact']:.2f}), direction "
                f"{j['direction']:+d}, gear ratio {_fmt(j['gear_ratio'])}"
            )
        mount = self.parameters.mount
        out += [
            "",
            "sensor mounting (sensor frame in platform frame), rotation vector [deg]: "
            + " ".join(f"{a:+.4f}" for a in np.degrees(_log(mount))),
            f"calibrated design: {self.design.summary()}",
        ]
        extra = [m for m in self.messages if m not in ident.warnings]
        if extra:
            out.append("")
            out += [f"note: {m}" for m in extra]
        if np.any(~self.used):
            out.append(f"excluded readings (lines): {lines_of[~self.used].tolist()}")
        if np.any(self.outliers):
            out.append(
                f"outliers (lines, down-weighted by the loss): {lines_of[self.outliers].tolist()}"
            )
        return "\n".join(out) + "\n"

    @property
    def start_design_name(self) -> str:
        """Name of the design calibration started from."""
        name = self.design.name
        return name[: -len("_calibrated")] if name.endswith("_calibrated") else name

    def plot_residuals(self, path: str | Path) -> Path:
        """Write a residual plot (PNG): error per reading before/after, components after.

        Needs matplotlib (``pip install spm-pin[plot]``); imported here only.
        """
        try:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise InputError(
                "the residual plot needs matplotlib: pip install spm-pin[plot]",
                argument="path",
                value=str(path),
            ) from exc
        lines = self.readings.lines
        assert lines is not None
        used = self.used
        fig = Figure(figsize=(9.0, 6.5))
        FigureCanvasAgg(fig)
        top, bottom = fig.subplots(2, 1, sharex=True)
        x = lines[used]
        top.plot(x, self.error_start_deg[used], "o", ms=3, color="0.6", label="before")
        top.plot(x, self.error_deg[used], "o", ms=3, color="C0", label="after")
        if np.any(self.outliers):
            top.plot(
                lines[self.outliers],
                self.error_deg[self.outliers],
                "x",
                ms=8,
                color="C3",
                label="outlier",
            )
        top.set_yscale("log")
        top.set_ylabel("orientation error [deg]")
        top.set_title(
            f"Calibration of {self.start_design_name}: rms "
            f"{_rms(self.error_start_deg[used]):.3g} -> {_rms(self.error_deg[used]):.3g} deg"
        )
        top.legend(loc="upper right", fontsize="small")
        comps = np.degrees(self.residuals[used])
        labels = (
            ["x", "y", "z"]
            if comps.shape[1] == 3
            else [f"v{i}{c}" for i in (1, 2, 3) for c in "xyz"]
        )
        for j in range(comps.shape[1]):
            bottom.plot(x, comps[:, j], ".", ms=3, label=labels[j] if comps.shape[1] == 3 else None)
        band = 2.0 * self.sigma_deg
        bottom.axhline(band, color="0.5", lw=0.8, ls="--")
        bottom.axhline(-band, color="0.5", lw=0.8, ls="--")
        bottom.set_ylabel("residual after [deg]")
        bottom.set_xlabel("line in the readings file")
        if comps.shape[1] == 3:
            bottom.legend(loc="upper right", fontsize="small", ncol=3)
        fig.tight_layout()
        out = Path(path)
        fig.savefig(out, dpi=110)
        return out


def _rms(values: FloatArray) -> float:
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values**2))) if values.size else math.nan


def _errors_deg(kind: str, predicted: FloatArray, measured: FloatArray) -> FloatArray:
    if kind == "quaternion":
        return np.degrees(_error_angle(predicted, measured))
    sine = np.linalg.norm(cross(predicted, measured), axis=-1)
    cosine = np.sum(predicted * measured, axis=-1)
    result: FloatArray = np.degrees(np.max(np.arctan2(sine, cosine), axis=-1))
    return result


def _initial_offsets(
    readings: Readings, design: SPMDesign, start: CalibrationParameters
) -> FloatArray | None:
    """Offsets from inverse kinematics of the measured orientations (circular mean)."""
    if readings.kind == "quaternion":
        R = start.reference.T @ readings.orientation @ start.mount.T
    else:
        v = np.einsum("kj,nik->nij", start.reference, readings.orientation)  # R_ref^T v
        H = np.einsum("nij,ik->njk", v, design.v0)  # sum_i v_i v_i0^T
        U, _, Vt = np.linalg.svd(H)
        S = np.ones((len(readings), 3))
        S[:, 2] = np.sign(np.linalg.det(U @ Vt))
        R = (U * S[:, None, :]) @ Vt
    ik = inverse_kinematics(R, design)
    ok = np.asarray(ik.reachable)
    if not np.any(ok):
        return None
    diff = readings.theta[ok] - ik.theta[ok]
    mean = np.angle(np.mean(np.exp(1j * diff), axis=0))
    spread = np.angle(np.exp(1j * (diff - mean)))
    result: FloatArray = mean + np.median(spread, axis=0)
    return result


def calibrate(
    readings: Readings,
    design: SPMDesign | str | None = None,
    *,
    parameters: Sequence[str] | str | None = None,
    start: CalibrationParameters | None = None,
    mount: npt.ArrayLike | None = None,
    reference: npt.ArrayLike | None = None,
    loss: str = "soft_l1",
    noise_deg: float = 0.5,
    confidence: float = 0.95,
    jacobian: str = "analytic",
    initial_offsets: bool = True,
    max_nfev: int = 200,
) -> CalibrationResult:
    """Identify the model's parameters from readings of the prototype.

    Args:
        readings: The readings (:func:`load_readings`, :func:`synthetic_readings`).
        design: The nominal design to start from (default: the prototype).
        parameters: Names (or groups) to identify; default ``offsets, links, mount``
            for quaternion readings and ``offsets, links`` for axis readings.
        start: Starting values of all parameters (default: zero offsets, the design's
            link angles, ``mount`` and ``reference``).
        mount: Nominal sensor frame in the platform frame (3, 3) (default identity).
        reference: Nominal world frame in the sensor's reference frame (default identity).
        loss: Robust loss of :func:`scipy.optimize.least_squares`: ``"soft_l1"``
            (default), ``"huber"``, ``"cauchy"``, ``"arctan"`` or ``"linear"``.
        noise_deg: Expected measurement noise per axis [deg] (0.5 for a typical IMU);
            sets the first loss scale, then the scale follows the residuals.
        confidence: Level of the confidence intervals, in (0, 1).
        jacobian: ``"analytic"`` (default) or ``"2-point"`` / ``"3-point"`` finite
            differences (slower; for checking).
        initial_offsets: Start the offsets from inverse kinematics of the measured
            orientations (robust to offsets of any size).
        max_nfev: Limit on residual evaluations per solve.

    Returns:
        CalibrationResult. When the readings cannot separate some parameters, an
        :class:`IdentifiabilityWarning` is issued, those parameters keep their starting
        values with infinite intervals, and ``result.ok`` is False.

    Raises:
        InputError: a bad argument, or no reading can be assembled by the start model.
        ConvergenceError: the solver stopped without converging.
    """
    from scipy.optimize import least_squares
    from scipy.special import chdtri, stdtrit

    if not isinstance(readings, Readings):
        raise InputError(
            f"readings must be Readings (see load_readings), got {type(readings).__name__}",
            argument="readings",
            value=readings,
        )
    design = check_design(design)
    names = _expand(parameters, readings.kind)
    if loss not in _LOSS_WEIGHTS:
        raise InputError(
            f"loss must be one of {list(_LOSS_WEIGHTS)}, got {loss!r}", argument="loss", value=loss
        )
    if jacobian not in ("analytic", "2-point", "3-point"):
        raise InputError(
            f"jacobian must be 'analytic', '2-point' or '3-point', got {jacobian!r}",
            argument="jacobian",
            value=jacobian,
        )
    _check_positive(noise_deg, "noise_deg")
    if (
        isinstance(confidence, bool)
        or not isinstance(confidence, (int, float))
        or not (0.0 < confidence < 1.0)
    ):
        raise InputError(
            f"confidence must lie strictly between 0 and 1, got {confidence!r}",
            argument="confidence",
            value=confidence,
        )
    if isinstance(max_nfev, bool) or not isinstance(max_nfev, int) or max_nfev < 1:
        raise InputError(
            f"max_nfev must be a positive integer, got {max_nfev!r}", argument="max_nfev"
        )
    if start is None:
        start = CalibrationParameters.nominal(design, mount=mount, reference=reference)
    elif not isinstance(start, CalibrationParameters):
        raise InputError("start must be CalibrationParameters", argument="start", value=start)
    messages: list[str] = []
    nominal = start
    x_nominal = nominal.vector(nominal)
    if initial_offsets and any(n.startswith("offset") for n in names):
        guess = _initial_offsets(readings, start.design(design), start)
        if guess is not None:
            offsets = np.array(start.offsets)
            for i in range(3):
                if f"offset_{i + 1}" in names:
                    offsets[i] = guess[i]
            start = dataclasses.replace(start, offsets=offsets)
    x_start = start.vector(start)
    index = [PARAMETER_NAMES.index(n) for n in names]

    model_all = _Model(readings.theta, readings.orientation, readings.kind, design, start)
    first = model_all.evaluate(x_start, jac=True)
    used = first.reachable
    lines = readings.lines
    assert lines is not None
    if not np.any(used):
        raise InputError(
            "the start model cannot assemble any reading (no home-mode assembly at the "
            "readings' input angles); check the servo units, directions and zero offsets",
            argument="readings",
        )
    J0 = first.jacobian
    assert J0 is not None
    J0 = J0[used].reshape(-1, len(PARAMETER_NAMES))[:, index]
    kept, dropped, combos = _select(J0, names)
    free = [index[j] for j in kept]
    x_final = x_start.copy()
    f_scale = _LOSS_SCALE * math.radians(noise_deg)
    nfev = njev = 0

    def solve(used: BoolArray, z: FloatArray, f_scale: float) -> tuple[FloatArray, float]:
        """Identify the free parameters from the readings ``used``, starting at z."""
        nonlocal nfev, njev
        model = _Model(
            readings.theta[used], readings.orientation[used], readings.kind, design, start
        )

        def fun(z: FloatArray) -> FloatArray:
            x = x_start.copy()
            x[free] = z
            return model.evaluate(x, jac=False).residual.reshape(-1)

        def jac(z: FloatArray) -> FloatArray:
            x = x_start.copy()
            x[free] = z
            J = model.evaluate(x, jac=True).jacobian
            assert J is not None
            return J.reshape(-1, len(PARAMETER_NAMES))[:, free]

        rounds = 1 if loss == "linear" else 2
        for round_ in range(rounds):
            solution: OptimizeResult = least_squares(
                fun,
                z,
                jac=jac if jacobian == "analytic" else jacobian,  # type: ignore[arg-type]
                method="trf",
                loss=loss,  # type: ignore[arg-type]
                f_scale=f_scale,
                max_nfev=max_nfev,
                x_scale=1.0,
            )
            nfev += int(solution.nfev)
            njev += int(solution.njev or 0)
            if solution.status <= 0:
                raise ConvergenceError(
                    f"calibration did not converge: {solution.message}",
                    data={"result": solution, "parameters": [PARAMETER_NAMES[i] for i in free]},
                )
            z = np.asarray(solution.x, dtype=float)
            if round_ + 1 < rounds:
                sigma = 1.4826 * float(np.median(np.abs(fun(z))))
                f_scale = max(_LOSS_SCALE * sigma, 1e-9)
        return z, f_scale

    if free:
        z = x_start[free]
        # Readings the start model cannot assemble join once the fitted model can.
        for _ in range(3):
            z, f_scale = solve(used, z, _LOSS_SCALE * math.radians(noise_deg))
            x_final[free] = z
            now = model_all.evaluate(x_final, jac=False).reachable
            if np.array_equal(now, used) or np.sum(now) < np.sum(used):
                break
            used = now
    if not np.all(used):
        messages.append(
            f"{int(np.sum(~used))} reading(s) left out: the model cannot assemble them "
            f"(lines {lines[~used].tolist()})"
        )
    model = _Model(readings.theta[used], readings.orientation[used], readings.kind, design, start)
    k = model.k
    final = model.evaluate(x_final, jac=True)
    assert final.jacobian is not None
    J_all = final.jacobian.reshape(-1, len(PARAMETER_NAMES))
    r = final.residual.reshape(-1)
    m = r.size
    J_free = J_all[:, free]
    z2 = (r / f_scale) ** 2
    weights = _LOSS_WEIGHTS[loss](z2)
    dof = m - len(free)
    covariance = np.full((len(free), len(free)), np.inf)
    if free and dof > 0:
        # Huber's covariance of an M-estimate: [sum psi^2 / dof] / mean(psi')^2 (J^T J)^-1
        # with psi(r) = r rho'(r^2); for the linear loss this is s^2 (J^T J)^-1.
        slope = float(np.mean(_LOSS_SLOPES[loss](z2)))
        psi2 = float(np.sum((weights * r) ** 2) / dof)
        if slope > 0.1:
            s2 = psi2 / slope**2
            H = J_free.T @ J_free
        else:  # most residuals beyond the loss scale: fall back to weighted least squares
            s2 = float(np.sum(weights * r * r) / dof)
            H = J_free.T @ (weights[:, None] * J_free)
        try:
            covariance = s2 * np.linalg.inv(H)
        except np.linalg.LinAlgError:
            covariance = np.full((len(free), len(free)), np.inf)
    if not np.all(np.isfinite(covariance)):
        covariance = np.full((len(free), len(free)), np.inf)
    ident = _identifiability(
        J_all[:, index], names, kept, dropped, combos, covariance if dof > 0 else None
    )
    t = float(stdtrit(dof, 0.5 + confidence / 2.0)) if dof > 0 else math.inf
    estimates = []
    for j, name in enumerate(names):
        p = index[j]
        value, origin = float(x_final[p]), float(x_nominal[p])
        if j in kept and dof > 0:
            std = float(math.sqrt(max(covariance[kept.index(j), kept.index(j)], 0.0)))
            if not math.isfinite(std):
                std = math.inf
        else:
            std = math.inf
        half = t * std if math.isfinite(std) else math.inf
        estimates.append(
            ParameterEstimate(
                name=name,
                start=origin,
                value=value,
                std=std,
                low=value - half,
                high=value + half,
                identified=j in kept,
            )
        )
    parameters_final = CalibrationParameters.from_vector(x_final, start)
    calibrated = parameters_final.design(design, name=f"{design.name}_calibrated")

    # Per-reading errors before and after, over all readings.
    n = len(readings)
    at_nominal = model_all.evaluate(x_nominal, jac=False)
    before = _errors_deg(readings.kind, at_nominal.predicted, readings.orientation)
    after_eval = model_all.evaluate(x_final, jac=False)
    after = _errors_deg(readings.kind, after_eval.predicted, readings.orientation)
    residuals = np.full((n, k), np.nan)
    residuals[used] = final.residual
    pose_weights = np.full(n, np.nan)
    pose_weights[used] = weights.reshape(-1, k).mean(axis=1)
    sigma = 1.4826 * float(np.median(np.abs(r))) if r.size else math.nan
    outliers = np.zeros(n, dtype=bool)
    if sigma > 0:
        dof_pose = 3 if readings.kind == "quaternion" else 6
        limit = math.sqrt(float(chdtri(dof_pose, _OUTLIER_P))) * sigma
        norms = np.linalg.norm(final.residual, axis=1)
        outliers[np.nonzero(used)[0][norms > limit]] = True
    if np.any(outliers):
        messages.append(
            f"{int(np.sum(outliers))} reading(s) fit far worse than the noise level "
            f"(lines {lines[outliers].tolist()}); the robust loss down-weights them"
        )
    all_messages = [*ident.warnings, *messages]
    if not ident.ok:
        warnings.warn(
            "calibration: " + "; ".join(ident.warnings), IdentifiabilityWarning, stacklevel=2
        )
    return CalibrationResult(
        design=calibrated,
        parameters=parameters_final,
        start=nominal,
        estimates=tuple(estimates),
        covariance=covariance,
        identifiability=ident,
        confidence=float(confidence),
        readings=readings,
        used=used,
        error_start_deg=np.where(used, before, np.nan),
        error_deg=np.where(used, after, np.nan),
        residuals=residuals,
        weights=pose_weights,
        outliers=outliers,
        sigma_deg=math.degrees(sigma),
        loss=loss,
        f_scale=f_scale,
        cost=float(0.5 * np.sum(f_scale**2 * _rho(loss, (r / f_scale) ** 2))),
        nfev=nfev,
        njev=njev,
        method=jacobian,
        messages=tuple(all_messages),
    )


def _rho(loss: str, z: FloatArray) -> FloatArray:
    result: FloatArray
    if loss == "linear":
        result = z
    elif loss == "soft_l1":
        result = 2.0 * (np.sqrt(1.0 + z) - 1.0)
    elif loss == "huber":
        result = np.where(z <= 1.0, z, 2.0 * np.sqrt(np.maximum(z, 1.0)) - 1.0)
    elif loss == "cauchy":
        result = np.log1p(z)
    else:
        result = np.arctan(z)
    return result


def _check_positive(value: Any, name: str) -> float:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.floating))
        or not math.isfinite(value)
        or value <= 0
    ):
        raise InputError(
            f"{name} must be a positive finite number, got {value!r}", argument=name, value=value
        )
    return float(value)


# ========================================================================= observability
@dataclasses.dataclass(frozen=True)
class Observability:
    """How well a set of poses determines the parameters (before any reading is taken).

    Attributes:
        index: Observability index O1 = (s_1 ... s_n)^(1/n) / sqrt(poses) of the
            identification Jacobian (D-optimality; larger is better) [rad/rad].
        condition_number: Of the column-normalised Jacobian (smaller is better).
        singular_values: Of the (unscaled) Jacobian, descending.
        predicted_std: Expected standard deviation of each parameter [rad] for
            ``noise_deg`` per axis (inf where not identifiable).
        parameters: The parameter names, in order.
        identifiability: Which parameters the poses can separate.
    """

    index: float
    condition_number: float
    singular_values: FloatArray
    predicted_std: FloatArray
    parameters: tuple[str, ...]
    identifiability: Identifiability

    def as_dict(self) -> dict[str, Any]:
        """Plain data (degrees for the predicted deviations)."""
        return {
            "index": self.index,
            "condition_number": self.condition_number,
            "singular_values": self.singular_values.tolist(),
            "predicted_std_deg": {
                n: (math.degrees(s) if math.isfinite(s) else None)
                for n, s in zip(self.parameters, self.predicted_std, strict=True)
            },
            "identifiability": self.identifiability.as_dict(),
        }


def _pose_jacobians(
    theta: FloatArray,
    design: SPMDesign,
    names: Sequence[str],
    kind: str,
    start: CalibrationParameters,
) -> tuple[FloatArray, BoolArray]:
    """Identification Jacobian blocks (N, k, P) at readings ``theta`` = model inputs."""
    model = _Model(theta, None, kind, design, start)
    x = start.vector(start)
    evaluation = model.evaluate(x, jac=True)
    assert evaluation.jacobian is not None
    index = [PARAMETER_NAMES.index(n) for n in names]
    return evaluation.jacobian[:, :, index], evaluation.reachable


def _observability_of(
    blocks: FloatArray, names: Sequence[str], noise: float, poses: int
) -> Observability:
    J = blocks.reshape(-1, blocks.shape[-1])
    kept, dropped, combos = _select(J, names)
    singular = np.linalg.svd(J, compute_uv=False)
    P = J.shape[1]
    if singular.size >= P and singular[P - 1] > 0:
        index = float(np.exp(np.mean(np.log(singular[:P])))) / math.sqrt(poses)
    else:
        index = 0.0
    std = np.full(P, np.inf)
    if kept:
        sub = J[:, kept]
        cov = noise**2 * np.linalg.inv(sub.T @ sub)
        std[kept] = np.sqrt(np.diag(cov))
    ident = _identifiability(J, names, kept, dropped, combos, None)
    return Observability(
        index=index,
        condition_number=ident.condition_number,
        singular_values=np.asarray(singular, dtype=float),
        predicted_std=std,
        parameters=tuple(names),
        identifiability=ident,
    )


def observability(
    theta: npt.ArrayLike,
    design: SPMDesign | str | None = None,
    *,
    parameters: Sequence[str] | str | None = None,
    kind: str = "quaternion",
    noise_deg: float = 0.5,
) -> Observability:
    """Observability of the parameters from readings at input angles ``theta``.

    Args:
        theta: Input angles [rad] (N, 3) of the planned poses.
        design: The nominal design (default: the prototype).
        parameters: Names or groups (default as in :func:`calibrate`).
        kind: ``"quaternion"`` or ``"axes"`` readings.
        noise_deg: Measurement noise per axis [deg], for ``predicted_std``.

    Raises:
        InputError: bad arguments, or a pose without a home-mode assembly.
    """
    design = check_design(design)
    if kind not in _COMPONENTS:
        raise InputError(f"kind must be one of {sorted(_COMPONENTS)}", argument="kind", value=kind)
    names = _expand(parameters, kind)
    angles = _as_poses(theta, "theta")
    noise = math.radians(_check_positive(noise_deg, "noise_deg"))
    blocks, ok = _pose_jacobians(angles, design, names, kind, CalibrationParameters.nominal(design))
    if not np.all(ok):
        bad = np.nonzero(~ok)[0]
        raise InputError(
            f"poses {bad.tolist()} have no home-mode assembly", argument="theta", value=angles[bad]
        )
    return _observability_of(blocks, names, noise, angles.shape[0])


def _as_poses(theta: npt.ArrayLike, name: str) -> FloatArray:
    try:
        array = np.asarray(theta, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(f"{name} must be angles [rad] of shape (N, 3)", argument=name) from exc
    if (
        array.ndim != 2
        or array.shape[1] != 3
        or array.shape[0] < 1
        or not np.all(np.isfinite(array))
    ):
        raise InputError(
            f"{name} must be finite angles [rad] of shape (N, 3), got shape {array.shape}",
            argument=name,
            value=theta,
        )
    return array


@dataclasses.dataclass(frozen=True, eq=False)
class PosePlan:
    """Poses chosen for a calibration run.

    Attributes:
        theta: Input angles [rad] (N, 3), in the order to visit them (nearest
            neighbour from home).
        observability: Of the chosen poses.
        design: The nominal design planned for.
        candidates: How many admissible candidates the poses were chosen from.
        random_index: Observability index of as many random admissible poses (for
            comparison).
    """

    theta: FloatArray
    observability: Observability
    design: SPMDesign
    candidates: int
    random_index: float

    @property
    def theta_deg(self) -> FloatArray:
        """Input angles [deg] (N, 3)."""
        return np.degrees(self.theta)

    def to_csv(
        self, path: str | Path | None = None, *, joints: JointConvention | None = None
    ) -> str:
        """The pose list as CSV (``pose, theta1_deg, theta2_deg, theta3_deg``).

        With ``joints``, goal encoder counts ``servo1_ticks..servo3_ticks`` follow
        (rounded; the convention of :class:`JointConvention`).
        """
        obs = self.observability
        out = io.StringIO()
        out.write(
            f"# spm-pin calibration poses for {self.design.name}: {len(self.theta)} poses, "
            f"observability index {obs.index:.4g} (random poses: {self.random_index:.4g}), "
            f"condition number {obs.condition_number:.4g}\n"
        )
        out.write(
            "# At each pose: record the servo positions and the sensor orientation as one "
            "row of the readings file.\n"
        )
        header = ["pose", "theta1_deg", "theta2_deg", "theta3_deg"]
        if joints is not None:
            header += ["servo1_ticks", "servo2_ticks", "servo3_ticks"]
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(header)
        ticks = None if joints is None else np.rint(joints.angle_to_ticks(self.theta))
        for k, row in enumerate(self.theta_deg):
            values = [str(k + 1), *(f"{a:.6f}" for a in row)]
            if ticks is not None:
                values += [str(int(t)) for t in ticks[k]]
            writer.writerow(values)
        text = out.getvalue()
        if path is not None:
            Path(path).write_text(text, encoding="utf-8")
        return text


def load_poses(path: str | Path) -> FloatArray:
    """Input angles [rad] (N, 3) of a pose list written by :meth:`PosePlan.to_csv`.

    Needs the columns ``theta1_deg..theta3_deg`` (or ``_rad``); others are ignored.
    """
    path = Path(path)
    text, _ = _read_text(path, "pose list")
    header: list[str] | None = None
    rows: list[list[float]] = []
    cols: list[int] = []
    unit = "deg"
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        fields = [f.strip() for f in next(csv.reader([line]))]
        if header is None:
            header = fields
            for candidate in ("deg", "rad"):
                names = [f"theta{i}_{candidate}" for i in (1, 2, 3)]
                if all(n in header for n in names):
                    cols, unit = [header.index(n) for n in names], candidate
                    break
            else:
                raise FileFormatError(
                    f"missing columns theta1_deg, theta2_deg, theta3_deg (or _rad); the header "
                    f"has {header}",
                    path=str(path),
                    line=number,
                )
            continue
        if len(fields) != len(header):
            raise FileFormatError(
                f"{len(fields)} values, but the header has {len(header)} columns",
                path=str(path),
                line=number,
            )
        rows.append([_number(fields[c], header[c], number, str(path)) for c in cols])
    if not rows:
        raise FileFormatError("no poses in the file", path=str(path))
    theta = np.array(rows)
    return np.radians(theta) if unit == "deg" else theta


def _gaps_deg(theta: FloatArray, design: SPMDesign) -> FloatArray:
    """Gaps between adjacent proximal links [deg] of a coaxial design (N, 3)."""
    eta = np.asarray(design.eta)
    gaps = []
    for i in range(3):
        j = (i + 1) % 3
        gap = np.mod(eta[j] - eta[i], 2 * math.pi) + theta[:, i] - theta[:, j]
        gaps.append(np.degrees(gap))
    return np.stack(gaps, axis=1)


def _admissible(
    theta: FloatArray,
    design: SPMDesign,
    min_margin: float,
    min_gap_deg: float,
    accept: Callable[[FloatArray], npt.ArrayLike] | None,
) -> BoolArray:
    jac = jacobian(theta, design)
    ok = np.asarray(jac.reachable) & (np.nan_to_num(jac.singularity_margin) >= min_margin)
    if design.is_coaxial:
        ok &= np.all(_gaps_deg(theta, design) >= min_gap_deg, axis=1)
    if accept is not None and np.any(ok):
        verdict = np.asarray(accept(theta[ok]), dtype=bool)
        if verdict.shape != (int(np.sum(ok)),):
            raise InputError(
                f"accept must return one bool per pose, shape ({int(np.sum(ok))},), got "
                f"{verdict.shape}",
                argument="accept",
            )
        ok[np.nonzero(ok)[0][~verdict]] = False
    return ok


def _sample_poses(
    count: int,
    design: SPMDesign,
    rng: np.random.Generator,
    max_angle_deg: float,
    min_margin: float,
    min_gap_deg: float,
    accept: Callable[[FloatArray], npt.ArrayLike] | None,
) -> FloatArray:
    found: list[FloatArray] = []
    have = 0
    limit = math.radians(max_angle_deg)
    for _ in range(200):
        batch = rng.uniform(-limit, limit, size=(max(4 * (count - have), 256), 3))
        good = batch[_admissible(batch, design, min_margin, min_gap_deg, accept)]
        found.append(good)
        have += good.shape[0]
        if have >= count:
            return np.concatenate(found)[:count]
    raise InputError(
        f"found only {have} admissible poses of {count}: relax min_margin ({min_margin}), "
        f"min_gap_deg ({min_gap_deg}) or max_angle_deg ({max_angle_deg})",
        argument="min_margin",
        value=min_margin,
    )


def plan_poses(
    count: int,
    design: SPMDesign | str | None = None,
    *,
    parameters: Sequence[str] | str | None = None,
    kind: str = "quaternion",
    candidates: int = 2000,
    seed: int = 0,
    max_angle_deg: float = 90.0,
    min_margin: float = 0.25,
    min_gap_deg: float = 45.0,
    accept: Callable[[FloatArray], npt.ArrayLike] | None = None,
    noise_deg: float = 0.5,
) -> PosePlan:
    """Choose informative poses for a calibration run (greedy D-optimal design).

    Candidates are input angles uniform in [-max_angle_deg, max_angle_deg]^3 that the
    nominal design assembles, with singularity margin >= ``min_margin`` (see
    :func:`spm_pin.jacobian`), for coaxial designs gaps between adjacent proximal
    links >= ``min_gap_deg``, and accepted by ``accept`` (e.g. a collision check).
    Poses are added one at a time, each maximising log det(J^T J) of the poses so far
    (the observability index O1), then ordered by nearest neighbour from home.

    Args:
        count: Number of poses (>= 1).
        design: The nominal design (default: the prototype).
        parameters: Names or groups to identify (default as in :func:`calibrate`).
        kind: ``"quaternion"`` or ``"axes"`` readings.
        candidates: Number of admissible candidates to choose from.
        seed: Seed of the candidate sampler.
        max_angle_deg: Range of each input angle around home [deg].
        min_margin: Smallest singularity margin, in [0, 1).
        min_gap_deg: Smallest gap between adjacent proximal links [deg] (coaxial).
        accept: Optional filter, (M, 3) input angles [rad] -> (M,) bools.
        noise_deg: Measurement noise per axis [deg] for the predicted deviations.

    Returns:
        PosePlan; ``plan.to_csv(path)`` writes the pose list.
    """
    design = check_design(design)
    count = _check_count(count, "count")
    candidates = _check_count(candidates, "candidates")
    if kind not in _COMPONENTS:
        raise InputError(f"kind must be one of {sorted(_COMPONENTS)}", argument="kind", value=kind)
    names = _expand(parameters, kind)
    _check_positive(max_angle_deg, "max_angle_deg")
    noise = math.radians(_check_positive(noise_deg, "noise_deg"))
    if (
        isinstance(min_margin, bool)
        or not isinstance(min_margin, (int, float))
        or not (0.0 <= min_margin < 1.0)
    ):
        raise InputError(
            f"min_margin must lie in [0, 1), got {min_margin!r}", argument="min_margin"
        )
    if isinstance(min_gap_deg, bool) or not isinstance(min_gap_deg, (int, float)):
        raise InputError(
            f"min_gap_deg must be a number, got {min_gap_deg!r}", argument="min_gap_deg"
        )
    rng = np.random.default_rng(seed)
    pool = _sample_poses(
        max(candidates, count), design, rng, max_angle_deg, min_margin, min_gap_deg, accept
    )
    start = CalibrationParameters.nominal(design)
    blocks, _ = _pose_jacobians(pool, design, names, kind, start)
    P = blocks.shape[-1]
    scale = float(np.mean(np.einsum("nkp,nkp->n", blocks, blocks))) / P
    M = 1e-6 * max(scale, 1e-12) * np.eye(P)
    chosen: list[int] = []
    available = np.ones(pool.shape[0], dtype=bool)
    for _ in range(count):
        Minv = np.linalg.inv(M)
        S = blocks @ Minv @ np.swapaxes(blocks, -1, -2)
        gain = np.linalg.slogdet(np.eye(blocks.shape[1]) + S)[1]
        gain[~available] = -np.inf
        best = int(np.argmax(gain))
        chosen.append(best)
        available[best] = False
        M = M + blocks[best].T @ blocks[best]
    theta = _nearest_neighbour_order(pool[chosen])
    chosen_blocks, _ = _pose_jacobians(theta, design, names, kind, start)
    obs = _observability_of(chosen_blocks, names, noise, count)
    random_blocks = blocks[rng.choice(pool.shape[0], size=count, replace=False)]
    random_index = _observability_of(random_blocks, names, noise, count).index
    return PosePlan(
        theta=theta,
        observability=obs,
        design=design,
        candidates=int(pool.shape[0]),
        random_index=random_index,
    )


def _nearest_neighbour_order(theta: FloatArray) -> FloatArray:
    order: list[int] = []
    left = list(range(theta.shape[0]))
    here = np.zeros(3)
    while left:
        dist = np.max(np.abs(theta[left] - here), axis=1)
        k = left.pop(int(np.argmin(dist)))
        order.append(k)
        here = theta[k]
    return theta[order]


def _check_count(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise InputError(
            f"{name} must be a positive integer, got {value!r}", argument=name, value=value
        )
    return int(value)


# ============================================================================ synthetic
@dataclasses.dataclass(frozen=True, eq=False)
class SyntheticReadings:
    """Readings of a simulated prototype, with the truth behind them.

    Attributes:
        readings: What the prototype would report (quantised encoders, noisy sensor).
        truth: The parameters the readings were made with.
        design: The true (perturbed) design.
        theta: The true model input angles [rad] (N, 3).
        outliers: (N,) readings given a gross sensor error.
    """

    readings: Readings
    truth: CalibrationParameters
    design: SPMDesign
    theta: FloatArray
    outliers: BoolArray


def synthetic_readings(
    poses: int | npt.ArrayLike = 100,
    design: SPMDesign | str | None = None,
    *,
    seed: int = 0,
    truth: CalibrationParameters | None = None,
    offset_std_deg: float = 2.0,
    link_std_deg: float = 0.5,
    mount_std_deg: float = 2.0,
    noise_deg: float = 0.5,
    kind: str = "quaternion",
    unit: str = "ticks",
    joints: JointConvention | None = None,
    outlier_fraction: float = 0.0,
    outlier_deg: float = 20.0,
    max_angle_deg: float = 90.0,
    min_margin: float = 0.25,
) -> SyntheticReadings:
    """Readings of a perturbed prototype with realistic noise, reproducible by ``seed``.

    The truth (unless given) draws each offset from N(0, offset_std_deg), each link
    angle from the design's value + N(0, link_std_deg) and the mounting rotation
    vector from N(0, mount_std_deg) per axis; the reference is the identity. At each
    pose the servos stand at ``poses`` (commanded angles, the model's inputs at zero
    offsets; or that many random admissible poses), the encoders report whole counts
    (``joints``, 4096 per turn: 0.088 deg steps, also for ``unit="deg"``), and the
    sensor reports R_ref R R_mount exp([n]) with n ~ N(0, noise_deg^2) per axis (for
    axis readings, each axis turned by its own such n).

    Args:
        poses: Number of random poses, or commanded angles [rad] (N, 3).
        design: The nominal design (default: the prototype).
        seed: Seed of every random draw.
        truth: The true parameters (default: drawn as above).
        offset_std_deg: Spread of the drawn offsets [deg].
        link_std_deg: Spread of the drawn link angles [deg].
        mount_std_deg: Spread of the drawn mounting rotation [deg].
        noise_deg: Sensor noise per axis [deg] (0.5 for a typical IMU; 0 for none).
        kind: ``"quaternion"`` or ``"axes"``.
        unit: Unit the servo columns will be written in: ``"ticks"``, ``"deg"``, ``"rad"``.
        joints: Encoder convention (default: XM540, zero at 0 counts, direction +1).
        outlier_fraction: Fraction of readings given a gross sensor error.
        outlier_deg: Size of those errors [deg].
        max_angle_deg: Range of the random poses around home [deg].
        min_margin: Smallest singularity margin of the random poses.

    Raises:
        InputError: bad arguments, or given poses the true design cannot assemble.
    """
    design = check_design(design)
    if kind not in _COMPONENTS:
        raise InputError(f"kind must be one of {sorted(_COMPONENTS)}", argument="kind", value=kind)
    if unit not in _SERVO_UNITS:
        raise InputError(f"unit must be one of {list(_SERVO_UNITS)}", argument="unit", value=unit)
    for value, name in (
        (offset_std_deg, "offset_std_deg"),
        (link_std_deg, "link_std_deg"),
        (mount_std_deg, "mount_std_deg"),
        (noise_deg, "noise_deg"),
        (outlier_deg, "outlier_deg"),
    ):
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not (-1e308 <= value <= 1e308)  # NaN, inf and ints too large for a float
            or not (math.isfinite(value) and value >= 0)
        ):
            raise InputError(f"{name} must be a number >= 0, got {value!r}", argument=name)
    if (
        isinstance(outlier_fraction, bool)
        or not isinstance(outlier_fraction, (int, float))
        or not (0.0 <= outlier_fraction <= 1.0)
    ):
        raise InputError(
            f"outlier_fraction must lie in [0, 1], got {outlier_fraction!r}",
            argument="outlier_fraction",
        )
    joints = JointConvention() if joints is None else joints
    rng = np.random.default_rng(seed)
    if truth is None:
        link = np.radians(link_std_deg) * rng.standard_normal(3)
        truth = CalibrationParameters(
            offsets=np.radians(offset_std_deg) * rng.standard_normal(3),
            alpha1=design.alpha1 + link[0],
            alpha2=design.alpha2 + link[1],
            beta=design.beta + link[2],
            mount=_exp(np.radians(mount_std_deg) * rng.standard_normal(3)),
            reference=np.eye(3),
        )
    elif not isinstance(truth, CalibrationParameters):
        raise InputError("truth must be CalibrationParameters", argument="truth", value=truth)
    true_design = truth.design(design, name=f"{design.name}_true")
    if isinstance(poses, (int, np.integer)) and not isinstance(poses, bool):
        count = _check_count(poses, "poses")

        def shifted(t: FloatArray) -> npt.ArrayLike:
            """Poses the true design assembles at the true inputs."""
            return forward_kinematics(t - truth.offsets, true_design).reachable

        commanded = _sample_poses(count, design, rng, max_angle_deg, min_margin, 0.0, shifted)
    else:
        commanded = _as_poses(poses, "poses")
    counts = joints.angle_to_ticks(commanded)
    reported = np.rint(counts)
    theta_reading = joints.ticks_to_angle(reported)
    theta_true = commanded - truth.offsets
    fk = forward_kinematics(theta_true, true_design)
    if not np.all(fk.reachable):
        bad = np.nonzero(~np.asarray(fk.reachable))[0]
        raise InputError(
            f"the true design cannot assemble poses {bad.tolist()}",
            argument="poses",
            value=commanded[bad],
        )
    n = commanded.shape[0]
    noise = math.radians(noise_deg)
    outliers = np.zeros(n, dtype=bool)
    n_out = round(outlier_fraction * n)
    if n_out:
        outliers[rng.choice(n, size=n_out, replace=False)] = True
    if kind == "quaternion":
        measured = truth.reference @ fk.R @ truth.mount
        kicks = noise * rng.standard_normal((n, 3))
        measured = np.stack([measured[k] @ _exp(kicks[k]) for k in range(n)])
        for k in np.nonzero(outliers)[0]:
            axis = rng.standard_normal(3)
            measured[k] = measured[k] @ _exp(
                math.radians(outlier_deg) * axis / np.linalg.norm(axis)
            )
    else:
        v = np.einsum("jk,nik->nij", truth.reference, fk.v)
        kicks = noise * rng.standard_normal((n, 3, 3))
        measured = np.stack(
            [np.stack([_exp(kicks[k, i]) @ v[k, i] for i in range(3)]) for k in range(n)]
        )
        for k in np.nonzero(outliers)[0]:
            axis = rng.standard_normal(3)
            turn = _exp(math.radians(outlier_deg) * axis / np.linalg.norm(axis))
            measured[k] = measured[k] @ turn.T
    readings = Readings(
        theta=theta_reading,
        orientation=measured,
        kind=kind,
        labels=tuple(str(k + 1) for k in range(n)),
        joints=joints,
        servo_unit=unit,
    )
    return SyntheticReadings(
        readings=readings, truth=truth, design=true_design, theta=theta_true, outliers=outliers
    )
