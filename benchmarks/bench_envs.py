"""Environment benchmark: steps of ``spm_pin/Orient-v0`` and ``spm_pin/OrientDynamic-v0``,
batched and one at a time, beside the usual ways to build and batch such environments.

Run from the repository root::

    python -m benchmarks.bench_envs [--out FILE.json] [--quick]

It prints a short table and writes JSON (default ``benchmarks/results/envs.json``).
Importing this module limits numpy to one thread (see ``_common.limit_to_one_thread``).

What is measured (the prototype, random starts and goals, seeded random actions,
``safety="clip"``):

1. ``results.vector``: one step of :class:`~spm_pin.envs.OrientVectorEnv` with N robots
   (N = 4096; 256 in a quick run), per env step.
2. ``results.single``: one step of :class:`~spm_pin.envs.OrientEnv`.
3. ``peer``: Gymnasium's ``SyncVectorEnv`` over 64 single environments (the usual way
   to batch an environment: N Python objects), per env step.
4. ``dynamic``: one step of :class:`~spm_pin.envs.OrientDynamicVectorEnv` (position
   actuation, 20 physics steps of 1 ms per step) with N = 4096 robots and with the
   MuJoCo peer's N, and of :class:`~spm_pin.envs.OrientDynamicEnv`; the loop-closure
   error of the batch's states after the timed steps; the batch (N = 4096) and the
   single environment again with the cover of section 7 as their safe set
   (``cover_only``: no collision query in a step); the compiled physics of a batch
   runs on every core the process may use (in chunks of at least 256 robots;
   ``threads`` in each row), and the cover_only batch once more on one thread.
5. ``mujoco_peer``: the same task built the usual way on MuJoCo
   (:class:`benchmarks._mujoco_env.MujocoOrientEnv`: the exported MJCF, position
   actuators, ``mj_step`` with ``nstep`` 20 at the same 1 ms step), one environment
   and ``SyncVectorEnv`` over 64 copies; the welds' closure error after the timed steps
   (MuJoCo's default weld stiffness).
6. ``physics``: the dynamic environment's physics, the reduced dynamics
   (:class:`~spm_pin.dynamics.ReducedDynamics`, one robot), beside the constrained
   simulator (:class:`~spm_pin.dynamics.Simulator`), both semi-implicit Euler at 1 ms,
   the robot hanging and swinging freely for 10 s (1 s chunks timed); the loop-closure
   error after it.
7. ``cover``: the batched step of 1. with a saved cover of the safe set
   (``OrientSettings.cover``: states in certified cells pass the safety check by a
   table lookup): the cover's fill level, fill time and file size, the time per step,
   the fraction of the safety checks the lookup settled, and whether the robots
   reached the same states as without the cover (to 1e-9: with numba the step is
   compiled, and its rotation comes from another Newton); ``cover.cover_only``: the
   same with ``cover_only=True`` (the certified cells are the safe set: no collision
   check in a step), and how much of the safe set the cells hold (random safe
   inputs, safe grid vertices).
8. The targets' rows are timed side by side with a peer (:func:`side_by_side`): in
   alternating windows, about as long for each, each pooled over the windows, with
   the median of the windows' ratios (``peer``, ``paired_ratio_ours_vs_peer``). The
   kinematic cover_only batch beside ``SyncVectorEnv`` (20 windows of 5 calls and 1),
   the dynamic one beside MuJoCo's ``SyncVectorEnv`` (20 windows of 1 and 1), the
   dynamic single step beside MuJoCo's (50 windows of 200 steps and 20). On a shared
   or throttled CPU the speed changes in phases: 300 steps back to back (6 ms) fall
   in one of them whole; the windows spread over seconds, and a slow phase slows
   both alike.
9. ``targets``: the kinematic environment's >= 1,000,000 env steps/s batched
   (N = 4096, one core), without a cover, with the cover, and with cover_only; the
   dynamic environment's >= 200,000 env steps/s batched (N = 4096) and one env step
   <= 20 us, both with cover_only (its fastest safety check; section 4 has them
   with cover_only too, beside the rows without a cover).

Each timed call is one step with seeded random actions drawn before the timing.
Batched steps are timed with a garbage collection before each sample; single steps
(ours and MuJoCo's alike) back to back with the collector off after one collection,
as ``timeit`` times: a full collection of a heap holding thousands of robots before
each step of some microseconds would leave the CPU's caches cold and time that.

MuJoCo is optional: without it, ``mujoco_peer`` says so and the rest runs.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable, Sequence
from typing import Any

from ._common import limit_to_one_thread

#: Whether the one-thread limit was set before numpy was imported.
THREADS_LIMITED = limit_to_one_thread()

import importlib.util  # noqa: E402
import itertools  # noqa: E402
import math  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import gymnasium  # noqa: E402
import numpy as np  # noqa: E402
import numpy.typing as npt  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin import dynamics as D  # noqa: E402
from spm_pin.envs import (  # noqa: E402
    OrientDynamicEnv,
    OrientDynamicVectorEnv,
    OrientEnv,
    OrientSettings,
    OrientVectorEnv,
)
from spm_pin.envs._safe_lookup import SafeLookup  # noqa: E402
from spm_pin.kinematics import forward_kinematics  # noqa: E402
from spm_pin.planning import SafeCover, safe_set_of  # noqa: E402

from ._common import (  # noqa: E402
    format_rate,
    format_seconds,
    format_table,
    machine_info,
    run_main,
    standard_parser,
    target,
    time_alternating,
    time_call,
    with_all_pass,
)

FloatArray = npt.NDArray[np.float64]

#: Seed of the episodes and actions.
SEED = 20_250_228
#: The project's target [env steps/s], batched N = 4096.
TARGET_STEPS_PER_SECOND = 1_000_000.0
#: The dynamic environment's targets, judged with its fastest safety
#: check (``cover_only``): batched env steps/s (N = 4096) and one env step [s].
TARGET_DYNAMIC_STEPS_PER_SECOND = 200_000.0
TARGET_DYNAMIC_SINGLE_S = 20e-6


#: Physics step of the dynamic environment and of its peers [s].
DT = 1e-3
#: Where the free swing of the physics section starts [rad] (the robot hanging).
SWING_START = np.radians([20.0, -10.0, 5.0])
#: Goals drawn for the MuJoCo peer (from the kinematic environment's episodes).
PEER_GOALS = 256
#: Random inputs drawn to measure how much of the safe set a cover certifies.
CERTIFIED_SAMPLES = 20_000


@dataclasses.dataclass(frozen=True)
class Sizes:
    """Batch sizes, repeat counts and durations of one run."""

    batch: int
    peer_batch: int
    repeats: int
    single_repeats: int
    dynamic_batch: int
    dynamic_repeats: int
    dynamic_single_repeats: int
    # side by side with a peer (:func:`side_by_side`): (windows, our calls per window,
    # the peer's calls per window) of the targets' rows
    side_kinematic: tuple[int, int, int]  # the cover_only batch, SyncVectorEnv
    side_dynamic: tuple[int, int, int]  # the dynamic cover_only batch, MuJoCo's batch
    side_single: tuple[int, int, int]  # the dynamic cover_only single step, MuJoCo's
    swing_time: float  # [s] of the physics section
    swing_chunk: float  # [s] timed at a time
    cover_level: int  # finest level the cover of the ``cover`` section is filled to


FULL = Sizes(
    batch=4096,
    peer_batch=64,
    repeats=15,
    single_repeats=300,
    dynamic_batch=4096,
    dynamic_repeats=15,
    dynamic_single_repeats=300,
    side_kinematic=(20, 5, 1),
    side_dynamic=(20, 1, 1),
    side_single=(50, 200, 20),
    swing_time=10.0,
    swing_chunk=1.0,
    cover_level=3,
)
QUICK = Sizes(
    batch=256,
    peer_batch=16,
    repeats=3,
    single_repeats=30,
    dynamic_batch=64,
    dynamic_repeats=3,
    dynamic_single_repeats=5,
    side_kinematic=(2, 2, 1),
    side_dynamic=(2, 1, 1),
    side_single=(3, 5, 2),
    swing_time=0.2,
    swing_chunk=0.05,
    cover_level=0,
)


def _stepper(env: Any, n: int, calls: int) -> Any:
    """A call that steps ``env`` once with the next seeded random actions, drawn
    before the timing (``calls`` of them, then again from the first): the timed call
    is the step alone."""
    rng = np.random.default_rng(SEED)
    shape = (3,) if n == 0 else (n, 3)
    drawn = [rng.uniform(-1.0, 1.0, size=shape).astype(np.float32) for _ in range(calls)]
    turn = itertools.cycle(drawn)

    def step() -> Any:
        return env.step(next(turn))

    return step


def timed_steps(env: Any, n: int, repeats: int) -> dict[str, Any]:
    """``repeats`` timed steps of ``env`` (n robots; 0: a single env) by
    :func:`_stepper`, after one warm-up step: their summary per env step and ``n`` (1
    for a single env). A batch's samples each follow a garbage collection; a single
    env's run back to back (see the module)."""
    items = max(n, 1)
    timed = time_call(_stepper(env, n, repeats + 1), repeats=repeats, collect_each=n > 0)
    return {**timed.timing.summary(items=items), "n": items}


def closure_error(theta: FloatArray, R: FloatArray, design: spm.SPMDesign) -> float:
    """Largest |w_i(theta) . R v_i0 - cos(alpha2)| [rad-like] over robots (n, 3) with
    platform rotations R (n, 3, 3): how far the states are from closing the loops."""
    w = forward_kinematics(theta, design).w
    v = np.einsum("nij,kj->nki", R, design.v0)
    return float(np.abs(np.einsum("nki,nki->nk", w, v) - math.cos(design.alpha2)).max())


def bench_cover(
    sizes: Sizes, plain: OrientVectorEnv, path: Path, peer: Any, n_peer: int
) -> dict[str, Any]:
    """``OrientVectorEnv`` with a cover filled to ``cover_level`` and saved, per env
    step, stepped with the same episodes and actions as ``plain`` (already stepped by
    :func:`time_call` with ``repeats``): the fill time, the file's size, the fraction
    of the safety checks the lookup settled, the same states as ``plain``; the same
    with ``cover_only``, side by side with ``peer`` (``n_peer`` environments:
    :func:`side_by_side`)."""
    settings = OrientSettings()
    cover = SafeCover(safe_set_of(settings.the_design, settings.plan_settings))
    start = time.perf_counter()
    cover.fill(max_level=sizes.cover_level)
    fill_s = time.perf_counter() - start
    cover.save(path)
    size = path.stat().st_size
    start = time.perf_counter()
    env = OrientVectorEnv(sizes.batch, settings, cover=str(path))
    load_s = time.perf_counter() - start
    only = OrientVectorEnv(sizes.batch, settings, cover=str(path), cover_only=True)
    env.reset(seed=SEED)
    timed = timed_steps(env, sizes.batch, sizes.repeats)
    lookup = env.core.lookup
    assert lookup is not None
    only.reset(seed=SEED)
    timed_only = side_by_side(only, sizes.batch, peer, n_peer, sizes.side_kinematic)
    # How much of the safe set the certified cells hold: random inputs, checked.
    rng = np.random.default_rng(SEED)
    theta = rng.uniform(-math.pi, math.pi, size=(CERTIFIED_SAMPLES, 3))
    safe = env.core.safe_set.evaluate(theta).safe
    certified = SafeLookup(cover).covered(theta[safe])
    difference = max(
        float(np.abs(env.core.theta - plain.core.theta).max()),
        float(np.abs(env.core.R - plain.core.R).max()),
    )
    return {
        **timed,
        "compiled": bool(env.core.fused),
        "rows_stepped_by_numpy": env.core.handed_rows,
        "cover_only": {
            **timed_only,
            "compiled": bool(only.core.fused),
            "rows_stepped_by_numpy": only.core.handed_rows,
            "safe_vertices_kept": only.core.vertices.shape[0] / env.core.vertices.shape[0],
            "safe_inputs_certified": float(np.mean(certified)),
            "safe_inputs_drawn": int(np.count_nonzero(safe)),
        },
        "states_max_difference": difference,
        "cover_level": sizes.cover_level,
        "fill_s": fill_s,
        "load_s": load_s,
        "file_bytes": size,
        "covered_root_cells": lookup.covered_root_cells,
        "covered_finer_cells": lookup.covered_finer_cells,
        "checks": lookup.asked,
        "settled_fraction": lookup.settled / lookup.asked if lookup.asked else float("nan"),
        "same_states_as_without": difference <= 1e-9,
    }


def side_by_side(
    ours: Any, n: int, peer: Any | None, n_peer: int, side: tuple[int, int, int]
) -> dict[str, Any]:
    """Steps of ``ours`` (n robots; 0: a single env) and of ``peer`` (``n_peer``) timed
    in alternating windows (:func:`~benchmarks._common.time_alternating`; ``side``:
    windows, our calls and the peer's per window; a garbage collection before each
    sample of a batch): ours pooled over the windows, per env step, with the peer's
    as ``peer`` and the median of the windows' ratios of the time per env step
    (``paired_ratio_ours_vs_peer``); ours alone without a peer."""
    windows, count, count_peer = side
    items, items_peer = max(n, 1), max(n_peer, 1)
    calls = {"ours": (_stepper(ours, n, windows * count + 1), count)}
    if peer is not None:
        calls["peer"] = (_stepper(peer, n_peer, windows * count_peer + 1), count_peer)
    timings, ratio = time_alternating(calls, windows=windows, collect_each=n > 0)
    out: dict[str, Any] = {
        **timings["ours"].summary(items=items),
        "n": items,
        "windows": windows,
        "per_window": {name: calls_ for name, (_, calls_) in calls.items()},
    }
    if peer is not None:
        out["peer"] = {**timings["peer"].summary(items=items_peer), "n": items_peer}
        out["paired_ratio_ours_vs_peer"] = ratio * items_peer / items
    return out


def _mujoco(goals: FloatArray) -> Any | None:
    """The MuJoCo peer's single env on ``goals``, reset; None without MuJoCo."""
    if importlib.util.find_spec("mujoco") is None:
        return None
    from ._mujoco_env import MujocoOrientEnv

    env = MujocoOrientEnv(goals, physics_dt=DT, max_steps=10**7)
    env.reset(seed=SEED)
    return env


def _mujoco_vector(goals: FloatArray, n: int) -> Any | None:
    """``SyncVectorEnv`` over ``n`` copies of :func:`_mujoco`'s env, reset; None
    without MuJoCo."""
    copies = [env for env in (_mujoco(goals) for _ in range(n)) if env is not None]
    if not copies:
        return None
    vector = gymnasium.vector.SyncVectorEnv([_returning(env) for env in copies])
    vector.reset(seed=SEED)
    return vector


def bench_dynamic(sizes: Sizes, cover: Path, goals: FloatArray) -> dict[str, Any]:
    """``OrientDynamicVectorEnv`` at N = ``dynamic_batch`` and at the peer's N, and the
    single ``OrientDynamicEnv``, per env step; the batch at N = ``dynamic_batch`` and
    the single env again with the saved ``cover`` as their safe set (``cover_only``),
    the single env side by side with MuJoCo's on ``goals`` (:func:`side_by_side`)."""
    out: dict[str, Any] = {}
    closure = 0.0
    plain = OrientSettings()
    only = OrientSettings(cover=str(cover), cover_only=True)
    for key, n, settings, threads in (
        ("vector", sizes.dynamic_batch, plain, None),
        ("vector_peer_n", sizes.peer_batch, plain, None),
        ("vector_cover_only", sizes.dynamic_batch, only, None),
        ("vector_cover_only_one_thread", sizes.dynamic_batch, only, 1),
    ):
        env = OrientDynamicVectorEnv(n, settings)
        env.core.threads = threads
        env.reset(seed=SEED)
        if key == "vector_cover_only":  # the target's row: beside MuJoCo's batch
            peer = _mujoco_vector(goals, sizes.peer_batch)
            timing = side_by_side(env, n, peer, sizes.peer_batch, sizes.side_dynamic)
        else:
            timing = timed_steps(env, n, sizes.dynamic_repeats)
        out[key] = {**timing, "threads": env.core.chunks(n)}
        closure = max(closure, closure_error(env.core.theta, env.core.R, env.core.design))
    single = OrientDynamicEnv(plain, max_steps=10**7)
    single.reset(seed=SEED)
    out["single"] = timed_steps(single, 0, sizes.dynamic_single_repeats)
    ours = OrientDynamicEnv(only, max_steps=10**7)
    ours.reset(seed=SEED)
    out["single_cover_only"] = side_by_side(ours, 0, _mujoco(goals), 0, sizes.side_single)
    out["closure_error"] = closure
    out["physics_steps_per_env_step"] = single.core.substeps
    out["actuation"] = single.physics.actuation
    return out


def _returning(env: gymnasium.Env[Any, Any]) -> Callable[[], gymnasium.Env[Any, Any]]:
    """A maker of ``env`` (``SyncVectorEnv`` takes makers)."""
    return lambda: env


def bench_mujoco_peer(sizes: Sizes, goals: FloatArray) -> dict[str, Any]:
    """The task on MuJoCo built the usual way, one env and ``SyncVectorEnv`` of
    ``peer_batch`` copies, per env step; unavailable without MuJoCo."""
    single = _mujoco(goals)
    if single is None:
        return {"available": False, "reason": "mujoco is not installed"}
    out: dict[str, Any] = {
        "available": True,
        "method": "MujocoOrientEnv (benchmarks/_mujoco_env.py): urdf/spm.xml with position "
        f"actuators, mj_step nstep={single.frame_skip} at {DT:g} s per env step; "
        "gymnasium.vector.SyncVectorEnv over N copies",
        "physics_steps_per_env_step": single.frame_skip,
        "single": timed_steps(single, 0, sizes.single_repeats),
    }
    n = sizes.peer_batch
    vector = _mujoco_vector(goals, n)
    assert vector is not None
    out["vector"] = timed_steps(vector, n, sizes.repeats)
    out["closure_error"] = max(env.closure_residual() for env in [single, *vector.envs])
    return out


def bench_physics(sizes: Sizes) -> dict[str, Any]:
    """The reduced dynamics beside the constrained simulator: a free swing, hanging,
    timed in chunks; the loop-closure error over it."""
    robot = spm.build_robot()
    hanging = D.ClosedLoopDynamics(robot, gravity=(0.0, 0.0, 9.81))
    reduced = D.ReducedDynamics.from_dynamics(hanging)
    chunk = max(1, round(sizes.swing_chunk / DT))
    chunks = max(1, round(sizes.swing_time / sizes.swing_chunk))
    state: dict[str, FloatArray] = {
        "theta": SWING_START[None].copy(),
        "rate": np.zeros((1, 3)),
    }
    state["R"] = reduced.rotation(state["theta"])
    drift = {"reduced": 0.0, "constrained": 0.0}

    def swing_reduced() -> None:
        theta, rate, R = state["theta"], state["rate"], state["R"]
        for _ in range(chunk):
            step = reduced.step(theta, rate, None, DT, integrator="euler", reference=R)
            theta, rate, R = step.theta, step.theta_dot, step.R
        state.update(theta=theta, rate=rate, R=R)
        error = closure_error(theta, reduced.rotation(theta, R), robot.design)
        drift["reduced"] = max(drift["reduced"], error)

    simulator = D.Simulator(hanging, dt=DT, integrator="euler", state=SWING_START)

    def swing_constrained() -> None:
        error = simulator.run(chunk * DT, record_every=chunk).max_closure_residual
        drift["constrained"] = max(drift["constrained"], float(error))

    timed = time_call(swing_reduced, repeats=chunks, warmup=0)
    timed_c = time_call(swing_constrained, repeats=chunks, warmup=0)
    n = sizes.dynamic_batch
    rng = np.random.default_rng(SEED)
    theta0 = SWING_START + rng.uniform(-0.05, 0.05, (n, 3))
    R0 = reduced.rotation(theta0)
    batch_steps = round(0.02 / DT)  # one control period

    def swing_batch() -> None:
        theta, rate, R = theta0, np.zeros_like(theta0), R0
        for _ in range(batch_steps):
            step = reduced.step(theta, rate, None, DT, integrator="euler", reference=R)
            theta, rate, R = step.theta, step.theta_dot, step.R

    timed_b = time_call(swing_batch, repeats=sizes.dynamic_repeats)
    steps = chunk * chunks
    batched = {**timed_b.timing.summary(items=n * batch_steps), "n": n, "steps": batch_steps}
    ours = {**timed.timing.summary(items=chunk), "n": 1, "steps": steps}
    peer = {**timed_c.timing.summary(items=chunk), "n": 1, "steps": steps}
    return {
        "duration_s": steps * DT,
        "dt_s": DT,
        "reduced": ours,
        "reduced_batched": batched,
        "constrained": peer,
        "speed_ratio_reduced_vs_constrained": peer["median_s"] / ours["median_s"],
        "speed_ratio_reduced_batched_vs_constrained": peer["per_item_s"] / batched["per_item_s"],
        "reduced_closure_error": drift["reduced"],
        "constrained_closure_error": drift["constrained"],
        "final_theta_rad": {
            "reduced": state["theta"][0].tolist(),
            "constrained": simulator.theta.tolist(),
        },
    }


def run(sizes: Sizes, *, quick: bool) -> dict[str, Any]:
    """Run every section and return the JSON payload."""
    results: dict[str, dict[str, Any]] = {}
    vector = OrientVectorEnv(sizes.batch)
    vector.reset(seed=SEED)
    results["vector"] = timed_steps(vector, sizes.batch, sizes.repeats)
    folder = tempfile.TemporaryDirectory()
    cover_path = Path(folder.name) / "cover.npz"
    peer_env = gymnasium.vector.SyncVectorEnv(
        [lambda: OrientEnv(max_steps=10**7) for _ in range(sizes.peer_batch)]
    )
    peer_env.reset(seed=SEED)
    cover = bench_cover(sizes, vector, cover_path, peer_env, sizes.peer_batch)
    cover["speed_ratio_vs_without"] = results["vector"]["median_s"] / cover["median_s"]
    single = OrientEnv(max_steps=10**7)
    single.reset(seed=SEED)
    results["single"] = timed_steps(single, 0, sizes.single_repeats)
    peer = {
        **timed_steps(peer_env, sizes.peer_batch, sizes.repeats),
        "method": "gymnasium.vector.SyncVectorEnv over single OrientEnv objects",
    }
    peer["speed_ratio_ours_vs_peer"] = (
        results["vector"]["per_second"] / peer["per_second"] if peer["per_second"] else None
    )
    dynamic = bench_dynamic(sizes, cover_path, vector.core.goal[:PEER_GOALS].copy())
    folder.cleanup()
    mujoco_peer = bench_mujoco_peer(sizes, vector.core.goal[:PEER_GOALS].copy())
    if mujoco_peer["available"]:
        mujoco_peer["speed_ratio_ours_vs_peer"] = {
            "vector": dynamic["vector"]["per_second"] / mujoco_peer["vector"]["per_second"],
            "vector_same_n": dynamic["vector_peer_n"]["per_second"]
            / mujoco_peer["vector"]["per_second"],
            "single": mujoco_peer["single"]["median_s"] / dynamic["single"]["median_s"],
        }
    physics = bench_physics(sizes)
    full = sizes.batch == 4096
    rate = results["vector"]["per_second"] if full else float("nan")
    rate_cover = cover["per_second"] if full else float("nan")
    rate_only = cover["cover_only"]["per_second"] if full else float("nan")
    targets: dict[str, Any] = {}
    if not quick:
        targets["vector_steps_per_second"] = target(
            rate, TARGET_STEPS_PER_SECOND, at_least=True, unit="1/s"
        )
        targets["vector_cover_steps_per_second"] = target(
            rate_cover, TARGET_STEPS_PER_SECOND, at_least=True, unit="1/s"
        )
        targets["vector_cover_only_steps_per_second"] = target(
            rate_only, TARGET_STEPS_PER_SECOND, at_least=True, unit="1/s"
        )
        targets["dynamic_vector_steps_per_second"] = target(
            dynamic["vector_cover_only"]["per_second"] if full else float("nan"),
            TARGET_DYNAMIC_STEPS_PER_SECOND,
            at_least=True,
            unit="1/s",
        )
        targets["dynamic_single_step_s"] = target(
            dynamic["single_cover_only"]["median_s"],
            TARGET_DYNAMIC_SINGLE_S,
            at_least=False,
            unit="s",
        )
    with_all_pass(targets)
    return {
        "benchmark": "envs",
        "machine": machine_info(
            ("numpy", "gymnasium", "mujoco", "pin"), {"spm_pin": spm.__version__}
        ),
        "config": {
            "quick": quick,
            "seed": SEED,
            "sizes": dataclasses.asdict(sizes),
            "threads_limited_before_numpy": THREADS_LIMITED,
            "control_period_s": vector.settings.control_period,
            "physics_dt_s": DT,
            "safety": vector.settings.safety,
            "timing": "perf_counter; 1 warm-up call; median/p95/p99 over repeated calls",
        },
        "results": results,
        "cover": cover,
        "peer": peer,
        "dynamic": dynamic,
        "mujoco_peer": mujoco_peer,
        "physics": physics,
        "targets": targets,
    }


def report(payload: dict[str, Any]) -> str:
    """The human-readable summary of a run."""
    config, results, peer = payload["config"], payload["results"], payload["peer"]
    threads = "1 thread" if config["threads_limited_before_numpy"] else "threads not limited"
    head = f"spm-pin environment benchmark: prototype, {threads}" + (
        ", QUICK" if config["quick"] else ""
    )
    rows = []
    cover = payload["cover"]
    for label, entry in (
        (f"OrientVectorEnv, N = {results['vector']['n']}", results["vector"]),
        (f"OrientVectorEnv + cover (level {cover['cover_level']}), N = {cover['n']}", cover),
        (
            f"OrientVectorEnv, cover_only (level {cover['cover_level']}), N = {cover['n']}",
            cover["cover_only"],
        ),
        ("OrientEnv, one step", results["single"]),
        (f"peer: SyncVectorEnv, N = {peer['n']}", peer),
    ):
        rows.append(
            [
                label,
                format_seconds(entry["median_s"]),
                format_seconds(entry["p95_s"]),
                format_rate(entry["per_second"]),
            ]
        )
    dynamic, mj = payload["dynamic"], payload["mujoco_peer"]
    cases = [
        (f"OrientDynamicVectorEnv, N = {dynamic['vector']['n']}", dynamic["vector"]),
        (f"OrientDynamicVectorEnv, N = {dynamic['vector_peer_n']['n']}", dynamic["vector_peer_n"]),
        (
            f"OrientDynamicVectorEnv, cover_only, N = {dynamic['vector_cover_only']['n']}, "
            f"{dynamic['vector_cover_only']['threads']} threads",
            dynamic["vector_cover_only"],
        ),
        (
            f"OrientDynamicVectorEnv, cover_only, N = {dynamic['vector_cover_only']['n']}, "
            "one thread",
            dynamic["vector_cover_only_one_thread"],
        ),
        ("OrientDynamicEnv, one step", dynamic["single"]),
        ("OrientDynamicEnv, cover_only, one step", dynamic["single_cover_only"]),
    ]
    if mj["available"]:
        cases += [
            (f"peer: MuJoCo env, SyncVectorEnv, N = {mj['vector']['n']}", mj["vector"]),
            ("peer: MuJoCo env, one step", mj["single"]),
        ]
    sides = (
        ("cover_only batch", f"SyncVectorEnv, N = {peer['n']}", cover["cover_only"]),
        ("dynamic cover_only batch", "MuJoCo env, SyncVectorEnv", dynamic["vector_cover_only"]),
        ("dynamic cover_only step", "MuJoCo env, one step", dynamic["single_cover_only"]),
    )
    for _, name, side in sides:
        if "peer" in side:
            cases.append((f"peer: {name} (side by side)", side["peer"]))
    for label, entry in cases:
        rows.append(
            [
                label,
                format_seconds(entry["median_s"]),
                format_seconds(entry["p95_s"]),
                format_rate(entry["per_second"]),
            ]
        )
    table = format_table(["case", "median per call", "p95", "env steps/s"], rows)
    lines = ["Targets"]
    if "vector_steps_per_second" not in payload["targets"]:
        lines.append("  (not evaluated in a quick run)")
    for key, what in (
        ("vector_steps_per_second", ""),
        ("vector_cover_steps_per_second", ", cover"),
        ("vector_cover_only_steps_per_second", ", cover_only"),
        ("dynamic_vector_steps_per_second", ", dynamic, cover_only"),
    ):
        record = payload["targets"].get(key)
        if record is not None:
            lines.append(
                f"  {'PASS' if record['pass'] else 'FAIL'}  batched env steps/s (N = 4096"
                f"{what}): {format_rate(record['value'])} (>= {record['threshold']:,.0f})"
            )
    single = payload["targets"].get("dynamic_single_step_s")
    if single is not None:
        lines.append(
            f"  {'PASS' if single['pass'] else 'FAIL'}  one dynamic env step (cover_only): "
            f"{format_seconds(single['value'])} (<= {format_seconds(single['threshold'])})"
        )
    ratio = peer["speed_ratio_ours_vs_peer"]
    notes = [
        f"batched vs SyncVectorEnv: {ratio:.1f}x more env steps/s",
        *(
            f"{what} side by side with its peer: {side['windows']} windows of "
            + " and ".join(f"{count} ({who})" for who, count in side["per_window"].items())
            + " calls, pooled; ours faster by the median of the windows' ratios: "
            f"{1.0 / side.get('paired_ratio_ours_vs_peer', math.nan):,.1f}x"
            for what, _, side in sides
            if "peer" in side  # the peer may be missing (MuJoCo not installed)
        ),
        f"cover of level {cover['cover_level']}: filled in {cover['fill_s']:.1f} s, "
        f"{cover['file_bytes'] / 1e6:.2f} MB, loaded in {cover['load_s']:.2f} s; the lookup "
        f"settled {100 * cover['settled_fraction']:.1f}% of {cover['checks']:,} safety "
        f"checks; {cover['speed_ratio_vs_without']:.2f}x the env steps/s without it; same "
        f"states as without: {cover['same_states_as_without']}",
        f"cover_only: the certified cells hold "
        f"{100 * cover['cover_only']['safe_inputs_certified']:.1f}% of "
        f"{cover['cover_only']['safe_inputs_drawn']:,} random safe inputs and "
        f"{100 * cover['cover_only']['safe_vertices_kept']:.1f}% of the safe grid "
        f"vertices (starts and goals); rows stepped by numpy: "
        f"{cover['cover_only']['rows_stepped_by_numpy']:,}",
    ]
    if mj["available"]:
        r = mj["speed_ratio_ours_vs_peer"]
        notes.append(
            f"dynamic vs MuJoCo peer: batched {r['vector']:.2f}x (same N: "
            f"{r['vector_same_n']:.2f}x) the env steps/s, single step {r['single']:.3f}x "
            f"as fast; closure error after the timed steps: ours "
            f"{dynamic['closure_error']:.1e}, MuJoCo welds {mj['closure_error']:.1e} rad"
        )
    else:
        notes.append(f"MuJoCo peer not run: {mj['reason']}")
    ph = payload["physics"]
    notes.append(
        f"physics, {ph['duration_s']:g} s free swing: reduced dynamics "
        f"{format_seconds(ph['reduced']['per_item_s'])} per step, constrained simulator "
        f"{format_seconds(ph['constrained']['per_item_s'])} "
        f"({ph['speed_ratio_reduced_vs_constrained']:.2f}x; batched, N = "
        f"{ph['reduced_batched']['n']}: {format_seconds(ph['reduced_batched']['per_item_s'])} "
        f"per robot-step, {ph['speed_ratio_reduced_batched_vs_constrained']:.2f}x); "
        f"closure error: reduced "
        f"{ph['reduced_closure_error']:.1e}, constrained {ph['constrained_closure_error']:.1e}"
    )
    return "\n\n".join([head, table, "\n".join(notes), "\n".join(lines)])


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the summary, write the JSON; returns the exit code."""
    parser = standard_parser(
        "envs",
        "Env steps per second of spm-pin's Gymnasium environments, batched and single, "
        "beside SyncVectorEnv and a MuJoCo environment.",
        quick_help="small batches, few repeats (smoke test)",
    )
    return run_main(
        parser, lambda args: run(QUICK if args.quick else FULL, quick=args.quick), report, argv
    )


if __name__ == "__main__":
    sys.exit(main())
