"""What is wrong with an input file, said so that the user can fix it."""

from __future__ import annotations

from dataclasses import dataclass

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


class DataFileError(InputError):
    """A file was rejected as a whole; ``problems`` lists every reason found.

    The message shows the first problems; the attribute holds them all so that a program can
    report each one.
    """

    def __init__(self, file: str, problems: list[Problem], kind: str = "data file"):
        self.file = file
        self.kind = kind
        self.problems = list(problems)
        super().__init__(self._message())

    def _message(self) -> str:
        count = len(self.problems)
        noun = "problem" if count == 1 else "problems"
        head = f"{self.file}: rejected as {self.kind} ({count} {noun}):"
        lines = [head, *(f"  - {problem}" for problem in self.problems[:_SHOWN])]
        if count > _SHOWN:
            lines.append(f"  ... and {count - _SHOWN} more of the same kinds")
        return "\n".join(lines)
