"""The closed loop: from the paper's basic model to one the bench data cannot fault.

Steps
-----
1. ``bmbe``: the paper's basic model (orifice equation, C_d = 0.4, uniform pressure), as is.
2. ``bmbebf``: its discharge coefficient fitted (a C_d scale) — the paper's best-fit basic model.
3. ``cfd-maps``: the CFD grid maps replace the orifice equation and the uniform pressure, with a
   fitted flow-force scale — the paper's CFDA without friction.
4. ``cfda``: plus Coulomb friction s·(K1 + K2·p_L), one K1 and one K2 for all temperatures.
5. Then, until nothing significant is left: diagnose (:mod:`~surrogate.diagnosis.diagnose`), add
   the best significant
   candidate, refit every free parameter together.
6. ``calibrated maps``: what the maps' own error explains of the rest, fitted as map corrections
   per opening within the maps' uncertainty (:mod:`.bench_calibration`), kept only if it
   predicts the held-out runs better.
7. The calibrated model diagnosed, as in 5.: when the calibration was kept, the model is not the
   one the loop's last diagnosis saw. A finding the maps' error hid until the maps were
   calibrated is added as any other, while additions are left; the last diagnosis is the
   workflow's final diagnosis, of the model its report and model file hold.

Every step refits all free parameters against every sample of the log
(:func:`~surrogate.fitting.logfit.fit_to_log`);
the RMS after each step is the *error staircase*. Next to it stands each step's RMS on runs its
fit did not see (each run predicted by a refit to the others; :mod:`~surrogate.fitting.heldout`):
a step the
diagnosis adds must lower it, and the RMS with one temperature or one pilot pressure left out
too, so the loop stops when the held-out RMS stops falling. Each
step carries the category of what it added (valve physics, map correction, sensor).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace


from ..data.loaders import BenchLog
from ..diagnosis.diagnose import Diagnoser
from ..diagnosis.result import Diagnosis
from ..effects import LIBRARY, DischargeScale, EffectLibrary, FlowForceScale
from ..fitting.heldout import HEADLINE, replayed_heldout_rms, run_groups
from ..fitting.identifiability import (Entangled, PushedToBound, entangled_pairs,
                                       pushed_to_bounds)
from ..fitting.logfit import Column, fit_to_log, probe_columns
from ..fitting.residuals import LogReplay, noise_floor, replay_log
from ..fitting.leastsquares import FitResult, free_parameters
from ..maps.registry import MapsSpec
from ..core.memory import release_freed
from ..model import ValveModel
from ..core.parallel import blas_limited, single_threaded
from ..description.presets import bmbe, bmbebf_step, cfd_maps_step, cfda_step, maps
from ..solver.map_tables import release_tables
from ..description.spec import ModelSpec, ValveSource
from ..core.units import from_si
from .bench_calibration import calibrate_maps

MAX_ADDITIONS = 8  # effects the loop may add after the paper's steps
#: candidates refused on their full refit after which a step is diagnosed no more
REFUSALS = 2


@dataclass(frozen=True)
class Step:
    """One step of the staircase.

    Attributes
    ----------
    model : ValveModel
        The model after the step, fitted.
    added : tuple of str
        Effects added in this step (none for the starting model).
    reason : str
        What the step is, for the steps no diagnosis chose (the paper's, the starting model,
        the maps' calibration); "" for a diagnosed step, whose reason is its diagnosis
        (:func:`surrogate.reporting.documents.step_reason` words it).
    log_replay : LogReplay
        Its replay of the log.
    rms : float
        Residual RMS [Pa].
    diagnosis : Diagnosis or None
        The diagnosis that chose the step's effect.
    category : str
        What the step added: "physics", "map correction", "sensor" ("" for the first step);
        for look-alikes the log cannot tell apart, each of theirs ("physics or sensor").
    heldout_rms : float
        RMS on held-out runs [Pa]: for a step the diagnosis chose, the figure it judged the
        step by; otherwise :func:`heldout_rms` of the step's fit.
    heldout_check : float
        :func:`heldout_rms` of the step's own fit [Pa], the same way for every step: a
        diagnosed step is kept only if it does not rise over the step before.
    entangled : tuple of Entangled
        Pairs of the step's fitted parameters the log cannot separate
        (:mod:`~surrogate.fitting.identifiability`).
    pushed : tuple of PushedToBound
        Parameters the step drove onto a bound, with the terms that did it.
    columns : tuple of Column
        Δp's change at the solved samples for a probe step of each free parameter
        (:func:`~surrogate.fitting.logfit.probe_columns`): the held-out check's, and the next
        diagnosis' linearisation.
    """

    model: ValveModel
    added: tuple[str, ...]
    reason: str
    log_replay: LogReplay
    rms: float
    diagnosis: Diagnosis | None = None
    category: str = ""
    heldout_rms: float = float("nan")
    heldout_check: float = float("nan")
    entangled: tuple[Entangled, ...] = ()
    pushed: tuple[PushedToBound, ...] = ()
    columns: tuple[Column, ...] = ()

    @property
    def shape_free(self) -> bool:
        """Whether the step added a shape-free term (:mod:`surrogate.effects.shapes`): a shape
        the data drew, without a name; its effects file is what the user takes over."""
        best = None if self.diagnosis is None else self.diagnosis.best
        return best is not None and best.shape_free and best.name in self.added


@dataclass(frozen=True)
class Workflow:
    """The staircase and the final diagnosis: the final model's (the last step's), whether the
    loop's last diagnosis or one made after the maps' calibration followed the loop (and what
    the loop added after it)."""

    log: BenchLog
    steps: tuple[Step, ...]
    final_diagnosis: Diagnosis
    noise_floor: float  # [Pa], of the final model's residual
    seconds: float = 0.0
    maps: str = ""  # the kind of the CFD steps' maps ("" when started from a given model)
    dropped: str = ""  # why a diagnosed step was refused after its full refit ("" if none)
    #: the diagnosis that ended the loop, when a later step followed it (None otherwise)
    loop_end: Diagnosis | None = None

    def __post_init__(self):
        if self.final_diagnosis.model is not self.final.model:
            raise ValueError(f"the final diagnosis is of {self.final_diagnosis.model.name!r}, "
                             f"not of the final model {self.final.model.name!r}")

    @property
    def final(self) -> Step:
        return self.steps[-1]

    @property
    def declined(self) -> list:
        """The physics claims its diagnoses withheld for look-alikes of other kinds, in order
        (:class:`~surrogate.diagnosis.result.Declined`; the final diagnosis' last)."""
        diagnoses = [step.diagnosis for step in self.steps if step.diagnosis is not None]
        ends = [self.loop_end] if self.loop_end is not None else []
        return [diagnosis.declined for diagnosis in [*diagnoses, *ends, self.final_diagnosis]
                if diagnosis.declined is not None]


def paper_steps(valve: ValveSource, maps_spec: MapsSpec
                ) -> list[tuple[Callable[[ModelSpec], ModelSpec], list[str], str, str]]:
    """The paper's steps after BMBE as (next spec from the previous one, added, category,
    reason)."""
    return [
        (bmbebf_step, [DischargeScale.name], DischargeScale.category,
         "the paper's BMBEBF: the orifice equation's discharge coefficient fitted"),
        (lambda previous: cfd_maps_step(previous, maps_spec),
         [f"{maps_spec.flow.kind} maps", FlowForceScale.name], FlowForceScale.category,
         "CFD maps of flow and force replace the orifice equation (the paper's CFDA without "
         "friction), with a fitted flow-force scale"),
        (cfda_step, ["friction_constant", "friction_load_pressure"], "physics",
         "the paper's CFDA: Coulomb friction K1 + K2·p_L, one pair for all temperatures"),
    ]


def heldout_rms(fitted: FitResult | None, log_replay: LogReplay,
                schemes: dict[str, dict[str, list[str]]], columns=None) -> float:
    """A fitted model's RMS on held-out runs [Pa], each run predicted by a refit to the others
    and replayed (:func:`~surrogate.fitting.heldout.replayed_heldout_rms`; ``columns``: the
    free parameters' probe columns at ``log_replay``, if already made); without free parameters it
    is the RMS itself."""
    if fitted is None or not fitted.names:
        return log_replay.rms()
    keys = fitted.names if columns is None else [column.key for column in columns]
    # the other schemes judge candidates, not steps: refit only for the runs left out
    return replayed_heldout_rms(fitted.model, keys, log_replay, schemes[HEADLINE], columns=columns)


class _Staircase:
    """The steps so far: each model fitted to the log, replayed, and reported."""

    def __init__(self, log: BenchLog, progress: Callable[[str], None], diagnoser: Diagnoser,
                 narrate: Callable[[Diagnosis], str] | None = None):
        self.log, self.progress, self.narrate = log, progress, narrate
        self.diagnoser = replace(diagnoser, progress=lambda message: progress(f"  {message}"))
        self.steps: list[Step] = []
        self.schemes = run_groups(log)
        self.refusals: list[str] = []  # why each refused candidate was not kept
        self.additions = 0  # effects added by diagnosis so far

    @property
    def last(self) -> Step:
        return self.steps[-1]

    def record(self, model: ValveModel, added: list[str], category: str, reason: str,
               diagnosis: Diagnosis | None = None, warm_start: LogReplay | None = None,
               calibration=None) -> Step:
        """Fit ``model`` (``warm_start``: a replay close to its optimum), replay it, add the step
        (``calibration``: the :class:`.bench_calibration.BenchCalibration` it adds, which its
        held-out figure refits too)."""
        if warm_start is None and self.steps and self.last.model.flow_map is model.flow_map:
            warm_start = self.last.log_replay
        fitted = None
        if model.parameters().free():
            self.progress(f"fitting {model.name} ({len(model.parameters().free())} free "
                          "parameter(s))")
            fitted = fit_to_log(model, self.log, start=warm_start, progress=self.progress)
            model = fitted.model
        release_freed()  # the fit's working arrays, before the step's replay and checks
        log_replay = replay_log(model, self.log, guess=warm_start)
        # probed once: for the step's held-out check and the next diagnosis' linearisation
        if fitted is not None:
            self.progress("checking the step on held-out runs (each run refitted without it and "
                          "replayed)")
        columns = tuple(probe_columns(model, [key for key, _ in free_parameters(model)],
                                      log_replay)) if fitted is not None else ()
        check = (heldout_rms(fitted, log_replay, self.schemes, list(columns)) if calibration is None
                 else calibration.heldout_rms(fitted, log_replay, self.schemes, list(columns)))
        best = None if diagnosis is None else diagnosis.best
        pushed = (pushed_to_bounds(self.last.model, model, added) if self.steps else [])
        step = Step(model=model, added=tuple(added), reason=reason, log_replay=log_replay,
                    rms=log_replay.rms(), diagnosis=diagnosis, category=category,
                    heldout_rms=check if best is None else best.heldout_rms,
                    heldout_check=check, entangled=tuple(entangled_pairs(fitted)),
                    pushed=tuple(pushed), columns=columns)
        self.steps.append(step)
        self.progress(f"step {len(self.steps)}: {model.name:<28} rms "
                      f"{from_si(step.rms, 'bar'):6.3f} bar, held out "
                      f"{from_si(step.heldout_rms, 'bar'):6.3f} bar   (+ "
                      f"{', '.join(added) or 'nothing'})")
        for moved in pushed:
            self.progress(f"  {moved.parameter} driven to its bound ({moved.before:.4g} -> "
                          f"{moved.after:.4g} {moved.unit}) by {', '.join(moved.by)}")
        return step

    def diagnose_last(self, refused: list[str] | None = None) -> Diagnosis:
        """Diagnose the last step's model (:class:`~surrogate.diagnosis.diagnose.Diagnoser`,
        from the step's replay and probe columns), without the candidates ``refused``."""
        current, refused = self.last, refused or []
        self.progress(f"diagnosing {current.model.name} ..."
                      + (f" (without {', '.join(refused)})" if refused else ""))
        diagnosis = self.diagnoser.diagnose(current.model, self.log, base=current.log_replay,
                                            exclude=refused,
                                            own_columns=list(current.columns) or None)
        if self.narrate is not None:
            self.progress(f"  {self.narrate(diagnosis)}")
        return diagnosis

    def add_diagnosed(self, max_additions: int) -> Diagnosis:
        """Diagnose the last step and add its best significant candidate, until none is left
        or ``max_additions`` were added in all (:attr:`additions` counts them across calls);
        return the last diagnosis. A candidate whose full refit
        predicts the held-out runs worse is refused, and the step diagnosed again without it
        (at most :data:`REFUSALS` times a step) for another explanation of the same finding:
        a term of the same kind (a laminar leakage for a leakage of free shape). A term of
        another kind is another finding, which the first outranked: the loop stops there."""
        refused, kinds = [], set()
        while True:
            current = self.last
            diagnosis = self.diagnose_last(refused)
            best = diagnosis.best
            if (best is None or self.additions >= max_additions
                    or (kinds and best.kind not in kinds)):
                return diagnosis
            # the diagnosis already refitted every parameter with the effect added: polish that
            categories = dict.fromkeys(c.category for c in diagnosis.explanations)
            step = self.record(best.model.copy(name=f"{current.model.name}+{best.name}"),
                               [best.name], " or ".join(categories), "", diagnosis,
                               warm_start=best.replay)
            if step.heldout_check > current.heldout_check:
                # the diagnosis judged the term on its own linearised refit; refitted for real
                # without each run and replayed there, it predicts unseen runs worse: refuse it
                # rather than keep a step that rises (a leak shape whose linear refits promised
                # 0.98 bar predicted the hottest run, fitted to the others, 7 bar off; case
                # 4247 on GP maps), and ask the diagnosis what else explains the log
                self.steps.pop()
                refused.append(best.name)
                kinds.add(best.kind)
                self.refusals.append(f"{best.name} was not kept: after the full refit its RMS "
                                     f"on held-out runs rose from "
                                     f"{from_si(current.heldout_check, 'bar'):.3f} to "
                                     f"{from_si(step.heldout_check, 'bar'):.3f} bar")
                self.progress(f"  {self.refusals[-1]}")
                if len(refused) > REFUSALS:
                    return diagnosis
                continue
            self.additions += 1
            refused, kinds = [], set()

    def calibrate(self) -> bool:
        """Add the maps' calibration (:mod:`.bench_calibration`) unless it predicts the held-out
        runs no better than the step before; return whether it was added."""
        current = self.last
        self.progress(f"calibrating the maps of {current.model.name} to the bench ...")
        calibration = calibrate_maps(current.model, self.log, current.log_replay)
        if calibration is None:
            return False
        step = self.record(calibration.model.copy(name=f"{current.model.name}+calibrated maps"),
                           calibration.names, "map correction", calibration.describe(),
                           warm_start=calibration.replay, calibration=calibration)
        if step.heldout_check > current.heldout_check:
            self.steps.pop()
            self.progress(f"  the calibration was not kept: it predicts the held-out runs worse "
                          f"({from_si(current.heldout_check, 'bar'):.3f} -> "
                          f"{from_si(step.heldout_check, 'bar'):.3f} bar)")
            return False
        return True


@blas_limited()
@single_threaded
def run_workflow(log: BenchLog, *, start: ValveModel | None = None,
                 library: EffectLibrary = LIBRARY, candidates: list[str] | None = None,
                 valve: ValveSource | None = None, maps_spec: MapsSpec | None = None,
                 max_additions: int = MAX_ADDITIONS, calibrate: bool = True,
                 shapes: bool = True, progress: Callable[[str], None] | None = None,
                 narrate: Callable[[Diagnosis], str] | None = None) -> Workflow:
    """Run the loop on ``log`` (see the module docstring).

    Parameters
    ----------
    log : BenchLog
    start : ValveModel, optional
        Start here instead of at ``bmbe`` and skip the paper's steps.
    library : EffectLibrary
        The effects the diagnosis may choose from (default: the built-in ones).
    candidates : list of str, optional
        Names of the library's effects to restrict the diagnosis to.
    valve : ValveSource, optional
        The valve of the paper's steps (default: the shipped one).
    maps_spec : MapsSpec, optional
        The CFD maps of the paper's steps (default: grid maps of the shipped samples).
    max_additions : int
        Effects added by diagnosis at most.
    calibrate : bool
        End with the maps calibrated to the bench (:mod:`.bench_calibration`), when that predicts
        the held-out runs better.
    shapes : bool
        Whether the diagnoses try terms of free shape beside the library
        (:mod:`surrogate.diagnosis.shapes`).
    progress : callable, optional
        Called with a line of text at every stage.
    narrate : callable, optional
        Words for a diagnosis (:func:`surrogate.reporting.prose.summarise`), said after each.
    """
    began = time.perf_counter()
    staircase = _Staircase(log, progress or (lambda message: None), Diagnoser(
        library, candidates=None if candidates is None else tuple(candidates), shapes=shapes),
        narrate)
    maps_spec = maps_spec or maps("grid")
    if start is None:
        spec = bmbe(valve)
        staircase.record(spec.build(library), [], "", spec.description)
        for make, added, category, reason in paper_steps(spec.valve, maps_spec):
            spec = make(ModelSpec.of(staircase.last.model))  # from the fitted previous step
            staircase.record(spec.build(library), added, category, reason)
    else:
        staircase.record(start, [], "", f"the starting model {start.name!r}")
    diagnosis = loop_end = staircase.add_diagnosed(max_additions)
    if calibrate and staircase.calibrate():
        # the final diagnosis is the final model's: what is left after the calibration too. A
        # finding there, which the maps' error hid until the maps were calibrated, is added as
        # any other (the calibration's factors refitted with it) while additions are left: the
        # loop stopped before the calibration, and its summary named a leak it had not added
        # (off-library case 4550, a leak growing with the temperature, on both kinds of maps)
        diagnosis = staircase.add_diagnosed(max_additions)
    else:
        loop_end = None
    steps = staircase.steps
    floor = noise_floor(steps[-1].log_replay.residual, steps[-1].log_replay.runs,
                        source=steps[-1].log_replay.log.source)
    for step in steps:  # the fits are done: their tables go (the steps' replays asked the maps)
        release_tables(step.model)
    return Workflow(log=log, steps=tuple(steps), final_diagnosis=diagnosis, noise_floor=floor,
                    seconds=time.perf_counter() - began,
                    maps=maps_spec.flow.kind if start is None else "",
                    dropped="; ".join(staircase.refusals), loop_end=loop_end)

