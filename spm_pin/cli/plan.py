"""``spm plan``: a safe, near-shortest path between input angles or orientations
(:func:`spm_pin.planning.plan`).

Command::

    spm plan [--from T1 T2 T3 | --from-rpy R P Y | --from-quaternion W X Y Z]
             (--to T1 T2 T3 | --to-rpy R P Y | --quaternion W X Y Z)
             [--turns N] [--margin-mm MM] [--min-dexterity D] [--design NAME|FILE] [--json]
             [--out FILE.csv [--rate HZ]] [--html FILE] [--png FILE] [--cells FILE]

Prints the waypoints and their times along the fastest motion under the servos' guard
limits (time-optimal along the path, corners rounded where a spline is certified
safe; toppra, the planning extra), beside the trapezoidal profile that stops at every
waypoint; the length (and the straight line's and the grid search's,
to compare), the smallest link distance at the checked samples, the smallest
dexterity and singularity margin, and the planning time. An unsafe start or goal, or
a goal the start cannot reach within the safe set, exits with status 2 and one line
saying why (and the nearest safe input). ``--cells FILE`` keeps the safe set's
certified cells (:class:`~spm_pin.planning.SafeCover`) between runs.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from .._records import Record
from ..errors import InputError
from ..rotations import matrix_from_quaternion, matrix_from_rpy, rpy_from_matrix
from ._options import UsageError as _UsageError
from ._options import add_design_option as _add_design_option
from ._options import add_json_option as _add_json_option
from ._options import angle_deg as _angle_deg
from ._options import design_of as _design
from ._options import emit as _emit
from ._options import number as _number

__all__ = ["CSV_COLUMNS", "add_parser", "plan_record", "write_csv"]

#: Most samples at which the exact link distances are reported.
DISTANCE_SAMPLES = 60
#: Frames per second of the --html animation.
ANIMATION_FPS = 25.0
#: Columns of the --out file.
CSV_COLUMNS = (
    "t_s",
    *(f"theta{i}_deg" for i in (1, 2, 3)),
    *(f"theta{i}_dot_deg_s" for i in (1, 2, 3)),
    *(f"theta{i}_ddot_deg_s2" for i in (1, 2, 3)),
)


def write_csv(path: str | Path, trajectory: Any, rate: float) -> int:
    """Write a trajectory sampled at ``rate`` [Hz] (the end included) as CSV with
    :data:`CSV_COLUMNS`; returns the number of rows."""
    t = trajectory.times_at_rate(rate)
    theta, speed, acceleration = trajectory.sample(t)
    table = np.column_stack([t, np.degrees(theta), np.degrees(speed), np.degrees(acceleration)])
    np.savetxt(path, table, delimiter=",", header=",".join(CSV_COLUMNS), comments="", fmt="%.10g")
    return int(t.size)


def _animate(path: str, safe: Any, trajectory: Any) -> str:
    """A meshcat page of the motion (the viz extra)."""
    try:  # imported here: meshcat is an optional dependency (the viz extra)
        from ..viz import Visualizer
    except ImportError as exc:
        raise _UsageError(str(exc)) from exc
    viz = Visualizer(safe.robot)
    theta, _, _ = trajectory.sample(trajectory.times_at_rate(ANIMATION_FPS))
    viz.animate(theta, dt=1.0 / ANIMATION_FPS)
    return str(viz.save_html(path))


def _end(args: argparse.Namespace, which: str) -> Any:
    angles = getattr(args, f"{which}_deg")
    rpy = getattr(args, f"{which}_rpy")
    quaternion = getattr(args, f"{which}_quaternion")
    if angles is not None:
        return np.radians(angles)
    if rpy is not None:
        return matrix_from_rpy(np.radians(rpy))
    if quaternion is not None:
        return matrix_from_quaternion(np.asarray(quaternion, dtype=float))
    return np.zeros(3)  # the start defaults to home


def plan_record(args: argparse.Namespace) -> Record:
    """The record ``spm plan`` prints."""
    from ..collision import checker_of
    from ..hardware.config import SafetyLimits
    from ..planning import PlanSettings, plan, safe_set_of

    limits = SafetyLimits()
    settings = PlanSettings(
        margin=args.margin_mm * 1e-3 if args.margin_mm is not None else limits.collision_margin,
        min_dexterity=args.min_dexterity,
        min_singularity_margin=limits.min_singularity_margin,
    )
    design = _design(args)
    cells_read = 0
    if design.is_coaxial:
        safe: Any = safe_set_of(design, settings)
        if args.cells is not None and Path(args.cells).exists():
            safe.cover.load(args.cells)
            cells_read = safe.cover.known_cells
        path = plan(
            _end(args, "from"), _end(args, "to"), settings=settings, turns=args.turns, safe=safe
        )
    else:  # planned in the 3-D input space
        for value, flag in ((args.cells, "--cells"), (args.png, "--png")):
            if value is not None:
                raise _UsageError(
                    f"{flag} is about the gap plane of coaxial designs; {design.name!r} is "
                    "not coaxial"
                )
        path = plan(
            _end(args, "from"), _end(args, "to"), design, settings=settings, turns=args.turns
        )
        safe = path.safe
    try:
        trajectory = path.timed(limits)
    except ImportError as exc:
        raise _UsageError(str(exc)) from exc
    samples = safe.densify(path.theta)
    every = max(1, samples.shape[0] // DISTANCE_SAMPLES)
    checker = checker_of(safe.robot)
    chosen = np.vstack([samples[::every], samples[-1:]])
    q = np.array([safe.robot.configuration(x) for x in chosen])
    clearance = float(np.min(checker.clearances(q, include_fixed=True)))
    from ..kinematics import forward_kinematics

    R_goal = np.asarray(forward_kinematics(path.goal, safe.design).R, dtype=float)
    record: Record = {
        "theta_deg": np.degrees(path.theta),
        "t_s": trajectory.times,
        "duration_s": trajectory.duration,
        "smoothed": trajectory.smoothed,
        "trapezoid_duration_s": trajectory.trapezoid_duration,
        "length_deg": path.length_deg,
        "straight_length_deg": path.straight_length_deg,
        "grid_length_deg": path.grid_length_deg,
        "goal_rpy_deg": np.degrees(rpy_from_matrix(R_goal)),
        "turns": path.turns,
        "min_clearance_m": clearance,
        "min_dexterity": path.min_dexterity,
        "min_singularity_margin": path.min_singularity_margin,
        "samples_checked": path.samples,
        "planning_time_ms": path.planning_time_ms,
        "safe_set_build_s": safe.build_time_s,
        "limits": {
            "max_speed_deg_s": math.degrees(limits.max_speed),
            "max_acceleration_deg_s2": math.degrees(limits.max_acceleration),
            "margin_m": settings.margin,
            "min_dexterity": settings.min_dexterity,
            "min_singularity_margin": settings.min_singularity_margin,
        },
    }
    if args.cells is not None:
        safe.cover.save(args.cells)
        record["cells"] = {
            "file": str(args.cells),
            "read": cells_read,
            "written": safe.cover.known_cells,
        }
    if args.out is not None:
        write_csv(args.out, trajectory, args.rate)
        record["csv"] = str(args.out)
        record["rate_hz"] = args.rate
    if args.html is not None:
        record["html"] = _animate(args.html, safe, trajectory)
    if args.png is not None:
        from ..planning import save_path_figure

        record["png"] = str(save_path_figure(args.png, safe, path))
    return record


def _run_plan(args: argparse.Namespace) -> int:
    if args.turns is not None and args.to_deg is not None:
        raise InputError(
            "--turns applies to an orientation goal (--to-rpy or --quaternion); input "
            "angles given with --to already fix the turn",
            argument="turns",
        )
    args.turns = args.turns or 0
    _emit(plan_record(args), args.json)
    return 0


def _dexterity(text: str) -> float:
    value = _number(text)
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"the dexterity lies in [0, 1], got {text}")
    return value


def _rate(text: str) -> float:
    value = _number(text)
    if not 0.0 < value <= 100000.0:
        raise argparse.ArgumentTypeError(f"the rate lies in (0, 100000] Hz, got {text}")
    return value


def _margin_mm(text: str) -> float:
    value = _number(text)
    if not 0.0 <= value <= 50.0:
        raise argparse.ArgumentTypeError(f"the margin lies in [0, 50] mm, got {text}")
    return value


def add_parser(commands: Any) -> None:
    """``spm plan``."""
    parser = commands.add_parser(
        "plan",
        help="a safe, near-shortest path between input angles or orientations",
        description="Plan a path whose every state, along the whole continuous motion, "
        "assembles in the home mode, keeps the dexterity and singularity margin above "
        "their thresholds and the links at least the margin apart (coaxial designs). "
        "Orientation goals turn the platform the shortest way about the axis, or --turns "
        "whole turns more.",
    )
    start = parser.add_mutually_exclusive_group()
    start.add_argument(
        "--from",
        dest="from_deg",
        nargs=3,
        type=_angle_deg,
        metavar=("T1", "T2", "T3"),
        help="input angles at the start [deg] (default: home, 0 0 0)",
    )
    start.add_argument(
        "--from-rpy",
        dest="from_rpy",
        nargs=3,
        type=_number,
        metavar=("R", "P", "Y"),
        help="orientation at the start: roll, pitch, yaw [deg] (as spm ik --rpy)",
    )
    start.add_argument(
        "--from-quaternion",
        dest="from_quaternion",
        nargs=4,
        type=_number,
        metavar=("W", "X", "Y", "Z"),
        help="orientation at the start: quaternion, scalar first",
    )
    goal = parser.add_mutually_exclusive_group(required=True)
    goal.add_argument(
        "--to",
        dest="to_deg",
        nargs=3,
        type=_angle_deg,
        metavar=("T1", "T2", "T3"),
        help="input angles at the goal [deg]",
    )
    goal.add_argument(
        "--to-rpy",
        dest="to_rpy",
        nargs=3,
        type=_number,
        metavar=("R", "P", "Y"),
        help="orientation at the goal: roll, pitch, yaw [deg] (as spm ik --rpy)",
    )
    goal.add_argument(
        "--quaternion",
        dest="to_quaternion",
        nargs=4,
        type=_number,
        metavar=("W", "X", "Y", "Z"),
        help="orientation at the goal: quaternion, scalar first",
    )
    parser.add_argument(
        "--turns",
        type=int,
        default=None,
        metavar="N",
        help="whole turns about the axis added to the shortest one (orientation goals)",
    )
    parser.add_argument(
        "--margin-mm",
        type=_margin_mm,
        default=None,
        metavar="MM",
        help="clearance margin between links [mm] (default: the servos' guard's, 0.5)",
    )
    parser.add_argument(
        "--min-dexterity",
        type=_dexterity,
        default=0.0,
        metavar="D",
        help="smallest dexterity 1/kappa(J) along the path (default: 0)",
    )
    parser.add_argument(
        "--out",
        metavar="FILE.csv",
        default=None,
        help="write the timed motion sampled at --rate: t_s, theta1_deg..theta3_deg, their "
        "speeds [deg/s] and accelerations [deg/s^2]",
    )
    parser.add_argument(
        "--rate",
        type=_rate,
        default=100.0,
        metavar="HZ",
        help="sampling rate of --out [Hz] (default: 100)",
    )
    parser.add_argument(
        "--html",
        metavar="FILE",
        default=None,
        help="write a meshcat animation of the motion (the viz extra)",
    )
    parser.add_argument(
        "--cells",
        metavar="FILE",
        default=None,
        help="keep the certified cells of the safe set in FILE (.npz): read them when it "
        "exists (same design and settings, else exit 2), write them back grown; later "
        "plans then take a fraction of a millisecond",
    )
    parser.add_argument(
        "--png",
        metavar="FILE",
        default=None,
        help="draw the path on the safe set in the gap plane (PNG; the plot extra)",
    )
    _add_design_option(parser)
    _add_json_option(parser)
    parser.set_defaults(run=_run_plan)
