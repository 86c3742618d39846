"""``spm workspace``: maps of the workspace over the gaps between the proximal links
(:mod:`spm_pin.workspace`, imported when the command runs), written to a folder."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from .._records import Record
from ._options import add_design_option as _add_design_option
from ._options import add_json_option as _add_json_option
from ._options import add_margin_option as _add_margin_option
from ._options import design_of as _design
from ._options import emit as _emit
from ._options import number as _number

__all__ = ["add_parser"]


def _run_workspace(args: argparse.Namespace) -> int:
    from ..workspace import WorkspaceSettings, workspace_map

    design = _design(args)
    settings = WorkspaceSettings(
        margin=args.margin_mm * 1e-3,
        min_dexterity=args.min_dexterity,
        clearance=not args.no_clearance,
    )
    progress = not args.quiet and sys.stderr.isatty()
    result = workspace_map(
        design,
        step_deg=args.step,
        gap_range_deg=(args.range[0], args.range[1]),
        samples=args.samples,
        seed=args.seed,
        settings=settings,
        workers=args.workers,
        progress=progress,
    )
    written = result.save(args.out, plots=not args.no_plots)
    record: Record = {
        "design": design.name,
        "step_deg": result.step_deg,
        "samples": args.samples,
        "seed": result.seed,
        **result.summary(),
        "out": str(args.out),
        "files": [str(path) for path in written.values()],
    }
    _emit(record, args.json)
    return 0


def add_parser(commands: Any) -> None:
    """``spm workspace``."""
    workspace = commands.add_parser(
        "workspace",
        help="maps of the workspace over the gaps between the proximal links",
        description="Reachability, type I/II singularities, dexterity, self-collision, "
        "clearance and the safe set over the gaps D12, D23 between the proximal links, "
        "and the orientation workspace (tilt, torsion). Writes workspace.npz, "
        "workspace.csv, summary.json and PNG plots to --out.",
    )
    points = workspace.add_mutually_exclusive_group()
    points.add_argument(
        "--step", type=_number, default=2.0, metavar="DEG", help="grid step [deg] (default 2)"
    )
    points.add_argument(
        "--samples", type=int, metavar="N", help="N random points instead of a grid (see --seed)"
    )
    workspace.add_argument(
        "--seed", type=int, default=0, metavar="S", help="seed of --samples (default 0)"
    )
    workspace.add_argument(
        "--range",
        type=_number,
        nargs=2,
        default=(0.0, 360.0),
        metavar=("LOW", "HIGH"),
        help="range of every gap [deg] (default 0 360)",
    )
    _add_margin_option(workspace, "safety margin of the safe set [mm] (default 0)")
    workspace.add_argument(
        "--min-dexterity",
        type=_number,
        default=0.2,
        metavar="X",
        help="smallest dexterity 1/kappa(J) of the safe set (default 0.2)",
    )
    workspace.add_argument(
        "--no-clearance", action="store_true", help="skip the clearance field (faster)"
    )
    workspace.add_argument(
        "--workers", type=int, default=1, metavar="N", help="worker processes (default 1)"
    )
    workspace.add_argument(
        "--out", metavar="DIR", default="workspace", help="output folder (default ./workspace)"
    )
    workspace.add_argument("--no-plots", action="store_true", help="write no PNG plots")
    workspace.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_json_option(workspace)
    _add_design_option(workspace)
    workspace.set_defaults(run=_run_workspace)
