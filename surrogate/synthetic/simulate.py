"""Synthetic bench logs with known physics, to prove that the workbench finds what is hidden.

A synthetic log is made in three steps:

1. **The test sequence.** The shipped log's inputs (q, p_P, p_B and temperature, run by run) are
   smoothed by a centred moving average: these are the noise-free sensor readings. The runs,
   times, ramp directions and set points stay those of the real test sequence.
2. **The truth.** A *truth model* — a reference valve model with one effect switched on or
   changed — is replayed over that sequence with the package's own solver and friction play,
   giving the true p_L. Sensor effects act as they do in a fitted model: the truth model reads
   the noise-free readings and corrects them, so a pilot-transducer offset is an error of the
   *readings*.
3. **The noise.** Independent Gaussian noise like the shipped bench's sensors (its README: p_L
   and p_P 0.3 bar, p_B 0.05 bar, q 0.5 % + 0.02 L/min, temperature 0.1 °C, all 1σ) is added to
   every reading, p_L included.

The model under test starts from the reference without the hidden effect and never sees the
truth model. With perfect maps (the default) the truth runs on the very maps the model under test
uses; with a :class:`~.mismatch.MapMismatch` it runs on maps of perturbed CFD samples, with
behaviour where the CFD has no samples and a back-pressure dependence the maps lack
(:mod:`.mismatch`), the way a real valve differs from its CFD.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..data.loaders import BenchLog, CfdSamples, load_cfd_samples
from ..effects import LIBRARY, Effect, EffectLibrary, PerRunEffect
from ..core.errors import InputError
from ..fitting.residuals import replay_log
from ..maps.registry import MapsSpec
from ..model import ValveModel
from ..core.paths import SHIPPED_CFD_SAMPLES
from ..description.presets import cfda, cfda_effects
from ..description.spec import EffectSpec, ModelSpec, ValveSource
from ..core.units import to_si
from ..workbench.workflow import Workflow, run_workflow
from .mismatch import MapMismatch, mismatched_truth
from .visibility import left_nothing_to_find, over_floor

#: a magnitude an engineer could meet on a real valve, per library effect (display units). The
#: pilot-pressure frictions are set where they stand out from the K1 + K2·p_L friction the model
#: already has: at 0.06 N/bar most of them is absorbed by refitting K1 and K2, and what is left
#: is within the noise.
REALISTIC_MAGNITUDES: dict[str, dict[str, float]] = {
    "flow_force_scale": {"scale": 0.8},
    "back_pressure_flow_force": {"gamma": 0.05},
    "seat_flow_force": {"k": 0.6},
    "spring_preload_offset": {"delta_F": 15.0},
    "progressive_spring": {"beta": 0.3},
    "friction_constant": {"K1": 8.0},
    "friction_load_pressure": {"K2": 0.08},
    "friction_pilot_pressure": {"K_P": 0.1},
    "friction_seal_pressure": {"K_LP": 0.06},
    "friction_pilot_differential": {"K_Pe": 0.1},
    "friction_viscous": {"K_nu": 4.0},
    "discharge_scale": {"c": 0.9},
    "laminar_leakage": {"G": 0.004},
    "pilot_transducer_offset": {"delta": 0.8},
    # per-run effects: the standard deviation of the runs' values, drawn with the case's seed
    "pilot_zero_drift": {"delta": 0.4},
    "flowmeter_gain": {"g": 0.04},
}


@dataclass(frozen=True)
class SensorNoise:
    """Standard deviations of the sensor noise (SI units).

    Attributes
    ----------
    p_L, p_P, p_B : float
        Pressure transducers [Pa].
    q_relative : float
        Flowmeter noise as a fraction of the reading [1].
    q_absolute : float
        Flowmeter noise floor [m^3/s]; the flow's σ is q_relative·q + q_absolute.
    temperature : float
        Temperature sensor [K].
    """

    p_L: float = to_si(0.3, "bar")
    p_P: float = to_si(0.3, "bar")
    p_B: float = to_si(0.05, "bar")
    q_relative: float = 0.005
    q_absolute: float = to_si(0.02, "L/min")
    temperature: float = 0.1

    def scaled(self, factor: float) -> "SensorNoise":
        """All standard deviations times ``factor`` (0 for noise-free data)."""
        return SensorNoise(self.p_L * factor, self.p_P * factor, self.p_B * factor,
                           self.q_relative * factor, self.q_absolute * factor,
                           self.temperature * factor)


def noise_free_sequence(log: BenchLog, *, window: int = 15, every: int = 1) -> BenchLog:
    """The noise-free readings of ``log``'s test sequence.

    Parameters
    ----------
    log : BenchLog
        A measured log (the shipped one, usually).
    window : int
        Samples in the centred moving average that removes the sensor noise.
    every : int
        Keep every ``every``-th sample (after smoothing) for quicker experiments.
    """
    if window < 1 or every < 1:
        raise InputError("window and every must be at least 1")
    frame = log.frame.copy()
    smoothed = ["q", "p_P", "p_B", "temperature"]
    frame[smoothed] = (frame.groupby("run", sort=False)[smoothed]
                       .transform(lambda column: column.rolling(window, center=True,
                                                                min_periods=1).mean()))
    frame["q"] = frame["q"].clip(lower=0.0)
    if every > 1:
        frame = frame[frame.groupby("run", sort=False).cumcount() % every == 0]
    return BenchLog(frame.reset_index(drop=True), f"test sequence of {log.source}")


def simulate(truth: ValveModel, sequence: BenchLog, *, noise: SensorNoise | None = None,
             seed: int = 0) -> BenchLog:
    """A synthetic bench log: ``truth`` replayed over ``sequence``, with sensor noise.

    Raises
    ------
    InputError
        If the truth model cannot be solved at some sample (a synthetic log never holds a
        silently missing value).
    """
    noise = SensorNoise() if noise is None else noise
    log_replay = replay_log(truth, sequence, diagnostics=False)
    if not log_replay.ok.all():
        bad = np.flatnonzero(~log_replay.ok)
        raise InputError(f"the truth model {truth.name!r} cannot be solved at {bad.size} "
                         f"sample(s) of the sequence (first: index {bad[0]}); choose a smaller "
                         "magnitude")
    rng = np.random.default_rng(seed)
    frame = sequence.frame.copy()
    size = len(frame)
    frame["p_L"] = frame["p_B"] + log_replay.replay.dp + noise.p_L * rng.standard_normal(size)
    frame["p_P"] = frame["p_P"] + noise.p_P * rng.standard_normal(size)
    frame["p_B"] = frame["p_B"] + noise.p_B * rng.standard_normal(size)
    spread = noise.q_relative * frame["q"] + noise.q_absolute
    frame["q"] = (frame["q"] + spread * rng.standard_normal(size)).clip(lower=0.0)
    frame["temperature"] = frame["temperature"] + noise.temperature * rng.standard_normal(size)
    return BenchLog(frame, f"simulated by {truth.name!r} (seed {seed})")


#: the reference valve's own values, not start values: CFDA fitted to the shipped bench,
#: flow-force scale [-], K1 [N], K2 [N/bar] (the fits start from presets.CFDA_START)
REFERENCE_VALUES = {"scale": 0.83, "K1": 6.3, "K2": 0.08}


def reference_spec(maps_spec: MapsSpec | None = None, valve: ValveSource | None = None
                   ) -> ModelSpec:
    """The valve the synthetic logs start from: CFDA with the shipped bench's fitted values
    (:data:`REFERENCE_VALUES`), on ``maps_spec`` (default: the grid maps)."""
    return cfda(valve, maps_spec, "reference").with_effects(cfda_effects(**REFERENCE_VALUES))


@dataclass(frozen=True)
class HiddenEffectCase:
    """A synthetic log with one hidden effect, and the model that has to find it.

    Attributes
    ----------
    hidden : str
        The effect switched on (or changed) in the truth, or "" for the control case.
    truth : ValveModel
        The model that made the log (with a mismatch: the virtual valve).
    start : ValveModel
        The reference without the hidden effect; its free parameters start from the presets'
        values, not from the truth.
    log : BenchLog
        The synthetic log.
    """

    hidden: str
    truth: ValveModel
    start: ValveModel
    log: BenchLog


def hidden_effect_case(hidden: str | None, values: dict[str, float] | None = None, *,
                       sequence: BenchLog, seed: int = 0, reference: ModelSpec | None = None,
                       library: EffectLibrary = LIBRARY,
                       noise: SensorNoise | None = None, mismatch: MapMismatch | None = None,
                       samples: CfdSamples | None = None,
                       maps_under_test: MapsSpec | None = None,
                       valve_maps: MapsSpec | None = None) -> HiddenEffectCase:
    """Make a synthetic log with effect ``hidden`` (from ``library``) at ``values`` (display
    units; default its :data:`REALISTIC_MAGNITUDES`), or with nothing hidden when ``hidden`` is
    None.

    ``reference`` is the valve without the effect (default :func:`reference_spec`); an effect
    the reference already has (the flow-force scale, say) is set to ``values`` in the truth and
    removed from the starting model.

    With ``mismatch`` the truth is the virtual valve of :func:`.mismatch.mismatched_truth`: the
    reference's valve and effects on maps of ``samples`` (default: the shipped CFD samples)
    perturbed with the case's ``seed``. ``maps_under_test`` puts the starting model on other maps
    (default: the reference's); with ``mismatch`` the virtual valve is then those maps wrapped
    with the case's draws (``own_maps`` of :func:`.mismatch.mismatched_truth`). ``valve_maps``
    puts that virtual valve on maps other than the model's: the same kind trained on every
    sample, say, where the model's left an opening out (:mod:`.left_out`).
    """
    reference = reference or reference_spec()
    truth = reference.named(f"reference + {hidden}" if hidden else "reference")
    start_effects = list(reference.effects)
    if hidden:
        values = REALISTIC_MAGNITUDES.get(hidden, {}) if values is None else values
        if not values:
            raise InputError(f"give the values of hidden effect {hidden!r}'s parameters")
        effect = _hidden_effect(library.effect(hidden), truth, sequence, values, seed)
        truth = truth.with_effects([*(e for e in truth.effects if e.name != hidden),
                                    EffectSpec.of(effect)])
        start_effects = [e for e in start_effects if e.name != hidden]
    # a model under test on other maps meets a valve built around those maps (mismatch.py)
    valve_maps = valve_maps or maps_under_test
    own_maps = mismatch is not None and valve_maps not in (None, reference.maps)
    truth_model = (truth.with_maps(valve_maps) if own_maps else truth).build(library)
    if mismatch is not None:
        samples = samples if samples is not None else load_cfd_samples(SHIPPED_CFD_SAMPLES)
        truth_model = mismatched_truth(truth_model, samples, seed, mismatch, own_maps=own_maps)
    log = simulate(truth_model, sequence, noise=noise, seed=seed)
    # the fit starts from the presets' values, not from the truth
    starting = {effect.name: effect for effect in cfda_effects()}
    start = reference.with_effects([starting.get(e.name, e) for e in start_effects],
                                   name="start")
    if maps_under_test is not None:
        start = start.with_maps(maps_under_test)
    return HiddenEffectCase(hidden or "", truth_model, start.build(library), log)


def _hidden_effect(cls: type[Effect], truth: ModelSpec, sequence: BenchLog,
                   values: dict[str, float], seed: int) -> Effect:
    """The hidden effect at ``values`` (display units): the truth's own, changed, or a new one
    for the sequence's runs."""
    existing = next((e for e in truth.effects if e.name == cls.name), None)
    effect = (existing.build(EffectLibrary([cls]), f"the reference's {cls.name}") if existing
              else cls.for_runs(sequence.run_ids))
    if isinstance(effect, PerRunEffect):
        _draw_per_run(effect, values, seed)
        return effect
    for key, value in values.items():
        if key not in effect.params:
            raise InputError(f"hidden effect {cls.name!r} has no parameter {key!r}; it has "
                             f"{', '.join(effect.params)}")
        parameter = effect.params[key]
        parameter.set_display(value)
        if not parameter.min <= parameter.value <= parameter.max:
            low, high = parameter.display_bounds
            raise InputError(f"hidden effect {cls.name!r}: {key} = {value:g} {parameter.unit} "
                             f"lies outside its bounds [{low:g}, {high:g}]")
    return effect


def _draw_per_run(effect: PerRunEffect, values: dict[str, float], seed: int) -> None:
    """Give each run's parameter a value drawn from N(0, σ), σ = ``values[template]`` (display
    units), with its own random stream so the noise of the log stays that of ``seed``."""
    name = effect.template.name
    if set(values) != {name}:
        raise InputError(f"{effect.name} takes the spread of its per-run values as {name!r}; "
                         f"got {', '.join(values)}")
    draws = np.random.default_rng([seed, 7919]).standard_normal(len(effect.params))
    for parameter, draw in zip(effect.params.values(), draws):
        parameter.set_display(values[name] * draw)


def scaled_magnitude(hidden: str, factor: float) -> dict[str, float]:
    """The hidden effect's realistic values scaled by ``factor`` away from its "off" value (1
    for a scale, 0 otherwise), in display units."""
    values = {}
    for key, value in REALISTIC_MAGNITUDES[hidden].items():
        neutral = 1.0 if key in ("scale", "c") else 0.0
        values[key] = neutral + factor * (value - neutral)
    return values


def random_settings(count: int, seed: int) -> list[tuple[str, float, dict[str, float]]]:
    """``count`` randomised hidden-effect settings: (effect, magnitude factor 0.6–1.5, values),
    the effect drawn from :data:`REALISTIC_MAGNITUDES`."""
    rng = np.random.default_rng(seed)
    names = sorted(REALISTIC_MAGNITUDES)
    settings = []
    for _ in range(count):
        hidden = names[rng.integers(len(names))]
        factor = float(rng.uniform(0.6, 1.5))
        settings.append((hidden, factor, scaled_magnitude(hidden, factor)))
    return settings


@dataclass(frozen=True)
class StressCase:
    """One log of a stress test: what is hidden (None: nothing), how strongly (the factor on its
    realistic magnitude, and the values), and the seed of its noise and map mismatch."""

    hidden: str | None
    factor: float
    values: dict[str, float] | None
    seed: int

    @property
    def weak_leakage(self) -> bool:
        """Whether the case hides a laminar leakage of at most :data:`WEAK_LEAKAGE` times its
        realistic size."""
        return self.hidden == "laminar_leakage" and self.factor <= WEAK_LEAKAGE


#: a hidden leakage this much of its realistic size or less is *weak*: the maps' error hides it
#: best (the stress suite's usual misses), so the evaluations count it apart
WEAK_LEAKAGE = 1.2

#: the randomised settings (seeds of :func:`random_settings`) of the stress suite
STRESS_SETTINGS = (2026, 2027)


def stress_suite(cases: int = 20, controls: int = 5,
                 settings: tuple[int, ...] = STRESS_SETTINGS) -> list[StressCase]:
    """The cases of the workbench's stress test (tests/synthetic/test_mismatch.py, eval/workbench.py):
    for each settings seed, ``cases`` randomised hidden effects and ``controls`` logs with
    nothing hidden, every one with its own seed."""
    suite = []
    for setting in settings:
        # a setting's seeds depend on it alone, not on the settings run with it
        offset = 1000 * (setting - STRESS_SETTINGS[0])
        suite += [StressCase(hidden, factor, values, 200 + number + offset)
                  for number, (hidden, factor, values)
                  in enumerate(random_settings(cases, seed=setting))]
        suite += [StressCase(None, 0.0, None, 100 + number + offset)
                  for number in range(controls)]
    return suite


@dataclass(frozen=True)
class StressOutcome:
    """What the workflow made of one stress case's log, and of its twin's where that was run
    (the same virtual valve with nothing hidden, :func:`run_stress_case`)."""

    case: StressCase
    workflow: Workflow
    seconds: float
    twin: Workflow | None = None

    @property
    def added(self) -> list[str]:
        """The effects added after the starting model, in order."""
        return [name for step in self.workflow.steps[1:] for name in step.added]

    @property
    def found(self) -> bool:
        """Whether the hidden effect was found and nothing invented (:func:`cleanly_identified`)."""
        return cleanly_identified(self.workflow, self.case.hidden)

    @property
    def invisible(self) -> bool:
        """Whether the hidden effect left the log nothing to find: the diagnosis added nothing
        and withheld nothing, and the log ends as its twin does
        (:func:`.visibility.left_nothing_to_find`)."""
        if self.case.hidden is None or self.twin is None or not quiet(self.workflow):
            return False
        return left_nothing_to_find(over_floor(self.workflow), over_floor(self.twin))

    @property
    def clean(self) -> bool:
        """Whether the hidden effect was found, or left nothing to find, and nothing was
        invented (the off-library suite's judgement, :mod:`.visibility`)."""
        return self.found or self.invisible

    @property
    def invented(self) -> list[str]:
        """The physics or sensor effects added that the hidden one does not account for."""
        return unexplained_additions(self.workflow, self.case.hidden)

    @property
    def shapes_beside_library(self) -> list[str]:
        """The shape-free terms added after the step that added the hidden library effect (or
        a look-alike the log cannot tell from it): the log was already explained by a named
        term, so each is a patch the library term did not need (the goal is none)."""
        steps = self.workflow.steps
        found = next((number for number, step in enumerate(steps)
                      if step.diagnosis is not None and step.diagnosis.best is not None
                      and self.case.hidden in step.diagnosis.best.group
                      and step.diagnosis.best.name in step.added), None)
        if found is None:
            return []
        return [name for step in steps[found + 1:] if step.shape_free for name in step.added]


def run_stress_case(case: StressCase, sequence: BenchLog, maps_under_test: MapsSpec, *,
                    valve_maps: MapsSpec | None = None, mismatch: MapMismatch | None = None,
                    max_additions: int = 3, twin: bool = True) -> StressOutcome:
    """The workflow on the log of one stress case: the virtual valve on ``valve_maps`` (default:
    the model's own) with ``mismatch`` (default: the suite's, :class:`MapMismatch`), the model
    under test on ``maps_under_test``, at most ``max_additions`` effects added (the stress
    tests' and the evaluations' one loop). Where a hidden effect's log ends with nothing
    diagnosed, its twin (the same valve, map mismatch and noise, nothing hidden) is run too,
    to tell an effect the log does not show from one the loop missed (``twin=False``: never;
    the outcome is then clean only where the effect was found)."""
    began = time.perf_counter()
    mismatch = MapMismatch() if mismatch is None else mismatch

    def workflow_of(hidden: str | None, values: dict[str, float] | None) -> Workflow:
        made = hidden_effect_case(hidden, values, sequence=sequence, seed=case.seed,
                                  mismatch=mismatch, maps_under_test=maps_under_test,
                                  valve_maps=valve_maps)
        return run_workflow(made.log, start=made.start, max_additions=max_additions)

    workflow = workflow_of(case.hidden, case.values)
    nothing_hidden = (workflow_of(None, None)
                      if twin and case.hidden is not None and quiet(workflow) else None)
    return StressOutcome(case, workflow, time.perf_counter() - began, nothing_hidden)


def quiet(workflow: Workflow) -> bool:
    """Whether no diagnosis of ``workflow`` added a term or withheld a claim (the paper's steps
    aside)."""
    return not workflow.declined and not any(
        step.added for step in workflow.steps[1:] if step.diagnosis is not None)


def identified(diagnosis, hidden: str, library: EffectLibrary = LIBRARY) -> bool:
    """Whether a diagnosis found the hidden effect: its best candidate is significant, ranked
    first, and is the effect or a candidate the data cannot tell from it. A per-run effect never
    joins a model (it cannot predict another run): it is found when no candidate is significant
    and the diagnosis' sensor checks flag a run for it (they flag none where nothing is hidden:
    tests/synthetic/test_hidden_effects.py)."""
    best = diagnosis.best
    if _per_run(hidden, library):
        return best is None and any(check.effect == hidden for check in diagnosis.sensor_checks)
    return best is not None and diagnosis.candidates[0] is best and hidden in best.group


def unexplained_additions(workflow, hidden: str | None,
                          library: EffectLibrary = LIBRARY) -> list[str]:
    """The physics and sensor effects a workflow added beyond the paper's steps that are neither
    the hidden effect nor one the data cannot tell from it (map corrections may patch the maps
    anywhere: they are labelled as such, not counted; a shape-free term's category is its own,
    :mod:`surrogate.effects.shapes`)."""
    extra = []
    for step in workflow.steps[1:]:
        if step.diagnosis is None:  # a paper step
            continue
        group = step.diagnosis.best.group if step.diagnosis.best else step.added
        for name in step.added:
            if _category(name, step.model, library) == "map correction":
                continue
            if hidden and hidden in group:
                continue
            extra.append(name)
    return extra


def cleanly_identified(workflow, hidden: str | None, library: EffectLibrary = LIBRARY) -> bool:
    """Whether a workflow found the hidden effect and invented nothing: it added the effect (or
    one the data cannot tell from it; a per-run effect: flagged it in the final diagnosis'
    sensor checks, :func:`identified`) and no other physics or sensor effect. With nothing
    hidden: no physics or sensor effect added."""
    if unexplained_additions(workflow, hidden, library):
        return False
    if not hidden:
        return True
    if _per_run(hidden, library):
        return identified(workflow.final_diagnosis, hidden, library)
    return any(step.diagnosis is not None and step.diagnosis.best is not None
               and hidden in step.diagnosis.best.group for step in workflow.steps[1:])


def withheld_claims(workflow) -> list[str]:
    """The physics claims a workflow's diagnoses withheld for their look-alikes of other kinds,
    as "claim (look-alike, ...)": a log that cannot tell them apart, said so."""
    return [f"{d.claim.name} ({', '.join(r.name for r in d.rivals)})"
            for d in workflow.declined]


def _category(name: str, model: ValveModel, library: EffectLibrary) -> str:
    """The category of the effect ``name`` a step added: the model's own (a shape-free term is
    in no library), else the library's."""
    if model.has_effect(name):
        return model.effect(name).category
    return library[name].category if name in library else "physics"


def _per_run(name: str, library: EffectLibrary) -> bool:
    """Whether ``name`` is a per-run effect of ``library`` (a name it lacks is not)."""
    return name in library and issubclass(library[name], PerRunEffect)
