"""The CFD's own error: what no map fitted to the samples can see, and every map's σ carries.

A CFD result is a simulator's output, not the valve (Kennedy and O'Hagan's discrepancy). With one
mesh per opening, each opening's samples share a bias of their own: the paper's mesh study
(Table 4) moved Δp by −1.84 to +1.86 % when the cells at 0.10 mm were refined from 1.7 to 3.1
million, and its choice between two cavitation models moved f_sim by 1.06 %, a few per cent of
the flow-force part of f_sim. A map fitted to the samples reproduces that bias exactly, and
cross-validation, which scores a map against samples it did not see, cannot see it: a GP then
called its flow certain to 0.05 % where it was 0.3 % off a virtual valve
(``eval/valve_coverage.py``).

So every map built from CFD samples reports σ² = σ_interpolation² + σ_CFD²: the first from its
calibration (:mod:`.calibration`, fitted on cross-validation), the second from here, as
:attr:`~.base.FlowMap.cfd_error` and :attr:`~.base.ForceMap.cfd_error` in the calibrations' ln
units. σ at a sampled opening is then never smaller than the CFD's own error there. The
workbench's allowance for the maps' error (:mod:`surrogate.fitting.discrepancy`) reads the same σ.
"""

from __future__ import annotations

import numpy as np

#: Δp's change with mesh refinement at u = 0.10 mm, q = 1, 3, 6, 9, 12 L/min [%] (Table 4)
MESH_STUDY_DP_CHANGE = (1.53, 1.86, -0.88, -1.64, -1.84)

#: one σ of the relative error each opening's mesh puts on Δp at a given flow and on the flow
#: force [1]: about the mesh study's RMS (1.6 %) for Δp; for the flow force, the cavitation
#: model's 1.06 % of f_sim is 1.4 to 4.5 % of the flow force at 0.10 mm, 40 °C
CFD_ERROR = {"dp": 0.015, "flow force": 0.025}

#: the same in the calibrations' units: ln C_d (= −ln Δp / 2 at a given flow) and the relative
#: flow force
FLOW_CFD_ERROR = CFD_ERROR["dp"] / 2.0
FORCE_CFD_ERROR = CFD_ERROR["flow force"]

#: one σ of ln C_d at the middle of an unsampled gap between openings (no CFD run there) [1]:
#: how far the valve may stray from a smooth bridge where no mesh says anything. Map kinds bridge
#: the shipped 0.20–0.63 mm gap by different rules (the grid's power law, the GP's kernel, the
#: networks' features) and their flows there differ by 2.4 to 7 % from one another (``python
#: eval/valve_coverage.py --truth nn``, ``--truth gp``, each kind's maps wrong by the same
#: draws): none of them is the valve's, and ±2σ at the gap's middle holds that spread
GAP_FLOW_ERROR = 0.03


def gap_error(gaps: list[tuple[float, float]], u, size: float = GAP_FLOW_ERROR) -> np.ndarray:
    """σ [ln units] that an unsampled gap adds at openings ``u`` [m]: ``size``·sin(π·t), t the
    position across the gap in ln u (0 at the openings that bound it), 0 outside every gap."""
    u = np.asarray(u, float)
    error = np.zeros(u.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_u = np.log(u)
        for low, high in gaps:
            share = (log_u - np.log(low)) / (np.log(high) - np.log(low))
            inside = (share > 0.0) & (share < 1.0)
            error = np.where(inside, size * np.sin(np.pi * np.clip(share, 0.0, 1.0)), error)
    return error


__all__ = ["CFD_ERROR", "FLOW_CFD_ERROR", "FORCE_CFD_ERROR", "GAP_FLOW_ERROR",
           "MESH_STUDY_DP_CHANGE", "gap_error"]
