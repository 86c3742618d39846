"""Hardware benchmark: the model-servo sync loop against the emulated XM540-W150 bus.

Run from the repository root::

    python -m benchmarks.bench_hardware [--out FILE.json] [--quick]

It prints a table and writes JSON (default ``benchmarks/results/hardware.json``).

The emulated bus runs in its own process on a pseudo-terminal and the unmodified
dynamixel-sdk talks to it, as to a U2D2 adapter, so the bus stages include the SDK and
the terminal but not the wire. Both ends run deliberately at 1 Mbit/s (the emulator's
default is the servos' factory default, 57600 bit/s), and the packet timeout allows
for the emulator's latency on a loaded machine (``LATENCY_TIMER_MS``). What is
measured:

1. ``bus``: one sync read of the state block of 3 servos (fast and plain) and one sync
   write of 3 goal positions, per call.
2. ``loop``: :meth:`ServoSync.step` streaming a pre-checked path (home to the study's
   input [60, 90, 120] deg and back) as fast as it goes, with the time of each stage:
   read (sync read), kinematics (home-mode FK; with the model update also the closed
   configuration q), guard (the checks of the goal: static ones cached by the path
   check, speed and acceleration every cycle), write (sync write). Twice: without and
   with the model update. Stage times are CPU time of the loop's thread
   (:func:`time.thread_time`; the SDK busy-waits, so a read costs its wait too), so
   other processes on busy cores do not change the verdict; the whole cycle is
   wall-clock.
3. ``guard``: the static checks of goals not seen before (FK, Jacobian, collisions),
   one goal per call, and the whole-path check per sample.
4. ``wire``: the bytes one cycle puts on a real 1 Mbps bus (10 bits a byte, Return
   Delay Time 0), to add to the loop time on real hardware.
5. ``control_cycle``: one streaming cycle of a new orientation target (inverse
   kinematics, the guard's static checks, Goal Positions) on the single-input fast
   path with its kernels compiled by numba (extra ``fast``), with its stages, beside
   the batch path (the same calls on (1, 3) arrays); ``control_cycle_python``: the
   same cycle with the Python kernels (``SPM_PIN_JIT=0``, in a child process), what a
   user without the extra gets.
6. ``stream``: :class:`~spm_pin.hardware.orientation.OrientationStream` tracking the
   platform rotations of the loop's path, one target a cycle: the software part of a
   cycle (thread CPU time without the bus stages), and the stream's own part of it
   (solve, rate limit, the step certified in the safe set).
7. ``targets``: the software part of a cycle (kinematics + guard, no model update) at
   >= 500 Hz; the streaming cycle's median <= 100 us.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from typing import Any

from ._common import limit_to_one_thread

#: Whether the one-thread limit was set before numpy was imported.
THREADS_LIMITED = limit_to_one_thread()

import numpy as np  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin import _jit  # noqa: E402
from spm_pin.hardware import (  # noqa: E402
    EmulatedBus,
    HardwareConfig,
    SafetyGuard,
    SafetyLimits,
    ServoBus,
    ServoSettings,
    ServoSync,
    plan_linear,
)
from spm_pin.hardware.driver import STATE_BLOCK  # noqa: E402
from spm_pin.hardware.emulated_bus import LATENCY_TIMER_MS  # noqa: E402
from spm_pin.hardware.joints import JointMap  # noqa: E402

from ._common import (  # noqa: E402
    Timing,
    format_count,
    format_rate,
    format_seconds,
    format_table,
    machine_info,
    run_main,
    standard_parser,
    target,
    time_each,
    with_all_pass,
)

#: The study's demonstration input [deg].
DEMO_DEG = (60.0, 90.0, 120.0)
#: The project's target for the software part of a cycle [Hz].
TARGET_SOFTWARE_RATE = 500.0
#: The project's target for one streaming cycle (target -> IK -> guard -> pulses),
#: median [s].
TARGET_CONTROL_CYCLE_S = 100e-6
#: Loop rate the streamed path is planned for [Hz] (faster than the loop runs, so the
#: commanded speed stays below the guard's limit).
PLAN_RATE_HZ = 1000.0
#: Seed of the random goals of the guard section.
SEED = 20_260_811
#: Line rate of the wire-time estimate and of the emulated bus [bit/s] and bits per
#: byte (start, 8, stop). Deliberately 1 Mbit/s, the rate a 3-servo robot's loop is set
#: to, not the emulator's default (57600, the servos' factory default).
WIRE_BAUD = 1_000_000
BITS_PER_BYTE = 10

#: Sizes: bus calls, loop cycles, cold guard checks, and the fraction of the way to
#: the demonstration input that the streamed path goes (quick: a short path, so that
#: checking it whole before the first command stays short).
SIZES: dict[str, dict[str, float]] = {
    "full": {"bus": 1000, "cycles": 2000, "guard": 300, "reach": 1.0},
    "quick": {"bus": 60, "cycles": 150, "guard": 20, "reach": 0.05},
}


def _config(port: str) -> HardwareConfig:
    return HardwareConfig(
        port=port,
        baudrate=WIRE_BAUD,  # deliberately 1 Mbit/s: see WIRE_BAUD
        latency_timer_ms=LATENCY_TIMER_MS,
        rate_hz=PLAN_RATE_HZ,
        servo=ServoSettings(profile_velocity=4.0, profile_acceleration=40.0),
        safety=SafetyLimits(max_speed=2.0, max_acceleration=10.0),
    )


def bench_bus(bus: ServoBus, n: int) -> dict[str, Any]:
    """Sync read (fast and plain) and sync write, one call per sample."""
    results: dict[str, Any] = {}
    for name, fast in (("sync_read_fast", True), ("sync_read_plain", False)):
        bus.fast_sync_read = fast
        timing, _ = time_each(lambda _: bus.sync_read(), list(range(n)), warmup=5)
        results[name] = {**timing.summary(), "n": n}
    bus.fast_sync_read = True
    goals = bus.sync_read().goal
    targets = dict(zip(bus.ids, goals, strict=True))
    timing, _ = time_each(lambda _: bus.sync_write_goals(targets), list(range(n)), warmup=5)
    results["sync_write"] = {**timing.summary(), "n": n}
    return results


def _stage_summary(samples: list[dict[str, float]], total: list[float]) -> dict[str, Any]:
    stages = {}
    for stage in ("read", "kinematics", "view", "guard", "write"):
        values = [s[stage] for s in samples]
        stages[stage] = Timing(tuple(values)).summary()
    software = [s["kinematics"] + s["guard"] for s in samples]
    return {
        "cycles": len(samples),
        "stages": stages,
        "software": Timing(tuple(software)).summary(),
        "cycle": Timing(tuple(total)).summary(),
    }


def bench_loop(
    bus: ServoBus,
    emulated: EmulatedBus,
    guard: SafetyGuard,
    cycles: int,
    reach: float,
    *,
    update_model: bool,
) -> dict[str, Any]:
    """Stream a pre-checked path through ServoSync.step; time every stage."""
    config = _config(emulated.port)
    robot = guard.robot
    # Stage times in CPU time of this thread: what the software costs, which other
    # processes on busy cores do not inflate (the cycle below is wall-clock).
    sync = ServoSync(
        bus, config, robot=robot, guard=guard, update_model=update_model, clock=time.thread_time
    )
    emulated.reset()
    try:
        sync.start()
        limits = config.safety
        out = plan_linear(
            sync.goal,  # type: ignore[arg-type]
            reach * np.radians(DEMO_DEG),
            max_speed=limits.max_speed,
            max_acceleration=limits.max_acceleration,
            period=config.period,
        )
        back = plan_linear(
            out[-1],
            np.zeros(3),
            max_speed=limits.max_speed,
            max_acceleration=limits.max_acceleration,
            period=config.period,
        )
        path = np.vstack([out, back])
        check_start = time.perf_counter()
        guard.check_path(path, period=config.period, start=sync.goal).require()
        check_time = time.perf_counter() - check_start
        samples: list[dict[str, float]] = []
        totals: list[float] = []
        sent = 0
        for k in range(cycles + 20):
            goal = path[k % len(path)]  # home -> demo -> home, again and again
            start = time.perf_counter()
            result = sync.step(goal)
            elapsed = time.perf_counter() - start
            if not result.sent:
                continue
            sent += 1
            if k >= 20:  # warm-up cycles
                samples.append(result.timings)
                totals.append(elapsed)
        summary = _stage_summary(samples, totals)
        summary["path_samples"] = len(path)
        summary["path_check_s"] = check_time
        summary["path_check_per_sample_s"] = check_time / len(path)
        summary["sent"] = sent
        summary["refused_or_failed"] = cycles + 20 - sent
        summary["update_model"] = update_model
        return summary
    finally:
        sync.release()


def bench_stream(
    bus: ServoBus, emulated: EmulatedBus, guard: SafetyGuard, cycles: int, reach: float
) -> dict[str, Any]:
    """:class:`OrientationStream` tracking the platform rotations of the loop's path
    (home -> demo -> home), one target per cycle: the software part of each cycle
    (solve, rate limit, the step certified in the safe set, the sync loop's
    kinematics with the model's closed configuration, as ``spm servo stream`` runs
    it, and guard), in CPU time of this thread without the bus stages."""
    from spm_pin.hardware.orientation import OrientationStream

    config = _config(emulated.port)
    sync = ServoSync(bus, config, robot=guard.robot, guard=guard, clock=time.thread_time)
    emulated.reset()
    try:
        sync.start()
        limits = config.safety
        path = plan_linear(
            sync.goal,  # type: ignore[arg-type]
            reach * np.radians(DEMO_DEG),
            max_speed=limits.max_speed,
            max_acceleration=limits.max_acceleration,
            period=config.period,
        )
        path = np.vstack([path, path[::-1]])
        targets = list(spm.forward_kinematics(path, sync.design).R)
        stream = OrientationStream(sync)
        software: list[float] = []
        own: list[float] = []
        actions: dict[str, int] = {}
        for k in range(cycles + 20):
            start = time.thread_time()
            step = stream.step(targets[k % len(targets)])
            spent = time.thread_time() - start
            actions[step.action] = actions.get(step.action, 0) + 1
            timings = step.sync.timings
            if k >= 20 and step.sync.sent:  # after the warm-up cycles
                bus_time = timings.get("read", 0.0) + timings.get("write", 0.0)
                software.append(spent - bus_time)
                own.append(spent - sum(timings.values()))
        return {
            "cycles": len(software),
            "software": Timing(tuple(software)).summary(),
            "stream_own": Timing(tuple(own)).summary(),
            "actions": actions,
        }
    finally:
        sync.release()


def bench_guard(robot: spm.SPMRobot, n: int) -> dict[str, Any]:
    """Static checks of goals never seen before, one per call."""
    rng = np.random.default_rng(SEED)
    guard = SafetyGuard(robot)
    goals = list(
        np.radians(DEMO_DEG) * rng.uniform(0.0, 1.0, size=(n, 1)) + rng.normal(0, 0.01, (n, 3))
    )
    timing, verdicts = time_each(guard.check, goals, warmup=0)
    return {
        **timing.summary(),
        "n": n,
        "safe_fraction": float(np.mean([v.safe for v in verdicts])),
        "computed": int(guard.stats["computed"]),
    }


def bench_control_cycle(robot: spm.SPMRobot, n: int) -> dict[str, Any]:
    """One streaming cycle of orientation targets never seen before: target R ->
    home-mode inverse kinematics -> the guard's static checks -> Goal Positions, on the
    single-input fast path and, as the peer, on the batch path (the same functions with
    (1, 3) arrays, as every cycle ran before the fast path), with each stage's time."""
    rng = np.random.default_rng(SEED + 1)
    base = np.radians(DEMO_DEG) * rng.uniform(0.0, 1.0, size=(n, 1)) + rng.normal(0, 0.01, (n, 3))
    targets = list(spm.forward_kinematics(base, robot.design).R)
    joints = JointMap(HardwareConfig().joints)
    fast_guard, batch_guard = SafetyGuard(robot), SafetyGuard(robot)
    stages: dict[str, list[float]] = {"ik": [], "guard": [], "pulses": []}

    def fast(R: np.ndarray) -> dict[int, int]:
        t0 = time.perf_counter()
        theta = spm.inverse_kinematics(R, robot.design).theta
        t1 = time.perf_counter()
        fast_guard.check(theta).require()
        t2 = time.perf_counter()
        pulses = joints.to_pulses(theta)
        stages["ik"].append(t1 - t0)
        stages["guard"].append(t2 - t1)
        stages["pulses"].append(time.perf_counter() - t2)
        return pulses

    def batch(R: np.ndarray) -> dict[int, int]:
        theta = spm.inverse_kinematics(R[None], robot.design).theta[0]
        batch_guard._compute(theta[None])[0].require()
        return joints.to_pulses(theta)

    fast_timing, fast_pulses = time_each(fast, targets, warmup=0)
    batch_timing, batch_pulses = time_each(batch, targets, warmup=0)
    share = {name: float(np.median(values)) for name, values in stages.items()}
    return {
        "compiled": _jit.available(),
        "fast": fast_timing.summary(),
        "batch": batch_timing.summary(),
        "stages_median_s": share,
        "n": n,
        "same_goals": fast_pulses == batch_pulses,
    }


def _python_cycle(n: int) -> dict[str, Any]:
    if _jit.available():  # pragma: no cover - the parent switched it off
        raise RuntimeError(f"{_jit.ENV_VARIABLE}=0 did not reach the child process")
    return bench_control_cycle(spm.build_robot(), n)


def bench_control_cycle_python(n: int) -> dict[str, Any]:
    """:func:`bench_control_cycle` with the Python kernels: in a child process started
    with ``SPM_PIN_JIT=0`` (nothing compiled there)."""
    import concurrent.futures
    import multiprocessing
    import os

    previous = os.environ.get(_jit.ENV_VARIABLE)
    os.environ[_jit.ENV_VARIABLE] = "0"
    try:
        context = multiprocessing.get_context("spawn")
        with concurrent.futures.ProcessPoolExecutor(1, mp_context=context) as pool:
            result: dict[str, Any] = pool.submit(_python_cycle, n).result(timeout=900)
    finally:
        if previous is None:
            del os.environ[_jit.ENV_VARIABLE]
        else:
            os.environ[_jit.ENV_VARIABLE] = previous
    return result


def wire_estimate() -> dict[str, Any]:
    """Bytes of one cycle on a real bus and their time at WIRE_BAUD."""
    n = 3
    length = STATE_BLOCK[1]
    sync_read_instruction = 14 + n  # header .. CRC with the id list
    fast_reply = 11 + n * (length + 4) - 2 + 1  # one status packet, a segment per servo
    plain_replies = n * (11 + length)
    sync_write = 14 + n * 5
    byte_time = BITS_PER_BYTE / WIRE_BAUD
    fast = sync_read_instruction + fast_reply + sync_write
    plain = sync_read_instruction + plain_replies + sync_write
    return {
        "baud": WIRE_BAUD,
        "bytes_fast": fast,
        "bytes_plain": plain,
        "seconds_fast": fast * byte_time,
        "seconds_plain": plain * byte_time,
    }


def run(sizes: dict[str, float], *, quick: bool) -> dict[str, Any]:
    """Run every section and return the JSON payload."""
    robot = spm.build_robot()
    cycles, reach = int(sizes["cycles"]), float(sizes["reach"])
    # Both ends deliberately at 1 Mbit/s (WIRE_BAUD), not the emulator's factory
    # default; the packet timeout allows for the emulator's latency on a loaded machine
    # (LATENCY_TIMER_MS), which changes no timing of a transaction that succeeds.
    with (
        EmulatedBus((1, 2, 3), baudrate=WIRE_BAUD) as emulated,
        ServoBus(
            emulated.port, (1, 2, 3), baudrate=WIRE_BAUD, latency_timer_ms=LATENCY_TIMER_MS
        ) as bus,
    ):
        config = _config(emulated.port)
        guard = SafetyGuard(robot, config.safety)  # shared: the second path check is cached
        bus.identify()
        bus.configure(config.servo)
        results: dict[str, Any] = {"bus": bench_bus(bus, int(sizes["bus"]))}
        results["loop"] = bench_loop(bus, emulated, guard, cycles, reach, update_model=False)
        results["loop_with_model"] = bench_loop(
            bus, emulated, guard, cycles, reach, update_model=True
        )
        results["stream"] = bench_stream(bus, emulated, guard, cycles, reach)
    results["guard_cold"] = bench_guard(robot, int(sizes["guard"]))
    results["control_cycle"] = bench_control_cycle(robot, int(sizes["guard"]))
    results["control_cycle_python"] = bench_control_cycle_python(int(sizes["guard"]))
    results["wire"] = wire_estimate()
    software = results["loop"]["software"]["per_second"]
    cycle = results["control_cycle"]["fast"]["median_s"]
    return {
        "benchmark": "hardware",
        "machine": machine_info(
            ("numpy", "pin", "coal", "dynamixel-sdk", "numba"), {"spm_pin": spm.__version__}
        ),
        "config": {
            "quick": quick,
            "sizes": sizes,
            "plan_rate_hz": PLAN_RATE_HZ,
            "baud": WIRE_BAUD,
            "latency_timer_ms": LATENCY_TIMER_MS,
            "threads_limited_before_numpy": THREADS_LIMITED,
            "timing": "perf_counter per call or per cycle after warm-up, loop stages in "
            "thread CPU time (thread_time); median/p95/p99",
        },
        "results": results,
        "targets": with_all_pass(
            {
                "software_per_second": target(
                    software, TARGET_SOFTWARE_RATE, at_least=True, unit="Hz"
                ),
                "control_cycle_median": target(
                    cycle, TARGET_CONTROL_CYCLE_S, at_least=False, unit="s"
                ),
            }
        ),
    }


def report(payload: dict[str, Any]) -> str:
    """The printed summary."""
    results = payload["results"]
    rows = []
    for key, label in (
        ("sync_read_fast", "sync read, fast (3 servos)"),
        ("sync_read_plain", "sync read, plain (3 servos)"),
        ("sync_write", "sync write (3 goals)"),
    ):
        r = results["bus"][key]
        rows.append(
            [
                label,
                format_count(r["n"]),
                format_seconds(r["median_s"]),
                format_seconds(r["p95_s"]),
                format_rate(r["per_second"]),
            ]
        )
    for key, label in (("loop", "loop"), ("loop_with_model", "loop + model q")):
        loop = results[key]
        for stage in ("read", "kinematics", "guard", "write"):
            r = loop["stages"][stage]
            rows.append(
                [
                    f"{label}: {stage}",
                    format_count(loop["cycles"]),
                    format_seconds(r["median_s"]),
                    format_seconds(r["p95_s"]),
                    "",
                ]
            )
        for part in ("software", "cycle"):
            r = loop[part]
            rows.append(
                [
                    f"{label}: {part}",
                    format_count(loop["cycles"]),
                    format_seconds(r["median_s"]),
                    format_seconds(r["p95_s"]),
                    format_rate(r["per_second"]),
                ]
            )
    guard = results["guard_cold"]
    rows.append(
        [
            "guard, goal not seen before",
            format_count(guard["n"]),
            format_seconds(guard["median_s"]),
            format_seconds(guard["p95_s"]),
            format_rate(guard["per_second"]),
        ]
    )
    cycle = results["control_cycle"]
    stream = results["stream"]
    for key, label in (
        ("software", "orientation stream: software"),
        ("stream_own", "orientation stream: solve, limit, certify"),
    ):
        rows.append(
            [
                label,
                format_count(stream["cycles"]),
                format_seconds(stream[key]["median_s"]),
                format_seconds(stream[key]["p95_s"]),
                format_rate(stream[key]["per_second"]),
            ]
        )
    python = results["control_cycle_python"]
    for part, key, label in (
        (cycle, "fast", "control cycle, fast path" + (", compiled" if cycle["compiled"] else "")),
        (python, "fast", "control cycle, fast path, Python kernels"),
        (cycle, "batch", "control cycle, batch path"),
    ):
        rows.append(
            [
                label,
                format_count(part["n"]),
                format_seconds(part[key]["median_s"]),
                format_seconds(part[key]["p95_s"]),
                format_rate(part[key]["per_second"]),
            ]
        )
    table = format_table(["case", "n", "median", "p95", "rate"], rows)
    wire = results["wire"]
    loop = results["loop"]
    notes = (
        f"Path check before the first command: {loop['path_samples']} samples in "
        f"{format_seconds(loop['path_check_s'])} "
        f"({format_seconds(loop['path_check_per_sample_s'])} per sample).\n"
        f"On a real bus at {wire['baud']:,} bit/s add the wire time: {wire['bytes_fast']} "
        f"bytes per cycle with fast sync read ({format_seconds(wire['seconds_fast'])}), "
        f"{wire['bytes_plain']} plain ({format_seconds(wire['seconds_plain'])})."
    )
    t = payload["targets"]["software_per_second"]
    status = "PASS" if t["pass"] else "FAIL"
    lines = (
        f"Targets\n  {status}  software part of a cycle (kinematics + guard): "
        f"{format_rate(t['value'])} (>= {format_rate(t['threshold'])})"
    )
    c = payload["targets"]["control_cycle_median"]
    lines += (
        f"\n  {'PASS' if c['pass'] else 'FAIL'}  one streaming cycle (target -> IK -> guard -> "
        f"Goal Position), median: {format_seconds(c['value'])} (<= "
        f"{format_seconds(c['threshold'])})"
    )
    head = "spm-pin hardware benchmark: ServoSync against the emulated XM540-W150 bus"
    return "\n\n".join([head, table, notes, lines])


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the summary, write the JSON; returns the exit code."""
    parser = standard_parser(
        "hardware",
        "Rate and stage times of the model-servo sync loop on the emulated bus.",
    )
    return run_main(
        parser,
        lambda args: run(SIZES["quick" if args.quick else "full"], quick=args.quick),
        report,
        argv,
    )


if __name__ == "__main__":
    sys.exit(main())
