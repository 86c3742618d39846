"""The benchmarks' figures as one pyperf suite: write it, and read its rows back.

Every row of the table (a :class:`~benchmarks._figures.Figure`) becomes one
``pyperf.Benchmark`` holding our raw samples, named ``<benchmark>/<figure>`` (e.g.
``kinematics/fk-home``), and, when the row has a peer, a second one holding the
peer's samples from the same run, named ``<benchmark>/<figure> [peer: <peer>]``. All
of them go into one ``pyperf.BenchmarkSuite`` file (``suite.json``), which keeps every
value with its metadata; pyperf computes the statistics (median, percentiles) and
compares two such files (``python -m pyperf compare_to OLD.json NEW.json``).

Metadata of a figure's benchmark (besides pyperf's ``name`` and ``unit``):

- ``description``: the row's label; ``benchmark``: which benchmark measured it;
  ``figure``: the name of our benchmark of the row (a peer points to ours with it);
  ``role``: ``ours`` or ``peer``; ``peer``: the peer's short name;
- ``quantity``: ``time`` (unit ``second``, one value per call or per item) or
  ``value`` (an accuracy, a fraction or a count: one value, pyperf unit
  ``integer`` since pyperf knows no other plain number; the real unit in
  ``value_unit``);
- ``direction``: ``lower`` or ``higher`` (is better);
- ``loops`` and ``inner_loops``: 1 and the batch size for batch calls (the values
  are per item, as pyperf's are per inner loop);
- on ours: ``ratio`` (how many times better ours is than the peer), ``targets``
  (their names) and per target ``target.<name>.comparison``, ``.threshold``,
  ``.value``, ``.unit``, ``.verdict``.

Metadata of the whole run (the same on every benchmark, so pyperf stores it once as
the suite's): pyperf's own (date, CPU, Python, ...), ``suite``, ``quick``,
``complete``, ``jobs``, ``benchmarks`` (the ones selected, in order),
``status.<name>``, ``reason.<name>``, ``seconds.<name>``, ``load_avg_start``,
``load_avg_end``, ``version.<package>``, ``git_commit``, and ``not_stored`` for
figures pyperf could not hold (it keeps positive values only: an exact zero).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pyperf  # type: ignore[import-untyped]

from ._common import machine_info
from ._figures import Analysis, Figure

__all__ = [
    "PACKAGES",
    "SUITE_JSON",
    "Outcome",
    "Row",
    "build_suite",
    "figure_name",
    "load_average",
    "load_suite",
    "peer_benchmark_name",
    "rows",
    "run_info",
]

#: Name of the suite file in the output folder.
SUITE_JSON = "suite.json"
#: The ``suite`` metadata of every benchmark of the file.
SUITE_NAME = "spm-pin benchmarks"
#: Packages whose versions the suite records.
PACKAGES = ("spm-pin", "numpy", "scipy", "pin", "coal", "mujoco", "dynamixel-sdk")
#: pyperf's metadata that describe the gathering process, not the benchmarks.
_GATHERER_ONLY = ("mem_max_rss", "mem_peak_pagefile_usage", "command_max_rss")

MetadataValue = int | float | str


@dataclasses.dataclass(frozen=True)
class Outcome:
    """What one benchmark's run gave: its status and, when it ran, its rows."""

    name: str
    status: str  # "ok", "failed" or "skipped"
    seconds: float
    reason: str | None = None
    analysis: Analysis | None = None


# ------------------------------------------------------------------------ writing
def _meta(value: Any) -> MetadataValue | None:
    """A metadata value pyperf accepts (int, float or one-line non-empty str)."""
    if value is None:
        return None
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else repr(value)
    text = " ".join(str(value).split())
    return text or None


def _put(metadata: dict[str, MetadataValue], key: str, value: Any) -> None:
    converted = _meta(value)
    if converted is not None:
        metadata[key] = converted


def figure_name(benchmark: str, key: str) -> str:
    """``kinematics``, ``fk_home`` -> ``kinematics/fk-home``."""
    return f"{benchmark}/{key.replace('_', '-')}"


def peer_benchmark_name(name: str, peer: str) -> str:
    """The name of the peer's benchmark beside ours."""
    return f"{name} [peer: {peer}]"


def load_average() -> float | None:
    """The 1-minute load average of the machine, when the system tells it."""
    try:
        return round(os.getloadavg()[0], 2)
    except (AttributeError, OSError):
        return None


def run_info(
    outcomes: Sequence[Outcome],
    *,
    quick: bool,
    jobs: int,
    complete: bool,
    load_start: float | None,
) -> dict[str, MetadataValue]:
    """The metadata of the whole run (see the module's docstring)."""
    collected = pyperf.Run([1.0], metadata={"name": "run"}).get_metadata()
    metadata: dict[str, MetadataValue] = {
        k: v for k, v in collected.items() if k not in (*_GATHERER_ONLY, "name")
    }
    machine = machine_info(PACKAGES)
    _put(metadata, "suite", SUITE_NAME)
    _put(metadata, "quick", quick)
    _put(metadata, "complete", complete)
    _put(metadata, "jobs", jobs)
    _put(metadata, "benchmarks", " ".join(o.name for o in outcomes))
    _put(metadata, "isolation", "one interpreter per benchmark, thread pools limited to 1")
    _put(metadata, "load_avg_start", load_start)
    _put(metadata, "load_avg_end", load_average())
    _put(metadata, "python", machine["python"])
    _put(metadata, "usable_cpus", machine["usable_cpus"])
    _put(metadata, "git_commit", machine["git_commit"])
    for package, version in machine["packages"].items():
        _put(metadata, f"version.{package}", version)
    for outcome in outcomes:
        _put(metadata, f"status.{outcome.name}", outcome.status)
        _put(metadata, f"reason.{outcome.name}", outcome.reason)
        _put(metadata, f"seconds.{outcome.name}", round(outcome.seconds, 3))
        if outcome.analysis is not None:
            _put(metadata, f"adapter_error.{outcome.name}", outcome.analysis.adapter_error)
    return metadata


def _storable(values: Sequence[float]) -> bool:
    return bool(values) and all(math.isfinite(v) and v > 0 for v in values)


def _figure_metadata(benchmark: str, figure: Figure) -> dict[str, MetadataValue]:
    """What ours and the peer's benchmark of a row share."""
    metadata: dict[str, MetadataValue] = {}
    _put(metadata, "benchmark", benchmark)
    _put(metadata, "figure", figure_name(benchmark, figure.key))
    _put(metadata, "quantity", figure.kind)
    _put(metadata, "unit", "second" if figure.kind == "time" else "integer")
    if figure.kind != "time":
        _put(metadata, "value_unit", figure.unit)
    _put(metadata, "direction", "higher" if figure.higher_is_better else "lower")
    _put(metadata, "peer", figure.peer_name)
    if figure.kind == "time":
        _put(metadata, "loops", 1)
        if figure.items > 1:
            _put(metadata, "inner_loops", figure.items)
    return metadata


def _target_metadata(
    metadata: dict[str, MetadataValue], figure: Figure, targets: Mapping[str, Any]
) -> None:
    _put(metadata, "targets", " ".join(figure.targets))
    for name in figure.targets:
        record = targets[name]
        for field in ("comparison", "threshold", "value", "unit", "verdict"):
            _put(metadata, f"target.{name}.{field}", record.get(field))


def figure_benchmarks(
    benchmark: str,
    figure: Figure,
    targets: Mapping[str, Any],
    common: Mapping[str, MetadataValue],
) -> tuple[list[Any], list[str]]:
    """Our pyperf benchmark of one row and the peer's; and what could not be stored.

    Returns:
        The ``pyperf.Benchmark`` objects (ours first) and a note per figure left out
        (pyperf keeps positive values only).
    """
    name = figure_name(benchmark, figure.key)
    shared = _figure_metadata(benchmark, figure)
    if not _storable(figure.ours):
        return [], [f"{name} (ours: {min(figure.ours, default=math.nan):g})"]
    ours = dict(common, **shared)
    _put(ours, "name", name)
    _put(ours, "role", "ours")
    _put(ours, "description", figure.label)
    _put(ours, "ratio", figure.ratio)
    _target_metadata(ours, figure, targets)
    made = [pyperf.Benchmark([pyperf.Run(figure.ours, metadata=ours, collect_metadata=False)])]
    notes: list[str] = []
    if figure.peer is not None and figure.peer_name is not None:
        peer_name = peer_benchmark_name(name, figure.peer_name)
        if _storable(figure.peer):
            peer = dict(common, **shared)
            _put(peer, "name", peer_name)
            _put(peer, "role", "peer")
            _put(peer, "description", f"{figure.label} (peer: {figure.peer_name})")
            run = pyperf.Run(figure.peer, metadata=peer, collect_metadata=False)
            made.append(pyperf.Benchmark([run]))
        else:
            notes.append(f"{peer_name} ({min(figure.peer, default=math.nan):g})")
    return made, notes


def build_suite(outcomes: Sequence[Outcome], common: Mapping[str, MetadataValue]) -> Any:
    """One ``pyperf.BenchmarkSuite`` of every row of the benchmarks that ran.

    Returns:
        The suite, or None when no benchmark gave a figure (pyperf's suites are never
        empty).
    """
    made: list[Any] = []
    notes: list[str] = []
    for outcome in outcomes:
        if outcome.analysis is None:
            continue
        for figure in outcome.analysis.figures:
            benchmarks, left_out = figure_benchmarks(
                outcome.name, figure, outcome.analysis.targets, common
            )
            made += benchmarks
            notes += left_out
    if not made:
        return None
    if notes:  # every benchmark carries it, so that pyperf keeps it as the suite's
        for benchmark in made:
            benchmark.update_metadata({"not_stored": "; ".join(notes)})
    return pyperf.BenchmarkSuite(made)


def load_suite(path: str | Path) -> Any:
    """A suite written by :func:`build_suite` (``pyperf.BenchmarkSuite.load``).

    Raises:
        ValueError: The file is not a pyperf suite of spm-pin's benchmarks.
    """
    try:
        suite = pyperf.BenchmarkSuite.load(str(path))
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{path} is not a pyperf suite ({type(exc).__name__}: {exc})") from exc
    if suite.get_metadata().get("suite") != SUITE_NAME:
        raise ValueError(f"{path} is not a suite written by `python -m benchmarks`")
    return suite


# ------------------------------------------------------------------------ reading
@dataclasses.dataclass(frozen=True)
class Row:
    """One row of the table, read back from a suite.

    Attributes:
        benchmark: The benchmark that measured it (``kinematics`` ...).
        label: The first column.
        kind: ``"time"``, ``"value"`` or ``"status"`` (a benchmark that did not run).
        unit: ``"s"`` for times, the value's unit otherwise.
        ours: Our ``pyperf.Benchmark`` (None for a status row).
        peer: The peer's, or None.
        peer_name: The peer's short name.
        ratio: How many times better ours is than the peer.
        targets: ``name``, ``comparison``, ``threshold``, ``value``, ``unit``,
            ``verdict`` of each target the row shows.
        status: The benchmark's status (``ok``, ``skipped``, ``failed``).
    """

    benchmark: str
    label: str
    kind: str
    unit: str = "s"
    ours: Any = None
    peer: Any = None
    peer_name: str | None = None
    ratio: float | None = None
    targets: tuple[dict[str, Any], ...] = ()
    status: str = "ok"


def _float(value: Any) -> float | None:
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def _row(ours: Any, peer: Any) -> Row:
    metadata = ours.get_metadata()
    targets = []
    for name in str(metadata.get("targets", "")).split():
        prefix = f"target.{name}."
        targets.append(
            {
                "name": name,
                "comparison": metadata.get(prefix + "comparison"),
                "threshold": _float(metadata.get(prefix + "threshold")),
                "value": _float(metadata.get(prefix + "value")),
                "unit": str(metadata.get(prefix + "unit", "")),
                "verdict": metadata.get(prefix + "verdict"),
            }
        )
    kind = str(metadata.get("quantity", "time"))
    return Row(
        benchmark=str(metadata.get("benchmark", ours.get_name().split("/")[0])),
        label=str(metadata.get("description", ours.get_name())),
        kind=kind,
        unit="s" if kind == "time" else str(metadata.get("value_unit", "")),
        ours=ours,
        peer=peer,
        peer_name=None if peer is None else str(metadata.get("peer", "peer")),
        ratio=_float(metadata.get("ratio")),
        targets=tuple(targets),
    )


def rows(suite: Any) -> list[Row]:
    """The table's rows, in the order the benchmarks ran; a benchmark that did not run
    gets one status row."""
    info = suite.get_metadata()
    peers = {}
    for bench in suite:
        metadata = bench.get_metadata()
        if metadata.get("role") == "peer":
            peers[metadata.get("figure")] = bench
    by_benchmark: dict[str, list[Row]] = {}
    for bench in suite:
        metadata = bench.get_metadata()
        if metadata.get("role", "ours") == "ours":
            row = _row(bench, peers.get(bench.get_name()))
            by_benchmark.setdefault(row.benchmark, []).append(row)
    names = str(info.get("benchmarks", "")).split() or list(by_benchmark)
    table: list[Row] = []
    for name in names:
        status = str(info.get(f"status.{name}", "ok"))
        if status == "ok":
            table += by_benchmark.get(name, [])
            continue
        reason = info.get(f"reason.{name}", "no reason")
        label = f"{name}: not run ({status}: {reason})"
        table.append(Row(name, label, "status", status=status))
    return table
