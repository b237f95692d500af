"""A virtual valve that differs from its CFD samples the way a real one does.

A synthetic log made by the very maps the model under test uses proves little: there the maps are
perfect. A real valve's are not (the paper's Table 4 and the guide's section 6):

* **each opening's mesh carries its own systematic error**: refining the mesh moved Δp by up to
  1.9 % and the choice of cavitation model moved f_sim by about 1 %. Here every sampled opening
  gets a Δp error and a flow-force error of its own, drawn once per case and shared by all its
  temperatures and flows (:attr:`MapMismatch.dp_per_opening`, :attr:`MapMismatch.force_per_opening`);
* **where the CFD has no opening the valve follows its own curve**: below the smallest opening and
  across the unsampled gap (0.20–0.63 mm in the shipped set) the real characteristic does not
  follow the grid's power-law bridge. Here extra sweeps at openings inside those ranges carry a
  smooth deviation from the bridge (:attr:`MapMismatch.gap_dp`, :attr:`MapMismatch.gap_force`,
  :attr:`MapMismatch.seat_exponent`);
* **the flow force depends on the back pressure through cavitation**, which maps built at one
  back pressure miss: here f_ff·(1 + c·ln((p_B + p_atm)/(p_ref + p_atm))), zero at the samples'
  back pressure (:class:`CavitationFlowForce`, :attr:`MapMismatch.cavitation`).

The valve's maps are grid maps built from the perturbed samples (plus the extra sweeps), so their
errors are those of a CFD that was run once more with other meshes. :func:`mismatched_samples`
returns those samples, which a user can write out and train any map kind on;
:func:`mismatched_truth` turns a model spec into the virtual valve.

A grid valve bridges openings and gaps the grid's way, which is not a learned map's: between
them a GP and the grid differ by more than a real valve differs from either. So for a model under
test on other maps, :func:`mismatched_truth` can instead wrap that model's own maps with the same
draws (:class:`PerturbedFlowMap`, :class:`PerturbedForceMap`): the virtual valve is then "these
maps, wrong by a CFD's error", whatever their kind.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..data.loaders import CfdSamples
from ..effects import BalanceState, Effect, Parameter
from ..fluid import FluidState
from ..maps.base import FlowMap, ForceMap
from ..maps.cfd_error import SEAT_EXPONENT_ERROR
from ..maps.coverage import Coverage
from ..maps.grid import GridFlowMap, GridForceMap
from ..model import ValveModel
from ..core.units import BAR, P_ATM
from ..valve import ValveParameters


@dataclass(frozen=True)
class MapMismatch:
    """How far the virtual valve strays from its CFD samples (1σ of each random draw).

    Attributes
    ----------
    dp_per_opening : float
        Relative Δp error of each sampled opening's sweeps [1] (the paper's mesh study: ≤ 1.9 %).
    force_per_opening : float
        Relative flow-force error of each sampled opening [1].
    gap_dp, gap_force : float
        Amplitude of a smooth bump (a half sine in ln u) in Δp and in the flow-force fraction
        across every unsampled gap between openings [1].
    seat_exponent : float
        Exponents k of the continuation below the smallest opening u₀: Δp and the flow-force
        fraction change by (u/u₀)^k there instead of being held [1].
    cavitation : float
        The coefficient c of :class:`CavitationFlowForce` [1].
    """

    dp_per_opening: float = 0.015
    force_per_opening: float = 0.025
    gap_dp: float = 0.03
    gap_force: float = 0.05
    seat_exponent: float = SEAT_EXPONENT_ERROR
    cavitation: float = 0.03

    def scaled(self, factor: float) -> "MapMismatch":
        """Every spread times ``factor`` (0: the valve is its CFD)."""
        return MapMismatch(*(factor * getattr(self, name) for name in self.__dataclass_fields__))


class CavitationFlowForce(Effect):
    """The flow force changing with back pressure through cavitation:
    f_ff → f_ff·(1 + c·ln((p_B + p_atm)/(p_ref + p_atm))).

    Lower back pressure lets the jet cavitate more, which changes the pressure on the piston. The
    virtual valve of :mod:`.mismatch` has it; the library's linear
    ``back_pressure_flow_force`` is the candidate that approximates it.
    """

    name = "cavitation_flow_force"
    kind = "force"
    category = "map correction"
    title = "flow force changed by cavitation at low back pressure"
    parameter_specs = (
        Parameter("c", 0.0, "1", min=-0.5, max=0.5,
                  description="relative flow-force change per unit ln of absolute back pressure"),
        Parameter("p_ref", 5.0 * BAR, "bar", min=0.0, max=50.0 * BAR, vary=False,
                  description="back pressure of the CFD samples"),
    )
    validity = "A smooth stand-in for cavitation; zero at the samples' back pressure."

    def force(self, state: BalanceState) -> np.ndarray:
        return cavitation_change(self["c"], state.p_B, self["p_ref"]) * state.flow_force


def cavitation_change(c: float, p_B, p_ref: float) -> np.ndarray:
    """The relative change c·ln((p_B + p_atm)/(p_ref + p_atm)) of the flow force at back
    pressure ``p_B`` [Pa] against ``p_ref`` [Pa] (:class:`CavitationFlowForce`) [1]."""
    return c * np.log((np.maximum(p_B, 0.0) + P_ATM) / (p_ref + P_ATM))


@dataclass(frozen=True)
class MismatchDraw:
    """One case's random draws (relative, per opening [m]) and what they were drawn from."""

    dp_error: dict[float, float]
    force_error: dict[float, float]
    gap_dp: list[float]
    gap_force: list[float]
    seat_dp: float
    seat_force: float
    cavitation: float

    @classmethod
    def draw(cls, openings: np.ndarray, gaps: int, mismatch: MapMismatch,
             seed: int) -> "MismatchDraw":
        rng = np.random.default_rng([seed, 104729])  # its own stream: the log's noise keeps seed
        size = len(openings)
        return cls(dict(zip(openings, mismatch.dp_per_opening * rng.standard_normal(size))),
                   dict(zip(openings, mismatch.force_per_opening * rng.standard_normal(size))),
                   list(mismatch.gap_dp * rng.standard_normal(gaps)),
                   list(mismatch.gap_force * rng.standard_normal(gaps)),
                   float(mismatch.seat_exponent * rng.standard_normal()),
                   float(mismatch.seat_exponent * rng.standard_normal()),
                   float(mismatch.cavitation * rng.standard_normal()))


#: openings added inside each unsampled gap (fractions of the gap in ln u) and below the
#: smallest sampled opening (fractions of it)
GAP_POSITIONS = (0.25, 0.5, 0.75)
SEAT_FRACTIONS = (0.3, 0.6)


def mismatched_samples(samples: CfdSamples, valve: ValveParameters, seed: int,
                       mismatch: MapMismatch = MapMismatch()) -> tuple[CfdSamples, MismatchDraw]:
    """The samples a CFD with other meshes would have given, plus sweeps where none were run.

    Returns the perturbed samples (the originals' rows changed in place, in SI, plus extra sweeps
    inside the unsampled gaps and below the smallest opening) and the draws behind them.
    """
    frame = samples.frame.copy()
    back_area = valve.A_s3 - valve.A_B
    draw, gaps = _draw(samples, mismatch, seed)
    # 1. each sampled opening's own systematic error, in Δp and in the flow-force fraction
    dp = (frame["p_L"] - frame["p_B"]).to_numpy()
    fraction = ((frame["f_sim"] - frame["p_L"] * valve.A_L - frame["p_B"] * back_area)
                / (valve.A_L * dp)).to_numpy()
    u = frame["u"].to_numpy()
    dp = dp * (1.0 + np.array([draw.dp_error[x] for x in u]))
    fraction = fraction * (1.0 + np.array([draw.force_error[x] for x in u]))
    _set_dp_and_fraction(frame, dp, fraction, valve.A_L, back_area)
    # 2. the valve's own curve where the CFD has no opening: sweeps bridged by the perturbed
    # grid, then bent away from its bridge
    perturbed = CfdSamples(frame, samples.source)
    flow = GridFlowMap.from_samples(perturbed)
    force = GridForceMap.from_samples(perturbed, valve)
    extra = []
    for (low, high), bump_dp, bump_force in zip(gaps, draw.gap_dp, draw.gap_force):
        for t in GAP_POSITIONS:
            bend = np.sin(np.pi * t)
            extra.append(_bridged_sweeps(frame, flow, force, valve, low * (high / low) ** t,
                                         low, high, 1.0 + bump_dp * bend,
                                         1.0 + bump_force * bend))
    smallest = min(draw.dp_error)
    for share in SEAT_FRACTIONS:
        extra.append(_bridged_sweeps(frame, flow, force, valve, smallest * share, smallest,
                                     smallest, share ** draw.seat_dp, share ** draw.seat_force))
    frame = pd.concat([frame, *extra], ignore_index=True)
    frame["line"] = np.arange(2, len(frame) + 2)
    return CfdSamples(frame, f"{samples.source}, perturbed (mismatch seed {seed})"), draw


def _draw(samples: CfdSamples, mismatch: MapMismatch,
          seed: int) -> tuple[MismatchDraw, list[tuple[float, float]]]:
    """The case's draws for the openings and unsampled gaps of ``samples``, and those gaps."""
    gaps = Coverage.of_samples(samples.frame).gaps()
    openings = np.unique(samples.frame["u"].to_numpy())
    return MismatchDraw.draw(openings, len(gaps), mismatch, seed), gaps


def _set_dp_and_fraction(frame: pd.DataFrame, dp: np.ndarray, fraction: np.ndarray, A_L: float,
                         back_area: float) -> None:
    frame["p_L"] = frame["p_B"].to_numpy() + dp
    frame["f_sim"] = frame["p_L"] * A_L + frame["p_B"] * back_area + fraction * A_L * dp


def _bridged_sweeps(frame: pd.DataFrame, flow: GridFlowMap, force: GridForceMap,
                    valve: ValveParameters, u: float, low: float, high: float, dp_factor: float,
                    force_factor: float) -> pd.DataFrame:
    """Sweeps at opening ``u`` for every fluid state of the reference back pressure, at the flows
    of the neighbouring openings ``low`` and ``high``, from the grid times the factors."""
    reference = flow.fixed_back_pressure
    at_reference = frame[np.isclose(frame["p_B"], reference, rtol=0, atol=1e-3 * BAR)
                         & frame["u"].isin([low, high]) & (frame["q"] > 0)]
    rows = []
    for _, level in at_reference.groupby("nu"):
        flows = np.unique(level["q"].to_numpy())
        first = level.iloc[0]
        fluid = FluidState(np.full(len(flows), first["nu"]), np.full(len(flows), first["rho"]))
        p_B = np.full(len(flows), reference)
        opening = np.full(len(flows), u)
        bridged = flow.pressure_drop(flows, p_B, opening, fluid)  # the grid's own bridge
        fraction = force.flow_force(p_B + bridged, p_B, opening, fluid) / (valve.A_L * bridged)
        dp, fraction = bridged * dp_factor, fraction * force_factor
        sweep = pd.DataFrame({"case": [f"X{u * 1e6:.0f}-{i}" for i in range(len(flows))],
                              "oil": first["oil"], "temperature": first["temperature"],
                              "nu": first["nu"], "rho": first["rho"], "u": u, "q": flows,
                              "p_B": p_B})
        _set_dp_and_fraction(sweep, dp, fraction, valve.A_L, valve.A_s3 - valve.A_B)
        rows.append(sweep)
    return pd.concat(rows, ignore_index=True)


class MismatchFactor:
    """The factor a case's draws put on Δp (or on the flow force) at opening u [m]: the draw of
    each sampled opening, interpolated in ln u between neighbours, plus the bump across every
    unsampled gap, (u/u₀)^k below the smallest opening u₀ and held above the largest — what the
    grid of :func:`mismatched_samples` does to its samples, as a function."""

    def __init__(self, errors: dict[float, float], gaps: list[tuple[float, float]],
                 bumps: list[float], seat: float):
        self.openings = np.array(sorted(errors))
        self.errors = np.array([errors[u] for u in self.openings])
        self.gaps, self.bumps, self.seat = gaps, bumps, seat

    def __call__(self, u) -> np.ndarray:
        u = np.asarray(u, float)
        x = np.log(np.clip(u, self.openings[0], self.openings[-1]))
        factor = 1.0 + np.interp(x, np.log(self.openings), self.errors)
        for (low, high), bump in zip(self.gaps, self.bumps):
            t = (x - np.log(low)) / np.log(high / low)
            inside = (t > 0.0) & (t < 1.0)
            factor = factor * np.where(inside, 1.0 + bump * np.sin(np.pi * np.clip(t, 0, 1)),
                                       1.0)
        # below the smallest opening down to the lowest extra sweep, then held (the grid of the
        # perturbed samples holds its Δp's factor there and continues its flow force's power)
        below = np.clip(u / self.openings[0], min(SEAT_FRACTIONS), 1.0)
        return factor * below ** self.seat


class PerturbedFlowMap(FlowMap):
    """A flow map whose Δp at a given flow is ``factor(u)`` times another's."""

    kind = "perturbed flow map"

    def __init__(self, base: FlowMap, factor: MismatchFactor):
        self.base, self.factor = base, factor

    def pressure_drop(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        return self.base.pressure_drop(q, p_B, u, fluid) * self.factor(u)

    def flow(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        p_B = np.asarray(p_B, float)
        dp = (np.asarray(p_L, float) - p_B) / self.factor(u)
        return self.base.flow(p_B + dp, p_B, u, fluid)


class PerturbedForceMap(ForceMap):
    """A force map whose flow force is ``factor(u)`` times another's."""

    kind = "perturbed force map"

    def __init__(self, base: ForceMap, factor: MismatchFactor):
        self.base, self.factor = base, factor

    def flow_force(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        return self.base.flow_force(p_L, p_B, u, fluid) * self.factor(u)

    def force(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        return (self.base.force(p_L, p_B, u, fluid)
                + (self.factor(u) - 1.0) * self.base.flow_force(p_L, p_B, u, fluid))


def perturbed_maps(flow: FlowMap, force: ForceMap, samples: CfdSamples, seed: int,
                   mismatch: MapMismatch = MapMismatch()
                   ) -> tuple["PerturbedFlowMap", "PerturbedForceMap", MismatchDraw]:
    """``flow`` and ``force`` wrong by the draws of case ``seed`` (each sampled opening's own
    error, the gaps' bumps, the seat's exponent), and the draws (their ``cavitation`` is for
    :class:`CavitationFlowForce`)."""
    draw, gaps = _draw(samples, mismatch, seed)
    return (PerturbedFlowMap(flow, MismatchFactor(draw.dp_error, gaps, draw.gap_dp,
                                                  draw.seat_dp)),
            PerturbedForceMap(force, MismatchFactor(draw.force_error, gaps, draw.gap_force,
                                                    draw.seat_force)), draw)


def mismatched_truth(model: ValveModel, samples: CfdSamples, seed: int,
                     mismatch: MapMismatch = MapMismatch(), *,
                     own_maps: bool = False) -> ValveModel:
    """``model`` (its valve and effects) on grid maps of :func:`mismatched_samples`, with the
    case's :class:`CavitationFlowForce`: the virtual valve. With ``own_maps`` the valve keeps
    ``model``'s maps instead, wrapped with the same draws (:class:`PerturbedFlowMap`,
    :class:`PerturbedForceMap`)."""
    if own_maps:  # the draws alone: no perturbed samples to build grids from
        flow, force, draw = perturbed_maps(model.flow_map, model.force_map, samples, seed,
                                           mismatch)
        reference = GridFlowMap.from_samples(samples).fixed_back_pressure
    else:
        perturbed, draw = mismatched_samples(samples, model.valve, seed, mismatch)
        flow = GridFlowMap.from_samples(perturbed)
        force = GridForceMap.from_samples(perturbed, model.valve)
        reference = flow.fixed_back_pressure
    cavitation = CavitationFlowForce()
    cavitation.params["c"].value = draw.cavitation
    cavitation.params["p_ref"].value = reference
    effects = [e.copy() for e in model.effects if e.name != CavitationFlowForce.name]
    return ValveModel(model.valve, flow, force, [*effects, cavitation],
                      f"{model.name} (virtual valve, mismatch seed {seed})")
