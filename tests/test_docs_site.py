"""The documentation site builds with warnings as errors, and what it shows is whole.

`mkdocs build --strict` runs into a temporary folder; the built pages are then
checked: every page of the navigation exists, every internal link and anchor resolves
(also the links mkdocstrings writes into the API reference), and the API reference
documents every public name. The commands of the getting-started page's tour run, and
the figure script draws its figure.

Without mkdocs (the `docs` extra) these tests skip, except under CI (CI=true), where
they fail: the site is part of what CI checks.
"""

from __future__ import annotations

import html.parser
import importlib
import importlib.util
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import Any
from urllib.parse import unquote, urlsplit

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
CONFIG = ROOT / "mkdocs.yml"
IN_CI = os.environ.get("CI", "").strip().lower() in ("1", "true", "yes")

#: Seconds a full build may take (about 10 s on one core).
BUILD_TIMEOUT = 600
#: Seconds one command of the getting-started tour may take.
COMMAND_TIMEOUT = 120


def _require(module: str, why: str) -> ModuleType:
    """Import ``module``; skip without it, but fail under CI."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        message = f"{module} is not installed ({why}): {exc}"
        if IN_CI:
            pytest.fail(f"{message}; CI must install it")
        pytest.skip(message)


def _config() -> dict[str, Any]:
    """mkdocs.yml as plain data (mkdocs' own tags such as !relative read as None)."""
    yaml = _require("yaml", "PyYAML comes with mkdocs: pip install '.[docs]'")

    class Loader(yaml.SafeLoader):  # type: ignore[misc,name-defined]
        pass

    Loader.add_multi_constructor("!", lambda loader, suffix, node: None)
    with CONFIG.open(encoding="utf-8") as stream:
        config: dict[str, Any] = yaml.load(stream, Loader=Loader)
    return config


def _nav_pages(nav: Any) -> list[str]:
    """Every page path in a mkdocs nav (nested lists of titles -> pages)."""
    if isinstance(nav, str):
        return [] if "://" in nav else [nav]
    if isinstance(nav, list):
        return [page for item in nav for page in _nav_pages(item)]
    if isinstance(nav, dict):
        return [page for value in nav.values() for page in _nav_pages(value)]
    return []


# --------------------------------------------------------------------------- sources


def test_nav_pages_exist() -> None:
    pages = _nav_pages(_config()["nav"])
    assert pages, "mkdocs.yml has no nav"
    missing = [page for page in pages if not (DOCS / page).is_file()]
    assert not missing, f"pages in the nav of mkdocs.yml but not in docs/: {missing}"
    assert len(set(pages)) == len(pages), "a page appears twice in the nav"


def test_every_page_is_in_nav() -> None:
    pages = set(_nav_pages(_config()["nav"]))
    on_disk = {path.relative_to(DOCS).as_posix() for path in DOCS.rglob("*.md")}
    left_out = sorted(on_disk - pages)
    assert not left_out, f"pages in docs/ that the nav of mkdocs.yml leaves out: {left_out}"


# --------------------------------------------------------------------------- the build


class _Page(html.parser.HTMLParser):
    """The ids and the link targets (href, src) of one built HTML page."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.links: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = dict(attrs)
        if values.get("id"):
            self.ids.add(str(values["id"]))
        if tag in ("a", "link") and values.get("href"):
            self.links.append(str(values["href"]))
        if tag in ("img", "script") and values.get("src"):
            self.links.append(str(values["src"]))


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The site, built once by `mkdocs build --strict` into a temporary folder."""
    _require("mkdocs", "pip install '.[docs]'")
    _require("mkdocstrings", "pip install '.[docs]'")
    out = tmp_path_factory.mktemp("site")
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    command = ["mkdocs", "build", "--strict", "--config-file", str(CONFIG), "--site-dir", str(out)]
    result = subprocess.run(
        [sys.executable, "-m", *command],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=BUILD_TIMEOUT,
        check=False,
    )
    log = result.stdout + result.stderr
    warnings = [line for line in log.splitlines() if re.match(r"\s*(WARNING|ERROR)\b", line)]
    shown = "\n".join(warnings or log.splitlines()[-30:])
    assert result.returncode == 0 and not warnings, f"mkdocs build --strict failed:\n{shown}"
    return out


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    return page


def _target(site: Path, page: Path, link: str) -> tuple[Path, str] | None:
    """The file and fragment an internal link points to (None for external links)."""
    parts = urlsplit(link)
    if parts.scheme or parts.netloc or link.startswith(("mailto:", "javascript:", "data:")):
        return None
    if not parts.path:
        return page, unquote(parts.fragment)
    base = site if parts.path.startswith("/") else page.parent  # 404.html links from the root
    target = (base / unquote(parts.path).lstrip("/")).resolve()
    if target.is_dir() or parts.path.endswith("/"):
        target = target / "index.html"
    return target, unquote(parts.fragment)


def test_site_builds_strict(site: Path) -> None:
    assert (site / "index.html").is_file()
    assert (site / "api" / "index.html").is_file()


def test_nav_pages_are_built(site: Path) -> None:
    for page in _nav_pages(_config()["nav"]):
        stem = page.removesuffix(".md")
        if stem == "index" or stem.endswith("/index"):
            built = site / stem.removesuffix("index") / "index.html"
        else:
            built = site / stem / "index.html"
        assert built.is_file(), f"{page} was not built ({built} is missing)"


def test_internal_links_resolve(site: Path) -> None:
    parsed: dict[Path, _Page] = {}

    def parse(path: Path) -> _Page:
        if path not in parsed:
            parsed[path] = _parse(path)
        return parsed[path]

    broken: list[str] = []
    for page in sorted(site.rglob("*.html")):
        links = parse(page).links
        for link in links:
            target = _target(site, page, link)
            if target is None:
                continue
            path, fragment = target
            where = f"{page.relative_to(site)}: {link}"
            if not path.exists():
                broken.append(f"{where} (no file {path})")
            elif fragment and path.suffix == ".html" and fragment not in parse(path).ids:
                broken.append(f"{where} (no anchor #{fragment})")
    assert not broken, f"{len(broken)} broken internal links:\n" + "\n".join(broken[:50])


def _api_modules() -> dict[str, list[str]]:
    """API page -> the modules its `::: identifier` blocks render."""
    pages: dict[str, list[str]] = {}
    for path in sorted((DOCS / "api").glob("*.md")):
        identifiers = re.findall(r"^::: *([\w.]+)", path.read_text(encoding="utf-8"), re.M)
        if identifiers:
            pages[path.stem] = identifiers
    return pages


def test_api_reference_documents_every_public_name(site: Path) -> None:
    missing: list[str] = []
    for stem, identifiers in _api_modules().items():
        ids = _parse(site / "api" / stem / "index.html").ids
        for identifier in identifiers:
            try:
                module = importlib.import_module(identifier)
            except ImportError as exc:
                # ModuleNotFoundError for the identifier itself: a single object, not a
                # module. Anything else is an optional dependency (viz: meshcat) that is
                # missing (also a ModuleNotFoundError, so told apart by its name).
                if exc.name == identifier:
                    continue
                if IN_CI:
                    raise
                continue
            for name in getattr(module, "__all__", []):
                obj = getattr(module, name)
                canonical = f"{getattr(obj, '__module__', '')}.{getattr(obj, '__qualname__', '')}"
                if f"{identifier}.{name}" not in ids and canonical not in ids:
                    missing.append(f"api/{stem}.md: {identifier}.{name}")
    assert not missing, (
        "public names without an entry in the API reference (give them a docstring, or a "
        "#: comment for constants):\n" + "\n".join(missing)
    )


def test_api_index_lists_the_top_level_names() -> None:
    import spm_pin

    text = (DOCS / "api" / "index.md").read_text(encoding="utf-8")
    listed = set(re.findall(r"\[`(\w+)`\]\[", text))
    missing = sorted(set(spm_pin.__all__) - listed - {"__version__"})
    assert not missing, f"names of spm_pin.__all__ missing from docs/api/index.md: {missing}"
    assert "__version__" in text


# --------------------------------------------------------------------------- the pages' extras


def _tour_commands() -> list[str]:
    text = (DOCS / "getting-started.md").read_text(encoding="utf-8")
    commands = []
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        for line in block.splitlines():
            line = line.split("  #", 1)[0].strip()
            if line.startswith("spm "):
                commands.append(line)
    return commands


def test_getting_started_tour_runs(tmp_path: Path) -> None:
    commands = _tour_commands()
    assert len(commands) >= 5, commands
    for command in commands:
        if "--html" in command and importlib.util.find_spec("meshcat") is None and not IN_CI:
            continue  # spm show --html needs the viz extra
        args = shlex.split(command)[1:]
        result = subprocess.run(
            [sys.executable, "-m", "spm_pin", *args],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=COMMAND_TIMEOUT,
            check=False,
        )
        assert result.returncode == 0, f"`{command}` failed:\n{result.stderr}"
        assert result.stdout.strip(), f"`{command}` printed nothing"


def test_conventions_figure_draws(tmp_path: Path) -> None:
    _require("matplotlib", "the plot extra, for docs/figures.py")
    result = subprocess.run(
        [
            sys.executable,
            str(DOCS / "figures.py"),
            "--out",
            str(tmp_path),
            "--workspace-step",
            "10",
        ],
        capture_output=True,
        text=True,
        timeout=COMMAND_TIMEOUT,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    for name in ("conventions.png", "workspace_gap_map.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
        assert (DOCS / "images" / name).is_file(), "run: python docs/figures.py"


# --------------------------------------------------------------------------- formulas

#: Pages whose formulas the site renders (their sources write them in TeX).
FORMULA_PAGES = ("conventions", "kinematics", "dynamics", "closure", "calibration", "hardware")
#: The KaTeX files the site ships (no network at build or view time).
KATEX_FILES = (
    "javascripts/katex/katex.min.js",
    "javascripts/katex/auto-render.min.js",
    "javascripts/katex/katex.min.css",
    "javascripts/katex.js",
)


def test_formulas_are_marked_for_katex(site: Path) -> None:
    for name in KATEX_FILES:
        assert (site / name).is_file(), f"{name} is not in the site"
    for stem in FORMULA_PAGES:
        page = site / stem / "index.html"
        text = page.read_text(encoding="utf-8")
        assert 'class="arithmatex"' in text, f"{stem}: no formula marked by arithmatex"
        links = _parse(page).links
        for name in KATEX_FILES:
            assert any(link.endswith(name) for link in links), f"{stem} does not load {name}"
        assert not any(link.startswith(("http:", "https:")) and "katex" in link for link in links)


def _chromium() -> Any:
    """A headless Chromium through spm_pin.viz.browser; skip without one (fail under CI)."""
    _require("playwright", "pip install playwright, for the browser checks")
    from spm_pin.viz.browser import chromium, find_chromium

    if find_chromium() is None:
        if IN_CI:
            pytest.fail("no Chromium on the PATH; CI must install it")
        pytest.skip("no Chromium on the PATH")
    return chromium()


_COUNT_FORMULAS = """() => ({
    marked: document.querySelectorAll('.arithmatex').length,
    rendered: document.querySelectorAll('.arithmatex .katex').length,
    errors: document.querySelectorAll('.katex-error').length,
})"""


def test_katex_renders_the_formulas_offline(site: Path) -> None:
    with _chromium() as browser:
        page = browser.new_page()
        requested: list[str] = []

        def route(handle: Any) -> None:
            url = handle.request.url
            if url.startswith("file:"):
                handle.continue_()
            else:
                requested.append(url)
                handle.abort()

        page.route("**/*", route)
        try:
            for stem in FORMULA_PAGES:
                page.goto((site / stem / "index.html").as_uri())
                page.wait_for_function(
                    "document.querySelectorAll('.arithmatex .katex').length > 0", timeout=20_000
                )
                counts = page.evaluate(_COUNT_FORMULAS)
                assert counts["marked"] > 0 and counts["errors"] == 0, (stem, counts)
                assert counts["rendered"] == counts["marked"], (stem, counts)
        finally:
            page.close()
    # (the theme asks for web fonts and the repository's stars, and does without them)
    maths = [url for url in requested if "katex" in url.lower() or "mathjax" in url.lower()]
    assert not maths, f"the formulas need the network: {maths}"


# --------------------------------------------------------------------------- pictures


def _pixels(name: str) -> Any:
    """The RGB pixels (height, width, 3) of docs/images/<name>, as ints."""
    image = _require("PIL.Image", "Pillow comes with matplotlib: pip install '.[plot]'")
    import numpy as np

    with image.open(DOCS / "images" / name) as picture:
        return np.asarray(picture.convert("RGB")).astype(int)


def _colour_masks(pixels: Any) -> dict[str, Any]:
    """Where the colours that matter are: the legs' hues, the contact markers' red
    (spm_pin.viz.contacts.CONTACT_COLOR, shaded) and the near-black of colliding links
    (spm_pin.viz.COLLIDING_COLOR, 0.12 grey, shaded)."""
    r, g, b = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    return {
        "leg 1 blue": (b > r + 80) & (b > g + 20),
        "leg 2 orange": (r > 180) & (r > g + 50) & (g > b + 40),
        "leg 3 purple": (b > g + 50) & (r > g + 30),
        "contact red": (r > 150) & (g < 70) & (b < 70),
        "near-black": pixels.max(axis=-1) < 40,
    }


def _colour_counts(pixels: Any) -> dict[str, int]:
    """How many pixels have each colour of :func:`_colour_masks`."""
    return {name: int(mask.sum()) for name, mask in _colour_masks(pixels).items()}


#: Least pixels of a colour that count as "visible" in a 960 x 720 picture.
VISIBLE_PIXELS = {"leg": 1000, "contact red": 100, "near-black": 5000}


def test_picture_of_the_study_input_shows_three_legs_and_no_collision() -> None:
    pixels = _pixels("spm_safe.png")
    assert pixels.shape == (720, 960, 3)
    counts = _colour_counts(pixels)
    for leg in ("leg 1 blue", "leg 2 orange", "leg 3 purple"):
        assert counts[leg] >= VISIBLE_PIXELS["leg"], (leg, counts)
    assert counts["near-black"] == 0, counts
    assert counts["contact red"] == 0, counts


def test_picture_of_the_colliding_input_shows_black_links_and_contacts() -> None:
    pixels = _pixels("spm_colliding.png")
    assert pixels.shape == (720, 960, 3)
    counts = _colour_counts(pixels)
    assert counts["near-black"] >= VISIBLE_PIXELS["near-black"], counts
    assert counts["contact red"] >= VISIBLE_PIXELS["contact red"], counts
    # leg 1 is free and keeps its colour; legs 2 and 3 collide: no orange, no purple
    assert counts["leg 1 blue"] >= VISIBLE_PIXELS["leg"], counts
    assert counts["leg 2 orange"] < 50 and counts["leg 3 purple"] < 50, counts
    # the red markers sit on the black links: within 30 px of near-black pixels
    import numpy as np

    masks = _colour_masks(pixels)
    red, dark = np.argwhere(masks["contact red"]), np.argwhere(masks["near-black"])
    nearest = np.min(np.abs(red[:, None, :] - dark[None, ::20, :]).max(axis=-1), axis=1)
    assert np.median(nearest) <= 30, "the contact markers are away from the black links"


def test_pictures_of_the_poses_are_full_size() -> None:
    for name in ("spm_home.png", "spm_demo.png", "spm_safe.png", "spm_colliding.png"):
        assert _pixels(name).shape == (720, 960, 3), name
    assert _pixels("workspace_gap_map.png").shape[1] >= 1000
