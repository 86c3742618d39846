"""``spm show`` and ``spm animate``: the robot in meshcat, in a live viewer or a
self-contained HTML file (the viz extra, imported when a command runs)."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._records import Record
from .._records import dumps as _dumps
from .._records import plain as _plain
from .._records import render as _render
from ..design import SPMDesign
from ..errors import UnreachableError
from ..kinematics import forward_kinematics_all
from ._options import UsageError as _UsageError
from ._options import add_angle_arguments as _add_angle_arguments
from ._options import add_design_option as _add_design_option
from ._options import add_json_option as _add_json_option
from ._options import add_motion_options as _add_motion_options
from ._options import design_of as _design
from ._options import emit as _emit
from ._options import number as _number

__all__ = ["add_parsers"]


def _visualizer(args: argparse.Namespace) -> Any:
    """A :class:`~spm_pin.viz.Visualizer` of the chosen design with the chosen overlays."""
    try:  # imported here: meshcat is an optional dependency (the viz extra)
        from ..collision import build_robot
        from ..viz import Visualizer
    except ImportError as exc:
        raise _UsageError(str(exc)) from exc
    robot = build_robot(_design(args))
    return Visualizer(robot, joint_axes=args.axes, platform_frame=args.frame, view=args.view)


#: The camera's preset views (spm_pin.viz.views.VIEWS, named here so that building the
#: parser does not import meshcat).
_VIEWS = ("iso", "top", "front", "side")


def _add_view_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--axes", action="store_true", help="draw the joint axes u_i, w_i, v_i")
    parser.add_argument("--frame", action="store_true", help="draw the platform frame")
    parser.add_argument(
        "--view",
        choices=_VIEWS,
        default=_VIEWS[0],
        help="camera view, framed on the robot: iso (default: the three legs and the "
        "platform's face), top, front or side; the saved page has a button for each",
    )


def _serve_until_interrupted(viz: Any, record: Record, as_json: bool) -> None:
    """Run a live viewer until Ctrl-C or SIGTERM; the server is always stopped."""
    import signal
    import threading

    def interrupt(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        with viz:
            record["url"] = viz.url
            if as_json:
                print(_dumps(record), flush=True)
            else:
                print("\n".join(_render(_plain(record))))
                print("serving the viewer; open the url in a browser, Ctrl-C to stop", flush=True)
            with contextlib.suppress(KeyboardInterrupt):
                threading.Event().wait()
    finally:
        signal.signal(signal.SIGTERM, previous)


def _assembly_mode(theta_deg: Sequence[float], mode: str, design: SPMDesign) -> str:
    """--mode of show: 'nearest', 'home', a label, or an index of 'spm fk --all'."""
    if not mode.isdigit():
        return mode
    every = forward_kinematics_all(np.radians(np.asarray(theta_deg, dtype=float)), design)
    count = int(every.count)
    if int(mode) >= count:
        raise _UsageError(
            f"--mode {mode}: theta = {list(theta_deg)} deg has {count} assembly mode(s), "
            f"indices 0..{count - 1} of 'spm fk T1 T2 T3 --all'"
            if count
            else f"--mode {mode}: theta = {list(theta_deg)} deg has no real assembly mode"
        )
    return str(every.labels[int(mode)])


def _display(viz: Any, theta_deg: Sequence[float], mode: str, clearance: bool = False) -> Any:
    """viz.display at theta [deg] in --mode, with command-line hints on failure."""
    try:
        return viz.display(np.radians(theta_deg), mode=mode, clearance=clearance)
    except UnreachableError as exc:
        raise _UsageError(
            f"theta = {list(theta_deg)} deg has no assembly in mode {mode!r}; 'spm fk "
            f"{' '.join(f'{t:g}' for t in theta_deg)} --all' lists the modes that exist, and "
            "--mode nearest (the default) shows the one nearest to home"
        ) from exc


def _run_show(args: argparse.Namespace) -> int:
    viz = _visualizer(args)
    theta_deg = [args.T1, args.T2, args.T3]
    mode = _assembly_mode(theta_deg, args.mode, viz.robot.design)
    pairs = _display(viz, theta_deg, mode, args.clearance)
    viz.set_view(args.view)  # framed on the pose shown
    record: Record = {
        "design": viz.robot.design.name,
        "theta_deg": theta_deg,
        "mode": viz.mode,
        "home": viz.home,
        "colliding": [list(pair) for pair in pairs],
        "depth_mm": {c.name: round(1000.0 * c.depth, 4) for c in viz.contacts},
    }
    if viz.clearance is not None:
        record["clearance"] = {
            "pair": list(viz.clearance.pair),
            "mm": round(1000.0 * viz.clearance.distance, 4),
        }
    if args.html is None:
        _serve_until_interrupted(viz, record, args.json)
        return 0
    record["html"] = str(viz.save_html(args.html))
    _emit(record, args.json)
    return 0


def _run_animate(args: argparse.Namespace) -> int:
    if args.samples < 2:
        raise _UsageError(f"--samples must be at least 2, got {args.samples}")
    if not args.duration > 0:
        raise _UsageError(f"--duration must be positive [s], got {args.duration:g}")
    viz = _visualizer(args)
    start = np.radians(args.from_deg)
    end = np.radians(args.to_deg)
    path = start + np.linspace(0.0, 1.0, args.samples)[:, None] * (end - start)
    motion = viz.animate(path, dt=args.duration / (args.samples - 1))
    viz.set_view(args.view)  # framed on the motion
    record: Record = {
        "design": viz.robot.design.name,
        "from_deg": args.from_deg,
        "to_deg": args.to_deg,
        "samples": args.samples,
        "duration_s": args.duration,
        "modes": list(dict.fromkeys(motion.modes)),
        "colliding_samples": motion.colliding_samples,
        "html": str(viz.save_html(args.html)),
    }
    _emit(record, args.json)
    return 0


def add_parsers(commands: Any) -> None:
    """``spm show`` and ``spm animate``."""
    show = commands.add_parser(
        "show",
        help="show the robot at input angles (live viewer or HTML file)",
        description="Show the robot at input angles T1 T2 T3 [deg] with meshcat, colliding "
        "links in black with red markers where they touch (depths listed on a saved page): "
        "in a live viewer (open the printed url; Ctrl-C stops it) or, with "
        "--html, in a self-contained HTML file. Needs the viz extra.",
    )
    _add_angle_arguments(show)
    show.add_argument("--html", metavar="FILE", help="write the scene to FILE instead of serving")
    show.add_argument(
        "--mode",
        default="nearest",
        metavar="LABEL|INDEX",
        help="assembly mode: nearest (default: the home mode where it exists, else the real "
        "mode nearest to it, named in the output), home, or a label or index of "
        "'spm fk T1 T2 T3 --all' such as +-+/+, -+-/-#2 or 3",
    )
    show.add_argument(
        "--clearance",
        action="store_true",
        help="also mark the nearest non-colliding link pair's closest points and clearance",
    )
    _add_view_options(show)
    _add_json_option(show)
    _add_design_option(show)
    show.set_defaults(run=_run_show)

    from ..study import DEMO_SAMPLES  # here: the study loads only when the parser is built

    animate = commands.add_parser(
        "animate",
        help="write an animation of a motion between input angles to an HTML file",
        description="Animate the straight motion in input space from --from (default home) "
        "to --to [deg], followed continuously from the home assembly mode (where it does not "
        "exist at --from, from the real mode nearest to it; 'modes' names the modes shown), "
        "colliding links in black, into a self-contained HTML file. Needs the viz extra.",
    )
    _add_motion_options(animate, to_required=True)
    animate.add_argument(
        "--samples",
        type=int,
        default=DEMO_SAMPLES,
        metavar="N",
        help=f"samples of the motion, ends included (default: {DEMO_SAMPLES})",
    )
    animate.add_argument(
        "--duration",
        type=_number,
        default=2.0,
        metavar="S",
        help="duration of the animation [s] (default: 2)",
    )
    animate.add_argument("--html", metavar="FILE", required=True, help="the HTML file to write")
    _add_view_options(animate)
    _add_json_option(animate)
    _add_design_option(animate)
    animate.set_defaults(run=_run_animate)
