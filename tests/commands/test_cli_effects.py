"""``effects``: every effect a model may name is listed with its parameters, units and bounds, as
text and as JSON; with --effects-file, that file's effects, checked as fit would check them."""

from __future__ import annotations

import json

import pytest

from surrogate.cli import main
from surrogate.effects import KNOWN, LIBRARY
from surrogate.core.paths import PROJECT_ROOT

pytestmark = pytest.mark.pipeline  # every test here runs a command end to end

EXAMPLE = PROJECT_ROOT / "examples" / "seat_force.py"


@pytest.fixture(scope="module")
def listing():
    """The JSON listing of the built-in effects."""
    with pytest.MonkeyPatch.context():
        import contextlib
        import io

        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            assert main(["effects", "--json"]) == 0
    return json.loads(out.getvalue())


def test_every_known_effect_is_listed_once_in_its_group(listing):
    groups = {group["group"]: [e["name"] for e in group["effects"]] for group in listing["groups"]}
    assert list(groups) == ["library", "shape-free", "calibration"]
    assert groups["library"] == list(LIBRARY)
    assert sorted(sum(groups.values(), [])) == sorted(KNOWN)


def test_each_effect_says_what_it_is(listing):
    for group in listing["groups"]:
        for effect in group["effects"]:
            cls = KNOWN[effect["name"]]
            assert (effect["title"], effect["category"], effect["kind"]) == \
                (cls.title, cls.category, cls.kind)
            assert effect["description"] == cls.describe() and effect["description"]
            assert effect["parameters"] or effect.get("parameters_note") or \
                effect["name"] == "pilot_zero_drift"


def test_parameters_come_with_display_units_and_bounds(listing):
    effects = {e["name"]: e for group in listing["groups"] for e in group["effects"]}
    (k2,) = effects["friction_load_pressure"]["parameters"]
    assert (k2["name"], k2["unit"], k2["min"], k2["max"], k2["off"]) == ("K2", "N/bar", 0.0, 1.0,
                                                                         0.0)
    nu_ref = effects["friction_viscous"]["parameters"][1]
    assert (nu_ref["unit"], nu_ref["off"]) == ("cSt", 46.0)  # display units, not SI
    (delta,) = effects["pilot_zero_drift"]["parameters"]
    assert delta["per_run"] and delta["name"] == "delta_<run>" and delta["unit"] == "bar"
    assert "knots" in effects["shape_leakage"]["parameters_note"]


def test_the_text_listing_names_every_effect_with_its_units(capsys):
    assert main(["effects"]) == 0
    out = capsys.readouterr().out
    for name in KNOWN:
        assert f"  {name}: {KNOWN[name].title}" in out
    assert "K2 [N/bar]: 0 to 1, off at 0" in out
    assert "library (16)" in out


def test_an_effects_file_lists_its_own_effects(capsys):
    assert main(["effects", "--effects-file", str(EXAMPLE), "--json"]) == 0
    (group,) = json.loads(capsys.readouterr().out)["groups"]
    assert group["group"] == "custom"
    (effect,) = group["effects"]
    assert effect["name"] == "seat_land_force" and effect["source"] == str(EXAMPLE)
    assert [(p["name"], p["unit"]) for p in effect["parameters"]] == [("a", "N/bar"),
                                                                       ("u0", "mm")]


def test_an_effects_file_clashing_with_the_library_is_refused(tmp_path, capsys):
    clash = tmp_path / "clash.py"
    clash.write_text(EXAMPLE.read_text().replace('"seat_land_force"', '"friction_constant"')
                     .replace("def seat_land_force", "def friction_constant"))
    assert main(["effects", "--effects-file", str(clash)]) == 2
    err = capsys.readouterr().err
    assert "clash.py" in err and "friction_constant" in err and "Traceback" not in err
