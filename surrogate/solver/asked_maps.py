"""The maps asked about a log's samples replay after replay, the flow map's reading at each
sample's measured flow kept.

A replay that asks the maps (one that reports, a fit's first, or one whose model corrects an
input the maps' tables cannot follow, such as a pilot transducer's offset) asks the flow map
about each sample at its measured flow, at a dozen openings, and the next such replay of the same
log asks it again at the same flows. A map that can read what depends on the flow alone once
(:meth:`surrogate.maps.base.FlowMap.at_flows`: a grid reads its sweeps at the flow, and blends
them at each opening) has that reading kept here for the samples' flows, per map, and every
balance at those flows blends it: the same values, to the bit, as the map asked afresh. A flow
the model changes (a flowmeter's gain, a discharge correction) asks the map as ever, and so does
a model with a leak, whose flow split asks the restriction at new flows at every step
(:meth:`~surrogate.maps.base.FlowMap.at_openings` prepares for that).
"""

from __future__ import annotations

import hashlib
import threading
import weakref

import numpy as np

from ..maps.base import FlowMap
from ..model import Balance, ValveModel
from ..points import OperatingPoints

#: points a map's readings are kept for at most, over all sets of points (a reading takes a
#: hundred bytes per point): the oldest sets are let go first
KEPT_POINTS = 100_000

_KEPT: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
_KEPT_LOCK = threading.Lock()


def asked_balance(model: ValveModel, points: OperatingPoints, fluid, keep: bool = False):
    """``balance(u, index)``: ``model``'s balance of the (measured) points ``index``
    (positions) at openings ``u`` [m], its maps asked; with ``keep`` (a solver, which asks
    about the points a dozen times), its flow map's reading at the points' measured flows kept
    (:func:`kept_flows`) where the map prepares one and the model has no leak."""
    flows = (None if not keep or model.has_leakage
             else kept_flows(model.flow_map, points, fluid))
    if flows is None:
        return lambda u, index: model.balance(u, points[index], fluid[index])
    return AskedBalance(model, points, fluid, flows)


def kept_flows(flow_map: FlowMap, points: OperatingPoints, fluid):
    """``flow_map.at_flows`` at the points' measured flows, made once per map and set of
    points (the flows and fluid states; :data:`KEPT_POINTS` kept), or None for a map that
    prepares nothing at a flow, or too many points."""
    if type(flow_map).at_flows is FlowMap.at_flows or not 0 < len(points) <= KEPT_POINTS:
        return None
    digest = hashlib.blake2b(digest_size=16)
    for column in (points.q, np.ravel(fluid.nu)):
        digest.update(np.ascontiguousarray(column, float).tobytes())
    key = digest.digest()
    with _KEPT_LOCK:
        kept = _KEPT.setdefault(flow_map, {})
        found = kept.pop(key, None)
        if found is not None:
            kept[key] = found  # the most recent last
            return found[1]
    flows = flow_map.at_flows(points.q, points.p_B, fluid)
    with _KEPT_LOCK:
        kept = _KEPT.setdefault(flow_map, {})
        kept[key] = (len(points), flows)
        while sum(count for count, _ in kept.values()) > KEPT_POINTS:
            kept.pop(next(iter(kept)))
    return flows


class AskedBalance:
    """A model's balance at given (measured) points, its flow map read from ``flows`` (the
    map's reading at the points' measured flows, :meth:`~surrogate.maps.base.FlowMap.at_flows`)
    where the model asks it at those flows."""

    def __init__(self, model: ValveModel, points: OperatingPoints, fluid, flows):
        self.model, self.points, self.fluid, self.flows = model, points, fluid, flows

    def __call__(self, u, index: np.ndarray) -> Balance:
        """The balance of the points ``index`` at openings ``u`` [m]."""
        u = np.broadcast_to(np.asarray(u, float), np.shape(index))
        points, fluid = self.points[index], self.fluid[index]
        return self.model.balance(u, points, fluid, _AskedMaps(self, u, index, points, fluid))


class _AskedMaps:
    """The maps at one balance call's points and openings, as a
    :class:`~surrogate.model.ValveModel` asks them (its ``maps`` argument): the flow map from
    its kept reading at the measured flows, the force map as ever."""

    def __init__(self, balance: AskedBalance, u: np.ndarray, index: np.ndarray,
                 points: OperatingPoints, fluid):
        self.model, self.flows, self.measured = balance.model, balance.flows, balance.points.q
        self.u, self.index, self.fluid = u, index, fluid
        # the points as the model corrects them (the same object when nothing does): the
        # maps see the true back pressure
        self.true = self.model.true_points(points)

    def pressure_drop(self, q: np.ndarray, index=slice(None)) -> np.ndarray:
        """Δp [Pa] that passes the flow ``q`` [m^3/s] through the restriction at the points
        ``index`` (all by default)."""
        where = self.index[index]
        if np.array_equal(q, self.measured.take(where)):  # the measured flows: kept
            return self.flows(self.u[index], where)
        return self.model.flow_map.pressure_drop(q, self.true.p_B[index], self.u[index],
                                                 self.fluid[index])

    def flow_force(self, dp: np.ndarray) -> np.ndarray:
        """f_ff [N] at the pressure drops ``dp`` [Pa] of all the points, asked of the force
        map."""
        return self.model.flow_force(self.u, dp, self.true, self.fluid)
