"""``spm fk``, ``spm ik`` and ``spm design``: forward and inverse kinematics of one
input or orientation as records, and design files.

The records (:func:`fk_record`, :func:`ik_record`) are plain data: the text and JSON
output of the commands. :data:`FK_SOLVERS` names the forward-kinematics solvers that
``spm fk --solver`` offers.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

from .._records import FloatArray, Record, fk_all_record
from .._records import assembly_label as _assembly_label
from .._records import orientation as _orientation
from ..design import SPMDesign
from ..kinematics import (
    WORKING_MODE_LABELS,
    forward_kinematics,
    inverse_kinematics,
    jacobian,
)
from ..kinematics._common import as_rotation
from ..kinematics.fk import satisfies_home_rule
from ..rotations import (
    matrix_from_quaternion,
    matrix_from_rpy,
)
from ._options import UsageError as _UsageError
from ._options import add_angle_arguments as _add_angle_arguments
from ._options import add_design_option as _add_design_option
from ._options import add_json_option as _add_json_option
from ._options import design_of as _design
from ._options import emit as _emit
from ._options import mode as _mode
from ._options import number as _number

__all__ = ["FK_SOLVERS", "FKSolution", "add_parsers", "fk_record", "ik_record"]


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


# ---------------------------------------------------------------------------- parsers
def add_parsers(commands: Any) -> None:
    """``spm fk``, ``spm ik`` and ``spm design``."""
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
