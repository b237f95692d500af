"""What is wrong with an input file, said so that the user can fix it."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, replace

from ..core.errors import InputError

_SHOWN = 25  # lines printed in a message; all the problems stay in DataFileError.problems
#: a column with this many problems of one kind gets one verdict (a unit mistake fails every
#: row alike: thousands of near-identical lines would bury the one fact, and other problems)
GROUPED_FROM = 4
#: the rows a verdict quotes
FIRST_ROWS = 3
_NUMBER = re.compile(r"[+-]?\d+(\.\d*)?([eE][+-]?\d+)?")


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a file.

    Attributes
    ----------
    file : str
        The file, as the user named it.
    line : int or None
        Line number in the file (1 is the header), or None for the file as a whole.
    column : str or None
        The column concerned, or None.
    value : str or None
        The offending text as found in the file, or None.
    expected : str
        What the file should have had instead.
    """

    file: str
    line: int | None
    column: str | None
    value: str | None
    expected: str

    def __str__(self) -> str:
        where = self.file
        if self.line is not None:
            where += f", line {self.line}"
        if self.column is not None:
            where += f", column '{self.column}'"
        if self.value is None:
            return f"{where}: expected {self.expected}"
        return f"{where}: got {self.value!r}, expected {self.expected}"

    def redacted(self, columns: Mapping[str, str]) -> "Problem":
        """This problem without the file's content, for a file the user did not name (a model
        file's ``cfd = ...`` did): never the value, nor a column name the schema lacks (the
        header is content too). A problem of the file as a whole or of its header keeps what was
        expected, which the readers phrase in the schema's terms; a row's problem says what its
        column allows (``columns``: name -> that description) instead, as the checks across
        rows quote other cells."""
        column = self.column if self.column in columns else None
        if self.column is None or self.line == 1:
            return replace(self, column=column, value=None)
        return replace(self, column=column, value=None,
                       expected=f"{columns[column]} (this cell is not, alone or against other "
                                "rows)" if column else "a valid row")


class DataFileError(InputError):
    """A file was rejected as a whole; ``problems`` lists every reason found.

    The message shows the first problems; the attribute holds them all so that a program can
    report each one.
    """

    def __init__(self, file: str, problems: list[Problem], kind: str = "data file",
                 note: str = ""):
        self.file = file
        self.kind = kind
        self.problems = list(problems)
        self.note = note
        super().__init__(self._message())

    def redacted(self, columns: Mapping[str, str], named_by: str = "another file"
                 ) -> "DataFileError":
        """The same rejection without quoting the file (:meth:`Problem.redacted`), for a file
        reached through ``named_by``: errors echo only what the user gave as data."""
        return DataFileError(self.file, [problem.redacted(columns) for problem in self.problems],
                             self.kind, note=f"(its values are not shown: the file was named by "
                                             f"{named_by}; `check-data {self.file}` shows them)")

    def _message(self) -> str:
        count = len(self.problems)
        noun = "problem" if count == 1 else "problems"
        head = f"{self.file}: rejected as {self.kind} ({count} {noun}):"
        shown = verdicts(self.problems)
        lines = [head, *(f"  - {text}" for text, _ in shown[:_SHOWN])]
        if len(shown) > _SHOWN:
            left = sum(size for _, size in shown[_SHOWN:])
            lines.append(f"  ... and {left} more of the same kinds")
        if self.note:
            lines.append(f"  {self.note}")
        return "\n".join(lines)


def verdicts(problems: list[Problem]) -> list[tuple[str, int]]:
    """The problems as printed lines, each with how many problems it stands for: a column's
    problems of one kind (the same expectation but for the numbers in it) become one verdict
    when there are :data:`GROUPED_FROM` or more, quoting the first rows and the count; the
    others stay one line each. Lines come in the order of each group's first problem."""
    groups: dict[tuple, list[Problem]] = {}
    for index, problem in enumerate(problems):
        if problem.column is None or problem.line is None:
            key = (index,)
        else:  # the kind of a row's problem: the part before any hint, numbers left out
            key = (problem.column, _NUMBER.sub("#", problem.expected.split("; ")[0]))
        groups.setdefault(key, []).append(problem)
    lines = []
    for members in groups.values():
        if len(members) < GROUPED_FROM:
            lines += [(str(problem), 1) for problem in members]
        else:
            lines.append((_verdict(members), len(members)))
    return lines


def _verdict(members: list[Problem]) -> str:
    """One line for many rows of one column alike: where, how many, the first values."""
    first = members[0]
    rows = ", ".join(str(problem.line) for problem in members[:FIRST_ROWS])
    values = [problem.value for problem in members[:FIRST_ROWS] if problem.value is not None]
    got = f"got {', '.join(repr(v) for v in values)}; " if values else ""
    return (f"{first.file}, column '{first.column}': {len(members)} rows rejected alike, "
            f"first on lines {rows}: {got}expected {first.expected}")
