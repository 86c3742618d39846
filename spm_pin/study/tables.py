"""The study's numbers as HTML tables, one view per section (:func:`section_tables`):
the forward kinematics three ways with their cross-checks, every assembly mode, the
Jacobian, the motion's samples, the colliding pairs, the workspace summary and the
actuator torques with the servo's verdict (stated once)."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._records import Record
from .._records import plain as _plain
from .context import FK_METHODS as _FK_METHODS
from .context import SHOWN_SAMPLES as _SHOWN_SAMPLES
from .context import STUDY_AGREEMENT, DemoSection
from .context import methods as _methods
from .context import sci as _sci
from .context import verdict as _verdict

__all__ = ["MODE_LABEL_NOTE", "record_table", "section_tables"]

#: What an assembly-mode label means (shown under the table of modes).
MODE_LABEL_NOTE = (
    "A label gives the signs of b<sub>11</sub>, b<sub>22</sub>, b<sub>33</sub> and, after "
    "the slash, of det A; a second mode with the same signs carries #2."
)
#: Record keys that name report files (shown as figures and scenes, not in tables).
_FILE_KEYS = frozenset({"plot", "plots", "scene", "files"})
_RPM = 60.0 / (2.0 * math.pi)


def _e(text: Any) -> str:
    return html.escape(str(text))


def _number(key: str, value: float) -> str:
    """A number for a table cell: scientific for small errors, else 6 decimals."""
    if value is None or not math.isfinite(value):
        return "n/a"
    if any(word in key for word in ("residual", "error", "deviation", "opening")):
        return f"{value:.1e}"
    if float(value).is_integer() and abs(value) < 1e9:
        return f"{value:.0f}"
    return f"{round(value, 6) + 0.0:.6f}".rstrip("0").rstrip(".")


def _cell(key: str, value: Any) -> str:
    """A value of a plain record as the text of one cell (HTML)."""
    if value is None:
        return "n/a"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return _number(key, value)
    if isinstance(value, (list, tuple)):
        if not value:
            return "none"
        if all(isinstance(v, (list, tuple)) for v in value):
            return "<br>".join(_cell(key, row) for row in value)
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            return ", ".join(_number(key, float(v)) for v in value)
        return ", ".join(_e(v) for v in value)
    return _e(value)


def _label(key: str) -> str:
    """A record key as a row heading: ``peak_torque_nm`` -> ``peak torque [N m]``."""
    units = {
        "_deg": " [deg]",
        "_kg": " [kg]",
        "_m_s2": " [m/s²]",
        "_nm": " [N m]",
        "_rpm": " [rpm]",
        "_rad": " [rad]",
        "_m": " [m]",
        "_s": " [s]",
    }
    for suffix, unit in units.items():
        if key.endswith(suffix):
            return key.removesuffix(suffix).replace("_", " ") + unit
    return key.replace("_", " ")


def record_table(record: Record, skip: Sequence[str] = ()) -> str:
    """A plain record as a two-column table (nested records as ``outer: inner`` rows).

    Keys whose value is None, the keys in ``skip`` and those naming report files are
    left out; lists of records are not shown (their sections give them a table).
    """
    rows: list[str] = []

    def add(prefix: str, data: Record) -> None:
        for key, value in data.items():
            if key in skip or key in _FILE_KEYS or value is None:
                continue
            name = f"{prefix}{_label(key)}"
            if isinstance(value, dict):
                add(f"{name}: ", value)
            elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
                continue
            else:
                rows.append(f'<tr><th scope="row">{_e(name)}</th><td>{_cell(key, value)}</td></tr>')

    add("", record)
    return '<table class="record">' + "".join(rows) + "</table>" if rows else ""


def _vector_cells(v: Any, decimals: int = 6) -> str:
    cells = np.asarray(v, dtype=float).ravel()
    return "".join(f"<td>{round(float(x), decimals) + 0.0:.{decimals}f}</td>" for x in cells)


def _wide(table: str) -> str:
    """A table that scrolls sideways on a narrow page instead of widening it."""
    return f'<div class="wide">{table}</div>'


def _axes_head(first: Sequence[str], last: Sequence[str] = ()) -> str:
    """Two heading rows: ``first`` columns, v_1, v_2, v_3 with x, y, z under each, then
    ``last`` columns (headings are HTML)."""
    top = "".join(f'<th rowspan="2">{name}</th>' for name in first)
    top += "".join(f'<th colspan="3">v<sub>{i}</sub></th>' for i in (1, 2, 3))
    top += "".join(f'<th rowspan="2">{name}</th>' for name in last)
    return f"<tr>{top}</tr><tr>" + "<th>x</th><th>y</th><th>z</th>" * 3 + "</tr>"


#: The heading of a deviation column.
_DEVIATION = "max |v - v<sub>{}</sub>|"


def _deviation_text(key: str, value: float) -> str:
    return "(reference)" if key == "analytic" else f"{value:.1e}"


# ------------------------------------------------------------------ the sections
def _forward_kinematics(data: Record) -> str:
    """The platform axes by every method (rows) and the cross-checks."""
    methods = _methods(data)
    rows = [
        f"<tr><th scope='row'>{_e(_FK_METHODS[key])}</th>{_vector_cells(method['v'])}"
        f"<td>{_deviation_text(key, method['deviation_from_analytic'])}</td></tr>"
        for key, method in methods.items()
    ]
    axes = _wide(
        '<table class="fk">'
        + _axes_head(["method"], [_DEVIATION.format("analytic")])
        + "".join(rows)
        + "</table>"
    )
    checks, tolerance = data["within_tolerance"], data["tolerance"]
    projection = methods["projection"]
    notes = {}
    notes["projection"] = (
        f"{projection['iterations']} Newton steps from home, closure residual "
        f"{projection['residual']:.1e}"
    )
    if "mujoco" in methods:
        notes["mujoco"] = (
            "soft welds (spring-dampers) carry the platform's weight: they open by "
            f"{methods['mujoco']['weld_opening_rad']:.1e} rad"
        )
    if "mujoco_no_gravity" in methods:
        notes["mujoco_no_gravity"] = (
            "without load the welds close: they open by "
            f"{methods['mujoco_no_gravity']['weld_opening_rad']:.1e} rad"
        )
    check_rows = [
        f"<tr><th scope='row'>{_e(_FK_METHODS[key])}</th>"
        f"<td>{methods[key]['deviation_from_analytic']:.1e}</td>"
        f"<td>{_e(_verdict(checks[key], tolerance[key]))}</td><td class='note'>{_e(note)}</td></tr>"
        for key, note in notes.items()
        if key in methods
    ]
    check_rows.append(
        "<tr><th scope='row'>the study (its model against CoppeliaSim)</th>"
        f"<td>about {_sci(STUDY_AGREEMENT)}</td><td></td><td></td></tr>"
    )
    cross = (
        '<table class="checks"><tr><th>against the analytic axes</th>'
        "<th>max |v - v<sub>analytic</sub>|</th><th>verdict</th><th>note</th></tr>"
        + "".join(check_rows)
        + "</table>"
    )
    rpy = ", ".join(f"{float(x):.6f}" for x in data["rpy_deg"])
    pose = record_table({"assembly mode (home)": data["mode"], "roll, pitch, yaw [deg]": rpy})
    return axes + cross + pose


def _assembly_modes(data: Record) -> str:
    rows = [
        f"<tr><th scope='row'>{_e(mode['label'])}</th><td>{'yes' if mode['home'] else ''}</td>"
        f"{_vector_cells(mode['v'], 4)}<td>{float(mode['residual']):.1e}</td></tr>"
        for mode in data["modes"]
    ]
    head = _axes_head(["mode", "home"], ["residual"])
    return (
        f"<p>{data['count']} real assembly modes, one row each.</p>"
        + _wide(f'<table class="modes">{head}{"".join(rows)}</table>')
        + f'<p class="note">{MODE_LABEL_NOTE}</p>'
    )


def _velocity(data: Record) -> str:
    J = np.asarray(data["J"], dtype=float)
    rows = "".join(
        f"<tr><th scope='row'>omega<sub>{'xyz'[r]}</sub></th>"
        + "".join(f"<td>{x:.6f}</td>" for x in J[r])
        + "</tr>"
        for r in range(3)
    )
    head = "".join(f"<th>theta_dot<sub>{i}</sub></th>" for i in (1, 2, 3))
    matrix = f'<table class="jacobian"><tr><th>J</th>{head}</tr>{rows}</table>'
    return matrix + record_table(data, skip=("J",))


def _motion(data: Record) -> str:
    path = data.get("path") or []
    shown = [k for k in _SHOWN_SAMPLES if k < len(path)]
    has_mujoco = any(sample.get("deviation_mujoco") is not None for sample in path)
    last = ["projection", "MuJoCo"] if has_mujoco else ["projection"]
    head = _axes_head(["sample", "theta [deg]"], [f"{m}<br>deviation" for m in last])
    rows = []
    for k in shown:
        sample = path[k]
        theta = ", ".join(f"{float(x):g}" for x in np.round(sample["theta_deg"], 6))
        mujoco = f"<td>{sample['deviation_mujoco']:.1e}</td>" if has_mujoco else ""
        rows.append(
            f"<tr><th scope='row'>{k}</th><td>{theta}</td>{_vector_cells(sample['v'], 4)}"
            f"<td>{sample['deviation_projection']:.1e}</td>{mujoco}</tr>"
        )
    samples = (
        f"<p>The analytic platform axes at {len(shown)} of the {len(path)} samples (every "
        "sample is in the figure below and in the JSON record), and the largest deviation "
        "max |v<sub>method</sub> - v| of the other methods:</p>"
        + _wide(f'<table class="samples">{head}{"".join(rows)}</table>')
        if rows
        else ""
    )
    return record_table(data, skip=("path",)) + samples


def _colliding_input(data: Record) -> str:
    pairs = data.get("pairs") or []
    rows = "".join(f"<tr><td>{_e(first)}</td><td>{_e(second)}</td></tr>" for first, second in pairs)
    table = (
        f'<table class="pairs"><tr><th colspan="2">colliding link pairs ({len(pairs)})</th></tr>'
        f"{rows}</table>"
        if pairs
        else "<p>No link pair collides.</p>"
    )
    return record_table(data, skip=("pairs",)) + table


def _torques(data: Record) -> str:
    """The verdict (once), the limiting factor, per-joint figures, the worst sample."""
    verdict = f'<p class="verdict"><strong>{_e(data["verdict"])}</strong></p>'
    worst, servo = data["worst"], data["servo"]
    speed_share = abs(worst["speed_rpm"]) / servo["no_load_speed_rpm"]
    torque_share = abs(worst["torque_nm"]) / servo["stall_torque_nm"]
    limit = data.get("limiting_factor")
    if limit is not None:
        other = "torque" if limit == "speed" else "speed"
        verdict += (
            f"<p>The peak load is set by {limit}, not {other}: at that sample joint "
            f"{_e(worst['joint'])} turns at {100.0 * speed_share:.1f}% of the no-load speed "
            f"({servo['no_load_speed_rpm']:g} rpm) and needs {100.0 * torque_share:.1f}% of "
            f"the stall torque ({servo['stall_torque_nm']:g} N m).</p>"
        )
    peak = np.asarray(data["peak_torque_nm"], dtype=float)
    rms = np.asarray(data["rms_torque_nm"], dtype=float)
    speed = np.asarray(data["peak_speed_rpm"], dtype=float)
    joints = "".join(f"<th>u<sub>{i}</sub></th>" for i in (1, 2, 3))
    rows = [
        ("peak |torque| [N m]", [f"{x:.4f}" for x in peak]),
        ("RMS torque [N m]", [f"{x:.4f}" for x in rms]),
        ("peak |speed| [rpm]", [f"{x:.2f}" for x in speed]),
        ("peak |speed| [rad/s]", [f"{x / _RPM:.3f}" for x in speed]),
    ]
    body = "".join(
        f"<tr><th scope='row'>{name}</th>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>"
        for name, cells in rows
    )
    per_joint = f'<table class="joints"><tr><th></th>{joints}</tr>{body}</table>'
    return (
        verdict
        + per_joint
        + record_table(
            data,
            skip=(
                "verdict",
                "limiting_factor",
                "peak_torque_nm",
                "rms_torque_nm",
                "peak_speed_rpm",
            ),
        )
    )


def section_tables(section: DemoSection) -> str:
    """The HTML tables of one section (any section: unknown ones as a record table)."""
    data = _plain(section.data)
    if section.key == "forward_kinematics":
        return _forward_kinematics(data)
    if section.key == "assembly_modes":
        return _assembly_modes(data)
    if section.key == "velocity":
        return _velocity(data)
    if section.key == "motion":
        return _motion(data)
    if section.key == "colliding_input":
        return _colliding_input(data)
    if section.key == "torques":
        return _torques(data)
    if section.key == "workspace":
        return record_table(data, skip=("colliding_points_by_pair", "margin_m"))
    return record_table(_plain(section.text) if section.text is not None else data)
