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

__all__ = [
    "CHROMIUM_ARGS",
    "CHROMIUM_NAMES",
    "DEFAULT_TIMEOUT_S",
    "chromium",
    "find_chromium",
    "screenshot",
]

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
#: Hides the page's controls (the view buttons, meshcat's control panel) for a picture.
_HIDE_CONTROLS = "#spm-views, .dg { display: none !important; }"
#: How long Chromium may take to start, and a page to load and build its scene [s].
DEFAULT_TIMEOUT_S = 30.0


def find_chromium() -> str | None:
    """The first Chromium executable on the PATH (:data:`CHROMIUM_NAMES`), or None."""
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path is not None:
            return path
    return None


@contextlib.contextmanager
def chromium(
    executable: str | Path | None = None, *, timeout_s: float = DEFAULT_TIMEOUT_S
) -> Iterator[Any]:
    """A headless Chromium (a Playwright ``Browser``), closed on exit.

    Args:
        executable: The Chromium to run: a path or a name on the PATH (default:
            :func:`find_chromium`).
        timeout_s: How long it may take to start [s].

    Raises:
        InputError: bad timeout.
        ViewerError: Playwright is not installed, no Chromium was found or it did not
            start.
    """
    timeout_ms = _timeout_ms(timeout_s)
    try:
        from playwright.sync_api import sync_playwright
    except ImportError as exc:
        raise ViewerError(
            f"pictures need Playwright for Python ({exc}); install it with: pip install playwright"
        ) from exc
    if executable is not None:
        path = shutil.which(str(executable))
        if path is None:
            raise ViewerError(f"no Chromium at {str(executable)!r} (not an executable file)")
    else:
        path = find_chromium()
    if path is None:
        raise ViewerError(
            f"no Chromium found on the PATH (tried {', '.join(CHROMIUM_NAMES)}); install one "
            "(Debian: apt install chromium) or pass executable="
        )
    with sync_playwright() as playwright:
        try:
            browser = playwright.chromium.launch(
                executable_path=path, args=list(CHROMIUM_ARGS), timeout=timeout_ms
            )
        except Exception as exc:  # playwright's Error: no such browser, crash, timeout
            first = str(exc).strip().splitlines()[:1] or [type(exc).__name__]
            raise ViewerError(f"Chromium {path} did not start: {first[0]}") from exc
        try:
            yield browser
        finally:
            browser.close()


def _timeout_ms(timeout_s: float) -> float:
    if (
        isinstance(timeout_s, bool)
        or not isinstance(timeout_s, (int, float))
        or not math.isfinite(timeout_s)
        or timeout_s <= 0
    ):
        raise InputError(
            f"timeout_s must be a positive number [s], got {timeout_s!r}",
            argument="timeout_s",
            value=timeout_s,
        )
    return 1000.0 * float(timeout_s)


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
    timeout_s: float = DEFAULT_TIMEOUT_S,
    overlays: bool = False,
) -> Path:
    """Render a saved scene (:meth:`~spm_pin.viz.Visualizer.save_html`) to a PNG file.

    The picture is the viewer's canvas only, or with ``overlays`` the page as it
    shows: the canvas with the key, the pose caption and the contact list, without
    the controls (view buttons, meshcat's control panel). The page is opened with
    every network request blocked: a saved scene needs none.

    Args:
        html: The HTML file.
        png: The PNG file to write.
        size: Width and height [px].
        time: For an animation, the time to show [s] (default: 0, its first frame).
        browser: A Playwright ``Browser`` to reuse (default: start :func:`chromium`).
        timeout_s: How long the page may take to load and build its scene, and
            Chromium to start [s].
        overlays: Keep the page's key, caption and contact list in the picture.

    Returns:
        The PNG path.

    Raises:
        InputError: bad size, time or timeout.
        FileNotFoundError: no such HTML file.
        ViewerError: no Playwright or Chromium, or the page did not build its scene.
    """
    width, height = _check_size(size)
    timeout_ms = _timeout_ms(timeout_s)
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
        with chromium(timeout_s=timeout_s) as own:
            return screenshot(
                source,
                png,
                size=size,
                time=time,
                browser=own,
                timeout_s=timeout_s,
                overlays=overlays,
            )
    page = browser.new_page(viewport={"width": width, "height": height})
    try:
        page.set_default_timeout(timeout_ms)
        url = source.as_uri()
        page.route("**/*", lambda route: _only(route, url))
        try:
            page.goto(url)
            page.wait_for_function("window.spm_scene_ready === true", timeout=timeout_ms)
        except Exception as exc:  # playwright's TimeoutError
            raise ViewerError(
                f"{source} did not build a scene within {timeout_s:g} s (not an spm-pin scene?)"
            ) from exc
        if overlays:
            page.add_style_tag(content=_HIDE_CONTROLS)
        data_url = page.evaluate(_CAPTURE, 0.0 if time is None else float(time))
        data = page.screenshot(type="png") if overlays else None
    finally:
        page.close()
    target = Path(png)
    target.write_bytes(data if data is not None else base64.b64decode(data_url.split(",", 1)[1]))
    return target
