"""Fuzz suite: malformed files and misused commands.

Every case runs the command line on a folder of inputs, one of them broken (or the command
misused), and must

* exit with code 2 and a message that names what is wrong (the words listed with the case);
* print no traceback;
* write nothing: the folder holds exactly the files it held before, byte for byte, so no output
  appeared and no input changed.

The hand-made table covers CFD samples, bench logs, valve files, model files, effects files and
command-line misuse; hypothesis adds generated corruptions of each kind of file.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import os
import subprocess
import sys
import tempfile
import zipfile
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from surrogate.cli import main
from surrogate.effects import LIBRARY
from surrogate.maps.learned import trained_folder
from surrogate.core.paths import PROJECT_ROOT, SHIPPED_BENCH_LOG, SHIPPED_CFD_SAMPLES
from surrogate.description.presets import preset

# --- the good inputs every case starts from ------------------------------------------------------

CFD = SHIPPED_CFD_SAMPLES.read_text()
VALVE = resources.files("surrogate.valves").joinpath("paper_cbv.toml").read_text()
MODEL = preset("cfda").to_toml()
#: a model file in the first format, which still loads: [model] holds the valve and the maps
MODEL_V1 = """[model]
name = "cfda"
valve = "shipped"
maps = { kind = "grid" }

[[effects]]
name = "flow_force_scale"
[effects.parameters]
scale = { value = 0.9, unit = "1", min = 0.0, max = 3.0, vary = true }

[[effects]]
name = "friction_constant"
[effects.parameters]
K1 = { value = 6.5, unit = "N", min = 0.0, max = 200.0, vary = true }
"""
EFFECTS = (PROJECT_ROOT / "examples" / "seat_force.py").read_text()


def _small_log() -> str:
    """Two runs of the shipped log, every 10th sample: valid, and quick to replay."""
    lines = SHIPPED_BENCH_LOG.read_text().splitlines()
    kept = [line for index, line in enumerate(lines[1:])
            if line.split(",")[0] in ("R01", "R06") and index % 10 == 0]
    return "\n".join([lines[0], *kept]) + "\n"


LOG = _small_log()
QUERIES = "u_mm,p_L_bar,p_B_bar,temperature_C\n0.1,50,5,40\n0.2,80,5,40\n"
GOOD_FILES = {"cfd.csv": CFD, "log.csv": LOG, "valve.toml": VALVE, "model.toml": MODEL,
              "effects.py": EFFECTS, "queries.csv": QUERIES}


# --- editing the good files ----------------------------------------------------------------------

def set_cell(text: str, line: int, column: str, value: str) -> str:
    """``text`` with one cell replaced; ``line`` counts from 1 (the header), as editors do."""
    rows = text.splitlines()
    header = rows[0].split(",")
    cells = rows[line - 1].split(",")
    cells[header.index(column)] = value
    rows[line - 1] = ",".join(cells)
    return "\n".join(rows) + "\n"


def map_column(text: str, column: str, function) -> str:
    """``text`` with ``function`` applied to every value of a numeric column."""
    rows = text.splitlines()
    index = rows[0].split(",").index(column)
    out = [rows[0]]
    for row in rows[1:]:
        cells = row.split(",")
        cells[index] = repr(function(float(cells[index])))
        out.append(",".join(cells))
    return "\n".join(out) + "\n"


def drop_column(text: str, column: str) -> str:
    rows = [row.split(",") for row in text.splitlines()]
    index = rows[0].index(column)
    return "\n".join(",".join(c for i, c in enumerate(row) if i != index) for row in rows) + "\n"


def in_unit(text: str, column: str, name: str, function) -> str:
    """``text`` with a numeric column renamed ``name`` and its values mapped by ``function``:
    the column as a bench logging in another unit writes it."""
    return replace(map_column(text, column, function), column, name)


def copy_column(text: str, column: str, name: str, function) -> str:
    """``text`` with a column ``name`` added: ``function`` of the values of ``column``."""
    rows = text.splitlines()
    index = rows[0].split(",").index(column)
    return "\n".join([rows[0] + "," + name] + [
        row + "," + repr(function(float(row.split(",")[index]))) for row in rows[1:]]) + "\n"


def semicolons(text: str) -> str:
    """``text`` as a spreadsheet exports it where the comma is the decimal separator."""
    def cell(value: str) -> str:
        try:
            float(value)
        except ValueError:
            return value
        return value.replace(".", ",")
    return "\n".join(";".join(cell(c) for c in row.split(",")) for row in text.splitlines()) + "\n"


PSI = 14.503773773  # psi per bar


def replace(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def effect_file(kind: str, body: str, signature: str = "state, k=1.0", decorator: str = "") -> str:
    """An effects file with one custom effect ``fuzzed_<kind>`` returning ``body``."""
    decorator = decorator or f'@custom_effect("{kind}", units={{"k": "1"}})'
    return ("import numpy as np\nfrom surrogate.effects import custom_effect\n\n\n"
            f"{decorator}\ndef fuzzed_{kind}({signature}):\n    \"\"\"A fuzzed effect.\"\"\"\n"
            f"    return {body}\n")


#: a custom force that reads its whole batch: fine for a fit, not a function of one state
BATCH_EFFECT = effect_file("force", "k * state.p_L / np.mean(state.p_L)",
                           signature="state, k=0.0").replace("fuzzed_force", "batch_force")
BATCH_EFFECT_ENTRY = """
[[effects]]
name = "batch_force"
[effects.parameters]
k = { value = 2.0, unit = "1", min = 0.0, max = 10.0, vary = false }
"""
SENSOR_ENTRY = """[[effects]]
name = "pilot_transducer_offset"
[effects.parameters]
delta = { value = 0.5, unit = "bar", min = -5.0, max = 5.0, vary = true }
"""


@dataclass(frozen=True)
class Link:
    """A symbolic link to ``target`` where a case's file would be."""

    target: str


@dataclass(frozen=True)
class Fifo:
    """A named pipe (FIFO) where a case's file would be: a read of it never returns."""


@dataclass(frozen=True)
class Case:
    """A command line run on the good files with ``files`` replacing or adding some."""

    id: str
    argv: tuple[str, ...]
    words: tuple[str, ...]
    files: dict = field(default_factory=dict)


def check(cfd: str = None, *, words=(), id: str) -> Case:
    return Case(id, ("check-data", "bad.csv"), ("bad.csv", *words), {"bad.csv": cfd})


COMPARE = ("compare", "--model", "cfda", "--data", "log.csv", "--out", "out")
FIT = ("fit", "--model", "cfda", "--data", "log.csv", "--out", "out")


def with_log(text: str, *, words=(), id: str) -> Case:
    return Case(id, COMPARE, ("log.csv", *words), {"log.csv": text})


def with_valve(text: str, *, words=(), id: str) -> Case:
    return Case(id, (*COMPARE, "--valve", "valve.toml"), ("valve.toml", *words),
                {"valve.toml": text})


def with_model(text: str, *, words=(), id: str) -> Case:
    return Case(id, ("compare", "--model", "model.toml", "--data", "log.csv", "--out", "out"),
                ("model.toml", *words), {"model.toml": text})


def with_effects(text: str, add: str, *, words=(), id: str) -> Case:
    return Case(id, (*FIT, "--effects-file", "fx.py", "--add", add), words, {"fx.py": text})


# --- trained surrogate folders: copies of the shipped ones, edited -------------------------------

TRAINED_FILES = {kind: {name: (trained_folder(kind) / name).read_bytes()
                        for name in ("surrogate.json", "flow.npz", "force.npz")}
                 for kind in ("nn", "gp")}


def npz_bytes(arrays: dict) -> bytes:
    stream = io.BytesIO()
    np.savez(stream, **arrays)
    return stream.getvalue()


def surrogate(kind: str = "nn", folder: str | None = None, *, weights: str = "flow",
              arrays=None, raw: bytes | None = None, reseal: bool = True, manifest=None,
              manifest_text: str | None = None) -> dict:
    """The files of a copy of the shipped ``kind`` surrogate in ``folder`` (default: named like
    the kind): ``arrays(dict)`` edits the arrays of its ``weights`` file in place (or ``raw``
    replaces the file's bytes), ``manifest(dict)`` edits its manifest in place (or
    ``manifest_text`` replaces it). ``reseal`` records the edited file's SHA-256, as a manifest
    consistent with its weights would, so that the check under test is the one that refuses
    them, not the seal."""
    files = dict(TRAINED_FILES[kind])
    name = f"{weights}.npz"
    if arrays is not None:
        with np.load(io.BytesIO(files[name])) as data:
            edited = {key: data[key] for key in data.files}
        arrays(edited)
        files[name] = npz_bytes(edited)
    if raw is not None:
        files[name] = raw
    document = json.loads(files["surrogate.json"])
    if reseal and (arrays is not None or raw is not None):
        document[weights]["predictor"]["sha256"] = hashlib.sha256(files[name]).hexdigest()
    if manifest is not None:
        manifest(document)
    files["surrogate.json"] = (manifest_text if manifest_text is not None
                               else json.dumps(document, indent=2) + "\n").encode()
    return {f"{folder or kind}/{key}": value for key, value in files.items()}


def unsealed(document: dict) -> None:
    """A manifest as versions before the weights' hashes wrote it."""
    for name in ("flow", "force"):
        document[name]["predictor"].pop("sha256")


def predict_with(kind: str, *, words=(), id: str, **edits) -> Case:
    """``predict`` on an edited copy of the shipped ``kind`` surrogate (:func:`surrogate`)."""
    return Case(id, ("predict", "--maps", f"./{kind}", "--input", "queries.csv", "--output",
                     "out.csv"), words, surrogate(kind, **edits))


#: a model on the trained surrogate in ./nn, recording that folder's manifest (as fit writes it)
MODEL_ON_NN = MODEL.split("[maps]")[0] + (
    '[maps]\nkind = "nn"\nfolder = "nn"\nsurrogate_sha256 = "'
    + hashlib.sha256(TRAINED_FILES["nn"]["surrogate.json"]).hexdigest() + '"\n\n[[effects]]'
    + MODEL.split("[[effects]]", 1)[1])
SECRET = "TOPSECRET-do-not-echo-7f3a"


def model_on_cfd(path: str) -> str:
    """The good model file with its grid maps on the CFD samples ``path`` (no hash recorded)."""
    lines = replace(MODEL, 'cfd = "shipped"', f'cfd = "{path}"').splitlines(keepends=True)
    return "".join(line for line in lines if not line.startswith("cfd_sha256"))


CASES = [
    # CFD samples --------------------------------------------------------------------------------
    check(set_cell(CFD, 7, "q_lpm", "abc"), words=("line 7", "'q_lpm'", "a number"),
          id="cfd: text for a number"),
    check(set_cell(CFD, 3, "rho_kg_m3", ""), words=("line 3", "empty"), id="cfd: empty cell"),
    check(set_cell(CFD, 4, "f_sim_N", "nan"), words=("line 4", "finite"), id="cfd: NaN"),
    check(set_cell(CFD, 4, "f_sim_N", "-inf"), words=("line 4", "finite"), id="cfd: -inf"),
    check(set_cell(CFD, 6, "u_mm", "-0.05"), words=("line 6", "'u_mm'"), id="cfd: negative u"),
    check(set_cell(CFD, 6, "u_mm", "630"), words=("line 6", "µm"), id="cfd: u in micrometres"),
    check(set_cell(CFD, 8, "q_lpm", "-1"), words=("line 8", "'q_lpm'"), id="cfd: negative q"),
    check(set_cell(CFD, 8, "q_lpm", "1e6"), words=("line 8", "5000 L/min"), id="cfd: huge q"),
    check(set_cell(CFD, 9, "p_L_bar", "1e30"), words=("line 9", "1000 bar"), id="cfd: p_L 1e30"),
    check(map_column(CFD, "p_L_bar", lambda v: v * 14.5038), words=("psi",),
          id="cfd: p_L in psi"),
    check(set_cell(CFD, 3, "p_B_bar", "-2"), words=("line 3", "-1.013"),
          id="cfd: below vacuum"),
    check(set_cell(CFD, 12, "p_L_bar", "4.0"), words=("line 12", "load pressure >= back"),
          id="cfd: p_L below p_B"),
    check(set_cell(CFD, 9, "nu_cSt", "0"), words=("line 9", "'nu_cSt'"), id="cfd: zero nu"),
    check(set_cell(CFD, 9, "nu_cSt", "4.6e-05"), words=("line 9", "m²/s"),
          id="cfd: nu in m2/s"),
    check(set_cell(CFD, 7, "nu_cSt", "5"), words=("line 7", "same viscosity", "20 °C"),
          id="cfd: nu inconsistent at its temperature"),
    check(set_cell(CFD, 10, "rho_kg_m3", "86.9"), words=("line 10", "600 to 1200"),
          id="cfd: density out of range"),
    check(set_cell(CFD, 10, "rho_kg_m3", "0.86921"), words=("line 10", "g/cm³"),
          id="cfd: density in g/cm3"),
    check(set_cell(CFD, 10, "rho_kg_m3", "900"), words=("line 10", "same density"),
          id="cfd: density inconsistent at its temperature"),
    check(map_column(CFD, "nu_cSt", lambda v: 200.0 if v == 46.0 else v),
          words=("viscosity of ISO VG46 HV falling",), id="cfd: viscosity rising with temperature"),
    check(set_cell(CFD, 11, "temperature_C", "293.15"),
          words=("line 11", "-40 to 200", "293.15 K = 20 °C"),
          id="cfd: temperature in kelvin"),
    check(set_cell(CFD, 4, "p_L_bar", "20"), words=("rising with the flow", "line 3"),
          id="cfd: pressure drop falling with flow"),
    check(set_cell(CFD, 5, "f_sim_N", "1e9"), words=("line 5", "'f_sim_N'"),
          id="cfd: absurd force"),
    check(set_cell(CFD, 13, "case", "C0002"), words=("line 13", "already on line 3"),
          id="cfd: duplicate case"),
    check(drop_column(CFD, "p_B_bar"), words=("'p_B_bar'", "missing"), id="cfd: missing column"),
    check(replace(CFD, "q_lpm", "Q_lpm"), words=("did you mean 'q_lpm'",),
          id="cfd: misspelt column"),
    check("\n".join([CFD.splitlines()[0] + ",mesh"]
                    + [r + ",fine" for r in CFD.splitlines()[1:]]) + "\n",
          words=("'mesh'", "only the documented"), id="cfd: extra column"),
    check(set_cell(CFD, 2, "u_mm", '"0,05"'), words=("decimal point",), id="cfd: decimal comma"),
    check(semicolons(CFD).replace("0,05", "0.05", 1), words=("decimal point", "decimal commas"),
          id="cfd: semicolons mixing decimal commas and points"),
    check(CFD.replace(",", "\t"), words=("tabs",), id="cfd: tabs"),
    check("", words=("empty",), id="cfd: empty file"),
    check(CFD.splitlines()[0] + "\n", words=("at least one data row",), id="cfd: header only"),
    check('{"case": "C0001"}\n', words=("JSON",), id="cfd: JSON"),
    check("\n".join(CFD.splitlines()[:5] + [CFD.splitlines()[5].rsplit(",", 1)[0]]) + "\n",
          words=("line 6", "10 comma-separated fields"), id="cfd: short row"),
    Case("cfd: binary file", ("check-data", "bad.csv"), ("bad.csv", "binary"),
         {"bad.csv": b"\x89PNG\r\n\x1a\n\x00\x00\x00"}),
    Case("cfd: UTF-16 with a byte-order mark", ("check-data", "bad.csv"),
         ("bad.csv", "UTF-16", "CSV UTF-8"), {"bad.csv": CFD.encode("utf-16")}),
    Case("log: UTF-16 without a byte-order mark", ("check-data", "bad.csv"),
         ("bad.csv", "UTF-16"), {"bad.csv": LOG.encode("utf-16-le")}),
    check("\n\n\n" + replace(CFD, "q_lpm", "Q_lpm"), words=("line 4", "did you mean 'q_lpm'"),
          id="cfd: misspelt header after blank lines"),
    Case("cfd: not UTF-8", ("check-data", "bad.csv"), ("bad.csv", "UTF-8"),
         {"bad.csv": CFD.replace("ISO VG46 HV", "ISO VG46 HV\xe9", 1).encode("latin-1")}),
    Case("cfd: broken file for grid maps", ("predict", "--maps", "grid", "--cfd", "bad.csv",
                                            "--input", "queries.csv", "--output", "out.csv"),
         ("bad.csv", "line 9"), {"bad.csv": set_cell(CFD, 9, "p_L_bar", "1e30")}),
    Case("cfd: a bench log where CFD samples belong",
         ("predict", "--maps", "grid", "--cfd", "log.csv", "--input", "queries.csv",
          "--output", "out.csv"), ("log.csv", "bench log")),

    # bench logs ---------------------------------------------------------------------------------
    with_log(set_cell(LOG, 5, "time_s", "0.5"), words=("line 5", "time increasing"),
             id="log: time going back"),
    with_log(set_cell(LOG, 6, "p_Pe_nominal_bar", "65"), words=("line 6", "one set point"),
             id="log: set point changing in a run"),
    with_log(set_cell(LOG, 7, "direction", "sideways"), words=("line 7", "'up', 'down'"),
             id="log: unknown direction"),
    with_log(set_cell(LOG, 8, "p_L_bar", "1e30"), words=("line 8", "1000 bar"),
             id="log: p_L 1e30"),
    with_log(set_cell(LOG, 8, "p_P_bar", "1e30"), words=("line 8", "'p_P_bar'"),
             id="log: p_P 1e30"),
    with_log(set_cell(LOG, 9, "p_L_bar", "0.5"), words=("line 9", "load pressure >= back"),
             id="log: p_L below p_B"),
    with_log(map_column(map_column(map_column(LOG, "p_L_bar", lambda v: v * 14.5038),
                                   "p_B_bar", lambda v: v * 14.5038),
                        "p_P_bar", lambda v: v * 14.5038), words=("psi",), id="log: psi"),
    with_log(map_column(map_column(LOG, "p_B_bar", lambda v: v * 14.5038),
                        "p_P_bar", lambda v: v * 14.5038), words=("look like psi",),
             id="log: pilot and back pressure in psi"),
    with_log(map_column(LOG, "p_Pe_nominal_bar", lambda v: v * 14.5038),
             words=("p_Pe_nominal_bar looks like psi",), id="log: set point in psi"),
    with_log(set_cell(LOG, 10, "p_P_bar", "140"), words=("line 10", "set point"),
             id="log: pilot far from its set point"),
    with_log(map_column(LOG, "temperature_C", lambda v: v + 273.15),
             words=("-40 to 200", "in K or"),
             id="log: temperature in kelvin"),
    with_log(set_cell(LOG, 11, "q_lpm", "-3"), words=("line 11", "'q_lpm'"),
             id="log: negative flow"),
    with_log(set_cell(LOG, 11, "run", ""), words=("line 11", "'run'", "empty"),
             id="log: empty run id"),
    with_log(drop_column(LOG, "direction"), words=("'direction'", "missing"),
             id="log: missing column"),
    with_log(LOG.replace("p_B_bar", "p_L_bar", 1), words=("each column name once",),
             id="log: duplicated column"),
    with_log(CFD, words=("CFD-sample file",), id="log: CFD samples where a log belongs"),
    with_log("\n".join(LOG.splitlines()[:4]) + "\n", words=("log.csv: the noise floor", "3"),
             id="log: too short for a noise floor"),
    # bench logs as benches and spreadsheets write them: new input paths, new ways to fail
    with_log(map_column(map_column(map_column(LOG, "p_L_bar", lambda v: v * PSI),
                                   "p_B_bar", lambda v: v * PSI),
                        "p_P_bar", lambda v: v * PSI),
             words=("column 'p_L_bar'", "rows rejected alike", "first on lines 2, 3, 4", "psi"),
             id="log: psi under _bar names, one verdict per column"),
    with_log(copy_column(LOG, "p_B_bar", "p_B_kPa", lambda v: v * 100),
             words=("'p_B_kPa'", "one column for the back pressure", "'p_B_bar' and 'p_B_kPa'"),
             id="log: a pressure given in two units"),
    with_log(set_cell(in_unit(LOG, "p_L_bar", "p_L_psi", lambda v: v * PSI), 8, "p_L_psi",
                      "1e30"), words=("line 8", "'p_L_psi'", "14503.8 psi"),
             id="log: p_L_psi 1e30"),
    with_log(set_cell(in_unit(LOG, "p_L_bar", "p_L_psi", lambda v: v * PSI), 9, "p_L_psi",
                      "7"), words=("line 9", "'p_L_psi'", "load pressure >= back",
                                   "converted to bar"),
             id="log: p_L_psi below p_B"),
    with_log(set_cell(in_unit(LOG, "q_lpm", "q_gpm", lambda v: v / 3.785411784), 11, "q_gpm",
                      "-1"), words=("line 11", "'q_gpm'", "US gpm"), id="log: negative q_gpm"),
    with_log(set_cell(in_unit(LOG, "temperature_C", "temperature_F", lambda v: v * 1.8 + 32), 5,
                      "temperature_F", "1000"), words=("line 5", "'temperature_F'",
                                                       "-40 to 392 °F"),
             id="log: temperature_F of 1000 °F"),
    with_log(replace(LOG, "q_lpm", "Q_lpm"), words=("'q_lpm'", "missing", "is 'Q_lpm' it"),
             id="log: misspelt column, kept as an extra one"),
    with_log(set_cell(LOG, 7, "direction", "+2"), words=("line 7", "+1 (up), -1 (down)"),
             id="log: direction +2"),
    with_log(semicolons(set_cell(LOG, 5, "q_lpm", "abc")), words=("line 5", "'q_lpm'", "a number"),
             id="log: semicolons with decimal commas, a bad cell"),
    with_log(semicolons(set_cell(LOG, 7, "q_lpm", "abc")).replace("\nR01;", '\n"R01, rig 2";',
                                                                 5).replace('"R01, rig 2"',
                                                                            "R01", 4),
             words=("line 7", "'q_lpm'", "a number"),
             id="log: semicolons with a quoted comma in a run id, a bad cell"),
    with_log(semicolons(LOG).replace("1,4", "1.4", 1),
             words=("line", "decimal point", "decimal commas"),
             id="log: semicolons mixing decimal commas and points"),
    with_log(semicolons(LOG).replace(";", "\t"), words=("tabs",),
             id="log: tab-separated with decimal commas"),
    Case("log: too few samples to fit", (*FIT, "--add", "friction_viscous"),
         ("log.csv: fitting", "needs more than 4 samples"),
         {"log.csv": "\n".join(LOG.splitlines()[:3]) + "\n"}),
    Case("log: missing file", ("compare", "--model", "cfda", "--data", "nowhere.csv"),
         ("nowhere.csv",)),

    # valve files --------------------------------------------------------------------------------
    with_valve(replace(VALVE, "A_L_mm2 = 10.7", "A_L_mm2 = 10.7e-6"), words=("A_L_mm2", "m²"),
               id="valve: area in m2"),
    with_valve(replace(VALVE, "U_max_mm = 0.63", "U_max_mm = 0.001"), words=("U_max_mm",),
               id="valve: stroke of a micrometre"),
    with_valve(replace(VALVE, "F_cr_N = 226.0", "F_cr_N = 1e30"), words=("F_cr_N",),
               id="valve: force 1e30"),
    with_valve(replace(VALVE, "U_max_mm = 0.63", "U_max_mm = inf"), words=("U_max_mm",),
               id="valve: infinite stroke"),
    with_valve(replace(VALVE, "w_mm = 12.0", "w_mm = nan"), words=("w_mm",), id="valve: NaN"),
    with_valve(replace(VALVE, "A_L_mm2 = 10.7", "A_L_mm2 = -10.7"), words=("A_L_mm2",),
               id="valve: negative area"),
    with_valve(replace(VALVE, "F_cr_N = 226.0", 'F_cr_N = "226"'), words=("F_cr_N", "number"),
               id="valve: text for a number"),
    with_valve(replace(VALVE, "F_cr_N = 226.0", "F_cr_N = true"), words=("F_cr_N", "number"),
               id="valve: boolean for a number"),
    with_valve(replace(VALVE, "K_f_N_per_m = 1.14e5", "K_f_N_per_m = 114"),
               words=("K_f_N_per_m", "N/mm"), id="valve: spring rate in N/mm"),
    with_valve(replace(VALVE, "K_f_N_per_m", "K_f"), words=("missing K_f_N_per_m",),
               id="valve: misspelt key"),
    with_valve(replace(VALVE, "w_mm = 12.0", "w_mm = 12.0\ncolour = 'red'"),
               words=("unknown colour",), id="valve: unknown key"),
    with_valve(replace(VALVE, "A_s3_mm2 = 46.0", "A_s3_mm2 = 30.0"), words=("must exceed",),
               id="valve: spring chamber smaller than A_B"),
    with_valve(replace(VALVE, "nu100_cSt = 8.0", "nu100_cSt = 80.0"), words=("nu40 > nu100",),
               id="valve: oil thicker when hot"),
    with_valve(replace(VALVE, "rho15_kg_m3 = 872.0", "rho15_kg_m3 = 0.872"),
               words=("rho15",), id="valve: density in g/cm3"),
    with_valve(replace(VALVE, "expansion_per_K = 6.4e-4", "expansion_per_K = 0.5"),
               words=("expansion",), id="valve: absurd expansion"),
    with_valve(replace(VALVE, "[oil]", "[oil"), words=("not valid TOML",),
               id="valve: not TOML"),
    with_valve(VALVE.split("[oil]")[0], words=("missing oil",), id="valve: no oil"),
    Case("valve: missing file", (*COMPARE, "--valve", "nowhere.toml"), ("nowhere.toml",)),

    # model files --------------------------------------------------------------------------------
    with_model(replace(MODEL, 'K1 = { value = 6.5, unit = "N", min = 0.0, max = 200.0, ',
                       'K1 = { value = 6.5, unit = "N", min = 6.5, max = 6.5, '),
               words=("K1", "min = 6.5 must be below max"), id="model: min equals max"),
    with_model(replace(MODEL, 'K1 = { value = 6.5, unit = "N", min = 0.0, max = 200.0, ',
                       'K1 = { value = 6.5, unit = "N", min = 10.0, max = 5.0, '),
               words=("K1", "must be below max"), id="model: min above max"),
    with_model(replace(MODEL, '[effects.parameters]\nscale = { value = 0.9, unit = "1", min = 0.0, '
                              'max = 3.0, vary = true }', "parameters = [1, 2]"),
               words=("parameters must be a table",), id="model: parameters as a list"),
    with_model(replace(MODEL_V1, 'maps = { kind = "grid" }', "maps = 3"), words=("maps",),
               id="model: maps as a number"),
    with_model(replace(MODEL_V1, 'maps = { kind = "grid" }',
                       'maps = { kind = "orifice", discharge_coefficient = -1 }'),
               words=("discharge_coefficient",), id="model: negative discharge coefficient"),
    with_model(replace(MODEL_V1, 'maps = { kind = "grid" }',
                       'maps = { kind = "orifice", discharge_coefficient = "x" }'),
               words=("discharge_coefficient", "number"), id="model: text discharge coefficient"),
    with_model(replace(MODEL_V1, 'maps = { kind = "grid" }',
                       'maps = { kind = "orifice", discharge_coefficient = 2.5 }'),
               words=("discharge_coefficient",), id="model: discharge coefficient above 1"),
    with_model(replace(MODEL_V1, 'maps = { kind = "grid" }', 'maps = { kind = "grid", smooth = 1 }'),
               words=("'smooth'",), id="model: unknown map option"),
    with_model(replace(MODEL_V1, 'maps = { kind = "grid" }', 'maps = { cfd = "x.csv" }'),
               words=("needs a kind",), id="model: map kind missing"),
    with_model("surprise = 1\n" + MODEL, words=("'surprise'",), id="model: unknown top key"),
    with_model(replace(MODEL, '[model]\n', '[model]\nauthor = "me"\n'), words=("'author'",),
               id="model: unknown model key"),
    with_model(replace(MODEL, 'name = "friction_constant"\n',
                       'name = "friction_constant"\ncolour = "red"\n'),
               words=("'colour'",), id="model: unknown effect key"),
    with_model(replace(MODEL, 'unit = "N", min = 0.0', 'unit = "N", step = 1.0, min = 0.0'),
               words=("'step'",), id="model: unknown parameter key"),
    with_model(MODEL + '\n[[effects]]\nname = "friction_constant"\n',
               words=("already effect",), id="model: duplicated effect"),
    with_model(replace(MODEL, "max = 200.0, vary = true", 'max = 200.0, vary = "no"'),
               words=("vary must be true or false",), id="model: vary as text"),
    with_model(replace(MODEL, "max = 200.0, vary = true", "max = 200.0, vary = 1"),
               words=("vary must be true or false",), id="model: vary as a number"),
    with_model(replace(MODEL, "K1 = { value = 6.5,", "K1 = { value = 600.0,"),
               words=("outside",), id="model: value outside its bounds"),
    with_model(replace(MODEL, "K1 = { value = 6.5,", "K1 = { value = nan,"),
               words=("finite",), id="model: NaN value"),
    with_model(replace(MODEL, "K1 = { value = 6.5,", 'K1 = { value = "6.5",'),
               words=("number",), id="model: text value"),
    with_model(replace(MODEL, 'K1 = { value = 6.5, unit = "N"', 'K1 = { value = 6.5, unit = "kN"'),
               words=("is in N",), id="model: wrong unit"),
    with_model(replace(MODEL, 'unit = "N", min = 0.0', 'unit = "N", min = -5.0'),
               words=("reach beyond the parameter's own",), id="model: negative friction allowed"),
    with_model(replace(MODEL, 'name = "friction_constant"', 'name = "friction_magic"'),
               words=("unknown effect 'friction_magic'",), id="model: unknown effect"),
    with_model(replace(MODEL, '[model]\nname = "cfda"', "[model]\nname = 5"),
               words=("name must be a string",), id="model: name as a number"),
    with_model(MODEL + '\n[[effects]]\nname = "pilot_zero_drift"\n[effects.parameters]\n'
               'delta_R01 = { value = 0.1, unit = "bar", min = -2.0, max = 2.0, vary = true }\n'
               'delta_R99 = { value = 0.2, unit = "bar", min = -2.0, max = 2.0, vary = true }\n',
               words=("pilot_zero_drift", "R99", "log.csv lacks"),
               id="model: per-run parameters of a run the log lacks"),
    with_model(replace(MODEL_V1, 'valve = "shipped"', 'valve = "nowhere.toml"'),
               words=("nowhere.toml",), id="model: valve file missing (format 1)"),
    with_model(MODEL.split("[valve]")[0] + '[valve]\nsource = "nowhere.toml"\n\n[maps]'
               + MODEL.split("[maps]")[1], words=("nowhere.toml",),
               id="model: valve file missing"),
    with_model(replace(MODEL, "A_L_mm2 = 10.7", "A_L_mm2 = 10.7e-6"), words=("A_L_mm2", "m²"),
               id="model: valve area in m2"),
    with_model(replace(MODEL, 'cfd_sha256 = "', 'cfd_sha256 = "0'), words=("cfd_sha256",),
               id="model: a malformed CFD hash"),
    with_model(replace(MODEL, 'cfd_sha256 = "d', 'cfd_sha256 = "e'),
               words=("not the ones the model was built from",),
               id="model: CFD samples other than the model's"),
    with_model(replace(MODEL, "format = 2", "format = 7"), words=("format 7",),
               id="model: a future format"),
    with_model(MODEL.replace("[[effects]]", "[[effect]]").replace("[effects.", "[effect."),
               words=("'effect'",),
               id="model: misspelt effects table"),
    with_model("[model\n", words=("not a valid TOML",), id="model: not TOML"),
    with_model('[model]\nname = "x"\n', words=("maps",), id="model: no maps"),
    Case("model: unknown preset", ("compare", "--model", "cfdaa", "--data", "log.csv"),
         ("unknown model 'cfdaa'", "preset")),

    # effects files ------------------------------------------------------------------------------
    with_effects("def broken(:\n", "broken", words=("fx.py", "SyntaxError"),
                 id="effects: syntax error"),
    with_effects("raise RuntimeError('no licence')\n", "x",
                 words=("fx.py", "line 1", "RuntimeError", "no licence"),
                 id="effects: raises on import"),
    with_effects("import sys\nsys.exit(0)\n", "x", words=("fx.py", "SystemExit"),
                 id="effects: sys.exit on import"),
    with_effects("x = 1\n", "x", words=("fx.py", "defines no effect"),
                 id="effects: defines none"),
    with_effects(effect_file("force", "1 / 0"), "fuzzed_force",
                 words=("fuzzed_force", "ZeroDivisionError"), id="effects: raises when called"),
    with_effects(effect_file("force", "np.zeros(3)"), "fuzzed_force",
                 words=("fuzzed_force", "shape"), id="effects: wrong shape"),
    with_effects(effect_file("force", "'a lot'"), "fuzzed_force",
                 words=("fuzzed_force", "must return numbers"), id="effects: returns text"),
    with_effects(effect_file("force", "state.u * np.nan"), "fuzzed_force",
                 words=("fuzzed_force", "non-finite"), id="effects: returns NaN"),
    with_effects(effect_file("force", "np.inf + state.u"), "fuzzed_force",
                 words=("fuzzed_force", "non-finite"), id="effects: returns inf"),
    with_effects(effect_file("friction", "-k + 0 * state.u"), "fuzzed_friction",
                 words=("fuzzed_friction", ">= 0"), id="effects: negative friction"),
    with_effects(effect_file("force", "1e30 + 0 * state.u"), "fuzzed_force",
                 words=("fuzzed_force", "beyond any hydraulic force"), id="effects: 1e30 N"),
    with_effects(effect_file("force", "sys.exit(0)", "state, k=1.0").replace(
        "import numpy", "import sys\nimport numpy"), "fuzzed_force",
        words=("fuzzed_force", "SystemExit"), id="effects: sys.exit when called"),
    with_effects(effect_file("sensor", "[1, 2]", "points, k=1.0"), "fuzzed_sensor",
                 words=("fuzzed_sensor", "OperatingPoints"), id="effects: sensor returns a list"),
    with_effects(effect_file("leakage", "-k * dp", "dp, state, k=1.0"), "fuzzed_leakage",
                 words=("fuzzed_leakage", ">= 0"), id="effects: negative leakage"),
    with_effects(effect_file("force", "k", decorator='@custom_effect("spin")'), "fuzzed_force",
                 words=("fx.py", "'spin'"), id="effects: unknown kind"),
    with_effects(effect_file("force", "k", "state, k"), "fuzzed_force",
                 words=("fx.py", "numeric default"), id="effects: parameter without default"),
    with_effects(effect_file("force", "k",
                             decorator='@custom_effect("force", units={"k": "furlong"})'),
                 "fuzzed_force", words=("fx.py", "unknown unit 'furlong'"),
                 id="effects: unknown unit"),
    with_effects(effect_file("force", "k",
                             decorator='@custom_effect("force", bounds={"j": (0, 1)})'),
                 "fuzzed_force", words=("fx.py", "unknown parameter"),
                 id="effects: bounds of an unknown parameter"),
    with_effects(effect_file("force", "k",
                             decorator='@custom_effect("force", bounds={"k": (2, 3)})'),
                 "fuzzed_force", words=("fx.py", "outside its bounds"),
                 id="effects: default outside its bounds"),
    with_effects(effect_file("force", "k").replace("fuzzed_force", "friction_constant"),
                 "friction_constant", words=("fx.py", "friction_constant", "exists already"),
                 id="effects: a built-in's name"),
    Case("effects: missing file", (*FIT, "--effects-file", "nowhere.py", "--add", "x"),
         ("nowhere.py", "not found")),
    Case("effects: a data file given as the effects file",
         (*FIT, "--effects-file", "log.csv", "--add", "x"), ("log.csv", "expected a .py file")),
    Case("effects: a data file listed as effects", ("effects", "--effects-file", "log.csv"),
         ("log.csv", "expected a .py file")),

    # command-line misuse ------------------------------------------------------------------------
    Case("cli: no command", (), ("required", "COMMAND")),
    Case("cli: unknown command", ("refit",), ("invalid choice", "'refit'")),
    Case("cli: unknown option", ("compare", "--model", "cfda", "--frobnicate"),
         ("unrecognized arguments", "--frobnicate")),
    Case("cli: fit without --out", ("fit", "--model", "cfda", "--data", "log.csv"),
         ("--out", "required")),
    Case("cli: compare without --model", ("compare", "--data", "log.csv"), ("--model",)),
    Case("cli: fit writing over its bench log", ("fit", "--model", "cfda", "--data", "log.csv",
                                                 "--add", "friction_viscous", "--out", "log.csv"),
         ("--out log.csv", "input")),
    Case("cli: fit writing over its model file",
         ("fit", "--model", "model.toml", "--data", "log.csv", "--out", "model.toml"),
         ("--out model.toml", "input")),
    Case("cli: fit writing over its effects file",
         (*FIT[:-1], "fx.py", "--effects-file", "fx.py", "--add", "seat_land_force"),
         ("--out fx.py", "input"), {"fx.py": EFFECTS}),
    Case("cli: fit writing over its valve file", ("fit", "--model", "cfda", "--data", "log.csv",
                                                  "--valve", "valve.toml", "--out", "valve.toml"),
         ("--out valve.toml", "input")),
    Case("cli: predict writing over its queries",
         ("predict", "--maps", "grid", "--input", "queries.csv", "--output", "queries.csv"),
         ("--output queries.csv", "input")),
    Case("cli: simulate writing over its sequence",
         ("simulate", "--sequence", "log.csv", "--out", "log.csv"), ("--out log.csv", "input")),
    Case("cli: compare writing into the folder of its log",
         ("compare", "--model", "cfda", "--data", "logs/log.csv", "--out", "logs"),
         ("--out logs", "holds the input"), {"logs/log.csv": LOG}),
    Case("cli: compare --out naming a file", (*COMPARE[:-1], "log.csv"), ("--out", "input")),
    Case("cli: compare --out naming an existing file", (*COMPARE[:-1], "queries.csv"),
         ("--out queries.csv", "this is a file")),
    Case("cli: fit --out naming a file", (*FIT[:-1], "queries.csv", "--add", "friction_viscous"),
         ("--out queries.csv", "this is a file")),
    Case("cli: fit --out in the old spelling naming a folder",
         (*FIT[:-1], "folder.toml", "--add", "friction_viscous"),
         ("--out folder.toml", "this is a folder"), {"folder.toml/keep.txt": "kept"}),
    Case("cli: predict with --input and --data both",
         ("predict", "--maps", "grid", "--input", "queries.csv", "--data", "queries.csv",
          "--out", "out"), ("--input", "--data", "give --data only")),
    Case("cli: predict without --out", ("predict", "--maps", "grid", "--data", "queries.csv"),
         ("--out FOLDER", "predictions.csv")),
    Case("cli: predict without --data", ("predict", "--maps", "grid", "--out", "out"),
         ("--data FILE", "query CSV")),
    Case("cli: --out under a file", (*FIT[:-1], "queries.csv/model.toml"),
         ("queries.csv", "is a file, not a folder")),
    Case("cli: --out where nothing can be written", (*FIT[:-1], "/proc/cbv/model.toml"),
         ("/proc/cbv/model.toml", "cannot write")),
    Case("cli: negative --max-additions", ("workflow", "--data", "log.csv", "--out", "out",
                                           "--max-additions", "-1"),
         ("--max-additions", ">= 0")),
    Case("cli: --max-additions not a number", ("workflow", "--data", "log.csv",
                                                "--max-additions", "many"),
         ("--max-additions", "'many'")),
    Case("cli: simulate --every 0", ("simulate", "--every", "0", "--out", "out.csv"),
         ("--every", ">= 1")),
    Case("cli: simulate negative noise", ("simulate", "--noise-scale", "-1", "--out", "out.csv"),
         ("--noise-scale",)),
    Case("cli: simulate --set without a number",
         ("simulate", "--hidden", "friction_viscous", "--set", "K_nu=lots", "--out", "out.csv"),
         ("--set", "PARAM=NUMBER")),
    Case("cli: simulate --set of an unknown parameter",
         ("simulate", "--hidden", "friction_viscous", "--set", "K_mu=1", "--every", "50",
          "--out", "out.csv"), ("no parameter 'K_mu'",)),
    Case("cli: simulate --set outside the bounds",
         ("simulate", "--hidden", "friction_viscous", "--set", "K_nu=-5", "--every", "50",
          "--out", "out.csv"), ("K_nu", "outside its bounds")),
    Case("cli: simulate --set without --hidden", ("simulate", "--set", "K_nu=1", "--out",
                                                  "out.csv"), ("--set needs --hidden",)),
    Case("cli: simulate an unknown effect", ("simulate", "--hidden", "warp_drive", "--out",
                                             "out.csv"), ("unknown effect 'warp_drive'",)),
    Case("cli: simulate a mismatch beyond any valve", ("simulate", "--mismatch", "50", "--out",
                                                       "out.csv"), ("--mismatch 50", "0 to 10")),
    Case("cli: simulate a negative mismatch", ("simulate", "--mismatch", "-1", "--out",
                                               "out.csv"), ("--mismatch -1",)),
    Case("cli: simulate on an unknown map kind",
         ("simulate", "--mismatch", "1", "--maps", "warp", "--out", "out.csv"),
         ("unknown map kind 'warp'",)),
    Case("cli: diagnose an unknown candidate",
         ("diagnose", "--model", "cfda", "--data", "log.csv", "--candidates", "friction_magic"),
         ("unknown effect 'friction_magic'",)),
    Case("cli: diagnose only what the model has",
         ("diagnose", "--model", "cfda", "--data", "log.csv", "--candidates",
          "friction_constant"), ("nothing to diagnose",)),
    Case("cli: fit an unknown effect", (*FIT, "--add", "warp_drive"),
         ("unknown effect 'warp_drive'",)),
    Case("cli: fit an effect the model has", (*FIT, "--add", "friction_constant"),
         ("friction_constant already",)),
    Case("cli: fit the same effect twice", (*FIT, "--add", "friction_viscous", "--add",
                                            "friction_viscous"), ("more than once",)),
    Case("cli: predict with an unknown map kind",
         ("predict", "--maps", "spline", "--input", "queries.csv", "--output", "out.csv"),
         ("unknown map kind 'spline'",)),
    Case("cli: paper with an unknown map kind", ("paper", "--maps", "spline", "--data",
                                                 "log.csv", "--out", "out"),
         ("unknown map kind 'spline'",)),
    Case("cli: predict without a fluid", ("predict", "--maps", "grid", "--input", "q.csv",
                                          "--output", "out.csv"), ("q.csv", "temperature_C"),
         {"q.csv": "u_mm,p_L_bar,p_B_bar\n0.1,50,5\n"}),
    Case("cli: check-data of a missing file", ("check-data", "nowhere.csv"), ("nowhere.csv",)),

    # what a run reads, through its model file and its maps: never an output ----------------------
    Case("guard: fit over the CFD samples its model's maps name",
         ("fit", "--model", "model.toml", "--data", "log.csv", "--out", "cfd.csv"),
         ("--out cfd.csv", "that is the input", "the grid maps' cfd", "model.toml"),
         {"model.toml": replace(MODEL, 'cfd = "shipped"', 'cfd = "cfd.csv"')}),
    Case("guard: fit over the valve file of a format-1 model",
         ("fit", "--model", "model.toml", "--data", "log.csv", "--out", "valve.toml"),
         ("--out valve.toml", "that is the input", "valve file", "model.toml"),
         {"model.toml": replace(MODEL_V1, 'valve = "shipped"', 'valve = "valve.toml"')}),
    Case("guard: fit over a surrogate's manifest",
         ("fit", "--model", "cfda", "--maps", "./nn", "--data", "log.csv", "--out",
          "nn/surrogate.json"), ("--out nn/surrogate.json", "inside the input folder", "nn"),
         surrogate("nn")),
    Case("guard: predict over NN weights",
         ("predict", "--maps", "./nn", "--input", "queries.csv", "--output", "nn/flow.npz"),
         ("--output nn/flow.npz", "inside the input folder"), surrogate("nn")),
    Case("guard: predict over GP weights",
         ("predict", "--maps", "./gp", "--input", "queries.csv", "--output", "gp/force.npz"),
         ("--output gp/force.npz", "inside the input folder"), surrogate("gp")),
    Case("guard: fit into the surrogate folder a model file names",
         ("fit", "--model", "model.toml", "--data", "log.csv", "--out", "nn/model.toml"),
         ("--out nn/model.toml", "inside the input folder", "model.toml"),
         {"model.toml": MODEL_ON_NN, **surrogate("nn")}),
    Case("guard: compare into a surrogate folder",
         ("compare", "--model", "model.toml", "--data", "log.csv", "--out", "nn"),
         ("--out nn", "that is the input"), {"model.toml": MODEL_ON_NN, **surrogate("nn")}),
    Case("guard: diagnose writing a folder that holds the model's CFD samples",
         ("diagnose", "--model", "model.toml", "--data", "log.csv", "--out", "data"),
         ("--out data", "holds the input", "cfd"),
         {"model.toml": model_on_cfd("data/cfd.csv"),
          "data/cfd.csv": CFD}),
    Case("guard: workflow into a surrogate folder",
         ("workflow", "--maps", "./gp", "--data", "log.csv", "--out", "gp/results"),
         ("--out gp/results", "inside the input folder"), surrogate("gp")),
    Case("guard: simulate over a surrogate's weights",
         ("simulate", "--maps", "./nn", "--out", "nn/force.npz"),
         ("--out nn/force.npz", "inside the input folder"), surrogate("nn")),
    Case("guard: paper into a surrogate folder",
         ("paper", "--maps", "./nn", "--data", "log.csv", "--out", "nn"),
         ("--out nn", "that is the input"), surrogate("nn")),
    Case("guard: suggest-cfd over the CFD samples --cfd names",
         ("suggest-cfd", "--maps", "grid", "--cfd", "cfd.csv", "--data", "log.csv", "--out",
          "cfd.csv"), ("--out cfd.csv", "that is the input")),
    Case("guard: predict over a weight file outside the folder that its manifest names",
         ("predict", "--maps", "./nn", "--input", "queries.csv", "--output", "flow.npz"),
         ("--output flow.npz", "that is the input"),
         {**surrogate("nn", manifest=lambda m: m["flow"]["predictor"].update(
             file="../flow.npz")), "flow.npz": TRAINED_FILES["nn"]["flow.npz"]}),

    # trained surrogates: sealed, checked, contained ---------------------------------------------
    predict_with("nn", arrays=lambda a: a.update(
        {key: value * 1.5 for key, value in a.items() if key.endswith("offset")}),
        reseal=False, words=("nn/flow.npz", "not the ones the manifest recorded", "SHA-256"),
        id="surrogate: NN weights edited after training"),
    predict_with("gp", weights="force", arrays=lambda a: a.update(dual=a["dual"] * 1.01),
                 reseal=False, words=("gp/force.npz", "not the ones the manifest recorded"),
                 id="surrogate: GP weights edited after training"),
    predict_with("nn", arrays=lambda a: a.update({"2/hidden.0": a["2/hidden.0"][:, :1]}),
                 words=("nn/flow.npz", "member 2", "'hidden.0'", "shape (16, 1)", "(16, 2)"),
                 id="surrogate: NN array of the wrong shape"),
    predict_with("nn", weights="force", arrays=lambda a: a.update(
        {"0/local_W": a["0/local_W"][:6]}), words=("nn/force.npz", "'local_W'", "(7, 8)"),
        id="surrogate: bridged NN array of the wrong shape"),
    predict_with("nn", weights="force", arrays=lambda a: a.pop("3/local_m"),
                 words=("nn/force.npz", "member 3", "missing array(s) local_m"),
                 id="surrogate: bridged NN without its pressure-level slopes"),
    predict_with("nn", arrays=lambda a: a.update({"1/bias.1": a["1/bias.1"] * np.nan}),
                 words=("nn/flow.npz", "'bias.1'", "NaN"), id="surrogate: NaN NN weights"),
    predict_with("gp", arrays=lambda a: a.update(dual=a["dual"] * np.nan),
                 words=("gp/flow.npz", "'dual'", "NaN"), id="surrogate: NaN GP weights"),
    predict_with("gp", weights="force", arrays=lambda a: a.update(dual=a["dual"][:-1]),
                 words=("gp/force.npz", "'dual'", "shape (153,)", "(154,)"),
                 id="surrogate: GP array of the wrong shape"),
    predict_with("gp", weights="force", arrays=lambda a: a.update(
        held_range=a["held_range"][:, ::-1]),
        words=("gp/force.npz", "'held_range'", "(low, high)"),
        id="surrogate: GP held range upside down"),
    predict_with("gp", arrays=lambda a: a.update(opening_trend_column=np.array(7)),
                 words=("gp/flow.npz", "'opening_trend_column'", "feature column 0 to 2"),
                 id="surrogate: GP trend in a column it does not read"),
    predict_with("gp", arrays=lambda a: a.update(
        opening_trend_range=a["opening_trend_range"][::-1]),
        words=("gp/flow.npz", "'opening_trend_range'", "(low, high)"),
        id="surrogate: GP trend range upside down"),
    predict_with("gp", arrays=lambda a: a.pop("opening_trend_range"),
                 words=("gp/flow.npz", "missing array 'opening_trend_range'"),
                 id="surrogate: GP trend without its range"),
    predict_with("gp", manifest=lambda m: m["force"].update(feature_names=["log_reynolds"]),
                 words=("gp/surrogate.json", "force", "feature_names", "log_pressure_drop"),
                 id="surrogate: force map naming features it cannot read"),
    predict_with("gp", arrays=lambda a: a.update(cholesky=a["cholesky"].T),
                 words=("gp/flow.npz", "'cholesky'", "lower triangular"),
                 id="surrogate: GP Cholesky factor not triangular"),
    predict_with("nn", arrays=lambda a: a.pop("0/linear"),
                 words=("nn/flow.npz", "member 0", "missing array", "linear"),
                 id="surrogate: NN array missing"),
    predict_with("gp", arrays=lambda a: a.pop("cholesky"),
                 words=("gp/flow.npz", "missing array 'cholesky'"),
                 id="surrogate: GP array missing"),
    predict_with("nn", arrays=lambda a: a.update({"0/extra": np.zeros(3)}),
                 words=("nn/flow.npz", "unexpected array", "extra"),
                 id="surrogate: NN array the architecture lacks"),
    predict_with("nn", raw=TRAINED_FILES["nn"]["flow.npz"][:5000], reseal=False,
                 words=("nn/flow.npz", "not the ones the manifest recorded"),
                 id="surrogate: truncated weights"),
    predict_with("nn", raw=TRAINED_FILES["nn"]["flow.npz"][:5000], reseal=False,
                 manifest=unsealed, words=("nn/flow.npz", "cannot load", "not sealed"),
                 id="surrogate: truncated weights, unsealed manifest"),
    predict_with("gp", raw=b"not a zip archive", manifest=unsealed,
                 words=("gp/flow.npz", "cannot load GP arrays"),
                 id="surrogate: GP weights not an npz"),
    predict_with("nn", manifest=lambda m: m["features"].update(A_L=0),
                 words=("nn/surrogate.json", "features.A_L", "must lie in (1e-10"),
                 id="surrogate: manifest with A_L = 0"),
    predict_with("gp", manifest=lambda m: m["features"].update(w=-0.012),
                 words=("gp/surrogate.json", "features.w"), id="surrogate: negative w"),
    predict_with("nn", manifest=lambda m: m["flow"]["predictor"]["feature_std"].__setitem__(
        1, 0.0), words=("nn/surrogate.json", "feature_std", "> 0"),
        id="surrogate: a feature's std of zero"),
    predict_with("gp", manifest=lambda m: m["force"]["domain"].update(reach=float("nan")),
                 words=("gp/surrogate.json", "force.domain.reach", "finite"),
                 id="surrogate: NaN in the manifest"),
    predict_with("nn", manifest=lambda m: m["force"]["predictor"].update(output="guess"),
                 words=("nn/surrogate.json", "output", "log_negative_fraction"),
                 id="surrogate: unknown network output"),
    predict_with("gp", manifest=lambda m: m["flow"]["predictor"].update(target=3),
                 words=("gp/surrogate.json", "target", "must be a string"),
                 id="surrogate: GP target not a string"),
    predict_with("nn", manifest=lambda m: m["flow"]["predictor"]["architecture"].update(
        groups=[[0, 7]]), words=("nn/surrogate.json", "architecture", "feature index"),
        id="surrogate: architecture naming a feature that does not exist"),
    predict_with("nn", manifest=lambda m: m["flow"]["predictor"]["architecture"].update(
        width="wide"), words=("nn/surrogate.json", "architecture", "malformed"),
        id="surrogate: architecture with text for a number"),
    predict_with("nn", manifest=lambda m: m["flow"]["predictor"].update(members=4),
                 words=("nn/flow.npz", "5 member(s)"), id="surrogate: member count off"),
    predict_with("nn", manifest_text="[1, 2, 3]\n",
                 words=("nn/surrogate.json", "JSON object", "an array"),
                 id="surrogate: manifest is a JSON list"),
    predict_with("gp", manifest=lambda m: m.pop("features"),
                 words=("gp/surrogate.json", "missing key 'features'"),
                 id="surrogate: manifest without features"),
    predict_with("nn", manifest=lambda m: m["force"].pop("domain"),
                 words=("nn/surrogate.json", "force", "missing key 'domain'"),
                 id="surrogate: manifest without a domain"),
    predict_with("nn", manifest=lambda m: m["flow"]["predictor"].update(sha256="abc"),
                 words=("nn/surrogate.json", "sha256", "64 hex"),
                 id="surrogate: malformed weight hash"),
    Case("surrogate: a weight file outside its folder",
         ("predict", "--maps", "./nn", "--input", "queries.csv", "--output", "out.csv"),
         ("nn/surrogate.json", "'../elsewhere/flow.npz'", "outside the surrogate folder"),
         {**surrogate("nn", manifest=lambda m: m["flow"]["predictor"].update(
             file="../elsewhere/flow.npz")),
          "elsewhere/flow.npz": TRAINED_FILES["nn"]["flow.npz"]}),
    predict_with("gp", manifest=lambda m: m["force"]["predictor"].update(file="/etc/hostname"),
                 words=("gp/surrogate.json", "outside the surrogate folder"),
                 id="surrogate: a weight file by absolute path"),
    predict_with("nn", manifest_text='{"a": ' * 5000 + "1" + "}" * 5000,
                 words=("nn/surrogate.json", "nested too deep"),
                 id="surrogate: manifest nested 5000 deep"),
    predict_with("nn", manifest_text='{"format_version": 2, "kind": "nn", "x": '
                 + "[" * 40 + "]" * 40 + "}", words=("nn/surrogate.json", "nested too deep"),
                 id="surrogate: manifest nested 40 deep"),
    Case("surrogate: a model file on edited weights",
         ("compare", "--model", "model.toml", "--data", "log.csv"),
         ("model.toml", "nn/flow.npz", "not the ones the manifest recorded"),
         {"model.toml": MODEL_ON_NN, **surrogate("nn", arrays=lambda a: a.update(
             {"0/offset": a["0/offset"] + 0.1}), reseal=False)}),
    Case("surrogate: a model file on a resealed manifest",
         ("compare", "--model", "model.toml", "--data", "log.csv"),
         ("model.toml", "not the one the model was built on"),
         {"model.toml": MODEL_ON_NN, **surrogate("nn", arrays=lambda a: a.update(
             {"0/offset": a["0/offset"] + 0.1}))}),

    # a --maps value that is a kind and a folder here --------------------------------------------
    Case("maps: predict --maps nn beside a surrogate folder nn",
         ("predict", "--maps", "nn", "--input", "queries.csv", "--output", "out.csv"),
         ("--maps nn", "ambiguous", "map kind", "--maps ./nn", "for the folder",
          str(trained_folder("nn"))), surrogate("nn")),
    Case("maps: compare --maps gp beside a surrogate folder gp",
         ("compare", "--model", "cfda", "--maps", "gp", "--data", "log.csv"),
         ("--maps gp", "ambiguous", "--maps ./gp"), surrogate("gp")),
    Case("maps: simulate --maps nn beside a surrogate folder nn",
         ("simulate", "--maps", "nn", "--out", "out.csv"), ("--maps nn", "ambiguous"),
         surrogate("nn")),
    Case("maps: paper --maps gp beside a surrogate folder gp",
         ("paper", "--maps", "gp", "--data", "log.csv", "--out", "out"),
         ("--maps gp", "ambiguous"), surrogate("gp")),
    Case("maps: suggest-cfd --maps nn beside a surrogate folder nn",
         ("suggest-cfd", "--maps", "nn", "--data", "log.csv", "--out", "out"),
         ("--maps nn", "ambiguous"), surrogate("nn")),
    Case("maps: workflow --maps nn beside a surrogate folder nn",
         ("workflow", "--maps", "nn", "--data", "log.csv", "--out", "out"),
         ("--maps nn", "ambiguous"), surrogate("nn")),
    Case("maps: --maps grid beside a surrogate folder grid",
         ("predict", "--maps", "grid", "--input", "queries.csv", "--output", "out.csv"),
         ("--maps grid", "ambiguous", "--maps ./grid", "rename"), surrogate("nn", "grid")),
    Case("maps: predict --maps NN beside a surrogate folder NN",
         ("predict", "--maps", "NN", "--input", "queries.csv", "--output", "out.csv"),
         ("--maps NN", "ambiguous", "--maps ./NN", "for the folder"), surrogate("nn", "NN")),
    Case("maps: a near miss of a kind", ("predict", "--maps", "gpp", "--input", "queries.csv",
                                         "--output", "out.csv"),
         ("unknown map kind 'gpp'", "did you mean 'gp'?")),
    Case("model: a near miss of a preset", ("compare", "--model", "CFAD", "--data", "log.csv"),
         ("unknown model 'CFAD'", "did you mean 'cfda'?")),
    Case("effects: a broken effects file listed", ("effects", "--effects-file", "fx.py"),
         ("fx.py",), {"fx.py": effect_file("force", "float('nan') * state.p_L")}),
    Case("maps: a format-1 model's maps = \"nn\" beside a surrogate folder nn",
         ("compare", "--model", "model.toml", "--data", "log.csv"),
         ("model.toml", "ambiguous", 'folder = "./nn"'),
         {"model.toml": replace(MODEL_V1, 'maps = { kind = "grid" }', 'maps = "nn"'),
          **surrogate("nn")}),

    # export ---------------------------------------------------------------------------------------
    Case("export: a custom effect that reads its batch cannot be tabulated",
         ("export", "--model", "batch.toml", "--effects-file", "fx.py", "--data", "log.csv",
          "--format", "fmu", "--out", "out"),
         ("batch.toml", "batch_force", "fx.py", "cannot be tabulated", "elementwise"),
         {"fx.py": BATCH_EFFECT, "batch.toml": MODEL + BATCH_EFFECT_ENTRY}),
    Case("export: a model of sensor terms only",
         ("export", "--model", "sensor.toml", "--data", "log.csv", "--format", "tables",
          "--out", "out"),
         ("sensor.toml", "pilot_transducer_offset", "belongs to the bench"),
         {"sensor.toml": MODEL.split("[[effects]]")[0] + SENSOR_ENTRY}),
    Case("export: an output folder holding its bench log",
         ("export", "--model", "cfda", "--data", "log.csv", "--format", "tables", "--out", "."),
         ("--out", "holds the input", "log.csv")),
    Case("export: a grid too coarse for the tolerance asked",
         ("export", "--model", "cfda", "--data", "log.csv", "--format", "fmu",
          "--grid-scale", "0.25", "--tolerance", "0.001", "--out", "out"),
         ("--grid-scale 0.25", "not met", "--tolerance 0.001", "log.csv")),
    Case("export: onnx of a model on grid maps",
         ("export", "--model", "cfda", "--data", "log.csv", "--format", "onnx", "--out", "out"),
         ("cfda", "onnx", "nn", "gp")),
    Case("export: a grid scale out of range",
         ("export", "--model", "cfda", "--data", "log.csv", "--format", "tables",
          "--grid-scale", "100", "--out", "out"),
         ("--grid-scale", "[0.25, 8]")),
    Case("steady: an empty flow range",
         ("steady", "--model", "cfda", "--p-P-bar", "65", "--q-lpm", "5", "1", "--out", "out"),
         ("--q-lpm", "LOW < HIGH")),

    # files a model names are not echoed; nesting -------------------------------------------------
    Case("leak: a model's cfd naming a file that is no CSV",
         ("compare", "--model", "model.toml", "--data", "log.csv"),
         ("secret.txt", "not a CSV file", "check-data"),
         {"model.toml": model_on_cfd("secret.txt"),
          "secret.txt": SECRET + "\nmore\n"}),
    Case("leak: a model's cfd reaching up a folder for a CSV",
         ("compare", "--model", "sub/model.toml", "--data", "log.csv"),
         ("secret.csv", "column 'case'", "missing from the header", "check-data"),
         {"sub/model.toml": model_on_cfd("../secret.csv"),
          "secret.csv": f"{SECRET},x,y\n1,2,3\n"}),
    Case("leak: a model's cfd naming CFD samples with a bad cell",
         ("compare", "--model", "model.toml", "--data", "log.csv"),
         ("bad.csv", "line 7", "'q_lpm'", "flow, 0 to 5000"),
         {"model.toml": model_on_cfd("bad.csv"),
          "bad.csv": set_cell(CFD, 7, "q_lpm", SECRET)}),
    Case("leak: a model's valve naming a file with keys of its own",
         ("compare", "--model", "model.toml", "--data", "log.csv"),
         ("secret.toml", "not a valid valve file", "--valve"),
         {"model.toml": MODEL.split("[valve]")[0] + '[valve]\nsource = "secret.toml"\n\n[maps]'
          + MODEL.split("[maps]")[1], "secret.toml": f"{SECRET} = 1\n"}),
    Case("leak: a format-1 model's valve naming a file that is no TOML",
         ("compare", "--model", "model.toml", "--data", "log.csv"),
         ("secret.toml", "not a valid valve file", "--valve"),
         {"model.toml": replace(MODEL_V1, 'valve = "shipped"', 'valve = "secret.toml"'),
          "secret.toml": f"{SECRET} is not TOML\n"}),
    with_model("[model]\nname = \"x\"\nmaps = " + "[" * 5000 + "]" * 5000 + "\n",
               words=("nested too deep",), id="nesting: a model 5000 levels deep"),
    with_model("[" + ".".join(["x"] * 5000) + "]\n", words=("nested too deep",),
               id="nesting: a model's table header 5000 levels deep"),
    with_valve("a = " + "{ b = " * 3000 + "1" + " }" * 3000 + "\n", words=("nested too deep",),
               id="nesting: a valve file 3000 levels deep"),
]


# --- what no input may do: run code, read forever, write through a link, flow on with nonsense --

def npz_claiming(shape: tuple[int, ...]) -> bytes:
    """An ``.npz`` whose one array's header claims ``shape`` (float64) and holds no data: a few
    hundred bytes asking for gigabytes."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False,
                                                   "shape": shape})
    stream = io.BytesIO()
    with zipfile.ZipFile(stream, "w") as archive:
        archive.writestr("0/hidden.0.npy", header.getvalue())  # the magic string included
    return stream.getvalue()


def compressed_npz(kind: str, weights: str, arrays: dict) -> bytes:
    """The shipped ``kind``'s ``weights`` archive with ``arrays`` replaced, compressed: 16 MB of
    zeros pack into a few kB."""
    with np.load(io.BytesIO(TRAINED_FILES[kind][f"{weights}.npz"])) as data:
        edited = {key: data[key] for key in data.files} | arrays
    stream = io.BytesIO()
    np.savez_compressed(stream, **edited)
    return stream.getvalue()


def scaled(factor: float):
    """An ``arrays`` edit multiplying every weight by ``factor``."""
    return lambda arrays: arrays.update({key: value * factor for key, value in arrays.items()})


def _unsealed_manifest_hash() -> str:
    document = json.loads(TRAINED_FILES["nn"]["surrogate.json"])
    unsealed(document)
    return hashlib.sha256((json.dumps(document, indent=2) + "\n").encode()).hexdigest()


#: a model on ./nn recording the hash of its manifest from before the weights were sealed
MODEL_ON_UNSEALED_NN = MODEL_ON_NN.replace(
    hashlib.sha256(TRAINED_FILES["nn"]["surrogate.json"]).hexdigest(), _unsealed_manifest_hash())


def _shape_model() -> str:
    from surrogate.effects.shapes import OpeningForce
    from surrogate.description.spec import EffectSpec

    shape = OpeningForce.on_knots(np.linspace(0.05e-3, 0.55e-3, 6))
    spec = preset("cfda")
    return dataclasses.replace(spec, effects=spec.effects + (EffectSpec.of(shape),)).to_toml()


#: a model whose last effect is a force of the opening of free shape, knots 0.05 to 0.55 mm
SHAPE_MODEL = _shape_model()
KNOT = '{key} = {{ value = {value!r}, unit = "mm", min = 0.0, max = 100.0, vary = false }}\n'


def with_knot(key: str, value: float) -> str:
    """SHAPE_MODEL with one knot set (or added) to ``value`` [mm]."""
    lines = [line for line in SHAPE_MODEL.splitlines(keepends=True)
             if not line.startswith(key + " =")]
    return "".join(lines) + KNOT.format(key=key, value=value)


FLEET = ("fleet", "--model", "cfda", "--data", "logs", "--out", "out")


def fleet(id: str, files: dict, words: tuple, *options: str) -> Case:
    return Case(id, (*FLEET, *options), words, {"logs/SN1.csv": LOG, **files})


CASES += [
    # outputs: never through a link, never over a folder of the user's ---------------------------
    fleet("links: a fleet's valves folder linked to the surrogate folder it reads",
          {**surrogate("nn"), "out/valves": Link("../nn")}, ("out/valves", "symbolic link"),
          "--maps", "./nn"),
    fleet("links: a fleet's valves folder is a file", {"out/valves": "mine\n"},
          ("out/valves", "is a file where this run writes a folder")),
    fleet("links: a valve's record is a folder", {"out/valves/SN1.json/keep.txt": "mine\n"},
          ("SN1.json", "is a folder where this run writes a file")),
    fleet("links: a fleet's report is a link", {"out/report.html": Link("../secret.txt"),
                                                "secret.txt": SECRET},
          ("out/report.html", "symbolic link")),
    Case("links: export over a folder of the user's named like its output",
         ("export", "--model", "cfda", "--maps", "nn", "--format", "onnx", "--data", "log.csv",
          "--out", "out"), ("out/flow.onnx", "is a folder where this run writes a file"),
         {"out/flow.onnx/keep.txt": "mine\n"}),

    # reads: regular files only, of bounded size, checked before a byte is read ------------------
    Case("reads: check-data /dev/zero", ("check-data", "/dev/zero"),
         ("/dev/zero", "a device, not a regular file")),
    Case("reads: check-data of a FIFO", ("check-data", "pipe.csv"), ("pipe.csv", "FIFO"),
         {"pipe.csv": Fifo()}),
    Case("reads: check-data of a folder", ("check-data", "dir.csv"), ("dir.csv", "a folder"),
         {"dir.csv/keep.txt": "x"}),
    Case("reads: a table beyond --max-input-mb", ("check-data", "log.csv", "--max-input-mb",
                                                  "0.001"),
         ("log.csv", "larger than", "--max-input-mb")),
    with_model(model_on_cfd("/dev/zero"), words=("/dev/zero", "not a regular file"),
               id="reads: a model's CFD samples at /dev/zero"),
    with_model(MODEL.split("[valve]")[0] + '[valve]\nsource = "/dev/zero"\n\n[maps]'
               + MODEL.split("[maps]")[1], words=("/dev/zero", "not a valid valve file"),
               id="reads: a model's valve file at /dev/zero"),
    with_valve(Link("/dev/zero"), words=("valve.toml", "not a regular file"),
               id="reads: a valve file linked to /dev/zero"),
    Case("reads: a model file that is a FIFO", ("compare", "--model", "m.toml", "--data",
                                                 "log.csv"), ("m.toml", "FIFO"),
         {"m.toml": Fifo()}),
    Case("reads: an effects file that is a FIFO",
         (*FIT, "--effects-file", "fx.py", "--add", "x"), ("fx.py", "FIFO"), {"fx.py": Fifo()}),
    predict_with("nn", raw=npz_claiming((10**8,)), words=("nn/flow.npz", "larger than"),
                 id="reads: a weight array claiming 800 MB"),
    Case("reads: zeros unpacking beyond the weights' bound",
         ("predict", "--maps", "./nn", "--input", "queries.csv", "--output", "out.csv",
          "--max-input-mb", "16"), ("nn/flow.npz", "unpacked", "--max-input-mb"),
         surrogate("nn", raw=compressed_npz("nn", "flow", {"0/hidden.0": np.zeros(2_000_000)}))),
    Case("reads: a FIFO as an unsealed folder's weights",
         ("predict", "--maps", "./nn", "--input", "queries.csv", "--output", "out.csv"),
         ("nn/flow.npz", "FIFO"), {**surrogate("nn", manifest=unsealed), "nn/flow.npz": Fifo()}),

    # a scheduler's address: refused in seconds, located ------------------------------------------
    fleet("scheduler: not an address", {}, ("--scheduler 'notaurl'", "tcp://host:8786"),
          "--scheduler", "notaurl"),
    fleet("scheduler: a port out of range", {}, ("not a scheduler's address",),
          "--scheduler", "tcp://127.0.0.1:99999"),
    fleet("scheduler: a refused port", {}, ("tcp://127.0.0.1:1", "cannot connect"),
          "--scheduler", "tcp://127.0.0.1:1"),

    # finite nonsense: maps and results no valve has ----------------------------------------------
    predict_with("nn", arrays=scaled(1e300), words=("nn maps", "no valve has that"),
                 id="nonsense: NN weights scaled by 1e300 and sealed again"),
    predict_with("gp", weights="force", arrays=lambda a: a.update(dual=a["dual"] * 1e300),
                 words=("gp maps", "force map", "no valve has that"),
                 id="nonsense: GP weights scaled by 1e300 and sealed again"),
    Case("nonsense: a model's pre-seal hash accepting swapped weights",
         ("steady", "--model", "model.toml", "--p-P-bar", "60", "--out", "out"),
         ("nn maps", "no valve has that"),
         {"model.toml": MODEL_ON_UNSEALED_NN,
          **surrogate("nn", arrays=scaled(1e30), reseal=False, manifest=unsealed)}),
    predict_with("gp", manifest=lambda m: m["flow"]["calibration"].update(scale=1e308),
                 words=("flow.calibration.scale", "must lie in"),
                 id="nonsense: a calibration scale of 1e308"),
    Case("nonsense: steady at a pilot pressure of 1e9 bar",
         ("steady", "--model", "cfda", "--p-P-bar", "1e9", "--out", "out"),
         ("--p-P-bar", "1000 bar")),
    Case("nonsense: steady at 1e6 L/min", ("steady", "--model", "cfda", "--p-P-bar", "60",
                                           "--q-lpm", "1", "1e6", "--out", "out"),
         ("--q-lpm", "5000 L/min")),
    # the last sample of the first run, and the first: time still rises within the run
    with_log(set_cell(LOG, 93, "time_s", "1e308"), words=("line 93", "'time_s'", "1e+07 s"),
             id="nonsense: time 1e308 s"),
    with_log(set_cell(LOG, 2, "time_s", "-1e308"), words=("line 2", "'time_s'", "1e+07 s"),
             id="nonsense: time -1e308 s"),

    # accepted before, refused now ----------------------------------------------------------------
    with_valve(VALVE.replace("[valve]", "[[valve]]"), words=("[valve]", "one table"),
               id="valve: an array of tables"),
    with_valve(b"\x7fELF\x02\x01\x01\x00\xff\xfe\x00", words=("valve.toml", "not UTF-8"),
               id="valve: a binary file"),
    with_model(with_knot("knot_3", 0.01), words=("knot_3", "does not lie above knot_2"),
               id="model: shape knots out of order"),
    with_model(with_knot("knot_3", 0.15), words=("knot_3", "rise strictly"),
               id="model: shape knots repeated"),
    with_model(SHAPE_MODEL + "".join(KNOT.format(key=f"knot_{i}", value=0.6 + i * 1e-3)
                                     for i in range(7, 3001)),
               words=("3000 knots", "2 to 64"), id="model: 3000 shape knots"),
    with_log(set_cell(LOG, 5, "run", "R01\x1b[2J"), words=("line 5", "'run'", "control"),
             id="log: a run id with an ANSI escape"),
    with_log(set_cell(LOG, 5, "run", '"R01\nrm -rf"'), words=("'run'", "control"),
             id="log: a run id with a line break"),
    with_log(set_cell(LOG, 5, "run", "R" * 101),
             words=("line 5", "'run'", "1 to 100 characters"),
             id="log: a run id of 101 characters"),
    fleet("fleet: a log linked to a file outside", {"logs/SN2.csv": Link("../secret.txt"),
                                                   "secret.txt": f"{SECRET}\nroot:x:0:0\n"},
          ("logs/SN2.csv", "symbolic link")),
    fleet("fleet: a folder named like a log", {"logs/x.csv/keep.txt": "x"},
          ("logs/x.csv", "a folder")),
    fleet("fleet: a FIFO named like a log", {"logs/SN2.csv": Fifo()}, ("logs/SN2.csv", "FIFO")),
    fleet("fleet: a link that loops", {"logs/loop.csv": Link("loop.csv")},
          ("logs/loop.csv", "symbolic link")),
    fleet("fleet: a log linked to /dev/zero", {"logs/zero.csv": Link("/dev/zero")},
          ("logs/zero.csv", "symbolic link")),
    fleet("fleet: a serial with a space", {"logs/SN 2.csv": LOG}, ("SN 2.csv", "rename")),
]


@pytest.fixture
def registry():
    """Loading a user's effects changes nothing global: the built-in library stays as it was."""
    before = dict(LIBRARY)
    yield
    assert dict(LIBRARY) == before


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every entry below ``folder``: a file's bytes, a link's target, or its kind (never
    reading a FIFO or following a link)."""
    def state(path: Path) -> bytes:
        if path.is_symlink():
            return b"<link>" + os.readlink(path).encode()
        if path.is_dir():
            return b"<dir>"
        return path.read_bytes() if path.is_file() else b"<special>"
    return {str(path.relative_to(folder)): state(path) for path in sorted(folder.rglob("*"))}


def run_case(folder: Path, case: Case, capsys, monkeypatch, *, as_json: bool = False):
    for name, content in {**GOOD_FILES, **case.files}.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, Link):
            path.symlink_to(content.target)
        elif isinstance(content, Fifo):
            os.mkfifo(path)
        elif isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")
    monkeypatch.chdir(folder)
    before = snapshot(folder)
    argv = [*case.argv, "--json"] if as_json and case.argv and case.argv[0] != "check-data" \
        else list(case.argv)
    code = main(argv)
    captured = capsys.readouterr()
    assert snapshot(folder) == before, "an output appeared or an input changed"
    return code, captured


@pytest.mark.pipeline
@pytest.mark.parametrize("case", CASES, ids=[case.id for case in CASES])
def test_bad_input_exits_2_naming_the_problem_and_writes_nothing(case, tmp_path, capsys,
                                                                 monkeypatch, registry):
    code, captured = run_case(tmp_path, case, capsys, monkeypatch)
    assert code == 2, captured.err
    assert "Traceback" not in captured.err
    assert SECRET not in captured.err + captured.out  # no case quotes a file nobody named
    for word in case.words:
        assert word in captured.err, f"{word!r} missing from: {captured.err}"


def test_the_table_has_over_a_hundred_cases():
    assert len(CASES) >= 100
    assert len({case.id for case in CASES}) == len(CASES)


JSON_CASES = [case for case in CASES if case.id in (
    "log: p_L 1e30", "model: vary as text", "cli: negative --max-additions",
    "effects: returns NaN", "cli: fit writing over its bench log")]


@pytest.mark.pipeline
@pytest.mark.parametrize("case", JSON_CASES, ids=[case.id for case in JSON_CASES])
def test_json_mode_reports_errors_as_json(case, tmp_path, capsys, monkeypatch, registry):
    code, captured = run_case(tmp_path, case, capsys, monkeypatch, as_json=True)
    assert code == 2
    error = json.loads(captured.out)["error"]
    assert error["exit_code"] == 2
    for word in case.words:
        assert word in error["message"]
    if case.id == "log: p_L 1e30":
        assert any(p["line"] == 8 and p["column"] == "p_L_bar" for p in error["problems"])


@pytest.mark.pipeline
@pytest.mark.slow
@pytest.mark.parametrize("case", [CASES[0], JSON_CASES[1], next(
    case for case in CASES if case.id == "nesting: a valve file 3000 levels deep")],
                         ids=["cfd", "model", "cli"])
def test_a_real_process_prints_no_traceback(case, tmp_path):
    for name, content in {**GOOD_FILES, **case.files}.items():
        (tmp_path / name).write_text(content) if isinstance(content, str) \
            else (tmp_path / name).write_bytes(content)
    done = subprocess.run([sys.executable, "-m", "surrogate", *case.argv], cwd=tmp_path,
                          capture_output=True, text=True)
    assert done.returncode == 2
    assert "Traceback" not in done.stderr and case.words[0] in done.stderr


@pytest.mark.pipeline
def test_an_internal_error_is_one_line_and_a_file_of_details(tmp_path, capsys, monkeypatch):
    """A bug (simulated here) is not bad input: exit 1, one line, the traceback in a file."""
    from surrogate.commands import check_data

    def broken(args):
        raise ZeroDivisionError("simulated bug")

    monkeypatch.setattr(check_data, "run", broken)
    assert main(["check-data", str(SHIPPED_CFD_SAMPLES)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "internal error" in err and "simulated bug" in err
    details = Path(err.rsplit("details are in ", 1)[1])
    assert "Traceback" in details.read_text() and "ZeroDivisionError" in details.read_text()
    details.unlink()


# --- generated cases ----------------------------------------------------------------------------

BAD_NUMBERS = st.one_of(
    st.sampled_from(["", "abc", "nan", "NaN", "inf", "-inf", "1,5", "0x10", "--1", "1e400",
                     "1.2.3", "twelve", "∞"]),
    st.floats(min_value=1e7, max_value=1e300).map(repr),  # beyond every column's limits
    st.floats(min_value=-1e300, max_value=-1e7).map(repr),
)


@pytest.mark.pipeline
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(["cfd", "log"]), line=st.integers(2, 60), value=BAD_NUMBERS,
       data=st.data())
def test_generated_bad_cells_are_located(kind, line, value, data):
    text = CFD if kind == "cfd" else LOG
    columns = [c for c in text.splitlines()[0].split(",") if c.endswith(
        ("_bar", "_mm", "_lpm", "_cSt", "_kg_m3", "_N", "_C"))]
    column = data.draw(st.sampled_from(columns))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "bad.csv"
        path.write_text(set_cell(text, line, column, value))
        before = path.read_bytes()
        code = main(["check-data", str(path), "--json"])
        assert path.read_bytes() == before and sorted(Path(folder).iterdir()) == [path]
    assert code == 2


VALVE_KEYS = ["A_L_mm2", "alpha_P", "A_s3_mm2", "F_cr_N", "K_f_N_per_m", "U_max_mm", "w_mm",
              "nu40_cSt", "nu100_cSt", "rho15_kg_m3"]
BAD_TOML_VALUES = st.one_of(
    st.sampled_from(["0", "-1", "inf", "-inf", "nan", '"12"', "true", "[1, 2]", "{ a = 1 }",
                     "1e30", "1e-30"]),
    st.floats(min_value=1e10, max_value=1e300).map(repr),  # beyond every key's limit
)


@settings(max_examples=40, deadline=None)
@given(key=st.sampled_from(VALVE_KEYS), value=BAD_TOML_VALUES)
def test_generated_bad_valve_values_name_the_key(key, value):
    lines = [f"{key} = {value}" if line.split("=")[0].strip() == key else line
             for line in VALVE.splitlines()]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "valve.toml"
        path.write_text("\n".join(lines) + "\n")
        from surrogate.core.errors import InputError
        from surrogate.valve import load_valve

        with pytest.raises(InputError) as caught:
            load_valve(path)
    message = str(caught.value)
    assert str(path) in message
    # the key, or for the oil's ordering rule the pair it breaks
    assert key in message or key.split("_")[0] in message, message


MODEL_PLACES = ["top", "model", "effect", "parameter"]


@settings(max_examples=30, deadline=None)
@given(place=st.sampled_from(MODEL_PLACES),
       key=st.from_regex(r"[a-z][a-z_]{2,12}", fullmatch=True))
def test_generated_unknown_model_keys_are_refused(place, key):
    from surrogate.core.errors import InputError
    from surrogate.parameters import _RECORD_KEYS as _PARAMETER_KEYS
    from surrogate.description.spec import _EFFECT_KEYS, _MODEL_KEYS, _TOP_KEYS

    known = {"top": _TOP_KEYS, "model": _MODEL_KEYS, "effect": _EFFECT_KEYS,
             "parameter": _PARAMETER_KEYS}[place]
    if key in known or key in ("scale", "k1", "k2"):
        return
    text = {"top": f"{key} = 1\n" + MODEL,
            "model": MODEL.replace("[model]\n", f"[model]\n{key} = 1\n", 1),
            "effect": MODEL.replace('name = "flow_force_scale"\n',
                                    f'name = "flow_force_scale"\n{key} = 1\n', 1),
            "parameter": MODEL.replace("scale = { value", f"scale = {{ {key} = 1, value", 1)}[place]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "model.toml"
        path.write_text(text)
        from surrogate.description.modelfile import load_model

        with pytest.raises(InputError, match=f"'{key}'"):
            load_model(str(path))


# --- what a run reads, and what its errors may quote ---------------------------------------------

LEAK_CASES = [case for case in CASES if case.id.startswith("leak:")]


@pytest.mark.pipeline
@pytest.mark.parametrize("as_json", [False, True], ids=["text", "json"])
@pytest.mark.parametrize("case", LEAK_CASES, ids=[case.id for case in LEAK_CASES])
def test_a_file_a_model_names_is_never_quoted(case, as_json, tmp_path, capsys, monkeypatch,
                                              registry):
    """A model's cfd = ... may name any file (../../etc/passwd): its errors say what is wrong
    without a byte of it, on stderr and in the JSON error."""
    code, captured = run_case(tmp_path, case, capsys, monkeypatch, as_json=as_json)
    assert code == 2 and "Traceback" not in captured.err
    assert SECRET not in captured.err and SECRET not in captured.out
    if as_json:
        error = json.loads(captured.out)["error"]
        hint = "--valve" if "valve" in case.id else "check-data"
        assert error["exit_code"] == 2 and hint in error["message"]


@pytest.mark.pipeline
def test_a_file_the_user_names_is_quoted(tmp_path, capsys, monkeypatch):
    """The control of the test above: the same files, named directly, are quoted."""
    monkeypatch.chdir(tmp_path)
    for case in LEAK_CASES:
        if "no TOML" in case.id:  # the TOML parser's message quotes nothing anyway
            continue
        name, content = next((name, content) for name, content in case.files.items()
                             if "model.toml" not in name)
        Path(name).write_text(content)
        argv = (["compare", "--model", "cfda", "--valve", name] if name.endswith(".toml")
                else ["check-data", name])
        assert main(argv) == 2
        assert SECRET in capsys.readouterr().err, case.id


def _args(**values):
    import argparse

    return argparse.Namespace(**{"model": None, "maps": None, "data": None, "valve": None,
                                 "effects_file": [], "input": None, "cfd": None,
                                 "sequence": None, **values})


@pytest.mark.parametrize("target", ["surrogate/trained/nn/flow.npz", "surrogate/trained/gp",
                                    "measurements/new_log.csv", "cfd_samples/cfd_samples.csv",
                                    "surrogate/valves/paper_cbv.toml"])
def test_the_shipped_data_is_an_input_of_every_run(target):
    """No command writes over or into what the package ships, whatever its options (checked
    on the guard itself: running a command against the shipped files would risk them)."""
    from surrogate.commands.common import guard_outputs
    from surrogate.core.errors import InputError
    from surrogate.core.outputs import Output

    with pytest.raises(InputError, match="input"):
        guard_outputs(_args(), Output("--out", PROJECT_ROOT / target, "file"))


def test_inputs_are_followed_through_symbolic_links(tmp_path, monkeypatch):
    """An output reached through a link to an input, or into a linked surrogate folder, is an
    input all the same."""
    from surrogate.commands.common import guard_outputs, maps_option
    from surrogate.core.errors import InputError
    from surrogate.core.outputs import Output

    monkeypatch.chdir(tmp_path)
    for name, content in surrogate("nn", "real").items():
        Path(name).parent.mkdir(exist_ok=True)
        Path(name).write_bytes(content)
    Path("linked").symlink_to("real")
    Path("cfd.csv").write_text(CFD)
    Path("alias.csv").symlink_to("cfd.csv")
    Path("model.toml").write_text(model_on_cfd("cfd.csv"))
    with pytest.raises(InputError, match="--out real/flow.npz: lies inside the input folder"):
        guard_outputs(_args(maps=maps_option("./linked")), Output("--out", "real/flow.npz"))
    with pytest.raises(InputError, match="--out alias.csv: that is the input"):
        guard_outputs(_args(model="model.toml"), Output("--out", "alias.csv"))
    guard_outputs(_args(model="model.toml", maps=maps_option("./linked")),
                  Output("--out", "fine.toml"))


def test_a_local_folder_named_like_a_kind_without_a_surrogate_is_no_ambiguity(tmp_path,
                                                                            monkeypatch):
    from surrogate.commands.common import maps_option

    monkeypatch.chdir(tmp_path)
    (tmp_path / "nn").mkdir()
    (tmp_path / "nn" / "notes.txt").write_text("not a surrogate")
    assert maps_option("nn").spec().flow.settings["folder"] == "shipped"
    (tmp_path / "nn" / "surrogate.json").write_text(TRAINED_FILES["nn"]["surrogate.json"].decode())
    from surrogate.core.errors import InputError

    with pytest.raises(InputError, match="ambiguous"):
        maps_option("nn").spec()


def test_training_refuses_an_out_folder_that_holds_its_cfd_samples(tmp_path):
    """``training/train.py --out`` writes one folder per kind: never over what it trains on,
    and it says so before any training."""
    (tmp_path / "nn").mkdir()
    (tmp_path / "nn" / "cfd.csv").write_text(CFD)
    before = snapshot(tmp_path)
    done = subprocess.run([sys.executable, str(PROJECT_ROOT / "training" / "train.py"),
                           "--cfd", "nn/cfd.csv", "--out", ".", "--kinds", "nn"],
                          cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "--out nn" in done.stderr and "holds the input nn/cfd.csv" in done.stderr
    assert snapshot(tmp_path) == before


@pytest.mark.pipeline
@pytest.mark.parametrize("greeting, words", [
    (b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n", "an HTTP server"),
    (b"\xff" * 16, "does not speak Dask's protocol"),
    (b"", "closed the connection"),
    (None, "nothing answered within"),
], ids=["http", "garbage", "closes", "silent"])
def test_a_scheduler_address_where_something_else_listens_is_refused(greeting, words, tmp_path,
                                                                     capsys, monkeypatch):
    """A port where an HTTP server (a Dask dashboard), another protocol or nothing at all
    answers: exit 2 naming the address, no traceback, nothing written (Dask itself read an HTTP
    reply as a 3 EiB frame and failed with MemoryError after a minute)."""
    import socket
    import threading

    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    stop = threading.Event()

    def serve():
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                connection, _ = server.accept()
            except TimeoutError:
                continue
            with connection:
                if greeting is not None:
                    connection.sendall(greeting)
                    if greeting:
                        stop.wait(5)  # keep it open, as a server waiting for more would
                else:
                    stop.wait(5)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        address = f"tcp://127.0.0.1:{port}"
        case = fleet("scheduler: something else", {}, (address, words), "--scheduler", address)
        code, captured = run_case(tmp_path, case, capsys, monkeypatch)
    finally:
        stop.set()
        thread.join()
        server.close()
    assert code == 2 and "Traceback" not in captured.err
    for word in case.words:
        assert word in captured.err, captured.err
