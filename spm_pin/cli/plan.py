"""``spm plan``: a safe, near-shortest path between input angles or orientations
(:func:`spm_pin.planning.plan`).

Command::

    spm plan [--from T1 T2 T3 | --from-rpy R P Y | --from-quaternion W X Y Z]
             (--to T1 T2 T3 | --to-rpy R P Y | --quaternion W X Y Z)
             [--turns N] [--margin-mm MM] [--min-dexterity D] [--design NAME|FILE] [--json]

Prints the waypoints and their times (a trapezoidal speed profile along the path at
the servos' guard limits), the length (and the straight line's and the grid search's,
to compare), the smallest link distance at the checked samples, the smallest
dexterity and singularity margin, and the planning time. An unsafe start or goal, or
a goal the start cannot reach within the safe set, exits with status 2 and one line
saying why (and the nearest safe input).
"""

from __future__ import annotations

import argparse
import math
from typing import Any

import numpy as np

from .._records import Record
from ..errors import InputError
from ..rotations import matrix_from_quaternion, matrix_from_rpy, rpy_from_matrix
from ._options import add_design_option as _add_design_option
from ._options import add_json_option as _add_json_option
from ._options import angle_deg as _angle_deg
from ._options import design_of as _design
from ._options import emit as _emit
from ._options import number as _number

__all__ = ["add_parser", "path_times", "plan_record"]

#: Most samples at which the exact link distances are reported.
DISTANCE_SAMPLES = 60


def path_times(theta: Any, max_speed: float, max_acceleration: float) -> Any:
    """Times [s] of the waypoints (n, 3) [rad] along a trapezoidal speed profile of the
    path's length (every joint then stays within both limits, from rest to rest)."""
    steps = np.linalg.norm(np.diff(np.asarray(theta, dtype=float), axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(steps)])
    total = float(s[-1])
    v, a = max_speed, max_acceleration
    if total == 0.0:
        return np.zeros_like(s)
    if total >= v * v / a:
        t_acc = v / a
        duration = total / v + t_acc
        s_acc = 0.5 * a * t_acc**2
        t = np.where(
            s <= s_acc,
            np.sqrt(2.0 * s / a),
            np.where(
                s <= total - s_acc,
                t_acc + (s - s_acc) / v,
                duration - np.sqrt(np.maximum(2.0 * (total - s) / a, 0.0)),
            ),
        )
    else:
        t_half = math.sqrt(total / a)
        t = np.where(
            s <= total / 2.0,
            np.sqrt(2.0 * s / a),
            2.0 * t_half - np.sqrt(np.maximum(2.0 * (total - s) / a, 0.0)),
        )
    return t


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
    from ..planning import PlanSettings, plan, safe_set

    limits = SafetyLimits()
    settings = PlanSettings(
        margin=args.margin_mm * 1e-3 if args.margin_mm is not None else limits.collision_margin,
        min_dexterity=args.min_dexterity,
        min_singularity_margin=limits.min_singularity_margin,
    )
    safe = safe_set(_design(args), settings)
    path = plan(
        _end(args, "from"), _end(args, "to"), settings=settings, turns=args.turns, safe=safe
    )
    times = path_times(path.theta, limits.max_speed, limits.max_acceleration)
    samples = safe.densify(path.theta)
    every = max(1, samples.shape[0] // DISTANCE_SAMPLES)
    checker = checker_of(safe.robot)
    chosen = np.vstack([samples[::every], samples[-1:]])
    q = np.array([safe.robot.configuration(x) for x in chosen])
    clearance = float(np.min(checker.clearances(q, include_fixed=True)))
    from ..kinematics import forward_kinematics

    R_goal = np.asarray(forward_kinematics(path.goal, safe.design).R, dtype=float)
    return {
        "theta_deg": np.degrees(path.theta),
        "t_s": times,
        "duration_s": float(times[-1]),
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
    _add_design_option(parser)
    _add_json_option(parser)
    parser.set_defaults(run=_run_plan)
