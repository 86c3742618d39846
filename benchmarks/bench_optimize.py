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
   full runs only);
5. ``engines``: the evaluations of a study (:func:`spm_pin.optimize.run_study`'s
   trial, objectives tilt and peak_torque at the default settings, 6-degree grid) of
   one list of random designs (40; ``--quick``: 6), new to every process, scored one
   after the other in this process, on a Dask ``LocalCluster`` of 2 worker processes
   through the study's own engine (up to 2 in flight per worker), and on a plain
   ``concurrent.futures.ProcessPoolExecutor(2)`` (the peer). Each rate is scores per
   second of wall time once the workers are up and warm (one evaluation each before
   the clock starts; the start-up is reported apart); the scaling efficiency is
   rate / (workers x in-process rate). Every engine's scores must be equal
   (``equal_scores``). Skipped without Dask distributed.
6. ``pareto``: the time to a Pareto front of a two-objective study of P designs
   (500; ``--quick``: 12) of the engines section's space, objectives and settings,
   wall time from the call to its answer, start-up included: through the library's
   own :func:`spm_pin.optimize.run_study` on a Dask ``LocalCluster`` of 2 processes
   (``workers=2``), and the peer: the same study (Optuna's NSGA-II, the same
   population and seed, the same evaluation ``_evaluate_trial``) driven through
   Optuna's ask/tell interface on a plain ``ProcessPoolExecutor(2)`` (spawn), up to
   2 trials in flight per worker. Each reports its wall time, designs per second,
   the size of its Pareto front (feasible, non-dominated: the study's definition)
   and its failed and infeasible trials; the start-up of a cluster (or pool) alone is
   measured apart, not subtracted. Skipped without Optuna (the peer too) or Dask
   distributed (ours).
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import itertools
import logging
import multiprocessing
import os
import sys
import time
import warnings
from collections.abc import Sequence
from typing import Any

from ._common import limit_to_one_thread

#: Whether the one-thread limit was set before numpy was imported.
THREADS_LIMITED = limit_to_one_thread()

import numpy as np  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin.optimize import DesignSpace, Variable, safe_workspace_score  # noqa: E402
from spm_pin.optimize._engines import (  # noqa: E402
    IN_FLIGHT_PER_THREAD,
    dask_client,
    evaluate_on_cluster,
)
from spm_pin.optimize.study import (  # noqa: E402
    OBJECTIVES,
    StudySettings,
    TrialRecord,
    _evaluate_trial,
    _pareto,
    run_study,
)
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
    engine_designs: int
    pareto_designs: int


# One evaluation of the engines' space costs about 0.4 s on one core (2026, CI-class
# machine), so 500 designs on 2 workers take about 100-150 s per engine of the
# Pareto section (quick: 12 designs, a few seconds each).
FULL = Sizes(scores=15, new_designs=5, maps=3, engine_designs=40, pareto_designs=500)
QUICK = Sizes(scores=3, new_designs=2, maps=1, engine_designs=6, pareto_designs=12)

#: The engines section: its design space, objectives, settings and worker processes.
ENGINE_SPACE = DesignSpace(
    (Variable("alpha1_deg", 35.0, 75.0), Variable("alpha2_deg", 60.0, 120.0))
)
ENGINE_OBJECTIVES = ("tilt", "peak_torque")
ENGINE_SETTINGS = StudySettings()
ENGINE_WORKERS = 2
#: The Pareto section's study: the seed and NSGA-II population of ``run_study``.
PARETO_SEED = 0
PARETO_POPULATION = 20


def _engine_tasks(count: int) -> tuple[tuple[Any, ...], list[tuple[Any, ...]]]:
    """The warm-up task and ``count`` tasks (arguments of the study's evaluation) of
    random designs of :data:`ENGINE_SPACE` (seeded), each under its own name."""
    rng = np.random.default_rng(0)

    def task(label: str) -> tuple[Any, ...]:
        values = {v.name: float(rng.uniform(v.low, v.high)) for v in ENGINE_SPACE.variables}
        return (ENGINE_SPACE, values, ENGINE_OBJECTIVES, ENGINE_SETTINGS, label)

    warm = task("bench-warm-up")
    return warm, [task(f"bench-{k}") for k in range(count)]


def _engine_entry(workers: int, seconds: float, count: int, single: float | None) -> dict[str, Any]:
    rate = count / seconds
    return {
        "workers": workers,
        "seconds": seconds,
        "per_second": rate,
        "efficiency": None if single is None else rate / (workers * single),
    }


def run_engines(count: int) -> dict[str, Any]:
    """Scores per second of a study's evaluations in this process, on a Dask
    LocalCluster and on a ProcessPoolExecutor (see the module)."""
    warm, tasks = _engine_tasks(count)
    out: dict[str, Any] = {
        "designs": count,
        "objectives": list(ENGINE_OBJECTIVES),
        "step_deg": ENGINE_SETTINGS.step_deg,
        "cpus": os.cpu_count(),
        "load_average_before": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
    }
    _evaluate_trial(*warm)  # imports and one-off set-up (not the designs' own)
    start = time.perf_counter()
    serial = [_evaluate_trial(*task) for task in tasks]
    in_process = _engine_entry(1, time.perf_counter() - start, count, None)
    single = in_process["per_second"]
    out["in_process"] = in_process
    outcomes = {"in_process": serial}
    # The peer: a plain process pool, spawned (as Dask's workers are), warmed up.
    start = time.perf_counter()
    with concurrent.futures.ProcessPoolExecutor(
        ENGINE_WORKERS,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_evaluate_trial,
        initargs=warm,
    ) as pool:
        for future in [pool.submit(time.sleep, 0.5) for _ in range(ENGINE_WORKERS)]:
            future.result()  # every process up and warm
        startup = time.perf_counter() - start
        start = time.perf_counter()
        pooled = list(pool.map(_evaluate_trial, *zip(*tasks, strict=True)))
        seconds = time.perf_counter() - start
    out["process_pool"] = {
        **_engine_entry(ENGINE_WORKERS, seconds, count, single),
        "startup_s": startup,
        "method": "concurrent.futures.ProcessPoolExecutor(2, spawn), pool.map",
    }
    outcomes["process_pool"] = pooled
    try:
        import distributed  # noqa: F401
    except ImportError:
        out["dask_local_cluster"] = {"skipped": "dask[distributed] is not installed"}
    else:
        start = time.perf_counter()
        with dask_client(ENGINE_WORKERS, None) as client:  # the study's LocalCluster
            client.run(_evaluate_trial, *warm)  # on every worker
            startup = time.perf_counter() - start
            results: dict[int, Any] = {}
            pending = iter(enumerate(tasks))

            def tell(key: int, result: Any, reason: str | None) -> None:
                results[key] = result if reason is None else reason

            start = time.perf_counter()
            evaluate_on_cluster(client, count, lambda: next(pending), _evaluate_trial, tell)
            seconds = time.perf_counter() - start
        out["dask_local_cluster"] = {
            **_engine_entry(ENGINE_WORKERS, seconds, count, single),
            "startup_s": startup,
            "method": "distributed.LocalCluster(2 processes, 1 thread each), the study's engine",
        }
        outcomes["dask_local_cluster"] = [results[k] for k in range(count)]
    out["equal_scores"] = all(found == serial for found in outcomes.values())
    out["failed"] = sum(o.error is not None for o in serial)
    return out


def _load_average() -> float | None:
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else None


def _pareto_entry(
    method: str, seconds: float, startup: float, records: Sequence[TrialRecord]
) -> dict[str, Any]:
    """One engine's figures of the Pareto section from its trials (records)."""
    chosen = tuple(OBJECTIVES[name] for name in ENGINE_OBJECTIVES)
    count = len(records)
    return {
        "method": method,
        "seconds": seconds,
        "values_s": [seconds],  # one sample: the figures' timing row reads it
        "items": count,
        "per_second": count / seconds,
        "startup_s": startup,
        "designs": count,
        "pareto": len(_pareto(tuple(records), chosen)),
        "failed": sum(r.state == "FAIL" for r in records),
        "infeasible": sum(r.state == "COMPLETE" and not r.feasible for r in records),
    }


def _pool_startup(workers: int) -> float:
    """Seconds until a spawned ``ProcessPoolExecutor(workers)`` has run a short task
    on each of its processes (the task's own 0.1 s taken off)."""
    start = time.perf_counter()
    with concurrent.futures.ProcessPoolExecutor(
        workers, mp_context=multiprocessing.get_context("spawn")
    ) as pool:
        for future in [pool.submit(time.sleep, 0.1) for _ in range(workers)]:
            future.result()
        return time.perf_counter() - start - 0.1


def _cluster_startup(workers: int) -> float:
    """Seconds until the study's ``LocalCluster`` of ``workers`` processes has them all
    connected (then it is closed)."""
    start = time.perf_counter()
    with dask_client(workers, None) as client:
        client.wait_for_workers(workers)
        return time.perf_counter() - start


def _peer_study(count: int, workers: int) -> list[TrialRecord]:
    """The peer of ``run_study``: the same study driven by hand with Optuna's ask/tell
    on a plain spawned ``ProcessPoolExecutor(workers)``, up to
    :data:`~spm_pin.optimize._engines.IN_FLIGHT_PER_THREAD` trials in flight per
    worker, each told as it completes. Its sampler is Optuna's NSGA-II with
    ``run_study``'s population and seed (one sampler for the study, as Optuna's
    documentation writes it; ``run_study`` seeds one per trial from (seed, number)).
    Constraints go to Optuna as ``run_study`` gives them: per trial on Optuna >= 5,
    through ``constraints_func`` before."""
    import optuna
    from optuna.trial import TrialState

    native = hasattr(optuna.trial.Trial, "set_constraint")
    names = ENGINE_OBJECTIVES

    def constraints_of(trial: Any) -> Sequence[float]:
        values: Sequence[float] = trial.user_attrs.get("constraints", [])
        return values

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        sampler = optuna.samplers.NSGAIISampler(
            population_size=PARETO_POPULATION,
            seed=PARETO_SEED,
            constraints_func=None if native else constraints_of,
        )
    directions: Any = [OBJECTIVES[name].direction for name in names]
    study = optuna.create_study(directions=directions, sampler=sampler)
    distributions: dict[str, Any] = {
        v.name: optuna.distributions.FloatDistribution(float(v.low), float(v.high))
        for v in ENGINE_SPACE.variables
    }
    records: list[TrialRecord] = []
    in_flight: dict[concurrent.futures.Future[Any], Any] = {}
    asked = 0
    with concurrent.futures.ProcessPoolExecutor(
        workers, mp_context=multiprocessing.get_context("spawn")
    ) as pool:
        while asked < count or in_flight:
            while asked < count and len(in_flight) < IN_FLIGHT_PER_THREAD * workers:
                trial = study.ask(distributions)
                arguments = (ENGINE_SPACE, dict(trial.params), names, ENGINE_SETTINGS)
                future = pool.submit(_evaluate_trial, *arguments, f"peer-{trial.number}")
                in_flight[future] = trial
                asked += 1
            done, _ = concurrent.futures.wait(
                in_flight, return_when=concurrent.futures.FIRST_COMPLETED
            )
            for future in done:
                trial = in_flight.pop(future)
                outcome = future.result()
                values = {k: float(v) for k, v in trial.params.items()}
                if outcome.scores is None:
                    study.tell(trial, state=TrialState.FAIL)
                    record = TrialRecord(trial.number, "FAIL", values, {}, {}, False, outcome.error)
                else:
                    if native:
                        for key, limit in outcome.constraints.items():
                            trial.set_constraint(key, limit)
                    else:
                        trial.set_user_attr("constraints", list(outcome.constraints.values()))
                    study.tell(trial, list(outcome.scores))
                    constraints = dict(outcome.constraints)
                    record = TrialRecord(
                        trial.number,
                        "COMPLETE",
                        values,
                        dict(zip(names, outcome.scores, strict=True)),
                        constraints,
                        all(c <= 0.0 for c in constraints.values()),
                        None,
                    )
                records.append(record)
    return sorted(records, key=lambda r: r.number)


def run_pareto(count: int) -> dict[str, Any]:
    """The time to a Pareto front of ``count`` designs: ``run_study`` on a Dask
    LocalCluster beside a ProcessPoolExecutor driven through Optuna's ask/tell (see
    the module)."""
    out: dict[str, Any] = {
        "designs": count,
        "objectives": list(ENGINE_OBJECTIVES),
        "variables": [v.name for v in ENGINE_SPACE.variables],
        "step_deg": ENGINE_SETTINGS.step_deg,
        "constraints": list(ENGINE_SETTINGS.constraint_names()),
        "sampler": f"optuna NSGAIISampler(population_size={PARETO_POPULATION}, seed={PARETO_SEED})",
        "workers": ENGINE_WORKERS,
        "in_flight_per_worker": IN_FLIGHT_PER_THREAD,
        "cpus": os.cpu_count(),
        "timing": "wall time of one run from the call to the answer, start-up included; "
        "startup_s: the cluster (pool) alone, measured apart",
    }
    try:
        import optuna
    except ImportError:
        out["ours"] = {"skipped": "optuna is not installed"}
        out["process_pool"] = {"skipped": "optuna is not installed"}
        return out
    level = optuna.logging.get_verbosity()
    optuna.logging.set_verbosity(logging.WARNING)  # no line per trial
    try:
        try:
            import distributed  # noqa: F401
        except ImportError:
            out["ours"] = {"skipped": "dask[distributed] is not installed"}
        else:
            startup = _cluster_startup(ENGINE_WORKERS)
            out["ours"] = {"load_average_before": _load_average()}
            start = time.perf_counter()
            result = run_study(
                ENGINE_SPACE,
                ENGINE_OBJECTIVES,
                count,
                settings=ENGINE_SETTINGS,
                seed=PARETO_SEED,
                population_size=PARETO_POPULATION,
                workers=ENGINE_WORKERS,
            )
            seconds = time.perf_counter() - start
            out["ours"].update(
                _pareto_entry(
                    "spm_pin.optimize.run_study(workers=2): Dask LocalCluster of 2 processes, "
                    "1 thread each",
                    seconds,
                    startup,
                    result.trials,
                )
            )
            out["ours"]["pareto_of_study"] = len(result.pareto)  # the study's own answer
        startup = _pool_startup(ENGINE_WORKERS)
        load = _load_average()
        start = time.perf_counter()
        records = _peer_study(count, ENGINE_WORKERS)
        seconds = time.perf_counter() - start
        out["process_pool"] = {
            "load_average_before": load,
            **_pareto_entry(
                "optuna ask/tell + concurrent.futures.ProcessPoolExecutor(2, spawn), "
                f"{IN_FLIGHT_PER_THREAD} trials in flight per worker",
                seconds,
                startup,
                records,
            ),
        }
    finally:
        optuna.logging.set_verbosity(level)
    if "skipped" not in out["ours"]:
        out["speed_ratio_ours_vs_peer"] = out["process_pool"]["seconds"] / out["ours"]["seconds"]
    return out


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
    results["engines"] = run_engines(sizes.engine_designs)
    results["pareto"] = run_pareto(sizes.pareto_designs)
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


def _pareto_table(pareto: dict[str, Any]) -> str:
    """The Pareto section of the report."""
    rows = []
    for label, key in (
        ("run_study, Dask LocalCluster", "ours"),
        ("peer: ask/tell + ProcessPoolExecutor", "process_pool"),
    ):
        entry = pareto[key]
        if "skipped" in entry:
            rows.append([label, "skipped", "-", "-", "-", "-", "-"])
            continue
        rows.append(
            [
                label,
                f"{entry['seconds']:.2f} s",
                format_rate(entry["per_second"]),
                str(entry["pareto"]),
                str(entry["failed"]),
                str(entry["infeasible"]),
                format_seconds(entry["startup_s"]),
            ]
        )
    ratio = pareto.get("speed_ratio_ours_vs_peer")
    return (
        f"Time to a Pareto front of {pareto['designs']} designs "
        f"({', '.join(pareto['objectives'])}, {pareto['step_deg']:g} deg; "
        f"{pareto['workers']} workers, {pareto['cpus']} CPUs; start-up included"
        + ("" if ratio is None else f"; ours {ratio:.2f}x the peer's speed")
        + ")\n"
        + format_table(
            ["engine", "time", "designs/s", "front", "failed", "infeasible", "start-up"], rows
        )
    )


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
    engines = results["engines"]
    load = engines["load_average_before"]
    load = "n/a" if load is None else f"{load:.2f}"
    engine_rows = []
    for label, key in (
        ("in process, one after the other", "in_process"),
        ("Dask LocalCluster (the study's engine)", "dask_local_cluster"),
        ("peer: ProcessPoolExecutor", "process_pool"),
    ):
        entry = engines[key]
        if "skipped" in entry:
            engine_rows.append([label, "-", "skipped", "-", "-", "-"])
            continue
        efficiency = entry["efficiency"]
        engine_rows.append(
            [
                label,
                str(entry["workers"]),
                f"{entry['seconds']:.2f} s",
                format_rate(entry["per_second"]),
                "-" if efficiency is None else f"{efficiency:.0%}",
                format_seconds(entry["startup_s"]) if "startup_s" in entry else "-",
            ]
        )
    engine_table = (
        f"Study evaluations of {engines['designs']} designs "
        f"({', '.join(engines['objectives'])}, {engines['step_deg']:g} deg; "
        f"{engines['cpus']} CPUs, load before {load}; "
        f"equal scores: {engines['equal_scores']})\n"
        + format_table(
            ["engine", "workers", "time", "scores/s", "efficiency", "start-up"], engine_rows
        )
    )
    pareto_table = _pareto_table(results["pareto"])
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
    return "\n\n".join([head, table, notes, engine_table, pareto_table, "\n".join(lines)])


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
