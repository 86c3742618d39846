"""The ``spm`` command: kinematics of spherical parallel manipulators from the shell.

Angles are degrees on the command line and radians inside. Every command prints
human-readable text by default and JSON with ``--json`` (vectors as lists, ``null``
where a value does not exist; NaN is never emitted).

Commands::

    spm fk T1 T2 T3 [--all] [--json] [--design NAME|FILE] [--solver analytic|projection]
    spm ik (--matrix R11 .. R33 | --quaternion W X Y Z | --rpy ROLL PITCH YAW)
           [--mode LABEL|INDEX] [--all] [--json] [--design NAME|FILE]
    spm design [--preset NAME | --design NAME|FILE] [--out FILE]
    spm demo [--out DIR] [--quick] [--workspace-step DEG] [--quiet] [--json]
    spm export [--design NAME|FILE] [--out DIR] [--json]
    spm show T1 T2 T3 [--html FILE] [--mode LABEL] [--axes] [--frame] [--json] [--design NAME|FILE]
    spm animate [--from T1 T2 T3] --to T1 T2 T3 [--samples N] [--duration S] --html FILE
                [--axes] [--frame] [--json] [--design NAME|FILE]
    spm servo emulate [--ids ID ...] | status | move T1 T2 T3 | follow  (see spm servo -h)
    spm calibrate READINGS.csv [--out FILE] [--design NAME|FILE] [--parameters LIST] [--force]
                [--report FILE] [--plot FILE | --no-plot] [--offsets FILE]
                [--servo-config FILE [--servo-out FILE]] [--json]
    spm plan-poses N [--out FILE] [--design NAME|FILE] [--parameters LIST] [--seed S] [--json]
    spm synth-readings [N] --out FILE [--poses FILE] [--seed S] [--unit UNIT] [--json]
    spm torques [--from T1 T2 T3] (--to T1 T2 T3 | --file CSV) [--duration S] [--rate HZ]
                [--gravity GX GY GZ] [--plot FILE] [--json] [--design NAME|FILE]
    spm collide T1 T2 T3 [--margin-mm MM] [--json] [--design NAME|FILE]
    spm workspace [--step DEG | --samples N [--seed S]] [--range LOW HIGH] [--margin-mm MM]
                [--min-dexterity X] [--no-clearance] [--workers N] [--out DIR]
                [--no-plots] [--quiet] [--json] [--design NAME|FILE]

Every bad argument and every :class:`~spm_pin.SPMError` raised by the library is
reported as one line ``spm: error: ...`` on stderr with exit status 2 (so is an
orientation that ``spm ik`` cannot reach, naming every leg that cannot close).
``spm torques`` exits with status 1 when the motion exceeds the servos'
torque-speed envelope (its report is printed all the same), ``spm demo`` when its
cross-checks disagree, ``spm calibrate`` when the readings cannot identify the
parameters. Lists of results (``--all``) are numbered from 0 in text as in JSON, the
numbers that ``--mode INDEX`` takes.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import math
import os
import sys
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._records import (
    FloatArray,
    Record,
    fk_all_record,
)
from .._records import assembly_label as _assembly_label
from .._records import checked_links as _checked_links
from .._records import dumps as _dumps
from .._records import orientation as _orientation
from .._records import plain as _plain
from .._records import render as _render
from .._records import worst_sample as _worst_sample
from .._version import __version__
from ..design import SPMDesign
from ..errors import SPMError, UnreachableError
from ..kinematics import (
    WORKING_MODE_LABELS,
    forward_kinematics,
    forward_kinematics_all,
    inverse_kinematics,
    jacobian,
)
from ..kinematics._common import as_rotation
from ..kinematics.fk import satisfies_home_rule
from ..rotations import (
    matrix_from_quaternion,
    matrix_from_rpy,
)
from ._options import EXIT_OVER_LIMITS, EXIT_USAGE
from ._options import Parser as _Parser
from ._options import UsageError as _UsageError
from ._options import add_angle_arguments as _add_angle_arguments
from ._options import add_design_option as _add_design_option
from ._options import add_json_option as _add_json_option
from ._options import add_kind_option as _add_kind_option
from ._options import add_margin_option as _add_margin_option
from ._options import add_motion_options as _add_motion_options
from ._options import add_noise_option as _add_noise_option
from ._options import design_of as _design
from ._options import emit as _emit
from ._options import mode as _mode
from ._options import number as _number

__all__ = [
    "FK_SOLVERS",
    "FKSolution",
    "build_parser",
    "collide_record",
    "fk_all_record",
    "fk_record",
    "ik_record",
    "main",
]


# -------------------------------------------------------------------------------- fk
@dataclasses.dataclass(frozen=True)
class FKSolution:
    """What a forward-kinematics solver returns for one input.

    Attributes:
        R: Platform rotation (3, 3), or None when the solver finds no assembly.
        residual: Closure residual of the solution (NaN when there is none).
    """

    R: FloatArray | None
    residual: float


def _fk_analytic(theta: FloatArray, design: SPMDesign) -> FKSolution:
    fk = forward_kinematics(theta, design)
    if not bool(fk.reachable):
        return FKSolution(R=None, residual=math.nan)
    return FKSolution(R=fk.R, residual=float(fk.residual))


def _fk_projection(theta: FloatArray, design: SPMDesign) -> FKSolution:
    """Newton projection on the Pinocchio model (:class:`~spm_pin.ClosedLoop`), from home.

    Cold start at home, path following from home if Newton fails. The residual is the
    norm of the two welds' errors [rad]; R is the platform frame's rotation.
    """
    from ..closure import ClosedLoop
    from ..errors import ConvergenceError
    from ..model.robot import build_robot

    robot = build_robot(design)
    try:
        result = ClosedLoop.from_robot(robot).project(theta)
    except ConvergenceError:
        return FKSolution(R=None, residual=math.nan)
    R = np.array(robot.placement(result.q, "platform").rotation)
    return FKSolution(R=R, residual=result.residual)


#: Forward-kinematics solvers selectable with ``spm fk --solver NAME``. Every solver
#: yields the same output keys; everything but R and the residual (each solver's own
#: closure measure) is derived from R.
FK_SOLVERS: dict[str, Callable[[FloatArray, SPMDesign], FKSolution]] = {
    "analytic": _fk_analytic,
    "projection": _fk_projection,
}

_FK_KEYS = (
    "mode",
    "home",
    "R",
    "v",
    "rpy_deg",
    "quaternion_wxyz",
    "residual",
    "dexterity",
    "dexterity_ga",
    "singularity_margin",
    "det_a",
    "b",
    "type_i_singular",
    "type_ii_singular",
    "J",
)


def fk_record(theta_deg: Sequence[float], design: SPMDesign, solver: str = "analytic") -> Record:
    """Forward kinematics of one input [deg] with velocity data, as a record."""
    theta = np.radians(np.asarray(theta_deg, dtype=float))
    solution = FK_SOLVERS[solver](theta, design)
    record: Record = {
        "design": design.name,
        "solver": solver,
        "theta_deg": list(theta_deg),
        "reachable": solution.R is not None,
    }
    record.update(dict.fromkeys(_FK_KEYS))
    if solution.R is None:
        return record
    R = solution.R
    # A batch of one: the Jacobian flags a type II singularity instead of raising.
    jac = jacobian(theta[None], design, R=R[None])
    b, det_a = jac.b[0], float(jac.det_a[0])
    record.update(
        {
            "mode": _assembly_label(b, det_a),
            "home": bool(satisfies_home_rule(b, np.asarray(det_a), design)),
            **_orientation(R),
            "v": np.einsum("jk,ik->ij", R, design.v0),
            "residual": solution.residual,
            "dexterity": jac.dexterity[0],
            "dexterity_ga": jac.dexterity_ga[0],
            "singularity_margin": jac.singularity_margin[0],
            "det_a": det_a,
            "b": b,
            "type_i_singular": jac.type_i[0],
            "type_ii_singular": jac.type_ii[0],
            "J": jac.J[0],
        }
    )
    return record


def _run_fk(args: argparse.Namespace) -> int:
    design = _design(args)
    theta_deg = [args.T1, args.T2, args.T3]
    if args.all:
        record = fk_all_record(theta_deg, design)
    else:
        record = fk_record(theta_deg, design, args.solver)
        if not record["reachable"] and not args.json:
            record["note"] = "no home-mode assembly at this input; --all lists every assembly mode"
    _emit(record, args.json)
    return 0


# -------------------------------------------------------------------------------- ik
def _target_rotation(args: argparse.Namespace) -> FloatArray:
    """The orientation given by --matrix, --quaternion or --rpy [deg]."""
    if args.matrix is not None:
        return as_rotation(np.reshape(args.matrix, (3, 3)), "--matrix")
    if args.quaternion is not None:
        return matrix_from_quaternion(args.quaternion)
    return matrix_from_rpy(np.radians(args.rpy))


def ik_record(
    R: FloatArray, design: SPMDesign, mode: int | str = 0, *, all_modes: bool = False
) -> Record:
    """Inverse kinematics of one rotation, in one working mode or all 8, as a record.

    An unreachable orientation is an answer, not an error: ``reachable`` is False,
    ``theta_deg`` is None and ``failing_leg`` names the first leg that cannot close.
    """
    modes = range(len(WORKING_MODE_LABELS)) if all_modes else (mode,)
    # Batches of one: an unreachable orientation is flagged instead of raised.
    results = [inverse_kinematics(R[None], design, mode=m) for m in modes]
    indices = list(modes) if all_modes else [_working_mode_index(mode)]
    leg_reachable = results[0].leg_reachable[0]  # the same in every working mode
    reachable = bool(np.all(leg_reachable))
    solutions = [
        {
            "theta_deg": np.degrees(ik.theta[0]) if reachable else None,
            "index": index,
            "mode": ik.mode,
            "home": ik.mode == WORKING_MODE_LABELS[0],
            "b": ik.b[0] if reachable else None,
        }
        for ik, index in zip(results, indices, strict=True)
    ]
    record: Record = {"design": design.name}
    if all_modes:
        record["reachable"] = reachable
        record["modes"] = [{"label": s.pop("mode"), **s} for s in solutions]
    else:
        record["theta_deg"] = solutions[0].pop("theta_deg")
        record["reachable"] = reachable
        record.update(solutions[0])
    record["leg_reachable"] = leg_reachable
    record["failing_legs"] = [int(i) + 1 for i in np.flatnonzero(~np.asarray(leg_reachable))]
    record.update(_orientation(R))
    return record


def _working_mode_index(mode: int | str) -> int:
    return mode if isinstance(mode, int) else WORKING_MODE_LABELS.index(mode)


def _run_ik(args: argparse.Namespace) -> int:
    design = _design(args)
    R = _target_rotation(args)
    record = ik_record(R, design, args.mode, all_modes=args.all)
    if not record["reachable"]:
        legs = record["failing_legs"]
        which = f"leg {legs[0]}" if len(legs) == 1 else "legs " + _and_list(map(str, legs))
        rpy = ", ".join(f"{x:g}" for x in np.round(np.asarray(record["rpy_deg"], dtype=float), 6))
        raise _UsageError(
            f"the orientation (rpy = [{rpy}] deg) is out of reach of design "
            f"{design.name!r}: {which} cannot close (no input angle puts w_i at alpha2 from "
            "v_i); 'spm workspace' maps the reachable orientations"
        )
    _emit(record, args.json)
    return 0


def _and_list(items: Iterable[str]) -> str:
    """'2 and 3', '1, 2 and 3'."""
    words = list(items)
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


# ---------------------------------------------------------------------------- design
def _run_design(args: argparse.Namespace) -> int:
    design = _design(args)
    if args.out is None:
        print(design.to_toml(), end="")
    else:
        path = design.save(args.out)
        print(f"wrote design {design.name!r} to {path}")
    return 0


# ------------------------------------------------------------------------------ demo
def _run_demo(args: argparse.Namespace) -> int:
    # Imported here: the demo gathers every layer (Pinocchio, MuJoCo, meshcat, plots).
    from ..demo import DemoContext, run_demo

    changes: Record = {"out": Path(args.out)}
    if args.workspace_step is not None:
        changes["workspace_step_deg"] = args.workspace_step
    ctx = DemoContext.quick(**changes) if args.quick else DemoContext(**changes)
    result = run_demo(ctx, progress="off" if args.quiet else "auto")
    print(_dumps(result.record) if args.json else "\n".join(result.lines))
    if result.failed_checks:  # the solvers disagree: exit status 1, like a failed test
        failed = ", ".join(result.failed_checks)
        print(f"spm: warning: cross-checks outside their tolerance: {failed}", file=sys.stderr)
        return 1
    return 0


# ---------------------------------------------------------------------------- export
def _run_export(args: argparse.Namespace) -> int:
    design = _design(args)
    # Imported here: the model layer (trimesh) is not needed by the other commands.
    from ..model.export import export

    written = export(design, args.out)
    if args.json:
        print(
            _dumps(
                {
                    "design": design.name,
                    "out": str(args.out),
                    "files": [str(p) for p in written.values()],
                }
            )
        )
    else:
        print(f"wrote the robot files of design {design.name!r} to {args.out}:")
        for path in written.values():
            print(f"  {path}")
    return 0


# ------------------------------------------------------------------------ show/animate
def _visualizer(args: argparse.Namespace) -> Any:
    """A :class:`~spm_pin.viz.Visualizer` of the chosen design with the chosen overlays."""
    try:  # imported here: meshcat is an optional dependency (the viz extra)
        from ..collision import build_robot
        from ..viz import Visualizer
    except ImportError as exc:
        raise _UsageError(str(exc)) from exc
    robot = build_robot(_design(args))
    return Visualizer(robot, joint_axes=args.axes, platform_frame=args.frame)


def _add_view_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--axes", action="store_true", help="draw the joint axes u_i, w_i, v_i")
    parser.add_argument("--frame", action="store_true", help="draw the platform frame")


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


def _display(viz: Any, theta_deg: Sequence[float], mode: str) -> Any:
    """viz.display at theta [deg] in --mode, with command-line hints on failure."""
    try:
        return viz.display(np.radians(theta_deg), mode=mode)
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
    pairs = _display(viz, theta_deg, mode)
    record: Record = {
        "design": viz.robot.design.name,
        "theta_deg": theta_deg,
        "mode": viz.mode,
        "home": viz.home,
        "colliding": [list(pair) for pair in pairs],
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


# ----------------------------------------------------------------------- calibration
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


def _add_calibration_parsers(commands: Any) -> None:
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


# --------------------------------------------------------------------------- torques
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


def _add_torques_parser(commands: Any) -> None:
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


# ------------------------------------------------------------------ collide/workspace
def collide_record(theta_deg: Sequence[float], design: SPMDesign, margin_m: float = 0.0) -> Record:
    """Self-collision at one input [deg], whichever assembly mode exists, as a record.

    Keys: ``theta_deg``, ``reachable`` (a home-mode assembly exists), ``mode`` (the
    assembly mode checked, null when no assembly exists and only the proximal links
    were checked), ``home``, ``checked``, ``collision``, ``pairs`` (colliding link
    pairs, lists of two names), ``min_distance_m`` and its ``min_distance_pair``,
    ``margin_m``, ``fixed_clearance_m`` and ``distances`` (every checked pair).
    """
    from ..collision import build_robot, check_input

    robot = build_robot(design)
    report = check_input(np.radians(np.asarray(theta_deg, dtype=float)), robot, margin=margin_m)
    nearest = min(report.distances, key=lambda pair: report.distances[pair])
    return {
        "design": design.name,
        "theta_deg": list(theta_deg),
        "reachable": report.reachable,
        "mode": report.mode,
        "home": report.home,
        "checked": _checked_links(report),
        "collision": report.collision,
        "pairs": [list(pair) for pair in report.pairs],
        "min_distance_m": report.min_distance,
        "min_distance_pair": list(nearest),
        "margin_m": report.margin,
        "fixed_clearance_m": robot.collision_checker.fixed_clearance,
        "distances": [
            {"pair": list(pair), "distance_m": distance}
            for pair, distance in report.distances.items()
        ],
    }


def _run_collide(args: argparse.Namespace) -> int:
    design = _design(args)
    record = collide_record([args.T1, args.T2, args.T3], design, args.margin_mm * 1e-3)
    if not args.json:
        distances = record.pop("distances")
        record["pairs"] = ["-".join(pair) for pair in record["pairs"]] or None
        record["min_distance_pair"] = "-".join(record["min_distance_pair"])
        record["distances_m"] = {"-".join(d["pair"]): d["distance_m"] for d in distances}
        if record["pairs"] is None:
            record["pairs"] = "none"
    _emit(record, args.json)
    return 0


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


def _add_collision_parsers(commands: Any) -> None:
    """``spm collide`` and ``spm workspace``."""
    collide = commands.add_parser(
        "collide",
        help="self-collision of the links at input angles",
        description="Which link pairs collide at input angles T1 T2 T3 [deg], and the "
        "distance of every checked pair. Checks the home assembly mode; where it does not "
        "exist, the real assembly mode nearest to it (named in the output); with no real "
        "assembly at all, the proximal links, which theta alone places.",
    )
    _add_angle_arguments(collide)
    _add_margin_option(
        collide,
        "safety margin [mm]: links nearer than this count as colliding (default 0; "
        "the prototype's drive tubes are 1 mm apart everywhere)",
    )
    _add_json_option(collide)
    _add_design_option(collide)
    collide.set_defaults(run=_run_collide)

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


# ---------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``spm`` (errors raise instead of exiting)."""
    parser = _Parser(
        prog="spm",
        description="Kinematics of spherical parallel manipulators (angles in degrees).",
    )
    parser.add_argument("--version", action="version", version=f"spm-pin {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    fk = commands.add_parser(
        "fk",
        help="forward kinematics: input angles -> platform orientation",
        description="Platform orientation at input angles T1 T2 T3 [deg] (home assembly "
        "mode), with Jacobian, singularity and dexterity data.",
    )
    _add_angle_arguments(fk)
    fk.add_argument("--all", action="store_true", help="every real assembly mode")
    fk.add_argument(
        "--solver",
        choices=sorted(FK_SOLVERS),
        default="analytic",
        help="analytic (default, the home assembly mode) or projection (Newton projection "
        "on the Pinocchio model from home); --all is always analytic",
    )
    _add_json_option(fk)
    _add_design_option(fk)
    fk.set_defaults(run=_run_fk)

    ik = commands.add_parser(
        "ik",
        help="inverse kinematics: platform orientation -> input angles",
        description="Input angles [deg] that put the platform at an orientation.",
    )
    target = ik.add_mutually_exclusive_group(required=True)
    target.add_argument(
        "--matrix",
        nargs=9,
        type=_number,
        metavar=tuple(f"R{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3)),
        help="rotation matrix, row by row",
    )
    target.add_argument(
        "--quaternion",
        nargs=4,
        type=_number,
        metavar=("W", "X", "Y", "Z"),
        help="quaternion, scalar first (normalised)",
    )
    target.add_argument(
        "--rpy",
        nargs=3,
        type=_number,
        metavar=("ROLL", "PITCH", "YAW"),
        help="fixed-axis angles [deg], R = Rz(yaw) Ry(pitch) Rx(roll)",
    )
    which = ik.add_mutually_exclusive_group()
    which.add_argument(
        "--mode",
        type=_mode,
        default=0,
        metavar="LABEL|INDEX",
        help="working mode: 0..7 or a label such as +-+ (default: 0, the home mode +++)",
    )
    which.add_argument("--all", action="store_true", help="all 8 working modes")
    _add_json_option(ik)
    _add_design_option(ik)
    ik.set_defaults(run=_run_ik)

    design = commands.add_parser(
        "design",
        help="print or write a design file",
        description="Print a design as TOML (or write it with --out), to start a design "
        "file from a preset.",
    )
    source = design.add_mutually_exclusive_group()
    source.add_argument("--preset", choices=["prototype", "agile_eye"], help="preset design")
    _add_design_option(source)
    design.add_argument("--out", metavar="FILE", help="write the TOML to FILE")
    design.set_defaults(run=_run_design)

    demo = commands.add_parser(
        "demo",
        help="the published study of the prototype, reproduced, with an HTML report",
        description="The published study of the prototype, reproduced and extended: forward "
        "kinematics at theta = [60, 90, 120] deg analytically, by Newton projection and by "
        "MuJoCo; the motion from home at 25 samples; the colliding input [60, 90, 220] deg; "
        "the safe workspace; the actuator torques. Writes DIR/index.html (plots and "
        "meshcat scenes, works offline) and DIR/demo.json. Progress goes to stderr. "
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
    demo.add_argument("--quiet", action="store_true", help="no progress on stderr")
    _add_json_option(demo)
    demo.set_defaults(run=_run_demo)

    export = commands.add_parser(
        "export",
        help="write the URDF, MJCF and link meshes",
        description="Write the robot files of a design: DIR/spm.urdf (open tree), "
        "DIR/spm.xml (MJCF with the loop-closing welds) and DIR/meshes/<link>.stl.",
    )
    export.add_argument(
        "--out", metavar="DIR", default="urdf", help="output directory (default: ./urdf)"
    )
    _add_json_option(export)
    _add_design_option(export)
    export.set_defaults(run=_run_export)

    show = commands.add_parser(
        "show",
        help="show the robot at input angles (live viewer or HTML file)",
        description="Show the robot at input angles T1 T2 T3 [deg] with meshcat, colliding "
        "links in black: in a live viewer (open the printed url; Ctrl-C stops it) or, with "
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
    _add_view_options(show)
    _add_json_option(show)
    _add_design_option(show)
    show.set_defaults(run=_run_show)

    from ..demo import DEMO_SAMPLES  # here: spm_pin.demo imports this module

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

    _add_calibration_parsers(commands)
    _add_torques_parser(commands)
    _add_collision_parsers(commands)

    # spm servo ...: defined with the hardware layer (its SDK is imported only when run).
    from .servo import add_servo_parser

    add_servo_parser(commands)
    return parser


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _subcommands(parser: argparse.ArgumentParser) -> list[str]:
    """The names of the parser's subcommands."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return list(action.choices)
    return []


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``spm`` with ``argv`` (default: ``sys.argv[1:]``); return the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(None if argv is None else list(argv))
        if args.command is None:
            commands = ", ".join(sorted(_subcommands(parser)))
            raise _UsageError(f"a command is required: one of {commands} (see spm --help)")
        status: int = args.run(args)
        return status
    except SystemExit as exc:  # --help and --version
        return exc.code if isinstance(exc.code, int) else 0
    except BrokenPipeError:  # the reader went away (spm demo | head): stop quietly
        with contextlib.suppress(OSError, ValueError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except (_UsageError, SPMError, OSError) as exc:
        message = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        if isinstance(exc, OSError) and exc.filename is not None:
            message = f"{exc.filename}: {message}"
        print(f"spm: error: {_one_line(message)}", file=sys.stderr)
        return EXIT_USAGE
