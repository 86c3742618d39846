"""Options and helpers that every command group of ``spm`` shares: the parser that
raises instead of exiting, number and angle arguments [deg], ``--design``,
``--json``, the motion, noise and margin options, and printing a record."""

from __future__ import annotations

import argparse
import math
import re
from typing import Any, NoReturn

from .._records import Record, dumps, plain, render
from ..design import SPMDesign
from ..kinematics._common import ANGLE_LIMIT

__all__ = [
    "ANGLE_LIMIT_DEG",
    "EXIT_INTERRUPTED",
    "EXIT_OVER_LIMITS",
    "EXIT_USAGE",
    "NEGATIVE_ARGUMENT",
    "Parser",
    "UsageError",
    "add_angle_arguments",
    "add_design_option",
    "add_json_option",
    "add_kind_option",
    "add_margin_option",
    "add_motion_options",
    "add_noise_option",
    "angle_deg",
    "design_of",
    "emit",
    "mode",
    "number",
    "one_line",
]


#: Exit status for bad arguments and library errors.
EXIT_USAGE = 2
#: Exit status of ``spm torques`` when the motion exceeds the servos' torque-speed
#: envelope (the report is printed all the same).
EXIT_OVER_LIMITS = 1
#: Exit status after Ctrl-C (128 + SIGINT, as a shell reports it).
EXIT_INTERRUPTED = 130

#: Numbers that argparse must treat as positionals, not options: negative decimals
#: with exponents, -inf/-nan (rejected later with a clear message), working-mode
#: labels such as ``-+-`` and assembly-mode labels such as ``-+-/+``.
NEGATIVE_ARGUMENT = re.compile(
    r"^-(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$|^-(inf|infinity|nan)$|^-[+-]{2}(/[+-])?$",
    re.IGNORECASE,
)


class UsageError(Exception):
    """A bad command line (reported on one line, exit status 2)."""


class Parser(argparse.ArgumentParser):
    """ArgumentParser that raises on errors instead of printing usage and exiting."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # argparse's own pattern misses "-1e-3" and "-+-"; without this they would be
        # taken for unknown options.
        self._negative_number_matcher = NEGATIVE_ARGUMENT

    def error(self, message: str) -> NoReturn:
        raise UsageError(message)


# ----------------------------------------------------------------------- arguments
def number(text: str) -> float:
    """A finite number from the command line (argparse ``type``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not allowed: numbers must be finite")
    return value


#: Largest |input angle| on the command line [deg]: the library's ANGLE_LIMIT.
ANGLE_LIMIT_DEG = math.degrees(ANGLE_LIMIT)


def angle_deg(text: str) -> float:
    """An input angle [deg] from the command line (argparse ``type``): finite and within
    the library's range, said in degrees."""
    value = number(text)
    if abs(value) > ANGLE_LIMIT_DEG:
        raise argparse.ArgumentTypeError(
            f"{text!r} is out of range: input angles must lie within +-{ANGLE_LIMIT_DEG:,.0f} "
            f"deg ({ANGLE_LIMIT:g} rad, {ANGLE_LIMIT / (2 * math.pi):.0f} turns), where "
            "double precision keeps the kinematics within their 1e-12 tolerance"
        )
    return value


def mode(text: str) -> int | str:
    """A working mode: an index 0..7 or a label such as ``+-+`` (checked by the library)."""
    return int(text) if text.isdigit() else text


def design_of(args: argparse.Namespace) -> SPMDesign:
    """The design named by ``--design NAME|FILE`` or ``--preset`` (default: the prototype).

    ``--design`` takes a preset name or a design file (:meth:`SPMDesign.from_spec`: a
    bare preset name is the preset even if a file of that name exists; ``./NAME`` is
    the file).
    """
    spec: str | None = getattr(args, "design", None)
    if spec is not None:
        return SPMDesign.from_spec(spec)
    return SPMDesign.preset(getattr(args, "preset", None) or "prototype")


def add_angle_arguments(parser: argparse.ArgumentParser) -> None:
    """The positionals T1 T2 T3: input angles [deg]."""
    for i in (1, 2, 3):
        parser.add_argument(f"T{i}", type=angle_deg, help=f"input angle theta_{i} [deg]")


def add_design_option(parser: argparse._ActionsContainer) -> None:
    parser.add_argument(
        "--design",
        metavar="NAME|FILE",
        help=f"a preset ({', '.join(SPMDesign.preset_names())}) or a design TOML file "
        "(default: the prototype; see 'spm design')",
    )


def add_motion_options(parser: argparse.ArgumentParser, *, to_required: bool) -> None:
    """--from and --to: the input angles [deg] at the start and the end of a motion."""
    parser.add_argument(
        "--from",
        dest="from_deg",
        nargs=3,
        type=angle_deg,
        default=[0.0, 0.0, 0.0],
        metavar=("T1", "T2", "T3"),
        help="input angles at the start [deg] (default: 0 0 0)",
    )
    parser.add_argument(
        "--to",
        dest="to_deg",
        nargs=3,
        type=angle_deg,
        required=to_required,
        metavar=("T1", "T2", "T3"),
        help="input angles at the end [deg]",
    )


def add_json_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")


def add_kind_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--kind",
        choices=["quaternion", "axes"],
        default="quaternion",
        help="what the sensor measures (default: quaternion)",
    )


def add_noise_option(parser: argparse.ArgumentParser, text: str) -> None:
    parser.add_argument("--noise-deg", type=number, default=0.5, metavar="D", help=text)


def add_margin_option(parser: argparse.ArgumentParser, text: str) -> None:
    parser.add_argument("--margin-mm", type=number, default=0.0, metavar="MM", help=text)


def emit(record: Record, as_json: bool) -> None:
    text = dumps(record) if as_json else "\n".join(render(plain(record)))
    print(text)


def one_line(text: str) -> str:
    """``text`` on one line: runs of white space (newlines too) become one space."""
    return " ".join(str(text).split())
