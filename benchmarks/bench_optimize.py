"""Optimization benchmark: one score of a design's safe orientation workspace.

Run from the repository root::

    python -m benchmarks.bench_optimize [--out FILE.json] [--quick]

It prints a short table and writes JSON (default ``benchmarks/results/optimize.json``).
Importing this module limits numpy to one thread (see ``_common.limit_to_one_thread``).

What is measured (2-degree grid of the gap plane, margin 0, dexterity >= 0.2: the
defaults of ``spm workspace``):

1. ``score``: :func:`spm_pin.optimize.safe_workspace_score` of the prototype, its
   collision model already built (repeated scores of one design);
2. ``score_new_design``: the same score of a design seen for the first time (a copy
   of the prototype under a new name each call), its collision model built in the
   call: the cost of one design of a study;
3. ``peer``: :func:`spm_pin.workspace.workspace_map` at the same settings without
   the clearance field, and ``peer_clearance`` with it (what ``spm workspace`` runs
   by default), warm;
4. ``targets``: the score's safe set and figures equal to the maps'
   (``equal_to_map``), and one score <= 0.5 s on one core (the median of ``score``;
   full runs only).
"""

from __future__ import annotations

import dataclasses
import itertools
import sys
from collections.abc import Sequence
from typing import Any

from ._common import limit_to_one_thread

#: Whether the one-thread limit was set before numpy was imported.
THREADS_LIMITED = limit_to_one_thread()

import numpy as np  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin.optimize import safe_workspace_score  # noqa: E402
from spm_pin.workspace import WorkspaceMap, WorkspaceSettings, workspace_map  # noqa: E402

from ._common import (  # noqa: E402
    format_rate,
    format_seconds,
    format_table,
    machine_info,
    run_main,
    standard_parser,
    target,
    time_call,
    with_all_pass,
)

#: The project's target for one score at 2 degrees [s].
TARGET_SCORE_S = 0.5
#: Grid step of the score and of the maps [deg].
STEP_DEG = 2.0
#: The figures compared with the map's summary.
FIGURES = ("safe_fraction", "max_safe_tilt_deg", "safe_tilt_every_direction_deg")


@dataclasses.dataclass(frozen=True)
class Sizes:
    """Repeat counts of one run."""

    scores: int
    new_designs: int
    maps: int


FULL = Sizes(scores=15, new_designs=5, maps=3)
QUICK = Sizes(scores=3, new_designs=2, maps=1)


def run(sizes: Sizes, *, quick: bool) -> dict[str, Any]:
    """Run every section and return the JSON payload."""
    design = spm.SPMDesign.prototype()
    results: dict[str, dict[str, Any]] = {}
    timed = time_call(lambda: safe_workspace_score(design, step_deg=STEP_DEG), repeats=sizes.scores)
    score = timed.value
    results["score"] = {
        **timed.timing.summary(),
        "points": score.points,
        "collision_checks": score.collision_checks,
        "figures": {key: getattr(score, key) for key in FIGURES},
    }
    names = (f"prototype-copy-{k}" for k in itertools.count())

    def new_design() -> Any:
        fresh = dataclasses.replace(design, name=next(names))
        return safe_workspace_score(fresh, step_deg=STEP_DEG)

    timed = time_call(new_design, repeats=sizes.new_designs)
    results["score_new_design"] = timed.timing.summary()
    peers: dict[str, dict[str, Any]] = {}
    for key, clearance in (("peer", False), ("peer_clearance", True)):
        settings = WorkspaceSettings(clearance=clearance)

        def full_map(settings: WorkspaceSettings = settings) -> WorkspaceMap:
            return workspace_map(design, step_deg=STEP_DEG, settings=settings, progress=False)

        timed_map = time_call(full_map, repeats=sizes.maps)
        summary = timed_map.value.summary()
        peers[key] = {
            **timed_map.timing.summary(),
            "method": f"spm_pin.workspace.workspace_map, clearance={clearance}, one process",
            "figures": {name: summary[name] for name in FIGURES},
            "safe_equal": bool(np.array_equal(timed_map.value["safe"], score.safe)),
        }
    peer = peers["peer"]
    peer["speed_ratio_ours_vs_peer"] = peer["median_s"] / results["score"]["median_s"]
    equal = all(
        p["safe_equal"] and p["figures"] == results["score"]["figures"] for p in peers.values()
    )
    targets: dict[str, Any] = {
        "equal_to_map": target(float(equal), 1.0, at_least=True, unit="fraction"),
    }
    if not quick:  # a few repeats say little about a time
        targets["score_2deg_s"] = target(
            results["score"]["median_s"], TARGET_SCORE_S, at_least=False, unit="s"
        )
    with_all_pass(targets)
    return {
        "benchmark": "optimize",
        "machine": machine_info(("numpy", "pin", "coal"), {"spm_pin": spm.__version__}),
        "config": {
            "quick": quick,
            "step_deg": STEP_DEG,
            "margin_m": score.margin,
            "min_dexterity": score.min_dexterity,
            "sizes": dataclasses.asdict(sizes),
            "threads_limited_before_numpy": THREADS_LIMITED,
            "timing": "perf_counter; 1 warm-up call; median/p95/p99 over repeated calls",
        },
        "results": results,
        "peer": peer,
        "peer_clearance": peers["peer_clearance"],
        "targets": targets,
    }


def report(payload: dict[str, Any]) -> str:
    """The human-readable summary of a run."""
    config, results = payload["config"], payload["results"]
    threads = "1 thread" if config["threads_limited_before_numpy"] else "threads not limited"
    head = f"spm-pin optimization benchmark: prototype, {config['step_deg']:g} deg, {threads}" + (
        ", QUICK" if config["quick"] else ""
    )
    rows = []
    for label, entry in (
        ("safe_workspace_score", results["score"]),
        ("safe_workspace_score, new design", results["score_new_design"]),
        ("peer: workspace_map, no clearance", payload["peer"]),
        ("peer: workspace_map, clearance", payload["peer_clearance"]),
    ):
        rows.append(
            [
                label,
                format_seconds(entry["median_s"]),
                format_seconds(entry["p95_s"]),
                format_rate(entry["per_second"]),
            ]
        )
    table = format_table(["case", "median", "p95", "scores/s"], rows)
    lines = ["Targets"]
    for name, record in payload["targets"].items():
        if name == "all_pass":
            continue
        lines.append(
            f"  {'PASS' if record['pass'] else 'FAIL'}  {name}: {record['value']:.4g} "
            f"({record['comparison']} {record['threshold']:g} {record['unit']})"
        )
    figures = results["score"]["figures"]
    notes = (
        f"figures: safe fraction {figures['safe_fraction']:.4f}, largest safe tilt "
        f"{figures['max_safe_tilt_deg']:.2f} deg, in every direction "
        f"{figures['safe_tilt_every_direction_deg']:.2f} deg; "
        f"{payload['peer']['speed_ratio_ours_vs_peer']:.1f}x faster than the map"
    )
    return "\n\n".join([head, table, notes, "\n".join(lines)])


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the summary, write the JSON; returns the exit code."""
    parser = standard_parser(
        "optimize",
        "One score of a design's safe orientation workspace beside a workspace map.",
        quick_help="few repeats (smoke test)",
    )
    return run_main(
        parser, lambda args: run(QUICK if args.quick else FULL, quick=args.quick), report, argv
    )


if __name__ == "__main__":
    sys.exit(main())
