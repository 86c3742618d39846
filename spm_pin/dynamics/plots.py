"""A picture of a motion's actuator torques against a servo's torque-speed envelope.

:func:`plot_torques` writes a PNG with matplotlib (the ``plot`` extra), imported when
it is called.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from ..errors import InputError
from .closed_loop import InverseDynamicsResult
from .servo import XM540_W150, ServoModel, check_servo
from .simulator import SimulationResult

__all__ = ["plot_torques"]


def plot_torques(
    motion: InverseDynamicsResult | SimulationResult,
    path: str | Path,
    servo: ServoModel = XM540_W150,
    *,
    title: str | None = None,
) -> Path:
    """Write a PNG of the actuator torques against the servo's torque-speed envelope.

    Left: torque against time for each input, with the stall torque. Right: every
    sample in the torque-speed plane with the envelope of :meth:`ServoModel.torque_limits`
    (a sample outside it needs more than the servo can give). Needs matplotlib
    (``pip install 'spm-pin[plot]'``), imported here only; no global pyplot state is used.

    Args:
        motion: An :class:`InverseDynamicsResult` with ``time`` (from a
            :class:`Trajectory`) or a :class:`SimulationResult`.
        path: The PNG file to write.
        servo: The servo whose envelope is drawn.
        title: Figure title (default: a summary of the check).

    Returns:
        The path written.

    Raises:
        InputError: a motion without sample times.
        ImportError: matplotlib is missing.
    """
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
    figure = Figure(figsize=(11.0, 4.5), layout="constrained")
    FigureCanvasAgg(figure)
    left, right = figure.subplots(1, 2)
    colors = ("tab:blue", "tab:orange", "tab:green")
    for joint in range(3):
        left.plot(time, torque[:, joint], color=colors[joint], label=f"u_{joint + 1}")
        right.plot(speed[:, joint], torque[:, joint], ".", ms=2, color=colors[joint])
    stall = servo.stall_torque
    peak = float(np.abs(torque).max(initial=0.0))
    zoom = peak < 0.1 * stall  # the motion uses little of the servo: show the torques
    for sign in (1.0, -1.0):
        left.axhline(sign * stall, color="k", lw=0.8, ls="--", label=None)
    if zoom:
        left.set_ylim(-1.3 * peak - 1e-6, 1.3 * peak + 1e-6)
        left.set_title(f"stall torque +-{stall:g} N m: off scale", fontsize=8)
    left.set_xlabel("time [s]")
    left.set_ylabel("actuator torque [N m]")
    left.legend(loc="best")
    left.grid(True, alpha=0.3)
    reach = max(2.0 * servo.no_load_speed, 1.1 * float(np.abs(speed).max(initial=0.0)))
    omega = np.linspace(-reach, reach, 401)
    lower, upper = servo.torque_limits(omega)
    right.fill_between(omega, lower, upper, color="0.85", label=f"{servo.name} envelope")
    right.plot(omega, upper, "k", lw=0.8)
    right.plot(omega, lower, "k", lw=0.8)
    if zoom:
        right.set_ylim(-2.0 * peak - 1e-6, 2.0 * peak + 1e-6)
    right.set_xlabel("speed [rad/s]")
    right.set_ylabel("actuator torque [N m]")
    right.legend(loc="upper right")
    right.grid(True, alpha=0.3)
    heading = title if title is not None else check.message
    figure.suptitle(textwrap.fill(heading, 110), fontsize=9)
    out = Path(path)
    figure.savefig(out, format="png", dpi=110)
    return out
