"""Which physical effect is the model missing? Refit with each candidate and judge the gain.

Procedure
---------
1. Replay the model over the log: residual r0, its noise floor σ (:func:`.residuals.noise_floor`)
   and its effective number of independent samples n_eff (:func:`.residuals.effective_samples`).
2. *Screen* every candidate (each library effect the model lacks, and custom ones): linearise the
   replay around the current parameters, one finite-difference replay per parameter (the model's
   own columns are shared by all candidates), and solve the bounded linear least-squares problem
   for the model's parameters together with the candidate's.
3. *Refit* the most promising candidates for real (nonlinear least squares over every free
   parameter, starting from the linear solution); their RMS, parameters and standard errors are
   the reported ones. The others keep their screening estimate, marked as such.
4. Judge each candidate by ΔBIC = n_eff·ln(RSS_after/RSS_before) + k·ln(n_eff), with k its
   number of parameters.

Significance rule
-----------------
A candidate is **significant** when all three hold:

* ΔBIC < −10 (very strong evidence, Kass & Raftery), counted with n_eff so that residuals
  correlated in time do not pass as thousands of independent samples;
* the residual before is not already noise: RMS_before > 1.1·σ;
* the gain is more than a sliver of noise: RMS_before − RMS_after > 0.05·σ.

Candidates that change the model's prediction the same way (the difference between their
prediction changes is under 5 % of either) cannot be told apart on these data — a spring preload
offset and a pilot-transducer offset both act as a constant force — and are reported as one group.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import lsq_linear

from ..data.loaders import BenchLog
from ..effects import REGISTRY, Effect
from ..fitting import free_parameters
from ..model import ValveModel
from ..units import from_si
from .fit import fit_to_log
from .residuals import LogReplay, effective_samples, noise_floor, replay_log

BIC_THRESHOLD = -10.0
NOISE_MARGIN = 1.1  # the residual must exceed the noise floor by 10 %
GAIN_FRACTION = 0.05  # and a candidate must remove at least 5 % of the noise floor
SAME_CHANGE = 0.05  # prediction changes within 5 % of each other: indistinguishable
REFITS = 4  # candidates refitted for real after screening
_STEP_FRACTION = 0.02  # finite-difference step: 2 % of a parameter's range (or of its value)


@dataclass
class Candidate:
    """One candidate effect, refitted together with the model's free parameters."""

    name: str
    title: str
    description: str
    kind: str
    rms_after: float  # [Pa]
    delta_bic: float
    significant: bool = False
    refitted: bool = False  # False: the numbers are the linearised screening estimate
    group: list[str] = field(default_factory=list)
    params: list = field(default_factory=list)  # fitted Parameters of the candidate
    change: np.ndarray | None = field(default=None, repr=False)  # prediction change [Pa]
    model: ValveModel | None = field(default=None, repr=False)

    def to_json(self) -> dict:
        return {
            "name": self.name, "description": self.description, "title": self.title,
            "kind": self.kind, "rms_after_bar": round(float(from_si(self.rms_after, "bar")), 4),
            "delta_bic": round(float(self.delta_bic), 2), "significant": bool(self.significant),
            "refitted": self.refitted, "group": self.group,
            "params": {p.name: {"value": p.display_value, "unit": p.unit,
                                "stderr": p.display_stderr} for p in self.params},
        }


@dataclass
class Diagnosis:
    """The result of :func:`diagnose`."""

    model: ValveModel
    base: LogReplay
    rms_before: float  # [Pa]
    noise_floor: float  # [Pa]
    effective_samples: float
    candidates: list[Candidate]
    correlations: dict[str, float]
    summary: str

    @property
    def best(self) -> Candidate | None:
        """The best significant candidate, or None."""
        return next((c for c in self.candidates if c.significant), None)

    def to_json(self) -> dict:
        return {"model": self.model.name,
                "rms_before_bar": round(float(from_si(self.rms_before, "bar")), 4),
                "noise_floor_bar": round(float(from_si(self.noise_floor, "bar")), 4),
                "effective_samples": round(self.effective_samples, 1),
                "summary": self.summary,
                "candidates": [c.to_json() for c in self.candidates],
                "residual_correlations": {k: round(v, 3) for k, v in self.correlations.items()}}


def candidate_effects(model: ValveModel, names: Iterable[str] | None = None) -> list[type[Effect]]:
    """The registered effects the model does not have (or those named)."""
    chosen = REGISTRY if names is None else {name: REGISTRY[name] for name in names}
    return [cls for name, cls in chosen.items() if not model.has_effect(name)]


def diagnose(model: ValveModel, log: BenchLog, *, candidates: Iterable[str] | None = None,
             base: LogReplay | None = None, refits: int = REFITS, progress=None) -> Diagnosis:
    """Rank the candidate effects by how much of the residual they explain (see module doc)."""
    say = progress or (lambda message: None)
    base = base or replay_log(model, log)
    residual = base.residual
    ok = np.isfinite(residual)
    rss_before = float(np.sum(residual[ok] ** 2))
    rms_before = float(np.sqrt(rss_before / ok.sum()))
    floor = noise_floor(residual, base.runs)
    n_eff = effective_samples(residual, base.runs)

    own = free_parameters(model)
    say(f"screening: linearising the replay in the model's {len(own)} free parameter(s)")
    own_columns = [_column(model, log, base, name, effect.name, parameter.name)
                   for name, effect, parameter in own]
    screened = []
    for cls in candidate_effects(model, candidates):
        trial = model.copy()
        effect = cls()
        trial.effects.append(effect)
        columns, steps = [], []
        for parameter in effect.params.values():
            if parameter.vary:
                columns.append(_column(trial, log, base, f"{cls.name}.{parameter.name}",
                                       cls.name, parameter.name))
        screened.append(_screen(cls, trial, own, own_columns, columns, residual, ok, n_eff,
                                rss_before))
    screened.sort(key=lambda c: c.rms_after)
    say(f"screened {len(screened)} candidates; refitting the best {min(refits, len(screened))}")

    for candidate in screened[:refits]:
        result = fit_to_log(candidate.model, log, start=base)
        played = replay_log(result.model, log, guess=base, extrapolation=False)
        fitted_ok = np.isfinite(played.residual) & ok
        rss = float(np.sum(played.residual[fitted_ok] ** 2)) * ok.sum() / max(fitted_ok.sum(), 1)
        candidate.rms_after = float(np.sqrt(rss / ok.sum()))
        candidate.delta_bic = _delta_bic(rss, rss_before, n_eff, len(_own_params(candidate)))
        candidate.params = [p for p in result.model.effect(candidate.name).params.values()]
        candidate.change = np.where(fitted_ok, played.replay.dp - base.replay.dp, 0.0)
        candidate.model = result.model
        candidate.refitted = True
        say(f"  {candidate.name}: rms {from_si(candidate.rms_after, 'bar'):.3f} bar, "
            f"ΔBIC {candidate.delta_bic:.1f}")
    screened.sort(key=lambda c: (not c.refitted, c.rms_after))

    for candidate in screened:
        candidate.significant = (candidate.delta_bic < BIC_THRESHOLD
                                 and rms_before > NOISE_MARGIN * floor
                                 and rms_before - candidate.rms_after > GAIN_FRACTION * floor)
    _group(screened)
    correlations = residual_correlations(base)
    diagnosis = Diagnosis(model, base, rms_before, floor, n_eff, screened, correlations, "")
    diagnosis.summary = summarise(diagnosis)
    return diagnosis


def _own_params(candidate: Candidate) -> list[str]:
    return [p.name for p in candidate.model.effect(candidate.name).params.values() if p.vary]


def _step(parameter) -> float:
    span = parameter.max - parameter.min
    step = _STEP_FRACTION * (span if np.isfinite(span) else max(abs(parameter.value), 1.0))
    return step if parameter.value + step <= parameter.max else -step


def _column(model: ValveModel, log: BenchLog, base: LogReplay, label: str, effect_name: str,
            parameter_name: str) -> tuple[str, float, np.ndarray]:
    """(label, step, ∂Δp/∂parameter · step) by a forward difference, warm-started."""
    trial = model.copy()
    parameter = trial.effect(effect_name).params[parameter_name]
    step = _step(parameter)
    parameter.value += step
    played = replay_log(trial, log, guess=base, extrapolation=False)
    change = np.where(np.isfinite(played.replay.dp) & np.isfinite(base.replay.dp),
                      played.replay.dp - base.replay.dp, 0.0)
    return label, step, change


def _screen(cls, trial: ValveModel, own, own_columns, columns, residual, ok, n_eff,
            rss_before) -> Candidate:
    """Bounded linear least squares in the model's and the candidate's parameters."""
    all_columns = own_columns + columns
    parameters = [p for _, _, p in own] + [p for p in trial.effect(cls.name).params.values()
                                           if p.vary]
    if not all_columns:
        change = np.zeros_like(residual)
        solution = np.zeros(0)
    else:
        matrix = np.column_stack([c for _, _, c in all_columns])[ok]
        steps = np.array([s for _, s, _ in all_columns])
        lower = np.array([(p.min - p.value) / s for p, s in zip(parameters, steps)])
        upper = np.array([(p.max - p.value) / s for p, s in zip(parameters, steps)])
        lower, upper = np.minimum(lower, upper), np.maximum(lower, upper)
        solution = lsq_linear(matrix, -residual[ok], bounds=(lower, upper)).x
        change = np.zeros_like(residual)
        change[ok] = matrix @ solution
        for parameter, step, weight in zip(parameters, steps, solution):
            parameter.value = float(np.clip(parameter.value + step * weight, parameter.min,
                                            parameter.max))
    rss = float(np.sum((residual[ok] + change[ok]) ** 2))
    k = len(columns)
    return Candidate(cls.name, cls.title, cls.describe(), cls.kind, float(np.sqrt(rss / ok.sum())),
                     _delta_bic(rss, rss_before, n_eff, k), change=change, model=trial,
                     params=list(trial.effect(cls.name).params.values()))


def _delta_bic(rss_after: float, rss_before: float, n_eff: float, extra: int) -> float:
    return float(n_eff * np.log(max(rss_after, 1e-300) / rss_before) + extra * np.log(n_eff))


def _group(candidates: list[Candidate]) -> None:
    """Put candidates whose prediction changes agree within 5 % into one group."""
    for candidate in candidates:
        candidate.group = [candidate.name]
    for i, a in enumerate(candidates):
        for b in candidates[i + 1:]:
            if a.change is None or b.change is None:
                continue
            size = max(np.linalg.norm(a.change), np.linalg.norm(b.change))
            if size > 0 and np.linalg.norm(a.change - b.change) <= SAME_CHANGE * size:
                a.group.append(b.name)
                b.group.append(a.name)


CORRELATION_VARIABLES = ("q", "p_L", "p_P", "p_B", "p_Pe", "temperature", "|p_L - p_P|")


def residual_correlations(base: LogReplay) -> dict[str, float]:
    """Pearson correlation of the residual with candidate variables, and of the residual signed
    by the ramp direction (a hysteresis misfit) with the same variables."""
    frame = base.log.frame
    values = {"q": frame["q"], "p_L": frame["p_L"], "p_P": frame["p_P"], "p_B": frame["p_B"],
              "p_Pe": frame["p_P"] - frame["p_B"], "temperature": frame["temperature"],
              "|p_L - p_P|": (frame["p_L"] - frame["p_P"]).abs()}
    ok = np.isfinite(base.residual)
    signed = base.residual * np.where(frame["direction"].to_numpy() == "up", 1.0, -1.0)
    result = {}
    for name, series in values.items():
        x = np.asarray(series, float)[ok]
        if np.std(x) == 0:
            continue
        result[f"residual~{name}"] = float(np.corrcoef(base.residual[ok], x)[0, 1])
        result[f"hysteresis~{name}"] = float(np.corrcoef(signed[ok], x)[0, 1])
    return result


def summarise(diagnosis: Diagnosis) -> str:
    """A plain sentence naming the most likely missing effect, or saying that none is left."""
    before = from_si(diagnosis.rms_before, "bar")
    floor = from_si(diagnosis.noise_floor, "bar")
    best = diagnosis.best
    if best is None:
        if diagnosis.rms_before <= NOISE_MARGIN * diagnosis.noise_floor:
            return (f"Nothing beyond noise is left: the residual RMS ({before:.2f} bar) is within "
                    f"{NOISE_MARGIN:.1f}x the noise floor ({floor:.2f} bar) and no candidate "
                    "improves the model significantly.")
        return (f"No candidate in the library explains the residual significantly, but it "
                f"({before:.2f} bar) is still {before / floor:.1f}x the noise floor "
                f"({floor:.2f} bar): the missing physics may lie outside the library; a custom "
                "effect (--effects-file) can test a hypothesis.")
    params = ", ".join(str(p) for p in best.params if p.vary)
    sentence = (f"The most likely missing effect is {best.title} ({best.name}): adding it lowers "
                f"the residual RMS from {before:.2f} to {from_si(best.rms_after, 'bar'):.2f} bar "
                f"(noise floor {floor:.2f} bar, ΔBIC {best.delta_bic:.0f}) with {params}.")
    if len(best.group) > 1:
        others = [name for name in best.group if name != best.name]
        sentence += (f" These data cannot tell it apart from {', '.join(others)}, which changes "
                     "the prediction the same way; pick by physical knowledge or a dedicated test.")
    return sentence
