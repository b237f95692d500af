"""The paper's comparison on a bench log: Table 5 (model accuracy) and Table 6 (friction).

:func:`reproduce` runs the whole comparison and returns plain records; :mod:`.figures` and
:mod:`.report` turn them into figures and files.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import pandas as pd

from ..data.loaders import BenchLog, BenchRun
from ..core.errors import InputError
from ..fitting.logfit import fit_to_log
from ..fitting.residuals import run_rows
from ..maps.registry import MapsSpec
from ..description.presets import TABLE6_FRICTION_START
from ..description.spec import ValveSource
from ..core.units import from_si
from .median import median_line
from .models import FIT_P_PE, FIT_TEMPERATURE, PaperModels, build_paper_models, mean_abs_distance

TABLE5_P_PE_BAR = (50.0, 65.0, 80.0)
TABLE6_P_PE_BAR = (65.0, 50.0)
TEMPERATURES_C = (20.0, 40.0, 60.0)
_TEMPERATURE_MATCH = 5.0  # [K] a run belongs to a nominal temperature within this


def category(mean_abs_bar: float) -> str:
    """The paper's accuracy classes: "++" below 5 bar, "−" above 15 bar, "+" in between.

    The paper's legend calls "+" "more than 10 bar" and leaves 5–10 bar unnamed; here "+" covers
    all of 5–15 bar.
    """
    if mean_abs_bar < 5.0:
        return "++"
    if mean_abs_bar <= 15.0:
        return "+"
    return "-"


def find_run(log: BenchLog, p_Pe_bar: float, temperature_C: float) -> BenchRun:
    """The run at set point ``p_Pe_bar`` whose mean temperature is nearest ``temperature_C``."""
    candidates = [run for run in log.runs()
                  if abs(from_si(run.p_Pe_nominal, "bar") - p_Pe_bar) < 0.5
                  and abs(from_si(run.temperature, "degC") - temperature_C) < _TEMPERATURE_MATCH]
    if not candidates:
        raise InputError(f"{log.source}: no run at p_Pe = {p_Pe_bar:g} bar and "
                         f"{temperature_C:g} °C (±{_TEMPERATURE_MATCH:g} K); the paper's "
                         "comparison needs runs at 50, 65 and 80 bar and 20, 40 and 60 °C")
    return min(candidates,
               key=lambda run: abs(from_si(run.temperature, "degC") - temperature_C))


@dataclass(frozen=True)
class PaperComparison:
    """Everything the paper's comparison produced (SI inside; records in display units)."""

    models: PaperModels
    lines: dict[str, pd.DataFrame]  # run id -> median line
    runs: dict[tuple[float, float], BenchRun]  # (p_Pe bar, °C) -> run
    table5: list[dict] = field(default_factory=list)
    table6: list[dict] = field(default_factory=list)
    friction_models: dict[tuple[float, float], object] = field(default_factory=dict)

    def to_json(self) -> dict:
        return {
            "fitted": {"BMBEBF_discharge_coefficient": self.models.fitted_discharge_coefficient,
                       "CFDA_flow_force_scale": self.models.fitted_flow_force_scale},
            "table5": self.table5,
            "table6": self.table6,
        }


def reproduce(valve: ValveSource, maps: MapsSpec, log: BenchLog,
              progress: Callable[[str], None] = lambda message: None) -> PaperComparison:
    """Fit the paper's models on ``log`` and compute Tables 5 and 6.

    Parameters
    ----------
    valve, maps
        The valve and its CFD maps (grid or learned).
    log : BenchLog
        Needs runs at p_Pe = 50, 65 and 80 bar and 20, 40 and 60 °C.
    progress : callable
        Called with a short message at each step.
    """
    runs = {(p, t): find_run(log, p, t) for p in (*TABLE5_P_PE_BAR, 120.0) for t in TEMPERATURES_C
            if p != 120.0 or _has_run(log, p, t)}
    lines = {run.run: median_line(run) for run in runs.values()}
    fit_run = runs[(from_si(FIT_P_PE, "bar"), from_si(FIT_TEMPERATURE, "degC"))]
    progress(f"fitting BMBEBF and CFDA to the median line of run {fit_run.run}")
    models = build_paper_models(valve, maps, lines[fit_run.run])
    comparison = PaperComparison(models, lines, runs)

    progress("Table 5: mean distance from the median lines")
    for p_Pe in TABLE5_P_PE_BAR:
        for temperature in TEMPERATURES_C:
            line = lines[runs[(p_Pe, temperature)].run]
            for name, model in models.table5_models().items():
                distance = from_si(mean_abs_distance(model, line), "bar")
                comparison.table5.append({
                    "model": name, "p_Pe_bar": p_Pe, "temperature_C": temperature,
                    "mean_abs_bar": round(float(distance), 3), "category": category(distance)})

    for temperature in TEMPERATURES_C:
        for p_Pe in TABLE6_P_PE_BAR:
            run = runs[(p_Pe, temperature)]
            progress(f"Table 6: friction K1, K2 at {temperature:g} °C fitted to run {run.run} "
                     f"(p_Pe = {p_Pe:g} bar)")
            result = fit_friction(models, run, log)
            comparison.friction_models[(p_Pe, temperature)] = result.model
            K1 = result.model.effect("friction_constant").params["K1"]
            K2 = result.model.effect("friction_load_pressure").params["K2"]
            comparison.table6.append({
                "temperature_C": temperature, "fitted_on_p_Pe_bar": p_Pe,
                "K1_N": round(K1.display_value, 3), "K2_N_per_bar": round(K2.display_value, 5),
                "K1_stderr_N": _rounded(K1.display_stderr, 3),
                "K2_stderr_N_per_bar": _rounded(K2.display_stderr, 5),
                "rms_bar": round(float(from_si(result.rms, "bar")), 3)})
    return comparison


def fit_friction(models: PaperModels, run: BenchRun, log: BenchLog):
    """K1 and K2 of CFDA's Coulomb friction, fitted to every sample of ``run`` by replaying it
    as the workbench replays a log (:func:`surrogate.fitting.logfit.fit_to_log`)."""
    start = models.cfda_with_friction(**TABLE6_FRICTION_START)
    return fit_to_log(start, log.take(run_rows(log, run.run)),
                      ["friction_constant.K1", "friction_load_pressure.K2"], tolerance=1e-8,
                      max_evaluations=200)


def _has_run(log: BenchLog, p_Pe: float, temperature: float) -> bool:
    try:
        find_run(log, p_Pe, temperature)
    except InputError:
        return False
    return True


def _rounded(value, digits):
    return None if value is None else round(float(value), digits)
