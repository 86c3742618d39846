"""Every Python snippet in the documentation runs (in order, per page) and its
asserts hold, so the docs cannot rot."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"
PAGES = sorted(DOCS.glob("*.md"))
SNIPPET = re.compile(r"```python\n(.*?)```", re.DOTALL)


def test_docs_have_snippets() -> None:
    assert PAGES, "no documentation pages found"
    assert any(SNIPPET.search(page.read_text()) for page in PAGES)


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_snippets_run(page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {"__name__": "__docs__"}
    for number, code in enumerate(SNIPPET.findall(page.read_text()), start=1):
        try:
            exec(compile(code, f"{page.name}[snippet {number}]", "exec"), namespace)
        except Exception as exc:  # pragma: no cover - the failure message is the point
            pytest.fail(f"{page.name}, snippet {number} failed: {exc!r}\n{code}")


# --------------------------------------------------------------------------- images

IMAGE = re.compile(r"!\[(?:[^\[\]]|\[[^\]]*\])*\]\(([^)\s]+)\)")
#: Largest picture the docs may ship [bytes].
MAX_IMAGE_BYTES = 300_000


def test_every_referenced_image_exists() -> None:
    referenced = {
        (page.name, target)
        for page in PAGES
        for target in IMAGE.findall(page.read_text(encoding="utf-8"))
        if "://" not in target
    }
    assert any(target == "images/spm_colliding.png" for _, target in referenced)
    missing = [f"{page}: {target}" for page, target in referenced if not (DOCS / target).is_file()]
    assert not missing, f"images the docs show but docs/ lacks: {missing}"


def test_collision_and_workspace_pages_show_their_figures() -> None:
    collision = (DOCS / "collision.md").read_text(encoding="utf-8")
    shown = IMAGE.findall(collision)
    for picture in ("images/spm_safe.png", "images/spm_colliding.png"):
        assert picture in shown, f"collision.md does not show {picture}"
    assert "images/workspace_gap_map.png" in shown
    # the pictures are made by the project's own scripts, and the page says how
    assert "examples/visualize.py --png docs/images" in collision
    assert "docs/figures.py" in collision


def test_pictures_are_small() -> None:
    pictures = sorted((DOCS / "images").glob("*.png"))
    assert len(pictures) >= 6
    too_big = [
        f"{p.name}: {p.stat().st_size} B" for p in pictures if p.stat().st_size > MAX_IMAGE_BYTES
    ]
    assert not too_big, f"pictures above {MAX_IMAGE_BYTES} B (compress them): {too_big}"


# --------------------------------------------------------------------------- formulas

#: Pages whose formulas are TeX (pymdownx.arithmatex: $...$ inline, $$...$$ display).
FORMULA_PAGES = (
    "conventions.md",
    "kinematics.md",
    "dynamics.md",
    "closure.md",
    "calibration.md",
    "hardware.md",
)
#: ASCII spellings of formulas that the pages now write in TeX.
ASCII_FORMULAS = (
    "sin a1 cos(eta_i",
    "w_i . v_i = cos",
    "v = S theta_dot",
    "A^-1 B",
    "M(q) qdd",
    "upper(omega) =",
    "* 2 pi /",
    "120 + theta_1 - theta_2",
)
#: Markdown that may precede an indented block that is not code: a list item or an
#: admonition, whose content is indented.
_CONTAINER = re.compile(r"^\s*(?:[-*+]|\d+\.|!!!|\?\?\?)\s")


def _indented_blocks(text: str) -> list[str]:
    """The first line of every indented (4-space) code block outside fences."""
    blocks: list[str] = []
    fenced = False
    context = ""  # the last non-blank line outside an indented block
    previous = ""
    for line in text.splitlines():
        starts_block = (
            not fenced
            and line.startswith("    ")
            and bool(line.strip())
            and not previous.strip()
            and not context.startswith("    ")
            and not _CONTAINER.match(context)
        )
        if line.lstrip().startswith("```"):
            fenced = not fenced
        elif starts_block:
            blocks.append(line.strip())
        if line.strip():
            context = line
        previous = line
    return blocks


def test_no_indented_code_blocks() -> None:
    """Formulas are TeX and code is fenced: an indented block is an ASCII formula
    (or unmarked code) left over."""
    found = [
        f"{page.name}: {block}" for page in PAGES for block in _indented_blocks(page.read_text())
    ]
    assert not found, "indented blocks (write formulas as $$ TeX $$, fence code):\n" + "\n".join(
        found
    )


def test_indented_block_finder_finds_ascii_formulas() -> None:
    text = "Each leg obeys\n\n    w_i . v_i = cos a2\n\nand\n\n- item\n\n    continued\n"
    assert _indented_blocks(text) == ["w_i . v_i = cos a2"]


@pytest.mark.parametrize("name", FORMULA_PAGES)
def test_formulas_are_tex(name: str) -> None:
    text = (DOCS / name).read_text(encoding="utf-8")
    outside_code = re.sub(r"```.*?```|`[^`\n]*`", "", text, flags=re.DOTALL)
    display = re.findall(r"^\$\$\n(.*?)\n\$\$$", outside_code, re.DOTALL | re.MULTILINE)
    assert display, f"{name} has no display formula ($$ ... $$)"
    for formula in display:
        assert "\\" in formula or "_" in formula, f"{name}: not TeX: {formula!r}"
    # the ASCII spellings the TeX replaced
    for ascii_form in ASCII_FORMULAS:
        assert ascii_form not in outside_code, f"{name}: ASCII formula {ascii_form!r} left"
