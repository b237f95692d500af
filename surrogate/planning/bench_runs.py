"""Which bench run would tell two look-alike candidates apart.

Two candidates that change the log's prediction the same way (a spring-preload offset and a
pilot-transducer offset both act as a constant force) cannot be told apart on that log. They may
differ elsewhere: at another oil temperature, another pilot set point, another back pressure.
This module replays both fitted models over runs the bench could make next: each run of the log
as a template, moved to every combination of

* temperatures: the log's, and 10 K below and above its range;
* pilot set points p_Pe: the log's, and 15 bar below and 20 bar above its range;
* back pressures: the template's, and 10 bar above it,

leaving out the combinations the log already holds (the data have seen them). The run where
the two predictions differ most, against the noise floor, is the one to make; if none differs
by the noise floor, no such run decides and a dedicated test (a calibration, a part swap) must.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..data.loaders import BenchLog
from ..effects import PerRunEffect
from ..fitting.residuals import replay_log
from ..model import ValveModel
from ..core.units import BAR, from_si, to_si

TEMPERATURE_STEP = 10.0  # [K] beyond the log's range
SET_POINT_BELOW, SET_POINT_ABOVE = 15.0 * BAR, 20.0 * BAR  # [Pa] beyond the log's range
BACK_PRESSURE_STEP = 10.0 * BAR  # [Pa] above the template's
EVERY = 4  # every how many samples of a template run to replay (a ramp needs no more)


def search_range() -> str:
    """The runs :func:`candidate_runs` tries, in words."""
    return (f"within {TEMPERATURE_STEP:.0f} K, {from_si(SET_POINT_BELOW, 'bar'):.0f} bar below "
            f"and {from_si(SET_POINT_ABOVE, 'bar'):.0f} bar above the log's settings, or with "
            f"{from_si(BACK_PRESSURE_STEP, 'bar'):.0f} bar more back pressure")


@dataclass(frozen=True)
class Separation:
    """The bench run where two models' Δp predictions differ most.

    Attributes
    ----------
    temperature : float
        Oil temperature of the run [K].
    set_point : float
        Pilot set point p_Pe [Pa].
    back_pressure_rise : float
        Back pressure above the template run's [Pa].
    difference : float
        RMS of the two predictions' difference over the run [Pa].
    noise_floor : float
        The log's noise floor [Pa], for scale.
    between : tuple of str
        Names of what the two models stand for.
    """

    temperature: float
    set_point: float
    back_pressure_rise: float
    difference: float
    noise_floor: float
    between: tuple[str, str] = ("first", "second")

    @property
    def decides(self) -> bool:
        """Whether the run separates the two by more than the noise floor."""
        return self.difference > self.noise_floor

    def to_json(self) -> dict:
        return {"between": list(self.between),
                "temperature_degC": round(float(from_si(self.temperature, "degC")), 1),
                "p_Pe_bar": round(float(from_si(self.set_point, "bar")), 1),
                "back_pressure_rise_bar": round(float(from_si(self.back_pressure_rise, "bar")), 1),
                "difference_bar": round(float(from_si(self.difference, "bar")), 4),
                "decides": bool(self.decides)}

    def where(self) -> str:
        """The run's settings, in words ("at 10 °C and p_Pe = 35 bar ...")."""
        return (f"at {from_si(self.temperature, 'degC'):.0f} °C and p_Pe = "
                f"{from_si(self.set_point, 'bar'):.0f} bar"
                + (f" with {from_si(self.back_pressure_rise, 'bar'):.0f} bar more back pressure"
                   if self.back_pressure_rise else ""))

    def __str__(self) -> str:
        return f"a bench run {self.where()}"

    def gap(self) -> str:
        """How far apart the two predictions are on that run, in words."""
        return (f"{from_si(self.difference, 'bar'):.2f} bar RMS, "
                f"{self.difference / self.noise_floor:.1f}× the noise floor")


def candidate_runs(log: BenchLog) -> tuple[BenchLog, pd.DataFrame]:
    """The runs the bench could make next, as one log (a run per combination), and a table of
    their settings (``run``, ``temperature`` [K], ``set_point`` [Pa], ``rise`` [Pa])."""
    frame = log.frame
    by_run = frame.groupby("run", sort=False).agg(temperature=("temperature", "median"),
                                                  set_point=("p_Pe_nominal", "first"))
    # whole degrees Celsius, as a bench is set
    temperatures = to_si(np.unique(np.round(from_si(by_run["temperature"].to_numpy(), "degC"))),
                         "degC")
    temperatures = np.concatenate([[temperatures[0] - TEMPERATURE_STEP], temperatures,
                                   [temperatures[-1] + TEMPERATURE_STEP]])
    set_points = np.unique(by_run["set_point"].to_numpy())
    set_points = np.concatenate([[set_points[0] - SET_POINT_BELOW], set_points,
                                 [set_points[-1] + SET_POINT_ABOVE]])
    set_points = set_points[set_points > 0]
    measured = {(round(from_si(t, "degC")), s)
                for t, s in zip(by_run["temperature"], by_run["set_point"])}
    # the template for a set point: the log's run nearest to it (its ramp suits that opening)
    nearest = {s: by_run.index[int(np.argmin(np.abs(by_run["set_point"].to_numpy() - s)))]
               for s in set_points}
    templates = {s: frame[frame["run"] == run].iloc[::EVERY] for s, run in nearest.items()}
    pieces, settings = [], []
    for temperature in temperatures:
        for set_point in set_points:
            for rise in (0.0, BACK_PRESSURE_STEP):
                if rise == 0.0 and (round(from_si(temperature, "degC")), set_point) in measured:
                    continue
                template = templates[set_point].copy()
                name = f"next{len(settings) + 1:03d}"
                shift = set_point - template["p_Pe_nominal"].iloc[0]
                template["run"] = name
                template["temperature"] = temperature
                template["p_Pe_nominal"] = set_point
                template["p_P"] = template["p_P"] + shift + rise
                template["p_B"] = template["p_B"] + rise
                template["p_L"] = template["p_L"] + rise
                pieces.append(template)
                settings.append({"run": name, "temperature": temperature,
                                 "set_point": set_point, "rise": rise})
    runs = BenchLog(pd.concat(pieces, ignore_index=True), f"runs to make after {log.source}")
    return runs, pd.DataFrame(settings)


def separating_run(first: ValveModel, second: ValveModel, log: BenchLog, noise_floor: float,
                   between: tuple[str, str] = ("first", "second")) -> Separation | None:
    """The candidate run (:func:`candidate_runs`) where the two fitted models' Δp differ most,
    or None when they cannot be compared there (a parameter per run of ``log``, which a new run
    does not have, or no run both models solve)."""
    if any(isinstance(effect, PerRunEffect) for model in (first, second)
           for effect in model.effects):
        return None
    runs, settings = candidate_runs(log)
    a = replay_log(first, runs, diagnostics=False).replay.dp
    b = replay_log(second, runs, diagnostics=False).replay.dp
    difference = pd.Series((a - b) ** 2).groupby(runs.frame["run"].to_numpy()).mean()
    difference = np.sqrt(difference.dropna())
    if difference.empty:
        return None
    best = settings.set_index("run").loc[difference.idxmax()]
    return Separation(float(best["temperature"]), float(best["set_point"]), float(best["rise"]),
                      float(difference.max()), float(noise_floor), between)
