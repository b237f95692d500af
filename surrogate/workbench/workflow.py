"""The closed loop: from the paper's basic model to one the bench data cannot fault.

Steps
-----
1. ``bmbe``: the paper's basic model (orifice equation, C_d = 0.4, uniform pressure), as is.
2. ``bmbebf``: its discharge coefficient fitted (a C_d scale) — the paper's best-fit basic model.
3. ``cfd-maps``: the CFD grid maps replace the orifice equation and the uniform pressure, with a
   fitted flow-force scale — the paper's CFDA without friction.
4. ``cfda``: plus Coulomb friction s·(K1 + K2·p_L), one K1 and one K2 for all temperatures.
5. Then, until nothing significant is left: diagnose (:mod:`.diagnose`), add the best significant
   candidate, refit every free parameter together.

Every step refits all free parameters against every sample of the log (:func:`.fit.fit_to_log`);
the RMS after each step is the *error staircase*.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from ..data.loaders import BenchLog
from ..effects import ConstantFriction, DischargeScale, FlowForceScale, LoadPressureFriction
from ..maps.registry import build_maps
from ..model import MapsSource, ValveModel
from ..modelfile import cfda_effects, preset
from ..units import from_si
from .diagnose import Diagnosis, diagnose
from .fit import fit_to_log
from .residuals import LogReplay, noise_floor, replay_log

MAX_ADDITIONS = 8  # effects the loop may add after the paper's steps


@dataclass
class Step:
    """One step of the staircase.

    Attributes
    ----------
    model : ValveModel
        The model after the step, fitted.
    added : list of str
        Effects added in this step ([] for the starting model).
    reason : str
        Why (the paper's step, or the diagnosis' sentence).
    played : LogReplay
        Its replay of the log.
    rms : float
        Residual RMS [Pa].
    diagnosis : Diagnosis or None
        The diagnosis that chose the step's effect.
    """

    model: ValveModel
    added: list[str]
    reason: str
    played: LogReplay
    rms: float
    diagnosis: Diagnosis | None = None

    def to_json(self) -> dict:
        parameters = {f"{effect.name}.{p.name}": {"value": round(p.display_value, 6),
                                                  "unit": p.unit, "stderr": p.display_stderr}
                      for effect, p in self.model.parameters() if p.vary}
        return {"model": self.model.name, "added": self.added,
                "rms_bar": round(float(from_si(self.rms, "bar")), 4), "reason": self.reason,
                "parameters": parameters}


@dataclass
class Workflow:
    """The staircase and the final diagnosis."""

    log: BenchLog
    steps: list[Step]
    final_diagnosis: Diagnosis
    noise_floor: float  # [Pa], of the final model's residual
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)

    @property
    def final(self) -> Step:
        return self.steps[-1]

    def to_json(self) -> dict:
        return {"data": self.log.source, "samples": len(self.log),
                "noise_floor_bar": round(float(from_si(self.noise_floor, "bar")), 4),
                "final_rms_over_noise": round(self.final.rms / self.noise_floor, 3),
                "summary": self.final_diagnosis.summary,
                "steps": [step.to_json() for step in self.steps],
                "seconds": round(self.seconds, 1)}


def paper_steps(valve) -> list[tuple[str, Callable[[ValveModel], ValveModel], list[str], str]]:
    """The paper's steps as (name, make from the previous model, added effects, reason)."""

    def bmbebf(previous: ValveModel) -> ValveModel:
        return previous.with_effects([DischargeScale()], name="bmbebf")

    def cfd_maps(previous: ValveModel) -> ValveModel:
        flow_map, force_map = build_maps("grid", valve)
        return ValveModel(valve, flow_map, force_map, [FlowForceScale(scale=0.9)], "cfd-maps",
                          MapsSource("grid"))

    def cfda(previous: ValveModel) -> ValveModel:
        starting = {e.name: e for e in cfda_effects()}
        return previous.with_effects(
            [*previous.effects, starting[ConstantFriction.name],
             starting[LoadPressureFriction.name]], name="cfda")

    return [
        ("bmbebf", bmbebf, [DischargeScale.name],
         "the paper's BMBEBF: the orifice equation's discharge coefficient fitted"),
        ("cfd-maps", cfd_maps, ["grid maps", FlowForceScale.name],
         "CFD maps of flow and force replace the orifice equation (the paper's CFDA without "
         "friction), with a fitted flow-force scale"),
        ("cfda", cfda, [ConstantFriction.name, LoadPressureFriction.name],
         "the paper's CFDA: Coulomb friction K1 + K2·p_L, one pair for all temperatures"),
    ]


def run_workflow(log: BenchLog, *, start: ValveModel | None = None,
                 candidates: list[str] | None = None, max_additions: int = MAX_ADDITIONS,
                 progress: Callable[[str], None] | None = None) -> Workflow:
    """Run the loop on ``log`` (see the module docstring).

    Parameters
    ----------
    log : BenchLog
    start : ValveModel, optional
        Start here instead of at ``bmbe`` and skip the paper's steps.
    candidates : list of str, optional
        Effect names the diagnosis may choose from (default: every registered effect).
    max_additions : int
        Effects added by diagnosis at most.
    progress : callable, optional
        Called with a line of text at every stage.
    """
    began = time.perf_counter()
    say = progress or (lambda message: None)
    steps: list[Step] = []

    def record(model: ValveModel, added: list[str], reason: str,
               diagnosis: Diagnosis | None = None, near: LogReplay | None = None) -> Step:
        """Fit ``model`` (``near``: a replay close to its optimum), replay it, add the step."""
        if near is None and steps and steps[-1].model.flow_map is model.flow_map:
            near = steps[-1].played
        if any(p.vary for _, p in model.parameters()):
            model = fit_to_log(model, log, start=near).model
        played = replay_log(model, log, guess=near)
        step = Step(model, added, reason, played, played.rms(), diagnosis)
        steps.append(step)
        say(f"step {len(steps)}: {model.name:<28} rms {from_si(step.rms, 'bar'):6.3f} bar"
            f"   (+ {', '.join(added) or 'nothing'})")
        return step

    if start is None:
        model = preset("bmbe")
        record(model, [], "the paper's basic model BMBE: orifice equation with C_d = 0.4 and "
                          "a uniform pressure on the piston")
        for _, make, added, reason in paper_steps(model.valve):
            record(make(steps[-1].model), added, reason)
    else:
        record(start, [], f"the starting model {start.name!r}")

    additions = 0
    while True:
        current = steps[-1]
        say(f"diagnosing {current.model.name} ...")
        diagnosis = diagnose(current.model, log, base=current.played, candidates=candidates)
        say(f"  {diagnosis.summary}")
        best = diagnosis.best
        if best is None or additions == max_additions:
            break
        # the diagnosis already refitted every parameter with the effect added: polish that
        record(best.model.copy(name=f"{current.model.name}+{best.name}"), [best.name],
               diagnosis.summary, diagnosis, near=best.replay)
        additions += 1
    floor = noise_floor(steps[-1].played.residual, steps[-1].played.runs)
    return Workflow(log, steps, diagnosis, floor, time.perf_counter() - began)

