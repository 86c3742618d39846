"""Run every benchmark, gather their JSON into one file and one markdown table.

``python -m benchmarks`` (see :func:`main`) runs each ``benchmarks/bench_<name>.py`` in
its own interpreter (``python -m benchmarks.bench_<name> --out DIR/<name>.json``), one
after the other, with numpy's thread pools limited to one thread through the child's
environment. It then writes, in DIR (default ``benchmarks/results/``):

- ``<name>.json`` and ``<name>.log``: each benchmark's own JSON and printed report;
- ``summary.json``: the machine, the run's settings and, per benchmark, its status,
  its full JSON (``result``), its headline figures beside the peer measured in the same
  run (``figures``) and every target with its verdict, measured value, peer value and
  ratio (``targets``);
- ``summary.md``: those figures as one markdown table
  (figure | ours median | p95 | peer | ratio | target | verdict).

``--update-docs`` puts the table into ``docs/benchmarks.md`` between
:data:`START_MARKER` and :data:`END_MARKER` (full runs of every benchmark only).

Each benchmark's JSON has its own layout; the adapters below (one per benchmark)
pick the headline figures out of it. A target that no adapter places gets a row of
its own, so every target reaches the table even when a benchmark adds one.

This module imports only the standard library (the benchmarks import numpy, in their
own processes).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, TextIO

from ._common import (
    RESULTS_DIR,
    THREAD_ENV_VARS,
    format_rate,
    format_seconds,
    machine_info,
    write_json,
)

__all__ = [
    "BENCHMARKS",
    "END_MARKER",
    "START_MARKER",
    "TABLE_HEADER",
    "Benchmark",
    "Figure",
    "main",
    "render_markdown",
    "replace_between_markers",
]

#: The repository root (``python -m benchmarks.bench_<name>`` runs from here).
ROOT = Path(__file__).resolve().parent.parent
#: The documentation page that shows the latest table.
DOCS_PAGE = ROOT / "docs" / "benchmarks.md"
#: The generated table sits between these two lines of the page.
START_MARKER = "<!-- bench-table:start -->"
END_MARKER = "<!-- bench-table:end -->"
#: Columns of the markdown table.
TABLE_HEADER = ("figure", "ours median", "p95", "peer", "ratio", "target", "verdict")
#: Names of the combined outputs in the output folder.
SUMMARY_JSON = "summary.json"
SUMMARY_MD = "summary.md"
#: Packages whose versions the summary records.
PACKAGES = ("spm-pin", "numpy", "scipy", "pin", "coal", "mujoco", "dynamixel-sdk")
#: Default time limit of one benchmark [s] (a full run of the slowest takes minutes).
DEFAULT_TIMEOUT_S = 1800.0
#: Lines of a failed benchmark's log kept in the summary.
LOG_TAIL_LINES = 30
#: Missing modules that make a benchmark "skipped" rather than "failed" are the
#: optional ones: anything but the project's own packages.
OWN_PACKAGES = ("spm_pin", "benchmarks")
#: What the ratio column means (also written into the summary JSON).
RATIO_MEANING = (
    "how many times better ours is than the peer: peer time / our time for timings, "
    "peer value / our value for errors and residuals, our value / peer value for "
    "counts and fractions; below 1 the peer is ahead"
)
#: Legend printed under the table.
LEGEND = (
    "ours median, p95: per call or per item (batch calls: the batch time divided by its "
    "size), or the measured value for accuracy rows; peer: the peer's median (or value) "
    "in the same run; ratio: " + RATIO_MEANING + "; target: the threshold and, in "
    "brackets, the measured value it is checked against."
)


# ----------------------------------------------------------------------- figures
@dataclasses.dataclass(frozen=True)
class Figure:
    """One row of the table: our figure beside the peer's, and the targets it carries.

    Attributes:
        key: Name of the row within its benchmark (stable, for JSON readers).
        label: What the row measures (first column).
        kind: ``"time"`` (``median`` and ``p95`` in seconds) or ``"value"`` (a measured
            number in ``unit``; no p95) or ``"status"`` (a benchmark that did not run).
        median: Our median time [s] or our value.
        p95: Our 95th percentile [s] (times only).
        unit: Unit of a value (``""``, ``"rad"``, ``"fraction"``, ``"count"`` ...).
        peer_name: Short name of the peer, or None when there is none.
        peer: The peer's median time [s] or value, same unit as ours.
        ratio: How many times better ours is (see :data:`RATIO_MEANING`).
        higher_is_better: For values: True for counts and fractions (then the ratio is
            ours / peer), False for errors (peer / ours). Times: lower is better.
        targets: Names of the benchmark's targets this row shows.
    """

    key: str
    label: str
    kind: str
    median: float | None
    p95: float | None = None
    unit: str = "s"
    peer_name: str | None = None
    peer: float | None = None
    ratio: float | None = None
    higher_is_better: bool = False
    targets: tuple[str, ...] = ()

    def to_json(self) -> dict[str, Any]:
        """The row as plain JSON data."""
        return {
            "key": self.key,
            "label": self.label,
            "kind": self.kind,
            "unit": self.unit,
            "ours": {"median": self.median, "p95": self.p95},
            "peer": (
                None if self.peer_name is None else {"name": self.peer_name, "value": self.peer}
            ),
            "ratio": self.ratio,
            "targets": list(self.targets),
        }


def _advantage(ours: float | None, peer: float | None, *, higher_is_better: bool) -> float | None:
    """How many times better ``ours`` is than ``peer`` (None when undefined)."""
    if ours is None or peer is None:
        return None
    top, bottom = (ours, peer) if higher_is_better else (peer, ours)
    if bottom == 0 or not math.isfinite(top / bottom):
        return None
    return top / bottom


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
        entry: Our entry: ``median_s`` and ``p95_s`` (and ``items``).
        per_item: Divide by ``items`` (batch calls: per solution, per step).
        peer: The peer's entry, read the same way.
        ratio: The benchmark's own speed ratio; by default peer median / our median.
    """

    def stats(e: Mapping[str, Any]) -> tuple[float, float]:
        items = float(e.get("items", 1)) if per_item else 1.0
        return float(e["median_s"]) / items, float(e["p95_s"]) / items

    median, p95 = stats(entry)
    peer_median = stats(peer)[0] if peer is not None else None
    if ratio is None:
        ratio = _advantage(median, peer_median, higher_is_better=False)
    return Figure(
        key,
        label,
        "time",
        median,
        p95,
        peer_name=peer_name if peer is not None else None,
        peer=peer_median,
        ratio=ratio,
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
        float(value),
        unit=unit,
        peer_name=peer_name if peer is not None else None,
        peer=None if peer is None else float(peer),
        ratio=_advantage(float(value), peer, higher_is_better=higher_is_better),
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
            float(workspace["parallel_s"]),
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
    )
}


# ------------------------------------------------------------------------ targets
def _verdict(record: Mapping[str, Any]) -> str:
    return "PASS" if record.get("pass") else "FAIL"


def _peer_for_target(record: Mapping[str, Any], figure: Figure) -> tuple[Any, str | None]:
    """The peer's value beside a target: in the target's unit when it has one."""
    if figure.peer is None:
        return None, None
    if figure.kind == "time" and record.get("unit") in ("1/s", "Hz"):
        return 1.0 / figure.peer if figure.peer > 0 else None, record.get("unit")
    if figure.kind == "time":
        return figure.peer, "s"
    return figure.peer, figure.unit


def gather_targets(
    data: Mapping[str, Any], figures: list[Figure]
) -> tuple[dict[str, dict[str, Any]], list[Figure]]:
    """Every target of a benchmark with verdict, peer value and ratio.

    Targets that no figure names get a row of their own (appended to ``figures``).

    Returns:
        The target records by name and the rows, completed.
    """
    raw = {k: v for k, v in data.get("targets", {}).items() if isinstance(v, Mapping)}
    owner: dict[str, Figure] = {}
    rows: list[Figure] = []
    for figure in figures:
        # A target goes to the first row that names it; one the JSON lacks (this run
        # did not evaluate it, e.g. the 1-degree map of a quick run) is left out.
        names = tuple(n for n in dict.fromkeys(figure.targets) if n in raw and n not in owner)
        row = dataclasses.replace(figure, targets=names)
        owner.update(dict.fromkeys(names, row))
        rows.append(row)
    for name, record in raw.items():
        if name not in owner:
            figure = valued(
                name, f"{data.get('benchmark', '?')}: {name}", record["value"], targets=(name,)
            )
            figure = dataclasses.replace(figure, unit=str(record.get("unit", "")))
            owner[name] = figure
            rows.append(figure)
    targets: dict[str, dict[str, Any]] = {}
    for name, record in raw.items():
        figure = owner[name]
        peer_value, peer_unit = _peer_for_target(record, figure)
        targets[name] = {
            "figure": figure.key,
            "value": record.get("value"),
            "threshold": record.get("threshold"),
            "comparison": record.get("comparison"),
            "unit": record.get("unit", ""),
            "pass": bool(record.get("pass")),
            "verdict": _verdict(record),
            "peer": figure.peer_name,
            "peer_value": peer_value,
            "peer_unit": peer_unit,
            "ratio": figure.ratio,
        }
    return targets, rows


# ------------------------------------------------------------------------ running
@dataclasses.dataclass
class Run:
    """What one benchmark's process did."""

    name: str
    status: str  # "ok", "failed" or "skipped"
    seconds: float
    returncode: int | None
    reason: str | None
    command: list[str]
    json_path: Path
    log_path: Path
    log_tail: str | None = None  # the end of a failed benchmark's output


MISSING_MODULE = re.compile(r"ModuleNotFoundError: No module named '([^']+)'")


def child_environment() -> dict[str, str]:
    """This environment with every thread pool of numpy and BLAS limited to one thread."""
    env = dict(os.environ)
    env.update(dict.fromkeys(THREAD_ENV_VARS, "1"))
    return env


def _wait(
    process: subprocess.Popen[bytes],
    timeout: float,
    tick: Callable[[float], None] | None,
) -> int | None:
    """Wait for ``process`` (ticking once a second); None after ``timeout`` seconds."""
    start = time.perf_counter()
    while True:
        elapsed = time.perf_counter() - start
        if elapsed >= timeout:
            return None
        try:
            return process.wait(timeout=min(1.0, timeout - elapsed))
        except subprocess.TimeoutExpired:
            if tick is not None:
                tick(time.perf_counter() - start)


def _stop(process: subprocess.Popen[bytes]) -> None:
    """End a benchmark's process group (it may have started workers or an emulator)."""
    try:
        os.killpg(process.pid, signal.SIGTERM)
        process.wait(timeout=10)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()


def run_benchmark(
    benchmark: Benchmark,
    out_dir: Path,
    *,
    quick: bool,
    timeout: float,
    tick: Callable[[float], None] | None = None,
) -> Run:
    """Run one benchmark in a fresh interpreter; its report goes to ``<name>.log``."""
    json_path = out_dir / f"{benchmark.name}.json"
    log_path = out_dir / f"{benchmark.name}.log"
    json_path.unlink(missing_ok=True)  # never report an older run's file
    command = [sys.executable, "-m", benchmark.module, "--out", str(json_path)]
    if quick:
        command.append("--quick")
    start = time.perf_counter()
    with log_path.open("wb") as log:
        process = subprocess.Popen(
            command,
            cwd=ROOT,
            env=child_environment(),
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,  # its own process group, ended as one on timeout
        )
        try:
            returncode = _wait(process, timeout, tick)
        except BaseException:
            _stop(process)
            raise
        if returncode is None:
            _stop(process)
    seconds = time.perf_counter() - start
    status, reason, log_tail = "ok", None, None
    if returncode is None:
        status, reason = "failed", f"timed out after {timeout:g} s"
    elif returncode != 0 or not json_path.is_file():
        text = log_path.read_text(errors="replace")
        missing = MISSING_MODULE.findall(text)
        if missing and missing[-1].split(".")[0] not in OWN_PACKAGES:
            status = "skipped"
            reason = f"optional module {missing[-1]!r} is not installed"
        else:
            status = "failed"
            lines = text.splitlines()[-LOG_TAIL_LINES:]
            log_tail = "\n".join(lines)
            last = lines[-1] if lines else "no output"
            reason = f"exit status {returncode}: {last}"
    return Run(
        benchmark.name,
        status,
        seconds,
        returncode,
        reason,
        command[1:],
        json_path,
        log_path,
        log_tail,
    )


# ------------------------------------------------------------------------ summary
def summarize_run(run: Run, benchmark: Benchmark) -> dict[str, Any]:
    """One benchmark's part of the summary JSON."""
    entry: dict[str, Any] = {
        "status": run.status,
        "seconds": run.seconds,
        "returncode": run.returncode,
        "reason": run.reason,
        "log_tail": run.log_tail,
        "command": " ".join(
            ["python", "-m", benchmark.module, "--out", run.json_path.name]
            + (["--quick"] if "--quick" in run.command else [])
        ),
        "json": run.json_path.name,
        "log": run.log_path.name,
        "peer": benchmark.peer,
    }
    if run.status != "ok":
        label = f"{run.name}: not run ({run.status}: {run.reason or 'no reason'})"
        entry.update(
            figures=[Figure("status", label, "status", None).to_json()],
            targets={},
            all_pass=None,
            result=None,
        )
        return entry
    entry.update(analyse(benchmark, json.loads(run.json_path.read_text(encoding="utf-8"))))
    return entry


def analyse(benchmark: Benchmark, data: Mapping[str, Any]) -> dict[str, Any]:
    """The rows and targets of one benchmark's JSON (``data``, kept as ``result``).

    When the adapter does not understand the JSON (its layout changed), the targets
    still get a row each and ``adapter_error`` says what went wrong.
    """
    try:
        figures = benchmark.figures(data)
        adapter_error = None
    except (KeyError, TypeError, ValueError, ZeroDivisionError) as exc:
        figures, adapter_error = [], f"{type(exc).__name__}: {exc}"
    targets, rows = gather_targets(data, figures)
    return {
        "figures": [f.to_json() for f in rows],
        "targets": targets,
        "all_pass": all(t["pass"] for t in targets.values()),
        "adapter_error": adapter_error,
        "result": data,
    }


def _spm_version(benchmarks: Mapping[str, Any]) -> str | None:
    for entry in benchmarks.values():
        result = entry.get("result")
        if result is not None and result.get("machine", {}).get("spm_pin"):
            return str(result["machine"]["spm_pin"])
    return None


def build_summary(
    entries: Mapping[str, dict[str, Any]],
    *,
    quick: bool,
    jobs: int,
    selected: Sequence[str],
    load_start: list[float] | None,
    seconds: float,
) -> dict[str, Any]:
    """The combined JSON: machine, settings, every benchmark, counts."""
    benchmarks = dict(entries)
    env = child_environment()
    machine = machine_info(PACKAGES)
    machine["thread_env"] = {name: env.get(name) for name in THREAD_ENV_VARS}
    machine["load_average_start"] = load_start
    machine["load_average_end"] = _load_average()
    if machine["packages"].get("spm-pin") is None:
        machine["packages"]["spm-pin"] = _spm_version(benchmarks)
    targets = [t for entry in benchmarks.values() for t in entry["targets"].values()]
    statuses = [entry["status"] for entry in benchmarks.values()]
    return {
        "suite": "spm-pin benchmarks",
        "schema": 1,
        "machine": machine,
        "config": {
            "quick": quick,
            "benchmarks": list(selected),
            "complete": list(selected) == list(BENCHMARKS),
            "jobs": jobs,
            "isolation": "one interpreter per benchmark; thread pools limited to 1 thread",
            "ratio": RATIO_MEANING,
        },
        "summary": {
            "seconds": seconds,
            "benchmarks": len(statuses),
            "ok": statuses.count("ok"),
            "failed": statuses.count("failed"),
            "skipped": statuses.count("skipped"),
            "targets": len(targets),
            "targets_passed": sum(t["pass"] for t in targets),
            "targets_failed": sum(not t["pass"] for t in targets),
        },
        "benchmarks": benchmarks,
    }


def _load_average() -> list[float] | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


# ----------------------------------------------------------------------- markdown
def format_value(value: float | None, unit: str) -> str:
    """A measured value or threshold in its unit, for the table."""
    if value is None or not math.isfinite(value):
        return "—"
    if unit == "s":
        return format_seconds(value)
    if unit == "1/s":
        return format_rate(value)
    if unit == "Hz":
        return format_rate(value).replace(" /s", " Hz")
    if unit == "x":
        return format_ratio(value)
    if unit == "fraction":
        return f"{100 * value:.1f}%"
    if unit == "count" or (unit == "" and float(value).is_integer() and abs(value) < 1e6):
        return f"{value:,.0f}"
    text = f"{value:.1e}"
    return f"{text} {unit}" if unit and unit != "relative" else text


def format_ratio(ratio: float | None) -> str:
    """``"111x"``, ``"2.60x"``, ``"0.32x"``, ``"0.036x"``; ``"—"`` when undefined."""
    if ratio is None or not math.isfinite(ratio):
        return "—"
    if ratio >= 10:
        return f"{ratio:,.0f}x"
    return f"{ratio:.2f}x" if ratio >= 0.1 else f"{ratio:.2g}x"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def table_rows(summary: Mapping[str, Any]) -> list[list[str]]:
    """The table's rows, one per figure, in benchmark order."""
    rows: list[list[str]] = []
    for entry in summary["benchmarks"].values():
        targets = entry["targets"]
        for figure in entry["figures"]:
            ours = figure["ours"]
            if figure["kind"] == "status":
                rows.append([figure["label"], "—", "—", "—", "—", "—", entry["status"].upper()])
                continue
            unit = "s" if figure["kind"] == "time" else figure["unit"]
            peer = figure["peer"]
            peer_text = "—"
            if peer is not None:
                peer_text = f"{format_value(peer['value'], unit)} ({peer['name']})"
            cells, verdicts = [], []
            for name in figure["targets"]:
                t = targets[name]
                symbol = "≥" if t["comparison"] == ">=" else "≤"
                cells.append(
                    f"{symbol} {format_value(t['threshold'], t['unit'])} "
                    f"({format_value(t['value'], t['unit'])})"
                )
                verdicts.append(t["verdict"])
            rows.append(
                [
                    figure["label"],
                    format_value(ours["median"], unit),
                    format_value(ours["p95"], "s") if figure["kind"] == "time" else "—",
                    peer_text,
                    format_ratio(figure["ratio"]),
                    "; ".join(cells) or "—",
                    "; ".join(verdicts) or "—",
                ]
            )
    return rows


def markdown_table(rows: Sequence[Sequence[str]]) -> str:
    """A GitHub-flavoured markdown table with :data:`TABLE_HEADER`."""
    align = ["---"] + ["---:"] * 4 + ["---", "---"]
    lines = ["| " + " | ".join(TABLE_HEADER) + " |", "| " + " | ".join(align) + " |"]
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def caption(summary: Mapping[str, Any]) -> str:
    """One paragraph: when, on what, how the run was made, how many targets passed."""
    machine, config, counts = summary["machine"], summary["config"], summary["summary"]
    packages = machine["packages"]
    versions = ", ".join(f"{name} {v}" for name, v in packages.items() if v is not None)
    cpus = machine.get("usable_cpus") or machine.get("logical_cpus")
    date = str(machine.get("date_utc", ""))[:10]
    sentences = [
        f"Measured on {date}, {cpus} logical CPUs, Python {machine['python']}, {versions}.",
        "Each benchmark ran in its own interpreter, numpy limited to one thread.",
    ]
    load = machine.get("load_average_start"), machine.get("load_average_end")
    if load[0] and load[1]:
        sentences.append(
            f"Load average (1 min) of the machine: {load[0][0]:g} at the start, "
            f"{load[1][0]:g} at the end."
        )
    if config["quick"]:
        sentences.append("Quick run: smoke-test sizes, the figures are not representative.")
    if not config["complete"]:
        sentences.append("Only " + ", ".join(config["benchmarks"]) + " ran.")
    if config["jobs"] > 1:
        sentences.append(f"{config['jobs']} benchmarks ran at a time: timings disturbed.")
    outcome = f"{counts['targets_passed']} of {counts['targets']} targets passed"
    for status in ("failed", "skipped"):
        if counts[status]:
            noun = "benchmark" if counts[status] == 1 else "benchmarks"
            outcome += f"; {counts[status]} {noun} {status}"
    sentences.append(outcome + ".")
    return " ".join(sentences)


def render_markdown(summary: Mapping[str, Any], *, legend: bool = True) -> str:
    """The caption and the table; with ``legend``, what the columns and peers are
    (``summary.md`` has it; the documentation page explains them in its own words)."""
    parts = [caption(summary), markdown_table(table_rows(summary))]
    if legend:
        peers = "\n".join(
            f"- {name}: {entry['peer']}." for name, entry in summary["benchmarks"].items()
        )
        parts += [LEGEND, "Peers, measured in the same process and run:\n\n" + peers]
    return "\n\n".join(parts)


def replace_between_markers(page: str, block: str) -> str:
    """``page`` with the text between :data:`START_MARKER` and :data:`END_MARKER`
    replaced by ``block``.

    Raises:
        ValueError: When the markers are missing, repeated or out of order.
    """
    if page.count(START_MARKER) != 1 or page.count(END_MARKER) != 1:
        raise ValueError(
            f"the page needs exactly one {START_MARKER!r} line and one {END_MARKER!r} line"
        )
    head, rest = page.split(START_MARKER)
    if END_MARKER not in rest:
        raise ValueError(f"{END_MARKER!r} must come after {START_MARKER!r}")
    _, tail = rest.split(END_MARKER)
    return f"{head}{START_MARKER}\n{block.strip()}\n{END_MARKER}{tail}"


# --------------------------------------------------------------------------- main
class _Progress:
    """One line per benchmark; on a terminal, its running time while it runs."""

    def __init__(self, total: int, stream: TextIO, *, live: bool) -> None:
        self.total, self.stream, self.live = total, stream, live

    def _line(self, index: int, name: str, text: str, *, end: str = "\n") -> None:
        line = f"[{index}/{self.total}] {name}: {text}"
        if self.live:  # overwrite the running line
            line = "\r" + line.ljust(60)
        self.stream.write(line + end)
        self.stream.flush()

    def start(self, index: int, name: str) -> None:
        self._line(index, name, "running ...", end="" if self.live else "\n")

    def tick(self, index: int, name: str) -> Callable[[float], None] | None:
        if not self.live:
            return None
        return lambda elapsed: self._line(index, name, f"running ... {elapsed:.0f} s", end="")

    def done(self, index: int, run: Run, entry: Mapping[str, Any]) -> None:
        if run.status == "ok":
            targets = entry["targets"].values()
            passed = sum(t["pass"] for t in targets)
            failed = [name for name, t in entry["targets"].items() if not t["pass"]]
            text = f"ok in {run.seconds:.1f} s, targets {passed}/{len(targets)} PASS"
            if failed:
                text += f" (FAIL: {', '.join(failed)})"
        else:
            text = f"{run.status.upper()} after {run.seconds:.1f} s: {run.reason}"
            if run.status == "failed":
                text += f" (its output: {run.log_path})"
        self._line(index, run.name, text)


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Command-line options."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks",
        description="Run every spm-pin benchmark (each in its own interpreter) and write "
        "one JSON file and one markdown table of our figures beside the peers'.",
    )
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke test)")
    parser.add_argument(
        "--only",
        nargs="+",
        metavar="NAME",
        choices=list(BENCHMARKS),
        help=f"run only these benchmarks ({', '.join(BENCHMARKS)})",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=RESULTS_DIR,
        metavar="DIR",
        help="output folder (default: benchmarks/results)",
    )
    parser.add_argument(
        "--update-docs",
        action="store_true",
        help="put the table into docs/benchmarks.md (full runs of every benchmark only)",
    )
    parser.add_argument(
        "--from",
        dest="from_json",
        type=Path,
        metavar="SUMMARY",
        help="do not run: render the table (and, with --update-docs, the page) from a "
        "summary.json written earlier",
    )
    parser.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="benchmarks run at a time (default 1; more disturbs the timings: smoke tests)",
    )
    parser.add_argument(
        "--timeout",
        type=float,
        default=DEFAULT_TIMEOUT_S,
        metavar="SECONDS",
        help=f"time limit of one benchmark (default {DEFAULT_TIMEOUT_S:g})",
    )
    parser.add_argument(
        "--check", action="store_true", help="exit with status 1 when a target fails"
    )
    args = parser.parse_args(argv)
    if args.jobs < 1:
        parser.error("--jobs must be at least 1")
    if args.update_docs and args.from_json is None and (args.quick or args.only or args.jobs > 1):
        parser.error("--update-docs needs a full run of every benchmark, one at a time")
    return args


def run_all(args: argparse.Namespace, stream: TextIO) -> dict[str, Any]:
    """Run the selected benchmarks and return the summary."""
    selected = list(args.only or BENCHMARKS)
    selected = [name for name in BENCHMARKS if name in selected]  # suite order
    out_dir: Path = args.out
    out_dir.mkdir(parents=True, exist_ok=True)
    progress = _Progress(len(selected), stream, live=args.jobs == 1 and stream.isatty())
    stream.write(
        f"spm-pin benchmarks: {len(selected)} to run{' (quick)' if args.quick else ''}, "
        f"output in {out_dir}\n"
    )
    load_start = _load_average()
    start = time.perf_counter()

    def one(index: int, name: str) -> dict[str, Any]:
        progress.start(index, name)
        run = run_benchmark(
            BENCHMARKS[name],
            out_dir,
            quick=args.quick,
            timeout=args.timeout,
            tick=progress.tick(index, name),
        )
        entry = summarize_run(run, BENCHMARKS[name])
        progress.done(index, run, entry)
        return entry

    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        futures = {name: pool.submit(one, k, name) for k, name in enumerate(selected, start=1)}
        entries = {name: future.result() for name, future in futures.items()}
    return build_summary(
        entries,
        quick=args.quick,
        jobs=args.jobs,
        selected=selected,
        load_start=load_start,
        seconds=time.perf_counter() - start,
    )


def update_docs(summary: Mapping[str, Any], page: Path) -> None:
    """Write the table into the documentation page, from a full run only.

    Raises:
        ValueError: A quick, partial, parallel or failed run (the page shows full
            results), or a page without the markers.
    """
    config, counts = summary["config"], summary["summary"]
    problems = []
    if config["quick"]:
        problems.append("it is a quick run")
    if not config["complete"]:
        problems.append("it ran only " + ", ".join(config["benchmarks"]))
    if config["jobs"] != 1:
        problems.append(f"it ran {config['jobs']} benchmarks at a time")
    if counts["ok"] != counts["benchmarks"]:
        problems.append("some benchmarks did not run")
    if problems:
        raise ValueError(
            "not updating the docs from this run: "
            + "; ".join(problems)
            + ". Run `python -m benchmarks --update-docs` without --quick, --only, --jobs."
        )
    markdown = render_markdown(summary, legend=False)
    page.write_text(replace_between_markers(page.read_text(encoding="utf-8"), markdown))


def main(argv: Sequence[str] | None = None, stream: TextIO | None = None) -> int:
    """Run (or re-render) the suite; returns the exit code.

    0 when every selected benchmark ran (targets may still FAIL, unless ``--check``);
    1 when a benchmark failed (or, with ``--check``, a target failed); 2 when the
    docs could not be updated.
    """
    args = parse_args(argv)
    out = sys.stdout if stream is None else stream
    if args.from_json is not None:
        summary = json.loads(args.from_json.read_text(encoding="utf-8"))
        for name, entry in summary["benchmarks"].items():  # rows by today's adapters
            if entry.get("result") is not None and name in BENCHMARKS:
                entry.update(analyse(BENCHMARKS[name], entry["result"]))
        out_dir = args.from_json.parent
    else:
        summary = run_all(args, out)
        out_dir = args.out
        write_json(out_dir / SUMMARY_JSON, summary)
    markdown = render_markdown(summary)
    (out_dir / SUMMARY_MD).write_text(markdown + "\n", encoding="utf-8")
    out.write("\n" + markdown + "\n\n")
    written = (
        [out_dir / SUMMARY_MD] if args.from_json else [out_dir / SUMMARY_JSON, out_dir / SUMMARY_MD]
    )
    out.write(f"Written: {', '.join(map(str, written))}\n")
    if args.update_docs:
        try:
            update_docs(summary, DOCS_PAGE)
        except (ValueError, OSError) as exc:
            (sys.stderr if stream is None else stream).write(f"error: {exc}\n")
            return 2
        out.write(f"Table written into {DOCS_PAGE.relative_to(ROOT)}\n")
    counts = summary["summary"]
    if counts["failed"]:
        return 1
    if args.check and counts["targets_failed"]:
        return 1
    return 0
