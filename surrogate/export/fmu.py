"""The fitted valve as an FMU: FMI 2.0 co-simulation, standalone, generic C plus the tables.

Design: the valve is tabulated with the package's own solver (:mod:`.tables`), so every map
kind and every effect, a custom one included, leaves the same way; the FMU is one C file that
knows nothing of maps or effects (``fmu_valve.c``: cubic-convolution lookups and the friction
play as internal state) and reads the tables from ``resources/tables.bin`` when it is
instantiated. The other route, C generated per map kind and per effect, would have to
reimplement every map (a GP's kernel, a network, a grid of monotone cubics) and could not take a
user's Python effect at all.

Contents of ``<name>.fmu`` (a zip):

* ``modelDescription.xml``: inputs q [m3/s], p_B [Pa], p_P [Pa], T [K]; outputs p_L [Pa],
  Δp [Pa], u [m]. SI, the units a Modelica or Simscape model connects to without conversion,
  declared with display units (L/min, bar, °C, mm) for the tools that show them;
* ``sources/fmu_valve.c``: the C, which an importer may compile itself;
* ``binaries/linux64/<id>.so``: compiled at export time with the system's C compiler, when one
  is found (else the FMU is source-only, and the export says so);
* ``resources/tables.bin`` (the tables, single precision) and ``resources/manifest.json``
  (what the tables are of, the grid, and what was left out: sensor and per-run terms);
* ``documentation/index.html``: the same in words.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import uuid
import zipfile
from dataclasses import dataclass
from datetime import datetime, timezone
from importlib import resources
from pathlib import Path

import numpy as np

from .. import __version__
from .tables import EDGE_TABLES, TableGrid, ValveTables

#: the axis codes of ``tables.bin`` (the C's AXIS_*)
AXIS_CODES = {"q": 0, "u": 1, "p_B": 2, "p_P": 3, "temperature": 4}
#: the C source, shipped with the package
SOURCE = "fmu_valve.c"
PLATFORM = "linux64"

#: (name, value reference, causality, unit, display unit, description); no unit: an Integer
VARIABLES = (
    ("q", 0, "input", "m3/s", "L/min", "flow through the valve, load to back port"),
    ("p_B", 1, "input", "Pa", "bar", "back pressure (gauge)"),
    ("p_P", 2, "input", "Pa", "bar", "pilot pressure (gauge)"),
    ("T", 3, "input", "K", "degC", "oil temperature"),
    ("p_L", 4, "output", "Pa", "bar", "load pressure (gauge), p_B + dp"),
    ("dp", 5, "output", "Pa", "bar", "pressure drop p_L - p_B"),
    ("u", 6, "output", "m", "mm", "piston opening (friction play as internal state)"),
    ("outside", 7, "output", None, None,
     "inputs beyond the tables' range, held at its edge: 1 q (above the highest tabulated flow "
     "or negative), 2 p_B, 4 p_P, 8 T, summed; 0 inside"),
)
#: unit -> (exponents of kg, m, s, K), display unit, factor, offset (display = factor*SI+offset)
UNITS = {"m3/s": ({"m": 3, "s": -1}, "L/min", 60000.0, 0.0),
         "Pa": ({"kg": 1, "m": -1, "s": -2}, "bar", 1e-5, 0.0),
         "K": ({"K": 1}, "degC", 1.0, -273.15),
         "m": ({"m": 1}, "mm", 1000.0, 0.0)}


@dataclass(frozen=True)
class FmuResult:
    """What :func:`write_fmu` wrote.

    Attributes
    ----------
    path : Path
        The FMU.
    compiled : bool
        Whether it holds a linux64 binary.
    compiler : str
        The compiler used, or why there is no binary.
    """

    path: Path
    compiled: bool
    compiler: str


def model_identifier(name: str) -> str:
    """A C identifier from a model's name (``cfda-gp+friction_viscous`` ->
    ``cfda_gp_friction_viscous``), at most 60 characters."""
    identifier = "".join(c if c.isalnum() else "_" for c in name).strip("_") or "valve"
    if identifier[0].isdigit():
        identifier = "valve_" + identifier
    return identifier[:60]


def tables_bytes(tables: ValveTables) -> bytes:
    """``tables.bin``: the five tables as the C reads them (little-endian; see fmu_valve.c)."""
    parts = [b"CBVTAB01", struct.pack("<i", len(tables.tables))]
    for table in tables.tables:
        parts.append(struct.pack("<i", len(table.axes)))
        for axis, nodes in zip(table.axes, table.nodes):
            parts.append(struct.pack("<ii", AXIS_CODES[axis], len(nodes)))
        for nodes in table.nodes:
            parts.append(np.asarray(nodes, "<f8").tobytes())
        parts.append(np.ascontiguousarray(table.values, dtype="<f4").tobytes())
    return b"".join(parts)


def find_compiler() -> str | None:
    """The system's C compiler: $CC, else cc, gcc or clang on the PATH; None if none."""
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return shutil.which(name)
    return None


def compile_binary(source: Path, target: Path, compiler: str) -> str | None:
    """Compile ``source`` into the shared library ``target``; None on success, else the
    compiler's complaint (its first lines)."""
    command = [compiler, "-shared", "-fPIC", "-O2", "-std=c99", "-o", str(target), str(source),
               "-lm"]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=300)
    except (OSError, subprocess.TimeoutExpired) as error:
        return str(error)
    if done.returncode != 0:
        return "\n".join((done.stderr or done.stdout).strip().splitlines()[:8])
    return None


def model_description(identifier: str, guid: str, tables: ValveTables, description: str,
                      start: dict[str, float]) -> str:
    """modelDescription.xml (FMI 2.0, co-simulation)."""
    from xml.sax.saxutils import escape  # here: it imports urllib, 0.07 s of every command

    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    units = []
    for unit, (exponents, display, factor, offset) in UNITS.items():
        base = " ".join(f'{key}="{value}"' for key, value in exponents.items())
        units.append(f'    <Unit name="{unit}">\n      <BaseUnit {base}/>\n'
                     f'      <DisplayUnit name="{display}" factor="{factor!r}" '
                     f'offset="{offset!r}"/>\n    </Unit>')
    variables = []
    for name, reference, causality, unit, display, meaning in VARIABLES:
        if causality == "input":
            attributes = f'start="{start[name]!r}"'
            variability = 'variability="continuous"'
        else:
            attributes = ""
            variability = ('variability="continuous"' if unit else 'variability="discrete"')
            variability += ' initial="calculated"'
        kind = (f'<Real unit="{unit}" displayUnit="{display}" {attributes}/>' if unit
                else "<Integer/>")
        variables.append(
            f'    <ScalarVariable name="{name}" valueReference="{reference}" '
            f'causality="{causality}" {variability} description="{escape(meaning)}">\n'
            f'      {kind}\n'
            f'    </ScalarVariable>')
    inputs = " ".join(str(index + 1) for index, v in enumerate(VARIABLES) if v[2] == "input")
    outputs = "\n".join(f'      <Unknown index="{index + 1}" dependencies="{inputs}"/>'
                        for index, v in enumerate(VARIABLES) if v[2] == "output")
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="{escape(tables.model, {'"': '&quot;'})}"
  guid="{guid}" description="{escape(description, {'"': '&quot;'})}"
  generationTool="cbv-surrogate {__version__}" generationDateAndTime="{stamp}"
  variableNamingConvention="flat" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="{identifier}" canHandleVariableCommunicationStepSize="true"
    canInterpolateInputs="false" canBeInstantiatedOnlyOncePerProcess="false"
    canGetAndSetFMUstate="false" canSerializeFMUstate="false"
    providesDirectionalDerivative="false">
    <SourceFiles>
      <File name="{SOURCE}"/>
    </SourceFiles>
  </CoSimulation>
  <UnitDefinitions>
{chr(10).join(units)}
  </UnitDefinitions>
  <DefaultExperiment startTime="0.0" stepSize="0.01"/>
  <ModelVariables>
{chr(10).join(variables)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{outputs}
    </Outputs>
    <InitialUnknowns>
{outputs}
    </InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def _documentation(tables: ValveTables, manifest: dict) -> str:
    from xml.sax.saxutils import escape  # as model_description's

    left_out = "".join(f"<li><code>{escape(name)}</code>: {escape(why)}</li>"
                       for name, why in tables.left_out.items()) or "<li>nothing</li>"
    rows = "".join(f"<tr><td>{name}</td><td>{causality}</td><td>"
                   f"{f'{unit} (shown in {display})' if unit else 'integer'}"
                   f"</td><td>{escape(meaning)}</td></tr>"
                   for name, _, causality, unit, display, meaning in VARIABLES)
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{escape(tables.model)}"
            f"</title></head><body><h1>{escape(tables.model)}: a counterbalance valve</h1>"
            "<p>A quasi-static valve exported by cbv-surrogate: the fitted model's valve physics "
            "as tables over the inputs, interpolated in C, with Coulomb friction as a play "
            "(internal state: the piston's opening). Each communication step is one update of "
            "the play for the inputs set at its start; outputs answer the inputs set now. "
            "The piston starts closed. Inputs beyond the tables' range are held at its edge; "
            "the output <code>outside</code> says which, and the logger warns when one leaves "
            "it.</p>"
            f"<table border='1'><tr><th>variable</th><th>causality</th><th>unit</th>"
            f"<th>meaning</th></tr>{rows}</table>"
            f"<h2>Left out</h2><ul>{left_out}</ul>"
            f"<h2>Tables</h2><pre>{escape(json.dumps(manifest['grid'], indent=2))}</pre>"
            f"<p>Play: {escape(manifest['play'])}</p>"
            f"<p>Interpolation: {escape(manifest['interpolation'])}</p></body></html>\n")


def write_fmu(tables: ValveTables, grid: TableGrid, path: Path, extra: dict | None = None,
              compiler: str | None = "auto", progress=None) -> FmuResult:
    """Write ``tables`` as the FMU ``path`` (whose folder the caller stages).

    Parameters
    ----------
    tables : ValveTables
    grid : TableGrid
        The grid they were made on, for the manifest.
    path : Path
        The ``.fmu`` file to write.
    extra : dict, optional
        More for ``resources/manifest.json`` (the resolution error, the source model).
    compiler : str or None
        The C compiler; "auto" looks for one (:func:`find_compiler`), None writes a
        source-only FMU.
    progress : callable, optional
        Told what is being done.
    """
    progress = progress or (lambda message: None)
    identifier = model_identifier(tables.model)
    data = tables_bytes(tables)
    guid = "{" + str(uuid.UUID(hashlib.sha256(data).hexdigest()[:32])) + "}"
    manifest = tables.manifest(grid) | (extra or {}) | {
        "fmu": {"fmi_version": "2.0", "kind": "co-simulation", "model_identifier": identifier,
                "units": "SI: q [m3/s], p_B, p_P, p_L, dp [Pa], T [K], u [m]; display units "
                         "L/min, bar, degC, mm are declared",
                "state": "the piston's opening u and the ratio r of the play (see play)"}}
    start = {"q": float(np.sqrt(grid.q[0] * grid.q[1])), "p_B": float(np.mean(grid.p_B)),
             "p_P": float(np.mean(grid.p_P)), "T": float(np.mean(grid.temperature))}
    description = (f"counterbalance valve {tables.model}, tabulated by cbv-surrogate; "
                   f"left out: {', '.join(tables.left_out) or 'nothing'}")
    source = resources.files("surrogate.export").joinpath(SOURCE).read_text()
    compiled, used = False, "no C compiler found (looked for $CC, cc, gcc, clang)"
    with tempfile.TemporaryDirectory(prefix="cbv-fmu-") as work:
        work = Path(work)
        binary = None
        if compiler == "auto":
            compiler = find_compiler()
        if compiler is not None:
            (work / SOURCE).write_text(source)
            binary = work / f"{identifier}.so"
            progress(f"compiling the FMU's binary with {compiler}")
            problem = compile_binary(work / SOURCE, binary, compiler)
            if problem is None:
                compiled, used = True, compiler
            else:
                used = f"{compiler} failed: {problem}"
                binary = None
        with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as fmu:
            fmu.writestr("modelDescription.xml",
                         model_description(identifier, guid, tables, description, start))
            fmu.writestr(f"sources/{SOURCE}", source)
            fmu.writestr("resources/tables.bin", data)
            fmu.writestr("resources/manifest.json",
                         json.dumps(manifest, indent=2, allow_nan=False) + "\n")
            fmu.writestr("documentation/index.html", _documentation(tables, manifest))
            if binary is not None:
                fmu.write(binary, f"binaries/{PLATFORM}/{identifier}.so")
    return FmuResult(path, compiled, used)


__all__ = ["EDGE_TABLES", "FmuResult", "find_compiler", "model_identifier", "write_fmu"]


def print_log_message(component, instance: bytes, status: int, category: bytes,
                      message: bytes) -> None:
    """The FMU's log messages on stderr (FMPy's logger callback signature)."""
    print(f"{instance.decode(errors='replace')} [{category.decode(errors='replace')}] "
          f"{message.decode(errors='replace')}", file=sys.stderr)


def simulate_log(fmu, points, runs: np.ndarray, output: str = "dp", logger=None) -> np.ndarray:
    """The FMU's ``output`` [SI; ``outside``: its flags] at every sample of ``points``, each
    run simulated in FMPy (the export extra's) from rest. A communication step commits the play
    for the inputs set at its start, so the output recorded at t_(k+1) answers sample k.
    ``logger``: FMPy's logger callback (component, instance, status, category, message)."""
    from fmpy import extract, read_model_description, simulate_fmu

    # always a logger of our own: FMPy's native proxy keeps pointing at the last logger it was
    # given, so a caller's logger that has since been collected would crash FMPy's default
    logger = logger or print_log_message
    description = read_model_description(fmu)
    folder = extract(fmu)
    found = np.full(len(points), np.nan)
    for run in dict.fromkeys(runs):
        index = np.flatnonzero(runs == run)
        step = 0.01
        signals = np.zeros(len(index), dtype=[("time", float), ("q", float), ("p_B", float),
                                              ("p_P", float), ("T", float)])
        signals["time"] = np.arange(len(index)) * step
        signals["q"], signals["p_B"] = points.q[index], points.p_B[index]
        signals["p_P"], signals["T"] = points.p_P[index], points.temperature[index]
        result = simulate_fmu(folder, model_description=description, start_time=0.0,
                              stop_time=len(index) * step, output_interval=step,
                              input=signals, output=[output], logger=logger)
        found[index] = result[output][1:len(index) + 1]
    return found
