"""The readings file (CSV): its settings, header columns and orientation columns, read
into arrays for :func:`spm_pin.calibration.parse_readings`."""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..errors import FileFormatError, InputError
from ..rotations import matrix_from_quaternion, matrix_from_rpy
from ._constants import ANGLE_UNITS, SERVO_UNITS, UNIT_TOL, FloatArray, IntArray
from .convention import JointConvention

SETTING = re.compile(r"^#\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*(.*?)\s*$")
_SERVO_COLUMN = re.compile(r"^servo([123])_(.+)$")
_EULER_COLUMN = re.compile(r"^(roll|pitch|yaw)_(.+)$")
_QUATERNION = ("qw", "qx", "qy", "qz")
_AXES = tuple(f"v{i}_{c}" for i in (1, 2, 3) for c in "xyz")
SETTINGS = ("ticks_per_turn", "direction", "zero_offset", "gear_ratio")
#: Older names of settings, still read.
SETTING_ALIASES = {"zero_offset_ticks": "zero_offset"}
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


def parse_settings(
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


def parse_header(header: Sequence[str], line: int, source: str | None) -> _Columns:
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
            if unit not in SERVO_UNITS:
                raise fail(
                    f"column {name!r}: unit {unit!r} is not allowed; servo positions are in "
                    f"{', '.join(SERVO_UNITS)} (e.g. servo{servo.group(1)}_deg)"
                )
            servo_units[int(servo.group(1))] = unit
        elif euler is not None:
            unit = euler.group(2)
            if unit not in ANGLE_UNITS:
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


def parse_orientation(
    values: Mapping[str, FloatArray], columns: _Columns, lines: IntArray, source: str | None
) -> FloatArray:
    if columns.kind == "axes":
        axes = np.stack([values[c] for c in columns.orientation], axis=1).reshape(-1, 3, 3)
        norm = np.linalg.norm(axes, axis=-1)
        bad = np.argwhere(np.abs(norm - 1.0) > UNIT_TOL)
        if bad.size:
            k, i = int(bad[0, 0]), int(bad[0, 1])
            raise FileFormatError(
                f"columns v{i + 1}_x, v{i + 1}_y, v{i + 1}_z: the measured axis has length "
                f"{norm[k, i]:.6g}; axes must be unit vectors (within {UNIT_TOL})",
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
    bad_q = np.nonzero(np.abs(norm - 1.0) > UNIT_TOL)[0]
    if bad_q.size:
        k = int(bad_q[0])
        raise FileFormatError(
            f"columns qw, qx, qy, qz: the quaternion has norm {norm[k]:.6g}; it must be a unit "
            f"quaternion (within {UNIT_TOL}) - angles belong in roll_deg, pitch_deg, yaw_deg",
            path=source,
            line=int(lines[k]),
        )
    return matrix_from_quaternion(q)
