"""The Python examples of the README and the manual (docs/) run as written: documentation whose
code fails teaches nothing."""

from __future__ import annotations

import contextlib
import io
import re

import pytest

from surrogate.maps.registry import MAP_KINDS
from surrogate.core.paths import PROJECT_ROOT

PAGES = [PROJECT_ROOT / "README.md", *sorted((PROJECT_ROOT / "docs").glob("*.md"))]
BLOCKS = [(page.relative_to(PROJECT_ROOT).as_posix(), number, code) for page in PAGES
          for number, code in enumerate(re.findall(r"```python\n(.+?)\n```", page.read_text(),
                                                   re.S), start=1)]


@pytest.mark.parametrize("page, number, code", BLOCKS,
                         ids=[f"{page} block {number}" for page, number, _ in BLOCKS])
def test_documented_example_runs(page, number, code, monkeypatch):
    monkeypatch.chdir(PROJECT_ROOT)  # the examples use the shipped files' relative paths
    kinds = dict(MAP_KINDS)
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            exec(compile(code, f"{page} (block {number})", "exec"),
                 {"__name__": "documented_example"})
    finally:  # an example may register a map kind: the other tests see the built-in ones
        MAP_KINDS.clear()
        MAP_KINDS.update(kinds)


def test_the_documentation_has_its_examples():
    assert len(BLOCKS) >= 5 and any(page == "README.md" for page, _, _ in BLOCKS)


def test_the_readme_reads_in_five_minutes_and_its_links_lead_somewhere():
    """At most 200 lines; every relative link of the README and the manual names a file that
    exists."""
    assert len(PAGES[0].read_text().splitlines()) <= 200
    for page in PAGES:
        for target in re.findall(r"\]\((?!https?:|#)([^)#]+)", page.read_text()):
            assert (page.parent / target).exists(), f"{page.name}: no {target}"
