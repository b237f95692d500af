"""The README's Python examples run as written (a README whose code fails teaches nothing)."""

from __future__ import annotations

import contextlib
import io
import re

import pytest

from surrogate.maps.registry import MAP_KINDS
from surrogate.paths import PROJECT_ROOT

BLOCKS = re.findall(r"```python\n(.+?)\n```", (PROJECT_ROOT / "README.md").read_text(), re.S)


@pytest.mark.parametrize("code", BLOCKS, ids=[f"block {i + 1}" for i in range(len(BLOCKS))])
def test_readme_example_runs(code, monkeypatch):
    monkeypatch.chdir(PROJECT_ROOT)  # the examples use the shipped files' relative paths
    kinds = dict(MAP_KINDS)
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            exec(compile(code, "README.md", "exec"), {"__name__": "readme_example"})
    finally:  # an example may register a map kind: the other tests see the built-in ones
        MAP_KINDS.clear()
        MAP_KINDS.update(kinds)


def test_the_readme_has_its_examples():
    assert len(BLOCKS) >= 5
