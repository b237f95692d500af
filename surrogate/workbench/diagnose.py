"""Which physical effect is the model missing? Refit with each candidate and judge the gain.

Procedure
---------
1. Replay the model over the log: residual r0, its noise floor σ (:func:`.residuals.noise_floor`)
   and its effective number of independent samples n_eff (:func:`.residuals.effective_samples`).
2. *Linearise*: one finite-difference replay per free parameter of the model (shared by every
   candidate) and per parameter of each candidate effect.
3. *Refit* every candidate together with the model's free parameters: bounded linear least
   squares on the linearisation, then up to four Gauss–Newton steps in which every new point is
   replayed for real and the Jacobian is corrected by Broyden's update (one replay per step
   instead of one per parameter); a step that lowers the RSS by less than
   :data:`SETTLED_GAIN` of it ends the refit. Only the four front runners after the first real
   replay (and any as good as the last of them) take those steps; the others keep the RMS of
   that first replay, an upper bound, as they are far behind. The reported RMS is that of a real
   replay at the reported parameters, never a linear estimate. Standard errors come from the
   final Jacobian, inflated by √(n/n_eff) because the samples are not independent. The
   candidates are independent of each other and are refitted side by side on threads
   (:mod:`..parallel`).
4. Judge each candidate by ΔBIC = n_eff·ln(RSS_after/RSS_before) + k·ln(n_eff), with k its
   number of parameters the data inform, and rank them by it, best (most negative) first: among
   candidates with as many parameters this is the order of their RMS.

Significance rule
-----------------
A candidate is **significant** when all three hold:

* ΔBIC < −10 (very strong evidence, Kass & Raftery), counted with n_eff so that residuals
  correlated in time do not pass as thousands of independent samples;
* the residual before is not already noise: RMS_before > 1.1·σ;
* the gain is more than a sliver of noise: RMS_before − RMS_after > 0.05·σ.

Candidates that change the model's prediction the same way (cosine of their prediction changes
above 0.98) while the data prefer neither (|ΔBIC between them| < 10) cannot be told apart on
these data — a spring preload offset and a pilot-transducer offset both act as a constant force —
and are reported as one group.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import lsq_linear

from ..data.loaders import BenchLog
from ..effects import REGISTRY, Effect, effect_class
from ..fitting import FAILURE_RESIDUAL, free_parameters
from ..model import ValveModel
from ..parallel import map_threads
from ..units import from_si
from .fit import felt, probe_change
from .residuals import LogReplay, effective_samples, noise_floor, replay_log, run_rows

BIC_THRESHOLD = -10.0
NOISE_MARGIN = 1.1  # the residual must exceed the noise floor by 10 %
GAIN_FRACTION = 0.05  # and a candidate must remove at least 5 % of the noise floor
# a residual within 1.3x the noise floor counts as noise in the summary: the floor estimate runs
# ~10 % low when friction holds the piston (input noise then reaches Δp in bursts, not white)
NOISE_LEVEL = 1.3
SAME_DIRECTION = 0.98  # cosine of two prediction changes above which they act alike
REFINE_STEPS = 4  # Gauss–Newton steps per front-running candidate after the linear solution
REFINED = 4  # candidates refined by those steps (with any as good as the last of them)


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
    group: list[str] = field(default_factory=list)
    params: list = field(default_factory=list)  # fitted Parameters of the candidate
    change: np.ndarray | None = field(default=None, repr=False)  # prediction change [Pa]
    model: ValveModel | None = field(default=None, repr=False)  # the current model + this effect
    replay: LogReplay | None = field(default=None, repr=False)  # its replay of the log

    def to_json(self) -> dict:
        return {
            "name": self.name, "description": self.description, "title": self.title,
            "kind": self.kind, "rms_after_bar": round(float(from_si(self.rms_after, "bar")), 4),
            "delta_bic": round(float(self.delta_bic), 2), "significant": bool(self.significant),
            "group": self.group,
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
    """The registered effects the model does not have (or those named).

    Raises
    ------
    InputError
        For a name no effect is registered under.
    """
    chosen = REGISTRY if names is None else {name: effect_class(name) for name in names}
    return [cls for name, cls in chosen.items() if not model.has_effect(name)]


def diagnose(model: ValveModel, log: BenchLog, *, candidates: Iterable[str] | None = None,
             base: LogReplay | None = None, steps: int = REFINE_STEPS,
             progress=None, workers: int | None = None) -> Diagnosis:
    """Rank the candidate effects by how much of the residual they explain (see module doc).

    Parameters
    ----------
    model : ValveModel
        The current model, with its free parameters already fitted to ``log``.
    log : BenchLog
    candidates : iterable of str, optional
        Effect names to try; default every registered effect the model lacks.
    base : LogReplay, optional
        The model's replay of ``log``, if already computed.
    steps : int
        Gauss–Newton steps (one replay each) per candidate after the linear solution.
    progress : callable, optional
        Called with a line of text as the work proceeds.
    workers : int, optional
        Threads refitting candidates side by side (default :func:`..parallel.default_workers`);
        the result does not depend on it.
    """
    say = progress or (lambda message: None)
    base = base or replay_log(model, log)
    residual = base.residual
    ok = np.isfinite(residual)
    rss_before = float(np.sum(residual[ok] ** 2))
    rms_before = float(np.sqrt(rss_before / ok.sum()))
    floor = noise_floor(residual, base.runs)
    n_eff = effective_samples(residual, base.runs)
    problem = _Problem(log, base, ok, n_eff, rss_before)

    own = free_parameters(model)
    say(f"linearising the replay in the model's {len(own)} free parameter(s)")
    own_columns = [column for column in map_threads(
        lambda entry: problem.column(model, entry[1].name, entry[2].name), own, workers=workers)
        if column.felt]
    classes = candidate_effects(model, candidates)

    def linearise(cls: type[Effect]) -> tuple[type[Effect], ValveModel, list[_Column]]:
        trial = model.copy()
        trial.effects.append(cls.for_runs(log.run_ids))
        columns = [problem.column(trial, cls.name, name)
                   for name, parameter in trial.effect(cls.name).params.items() if parameter.vary]
        # a parameter the data do not feel (a run's pilot offset while its piston sits on the
        # stop) stays where it is: an empty column leaves the linear step undetermined
        return cls, trial, [c for c in columns if c.felt]

    def first_step(entry) -> _Refit:
        cls, trial, columns = entry
        return _Refit(problem, cls, trial, own_columns + columns, len(columns)).advance(1)

    # the candidates are independent: linearise and refit them side by side. Every candidate gets
    # its linear solution replayed for real; only the front runners are refined further, the
    # others keep that first real RMS (an upper bound: refining only lowers it)
    linearised = list(map_threads(linearise, classes, workers=workers))
    refits = list(map_threads(first_step, linearised, workers=workers))
    first = [refit.candidate() for refit in refits]
    chosen = _front_runners(first)
    refined = dict(zip(chosen, map_threads(lambda i: refits[i].advance(steps).candidate(),
                                           chosen, workers=workers)))
    results = [refined.get(i, candidate) for i, candidate in enumerate(first)]
    for number, candidate in enumerate(results, start=1):
        say(f"  [{number}/{len(classes)}] {candidate.name}: rms "
            f"{from_si(candidate.rms_after, 'bar'):.3f} bar, ΔBIC {candidate.delta_bic:.1f}"
            + ("" if number - 1 in refined else " (not refined)"))
    # best first by ΔBIC, which weighs the gain against the parameters it took (an offset per
    # run always fits a little better than one offset; it must fit better by enough)
    results.sort(key=lambda c: (c.delta_bic, c.rms_after))
    for candidate in results:
        candidate.significant = (candidate.delta_bic < BIC_THRESHOLD
                                 and rms_before > NOISE_MARGIN * floor
                                 and rms_before - candidate.rms_after > GAIN_FRACTION * floor)
    _group(results, n_eff)
    correlations = residual_correlations(base)
    diagnosis = Diagnosis(model, base, rms_before, floor, n_eff, results, correlations, "")
    diagnosis.summary = summarise(diagnosis)
    return diagnosis


@dataclass
class _Column:
    """One parameter's column of the replay's Jacobian: (Δp change per step) and the step [SI]."""

    effect: str
    parameter: str
    step: float
    change: np.ndarray
    felt: bool = True  # whether the data determine the parameter (:func:`.fit.felt`)


@dataclass
class _Problem:
    """The log, the base replay and what the refits share."""

    log: BenchLog
    base: LogReplay
    ok: np.ndarray
    n_eff: float
    rss_before: float

    def replay(self, model: ValveModel) -> LogReplay:
        return replay_log(model, self.log, guess=self.base, extrapolation=False)

    def column(self, model: ValveModel, effect_name: str, parameter_name: str) -> _Column:
        """∂Δp/∂parameter · step by a forward difference, warm-started from the base replay; a
        parameter scoped to one run replays that run only."""
        scope = model.effect(effect_name).params[parameter_name].scope
        if scope is None:
            step, change = probe_change(model, effect_name, parameter_name, self.log, self.base)
            determined = felt(change[self.ok], scoped=False)
        else:
            rows = run_rows(self.log, scope)
            step, in_run = probe_change(model, effect_name, parameter_name, self.log.take(rows),
                                        self.base.take(rows))
            determined = felt(in_run, scoped=True)
            change = np.zeros(len(self.ok))
            change[rows] = in_run
        return _Column(effect_name, parameter_name, step,
                       np.where(np.isfinite(change), change, 0.0)[self.ok], determined)


#: a Gauss–Newton step that lowers the RSS by less than this share of it ends a refit: the RMS
#: is then settled to 5e-5 of itself, and ΔBIC to ~1e-4·n_eff, a fraction of its threshold
SETTLED_GAIN = 1e-4


class _Refit:
    """Bounded Gauss–Newton with Broyden updates in z = (parameter − start)/step, which can be
    resumed: every candidate takes its first step, the front runners take more."""

    def __init__(self, problem: _Problem, cls, trial: ValveModel, columns: list[_Column],
                 extra: int):
        self.problem, self.cls, self.trial, self.extra = problem, cls, trial, extra
        self.parameters = [trial.effect(c.effect).params[c.parameter] for c in columns]
        self.start = np.array([p.value for p in self.parameters])
        self.scale = np.array([c.step for c in columns])
        lower = np.array([(p.min - p.value) / c.step for p, c in zip(self.parameters, columns)])
        upper = np.array([(p.max - p.value) / c.step for p, c in zip(self.parameters, columns)])
        self.lower, self.upper = np.minimum(lower, upper), np.maximum(lower, upper)
        self.jacobian = np.column_stack([c.change for c in columns])
        self.base_residual = problem.base.residual[problem.ok]
        self.best_z = np.zeros(len(columns))
        self.best_residual, self.best_replay = self.base_residual, problem.base
        self.best_rss = problem.rss_before
        self.z, self.r = self.best_z, self.base_residual
        self.replays = 0
        self.settled = False

    def advance(self, steps: int) -> "_Refit":
        """Take up to ``steps`` more steps, each one real replay; stop early once settled."""
        for _ in range(steps):
            if self.settled:
                break
            self._step()
        return self

    def _step(self) -> None:
        target = lsq_linear(self.jacobian, -self.r + self.jacobian @ self.z,
                            bounds=(self.lower, self.upper)).x
        if np.allclose(target, self.z, rtol=0, atol=1e-4):
            self.settled = True
            return
        self._assign(target)
        played = self.problem.replay(self.trial)
        self.replays += 1
        new = played.residual[self.problem.ok]
        new = np.where(np.isfinite(new), new, FAILURE_RESIDUAL)
        # Broyden: make the Jacobian reproduce the change just observed
        dz = target - self.z
        self.jacobian = self.jacobian + np.outer((new - self.r) - self.jacobian @ dz,
                                                 dz) / float(dz @ dz)
        rss = float(np.sum(new**2))
        # the first replay is the linear solution, judged against the model without the
        # candidate; after that, a step that gains (almost) nothing means the refit is done
        if self.replays > 1 and rss > (1.0 - SETTLED_GAIN) * self.best_rss:
            self.settled = True
        if rss < self.best_rss:
            self.best_z, self.best_residual, self.best_replay = target, new, played
            self.best_rss = rss
            self.z, self.r = target, new
        else:  # the updated Jacobian proposes a new step from the best point so far
            self.z, self.r = self.best_z, self.best_residual

    def _assign(self, z) -> None:
        values = np.clip(self.start + self.scale * z, [p.min for p in self.parameters],
                         [p.max for p in self.parameters])
        for parameter, value in zip(self.parameters, values):
            parameter.value = float(value)

    def candidate(self) -> Candidate:
        """The candidate at the best point so far, with standard errors."""
        self._assign(self.best_z)
        self._standard_errors()
        problem = self.problem
        change = np.zeros(len(problem.ok))
        change[problem.ok] = self.best_residual - self.base_residual
        cls = self.cls
        own = [p for p in self.trial.effect(cls.name).params.values()]
        return Candidate(cls.name, cls.title, cls.describe(), cls.kind,
                         float(np.sqrt(self.best_rss / problem.ok.sum())),
                         _delta_bic(self.best_rss, problem.rss_before, problem.n_eff, self.extra),
                         params=own, change=change, model=self.trial, replay=self.best_replay)

    def _standard_errors(self) -> None:
        residual, parameters = self.best_residual, self.parameters
        count = len(residual)
        dof = max(count - len(parameters), 1)
        variance = float(np.sum(residual**2)) / dof * count / self.problem.n_eff
        try:
            covariance = np.linalg.pinv(self.jacobian.T @ self.jacobian) * variance
        except np.linalg.LinAlgError:
            covariance = np.full((len(parameters),) * 2, np.nan)
        errors = np.sqrt(np.clip(np.diag(covariance), 0.0, None)) * np.abs(self.scale)
        for parameter, error in zip(parameters, errors):
            usable = np.isfinite(error) and not parameter.at_bound
            parameter.stderr = float(error) if usable else None


def _front_runners(candidates: list[Candidate]) -> list[int]:
    """Indices of the candidates worth refining: the :data:`REFINED` best by ΔBIC after their
    first real replay, and any within 2·|:data:`BIC_THRESHOLD`| of the last of those (so that
    two candidates the data may not tell apart are refined alike)."""
    order = sorted(range(len(candidates)), key=lambda i: candidates[i].delta_bic)
    if len(order) <= REFINED:
        return order
    cut = candidates[order[REFINED - 1]].delta_bic - 2.0 * BIC_THRESHOLD
    return [i for i in order if candidates[i].delta_bic <= cut]


def _delta_bic(rss_after: float, rss_before: float, n_eff: float, extra: int) -> float:
    return float(n_eff * np.log(max(rss_after, 1e-300) / rss_before) + extra * np.log(n_eff))


def _group(candidates: list[Candidate], n_eff: float) -> None:
    """Group candidates the data cannot tell apart.

    Two candidates are one group when they change the prediction the same way (the cosine of
    their prediction changes exceeds :data:`SAME_DIRECTION`) and the data do not prefer either
    (their BICs differ by less than :data:`BIC_THRESHOLD` in size).
    """
    for candidate in candidates:
        candidate.group = [candidate.name]
    for i, a in enumerate(candidates):
        for b in candidates[i + 1:]:
            size = np.linalg.norm(a.change) * np.linalg.norm(b.change)
            if size == 0:
                continue
            cosine = float(a.change @ b.change) / size
            if cosine > SAME_DIRECTION and abs(a.delta_bic - b.delta_bic) < -BIC_THRESHOLD:
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
        if diagnosis.rms_before <= NOISE_LEVEL * diagnosis.noise_floor:
            return (f"Nothing beyond noise is left: the residual RMS ({before:.2f} bar) is within "
                    f"{NOISE_LEVEL:.1f}x the noise floor ({floor:.2f} bar) and no candidate "
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
