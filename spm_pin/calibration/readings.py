"""Readings of the prototype (:class:`Readings`: servo angles and measured orientations,
one per pose) and the readings file: :func:`parse_readings`, :func:`load_readings`,
:meth:`Readings.to_csv` (the format is described in :mod:`spm_pin.calibration`)."""

from __future__ import annotations

import csv
import dataclasses
import io
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..design import _read_text
from ..errors import FileFormatError, InputError
from ..kinematics._common import as_rotation
from ..rotations import matrix_from_quaternion, quaternion_from_matrix
from ._constants import (
    COMPONENTS,
    SERVO_UNITS,
    UNIT_TOL,
    FloatArray,
    IntArray,
    format_float,
    parse_number,
)
from ._readings_file import (
    SETTING,
    SETTING_ALIASES,
    SETTINGS,
    parse_header,
    parse_orientation,
    parse_settings,
)
from .convention import JointConvention


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
        if self.kind not in COMPONENTS:
            raise InputError(
                f"kind must be one of {sorted(COMPONENTS)}, got {self.kind!r}",
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
            if np.any(np.abs(norm - 1.0) > UNIT_TOL):
                bad = int(np.argwhere(np.abs(norm - 1.0) > UNIT_TOL)[0, 0])
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
        if self.servo_unit not in SERVO_UNITS:
            raise InputError(
                f"servo_unit must be one of {list(SERVO_UNITS)}, got {self.servo_unit!r}",
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
        if q.ndim != 2 or q.shape[1] != 4 or np.any(~(np.abs(norm - 1.0) <= UNIT_TOL)):
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
        """The readings as CSV text (format in :mod:`spm_pin.calibration`), also written to
        ``path``.

        Args:
            path: File to write, or None.
            unit: Unit of the servo columns: ``"ticks"`` (rounded to whole counts),
                ``"deg"`` or ``"rad"``; default: the unit they were read in.
            comments: Lines of text for the top of the file (no ``key = value`` lines,
                which would read as settings).
        """
        unit = self.servo_unit if unit is None else unit
        if unit not in SERVO_UNITS:
            raise InputError(
                f"unit must be one of {list(SERVO_UNITS)}, got {unit!r}", argument="unit"
            )
        lines = [str(c) for c in comments]
        for line in lines:
            if "\n" in line or SETTING.match("# " + line):
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
        out.write(f"# zero_offset = {', '.join(format_float(z) for z in j.zero_offset_ticks)}\n")
        out.write(f"# gear_ratio = {', '.join(format_float(g) for g in j.gear_ratio)}\n")
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
            servo_text = [[format_float(a) for a in row] for row in angles]
        for k in range(len(self)):
            label = self.labels[k] or str(k + 1)
            row = [label, *servo_text[k], *(format_float(x) for x in values[k])]
            row += [self.extra[name][k] for name in extra]
            writer.writerow(row)
        text = out.getvalue()
        if path is not None:
            Path(path).write_text(text, encoding="utf-8")
        return text


def parse_readings(
    text: str, *, source: str | None = None, joints: JointConvention | None = None
) -> Readings:
    """Parse readings CSV text (format in :mod:`spm_pin.calibration`).

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
            match = SETTING.match(line)
            if match is None:
                continue
            if header is not None:
                raise FileFormatError(
                    f"setting {match.group(1)!r} after the header row (line {header_line}); "
                    "settings go before the header",
                    path=source,
                    line=number,
                )
            key = SETTING_ALIASES.get(match.group(1), match.group(1))
            if key not in SETTINGS:
                raise FileFormatError(
                    f"unknown setting {key!r}; allowed: {list(SETTINGS)}", path=source, line=number
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
    convention = parse_settings(settings, setting_lines, source, joints)
    columns = parse_header(header, header_line, source)
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
            values[name][k] = parse_number(field, name, number, source)
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
    orientation = parse_orientation(values, columns, lines, source)
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
