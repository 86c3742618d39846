"""Loop-closure benchmark: Newton projection on the SPM, side by side with scipy.

Run from the repository root::

    python -m benchmarks.bench_closure [--out FILE.json] [--quick]

It prints a short table and writes JSON (default ``benchmarks/results/closure.json``).

One core: importing this module sets ``OMP_NUM_THREADS`` and the other variables of
``_common.THREAD_ENV_VARS`` to 1 before numpy is imported (effective from a fresh
interpreter; the JSON records whether it was, ``config.threads_limited_before_numpy``).

What is measured, per call (one input per call, the way a control loop calls it), on
the prototype SPM as a :class:`spm_pin.ClosedLoop` (9 joints, two welds, 12 rows of
rank 6), with seeded inputs:

1. ``warm_1deg``: :meth:`~spm_pin.ClosedLoop.project` along a random walk of the
   inputs with steps of up to 1 degree per joint, each call warm-started from the
   previous :class:`~spm_pin.ProjectionResult` (first-order predictor);
   ``warm_servo``: the same along smooth paths at the XM540-W150's no-load speed
   (53 rpm) sampled at 1 kHz (steps up to 0.32 degree); ``warm_1deg_array``: the 1
   degree walk warm-started from the previous q as a plain array (no predictor).
2. ``peer``: ``scipy.optimize.least_squares`` on the same residual (the same
   Pinocchio calls: kinematics, the two welds' calc, the constraint Jacobian's passive
   columns) along the same 1 degree walk, warm-started from the previous solution:
   the default call ``least_squares(f, x0)`` (``trf``, finite-difference Jacobian;
   it stops near 1e-8), the same with ``xtol = ftol = gtol = 1e-15`` so that it
   reaches our 1e-12 closure (the target's peer), and the tuned call (``lm``,
   MINPACK, with the exact Jacobian, tolerances 1e-15). Speed ratios are the peer's
   median over ours (``warm_1deg``).
3. ``cold``: :meth:`~spm_pin.ClosedLoop.project` from home (q = 0) on random reachable
   inputs (uniform in [-pi, pi]^3 with a home-mode assembly): time, Newton
   iterations, how many needed the path-following fallback, how many failed.
4. ``follow_study``: :meth:`~spm_pin.ClosedLoop.follow` on the study's 25-sample
   motion from home to theta = [60, 90, 120] deg.

Every answer is checked against the analytic forward kinematics (``max_error_rad``:
joint angles against ``SPMRobot.configuration``). Targets: warm-started median
<= 25 us; >= 20x the peer; closure residual <= 1e-12.

Timing: ``time.perf_counter`` around each call with the garbage collector paused; one
pass of warm-up calls first; median, p95 and p99 over the calls.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Callable, Sequence
from typing import Any

from ._common import limit_to_one_thread

#: Whether the one-thread limit was set before numpy was imported.
THREADS_LIMITED = limit_to_one_thread()

import numpy as np  # noqa: E402
import numpy.typing as npt  # noqa: E402
import pinocchio as pin  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin.closure import DEFAULT_TOL  # noqa: E402

from ._common import (  # noqa: E402
    Timing,
    format_count,
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

#: Seed of every random input of this benchmark.
SEED = 20_240_612
#: Largest step per joint of the random walk [rad].
WALK_STEP = math.radians(1.0)
#: XM540-W150 no-load speed at 12 V (53 rpm) [rad/s] and the control rate [Hz].
SERVO_SPEED = 53.0 * 2.0 * math.pi / 60.0
CONTROL_RATE = 1000.0
#: Peer tolerances (xtol, ftol, gtol of least_squares).
PEER_TOL = 1e-15

#: The peer of the speed target: least_squares(residual, x0) as called by default (trf,
#: finite-difference Jacobian), with tolerances tightened so that it reaches the same
#: 1e-12 closure as ours. The default tolerances stop near 1e-8 (reported too), and
#: the tuned call (MINPACK lm with the exact Jacobian) is reported with its own ratio.
PRIMARY_PEER = "default_tight"
#: Peer rows: key -> label.
PEER_LABELS = {
    "default": "least_squares(f, x0), default tolerances",
    "default_tight": "least_squares(f, x0, tol 1e-15)",
    "lm_exact_jacobian_tight": "least_squares lm + exact Jacobian, tol 1e-15",
}

#: The project's targets.
TARGET_WARM_MEDIAN_S = 25e-6
TARGET_SPEEDUP = 20.0
TARGET_RESIDUAL = 1e-12


@dataclasses.dataclass(frozen=True)
class Sizes:
    """Problem sizes of one run."""

    walk: int
    servo: int
    peer: int
    cold: int
    study_repeats: int


FULL = Sizes(walk=5_000, servo=5_000, peer=500, cold=2_000, study_repeats=50)
QUICK = Sizes(walk=150, servo=150, peer=15, cold=40, study_repeats=3)


# -------------------------------------------------------------------------- inputs
def random_walk(robot: spm.SPMRobot, n: int, rng: np.random.Generator) -> FloatArray:
    """``n`` inputs, steps uniform in [-1, 1] deg per joint, kept in the home-mode
    workspace away from singularities (a step that leaves it is drawn again)."""
    theta = np.radians([10.0, 20.0, 30.0])
    path = [theta]
    while len(path) < n:
        candidate = path[-1] + rng.uniform(-WALK_STEP, WALK_STEP, size=3)
        jac = spm.jacobian(candidate[None], robot.design)
        if bool(jac.singularity_margin[0] > 0.1) and bool(
            spm.forward_kinematics(candidate, robot.design).reachable
        ):
            path.append(candidate)
    return np.array(path)


def servo_path(robot: spm.SPMRobot, n: int, rng: np.random.Generator) -> FloatArray:
    """``n`` samples at 1 kHz of sums of sines whose speed never exceeds the servo's.

    Each joint: a sin(2 pi f t + phi) + c with a f 2 pi <= SERVO_SPEED; redrawn until
    the whole path has a home-mode assembly clear of singularities.
    """
    time = np.arange(n)[:, None] / CONTROL_RATE
    while True:
        frequency = rng.uniform(0.2, 1.0, size=(1, 3))
        amplitude = np.minimum(
            rng.uniform(0.2, 0.8, size=(1, 3)), SERVO_SPEED / (2 * np.pi * frequency)
        )
        phase = rng.uniform(0.0, 2 * np.pi, size=(1, 3))
        path = amplitude * np.sin(2 * np.pi * frequency * time + phase) + rng.uniform(-np.pi, np.pi)
        jac = spm.jacobian(path, robot.design)
        if spm.forward_kinematics(path, robot.design).reachable.all() and bool(
            np.min(jac.singularity_margin) > 0.1
        ):
            result: FloatArray = path
            return result


def wrap(angle: FloatArray) -> FloatArray:
    """Angles into [-pi, pi)."""
    result: FloatArray = np.mod(angle + np.pi, 2 * np.pi) - np.pi
    return result


# ------------------------------------------------------------------------ ours
def _entry(timing: Timing, **extra: Any) -> dict[str, Any]:
    entry: dict[str, Any] = {"n": len(timing.samples), **timing.summary(items=1)}
    entry.update(extra)
    return entry


def bench_warm(
    loop: spm.ClosedLoop, path: FloatArray, expected: FloatArray, *, predictor: bool
) -> dict[str, Any]:
    """project() along ``path``, each call warm-started from the previous answer."""
    first = loop.project(path[0])
    for theta in path[1 : min(50, len(path))]:  # warm-up pass
        first = loop.project(theta, first if predictor else first.q)
    state = [loop.project(path[0])]

    def call(k: int) -> spm.ProjectionResult:
        previous = state[0]
        result = loop.project(path[k], previous if predictor else previous.q)
        state[0] = result
        return result

    timing, results = time_each(call, list(range(1, len(path))), warmup=0)
    q = np.array([r.q for r in results])
    iterations = np.array([r.iterations for r in results])
    return _entry(
        timing,
        start="previous ProjectionResult (predictor)" if predictor else "previous q (array)",
        max_step_deg=float(np.degrees(np.abs(np.diff(path, axis=0)).max())),
        iterations_histogram={str(k): int(c) for k, c in enumerate(np.bincount(iterations)) if c},
        mean_iterations=float(iterations.mean()),
        max_residual=max(r.residual for r in results),
        max_error_rad=float(np.abs(wrap(q - expected[1:])).max()),
    )


def bench_cold(loop: spm.ClosedLoop, theta: FloatArray, expected: FloatArray) -> dict[str, Any]:
    """project() from home on each input; failures are timed and counted."""

    def call(k: int) -> spm.ProjectionResult | None:
        try:
            return loop.project(theta[k])
        except spm.ConvergenceError:
            return None

    for k in range(min(20, len(theta))):
        call(k)
    timing, results = time_each(call, list(range(len(theta))), warmup=0)
    solved = [(k, r) for k, r in enumerate(results) if r is not None]
    answers = [r for _, r in solved]
    local = [r.iterations for r in answers if not r.continuation]
    errors = [float(np.abs(wrap(r.q - expected[k])).max()) for k, r in solved]
    return _entry(
        timing,
        start="home, q = 0",
        solved_fraction=len(solved) / len(theta),
        failed=len(theta) - len(solved),
        continuation=sum(r.continuation for r in answers),
        iterations_histogram={str(k): int(c) for k, c in enumerate(np.bincount(local)) if c},
        mean_iterations=float(np.mean(local)) if local else math.nan,
        max_residual=max(r.residual for r in answers),
        max_error_rad=max(errors),
        agree_fraction=sum(e < 1e-10 for e in errors) / len(theta),
    )


def bench_study(loop: spm.ClosedLoop, robot: spm.SPMRobot, repeats: int) -> dict[str, Any]:
    """follow() on the study's 25-sample motion from home to [60, 90, 120] deg."""
    path = np.linspace(0.0, 1.0, 25)[:, None] * np.radians([60.0, 90.0, 120.0])
    timed = time_call(lambda: loop.follow(path), repeats=repeats)
    followed = timed.value
    entry = {"n": 25, **timed.timing.summary(items=25)}
    entry.update(
        total_iterations=followed.total_iterations,
        max_substeps=int(followed.substeps.max()),
        max_residual=float(followed.residual.max()),
        max_error_rad=float(np.abs(wrap(followed.q - robot.configuration(path))).max()),
    )
    return entry


# ------------------------------------------------------------------------ peer
class PeerResidual:
    """The closure residual and its passive Jacobian, for scipy, with the same
    Pinocchio calls as the solver (kinematics, one calc per weld, the Jacobian)."""

    def __init__(self, loop: spm.ClosedLoop) -> None:
        self.model = loop.model
        self.data = loop.model.createData()
        self.models = loop.constraint_models
        self.datas = pin.StdVec_ConstraintData()
        for constraint in self.models:
            self.datas.append(constraint.createData())
        self.bare = [
            (c.extract(), d.extract()) for c, d in zip(self.models, self.datas, strict=True)
        ]
        self.active = loop.actuated_q_idx
        self.passive = loop.passive_q_idx
        self.q = np.zeros(self.model.nq)

    def set(self, theta: FloatArray) -> None:
        self.q[self.active] = theta

    def _kinematics(self, x: FloatArray) -> None:
        self.q[self.passive] = x
        pin.computeJointJacobians(self.model, self.data, self.q)
        for constraint, data in self.bare:
            constraint.calc(self.model, self.data, data)

    def residual(self, x: FloatArray) -> FloatArray:
        self._kinematics(x)
        result: FloatArray = np.concatenate([d.constraint_position_error for _, d in self.bare])
        return result

    def jacobian(self, x: FloatArray) -> FloatArray:
        self._kinematics(x)
        J = pin.getConstraintsJacobian(self.model, self.data, self.models, self.datas)
        result: FloatArray = J[:, self.passive]
        return result


def _time_peer(
    peer: PeerResidual, solve: Callable[[FloatArray], Any], path: FloatArray, x0: FloatArray
) -> tuple[Timing, list[Any]]:
    """One peer call per path point, each from the previous answer (a warm-up first)."""
    state = [x0.copy()]

    def call(k: int) -> Any:
        peer.set(path[k])
        answer = solve(state[0])
        state[0] = answer.x
        return answer

    for k in range(1, min(5, len(path))):
        call(k)
    state[0] = x0.copy()
    return time_each(call, list(range(1, len(path))), warmup=0)


def bench_peer(
    loop: spm.ClosedLoop, path: FloatArray, expected: FloatArray, ours_median: float
) -> dict[str, Any]:
    """least_squares along the first points of the 1 degree walk, warm-started."""
    peer = PeerResidual(loop)
    variants: dict[str, Callable[[FloatArray], Any]] = {
        "default": lambda x0: least_squares(peer.residual, x0),
        "default_tight": lambda x0: least_squares(
            peer.residual, x0, xtol=PEER_TOL, ftol=PEER_TOL, gtol=PEER_TOL
        ),
        "lm_exact_jacobian_tight": lambda x0: least_squares(
            peer.residual,
            x0,
            jac=peer.jacobian,
            method="lm",
            xtol=PEER_TOL,
            ftol=PEER_TOL,
            gtol=PEER_TOL,
        ),
    }
    out: dict[str, Any] = {
        "method": (
            "scipy.optimize.least_squares on the stacked weld residual (12 rows) in the 6 "
            "passive joints, the same Pinocchio calls as spm-pin's solver; x0 = previous "
            "solution's passive joints; one call per path point"
        ),
        "path": "the first points of warm_1deg",
    }
    for name, solve in variants.items():
        timing, answers = _time_peer(peer, solve, path, expected[0][loop.passive_q_idx])
        residual = [float(np.linalg.norm(a.fun)) for a in answers]
        error = [
            float(np.abs(wrap(a.x - expected[k + 1][loop.passive_q_idx])).max())
            for k, a in enumerate(answers)
        ]
        out[name] = _entry(
            timing,
            mean_evaluations=float(np.mean([a.nfev for a in answers])),
            max_residual=max(residual),
            median_residual=float(np.median(residual)),
            max_error_rad=max(error),
            speed_ratio_peer_over_ours=timing.median / ours_median,
        )
    out["speed_ratio"] = out[PRIMARY_PEER]["speed_ratio_peer_over_ours"]
    out["speed_ratio_tuned"] = out["lm_exact_jacobian_tight"]["speed_ratio_peer_over_ours"]
    return out


# ---------------------------------------------------------------------- targets
def evaluate_targets(results: dict[str, dict[str, Any]], peer: dict[str, Any]) -> dict[str, Any]:
    """The project's targets, each with value, threshold and pass flag."""
    residual = max(
        results[key]["max_residual"] for key in ("warm_1deg", "warm_servo", "cold", "follow_study")
    )
    targets: dict[str, Any] = {
        "warm_median": target(
            results["warm_1deg"]["median_s"], TARGET_WARM_MEDIAN_S, at_least=False, unit="s"
        ),
        "speedup_vs_least_squares": target(
            peer["speed_ratio"], TARGET_SPEEDUP, at_least=True, unit="x"
        ),
        "max_residual": target(residual, TARGET_RESIDUAL, at_least=False),
    }
    return with_all_pass(targets)


# ------------------------------------------------------------------------- report
def report(payload: dict[str, Any]) -> str:
    """The human-readable summary of a run."""
    machine, config = payload["machine"], payload["config"]
    results, peer, targets = payload["results"], payload["peer"], payload["targets"]
    threads = "1 thread" if config["threads_limited_before_numpy"] else "threads not limited"
    head = (
        f"spm-pin loop-closure benchmark: SPM prototype, {threads}"
        f"{', QUICK' if config['quick'] else ''}\n"
        f"Python {machine['python']}, pin {machine['packages'].get('pin')}, numpy "
        f"{machine['packages'].get('numpy')}, scipy {machine['packages'].get('scipy')}, "
        f"CPU {machine['cpu']}"
    )
    labels = {
        "warm_1deg": "project, warm (result), 1 deg walk",
        "warm_servo": "project, warm (result), servo 1 kHz",
        "warm_1deg_array": "project, warm (q array), 1 deg walk",
        "cold": "project, cold from home",
        "follow_study": "follow, study path (per point)",
    }
    rows = []
    for key, label in labels.items():
        r = results[key]
        median = r["median_s"] if key != "follow_study" else r["per_item_s"]
        p95 = r["p95_s"] if key != "follow_study" else r["p95_s"] / r["n"]
        if key == "follow_study":
            notes = f"{r['total_iterations']} iterations in all"
        elif key == "cold":
            notes = (
                f"{r['mean_iterations']:.1f} iterations on average; {r['continuation']} by "
                f"path following, {r['failed']} failed"
            )
        else:
            histogram = ", ".join(f"{k}: {v}" for k, v in r["iterations_histogram"].items())
            notes = f"iterations {histogram}"
        rows.append(
            [
                label,
                format_count(r["n"]),
                format_seconds(median),
                format_seconds(p95),
                f"{r['max_residual']:.1e}",
                f"{r['max_error_rad']:.1e}",
                notes,
            ]
        )
    table = format_table(["case", "n", "median", "p95", "residual", "error [rad]", "notes"], rows)
    peer_rows = []
    for name, label in PEER_LABELS.items():
        r = peer[name]
        peer_rows.append(
            [
                label,
                format_count(r["n"]),
                format_seconds(r["median_s"]),
                format_seconds(r["p95_s"]),
                f"{r['max_residual']:.1e}",
                f"{r['max_error_rad']:.1e}",
                f"{r['mean_evaluations']:.1f} evaluations, "
                f"{r['speed_ratio_peer_over_ours']:.0f}x ours",
            ]
        )
    peer_table = "Peer (same 1 deg walk, warm-started)\n" + format_table(
        ["case", "n", "median", "p95", "residual", "error [rad]", "notes"], peer_rows
    )
    lines = ["Targets"]
    for key, label in (
        ("warm_median", "warm-started projection, median"),
        ("speedup_vs_least_squares", "speed-up over scipy least_squares"),
        ("max_residual", "max closure residual"),
    ):
        t = targets[key]
        if t["unit"] == "s":
            value, limit = format_seconds(t["value"]), format_seconds(t["threshold"])
        elif t["unit"] == "x":
            value, limit = f"{t['value']:,.0f}x", f"{t['threshold']:,.0f}x"
        else:
            value, limit = f"{t['value']:.1e}", f"{t['threshold']:.0e}"
        status = "PASS" if t["pass"] else "FAIL"
        lines.append(f"  {status}  {label}: {value} ({t['comparison']} {limit})")
    lines.append(
        f"  (peer: {PEER_LABELS[PRIMARY_PEER]}; the tuned lm + exact Jacobian call is "
        f"{peer['speed_ratio_tuned']:,.0f}x slower than ours)"
    )
    return "\n\n".join([head, table, peer_table, "\n".join(lines)])


# --------------------------------------------------------------------------- main
def run(sizes: Sizes, *, quick: bool) -> dict[str, Any]:
    """Run every section and return the JSON payload."""
    rng = np.random.default_rng(SEED)
    robot = spm.build_robot()
    loop = spm.ClosedLoop.from_robot(robot)
    walk = random_walk(robot, sizes.walk, rng)
    walk_expected = robot.configuration(walk)
    servo = servo_path(robot, sizes.servo, rng)
    servo_expected = robot.configuration(servo)
    cold_inputs = _reachable(robot, sizes.cold, rng)

    results: dict[str, dict[str, Any]] = {
        "warm_1deg": bench_warm(loop, walk, walk_expected, predictor=True),
        "warm_servo": bench_warm(loop, servo, servo_expected, predictor=True),
        "warm_1deg_array": bench_warm(loop, walk, walk_expected, predictor=False),
        "cold": bench_cold(loop, cold_inputs, robot.configuration(cold_inputs)),
        "follow_study": bench_study(loop, robot, sizes.study_repeats),
    }
    n_peer = sizes.peer + 1
    peer = bench_peer(loop, walk[:n_peer], walk_expected[:n_peer], results["warm_1deg"]["median_s"])
    return {
        "benchmark": "closure",
        "machine": machine_info(("numpy", "scipy", "pin"), {"spm_pin": spm.__version__}),
        "config": {
            "quick": quick,
            "design": robot.design.name,
            "seed": SEED,
            "sizes": dataclasses.asdict(sizes),
            "threads_limited_before_numpy": THREADS_LIMITED,
            "tolerance": DEFAULT_TOL,
            "timing": "perf_counter per call, gc paused; a warm-up pass first; "
            "median/p95/p99 over the calls",
        },
        "results": results,
        "peer": peer,
        "targets": evaluate_targets(results, peer),
    }


def _reachable(robot: spm.SPMRobot, n: int, rng: np.random.Generator) -> FloatArray:
    """``n`` inputs uniform in [-pi, pi]^3 with a home-mode assembly."""
    kept: list[FloatArray] = []
    have = 0
    while have < n:
        chunk = rng.uniform(-math.pi, math.pi, size=(max(2 * n, 100), 3))
        good = chunk[spm.forward_kinematics(chunk, robot.design).reachable]
        kept.append(good)
        have += good.shape[0]
    return np.concatenate(kept)[:n]


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the summary, write the JSON; returns the exit code."""
    parser = standard_parser(
        "closure",
        "Speed and accuracy of spm-pin's loop-closure solver, next to scipy.",
    )
    return run_main(
        parser, lambda args: run(QUICK if args.quick else FULL, quick=args.quick), report, argv
    )


if __name__ == "__main__":
    sys.exit(main())
