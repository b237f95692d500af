"""The valve's operating envelope: the inputs a system simulation may feed an exported valve.

A bench log covers a few ramps; a machine's simulation leaves that range at once (another back
pressure, a cold start, a larger flow). So the tables of an export span the valve's envelope,
not the fitted log's:

* flow from nearly zero (a share of the highest; below it the valve sits at its cracking point
  and is held there) to a margin above the largest flow either the CFD or the bench saw;
* back pressure from zero to at least :data:`BACK_PRESSURE_BAR`;
* pilot pressure from zero to the one that holds the piston on its stop with no flow at the
  highest back pressure (beyond it the piston cannot move, so holding the table's edge is the
  valve's own behaviour), and at least past the log's;
* the temperatures of the CFD's viscosities and the log's, widened by
  :data:`TEMPERATURE_MARGIN_K` either side.

Everything beyond the maps' samples inside this envelope is the maps' extrapolation, as it is in
the package's own solver; the export's manifest says which share of the envelope that is.
"""

from __future__ import annotations

import numpy as np

from ..model import ValveModel
from ..points import OperatingPoints
from ..core.units import to_si
from .tables import TableGrid

#: the highest tabulated flow over the largest flow sampled by the CFD or measured [-]
FLOW_MARGIN = 1.25
#: the lowest tabulated flow as a share of the highest [-]
LOWEST_FLOW_SHARE = 0.02
#: [bar] the back pressure the tables reach at least (return lines of mobile machines)
BACK_PRESSURE_BAR = 10.0
#: the highest tabulated pilot pressure over the one that holds the piston on its stop [-]
PILOT_MARGIN = 1.1
#: [bar] the pilot pressure the tables reach at least beyond the log's highest
PILOT_BEYOND_LOG_BAR = 10.0
#: [K] the temperature range's widening beyond the CFD's and the log's temperatures
TEMPERATURE_MARGIN_K = 10.0


def valve_envelope(model: ValveModel, points: OperatingPoints, scale: float = 1.0
                   ) -> TableGrid:
    """The grid over ``model``'s valve's envelope (see the module's docstring); ``points`` (the
    fitted bench log's) only widen it."""
    valve, coverage = model.valve, model.flow_map.coverage
    q, p_B = points.q[np.isfinite(points.q)], points.p_B[np.isfinite(points.p_B)]
    p_P = points.p_P[np.isfinite(points.p_P)]
    temperature = points.temperature[np.isfinite(points.temperature)]
    sampled_q = float(np.max(coverage.q_high)) if coverage is not None else 0.0
    q_high = FLOW_MARGIN * max(sampled_q, float(q.max(initial=0.0)))
    p_B_high = max(float(to_si(BACK_PRESSURE_BAR, "bar")), float(p_B.max(initial=0.0)))
    # net force with no flow, p_L = p_B and the piston on its stop: A_P (p_P - p_B) - F_cr - K_f U
    on_stop = p_B_high + (valve.F_cr + valve.K_f * valve.U_max) / valve.A_P
    p_P_high = max(PILOT_MARGIN * on_stop,
                   float(p_P.max(initial=0.0)) + float(to_si(PILOT_BEYOND_LOG_BAR, "bar")))
    known = list(temperature)
    if coverage is not None:
        known += list(valve.oil.temperature(np.asarray(coverage.nu_range, float)))
    t_low, t_high = min(known), max(known)
    return TableGrid((LOWEST_FLOW_SHARE * q_high, q_high), (0.0, p_B_high), (0.0, p_P_high),
                     (t_low - TEMPERATURE_MARGIN_K, t_high + TEMPERATURE_MARGIN_K), scale)


#: the states of :func:`probe_runs`: shares of each range (back pressure, pilot pressure,
#: temperature), the corners a machine's simulation visits that a bench log seldom does
PROBE_STATES = ((0.05, 0.25, 0.05), (0.9, 0.75, 0.95), (0.9, 0.5, 0.05), (0.05, 0.4, 0.95))
#: samples per ramp of :func:`probe_runs`, up and down each
PROBE_SAMPLES = 60


def probe_runs(grid: TableGrid) -> tuple[OperatingPoints, np.ndarray]:
    """Smooth runs across ``grid``'s ranges, none of them a fitted log's: at each of
    :data:`PROBE_STATES`, the flow ramped up and down from 3 % to 95 % of its range (evenly in
    ln q). Returns the points and their run labels (0, 1, ...)."""
    q_low, q_high = grid.q
    ramp = np.geomspace(q_low + 0.03 * (q_high - q_low), q_low + 0.95 * (q_high - q_low),
                        PROBE_SAMPLES)
    ramp = np.r_[ramp, ramp[::-1]]
    columns = {"p_B": [], "p_P": [], "temperature": []}
    for state in PROBE_STATES:
        for name, share in zip(columns, state):
            low, high = getattr(grid, name)
            columns[name].append(np.full(ramp.size, low + share * (high - low)))
    runs = np.repeat(np.arange(len(PROBE_STATES)), ramp.size)
    return (OperatingPoints.create(np.tile(ramp, len(PROBE_STATES)),
                                   np.concatenate(columns["p_P"]),
                                   np.concatenate(columns["p_B"]),
                                   np.concatenate(columns["temperature"])), runs)
