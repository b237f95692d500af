"""The documented file schemas: columns, file units, SI names and physical bounds.

The two schemas here are the single source of truth for ``cfd_samples/README.md`` and
``measurements/README.md``: a column is added, renamed or bounded here and nowhere else.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .. import limits
from ..limits import Range
from ..units import label


@dataclass(frozen=True)
class Column:
    """One column of a file schema.

    Attributes
    ----------
    name : str
        Header name in the file.
    si_name : str
        Name of the column in the loaded, SI table.
    meaning : str
        What it holds, in words (used in messages and READMEs).
    unit : str or None
        File unit (a key of :mod:`surrogate.units`), or None for a text column.
    range : Range or None
        Plausible values in the file unit (:mod:`surrogate.limits`); None for any finite number.
    choices : tuple of str
        Allowed values of a text column; empty for any non-empty text.
    """

    name: str
    si_name: str
    meaning: str
    unit: str | None = None
    range: Range | None = None
    choices: tuple[str, ...] = ()

    @property
    def is_number(self) -> bool:
        return self.unit is not None

    def allowed(self) -> str:
        """The allowed values in short: ``"0 to 100 mm"``, ``"'up', 'down'"``."""
        if not self.is_number:
            return ", ".join(repr(c) for c in self.choices) if self.choices else "non-empty text"
        if self.range is not None:
            return self.range.describe()
        return f"finite, in {label(self.unit)}"

    def describe_expected(self) -> str:
        """What a valid cell looks like, for error messages."""
        return f"{self.meaning}, {self.allowed()}"


@dataclass(frozen=True)
class FileSchema:
    """The columns of one kind of file, in the documented order."""

    kind: str
    columns: tuple[Column, ...]
    description: str
    identifying: frozenset[str] = field(default_factory=frozenset)
    allow_extra: bool = False  # other columns are kept as they are instead of rejected

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(column.name for column in self.columns)

    def column(self, name: str) -> Column:
        return next(column for column in self.columns if column.name == name)


def _pressure(name: str, si_name: str, meaning: str) -> Column:
    return Column(name, si_name, meaning, "bar", limits.PRESSURE)


_TEMPERATURE = Column("temperature_C", "temperature", "temperature", "degC", limits.TEMPERATURE)
_FLOW = Column("q_lpm", "q", "flow", "L/min", limits.FLOW)
_OPENING = Column("u_mm", "u", "piston position", "mm", limits.OPENING)
_VISCOSITY = Column("nu_cSt", "nu", "kinematic viscosity", "cSt", limits.VISCOSITY)
_DENSITY = Column("rho_kg_m3", "rho", "density", "kg/m^3", limits.DENSITY)

CFD_SCHEMA = FileSchema(
    kind="CFD-sample file",
    description="one row per steady CFD run",
    identifying=frozenset({"case", "f_sim_N", "u_mm"}),
    columns=(
        Column("case", "case", "run id, unique within the file"),
        Column("oil", "oil", "oil name"),
        _TEMPERATURE,
        _VISCOSITY,
        _DENSITY,
        _OPENING,
        _FLOW,
        _pressure("p_B_bar", "p_B", "back pressure (gauge)"),
        _pressure("p_L_bar", "p_L", "load pressure (gauge)"),
        Column("f_sim_N", "f_sim", "axial fluid force on the piston inside the CFD domain", "N",
               limits.FORCE),
    ),
)

BENCH_SCHEMA = FileSchema(
    kind="bench log",
    description="one row per bench sample",
    identifying=frozenset({"run", "time_s", "direction"}),
    columns=(
        Column("run", "run", "ramp-test id"),
        Column("time_s", "time", "time within the run", "s"),
        _TEMPERATURE,
        Column("p_Pe_nominal_bar", "p_Pe_nominal", "set point of p_Pe = p_P - p_B", "bar",
               limits.PRESSURE_DIFFERENCE),
        _FLOW,
        _pressure("p_L_bar", "p_L", "load pressure (gauge)"),
        _pressure("p_B_bar", "p_B", "back pressure (gauge)"),
        _pressure("p_P_bar", "p_P", "pilot pressure (gauge)"),
        Column("direction", "direction", "ramp direction", choices=("up", "down")),
    ),
)

SCHEMAS = (CFD_SCHEMA, BENCH_SCHEMA)

_QUERY_STATE = (
    _OPENING,
    _pressure("p_L_bar", "p_L", "load pressure (gauge)"),
    _pressure("p_B_bar", "p_B", "back pressure (gauge)"),
)

#: map queries with the valve's own oil at a temperature
QUERY_AT_TEMPERATURE = FileSchema(
    kind="map query file", description="one row per query, oil given by its temperature",
    columns=(*_QUERY_STATE, _TEMPERATURE), allow_extra=True)

#: map queries with any oil, given by its viscosity and density
QUERY_WITH_FLUID = FileSchema(
    kind="map query file", description="one row per query, fluid given by ν and ρ",
    columns=(*_QUERY_STATE,
             _VISCOSITY, _DENSITY),
    allow_extra=True)


def schema_table(schema: FileSchema) -> str:
    """The schema as a Markdown table: column, unit, meaning, allowed values."""
    rows = ["| column | unit | meaning | allowed |", "|---|---|---|---|"]
    for column in schema.columns:
        unit = label(column.unit) if column.unit else "–"
        rows.append(f"| `{column.name}` | {unit} | {column.meaning} | {column.allowed()} |")
    return "\n".join(rows)
