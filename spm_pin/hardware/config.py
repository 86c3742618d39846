"""The servo configuration: port, joints, servo settings and safety limits, in TOML.

A configuration file (angles in degrees, as everywhere on disk)::

    port = "/dev/ttyUSB0"
    baudrate = 57600      # the servos' factory default; 1000000 once they are set to it
    latency_timer_ms = 16.0
    rate_hz = 100.0

    [[joints]]            # one table per actuated joint, u_1, u_2, u_3 in order
    joint = "u_1"
    servo_id = 1
    direction = 1         # +1: servo and joint turn the same way, -1: opposite
    gear_ratio = 1.0      # servo turns per joint turn (1:1 on the prototype)
    zero_offset = 2048    # Present Position [pulses] when theta_i = 0

    [servo]               # written to every servo by ServoBus.configure
    profile_velocity_deg_s = 120.0
    profile_acceleration_deg_s2 = 1200.0
    velocity_limit_deg_s = 300.0
    current_limit_a = 5.5
    return_delay_us = 0.0
    shutdown = ["overheating", "electrical shock", "overload"]

    [safety]              # the guard's limits
    min_singularity_margin = 0.1
    collision_margin_mm = 0.5
    max_speed_deg_s = 90.0
    max_acceleration_deg_s2 = 360.0

Every key is optional (the defaults above). The servos' profile must be at least as
fast as the guard's limits (times the gear ratio), or the servos could not follow the
path the guard checked.

:meth:`HardwareConfig.load` reports every unknown or malformed key with the file
name; :meth:`HardwareConfig.save` writes a file that loads back to the same values
(degrees rounded to 1e-9).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import tomli_w

from ..design import _parse_toml, _read_text
from ..errors import FileFormatError, InputError
from .control_table import HardwareErrorFlag
from .servo_data import ServoSettings

__all__ = [
    "HardwareConfig",
    "JointConfig",
    "RebootPolicy",
    "SafetyLimits",
]

_JOINT_NAMES = ("u_1", "u_2", "u_3")
#: Joint range that keeps every servo inside its extended-position range
#: (+-256 turns) with margin [rad]: +-200 turns of the joint at a 1:1 gear.
_DEFAULT_THETA_LIMIT = 200 * 2 * math.pi


def _real(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _check_count(value: Any, name: str, low: int, high: int) -> None:
    """InputError unless ``value`` is an int (not a bool) in low..high."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise InputError(
            f"{name} must be an integer >= {low}, got {value!r}", argument=name, value=value
        )
    if not low <= value <= high:
        raise InputError(
            f"{name} must lie in {low}..{high}, got {value}", argument=name, value=value
        )


def _flags(names: Sequence[str], key: str, source: str | None) -> HardwareErrorFlag:
    flags = HardwareErrorFlag(0)
    known = {flag.name.lower().replace("_", " "): flag for flag in HardwareErrorFlag if flag.name}
    for name in names:
        if not isinstance(name, str) or name.lower().replace("_", " ") not in known:
            raise FileFormatError(
                f"{key}: unknown hardware error {name!r}; known: {sorted(known)}", path=source
            )
        flags |= known[name.lower().replace("_", " ")]
    return flags


@dataclasses.dataclass(frozen=True)
class JointConfig:
    """How one actuated joint maps to its servo.

    theta_i = direction * (pulses - zero_offset - 4096 k_i) * 2 pi / 4096 / gear_ratio,
    with k_i the servo turns fixed when the loop starts (see
    :class:`~spm_pin.hardware.joints.JointMap`).

    Attributes:
        joint: ``"u_1"``, ``"u_2"`` or ``"u_3"``.
        servo_id: Dynamixel id (0..252).
        direction: +1 when servo and joint turn the same way, -1 otherwise.
        gear_ratio: Servo turns per joint turn (> 0; 1 on the prototype).
        zero_offset: Present Position of the servo at theta_i = 0 [pulses].
    """

    joint: str
    servo_id: int
    direction: int = 1
    gear_ratio: float = 1.0
    zero_offset: int = 2048

    def __post_init__(self) -> None:
        if self.joint not in _JOINT_NAMES:
            raise InputError(
                f"joint must be one of {list(_JOINT_NAMES)}, got {self.joint!r}",
                argument="joint",
                value=self.joint,
            )
        if (
            isinstance(self.servo_id, bool)
            or not isinstance(self.servo_id, int)
            or not 0 <= self.servo_id <= 252
        ):
            raise InputError(
                f"servo_id must be an integer in 0..252, got {self.servo_id!r}",
                argument="servo_id",
                value=self.servo_id,
            )
        if self.direction not in (1, -1) or isinstance(self.direction, bool):
            raise InputError(
                f"direction must be 1 or -1, got {self.direction!r}",
                argument="direction",
                value=self.direction,
            )
        if not _real(self.gear_ratio) or self.gear_ratio <= 0:
            raise InputError(
                f"gear_ratio must be a positive number (servo turns per joint turn), got "
                f"{self.gear_ratio!r}",
                argument="gear_ratio",
                value=self.gear_ratio,
            )
        if isinstance(self.zero_offset, bool) or not isinstance(self.zero_offset, int):
            raise InputError(
                f"zero_offset must be an integer number of pulses, got {self.zero_offset!r}",
                argument="zero_offset",
                value=self.zero_offset,
            )


@dataclasses.dataclass(frozen=True)
class SafetyLimits:
    """What the guard requires of every goal before it is sent.

    Attributes:
        min_singularity_margin: Smallest accepted ``spm.jacobian(...).singularity_margin``
            (0..1; 0 is singular).
        min_dexterity: Smallest accepted dexterity 1/kappa(J) (0..1; 0 disables).
        collision_margin: Links closer than this count as colliding [m]; the
            prototype's nested drive tubes are 1 mm apart, so keep it below 1 mm.
        max_speed: Largest joint speed of a commanded motion [rad/s].
        max_acceleration: Largest joint acceleration of a commanded motion [rad/s^2].
        theta_min: Lower joint limits [rad], (3,).
        theta_max: Upper joint limits [rad], (3,).
        path_resolution: Largest joint step between two checked samples of a path
            [rad]; longer steps are subdivided for checking.
    """

    min_singularity_margin: float = 0.1
    min_dexterity: float = 0.0
    collision_margin: float = 0.0005
    max_speed: float = math.radians(90.0)
    max_acceleration: float = math.radians(360.0)
    theta_min: tuple[float, float, float] = (-_DEFAULT_THETA_LIMIT,) * 3
    theta_max: tuple[float, float, float] = (_DEFAULT_THETA_LIMIT,) * 3
    path_resolution: float = math.radians(1.0)

    def __post_init__(self) -> None:
        for name, low, high in (
            ("min_singularity_margin", 0.0, 1.0),
            ("min_dexterity", 0.0, 1.0),
            ("collision_margin", 0.0, 0.1),
        ):
            value = getattr(self, name)
            if not _real(value) or not low <= value < high:
                raise InputError(
                    f"{name} must be a number in [{low}, {high}), got {value!r}",
                    argument=name,
                    value=value,
                )
        for name in ("max_speed", "max_acceleration", "path_resolution"):
            value = getattr(self, name)
            if not _real(value) or value <= 0:
                raise InputError(
                    f"{name} must be a positive number, got {value!r}", argument=name, value=value
                )
        for name in ("theta_min", "theta_max"):
            value = getattr(self, name)
            if len(value) != 3 or not all(_real(v) for v in value):
                raise InputError(
                    f"{name} must be 3 finite angles [rad], got {value!r}",
                    argument=name,
                    value=value,
                )
            object.__setattr__(self, name, tuple(float(v) for v in value))
        if not all(lo < hi for lo, hi in zip(self.theta_min, self.theta_max, strict=True)):
            raise InputError(
                f"theta_min {self.theta_min} must lie below theta_max {self.theta_max}",
                argument="theta_min",
                value=self.theta_min,
            )


@dataclasses.dataclass(frozen=True)
class RebootPolicy:
    """When the loop may reboot a servo that reports a hardware error.

    A reboot clears the error and drops torque; the loop then restores the profile,
    holds the present position and turns torque on again. Overheating and encoder
    errors are never cleared this way (the servo needs cooling or service).

    Attributes:
        max_reboots: Reboots allowed per servo during one session.
        reboot_on: The errors a reboot may clear.
    """

    max_reboots: int = 1
    reboot_on: HardwareErrorFlag = HardwareErrorFlag.OVERLOAD | HardwareErrorFlag.ELECTRICAL_SHOCK

    def __post_init__(self) -> None:
        _check_count(self.max_reboots, "max_reboots", 0, 10)
        never = HardwareErrorFlag.OVERHEATING | HardwareErrorFlag.MOTOR_ENCODER
        if self.reboot_on & never:
            raise InputError(
                "reboot_on must not include overheating or the motor encoder (a reboot does "
                "not cure them)",
                argument="reboot_on",
                value=self.reboot_on,
            )


def _default_joints() -> tuple[JointConfig, JointConfig, JointConfig]:
    return (JointConfig("u_1", 1), JointConfig("u_2", 2), JointConfig("u_3", 3))


@dataclasses.dataclass(frozen=True)
class HardwareConfig:
    """Everything the hardware layer needs to know about a robot's servos.

    Attributes:
        port: Serial device.
        baudrate: Line rate [bit/s] (every servo's Baud Rate item; default the
            XM540-W150's factory default, 57600, which the emulator also uses).
        latency_timer_ms: Latency allowed for in the packet timeout [ms].
        retries: Extra attempts of a failed transaction.
        fast_sync_read: True, False, or None (use it when the firmware has it).
        rate_hz: Loop rate of moves and follows [Hz].
        max_failures: Consecutive failed cycles after which torque goes off.
        joints: The three actuated joints, u_1, u_2, u_3 in order.
        servo: Settings written to every servo.
        safety: The guard's limits.
        reboot: The reboot policy.
    """

    port: str = "/dev/ttyUSB0"
    baudrate: int = 57_600
    latency_timer_ms: float = 16.0
    retries: int = 2
    fast_sync_read: bool | None = None
    rate_hz: float = 100.0
    max_failures: int = 3
    joints: tuple[JointConfig, JointConfig, JointConfig] = dataclasses.field(
        default_factory=_default_joints
    )
    servo: ServoSettings = dataclasses.field(default_factory=ServoSettings)
    safety: SafetyLimits = dataclasses.field(default_factory=SafetyLimits)
    reboot: RebootPolicy = dataclasses.field(default_factory=RebootPolicy)

    def __post_init__(self) -> None:
        joints = tuple(self.joints)
        if len(joints) != 3 or [j.joint for j in joints] != list(_JOINT_NAMES):
            raise InputError(
                f"joints must be u_1, u_2, u_3 in order, got {[j.joint for j in joints]}",
                argument="joints",
                value=self.joints,
            )
        ids = [j.servo_id for j in joints]
        if len(set(ids)) != 3:
            raise InputError(
                f"every joint needs its own servo id, got {ids}", argument="joints", value=ids
            )
        object.__setattr__(self, "joints", joints)
        if not _real(self.rate_hz) or not 1.0 <= self.rate_hz <= 2000.0:
            raise InputError(
                f"rate_hz must lie in [1, 2000] Hz, got {self.rate_hz!r}",
                argument="rate_hz",
                value=self.rate_hz,
            )
        # The servos must be able to track the checked path: each servo moves to its
        # goal at its own profile, so a profile slower than the path lets the joints
        # drift off the straight line the guard checked.
        gear = max(j.gear_ratio for j in joints)
        if self.servo.profile_velocity < self.safety.max_speed * gear:
            raise InputError(
                f"servo profile velocity {self.servo.profile_velocity:g} rad/s is below the "
                f"guard's max_speed {self.safety.max_speed:g} rad/s x gear ratio {gear:g}: the "
                "servos could not track the checked path; raise the profile or lower max_speed",
                argument="servo",
                value=self.servo.profile_velocity,
            )
        if self.servo.profile_acceleration < self.safety.max_acceleration * gear:
            raise InputError(
                f"servo profile acceleration {self.servo.profile_acceleration:g} rad/s^2 is "
                f"below the guard's max_acceleration {self.safety.max_acceleration:g} rad/s^2 x "
                f"gear ratio {gear:g}: the servos could not track the checked path",
                argument="servo",
                value=self.servo.profile_acceleration,
            )
        _check_count(self.max_failures, "max_failures", 1, 100)

    @property
    def ids(self) -> tuple[int, int, int]:
        """Servo ids of u_1, u_2, u_3."""
        a, b, c = (j.servo_id for j in self.joints)
        return (a, b, c)

    @property
    def period(self) -> float:
        """Loop period [s]."""
        return 1.0 / self.rate_hz

    def replace(self, **changes: Any) -> HardwareConfig:
        """A copy with some fields changed (``config.replace(port="/dev/pts/3")``)."""
        return dataclasses.replace(self, **changes)

    # ------------------------------------------------------------------ TOML
    def to_dict(self) -> dict[str, Any]:
        """Plain data in file units (degrees, mm, microseconds)."""
        servo, safety = self.servo, self.safety

        def deg(angle: float) -> float:
            return round(math.degrees(angle), 9) + 0.0

        return {
            "port": self.port,
            "baudrate": self.baudrate,
            "latency_timer_ms": self.latency_timer_ms,
            "retries": self.retries,
            "fast_sync_read": "auto" if self.fast_sync_read is None else self.fast_sync_read,
            "rate_hz": self.rate_hz,
            "max_failures": self.max_failures,
            "joints": [dataclasses.asdict(j) for j in self.joints],
            "servo": {
                "profile_velocity_deg_s": deg(servo.profile_velocity),
                "profile_acceleration_deg_s2": deg(servo.profile_acceleration),
                "velocity_limit_deg_s": deg(servo.velocity_limit),
                "current_limit_a": servo.current_limit,
                "return_delay_us": round(servo.return_delay * 1e6, 6),
                "shutdown": servo.shutdown.describe(),
            },
            "safety": {
                "min_singularity_margin": safety.min_singularity_margin,
                "min_dexterity": safety.min_dexterity,
                "collision_margin_mm": round(safety.collision_margin * 1e3, 9),
                "max_speed_deg_s": deg(safety.max_speed),
                "max_acceleration_deg_s2": deg(safety.max_acceleration),
                "theta_min_deg": [deg(v) for v in safety.theta_min],
                "theta_max_deg": [deg(v) for v in safety.theta_max],
                "path_resolution_deg": deg(safety.path_resolution),
            },
            "reboot": {
                "max_reboots": self.reboot.max_reboots,
                "reboot_on": self.reboot.reboot_on.describe(),
            },
        }

    def to_toml(self) -> str:
        """The configuration as TOML text."""
        header = (
            "# spm-pin servo configuration: angles in degrees, lengths in mm, positions in pulses\n"
        )
        return header + tomli_w.dumps(self.to_dict())

    def save(self, path: str | Path) -> Path:
        """Write the configuration to a TOML file and return its path."""
        out = Path(path)
        out.write_text(self.to_toml(), encoding="utf-8")
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, source: str | None = None) -> HardwareConfig:
        """Inverse of :meth:`to_dict`; every key is optional, unknown keys are errors."""
        reader = _Reader(source)
        top = reader.table(data, "", _TOP_KEYS)
        kwargs: dict[str, Any] = {}
        for key in ("port",):
            if key in top:
                kwargs[key] = reader.string(top[key], key)
        for key in ("baudrate", "retries", "max_failures"):
            if key in top:
                kwargs[key] = reader.integer(top[key], key)
        for key in ("latency_timer_ms", "rate_hz"):
            if key in top:
                kwargs[key] = reader.number(top[key], key)
        if "fast_sync_read" in top:
            value = top["fast_sync_read"]
            if value not in ("auto", True, False):
                raise FileFormatError(
                    f'fast_sync_read must be true, false or "auto", got {value!r}', path=source
                )
            kwargs["fast_sync_read"] = None if value == "auto" else value
        try:
            if "joints" in top:
                joints = top["joints"]
                if not isinstance(joints, list):
                    raise FileFormatError("[[joints]] must be an array of tables", path=source)
                kwargs["joints"] = tuple(reader.joint(j, k) for k, j in enumerate(joints))
            if "servo" in top:
                kwargs["servo"] = reader.servo(top["servo"])
            if "safety" in top:
                kwargs["safety"] = reader.safety(top["safety"])
            if "reboot" in top:
                kwargs["reboot"] = reader.reboot(top["reboot"])
            return cls(**kwargs)
        except InputError as exc:
            if isinstance(exc, FileFormatError):
                raise
            raise FileFormatError(str(exc), path=source) from exc

    @classmethod
    def from_toml(cls, text: str, *, source: str | None = None) -> HardwareConfig:
        """Parse TOML text (see :meth:`to_toml`)."""
        return cls.from_dict(_parse_toml(text, source), source=source)

    @classmethod
    def load(cls, path: str | Path) -> HardwareConfig:
        """Read a configuration file written by :meth:`save` (or by hand)."""
        text, source = _read_text(path, "servo configuration")
        return cls.from_toml(text, source=source)


_TOP_KEYS = {
    "port",
    "baudrate",
    "latency_timer_ms",
    "retries",
    "fast_sync_read",
    "rate_hz",
    "max_failures",
    "joints",
    "servo",
    "safety",
    "reboot",
}
_JOINT_KEYS = {"joint", "servo_id", "direction", "gear_ratio", "zero_offset"}
_SERVO_KEYS = {
    "profile_velocity_deg_s",
    "profile_acceleration_deg_s2",
    "velocity_limit_deg_s",
    "current_limit_a",
    "return_delay_us",
    "shutdown",
}
_SAFETY_KEYS = {
    "min_singularity_margin",
    "min_dexterity",
    "collision_margin_mm",
    "max_speed_deg_s",
    "max_acceleration_deg_s2",
    "theta_min_deg",
    "theta_max_deg",
    "path_resolution_deg",
}
_REBOOT_KEYS = {"max_reboots", "reboot_on"}


class _Reader:
    """Typed access to TOML data with errors that name the file and the key."""

    def __init__(self, source: str | None) -> None:
        self.source = source

    def fail(self, message: str) -> FileFormatError:
        return FileFormatError(message, path=self.source)

    def table(self, data: Any, name: str, allowed: set[str]) -> Mapping[str, Any]:
        where = f"[{name}]" if name else "the file"
        if not isinstance(data, Mapping):
            raise self.fail(f"{where} must be a table")
        unknown = set(data) - allowed
        if unknown:
            raise self.fail(
                f"{where} has unknown key(s) {sorted(unknown)}; allowed: {sorted(allowed)}"
            )
        return data

    def number(self, value: Any, key: str) -> float:
        if not _real(value):
            raise self.fail(f"{key} must be a finite number, got {value!r}")
        return float(value)

    def integer(self, value: Any, key: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(f"{key} must be an integer, got {value!r}")
        return value

    def string(self, value: Any, key: str) -> str:
        if not isinstance(value, str):
            raise self.fail(f"{key} must be a string, got {value!r}")
        return value

    def angles(self, value: Any, key: str) -> tuple[float, float, float]:
        if not isinstance(value, list) or len(value) != 3:
            raise self.fail(f"{key} must be a list of 3 angles [deg], got {value!r}")
        a, b, c = (math.radians(self.number(v, key)) for v in value)
        return (a, b, c)

    def names(self, value: Any, key: str) -> HardwareErrorFlag:
        if not isinstance(value, list):
            raise self.fail(f"{key} must be a list of hardware error names, got {value!r}")
        return _flags(value, key, self.source)

    def joint(self, data: Any, index: int) -> JointConfig:
        table = self.table(data, f"joints {index + 1}", _JOINT_KEYS)
        if "joint" not in table or "servo_id" not in table:
            raise self.fail(f"[[joints]] number {index + 1} needs 'joint' and 'servo_id'")
        return JointConfig(
            joint=self.string(table["joint"], "joint"),
            servo_id=self.integer(table["servo_id"], "servo_id"),
            direction=self.integer(table.get("direction", 1), "direction"),
            gear_ratio=self.number(table.get("gear_ratio", 1.0), "gear_ratio"),
            zero_offset=self.integer(table.get("zero_offset", 2048), "zero_offset"),
        )

    def servo(self, data: Any) -> ServoSettings:
        table = self.table(data, "servo", _SERVO_KEYS)
        default = ServoSettings()
        kwargs: dict[str, Any] = {}
        for key, field, scale in (
            ("profile_velocity_deg_s", "profile_velocity", math.radians(1.0)),
            ("profile_acceleration_deg_s2", "profile_acceleration", math.radians(1.0)),
            ("velocity_limit_deg_s", "velocity_limit", math.radians(1.0)),
            ("current_limit_a", "current_limit", 1.0),
            ("return_delay_us", "return_delay", 1e-6),
        ):
            if key in table:
                kwargs[field] = self.number(table[key], key) * scale
        if "shutdown" in table:
            kwargs["shutdown"] = self.names(table["shutdown"], "shutdown")
        return dataclasses.replace(default, **kwargs)

    def safety(self, data: Any) -> SafetyLimits:
        table = self.table(data, "safety", _SAFETY_KEYS)
        kwargs: dict[str, Any] = {}
        for key, field, scale in (
            ("min_singularity_margin", "min_singularity_margin", 1.0),
            ("min_dexterity", "min_dexterity", 1.0),
            ("collision_margin_mm", "collision_margin", 1e-3),
            ("max_speed_deg_s", "max_speed", math.radians(1.0)),
            ("max_acceleration_deg_s2", "max_acceleration", math.radians(1.0)),
            ("path_resolution_deg", "path_resolution", math.radians(1.0)),
        ):
            if key in table:
                kwargs[field] = self.number(table[key], key) * scale
        for key, field in (("theta_min_deg", "theta_min"), ("theta_max_deg", "theta_max")):
            if key in table:
                kwargs[field] = self.angles(table[key], key)
        return SafetyLimits(**kwargs)

    def reboot(self, data: Any) -> RebootPolicy:
        table = self.table(data, "reboot", _REBOOT_KEYS)
        kwargs: dict[str, Any] = {}
        if "max_reboots" in table:
            kwargs["max_reboots"] = self.integer(table["max_reboots"], "max_reboots")
        if "reboot_on" in table:
            kwargs["reboot_on"] = self.names(table["reboot_on"], "reboot_on")
        return RebootPolicy(**kwargs)
