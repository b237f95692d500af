"""Shape-free effects: their bases, their physics by construction, and their penalised refits."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from surrogate.effects.shapes import (SHAPE_FREE, TAIL, Leakage, OpeningForce, quantile_knots,
                                      rising_basis, spline_basis)
from surrogate.fitting.heldout import Linearised, RunBlocks
from surrogate.testing import check_effect

KNOTS = np.array([0.0, 1.0, 2.5, 3.0, 6.0, 10.0])


@pytest.mark.parametrize("cls", SHAPE_FREE, ids=[cls.name for cls in SHAPE_FREE])
def test_every_shape_free_effect_keeps_the_effect_contract(cls):
    check_effect(cls)


def test_the_spline_basis_is_a_partition_of_unity_held_beyond_the_knots():
    x = np.linspace(-2.0, 12.0, 57)
    basis = spline_basis(KNOTS, x)
    assert basis.shape == (57, len(KNOTS) + 2)
    assert np.allclose(basis.sum(axis=1), 1.0) and np.all(basis >= -1e-12)
    assert np.allclose(basis[x < 0], spline_basis(KNOTS, [0.0]))
    assert np.allclose(basis[x > 10], spline_basis(KNOTS, [10.0]))


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(0.0, 5.0), min_size=len(KNOTS) + 1, max_size=len(KNOTS) + 1))
def test_non_negative_coefficients_make_a_rising_non_negative_shape_zero_at_the_first_knot(c):
    x = np.linspace(-1.0, 11.0, 200)
    shape = rising_basis(KNOTS, x) @ np.array(c)
    assert np.all(np.diff(shape) >= -1e-9) and np.all(shape >= -1e-12)
    assert np.allclose(rising_basis(KNOTS, [0.0]) @ np.array(c), 0.0)


@pytest.mark.parametrize("cls", SHAPE_FREE, ids=lambda cls: cls.name)
def test_a_shape_is_its_basis_times_its_coefficients_whenever_they_change(cls):
    # the shape is evaluated as one cached spline; a fit changes the parameters in place
    rng = np.random.default_rng(3)
    effect = cls.on_knots(quantile_knots(rng.uniform(0.0, 4.0, 100)))
    x = rng.uniform(-1.0, 5.0, 300)
    for _ in range(3):
        for name in effect.coefficient_names():
            effect.params[name].value = abs(rng.normal())
        assert np.allclose(effect.shape(x), effect.basis(x) @ effect.coefficients,
                           rtol=1e-12, atol=1e-12)


def test_knots_follow_the_data_but_never_collapse_onto_a_held_value():
    held = np.r_[np.full(1000, 5.0), np.linspace(0.0, 10.0, 50)]
    knots = quantile_knots(held)
    assert knots[0] == np.quantile(held, TAIL) and knots[-1] == np.quantile(held, 1 - TAIL)
    assert 0.0 < knots[0] < 1.5 and 8.5 < knots[-1] < 10.0 and np.all(np.diff(knots) > 0.1)
    assert quantile_knots(np.linspace(3.0, 9.0, 100), start=0.0)[0] == 0.0


def test_a_few_far_samples_do_not_stretch_a_shape_over_a_range_they_cannot_determine():
    """The 120-bar runs' jumps to the stop: 99 % of the moving openings below 0.29 mm, a handful
    at 0.63 mm. The shape ends (and is held) where the data still lie."""
    rng = np.random.default_rng(3)
    openings = np.r_[rng.uniform(0.015, 0.29, 2000), np.full(8, 0.63)]
    knots = quantile_knots(openings)
    assert knots[-1] < 0.30 and knots[0] < 0.02


def test_a_shape_reads_back_from_its_parameters_as_a_model_file_writes_them():
    effect = OpeningForce.on_knots(np.linspace(0.02e-3, 0.63e-3, 6))
    for index, name in enumerate(effect.coefficient_names()):
        effect.params[name].value = np.sin(index)
    again = OpeningForce.for_parameters(list(effect.params))
    for name, parameter in effect.params.items():
        again.params[name].value = parameter.value
    u = np.linspace(0.0, 0.7e-3, 30)
    assert np.array_equal(again.shape(u), effect.shape(u))


def test_a_leakage_vanishes_without_a_pressure_drop_and_scales_with_fluidity():
    from surrogate import load_valve
    from surrogate.effects import FlowState
    from surrogate.fluid import FluidState

    effect = Leakage.on_knots(quantile_knots(np.linspace(20e5, 170e5, 100), start=0.0))
    for name in effect.coefficient_names():
        effect.params[name].value = 1e-6
    state = FlowState(np.full(3, 1e-4), np.full(3, 1e-4), np.zeros(3), np.zeros(3),
                      np.full(3, 313.0), FluidState(np.array([46e-6, 46e-6, 92e-6]),
                                                    np.full(3, 870.0)), load_valve())
    leak = effect.leakage(np.array([0.0, 100e5, 100e5]), state)
    assert leak[0] == 0.0 and np.isclose(leak[1], 2.0 * leak[2])


def test_a_roughness_penalty_in_the_linear_refits_equals_the_penalised_solve():
    """Held out with a roughness penalty: the refit without a run equals an explicit penalised
    least-squares solve on the other runs."""
    rng = np.random.default_rng(3)
    n, p = 60, 4
    runs = np.repeat(["a", "b", "c"], n // 3)
    jacobian, residual = rng.normal(size=(n, p)), rng.normal(size=n)
    rough = np.diff(np.eye(p), 2, axis=0) * 3.0
    offset = rough @ rng.normal(size=p)
    blocks = RunBlocks(Linearised(residual, jacobian), None, runs, 0.0, (rough, offset))
    weights = np.array([1.0, 0.0, 1.0])
    keep = runs != "b"
    explicit = np.linalg.lstsq(np.vstack([jacobian[keep], rough]),
                               -np.r_[residual[keep], offset], rcond=None)[0]
    assert np.allclose(blocks.step(weights), explicit, rtol=1e-6)
    plain = RunBlocks(Linearised(residual, jacobian), None, runs, 0.0)
    assert blocks.effective_parameters(np.arange(p)) < plain.effective_parameters(np.arange(p))
    assert np.isclose(plain.effective_parameters(np.arange(p)), p)


@pytest.mark.parametrize("cls", SHAPE_FREE, ids=[cls.name for cls in SHAPE_FREE])
def test_a_shape_handed_over_as_an_effects_file_reproduces_it(cls, tmp_path):
    """The written file loads as a user's effects file, keeps the effect contract, and at
    scale = 1 gives the fitted shape's output (to the table's interpolation)."""
    from surrogate import load_valve
    from surrogate.effects import load_effects_file
    from surrogate.effects.handover import write_effect_file
    from surrogate.testing import _call, _effect_states

    x = {"u": np.linspace(0.02e-3, 0.63e-3, 50), "nu": np.linspace(20e-6, 120e-6, 50),
         "q": np.linspace(1 / 6e4, 12 / 6e4, 50)}.get(cls.variable.name,
                                                     np.linspace(1e5, 170e5, 50))
    effect = cls.on_knots(cls.knots_for(x))
    for index, name in enumerate(effect.coefficient_names()):
        effect.params[name].value = effect.params[name].max * 0.1 * (1 + index % 3)
    assert write_effect_file(effect, tmp_path / "rough.py").read_text().count(
        "ROUGHNESS = 0\n") == 1  # fitted without a roughness penalty: none comes along
    effect.params["smoothing"].set_display(0.3)
    path = write_effect_file(effect, tmp_path / "found.py", origin="a log")
    (found,) = load_effects_file(path).values()
    check_effect(found)
    handed = found()
    handed.params["scale"].set_display(1.0)
    states = _effect_states(0, 40, load_valve())
    assert np.allclose(_call(handed, states), _call(effect, states), rtol=2e-3,
                       atol=2e-3 * np.max(np.abs(_call(effect, states))))
    # the roughness the shape was fitted under comes along: at scale = s the file's penalty is
    # the shape's own penalty on s·c, so a refit of scale is as cautious as one of the shape
    coefficients = np.array([effect.params[name].value if name in effect.coefficient_names()
                             else 0.0 for name in effect.params])
    for scale in (1.0, 0.4):
        shape_penalty = np.linalg.norm(effect.penalty(500) @ (scale * coefficients))
        assert np.linalg.norm(handed.penalty(500) @ [scale]) == pytest.approx(shape_penalty,
                                                                              rel=1e-5)


@pytest.mark.parametrize("smoothing, rough", [(0.0, True), (2.0, False)])
def test_a_shape_keeps_the_smoothness_its_diagnosis_chose_in_every_later_fit(
        valve, grid_maps, smoothing, rough):
    """A shape's ``smoothing`` is a penalty every fit of its model minimises with the sum of
    squares (a workflow's next step, ``fit`` with a model file): without it the spline follows
    the noise, with it the fit stays smooth though the data are the same."""
    from surrogate.fitting.leastsquares import fit
    from surrogate.model import ValveModel

    rng = np.random.default_rng(1)
    u = np.sort(rng.uniform(0.02e-3, 0.3e-3, 400))
    effect = OpeningForce(quantile_knots(u), smoothing=smoothing)
    model = ValveModel(valve, *grid_maps, [effect])
    truth = 1e5 * (u / 0.3e-3)  # a straight line [Pa]: the penalty's null space
    noisy = truth + rng.normal(0.0, 3e5, u.size)

    def residuals(trial):
        return 1e5 * trial.effect(effect.name).shape(u) - noisy

    fitted = fit(model, residuals).model.effect(effect.name)
    bends = np.abs(np.diff(fitted.coefficients, 2)).max()
    assert (bends > 0.5) == rough, fitted.coefficients
    penalty = model.penalty([f"{effect.name}.{name}" for name in effect.coefficient_names()],
                            u.size)
    assert (penalty is None) == (smoothing == 0.0)
    if penalty is not None:  # ‖L·c‖² in Pa²: √n·smoothing per unit of second difference
        matrix, offset = penalty
        assert np.allclose(matrix / (np.sqrt(u.size) * smoothing * 1e5),
                           effect.roughness()) and not offset.any()
