"""Plain-data records of results and their text form, shared by the study and the
command line: numpy data to JSON-ready values, aligned ``key  value`` text, and the
records both print (orientations, assembly modes, worst servo sample, checked links).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from .design import SPMDesign
from .kinematics import forward_kinematics_all
from .kinematics._common import mode_label
from .rotations import quaternion_from_matrix, rpy_from_matrix

__all__ = [
    "FloatArray",
    "Record",
    "assembly_label",
    "checked_links",
    "dumps",
    "fk_all_record",
    "orientation",
    "plain",
    "render",
    "worst_sample",
]

FloatArray = npt.NDArray[np.float64]
Record = dict[str, Any]


# ----------------------------------------------------------------------- JSON/text
def plain(value: Any) -> Any:
    """Lists, floats, ints, bools, strings and None (for NaN/inf) from numpy data."""
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        number = float(value) + 0.0  # + 0.0 turns -0.0 into 0.0
        return number if math.isfinite(number) else None
    return value


def dumps(record: Record) -> str:
    return json.dumps(plain(record), indent=2, allow_nan=False)


NUMBER_WIDTH = 12


def format_number(key: str, value: float) -> str:
    if any(word in key for word in ("residual", "error", "deviation")):
        return f"{value:{NUMBER_WIDTH}.3e}"
    return f"{round(value, 6) + 0.0:{NUMBER_WIDTH}.6f}"


def format_scalar(key: str, value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return format_number(key, value)
    return str(value)


def is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def render(record: Record, indent: str = "") -> list[str]:
    """Text lines for a plain record: ``key  value``, numbers aligned with 6 decimals.

    Keys whose value is None (``null`` in JSON) are left out.
    """
    record = {key: value for key, value in record.items() if value is not None}
    width = max((len(key) for key in record), default=0) + 2
    lines: list[str] = []
    for key, value in record.items():
        head = f"{indent}{key:<{width}}"
        if isinstance(value, dict):
            lines.append(f"{indent}{key}:")
            lines.extend(render(value, indent + "  "))
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            # Numbered from 0, as the JSON list and the --mode INDEX options count.
            for number, item in enumerate(value):
                lines.append(f"{indent}{key}[{number}]:")
                lines.extend(render(item, indent + "  "))
        elif isinstance(value, list) and value and all(isinstance(v, list) for v in value):
            for number, row in enumerate(value):
                prefix = head if number == 0 else " " * len(head)
                lines.append(prefix + render_row(key, row))
        elif isinstance(value, list):
            lines.append(head + (render_row(key, value) if value else "none"))
        else:
            lines.append(head + format_scalar(key, value))
    return lines


def render_row(key: str, row: list[Any]) -> str:
    if all(is_number(v) for v in row):
        return "".join(format_number(key, float(v)) for v in row)
    return "  ".join("null" if v is None else format_scalar(key, v) for v in row)


# ---------------------------------------------------------------- orientation data
def orientation(R: FloatArray) -> Record:
    """R, roll/pitch/yaw [deg] and the quaternion (w, x, y, z) of a rotation."""
    return {
        "R": R,
        "rpy_deg": np.degrees(rpy_from_matrix(R)),
        "quaternion_wxyz": quaternion_from_matrix(R),
    }


def assembly_label(b: FloatArray, det_a: float) -> str:
    """Assembly-mode label such as ``+++/-``: signs of b_11, b_22, b_33 and det A."""
    return mode_label(b) + ("/+" if det_a > 0 else "/-")


def fk_all_record(theta_deg: Sequence[float], design: SPMDesign) -> Record:
    """Every real assembly mode of one input [deg], as a record."""
    modes = forward_kinematics_all(np.radians(np.asarray(theta_deg, dtype=float)), design)
    count = int(modes.count)
    labels = modes.labels
    return {
        "design": design.name,
        "theta_deg": list(theta_deg),
        "reachable": bool(np.any(modes.home)),
        "count": count,
        "modes": [
            {
                "index": k,
                "label": labels[k],
                "home": modes.home[k],
                "R": modes.R[k],
                "v": modes.v[k],
                "b": modes.b[k],
                "det_a": modes.det_a[k],
                "residual": modes.residual[k],
            }
            for k in range(count)
        ],
    }


def worst_sample(result: Any, motion: Any, check: Any) -> Record:
    """The sample and joint nearest to the servo's limits (a ``check_servo`` result)."""
    t, j = check.worst_sample, check.worst_joint
    return {
        "joint": f"u_{j + 1}",
        "time_s": float(motion.time[t]),
        "torque_nm": float(result.torque[t, j]),
        "speed_rpm": float(result.theta_dot[t, j]) * 60.0 / (2.0 * math.pi),
    }


def checked_links(report: Any) -> str:
    """Which links a :func:`~spm_pin.collision.check_input` report checked, in words."""
    if report.mode is None:
        return "proximal links only (no real assembly mode: the other links have no pose)"
    if report.home:
        return "every link pair (home assembly mode)"
    return f"every link pair (assembly mode {report.mode}; the home mode does not exist)"
