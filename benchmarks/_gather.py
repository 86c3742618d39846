"""Run every benchmark and gather their headline figures into one pyperf suite.

``python -m benchmarks`` (see :func:`main`) runs each ``benchmarks/bench_<name>.py`` in
its own interpreter (``python -m benchmarks.bench_<name> --out DIR/<name>.json``), one
after the other, with numpy's thread pools limited to one thread through the child's
environment. It then writes, in DIR (default ``benchmarks/results/``):

- ``<name>.json`` and ``<name>.log``: each benchmark's own JSON and printed report;
- ``suite.json``: a pyperf suite with one benchmark per figure (ours, and the peer's
  measured in the same run) holding the raw samples, the run's settings and every
  target with its verdict as metadata (see :mod:`benchmarks._suite`);
- ``summary.md``: those figures as one markdown table
  (figure | ours median | p95 | peer | ratio | target | verdict).

``--update-docs`` puts the table into ``docs/benchmarks.md`` between the markers of
:mod:`benchmarks._report` (full runs of every benchmark only); ``--from SUITE`` renders
the table of a suite written before; ``--compare OLD [NEW]`` compares two suites.

The adapters that pick the figures out of each benchmark's JSON are in
:mod:`benchmarks._figures`.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, TextIO

from ._common import RESULTS_DIR, THREAD_ENV_VARS
from ._figures import BENCHMARKS, Benchmark, analyse
from ._report import compare, render_markdown, replace_between_markers, target_counts
from ._suite import SUITE_JSON, Outcome, build_suite, load_average, load_suite, rows, run_info

__all__ = ["BENCHMARKS", "main", "run_benchmark"]

#: The repository root (``python -m benchmarks.bench_<name>`` runs from here).
ROOT = Path(__file__).resolve().parent.parent
#: The documentation page that shows the latest table.
DOCS_PAGE = ROOT / "docs" / "benchmarks.md"
#: Name of the markdown table in the output folder.
SUMMARY_MD = "summary.md"
#: Default time limit of one benchmark [s] (a full run of the slowest takes minutes).
DEFAULT_TIMEOUT_S = 1800.0
#: Lines of a failed benchmark's log printed.
LOG_TAIL_LINES = 30
#: Missing modules that make a benchmark "skipped" rather than "failed" are the
#: optional ones: anything but the project's own packages.
OWN_PACKAGES = ("spm_pin", "benchmarks")


# ------------------------------------------------------------------------ running
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


def outcome_of(run: Run, benchmark: Benchmark) -> Outcome:
    """The run's status and, when it ran, the rows and targets of its JSON."""
    if run.status != "ok":
        return Outcome(run.name, run.status, run.seconds, run.reason)
    data = json.loads(run.json_path.read_text(encoding="utf-8"))
    return Outcome(run.name, "ok", run.seconds, None, analyse(benchmark, data))


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

    def done(self, index: int, run: Run, outcome: Outcome) -> None:
        if outcome.analysis is not None:
            targets = outcome.analysis.targets
            passed = sum(t["pass"] for t in targets.values())
            failed = [name for name, t in targets.items() if not t["pass"]]
            text = f"ok in {run.seconds:.1f} s, targets {passed}/{len(targets)} PASS"
            if failed:
                text += f" (FAIL: {', '.join(failed)})"
            if outcome.analysis.adapter_error:
                text += f" (figures not understood: {outcome.analysis.adapter_error})"
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
        "one pyperf suite and one markdown table of our figures beside the peers'.",
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
        metavar="SUITE",
        help="do not run: render the table (and, with --update-docs, the page) from a "
        "suite.json written earlier",
    )
    parser.add_argument(
        "--compare",
        nargs="+",
        type=Path,
        metavar="SUITE",
        help="do not run: compare OLD with NEW (default: the latest results, "
        "benchmarks/results/suite.json), one line per figure",
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
    if args.compare is not None and len(args.compare) > 2:
        parser.error("--compare takes OLD and at most one NEW suite")
    if args.update_docs and args.from_json is None and (args.quick or args.only or args.jobs > 1):
        parser.error("--update-docs needs a full run of every benchmark, one at a time")
    return args


def run_all(args: argparse.Namespace, stream: TextIO) -> list[Outcome]:
    """Run the selected benchmarks, in the suite's order; their outcomes."""
    selected = [name for name in BENCHMARKS if name in (args.only or BENCHMARKS)]
    out_dir: Path = args.out
    out_dir.mkdir(parents=True, exist_ok=True)
    progress = _Progress(len(selected), stream, live=args.jobs == 1 and stream.isatty())
    stream.write(
        f"spm-pin benchmarks: {len(selected)} to run{' (quick)' if args.quick else ''}, "
        f"output in {out_dir}\n"
    )

    def one(index: int, name: str) -> Outcome:
        progress.start(index, name)
        run = run_benchmark(
            BENCHMARKS[name],
            out_dir,
            quick=args.quick,
            timeout=args.timeout,
            tick=progress.tick(index, name),
        )
        outcome = outcome_of(run, BENCHMARKS[name])
        progress.done(index, run, outcome)
        if run.log_tail:
            stream.write(run.log_tail + "\n")
        return outcome

    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(one, k, name) for k, name in enumerate(selected, start=1)]
        return [future.result() for future in futures]


def update_docs(suite: Any, page: Path) -> None:
    """Write the table into the documentation page, from a full run only.

    Raises:
        ValueError: A quick, partial, parallel or failed run (the page shows full
            results), or a page without the markers.
    """
    info = suite.get_metadata()
    problems = []
    if info.get("quick"):
        problems.append("it is a quick run")
    if not info.get("complete"):
        problems.append("it ran only " + ", ".join(str(info.get("benchmarks", "")).split()))
    if int(info.get("jobs", 1)) != 1:
        problems.append(f"it ran {info['jobs']} benchmarks at a time")
    if any(row.status != "ok" for row in rows(suite)):
        problems.append("some benchmarks did not run")
    if problems:
        raise ValueError(
            "not updating the docs from this run: "
            + "; ".join(problems)
            + ". Run `python -m benchmarks --update-docs` without --quick, --only, --jobs."
        )
    markdown = render_markdown(suite, legend=False)
    page.write_text(replace_between_markers(page.read_text(encoding="utf-8"), markdown))


def _compare(paths: Sequence[Path], out: TextIO, err: TextIO) -> int:
    old_path = paths[0]
    new_path = paths[1] if len(paths) > 1 else RESULTS_DIR / SUITE_JSON
    try:
        old, new = load_suite(old_path), load_suite(new_path)
    except (OSError, ValueError) as exc:
        err.write(f"error: {exc}\n")
        return 2
    out.write(f"old: {old_path}\nnew: {new_path}\n\n{compare(old, new)}\n")
    return 0


def main(argv: Sequence[str] | None = None, stream: TextIO | None = None) -> int:
    """Run (or re-render, or compare) the suite; returns the exit code.

    0 when every selected benchmark ran (targets may still FAIL, unless ``--check``);
    1 when a benchmark failed (or, with ``--check``, a target failed); 2 when the
    docs could not be updated or a suite could not be read.
    """
    args = parse_args(argv)
    out = sys.stdout if stream is None else stream
    err = sys.stderr if stream is None else stream
    if args.compare is not None:
        return _compare(args.compare, out, err)
    written = []
    if args.from_json is not None:
        try:
            suite = load_suite(args.from_json)
        except (OSError, ValueError) as exc:
            err.write(f"error: {exc}\n")
            return 2
        out_dir = args.from_json.parent
    else:
        load_start = load_average()
        outcomes = run_all(args, out)
        out_dir = args.out
        common = run_info(
            outcomes,
            quick=args.quick,
            jobs=args.jobs,
            complete=len(outcomes) == len(BENCHMARKS),
            load_start=load_start,
        )
        built = build_suite(outcomes, common)
        if built is None:
            out.write("No benchmark gave a figure: no suite written.\n")
            return 1 if any(o.status == "failed" for o in outcomes) else 0
        path = out_dir / SUITE_JSON
        built.dump(str(path), replace=True)
        written.append(path)
        suite = load_suite(path)  # the table shows what the file holds
    markdown = render_markdown(suite)
    (out_dir / SUMMARY_MD).write_text(markdown + "\n", encoding="utf-8")
    written.append(out_dir / SUMMARY_MD)
    out.write("\n" + markdown + "\n\n")
    out.write(f"Written: {', '.join(map(str, written))}\n")
    if args.update_docs:
        try:
            update_docs(suite, DOCS_PAGE)
        except (ValueError, OSError) as exc:
            err.write(f"error: {exc}\n")
            return 2
        out.write(f"Table written into {DOCS_PAGE.relative_to(ROOT)}\n")
    table = rows(suite)
    if any(row.status == "failed" for row in table):
        return 1
    total, passed = target_counts(table)
    if args.check and passed < total:
        return 1
    return 0
