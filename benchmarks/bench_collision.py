"""Self-collision benchmark: one full pairwise check, distances, a workspace map.

Run from the repository root::

    python -m benchmarks.bench_collision [--out FILE.json] [--quick] [--workers N]

It prints a short table and writes JSON (default ``benchmarks/results/collision.json``).
One core for the per-call timings (thread variables set before numpy is imported, see
``_common``); the map uses ``--workers`` processes (default 2).

What is measured (seeded inputs; the same configurations for every method):

1. ``check_random``: ``robot.collision_checker.collisions(q)``, one call per
   configuration, over random inputs uniform in [-pi, pi]^3 that have a home-mode
   assembly (most of them collide somewhere); ``check_free`` / ``check_colliding``:
   the same calls split by outcome; ``check_path``: the same along a smooth motion
   (a command stream: each configuration close to the last); ``check_theta``:
   ``robot.collisions(theta)``, which also solves the configuration.
2. ``peer_bvh``: what plain Pinocchio does with the same shapes: one triangle-mesh BVH
   per link (``robot.collision_model``, coal OBBRSS), the 19 link pairs registered,
   ``pin.computeCollisions`` and the results read back.
3. ``fidelity``: the same drawn geometry in two exact forms, side by side: ``convex``
   (every convex piece of :func:`spm_pin.collision.convex_pieces`, every piece pair
   that the rotation-invariant bounds keep, ``pin.computeCollisions``) and ``bvh``
   (the peer), and the library's hybrid (certified tables, probes, culling BVHs) with
   probes off; the answers of every method are compared (pairs at a distance below
   1e-9 m are contacts that may go either way).
4. ``distances``: ``robot.distances(q)``, exact distances of all 19 pairs.
5. ``map``: a gap map (FK + dexterity + collision, no clearance) at 1 deg, with
   ``--workers`` processes (start-up included) and in this process.

Targets: one full check <= 20 us median (random reachable inputs); the 1-degree map
<= 10 s with 2 workers.

Where the time goes (see :mod:`spm_pin.collision`): table lookups in Python floats
settle most link pairs (about 3 us for the ten tables of the prototype); the probes
and culling BVHs of the rest take two Pinocchio calls. Inputs where links collide
cost little more than free ones, because the tables certify most collisions; the
tail (p95) comes from BVH traversals where two links pass within a few millimetres
of each other or touch where no probe looks. ``check_theta`` is dominated by the
forward kinematics of one input (``spm_pin.forward_kinematics``, about 120 us, and
about 1 ms for the few inputs that its float fast path leaves to the batch solver).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from collections.abc import Sequence
from typing import Any

from ._common import limit_to_one_thread

#: Whether the one-thread limit was set before numpy was imported.
THREADS_LIMITED = limit_to_one_thread()

import numpy as np  # noqa: E402
import numpy.typing as npt  # noqa: E402
import pinocchio as pin  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin.collision import LINK_PAIRS, CollisionChecker, checker_of  # noqa: E402
from spm_pin.workspace import WorkspaceSettings, workspace_map  # noqa: E402

from ._common import (  # noqa: E402
    Timing,
    format_count,
    format_seconds,
    format_table,
    machine_info,
    run_main,
    standard_parser,
    target,
    time_each,
    with_all_pass,
)

FloatArray = npt.NDArray[np.float64]

#: Seed of every random input of this benchmark.
SEED = 20_240_612
#: Pairs nearer than this [m] are contacts whose answer may go either way.
TIE_DISTANCE = 1e-9

#: The project's targets.
TARGET_CHECK_MEDIAN_S = 20e-6
TARGET_MAP_S = 10.0
TARGET_MAP_STEP_DEG = 1.0


@dataclasses.dataclass(frozen=True)
class Sizes:
    """Problem sizes of one run."""

    checks: int  # configurations timed with the library's check
    peer: int  # of them, timed with the BVH peer
    convex: int  # of them, timed with the convex-piece brute force
    distances: int
    map_step_deg: float
    repeats: int  # calls per configuration (the fastest is kept: noise on a shared machine)


FULL = Sizes(checks=2_000, peer=300, convex=100, distances=100, map_step_deg=1.0, repeats=5)
QUICK = Sizes(checks=60, peer=12, convex=6, distances=4, map_step_deg=15.0, repeats=1)


# ------------------------------------------------------------------------- inputs
def reachable_inputs(design: spm.SPMDesign, n: int, rng: np.random.Generator) -> FloatArray:
    """``n`` inputs uniform in [-pi, pi]^3 that have a home-mode assembly [rad]."""
    kept: list[FloatArray] = []
    have = 0
    while have < n:
        chunk = rng.uniform(-math.pi, math.pi, size=(max(2 * (n - have), 1_000), 3))
        good = chunk[spm.forward_kinematics(chunk, design).reachable]
        kept.append(good)
        have += good.shape[0]
    return np.concatenate(kept)[:n]


def smooth_path(design: spm.SPMDesign, n: int) -> FloatArray:
    """q along theta(t) = [60, 90, 120] deg sin(pi t) + [10, -20, 30] deg sin(3 pi t),
    t in [0, 1], n samples (a stream of commands: each close to the last)."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    theta = np.radians([60.0, 90.0, 120.0]) * np.sin(np.pi * t) + np.radians(
        [10.0, -20.0, 30.0]
    ) * np.sin(3.0 * np.pi * t)
    theta = theta[spm.forward_kinematics(theta, design).reachable]
    q: FloatArray = spm.build_robot(design).configuration(theta)
    return q


# ------------------------------------------------------------------------- methods
class PeerBVH:
    """Plain Pinocchio: one BVH per link (the robot's collision model), 19 pairs."""

    def __init__(self, robot: spm.SPMRobot) -> None:
        self.model = robot.model
        self.data = robot.model.createData()
        gm = pin.GeometryModel()
        for geometry in robot.collision_model.geometryObjects:
            gm.addGeometryObject(geometry)
        for a, b in LINK_PAIRS:
            gm.addCollisionPair(pin.CollisionPair(gm.getGeometryId(a), gm.getGeometryId(b)))
        self.geometry_model = gm
        self.geometry_data = pin.GeometryData(gm)
        self.results = [self.geometry_data.collisionResults[k] for k in range(len(LINK_PAIRS))]

    def __call__(self, q: FloatArray) -> list[tuple[str, str]]:
        pin.computeCollisions(
            self.model, self.data, self.geometry_model, self.geometry_data, q, False
        )
        return [pair for pair, r in zip(LINK_PAIRS, self.results, strict=True) if r.isCollision()]


class ConvexPieces:
    """Every convex piece as a geometry object; every piece pair that the library's
    rotation-invariant bounds keep at margin 0 (exact, no BVH)."""

    def __init__(self, checker: CollisionChecker) -> None:
        robot = checker.robot
        self.model = robot.model
        self.data = robot.model.createData()
        gm = pin.GeometryModel()
        for k, piece in enumerate(checker._pieces):
            frame = robot.link_frames[spm.model.LINK_NAMES[piece.link]]
            geometry = pin.GeometryObject(
                f"piece{k}",
                robot.model.frames[frame].parentJoint,
                frame,
                pin.SE3.Identity(),
                piece.shape,
            )
            gm.addGeometryObject(geometry)
        owners: list[tuple[str, str]] = []
        for geometry in checker._all:
            near = geometry.static_bound <= 0.0
            for i, j in zip(geometry.a[near], geometry.b[near], strict=True):
                gm.addCollisionPair(pin.CollisionPair(int(i), int(j)))
                owners.append(geometry.pair)
        self.geometry_model = gm
        self.geometry_data = pin.GeometryData(gm)
        for request in self.geometry_data.collisionRequests:
            request.break_distance = 0.0
            request.epa_max_iterations = 0
        self.results = [self.geometry_data.collisionResults[k] for k in range(len(owners))]
        self.owners = owners

    @property
    def pairs(self) -> int:
        return len(self.owners)

    def __call__(self, q: FloatArray) -> list[tuple[str, str]]:
        pin.computeCollisions(
            self.model, self.data, self.geometry_model, self.geometry_data, q, False
        )
        hits = {
            owner for owner, r in zip(self.owners, self.results, strict=True) if r.isCollision()
        }
        return [pair for pair in LINK_PAIRS if pair in hits]


# ------------------------------------------------------------------------- timing
def fastest_each(fn: Any, items: Sequence[Any], repeats: int) -> tuple[Timing, list[Any]]:
    """Per-item latency: the fastest of ``repeats`` calls per item (a shared machine
    adds delays; the fastest call is the one least disturbed)."""
    best: list[float] | None = None
    values: list[Any] = []
    for _ in range(repeats):
        timing, values = time_each(fn, items)
        samples = list(timing.samples)
        best = samples if best is None else [min(a, b) for a, b in zip(best, samples, strict=True)]
    assert best is not None
    return Timing(tuple(best)), values


def entry(timing: Timing, **extra: Any) -> dict[str, Any]:
    """Per-call statistics for JSON."""
    return {
        "n": len(timing.samples),
        "values_s": list(timing.samples),
        "median_s": timing.median,
        "p95_s": timing.p95,
        "p99_s": timing.p99,
        "mean_s": timing.mean,
        **extra,
    }


def table_summary(checker: CollisionChecker) -> dict[str, Any]:
    """The certified tables of the check at margin 0: how many, their cells, and the
    fraction of cells left undecided (checked at run time)."""
    tables = checker._plan(0.0).tables
    cells = sum(len(t.state) for t in tables)
    undecided = sum(sum(1 for v in t.state if v == 2) for t in tables)
    return {"tables": len(tables), "table_cells": cells, "undecided": undecided / max(cells, 1)}


def agreement(
    answers: Sequence[Sequence[tuple[str, str]]],
    reference: Sequence[Sequence[tuple[str, str]]],
    distances: Sequence[dict[tuple[str, str], float]] | None,
) -> dict[str, int]:
    """Configurations where two methods name the same colliding pairs; differences
    only at contacts (|distance| < TIE_DISTANCE) are counted apart."""
    same = ties = differ = 0
    for k, (mine, theirs) in enumerate(zip(answers, reference, strict=True)):
        diff = set(mine) ^ set(theirs)
        if not diff:
            same += 1
        elif distances is not None and all(abs(distances[k][p]) < TIE_DISTANCE for p in diff):
            ties += 1
        else:
            differ += 1
    return {"same": same, "contact_ties": ties, "different": differ}


# -------------------------------------------------------------------------- run
def run(sizes: Sizes, design: spm.SPMDesign, *, quick: bool, workers: int) -> dict[str, Any]:
    """Run every section and return the JSON payload."""
    rng = np.random.default_rng(SEED)
    robot = spm.build_robot(design)
    start = time.perf_counter()
    checker = checker_of(robot)  # the robot's own checker, built on first use
    build_s = time.perf_counter() - start
    start = time.perf_counter()
    checker._plan(0.0)  # the tables and engine of margin 0 (made on first use)
    plan_s = time.perf_counter() - start
    theta = reachable_inputs(design, sizes.checks, rng)
    q = robot.configuration(theta)
    qs = list(q)

    check, answers = fastest_each(checker.collisions, qs, sizes.repeats)
    colliding = np.array([bool(a) for a in answers])
    samples = np.array(check.samples)
    results: dict[str, Any] = {
        "check_random": entry(check, colliding_fraction=float(colliding.mean())),
        "check_free": entry(Timing(tuple(samples[~colliding]))) if np.any(~colliding) else None,
        "check_colliding": entry(Timing(tuple(samples[colliding]))) if np.any(colliding) else None,
    }
    theta_timing, _ = fastest_each(robot.collisions, list(theta[: sizes.peer]), 1)
    results["check_theta"] = entry(theta_timing)
    path = smooth_path(design, sizes.checks)
    path_timing, path_answers = fastest_each(checker.collisions, list(path), 1)
    results["check_path"] = entry(
        path_timing, colliding_fraction=float(np.mean([bool(a) for a in path_answers]))
    )

    peer = PeerBVH(robot)
    peer_timing, peer_answers = fastest_each(peer, qs[: sizes.peer], sizes.repeats)
    distances = [checker.distances(item) for item in qs[: sizes.peer]]
    results["peer_bvh"] = entry(
        peer_timing, pairs=len(LINK_PAIRS), objects=robot.collision_model.ngeoms
    )
    results["peer_bvh"]["agreement_with_library"] = agreement(
        answers[: sizes.peer], peer_answers, distances
    )

    # Fidelity: the same geometry as convex pieces only, and as BVHs only.
    convex = ConvexPieces(checker)
    convex_timing, convex_answers = fastest_each(convex, qs[: sizes.convex], 1)
    no_probes = CollisionChecker(robot, probes=0)
    bodies_timing, bodies_answers = fastest_each(no_probes.collisions, qs, sizes.repeats)
    geometry = checker.geometry_model(0.0)
    results["fidelity"] = {
        "pieces": len(checker.pieces),
        "convex": entry(
            convex_timing,
            piece_pairs=convex.pairs,
            agreement_with_library=agreement(
                answers[: sizes.convex], convex_answers, distances[: sizes.convex]
            ),
        ),
        "bvh_links": results["peer_bvh"],
        "hybrid_no_probes": entry(
            bodies_timing,
            agreement_with_library=agreement(answers, bodies_answers, None),
        ),
        "hybrid": {
            "median_s": check.median,
            "objects": geometry.ngeoms,
            "pairs": len(geometry.collisionPairs),
            "probes": sum(len(v) for v in checker.probes.values()),
            **table_summary(checker),
        },
        "checker_build_s": build_s,
        "plan_build_s": plan_s,
    }

    distance_timing, _ = fastest_each(checker.distances, qs[: sizes.distances], 1)
    results["distances"] = entry(distance_timing)

    results["map"] = bench_map(design, sizes.map_step_deg, workers)
    # Like for like: our calls on the peer's configurations (the first sizes.peer).
    ours_on_peer_inputs = Timing(check.samples[: sizes.peer]).median
    speed = results["peer_bvh"]["median_s"] / ours_on_peer_inputs
    payload: dict[str, Any] = {
        "benchmark": "collision",
        "machine": machine_info(("numpy", "pin", "coal"), {"spm_pin": spm.__version__}),
        "config": {
            "quick": quick,
            "design": design.name,
            "seed": SEED,
            "sizes": dataclasses.asdict(sizes),
            "workers": workers,
            "threads_limited_before_numpy": THREADS_LIMITED,
            "timing": "perf_counter per call; check_random, peer_bvh and hybrid_no_probes: "
            "the fastest of `repeats` calls per configuration, the others one call; "
            "median/p95/p99 over configurations",
        },
        "results": results,
        "peer": {
            "name": "pinocchio computeCollisions, one coal OBBRSS triangle BVH per link",
            "median_s": results["peer_bvh"]["median_s"],
            "speed_ratio_ours_vs_peer": speed,
        },
    }
    payload["targets"] = evaluate_targets(payload)
    return payload


def bench_map(design: spm.SPMDesign, step: float, workers: int) -> dict[str, Any]:
    """Gap map without clearance: with ``workers`` processes (start-up included) and in
    this process (its checker already built)."""
    settings = WorkspaceSettings(clearance=False)
    start = time.perf_counter()
    result = workspace_map(
        design, step_deg=step, settings=settings, workers=workers, progress=False
    )
    parallel_s = time.perf_counter() - start
    workspace_map(design, step_deg=30.0, settings=settings, progress=False)  # warm-up
    start = time.perf_counter()
    single = workspace_map(design, step_deg=step, settings=settings, progress=False)
    single_s = time.perf_counter() - start
    same = all(
        np.array_equal(result.fields[name], single.fields[name], equal_nan=True)
        for name in ("reachable", "collision", "pair_mask", "dexterity")
    )
    summary = result.summary()
    return {
        "step_deg": step,
        "points": len(result),
        "workers": workers,
        "parallel_s": parallel_s,
        "single_process_s": single_s,
        "per_point_s": single_s / max(len(result), 1),
        "same_result_parallel_and_single": same,
        "reachable_fraction": summary["reachable_fraction"],
        "collision_fraction_of_reachable": summary["collision_fraction_of_reachable"],
    }


def evaluate_targets(payload: dict[str, Any]) -> dict[str, Any]:
    """Pass/fail of the project's targets (the map target only at 1 deg)."""
    results = payload["results"]
    targets: dict[str, Any] = {
        "check_median": target(
            results["check_random"]["median_s"], TARGET_CHECK_MEDIAN_S, at_least=False, unit="s"
        ),
    }
    if results["map"]["step_deg"] == TARGET_MAP_STEP_DEG:
        targets["map_1deg"] = target(
            results["map"]["parallel_s"], TARGET_MAP_S, at_least=False, unit="s"
        )
    return with_all_pass(targets)


def report(payload: dict[str, Any]) -> str:
    """The human-readable summary of a run."""
    machine, config, results = payload["machine"], payload["config"], payload["results"]
    head = (
        f"spm-pin collision benchmark: design {config['design']}, "
        f"{'1 thread' if config['threads_limited_before_numpy'] else 'threads not limited'}"
        f"{', QUICK' if config['quick'] else ''}\n"
        f"Python {machine['python']}, pin {machine['packages'].get('pin')}, coal "
        f"{machine['packages'].get('coal')}, CPU {machine['cpu']}"
    )
    fidelity = results["fidelity"]
    rows = []
    cases = [
        ("check, random reachable inputs", results["check_random"]),
        ("check, collision-free ones", results["check_free"]),
        ("check, colliding ones", results["check_colliding"]),
        ("check along a smooth path", results["check_path"]),
        ("check from theta (solves q)", results["check_theta"]),
        ("peer: BVH per link, 19 pairs", results["peer_bvh"]),
        (f"convex pieces only ({fidelity['convex']['piece_pairs']} pairs)", fidelity["convex"]),
        ("hybrid without probes", fidelity["hybrid_no_probes"]),
        ("exact distances, 19 pairs", results["distances"]),
    ]
    for label, r in cases:
        if r is None:
            continue
        rows.append(
            [label, format_count(r["n"]), format_seconds(r["median_s"]), format_seconds(r["p95_s"])]
        )
    table = format_table(["case", "n", "median", "p95"], rows)
    m = results["map"]
    agreement = results["peer_bvh"]["agreement_with_library"]
    lines = [
        head,
        "",
        table,
        "",
        f"colliding fraction of the random inputs: "
        f"{100 * results['check_random']['colliding_fraction']:.0f}%",
        f"speed ours/peer (median): {payload['peer']['speed_ratio_ours_vs_peer']:,.0f}x; "
        f"same pairs as the peer: {agreement['same']}, contact ties "
        f"{agreement['contact_ties']}, different {agreement['different']}",
        f"hybrid: {fidelity['hybrid']['objects']} objects, {fidelity['hybrid']['pairs']} pairs "
        f"({fidelity['hybrid']['probes']} probes), {fidelity['hybrid']['tables']} tables "
        f"({fidelity['hybrid']['table_cells']:,} cells, "
        f"{100 * fidelity['hybrid']['undecided']:.1f}% undecided); "
        f"{fidelity['pieces']} convex pieces; "
        f"checker built in {format_seconds(fidelity['checker_build_s'])}, its tables "
        f"in {format_seconds(fidelity['plan_build_s'])}",
        f"map at {m['step_deg']:g} deg: {m['points']:,} points, {m['workers']} workers "
        f"{format_seconds(m['parallel_s'])} (start-up included), one process "
        f"{format_seconds(m['single_process_s'])}; same result: "
        f"{m['same_result_parallel_and_single']}",
        "",
        "Targets",
    ]
    for key, t in payload["targets"].items():
        if key == "all_pass":
            continue
        lines.append(
            f"  {key}: {format_seconds(t['value'])} {t['comparison']} "
            f"{format_seconds(t['threshold'])}  {'PASS' if t['pass'] else 'FAIL'}"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the summary, write the JSON; returns the exit code."""
    parser = standard_parser(
        "collision",
        "Speed of spm-pin's self-collision check and workspace map, next to "
        "a triangle-mesh BVH check of the same geometry.",
    )
    parser.add_argument("--workers", type=int, default=2, help="map processes (default 2)")
    parser.add_argument("--design", default="prototype", help="design preset (coaxial)")

    def run_with(args: argparse.Namespace) -> dict[str, Any]:
        design = spm.SPMDesign.preset(args.design)
        return run(QUICK if args.quick else FULL, design, quick=args.quick, workers=args.workers)

    return run_main(parser, run_with, report, argv)


if __name__ == "__main__":
    sys.exit(main())
