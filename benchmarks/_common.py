"""Shared helpers for the benchmarks: one-thread setup, timing, statistics, JSON output.

This module imports only the standard library, so a benchmark can call
:func:`limit_to_one_thread` *before* numpy is imported::

    from ._common import limit_to_one_thread

    THREADS_LIMITED = limit_to_one_thread()  # before numpy is imported

    import numpy as np  # noqa: E402

Each ``bench_<name>.py`` builds its command line with :func:`standard_parser` and
hands it to :func:`run_main` (run, print the report, write the JSON).

Timings use :func:`time.perf_counter`; every timed callable gets warm-up calls first,
and the garbage collector is paused while a sample runs (as :mod:`timeit` does).
Statistics are the median and the tail (p95, p99) of the samples.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import functools
import gc
import importlib.metadata
import json
import math
import os
import platform
import subprocess
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, Generic, TypeVar

__all__ = [
    "RESULTS_DIR",
    "THREAD_ENV_VARS",
    "Timed",
    "Timing",
    "default_output",
    "format_count",
    "format_rate",
    "format_seconds",
    "format_table",
    "limit_to_one_thread",
    "machine_info",
    "percentile",
    "run_main",
    "standard_parser",
    "target",
    "time_alternating",
    "time_call",
    "time_each",
    "to_jsonable",
    "with_all_pass",
    "write_json",
]

T = TypeVar("T")
A = TypeVar("A")

#: Where benchmarks write their JSON by default (git-ignored).
RESULTS_DIR = Path(__file__).resolve().parent / "results"

#: Environment variables that cap the thread pools of numpy's BLAS/LAPACK and OpenMP.
THREAD_ENV_VARS = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)


def limit_to_one_thread() -> bool:
    """Set every variable of :data:`THREAD_ENV_VARS` to ``"1"`` (one core).

    The thread pools read these variables once, when numpy (or scipy) is first
    imported, so call this before that import.

    Returns:
        True when numpy was not imported yet, i.e. the limit takes effect; False when
        numpy was already loaded (e.g. inside a test session), where the timings may
        use several threads.
    """
    for name in THREAD_ENV_VARS:
        os.environ[name] = "1"
    return "numpy" not in sys.modules


# ---------------------------------------------------------------------- statistics
def percentile(values: Iterable[float], q: float) -> float:
    """The q-th percentile (0..100) with linear interpolation (numpy's default rule)."""
    data = sorted(float(v) for v in values)
    if not data:
        raise ValueError("percentile of an empty sequence")
    if not 0.0 <= q <= 100.0:
        raise ValueError(f"q must lie in [0, 100], got {q}")
    position = (len(data) - 1) * q / 100.0
    low = math.floor(position)
    high = min(low + 1, len(data) - 1)
    return data[low] + (data[high] - data[low]) * (position - low)


@dataclasses.dataclass(frozen=True)
class Timing:
    """Samples of a wall-clock time [s] and their statistics."""

    samples: tuple[float, ...]

    def __post_init__(self) -> None:
        if not self.samples:
            raise ValueError("a Timing needs at least one sample")

    @property
    def median(self) -> float:
        """Median sample [s]."""
        return percentile(self.samples, 50.0)

    @property
    def p95(self) -> float:
        """95th percentile [s]."""
        return percentile(self.samples, 95.0)

    @property
    def p99(self) -> float:
        """99th percentile [s]."""
        return percentile(self.samples, 99.0)

    @property
    def mean(self) -> float:
        """Mean sample [s]."""
        return sum(self.samples) / len(self.samples)

    @property
    def total(self) -> float:
        """Sum of the samples [s]."""
        return sum(self.samples)

    def summary(self, items: int = 1) -> dict[str, Any]:
        """Statistics for JSON, when each sample processed ``items`` items.

        ``per_item_s`` is median / items and ``per_second`` is items / median;
        ``values_s`` holds every sample (per call, not per item), from which the
        gatherer builds the pyperf benchmark of the figure.
        """
        median = self.median
        return {
            "samples": len(self.samples),
            "values_s": list(self.samples),
            "items": items,
            "median_s": median,
            "p95_s": self.p95,
            "p99_s": self.p99,
            "mean_s": self.mean,
            "min_s": min(self.samples),
            "max_s": max(self.samples),
            "per_item_s": median / items,
            "per_second": items / median if median > 0 else math.inf,
        }


@dataclasses.dataclass(frozen=True)
class Timed(Generic[T]):
    """A timing together with the value the timed callable returned (last call)."""

    timing: Timing
    value: T


def _timed_once(fn: Callable[[], T]) -> tuple[float, T]:
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        start = time.perf_counter()
        value = fn()
        elapsed = time.perf_counter() - start
    finally:
        if gc_was_enabled:
            gc.enable()
    return elapsed, value


def time_call(
    fn: Callable[[], T], *, repeats: int, warmup: int = 1, collect_each: bool = True
) -> Timed[T]:
    """Time ``fn()`` ``repeats`` times after ``warmup`` untimed calls.

    Args:
        fn: The call to time (e.g. one batch call of the public API).
        repeats: Number of timed calls (>= 1).
        warmup: Number of untimed calls first (caches, lazy imports, allocations).
        collect_each: Collect garbage before every sample (calls of milliseconds or
            more: each starts from the same heap). False: once before the samples,
            which then run back to back with the collector off, as ``timeit`` times
            (calls of microseconds: a full collection before each would leave the
            CPU's caches cold and time that, not the call).

    Returns:
        The samples and the value of the last call.
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    for _ in range(warmup):
        fn()
    gc.collect()
    elapsed, value = _timed_once(fn)
    samples = [elapsed]
    for _ in range(repeats - 1):
        if collect_each:
            gc.collect()
        elapsed, value = _timed_once(fn)
        samples.append(elapsed)
    return Timed(Timing(tuple(samples)), value)


def time_alternating(
    calls: Mapping[str, tuple[Callable[[], Any], int]],
    *,
    windows: int,
    warmup: int = 1,
    collect_each: bool = False,
) -> tuple[dict[str, Timing], float]:
    """Time short calls side by side: ``windows`` windows, each running every call
    ``count`` times back to back (``calls``: name -> (call, count)), the calls' order
    turned by one from window to window. A slow phase of the machine then slows every
    call alike, and the samples span the whole run rather than one burst.

    Each call gets ``warmup`` untimed calls first; garbage is collected once, and the
    samples run with the collector off; ``collect_each``: collected before every
    sample too (as :func:`time_call` takes it).

    Returns:
        The pooled samples of each call, and the median over the windows of the
        first call's median over the second's (NaN with fewer than two calls).
    """
    if windows < 1:
        raise ValueError(f"windows must be >= 1, got {windows}")
    names = list(calls)
    if not names or any(count < 1 for _, count in calls.values()):
        raise ValueError("time_alternating needs calls, each run at least once a window")
    for call, _ in calls.values():
        for _ in range(warmup):
            call()
    gc.collect()
    samples: dict[str, list[float]] = {name: [] for name in names}
    ratios: list[float] = []
    for window in range(windows):
        medians: dict[str, float] = {}
        for k in range(len(names)):
            name = names[(window + k) % len(names)]
            call, count = calls[name]
            taken = []
            for _ in range(count):
                if collect_each:
                    gc.collect()
                taken.append(_timed_once(call)[0])
            samples[name] += taken
            medians[name] = percentile(taken, 50.0)
        if len(names) > 1:
            ratios.append(medians[names[0]] / medians[names[1]])
    ratio = percentile(ratios, 50.0) if ratios else math.nan
    return {name: Timing(tuple(values)) for name, values in samples.items()}, ratio


def time_each(
    fn: Callable[[A], T], items: Sequence[A], *, warmup: int = 1
) -> tuple[Timing, list[T]]:
    """Time ``fn(item)`` once per item (per-item latency), after ``warmup`` calls.

    Returns:
        One sample per item and the values, in the order of ``items``.
    """
    if not items:
        raise ValueError("time_each needs at least one item")
    for _ in range(warmup):
        fn(items[0])
    samples: list[float] = []
    values: list[T] = []
    gc.collect()
    for item in items:
        elapsed, value = _timed_once(functools.partial(fn, item))
        samples.append(elapsed)
        values.append(value)
    return Timing(tuple(samples)), values


# -------------------------------------------------------------------- machine info
def _cpu_model() -> str:
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        for line in cpuinfo.read_text(errors="replace").splitlines():
            if line.lower().startswith(("model name", "hardware", "cpu model")):
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine()


def _package_version(name: str) -> str | None:
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        module = sys.modules.get(name.replace("-", "_"))
        version = getattr(module, "__version__", None)
        return None if version is None else str(version)


def _git_commit() -> str | None:
    try:
        result = subprocess.run(
            ["git", "rev-parse", "--short=12", "HEAD"],
            cwd=Path(__file__).resolve().parent,
            capture_output=True,
            text=True,
            timeout=5,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    commit = result.stdout.strip()
    return commit if result.returncode == 0 and commit else None


def machine_info(
    packages: Sequence[str] = ("numpy", "scipy"), extra: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """What the numbers depend on: interpreter, package versions, CPU, thread limits.

    Args:
        packages: Distribution names whose versions to record (None if missing).
        extra: More entries to merge in (e.g. the version of the package under test).
    """
    affinity = getattr(os, "sched_getaffinity", None)
    info: dict[str, Any] = {
        "python": platform.python_version(),
        "implementation": platform.python_implementation(),
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu": _cpu_model(),
        "logical_cpus": os.cpu_count(),
        "usable_cpus": len(affinity(0)) if affinity is not None else None,
        "thread_env": {name: os.environ.get(name) for name in THREAD_ENV_VARS},
        "packages": {name: _package_version(name) for name in packages},
        "git_commit": _git_commit(),
        "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }
    info.update(extra or {})
    return info


# ------------------------------------------------------------------------- output
def to_jsonable(value: Any) -> Any:
    """Plain JSON data from numpy scalars/arrays, tuples, paths; NaN and inf become None."""
    if isinstance(value, Mapping):
        return {str(key): to_jsonable(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(item) for item in value]
    if isinstance(value, Path):
        return str(value)
    if hasattr(value, "tolist") and callable(value.tolist):  # numpy scalar or array
        return to_jsonable(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def write_json(path: str | Path, payload: Mapping[str, Any]) -> Path:
    """Write ``payload`` as indented, strict JSON (parent folders created)."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(to_jsonable(payload), indent=2, allow_nan=False)
    out.write_text(text + "\n", encoding="utf-8")
    return out


def default_output(name: str) -> Path:
    """``benchmarks/results/<name>.json``."""
    return RESULTS_DIR / f"{name}.json"


def target(value: float, threshold: float, *, at_least: bool, unit: str = "") -> dict[str, Any]:
    """A pass/fail record: ``value >= threshold`` (at_least) or ``value <= threshold``."""
    passed = value >= threshold if at_least else value <= threshold
    return {
        "value": value,
        "threshold": threshold,
        "comparison": ">=" if at_least else "<=",
        "unit": unit,
        "pass": bool(passed and math.isfinite(value)),
    }


def with_all_pass(targets: dict[str, Any]) -> dict[str, Any]:
    """``targets`` (records of :func:`target`) with ``"all_pass"`` added: every one passed."""
    targets["all_pass"] = all(t["pass"] for t in targets.values())
    return targets


# --------------------------------------------------------------------- command line
def standard_parser(
    name: str, description: str, *, quick_help: str = "small sizes (smoke test)"
) -> argparse.ArgumentParser:
    """The options every benchmark has: ``--out`` (its JSON file) and ``--quick``.

    Args:
        name: The benchmark's name: module ``benchmarks.bench_<name>``, default output
            ``benchmarks/results/<name>.json``.
        description: The ``--help`` text.
        quick_help: Help of ``--quick``.

    Returns:
        The parser; a benchmark adds its own options to it.
    """
    parser = argparse.ArgumentParser(
        prog=f"python -m benchmarks.bench_{name}", description=description
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=default_output(name),
        help=f"JSON output file (default: benchmarks/results/{name}.json)",
    )
    parser.add_argument("--quick", action="store_true", help=quick_help)
    return parser


def run_main(
    parser: argparse.ArgumentParser,
    run: Callable[[argparse.Namespace], dict[str, Any]],
    report: Callable[[dict[str, Any]], str],
    argv: Sequence[str] | None,
) -> int:
    """A benchmark's ``main``: parse ``argv``, run, print the report, write the JSON.

    Args:
        parser: From :func:`standard_parser` (it must have ``--out``).
        run: The options to the JSON payload.
        report: The payload to the printed summary.
        argv: The arguments (None: ``sys.argv[1:]``).

    Returns:
        The exit code, 0.
    """
    args = parser.parse_args(argv)
    payload = run(args)
    print(report(payload))
    out = write_json(args.out, payload)
    print(f"\nJSON written to {out}")
    return 0


def format_seconds(seconds: float) -> str:
    """A duration with a readable unit (ns, us, ms, s)."""
    if not math.isfinite(seconds):
        return "n/a"
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6)):
        if abs(seconds) >= scale:
            return f"{seconds / scale:.3g} {unit}"
    return f"{seconds / 1e-9:.3g} ns"


def format_rate(per_second: float) -> str:
    """A rate as an integer with thousands separators, e.g. ``"443,210 /s"``."""
    if not math.isfinite(per_second):
        return "n/a"
    if per_second >= 100:
        return f"{per_second:,.0f} /s"
    return f"{per_second:.3g} /s"


def format_count(count: int) -> str:
    """An integer with thousands separators."""
    return f"{count:,}"


def format_table(headers: Sequence[str], rows: Iterable[Sequence[str]]) -> str:
    """A plain-text table; the first column is left-aligned, the others right-aligned."""
    body = [list(map(str, row)) for row in rows]
    widths = [len(h) for h in headers]
    for row in body:
        for k, cell in enumerate(row):
            widths[k] = max(widths[k], len(cell))

    def line(cells: Sequence[str]) -> str:
        parts = [
            cell.ljust(widths[k]) if k == 0 else cell.rjust(widths[k])
            for k, cell in enumerate(cells)
        ]
        return "  ".join(parts).rstrip()

    rule = "  ".join("-" * w for w in widths)
    return "\n".join([line(headers), rule, *(line(row) for row in body)])
