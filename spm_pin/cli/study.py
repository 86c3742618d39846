"""``spm demo``: the published study of the prototype (:mod:`spm_pin.study`), run
from the shell, its report written to a folder and its record printed."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from .._records import Record
from .._records import dumps as _dumps
from ._options import add_json_option as _add_json_option
from ._options import number as _number

__all__ = ["add_parser"]


def _run_demo(args: argparse.Namespace) -> int:
    # Imported here: the study gathers every layer (Pinocchio, MuJoCo, meshcat, plots).
    from ..study import DemoContext, run_demo

    changes: Record = {"out": Path(args.out)}
    if args.workspace_step is not None:
        changes["workspace_step_deg"] = args.workspace_step
    if args.no_pictures:
        changes["pictures"] = False
    if args.chromium is not None:
        changes["chromium"] = args.chromium
    ctx = DemoContext.quick(**changes) if args.quick else DemoContext(**changes)
    result = run_demo(ctx, progress="off" if args.quiet else "auto")
    print(_dumps(result.record) if args.json else "\n".join(result.lines))
    if result.failed_checks:  # the solvers disagree: exit status 1, like a failed test
        failed = ", ".join(result.failed_checks)
        print(f"spm: warning: cross-checks outside their tolerance: {failed}", file=sys.stderr)
        return 1
    return 0


def add_parser(commands: Any) -> None:
    """``spm demo``."""
    demo = commands.add_parser(
        "demo",
        help="the published study of the prototype, reproduced, with an HTML report",
        description="The published study of the prototype, reproduced and extended: forward "
        "kinematics at theta = [60, 90, 120] deg analytically, by Newton projection and by "
        "MuJoCo; the motion from home at 25 samples; the colliding input [60, 90, 220] deg; "
        "the safe workspace; the actuator torques. Writes DIR/index.html (plots and "
        "meshcat scenes, works offline) and DIR/demo.json. With Playwright and a Chromium "
        '(pip install "spm-pin[browser]"; Debian: apt install chromium) a PNG picture of '
        "each scene goes beside it and into the report. Progress goes to stderr. "
        "Without mujoco, matplotlib or meshcat the parts that need them are skipped "
        '(pip install "spm-pin[demo]" brings them). Exit status 1 when the three ways '
        "of solving the loops disagree beyond their tolerances.",
    )
    demo.add_argument(
        "--out", metavar="DIR", default="spm-demo", help="report folder (default: ./spm-demo)"
    )
    demo.add_argument(
        "--quick",
        action="store_true",
        help="a coarser, faster run (10 deg workspace grid, 100 torque samples per second)",
    )
    demo.add_argument(
        "--workspace-step",
        type=_number,
        metavar="DEG",
        help="grid step of the workspace map [deg] (default 2; 10 with --quick)",
    )
    demo.add_argument(
        "--no-pictures",
        action="store_true",
        help="no PNG picture of each 3-D scene (they are rendered in a headless Chromium "
        "through Playwright when both are there)",
    )
    demo.add_argument(
        "--chromium",
        metavar="PATH",
        help="the Chromium that renders the pictures (default: chromium on the PATH)",
    )
    demo.add_argument("--quiet", action="store_true", help="no progress on stderr")
    _add_json_option(demo)
    demo.set_defaults(run=_run_demo)
