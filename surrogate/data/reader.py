"""Reading a CSV file cell by cell against a schema, keeping the line number of every row.

The standard library's :mod:`csv` reader is used rather than pandas because it reports the line
number of each record exactly, which is what an engineer needs to fix a file.
"""

from __future__ import annotations

import csv
import difflib
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import DataFileError, Problem
from .schema import SCHEMAS, Column, FileSchema

_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_NON_FINITE = {"nan", "+nan", "-nan", "inf", "+inf", "-inf", "infinity", "+infinity", "-infinity"}
_SNIFF_BYTES = 8192


@dataclass(frozen=True)
class RawTable:
    """The text of a CSV file: its header, its data rows and the line number of each row."""

    file: str
    header: tuple[str, ...]
    rows: list[list[str]]
    lines: list[int]


def read_raw_table(path: str | Path) -> RawTable:
    """Read ``path`` as comma-separated UTF-8 text.

    Blank lines are skipped. A byte-order mark (as written by spreadsheet programs) is accepted.

    Raises
    ------
    DataFileError
        If the file cannot be read, is empty, is binary or not UTF-8, or is not comma-separated.
    """
    name = str(path)
    try:
        data = Path(path).read_bytes()
    except OSError as error:
        raise DataFileError(name, [Problem(name, None, None, None,
                                           f"a readable file ({error.strerror})")]) from None
    if not data.strip():
        raise DataFileError(name, [Problem(name, None, None, None,
                                           "a header line and at least one data row; "
                                           "the file is empty")])
    if b"\x00" in data[:_SNIFF_BYTES]:
        raise DataFileError(name, [Problem(name, None, None, None,
                                           "comma-separated text; this file is binary "
                                           "(a spreadsheet or archive?), not CSV")])
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        line = data[: error.start].count(b"\n") + 1
        raise DataFileError(name, [Problem(name, line, None, None,
                                           "UTF-8 text; found bytes that are not "
                                           "(export the file as CSV UTF-8)")]) from None

    markup = {"{": "JSON", "[": "JSON", "<": "XML or HTML"}.get(text.lstrip()[:1])
    if markup:
        raise DataFileError(name, [Problem(name, None, None, None,
                                           f"comma-separated text; this looks like {markup}, "
                                           "not a CSV file")])

    reader = csv.reader(io.StringIO(text, newline=""))
    header: tuple[str, ...] | None = None
    rows, lines = [], []
    try:
        for record in reader:
            if not any(cell.strip() for cell in record):
                continue
            if header is None:
                header = tuple(cell.strip() for cell in record)
                header_line = reader.line_num
                continue
            rows.append([cell.strip() for cell in record])
            lines.append(reader.line_num)
    except csv.Error as error:
        raise DataFileError(name, [Problem(name, reader.line_num, None, None,
                                           f"well-formed CSV ({error})")]) from None
    assert header is not None  # the file has non-blank content
    if len(header) == 1:
        raise DataFileError(name, [_single_column_problem(name, header_line, header[0])])
    return RawTable(name, header, rows, lines)


def _single_column_problem(name: str, line: int, first: str) -> Problem:
    for separator, word in ((";", "semicolons"), ("\t", "tabs")):
        if separator in first:
            return Problem(name, line, None, first[:60],
                           f"comma-separated columns; this header is separated by {word}")
    return Problem(name, line, None, first[:60],
                   "a CSV header with comma-separated column names; this is not a CSV file")


def detect_schema(table: RawTable) -> FileSchema:
    """The schema whose identifying columns the header carries.

    Raises
    ------
    DataFileError
        If the header matches neither schema.
    """
    header = set(table.header)
    scores = [(len(schema.identifying & header), len(set(schema.names) & header), schema)
              for schema in SCHEMAS]
    scores.sort(key=lambda score: score[:2], reverse=True)
    best_identifying, best_overlap, best = scores[0]
    if best_identifying == 0 and best_overlap < 3:
        expected = "; or ".join(f"{s.kind}: {', '.join(s.names)}" for s in SCHEMAS)
        raise DataFileError(table.file, [Problem(table.file, 1, None, ",".join(table.header)[:80],
                                                 f"the header of a {expected}")])
    return best


def parse_cells(table: RawTable, schema: FileSchema) -> tuple[dict[str, np.ndarray], list[Problem]]:
    """Check every cell of every row against ``schema``.

    Returns
    -------
    values : dict
        Column name -> array of the parsed values (float for numbers, object for text), with NaN
        or None where a cell was bad.
    problems : list of Problem
        Header problems first, then cell problems in file order.
    """
    problems = _header_problems(table, schema)
    position = {name: index for index, name in enumerate(table.header)}
    present = [column for column in schema.columns if column.name in position]
    values = {column.name: (np.full(len(table.rows), np.nan) if column.is_number
                            else np.full(len(table.rows), None, dtype=object))
              for column in present}

    for row_index, (row, line) in enumerate(zip(table.rows, table.lines)):
        if len(row) != len(table.header):
            problems.append(Problem(table.file, line, None, ",".join(row)[:80],
                                    f"{len(table.header)} comma-separated fields as in the "
                                    f"header, found {len(row)}"))
            continue
        for column in present:
            text = row[position[column.name]]
            parsed, expected = _parse_cell(text, column)
            if expected is not None:
                problems.append(Problem(table.file, line, column.name, text, expected))
            else:
                values[column.name][row_index] = parsed

    if not table.rows:
        problems.append(Problem(table.file, None, None, None,
                                "at least one data row below the header; found none"))
    return values, problems


def _header_problems(table: RawTable, schema: FileSchema) -> list[Problem]:
    problems = []
    seen = set()
    for name in table.header:
        if name in seen:
            problems.append(Problem(table.file, 1, name, name, "each column name once"))
        seen.add(name)
    for column in schema.columns:
        if column.name not in seen:
            problems.append(Problem(table.file, 1, column.name, None,
                                    f"a column '{column.name}' ({column.meaning}"
                                    f"{', in ' + column.unit if column.unit else ''}); "
                                    "it is missing from the header"))
    known = set(schema.names)
    for name in table.header:
        if name not in known and not schema.allow_extra:
            close = difflib.get_close_matches(name, schema.names, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            problems.append(Problem(table.file, 1, name, name,
                                    f"only the documented columns of a {schema.kind}{hint}: "
                                    f"{', '.join(schema.names)}"))
    return problems


def _parse_cell(text: str, column: Column) -> tuple[object, str | None]:
    """Parse one cell: (value, None) if valid, else (None, what was expected)."""
    if not column.is_number:
        if not text:
            return None, f"{column.describe_expected()}; the cell is empty"
        if column.choices and text not in column.choices:
            return None, column.describe_expected()
        return text, None
    if not text:
        return None, f"{column.describe_expected()}; the cell is empty"
    if text.lower() in _NON_FINITE:
        return None, f"a finite number ({column.describe_expected()})"
    if not _NUMBER.match(text):
        hint = "; use a decimal point, not a comma" if re.fullmatch(r"[+-]?\d+,\d+", text) else ""
        return None, f"a number ({column.describe_expected()}){hint}"
    value = float(text)
    if not math.isfinite(value):
        return None, f"a finite number ({column.describe_expected()})"
    if column.range is not None and not column.range.contains(value):
        return None, column.describe_expected() + column.range.unit_hint(value)
    return value, None
