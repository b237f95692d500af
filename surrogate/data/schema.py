"""The documented file schemas: columns, file units, SI names and physical bounds.

The two schemas here are the single source of truth for ``cfd_samples/README.md`` and
``measurements/README.md``: a column is added, renamed or bounded here and nowhere else.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from .. import limits
from ..limits import Range
from ..core.units import from_si, label, to_si

#: the other units a bench log may give a quantity in: the documented unit -> (the suffix that
#: replaces the documented name's, the unit it means); ``p_L_psi`` is p_L in psi, ``q_gpm`` q in
#: US gallons per minute, ``temperature_F`` the temperature in °F
UNIT_SUFFIXES: dict[str, tuple[tuple[str, str], ...]] = {
    "bar": (("psi", "psi"), ("kPa", "kPa"), ("MPa", "MPa")),
    "L/min": (("gpm", "gpm"),),
    "degC": (("F", "degF"),),
}
#: how a bench log may write the ramp direction besides its words: +1 is up, as in the Python API
DIRECTION_SIGNS = {"1": "up", "+1": "up", "-1": "down", "1.0": "up", "+1.0": "up",
                   "-1.0": "down"}


#: the longest text cell (a run id, an oil's name): an id reaches the terminal, the reports and
#: file names, so it is printable (no escape sequence, line break or direction override) and short
TEXT_MAX = 100


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
        File unit (a key of :mod:`surrogate.core.units`), or None for a text column.
    range : Range or None
        Plausible values in the file unit (:mod:`surrogate.limits`); None for any finite number.
    choices : tuple of str
        Allowed values of a text column; empty for any non-empty text.
    aliases : dict
        Other spellings of the choices, read as the choice they map to (``"+1"`` -> ``"up"``).
    suffixes : tuple of (str, str)
        The other units the column may come in, as (name suffix, unit): ``("psi", "psi")`` lets
        ``p_L_psi`` stand for ``p_L_bar``, read in psi and converted (:meth:`in_unit`).
    """

    name: str
    si_name: str
    meaning: str
    unit: str | None = None
    range: Range | None = None
    choices: tuple[str, ...] = ()
    aliases: dict[str, str] = field(default_factory=dict, hash=False, compare=False)
    suffixes: tuple[tuple[str, str], ...] = ()

    @property
    def is_number(self) -> bool:
        return self.unit is not None

    def allowed(self) -> str:
        """The allowed values in short: ``"0 to 100 mm"``, ``"'up', 'down'"``."""
        if not self.is_number:
            if not self.choices:
                return f"printable text, 1 to {TEXT_MAX} characters"
            words = ", ".join(repr(c) for c in self.choices)
            signs = [f"{text} ({choice})" for text, choice in self.aliases.items()
                     if text in ("+1", "-1")]
            return f"{words} or {', '.join(signs)}" if signs else words
        if self.range is not None:
            return self.range.describe()
        return f"finite, in {label(self.unit)}"

    def describe_expected(self) -> str:
        """What a valid cell looks like, for error messages."""
        return f"{self.meaning}, {self.allowed()}"

    @property
    def stem(self) -> str:
        """The name without its unit suffix: ``"p_L"`` of ``"p_L_bar"``."""
        return self.name.rsplit("_", 1)[0] if self.unit else self.name

    def other_names(self) -> dict[str, str]:
        """The header names that stand for this column in another unit -> that unit."""
        return {f"{self.stem}_{suffix}": unit for suffix, unit in self.suffixes}

    def in_unit(self, name: str, unit: str) -> "Column":
        """This column as a file names it ``name`` and gives it in ``unit``: its range
        converted (through :mod:`surrogate.core.units`), so that a value is checked, and quoted, as
        written."""
        bounds = None
        if self.range is not None:
            low, high = (float(from_si(to_si(v, self.range.unit), unit))
                         for v in (self.range.low, self.range.high))
            bounds = Range(round(low, 4), round(high, 4), unit)
        return replace(self, name=name, unit=unit, range=bounds, suffixes=())

    def with_suffixes(self) -> "Column":
        """This column, accepting the other units of :data:`UNIT_SUFFIXES` by name suffix."""
        return replace(self, suffixes=UNIT_SUFFIXES.get(self.unit, ()))


@dataclass(frozen=True)
class FileSchema:
    """The columns of one kind of file, in the documented order."""

    kind: str
    columns: tuple[Column, ...]
    description: str
    identifying: frozenset[str] = field(default_factory=frozenset)
    #: other columns are accepted (and not read) instead of rejected
    allow_extra: bool = False

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

# Bench logs are taken as benches and spreadsheets write them: extra columns (ignored), other
# units named by suffix (converted), ±1 for the direction. CFD samples come from the project's
# own solver runs and keep the strict schema.
BENCH_SCHEMA = FileSchema(
    kind="bench log",
    description="one row per bench sample",
    identifying=frozenset({"run", "time_s", "direction"}),
    allow_extra=True,
    columns=(
        Column("run", "run", "ramp-test id"),
        Column("time_s", "time", "time within the run", "s", limits.TIME),
        _TEMPERATURE.with_suffixes(),
        Column("p_Pe_nominal_bar", "p_Pe_nominal", "set point of p_Pe = p_P - p_B", "bar",
               limits.PRESSURE_DIFFERENCE).with_suffixes(),
        _FLOW.with_suffixes(),
        _pressure("p_L_bar", "p_L", "load pressure (gauge)").with_suffixes(),
        _pressure("p_B_bar", "p_B", "back pressure (gauge)").with_suffixes(),
        _pressure("p_P_bar", "p_P", "pilot pressure (gauge)").with_suffixes(),
        Column("direction", "direction", "ramp direction", choices=("up", "down"),
               aliases=DIRECTION_SIGNS),
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
        others = ", ".join(f"`_{suffix}`" for suffix, _ in column.suffixes)
        others = f" (or {others})" if others else ""
        rows.append(f"| `{column.name}`{others} | {unit} | {column.meaning} | "
                    f"{column.allowed()} |")
    return "\n".join(rows)
