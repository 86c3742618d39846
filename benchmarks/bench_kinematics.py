"""Kinematics benchmark: speed and accuracy of FK and IK, side by side with fsolve.

Run from the repository root::

    python -m benchmarks.bench_kinematics [--out FILE.json] [--quick] [--design NAME]

It prints a short table and writes JSON (default ``benchmarks/results/kinematics.json``).

One core: importing this module sets ``OMP_NUM_THREADS``, ``OPENBLAS_NUM_THREADS``,
``MKL_NUM_THREADS`` (and the other variables of ``_common.THREAD_ENV_VARS``) to 1 in
``os.environ`` *before* numpy is imported. That only takes effect when numpy is not
loaded yet (``python -m`` from a fresh interpreter); the JSON records whether it did
(``config.threads_limited_before_numpy``).

What is measured (seeded inputs, so two runs or two versions compare like for like):

1. ``fk_home_reachable``: :func:`spm_pin.forward_kinematics` on a batch of reachable
   inputs (uniform in [-pi, pi]^3, keeping those with ``fk.reachable``);
   ``fk_home_uniform``: the same on uniform inputs, unreachable ones included.
2. ``fk_all_modes``: :func:`spm_pin.forward_kinematics_all`, with the distribution
   of the number of real assembly modes.
3. ``ik_reachable``: :func:`spm_pin.inverse_kinematics` (home working mode) on
   reachable rotations (FK solutions, turned about the coaxial axis at random), with
   the round-trip error; ``ik_uniform``: on uniformly random rotations.
4. ``peer``: what users do today without spm-pin: per input,
   ``scipy.optimize.fsolve`` on the 9 unknowns v_1, v_2, v_3 with the 9 equations
   |v_i| = 1, w_i . v_i = cos a2, v_i . v_j = v_i0 . v_j0, from the guess v = v_0.
   Each answer is classified against our certified home-mode answer.
   Also reported: the speed ratio by mean time and per home-mode answer, and our FK
   called one input at a time.
5. ``targets``: home-mode FK >= 1e5 per second with residual <= 1e-12 and >= 100x
   the fsolve approach (our median batch rate over 1 / the median fsolve time per
   input); home-mode FK on uniform inputs (unreachable ones included) >= 3e5 per
   second; IK >= 1e6 per second (reachable rotations).

Batch timings: one warm-up call, then repeated calls of the whole batch; the median
and p95 are over those repeats. The peer and single-input calls are timed per input.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from collections.abc import Sequence
from typing import Any

from ._common import limit_to_one_thread

#: Whether the one-thread limit was set before numpy was imported.
THREADS_LIMITED = limit_to_one_thread()

import numpy as np  # noqa: E402
import numpy.typing as npt  # noqa: E402
from scipy.optimize import fsolve  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin.rotations import matrix_from_quaternion  # noqa: E402

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
    time_call,
    time_each,
    with_all_pass,
)

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Seed of every random input of this benchmark.
SEED = 20_240_611

#: Two platform-axis sets closer than this (max abs difference) are the same answer.
SAME_SOLUTION_TOL = 1e-6
#: A converged peer answer within this of our home axes (but not within
#: SAME_SOLUTION_TOL) is the home mode found imprecisely.
NEAR_SOLUTION_TOL = 1e-4
#: |det[v_10 v_20 v_30]| at or below this: the home axes are coplanar (beta = 90 deg),
#: so a mirror image of the platform is itself a rotation and "mirror" cannot occur.
COPLANAR_TOL = 1e-9
#: |b_ii| or |det A| at or below this carry no sign (on a singularity).
SIGN_TOL = 1e-9

#: The project's targets.
TARGET_FK_PER_SECOND = 100_000.0
#: Home-mode FK on uniform inputs (unreachable ones included), issue 21.
TARGET_FK_UNIFORM_PER_SECOND = 300_000.0
TARGET_FK_RESIDUAL = 1e-12
TARGET_FK_SPEEDUP = 100.0
TARGET_IK_PER_SECOND = 1_000_000.0

#: Outcome labels of the peer's answers, in print order.
OUTCOMES = ("home", "other_mode", "mirror", "failed")


@dataclasses.dataclass(frozen=True)
class Sizes:
    """Problem sizes and repeat counts of one run."""

    fk: int
    all_modes: int
    ik: int
    peer: int
    repeats: int


FULL = Sizes(fk=100_000, all_modes=20_000, ik=1_000_000, peer=2_000, repeats=7)
QUICK = Sizes(fk=2_000, all_modes=500, ik=20_000, peer=40, repeats=3)


# -------------------------------------------------------------------------- inputs
def reachable_inputs(
    design: spm.SPMDesign, n: int, rng: np.random.Generator
) -> tuple[FloatArray, int]:
    """``n`` inputs uniform in [-pi, pi]^3 that have a home-mode assembly.

    Draws chunks of uniform inputs, keeps the reachable ones and tops up to ``n``.

    Returns:
        The inputs (n, 3) [rad] and how many uniform inputs were drawn.
    """
    kept: list[FloatArray] = []
    have = drawn = 0
    while have < n:
        chunk = rng.uniform(-math.pi, math.pi, size=(max(2 * (n - have), 1_000), 3))
        drawn += chunk.shape[0]
        good = chunk[spm.forward_kinematics(chunk, design).reachable]
        kept.append(good)
        have += good.shape[0]
    return np.concatenate(kept)[:n], drawn


def rotation_about(axis: FloatArray, angle: FloatArray) -> FloatArray:
    """Rotation matrices (n, 3, 3) by ``angle`` (n,) [rad] about the unit ``axis`` (3,)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    c, s = np.cos(angle)[:, None, None], np.sin(angle)[:, None, None]
    result: FloatArray = c * np.eye(3) + s * k + (1.0 - c) * np.outer(axis, axis)
    return result


def proximal_axes(theta: FloatArray, design: spm.SPMDesign) -> FloatArray:
    """w_i(theta_i) = rotation of w_i0 about u_i by theta_i (Rodrigues), rows (n, 3, 3).

    Written here from the design's home axes, independently of the library's FK.
    """
    u, w0 = design.u, design.w0
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
    along = np.sum(u * w0, axis=-1)[:, None] * u
    result: FloatArray = c * w0 + s * np.cross(u, w0) + (1.0 - c) * along
    return result


def home_rule(w: FloatArray, v: FloatArray, design: spm.SPMDesign) -> tuple[BoolArray, FloatArray]:
    """Independent check of the home assembly mode and of the closure.

    Home mode: every b_ii = (u_i x w_i) . v_i > 0 and det A (rows a_i = w_i x v_i) of
    the sign it has at home.

    Returns:
        (n,) home flags and (n,) closure residuals: max over |w_i . v_i - cos a2|,
        |v_i . v_j - v_i0 . v_j0| (i, j = 1..3, so |v_i| = 1 too).
    """
    b = np.sum(np.cross(design.u, w) * v, axis=-1)
    det_a = np.linalg.det(np.cross(w, v))
    det_home = np.linalg.det(np.cross(design.w0, design.v0))
    home = np.all(b > SIGN_TOL, axis=-1) & (det_a * np.sign(det_home) > SIGN_TOL)
    loop = np.abs(np.sum(w * v, axis=-1) - math.cos(design.alpha2)).max(axis=-1)
    gram = np.abs(v @ np.swapaxes(v, -1, -2) - design.v0 @ design.v0.T).max(axis=(-2, -1))
    residual: FloatArray = np.maximum(loop, gram)
    return home, residual


# --------------------------------------------------------------------------- peer
@dataclasses.dataclass(frozen=True)
class PeerAnswer:
    """One fsolve answer: the platform axes (rows) and MINPACK's status flag."""

    v: FloatArray
    ier: int


def fsolve_fk(w: FloatArray, design: spm.SPMDesign) -> PeerAnswer:
    """The public approach: fsolve on 9 unknowns (v_1, v_2, v_3) from the guess v_0.

    Equations: |v_i|^2 - 1 = 0, w_i . v_i - cos a2 = 0, v_i . v_j - v_i0 . v_j0 = 0
    for (i, j) = (1, 2), (2, 3), (3, 1). MINPACK hybrd with its finite-difference
    Jacobian (what ``fsolve(f, x0)`` does without ``fprime``).
    """
    cos_a2 = math.cos(design.alpha2)
    v0 = np.asarray(design.v0)
    g12, g23, g31 = float(v0[0] @ v0[1]), float(v0[1] @ v0[2]), float(v0[2] @ v0[0])

    def equations(x: FloatArray) -> FloatArray:
        v = x.reshape(3, 3)
        return np.array(
            [
                v[0] @ v[0] - 1.0,
                v[1] @ v[1] - 1.0,
                v[2] @ v[2] - 1.0,
                w[0] @ v[0] - cos_a2,
                w[1] @ v[1] - cos_a2,
                w[2] @ v[2] - cos_a2,
                v[0] @ v[1] - g12,
                v[1] @ v[2] - g23,
                v[2] @ v[0] - g31,
            ]
        )

    x, _info, ier, _message = fsolve(equations, v0.ravel(), full_output=True)
    return PeerAnswer(v=np.asarray(x, dtype=float).reshape(3, 3), ier=int(ier))


def classify(answer: PeerAnswer, v_home: FloatArray, design: spm.SPMDesign) -> str:
    """Label a peer answer against our home-mode axes ``v_home`` (rows).

    ``"failed"`` (ier != 1), ``"home"`` (max |v - v_home| < SAME_SOLUTION_TOL),
    ``"mirror"`` (det[v_1 v_2 v_3] of the other sign than det[v_10 v_20 v_30]: a
    left-handed, improper platform; impossible when the home axes are coplanar),
    else ``"other_mode"``.
    """
    if answer.ier != 1:
        return "failed"
    if float(np.abs(answer.v - v_home).max()) < SAME_SOLUTION_TOL:
        return "home"
    det_home = float(np.linalg.det(design.v0))
    if abs(det_home) > COPLANAR_TOL and float(np.linalg.det(answer.v)) * det_home < 0.0:
        return "mirror"
    return "other_mode"


def loop_residual(w: FloatArray, v: FloatArray, design: spm.SPMDesign) -> float:
    """max_i |w_i . v_i - cos a2|."""
    return float(np.abs(np.sum(w * v, axis=-1) - math.cos(design.alpha2)).max())


def equation_residual(w: FloatArray, v: FloatArray, design: spm.SPMDesign) -> float:
    """Max abs of all 9 peer equations (loops, unit norms, dot products)."""
    gram = np.abs(v @ v.T - design.v0 @ design.v0.T).max()
    return max(loop_residual(w, v, design), float(gram))


# ------------------------------------------------------------------------ sections
def _batch_entry(timing: Timing, n: int, **extra: Any) -> dict[str, Any]:
    entry: dict[str, Any] = {"n": n, **timing.summary(items=n)}
    entry.update(extra)
    return entry


def bench_fk(
    design: spm.SPMDesign, theta_reach: FloatArray, theta_uniform: FloatArray, repeats: int
) -> tuple[dict[str, dict[str, Any]], spm.FKResult, spm.FKResult]:
    """Home-mode FK on the reachable batch and on the uniform batch."""
    results: dict[str, dict[str, Any]] = {}
    timed = time_call(lambda: spm.forward_kinematics(theta_reach, design), repeats=repeats)
    fk = timed.value
    home, residual = home_rule(proximal_axes(theta_reach, design), fk.v, design)
    results["fk_home_reachable"] = _batch_entry(
        timed.timing,
        theta_reach.shape[0],
        reachable_fraction=float(np.mean(fk.reachable)),
        home_rate=float(np.mean(home & fk.reachable)),
        max_residual=float(np.nanmax(residual)),
        max_reported_residual=float(np.nanmax(fk.residual)),
    )
    timed_u = time_call(lambda: spm.forward_kinematics(theta_uniform, design), repeats=repeats)
    fk_u = timed_u.value
    ok = fk_u.reachable
    home_u, residual_u = home_rule(proximal_axes(theta_uniform[ok], design), fk_u.v[ok], design)
    results["fk_home_uniform"] = _batch_entry(
        timed_u.timing,
        theta_uniform.shape[0],
        reachable_fraction=float(np.mean(ok)),
        home_rate_of_reachable=float(np.mean(home_u)) if home_u.size else math.nan,
        max_residual=float(np.max(residual_u)) if residual_u.size else math.nan,
        max_reported_residual=float(np.max(fk_u.residual[ok])) if np.any(ok) else math.nan,
    )
    return results, fk, fk_u


def bench_fk_all(
    design: spm.SPMDesign,
    theta: FloatArray,
    home_reachable: BoolArray,
    home_rotation: FloatArray,
    repeats: int,
) -> dict[str, Any]:
    """All-modes FK; mode-count distribution; agreement with the home-mode FK.

    ``home_reachable`` and ``home_rotation`` are the home-mode FK on the same inputs.
    """
    timed = time_call(lambda: spm.forward_kinematics_all(theta, design), repeats=repeats)
    modes = timed.value
    counts = np.bincount(modes.count.reshape(-1), minlength=modes.valid.shape[-1] + 1)
    home_counts = np.bincount(np.sum(modes.home, axis=-1), minlength=2)
    has_home = np.any(modes.home, axis=-1)
    index = np.argmax(modes.home, axis=-1)
    rows = np.arange(theta.shape[0])
    both = has_home & home_reachable
    r_home = modes.R[rows, index]
    max_r_diff = (
        float(np.abs(r_home[both] - home_rotation[both]).max()) if np.any(both) else math.nan
    )
    n = theta.shape[0]
    return _batch_entry(
        timed.timing,
        n,
        solutions_per_second=float(np.sum(modes.count)) / timed.timing.median,
        mode_count_histogram={str(k): int(c) for k, c in enumerate(counts) if c},
        mode_count_fraction={str(k): float(c) / n for k, c in enumerate(counts) if c},
        home_mode_count_histogram={str(k): int(c) for k, c in enumerate(home_counts) if c},
        home_mode_agrees_with_fk=float(np.mean(has_home == home_reachable)),
        max_home_rotation_difference=max_r_diff,
        max_residual=float(np.max(modes.residual[modes.valid])),
    )


def ik_rotations(
    design: spm.SPMDesign, fk: spm.FKResult, theta: FloatArray, n: int, rng: np.random.Generator
) -> tuple[FloatArray, FloatArray]:
    """``n`` reachable rotations and the inputs that produce them (home working mode).

    Each is a home-mode FK solution; for a coaxial design it is turned about the
    common axis by a random angle c, which adds c to every input.
    """
    pick = rng.integers(0, theta.shape[0], size=n)
    rotation, expected = fk.R[pick], theta[pick]
    if design.is_coaxial:
        turn = rng.uniform(-math.pi, math.pi, size=n)
        rotation = rotation_about(np.asarray(design.u[0]), turn) @ rotation
        expected = expected + turn[:, None]
    return rotation, expected


def bench_ik(
    design: spm.SPMDesign,
    rotation: FloatArray,
    expected: FloatArray,
    uniform: FloatArray,
    repeats: int,
) -> dict[str, dict[str, Any]]:
    """IK (home working mode) on reachable and on uniformly random rotations."""
    timed = time_call(lambda: spm.inverse_kinematics(rotation, design), repeats=repeats)
    ik = timed.value
    error = np.angle(np.exp(1j * (ik.theta - expected)))
    ok = ik.reachable
    timed_u = time_call(lambda: spm.inverse_kinematics(uniform, design), repeats=repeats)
    return {
        "ik_reachable": _batch_entry(
            timed.timing,
            rotation.shape[0],
            reachable_fraction=float(np.mean(ok)),
            max_round_trip_error_rad=float(np.abs(error[ok]).max()) if np.any(ok) else math.nan,
        ),
        "ik_uniform": _batch_entry(
            timed_u.timing,
            uniform.shape[0],
            reachable_fraction=float(np.mean(timed_u.value.reachable)),
        ),
    }


def bench_peer(
    design: spm.SPMDesign, theta: FloatArray, fk: spm.FKResult, ours_per_second: float
) -> tuple[dict[str, Any], dict[str, Any]]:
    """fsolve per input versus ours on the same inputs; also ours one input per call."""
    n = theta.shape[0]
    w = proximal_axes(theta, design)  # outside the timed region (in the peer's favour)
    v_ours = fk.v[:n]
    with np.errstate(all="ignore"):
        timing, answers = time_each(lambda k: fsolve_fk(w[k], design), list(range(n)))
    labels = [classify(a, v_ours[k], design) for k, a in enumerate(answers)]
    counts = {label: labels.count(label) for label in OUTCOMES}
    converged = [k for k, label in enumerate(labels) if label != "failed"]
    residual_all = [loop_residual(w[k], a.v, design) for k, a in enumerate(answers)]
    residual_conv = [residual_all[k] for k in converged]
    distance = [float(np.abs(a.v - v_ours[k]).max()) for k, a in enumerate(answers)]
    equations_conv = [equation_residual(w[k], answers[k].v, design) for k in converged]
    failed_at_home = sum(
        1 for k, label in enumerate(labels) if label == "failed" and distance[k] < SAME_SOLUTION_TOL
    )
    other_near_home = sum(
        1
        for k, label in enumerate(labels)
        if label == "other_mode" and distance[k] < NEAR_SOLUTION_TOL
    )
    home_error = [distance[k] for k, label in enumerate(labels) if label == "home"]
    # Is each "other mode" answer one of our assembly modes?
    others = [k for k, label in enumerate(labels) if label == "other_mode"]
    other_matched = 0
    if others:
        modes = spm.forward_kinematics_all(theta[others], design)
        for j, k in enumerate(others):
            diff = np.abs(modes.v[j] - answers[k].v).max(axis=(-2, -1))
            other_matched += int(np.any(modes.valid[j] & (diff < SAME_SOLUTION_TOL)))

    home_ours, residual_ours = home_rule(w, v_ours, design)
    single = time_each(lambda k: spm.forward_kinematics(theta[k], design), list(range(n)))[0]
    peer_per_second = 1.0 / timing.median
    single_entry: dict[str, Any] = {"n": n, **single.summary(items=1)}
    peer: dict[str, Any] = {
        "method": (
            "scipy.optimize.fsolve (MINPACK hybrd, finite-difference Jacobian) on the 9 "
            "unknowns v_1, v_2, v_3 with |v_i| = 1, w_i . v_i = cos a2, "
            "v_i . v_j = v_i0 . v_j0; initial guess v = design.v0; one call per input; "
            "w_i computed outside the timed region"
        ),
        "n": n,
        **timing.summary(items=1),
        "throughput_per_second": n / timing.total,
        "outcomes": counts,
        "outcome_rates": {label: counts[label] / n for label in OUTCOMES},
        "home_rate": counts["home"] / n,
        "mirror_possible": bool(abs(float(np.linalg.det(design.v0))) > COPLANAR_TOL),
        "failed_but_at_home": failed_at_home,
        "other_mode_is_an_assembly_mode": other_matched,
        "other_mode_near_home": other_near_home,
        "max_v_error_of_home_answers": max(home_error) if home_error else math.nan,
        "max_equation_residual_converged": max(equations_conv) if equations_conv else math.nan,
        "max_loop_residual_converged": max(residual_conv) if residual_conv else math.nan,
        "median_loop_residual_converged": (
            float(np.median(residual_conv)) if residual_conv else math.nan
        ),
        "max_loop_residual_all": max(residual_all),
        "ours_home_rate": float(np.mean(home_ours & fk.reachable[:n])),
        "ours_max_residual": float(np.max(residual_ours)),
        "speed_ratio_ours_vs_peer": ours_per_second / peer_per_second,
        "speed_ratio_ours_vs_peer_throughput": ours_per_second * timing.total / n,
        "speed_ratio_ours_vs_peer_per_home_answer": (
            ours_per_second * n / (peer_per_second * counts["home"]) if counts["home"] else math.inf
        ),
        "speed_ratio_ours_single_call_vs_peer": single_entry["per_second"] / peer_per_second,
    }
    return peer, single_entry


def evaluate_targets(results: dict[str, dict[str, Any]], peer: dict[str, Any]) -> dict[str, Any]:
    """The project's targets, each with value, threshold and pass flag."""
    fk = results["fk_home_reachable"]
    residual = max(fk["max_residual"], fk["max_reported_residual"])
    targets: dict[str, Any] = {
        "fk_home_per_second": target(
            fk["per_second"], TARGET_FK_PER_SECOND, at_least=True, unit="1/s"
        ),
        "fk_home_uniform_per_second": target(
            results["fk_home_uniform"]["per_second"],
            TARGET_FK_UNIFORM_PER_SECOND,
            at_least=True,
            unit="1/s",
        ),
        "fk_home_max_residual": target(residual, TARGET_FK_RESIDUAL, at_least=False),
        "fk_home_speedup_vs_fsolve": target(
            peer["speed_ratio_ours_vs_peer"], TARGET_FK_SPEEDUP, at_least=True, unit="x"
        ),
        "ik_per_second": target(
            results["ik_reachable"]["per_second"], TARGET_IK_PER_SECOND, at_least=True, unit="1/s"
        ),
    }
    return with_all_pass(targets)


# ------------------------------------------------------------------------- report
def report(payload: dict[str, Any]) -> str:
    """The human-readable summary of a run."""
    machine, config = payload["machine"], payload["config"]
    results, peer, targets = payload["results"], payload["peer"], payload["targets"]
    packages = machine["packages"]
    threads = "1 thread" if config["threads_limited_before_numpy"] else "threads not limited"
    head = (
        f"spm-pin kinematics benchmark: design {config['design']}, {threads}"
        f"{', QUICK' if config['quick'] else ''}\n"
        f"Python {machine['python']}, numpy {packages.get('numpy')}, "
        f"scipy {packages.get('scipy')}, CPU {machine['cpu']}"
    )
    names = {
        "fk_home_reachable": "FK home, reachable inputs",
        "fk_home_uniform": "FK home, uniform inputs",
        "fk_all_modes": "FK all modes, uniform inputs",
        "ik_reachable": "IK home, reachable rotations",
        "ik_uniform": "IK home, uniform rotations",
        "fk_home_single_call": "FK home, one input per call",
    }
    rows = []
    for key, label in names.items():
        r = results[key]
        if key == "fk_all_modes":
            note = "modes " + ", ".join(
                f"{k}: {100 * f:.1f}%" for k, f in r["mode_count_fraction"].items()
            )
        elif key == "fk_home_single_call":
            note = "per-call median/p95"
        elif key.startswith("fk"):
            note = f"reachable {100 * r['reachable_fraction']:.1f}%"
            note += f", max residual {r['max_residual']:.1e}"
        else:
            note = f"reachable {100 * r['reachable_fraction']:.1f}%"
            if "max_round_trip_error_rad" in r:
                note += f", round trip {r['max_round_trip_error_rad']:.1e} rad"
        rows.append(
            [
                label,
                format_count(r["n"]),
                format_seconds(r["median_s"]),
                format_seconds(r["p95_s"]),
                format_seconds(r["per_item_s"]),
                format_rate(r["per_second"]),
                note,
            ]
        )
    table = format_table(
        ["case", "n", "median", "p95", "per solution", "per second", "notes"], rows
    )
    rates = peer["outcome_rates"]
    outcome_text = ", ".join(f"{k.replace('_', ' ')} {100 * rates[k]:.1f}%" for k in OUTCOMES)
    peer_text = (
        f"Peer: scipy fsolve, 9 equations in v_1..v_3 from guess v_0, {peer['n']:,} "
        f"reachable inputs\n"
        f"  per input: median {format_seconds(peer['median_s'])}, "
        f"p95 {format_seconds(peer['p95_s'])} -> {format_rate(peer['per_second'])}\n"
        f"  outcomes: {outcome_text}"
        f"{'' if peer['mirror_possible'] else ' (mirror impossible: coplanar v_i0)'}\n"
        f"  failed but at home anyway: {peer['failed_but_at_home']}; of the other-mode "
        f"answers, {peer['other_mode_is_an_assembly_mode']} are real assembly modes, "
        f"{peer['other_mode_near_home']} are the home mode within 1e-4 (imprecise)\n"
        f"  fsolve residual max |w.v - cos a2|: {peer['max_loop_residual_converged']:.1e} "
        f"(converged), {peer['max_loop_residual_all']:.1e} (all); all 9 equations "
        f"(converged): {peer['max_equation_residual_converged']:.1e}\n"
        f"  ours on the same inputs: home {100 * peer['ours_home_rate']:.1f}%, "
        f"max residual {peer['ours_max_residual']:.1e}\n"
        f"  speed ours/peer: {peer['speed_ratio_ours_vs_peer']:,.0f}x (batched, median), "
        f"{peer['speed_ratio_ours_vs_peer_throughput']:,.0f}x (batched, mean), "
        f"{peer['speed_ratio_ours_vs_peer_per_home_answer']:,.0f}x (per home answer), "
        f"{peer['speed_ratio_ours_single_call_vs_peer']:,.1f}x (one input per call)"
    )
    labels = {
        "fk_home_per_second": "FK home-mode rate",
        "fk_home_uniform_per_second": "FK home-mode rate, uniform inputs",
        "fk_home_max_residual": "FK home-mode max residual",
        "fk_home_speedup_vs_fsolve": "FK speed-up over fsolve",
        "ik_per_second": "IK rate",
    }
    lines = ["Targets"]
    for key, label in labels.items():
        t = targets[key]
        if key == "fk_home_max_residual":
            value, limit = f"{t['value']:.1e}", f"{t['threshold']:.0e}"
        elif t["unit"] == "x":
            value, limit = f"{t['value']:,.0f}x", f"{t['threshold']:,.0f}x"
        else:
            value, limit = format_rate(t["value"]), format_rate(t["threshold"])
        status = "PASS" if t["pass"] else "FAIL"
        lines.append(f"  {status}  {label}: {value} ({t['comparison']} {limit})")
    return "\n\n".join([head, table, peer_text, "\n".join(lines)])


# --------------------------------------------------------------------------- main
def run(sizes: Sizes, design: spm.SPMDesign, *, quick: bool) -> dict[str, Any]:
    """Run every section and return the JSON payload."""
    rng = np.random.default_rng(SEED)
    n_fk = max(sizes.fk, sizes.peer)
    theta_reach, drawn = reachable_inputs(design, n_fk, rng)
    theta_uniform = rng.uniform(-math.pi, math.pi, size=(max(sizes.fk, sizes.all_modes), 3))

    results, fk, fk_u = bench_fk(design, theta_reach, theta_uniform, sizes.repeats)
    results["fk_home_reachable"]["uniform_inputs_drawn"] = drawn
    n_all = sizes.all_modes
    results["fk_all_modes"] = bench_fk_all(
        design,
        theta_uniform[:n_all],
        fk_u.reachable[:n_all],
        fk_u.R[:n_all],
        sizes.repeats,
    )
    rotation, expected = ik_rotations(design, fk, theta_reach, sizes.ik, rng)
    quaternion = rng.standard_normal(size=(sizes.ik, 4))
    uniform_rotation = matrix_from_quaternion(quaternion)
    results.update(bench_ik(design, rotation, expected, uniform_rotation, sizes.repeats))
    del rotation, expected, uniform_rotation, quaternion

    peer, single = bench_peer(
        design, theta_reach[: sizes.peer], fk, results["fk_home_reachable"]["per_second"]
    )
    results["fk_home_single_call"] = single
    return {
        "benchmark": "kinematics",
        "machine": machine_info(("numpy", "scipy"), {"spm_pin": spm.__version__}),
        "config": {
            "quick": quick,
            "design": design.name,
            "seed": SEED,
            "sizes": dataclasses.asdict(sizes),
            "threads_limited_before_numpy": THREADS_LIMITED,
            "timing": "perf_counter; 1 warm-up call; median/p95/p99 over repeats of the "
            "whole batch call (per call for the peer and single-input rows)",
        },
        "results": results,
        "peer": peer,
        "targets": evaluate_targets(results, peer),
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the summary, write the JSON; returns the exit code."""
    parser = standard_parser(
        "kinematics",
        "Speed and accuracy of spm-pin's FK and IK, next to scipy fsolve.",
    )
    parser.add_argument(
        "--design",
        default="prototype",
        help="design preset: prototype (default) or agile_eye",
    )

    def run_with(args: argparse.Namespace) -> dict[str, Any]:
        return run(
            QUICK if args.quick else FULL, spm.SPMDesign.preset(args.design), quick=args.quick
        )

    return run_main(parser, run_with, report, argv)


if __name__ == "__main__":
    sys.exit(main())
