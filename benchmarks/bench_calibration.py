"""Calibration benchmark: identification time and accuracy, next to finite differences.

Run from the repository root::

    python -m benchmarks.bench_calibration [--out FILE.json] [--quick]

It prints a short table and writes JSON (default ``benchmarks/results/calibration.json``).
Importing this module limits numpy to one thread (see ``_common.limit_to_one_thread``).

What is measured (seeded synthetic readings of a perturbed prototype: encoder steps of
0.088 deg, sensor noise 0.5 deg per axis):

1. ``analytic``: :func:`spm_pin.calibration.calibrate` on 100 quaternion readings,
   9 parameters (3 encoder offsets, alpha1, alpha2, beta, 3 mounting angles), robust
   soft-L1 loss, analytic Jacobian. Also ``analytic_12``: the same with the sensor's
   reference frame free too (12 parameters; one is not identifiable and is reported).
2. ``peer``: the same problem solved the way a generic tool does it: the same call
   with ``jacobian="2-point"`` (scipy's default finite differences).
3. ``parse``: reading the 100-row CSV file.
4. Accuracy over several seeds: the error of each estimate in units of its standard
   deviation, and the joint Mahalanobis distance per parameter (about 1 when the
   covariances are right).
5. ``targets``: identification of >= 7 parameters from 100 readings in <= 2 s (median).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ._common import limit_to_one_thread

#: Whether the one-thread limit was set before numpy was imported.
THREADS_LIMITED = limit_to_one_thread()

import numpy as np  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin import calibration as cal  # noqa: E402

from ._common import (  # noqa: E402
    Timing,
    format_seconds,
    format_table,
    machine_info,
    run_main,
    standard_parser,
    target,
    time_call,
    with_all_pass,
)

#: Seed of the timed problem; the accuracy seeds follow it.
SEED = 20_240_905
#: The project's targets.
TARGET_SECONDS = 2.0
TARGET_PARAMETERS = 7


@dataclasses.dataclass(frozen=True)
class Sizes:
    """Problem sizes and repeat counts of one run."""

    readings: int
    repeats: int
    accuracy_seeds: int


FULL = Sizes(readings=100, repeats=15, accuracy_seeds=20)
QUICK = Sizes(readings=100, repeats=3, accuracy_seeds=3)


def _entry(timing: Timing, result: cal.CalibrationResult) -> dict[str, Any]:
    identified = result.identifiability.identified
    return {
        **timing.summary(items=1),
        "readings": len(result.readings),
        "parameters": len(result.estimates),
        "identified": len(identified),
        "nfev": result.nfev,
        "njev": result.njev,
        "ok": result.ok,
        "rms_error_after_deg": float(np.sqrt(np.nanmean(result.error_deg**2))),
    }


def accuracy(seeds: Sequence[int], readings: int) -> dict[str, Any]:
    """Errors of the estimates against the truth, in standard deviations."""
    z: list[float] = []
    distance: list[float] = []
    for seed in seeds:
        syn = cal.synthetic_readings(readings, seed=seed)
        result = cal.calibrate(syn.readings)
        truth = syn.truth.vector(result.start)
        values = np.array([e.value for e in result.estimates])
        expected = np.array([truth[cal.PARAMETER_NAMES.index(e.name)] for e in result.estimates])
        std = np.array([e.std for e in result.estimates])
        error = values - expected
        z += list(error / std)
        distance.append(float(error @ np.linalg.solve(result.covariance, error)) / error.size)
    z_abs = np.abs(np.array(z))
    return {
        "seeds": len(seeds),
        "max_abs_z": float(z_abs.max()),
        "fraction_within_2_std": float(np.mean(z_abs <= 2.0)),
        "mean_mahalanobis_per_parameter": float(np.mean(distance)),
    }


def run(sizes: Sizes, *, quick: bool) -> dict[str, Any]:
    """Run every section and return the JSON payload."""
    syn = cal.synthetic_readings(sizes.readings, seed=SEED)
    readings = syn.readings
    results: dict[str, dict[str, Any]] = {}
    timed = time_call(lambda: cal.calibrate(readings), repeats=sizes.repeats)
    results["analytic"] = _entry(timed.timing, timed.value)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "readings.csv"
        readings.to_csv(path)
        parsed = time_call(lambda: cal.load_readings(path), repeats=sizes.repeats)
    results["parse"] = {**parsed.timing.summary(items=len(readings)), "rows": len(readings)}

    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", cal.IdentifiabilityWarning)
        timed_12 = time_call(
            lambda: cal.calibrate(readings, parameters="offsets,links,mount,ref"),
            repeats=sizes.repeats,
        )
    results["analytic_12"] = _entry(timed_12.timing, timed_12.value)
    results["analytic_12"]["unidentified"] = list(timed_12.value.identifiability.unidentified)

    peer_timed = time_call(
        lambda: cal.calibrate(readings, jacobian="2-point"), repeats=sizes.repeats
    )
    peer = _entry(peer_timed.timing, peer_timed.value)
    ours, theirs = timed.value, peer_timed.value
    difference = max(
        abs(a.value - b.value) for a, b in zip(ours.estimates, theirs.estimates, strict=True)
    )
    peer.update(
        {
            "method": "scipy.optimize.least_squares (trf, soft_l1) with its default "
            "2-point finite-difference Jacobian, same residuals and start",
            "max_estimate_difference_deg": math.degrees(difference),
            "speed_ratio_ours_vs_peer": peer["median_s"] / results["analytic"]["median_s"],
        }
    )
    acc = accuracy([SEED + 1 + k for k in range(sizes.accuracy_seeds)], sizes.readings)
    analytic = results["analytic"]
    targets: dict[str, Any] = {
        "identification_seconds": target(
            analytic["median_s"], TARGET_SECONDS, at_least=False, unit="s"
        ),
        "parameters_identified": target(
            float(analytic["identified"]), TARGET_PARAMETERS, at_least=True
        ),
    }
    with_all_pass(targets)
    return {
        "benchmark": "calibration",
        "machine": machine_info(("numpy", "scipy"), {"spm_pin": spm.__version__}),
        "config": {
            "quick": quick,
            "seed": SEED,
            "sizes": dataclasses.asdict(sizes),
            "threads_limited_before_numpy": THREADS_LIMITED,
            "noise_deg": 0.5,
            "encoder_ticks_per_turn": cal.TICKS_PER_TURN,
            "timing": "perf_counter; 1 warm-up call; median/p95/p99 over repeated calls",
        },
        "results": results,
        "peer": peer,
        "accuracy": acc,
        "targets": targets,
    }


def report(payload: dict[str, Any]) -> str:
    """The human-readable summary of a run."""
    config, results, peer = payload["config"], payload["results"], payload["peer"]
    threads = "1 thread" if config["threads_limited_before_numpy"] else "threads not limited"
    head = (
        f"spm-pin calibration benchmark: prototype, {threads}{', QUICK' if config['quick'] else ''}"
    )
    rows = []
    for key, label in (
        ("analytic", "calibrate, analytic Jacobian"),
        ("analytic_12", "calibrate, 12 parameters"),
    ):
        r = results[key]
        rows.append(
            [
                label,
                f"{r['readings']}",
                f"{r['identified']}/{r['parameters']}",
                format_seconds(r["median_s"]),
                format_seconds(r["p95_s"]),
                f"{r['nfev']}",
            ]
        )
    rows.append(
        [
            "peer: 2-point finite differences",
            f"{peer['readings']}",
            f"{peer['identified']}/{peer['parameters']}",
            format_seconds(peer["median_s"]),
            format_seconds(peer["p95_s"]),
            f"{peer['nfev']}",
        ]
    )
    table = format_table(["case", "readings", "identified", "median", "p95", "nfev"], rows)
    acc = payload["accuracy"]
    parse = results["parse"]
    notes = (
        f"speed ours/peer: {peer['speed_ratio_ours_vs_peer']:.1f}x; largest estimate "
        f"difference {peer['max_estimate_difference_deg']:.1e} deg\n"
        f"parse {parse['rows']} rows: median {format_seconds(parse['median_s'])}\n"
        f"accuracy over {acc['seeds']} seeds: max |error|/std {acc['max_abs_z']:.2f}, "
        f"{100 * acc['fraction_within_2_std']:.0f}% within 2 std, Mahalanobis per "
        f"parameter {acc['mean_mahalanobis_per_parameter']:.2f} (1 when the covariances "
        "are right)"
    )
    lines = ["Targets"]
    t = payload["targets"]
    time_target = t["identification_seconds"]
    lines.append(
        f"  {'PASS' if time_target['pass'] else 'FAIL'}  identification of "
        f"{results['analytic']['identified']} parameters from "
        f"{results['analytic']['readings']} readings: "
        f"{format_seconds(time_target['value'])} (<= {time_target['threshold']:g} s)"
    )
    count = t["parameters_identified"]
    lines.append(
        f"  {'PASS' if count['pass'] else 'FAIL'}  parameters identified: "
        f"{count['value']:.0f} (>= {count['threshold']})"
    )
    return "\n\n".join([head, table, notes, "\n".join(lines)])


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the summary, write the JSON; returns the exit code."""
    parser = standard_parser(
        "calibration",
        "Speed and accuracy of spm-pin's calibration, next to finite differences.",
        quick_help="few repeats (smoke test)",
    )
    return run_main(
        parser, lambda args: run(QUICK if args.quick else FULL, quick=args.quick), report, argv
    )


if __name__ == "__main__":
    sys.exit(main())
