"""``spm calibrate``, ``spm plan-poses`` and ``spm synth-readings``: calibrating the
model against readings of the prototype (:mod:`spm_pin.calibration`, imported when a
command runs)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from .._records import Record
from .._records import dumps as _dumps
from ._options import UsageError as _UsageError
from ._options import add_design_option as _add_design_option
from ._options import add_json_option as _add_json_option
from ._options import add_kind_option as _add_kind_option
from ._options import add_noise_option as _add_noise_option
from ._options import design_of as _design
from ._options import emit as _emit
from ._options import number as _number
from ._options import one_line as _one_line

__all__ = ["EXIT_NOT_IDENTIFIED", "add_parsers"]


#: Exit status of ``spm calibrate`` when the readings cannot identify the parameters
#: (nothing is written unless --force).
EXIT_NOT_IDENTIFIED = 1


def _calibration_files(args: argparse.Namespace) -> dict[str, Path]:
    """Files that ``spm calibrate`` writes: explicit ones, and next to --out the report,
    the offsets (with --servo-config: the updated servo configuration) and the plot
    (``<stem>_report.txt``, ``_offsets.toml`` or ``_servos.toml``, ``_residuals.png``)."""
    files: dict[str, Path] = {}
    if args.out is not None:
        out = Path(args.out)
        stem = out.with_suffix("")
        files = {"design": out, "report": stem.with_name(stem.name + "_report.txt")}
        if args.servo_config is None:
            files["offsets"] = stem.with_name(stem.name + "_offsets.toml")
        else:
            files["servos"] = stem.with_name(stem.name + "_servos.toml")
        files["plot"] = stem.with_name(stem.name + "_residuals.png")
    for key, option in (
        ("report", "report"),
        ("offsets", "offsets"),
        ("servos", "servo_out"),
        ("plot", "plot"),
    ):
        if getattr(args, option) is not None:
            files[key] = Path(getattr(args, option))
    if args.no_plot:
        files.pop("plot", None)
    return files


def _run_calibrate(args: argparse.Namespace) -> int:
    import importlib.util
    import warnings

    from .. import calibration

    if args.no_plot and args.plot is not None:
        raise _UsageError("--plot and --no-plot exclude each other")
    if args.servo_out is not None and args.servo_config is None:
        raise _UsageError("--servo-out needs --servo-config (the configuration to update)")
    servo_config = None
    joints = None
    if args.servo_config is not None:
        # The configuration alone: spm_pin.hardware imports its SDK only to open a port.
        from ..hardware.config import HardwareConfig

        servo_config = HardwareConfig.load(args.servo_config)
        joints = calibration.JointConvention.from_servo_config(servo_config)
    readings = calibration.load_readings(args.readings, joints=joints)
    design = _design(args)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calibration.IdentifiabilityWarning)
        result = calibration.calibrate(
            readings,
            design,
            parameters=args.parameters,
            loss=args.loss,
            noise_deg=args.noise_deg,
            confidence=args.confidence,
        )
    # Before anything is written: the readings must fit the configuration's joints.
    servos = None if servo_config is None else result.servo_config(servo_config)
    files = _calibration_files(args)
    notes: list[str] = []
    if "plot" in files and args.plot is None and importlib.util.find_spec("matplotlib") is None:
        files.pop("plot")
        notes.append("no residual plot: matplotlib is missing (pip install spm-pin[plot])")
    trusted = result.ok or args.force
    written: dict[str, str] = {}
    if trusted:
        for key, path in files.items():
            if key == "design":
                result.design.save(path)
            elif key == "report":
                path.write_text(result.report(), encoding="utf-8")
            elif key == "offsets":
                path.write_text(result.offsets_toml(), encoding="utf-8")
            elif key == "servos":
                assert servos is not None  # --servo-out needs --servo-config
                servos.save(path)
            else:
                result.plot_residuals(path)
            written[key] = str(path)
    record = {**result.as_dict(), "files": written, "notes": notes}
    update = ""
    if servo_config is not None and servos is not None:
        before = [j.zero_offset for j in servo_config.joints]
        after = [j.zero_offset for j in servos.joints]
        record["servo_config"] = {
            "from": str(args.servo_config),
            "zero_offset_before": before,
            "zero_offset": after,
        }
        update = (
            f"servo configuration {args.servo_config}: zero_offset {before} -> {after} [pulses]"
        )
    if args.json:
        print(_dumps(record))
    else:
        print(result.report(), end="")
        if update:
            print(update)
        for key, path_text in written.items():
            print(f"wrote {key}: {path_text}")
        for note in notes:
            print(f"note: {note}")
    if not trusted:
        what = "nothing written; " if files else ""
        print(
            "spm: warning: "
            + _one_line("; ".join(result.identifiability.warnings))
            + f" ({what}--force accepts the result anyway)",
            file=sys.stderr,
        )
        return EXIT_NOT_IDENTIFIED
    return 0


def _run_plan_poses(args: argparse.Namespace) -> int:
    from .. import calibration

    if args.count < 1:
        raise _UsageError(f"N must be a positive number of poses, got {args.count}")
    design = _design(args)
    plan = calibration.plan_poses(
        args.count,
        design,
        parameters=args.parameters,
        kind=args.kind,
        candidates=args.candidates,
        seed=args.seed,
        max_angle_deg=args.max_angle_deg,
        min_margin=args.min_margin,
        min_gap_deg=args.min_gap_deg,
        noise_deg=args.noise_deg,
    )
    obs = plan.observability
    record: Record = {
        "design": design.name,
        "poses": int(plan.theta.shape[0]),
        "candidates": plan.candidates,
        "observability_index": obs.index,
        "random_poses_index": plan.random_index,
        "condition_number": obs.condition_number,
        "predicted_std_deg": obs.as_dict()["predicted_std_deg"],
        "warnings": list(obs.identifiability.warnings),
        "theta_deg": plan.theta_deg,
    }
    if args.out is not None:
        plan.to_csv(args.out)
        record["out"] = str(args.out)
    _emit(record, args.json)
    return 0


def _run_synth_readings(args: argparse.Namespace) -> int:
    from .. import calibration

    design = _design(args)
    if args.poses is not None:
        poses: Any = calibration.load_poses(args.poses)
    elif args.count < 1:
        raise _UsageError(f"N must be a positive number of readings, got {args.count}")
    else:
        poses = args.count
    data = calibration.synthetic_readings(
        poses,
        design,
        seed=args.seed,
        noise_deg=args.noise_deg,
        kind=args.kind,
        unit=args.unit,
        outlier_fraction=args.outliers,
    )
    truth = data.truth.as_dict()
    comments = [
        f"synthetic readings of {design.name} (seed {args.seed}, sensor noise "
        f"{args.noise_deg:g} deg per axis, {int(data.outliers.sum())} outliers)",
        *(f"true {key}: {value}" for key, value in truth.items() if "reference" not in key),
    ]
    data.readings.to_csv(args.out, comments=comments)
    record: Record = {
        "design": design.name,
        "readings": len(data.readings),
        "kind": args.kind,
        "unit": args.unit,
        "seed": args.seed,
        "out": str(args.out),
        "truth": truth,
        "outlier_lines": (np.nonzero(data.outliers)[0] + 1).tolist(),
    }
    _emit(record, args.json)
    return 0


def add_parsers(commands: Any) -> None:
    """``spm calibrate``, ``spm plan-poses`` and ``spm synth-readings``."""
    from ..calibration import PARAMETER_GROUPS, PARAMETER_NAMES

    names = f"names ({', '.join(PARAMETER_NAMES)}) or groups ({', '.join(PARAMETER_GROUPS)})"
    calibrate = commands.add_parser(
        "calibrate",
        help="identify encoder offsets, link angles and sensor mounting from readings",
        description="Calibrate the model against readings of the prototype (CSV: servo "
        "positions and a sensor orientation per pose; see docs/calibration.md). Prints a "
        "report; with --out writes the calibrated design (which every command takes with "
        "--design), FILE_report.txt, FILE_offsets.toml (encoder zero offsets for the servo "
        "configuration; with --servo-config CONFIG.toml instead FILE_servos.toml, that "
        "configuration with the identified zero offsets, for spm servo --config) and "
        "FILE_residuals.png. Exit status 1, nothing written, when the "
        "readings cannot identify the parameters (unless --force). Needs the calibration "
        "extra (scipy); the plot needs the plot extra (matplotlib).",
    )
    calibrate.add_argument("readings", metavar="READINGS.csv", help="the readings file")
    calibrate.add_argument("--out", metavar="FILE", help="write the calibrated design TOML")
    calibrate.add_argument(
        "--parameters",
        metavar="LIST",
        help=f"comma-separated {names} (default: offsets,links,mount; offsets,links for "
        "axis readings)",
    )
    calibrate.add_argument(
        "--loss",
        default="soft_l1",
        choices=["soft_l1", "huber", "cauchy", "arctan", "linear"],
        help="robust loss (default: soft_l1)",
    )
    _add_noise_option(calibrate, "expected sensor noise per axis [deg] (default: 0.5)")
    calibrate.add_argument(
        "--confidence",
        type=_number,
        default=0.95,
        metavar="C",
        help="level of the confidence intervals (default: 0.95)",
    )
    calibrate.add_argument("--report", metavar="FILE", help="write the report to FILE")
    calibrate.add_argument("--plot", metavar="FILE", help="write the residual plot (PNG) to FILE")
    calibrate.add_argument("--no-plot", action="store_true", help="write no residual plot")
    calibrate.add_argument(
        "--offsets",
        metavar="FILE",
        help="write the encoder zero offsets (the [[joints]] tables of a servo configuration) "
        "to FILE",
    )
    calibrate.add_argument(
        "--servo-config",
        metavar="FILE",
        help="the servo configuration (TOML, as for spm servo --config) the readings were "
        "taken with: converts tick columns when the readings file gives no settings, and "
        "with --out writes a copy with the identified zero offsets as FILE_servos.toml "
        "(instead of FILE_offsets.toml)",
    )
    calibrate.add_argument(
        "--servo-out",
        metavar="FILE",
        help="write the updated servo configuration to FILE (needs --servo-config)",
    )
    calibrate.add_argument(
        "--force",
        action="store_true",
        help="write the files even when some parameters are not identified",
    )
    _add_json_option(calibrate)
    _add_design_option(calibrate)
    calibrate.set_defaults(run=_run_calibrate)

    plan = commands.add_parser(
        "plan-poses",
        help="choose informative poses for a calibration run",
        description="Choose N poses that make the calibration parameters observable "
        "(greedy D-optimal over random admissible poses: reachable, away from "
        "singularities, proximal links apart) and write them as a pose list (CSV, "
        "theta_deg per pose) for the hardware to visit.",
    )
    plan.add_argument("count", type=int, metavar="N", help="number of poses")
    plan.add_argument("--out", metavar="FILE", help="write the pose list (CSV)")
    plan.add_argument("--parameters", metavar="LIST", help=f"comma-separated {names}")
    _add_kind_option(plan)
    plan.add_argument("--seed", type=int, default=0, help="seed of the candidates (default 0)")
    plan.add_argument(
        "--candidates", type=int, default=2000, metavar="C", help="candidates (default 2000)"
    )
    plan.add_argument(
        "--max-angle-deg",
        type=_number,
        default=90.0,
        metavar="A",
        help="range of each input around home [deg] (default 90)",
    )
    plan.add_argument(
        "--min-margin",
        type=_number,
        default=0.25,
        metavar="M",
        help="smallest singularity margin, 0..1 (default 0.25)",
    )
    plan.add_argument(
        "--min-gap-deg",
        type=_number,
        default=45.0,
        metavar="G",
        help="smallest gap between adjacent proximal links [deg] (default 45)",
    )
    _add_noise_option(
        plan, "sensor noise per axis [deg] for the predicted deviations (default 0.5)"
    )
    _add_json_option(plan)
    _add_design_option(plan)
    plan.set_defaults(run=_run_plan_poses)

    synth = commands.add_parser(
        "synth-readings",
        help="write readings of a simulated, perturbed prototype",
        description="Readings of a perturbed prototype (random offsets, link angles and "
        "sensor mounting, drawn from --seed) with encoder steps of 0.088 deg and sensor "
        "noise, at N random poses or at the poses of a pose list; the true values go into "
        "the file's comments and the output.",
    )
    synth.add_argument(
        "count", type=int, nargs="?", default=100, metavar="N", help="readings (default 100)"
    )
    synth.add_argument("--out", metavar="FILE", required=True, help="the readings file to write")
    synth.add_argument("--poses", metavar="FILE", help="pose list from 'spm plan-poses'")
    synth.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    synth.add_argument(
        "--unit",
        choices=["ticks", "deg", "rad"],
        default="ticks",
        help="unit of the servo columns (default: ticks, 4096 per turn)",
    )
    _add_kind_option(synth)
    _add_noise_option(synth, "sensor noise per axis [deg] (default 0.5)")
    synth.add_argument(
        "--outliers",
        type=_number,
        default=0.0,
        metavar="F",
        help="fraction of readings with a gross sensor error (default 0)",
    )
    _add_json_option(synth)
    _add_design_option(synth)
    synth.set_defaults(run=_run_synth_readings)
