"""``spm torques``: the actuator torques of a motion (closed-loop inverse dynamics,
:mod:`spm_pin.dynamics`, imported when the command runs) against the servos'
torque-speed envelope."""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

import numpy as np

from .._records import Record
from .._records import worst_sample as _worst_sample
from ._options import EXIT_OVER_LIMITS
from ._options import UsageError as _UsageError
from ._options import add_design_option as _add_design_option
from ._options import add_json_option as _add_json_option
from ._options import add_motion_options as _add_motion_options
from ._options import design_of as _design
from ._options import emit as _emit
from ._options import number as _number

__all__ = ["add_parser"]


def _run_torques(args: argparse.Namespace) -> int:
    # Imported here: Pinocchio (and matplotlib for --plot) only for this command.
    from ..dynamics import (
        XM540_W150,
        ClosedLoopDynamics,
        Trajectory,
        check_servo,
        inverse_dynamics,
        plot_torques,
    )
    from ..model.robot import build_robot

    design = _design(args)
    if args.file is not None:
        if args.to_deg is not None:
            raise _UsageError("give either --to or --file, not both")
        motion = Trajectory.load(args.file)
        source: Record = {"file": str(args.file)}
    else:
        if args.to_deg is None:
            raise _UsageError("a target is required: --to T1 T2 T3 (or --file CSV)")
        if not args.duration > 0:
            raise _UsageError(f"--duration must be positive [s], got {args.duration:g}")
        if not args.rate > 0:
            raise _UsageError(f"--rate must be positive [Hz], got {args.rate:g}")
        motion = Trajectory.minimum_jerk(
            np.radians(args.from_deg), np.radians(args.to_deg), args.duration, args.rate
        )
        source = {"minimum_jerk_from_deg": args.from_deg, "minimum_jerk_to_deg": args.to_deg}
    dynamics = ClosedLoopDynamics(build_robot(design), gravity=args.gravity)
    result = inverse_dynamics(dynamics, motion)
    servo = XM540_W150
    check = check_servo(result.torque, result.theta_dot, servo, time=motion.time)
    record: Record = {
        "design": design.name,
        "servo": {
            "name": servo.name,
            "stall_torque_nm": servo.stall_torque,
            "no_load_speed_rpm": servo.no_load_rpm,
            "voltage_v": servo.voltage,
        },
        "trajectory": {
            **source,
            "duration_s": motion.duration,
            "samples": int(motion.time.shape[0]),
        },
        "gravity_m_s2": list(args.gravity),
        "peak_torque_nm": check.peak_torque,
        "rms_torque_nm": check.rms_torque,
        "peak_speed_rpm": check.peak_speed * 60.0 / (2.0 * math.pi),
        "peak_power_w": np.abs(result.power).max(axis=0),
        "max_utilisation": check.max_utilisation,
        "within_limits": check.within_limits,
        "worst": _worst_sample(result, motion, check),
        "verdict": check.message,
        "plot": None,
    }
    if args.plot is not None:
        try:
            record["plot"] = str(plot_torques(result, args.plot, servo))
        except ImportError as exc:
            raise _UsageError(f"--plot needs matplotlib: {exc}") from exc
    _emit(record, args.json)
    if not check.within_limits:  # the servos cannot do it: a failure for scripts
        print(f"spm: warning: {check.message}", file=sys.stderr)
        return EXIT_OVER_LIMITS
    return 0


def add_parser(commands: Any) -> None:
    """``spm torques``."""
    torques = commands.add_parser(
        "torques",
        help="actuator torques of a motion against the servos' torque-speed limits",
        description="Closed-loop inverse dynamics of a motion: the torques the three "
        "XM540-W150 servos must give, their peak and RMS values, and a verdict against "
        "the servo's torque-speed envelope (7.3 N m stall, 53 rpm no-load at 12 V). The "
        "motion is a minimum-jerk move from --from (default home) to --to in --duration "
        "seconds, or a CSV file (time_s,theta_1_deg,theta_2_deg,theta_3_deg). Exit status 1 "
        "when the motion exceeds the servos' torque-speed envelope (the report is printed "
        "all the same).",
    )
    _add_motion_options(torques, to_required=False)
    torques.add_argument(
        "--file",
        metavar="CSV",
        help="the motion as CSV: time_s,theta_1_deg,theta_2_deg,theta_3_deg (or _rad)",
    )
    torques.add_argument(
        "--duration", type=_number, default=1.0, metavar="S", help="move time [s] (default 1)"
    )
    torques.add_argument(
        "--rate",
        type=_number,
        default=1000.0,
        metavar="HZ",
        help="samples per second of the move (default 1000)",
    )
    torques.add_argument(
        "--gravity",
        nargs=3,
        type=_number,
        default=[0.0, 0.0, -9.81],
        metavar=("GX", "GY", "GZ"),
        help="gravity in the base frame [m/s^2] (default: 0 0 -9.81, upright)",
    )
    torques.add_argument("--plot", metavar="FILE", help="write a PNG of the torques")
    _add_json_option(torques)
    _add_design_option(torques)
    torques.set_defaults(run=_run_torques)
