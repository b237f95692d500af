"""Loaders: a CSV in the documented schema in, a validated table in SI units out.

A file is accepted whole or rejected whole. Every problem found is reported together, each with
the file, the line, the column, the value and what was expected (see :mod:`.errors`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
import pandas as pd

from ..fluid import FluidState
from ..limits import PRESSURE_NOISE_BAR
from ..core.memory import release_freed
from ..core.units import to_si
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
    notes: tuple[str, ...] = field(default=(), compare=False)  # what the reading did

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
    ``notes`` says what reading the file did that its user should know of (columns ignored or
    converted, separators), one line each.
    """

    frame: pd.DataFrame
    source: str
    notes: tuple[str, ...] = field(default=(), compare=False)

    def __len__(self) -> int:
        return len(self.frame)

    @cached_property
    def sampling_interval(self) -> float:
        """The median interval between consecutive samples of a run [s] (NaN for a log
        without two timed samples in a run). Read once per log: every replay of the log asks
        for it (:func:`surrogate.fitting.residuals.state_smoothing_samples`), and reading the
        run labels out of pandas' text column takes longer than the median."""
        time, run = self.frame["time"].to_numpy(float), self.frame["run"].to_numpy()
        steps = np.diff(time)[run[1:] == run[:-1]]
        steps = steps[~np.isnan(steps)]  # as pandas' median skips them
        return float(np.median(steps)) if len(steps) else float("nan")

    @property
    def run_ids(self) -> list[str]:
        """Run ids in the order they first appear in the file."""
        # through a list: iterating pandas' text column costs ten times as much
        return list(dict.fromkeys(self.frame["run"].to_numpy().tolist()))

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


def load_cfd_samples(path: str | Path, *, named_by: str | None = None) -> CfdSamples:
    """Load and validate a CFD-sample file (schema: ``cfd_samples/README.md``).

    ``named_by``: the file the path came from (a model file), when the user did not name the
    file itself; its errors then quote nothing of it (:meth:`DataFileError.redacted`).

    Raises
    ------
    DataFileError
        With every problem found: file, line, column, value and what was expected.
    """
    try:
        frame, notes = _load(path, CFD_SCHEMA, _check_cfd_rows)
    except DataFileError as error:
        if named_by is None:
            raise
        raise error.redacted({column.name: column.describe_expected()
                              for column in CFD_SCHEMA.columns}, named_by) from None
    return CfdSamples(frame, str(path), tuple(notes))


def load_bench_log(path: str | Path, progress: Callable[[str], None] | None = None
                   ) -> BenchLog:
    """Load and validate a bench log (schema: ``measurements/README.md``); ``progress`` is
    told how far the reading and checking got, for big logs, and the log's notes (columns
    ignored or converted from other units, a ``;``-separated file), one line each.

    Raises
    ------
    DataFileError
        With every problem found: file, line, column, value and what was expected.
    """
    frame, notes = _load(path, BENCH_SCHEMA, _check_bench_runs, progress)
    return BenchLog(frame, str(path), tuple(notes))


def load_any(path: str | Path, progress: Callable[[str], None] | None = None
             ) -> CfdSamples | BenchLog:
    """Load a file of either kind, recognised by its header (``progress``: told how far the
    reading and checking got, for big files)."""
    table = read_raw_table(path, progress)
    schema = detect_schema(table)
    parsed = _parse(table, schema, progress)
    del table  # the file's bytes: the values are all that is needed from here
    if schema is CFD_SCHEMA:
        return CfdSamples(*_validated(parsed, CFD_SCHEMA, _check_cfd_rows, progress), str(path))
    frame, notes = _validated(parsed, BENCH_SCHEMA, _check_bench_runs, progress)
    return BenchLog(frame, str(path), notes)


def _load(path, schema: FileSchema, check: Callable,
          progress: Callable[[str], None] | None = None) -> tuple[pd.DataFrame, tuple[str, ...]]:
    table = read_raw_table(path, progress)
    detected = detect_schema_or_none(table)
    if detected is not None and detected is not schema:
        raise DataFileError(table.file, [Problem(table.file, table.header_line, None, None,
                                                 f"a {schema.kind}; this header is that of a "
                                                 f"{detected.kind}")], schema.kind)
    parsed = _parse(table, schema, progress)
    del table
    frame, notes = _validated(parsed, schema, check, progress)
    return frame, notes


def _validated(parsed, schema: FileSchema, check: Callable,
               progress: Callable[[str], None] | None) -> tuple[pd.DataFrame, tuple[str, ...]]:
    """The SI frame of a parsed file and its notes, told to ``progress`` once it is accepted."""
    *cells, notes, renamed = parsed
    frame = _validate(*cells, schema, check, renamed)
    if progress is not None:
        for note in notes:
            progress(note)
    return frame, tuple(notes)


def detect_schema_or_none(table: RawTable) -> FileSchema | None:
    try:
        return detect_schema(table)
    except DataFileError:
        return None


def _parse(table: RawTable, schema: FileSchema, progress: Callable[[str], None] | None):
    """(file, values, problems, line of each row, notes, {schema name: the file's name of the
    columns given in another unit}) of the table's cells against ``schema``."""
    values, problems, notes = parse_cells(table, schema, progress)
    renamed = {column.name: name for column in schema.columns
               for name in column.other_names() if name in table.header}
    return table.file, values, problems, np.asarray(table.lines, dtype=int), notes, renamed


def _validate(file: str, values: Values, problems: list[Problem], lines: np.ndarray,
              schema: FileSchema, check: Callable, renamed: dict[str, str] | None = None
              ) -> pd.DataFrame:
    problems += [_as_named(problem, renamed, schema) for problem in check(file, values, lines)]
    if problems:
        raise DataFileError(file, _in_file_order(problems), schema.kind)
    columns = {}
    for column in schema.columns:  # each file column given up as its SI column is made
        raw = values.pop(column.name)
        # text cells are str already (shared between equal cells): no copy per cell
        columns[column.si_name] = to_si(raw, column.unit) if column.is_number else raw
    frame = pd.DataFrame(columns, copy=False)
    frame["line"] = lines
    release_freed(len(frame))
    return frame


def _as_named(problem: Problem, renamed: dict[str, str] | None, schema: FileSchema) -> Problem:
    """A problem of the checks across rows, which see every column in the schema's unit, named
    by the file's column when the file gave it in another unit (the value, converted, says so)."""
    if not renamed or problem.column not in renamed:
        return problem
    unit = schema.column(problem.column).unit
    value = problem.value if problem.value is None else f"{problem.value} {unit}"
    return Problem(problem.file, problem.line, renamed[problem.column], value,
                   f"{problem.expected} (the column's values converted to {unit})")


def _in_file_order(problems: list[Problem]) -> list[Problem]:
    return sorted(problems, key=lambda p: (p.line is None, p.line or 0))


#: [-] rows of one oil at one temperature must agree on ν and ρ to this (rounding in the file)
FLUID_TOLERANCE = 0.005
#: a run's p_P − p_B must sit within this of its set point, as a fraction plus [bar]: regulated
#: benches hold it within a few bar; the shipped log's runs have medians within 0.04 bar
SET_POINT_TOLERANCE = (0.10, 2.0)
#: one sample's p_P − p_B may stray further while the regulator catches up: fraction, [bar]
SAMPLE_SET_POINT_TOLERANCE = (0.25, 5.0)
_PSI_PER_BAR = 14.5038


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
    if {"oil", "temperature_C", "nu_cSt", "rho_kg_m3"} <= set(values):
        problems += _check_fluid_consistency(file, values, lines)
    if {"oil", "temperature_C", "u_mm", "p_B_bar", "q_lpm", "p_L_bar"} <= set(values):
        problems += _check_sweeps(file, values, lines)
    return problems


def _check_fluid_consistency(file: str, values: Values, lines: np.ndarray) -> list[Problem]:
    """One ν and one ρ per oil and temperature, both falling as the temperature rises."""
    problems = []
    frame = pd.DataFrame({"oil": values["oil"], "T": values["temperature_C"],
                          "nu": values["nu_cSt"], "rho": values["rho_kg_m3"], "line": lines})
    frame = frame.dropna()
    for oil, of_oil in frame.groupby("oil", sort=False):
        medians = []
        for temperature, group in of_oil.groupby("T"):
            for column, name, unit in (("nu", "nu_cSt", "cSt"), ("rho", "rho_kg_m3", "kg/m³")):
                typical = float(group[column].median())
                off = group[np.abs(group[column] / typical - 1.0) > FLUID_TOLERANCE]
                for row in off.itertuples():
                    problems.append(Problem(
                        file, int(row.line), name, f"{getattr(row, column):g}",
                        f"the same {'viscosity' if column == 'nu' else 'density'} as the other "
                        f"rows of {oil} at {temperature:g} °C ({typical:g} {unit}, within "
                        f"{100 * FLUID_TOLERANCE:g} %)"))
            medians.append((temperature, group["nu"].median(), group["rho"].median(),
                            int(group["line"].min())))
        for (t0, nu0, rho0, _), (t1, nu1, rho1, line) in zip(medians, medians[1:]):
            for name, before, after, unit in (("nu_cSt", nu0, nu1, "cSt"),
                                              ("rho_kg_m3", rho0, rho1, "kg/m³")):
                if not after < before:
                    problems.append(Problem(
                        file, line, name, f"{after:g}",
                        f"{'viscosity' if name == 'nu_cSt' else 'density'} of {oil} falling as "
                        f"the temperature rises: {before:g} {unit} at {t0:g} °C, so less at "
                        f"{t1:g} °C"))
    return problems


def _check_sweeps(file: str, values: Values, lines: np.ndarray) -> list[Problem]:
    """Within a sweep (one oil, temperature, opening and back pressure) Δp rises with q: the
    flow through a fixed restriction rises with its pressure drop."""
    problems = []
    frame = pd.DataFrame({key: values[column] for key, column in (
        ("oil", "oil"), ("T", "temperature_C"), ("u", "u_mm"), ("p_B", "p_B_bar"),
        ("q", "q_lpm"), ("p_L", "p_L_bar"))})
    frame["line"] = lines
    frame = frame.dropna()
    for _, sweep in frame.groupby(["oil", "T", "u", "p_B"], sort=False):
        sweep = sweep.sort_values("q")
        q, dp, at = sweep["q"].to_numpy(), (sweep["p_L"] - sweep["p_B"]).to_numpy(), \
            sweep["line"].to_numpy()
        for k in np.flatnonzero((np.diff(q) > 0) & (np.diff(dp) <= 0)):
            problems.append(Problem(
                file, int(at[k + 1]), "p_L_bar", f"{sweep['p_L'].iloc[k + 1]:g}",
                f"p_L − p_B rising with the flow within a sweep (same oil, temperature, u_mm, "
                f"p_B_bar): {q[k + 1]:g} L/min gives {dp[k + 1]:g} bar here, but {q[k]:g} L/min "
                f"gives {dp[k]:g} bar on line {at[k]}"))
    return problems


def _check_bench_runs(file: str, values: Values, lines: np.ndarray) -> list[Problem]:
    """Within each run: time increasing, one set point, p_P − p_B following it; and p_L above
    p_B everywhere. Runs are grouped once (a log may hold thousands), problems come in the order
    the cell-by-cell rules would list them."""
    if "run" not in values:
        return []
    runs = pd.Series(values["run"])
    named = runs.notna().to_numpy()
    rows = np.flatnonzero(named)
    group = pd.factorize(runs[named], sort=False)[0]  # runs in order of appearance
    problems = []
    if "time_s" in values:
        problems += _time_problems(file, values["time_s"][rows], group, rows, lines,
                                   runs.to_numpy()[rows])
    if "p_Pe_nominal_bar" in values:
        problems += _set_point_problems(file, values, group, rows, lines,
                                        runs.to_numpy()[rows])
    if {"p_L_bar", "p_B_bar"} <= set(values):
        p_L, p_B = values["p_L_bar"], values["p_B_bar"]
        for i in np.flatnonzero(p_L < p_B - PRESSURE_NOISE_BAR):
            problems.append(Problem(file, int(lines[i]), "p_L_bar", f"{p_L[i]:g}",
                                    f"load pressure >= back pressure p_B_bar = {p_B[i]:g} bar "
                                    f"within the sensors' noise ({PRESSURE_NOISE_BAR:g} bar): "
                                    "flow runs from the load port to the back port"))
    return problems


def _time_problems(file, time, group, rows, lines, names) -> list[Problem]:
    """Samples whose time is not after the previous valid one of their run."""
    valid = ~np.isnan(time)
    frame = pd.DataFrame({"group": group[valid], "time": time[valid], "row": rows[valid]})
    previous = frame.groupby("group", sort=False)[["time", "row"]].shift(1)
    late = np.flatnonzero((frame["time"].to_numpy() <= previous["time"].to_numpy()))
    problems = []
    for k in late:
        row, before = int(frame["row"].iat[k]), int(previous["row"].iat[k])
        problems.append(Problem(file, int(lines[row]), "time_s", f"{frame['time'].iat[k]:g}",
                                f"time increasing within run {names[valid][k]!r}, i.e. > "
                                f"{previous['time'].iat[k]:g} s (line {lines[before]})"))
    return problems


def _set_point_problems(file, values, group, rows, lines, names) -> list[Problem]:
    """One set point per run (its first), and p_P − p_B following it (:func:`_check_set_point`)."""
    set_points = values["p_Pe_nominal_bar"][rows]
    frame = pd.DataFrame({"group": group, "set_point": set_points})
    first = frame.groupby("group", sort=False)["set_point"].transform("first").to_numpy()
    problems = []
    valid = ~np.isnan(set_points)
    for k in np.flatnonzero(valid & (set_points != first)):
        problems.append(Problem(file, int(lines[rows[k]]), "p_Pe_nominal_bar",
                                f"{set_points[k]:g}",
                                f"one set point per run: run {names[k]!r} started at "
                                f"{first[k]:g} bar"))
    if not {"p_P_bar", "p_B_bar"} <= set(values):
        return problems
    pilot = values["p_P_bar"][rows] - values["p_B_bar"][rows]
    typical = pd.Series(np.where(np.isfinite(pilot), pilot, np.nan)).groupby(group).transform(
        "median").to_numpy()
    has_set_point = ~np.isnan(first)
    first_row = pd.Series(rows).groupby(group).transform("first").to_numpy()
    fraction, absolute = SET_POINT_TOLERANCE
    run_off = has_set_point & np.isfinite(typical) & (
        np.abs(typical - first) > fraction * np.abs(first) + absolute)
    for k in np.flatnonzero(run_off & (rows == first_row)):
        problems.append(_run_set_point_problem(file, names[k], first[k], typical[k],
                                               int(lines[rows[k]])))
    fraction, absolute = SAMPLE_SET_POINT_TOLERANCE
    off = (has_set_point & np.isfinite(typical) & ~run_off & np.isfinite(pilot)
           & (np.abs(pilot - first) > fraction * np.abs(first) + absolute))
    for k in np.flatnonzero(off):
        problems.append(Problem(file, int(lines[rows[k]]), "p_P_bar",
                                f"{values['p_P_bar'][rows[k]]:g}",
                                f"p_P − p_B within {100 * fraction:g} % + {absolute:g} bar of run "
                                f"{names[k]!r}'s set point {first[k]:g} bar; here it is "
                                f"{pilot[k]:.4g} bar"))
    return problems


def _run_set_point_problem(file: str, run: str, set_point: float, typical: float,
                           line: int) -> Problem:
    """A run whose p_P − p_B sits away from its set point as a whole (a unit mix-up, say)."""
    fraction, absolute = SET_POINT_TOLERANCE
    hint = ""
    if set_point > 0 and abs(typical / set_point / _PSI_PER_BAR - 1.0) < 0.1:
        hint = "; p_P_bar and p_B_bar look like psi (1 bar = 14.5 psi)"
    elif typical > 0 and abs(set_point / typical / _PSI_PER_BAR - 1.0) < 0.1:
        hint = "; p_Pe_nominal_bar looks like psi (1 bar = 14.5 psi)"
    return Problem(file, line, "p_P_bar", None,
                   f"p_P − p_B near the set point of run {run!r} ({set_point:g} bar, within "
                   f"{100 * fraction:g} % + {absolute:g} bar); its median is {typical:.4g} "
                   f"bar{hint}")
