"""``python -m surrogate predict``: the contract for outside checks."""

import pandas as pd
import pytest

from surrogate.cli import main

pytestmark = pytest.mark.pipeline  # every test here runs a command end to end

ANOTHER_OIL = "case,u_mm,p_L_bar,p_B_bar,nu_cSt,rho_kg_m3\nA,0.1,50,5,32,870\nB,0.63,20,2,150,900\n"


@pytest.mark.parametrize("model", ["grid", "nn", "gp"])
def test_predict_with_another_oils_viscosity_and_density(tmp_path, model, capsys):
    source, target = tmp_path / "in.csv", tmp_path / "out.csv"
    source.write_text(ANOTHER_OIL)
    assert main(["predict", "--maps", model, "--input", str(source),
                 "--output", str(target)]) == 0
    out = pd.read_csv(target)
    assert list(out.columns[:6]) == ["case", "u_mm", "p_L_bar", "p_B_bar", "nu_cSt", "rho_kg_m3"]
    assert list(out["case"]) == ["A", "B"]
    assert (out["q_lpm_pred"] > 0).all() and (out["f_sim_N_pred"] > 0).all()
    assert out["extrapolating"].dtype == bool
    # every kind built from data gives a calibrated standard deviation, a fraction of the value
    assert (out["q_lpm_std"] > 0).all() and (out["q_lpm_std"] < 0.2 * out["q_lpm_pred"]).all()
    assert (out["f_sim_N_std"] > 0).all() and (out["f_sim_N_std"] < 0.5 * out["f_sim_N_pred"]).all()
    assert 3.5 < out["q_lpm_pred"][0] < 5.5  # u 0.1 mm, 45 bar: between the 40 and 60 °C sweeps
    # and says why a state lies outside the samples: B's 150 cSt is thicker than any CFD run's
    assert not out["extrapolating"][0] and pd.isna(out["outside_samples"][0])
    assert out["extrapolating"][1] and "viscosity outside" in out["outside_samples"][1]


def test_maps_without_data_leave_the_standard_deviation_empty(tmp_path):
    source, target = tmp_path / "in.csv", tmp_path / "out.csv"
    source.write_text(ANOTHER_OIL)
    assert main(["predict", "--maps", "orifice", "--input", str(source),
                 "--output", str(target)]) == 0
    out = pd.read_csv(target)
    assert out["q_lpm_std"].isna().all() and out["f_sim_N_std"].isna().all()
    assert not out["extrapolating"].any()


def test_predict_at_temperatures_of_the_valves_oil(tmp_path):
    source, target = tmp_path / "in.csv", tmp_path / "out.csv"
    source.write_text("u_mm,p_L_bar,p_B_bar,temperature_C\n0.1,88.5221,5,40\n")
    assert main(["predict", "--maps", "nn", "--input", str(source),
                 "--output", str(target)]) == 0
    assert pd.read_csv(target)["q_lpm_pred"][0] == pytest.approx(6.0, rel=0.02)  # CFD C0062


@pytest.mark.parametrize("content, words", [
    ("u_mm,p_L_bar,p_B_bar\n0.1,50,5\n", "either temperature_C"),
    ("u_mm,p_L_bar,p_B_bar,temperature_C,nu_cSt,rho_kg_m3\n0.1,50,5,40,46,858\n", "not both"),
    ("u_mm,p_L_bar,p_B_bar,nu_cSt,rho_kg_m3\n0.1,50,5,-4,858\n", "line 2, column 'nu_cSt'"),
])
def test_bad_query_file_exits_2_and_writes_nothing(tmp_path, content, words, capsys):
    source, target = tmp_path / "in.csv", tmp_path / "out.csv"
    source.write_text(content)
    assert main(["predict", "--maps", "grid", "--input", str(source),
                 "--output", str(target)]) == 2
    assert words in capsys.readouterr().err
    assert not target.exists()


def test_unknown_model_is_named(tmp_path, capsys):
    source = tmp_path / "in.csv"
    source.write_text(ANOTHER_OIL)
    assert main(["predict", "--maps", "spline", "--input", str(source),
                 "--output", str(tmp_path / "o.csv")]) == 2
    assert "unknown map kind 'spline'" in capsys.readouterr().err
