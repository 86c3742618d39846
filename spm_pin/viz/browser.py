"""Pictures of saved scenes, taken in a headless Chromium driven by Playwright.

Needs Playwright for Python (``pip install playwright``) and a Chromium on the
machine (Debian: ``apt install chromium``); Playwright's own browser download is
not used. WebGL runs on the CPU (SwiftShader), so no graphics card is needed.

Example::

    from spm_pin.viz import Visualizer
    from spm_pin.viz.browser import screenshot

    Visualizer().save_html("home.html")
    screenshot("home.html", "home.png")
"""

from __future__ import annotations

import base64
import contextlib
import math
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..errors import InputError
from .server import ViewerError

__all__ = ["CHROMIUM_ARGS", "CHROMIUM_NAMES", "chromium", "find_chromium", "screenshot"]

#: Executable names tried, in order, on the PATH.
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
#: Command-line flags for a headless Chromium with software WebGL and no network chatter.
CHROMIUM_ARGS = (
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--enable-unsafe-swiftshader",
    "--use-angle=swiftshader",
)
#: Pauses an animation at time t [s] (if there is one) and returns the canvas as a PNG
#: data URL.
_CAPTURE = """(t) => {
    const animator = viewer.animator;
    if (animator.actions.length > 0) {
        animator.play();
        animator.pause();
        animator.seek(t);
    }
    return viewer.capture_image();
}"""
#: How long to wait for a page to build its scene [ms].
_LOAD_TIMEOUT_MS = 30_000


def find_chromium() -> str | None:
    """The first Chromium executable on the PATH (:data:`CHROMIUM_NAMES`), or None."""
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path is not None:
            return path
    return None


@contextlib.contextmanager
def chromium(executable: str | Path | None = None) -> Iterator[Any]:
    """A headless Chromium (a Playwright ``Browser``), closed on exit.

    Args:
        executable: The Chromium to run (default: :func:`find_chromium`).

    Raises:
        ViewerError: Playwright is not installed or no Chromium was found.
    """
    try:
        from playwright.sync_api import sync_playwright
    except ImportError as exc:
        raise ViewerError(
            f"pictures need Playwright for Python ({exc}); install it with: pip install playwright"
        ) from exc
    path = str(executable) if executable is not None else find_chromium()
    if path is None:
        raise ViewerError(
            f"no Chromium found on the PATH (tried {', '.join(CHROMIUM_NAMES)}); install one "
            "(Debian: apt install chromium) or pass executable="
        )
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=path, args=list(CHROMIUM_ARGS))
        try:
            yield browser
        finally:
            browser.close()


def _only(route: Any, url: str) -> None:
    """Let the page load ``url`` and nothing else (a saved scene needs no network)."""
    if route.request.url == url:
        route.continue_()
    else:
        route.abort()


def _check_size(size: tuple[int, int]) -> tuple[int, int]:
    if (
        not isinstance(size, tuple)
        or len(size) != 2
        or not all(isinstance(n, int) and not isinstance(n, bool) and 16 <= n <= 8192 for n in size)
    ):
        raise InputError(
            f"size must be (width, height) in pixels, each 16..8192, got {size!r}",
            argument="size",
            value=size,
        )
    return size


def screenshot(
    html: str | Path,
    png: str | Path,
    *,
    size: tuple[int, int] = (800, 600),
    time: float | None = None,
    browser: Any = None,
) -> Path:
    """Render a saved scene (:meth:`~spm_pin.viz.Visualizer.save_html`) to a PNG file.

    The picture is the viewer's canvas only (no controls). The page is opened with
    every network request blocked: a saved scene needs none.

    Args:
        html: The HTML file.
        png: The PNG file to write.
        size: Width and height [px].
        time: For an animation, the time to show [s] (default: 0, its first frame).
        browser: A Playwright ``Browser`` to reuse (default: start :func:`chromium`).

    Returns:
        The PNG path.

    Raises:
        InputError: bad size or time.
        FileNotFoundError: no such HTML file.
        ViewerError: no Playwright or Chromium, or the page did not build its scene.
    """
    width, height = _check_size(size)
    if time is not None and (
        isinstance(time, bool)
        or not isinstance(time, (int, float))
        or not math.isfinite(time)
        or time < 0
    ):
        raise InputError(f"time must be >= 0 [s], got {time!r}", argument="time", value=time)
    source = Path(html).resolve()
    if not source.is_file():
        raise FileNotFoundError(2, "no such HTML file", str(source))
    if browser is None:
        with chromium() as own:
            return screenshot(source, png, size=size, time=time, browser=own)
    page = browser.new_page(viewport={"width": width, "height": height})
    try:
        url = source.as_uri()
        page.route("**/*", lambda route: _only(route, url))
        page.goto(url)
        try:
            page.wait_for_function("window.spm_scene_ready === true", timeout=_LOAD_TIMEOUT_MS)
        except Exception as exc:  # playwright's TimeoutError
            raise ViewerError(f"{source} did not build a scene (not an spm-pin scene?)") from exc
        data_url = page.evaluate(_CAPTURE, 0.0 if time is None else float(time))
    finally:
        page.close()
    target = Path(png)
    target.write_bytes(base64.b64decode(data_url.split(",", 1)[1]))
    return target
