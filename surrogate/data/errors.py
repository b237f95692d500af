"""What is wrong with an input file, said so that the user can fix it."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

from ..errors import InputError

_SHOWN = 25  # problems printed in a message; all of them stay in DataFileError.problems


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
        lines = [head, *(f"  - {problem}" for problem in self.problems[:_SHOWN])]
        if count > _SHOWN:
            lines.append(f"  ... and {count - _SHOWN} more of the same kinds")
        if self.note:
            lines.append(f"  {self.note}")
        return "\n".join(lines)
