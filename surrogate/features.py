"""Dimensionless features that carry the physics of the valve, for the learned maps.

Learned maps never see a temperature, nor raw pressures or flows: they see three dimensionless
numbers and predict a dimensionless correction to the basic model. That is what lets them
extrapolate to temperatures and oils the CFD never ran.

Flow map: Δp(q, p_B, u, fluid) through the discharge coefficient
-----------------------------------------------------------------
Target ``ln C_d`` of the orifice equation with a_d = w·u, i.e. Δp = ½ρ·(q/(C_d·w·u))², from

* ``log_reynolds`` = ln Re_q, Re_q = v·2u/ν with the jet velocity v = q/(w·u) and the hydraulic
  diameter 2u of the slot, so Re_q = 2q/(w·ν). The paper found C_d(u, Re) to collapse across
  temperatures; on the shipped samples it does so far better in this flow-based Reynolds number
  than in a pressure-based one. Temperature and oil enter only through Re_q.
* ``log_opening`` = ln(u/U), U the stroke.
* ``log_cavitation`` = ln σ_q, σ_q = (p_B + p_atm − p_sat)/(½ρv²): the absolute back pressure
  above the gas-release pressure (1.0 bar absolute) relative to the jet's dynamic pressure. Low
  values mean a cavitating jet, which chokes the flow. It carries the back-pressure dependence.

These are explicit in q, so the flow map gives the pressure drop the solver needs in closed form.

Force map: f_sim(p_L, p_B, u, fluid) through the flow-force fraction
--------------------------------------------------------------------
Target α = f_ff/(A_L·Δp), with the flow force f_ff = f_sim − p_L·A_L − p_B·(A_s3 − A_B) (paper
eqs. 10 and 17), or ln(1 + α), from the same three numbers built from Δp instead of q, as f_sim is
queried at a given load pressure: Re = U·sqrt(2Δp/ρ)/ν, u/U and σ = (p_B + p_atm − p_sat)/Δp.

A fourth force feature, ``log_pressure_drop`` = ln(Δp/p_atm), is offered to predictors that can
use it (the GP's force map does; :data:`FORCE_FEATURE_NAMES`). At a fixed Re and σ the samples'
α still drifts with the pressure level (the three numbers do not collapse the CFD completely):
measured by the project's four-scheme cross-validation (``eval/force_gp_structures.py``), the
GP's flow-force error falls from 3.6 to 1.9 % across sweeps and from 3.5 to 2.0 % at a left-out
temperature with it. A predictor saved with three force features keeps reading three.

Structure
---------
Both maps are additive in two parts, ln C_d = a(Re, u) + b(u, σ) — a viscous part and a cavitation
part. On the shipped samples this structure extrapolates to a left-out temperature with a third of
the error of a joint model of the three features (`eval/surrogates.py` measures it).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .fluid import FluidState, broadcast_query
from .core.units import BAR, P_ATM
from .valve import ValveParameters

FEATURE_NAMES = ("log_reynolds", "log_opening", "log_cavitation")
#: the force features a predictor may take: the first three, or all four
FORCE_FEATURE_NAMES = (*FEATURE_NAMES, "log_pressure_drop")
ADDITIVE_GROUPS = ((0, 1), (1, 2))  # (Re, u) and (u, σ)
# floors under quantities that go into a logarithm, far below anything physical
_SMALLEST_FLOW = 1e-30  # [m^3/s]
_SMALLEST_OPENING = 1e-15  # [m]
_SMALLEST_DP = 1e-30  # [Pa]
_SMALLEST_MARGIN = 1e2  # [Pa] absolute back pressure above p_sat, at least


@dataclass(frozen=True)
class FeatureSpec:
    """The constants that turn a query into features, stored with every learned map.

    Attributes
    ----------
    length : float
        Reference length U [m] (the stroke) of the opening and of the force map's Reynolds number.
    w : float
        Discharge-area coefficient of the orifice equation [m].
    A_L : float
        Effective load area [m^2].
    back_area : float
        A_s3 − A_B [m^2]: the area on which p_B acts in f_sim with uniform pressure.
    p_atm : float
        Atmospheric pressure [Pa], to turn gauge into absolute pressure.
    p_sat : float
        Absolute gas-release pressure [Pa].
    """

    length: float
    w: float
    A_L: float
    back_area: float
    p_atm: float = P_ATM
    p_sat: float = 1.0 * BAR

    @classmethod
    def for_valve(cls, valve: ValveParameters) -> "FeatureSpec":
        return cls(length=valve.U_max, w=valve.w, A_L=valve.A_L,
                   back_area=valve.A_s3 - valve.A_B)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "FeatureSpec":
        return cls(**{key: float(value) for key, value in data.items()})

    def _margin(self, p_B: np.ndarray) -> np.ndarray:
        return np.maximum(p_B + self.p_atm - self.p_sat, _SMALLEST_MARGIN)

    def cavitation_number(self, p_B, dp) -> np.ndarray:
        """σ = (p_B + p_atm − p_sat)/Δp [1] at back pressures ``p_B`` [Pa] and pressure drops
        ``dp`` [Pa] (> 0), broadcast together: the force features' third, before its log."""
        p_B, dp = np.broadcast_arrays(np.asarray(p_B, float), np.asarray(dp, float))
        return self._margin(p_B) / np.maximum(dp, _SMALLEST_DP)

    def flow_features(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        """(ln Re_q, ln(u/U), ln σ_q) of flattened queries, shape (n, 3)."""
        q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
        q = np.maximum(q.ravel(), _SMALLEST_FLOW)
        u = np.maximum(u.ravel(), _SMALLEST_OPENING)
        p_B = p_B.ravel()
        rho, nu = fluid.rho.ravel(), fluid.nu.ravel()
        velocity = q / (self.w * u)
        return np.column_stack([np.log(2.0 * q / (self.w * nu)), np.log(u / self.length),
                                np.log(self._margin(p_B) / (0.5 * rho * velocity**2))])

    def force_features(self, p_L, p_B, u, fluid: FluidState, count: int = 3) -> np.ndarray:
        """The first ``count`` of (ln Re, ln(u/U), ln σ, ln(Δp/p_atm)) of flattened queries,
        built from Δp; shape (n, count)."""
        if count not in (3, 4):
            raise ValueError(f"force features come as 3 or 4 columns, not {count}")
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        dp = np.maximum((p_L - p_B).ravel(), _SMALLEST_DP)
        rho, nu = fluid.rho.ravel(), fluid.nu.ravel()
        reynolds = self.length * np.sqrt(2.0 * dp / rho) / nu
        opening = np.maximum(u.ravel(), _SMALLEST_OPENING) / self.length
        columns = [np.log(reynolds), np.log(opening), np.log(self._margin(p_B.ravel()) / dp)]
        if count == 4:
            columns.append(np.log(dp / self.p_atm))
        return np.column_stack(columns)

    def orifice_pressure_drop(self, q, u, rho) -> np.ndarray:
        """Δp of the orifice equation with C_d = 1, ½ρ·(q/(w·u))² [Pa]."""
        return 0.5 * rho * (q / (self.w * u)) ** 2

    def uniform_force(self, p_L, p_B) -> np.ndarray:
        """f_sim with uniform pressure, p_L·A_L + p_B·(A_s3 − A_B) [N], flattened."""
        p_L, p_B = np.broadcast_arrays(np.asarray(p_L, float), np.asarray(p_B, float))
        return (p_L * self.A_L + p_B * self.back_area).ravel()


@dataclass(frozen=True)
class Targets:
    """Features and targets of a set of CFD samples."""

    flow_features: np.ndarray  # (n, 3)
    log_discharge: np.ndarray  # ln C_d
    force_features: np.ndarray  # (n, 4): all of FORCE_FEATURE_NAMES; predictors take a prefix
    flow_force_fraction: np.ndarray  # α


def targets(spec: FeatureSpec, frame) -> Targets:
    """Features and targets of the samples in an SI frame (``CfdSamples.frame``)."""
    fluid = FluidState(frame["nu"].to_numpy(), frame["rho"].to_numpy())
    p_L, p_B, u, q = (frame[name].to_numpy() for name in ("p_L", "p_B", "u", "q"))
    dp = p_L - p_B
    flow_force = frame["f_sim"].to_numpy() - spec.uniform_force(p_L, p_B)
    log_discharge = 0.5 * np.log(spec.orifice_pressure_drop(q, u, fluid.rho) / dp)
    return Targets(spec.flow_features(q, p_B, u, fluid), log_discharge,
                   spec.force_features(p_L, p_B, u, fluid, count=len(FORCE_FEATURE_NAMES)),
                   flow_force / (spec.A_L * dp))
