"""The headline figures of each benchmark, picked out of its JSON.

Each ``benchmarks/bench_<name>.py`` writes a JSON file of its own layout; one adapter
per benchmark (``figures_<name>``) turns it into :class:`Figure` rows: our raw samples
beside the peer's, measured in the same run, and the names of the targets the row
shows. :func:`analyse` adds a row for every target that no adapter places, so every
target reaches the suite even when a benchmark adds one. :mod:`benchmarks._suite`
stores the rows as pyperf benchmarks.

This module imports only the standard library.
"""

from __future__ import annotations

import dataclasses
import math
import statistics
from collections.abc import Callable, Mapping, Sequence
from typing import Any

__all__ = [
    "BENCHMARKS",
    "Analysis",
    "Benchmark",
    "Figure",
    "analyse",
    "timed",
    "valued",
]


# ----------------------------------------------------------------------- figures
@dataclasses.dataclass(frozen=True)
class Figure:
    """One row of the table: our figure beside the peer's, and the targets it carries.

    Attributes:
        key: Name of the row within its benchmark (stable: the pyperf benchmark's name
            is ``<benchmark>/<key>``).
        label: What the row measures (first column of the table).
        kind: ``"time"`` (samples in seconds) or ``"value"`` (one measured number in
            ``unit``: an accuracy, a fraction, a count).
        ours: Our samples [s], per item for batch calls; or ``(value,)``.
        unit: ``"s"`` for times; for values ``""``, ``"rad"``, ``"fraction"``,
            ``"count"``, ``"relative"`` ...
        items: Items per timed call (batch calls): ``ours`` and ``peer`` are already
            divided by it.
        peer_name: Short name of the peer, or None when there is none.
        peer: The peer's samples (or value), same unit as ours.
        ratio: How many times better ours is: the benchmark's own ratio when it has one
            (measured on the same inputs), else from the medians (see :func:`advantage`).
        higher_is_better: True for counts and fractions; False for times and errors.
        targets: Names of the benchmark's targets this row shows.
    """

    key: str
    label: str
    kind: str
    ours: tuple[float, ...]
    unit: str = "s"
    items: int = 1
    peer_name: str | None = None
    peer: tuple[float, ...] | None = None
    ratio: float | None = None
    higher_is_better: bool = False
    targets: tuple[str, ...] = ()


def advantage(ours: float | None, peer: float | None, *, higher_is_better: bool) -> float | None:
    """How many times better ``ours`` is than ``peer`` (None when undefined): peer / ours
    when lower is better, ours / peer when higher is better."""
    if ours is None or peer is None:
        return None
    top, bottom = (ours, peer) if higher_is_better else (peer, ours)
    if bottom == 0 or not math.isfinite(top / bottom):
        return None
    return top / bottom


def _samples(entry: Mapping[str, Any], items: int) -> tuple[float, ...]:
    return tuple(float(v) / items for v in entry["values_s"])


def timed(
    key: str,
    label: str,
    entry: Mapping[str, Any],
    *,
    per_item: bool = False,
    peer_name: str | None = None,
    peer: Mapping[str, Any] | None = None,
    ratio: float | None = None,
    targets: Sequence[str] = (),
) -> Figure:
    """A timing row from two timing entries of a benchmark's JSON.

    Args:
        entry: Our entry: ``values_s``, every sample (and ``items``).
        per_item: Divide by ``items`` (batch calls: per solution, per step).
        peer: The peer's entry, read the same way.
        ratio: The benchmark's own speed ratio; by default peer median / our median.
    """
    ours = _samples(entry, int(entry.get("items", 1)) if per_item else 1)
    theirs = None
    if peer is not None:
        theirs = _samples(peer, int(peer.get("items", 1)) if per_item else 1)
        if ratio is None:
            ratio = advantage(
                statistics.median(ours), statistics.median(theirs), higher_is_better=False
            )
    return Figure(
        key,
        label,
        "time",
        ours,
        items=int(entry.get("items", 1)) if per_item else 1,
        peer_name=peer_name if peer is not None else None,
        peer=theirs,
        ratio=ratio if peer is not None else None,
        targets=tuple(targets),
    )


def valued(
    key: str,
    label: str,
    value: float,
    *,
    unit: str = "",
    peer_name: str | None = None,
    peer: float | None = None,
    higher_is_better: bool = False,
    targets: Sequence[str] = (),
) -> Figure:
    """An accuracy or count row: one measured value, beside the peer's when given."""
    return Figure(
        key,
        label,
        "value",
        (float(value),),
        unit=unit,
        peer_name=peer_name if peer is not None else None,
        peer=None if peer is None else (float(peer),),
        ratio=advantage(float(value), peer, higher_is_better=higher_is_better),
        higher_is_better=higher_is_better,
        targets=tuple(targets),
    )


# ----------------------------------------------------------------------- adapters
def figures_kinematics(data: Mapping[str, Any]) -> list[Figure]:
    """FK and IK rates; the peer is scipy fsolve, one input per call."""
    results, peer = data["results"], data["peer"]
    fk = results["fk_home_reachable"]
    n_fk, n_ik = fk["n"], results["ik_reachable"]["n"]
    return [
        timed(
            "fk_home",
            f"kinematics: FK home mode, per solution (batch of {n_fk:,})",
            fk,
            per_item=True,
            peer_name="fsolve",
            peer=peer,
            ratio=peer["speed_ratio_ours_vs_peer"],
            targets=("fk_home_per_second", "fk_home_speedup_vs_fsolve"),
        ),
        timed(
            "fk_home_uniform",
            f"kinematics: FK home mode, uniform inputs, per input (batch of "
            f"{results['fk_home_uniform']['n']:,})",
            results["fk_home_uniform"],
            per_item=True,
            targets=("fk_home_uniform_per_second",),
        ),
        timed(
            "fk_home_single_call",
            "kinematics: FK home mode, one input per call",
            results["fk_home_single_call"],
            peer_name="fsolve",
            peer=peer,
            ratio=peer["speed_ratio_ours_single_call_vs_peer"],
        ),
        valued(
            "fk_home_residual",
            "kinematics: FK closure residual, max",
            max(fk["max_residual"], fk["max_reported_residual"]),
            peer_name="fsolve, converged answers",
            peer=peer["max_equation_residual_converged"],
            targets=("fk_home_max_residual",),
        ),
        valued(
            "fk_home_mode_rate",
            "kinematics: answers in the home assembly mode",
            peer["ours_home_rate"],
            unit="fraction",
            peer_name="fsolve",
            peer=peer["home_rate"],
            higher_is_better=True,
        ),
        timed(
            "fk_all_modes",
            "kinematics: FK all assembly modes, per input",
            results["fk_all_modes"],
            per_item=True,
        ),
        timed(
            "ik_home",
            f"kinematics: IK home mode, per rotation (batch of {n_ik:,})",
            results["ik_reachable"],
            per_item=True,
            targets=("ik_per_second",),
        ),
    ]


def figures_closure(data: Mapping[str, Any]) -> list[Figure]:
    """Newton projection per call; the peer is scipy least_squares, warm-started."""
    results, peer = data["results"], data["peer"]
    residual = max(
        results[key]["max_residual"] for key in ("warm_1deg", "warm_servo", "cold", "follow_study")
    )
    return [
        timed(
            "warm_1deg",
            "closure: project, warm start, 1 deg steps",
            results["warm_1deg"],
            peer_name="least_squares",
            peer=peer["default_tight"],
            ratio=peer["speed_ratio"],
            targets=("warm_median", "speedup_vs_least_squares"),
        ),
        timed(
            "warm_1deg_vs_tuned",
            "closure: project, warm start, vs tuned peer",
            results["warm_1deg"],
            peer_name="least_squares lm + exact Jacobian",
            peer=peer["lm_exact_jacobian_tight"],
            ratio=peer["speed_ratio_tuned"],
        ),
        timed(
            "warm_servo",
            "closure: project, warm start, servo path at 1 kHz",
            results["warm_servo"],
        ),
        timed("cold", "closure: project, cold from home", results["cold"]),
        timed(
            "follow_study",
            "closure: follow the study path, per point",
            results["follow_study"],
            per_item=True,
        ),
        valued(
            "max_residual",
            "closure: closure residual, max",
            residual,
            peer_name="least_squares",
            peer=peer["default_tight"]["max_residual"],
            targets=("max_residual",),
        ),
    ]


def figures_collision(data: Mapping[str, Any]) -> list[Figure]:
    """One full self-collision check; the peer is a triangle BVH per link."""
    results, peer = data["results"], data["peer"]
    workspace = results["map"]
    rows = [
        timed(
            "check_random",
            "collision: full self-collision check, random inputs",
            results["check_random"],
            peer_name="BVH per link",
            peer=results["peer_bvh"],
            ratio=peer["speed_ratio_ours_vs_peer"],
            targets=("check_median",),
        ),
        timed("check_path", "collision: check along a smooth path", results["check_path"]),
        timed("distances", "collision: exact distances, 19 pairs", results["distances"]),
    ]
    map_targets = ("map_1deg",) if "map_1deg" in data["targets"] else ()
    rows.append(
        Figure(
            "map",
            f"collision: workspace map at {workspace['step_deg']:g} deg "
            f"({workspace['points']:,} points, {workspace['workers']} processes)",
            "time",
            (float(workspace["parallel_s"]),),
            targets=map_targets,
        )
    )
    return rows


def figures_dynamics(data: Mapping[str, Any]) -> list[Figure]:
    """Simulated steps next to MuJoCo stepping the same MJCF; accuracy figures."""
    results, comparison = data["results"], data["comparison"]
    accuracy = data["accuracy"]
    stiff = accuracy["mujoco_stiff"]
    mujoco_closure = max(
        stiff["passive_hanging"]["mujoco_max_closure_residual"],
        stiff["driven"]["mujoco_max_closure_residual"],
    )
    theta_error = max(
        stiff["passive_hanging"]["max_theta_error_rad"], stiff["driven"]["max_theta_error_rad"]
    )
    return [
        timed(
            "step_euler_passive",
            "dynamics: simulator step, passive, semi-implicit Euler",
            results["ours_euler_passive"],
            per_item=True,
            peer_name="MuJoCo",
            peer=results["mujoco_euler_passive"],
            ratio=comparison["ours_euler_vs_mujoco_euler_python_loop"],
            targets=("steps_per_second",),
        ),
        timed(
            "step_euler_passive_c_loop",
            "dynamics: simulator step, passive, Euler, vs MuJoCo's C loop",
            results["ours_euler_passive"],
            per_item=True,
            peer_name="MuJoCo nstep",
            peer=results["mujoco_euler_passive_c_loop"],
        ),
        timed(
            "step_euler_servo",
            "dynamics: simulator step, servo-driven, Euler",
            results["ours_euler_servo"],
            per_item=True,
            peer_name="MuJoCo",
            peer=results["mujoco_euler_servo"],
            ratio=comparison["ours_euler_servo_vs_mujoco_euler_servo"],
        ),
        timed(
            "step_rk4_passive",
            "dynamics: simulator step, passive, RK4",
            results["ours_rk4_passive"],
            per_item=True,
            peer_name="MuJoCo",
            peer=results["mujoco_rk4_passive"],
        ),
        timed(
            "step_rk4_servo",
            "dynamics: simulator step, servo-driven, RK4",
            results["ours_rk4_servo"],
            per_item=True,
            peer_name="MuJoCo",
            peer=results["mujoco_rk4_servo"],
        ),
        timed(
            "inverse_trajectory",
            "dynamics: inverse dynamics along a move, per sample",
            results["inverse_trajectory"],
            per_item=True,
        ),
        timed(
            "forward_pinocchio",
            "dynamics: forward dynamics, one call",
            results["forward_pinocchio"],
            per_item=True,
        ),
        valued(
            "closure_drift",
            "dynamics: closure residual, max over every run",
            data["targets"]["closure_drift"]["value"],
            unit="rad",
            peer_name="MuJoCo stiff welds",
            peer=mujoco_closure,
            targets=("closure_drift",),
        ),
        valued(
            "energy_drift",
            f"dynamics: energy drift, RK4, {accuracy['energy']['duration_s']:g} s frictionless",
            accuracy["energy"]["relative_drift"],
            unit="relative",
            targets=("energy_drift",),
        ),
        valued(
            "mujoco_theta_agreement",
            f"dynamics: input angles against MuJoCo over {accuracy['duration_s']:g} s, max",
            theta_error,
            unit="rad",
            targets=("mujoco_theta_agreement",),
        ),
    ]


def figures_hardware(data: Mapping[str, Any]) -> list[Figure]:
    """The sync loop's stages on the emulated bus; Fast Sync Read beside plain."""
    results = data["results"]
    bus = results["bus"]
    return [
        timed(
            "loop_software",
            "hardware: sync loop, software part (kinematics + guard)",
            results["loop"]["software"],
            targets=("software_per_second",),
        ),
        timed("loop_cycle", "hardware: sync loop, whole cycle", results["loop"]["cycle"]),
        timed(
            "loop_with_model_cycle",
            "hardware: sync loop with the model update, whole cycle",
            results["loop_with_model"]["cycle"],
        ),
        timed(
            "sync_read",
            "hardware: Fast Sync Read of 3 servos",
            bus["sync_read_fast"],
            peer_name="plain Sync Read",
            peer=bus["sync_read_plain"],
        ),
        timed("guard_cold", "hardware: safety check of a new goal", results["guard_cold"]),
        timed(
            "control_cycle",
            "hardware: streaming cycle of a new orientation target (IK, guard, pulses)",
            results["control_cycle"]["fast"],
            peer_name="batch path",
            peer=results["control_cycle"]["batch"],
            targets=("control_cycle_median",),
        ),
        timed(
            "stream_software",
            "hardware: orientation stream, software part of a cycle (solve, limit, "
            "certified step, kinematics, guard)",
            results["stream"]["software"],
            peer_name="sync loop's software part, model updated",
            peer=results["loop_with_model"]["software"],
        ),
        timed(
            "control_cycle_python",
            "hardware: the same cycle, Python kernels (without the fast extra)",
            results["control_cycle_python"]["fast"],
        ),
    ]


def figures_calibration(data: Mapping[str, Any]) -> list[Figure]:
    """Identification time; the peer is the same solve with finite differences."""
    results, peer = data["results"], data["peer"]
    analytic = results["analytic"]
    return [
        timed(
            "analytic",
            f"calibration: identify {analytic['parameters']} parameters, "
            f"{analytic['readings']} readings",
            analytic,
            peer_name="2-point differences",
            peer=peer,
            ratio=peer["speed_ratio_ours_vs_peer"],
            targets=("identification_seconds",),
        ),
        valued(
            "identified",
            "calibration: parameters identified",
            analytic["identified"],
            unit="count",
            peer_name="2-point differences",
            peer=peer["identified"],
            higher_is_better=True,
            targets=("parameters_identified",),
        ),
        timed(
            "analytic_12",
            "calibration: identify 12 parameters (sensor frame free)",
            results["analytic_12"],
        ),
        timed("parse", "calibration: read the readings CSV", results["parse"]),
    ]


def figures_remote(data: Mapping[str, Any]) -> list[Figure]:
    """spm serve on loopback; the peer is the same query through the Python API."""
    results = data["results"]
    peer = results["peer"]
    rows = [
        timed(
            "get_state",
            "remote: GET /state round trip",
            results["get_state"],
            peer_name="backend.state() in process",
            peer=peer["state"],
        )
    ]
    for rate, key, targets in (
        (100, "stream_100", ()),
        (1000, "stream_1000", ("stream_1khz_p99",)),
    ):
        stream = results[key]
        readers = stream["readers"]["connections"]
        rows.append(
            timed(
                f"target_{rate}hz",
                f"remote: WS target answered, {rate:,} Hz, {readers} readers",
                stream["latency"],
                peer_name="backend.command() in process",
                peer=peer[f"command_{rate}"],
                targets=targets,
            )
        )
    slow = results.get("stream_1000_readers_100")
    if slow is not None and "latency" in slow:  # runs with readers at a display's rate
        rows.append(
            timed(
                "target_1000hz_readers_100hz",
                f"remote: WS target answered, 1,000 Hz, {slow['readers']['connections']} "
                "readers at 100 Hz",
                slow["latency"],
                peer_name="backend.command() in process",
                peer=peer["command_1000"],
            )
        )
    fast = results["stream_1000"]
    rows.append(
        valued(
            "answered_1khz",
            "remote: targets answered per second at 1 kHz",
            fast["answer_rate_hz"],
            unit="Hz",
            higher_is_better=True,
            targets=("stream_1khz_rate",),
        )
    )
    rows.append(
        valued(
            "delivered",
            "remote: targets answered and pushes received (nothing lost silently)",
            data["targets"]["nothing_lost_silently"]["value"],
            unit="fraction",
            higher_is_better=True,
            targets=("nothing_lost_silently",),
        )
    )
    return rows


def figures_envs(data: Mapping[str, Any]) -> list[Figure]:
    """Env steps of spm_pin/Orient-v0 (peer: SyncVectorEnv over single envs) and of
    spm_pin/OrientDynamic-v0 (peer: the task on MuJoCo, built the usual way); the
    dynamic environment's physics beside the constrained simulator."""
    results, peer = data["results"], data["peer"]
    vector = results["vector"]
    rows = [
        timed(
            "vector_step",
            f"envs: Orient-v0 batched step, per env step (N = {vector['n']:,})",
            vector,
            per_item=True,
            peer_name=f"SyncVectorEnv, N = {peer['n']}",
            peer=peer,
            ratio=peer["speed_ratio_ours_vs_peer"],
            targets=("vector_steps_per_second",),
        ),
        timed("single_step", "envs: Orient-v0 single env step", results["single"]),
    ]
    cover = data.get("cover")
    if cover is not None and "cover_only" in cover:  # runs with the cover_only rows
        level = cover["cover_level"]
        rows += [
            timed(
                "vector_step_cover",
                f"envs: Orient-v0 batched step with a cover (level {level}), per env step "
                f"(N = {cover['n']:,})",
                cover,
                per_item=True,
                peer_name=f"SyncVectorEnv, N = {peer['n']}",
                peer=peer,
                targets=("vector_cover_steps_per_second",),
            ),
            timed(
                "vector_step_cover_only",
                f"envs: Orient-v0 batched step, cover_only (level {level}), per env step "
                f"(N = {cover['cover_only']['n']:,})",
                cover["cover_only"],
                per_item=True,
                peer_name=f"SyncVectorEnv, N = {peer['n']}" + _beside(cover["cover_only"]),
                peer=cover["cover_only"].get("peer", peer),
                targets=("vector_cover_only_steps_per_second",),
            ),
        ]
    dynamic, mj = data.get("dynamic"), data.get("mujoco_peer")
    if dynamic is None:  # a run from before the dynamic environment's rows
        return rows
    ok = bool(mj and mj.get("available"))
    mj_vector = mj["vector"] if ok and mj else None
    mj_single = mj["single"] if ok and mj else None
    mj_name = f"MuJoCo env, SyncVectorEnv, N = {mj_vector['n']}" if mj_vector else None
    rows += [
        timed(
            "dynamic_vector_step",
            f"envs: OrientDynamic-v0 batched step, per env step (N = {dynamic['vector']['n']:,})",
            dynamic["vector"],
            per_item=True,
            peer_name=mj_name,
            peer=mj_vector,
        ),
        timed(
            "dynamic_vector_step_same_n",
            f"envs: OrientDynamic-v0 batched step, per env step "
            f"(N = {dynamic['vector_peer_n']['n']:,})",
            dynamic["vector_peer_n"],
            per_item=True,
            peer_name=mj_name,
            peer=mj_vector,
        ),
        timed(
            "dynamic_single_step",
            "envs: OrientDynamic-v0 single env step",
            dynamic["single"],
            peer_name="MuJoCo env",
            peer=mj_single,
        ),
    ]
    if "vector_cover_only" in dynamic:  # runs with the cover_only rows
        rows += [
            timed(
                "dynamic_vector_step_cover_only",
                f"envs: OrientDynamic-v0 batched step, cover_only, per env step "
                f"(N = {dynamic['vector_cover_only']['n']:,})",
                dynamic["vector_cover_only"],
                per_item=True,
                peer_name=None
                if mj_name is None
                else mj_name + _beside(dynamic["vector_cover_only"]),
                peer=dynamic["vector_cover_only"].get("peer", mj_vector),
                targets=("dynamic_vector_steps_per_second",),
            ),
        ]
    if "vector_cover_only_one_thread" in dynamic:  # runs with the threads' rows
        rows += [
            timed(
                "dynamic_vector_step_cover_only_one_thread",
                f"envs: OrientDynamic-v0 batched step, cover_only, one thread, per env "
                f"step (N = {dynamic['vector_cover_only_one_thread']['n']:,})",
                dynamic["vector_cover_only_one_thread"],
                per_item=True,
                peer_name=mj_name,
                peer=mj_vector,
            ),
        ]
    if "vector_cover_only" in dynamic:
        rows += [
            timed(
                "dynamic_single_step_cover_only",
                "envs: OrientDynamic-v0 single env step, cover_only",
                dynamic["single_cover_only"],
                peer_name="MuJoCo env" + _beside(dynamic["single_cover_only"]),
                peer=dynamic["single_cover_only"].get("peer", mj_single),
                targets=("dynamic_single_step_s",),
            ),
        ]
    rows += [
        valued(
            "dynamic_closure",
            "envs: OrientDynamic-v0 loop-closure error after the timed steps, max",
            dynamic["closure_error"],
            unit="rad",
            peer_name="MuJoCo env, default welds",
            peer=mj["closure_error"] if ok and mj else None,
        ),
    ]
    physics = data["physics"]
    batched = physics["reduced_batched"]
    rows += [
        timed(
            "reduced_step",
            "envs: reduced dynamics step, one robot",
            physics["reduced"],
            per_item=True,
            peer_name="constrained Simulator",
            peer=physics["constrained"],
        ),
        timed(
            "reduced_step_batched",
            f"envs: reduced dynamics step, per robot-step (N = {batched['n']:,})",
            batched,
            per_item=True,
            peer_name="constrained Simulator",
            peer=physics["constrained"],
        ),
        valued(
            "reduced_closure",
            f"envs: reduced dynamics closure error over a {physics['duration_s']:g} s swing, max",
            physics["reduced_closure_error"],
            unit="rad",
            peer_name="constrained Simulator",
            peer=physics["constrained_closure_error"],
        ),
    ]
    return rows


def _beside(entry: Mapping[str, Any]) -> str:
    """What a peer's name adds when the row timed it side by side (runs since the
    targets' rows alternate with their peer's in windows): ", side by side"."""
    return ", side by side" if "peer" in entry else ""


def figures_optimize(data: Mapping[str, Any]) -> list[Figure]:
    """One score of the safe orientation workspace (the peer: the workspace map); a
    study's evaluations per second in process and on a Dask LocalCluster (the peer: a
    ProcessPoolExecutor); the time to a Pareto front through ``run_study`` (the peer:
    the same study driven with Optuna's ask/tell on a ProcessPoolExecutor)."""
    results, peer = data["results"], data["peer"]
    rows = [
        timed(
            "score",
            "optimize: safe workspace score at 2 deg (prototype)",
            results["score"],
            peer_name="workspace_map, no clearance",
            peer=peer,
            ratio=peer["speed_ratio_ours_vs_peer"],
            targets=("score_2deg_s", "equal_to_map"),
        ),
        timed(
            "score_new_design",
            "optimize: safe workspace score of a new design (collision model built)",
            results["score_new_design"],
        ),
    ]
    if "engines" in results:  # runs from before the engines' rows have none
        rows += _optimize_engines(results["engines"])
    if "pareto" in results:
        rows += _optimize_pareto(results["pareto"])
    return rows


def _optimize_engines(engines: Mapping[str, Any]) -> list[Figure]:
    """Evaluations per second of a study's designs: in process, on Dask's LocalCluster
    beside the ProcessPoolExecutor (that one alone when Dask was skipped)."""
    count = engines["designs"]
    single, pool = engines["in_process"], engines["process_pool"]
    dask = engines.get("dask_local_cluster", {"skipped": "not in this run"})
    pool_name = f"ProcessPoolExecutor({pool['workers']})"
    rows = [
        valued(
            "engines_in_process",
            f"optimize: study evaluations per second, in process, one after the other "
            f"({count} designs)",
            single["per_second"],
            unit="1/s",
            higher_is_better=True,
        )
    ]
    if "skipped" in dask:
        rows += [
            valued(
                "engines_process_pool",
                f"optimize: study evaluations per second, peer {pool_name} alone "
                f"(Dask skipped: {dask['skipped']})",
                pool["per_second"],
                unit="1/s",
                higher_is_better=True,
            ),
            valued(
                "engines_process_pool_efficiency",
                f"optimize: scaling efficiency of the peer {pool_name}, "
                "rate / (workers x in-process rate)",
                pool["efficiency"],
                unit="fraction",
                higher_is_better=True,
            ),
        ]
    else:
        workers = dask["workers"]
        rows += [
            valued(
                "engines_dask",
                f"optimize: study evaluations per second, Dask LocalCluster of {workers} "
                "processes (the study's engine)",
                dask["per_second"],
                unit="1/s",
                peer_name=pool_name,
                peer=pool["per_second"],
                higher_is_better=True,
            ),
            valued(
                "engines_dask_efficiency",
                f"optimize: scaling efficiency on {workers} processes, "
                "rate / (workers x in-process rate)",
                dask["efficiency"],
                unit="fraction",
                peer_name=pool_name,
                peer=pool["efficiency"],
                higher_is_better=True,
            ),
        ]
    rows.append(
        valued(
            "engines_equal_scores",
            "optimize: every engine's scores equal to the in-process ones",
            1.0 if engines["equal_scores"] else 0.0,
            unit="fraction",
            higher_is_better=True,
        )
    )
    return rows


def _optimize_pareto(pareto: Mapping[str, Any]) -> list[Figure]:
    """The time to a Pareto front, run_study beside the ask/tell peer; the fronts'
    sizes (no ratio: a larger front is not a faster engine)."""
    ours, pool = pareto["ours"], pareto["process_pool"]
    if "skipped" in ours:
        return []
    available = "skipped" not in pool
    peer_name = f"Optuna ask/tell + ProcessPoolExecutor({pareto['workers']})"
    count, objectives = pareto["designs"], " and ".join(pareto["objectives"])
    return [
        timed(
            "pareto",
            f"optimize: time to a Pareto front of {count:,} designs ({objectives}; "
            f"run_study on a Dask LocalCluster of {pareto['workers']} processes, "
            "start-up included)",
            ours,
            peer_name=peer_name if available else None,
            peer=pool if available else None,
            ratio=pareto.get("speed_ratio_ours_vs_peer"),
        ),
        Figure(
            "pareto_front",
            f"optimize: designs on that Pareto front (feasible, non-dominated, of {count:,})",
            "value",
            (float(ours["pareto"]),),
            unit="count",
            peer_name=peer_name if available else None,
            peer=(float(pool["pareto"]),) if available else None,
            higher_is_better=True,
        ),
    ]


def figures_planning(data: Mapping[str, Any]) -> list[Figure]:
    """One plan between random safe inputs; the peers are OMPL's RRTConnect (when
    installed; on a subset of the pairs) and the straight line, certified."""
    results, peer = data["results"], data["peer"]
    plan, straight, ompl = results["plan"], peer["straight"], peer["ompl"]
    available = bool(ompl.get("available"))
    rows = [
        timed(
            "plan",
            f"planning: safe path between random safe inputs ({plan['n']:,} pairs)",
            plan,
            peer_name=f"OMPL RRTConnect + simplify, {ompl['n']} pairs" if available else None,
            peer=ompl if available else None,
            ratio=ompl["speed_ratio_ours_vs_peer"] if available else None,
        ),
        timed(
            "plan_cached",
            "planning: the same, with the certified cells precomputed "
            f"(level {results['cover']['fill_level']}, read from disk)",
            results["plan_cached"],
            targets=("plan_median_s", "plan_p99_s"),
        ),
        valued(
            "certified",
            "planning: paths certified as continuous safe motions",
            plan["certified_fraction"],
            unit="fraction",
            peer_name="OMPL RRTConnect + simplify" if available else None,
            peer=ompl["certified_fraction"] if available else None,
            higher_is_better=True,
            targets=("plan_success",),
        ),
        timed(
            "plan_vs_straight",
            "planning: safe path, beside certifying the straight line",
            plan,
            peer_name="straight line, SafeSet.certify",
            peer=straight,
            ratio=straight["speed_ratio_ours_vs_peer"],
        ),
        valued(
            "straight_safe",
            "planning: straight lines start-goal certified safe",
            1.0 - straight["unsafe_fraction"],
            unit="fraction",
            higher_is_better=True,
        ),
        timed("safe_set", "planning: build the safe set (prototype)", results["safe_set"]),
    ]
    duration = results["duration"]
    if duration.get("available"):
        rows.append(
            valued(
                "duration_vs_trapezoid",
                "planning: timed motion / trapezoid duration, straight lines (median)",
                duration["ratio_vs_trapezoid"]["median"],
                unit="relative",
            )
        )
    eye = results.get("eye")
    if eye is not None:  # older runs have no Agile Eye section
        rows.append(
            timed(
                "eye",
                f"planning: Agile Eye, safe path in 3-D input space ({eye['n']:,} pairs)",
                eye,
                targets=("eye_median_s",),
            )
        )
    return rows


@dataclasses.dataclass(frozen=True)
class Benchmark:
    """One benchmark of the suite.

    Attributes:
        name: ``bench_<name>.py``; also the JSON's ``benchmark`` entry.
        peer: What the figures are compared with (legend of the table).
        figures: The adapter: headline rows out of the benchmark's JSON.
    """

    name: str
    peer: str
    figures: Callable[[Mapping[str, Any]], list[Figure]]

    @property
    def module(self) -> str:
        """The module that ``python -m`` runs."""
        return f"benchmarks.bench_{self.name}"


#: Every benchmark, in the order they run and appear in the table.
BENCHMARKS: dict[str, Benchmark] = {
    b.name: b
    for b in (
        Benchmark(
            "kinematics",
            "scipy.optimize.fsolve on the 9 closure equations, one input per call",
            figures_kinematics,
        ),
        Benchmark(
            "closure",
            "scipy.optimize.least_squares on the same Pinocchio residual, warm-started "
            "(tolerances 1e-15, so that it reaches the same closure)",
            figures_closure,
        ),
        Benchmark(
            "collision",
            "Pinocchio computeCollisions on one coal triangle BVH per link, 19 pairs",
            figures_collision,
        ),
        Benchmark(
            "dynamics",
            "MuJoCo stepping the same MJCF at 1 ms, mj_step called from Python",
            figures_dynamics,
        ),
        Benchmark(
            "hardware",
            "no peer for the loop; the plain (one reply per servo) Sync Read beside the "
            "Fast Sync Read",
            figures_hardware,
        ),
        Benchmark(
            "calibration",
            "the same least-squares problem with scipy's 2-point finite-difference Jacobian",
            figures_calibration,
        ),
        Benchmark(
            "remote",
            "the same queries through the Python API in the same process "
            "(backend.state(), backend.command(): a goal through the guard)",
            figures_remote,
        ),
        Benchmark(
            "envs",
            "gymnasium.vector.SyncVectorEnv over single OrientEnv objects (N Python "
            "environments); for the dynamic environment, the same task built the usual way on "
            "MuJoCo (the exported MJCF, position actuators, mj_step at the same 1 ms step), "
            "one env and SyncVectorEnv over N copies; for its physics, the constrained "
            "Simulator",
            figures_envs,
        ),
        Benchmark(
            "optimize",
            "spm_pin.workspace.workspace_map at the same grid and thresholds "
            "(the full map, without the clearance field); for a study's evaluations, a "
            "plain concurrent.futures.ProcessPoolExecutor of as many processes; for the "
            "time to a Pareto front, the same study (Optuna NSGA-II, same population and "
            "seed) driven with Optuna's ask/tell on that pool",
            figures_optimize,
        ),
        Benchmark(
            "planning",
            "OMPL's RRTConnect + path simplification (Python bindings) in the same input "
            "space with the same validity check, on a subset of the pairs; and the "
            "straight line, certified",
            figures_planning,
        ),
    )
}


# ------------------------------------------------------------------------ targets
@dataclasses.dataclass(frozen=True)
class Analysis:
    """The rows and targets of one benchmark's JSON.

    Attributes:
        figures: The rows, in table order; each target is named by exactly one.
        targets: Every target by name: ``value``, ``threshold``, ``comparison``
            (``">="`` or ``"<="``), ``unit``, ``pass``, ``verdict`` and ``figure``
            (the key of its row).
        adapter_error: What went wrong when the adapter did not understand the JSON
            (its layout changed); the targets still get a row each.
    """

    figures: list[Figure]
    targets: dict[str, dict[str, Any]]
    adapter_error: str | None = None

    @property
    def all_pass(self) -> bool:
        """Every target passed."""
        return all(t["pass"] for t in self.targets.values())


def analyse(benchmark: Benchmark, data: Mapping[str, Any]) -> Analysis:
    """The rows and targets of one benchmark's JSON (``data``).

    A target goes to the first row that names it; a target that no row names gets a
    row of its own; one the JSON lacks (this run did not evaluate it, e.g. the
    1-degree map of a quick run) is left out.
    """
    try:
        figures = benchmark.figures(data)
        adapter_error = None
    except (KeyError, TypeError, ValueError, ZeroDivisionError) as exc:
        figures, adapter_error = [], f"{type(exc).__name__}: {exc}"
    raw = {k: v for k, v in data.get("targets", {}).items() if isinstance(v, Mapping)}
    owner: dict[str, str] = {}
    rows: list[Figure] = []
    for figure in figures:
        names = tuple(n for n in dict.fromkeys(figure.targets) if n in raw and n not in owner)
        owner.update(dict.fromkeys(names, figure.key))
        rows.append(dataclasses.replace(figure, targets=names))
    for name, record in raw.items():
        if name not in owner:
            value = float(record["value"]) if record.get("value") is not None else math.nan
            figure = valued(name, f"{benchmark.name}: {name}", value, targets=(name,))
            rows.append(dataclasses.replace(figure, unit=str(record.get("unit", ""))))
            owner[name] = name
    targets = {
        name: {
            "figure": owner[name],
            "value": record.get("value"),
            "threshold": record.get("threshold"),
            "comparison": record.get("comparison"),
            "unit": record.get("unit", ""),
            "pass": bool(record.get("pass")),
            "verdict": "PASS" if record.get("pass") else "FAIL",
        }
        for name, record in raw.items()
    }
    return Analysis(rows, targets, adapter_error)
