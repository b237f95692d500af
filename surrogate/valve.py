"""The valve's parameters: geometry, spring, stroke and the oil it runs on.

A valve is described by a small TOML file, so users can describe their own valve. The shipped one,
``surrogate/valves/paper_cbv.toml``, is the 3-port restrictive counterbalance valve of the paper::

    [valve]
    name = "..."
    A_L_mm2 = 10.7          # effective area of the load pressure [mm^2]
    alpha_P = 2.72          # pilot ratio A_P / A_L [-]
    ...

    [oil]
    name = "ISO VG46 HV"
    nu40_cSt = 46.0
    ...

Keys carry their file unit in their name; :class:`ValveParameters` holds SI values.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, fields
from importlib import resources
from pathlib import Path

from .core.errors import InputError
from .fluid import Oil
from .core.input_files import read_input_text
from .limits import PRESSURE_MAX_BAR, Range
from .core.tomlio import loads, require_keys
from .core.units import from_si, label, to_si

SHIPPED_VALVE = "paper_cbv.toml"

# field name -> (TOML key, file unit)
_FILE_KEYS = {
    "A_L": ("A_L_mm2", "mm^2"),
    "alpha_P": ("alpha_P", "1"),
    "A_s3": ("A_s3_mm2", "mm^2"),
    "F_cr": ("F_cr_N", "N"),
    "K_f": ("K_f_N_per_m", "N/m"),
    "U_max": ("U_max_mm", "mm"),
    "w": ("w_mm", "mm"),
}
# Plausible values in file units, wide enough for any poppet or spool valve from a 1 mm² pilot
# stage to a 1000 L/min cartridge; outside them a value is a unit or typing mistake (see
# surrogate.limits). The paper's valve: 10.7 mm², 2.72, 46 mm², 226 N, 1.14e5 N/m, 0.63 mm, 12 mm.
_PLAUSIBLE = {
    "A_L": Range(0.1, 1e4, "mm^2"),
    "alpha_P": Range(0.1, 100.0, "1"),
    "A_s3": Range(0.1, 1e5, "mm^2"),
    "F_cr": Range(0.1, 1e5, "N"),
    "K_f": Range(1e3, 1e9, "N/m"),
    "U_max": Range(0.01, 50.0, "mm"),
    "w": Range(0.1, 1000.0, "mm"),
}
# F_cr / A_L: the Δp at which the valve cracks open without pilot pressure [bar]
_CRACK_PRESSURE = Range(0.1, PRESSURE_MAX_BAR, "bar")


@dataclass(frozen=True)
class ValveParameters:
    """Parameters of a counterbalance valve in its piloted-relief mode (flow load -> back port).

    Parameters
    ----------
    name : str
        Display name.
    A_L : float
        Effective area on which the load pressure p_L acts [m^2].
    alpha_P : float
        Pilot ratio A_P / A_L [-].
    A_s3 : float
        Effective area in the main spring chamber, at back pressure, outside the CFD domain
        [m^2]; larger than A_B.
    F_cr : float
        Spring force at u = 0 (crack force) [N].
    K_f : float
        Spring rate [N/m].
    U_max : float
        Piston stroke to the mechanical stop [m].
    w : float
        Discharge-area coefficient of the basic model, a_d = w·u [m].
    oil : Oil
        The oil of the CFD samples and the bench.
    """

    name: str
    A_L: float
    alpha_P: float
    A_s3: float
    F_cr: float
    K_f: float
    U_max: float
    w: float
    oil: Oil

    def __post_init__(self):
        for field, (key, unit) in _FILE_KEYS.items():
            value = from_si(getattr(self, field), unit)
            plausible = _PLAUSIBLE[field]
            if not plausible.contains(value):
                raise InputError(f"valve {self.name!r}: {key} = {value:g} is not a plausible "
                                 f"value (expected {plausible.describe()}"
                                 f"{plausible.unit_hint(value)})")
        crack = from_si(self.P_cr, "bar")
        if not _CRACK_PRESSURE.contains(crack):
            raise InputError(
                f"valve {self.name!r}: the crack pressure F_cr_N / A_L_mm2 = {crack:.4g} bar is "
                f"implausible (expected {_CRACK_PRESSURE.describe()}); check the units of F_cr_N "
                f"[{label('N')}] and A_L_mm2 [{label('mm^2')}]")
        if not self.A_s3 > self.A_B:
            raise InputError(
                f"valve {self.name!r}: A_s3 = {from_si(self.A_s3, 'mm^2'):.3g} mm² must exceed "
                f"A_B = (alpha_P + 1)·A_L = {from_si(self.A_B, 'mm^2'):.3g} mm²")

    @property
    def A_P(self) -> float:
        """Effective area of the pilot pressure, α_P·A_L [m^2]."""
        return self.alpha_P * self.A_L

    @property
    def A_B(self) -> float:
        """Effective area of the back pressure, (α_P + 1)·A_L [m^2]."""
        return (self.alpha_P + 1.0) * self.A_L

    @property
    def P_cr(self) -> float:
        """Crack pressure F_cr / A_L [Pa]: the Δp at which the valve opens with p_Pe = 0."""
        return self.F_cr / self.A_L

    @classmethod
    def from_dict(cls, document: dict, *, source: str = "valve file") -> "ValveParameters":
        """Build from a parsed valve file: ``{"valve": {...}, "oil": {...}}`` in file units."""
        require_keys(document, {"valve", "oil"}, source)
        table = document["valve"]
        require_keys(table, {"name", *(key for key, _ in _FILE_KEYS.values())},
                      f"{source} [valve]")
        values = {}
        for field, (key, unit) in _FILE_KEYS.items():
            raw = table[key]
            if isinstance(raw, bool) or not isinstance(raw, (int, float)):
                raise InputError(f"{source} [valve]: {key} must be a number in {unit}, "
                                 f"got {raw!r}")
            values[field] = to_si(raw, unit)
        oil = Oil.from_dict(document["oil"], source=f"{source} [oil]")
        try:
            return cls(name=str(table["name"]), oil=oil, **values)
        except InputError as error:
            raise InputError(f"{source}: {error}") from None

    def to_dict(self) -> dict:
        """The valve file's content in file units; the inverse of :meth:`from_dict`."""
        table = {"name": self.name}
        for field, (key, unit) in _FILE_KEYS.items():
            table[key] = from_si(getattr(self, field), unit)
        return {"valve": table, "oil": self.oil.to_dict()}

    def describe(self) -> str:
        """A short multi-line description in display units."""
        lines = [f"{self.name}"]
        for f in fields(self):
            if f.name in _FILE_KEYS:
                key, unit = _FILE_KEYS[f.name]
                lines.append(f"  {key:<14} {from_si(getattr(self, f.name), unit):.6g}")
        lines.append(f"  oil            {self.oil.name}")
        return "\n".join(lines)


def shipped_valve_path() -> Path:
    """Where the shipped valve file is (the package's own data)."""
    return Path(str(resources.files("surrogate.valves").joinpath(SHIPPED_VALVE)))


def load_valve(path: str | Path | None = None) -> ValveParameters:
    """Read a valve file; ``None`` gives the shipped valve of the paper.

    Raises
    ------
    InputError
        If the file is not valid TOML or misses, misspells or mistypes a parameter; the message
        names the file and the key.
    """
    if path is None:
        text = resources.files("surrogate.valves").joinpath(SHIPPED_VALVE).read_text("utf-8")
        source = f"shipped valve {SHIPPED_VALVE}"
    else:
        path = Path(path)
        text = read_input_text(path, "a TOML valve file")
        source = str(path)
    try:
        document = loads(text, source)
    except tomllib.TOMLDecodeError as error:
        raise InputError(f"{source}: not valid TOML: {error}") from None
    return ValveParameters.from_dict(document, source=source)
