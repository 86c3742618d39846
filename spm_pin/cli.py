"""The ``spm`` command: kinematics of spherical parallel manipulators from the shell.

Angles are degrees on the command line and radians inside. Every command prints
human-readable text by default and JSON with ``--json`` (vectors as lists, ``null``
where a value does not exist; NaN is never emitted).

Commands::

    spm fk T1 T2 T3 [--all] [--json] [--design FILE] [--solver analytic]
    spm ik (--matrix R11 .. R33 | --quaternion W X Y Z | --rpy ROLL PITCH YAW)
           [--mode LABEL|INDEX] [--all] [--json] [--design FILE]
    spm design [--preset NAME | --design FILE] [--out FILE]
    spm demo [--out DIR] [--json]
    spm export [--design FILE] [--out DIR] [--json]

Every bad argument and every :class:`~spm_pin.SPMError` raised by the library is
reported as one line ``spm: error: ...`` on stderr with exit status 2.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import functools
import json
import math
import os
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
import numpy.typing as npt

from ._version import __version__
from .design import SPMDesign
from .errors import SPMError
from .kinematics import (
    WORKING_MODE_LABELS,
    FKResult,
    forward_kinematics,
    forward_kinematics_all,
    inverse_kinematics,
    jacobian,
    track,
)
from .kinematics._common import as_rotation, mode_label
from .kinematics.fk import satisfies_home_rule
from .rotations import (
    matrix_from_quaternion,
    matrix_from_rpy,
    quaternion_from_matrix,
    rpy_from_matrix,
)

__all__ = [
    "DEMO_SECTIONS",
    "FK_SOLVERS",
    "DemoContext",
    "DemoSection",
    "FKSolution",
    "build_parser",
    "demo_record",
    "fk_all_record",
    "fk_record",
    "ik_record",
    "main",
]

FloatArray = npt.NDArray[np.float64]
Record = dict[str, Any]

#: Exit status for bad arguments and library errors.
EXIT_USAGE = 2

#: Numbers that argparse must treat as positionals, not options: negative decimals
#: with exponents, -inf/-nan (rejected later with a clear message) and working-mode
#: labels such as ``-+-``.
_NEGATIVE_ARGUMENT = re.compile(
    r"^-(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$|^-(inf|infinity|nan)$|^-[+-]{2}$", re.IGNORECASE
)


class _UsageError(Exception):
    """A bad command line (reported on one line, exit status 2)."""


class _Parser(argparse.ArgumentParser):
    """ArgumentParser that raises on errors instead of printing usage and exiting."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # argparse's own pattern misses "-1e-3" and "-+-"; without this they would be
        # taken for unknown options.
        self._negative_number_matcher = _NEGATIVE_ARGUMENT

    def error(self, message: str) -> NoReturn:
        raise _UsageError(message)


# ----------------------------------------------------------------------- arguments
def _number(text: str) -> float:
    """A finite number from the command line (argparse ``type``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not allowed: numbers must be finite")
    return value


def _mode(text: str) -> int | str:
    """A working mode: an index 0..7 or a label such as ``+-+`` (checked by the library)."""
    return int(text) if text.isdigit() else text


def _design(args: argparse.Namespace) -> SPMDesign:
    """The design named by ``--design FILE`` or ``--preset`` (default: the prototype)."""
    path: str | None = getattr(args, "design", None)
    if path is not None:
        return SPMDesign.load(path)
    return SPMDesign.preset(getattr(args, "preset", None) or "prototype")


def _add_design_option(parser: argparse._ActionsContainer) -> None:
    parser.add_argument(
        "--design",
        metavar="FILE",
        help="design TOML file (default: the prototype; see 'spm design')",
    )


def _add_json_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")


# ----------------------------------------------------------------------- JSON/text
def _plain(value: Any) -> Any:
    """Lists, floats, ints, bools, strings and None (for NaN/inf) from numpy data."""
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        number = float(value) + 0.0  # + 0.0 turns -0.0 into 0.0
        return number if math.isfinite(number) else None
    return value


def _dumps(record: Record) -> str:
    return json.dumps(_plain(record), indent=2, allow_nan=False)


_NUMBER_WIDTH = 12


def _format_number(key: str, value: float) -> str:
    if any(word in key for word in ("residual", "error", "deviation")):
        return f"{value:{_NUMBER_WIDTH}.3e}"
    return f"{round(value, 6) + 0.0:{_NUMBER_WIDTH}.6f}"


def _format_scalar(key: str, value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return _format_number(key, value)
    return str(value)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _render(record: Record, indent: str = "") -> list[str]:
    """Text lines for a plain record: ``key  value``, numbers aligned with 6 decimals.

    Keys whose value is None (``null`` in JSON) are left out.
    """
    record = {key: value for key, value in record.items() if value is not None}
    width = max((len(key) for key in record), default=0) + 2
    lines: list[str] = []
    for key, value in record.items():
        head = f"{indent}{key:<{width}}"
        if isinstance(value, dict):
            lines.append(f"{indent}{key}:")
            lines.extend(_render(value, indent + "  "))
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for number, item in enumerate(value, start=1):
                lines.append(f"{indent}{key} {number}:")
                lines.extend(_render(item, indent + "  "))
        elif isinstance(value, list) and value and all(isinstance(v, list) for v in value):
            for number, row in enumerate(value):
                prefix = head if number == 0 else " " * len(head)
                lines.append(prefix + _render_row(key, row))
        elif isinstance(value, list):
            lines.append(head + (_render_row(key, value) if value else "none"))
        else:
            lines.append(head + _format_scalar(key, value))
    return lines


def _render_row(key: str, row: list[Any]) -> str:
    if all(_is_number(v) for v in row):
        return "".join(_format_number(key, float(v)) for v in row)
    return "  ".join("null" if v is None else _format_scalar(key, v) for v in row)


def _emit(record: Record, as_json: bool) -> None:
    text = _dumps(record) if as_json else "\n".join(_render(_plain(record)))
    print(text)


# ---------------------------------------------------------------- orientation data
def _orientation(R: FloatArray) -> Record:
    """R, roll/pitch/yaw [deg] and the quaternion (w, x, y, z) of a rotation."""
    return {
        "R": R,
        "rpy_deg": np.degrees(rpy_from_matrix(R)),
        "quaternion_wxyz": quaternion_from_matrix(R),
    }


def _assembly_label(b: FloatArray, det_a: float) -> str:
    """Assembly-mode label such as ``+++/-``: signs of b_11, b_22, b_33 and det A."""
    return mode_label(b) + ("/+" if det_a > 0 else "/-")


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


#: Forward-kinematics solvers selectable with ``spm fk --solver NAME``. Every solver
#: yields the same output keys; everything but R and the residual is derived from R.
FK_SOLVERS: dict[str, Callable[[FloatArray, SPMDesign], FKSolution]] = {
    "analytic": _fk_analytic,
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


def fk_all_record(theta_deg: Sequence[float], design: SPMDesign) -> Record:
    """Every real assembly mode of one input [deg], as a record."""
    modes = forward_kinematics_all(np.radians(np.asarray(theta_deg, dtype=float)), design)
    count = int(modes.count)
    labels = modes.labels
    return {
        "design": design.name,
        "theta_deg": list(theta_deg),
        "reachable": bool(np.any(modes.home)),
        "count": count,
        "modes": [
            {
                "label": labels[k],
                "home": modes.home[k],
                "R": modes.R[k],
                "v": modes.v[k],
                "b": modes.b[k],
                "det_a": modes.det_a[k],
                "residual": modes.residual[k],
            }
            for k in range(count)
        ],
    }


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
    leg_reachable = results[0].leg_reachable[0]  # the same in every working mode
    reachable = bool(np.all(leg_reachable))
    solutions = [
        {
            "theta_deg": np.degrees(ik.theta[0]) if reachable else None,
            "mode": ik.mode,
            "home": ik.mode == WORKING_MODE_LABELS[0],
            "b": ik.b[0] if reachable else None,
        }
        for ik in results
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
    record["failing_leg"] = None if reachable else int(np.argmin(leg_reachable)) + 1
    record.update(_orientation(R))
    return record


def _run_ik(args: argparse.Namespace) -> int:
    design = _design(args)
    R = _target_rotation(args)
    _emit(ik_record(R, design, args.mode, all_modes=args.all), args.json)
    return 0


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
#: The published study's demonstration input and its colliding input [deg].
DEMO_THETA_DEG = (60.0, 90.0, 120.0)
DEMO_COLLIDING_THETA_DEG = (60.0, 90.0, 220.0)
#: Samples of the motion from home to the demonstration input.
DEMO_SAMPLES = 25
#: Samples whose platform axes the text output shows.
_DEMO_SHOWN_SAMPLES = (0, 6, 12, 18, 24)


@dataclasses.dataclass(frozen=True)
class DemoContext:
    """What every demo section works from; the defaults are the published study."""

    design: SPMDesign = dataclasses.field(default_factory=SPMDesign.prototype)
    theta_deg: tuple[float, float, float] = DEMO_THETA_DEG
    colliding_theta_deg: tuple[float, float, float] = DEMO_COLLIDING_THETA_DEG
    samples: int = DEMO_SAMPLES

    @property
    def theta(self) -> FloatArray:
        """The demonstration input [rad]."""
        return np.radians(self.theta_deg)

    @property
    def colliding_theta(self) -> FloatArray:
        """The study's colliding input [rad]."""
        return np.radians(self.colliding_theta_deg)

    @functools.cached_property
    def home(self) -> FKResult:
        """The home assembly mode at the demonstration input (solved once)."""
        return forward_kinematics(self.theta, self.design)


@dataclasses.dataclass(frozen=True)
class DemoSection:
    """One section of the demo: its JSON key, a title, the data and (optionally) a
    shorter view of it for the text output."""

    key: str
    title: str
    data: Record
    text: Record | None = None


def _demo_design(ctx: DemoContext) -> DemoSection:
    d = ctx.design
    data = {
        "name": d.name,
        "summary": d.summary(),
        "alpha1_deg": math.degrees(d.alpha1),
        "alpha2_deg": math.degrees(d.alpha2),
        "beta_deg": math.degrees(d.beta),
        "eta_deg": np.degrees(d.eta),
        "coaxial": d.is_coaxial,
    }
    return DemoSection("design", "Design", data)


def _demo_assembly_modes(ctx: DemoContext) -> DemoSection:
    modes = forward_kinematics_all(ctx.theta, ctx.design)
    count = int(modes.count)
    labels = modes.labels
    data = {
        "theta_deg": ctx.theta_deg,
        "count": count,
        "modes": [
            {
                "label": labels[k],
                "home": modes.home[k],
                "residual": modes.residual[k],
                "v": modes.v[k],
            }
            for k in range(count)
        ],
    }
    return DemoSection("assembly_modes", "Every real assembly mode", data)


def _demo_home_mode(ctx: DemoContext) -> DemoSection:
    fk = ctx.home
    data = {
        "theta_deg": ctx.theta_deg,
        "reachable": fk.reachable,
        **_orientation(fk.R),
        "v": fk.v,
        "residual": fk.residual,
    }
    return DemoSection("home_mode", "The home assembly mode", data)


def _demo_velocity(ctx: DemoContext) -> DemoSection:
    jac = jacobian(ctx.theta, ctx.design, R=ctx.home.R)
    data = {
        "J": jac.J,
        "det_a": jac.det_a,
        "b": jac.b,
        "dexterity": jac.dexterity,
        "dexterity_ga": jac.dexterity_ga,
        "singularity_margin": jac.singularity_margin,
        "type_i_singular": jac.type_i,
        "type_ii_singular": jac.type_ii,
    }
    return DemoSection("velocity", "Velocity kinematics: omega = J theta_dot", data)


def _demo_inverse(ctx: DemoContext) -> DemoSection:
    ik = inverse_kinematics(ctx.home.R, ctx.design)
    error = np.degrees(np.max(np.abs(ik.theta - ctx.theta)))
    data = {
        "theta_deg": np.degrees(ik.theta),
        "mode": ik.mode,
        "b": ik.b,
        "round_trip_error_deg": error,
    }
    return DemoSection("inverse", "Inverse kinematics of the home R", data)


def _demo_motion(ctx: DemoContext) -> DemoSection:
    path_deg = np.linspace(0.0, 1.0, ctx.samples)[:, None] * np.asarray(ctx.theta_deg)
    path = np.radians(path_deg)
    motion = track(path, ctx.design)
    # Independent check: the home mode solved at every sample on its own.
    home = forward_kinematics(path, ctx.design)
    deviation = np.max(np.abs(motion.R - home.R))
    samples = [
        {
            "theta_deg": path_deg[i],
            "label": motion.labels[i],
            "home": motion.home[i],
            "v": motion.v[i],
        }
        for i in range(ctx.samples)
    ]
    summary = {
        "samples": ctx.samples,
        "all_home": bool(np.all(motion.home)),
        "lost": bool(np.any(motion.lost)),
        "subdivisions": motion.subdivisions,
        "deviation_from_fk": deviation,
    }
    shown = [i for i in _DEMO_SHOWN_SAMPLES if i < ctx.samples]
    text = {
        **summary,
        "shown": [{"sample": i, **samples[i]} for i in shown],
    }
    return DemoSection(
        "motion",
        f"Tracked motion from home to the input, {ctx.samples} samples",
        {**summary, "path": samples},
        text,
    )


def _demo_colliding_input(ctx: DemoContext) -> DemoSection:
    modes = forward_kinematics_all(ctx.colliding_theta, ctx.design)
    count = int(modes.count)
    data = {
        "theta_deg": ctx.colliding_theta_deg,
        "home_mode_exists": bool(np.any(modes.home)),
        "count": count,
        "labels": modes.labels[:count],
    }
    return DemoSection("colliding_input", "The study's colliding input", data)


#: The demo's sections, in order. A feature adds its section by appending a function
#: ``DemoContext -> DemoSection`` here.
DEMO_SECTIONS: list[Callable[[DemoContext], DemoSection]] = [
    _demo_design,
    _demo_assembly_modes,
    _demo_home_mode,
    _demo_velocity,
    _demo_inverse,
    _demo_motion,
    _demo_colliding_input,
]


def demo_record(ctx: DemoContext | None = None) -> tuple[Record, list[str]]:
    """The kinematic study of the prototype: its JSON record and its text lines."""
    if ctx is None:
        ctx = DemoContext()
    record: Record = {"theta_deg": ctx.theta_deg}
    where = ", ".join(f"{x:g}" for x in ctx.theta_deg)
    lines = [f"spm-pin {__version__}: kinematic study of the {ctx.design.name} at [{where}] deg"]
    for make_section in DEMO_SECTIONS:
        section = make_section(ctx)
        record[section.key] = section.data
        lines += ["", f"== {section.title} ==", *_render(_plain(section.text or section.data))]
    return _plain(record), lines


def _run_demo(args: argparse.Namespace) -> int:
    record, lines = demo_record()
    written: Path | None = None
    if args.out is not None:
        directory = Path(args.out)
        directory.mkdir(parents=True, exist_ok=True)
        written = directory / "demo.json"
        written.write_text(_dumps(record) + "\n", encoding="utf-8")
    if args.json:
        print(_dumps(record))
    else:
        print("\n".join(lines))
        if written is not None:
            print(f"\nwrote {written}")
    return 0


# ---------------------------------------------------------------------------- export
def _run_export(args: argparse.Namespace) -> int:
    design = _design(args)
    # Imported here: the model layer (trimesh) is not needed by the other commands.
    from .model.export import export

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
    for i in (1, 2, 3):
        fk.add_argument(f"T{i}", type=_number, help=f"input angle theta_{i} [deg]")
    fk.add_argument("--all", action="store_true", help="every real assembly mode")
    fk.add_argument(
        "--solver",
        choices=sorted(FK_SOLVERS),
        default="analytic",
        help="solver of the home assembly mode (default: analytic; --all is always analytic)",
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
        help="the kinematic study of the prototype",
        description="The kinematic study of the prototype at theta = [60, 90, 120] deg.",
    )
    demo.add_argument("--out", metavar="DIR", help="also write DIR/demo.json")
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
    return parser


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``spm`` with ``argv`` (default: ``sys.argv[1:]``); return the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(None if argv is None else list(argv))
        if args.command is None:
            raise _UsageError(
                "a command is required: fk, ik, design, export or demo (see spm --help)"
            )
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
