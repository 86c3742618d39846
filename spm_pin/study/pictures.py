"""Pictures of the report's 3-D scenes: each meshcat scene rendered to a PNG beside it
in a headless Chromium (:func:`spm_pin.viz.browser.screenshot`), with the scene's key,
pose caption and contact list, so the report reads without WebGL.

Optional: without Playwright or a Chromium (or with ``DemoContext(pictures=False)``)
the report shows the scenes alone and says in one line why there are no pictures.
Nothing is downloaded (the scenes are self-contained, every other request is refused)
and every step is bounded in time (:data:`PICTURE_TIMEOUT_S`).
"""

from __future__ import annotations

import dataclasses
import importlib
import shutil
import time
from collections.abc import Sequence
from pathlib import PurePosixPath

from .context import DemoContext, DemoSection, ReportItem

__all__ = [
    "INSTALL_PICTURES",
    "PICTURE_SIZE",
    "PICTURE_TIMEOUT_S",
    "ScenePictures",
    "picture_path",
    "take_pictures",
]

#: Width and height of each picture [px].
PICTURE_SIZE = (960, 720)
#: How long Chromium may take to start, and each scene to load and build [s].
PICTURE_TIMEOUT_S = 30.0
#: What brings the pictures.
INSTALL_PICTURES = (
    'pip install "spm-pin[browser]" and a Chromium on the PATH (Debian: apt install chromium)'
)


@dataclasses.dataclass(frozen=True)
class ScenePictures:
    """The pictures of the report's scenes.

    Attributes:
        files: Picture by scene, both relative to the report folder.
        note: Why some or all scenes have no picture, in one line (None: all have one).
        seconds: Wall time of the rendering [s].
    """

    files: dict[str, str]
    note: str | None
    seconds: float


def picture_path(scene: str) -> str:
    """The picture of a scene: its path with ``.png`` for ``.html``."""
    return str(PurePosixPath(scene).with_suffix(".png"))


def _unavailable(ctx: DemoContext) -> str | None:
    """Why no browser can render the pictures, or None."""
    try:
        importlib.import_module("playwright.sync_api")
    except ImportError:
        return "Playwright is not installed"
    from ..viz.browser import find_chromium

    if ctx.chromium is not None:
        if shutil.which(str(ctx.chromium)) is None:
            return f"no Chromium at {str(ctx.chromium)!r}"
    elif find_chromium() is None:
        return "no Chromium on the PATH"
    return None


def _first_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__


def take_pictures(ctx: DemoContext, sections: Sequence[DemoSection]) -> ScenePictures:
    """Render every scene of the sections to a PNG beside it (one browser for all).

    Never raises for a missing or failing browser: the scenes left without a picture
    and the reason are in the result's ``note``.

    Args:
        ctx: The study's settings (``out``, ``pictures``, ``chromium``).
        sections: The sections whose scenes are in ``ctx.out``.

    Returns:
        :class:`ScenePictures`.
    """
    scenes: list[ReportItem] = [item for section in sections for item in section.scenes]
    if ctx.out is None or not scenes:
        return ScenePictures({}, None, 0.0)
    if not ctx.pictures:
        return ScenePictures({}, "No pictures of the 3-D scenes: turned off.", 0.0)
    reason = _unavailable(ctx)
    if reason is not None:
        return ScenePictures(
            {},
            f"No pictures of the 3-D scenes: {reason}. They need Playwright and a Chromium: "
            f"{INSTALL_PICTURES}.",
            0.0,
        )
    from ..viz.browser import chromium, screenshot

    begin = time.perf_counter()
    files: dict[str, str] = {}
    note = None
    try:
        with chromium(ctx.chromium, timeout_s=PICTURE_TIMEOUT_S) as browser:
            for item in scenes:
                png = picture_path(item.path)
                screenshot(
                    ctx.out / item.path,
                    ctx.out / png,
                    size=PICTURE_SIZE,
                    time=item.picture_time_s,
                    browser=browser,
                    timeout_s=PICTURE_TIMEOUT_S,
                    overlays=True,
                )
                files[item.path] = png
    except Exception as exc:  # any failure of the browser leaves the scenes as they are
        left = [item.path for item in scenes if item.path not in files]
        note = f"No pictures of {', '.join(left)}: {_first_line(exc)}."
    return ScenePictures(files, note, time.perf_counter() - begin)
