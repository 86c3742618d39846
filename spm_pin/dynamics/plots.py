"""A picture of a motion's actuator torques against a servo's torque-speed envelope.

:func:`plot_torques` writes a PNG with matplotlib (the ``plot`` extra), imported when
it is called; :func:`torque_figure` gives its figure.
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ._constants import RPM, FloatArray
from .closed_loop import InverseDynamicsResult
from .servo import XM540_W150, ServoCheck, ServoModel, check_servo
from .simulator import SimulationResult

__all__ = ["plot_torques", "torque_figure"]


def plot_torques(
    motion: InverseDynamicsResult | SimulationResult,
    path: str | Path,
    servo: ServoModel = XM540_W150,
    *,
    title: str | None = None,
) -> Path:
    """Write a PNG of the actuator torques against the servo's torque-speed envelope.

    Left: torque against time for each input, with the stall torque. Right: every
    sample in the torque-speed plane inside the servo's full envelope
    (:meth:`ServoModel.torque_limits`: the current limit +-stall and the voltage lines
    through the stall torque at rest and zero torque at the no-load speed), with
    contours of the load (:meth:`ServoModel.utilisation`) and the sample of the peak
    load marked with what sets it (speed or torque). Speeds are in rpm, as in the
    servo's ratings. Needs matplotlib (``pip install 'spm-pin[plot]'``), imported here
    only; no global pyplot state is used.

    Args:
        motion: An :class:`InverseDynamicsResult` with ``time`` (from a
            :class:`Trajectory`) or a :class:`SimulationResult`.
        path: The PNG file to write.
        servo: The servo whose envelope is drawn.
        title: Figure title (default: the check's verdict).

    Returns:
        The path written.

    Raises:
        InputError: a motion without sample times.
        ImportError: matplotlib is missing.
    """
    figure = torque_figure(motion, servo, title=title)
    out = Path(path)
    figure.savefig(out, format="png", dpi=110)
    return out


def torque_figure(
    motion: InverseDynamicsResult | SimulationResult,
    servo: ServoModel = XM540_W150,
    *,
    title: str | None = None,
) -> Any:
    """The matplotlib ``Figure`` that :func:`plot_torques` writes (for inspection or
    other formats); the same arguments and errors, without the file."""
    if not isinstance(motion, (InverseDynamicsResult, SimulationResult)):
        raise InputError(
            "motion must be an InverseDynamicsResult or a SimulationResult, got "
            f"{type(motion).__name__}",
            argument="motion",
            value=motion,
        )
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:  # pragma: no cover - matplotlib is in the test extra
        raise ImportError("plot_torques needs matplotlib: pip install 'spm-pin[plot]'") from exc
    time = motion.time
    if time is None or np.ndim(motion.torque) != 2:
        raise InputError(
            "plot_torques needs a motion sampled in time (a Trajectory's inverse dynamics "
            "or a simulation)",
            argument="motion",
        )
    torque = np.asarray(motion.torque)
    speed = np.asarray(motion.theta_dot)
    check = check_servo(torque, speed, servo, time=time)
    figure = Figure(figsize=(12.0, 5.0), layout="constrained")
    FigureCanvasAgg(figure)
    left, right = figure.subplots(1, 2, width_ratios=(1.0, 1.15))
    colors = ("tab:blue", "tab:orange", "tab:green")
    stall = servo.stall_torque
    peak = float(np.abs(torque).max(initial=0.0))
    for joint in range(3):
        left.plot(time, torque[:, joint], color=colors[joint], label=f"u_{joint + 1}")
    if peak < 0.1 * stall:  # the motion uses little of the servo: show the torques
        left.set_ylim(-1.3 * peak - 1e-6, 1.3 * peak + 1e-6)
        left.set_title(f"the stall torque +-{stall:g} N m is off this scale", fontsize=9)
    else:
        for sign in (1.0, -1.0):
            left.axhline(sign * stall, color="k", lw=0.8, ls="--")
        left.set_title(f"stall torque +-{stall:g} N m (dashed)", fontsize=9)
    left.set_xlabel("time [s]")
    left.set_ylabel("actuator torque [N m]")
    left.legend(loc="best")
    left.grid(True, alpha=0.3)
    _envelope(right, servo, torque, speed / RPM, check, colors)
    heading = title if title is not None else check.message
    figure.suptitle(textwrap.fill(heading, 120), fontsize=9)
    return figure


def _envelope(
    axis: Any,
    servo: ServoModel,
    torque: FloatArray,
    speed_rpm: FloatArray,
    check: ServoCheck,
    colors: tuple[str, ...],
) -> None:
    """The torque-speed plane: the full envelope, load contours, the samples and the
    sample of the peak load."""
    stall, no_load = servo.stall_torque, servo.no_load_rpm
    reach = max(2.0 * no_load, float(np.abs(speed_rpm).max(initial=0.0))) * 1.1
    # The envelope: upper = min(stall, stall (1 - w/w0)), lower = max(-stall, ...).
    corners = np.array(
        [[-2.0 * no_load, stall], [0.0, stall], [2.0 * no_load, -stall], [0.0, -stall]]
    )
    axis.fill(
        corners[:, 0],
        corners[:, 1],
        facecolor="0.9",
        edgecolor="k",
        lw=1.0,
        label=f"{servo.name} envelope ({servo.voltage:g} V)",
    )
    grid_speed, grid_torque = np.meshgrid(
        np.linspace(-reach, reach, 301), np.linspace(-1.15 * stall, 1.15 * stall, 301)
    )
    load = servo.utilisation(grid_torque, grid_speed * RPM)
    lines = axis.contour(
        grid_speed, grid_torque, load, levels=(0.25, 0.5, 0.75), colors="0.45", linewidths=0.7
    )
    axis.clabel(lines, fmt=lambda x: f"{100.0 * x:.0f}%", fontsize=7)
    for joint in range(3):
        axis.plot(speed_rpm[:, joint], torque[:, joint], "-", lw=2.0, color=colors[joint])
    sample, joint = check.worst_sample, check.worst_joint
    axis.plot(
        speed_rpm[sample, joint],
        torque[sample, joint],
        "*",
        ms=14,
        color="gold",
        mec="k",
        label=f"peak load {100.0 * check.max_utilisation:.1f}% (u_{joint + 1}): "
        f"set by {check.limit}",
    )
    axis.axvline(no_load, color="tab:red", lw=0.8, ls=":")
    axis.axvline(-no_load, color="tab:red", lw=0.8, ls=":", label=f"no-load speed {no_load:g} rpm")
    axis.set_xlim(-reach, reach)
    axis.set_ylim(-1.15 * stall, 1.15 * stall)
    axis.set_xlabel("speed [rpm]")
    axis.set_ylabel("actuator torque [N m]")
    axis.set_title("torque-speed plane: load contours in %, samples as lines", fontsize=9)
    axis.legend(loc="upper right", fontsize=8)
    axis.grid(True, alpha=0.3)
