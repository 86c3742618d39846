"""Dynamics benchmark: simulated steps per second next to MuJoCo, inverse dynamics per
sample, and the accuracy figures (closure drift, energy drift, MuJoCo agreement).

Run from the repository root::

    python -m benchmarks.bench_dynamics [--out FILE.json] [--quick]

It prints a short table and writes JSON (default ``benchmarks/results/dynamics.json``).
Importing this module limits numpy's thread pools to one thread before numpy is
imported (see ``_common.limit_to_one_thread``).

What is measured (the prototype, the committed ``urdf/spm.xml``; deterministic inputs):

1. ``steps``: :class:`spm_pin.Simulator` at 1 kHz, timed over whole runs (states
   recorded only at the ends), for both integrators, passive (the robot hanging upside
   down, swinging from theta = [20, -10, 5] deg) and driven by the XM540-W150 servo
   model along a 1 s minimum-jerk move to [60, 90, 120] deg. Every step integrates,
   projects positions (Newton, closure residual <= 1e-12 checked) and velocities.
2. ``mujoco``: MuJoCo stepping the same MJCF at 1 ms in the same run: ``mj_step`` called
   from Python once per step (as our simulator is), with a Python servo controller,
   and ``mj_step(nstep=N)`` looping in C; Euler (MuJoCo's default) and RK4.
3. ``inverse``: closed-loop inverse dynamics of the 1 kHz minimum-jerk move (path
   following plus the null-space recipe), per sample; ``forward``: one forward-dynamics
   call, both methods.
4. ``reduced_euler_n{1,64,4096}``: the batched reduced dynamics
   (:class:`spm_pin.dynamics.ReducedDynamics`, numpy) stepping N robots at once,
   semi-implicit Euler at 1 ms, per robot-step; ``accuracy.reduced``: its closure drift
   (zero: only the inputs are integrated) beside the constrained simulator's after the
   energy run.
5. ``accuracy``: largest closure residual over every benchmarked run; energy drift of
   the frictionless passive motion over 10 s (rk4, 1 kHz; relative to the largest
   kinetic energy); agreement with MuJoCo over 3 s (stiff welds, RK4 at 0.1 ms) and,
   for context, with MuJoCo's stock settings (solref 0.02 s, Euler at 1 ms).
6. ``targets``: >= 50,000 simulated steps per second (passive, semi-implicit Euler, the
   like-for-like of MuJoCo's default ``mj_step``), closure drift <= 1e-10, energy drift
   <= 1e-6, MuJoCo agreement <= 1e-6 rad.

Timings: one warm-up call, then repeats; median and tails over the repeats. The machine
load matters (the JSON records the machine); compare runs on the same machine.
"""

from __future__ import annotations

import dataclasses
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
from spm_pin import dynamics as D  # noqa: E402

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
    with_all_pass,
)

FloatArray = npt.NDArray[np.float64]

#: The MJCF both simulators load.
MJCF = Path(__file__).resolve().parent.parent / "urdf" / "spm.xml"
#: Physics rate [s].
DT = 1e-3
#: Initial input angles of the passive motion [rad].
PASSIVE_START = np.radians([20.0, -10.0, 5.0])
#: Target of the driven move [rad] and its duration [s].
MOVE_GOAL = np.radians([60.0, 90.0, 120.0])
MOVE_TIME = 1.0

#: The project's targets.
TARGET_STEPS_PER_SECOND = 50_000.0
TARGET_DRIFT = 1e-10
TARGET_ENERGY = 1e-6
TARGET_MUJOCO_THETA = 1e-6


@dataclasses.dataclass(frozen=True)
class Sizes:
    """Run lengths and repeat counts."""

    steps: int  # steps per timed simulator run
    repeats: int
    energy_time: float  # [s]
    mujoco_time: float  # [s] of the cross-check
    inverse_rate: float  # [Hz] samples of the inverse-dynamics move
    forward_calls: int


FULL = Sizes(
    steps=2_000,
    repeats=7,
    energy_time=10.0,
    mujoco_time=3.0,
    inverse_rate=1000.0,
    forward_calls=2_000,
)
QUICK = Sizes(
    steps=200,
    repeats=3,
    energy_time=1.0,
    mujoco_time=0.3,
    inverse_rate=100.0,
    forward_calls=100,
)


def _entry(timing: Timing, items: int, **extra: Any) -> dict[str, Any]:
    entry: dict[str, Any] = {"n": items, **timing.summary(items=items)}
    entry.update(extra)
    return entry


def _step_entry(timing: Timing, steps: int, **extra: Any) -> dict[str, Any]:
    entry = _entry(timing, steps, **extra)
    entry["realtime_factor"] = entry["per_second"] * DT
    return entry


# --------------------------------------------------------------------------- ours
def bench_steps(
    upright: D.ClosedLoopDynamics, hanging: D.ClosedLoopDynamics, sizes: Sizes
) -> tuple[dict[str, dict[str, Any]], float]:
    """Simulator step rates; returns the entries and the largest closure residual."""
    motion = D.Trajectory.minimum_jerk(np.zeros(3), MOVE_GOAL, MOVE_TIME)
    servo = D.ServoController(D.XM540_W150, motion)
    duration = sizes.steps * DT
    results: dict[str, dict[str, Any]] = {}
    drift = 0.0
    cases: list[tuple[str, D.ClosedLoopDynamics, str, Any, FloatArray]] = [
        ("ours_euler_passive", hanging, "euler", None, PASSIVE_START),
        ("ours_euler_servo", upright, "euler", servo, np.zeros(3)),
        ("ours_rk4_passive", hanging, "rk4", None, PASSIVE_START),
        ("ours_rk4_servo", upright, "rk4", servo, np.zeros(3)),
    ]
    for name, dynamics, integrator, controller, theta in cases:
        sim = D.Simulator(dynamics, dt=DT, integrator=integrator)
        start = dynamics.configuration(theta)  # closed q: a reset costs microseconds

        def simulate(
            sim: D.Simulator = sim, controller: Any = controller, start: FloatArray = start
        ) -> D.SimulationResult:
            sim.reset(start)
            return sim.run(duration, controller, record_every=sizes.steps)

        timed = time_call(simulate, repeats=sizes.repeats)
        drift = max(drift, timed.value.max_closure_residual)
        results[name] = _step_entry(
            timed.timing,
            sizes.steps,
            integrator=integrator,
            controller="XM540-W150 servo" if controller is not None else "none (passive)",
            max_closure_residual=timed.value.max_closure_residual,
        )
    return results, drift


def bench_mujoco(hanging: D.ClosedLoopDynamics, sizes: Sizes) -> dict[str, dict[str, Any]]:
    """MuJoCo stepping the same MJCF at 1 ms, from Python and in C."""
    import mujoco

    results: dict[str, dict[str, Any]] = {}
    q0 = hanging.configuration(PASSIVE_START)
    motion = D.Trajectory.minimum_jerk(np.zeros(3), MOVE_GOAL, MOVE_TIME)
    servo = D.ServoController(D.XM540_W150, motion)
    idx = hanging.actuated_idx
    integrators = {
        "euler": mujoco.mjtIntegrator.mjINT_EULER,
        "rk4": mujoco.mjtIntegrator.mjINT_RK4,
    }
    for integrator, flag in integrators.items():
        model = mujoco.MjModel.from_xml_path(str(MJCF))
        model.opt.timestep = DT
        model.opt.integrator = flag
        data = mujoco.MjData(model)

        def reset(model: Any = model, data: Any = data, gravity: float = 9.81) -> None:
            mujoco.mj_resetData(model, data)
            model.opt.gravity[:] = (0.0, 0.0, gravity)
            data.qpos[:] = q0 if gravity > 0 else 0.0
            mujoco.mj_forward(model, data)

        def python_loop(model: Any = model, data: Any = data) -> None:
            reset(model, data)
            step = mujoco.mj_step
            for _ in range(sizes.steps):
                step(model, data)

        def c_loop(model: Any = model, data: Any = data) -> None:
            reset(model, data)
            mujoco.mj_step(model, data, nstep=sizes.steps)

        def servo_loop(model: Any = model, data: Any = data) -> None:
            reset(model, data, gravity=-9.81)
            step = mujoco.mj_step
            for k in range(sizes.steps):
                data.qfrc_applied[idx] = servo(k * DT, data.qpos[idx], data.qvel[idx])
                step(model, data)

        for label, fn, how in (
            ("passive", python_loop, "mj_step per step from Python"),
            ("passive_c_loop", c_loop, "mj_step(nstep=N), loop in C"),
            ("servo", servo_loop, "mj_step per step from Python, Python servo controller"),
        ):
            timed = time_call(fn, repeats=sizes.repeats)
            results[f"mujoco_{integrator}_{label}"] = _step_entry(
                timed.timing,
                sizes.steps,
                integrator=integrator,
                how=how,
                stock_welds=True,
            )
    return results


def bench_inverse(upright: D.ClosedLoopDynamics, sizes: Sizes) -> dict[str, dict[str, Any]]:
    """Inverse dynamics of a sampled move (per sample) and single forward calls."""
    motion = D.Trajectory.minimum_jerk(np.zeros(3), MOVE_GOAL, MOVE_TIME, sizes.inverse_rate)
    n = motion.time.shape[0]
    timed = time_call(lambda: D.inverse_dynamics(upright, motion), repeats=sizes.repeats)
    peak = np.abs(timed.value.torque).max(axis=0)
    results = {
        "inverse_trajectory": _entry(
            timed.timing, n, peak_torque_nm=peak, samples_per_second_of_motion=sizes.inverse_rate
        )
    }
    states = [
        (motion.theta[k], motion.theta_dot[k], motion.theta_ddot[k])
        for k in np.linspace(0, n - 1, 5).astype(int)
    ]
    q_states = [upright.configuration(s[0]) for s in states]

    def single() -> None:
        for q, (_, rate, acceleration) in zip(q_states, states, strict=True):
            upright._inverse_one(q, rate, acceleration)

    timed_single = time_call(single, repeats=sizes.repeats)
    results["inverse_single_state"] = _entry(
        timed_single.timing, len(states), note="closed q given"
    )
    torque = np.array([0.01, -0.02, 0.005])
    for method in ("pinocchio", "nullspace"):

        def forward(method: str = method) -> None:
            for _ in range(sizes.forward_calls // len(q_states)):
                for q, (_, rate, _) in zip(q_states, states, strict=True):
                    upright.forward(q, rate, torque, method=method)

        calls = (sizes.forward_calls // len(q_states)) * len(q_states)
        timed_forward = time_call(forward, repeats=sizes.repeats)
        results[f"forward_{method}"] = _entry(
            timed_forward.timing, calls, note="public API, checks"
        )
    return results


# ----------------------------------------------------------------------- accuracy
#: Batch sizes of the reduced dynamics.
REDUCED_BATCHES = (1, 64, 4096)


def bench_reduced(hanging: D.ClosedLoopDynamics, sizes: Sizes) -> dict[str, dict[str, Any]]:
    """Batched reduced dynamics (:class:`spm_pin.dynamics.ReducedDynamics`): N robots
    swinging from seeded states near PASSIVE_START, semi-implicit Euler at 1 ms, each
    step warm-started from the last; per item = one robot-step."""
    reduced = D.ReducedDynamics.from_dynamics(hanging)
    rng = np.random.default_rng(5)
    steps = max(10, sizes.steps // 20)
    results: dict[str, dict[str, Any]] = {}
    for n in REDUCED_BATCHES:
        theta0 = PASSIVE_START + rng.uniform(-0.05, 0.05, (n, 3))
        R0 = reduced.rotation(theta0)

        def simulate(theta0: FloatArray = theta0, R0: FloatArray = R0) -> FloatArray:
            theta, rate, R = theta0, np.zeros_like(theta0), R0
            for _ in range(steps):
                result = reduced.step(theta, rate, None, DT, integrator="euler", reference=R)
                theta, rate, R = result.theta, result.theta_dot, result.R
            return theta

        timed = time_call(simulate, repeats=sizes.repeats)
        results[f"reduced_euler_n{n}"] = _step_entry(
            timed.timing, steps * n, integrator="euler", note=f"{n} robots per step (numpy)"
        )
    return results


def _agreement(ours: D.SimulationResult, theirs: D.SimulationResult) -> dict[str, float]:
    return {
        "max_theta_error_rad": float(np.abs(ours.theta - theirs.theta).max()),
        "max_speed_error_rad_s": float(np.abs(ours.theta_dot - theirs.theta_dot).max()),
        "max_torque_error_nm": float(np.abs(ours.torque - theirs.torque).max()),
        "mujoco_max_closure_residual": theirs.max_closure_residual,
    }


def accuracy(
    upright: D.ClosedLoopDynamics, hanging: D.ClosedLoopDynamics, sizes: Sizes
) -> dict[str, Any]:
    """Energy drift and the MuJoCo cross-checks."""
    sim = D.Simulator(hanging, dt=DT, integrator="rk4", state=PASSIVE_START)
    run = sim.run(sizes.energy_time, record_every=10)
    energy = {
        "duration_s": sizes.energy_time,
        "integrator": "rk4",
        "relative_drift": float(np.abs(run.energy - run.energy[0]).max() / run.kinetic.max()),
        "max_kinetic_energy_j": float(run.kinetic.max()),
        "max_closure_residual": run.max_closure_residual,
    }
    euler = D.Simulator(hanging, dt=DT, integrator="euler", state=PASSIVE_START)
    run_euler = euler.run(sizes.energy_time, record_every=10)
    energy["euler_relative_drift"] = float(
        np.abs(run_euler.energy - run_euler.energy[0]).max() / run_euler.kinetic.max()
    )
    t = sizes.mujoco_time
    stiff: dict[str, Any] = {"settings": "solref (2e-4 s, 1), solimp 0.999/0.9999, RK4 0.1 ms"}
    ours = D.Simulator(hanging, state=PASSIVE_START).run(t, record_every=10)
    theirs = D.simulate_mujoco(MJCF, hanging, t, state=PASSIVE_START, record_every=10)
    stiff["passive_hanging"] = _agreement(ours, theirs)
    motion = D.Trajectory.minimum_jerk(np.zeros(3), MOVE_GOAL, MOVE_TIME)
    servo = D.ServoController(D.XM540_W150, motion)
    ours_d = D.Simulator(upright).run(t, servo, record_every=10)
    theirs_d = D.simulate_mujoco(MJCF, upright, t, servo, record_every=10)
    stiff["driven"] = _agreement(ours_d, theirs_d)
    inverse = D.inverse_dynamics(upright, theirs_d.theta, theirs_d.theta_dot, theirs_d.theta_ddot)
    stiff["driven"]["inverse_of_mujoco_motion_torque_error_nm"] = float(
        np.abs(inverse.torque - theirs_d.torque).max()
    )
    stiff["driven"]["peak_torque_nm"] = float(np.abs(ours_d.torque).max())
    stock_run = D.simulate_mujoco(
        MJCF,
        hanging,
        t,
        state=PASSIVE_START,
        substeps=1,
        integrator="euler",
        solref=(0.02, 1.0),
        solimp=(0.9, 0.95, 0.001, 0.5, 2.0),
        record_every=10,
    )
    stock = {
        "settings": "MuJoCo stock: solref (0.02 s, 1), solimp 0.9/0.95, Euler 1 ms",
        "passive_hanging": _agreement(ours, stock_run),
    }
    return {
        "energy": energy,
        "mujoco_stiff": stiff,
        "mujoco_stock": stock,
        "duration_s": t,
    }


def evaluate_targets(
    results: dict[str, dict[str, Any]], acc: dict[str, Any], drift: float
) -> dict[str, Any]:
    """The project's targets, each with value, threshold and pass flag."""
    stiff = acc["mujoco_stiff"]
    theta_error = max(
        stiff["passive_hanging"]["max_theta_error_rad"], stiff["driven"]["max_theta_error_rad"]
    )
    drift = max(drift, acc["energy"]["max_closure_residual"])
    targets: dict[str, Any] = {
        "steps_per_second": target(
            results["ours_euler_passive"]["per_second"],
            TARGET_STEPS_PER_SECOND,
            at_least=True,
            unit="1/s",
        ),
        "closure_drift": target(drift, TARGET_DRIFT, at_least=False, unit="rad"),
        "energy_drift": target(
            acc["energy"]["relative_drift"], TARGET_ENERGY, at_least=False, unit="relative"
        ),
        "mujoco_theta_agreement": target(
            theta_error, TARGET_MUJOCO_THETA, at_least=False, unit="rad"
        ),
    }
    return with_all_pass(targets)


# ------------------------------------------------------------------------- report
def report(payload: dict[str, Any]) -> str:
    """The human-readable summary of a run."""
    machine, config = payload["machine"], payload["config"]
    results, acc, targets = payload["results"], payload["accuracy"], payload["targets"]
    packages = machine["packages"]
    threads = "1 thread" if config["threads_limited_before_numpy"] else "threads not limited"
    head = (
        f"spm-pin dynamics benchmark: {config['design']}, dt = {config['dt_s'] * 1e3:g} ms, "
        f"{threads}{', QUICK' if config['quick'] else ''}\n"
        f"Python {machine['python']}, numpy {packages.get('numpy')}, pin "
        f"{packages.get('pin')}, mujoco {packages.get('mujoco')}, CPU {machine['cpu']}"
    )
    rows = []
    for key, r in results.items():
        rate = r["per_second"]
        realtime = f"{r['realtime_factor']:.0f}x" if "realtime_factor" in r else ""
        note = r.get("how") or r.get("controller") or r.get("note") or ""
        rows.append(
            [
                key,
                f"{r['n']:,}",
                format_seconds(r["per_item_s"]),
                format_seconds(r["p95_s"] / r["n"]),
                format_rate(rate),
                realtime,
                note,
            ]
        )
    table = format_table(
        ["case", "items", "per item", "p95/item", "per second", "real time", "notes"], rows
    )
    energy, stiff, stock = acc["energy"], acc["mujoco_stiff"], acc["mujoco_stock"]
    text = (
        f"Energy, frictionless passive motion over {energy['duration_s']:g} s at 1 kHz: "
        f"rk4 drift {energy['relative_drift']:.1e}, euler {energy['euler_relative_drift']:.1e}"
        f" (relative to the largest kinetic energy)\n"
        f"MuJoCo over {acc['duration_s']:g} s, {stiff['settings']}:\n"
        f"  passive (hanging): theta {stiff['passive_hanging']['max_theta_error_rad']:.1e} "
        f"rad, speed {stiff['passive_hanging']['max_speed_error_rad_s']:.1e} rad/s, "
        f"MuJoCo closure {stiff['passive_hanging']['mujoco_max_closure_residual']:.1e}\n"
        f"  driven (servos): theta {stiff['driven']['max_theta_error_rad']:.1e} rad, torque "
        f"{stiff['driven']['max_torque_error_nm']:.1e} N m (peak "
        f"{stiff['driven']['peak_torque_nm']:.3g}); our inverse dynamics of MuJoCo's motion "
        f"vs its torques {stiff['driven']['inverse_of_mujoco_motion_torque_error_nm']:.1e} N m"
        f"\n  {stock['settings']}: passive theta "
        f"{stock['passive_hanging']['max_theta_error_rad']:.1e} rad\n"
        f"Reduced dynamics: closure drift 0 by construction; the constrained simulator's "
        f"after {acc['reduced']['duration_s']:g} s: "
        f"{acc['reduced']['constrained_closure_drift_rad']:.1e} rad"
    )
    labels = {
        "steps_per_second": "simulated steps per second (passive, euler)",
        "closure_drift": "closure drift",
        "energy_drift": "energy drift",
        "mujoco_theta_agreement": "MuJoCo agreement",
    }
    lines = ["Targets"]
    for key, label in labels.items():
        t = targets[key]
        if key == "steps_per_second":
            value, limit = format_rate(t["value"]), format_rate(t["threshold"])
        else:
            value, limit = f"{t['value']:.1e}", f"{t['threshold']:.0e}"
        status = "PASS" if t["pass"] else "FAIL"
        lines.append(f"  {status}  {label}: {value} ({t['comparison']} {limit})")
    return "\n\n".join([head, table, text, "\n".join(lines)])


# --------------------------------------------------------------------------- main
def run(sizes: Sizes, *, quick: bool) -> dict[str, Any]:
    """Run every section and return the JSON payload."""
    robot = spm.build_robot()
    upright = D.ClosedLoopDynamics(robot)
    hanging = D.ClosedLoopDynamics(robot, gravity=(0.0, 0.0, 9.81))
    results, drift = bench_steps(upright, hanging, sizes)
    results.update(bench_mujoco(hanging, sizes))
    results.update(bench_inverse(upright, sizes))
    results.update(bench_reduced(hanging, sizes))
    acc = accuracy(upright, hanging, sizes)
    ours, theirs = results["ours_euler_passive"], results["mujoco_euler_passive"]
    comparison = {
        "ours_euler_vs_mujoco_euler_python_loop": ours["per_second"] / theirs["per_second"],
        "ours_euler_servo_vs_mujoco_euler_servo": results["ours_euler_servo"]["per_second"]
        / results["mujoco_euler_servo"]["per_second"],
    }
    batched = results[f"reduced_euler_n{REDUCED_BATCHES[-1]}"]["per_second"]
    comparison["reduced_batched_vs_ours_euler"] = batched / ours["per_second"]
    comparison["reduced_batched_vs_mujoco_euler_python_loop"] = batched / theirs["per_second"]
    comparison["reduced_batched_vs_mujoco_c_loop"] = (
        batched / results["mujoco_euler_passive_c_loop"]["per_second"]
    )
    acc["reduced"] = {
        "closure_drift_rad": 0.0,  # no passive joint is integrated
        "constrained_closure_drift_rad": acc["energy"]["max_closure_residual"],
        "duration_s": sizes.energy_time,
    }
    return {
        "benchmark": "dynamics",
        "machine": machine_info(("numpy", "pin", "mujoco"), {"spm_pin": spm.__version__}),
        "config": {
            "quick": quick,
            "design": robot.design.name,
            "mjcf": str(MJCF.relative_to(MJCF.parent.parent)),
            "dt_s": DT,
            "sizes": dataclasses.asdict(sizes),
            "threads_limited_before_numpy": THREADS_LIMITED,
            "timing": "perf_counter; 1 warm-up call; median/p95/p99 over repeats of whole "
            "runs of `steps` steps (states recorded at the ends only)",
        },
        "results": results,
        "comparison": comparison,
        "accuracy": acc,
        "targets": evaluate_targets(results, acc, drift),
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the summary, write the JSON; returns the exit code."""
    parser = standard_parser(
        "dynamics",
        "Speed and accuracy of spm-pin's constrained dynamics, next to MuJoCo.",
        quick_help="short runs (smoke test)",
    )
    return run_main(
        parser, lambda args: run(QUICK if args.quick else FULL, quick=args.quick), report, argv
    )


if __name__ == "__main__":
    sys.exit(main())
