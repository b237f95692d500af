"""Loaders: a CSV in the documented schema in, a validated table in SI units out.

A file is accepted whole or rejected whole. Every problem found is reported together, each with
the file, the line, the column, the value and what was expected (see :mod:`.errors`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..fluid import FluidState
from ..units import to_si
from .errors import DataFileError, Problem
from .reader import RawTable, detect_schema, parse_cells, read_raw_table
from .schema import BENCH_SCHEMA, CFD_SCHEMA, FileSchema

Values = dict[str, np.ndarray]


@dataclass(frozen=True)
class CfdSamples:
    """Validated CFD samples, SI inside.

    ``frame`` columns: ``case``, ``oil``, ``temperature`` [K], ``nu`` [m^2/s], ``rho`` [kg/m^3],
    ``u`` [m], ``q`` [m^3/s], ``p_B`` [Pa], ``p_L`` [Pa], ``f_sim`` [N], and ``line``, the line of
    each sample in its file.
    """

    frame: pd.DataFrame
    source: str

    def __len__(self) -> int:
        return len(self.frame)

    def fluid_state(self) -> FluidState:
        """ν and ρ of every sample, as the CFD run used them."""
        return FluidState(self.frame["nu"].to_numpy(), self.frame["rho"].to_numpy())

    def subset(self, mask) -> "CfdSamples":
        """The samples where ``mask`` (boolean array or pandas index) holds."""
        return CfdSamples(self.frame.loc[mask].reset_index(drop=True), self.source)


@dataclass(frozen=True)
class BenchRun:
    """One ramp test of a bench log, in time order, SI inside (see :class:`BenchLog`)."""

    run: str
    frame: pd.DataFrame

    def __len__(self) -> int:
        return len(self.frame)

    @property
    def temperature(self) -> float:
        """Mean oil temperature of the run [K]."""
        return float(self.frame["temperature"].mean())

    @property
    def p_Pe_nominal(self) -> float:
        """Set point of p_Pe = p_P - p_B [Pa]."""
        return float(self.frame["p_Pe_nominal"].iloc[0])


@dataclass(frozen=True)
class BenchLog:
    """A validated bench log, SI inside.

    ``frame`` columns: ``run``, ``time`` [s], ``temperature`` [K], ``p_Pe_nominal`` [Pa], ``q``
    [m^3/s], ``p_L``, ``p_B``, ``p_P`` [Pa], ``direction`` (``"up"`` or ``"down"``) and ``line``.
    """

    frame: pd.DataFrame
    source: str

    def __len__(self) -> int:
        return len(self.frame)

    @property
    def run_ids(self) -> list[str]:
        """Run ids in the order they first appear in the file."""
        return list(dict.fromkeys(self.frame["run"]))

    def runs(self) -> list[BenchRun]:
        """Every run, in file order."""
        groups = dict(tuple(self.frame.groupby("run", sort=False)))
        return [BenchRun(run, groups[run].reset_index(drop=True)) for run in self.run_ids]

    def take(self, rows) -> "BenchLog":
        """The log of these rows (positions), e.g. one run's, for a replay of that run alone."""
        return BenchLog(self.frame.iloc[rows].reset_index(drop=True), self.source)

    def run(self, run_id: str) -> BenchRun:
        """One run by its id."""
        frame = self.frame[self.frame["run"] == run_id]
        if frame.empty:
            raise KeyError(f"{self.source}: no run {run_id!r}; runs: {', '.join(self.run_ids)}")
        return BenchRun(run_id, frame.reset_index(drop=True))


def load_cfd_samples(path: str | Path) -> CfdSamples:
    """Load and validate a CFD-sample file (schema: ``cfd_samples/README.md``).

    Raises
    ------
    DataFileError
        With every problem found: file, line, column, value and what was expected.
    """
    frame = _load(path, CFD_SCHEMA, _check_cfd_rows)
    return CfdSamples(frame, str(path))


def load_bench_log(path: str | Path) -> BenchLog:
    """Load and validate a bench log (schema: ``measurements/README.md``).

    Raises
    ------
    DataFileError
        With every problem found: file, line, column, value and what was expected.
    """
    frame = _load(path, BENCH_SCHEMA, _check_bench_runs)
    return BenchLog(frame, str(path))


def load_any(path: str | Path) -> CfdSamples | BenchLog:
    """Load a file of either kind, recognised by its header."""
    table = read_raw_table(path)
    schema = detect_schema(table)
    if schema is CFD_SCHEMA:
        return CfdSamples(_validate(table, CFD_SCHEMA, _check_cfd_rows), str(path))
    return BenchLog(_validate(table, BENCH_SCHEMA, _check_bench_runs), str(path))


def _load(path, schema: FileSchema, check: Callable) -> pd.DataFrame:
    table = read_raw_table(path)
    detected = detect_schema_or_none(table)
    if detected is not None and detected is not schema:
        raise DataFileError(table.file, [Problem(table.file, 1, None, None,
                                                 f"a {schema.kind}; this header is that of a "
                                                 f"{detected.kind}")], schema.kind)
    return _validate(table, schema, check)


def detect_schema_or_none(table: RawTable) -> FileSchema | None:
    try:
        return detect_schema(table)
    except DataFileError:
        return None


def _validate(table: RawTable, schema: FileSchema, check: Callable) -> pd.DataFrame:
    values, problems = parse_cells(table, schema)
    lines = np.asarray(table.lines, dtype=int)
    problems += check(table.file, values, lines)
    if problems:
        raise DataFileError(table.file, _in_file_order(problems), schema.kind)
    frame = pd.DataFrame({
        column.si_name: (to_si(values[column.name], column.unit) if column.is_number
                         else values[column.name].astype(str))
        for column in schema.columns})
    frame["line"] = lines
    return frame


def _in_file_order(problems: list[Problem]) -> list[Problem]:
    return sorted(problems, key=lambda p: (p.line is None, p.line or 0))


def _check_cfd_rows(file: str, values: Values, lines: np.ndarray) -> list[Problem]:
    problems = []
    if "p_L_bar" in values and "p_B_bar" in values:
        p_L, p_B = values["p_L_bar"], values["p_B_bar"]
        for i in np.flatnonzero(p_L < p_B):  # NaN (a bad cell, reported already) compares False
            problems.append(Problem(file, int(lines[i]), "p_L_bar", f"{p_L[i]:g}",
                                    f"load pressure >= back pressure p_B_bar = {p_B[i]:g} bar "
                                    "(flow runs from the load port to the back port)"))
    if "case" in values:
        first_line: dict[str, int] = {}
        for case, line in zip(values["case"], lines):
            if case is None:
                continue
            if case in first_line:
                problems.append(Problem(file, int(line), "case", case,
                                        f"a unique case id; {case!r} is already on line "
                                        f"{first_line[case]}"))
            else:
                first_line[case] = int(line)
    return problems


def _check_bench_runs(file: str, values: Values, lines: np.ndarray) -> list[Problem]:
    if "run" not in values:
        return []
    problems = []
    runs = values["run"]
    for run in dict.fromkeys(r for r in runs if r is not None):
        rows = np.flatnonzero(runs == run)
        if "time_s" in values:
            time = values["time_s"][rows]
            valid = ~np.isnan(time)
            t, at = time[valid], rows[valid]
            for k in np.flatnonzero(np.diff(t) <= 0):
                problems.append(Problem(file, int(lines[at[k + 1]]), "time_s", f"{t[k + 1]:g}",
                                        f"time increasing within run {run!r}, i.e. > {t[k]:g} s "
                                        f"(line {lines[at[k]]})"))
        if "p_Pe_nominal_bar" in values:
            set_points = values["p_Pe_nominal_bar"][rows]
            valid = ~np.isnan(set_points)
            if valid.any():
                first = set_points[valid][0]
                for k in np.flatnonzero(valid & (set_points != first)):
                    problems.append(Problem(file, int(lines[rows[k]]), "p_Pe_nominal_bar",
                                            f"{set_points[k]:g}",
                                            f"one set point per run: run {run!r} started at "
                                            f"{first:g} bar"))
    return problems
