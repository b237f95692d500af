"""What a diagnosis found, as numbers: each candidate's scores and the diagnosis as a whole.

Both are immutable; the words that explain them are :mod:`surrogate.reporting.prose`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..fitting.heldout import HEADLINE, Linearised
from ..fitting.residuals import LogReplay
from ..model import ValveModel
from ..planning.bench_runs import Separation
from ..core.units import from_si
from .rule import RULE, SignificanceRule


class _Of:
    """An attribute of one of a record's parts, read as the record's own (a candidate's name is
    its label's, a diagnosis' noise floor its baseline's)."""

    def __init__(self, part: str):
        self.part = part

    def __set_name__(self, owner, name: str):
        self.name = name

    def __get__(self, record, owner=None):
        return self if record is None else getattr(getattr(record, self.part), self.name)


@dataclass(frozen=True)
class Label:
    """What a candidate is: its effect's name, title, description, kind and category
    (physics, map correction or sensor, :data:`surrogate.effects.CATEGORIES`), whether it has a
    parameter per run (a sensor check, never part of the model), and the size (display units)
    below which a per-run value is not flagged."""

    name: str
    title: str
    description: str
    kind: str
    category: str
    per_run: bool = False
    check_threshold: float = 0.0


@dataclass(frozen=True)
class Score:
    """How a candidate scored: its fit's RMS and its ΔBIC (against the maps' discrepancy once
    judged, :mod:`.judge`), on held-out runs, in the views of the hysteresis and over resamples
    of runs, the candidates the data cannot tell from it, and the rule's verdict
    (:mod:`.rule`)."""

    rms_after: float  # [Pa]
    delta_bic: float
    heldout_rms: float = float("nan")  # [Pa] on held-out runs, each left out in turn
    heldout: dict = field(default_factory=dict)  # [Pa] per held-out scheme (and "pooled")
    median_rms: float = float("nan")  # [Pa] of the median line of the runs' residual after
    half_width_rms: float = float("nan")  # [Pa] of the half-width (surrogate.fitting.hysteresis)
    inclusion: float = 0.0  # share of bootstrap resamples over runs that select it
    own_view: bool = True  # narrows the hysteresis view its physics acts on
    stable: bool = True  # it or its group is chosen in most resamples over runs
    group: tuple[str, ...] = ()  # it and the candidates these data cannot tell from it
    significant: bool = False


@dataclass(frozen=True)
class Candidate:
    """One candidate effect, refitted together with the model's free parameters: what it is
    (:class:`Label`), what was fitted, and how it scored (:class:`Score`), whose figures it
    reads as its own."""

    label: Label
    score: Score
    params: tuple = ()  # fitted Parameters of the candidate
    extra: float = 0  # parameters of its own the data inform (a shape's effective number)
    model: ValveModel | None = field(default=None, repr=False)  # the current model + this effect
    replay: LogReplay | None = field(default=None, repr=False)  # its replay of the log
    #: a shape-free term's fitted shape against its variable, with its band (None otherwise)
    curve: "ShapeCurve | None" = field(default=None, repr=False)
    change: np.ndarray | None = field(default=None, repr=False)  # prediction change [Pa]
    #: its residual and Jacobian at its fit, parameters on a bound held (and a shape's roughness)
    linearised: Linearised | None = field(default=None, repr=False)
    #: ∂Δp/∂(own parameter) at the model's point, per solved sample [Pa per unit], by forward
    #: differences (the refits' Broyden-corrected Jacobian no longer has true columns)
    probe: np.ndarray | None = field(default=None, repr=False)

    name = _Of("label")
    title = _Of("label")
    description = _Of("label")
    kind = _Of("label")
    category = _Of("label")
    per_run = _Of("label")
    check_threshold = _Of("label")
    rms_after = _Of("score")  # [Pa]
    delta_bic = _Of("score")
    heldout_rms = _Of("score")  # [Pa]
    heldout = _Of("score")  # [Pa] per scheme
    median_rms = _Of("score")  # [Pa]
    half_width_rms = _Of("score")  # [Pa]
    inclusion = _Of("score")
    own_view = _Of("score")
    stable = _Of("score")
    group = _Of("score")
    significant = _Of("score")

    def scored(self, **changes) -> "Candidate":
        """The candidate with its :class:`Score` changed as given."""
        return replace(self, score=replace(self.score, **changes))

    def settled(self) -> "Candidate":
        """The candidate as a finished diagnosis keeps it: the fitting's working arrays (its
        linearisation, probe columns and prediction change, a few megabytes on a long log)
        dropped. Its model, replay and curve stay: a workflow adds the best one from them and
        the report draws its shape."""
        return replace(self, linearised=None, probe=None, change=None)

    @property
    def shape_free(self) -> bool:
        """Whether this is a shape-free term (:mod:`surrogate.effects.shapes`), not a library
        effect with a named shape."""
        return self.curve is not None

    @property
    def effect(self):
        """The candidate's fitted effect (in :attr:`model`)."""
        return None if self.model is None else self.model.effect(self.name)

    def to_json(self) -> dict:
        return {
            "name": self.name, "description": self.description, "title": self.title,
            "kind": self.kind, "category": self.category,
            "rms_after_bar": rounded_bar(self.rms_after),
            "heldout_rms_bar": rounded_bar(self.heldout_rms),
            "median_line_rms_bar": rounded_bar(self.median_rms),
            "half_width_rms_bar": rounded_bar(self.half_width_rms),
            "heldout_rms_by_scheme_bar": {k: rounded_bar(v)
                                          for k, v in self.heldout.items() if k != "pooled"},
            "inclusion": round(float(self.inclusion), 3), "stable": bool(self.stable),
            "gains_in_own_view": bool(self.own_view),
            "delta_bic": round(float(self.delta_bic), 2), "significant": bool(self.significant),
            "per_run": bool(self.per_run), "group": list(self.group),
            "params": {p.name: p.to_record() for p in self.params},
            **({"shape": self.curve.to_json()} if self.curve is not None else {}),
        }


@dataclass(frozen=True)
class ShapeCurve:
    """A shape-free term's fitted shape on a grid of its variable, in display units.

    ``band`` is one standard deviation of the shape at each point, from the fit's covariance
    (penalised as the fit was); ``weight`` the roughness weight the held-out runs chose.
    """

    variable: str  # the variable's name (surrogate.effects.shapes.VARIABLES)
    label: str  # what it is, in words
    unit: str  # its display unit
    value_unit: str  # the shape's
    x: np.ndarray
    value: np.ndarray
    band: np.ndarray
    weight: float

    def to_json(self) -> dict:
        return {"variable": self.variable, "unit": self.unit, "value_unit": self.value_unit,
                "roughness_weight": self.weight,
                "x": [round(float(v), 6) for v in self.x],
                "value": [round(float(v), 6) for v in self.value],
                "band": [round(float(v), 6) for v in self.band]}


@dataclass(frozen=True)
class Rival:
    """A look-alike of another kind fitted in a physics claim's place (:mod:`.lookalikes`): a
    shape-free term of another physical kind, a shape-free correction of the maps, or the maps'
    own error within their σ (:data:`.lookalikes.MAPS_ERROR`, no model)."""

    name: str
    title: str
    kind: str
    category: str
    #: [Pa] on held-out runs, per scheme (:func:`~surrogate.fitting.heldout.run_groups`)
    heldout: dict
    #: [Pa] the same with the maps' error within their σ fitted beside it
    beside_maps: dict = field(default_factory=dict)
    model: ValveModel | None = field(default=None, repr=False)  # the model with it fitted

    @property
    def heldout_rms(self) -> float:
        """[Pa] on held-out runs, each left out in turn."""
        return self.heldout.get(HEADLINE, float("nan"))

    def to_json(self) -> dict:
        return {"name": self.name, "title": self.title, "kind": self.kind,
                "category": self.category, "heldout_rms_bar": rounded_bar(self.heldout_rms)}


@dataclass(frozen=True)
class Declined:
    """A physics claim the loop does not make: look-alikes of other kinds predict the held-out
    runs about as well (:meth:`.rule.SignificanceRule.beats`), closest first, and the bench run
    that would tell the claim from the closest with a model, if any."""

    claim: Candidate
    rivals: tuple[Rival, ...]
    separation: Separation | None = None
    #: [Pa] per scheme: the claim's held-out RMS with the maps' error fitted beside it
    beside_maps: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"claim": self.claim.name, "claim_heldout_rms_bar":
                rounded_bar(self.claim.heldout_rms),
                "claim_with_maps_error_heldout_rms_bar": rounded_bar(
                    self.beside_maps.get(HEADLINE, float("nan"))),
                "look_alikes": [rival.to_json() for rival in self.rivals],
                "separating_run": (None if self.separation is None
                                   else self.separation.to_json())}


@dataclass(frozen=True)
class SensorCheck:
    """A run whose per-run parameter lies well outside its standard error (display units)."""

    effect: str
    title: str
    run: str
    value: float
    stderr: float
    unit: str


@dataclass(frozen=True)
class MapLimit:
    """Where the maps' fitted discrepancy is largest: a discrepancy term and its RMS [Pa]."""

    where: str
    rms: float


@dataclass(frozen=True)
class Baseline:
    """The model's residual before any candidate, as the diagnosis judged it: its RMS, the noise
    floor, how many independent samples it holds, its RMS on held-out runs, what the maps' σ
    allows, where the maps' error is largest, and its hysteresis views."""

    rms_before: float  # [Pa]
    noise_floor: float  # [Pa]
    effective_samples: float
    correlations: dict[str, float] = field(default_factory=dict)  # with the log's variables
    heldout_by_scheme: dict = field(default_factory=dict)  # [Pa] per held-out scheme
    expected_rms: float = float("nan")  # [Pa] what noise and the maps' σ_Δp allow together
    map_limits: tuple[MapLimit, ...] = ()  # where the maps' error is largest
    median_before: float = float("nan")  # [Pa] RMS of the residual's median line
    half_width_before: float = float("nan")  # [Pa] RMS of its half-width

    @property
    def heldout_before(self) -> float:
        """[Pa] the model's RMS on runs left out in turn."""
        return self.heldout_by_scheme.get(HEADLINE, float("nan"))


@dataclass(frozen=True)
class Diagnosis:
    """The result of :class:`~surrogate.diagnosis.diagnose.Diagnoser`, in numbers: the residual
    it started from (:class:`Baseline`, whose figures it reads as its own), the candidates
    judged, and what it concluded; its summary in words is
    :func:`surrogate.reporting.prose.summarise`."""

    model: ValveModel
    base: LogReplay
    baseline: Baseline
    candidates: tuple[Candidate, ...]
    sensor_checks: tuple[SensorCheck, ...] = ()  # per-run readings off
    #: the bench run that would tell the best candidate from its first look-alike, if any
    separation: Separation | None = None
    #: candidates the model's own parameters already mimic on this log (:func:`.lookalikes.
    #: absorbed`): {candidate: (parameter, cosine of their columns)}
    absorbed: dict = field(default_factory=dict)
    #: the physics claim withheld because look-alikes of other kinds fit as well, if any
    declined: Declined | None = None
    #: the rule the diagnosis judged by, which its words quote (:mod:`surrogate.reporting.prose`)
    rule: SignificanceRule = RULE

    # the baseline's figures, read as the diagnosis' own
    rms_before = _Of("baseline")  # [Pa]
    noise_floor = _Of("baseline")  # [Pa]
    effective_samples = _Of("baseline")
    correlations = _Of("baseline")
    heldout_by_scheme = _Of("baseline")  # [Pa] per scheme
    heldout_before = _Of("baseline")  # [Pa]
    expected_rms = _Of("baseline")  # [Pa]
    map_limits = _Of("baseline")
    median_before = _Of("baseline")  # [Pa]
    half_width_before = _Of("baseline")  # [Pa]

    @property
    def best(self) -> Candidate | None:
        """The best significant candidate, or None."""
        return next((c for c in self.candidates if c.significant), None)

    @property
    def explanations(self) -> tuple[Candidate, ...]:
        """The finding's explanations: the best candidate and the look-alikes this log cannot
        tell from it, in rank order (empty without a finding)."""
        best = self.best
        return () if best is None else tuple(c for c in self.candidates if c.name in best.group)

    def group_inclusion(self, candidate: Candidate) -> float:
        """The share of resamples over runs that add ``candidate`` or a look-alike of its
        group."""
        return float(sum(c.inclusion for c in self.candidates if c.name in candidate.group))


def rounded_bar(value: float) -> float | None:
    """[Pa] -> bar to 4 decimals, None for NaN (JSON has no NaN)."""
    return round(float(from_si(value, "bar")), 4) if np.isfinite(value) else None

