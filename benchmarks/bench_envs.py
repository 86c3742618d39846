"""Environment benchmark: steps of ``spm_pin/Orient-v0``, batched and one at a time.

Run from the repository root::

    python -m benchmarks.bench_envs [--out FILE.json] [--quick]

It prints a short table and writes JSON (default ``benchmarks/results/envs.json``).
Importing this module limits numpy to one thread (see ``_common.limit_to_one_thread``).

What is measured (the prototype, random starts and goals, seeded random actions,
``safety="clip"``):

1. ``vector``: one step of :class:`~spm_pin.envs.OrientVectorEnv` with N robots
   (N = 4096; 256 in a quick run), per env step.
2. ``single``: one step of :class:`~spm_pin.envs.OrientEnv`.
3. ``peer``: Gymnasium's ``SyncVectorEnv`` over 64 single environments (the usual way
   to batch an environment: N Python objects), per env step.
4. ``targets``: the kinematic environment's >= 1,000,000 env steps/s batched
   (N = 4096, one core).
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Sequence
from typing import Any

from ._common import limit_to_one_thread

#: Whether the one-thread limit was set before numpy was imported.
THREADS_LIMITED = limit_to_one_thread()

import gymnasium  # noqa: E402
import numpy as np  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin.envs import OrientEnv, OrientVectorEnv  # noqa: E402

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

#: Seed of the episodes and actions.
SEED = 20_250_228
#: The project's target [env steps/s], batched N = 4096.
TARGET_STEPS_PER_SECOND = 1_000_000.0


@dataclasses.dataclass(frozen=True)
class Sizes:
    """Batch sizes and repeat counts of one run."""

    batch: int
    peer_batch: int
    repeats: int
    single_repeats: int


FULL = Sizes(batch=4096, peer_batch=64, repeats=15, single_repeats=300)
QUICK = Sizes(batch=256, peer_batch=16, repeats=3, single_repeats=30)


def _stepper(env: Any, n: int) -> Any:
    """A call that steps ``env`` once with the next seeded random actions."""
    rng = np.random.default_rng(SEED)
    shape = (3,) if n == 0 else (n, 3)

    def step() -> Any:
        return env.step(rng.uniform(-1.0, 1.0, size=shape).astype(np.float32))

    return step


def run(sizes: Sizes, *, quick: bool) -> dict[str, Any]:
    """Run every section and return the JSON payload."""
    results: dict[str, dict[str, Any]] = {}
    vector = OrientVectorEnv(sizes.batch)
    vector.reset(seed=SEED)
    timed = time_call(_stepper(vector, sizes.batch), repeats=sizes.repeats)
    results["vector"] = {**timed.timing.summary(items=sizes.batch), "n": sizes.batch}
    single = OrientEnv(max_steps=10**7)
    single.reset(seed=SEED)
    timed = time_call(_stepper(single, 0), repeats=sizes.single_repeats)
    results["single"] = {**timed.timing.summary(items=1), "n": 1}
    peer_env = gymnasium.vector.SyncVectorEnv(
        [lambda: OrientEnv(max_steps=10**7) for _ in range(sizes.peer_batch)]
    )
    peer_env.reset(seed=SEED)
    timed = time_call(_stepper(peer_env, sizes.peer_batch), repeats=sizes.repeats)
    peer = {
        **timed.timing.summary(items=sizes.peer_batch),
        "n": sizes.peer_batch,
        "method": "gymnasium.vector.SyncVectorEnv over single OrientEnv objects",
    }
    peer["speed_ratio_ours_vs_peer"] = (
        results["vector"]["per_second"] / peer["per_second"] if peer["per_second"] else None
    )
    rate = results["vector"]["per_second"] if sizes.batch == 4096 else float("nan")
    targets: dict[str, Any] = {}
    if not quick:
        targets["vector_steps_per_second"] = target(
            rate, TARGET_STEPS_PER_SECOND, at_least=True, unit="1/s"
        )
    with_all_pass(targets)
    return {
        "benchmark": "envs",
        "machine": machine_info(("numpy", "gymnasium"), {"spm_pin": spm.__version__}),
        "config": {
            "quick": quick,
            "seed": SEED,
            "sizes": dataclasses.asdict(sizes),
            "threads_limited_before_numpy": THREADS_LIMITED,
            "control_period_s": vector.settings.control_period,
            "safety": vector.settings.safety,
            "timing": "perf_counter; 1 warm-up call; median/p95/p99 over repeated calls",
        },
        "results": results,
        "peer": peer,
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
    for label, entry in (
        (f"OrientVectorEnv, N = {results['vector']['n']}", results["vector"]),
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
    table = format_table(["case", "median per call", "p95", "env steps/s"], rows)
    lines = ["Targets"]
    record = payload["targets"].get("vector_steps_per_second")
    if record is None:
        lines.append("  (not evaluated in a quick run)")
    else:
        lines.append(
            f"  {'PASS' if record['pass'] else 'FAIL'}  batched env steps/s (N = 4096): "
            f"{format_rate(record['value'])} (>= {record['threshold']:,.0f})"
        )
    ratio = peer["speed_ratio_ours_vs_peer"]
    notes = f"batched vs SyncVectorEnv: {ratio:.1f}x more env steps/s"
    return "\n\n".join([head, table, notes, "\n".join(lines)])


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the summary, write the JSON; returns the exit code."""
    parser = standard_parser(
        "envs",
        "Env steps per second of spm-pin's Gymnasium environment, batched and single.",
        quick_help="small batches, few repeats (smoke test)",
    )
    return run_main(
        parser, lambda args: run(QUICK if args.quick else FULL, quick=args.quick), report, argv
    )


if __name__ == "__main__":
    sys.exit(main())
