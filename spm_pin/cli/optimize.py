"""``spm optimize``: a design study on Optuna (:mod:`spm_pin.optimize.study`, imported
when the command runs), resumable from its storage file, its designs evaluated in this
process, on a local Dask cluster (``--workers N``) or on a running one
(``--scheduler ADDRESS``); with ``--out DIR`` the results are written there
(:func:`spm_pin.optimize.write_results`: the Pareto plot, the best designs as design
files, a page showing them and a JSON report)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from .._records import Record
from ._options import EXIT_INTERRUPTED, UsageError
from ._options import add_design_option as _add_design_option
from ._options import add_json_option as _add_json_option
from ._options import design_of as _design
from ._options import emit as _emit
from ._options import number as _number

__all__ = ["add_parser", "parse_variable"]


def parse_variable(text: str) -> tuple[str, float, float]:
    """``NAME=LOW:HIGH`` -> (name, low, high); ``alpha1`` stands for ``alpha1_deg``."""
    name, sep, bounds = text.partition("=")
    low, sep2, high = bounds.partition(":")
    if not (sep and sep2 and name):
        raise UsageError(f"--vary takes NAME=LOW:HIGH (e.g. alpha1=40:80), got {text!r}")
    try:
        values = (_number(low), _number(high))
    except argparse.ArgumentTypeError as exc:
        raise UsageError(f"--vary {text}: {exc}") from None
    if name in ("alpha1", "alpha2", "beta"):
        name += "_deg"
    return name, values[0], values[1]


def _space_file(path: str) -> list[tuple[str, float, float]]:
    """The variables of a TOML space file: ``[variables]`` ``NAME = [LOW, HIGH]``."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - exercised on Python 3.10 only
        import tomli as tomllib

    try:
        table = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise UsageError(f"--space {path}: not TOML: {exc}") from None
    variables = table.get("variables")
    if not isinstance(variables, dict) or not variables:
        raise UsageError(f"--space {path}: needs a [variables] table of NAME = [LOW, HIGH]")
    out = []
    for name, bounds in variables.items():
        if not (isinstance(bounds, list) and len(bounds) == 2):
            raise UsageError(f"--space {path}: {name} must be [LOW, HIGH], got {bounds!r}")
        out.append(parse_variable(f"{name}={bounds[0]}:{bounds[1]}"))
    return out


def _check_out(out: str) -> None:
    """Refuse an --out folder that cannot be made, before the study runs (the results
    are written after it)."""
    path = Path(out)
    existing = next((p for p in (path, *path.parents) if p.exists()), Path("."))
    if not existing.is_dir() or not os.access(existing, os.W_OK):
        what = "is not a folder" if not existing.is_dir() else "is not writable"
        raise UsageError(f"--out {out}: {existing} {what}")


def _run_optimize(args: argparse.Namespace) -> int:
    from ..optimize import DesignSpace, Variable
    from ..optimize.study import StudySettings, run_study

    items = [parse_variable(text) for text in args.vary or []]
    if args.space is not None:
        items += _space_file(args.space)
    if not items:
        raise UsageError("a design space is required: --vary NAME=LOW:HIGH ... or --space FILE")
    base = _design(args)
    space = DesignSpace(tuple(Variable(*item) for item in items), base=base)
    settings = StudySettings(
        step_deg=args.step,
        margin=args.margin_mm * 1e-3,
        cone_deg=args.cone,
        motion_tilt_deg=args.motion_tilt,
        motion_period_s=args.motion_period,
        payload_kg=args.payload_kg,
        payload_height_m=args.payload_height_mm * 1e-3,
        require_home_clearance=not args.allow_home_collision,
        max_torque_nm=args.max_torque,
        required_tilt_deg=args.required_tilt,
    )
    progress = not args.quiet and sys.stderr.isatty()
    enqueue = [space.values_of(base)] if args.include_base else []
    try:
        import optuna  # noqa: F401  (the optimize extra)
    except ImportError:
        raise UsageError("spm optimize needs Optuna: pip install 'spm-pin[optimize]'") from None
    if args.best < 1:
        raise UsageError(f"--best takes an integer >= 1, got {args.best}")
    if args.out is not None:
        _check_out(args.out)
    if args.workers > 1 or args.scheduler is not None:
        try:
            import distributed  # noqa: F401
        except ImportError:
            raise UsageError(
                "--workers and --scheduler need Dask: pip install 'dask[distributed]'"
            ) from None
    try:
        result = run_study(
            space,
            args.objectives,
            args.trials,
            settings=settings,
            seed=args.seed,
            storage=args.storage,
            population_size=args.population,
            enqueue=enqueue,
            progress=progress,
            workers=args.workers,
            scheduler=args.scheduler,
        )
    except KeyboardInterrupt:
        kept = (
            f"the finished trials are kept in {args.storage}: run the same command again "
            "to continue"
            if args.storage is not None
            else "nothing was kept (give --storage FILE to make a study resumable)"
        )
        print(f"spm optimize: interrupted; {kept}", file=sys.stderr)
        return EXIT_INTERRUPTED
    record: Record = {
        "design": base.name,
        "variables": [[v.name, v.low, v.high] for v in space.variables],
        "seed": args.seed,
        "storage": args.storage,
        "workers": args.workers,
        "scheduler": args.scheduler,
        "seconds": result.seconds,
        **result.summary(),
    }
    if args.out is not None:
        from ..optimize.results import write_results

        # the reference of the report is the design the study varies (--design)
        written = write_results(result, args.out, best=args.best, prototype=base)
        record["out"] = str(args.out)
        record["files"] = [str(path) for path in written.files]
        record["notes"] = written.report["notes"]
    if args.json:
        _emit(record, True)
    else:
        _print_text(record)
    return 0


def _print_text(record: dict[str, Any]) -> None:
    names = [o["name"] for o in record["objectives"]]
    print(
        f"{record['trials']} trials ({record['new_trials']} new, {record['failed']} failed, "
        f"{record['feasible']} feasible) in {record['seconds']:.1f} s"
    )
    print(
        "objectives: " + ", ".join(f"{o['name']} ({o['direction']})" for o in record["objectives"])
    )
    print(f"Pareto front ({len(record['pareto'])} designs):")
    for trial in record["pareto"]:
        values = " ".join(f"{k}={v:.4g}" for k, v in trial["values"].items())
        scores = " ".join(f"{n}={trial['scores'][n]:.4g}" for n in names)
        print(f"  #{trial['number']}: {values} -> {scores}")
    if "files" in record:
        print(f"wrote {len(record['files'])} files to {record['out']}:")
        for path in record["files"]:
            print(f"  {path}")
        for note in record["notes"]:
            print(f"  note: {note}")


def add_parser(commands: Any) -> None:
    """``spm optimize``."""
    parser = commands.add_parser(
        "optimize",
        help="search a design space for the best designs (Optuna; resumable)",
        description="A design study: vary link angles [deg] or sizes [m] of a design "
        "within bounds (a design that is not coaxial, such as agile_eye, takes "
        "cone_dexterity, peak_torque and envelope), score each candidate by the "
        "objectives (NSGA-II for "
        "several, TPE for one), under constraints, and print the Pareto front. With --out "
        "DIR, write there pareto.png, the best designs as design files best_1.toml ... "
        "(for --design FILE), designs.html and report.json (with the base design, "
        "--design, scored for comparison). With "
        "--storage FILE the study is kept in an Optuna journal file (or an RDB URL such "
        "as sqlite:///study.db): running again continues it up to --trials in all. "
        "--workers N or --scheduler ADDRESS evaluate the designs on Dask (this process "
        "alone writes the storage).",
    )
    parser.add_argument(
        "--objectives",
        nargs="+",
        default=["tilt"],
        metavar="NAME",
        help="tilt, max_tilt, safe_fraction, gci, cone_dexterity, peak_torque, envelope "
        "(default: tilt)",
    )
    parser.add_argument(
        "--vary",
        nargs="+",
        metavar="NAME=LOW:HIGH",
        help="variables and bounds, e.g. alpha1=40:80 alpha2=60:120 distal_radius=0.08:0.1",
    )
    parser.add_argument(
        "--space", metavar="FILE", help="a TOML file with [variables] NAME = [LOW, HIGH]"
    )
    parser.add_argument(
        "--trials", type=int, default=50, metavar="N", help="trials in all (default 50)"
    )
    parser.add_argument("--seed", type=int, default=0, metavar="S", help="seed (default 0)")
    parser.add_argument(
        "--storage", metavar="FILE|URL", help="study storage: journal file or RDB URL (resumable)"
    )
    parser.add_argument(
        "--population", type=int, default=20, metavar="N", help="NSGA-II population (default 20)"
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=1,
        metavar="N",
        help="evaluate on a local Dask cluster of N processes (default 1: in this process)",
    )
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="evaluate on the workers of a running Dask scheduler (tcp://host:8786)",
    )
    parser.add_argument(
        "--step", type=_number, default=6.0, metavar="DEG", help="workspace grid step (default 6)"
    )
    parser.add_argument(
        "--margin-mm", type=_number, default=0.0, metavar="MM", help="safety margin (default 0)"
    )
    parser.add_argument(
        "--cone", type=_number, default=20.0, metavar="DEG", help="cone of cone_dexterity"
    )
    parser.add_argument(
        "--motion-tilt", type=_number, default=20.0, metavar="DEG", help="tilt of the motion"
    )
    parser.add_argument(
        "--motion-period", type=_number, default=2.0, metavar="S", help="time of its turn [s]"
    )
    parser.add_argument(
        "--payload-kg", type=_number, default=0.0, metavar="KG", help="point mass on the platform"
    )
    parser.add_argument(
        "--payload-height-mm",
        type=_number,
        default=50.0,
        metavar="MM",
        help="its height above the centre (default 50)",
    )
    parser.add_argument(
        "--max-torque", type=_number, metavar="NM", help="constraint: peak torque at most NM"
    )
    parser.add_argument(
        "--required-tilt",
        type=_number,
        metavar="DEG",
        help="constraint: tilt safe in every direction at least DEG",
    )
    parser.add_argument(
        "--allow-home-collision", action="store_true", help="drop the home-clearance constraint"
    )
    parser.add_argument(
        "--include-base", action="store_true", help="evaluate the base design first"
    )
    parser.add_argument(
        "--out",
        metavar="DIR",
        help="write the results there: pareto.png, best_1.toml ..., designs.html, report.json",
    )
    parser.add_argument(
        "--best",
        type=int,
        default=5,
        metavar="N",
        help="with --out: write at most N designs of the Pareto front (default 5)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_json_option(parser)
    _add_design_option(parser)
    parser.set_defaults(run=_run_optimize)
