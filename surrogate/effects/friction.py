"""Coulomb friction of the piston: terms of the friction band's half-width.

Each term adds to the half-width f_μ >= 0 of the band; the solver makes friction oppose the
piston's motion, quasi-statically a play: the piston stays put while the net force lies inside
±f_μ and moves to the band's edge when it leaves it. The paper's model (eq. 8) is the sum of the
first two terms, s·(K1 + K2·p_L); the others are the pressure- and viscosity-dependent seal
frictions an engineer would suspect next.
"""

from __future__ import annotations

import numpy as np

from ..core.units import BAR, CST
from .base import BalanceState, Effect, Parameter

_PER_BAR = 1.0 / BAR
_K_MAX = 1.0 * _PER_BAR  # [N/Pa] 1 N per bar: far beyond a plausible seal


class ConstantFriction(Effect):
    """Constant Coulomb friction K1 of the piston's seals and guide (paper eq. 8)."""

    name = "friction_constant"
    kind = "friction"
    category = "physics"
    title = "constant Coulomb friction"
    parameter_specs = (Parameter("K1", 0.0, "N", min=0.0, max=200.0,
                                 description="friction force"),)
    validity = "Quasi-static; no velocity dependence (Stribeck) is modelled."

    def friction(self, state: BalanceState) -> np.ndarray:
        return np.broadcast_to(self["K1"], state.u.shape)


class LoadPressureFriction(Effect):
    """Friction K2·p_L that grows with the load pressure pressing the seals (paper eq. 8)."""

    name = "friction_load_pressure"
    kind = "friction"
    category = "physics"
    title = "friction proportional to the load pressure"
    parameter_specs = (Parameter("K2", 0.0, "N/bar", min=0.0, max=_K_MAX,
                                 description="friction per bar of load pressure"),)
    validity = "Linear in p_L (gauge); p_L below zero adds nothing."

    def friction(self, state: BalanceState) -> np.ndarray:
        return self["K2"] * np.maximum(state.p_L, 0.0)


class PilotPressureFriction(Effect):
    """Friction K_P·p_P from the pilot pressure pressing the pilot-side seal.

    The paper suspected such a term: its load-pressure friction could not explain how the
    hysteresis changes with the pilot pressure.
    """

    name = "friction_pilot_pressure"
    kind = "friction"
    category = "physics"
    title = "friction proportional to the pilot pressure"
    parameter_specs = (Parameter("K_P", 0.0, "N/bar", min=0.0, max=_K_MAX,
                                 description="friction per bar of pilot pressure"),)
    validity = "Linear in p_P (gauge); close to the p_Pe term when p_B is small and steady."

    def friction(self, state: BalanceState) -> np.ndarray:
        return self["K_P"] * np.maximum(state.p_P, 0.0)


class SealPressureFriction(Effect):
    """Friction K_LP·|p_L − p_P| of the seal between the load and the pilot chamber.

    A seal loaded by the pressure difference across it presses harder the larger that difference,
    whichever side is higher.
    """

    name = "friction_seal_pressure"
    kind = "friction"
    category = "physics"
    title = "friction proportional to the load–pilot pressure difference"
    parameter_specs = (Parameter("K_LP", 0.0, "N/bar", min=0.0, max=_K_MAX,
                                 description="friction per bar across the load/pilot seal"),)
    validity = "Linear in |p_L − p_P|; kinked where p_L = p_P."

    def friction(self, state: BalanceState) -> np.ndarray:
        return self["K_LP"] * np.abs(state.p_L - state.p_P)


class PilotDifferentialFriction(Effect):
    """Friction K_Pe·p_Pe proportional to the effective pilot pressure p_Pe = p_P − p_B.

    The seal between the pilot and the spring chamber (at back pressure) sees p_P − p_B.
    """

    name = "friction_pilot_differential"
    kind = "friction"
    category = "physics"
    title = "friction proportional to p_Pe = p_P − p_B"
    parameter_specs = (Parameter("K_Pe", 0.0, "N/bar", min=0.0, max=_K_MAX,
                                 description="friction per bar of p_P − p_B"),)
    validity = "Linear in p_P − p_B; close to the pilot-pressure term when p_B is small."

    def friction(self, state: BalanceState) -> np.ndarray:
        return self["K_Pe"] * np.maximum(state.p_P - state.p_B, 0.0)


class ViscousFriction(Effect):
    """Friction K_ν·ν/ν_ref that grows with the oil's viscosity, i.e. as the oil cools.

    A thicker oil film and stiffer, colder elastomer seals both raise the breakaway friction; the
    paper's hysteresis grew as the temperature fell.
    """

    name = "friction_viscous"
    kind = "friction"
    category = "physics"
    title = "friction growing with viscosity (falling temperature)"
    parameter_specs = (
        Parameter("K_nu", 0.0, "N", min=0.0, max=100.0,
                  description="friction at the reference viscosity"),
        Parameter("nu_ref", 46.0 * CST, "cSt", min=1.0 * CST, max=1e4 * CST, vary=False,
                  description="reference viscosity (ISO VG46 at 40 °C)"),
    )
    validity = "Proportional to ν; together with a constant term it spans any linear trend in ν."

    def friction(self, state: BalanceState) -> np.ndarray:
        return self["K_nu"] * state.fluid.nu / self["nu_ref"]
