"""``spm collide``: self-collision of the links at one input, whichever assembly mode
exists, as a record (:func:`collide_record`)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._records import Record
from .._records import checked_links as _checked_links
from ..design import SPMDesign
from ._options import add_angle_arguments as _add_angle_arguments
from ._options import add_design_option as _add_design_option
from ._options import add_json_option as _add_json_option
from ._options import add_margin_option as _add_margin_option
from ._options import design_of as _design
from ._options import emit as _emit

__all__ = ["add_parser", "collide_record"]


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


def add_parser(commands: Any) -> None:
    """``spm collide``."""
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
