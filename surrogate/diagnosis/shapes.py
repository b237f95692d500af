"""Fitting a shape-free effect (:mod:`surrogate.effects.shapes`) to a log, cheaply.

A shape-free term is linear in its coefficients: its hook's output is Σ_k c_k·b_k(x). To first
order, a sample's Δp answers a small extra hook output with a *sensitivity* that depends on the
sample's state, not on where the output came from. So one replay with a uniform output (a force
of 1 N everywhere, a friction band widened by 1 N ...) measures that sensitivity s at every
sample, and the Jacobian column of coefficient k is b_k(x)·s: a whole basis costs one replay,
not one per coefficient. Where friction holds the piston, a sample answers the output it met when
the piston last moved, not its own; the column is then approximate, and the refinement's real
replays (Gauss–Newton with Broyden updates,
:class:`~surrogate.fitting.leastsquares.Minimizer`) correct what it got wrong.

The roughness penalty's weight λ is chosen by the held-out runs: for each λ of
:data:`ROUGHNESS_WEIGHTS` the linearised fit is refitted without each run, each temperature and
each pilot pressure in turn (:class:`~surrogate.fitting.heldout.RunBlocks`, with the maps'
discrepancy), and the λ
that predicts the left-out runs best (pooled over the schemes) is kept.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from ..effects import BalanceState, Effect, FlowState, Parameter
from ..effects.shapes import NU_REFERENCE, PRESSURE_DROP, SHAPE_FREE, ShapeFreeEffect
from ..fitting.heldout import HEADLINE, POOLED, Linearised, RunBlocks, RunIndex
from ..fitting.logfit import ReadAlike, probe_change
from ..fitting.residuals import LogReplay
from ..fitting.leastsquares import Minimizer, bounded_linear_fit, compress
from ..model import ValveModel
from ..core.parallel import map_threads
from ..core.progress import Stage
from ..core.units import LPM, from_si, to_si
from .refit import candidate_of
from .result import Rival, ShapeCurve
from .rule import delta_bic

#: λ tried, relative to the columns' mean square (so that the choice does not depend on units)
ROUGHNESS_WEIGHTS = (1e-4, 1e-3, 1e-2, 1e-1, 1.0)


# --- probes: how Δp answers a uniform hook output ----------------------------------------------

class _Probe(Effect):
    """A uniform output ``v`` of one hook everywhere: the probe of :func:`sensitivities`."""

    category = "physics"
    title = "probe"


class _ForceProbe(_Probe):
    name, kind = "probe_force", "force"
    parameter_specs = (Parameter("v", 0.0, "N", min=-50.0, max=50.0),)

    def force(self, state: BalanceState) -> np.ndarray:
        return np.broadcast_to(self["v"], state.u.shape)


class _FrictionProbe(_Probe):
    name, kind = "probe_friction", "friction"
    parameter_specs = (Parameter("v", 0.0, "N", min=0.0, max=50.0),)

    def friction(self, state: BalanceState) -> np.ndarray:
        return np.broadcast_to(self["v"], state.u.shape)


class _LeakageProbe(_Probe):
    name, kind = "probe_leakage", "leakage"
    parameter_specs = (Parameter("v", 0.0, "L/min", min=0.0, max=5.0 * LPM),)

    def leakage(self, dp: np.ndarray, state: FlowState) -> np.ndarray:
        return np.where(dp > 0, self["v"], 0.0)


class _FlowForceProbe(_Probe):
    name, kind = "probe_flow_force", "force"
    parameter_specs = (Parameter("v", 0.0, "1", min=-1.0, max=1.0),)

    def force(self, state: BalanceState) -> np.ndarray:
        return self["v"] * state.flow_force


class _DischargeProbe(_Probe):
    name, kind = "probe_discharge", "flow"
    parameter_specs = (Parameter("v", 0.0, "1", min=-0.5, max=0.5),)

    def restriction_flow(self, q: np.ndarray, state: FlowState) -> np.ndarray:
        return q / (1.0 + self["v"])


#: the probe of each shape-free effect's hook, by what the shape scales
_PROBES = {"force": _ForceProbe, "friction": _FrictionProbe, "leakage": _LeakageProbe,
           "flow force": _FlowForceProbe, "discharge": _DischargeProbe}


def probe_of(cls: type[ShapeFreeEffect]) -> type[_Probe]:
    """The probe whose uniform output a shape of ``cls`` scales sample by sample."""
    if cls.kind == "flow":
        return _DischargeProbe
    if cls.kind == "force" and cls.value_unit == "1":
        return _FlowForceProbe
    return _PROBES[cls.kind]


def sensitivity(model: ValveModel, probe: type[_Probe], base: LogReplay,
                alike: ReadAlike | None = None) -> np.ndarray:
    """Δp's change [Pa] per SI unit of the probe's uniform output at every sample of ``base``'s
    log (0 where the model has no solution), from one replay warm-started at ``base``;
    ``alike``: the model's replay read from the tables, shared where it is the trial's too
    (:meth:`~surrogate.fitting.logfit.ReadAlike.extended_by`)."""
    trial = model.copy()
    trial.effects.append(probe())
    alike = alike and alike.extended_by(trial.effect(probe.name))
    step, change = probe_change(trial, probe.name, "v", base.log, base, alike)
    return np.where(np.isfinite(change), change, 0.0) / step


# --- the variables at the samples ----------------------------------------------------------------

def state_at_samples(model: ValveModel, base: LogReplay) -> dict[str, np.ndarray]:
    """Every shape's variable [SI] at each sample of ``base`` as the model sees it: the opening
    and Δp of its replay, the sensor-corrected readings, p_L = p_B + Δp, the oil's viscosity."""
    points = model.true_points(base.replay.points)
    dp = base.replay.dp
    return {"u": base.replay.u, "p_L": points.p_B + dp, "p_P": points.p_P, "p_B": points.p_B,
            "p_LP": points.p_B + dp - points.p_P, "nu": model.fluid(base.replay.points).nu,
            "q": points.q, "dp": dp}


def variable_values(cls: type[ShapeFreeEffect], state: dict[str, np.ndarray]) -> np.ndarray:
    return state[cls.variable.name]


def column_factor(cls: type[ShapeFreeEffect], state: dict[str, np.ndarray]) -> np.ndarray:
    """What multiplies the basis in the hook's output besides the coefficients (the laminar
    viscosity factor of a leakage, 1 otherwise)."""
    if cls.variable is PRESSURE_DROP:
        return NU_REFERENCE / state["nu"]
    return np.ones(len(state["u"]))


# --- the fit -------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ShapeColumns:
    """A shape-free effect on the log's knots and its linearised columns at the solved samples.

    Attributes
    ----------
    effect : ShapeFreeEffect
        The effect, off, on knots where the log's values of its variable lie.
    columns : numpy.ndarray
        (n, k) [Pa]: Δp's change at each solved sample for a step ``steps[j]`` of coefficient j.
    steps : numpy.ndarray
        (k,) [SI]: one display unit of each coefficient.
    roughness : numpy.ndarray
        The penalty's difference matrix over the coefficients (SI values).
    """

    effect: ShapeFreeEffect
    columns: np.ndarray
    steps: np.ndarray
    roughness: np.ndarray

    @property
    def scale(self) -> float:
        """The columns' mean square per coefficient [Pa²] (λ is relative to it)."""
        return float(np.sum(self.columns**2)) / max(self.columns.shape[1], 1)


def last_moving(x: np.ndarray, moving: np.ndarray, runs: np.ndarray) -> np.ndarray:
    """``x`` with each held sample's value replaced by that of the last sample of its run at
    which the piston moved (its own before the run's first move)."""
    frame = pd.DataFrame({"x": np.where(moving, x, np.nan), "run": runs})
    carried = frame.groupby("run", sort=False)["x"].ffill().to_numpy()
    return np.where(np.isfinite(carried), carried, x)


def shape_columns(cls: type[ShapeFreeEffect], state: dict[str, np.ndarray],
                  sensitivities: np.ndarray, ok: np.ndarray, moving: np.ndarray,
                  runs: np.ndarray, effect: ShapeFreeEffect | None = None) -> ShapeColumns:
    """The effect on knots at the values its variable takes where the piston moves (``moving``;
    where it rests on a stop or friction holds it, a shape's value changes nothing), or
    ``effect`` on its own knots, and its columns at the solved samples ``ok`` (``runs``: each
    sample's run)."""
    x = variable_values(cls, state)
    if effect is None:
        where = ok & moving & np.isfinite(x)
        effect = cls.on_knots(cls.knots_for(x[where if where.any() else ok & np.isfinite(x)]))
    steps = np.array([float(to_si(1.0, cls.value_unit) - to_si(0.0, cls.value_unit))]
                     * len(effect.coefficients))
    # A held piston stays where the shape's output put it when it last moved: that part of a
    # held sample's answer is the output at that moment. A flow or a leakage also acts on the
    # held sample itself, through the restriction at its fixed opening (local_sensitivity).
    def basis_at(values):
        return effect.basis(np.where(np.isfinite(values[ok]), values[ok], effect.knots[0]))

    now, then = basis_at(x), basis_at(last_moving(x, moving, runs))
    factor = column_factor(cls, state)[ok]
    local = local_sensitivity(cls, state)[ok]
    columns = (then * (factor * sensitivities[ok])[:, None]
               + (now - then) * (factor * local)[:, None])
    return ShapeColumns(effect, columns * steps, steps, effect.roughness())


def local_sensitivity(cls: type[ShapeFreeEffect], state: dict[str, np.ndarray]) -> np.ndarray:
    """Δp's change [Pa] per SI unit of the shape's output at a fixed opening: a flow effect
    scales the restriction's Δp ∝ (q/C_d)² by (1 + d)⁻², a leakage takes its flow from the
    restriction's; a force or a friction moves nothing while the piston is held."""
    dp, q = state["dp"], state["q"]
    if cls.kind == "flow":
        return -2.0 * dp
    if cls.kind == "leakage":
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(q > 0, -2.0 * dp / q, 0.0)
    return np.zeros(len(dp))


@dataclass(frozen=True)
class RoughnessChoice:
    """The roughness weight a shape's held-out runs chose, and the linear fit at it."""

    weight: float
    heldout: dict  # [Pa] per scheme and "pooled"
    coefficients: np.ndarray  # [SI]
    rms: float  # [Pa] of the linear fit, in sample
    objective: float = float("nan")  # its sum of squares with the maps' discrepancy [Pa²]
    extra: float = float("nan")  # its effective number of parameters
    own_step: np.ndarray | None = None  # the model's own parameters' move, in column steps
    fit: Linearised | None = None  # the linear fit's linearisation at its optimum


def choose_roughness(shape: ShapeColumns, residual: np.ndarray, own_matrix: np.ndarray,
                     runs: np.ndarray | RunIndex, discrepancy, prior: float, schemes: dict,
                     weights: tuple[float, ...] = ROUGHNESS_WEIGHTS,
                     own_roughness: tuple[np.ndarray, np.ndarray] | None = None
                     ) -> RoughnessChoice:
    """The weight of :data:`ROUGHNESS_WEIGHTS` whose linearised fit (the model's own columns
    ``own_matrix`` refitted too, coefficients within their bounds) predicts held-out runs best,
    pooled over the held-out schemes (:meth:`~surrogate.fitting.heldout.RunBlocks.heldout_rms`).

    ``residual`` [Pa] is the model's at its optimum on the solved samples, ``discrepancy`` and
    ``prior`` (s² [Pa²]) the maps' nuisance terms of the judgement, ``own_roughness`` the
    model's own penalty on ``own_matrix`` (a shape it already has; :func:`.judge.own_roughness`).
    """
    k, p = shape.columns.shape[1], own_matrix.shape[1]
    jacobian = np.column_stack([own_matrix, shape.columns])
    parameters = shape.effect.params
    names = shape.effect.coefficient_names()
    lower = np.r_[[-np.inf] * p, [parameters[n].min / s for n, s in zip(names, shape.steps)]]
    upper = np.r_[[np.inf] * p, [parameters[n].max / s for n, s in zip(names, shape.steps)]]
    kept_rows, kept_offset = ((np.zeros((0, p + k)), np.zeros(0)) if own_roughness is None else
                              (np.hstack([own_roughness[0], np.zeros((len(own_roughness[1]), k))]),
                               own_roughness[1]))
    ridge = 1e-8 * np.sqrt(shape.scale) * np.eye(p + k)  # keeps collinear columns defined
    compressed = compress(jacobian, -residual)  # the samples' rows, shared by every weight
    best = None
    for weight in weights:
        rough = np.vstack([kept_rows, np.hstack([np.zeros((shape.roughness.shape[0], p)),
                                                 np.sqrt(weight * shape.scale) * shape.roughness])])
        offset = np.r_[kept_offset, np.zeros(shape.roughness.shape[0])]
        theta = bounded_linear_fit(jacobian, -residual, (lower, upper), np.vstack([rough, ridge]),
                                   np.r_[-offset, np.zeros(p + k)], compressed)
        fitted = residual + jacobian @ theta
        # held out: refits of the shape's linearisation at this fit, its inactive bounds free
        active = np.r_[np.ones(p, bool), (theta[p:] > lower[p:] + 1e-9) | ~np.isfinite(lower[p:])]
        at_fit = Linearised(fitted, jacobian[:, active], (rough[:, active], rough @ theta + offset))
        blocks = RunBlocks(at_fit, discrepancy, runs, prior)
        heldout = blocks.heldout_rms(schemes)
        if best is None or heldout[POOLED] < best.heldout[POOLED]:
            mine = np.arange(p, int(active.sum()))
            best = RoughnessChoice(weight, heldout, theta[p:] * shape.steps,
                                   float(np.sqrt(np.mean(fitted**2))),
                                   blocks.objective(np.ones(len(blocks.labels))),
                                   blocks.effective_parameters(mine), theta[:p], at_fit)
    return best


# --- shape-free candidates -----------------------------------------------------------------------

#: points of a shape's curve in the diagnosis (its JSON, its figure)
CURVE_POINTS = 41


def shape_free_candidates(model: ValveModel, problem, own_columns, judge,
                          classes=SHAPE_FREE, *, steps: int, workers: int | None = None,
                          progress=None, must_beat: float | None = None,
                          heldout_to_beat: float | None = None,
                          finding_kind: str | None = None) -> tuple[list, list[Rival]]:
    """Every shape-free effect of ``classes`` fitted beside the model's own parameters and
    judged like a library candidate (:mod:`surrogate.diagnosis.judge`), with its roughness;
    and every one's linear fit as a :class:`~.result.Rival`, the look-alike a physics claim of
    another kind must beat (:func:`.lookalikes.declined`).

    Each shape's coefficients are linearised from one probe replay of its hook
    (:func:`sensitivity`; five replays in all, fewer where a column of the model's own stands in
    for a probe, :data:`PROBE_TWINS`), its roughness weight chosen by held-out runs
    (:func:`choose_roughness`), and only the shapes whose linear fit predicts the runs left out
    better by the rule's held-out gain are refitted for real (the others cannot pass the rule;
    they are left out, at no replay), the front runners among them (:func:`front_runners`).
    ``problem`` is the diagnosis' :class:`~surrogate.diagnosis.refit.DiagnosisProblem`,
    ``own_columns`` its model's columns, ``judge`` its :class:`~surrogate.diagnosis.judge.Judge`.
    With ``must_beat`` (a ΔBIC), only the shapes whose linear fit's ΔBIC is below it are
    refitted, or whose linear fit predicts the runs left out in turn better than
    ``heldout_to_beat`` [Pa] (a rival that may withhold a finding must be fitted as well as it).
    With ``finding_kind`` (the library finding's kind), the best shape of that kind whose linear
    fit predicts held-out runs better is refitted too: the finding's look-alike, if any.
    """
    progress = progress or (lambda message: None)
    base, ok = problem.base, problem.ok
    state = state_at_samples(model, base)
    probes = list(dict.fromkeys(probe_of(cls) for cls in classes))
    sensitivities = reused_sensitivities(probes, own_columns, ok)
    probes = [probe for probe in probes if probe not in sensitivities]
    progress(f"probing how Δp answers {len(probes)} kind(s) of shape-free term")
    sensitivities.update(zip(probes, map_threads(
        lambda probe: sensitivity(model, probe, base, problem.alike), probes, workers=workers)))

    def linear(cls):
        columns = shape_columns(cls, state, sensitivities[probe_of(cls)], ok,
                                base.replay.moving, base.runs)
        choice = choose_roughness(columns, problem.base_evaluation.residual, judge.own_matrix,
                                  judge.run_index, judge.discrepancy, judge.penalty,
                                  judge.schemes, own_roughness=judge.own_roughness)
        return cls, columns, choice

    def linear_bic(fit) -> float:
        choice = fit[2]
        return delta_bic(choice.objective, judge.objective_before, problem.n_eff, choice.extra)

    def predicts(fit) -> bool:
        return judge.rule.predicts_unseen(_Scores(fit[2].heldout), judge.heldout)

    def promising(fit) -> bool:
        if not predicts(fit):
            return False
        if must_beat is None:
            return True
        return linear_bic(fit) < must_beat or (heldout_to_beat is not None
                                               and fit[2].heldout[HEADLINE] < heldout_to_beat)

    every = list(map_threads(linear, classes, workers=workers))
    rivals = [linear_rival(model, own_columns, cls, columns, choice,
                           judge.maps_error_heldout(choice.fit))
              for cls, columns, choice in every]
    fits = front_runners([fit for fit in every if promising(fit)], judge, problem.n_eff)
    # and the best shape of the finding's own kind, refitted to see whether the log can tell
    # it from the finding (:func:`.lookalikes.alike_shapes`): the linear fit, at the model
    # without the term, understates a large friction's gain, whose sticking and sliding it
    # moves (a seal friction setting in above a load pressure: the library's friction of
    # |p_L − p_P| was added, and a friction of p_L of free shape on top of it a step later)
    same_kind = [fit for fit in every if fit[0].kind == finding_kind and predicts(fit)
                 and all(fit[0] is not other[0] for other in fits)]
    if same_kind:
        fits.append(min(same_kind, key=linear_bic))
    progress(f"refitting {len(fits)} shape-free term(s) whose linear fit predicts held-out runs "
             "better")
    refitting = Stage(progress, "refitting the shapes", len(fits))
    done = []
    for candidate in map_threads(lambda fit: _refitted(model, problem, own_columns, judge, *fit,
                                                       steps=steps), fits, workers=workers):
        done.append(candidate)
        refitting(len(done))
    return done, rivals


def linear_rival(model: ValveModel, own_columns, cls, columns: ShapeColumns,
                 choice: RoughnessChoice, beside_maps: dict) -> Rival:
    """A shape's linear fit as a rival: its held-out RMS (and ``beside_maps``, with the maps'
    error fitted beside it), and the model with the shape's fitted coefficients and the
    model's own parameters moved as the fit moved them (for the bench run that would tell it
    from a claim)."""
    rival = model.copy()
    parameters = rival.parameters()
    for column, step in zip(own_columns, choice.own_step):
        parameter = parameters[column.key]
        parameter.value = float(np.clip(parameter.value + step * column.step, parameter.min,
                                        parameter.max))
    effect = columns.effect.copy()
    for name, value in zip(effect.coefficient_names(), choice.coefficients):
        bounds = effect.params[name]
        bounds.value = float(np.clip(value, bounds.min, bounds.max))
    rival.effects.append(effect)
    return Rival(cls.name, cls.title, cls.kind, cls.category, choice.heldout, beside_maps,
                 rival)


#: shape-free terms refitted for real at most (with any whose linear fit comes within
#: :data:`FRONT_MARGIN` of the last of them), as the library's front runners
#: (:data:`surrogate.diagnosis.refit.REFINED`)
FRONT = 4
#: ΔBIC: the linear fit understates a shape's gain by up to about this much (a detent's ΔBIC
#: -117 linear, -155 refitted), so a shape this close to the front runners is refitted too
FRONT_MARGIN = 40.0

#: a model parameter whose Jacobian column is a probe's sensitivity times its step: a constant
#: friction widens the band as the friction probe does, a flow-force scale adds (scale − 1)·f_ff
#: as the flow-force probe does. Where the model has it free, its column (already replayed for
#: the diagnosis) stands in for the probe's replay.
PROBE_TWINS = {_FrictionProbe: "friction_constant.K1", _FlowForceProbe: "flow_force_scale.scale"}


def reused_sensitivities(probes, own_columns, ok: np.ndarray) -> dict:
    """The sensitivities of ``probes`` that the model's own columns already hold
    (:data:`PROBE_TWINS`), in :func:`sensitivity`'s form: per SI unit, at every sample, 0 where
    the model has no solution."""
    columns = {column.key: column for column in own_columns}
    found = {}
    for probe in probes:
        column = columns.get(PROBE_TWINS.get(probe, ""))
        if column is not None and column.felt:
            everywhere = np.zeros(len(ok))
            everywhere[ok] = column.change / column.step
            found[probe] = everywhere
    return found


def front_runners(fits: list, judge, n_eff: float) -> list:
    """The fits worth refitting for real: the :data:`FRONT` best by their linear fit's ΔBIC, and
    any within :data:`FRONT_MARGIN` of the last of them. A refit takes several replays; a shape
    far behind the front cannot overtake it."""
    if len(fits) <= FRONT:
        return fits
    scores = [delta_bic(choice.objective, judge.objective_before, n_eff, choice.extra)
              for _, _, choice in fits]
    cut = sorted(scores)[FRONT - 1] + FRONT_MARGIN
    return [fit for fit, score in zip(fits, scores) if score <= cut]


@dataclass(frozen=True)
class _Scores:
    """Held-out RMS per scheme, as the rule reads them off a candidate."""

    heldout: dict


def _refitted(model, problem, own_columns, judge, cls, columns: ShapeColumns,
              choice: RoughnessChoice, *, steps: int):
    """The shape refitted with the model's parameters (Gauss–Newton with Broyden updates, the
    roughness penalty included), judged, with its curve. The roughness the held-out runs chose
    becomes the effect's ``smoothing``, so that every later fit of it keeps the penalty
    (:meth:`~surrogate.effects.shapes.ShapeFreeEffect.penalty`).

    The linear fit that chose the roughness knows the shape only to first order about the model
    without it, and a large effect moves the piston far from there: it chose too smooth a
    detent (eval/offlibrary.py case 4243: weight 0.1, held-out RMS 1.42 bar after the refit,
    where 0.01 gives 1.01 bar). So the refit goes on to the next smaller weight of
    :data:`ROUGHNESS_WEIGHTS` while that predicts the held-out runs better, each try a few more
    replays from the last refit's point and Jacobian."""
    samples = len(problem.base_evaluation.residual)
    names = [c.key for c in own_columns] + [f"{cls.name}.{name}"
                                            for name in columns.effect.coefficient_names()]
    shape = list(range(len(own_columns), len(names)))

    def refit(start: ValveModel, weight: float, changes, steps_si, evaluation):
        trial = start.copy()
        trial.effect(cls.name).params["smoothing"].value = float(
            np.sqrt(weight * columns.scale / samples))
        minimizer = Minimizer(trial, problem, names)
        minimizer.linearise(changes, steps_si, evaluation).refine(1 + steps)
        # the refits of the judgement know no bounds: a coefficient on its bound takes no part
        candidate = candidate_of(cls, minimizer, len(columns.steps), problem)
        return minimizer, judge.judge(candidate, shape)

    start = model.copy()
    start.effects.append(columns.effect.copy())
    weight = choice.weight
    minimizer, judged = refit(start, weight, [c.change for c in own_columns]
                              + list(columns.columns.T),
                              [c.step for c in own_columns] + list(columns.steps),
                              problem.base_evaluation)
    for smaller in sorted((w for w in ROUGHNESS_WEIGHTS if w < weight), reverse=True):
        further, candidate = refit(minimizer.model, smaller, list(minimizer.refined_jacobian.T),
                                   list(minimizer.refined_steps), minimizer.refined[0])
        if not candidate.heldout[HEADLINE] < judged.heldout[HEADLINE]:
            break
        minimizer, judged, weight = further, candidate, smaller
    fitted = judged.model.effect(cls.name)
    return replace(judged, curve=shape_curve(fitted, judged.linearised, len(own_columns),
                                             problem.n_eff, weight))


def shape_curve(effect: ShapeFreeEffect, fit: Linearised, own_count: int, n_eff: float,
                weight: float):
    """The fitted shape on :data:`CURVE_POINTS` points of its variable, with one standard
    deviation from the penalised fit's covariance (σ² from the residual, widened for the
    samples' correlation in time, like the fit's standard errors); ``fit`` is its linearisation
    (coefficients on a bound held: they add no spread), its first ``own_count`` columns the model's
    own parameters, the rest the shape's coefficients."""
    x = np.linspace(effect.knots[0], effect.knots[-1], CURVE_POINTS)
    basis = effect.basis(x)
    jacobian, residual = fit.jacobian, fit.residual
    rough = fit.roughness[0] if fit.roughness is not None else np.zeros((0, jacobian.shape[1]))
    count, size = jacobian.shape
    free = [i for i in range(size) if i < own_count or np.any(jacobian[:, i])]
    jacobian, rough, size = jacobian[:, free], rough[:, free], len(free)
    variance = float(residual @ residual) / max(count - size, 1) * count / max(n_eff, 1.0)
    try:
        covariance = np.linalg.pinv(jacobian.T @ jacobian + rough.T @ rough) * variance
    except np.linalg.LinAlgError:
        covariance = np.full((size, size), np.nan)
    coefficient = [i - own_count for i in free if i >= own_count]
    shape_rows = [k for k, i in enumerate(free) if i >= own_count]
    steps = np.array([float(to_si(1.0, effect.value_unit) - to_si(0.0, effect.value_unit))]
                     * len(effect.coefficients))
    scaled = basis[:, coefficient] * steps[coefficient]
    block = covariance[np.ix_(shape_rows, shape_rows)]
    std = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", scaled, block, scaled), 0.0, None))
    variable = effect.variable
    return ShapeCurve(variable.name, variable.label, variable.unit, effect.value_unit,
                      from_si(x, variable.unit), from_si(effect.shape(x), effect.value_unit),
                      from_si(std, effect.value_unit) - from_si(0.0, effect.value_unit),
                      weight)
