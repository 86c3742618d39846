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
    spm optimize --objectives NAME ... (--vary NAME=LOW:HIGH ... | --space FILE)
                 [--trials N] [--seed S] [--storage FILE] [--workers N | --scheduler ADDRESS]
                 [--out DIR [--best N]] [--json] [--design NAME|FILE]
    spm serve [--host 127.0.0.1] [--port 8750] [--sim kinematic] [--design NAME|FILE]
              [--token-file FILE]

Every bad argument and every :class:`~spm_pin.SPMError` raised by the library is
reported as one line ``spm: error: ...`` on stderr with exit status 2 (so is an
orientation that ``spm ik`` cannot reach, naming every leg that cannot close).
``spm torques`` exits with status 1 when the motion exceeds the servos'
torque-speed envelope (its report is printed all the same), ``spm demo`` when its
cross-checks disagree, ``spm calibrate`` when the readings cannot identify the
parameters. Lists of results (``--all``) are numbered from 0 in text as in JSON, the
numbers that ``--mode INDEX`` takes.

This package holds the parser and :func:`main`; each command group is a module of its
own, beside the options they share (``_options``): ``kinematics`` (fk, ik, design),
``study`` (demo), ``model`` (export), ``view`` (show, animate), ``calibration``
(calibrate, plan-poses, synth-readings), ``dynamics`` (torques), ``collision``
(collide), ``workspace``, ``remote`` (serve) and ``servo``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from collections.abc import Sequence

from .._records import fk_all_record
from .._version import __version__
from ..errors import SPMError
from . import (
    calibration,
    collision,
    dynamics,
    kinematics,
    model,
    optimize,
    plan,
    remote,
    study,
    view,
    workspace,
)
from ._options import EXIT_INTERRUPTED, EXIT_OVER_LIMITS, EXIT_USAGE
from ._options import Parser as _Parser
from ._options import UsageError as _UsageError
from ._options import one_line as _one_line
from .calibration import EXIT_NOT_IDENTIFIED
from .collision import collide_record
from .kinematics import FK_SOLVERS, FKSolution, fk_record, ik_record

__all__ = [
    "EXIT_NOT_IDENTIFIED",
    "EXIT_OVER_LIMITS",
    "FK_SOLVERS",
    "FKSolution",
    "build_parser",
    "collide_record",
    "fk_all_record",
    "fk_record",
    "ik_record",
    "main",
]


# ---------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``spm`` (errors raise instead of exiting)."""
    parser = _Parser(
        prog="spm",
        description="Kinematics of spherical parallel manipulators (angles in degrees).",
    )
    parser.add_argument("--version", action="version", version=f"spm-pin {__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    kinematics.add_parsers(commands)  # fk, ik, design
    study.add_parser(commands)  # demo
    model.add_parser(commands)  # export
    view.add_parsers(commands)  # show, animate
    calibration.add_parsers(commands)  # calibrate, plan-poses, synth-readings
    dynamics.add_parser(commands)  # torques
    collision.add_parser(commands)  # collide
    workspace.add_parser(commands)  # workspace
    optimize.add_parser(commands)  # optimize
    plan.add_parser(commands)  # plan
    remote.add_parser(commands)  # serve

    # spm servo ...: defined with the hardware layer (its SDK is imported only when run).
    from .servo import add_servo_parser

    add_servo_parser(commands)
    return parser


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
    except KeyboardInterrupt:  # Ctrl-C: a line, not a traceback
        print("spm: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
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
