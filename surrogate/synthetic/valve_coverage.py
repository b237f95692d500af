"""How well a map's ±2σ covers a virtual valve, region by region (``eval/valve_coverage.py``).

Cross-validation scores a map against CFD samples it did not see, so it cannot see the CFD's own
error. Here σ is judged where the truth is known: in virtual valves whose CFD errs as a real one
does (:mod:`.mismatch`). For each region of operating points (:func:`regions`), the valve's own Δp
gives the load pressure, the map under test is asked its flow there and its flow force, with σ,
and :func:`score` counts the states within ±2σ of the valve's.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..fluid import FluidState
from ..maps.coverage import Coverage
from ..maps.grid import GridFlowMap, GridForceMap
from ..core.units import BAR, to_si
from .mismatch import MapMismatch, cavitation_change, mismatched_samples, perturbed_maps

#: the regions of operating points, in the order reports list them
REGIONS = ("sampled", "between", "gap", "below", "temperatures", "oils", "back pressures")
#: the band ±2σ should hold in every region
BAND = (0.85, 0.98)
GAP_SHARES = (0.25, 0.5, 0.75)
#: openings below the smallest sampled one, as shares of it: a bench log spends much of its time
#: there, near the seat (the shipped one down to 0.015 mm, 0.3 of the smallest, 0.05 mm)
BELOW_SHARES = (0.3, 0.5, 0.7)
OTHER_TEMPERATURES_C = (30.0, 50.0)
VISCOSITY_FACTORS = (0.7, 1.5)
OTHER_BACK_PRESSURES_BAR = (2.5, 7.5, 15.0)
#: the back pressure of the samples' sweeps (the others are the back-pressure set)
REFERENCE_BACK_BAR = 5.0
#: states whose valve Δp lies beyond the samples' are left out (no valve is run there)
DP_MAX_BAR = 400.0


def regions(samples, valve) -> dict[str, pd.DataFrame]:
    """The operating points of each region: u [m], q [m³/s], nu [m²/s], rho [kg/m³], p_B [Pa]."""
    frame = samples.frame[samples.frame["q"] > 0]
    reference = frame[np.isclose(frame["p_B"], REFERENCE_BACK_BAR * BAR)]
    openings = np.unique(frame["u"])
    gaps = Coverage.of_samples(samples.frame).gaps()

    def at_openings(opening_list, rows) -> pd.DataFrame:
        """Every fluid state and flow of ``rows`` (their openings' neighbours) at each opening."""
        out = []
        for u, neighbours in opening_list:
            neighbour_rows = rows[rows["u"].isin(neighbours)]
            for (nu, rho), level in neighbour_rows.groupby(["nu", "rho"]):
                flows = np.unique(level["q"])
                out.append(pd.DataFrame({"u": u, "q": flows, "nu": nu, "rho": rho,
                                         "p_B": REFERENCE_BACK_BAR * BAR}))
        return pd.concat(out, ignore_index=True)

    pairs = [(low, high) for low, high in zip(openings, openings[1:])
             if not any(np.isclose(low, a) and np.isclose(high, b) for a, b in gaps)]
    between = at_openings([(np.sqrt(low * high), (low, high)) for low, high in pairs], reference)
    gap = at_openings([(low * (high / low) ** t, (low, high)) for low, high in gaps
                       for t in GAP_SHARES], reference)
    smallest = reference[np.isclose(reference["u"], openings[0])]
    below = pd.concat([smallest[["u", "q", "nu", "rho", "p_B"]].assign(u=share * openings[0],
                                                                      q=smallest["q"] * share)
                       for share in BELOW_SHARES], ignore_index=True)
    sampled_40 = reference[np.isclose(reference["temperature"], to_si(40.0, "degC"))]
    sampled_openings = [(u, (u,)) for u in openings]
    temperatures = []
    for celsius in OTHER_TEMPERATURES_C:
        fluid = valve.oil.state(np.array([to_si(celsius, "degC")]))
        rows = at_openings(sampled_openings, sampled_40)
        temperatures.append(rows.assign(nu=float(fluid.nu[0]), rho=float(fluid.rho[0])))
    oils = [at_openings(sampled_openings, sampled_40).assign(nu=lambda t, f=factor: t["nu"] * f)
            for factor in VISCOSITY_FACTORS]
    backs = [at_openings(sampled_openings, sampled_40).assign(p_B=bar * BAR)
             for bar in OTHER_BACK_PRESSURES_BAR]
    return {"sampled": frame[["u", "q", "nu", "rho", "p_B"]].reset_index(drop=True),
            "between": between, "gap": gap, "below": below,
            "temperatures": pd.concat(temperatures, ignore_index=True),
            "oils": pd.concat(oils, ignore_index=True),
            "back pressures": pd.concat(backs, ignore_index=True)}


def valve_truth(samples, valve, seed: int, mismatch: MapMismatch, on=()):
    """(Δp(q, p_B, u, fluid), flow force(p_L, p_B, u, fluid)) of the virtual valve ``seed``:
    grid maps of its perturbed samples, or with ``on`` = [(flow map, force map), …] those maps
    wrong by the same draws, averaged when there are several, each weighted by 1/σ² where it is
    asked (a map that knows it cannot tell, the grid's flow force away from its back pressure,
    counts little): a valve that bridges openings, oils and back pressures as none of them
    alone does."""
    if not on:
        perturbed, draw = mismatched_samples(samples, valve, seed, mismatch)
        on = [(GridFlowMap.from_samples(perturbed), GridForceMap.from_samples(perturbed, valve))]
        pairs = on
    else:
        pairs = []
        for maps in on:
            flow, force, draw = perturbed_maps(*maps, samples, seed, mismatch)
            pairs.append((flow, force))
    reference = REFERENCE_BACK_BAR * BAR

    def pressure_drop(q, p_B, u, fluid):
        values = [np.log(flow.pressure_drop(q, p_B, u, fluid)) for flow, _ in pairs]
        weights = [_precision(base.log_discharge_std(q, p_B, u, fluid), values[0])
                   for base, _ in on]
        return np.exp(np.average(values, axis=0, weights=weights))

    def flow_force(p_L, p_B, u, fluid):
        values = [force.flow_force(p_L, p_B, u, fluid) for _, force in pairs]
        weights = [_precision(base.relative_force_std(p_L, p_B, u, fluid), values[0])
                   for _, base in on]
        return np.average(values, axis=0, weights=weights) * (
            1.0 + cavitation_change(draw.cavitation, p_B, reference))
    return pressure_drop, flow_force


def _precision(std, like: np.ndarray) -> np.ndarray:
    """1/σ² of a map where it is asked (1 for a map without σ), shaped like ``like``."""
    if std is None:
        return np.ones(np.shape(like))
    return np.broadcast_to(1.0 / np.square(std), np.shape(like))


def score(kind_maps, truth, table: pd.DataFrame) -> dict:
    """Errors and ±2σ coverage of one kind's maps on one region's states of one valve."""
    flow_map, force_map = kind_maps
    pressure_drop, true_flow_force = truth
    fluid = FluidState(table["nu"].to_numpy(), table["rho"].to_numpy())
    u, q, p_B = (table[key].to_numpy() for key in ("u", "q", "p_B"))
    dp = pressure_drop(q, p_B, u, fluid)
    keep = np.isfinite(dp) & (dp > 0) & (dp < DP_MAX_BAR * BAR)
    fluid = FluidState(fluid.nu[keep], fluid.rho[keep])
    u, q, p_B, dp = u[keep], q[keep], p_B[keep], dp[keep]
    p_L = p_B + dp
    with np.errstate(all="ignore"):
        q_map = flow_map.flow(p_L, p_B, u, fluid)
        q_std = flow_map.flow_std(p_L, p_B, u, fluid)
        f_true = true_flow_force(p_L, p_B, u, fluid)
        f_map = force_map.flow_force(p_L, p_B, u, fluid)
        f_std = force_map.force_std(p_L, p_B, u, fluid)
    out = {"states": int(keep.sum())}
    for name, predicted, true, std in (("q", q_map, q, q_std), ("flow force", f_map, f_true,
                                                                 f_std)):
        error = np.abs(predicted - true)
        relative = error / np.abs(true)
        out[name] = {"errors": relative, "sigmas": None if std is None else std / np.abs(true),
                     "covered": None if std is None else error <= 2.0 * std}
    return out


def summarise(parts: list[dict]) -> dict:
    """One kind and region over every valve: median and 90th percentile of the relative error
    [%], median σ [%], the share within ±2σ and its 90 % interval over the valves.

    A valve's states share its draws (one mesh bias per opening, one bump across the gap), so
    they fall inside or outside ±2σ together: the valve, not the state, is the unit of chance,
    and with five valves one unlucky draw moves a share by up to a fifth. The interval resamples
    whole valves (a bootstrap of ``BOOTSTRAP`` resamples, seeded so the table is repeatable).
    """
    summary = {"states": sum(part["states"] for part in parts)}
    for name in ("q", "flow force"):
        errors = np.concatenate([part[name]["errors"] for part in parts])
        entry = {"median error %": round(100 * float(np.median(errors)), 3),
                 "p90 error %": round(100 * float(np.quantile(errors, 0.9)), 3)}
        if parts[0][name]["covered"] is not None:
            sigmas = np.concatenate([part[name]["sigmas"] for part in parts])
            covered = np.concatenate([part[name]["covered"] for part in parts])
            entry |= {"median sigma %": round(100 * float(np.median(sigmas)), 3),
                      "within 2 sigma": round(float(np.mean(covered)), 3),
                      "within 2 sigma, 90 % interval": _interval_over_valves(
                          [part[name]["covered"] for part in parts])}
        summary[name] = entry
    return summary


#: resamples of the valves behind a share's interval
BOOTSTRAP = 2000


def _interval_over_valves(covered: list[np.ndarray]) -> list[float]:
    """5th and 95th percentiles of the share within ±2σ when whole valves are resampled."""
    inside = np.array([np.sum(part) for part in covered], float)
    states = np.array([len(part) for part in covered], float)
    draws = np.random.default_rng(0).integers(0, len(covered), (BOOTSTRAP, len(covered)))
    shares = inside[draws].sum(axis=1) / states[draws].sum(axis=1)
    return [round(float(value), 3) for value in np.quantile(shares, (0.05, 0.95))]
