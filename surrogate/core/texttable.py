"""Plain-text tables for a terminal whose columns never run into each other.

Each column is as wide as its widest cell (heading included), and columns are separated by at
least two spaces, so that a wide number (a 1,000-bar residual, a run id of twenty characters)
widens its column instead of merging with the next one. A value that is not measured (NaN) is
shown as words, not as ``nan``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

#: what a cell shows for a number that is not there (NaN)
MISSING = "–"


def cell(value, spec: str = "", missing: str = MISSING) -> str:
    """``value`` formatted with ``spec`` (a format spec such as ``".3f"``), ``missing`` for a
    NaN or None."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return missing
    try:
        if math.isnan(float(value)):
            return missing
    except (TypeError, ValueError):
        pass
    return format(value, spec)


def text_table(headings: Sequence[str], rows: Sequence[Sequence[str]], *,
               left: Sequence[int] = (0,), indent: str = "  ") -> list[str]:
    """The lines of a table: ``rows`` of already formatted cells under ``headings``, numbers
    right-aligned and the columns in ``left`` (indices) left-aligned, every column as wide as
    its widest cell and two spaces apart."""
    widths = [max([len(heading), *(len(row[index]) for row in rows)])
              for index, heading in enumerate(headings)]

    def line(cells: Sequence[str]) -> str:
        return indent + "  ".join(text.ljust(width) if index in left else text.rjust(width)
                                  for index, (text, width) in enumerate(zip(cells, widths))
                                  ).rstrip()

    return [line(headings), *(line(row) for row in rows)]
