"""Models as data: ModelSpec round trips, model files old and new, the valve a model records,
parameters, effect libraries and map kinds."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from surrogate.cli import main
from surrogate.effects import LIBRARY, EffectLibrary, load_effects_file
from surrogate.core.errors import InputError
from surrogate.maps.registry import MAP_KINDS, MapsSpec
from surrogate.description.modelfile import load_model, save_model
from surrogate.core.paths import PROJECT_ROOT
from surrogate.description.presets import PRESETS, basic_maps, maps, preset
from surrogate.description.spec import EffectSpec, ModelSpec, ValveSource
from surrogate.valve import load_valve

VALVE_TEXT = (PROJECT_ROOT / "surrogate" / "valves" / "paper_cbv.toml").read_text()


@pytest.mark.parametrize("name", PRESETS)
def test_every_preset_round_trips_through_toml_exactly(name):
    spec = preset(name)
    assert ModelSpec.from_toml(spec.to_toml()) == spec
    assert spec.build().name == name


def _value_in(parameter, fraction: float) -> float:
    low, high = parameter.display_bounds
    if np.isfinite(low) and np.isfinite(high):
        return low + fraction * (high - low)
    return parameter.display_value + fraction


@settings(max_examples=40, deadline=None)
@given(names=st.lists(st.sampled_from(sorted(LIBRARY)), min_size=0, max_size=5, unique=True),
       fraction=st.floats(0.0, 1.0), vary=st.booleans(),
       kind=st.sampled_from(["orifice", "grid", "nn", "gp", "mixed"]))
def test_any_spec_round_trips_through_toml_exactly(names, fraction, vary, kind):
    effects = []
    for name in names:
        effect = LIBRARY[name].for_runs(["R01", "R02"])
        for parameter in effect.params.values():
            parameter.set_display(_value_in(parameter, fraction))
            parameter.vary = vary
        effects.append(EffectSpec.of(effect))
    chosen = (MapsSpec(basic_maps().flow, maps("grid").force) if kind == "mixed"
              else basic_maps() if kind == "orifice" else maps(kind))
    spec = ModelSpec("random", ValveSource.shipped(), chosen, tuple(effects), "a test model")
    again = ModelSpec.from_toml(spec.to_toml())
    assert again == spec
    assert again.to_toml() == spec.to_toml()
    rebuilt = again.build()
    assert [e.name for e in rebuilt.effects] == names


def test_a_saved_model_rebuilds_with_its_fitted_values_and_maps(tmp_path):
    model = load_model("cfda")
    model.effect("friction_constant").params["K1"].set_display(7.25)
    path = tmp_path / "nested" / "m.toml"
    save_model(model, path)
    loaded = load_model(str(path))
    assert ModelSpec.of(loaded) == ModelSpec.of(model)
    assert loaded.effect("friction_constant").params["K1"].display_value == 7.25
    document = tomllib.loads(path.read_text())
    assert document["maps"]["cfd"] == "shipped" and len(document["maps"]["cfd_sha256"]) == 64


def test_a_model_file_of_the_first_format_still_loads(tmp_path):
    path = tmp_path / "old.toml"
    path.write_text('[model]\nname = "cfda"\nvalve = "shipped"\nmaps = { kind = "grid" }\n\n'
                    '[[effects]]\nname = "friction_constant"\n[effects.parameters]\n'
                    'K1 = { value = 7.5, unit = "N", min = 0.0, max = 200.0, vary = true }\n')
    model = load_model(str(path))
    assert model.effect("friction_constant").params["K1"].display_value == 7.5
    assert ModelSpec.of(model).maps.flow.kind == "grid"
    # and a surrogate folder as the map kind, as format 1 wrote learned maps
    folder = PROJECT_ROOT / "surrogate" / "trained" / "gp"
    path.write_text(f'[model]\nname = "x"\nmaps = {{ kind = "{folder}" }}\n')
    assert ModelSpec.of(load_model(str(path))).maps.flow.kind == "gp"


def test_paths_in_a_model_file_are_relative_to_the_file(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    (data / "cfd.csv").write_text((PROJECT_ROOT / "cfd_samples" / "cfd_samples.csv").read_text())
    spec = preset("cfda").with_maps(maps("grid", data / "cfd.csv"))
    path = tmp_path / "models" / "m.toml"
    path.parent.mkdir()
    spec.write(path)
    assert tomllib.loads(path.read_text())["maps"]["cfd"] == "../data/cfd.csv"
    assert ModelSpec.read(path) == spec


@pytest.mark.pipeline
def test_fit_records_and_uses_the_valve_it_was_given(two_run_log, tmp_path, capsys):
    valve_file = tmp_path / "my_valve.toml"
    valve_file.write_text(VALVE_TEXT.replace("F_cr_N = 226.0", "F_cr_N = 240.0"))
    out = tmp_path / "fitted.toml"
    assert main(["fit", "--model", "cfda", "--data", str(two_run_log), "--valve", str(valve_file),
                 "--out", str(out), "--quiet"]) == 0
    document = tomllib.loads(out.read_text())
    assert document["valve"]["F_cr_N"] == 240.0
    assert document["valve"]["source"] == "my_valve.toml"
    valve_file.unlink()  # the model file carries the values itself
    assert load_model(str(out)).valve.F_cr == 240.0


@pytest.mark.pipeline
def test_workflow_records_and_uses_the_valve_it_was_given(two_run_log, tmp_path, capsys):
    valve_file = tmp_path / "my_valve.toml"
    valve_file.write_text(VALVE_TEXT.replace("F_cr_N = 226.0", "F_cr_N = 240.0"))
    out = tmp_path / "workflow"
    assert main(["workflow", "--data", str(two_run_log), "--valve", str(valve_file),
                 "--out", str(out), "--max-additions", "0", "--quiet"]) == 0
    final = load_model(str(out / "final_model.toml"))
    assert final.valve.F_cr == 240.0 and final.valve == load_valve(valve_file)


def test_parameters_are_keyed_and_serialised_in_display_units():
    model = load_model("cfda")
    parameters = model.parameters()
    assert list(parameters) == ["flow_force_scale.scale", "friction_constant.K1",
                                "friction_load_pressure.K2"]
    assert parameters.valuesdict()["friction_load_pressure.K2"] == pytest.approx(0.05 / 1e5)
    record = parameters.to_records()["friction_load_pressure.K2"]
    assert record == {"value": 0.05, "unit": "N/bar", "min": 0.0, "max": 1.0, "vary": True}
    parameters["friction_constant.K1"].set_display(9.0)
    assert model.effect("friction_constant")["K1"] == 9.0  # the model's own objects
    assert parameters.free() == list(parameters)


def test_libraries_combine_and_loading_a_file_changes_nothing_global(tmp_path):
    before = dict(LIBRARY)
    custom = load_effects_file(PROJECT_ROOT / "examples" / "seat_force.py")
    combined = LIBRARY + custom
    assert set(combined) == set(LIBRARY) | {"seat_land_force"}
    assert dict(LIBRARY) == before
    with pytest.raises(InputError, match="exists already"):
        _ = combined + EffectLibrary([type("Copy", (custom["seat_land_force"],), {})])
    # a model naming the custom effect builds with the combined library only
    spec = preset("cfda").adding(EffectSpec.start(custom["seat_land_force"], a=0.1))
    assert spec.build(combined).has_effect("seat_land_force")
    with pytest.raises(InputError, match="unknown effect 'seat_land_force'"):
        spec.build()


def test_no_map_kind_is_chosen_by_name_outside_the_registry():
    """A new kind is one registration: no module but the registry tests for a kind's name."""
    kinds = "|".join(MAP_KINDS)
    branch = re.compile(rf"""(==|!=|\bin)\s*\(?\s*["']({kinds})["']""")
    offenders = []
    for path in (PROJECT_ROOT / "surrogate").rglob("*.py"):
        if path.name == "registry.py":
            continue
        for number, line in enumerate(path.read_text().splitlines(), start=1):
            if branch.search(line):
                offenders.append(f"{path.relative_to(PROJECT_ROOT)}:{number}: {line.strip()}")
    assert not offenders, offenders


def test_a_spec_lists_every_file_it_reads_by_the_path_flag_not_by_name(tmp_path):
    """What a model reads, for the guard over outputs: the valve file, and every ``path``
    option of its maps' kind, whatever the kind and the option are called."""
    from surrogate.maps.registry import MapKind, MapSource, Option, register

    table = tmp_path / "table.csv"
    table.write_text("x\n")
    register(MapKind("lookup", "a kind a plug-in adds", lambda options, valve, base: None,
                     (Option("table", "its file", path=True), Option("label", "a name"))))
    try:
        spec = preset("cfda").with_maps(MapsSpec.both("lookup", table=str(table), label="t"))
        valve = ValveSource.read(PROJECT_ROOT / "surrogate" / "valves" / "paper_cbv.toml")
        paths = [path for path, _ in spec.with_valve(valve).inputs()]
        assert table in paths and Path(valve.reference) in paths and len(paths) == 2
        assert [p for p, _ in MapSource.of("nn").inputs()][0].name == "nn"
    finally:
        del MAP_KINDS["lookup"]
