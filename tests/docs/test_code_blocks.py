"""Every Python code block of the README and the docs runs (the examples cannot rot).

A page's ```python blocks run in order in one namespace, in a temporary folder, as a reader would
paste them. A block right after the line ``<!-- skip -->`` is not run (it needs data that the tests
do not have, or shows a fragment); a page that holds ``<!-- slow -->`` runs in the slow lane, and one
that holds ``<!-- needs: MODULE -->`` is skipped where an optional MODULE is not installed.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
NEEDS = re.compile(r"<!-- needs: ([\w.]+) -->")
FENCE = re.compile(r"(?P<before>[^\n]*)\n```python[^\n]*\n(?P<code>.*?)\n```", re.S)


def code_blocks(text: str) -> list[str]:
    """The page's Python blocks to run, in order (module docstring)."""
    return [m["code"] for m in FENCE.finditer("\n" + text) if m["before"].strip() != "<!-- skip -->"]


def _param(page: Path):
    slow = "<!-- slow -->" in page.read_text()
    return pytest.param(page, id=str(page.relative_to(ROOT)), marks=[pytest.mark.slow] if slow else [])


def test_the_collector_finds_blocks_and_honours_skip():
    text = "intro\n```python\na = 1\n```\n<!-- skip -->\n```python\nraise SystemExit\n```\n```bash\nls\n```\n"
    assert code_blocks(text) == ["a = 1"]
    assert NEEDS.findall("<!-- slow -->\n<!-- needs: ray -->\ntext") == ["ray"]


@pytest.mark.parametrize("page", [_param(p) for p in PAGES if code_blocks(p.read_text())])
def test_code_blocks_run(page: Path, tmp_path, monkeypatch):
    for module in NEEDS.findall(page.read_text()):
        pytest.importorskip(module, reason=f"{page.name} needs the optional {module}")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__docs__"}
    for i, block in enumerate(code_blocks(page.read_text())):
        exec(compile(block, f"{page.name}[block {i}]", "exec", dont_inherit=True), namespace)  # as a script: no future flags
