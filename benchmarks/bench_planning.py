"""Planning benchmark: safe paths between random safe input angles of the prototype.

Run from the repository root::

    python -m benchmarks.bench_planning [--out FILE.json] [--quick]

It prints a short table and writes JSON (default ``benchmarks/results/planning.json``).
Importing this module limits numpy to one thread (see ``_common.limit_to_one_thread``).

What is measured (the prototype, the default :class:`~spm_pin.planning.PlanSettings`:
the servos' guard's thresholds, 2-degree grid):

1. ``safe_set``: the build of :class:`~spm_pin.planning.SafeSet` (kinematics,
   Lipschitz bounds and collision checks of every grid vertex), and its size. It is
   built in memory once per process (:func:`~spm_pin.planning.safe_set_of`).
2. ``plan``: :func:`spm_pin.planning.plan` between N random safe start/goal pairs
   (N = 1000; 10 in a quick run): safe grid vertices with a random mean input (yaw)
   in [-pi, pi), kept when :meth:`SafeSet.evaluate` finds them safe. Per call:
   median, p95, p99; detours (more than 2 waypoints), length against the straight
   line, failures (:class:`~spm_pin.errors.PlanningError`) by reason, and every
   path certified again as a continuous motion (:meth:`SafeSet.certify`).
3. ``peer.straight``: the straight line from start to goal, certified by
   :meth:`SafeSet.certify` (what moving without a planner costs to check, and how
   often it is unsafe).
4. ``peer.ompl``: OMPL's RRTConnect (its Python bindings, ``pip install ompl``) in
   the same space: the input angles as a ``RealVectorStateSpace(3)`` bounded by the
   safe set's extent at mean inputs between the start's and the goal's, state
   validity ``SafeSet.evaluate``, OMPL's discrete motion validation at its default
   resolution, 1 s time limit, then ``simplifySolution``. On the first 100 pairs (3
   in a quick run): a Python validity callback is slow. Its paths are then certified
   by :meth:`SafeSet.certify`. Without OMPL: ``{"available": false, "reason": ...}``.
5. ``duration``: where the straight line is safe, the time-optimal motion along the
   planned path (:meth:`PlannedPath.timed`, TOPP-RA) against the trapezoidal
   straight-line profile of :func:`spm_pin.hardware.sync.plan_linear` at the same
   joint speed and acceleration limits (100 pairs; 3 in a quick run).
6. ``cover`` and ``plan_cached``: the certified cells of the whole safe set
   precomputed down to the finest level, 5 (:meth:`SafeCover.fill`, a few minutes;
   level 0 in a quick run), saved to a file (its size), read back into a fresh safe
   set (the time, with the collision checks of every margin made), and the same
   pairs planned with them (what a user who keeps the file sees). Level 5 and not 3:
   the pieces of a path in cells that are not covered are certified by their own
   samples, which near the boundary of the safe set cost a few tenths of a
   millisecond each; finer cells leave fewer such pieces (with level 3 the p99 was
   about 18 ms).
7. ``eye``: the Agile Eye (not coaxial: it plans in its 3-D input space,
   :func:`~spm_pin.planning.input_space.plan_inputs`) between N random safe inputs
   (N = 200; 4 in a quick run): uniform in [-60, 60] deg per input, kept when a safe
   set of the whole [-180, 180] deg box finds them safe; consecutive states paired.
   The safe set of their planning box is built before the timing (its build time is
   reported: once per process, :func:`~spm_pin.planning.input_space.input_safe_set_of`).
   Per call: median, p95, p99; straight lines, failures, and every path certified
   again by that safe set.
8. ``targets``: every pair planned and certified (``plan_success``); full runs only:
   with the precomputed cells, the median plan <= 1 ms and its p99 <= 10 ms on one
   core (a precomputed map on disk is allowed); the Agile Eye's median plan
   <= 50 ms.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import shutil
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ._common import limit_to_one_thread

#: Whether the one-thread limit was set before numpy was imported.
THREADS_LIMITED = limit_to_one_thread()

import numpy as np  # noqa: E402
import numpy.typing as npt  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin.errors import PlanningError  # noqa: E402
from spm_pin.hardware.sync import plan_linear  # noqa: E402
from spm_pin.planning import PlannedPath, SafeSet, TimingLimits, plan  # noqa: E402
from spm_pin.planning.timing import DEFAULT_MAX_ACCELERATION, DEFAULT_MAX_SPEED  # noqa: E402

from ._common import (  # noqa: E402
    Timing,
    format_rate,
    format_seconds,
    format_table,
    machine_info,
    run_main,
    standard_parser,
    target,
    time_call,
    time_each,
    with_all_pass,
)

FloatArray = npt.NDArray[np.float64]
Pair = tuple[FloatArray, FloatArray]

#: Seed of the start/goal pairs (and of OMPL's sampler).
SEED = 20_260_301
#: The project's targets for one plan on one core [s].
TARGET_MEDIAN_S = 1e-3
TARGET_P99_S = 10e-3
#: The project's target for one plan of the Agile Eye [s].
TARGET_EYE_MEDIAN_S = 50e-3
#: OMPL's time limit per pair [s].
OMPL_TIME_LIMIT_S = 1.0
#: Joint limits of both timed motions (the servos' guard's): [rad/s], [rad/s^2].
MAX_SPEED = DEFAULT_MAX_SPEED
MAX_ACCELERATION = DEFAULT_MAX_ACCELERATION
#: Sampling period of plan_linear's trapezoid [s].
LINEAR_PERIOD_S = 1e-4
#: Two waypoints equal to the start and goal up to this [rad].
ENDPOINT_TOL = 1e-12


@dataclasses.dataclass(frozen=True)
class Sizes:
    """Pair counts and repeats of one run."""

    pairs: int
    ompl_pairs: int
    duration_pairs: int
    builds: int
    fill_level: int  # the certified cells precomputed down to this level

    eye_pairs: int  # pairs of the Agile Eye


FULL = Sizes(pairs=1000, ompl_pairs=100, duration_pairs=100, builds=3, fill_level=5, eye_pairs=200)
QUICK = Sizes(pairs=10, ompl_pairs=3, duration_pairs=3, builds=1, fill_level=0, eye_pairs=4)


# ------------------------------------------------------------------------- pairs
def sample_pairs(safe: SafeSet, n: int, seed: int = SEED) -> tuple[list[Pair], int]:
    """``n`` random safe (start, goal) pairs of input angles [rad], and how many
    states were drawn to find them.

    Each state is a safe vertex of the gap grid (uniform over the safe vertices) at a
    uniform random mean input in [-pi, pi), kept when :meth:`SafeSet.evaluate` finds
    it safe.
    """
    rng = np.random.default_rng(seed)
    rows, cols = np.nonzero(safe.safe)
    kept: list[FloatArray] = []
    drawn = 0
    while len(kept) < 2 * n:
        k = rng.integers(0, rows.size, size=2 * n)
        yaw = rng.uniform(-math.pi, math.pi, size=2 * n)
        theta = safe.theta_of(safe.d12[rows[k]], safe.d23[cols[k]], yaw)
        drawn += theta.shape[0]
        kept.extend(theta[np.asarray(safe.evaluate(theta).safe, dtype=bool)])
    return [(kept[2 * i], kept[2 * i + 1]) for i in range(n)], drawn


def _length_deg(theta: FloatArray) -> float:
    return float(np.sum(np.linalg.norm(np.degrees(np.diff(theta, axis=0)), axis=1)))


def _endpoint_error(theta: FloatArray, pair: Pair) -> float:
    return float(max(np.max(np.abs(theta[0] - pair[0])), np.max(np.abs(theta[-1] - pair[1]))))


def _stats(values: Sequence[float]) -> dict[str, float | None]:
    if not values:
        return {"median": None, "max": None, "min": None}
    array = np.asarray(values, dtype=float)
    return {
        "median": float(np.median(array)),
        "max": float(array.max()),
        "min": float(array.min()),
    }


# ---------------------------------------------------------------------- sections
def _cache_stats(safe: SafeSet) -> dict[str, int] | None:
    """Counters of the safe set's lazily grown cache of certified cells, if it has one."""
    stats = getattr(getattr(safe, "cover", None), "stats", None)
    return None if stats is None else {str(k): int(v) for k, v in dict(stats).items()}


def _warming(timing: Timing) -> dict[str, float]:
    """Median of the first and of the last tenth of the samples (caches that grow
    with the pairs show as a difference)."""
    tenth = max(1, len(timing.samples) // 10)
    return {
        "median_first_tenth_s": Timing(timing.samples[:tenth]).median,
        "median_last_tenth_s": Timing(timing.samples[-tenth:]).median,
    }


def _cover_section(design: spm.SPMDesign, level: int) -> dict[str, Any]:
    """Precompute the certified cells of the whole safe set down to ``level``
    (:meth:`SafeCover.fill`), save them to a temporary file and time reading them."""
    import tempfile
    import time

    safe = SafeSet(design)
    start = time.perf_counter()
    safe.cover.fill(max_level=level)
    fill_s = time.perf_counter() - start
    path = Path(tempfile.mkdtemp(prefix="spm-cover-")) / "cover.npz"
    safe.cover.save(path)
    fresh = SafeSet(design)
    start = time.perf_counter()
    fresh.cover.load(path)
    load_s = time.perf_counter() - start
    return {
        "fill_level": level,
        "fill_s": fill_s,
        "file_bytes": path.stat().st_size,
        "load_s": load_s,
        "cells": dict(safe.cover.stats),
        "path": str(path),
    }


def _plan_section(
    safe: SafeSet, pairs: list[Pair]
) -> tuple[dict[str, Any], list[PlannedPath | None]]:
    """Time :func:`plan` per pair (in order, on a safe set fresh for this section)."""

    def plan_one(pair: Pair) -> PlannedPath | PlanningError:
        try:
            return plan(pair[0], pair[1], safe=safe)
        except PlanningError as exc:
            return exc

    timing, outcomes = time_each(plan_one, pairs)
    failures: collections.Counter[str] = collections.Counter()
    paths: list[PlannedPath | None] = []
    detours = 0
    ratios: list[float] = []
    errors: list[float] = []
    waypoints: list[int] = []
    reported_ms: list[float] = []
    for pair, outcome in zip(pairs, outcomes, strict=True):
        if isinstance(outcome, PlanningError):
            failures[f"{outcome.check}: {'; '.join(outcome.reasons) or outcome}"] += 1
            paths.append(None)
            continue
        paths.append(outcome)
        theta = outcome.theta
        waypoints.append(theta.shape[0])
        detours += theta.shape[0] > 2
        errors.append(_endpoint_error(theta, pair))
        if outcome.straight_length_deg > 0:
            ratios.append(outcome.length_deg / outcome.straight_length_deg)
        reported_ms.append(outcome.planning_time_ms)
    entry = {
        **timing.summary(),
        **_warming(timing),
        "n": len(pairs),
        "planned": len(pairs) - sum(failures.values()),
        "failures": sum(failures.values()),
        "failure_reasons": dict(failures),
        "detours": detours,
        "detour_fraction": detours / len(pairs),
        "waypoints": _stats([float(w) for w in waypoints]),
        "length_vs_straight": _stats(ratios),
        "max_endpoint_error_rad": max(errors, default=math.nan),
        "planner_reported_ms": _stats(reported_ms),
        "cache_stats": _cache_stats(safe),
    }
    return entry, paths


def _eye_section(n: int) -> dict[str, Any]:
    """The Agile Eye: :func:`plan` between ``n`` random safe input pairs (3-D input
    space), its safe set built before the timing."""
    import time

    from spm_pin.planning import InputSafeSet
    from spm_pin.planning.input_space import _default_box, input_safe_set_of

    eye = spm.SPMDesign.agile_eye()
    whole = InputSafeSet(eye, low=np.radians([-180.0] * 3), high=np.radians([180.0] * 3))
    rng = np.random.default_rng(SEED)
    states: list[FloatArray] = []
    drawn = 0
    while len(states) < 2 * n and drawn < 200_000:
        theta = np.radians(rng.uniform(-60.0, 60.0, size=(2_000, 3)))
        drawn += theta.shape[0]
        states += list(theta[whole.evaluate(theta).safe])
    pairs = [(states[2 * k], states[2 * k + 1]) for k in range(min(n, len(states) // 2))]
    boxes = {_default_box(a, b) for a, b in pairs}
    start = time.perf_counter()
    for low, high in boxes:
        input_safe_set_of(eye, whole.settings, low, high)
    build_s = time.perf_counter() - start

    def plan_one(pair: Pair) -> PlannedPath | PlanningError:
        try:
            return plan(pair[0], pair[1], eye)
        except PlanningError as exc:
            return exc

    timing, outcomes = time_each(plan_one, pairs)
    failures: collections.Counter[str] = collections.Counter()
    straight = certified = 0
    for pair, outcome in zip(pairs, outcomes, strict=True):
        if isinstance(outcome, PlanningError):
            failures[str(outcome).split(":")[0]] += 1
            continue
        straight += outcome.theta.shape[0] == 2
        safe = input_safe_set_of(eye, whole.settings, *_default_box(*pair))
        certified += bool(safe.certify(outcome.theta)[0])
    return {
        **timing.summary(),
        "n": len(pairs),
        "states_drawn": drawn,
        "boxes": len(boxes),
        "safe_set_build_s": build_s,
        "planned": len(pairs) - sum(failures.values()),
        "straight": straight,
        "certified": certified,
        "failures": sum(failures.values()),
        "failure_reasons": dict(failures),
    }


def _certify_planned(
    safe: SafeSet, pairs: list[Pair], paths: list[PlannedPath | None], straight_ok: list[bool]
) -> dict[str, Any]:
    """Every planned path certified again (untimed): its ends are the pair's and
    :meth:`SafeSet.certify` passes; a path that is the straight line takes the
    straight-line peer's certificate."""
    certified = 0
    for pair, path, straight in zip(pairs, paths, straight_ok, strict=True):
        if path is None or _endpoint_error(path.theta, pair) > ENDPOINT_TOL:
            continue
        theta = path.theta
        is_straight = theta.shape[0] == 2 and np.array_equal(theta, np.vstack(pair))
        certified += straight if is_straight else bool(safe.certify(theta)[0])
    return {"certified": certified, "certified_fraction": certified / len(pairs)}


def _straight_section(safe: SafeSet, pairs: list[Pair]) -> tuple[dict[str, Any], list[bool]]:
    """Certify the straight line of every pair."""

    def certify(pair: Pair) -> bool:
        return bool(safe.certify(np.vstack(pair))[0])

    timing, ok = time_each(certify, pairs)
    unsafe = len(ok) - sum(ok)
    entry = {
        **timing.summary(),
        **_warming(timing),
        "n": len(pairs),
        "method": "straight line start -> goal in input space, SafeSet.certify",
        "unsafe": unsafe,
        "unsafe_fraction": unsafe / len(pairs),
        "length_deg": _stats([_length_deg(np.vstack(pair)) for pair in pairs]),
        "cache_stats": _cache_stats(safe),
    }
    return entry, ok


def _safe_extent(safe: SafeSet) -> tuple[FloatArray, FloatArray]:
    """Smallest and largest input angle of each joint over the safe vertices at mean
    input 0 [rad], (3,) each."""
    rows, cols = np.nonzero(safe.safe)
    theta = safe.theta_of(safe.d12[rows], safe.d23[cols], 0.0)
    return theta.min(axis=0), theta.max(axis=0)


_OMPL_SEEDED = False


def _ompl_section(safe: SafeSet, pairs: list[Pair], ours: Timing) -> dict[str, Any]:
    """OMPL's RRTConnect + simplification per pair, in the same space and with the same
    validity check; ``ours``: our per-pair times on the same pairs."""
    global _OMPL_SEEDED
    try:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou
    except ImportError as exc:  # an optional peer
        return {"available": False, "reason": f"{type(exc).__name__}: {exc}"}
    ou.setLogLevel(ou.LogLevel.LOG_ERROR)
    if not _OMPL_SEEDED:  # OMPL accepts a seed once, before its first sampler
        ou.RNG.setSeed(SEED)
        _OMPL_SEEDED = True
    low, high = _safe_extent(safe)
    checks = [0]

    def valid(state: Any) -> bool:
        checks[0] += 1
        theta = np.array([state[0], state[1], state[2]], dtype=float)
        return bool(safe.evaluate(theta[None]).safe[0])

    def solve(pair: Pair) -> dict[str, Any]:
        start, goal = pair
        space = ob.RealVectorStateSpace(3)
        bounds = ob.RealVectorBounds(3)
        y0, y1 = sorted((float(np.mean(start)), float(np.mean(goal))))
        for j in range(3):
            bounds.setLow(j, y0 + float(low[j]))
            bounds.setHigh(j, y1 + float(high[j]))
        space.setBounds(bounds)
        setup = og.SimpleSetup(space)
        setup.setStateValidityChecker(valid)
        info = setup.getSpaceInformation()
        a, b = space.allocState(), space.allocState()
        for j in range(3):
            a[j], b[j] = float(start[j]), float(goal[j])
        setup.setStartAndGoalStates(a, b)
        setup.setPlanner(og.RRTConnect(info))
        checks[0] = 0
        status = setup.solve(OMPL_TIME_LIMIT_S)
        exact = bool(setup.haveExactSolutionPath())
        if exact:
            setup.simplifySolution()
        theta = None
        if exact:
            path = setup.getSolutionPath()
            theta = np.array(
                [[path.getState(k)[j] for j in range(3)] for k in range(path.getStateCount())]
            )
        return {
            "status": str(status),
            "theta": theta,
            "solve_s": float(setup.getLastPlanComputationTime()),
            "simplify_s": float(setup.getLastSimplificationTime()) if exact else 0.0,
            "checks": checks[0],
            "resolution_deg": math.degrees(
                info.getStateValidityCheckingResolution() * space.getMaximumExtent()
            ),
        }

    timing, outcomes = time_each(solve, pairs)
    statuses: collections.Counter[str] = collections.Counter()
    solved = certified = 0
    lengths: list[float] = []
    versus_ours: list[float] = []
    errors: list[float] = []
    for pair, outcome in zip(pairs, outcomes, strict=True):
        statuses[outcome["status"]] += 1
        theta = outcome["theta"]
        if theta is None:
            continue
        solved += 1
        errors.append(_endpoint_error(theta, pair))
        certified += bool(safe.certify(theta)[0])
        lengths.append(_length_deg(theta))
        straight = _length_deg(np.vstack(pair))
        if straight > 0:
            versus_ours.append(lengths[-1] / straight)
    n = len(pairs)
    entry: dict[str, Any] = {
        "available": True,
        **timing.summary(),
        "n": n,
        "method": (
            "OMPL RRTConnect (default range) in RealVectorStateSpace(3) of the input "
            "angles, bounded by the safe set's extent at mean inputs between the ends; "
            "validity SafeSet.evaluate; DiscreteMotionValidator at OMPL's default "
            f"resolution; solve({OMPL_TIME_LIMIT_S:g} s) then simplifySolution(); the time "
            "is SimpleSetup's build + solve + simplify"
        ),
        "subset": f"the first {n} of the planned pairs (a Python validity callback is slow)",
        "time_limit_s": OMPL_TIME_LIMIT_S,
        "statuses": dict(statuses),
        "solved": solved,
        "success_fraction": solved / n,
        "certified": certified,
        "certified_fraction": certified / n,
        "certified_of_solved": certified / solved if solved else None,
        "length_deg": _stats(lengths),
        "length_vs_straight": _stats(versus_ours),
        "waypoints": _stats(
            [float(o["theta"].shape[0]) for o in outcomes if o["theta"] is not None]
        ),
        "max_endpoint_error_rad": max(errors, default=math.nan),
        "solve_s": _stats([o["solve_s"] for o in outcomes]),
        "simplify_s": _stats([o["simplify_s"] for o in outcomes]),
        "validity_checks": _stats([float(o["checks"]) for o in outcomes]),
        "resolution_deg": _stats([o["resolution_deg"] for o in outcomes]),
        "ours_median_s_same_pairs": ours.median,
        "speed_ratio_ours_vs_peer": timing.median / ours.median,
    }
    return entry


def _linear_duration(start: FloatArray, goal: FloatArray) -> float:
    """Duration [s] of plan_linear's trapezoid, from its samples.

    The samples lie ``LINEAR_PERIOD_S`` apart and the last one at the end; the last
    interval brakes at ``MAX_ACCELERATION`` to rest, so its length follows from the
    distance left after the sample before.
    """
    samples = plan_linear(
        start,
        goal,
        max_speed=MAX_SPEED,
        max_acceleration=MAX_ACCELERATION,
        period=LINEAR_PERIOD_S,
    )
    distance = float(np.max(np.abs(goal - start)))
    if distance == 0.0:
        return 0.0
    before = samples[-2] if samples.shape[0] > 1 else start
    left = distance - float(np.max(np.abs(before - start)))
    tail = math.sqrt(2.0 * max(left, 0.0) / MAX_ACCELERATION)
    return float((samples.shape[0] - 1) * LINEAR_PERIOD_S + tail)


def _duration_section(paths: list[PlannedPath]) -> dict[str, Any]:
    """Time-optimal timing along each planned (straight) path against the trapezoid."""
    limits = TimingLimits(max_speed=MAX_SPEED, max_acceleration=MAX_ACCELERATION)
    if not paths:
        return {"available": False, "reason": "no pair with a safe straight line"}
    try:
        timing, trajectories = time_each(lambda path: path.timed(limits), paths)
    except ImportError as exc:  # toppra: the planning extra
        return {"available": False, "reason": f"{type(exc).__name__}: {exc}"}
    ratios, linear, durations, baseline_gap = [], [], [], []
    for path, trajectory in zip(paths, trajectories, strict=True):
        trapezoid = _linear_duration(path.start, path.goal)
        linear.append(trapezoid)
        durations.append(trajectory.duration)
        baseline_gap.append(abs(trajectory.trapezoid_duration - trapezoid))
        if trapezoid > 0:
            ratios.append(trajectory.duration / trapezoid)
    return {
        "available": True,
        **timing.summary(),
        "n": len(paths),
        "method": (
            "PlannedPath.timed (TOPP-RA) against hardware.sync.plan_linear's trapezoid, "
            "the same joint limits, pairs whose straight line is safe; the time is one "
            "timed() call"
        ),
        "max_speed_rad_s": MAX_SPEED,
        "max_acceleration_rad_s2": MAX_ACCELERATION,
        "linear_period_s": LINEAR_PERIOD_S,
        "duration_s": _stats(durations),
        "trapezoid_s": _stats(linear),
        "ratio_vs_trapezoid": _stats(ratios),
        "max_trapezoid_disagreement_s": max(baseline_gap),
    }


def run(sizes: Sizes, *, quick: bool) -> dict[str, Any]:
    """Run every section and return the JSON payload."""
    design = spm.SPMDesign.prototype()
    results: dict[str, dict[str, Any]] = {}
    built = time_call(lambda: SafeSet(design), repeats=sizes.builds, warmup=0)
    safe = built.value
    results["safe_set"] = {
        **built.timing.summary(),
        "grid_shape": list(safe.safe.shape),
        "grid_step_deg": safe.settings.grid_step_deg,
        "safe_vertices": int(np.count_nonzero(safe.safe)),
        "map_bytes": int(safe.safe.nbytes),
        "map_bytes_packed": int(np.packbits(safe.safe).nbytes),
        "disk_cache": None,
        "note": (
            "built in memory once per process (spm_pin.planning.safe_set_of caches it); "
            "its certified cells may be saved to disk (see cover); the first build "
            "includes first-use costs"
        ),
    }
    results["cover"] = _cover_section(design, sizes.fill_level)
    pairs, drawn = sample_pairs(safe, sizes.pairs)
    # A fresh safe set per timed section: a safe set may cache what it certified (and
    # would then favour whichever section runs second).
    results["plan"], paths = _plan_section(SafeSet(design), pairs)
    results["plan"]["states_drawn"] = drawn
    # With the certified cells precomputed and read from disk (what a user keeps).
    loaded = SafeSet(design)
    saved = Path(results["cover"].pop("path"))
    loaded.cover.load(saved)
    shutil.rmtree(saved.parent, ignore_errors=True)
    results["plan_cached"], _ = _plan_section(loaded, pairs)
    straight_safe = SafeSet(design)
    straight, straight_ok = _straight_section(straight_safe, pairs)
    results["plan"].update(_certify_planned(straight_safe, pairs, paths, straight_ok))
    ours = Timing(tuple(results["plan"]["values_s"]))
    straight["speed_ratio_ours_vs_peer"] = straight["median_s"] / ours.median
    subset = min(sizes.ompl_pairs, len(pairs))
    ompl = _ompl_section(safe, pairs[:subset], Timing(ours.samples[:subset]))
    timed_paths = [p for p, ok in zip(paths, straight_ok, strict=True) if ok and p is not None]
    results["duration"] = _duration_section(timed_paths[: sizes.duration_pairs])
    targets: dict[str, Any] = {
        "plan_success": target(
            results["plan"]["certified_fraction"], 1.0, at_least=True, unit="fraction"
        ),
    }
    plan_entry = results["plan_cached"]
    if not quick:  # a few pairs say little about a time
        targets["plan_median_s"] = target(
            plan_entry["median_s"], TARGET_MEDIAN_S, at_least=False, unit="s"
        )
        targets["plan_p99_s"] = target(plan_entry["p99_s"], TARGET_P99_S, at_least=False, unit="s")
    results["eye"] = _eye_section(sizes.eye_pairs)
    if not quick:
        targets["eye_median_s"] = target(
            results["eye"]["median_s"], TARGET_EYE_MEDIAN_S, at_least=False, unit="s"
        )
    with_all_pass(targets)
    return {
        "benchmark": "planning",
        "machine": machine_info(
            ("numpy", "pin", "coal", "toppra", "ompl"), {"spm_pin": spm.__version__}
        ),
        "config": {
            "quick": quick,
            "seed": SEED,
            "sizes": dataclasses.asdict(sizes),
            "settings": dataclasses.asdict(safe.settings),
            "pairs": (
                "safe grid vertices (uniform) at a uniform mean input in [-pi, pi), kept "
                "when SafeSet.evaluate finds them safe; consecutive states paired"
            ),
            "ompl_time_limit_s": OMPL_TIME_LIMIT_S,
            "threads_limited_before_numpy": THREADS_LIMITED,
            "timing": (
                "perf_counter; 1 warm-up call; median/p95/p99 over pairs, one call each, "
                "in order; a fresh SafeSet for the plan and for the straight-line sections"
            ),
        },
        "results": results,
        "peer": {"straight": straight, "ompl": ompl},
        "targets": targets,
    }


def report(payload: dict[str, Any]) -> str:
    """The human-readable summary of a run."""
    config, results, peer = payload["config"], payload["results"], payload["peer"]
    threads = "1 thread" if config["threads_limited_before_numpy"] else "threads not limited"
    head = f"spm-pin planning benchmark: prototype, {threads}" + (
        ", QUICK" if config["quick"] else ""
    )
    plan_entry, straight, ompl = results["plan"], peer["straight"], peer["ompl"]
    cases = [
        ("safe set build", results["safe_set"]),
        (f"plan, {plan_entry['n']} pairs, cells new", plan_entry),
        (
            f"plan, cells precomputed (level {results['cover']['fill_level']})",
            results["plan_cached"],
        ),
        (f"peer: straight line certified, {straight['n']} pairs", straight),
    ]
    if ompl.get("available"):
        cases.append((f"peer: OMPL RRTConnect + simplify, {ompl['n']} pairs", ompl))
    cases.append((f"Agile Eye: plan in 3-D, {results['eye']['n']} pairs", results["eye"]))
    if results["duration"].get("available"):
        cases.append(
            (f"timed() along the path, {results['duration']['n']} pairs", results["duration"])
        )
    rows = [
        [
            label,
            format_seconds(entry["median_s"]),
            format_seconds(entry["p95_s"]),
            format_seconds(entry["p99_s"]),
            format_rate(entry["per_second"]),
        ]
        for label, entry in cases
    ]
    table = format_table(["case", "median", "p95", "p99", "calls/s"], rows)
    safe_set = results["safe_set"]
    notes = [
        f"safe set: {safe_set['safe_vertices']:,} safe vertices of a "
        f"{safe_set['grid_shape'][0]}x{safe_set['grid_shape'][1]} grid "
        f"({safe_set['map_bytes']:,} bytes as booleans)",
        f"plan: {plan_entry['planned']}/{plan_entry['n']} planned, "
        f"{plan_entry['certified']} certified, {plan_entry['detours']} detours, "
        f"{plan_entry['failures']} failures {plan_entry['failure_reasons'] or ''}".rstrip(),
        f"straight line unsafe: {straight['unsafe']}/{straight['n']} "
        f"({straight['unsafe_fraction']:.1%})",
    ]
    if ompl.get("available"):
        notes.append(
            f"OMPL: {ompl['solved']}/{ompl['n']} solved, {ompl['certified']} pass the "
            f"continuous certificate, {ompl['speed_ratio_ours_vs_peer']:.1f}x our time on "
            "the same pairs"
        )
    else:
        notes.append(f"OMPL: not available ({ompl['reason']})")
    duration = results["duration"]
    if duration.get("available"):
        ratio = duration["ratio_vs_trapezoid"]
        notes.append(
            f"duration vs trapezoid (straight lines): median {ratio['median']:.4f}, "
            f"max {ratio['max']:.4f}"
        )
    else:
        notes.append(f"duration: not measured ({duration['reason']})")
    eye = results["eye"]
    notes.append(
        f"Agile Eye: {eye['planned']}/{eye['n']} planned ({eye['straight']} straight), "
        f"{eye['certified']} certified again, {eye['failures']} failures "
        f"{eye['failure_reasons'] or ''}; safe set of {eye['boxes']} box(es) built first "
        f"in {eye['safe_set_build_s']:.1f} s".rstrip()
    )
    cover = results["cover"]
    notes.append(
        f"certified cells precomputed to level {cover['fill_level']}: "
        f"{cover['fill_s']:.1f} s, {cover['file_bytes'] / 1e6:.1f} MB on disk, "
        f"read in {cover['load_s']:.2f} s"
    )
    lines = ["Targets"]
    for name, record in payload["targets"].items():
        if name == "all_pass":
            continue
        lines.append(
            f"  {'PASS' if record['pass'] else 'FAIL'}  {name}: {record['value']:.4g} "
            f"({record['comparison']} {record['threshold']:g} {record['unit']})"
        )
    if config["quick"]:
        lines.append("  (time targets: full runs only)")
    return "\n\n".join([head, table, "\n".join(notes), "\n".join(lines)])


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the summary, write the JSON; returns the exit code."""
    parser = standard_parser(
        "planning",
        "Safe planning between random safe inputs of the prototype, beside the straight "
        "line and OMPL.",
        quick_help="10 pairs, 3 for OMPL (smoke test)",
    )
    return run_main(
        parser, lambda args: run(QUICK if args.quick else FULL, quick=args.quick), report, argv
    )


if __name__ == "__main__":
    sys.exit(main())
