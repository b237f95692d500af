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
from scipy.optimize import minimize_scalar

from ..effects import ConstantFriction, FlowForceScale, LoadPressureFriction
from ..maps.base import FlowMap, ForceMap
from ..maps.orifice import OrificeFlowMap, UniformPressureForceMap
from ..model import ValveModel
from ..solver import solve_steady
from ..valve import ValveParameters
from .median import median_points

BASIC_DISCHARGE_COEFFICIENT = 0.4  # the paper's BMBE choice, from C_d at u = 0.63 mm
FIT_P_PE = 65e5  # [Pa] set point of the run the paper fits to
FIT_TEMPERATURE = 313.15  # [K] (40 °C)


@dataclass
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
        """CFDA plus Coulomb friction s·(K1 + K2·p_L), K1 [N], K2 [N/Pa]."""
        model = self.cfda.copy("CFDA with friction")
        model.effects += [ConstantFriction(K1=K1), LoadPressureFriction(K2=K2)]
        return model


def median_line_error(model: ValveModel, line: pd.DataFrame) -> np.ndarray:
    """Model Δp minus median-line Δp at each bin, friction left out [Pa]; NaN where the solver
    failed."""
    solution = solve_steady(model, median_points(line), friction=False)
    return np.where(solution.ok, solution.dp - line["dp"].to_numpy(), np.nan)


def mean_abs_distance(model: ValveModel, line: pd.DataFrame) -> float:
    """Table 5's accuracy: mean |model − median line| [Pa]; failed bins count as infinitely far."""
    error = median_line_error(model, line)
    return float(np.mean(np.abs(error))) if np.all(np.isfinite(error)) else float("inf")


def _fit_scalar(build, line: pd.DataFrame, bounds: tuple[float, float]) -> float:
    """The value in ``bounds`` whose model ``build(value)`` is closest to the line (least squares)."""

    def cost(value):
        error = median_line_error(build(value), line)
        error = np.where(np.isfinite(error), error, 1e9)
        return float(np.mean(error**2))

    return float(minimize_scalar(cost, bounds=bounds, method="bounded",
                                 options={"xatol": 1e-5}).x)


def build_paper_models(valve: ValveParameters, flow_map: FlowMap, force_map: ForceMap,
                       fit_line: pd.DataFrame) -> PaperModels:
    """Build and fit the five models.

    Parameters
    ----------
    valve : ValveParameters
    flow_map, force_map : FlowMap, ForceMap
        The CFD maps (grid or learned).
    fit_line : pandas.DataFrame
        Median line of the run to fit to (the paper: 40 °C, p_Pe = 65 bar).
    """
    uniform = UniformPressureForceMap(valve)

    def orifice_model(discharge_coefficient, name):
        return ValveModel(valve, OrificeFlowMap(discharge_coefficient, valve.w), uniform,
                          name=name)

    bmbe = orifice_model(BASIC_DISCHARGE_COEFFICIENT, "BMBE")
    fitted_cd = _fit_scalar(lambda cd: orifice_model(cd, "BMBEBF"), fit_line, (0.05, 2.0))
    bmbebf = orifice_model(fitted_cd, "BMBEBF")

    def cfda_model(scale):
        return ValveModel(valve, flow_map, force_map, [FlowForceScale(scale=scale)], name="CFDA")

    scale = _fit_scalar(cfda_model, fit_line, (0.0, 2.0))
    cfda = cfda_model(scale)
    cfda_force = ValveModel(valve, OrificeFlowMap(BASIC_DISCHARGE_COEFFICIENT, valve.w), force_map,
                            [FlowForceScale(scale=scale)], name="CFDAForce")
    cfda_res = ValveModel(valve, flow_map, uniform, name="CFDARes")
    return PaperModels(bmbe, bmbebf, cfda, cfda_force, cfda_res, fitted_cd, scale)
