"""Map-query files: operating states at which to evaluate a flow and a force map.

Columns ``u_mm, p_L_bar, p_B_bar`` and either ``temperature_C`` (the valve's oil at that
temperature) or ``nu_cSt, rho_kg_m3`` (any fluid). Other columns (case ids, notes) are allowed
and carried through to the output unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..fluid import FluidState, Oil
from ..core.units import to_si
from .errors import DataFileError, Problem
from .reader import parse_cells, read_raw_table
from .schema import QUERY_AT_TEMPERATURE, QUERY_WITH_FLUID


@dataclass(frozen=True)
class Queries:
    """Validated queries: the raw text (to repeat in outputs) and the state in SI units."""

    raw: pd.DataFrame
    u: np.ndarray  # [m]
    p_L: np.ndarray  # [Pa]
    p_B: np.ndarray  # [Pa]
    temperature: np.ndarray | None  # [K], when the file gives temperatures
    nu: np.ndarray | None  # [m^2/s], when it gives the fluid
    rho: np.ndarray | None  # [kg/m^3]

    def fluid(self, oil: Oil) -> FluidState:
        """The fluid at each query: given directly, or the valve's oil at the temperature."""
        if self.temperature is not None:
            return oil.state(self.temperature)
        return FluidState(self.nu, self.rho)


def load_queries(path: str | Path) -> Queries:
    """Load and validate a map-query file.

    Raises
    ------
    DataFileError
        With file, line, column, value and what was expected for every problem.
    """
    table = read_raw_table(path, columnar=False)  # the output repeats the input's text
    header = set(table.header)
    has_temperature = "temperature_C" in header
    has_fluid = bool({"nu_cSt", "rho_kg_m3"} & header)
    if has_temperature == has_fluid:
        raise DataFileError(table.file, [Problem(
            table.file, table.header_line, None, ",".join(table.header)[:80],
            "columns u_mm, p_L_bar, p_B_bar and either temperature_C (the valve's oil) or "
            "nu_cSt and rho_kg_m3 (any fluid), " + ("not both" if has_temperature else
                                                   "one of the two"))], "map query file")
    schema = QUERY_AT_TEMPERATURE if has_temperature else QUERY_WITH_FLUID
    values, problems, _ = parse_cells(table, schema)  # extra columns are the user's own
    if problems:
        raise DataFileError(table.file, problems, schema.kind)
    raw = pd.DataFrame(table.rows, columns=list(table.header))
    si = {column.si_name: to_si(values[column.name], column.unit) for column in schema.columns}
    return Queries(raw, si["u"], si["p_L"], si["p_B"], si.get("temperature"), si.get("nu"),
                   si.get("rho"))
