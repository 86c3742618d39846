"""The study's report: ``index.html`` (the sections with their tables, figures and
meshcat scenes), the list of report files and the text output."""

from __future__ import annotations

import html
from pathlib import Path

from .._version import __version__
from ._extras import INSTALL_DEMO, Skipped
from .context import FILES as _FILES
from .context import DemoContext, DemoSection, ReportItem
from .context import degrees_text as _degrees_text
from .pictures import PICTURE_SIZE, ScenePictures
from .tables import section_tables as _section_tables

__all__ = ["report_files", "report_html", "text_output", "unique_skipped"]


# -------------------------------------------------------------------------- report
_STYLE = """
body { font-family: system-ui, sans-serif; max-width: 72rem; margin: 2rem auto;
       padding: 0 1rem; color: #222; line-height: 1.45; }
h1 { font-size: 1.6rem; } h2 { margin-top: 2.5rem; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; font-variant-numeric: tabular-nums; margin: 1rem 0;
        font-size: 0.85rem; }
.wide { overflow-x: auto; }
th, td { border: 1px solid #ccd; padding: 0.2rem 0.5rem; text-align: right;
         white-space: nowrap; }
th { background: #eef0f4; text-align: center; }
th[scope="row"], table.record td, table.pairs td, td.note { text-align: left; }
table.record th { font-weight: normal; }
td.note { white-space: normal; }
p.note, td.note { font-size: 0.85rem; color: #555; }
figure { margin: 1.2rem 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
iframe { width: 100%; height: 30rem; border: 1px solid #ccd; }
.pair { display: grid; grid-template-columns: repeat(auto-fit, minmax(22rem, 1fr));
        gap: 0.8rem; align-items: start; }
.pair img { width: 100%; height: auto; display: block; }
.pair iframe { height: auto; aspect-ratio: 4 / 3; }
figcaption { font-size: 0.9rem; color: #555; }
.skipped { background: #fff4e0; border-left: 4px solid #f0a020; padding: 0.5rem 0.8rem; }
"""


def _scene_html(item: ReportItem, picture: str | None) -> str:
    path, caption = html.escape(item.path), html.escape(item.caption)
    frame = f'<iframe src="{path}" title="{caption}" loading="lazy"></iframe>'
    link = f'<a href="{path}">Open the scene on its own page.</a>'
    if picture is None:
        return f"<figure>{frame}<figcaption>{caption} {link}</figcaption></figure>"
    width, height = PICTURE_SIZE
    note = f" {html.escape(item.picture_note)}" if item.picture_note else ""
    return (
        f'<figure><div class="pair"><a href="{path}"><img src="{html.escape(picture)}" '
        f'width="{width}" height="{height}" alt="Picture of the 3-D scene: {caption}"></a>'
        f"{frame}</div><figcaption>{caption}{note} First a picture of the scene (it reads "
        "without WebGL), then the scene itself: drag to orbit, scroll to zoom. "
        f"{link}</figcaption></figure>"
    )


def _section_html(section: DemoSection, pictures: ScenePictures) -> str:
    parts = [f'<section id="{section.key}">', f"<h2>{html.escape(section.title)}</h2>"]
    parts.append(_section_tables(section))
    for item in section.figures:
        parts.append(
            f'<figure><img src="{html.escape(item.path)}" alt="{html.escape(item.caption)}">'
            f"<figcaption>{html.escape(item.caption)}</figcaption></figure>"
        )
    for item in section.scenes:
        parts.append(_scene_html(item, pictures.files.get(item.path)))
    for skip in section.skipped:
        parts.append(_skipped_html(skip))
    parts.append("</section>")
    return "\n".join(parts)


def _skipped_html(skip: Skipped) -> str:
    return (
        f'<p class="skipped">Skipped: {html.escape(skip.part)} ({html.escape(skip.missing)} '
        f"is not installed; <code>{html.escape(skip.install)}</code>).</p>"
    )


def report_html(
    ctx: DemoContext,
    sections: list[DemoSection],
    skipped: list[Skipped],
    seconds: float,
    pictures: ScenePictures | None = None,
) -> str:
    where = _degrees_text(ctx.theta_deg)
    contents = "".join(
        f'<li><a href="#{section.key}">{html.escape(section.title)}</a></li>'
        for section in sections
    )
    missing = ""
    if skipped:
        missing = '<p class="skipped">Parts skipped for missing optional dependencies: ' + (
            "; ".join(html.escape(f"{s.part} ({s.missing})") for s in skipped)
            + f". Install them with <code>{html.escape(INSTALL_DEMO)}</code>.</p>"
        )
    if pictures is None:
        pictures = ScenePictures({}, None, 0.0)
    if pictures.note is not None:
        missing += f'<p class="skipped">{html.escape(pictures.note)}</p>'
    body = "\n".join(_section_html(section, pictures) for section in sections)
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>spm-pin demo: the {html.escape(ctx.design.name)}</title>
<style>{_STYLE}</style>
</head>
<body>
<h1>spm-pin {html.escape(__version__)}: the published study of the {html.escape(ctx.design.name)},
reproduced</h1>
<p>The study "Modeling and Simulation of Spherical Parallel Manipulators in CoppeliaSim
(V-REP)" compared the platform axes of a 3D-printed coaxial SPM computed from its kinematic
model with those of a simulation at theta = {html.escape(where)} deg, showed the motion from
home to that input at {ctx.samples} samples and found a link collision at
theta = {html.escape(_degrees_text(ctx.colliding_theta_deg))} deg. This report does the same
on the same prototype with spm-pin, and maps the safe workspace and the actuator torques
that the study left as future work. The scenes are interactive: drag to orbit, scroll to
zoom. Every number is in <a href="{_FILES["record"]}">{_FILES["record"]}</a>.</p>
{missing}
<nav><ol>{contents}</ol></nav>
{body}
<footer><p>Made by <code>spm demo</code> (spm-pin {html.escape(__version__)}) in
{seconds:.1f} s.</p></footer>
</body>
</html>
"""


def unique_skipped(skipped: list[Skipped]) -> list[Skipped]:
    seen: dict[tuple[str, str], Skipped] = {}
    for skip in skipped:
        seen.setdefault((skip.part, skip.missing), skip)
    return list(seen.values())


def report_files(
    out: Path, sections: list[DemoSection], pictures: ScenePictures | None = None
) -> dict[str, Path]:
    """Every file of the report, by its path relative to ``out``."""
    names = [_FILES["index"], _FILES["record"]]
    for section in sections:
        names += [item.path for item in (*section.figures, *section.scenes)]
        names += list(section.files)
    if pictures is not None:
        names += list(pictures.files.values())
    return {name: out / name for name in dict.fromkeys(names)}


def text_output(
    ctx: DemoContext,
    sections: list[DemoSection],
    skipped: list[Skipped],
    failed: list[str],
    files: dict[str, Path],
    seconds: float,
    pictures: ScenePictures | None = None,
) -> list[str]:
    where = _degrees_text(ctx.theta_deg)
    lines = [
        f"spm-pin {__version__}: the published study of the {ctx.design.name}, reproduced "
        f"(theta = {where} deg)"
    ]
    for section in sections:
        lines += ["", f"== {section.title} ==", *section.text_lines()]
    lines.append("")
    if failed:
        lines.append("Cross-checks OUTSIDE their tolerance: " + ", ".join(failed))
    if skipped:
        lines.append("Skipped (optional dependencies missing):")
        lines += [f"  {skip.part}: needs {skip.missing}" for skip in skipped]
        lines.append(f"  install them with: {INSTALL_DEMO}")
    if pictures is not None and pictures.note is not None:
        lines.append(pictures.note)
    if _FILES["index"] in files:
        index = files[_FILES["index"]]
        lines.append(f"report: {index} (open it in a browser; it works offline)")
    lines.append(f"done in {seconds:.1f} s")
    return lines
