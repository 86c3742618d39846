"""Text out of a pyperf suite of the benchmarks: the markdown table, and the
comparison of two suites.

The table (figure | ours median | p95 | peer | ratio | target | verdict) reads its
numbers from the suite with pyperf's statistics (``Benchmark.median()``,
``Benchmark.percentile(95)``), its targets and ratios from the benchmarks' metadata
(see :mod:`benchmarks._suite`). :func:`compare` prints one line per figure of two
suites: the old and new medians, their ratio, whether that is better or worse for the
figure's direction, and pyperf's significance test.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from ._common import format_rate, format_seconds, format_table
from ._figures import BENCHMARKS
from ._suite import PACKAGES, Row, rows

__all__ = [
    "END_MARKER",
    "LEGEND",
    "START_MARKER",
    "TABLE_HEADER",
    "caption",
    "compare",
    "format_ratio",
    "format_value",
    "markdown_table",
    "render_markdown",
    "replace_between_markers",
    "table_rows",
    "target_counts",
]

#: The generated table sits between these two lines of the documentation page.
START_MARKER = "<!-- bench-table:start -->"
END_MARKER = "<!-- bench-table:end -->"
#: Columns of the markdown table.
TABLE_HEADER = ("figure", "ours median", "p95", "peer", "ratio", "target", "verdict")
#: What the ratio column means.
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


# ----------------------------------------------------------------------- numbers
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


# ------------------------------------------------------------------------- table
def table_rows(table: Sequence[Row]) -> list[list[str]]:
    """The cells of the table, one list per row."""
    cells: list[list[str]] = []
    for row in table:
        if row.kind == "status":
            cells.append([row.label, "—", "—", "—", "—", "—", row.status.upper()])
            continue
        p95 = "—"
        if row.kind == "time" and row.ours.get_nvalue() > 1:
            p95 = format_value(row.ours.percentile(95), "s")
        peer = "—"
        if row.peer is not None:
            peer = f"{format_value(row.peer.median(), row.unit)} ({row.peer_name})"
        targets = [
            f"{'≥' if t['comparison'] == '>=' else '≤'} {format_value(t['threshold'], t['unit'])}"
            f" ({format_value(t['value'], t['unit'])})"
            for t in row.targets
        ]
        cells.append(
            [
                row.label,
                format_value(row.ours.median(), row.unit),
                p95,
                peer,
                format_ratio(row.ratio),
                "; ".join(targets) or "—",
                "; ".join(str(t["verdict"]) for t in row.targets) or "—",
            ]
        )
    return cells


def markdown_table(cells: Sequence[Sequence[str]]) -> str:
    """A GitHub-flavoured markdown table with :data:`TABLE_HEADER`."""
    align = ["---"] + ["---:"] * 4 + ["---", "---"]
    lines = ["| " + " | ".join(TABLE_HEADER) + " |", "| " + " | ".join(align) + " |"]
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in cells]
    return "\n".join(lines)


def target_counts(table: Sequence[Row]) -> tuple[int, int]:
    """How many targets the rows show, and how many of them passed."""
    verdicts = [t["verdict"] for row in table for t in row.targets]
    return len(verdicts), verdicts.count("PASS")


def caption(info: Mapping[str, Any], table: Sequence[Row]) -> str:
    """One paragraph: when, on what, how the run was made, how many targets passed."""
    packages = [key.removeprefix("version.") for key in info if key.startswith("version.")]
    packages.sort(key=lambda name: PACKAGES.index(name) if name in PACKAGES else len(PACKAGES))
    versions = ", ".join(f"{name} {info[f'version.{name}']}" for name in packages)
    cpus = info.get("usable_cpus") or info.get("cpu_count")
    date = str(info.get("date", ""))[:10]
    sentences = [
        f"Measured on {date}, {cpus} logical CPUs, Python {info.get('python')}, {versions}.",
        "Each benchmark ran in its own interpreter, numpy limited to one thread.",
    ]
    start, end = info.get("load_avg_start"), info.get("load_avg_end")
    if start is not None and end is not None:
        sentences.append(
            f"Load average (1 min) of the machine: {start:g} at the start, {end:g} at the end."
        )
    if info.get("quick"):
        sentences.append("Quick run: smoke-test sizes, the figures are not representative.")
    if not info.get("complete"):
        sentences.append("Only " + ", ".join(str(info.get("benchmarks", "")).split()) + " ran.")
    if int(info.get("jobs", 1)) > 1:
        sentences.append(f"{info['jobs']} benchmarks ran at a time: timings disturbed.")
    total, passed = target_counts(table)
    outcome = f"{passed} of {total} targets passed"
    for status in ("failed", "skipped"):
        count = sum(row.status == status for row in table)
        if count:
            outcome += f"; {count} {'benchmark' if count == 1 else 'benchmarks'} {status}"
    sentences.append(outcome + ".")
    if info.get("not_stored"):
        sentences.append(f"Not stored (pyperf keeps positive values only): {info['not_stored']}.")
    return " ".join(sentences)


def render_markdown(suite: Any, *, legend: bool = True) -> str:
    """The caption and the table of a suite; with ``legend``, what the columns and
    peers are (``summary.md`` has it; the documentation page explains them in its own
    words)."""
    table = rows(suite)
    parts = [caption(suite.get_metadata(), table), markdown_table(table_rows(table))]
    if legend:
        names = dict.fromkeys(row.benchmark for row in table)
        peers = "\n".join(
            f"- {name}: {BENCHMARKS[name].peer}." for name in names if name in BENCHMARKS
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


# ----------------------------------------------------------------------- compare
def _significance(old: Any, new: Any) -> str:
    """pyperf's verdict (Student's two-sample t-test at 95%), where it gives one."""
    if old.get_nvalue() < 2 or new.get_nvalue() < 2:
        return "— (one value)"
    try:  # what `python -m pyperf compare_to` calls
        from pyperf._compare import is_significant_benchs  # type: ignore[import-untyped]

        significant, t_score = is_significant_benchs(old, new)
    except Exception:  # pyperf's private API moved
        return "—"
    if t_score is None:  # pyperf could not test (e.g. constant samples)
        return "—"
    return f"{'significant' if significant else 'not significant'} (t={t_score:.2f})"


def _change(ratio: float, *, time: bool, higher_is_better: bool) -> str:
    """``"1.25x faster"``, ``"2.00x slower"``, ``"1.10x better"``, ``"same"``."""
    if ratio == 1.0:
        return "same"
    better = ratio > 1.0 if higher_is_better else ratio < 1.0
    factor = ratio if ratio >= 1.0 else 1.0 / ratio
    word = ("faster" if better else "slower") if time else ("better" if better else "worse")
    return f"{factor:.2f}x {word}"


def _show(bench: Any) -> str:
    metadata = bench.get_metadata()
    if metadata.get("quantity", "time") == "time":
        return format_value(bench.median(), "s")
    return format_value(bench.median(), str(metadata.get("value_unit", "")))


def compare(old: Any, new: Any) -> str:
    """One line per figure of two suites: old and new median, new / old, what that
    means for the figure's direction, and pyperf's significance test.

    Figures found in only one of the suites are listed under the table.
    """
    new_by_name = {bench.get_name(): bench for bench in new}
    old_names = [bench.get_name() for bench in old]
    lines = []
    for bench in old:
        name = bench.get_name()
        other = new_by_name.get(name)
        if other is None:
            continue
        metadata = other.get_metadata()
        ratio = other.median() / bench.median()
        change = _change(
            ratio,
            time=metadata.get("quantity", "time") == "time",
            higher_is_better=metadata.get("direction") == "higher",
        )
        lines.append(
            [name, _show(bench), _show(other), f"{ratio:.3g}", change, _significance(bench, other)]
        )
    headers = ("figure", "old median", "new median", "new/old", "change", "pyperf t-test")
    text = format_table(headers, lines) if lines else "No figure in common."
    only_old = [name for name in old_names if name not in new_by_name]
    only_new = [name for name in new_by_name if name not in set(old_names)]
    if only_old:
        text += "\n\nOnly in the old suite: " + ", ".join(only_old)
    if only_new:
        text += "\n\nOnly in the new suite: " + ", ".join(only_new)
    return text
