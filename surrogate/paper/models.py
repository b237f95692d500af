"""The paper's models (BMBE, BMBEBF, CFDA) and the ablations of its Figure 20, on any maps.

* **BMBE**, basic effort: orifice equation with C_d = 0.4, uniform pressure, no friction.
* **BMBEBF**, basic effort best fit: as BMBE with C_d fitted to the median line of the 40 °C,
  p_Pe = 65 bar run (the paper's fitting scenario; eq. 15 shows C_d and K_f trade off).
* **CFDA**, CFD assisted: the flow map q_sim and the force map f_sim, with one flow-force scale
  fitted to that same median line (the paper needed 0.9).
* **CFDAForce**: the force map with the basic model's orifice equation (C_d = 0.4) and the CFDA
  flow-force scale: what the f_sim map alone contributes.
* **CFDARes**: the flow map with a uniform pressure distribution: what the q_sim map alone
  contributes.

"Any maps" means the grid maps of the paper or the learned maps: the models are built from a flow
and a force map, whatever their kind.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..effects import DischargeScale, FlowForceScale
from ..fitting.leastsquares import fit
from ..maps.orifice import BASIC_DISCHARGE_COEFFICIENT
from ..maps.registry import MapsSpec
from ..model import ValveModel
from ..description.presets import basic_maps, bmbe, cfda_friction
from ..solver import solve_steady
from ..description.spec import EffectSpec, ModelSpec, ValveSource
from .median import median_points

FIT_P_PE = 65e5  # [Pa] set point of the run the paper fits to
FIT_TEMPERATURE = 313.15  # [K] (40 °C)


@dataclass(frozen=True)
class PaperModels:
    """The five models, with the two fitted constants."""

    bmbe: ValveModel
    bmbebf: ValveModel
    cfda: ValveModel
    cfda_force: ValveModel
    cfda_res: ValveModel
    fitted_discharge_coefficient: float
    fitted_flow_force_scale: float

    def table5_models(self) -> dict[str, ValveModel]:
        """The models of Table 5, by their names in the paper."""
        return {"BMBE": self.bmbe, "BMBEBF": self.bmbebf, "CFDA": self.cfda}

    def ablation_models(self) -> dict[str, ValveModel]:
        """The models of Figure 20."""
        return {"CFDA": self.cfda, "CFDAForce": self.cfda_force, "CFDARes": self.cfda_res}

    def cfda_with_friction(self, K1: float, K2: float) -> ValveModel:
        """CFDA plus Coulomb friction s·(K1 + K2·p_L), K1 [N], K2 [N/bar]."""
        spec = ModelSpec.of(self.cfda).adding(*cfda_friction(K1, K2), name="CFDA with friction")
        return spec.build()


def median_line_error(model: ValveModel, line: pd.DataFrame) -> np.ndarray:
    """Model Δp minus median-line Δp at each bin, friction left out [Pa]; NaN where the solver
    failed."""
    solution = solve_steady(model, median_points(line), friction=False)
    return np.where(solution.ok, solution.dp - line["dp"].to_numpy(), np.nan)


def mean_abs_distance(model: ValveModel, line: pd.DataFrame) -> float:
    """Table 5's accuracy: mean |model − median line| [Pa]; failed bins count as infinitely far."""
    error = median_line_error(model, line)
    return float(np.mean(np.abs(error))) if np.all(np.isfinite(error)) else float("inf")


def _fitted(spec: ModelSpec, line: pd.DataFrame) -> ValveModel:
    """The model of ``spec`` with its free parameter fitted to the median line (least squares,
    as every fit in the package)."""
    return fit(spec.build(), lambda model: median_line_error(model, line), tolerance=1e-10).model


def build_paper_models(valve: ValveSource, maps: MapsSpec, fit_line: pd.DataFrame
                       ) -> PaperModels:
    """Build and fit the five models, all from specs.

    Parameters
    ----------
    valve : ValveSource
    maps : MapsSpec
        The CFD maps (grid or learned).
    fit_line : pandas.DataFrame
        Median line of the run to fit to (the paper: 40 °C, p_Pe = 65 bar).
    """
    basic = bmbe(valve)
    bmbebf = _fitted(basic.adding(EffectSpec.start(DischargeScale), name="BMBEBF"), fit_line)
    cfda = _fitted(ModelSpec("CFDA", valve, maps, (EffectSpec.start(FlowForceScale),)), fit_line)
    scale_spec = EffectSpec.of(cfda.effect(FlowForceScale.name))
    cfda_force = ModelSpec("CFDAForce", valve, MapsSpec(basic_maps().flow, maps.force),
                           (scale_spec,)).build()
    cfda_res = ModelSpec("CFDARes", valve, MapsSpec(maps.flow, basic_maps().force)).build()
    discharge = BASIC_DISCHARGE_COEFFICIENT * bmbebf.effect(DischargeScale.name)["c"]
    return PaperModels(basic.named("BMBE").build(), bmbebf, cfda, cfda_force, cfda_res,
                       discharge, cfda.effect(FlowForceScale.name)["scale"])
