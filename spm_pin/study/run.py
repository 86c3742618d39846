"""Running the study: every section in order with progress on a stream, then the
report in the context's folder (:func:`run_demo`, :func:`demo_record`)."""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path
from typing import IO, Any, Literal

from .._records import Record
from .._records import dumps as _dumps
from .._records import plain as _plain
from .._version import __version__
from .context import FILES as _FILES
from .context import DemoContext, DemoResult, DemoSection
from .pictures import take_pictures as _take_pictures
from .report import report_files as _report_files
from .report import report_html as _report_html
from .report import text_output as _text
from .report import unique_skipped as _unique
from .sections import DEMO_SECTIONS

__all__ = ["ProgressMode", "demo_record", "run_demo"]


ProgressMode = Literal["auto", "bar", "lines", "off"]


class _Progress:
    """Progress over the sections on a stream: a tqdm bar, one line per section, or none."""

    def __init__(self, mode: ProgressMode, total: int, stream: IO[str]) -> None:
        if mode == "auto":
            isatty = getattr(stream, "isatty", None)
            mode = "bar" if callable(isatty) and isatty() else "lines"
        self.mode = mode
        self.total = total
        self.stream = stream
        self.count = 0
        self._bar: Any = None
        if mode == "bar":
            from tqdm.auto import tqdm

            self._bar = tqdm(total=total, desc="spm demo", unit="part", file=stream)

    def start(self, title: str) -> None:
        if self._bar is not None:
            self._bar.set_postfix_str(title[:40])

    def done(self, title: str, seconds: float) -> None:
        self.count += 1
        if self._bar is not None:
            self._bar.update(1)
        elif self.mode == "lines":
            print(
                f"spm demo [{self.count}/{self.total}] {title} ({seconds:.1f} s)",
                file=self.stream,
                flush=True,
            )

    def extra(self, what: str, seconds: float) -> None:
        """A step after the sections (not counted in the bar)."""
        if self.mode == "lines":
            print(f"spm demo: {what} ({seconds:.1f} s)", file=self.stream, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def run_demo(
    ctx: DemoContext | None = None,
    *,
    progress: ProgressMode = "auto",
    stream: IO[str] | None = None,
) -> DemoResult:
    """Run the study: every section, then the report in ``ctx.out`` (with a picture of
    each 3-D scene when ``ctx.pictures`` and a browser allow, :mod:`.pictures`).

    Args:
        ctx: What to run (default :class:`DemoContext`, the published study, no files).
        progress: ``"bar"`` (tqdm), ``"lines"`` (one line per finished section),
            ``"off"``, or ``"auto"``: a bar on a terminal, lines otherwise.
        stream: Where progress goes (default ``sys.stderr``).

    Returns:
        :class:`DemoResult`.

    Raises:
        InputError: bad settings in ``ctx``.
        OSError: the report folder cannot be made or written.
    """
    if ctx is None:
        ctx = DemoContext()
    if ctx.out is not None:
        ctx.out.mkdir(parents=True, exist_ok=True)
    begin = time.perf_counter()
    bar = _Progress(progress, len(DEMO_SECTIONS), sys.stderr if stream is None else stream)
    if bar.mode == "bar" and not ctx.workspace_progress:
        ctx = dataclasses.replace(ctx, workspace_progress=True)
    sections: list[DemoSection] = []
    timing: dict[str, float] = {}
    try:
        for make_section in DEMO_SECTIONS:
            bar.start(make_section.__name__.removeprefix("_demo_").replace("_", " "))
            start = time.perf_counter()
            section = make_section(ctx)
            timing[section.key] = time.perf_counter() - start
            sections.append(section)
            bar.done(section.title, timing[section.key])
        bar.start("pictures of the scenes")
        pictures = _take_pictures(ctx, sections)
        timing["pictures"] = pictures.seconds
        if pictures.files:
            bar.extra(f"pictures of the {len(pictures.files)} 3-D scenes", pictures.seconds)
    finally:
        bar.close()
    skipped = _unique([skip for section in sections for skip in section.skipped])
    failed = [
        f"{section.key}: {method}"
        for section in sections
        for method, within in section.data.get("within_tolerance", {}).items()
        if within is False
    ]
    record: Record = {
        "spm_pin_version": __version__,
        "theta_deg": ctx.theta_deg,
        "colliding_theta_deg": ctx.colliding_theta_deg,
        **{section.key: section.data for section in sections},
        "skipped": [skip.as_dict() for skip in skipped],
        "failed_checks": failed,
        "timing_s": timing,
        "runtime_s": None,
        "report": None,
    }
    files: dict[str, Path] = {}
    if ctx.out is not None:
        files = _report_files(ctx.out, sections, pictures)
        record["report"] = {
            "out": str(ctx.out),
            "index_html": str(files[_FILES["index"]]),
            "files": sorted(files),
            "pictures": pictures.files,
            "pictures_note": pictures.note,
        }
        seconds = time.perf_counter() - begin
        html_text = _report_html(ctx, sections, skipped, seconds, pictures)
        files[_FILES["index"]].write_text(html_text, encoding="utf-8")
    seconds = time.perf_counter() - begin
    record["runtime_s"] = seconds
    if ctx.out is not None:
        files[_FILES["record"]].write_text(_dumps(record) + "\n", encoding="utf-8")
    return DemoResult(
        record=_plain(record),
        lines=_text(ctx, sections, skipped, failed, files, seconds, pictures),
        sections=sections,
        skipped=skipped,
        failed_checks=failed,
        files=files,
        seconds=seconds,
    )


def demo_record(ctx: DemoContext | None = None) -> tuple[Record, list[str]]:
    """The study's JSON record and its text lines (:func:`run_demo` without progress)."""
    result = run_demo(ctx, progress="off")
    return result.record, result.lines
