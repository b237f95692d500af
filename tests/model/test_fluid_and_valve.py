"""The oil model reproduces the CFD samples' fluid columns; valve files load and fail clearly."""

import numpy as np
import pytest

from surrogate import load_valve
from surrogate.data import load_cfd_samples
from surrogate.core.errors import InputError
from surrogate.core.paths import SHIPPED_CFD_SAMPLES


def test_oil_reproduces_cfd_viscosity_and_density_within_half_a_percent():
    samples = load_cfd_samples(SHIPPED_CFD_SAMPLES).frame
    oil = load_valve().oil
    state = oil.state(samples["temperature"].to_numpy())
    np.testing.assert_allclose(state.nu, samples["nu"], rtol=0.005)
    np.testing.assert_allclose(state.rho, samples["rho"], rtol=0.005)


def test_oil_hits_its_datasheet_points_and_thins_with_temperature():
    oil = load_valve().oil
    assert oil.viscosity(313.15) == pytest.approx(46e-6, rel=1e-12)
    assert oil.viscosity(373.15) == pytest.approx(8e-6, rel=1e-12)
    assert oil.density(288.15) == pytest.approx(872.0)
    temperatures = np.linspace(233.15, 473.15, 50)
    assert np.all(np.diff(oil.viscosity(temperatures)) < 0)
    assert np.all(np.diff(oil.density(temperatures)) < 0)


def test_the_oils_temperature_at_a_viscosity_inverts_its_viscosity():
    oil = load_valve().oil
    temperature = np.linspace(250.0, 400.0, 31)
    np.testing.assert_allclose(oil.temperature(oil.viscosity(temperature)), temperature,
                               rtol=1e-12)
    assert oil.temperature(oil.nu40) == pytest.approx(313.15)


def test_shipped_valve_has_the_papers_parameters():
    valve = load_valve()
    assert valve.A_L == pytest.approx(10.7e-6)
    assert valve.A_P == pytest.approx(2.72 * 10.7e-6)
    assert valve.A_B == pytest.approx(3.72 * 10.7e-6)
    assert valve.A_s3 == pytest.approx(46e-6)
    assert (valve.F_cr, valve.K_f) == pytest.approx((226.0, 1.14e5))
    assert (valve.U_max, valve.w) == pytest.approx((0.63e-3, 12e-3))
    assert valve.P_cr == pytest.approx(226.0 / 10.7e-6)


def _write_valve(tmp_path, text: str):
    path = tmp_path / "valve.toml"
    path.write_text(text)
    return path


def _shipped_text(**replace) -> str:
    from importlib import resources

    text = resources.files("surrogate.valves").joinpath("paper_cbv.toml").read_text()
    for old, new in replace.items():
        text = text.replace(old, new)
    return text


def test_user_valve_file_round_trips(tmp_path):
    valve = load_valve(_write_valve(tmp_path, _shipped_text(**{"F_cr_N = 226.0": "F_cr_N = 300"})))
    assert valve.F_cr == 300.0
    assert type(valve).from_dict(valve.to_dict()) == valve


@pytest.mark.parametrize("edit, words", [
    ({"w_mm = 12.0": "w_mm = -1"}, "w_mm = -1 is not a plausible value (expected 0.1 to 1000 mm)"),
    ({"A_s3_mm2 = 46.0": "A_s3_mm2 = 30.0"}, "must exceed"),
    ({"U_max_mm = 0.63": "U_max_mm = \"0.63\""}, "U_max_mm must be a number in mm"),
    ({"K_f_N_per_m": "K_f"}, "missing K_f_N_per_m; unknown K_f"),
    ({"nu100_cSt = 8.0": "nu100_cSt = 80.0"}, "nu40 > nu100"),
    ({"[oil]": "[oil"}, "not valid TOML"),
])
def test_bad_valve_file_names_file_and_key(tmp_path, edit, words):
    path = _write_valve(tmp_path, _shipped_text(**edit))
    with pytest.raises(InputError) as caught:
        load_valve(path)
    message = str(caught.value)
    assert words in message, message
    assert message.startswith(str(path)), message


def test_subsets_of_points_and_fluid_states_are_as_made_afresh(valve):
    """The unchecked fast path of indexing gives what the checked constructor gives."""
    from surrogate.points import OperatingPoints

    n = 12
    points = OperatingPoints(np.linspace(1e-5, 2e-4, n), np.full(n, 3e6), np.full(n, 5e5),
                             np.linspace(300, 330, n), np.where(np.arange(n) % 2, 1, -1),
                             np.array([f"R{i // 4}" for i in range(n)]))
    fluid = valve.oil.state(points.temperature)
    fields = ("q", "p_P", "p_B", "temperature", "direction", "run")
    for index in (np.array([3, 0, 7]), np.arange(n) % 3 == 0, slice(2, 9), slice(None, None, 2),
                  5, np.array([], int)):
        fast, made = points[index], OperatingPoints(*(getattr(points, f)[index] for f in fields))
        for name in fields:
            np.testing.assert_array_equal(getattr(fast, name), getattr(made, name))
            assert getattr(fast, name).dtype == getattr(made, name).dtype
            assert getattr(fast, name).ndim == 1
        sub = fluid[index]
        np.testing.assert_array_equal(sub.nu, fluid.nu[index])
        np.testing.assert_array_equal(sub.rho, fluid.rho[index])
