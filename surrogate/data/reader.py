"""Reading a CSV file against a schema, keeping the line number of every row.

Two paths give the same values and the same problems:

* the **exact** path reads the file with the standard library's :mod:`csv` reader, which reports
  each record's line exactly (quoted fields may span lines), and checks cell by cell;
* the **columnar** path, for files without quotes (bench logs and CFD samples as benches and
  solvers write them), finds the lines with NumPy, reads the columns with pandas' C parser in
  chunks of :data:`CHUNK_ROWS` rows, checks whole columns at once and asks the cell-by-cell
  checker only about the cells that fail. A two-million-row log reads in seconds and in memory
  proportional to its numbers, not to Python objects per cell.

A file the columnar path cannot take as it is (a line of blanks or bare commas, a row with the
wrong number of fields) goes the exact way, which words those problems.

A ``;``-separated file (a spreadsheet's export where the comma is the decimal separator) is
turned into the comma-separated, decimal-point text both paths read, line for line, before
either sees it (:func:`_from_semicolons`).
"""

from __future__ import annotations

import csv
import difflib
import io
import math
import re
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from ..core.input_files import read_input, regular_file
from ..core.units import from_si, label, to_si
from .errors import DataFileError, Problem
from .schema import SCHEMAS, TEXT_MAX, Column, FileSchema

_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_NON_FINITE = {"nan", "+nan", "-nan", "inf", "+inf", "-inf", "infinity", "+infinity", "-infinity"}
_SNIFF_BYTES = 8192
#: rows the columnar path parses at a time: bounds the memory of the text being parsed
CHUNK_ROWS = 200_000
#: bytes that may appear in a number the columnar path accepts without a second look
_NUMBER_BYTES = np.frombuffer(b"0123456789.eE+-", dtype=np.uint8)
_NUMBER_CHARACTERS = set("0123456789.eE+- \t")
_UTF16_BOMS = (b"\xff\xfe", b"\xfe\xff")
#: a comma that is no decimal comma (not between two digits), in a ``;``-separated file
_OTHER_COMMA = re.compile(rb"(?<![0-9]),|,(?![0-9])")
_DECIMAL_COMMA = re.compile(rb"[0-9],[0-9]")
_DECIMAL_POINT = re.compile(rb"[0-9]\.[0-9]")
_DECIMAL_COMMA_NUMBER = re.compile(r"^[+-]?(\d+,\d*|,\d+)([eE][+-]?\d+)?$")


@dataclass(frozen=True)
class RawTable:
    """The text of a CSV file: its header, its data rows and the line number of each row.

    ``rows`` holds every row's cells (the exact path), or is None when ``body`` holds the data
    rows as CSV bytes for the columnar path (:func:`parse_cells`); ``lines`` has one line number
    per data row either way, and ``header_line`` is the header's.
    """

    file: str
    header: tuple[str, ...]
    rows: list[list[str]] | None
    lines: np.ndarray
    header_line: int = 1
    body: bytes | None = None  # the file's bytes, the data rows from ``body_start``
    body_start: int = 0
    spans: np.ndarray | None = None  # (2, rows): each data row's first and end byte in ``body``
    notes: tuple[str, ...] = ()  # what the reading did that the user should know of

    def __len__(self) -> int:
        return len(self.lines)

    def cell(self, row: int, column: int) -> str:
        """The text of one cell (a data row's position, a column's position in the header)."""
        if self.rows is not None:
            return self.rows[row][column]
        start, end = self.spans[:, row]
        return self.body[start:end].decode("utf-8").rstrip("\r").split(",")[column]


def read_raw_table(path: str | Path, progress: Callable[[str], None] | None = None, *,
                   columnar: bool = True) -> RawTable:
    """Read ``path`` as comma-separated UTF-8 text.

    Blank lines are skipped (line numbers stay those of the file). A byte-order mark (as written
    by spreadsheet programs) is accepted, and so is a ``;``-separated file with decimal commas
    or points (said in the table's ``notes``). ``progress`` is told how far the reading got.
    ``columnar=False`` keeps every row's cells (``rows``), for a caller that needs the text.

    Raises
    ------
    DataFileError
        If the file cannot be read, is empty, is binary, UTF-16 or otherwise not UTF-8, is
        neither comma- nor semicolon-separated, or mixes decimal commas and points.
    """
    name = str(path)
    size = regular_file(path, "a CSV file").st_size  # before a byte: /dev/zero, a FIFO
    if progress is not None:
        progress(f"reading {name} ({size / 1e6:.1f} MB)")
    data = read_input(path, "a CSV file", "table")
    if not data.strip():
        raise DataFileError(name, [Problem(name, None, None, None,
                                           "a header line and at least one data row; "
                                           "the file is empty")])
    if _looks_like_utf16(data[:_SNIFF_BYTES]):
        raise DataFileError(name, [Problem(name, None, None, None,
                                           "UTF-8 text; this file is UTF-16 (spreadsheet "
                                           "programs write it as 'Unicode text'): export it as "
                                           "CSV UTF-8")])
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

    notes = ()
    if _semicolon_separated(text):
        data, note = _from_semicolons(name, data, text)
        notes = (note,)
    table = None
    if columnar and b'"' not in data:
        del text  # the columnar path reads the bytes
        table = _columnar_table(name, data, 3 if data.startswith(b"\xef\xbb\xbf") else 0)
    if table is None:
        table = _exact_table(name, data.decode("utf-8-sig"))
    return replace(table, notes=notes) if notes else table


def _semicolon_separated(text: str) -> bool:
    """Whether the header (the first line with content) is separated by ``;`` and not by
    commas: a spreadsheet's export in a locale whose decimal separator is the comma."""
    for line in io.StringIO(text):
        if line.strip(" \t\r\n,;"):
            return ";" in line and "," not in line
    return False


def _from_semicolons(name: str, data: bytes, text: str) -> tuple[bytes, str]:
    """The bytes of a ``;``-separated file as comma-separated text with decimal points, line for
    line (so every line number stays the file's), and the note that says so.

    When every comma stands between two digits, each is a decimal comma and the bytes are
    translated at once; otherwise (a quoted cell, a comma in a text cell) the :mod:`csv` reader
    splits the rows and only cells that read as decimal-comma numbers are changed.

    Raises
    ------
    DataFileError
        If the file writes numbers with both decimal commas and decimal points: a point could be
        a thousands separator, and guessing which would change values silently.
    """
    commas = _DECIMAL_COMMA.search(data)
    if commas:
        point = _DECIMAL_POINT.search(data)
        if point:
            line = data[: point.start()].count(b"\n") + 1
            first = data[: commas.start()].count(b"\n") + 1
            row = text.split("\n")[line - 1].split(";")
            cell = next((c.strip() for c in row if _DECIMAL_POINT.search(c.encode())), None)
            raise DataFileError(name, [Problem(
                name, line, None, cell,
                f"one decimal separator throughout: this ';'-separated file writes decimal "
                f"commas (line {first}) and a decimal point here (a thousands separator?); "
                "export it again with one of them")])
    how = "decimal commas" if commas else "decimal points"
    note = f"{name}: read as ';'-separated with {how} (a spreadsheet's export)"
    if b'"' not in data and not _OTHER_COMMA.search(data):
        return data.translate(bytes.maketrans(b",;", b".,")), note
    out = io.StringIO(newline="")
    writer = csv.writer(out, lineterminator="\n")
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=";")
    written = 1  # lines written so far + 1: blank lines keep every record on its file line
    try:
        for record in reader:
            out.write("\n" * (reader.line_num - (written + record_lines(record)) + 1))
            writer.writerow([cell.replace(",", ".") if _DECIMAL_COMMA_NUMBER.match(cell.strip())
                             else cell for cell in record])
            written = reader.line_num + 1
    except csv.Error as error:
        raise DataFileError(name, [Problem(name, reader.line_num, None, None,
                                           f"well-formed ';'-separated CSV ({error})")]) from None
    return out.getvalue().encode("utf-8"), note


def record_lines(record: list[str]) -> int:
    """How many lines a record spans (its quoted cells may hold line breaks)."""
    return 1 + sum(cell.count("\n") for cell in record)


def _looks_like_utf16(head: bytes) -> bool:
    """A byte-order mark of UTF-16, or text that reads as UTF-16 with separators in it."""
    if head.startswith(_UTF16_BOMS):
        return True
    head = head[: len(head) // 2 * 2]
    for encoding in ("utf-16-le", "utf-16-be"):
        try:
            text = head.decode(encoding)
        except UnicodeDecodeError:
            continue
        printable = sum(character.isprintable() or character in "\r\n\t" for character in text)
        if text and printable > 0.95 * len(text) and any(c in text for c in ",;\t"):
            return True
    return False


def _exact_table(name: str, text: str) -> RawTable:
    """Every record through the :mod:`csv` reader, with its exact line."""
    reader = csv.reader(io.StringIO(text, newline=""))
    header: tuple[str, ...] | None = None
    header_line = 1
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
    return RawTable(name, header, rows, np.asarray(lines, dtype=np.int64), header_line)


def _columnar_table(name: str, data: bytes, offset: int) -> RawTable | None:
    """The table for the columnar path (the file's bytes ``data``, its text from ``offset``, past
    a byte-order mark), or None when the file needs the exact path: a line of blanks or bare
    commas that is not empty (the exact path skips it as the csv reader sees it), or a row whose
    number of fields is not the header's. Lines are found a block of bytes at a time, so the
    memory this takes is a few bytes per line, not per byte."""
    starts, ends, commas = [], [], []
    block = 1 << 24
    position = offset
    while position < len(data):
        window = np.frombuffer(data, dtype=np.uint8, count=min(block, len(data) - position),
                               offset=position)
        newlines = np.flatnonzero(window == ord("\n"))
        if position + len(window) == len(data):  # the last block: its last line may lack "\n"
            stop = len(window)
            line_ends = newlines if len(newlines) and newlines[-1] == stop - 1 \
                else np.r_[newlines, stop]
        elif len(newlines):  # the block ends at its last line's end
            stop = int(newlines[-1]) + 1
            line_ends = newlines
        else:
            return None  # a line longer than a block: no bench writes one
        line_starts = np.r_[0, line_ends[:-1] + 1]
        comma_at = np.flatnonzero(window[:stop] == ord(","))
        commas.append(np.searchsorted(comma_at, line_ends) - np.searchsorted(comma_at,
                                                                              line_starts))
        starts.append(line_starts + position)
        ends.append(line_ends + position)
        position += stop
    starts, ends, commas = np.concatenate(starts), np.concatenate(ends), np.concatenate(commas)
    view = np.frombuffer(data, dtype=np.uint8)
    carriage = (ends > starts) & (view[np.maximum(ends - 1, 0)] == ord("\r"))
    length = ends - starts - carriage
    # lines short enough to be blank are looked at one by one; data rows are longer than that
    short = np.flatnonzero(length <= commas + 8)
    blank = np.zeros(len(starts), dtype=bool)
    for index in short:
        blank[index] = not data[starts[index]:ends[index]].strip(b" \t\r,")
    filled = np.flatnonzero(~blank)
    if not len(filled):
        return None
    first = int(filled[0])
    header_text = data[starts[first]:ends[first]].decode("utf-8").rstrip("\r")
    header = tuple(cell.strip() for cell in header_text.split(","))
    if len(header) == 1:
        raise DataFileError(name, [_single_column_problem(name, first + 1, header[0])])
    if (blank[first:] & (length[first:] > 0)).any():
        return None
    body = filled[filled > first]
    if (commas[body] != len(header) - 1).any():
        return None
    return RawTable(name, header, None, body.astype(np.int64) + 1, first + 1, data,
                    int(ends[first]) + 1, np.vstack([starts[body], ends[body]]))


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
        raise DataFileError(table.file, [Problem(table.file, table.header_line, None,
                                                 ",".join(table.header)[:80],
                                                 f"the header of a {expected}")])
    return best


def parse_cells(table: RawTable, schema: FileSchema,
                progress: Callable[[str], None] | None = None
                ) -> tuple[dict[str, np.ndarray], list[Problem], list[str]]:
    """Check every cell of every row against ``schema``.

    A column the header gives in another unit (``p_L_psi`` for ``p_L_bar``,
    :meth:`Column.other_names`) is checked as written, in its own unit, then converted to the
    schema's unit; columns the schema lacks are left unread where it allows them.

    Returns
    -------
    values : dict
        Schema column name -> array of the parsed values in the schema's file unit (float for
        numbers, object for text), with NaN or None where a cell was bad.
    problems : list of Problem
        Header problems first, then cell problems in file order.
    notes : list of str
        What the reading did that the user should know of: columns ignored, columns converted,
        the separators read (one line each).
    """
    read_as, problems, notes = resolve_header(table, schema)
    notes = [*table.notes, *notes]
    position = {name: index for index, name in enumerate(table.header)}
    present = list(read_as.values())  # as the file has them: names and units
    values = {column.name: (np.full(len(table), np.nan) if column.is_number
                            else np.full(len(table), None, dtype=object))
              for column in present}
    if table.rows is None:
        try:
            problems += _parse_columns(table, present, position, values, progress)
        except _RowsDiffer:  # pandas saw other rows than the line scan: take the exact path
            exact = _exact_table(table.file, table.body.decode("utf-8-sig"))
            return parse_cells(replace(exact, notes=table.notes), schema, progress)
    else:
        for row_index, (row, line) in enumerate(zip(table.rows, table.lines)):
            if len(row) != len(table.header):
                problems.append(Problem(table.file, int(line), None, ",".join(row)[:80],
                                        f"{len(table.header)} comma-separated fields as in the "
                                        f"header, found {len(row)}"))
                continue
            for column in present:
                text = row[position[column.name]]
                parsed, expected = _parse_cell(text, column)
                if expected is not None:
                    problems.append(Problem(table.file, int(line), column.name, text, expected))
                else:
                    values[column.name][row_index] = parsed

    if not len(table):
        problems.append(Problem(table.file, None, None, None,
                                "at least one data row below the header; found none"))
    for name, column in read_as.items():  # other units to the schema's, through units.py
        if column.name != name:
            values[name] = from_si(to_si(values.pop(column.name), column.unit),
                                   schema.column(name).unit)
    return values, problems, notes


def resolve_header(table: RawTable, schema: FileSchema
                   ) -> tuple[dict[str, Column], list[Problem], list[str]]:
    """How the header gives each column of ``schema``: schema name -> the column as the file has
    it (its own name and unit when it is in another unit), the header's problems (a column
    twice, missing, or unknown where the schema allows no other) and the notes on columns
    converted and ignored."""
    problems = []
    seen = set()
    line = table.header_line
    for name in table.header:
        if name in seen:
            problems.append(Problem(table.file, line, name, name, "each column name once"))
        seen.add(name)
    read_as: dict[str, Column] = {}
    converted = []
    for column in schema.columns:
        given = [name for name in (column.name, *column.other_names()) if name in seen]
        if len(given) > 1:
            problems.append(Problem(table.file, line, given[1], given[1],
                                    f"one column for the {column.meaning}; the header has "
                                    f"{' and '.join(repr(g) for g in given)}"))
        if given and given[0] != column.name:
            unit = column.other_names()[given[0]]
            read_as[column.name] = column.in_unit(given[0], unit)
            converted.append(f"{given[0]} from {label(unit)}")
        elif given:
            read_as[column.name] = column
    known = {name for column in schema.columns for name in (column.name, *column.other_names())}
    extra = [name for name in dict.fromkeys(table.header) if name not in known]
    for column in schema.columns:
        if column.name not in read_as:
            close = difflib.get_close_matches(column.name, extra, n=1) if schema.allow_extra \
                else []
            hint = f" (is '{close[0]}' it, misspelt?)" if close else ""
            others = "".join(f" or '{name}' (in {label(unit)})"
                             for name, unit in column.other_names().items())
            problems.append(Problem(table.file, line, column.name, None,
                                    f"a column '{column.name}' ({column.meaning}"
                                    f"{', in ' + column.unit if column.unit else ''}){others}; "
                                    f"it is missing from the header{hint}"))
    notes = []
    if converted:
        notes.append(f"{table.file}: converted to the documented units: {', '.join(converted)}")
    if extra and schema.allow_extra:
        noun = "column" if len(extra) == 1 else "columns"
        notes.append(f"{table.file}: {len(extra)} {noun} not in the {schema.kind} schema kept "
                     f"in the file and ignored: {', '.join(extra)}")
    elif extra and not schema.allow_extra:
        for name in extra:
            close = difflib.get_close_matches(name, schema.names, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            problems.append(Problem(table.file, line, name, name,
                                    f"only the documented columns of a {schema.kind}{hint}: "
                                    f"{', '.join(schema.names)}"))
    return read_as, problems, notes


def _parse_columns(table: RawTable, present: list[Column], position: dict[str, int],
                   values: dict[str, np.ndarray],
                   progress: Callable[[str], None] | None) -> list[Problem]:
    """The columnar path of :func:`parse_cells`: whole columns parsed and checked at once, the
    cell-by-cell checker consulted for the cells that fail, problems in file order.

    Number columns are first read as numbers by the C parser, which makes no Python object per
    cell; a cell it cannot read at all (text where a number belongs) sends the file through a
    second reading as text, cell by cell where needed."""
    stage = None if progress is None or not hasattr(progress, "stage") \
        or len(table) < CHUNK_ROWS else progress.stage(f"checking {table.file}", len(table),
                                                       "rows")
    try:
        return _read_columns(table, present, position, values, stage, typed=True)
    except ValueError:  # a cell that is no number at all
        for column in present:
            values[column.name][:] = np.nan if column.is_number else None
        return _read_columns(table, present, position, values, stage, typed=False)


def _read_columns(table, present, position, values, stage, *, typed: bool) -> list[Problem]:
    found: list[tuple[int, int, Problem]] = []  # (row, column order, problem)
    stream = io.BytesIO(table.body)
    stream.seek(table.body_start)
    used = sorted({position[column.name] for column in present})
    types = {position[column.name]: (np.float64 if typed and column.is_number else str)
             for column in present}
    chunks = pd.read_csv(stream, header=None, names=range(len(table.header)), usecols=used,
                         dtype=types, na_filter=False, skip_blank_lines=True, engine="c",
                         index_col=False, chunksize=CHUNK_ROWS)
    start = 0
    for chunk in chunks:
        stop = start + len(chunk)
        if stop > len(table):
            raise _RowsDiffer
        for order, column in enumerate(present):
            index = position[column.name]
            target = values[column.name]
            if typed and column.is_number:
                bad = _typed_number_column(chunk[index].to_numpy(), column, target, start)
                texts = None
            else:
                texts = chunk[index].to_numpy(dtype=object)
                bad = (_number_column(texts, column, target, start) if column.is_number
                       else _text_column(texts, column, target, start))
            for row in bad:
                text = (texts[row] if texts is not None
                        else table.cell(start + row, index)).strip()
                parsed, expected = _parse_cell(text, column)
                if expected is None:  # the second look accepts it after all
                    target[start + row] = parsed
                    continue
                found.append((start + row, order, Problem(
                    table.file, int(table.lines[start + row]), column.name, text, expected)))
        start = stop
        if stage is not None:
            stage(stop)
    if start != len(table):
        raise _RowsDiffer
    found.sort(key=lambda item: (item[0], item[1]))
    return [problem for *_, problem in found]


def _typed_number_column(numbers: np.ndarray, column: Column, target: np.ndarray,
                         start: int) -> np.ndarray:
    """A chunk of a number column the C parser read as numbers, into ``target[start:]``; return
    the rows that need the cell-by-cell checker: not finite, or out of range."""
    good = np.isfinite(numbers)
    if column.range is not None:
        with np.errstate(invalid="ignore"):
            good &= (numbers >= column.range.low) & (numbers <= column.range.high)
    target[start:start + len(numbers)] = np.where(good, numbers, np.nan)
    return np.flatnonzero(~good)


class _RowsDiffer(Exception):
    """The columnar parser found another number of rows than the line scan."""


def _number_column(texts: np.ndarray, column: Column, target: np.ndarray,
                   start: int) -> np.ndarray:
    """Parse a chunk of a number column into ``target[start:]``; return the rows (in the chunk)
    whose cells need the cell-by-cell checker: not plain digits, not finite, out of range."""
    try:  # fixed-width bytes: every character of the chunk checked as one array
        encoded = texts.astype("S")
        width = max(encoded.dtype.itemsize, 1)
        characters = np.frombuffer(encoded.tobytes(), dtype=np.uint8).reshape(len(texts), width)
        odd = ~(np.isin(characters, _NUMBER_BYTES) | np.isin(characters, [0, 32, 9])).all(axis=1)
    except UnicodeEncodeError:  # a character beyond ASCII somewhere: the cells that hold one
        odd = np.array([not text.isascii() or not set(text) <= _NUMBER_CHARACTERS
                        for text in texts], dtype=bool)
    numbers = pd.to_numeric(pd.Series(texts), errors="coerce").to_numpy(dtype=float)
    good = np.isfinite(numbers) & ~odd
    if column.range is not None:
        with np.errstate(invalid="ignore"):
            good &= (numbers >= column.range.low) & (numbers <= column.range.high)
    target[start:start + len(texts)] = np.where(good, numbers, np.nan)
    return np.flatnonzero(~good)


def _text_column(texts: np.ndarray, column: Column, target: np.ndarray, start: int
                 ) -> np.ndarray:
    """Check a chunk of a text column, each distinct value once, into ``target[start:]``;
    return the rows whose cells the cell-by-cell checker must word."""
    distinct, inverse = np.unique(texts, return_inverse=True)
    parsed = [_parse_cell(text.strip(), column) for text in distinct]
    accepted = np.array([expected is None for _, expected in parsed], dtype=bool)
    clean = np.array([value for value, _ in parsed], dtype=object)
    rows = np.arange(len(texts))
    ok = accepted[inverse]
    target[start + rows[ok]] = clean[inverse[ok]]
    return rows[~ok]


def _parse_cell(text: str, column: Column) -> tuple[object, str | None]:
    """Parse one cell: (value, None) if valid, else (None, what was expected)."""
    if not column.is_number:
        if not text:
            return None, f"{column.describe_expected()}; the cell is empty"
        if len(text) > TEXT_MAX or not text.isprintable():
            return None, (f"{column.describe_expected()}; the cell holds control characters "
                          "or is too long")
        if text in column.aliases:
            return column.aliases[text], None
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
