"""Unit checks of individual library effects against their stated physics."""

from __future__ import annotations

import numpy as np
import pytest

from surrogate import load_valve
from surrogate.effects import BalanceState, NearSeatFlowForce
from surrogate.fluid import FluidState


def balance_state(u, flow_force):
    u = np.asarray(u, float)
    ones = np.ones_like(u)
    return BalanceState(u, 1e-4 * ones, 100e5 * ones, 5e5 * ones, 60e5 * ones, 313.15 * ones,
                        FluidState(46e-6 * ones, 860.0 * ones), flow_force * ones,
                        load_valve())


def test_near_seat_flow_force_acts_only_below_the_reference_opening():
    effect = NearSeatFlowForce(k=1.0, u_ref=0.05e-3)
    u = np.array([0.0125e-3, 0.025e-3, 0.05e-3, 0.2e-3])
    extra = effect.force(balance_state(u, -40.0))
    # k = 1: the flow force scales with u/u_ref below u_ref, so the extra force cancels
    # (1 − u/u_ref) of the (closing, negative) flow force and opens the valve
    assert extra == pytest.approx([30.0, 20.0, 0.0, 0.0])


def test_near_seat_flow_force_is_the_maps_rule_at_k_zero():
    effect = NearSeatFlowForce(k=0.0)
    assert np.all(effect.force(balance_state([1e-6, 1e-5, 1e-4], -40.0)) == 0.0)
