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
