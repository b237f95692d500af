"""A fitted shape handed over as code: an effects file the user reads, edits and tests.

A shape a diagnosis found (:mod:`.shapes`) is a hypothesis, not a finding with a name. The user
needs it in a form they can own: a ``@custom_effect`` file (:mod:`.custom`) holding the fitted
shape as a table in display units and one parameter, ``scale``, that a fit sets (about 1 when the
shape is right), under the roughness penalty the shape was fitted with (:func:`roughness_pull`). Added with ``--effects-file FILE --add NAME`` to ``fit`` or ``workflow``, it
reproduces the shape-free term's gain with a single parameter; the user can then replace the
table by a formula of their own (a spring with a kink, a detent) and watch the error.
"""

from __future__ import annotations

import ast
import keyword
import re
import textwrap
import unicodedata
from pathlib import Path

import numpy as np

from ..core.outputs import atomic_file
from ..core.units import to_si
from .shapes import ShapeFreeEffect

#: table rows written: enough that linear interpolation follows a cubic spline to well below
#: its standard error
TABLE_POINTS = 81

_SIGNATURES = {"force": "state", "friction": "state", "leakage": "dp, state", "flow": "q, state"}


def effect_name(effect: ShapeFreeEffect, suffix: str = "") -> str:
    """A Python identifier for the handed-over effect: ``found_`` + the shape's name."""
    base = "found_" + effect.name.removeprefix("shape_")
    return re.sub(r"\W", "_", base + (f"_{suffix}" if suffix else ""))


def effect_source(effect: ShapeFreeEffect, *, name: str | None = None, origin: str = "",
                  note: str = "") -> str:
    """The source of an effects file reproducing ``effect``'s fitted shape.

    Parameters
    ----------
    effect : ShapeFreeEffect
        The fitted shape-free effect.
    name : str, optional
        The effect's name in the file (default :func:`effect_name`).
    origin : str
        Where it was found (the bench log, the model), for the file's docstring.
    note : str
        What else to say about it (its gain, its look-alikes, a library term close to it).
    """
    name = name or effect_name(effect)
    if not name.isidentifier() or keyword.iskeyword(name):
        raise ValueError(f"{name!r} is not a Python name an effects file can define")
    variable = effect.variable
    x, values = effect.table(TABLE_POINTS)
    x_unit, value_unit = variable.unit, effect.value_unit
    x_factor = float(to_si(1.0, x_unit) - to_si(0.0, x_unit))
    value_factor = float(to_si(1.0, value_unit) - to_si(0.0, value_unit))
    if effect.rising:  # rounding must not make a rising table fall or go negative
        values = np.maximum.accumulate(np.maximum(values, 0.0))
    shape = (f"scale * np.interp({variable.source} / {x_factor!r}, X, VALUES) "
             f"* {value_factor!r}")
    bounds = (0.0, 3.0)
    pull = roughness_pull(effect)
    title = effect.title.replace(", of free shape", ", as found")
    doc = [f"{title[0].upper()}{title[1:]}."]
    if origin:
        doc.append(f"Found by cbv-surrogate's diagnosis on {origin}.")
    if note:
        doc.append(note)
    # the origin (a file name) and the note (names of runs and effects) come from the user's
    # inputs: as docstring text they are escaped, so that no name can end the string
    doc = [_docstring_text(paragraph) for paragraph in doc]
    doc.append(f"The table is the fitted shape: {variable.label} [{x_unit}] against the "
               f"{effect.quantity} [{value_unit}], linear between rows and held beyond them. "
               "scale = 1 reproduces it; a fit of scale says how much of it the data want. "
               "Replace the table by a formula of your own to test a physical explanation.")
    if pull > 0:
        doc.append("ROUGHNESS is the roughness penalty the shape was fitted under, carried "
                   "along scale: it pulls scale towards 0 as the diagnosis's fit pulled the "
                   "shape towards a straight line, so that a refit without some runs is as "
                   "cautious as the diagnosis's held-out check was. Set it to 0 to let the "
                   "data alone set scale.")
    docstring = "\n\n".join(textwrap.fill(paragraph, 95, initial_indent="    ",
                                          subsequent_indent="    ") for paragraph in doc)
    return checked_source(f'''"""{textwrap.fill(doc[0], 95)}

Use it:

    python -m surrogate fit --model MODEL --data LOG --effects-file {name}.py \\
        --add {name} --out fitted
    python -m surrogate workflow --data LOG --effects-file {name}.py --out DIR
"""

import numpy as np

from surrogate.effects import custom_effect

#: {variable.label} [{x_unit}]
X = np.array({_numbers(x)})
#: the {effect.quantity} there [{value_unit}]
VALUES = np.array({_numbers(values)})
#: a fit adds n·(ROUGHNESS·scale)² to its sum of squares over n residuals [bar]
ROUGHNESS = {pull:.6g}


@custom_effect({effect.kind!r}, units={{"scale": "1"}}, bounds={{"scale": {bounds!r}}},
               penalties={{"scale": ROUGHNESS}}, category={effect.category!r},
               title={title!r})
def {name}({_SIGNATURES[effect.kind]}, scale=0.0):
    """{docstring.strip()}
    """
    return {effect.formula.format(shape=f"({shape})")}
''')


def _docstring_text(text: str) -> str:
    """``text`` as it may stand in a triple-quoted docstring: backslashes and quotes escaped
    (no quote can close the string, no escape can start), control and format characters
    (newlines, ANSI escapes, bidirectional overrides) written as their escapes."""
    text = text.replace("\\", "\\\\").replace('"', '\\"')
    return "".join(character if unicodedata.category(character)[0] != "C"
                   else character.encode("unicode_escape").decode("ascii").replace(
                       "\\", "\\\\")
                   for character in text)


#: what an effects file the package writes may hold: literals, arithmetic, the names below,
#: attributes of them and calls; no other statement than its imports, assignments, the decorated
#: function and its return
_NODES = (ast.Module, ast.Expr, ast.Import, ast.ImportFrom, ast.alias, ast.Assign,
          ast.FunctionDef, ast.arguments, ast.arg, ast.Return, ast.Constant, ast.Name,
          ast.Load, ast.Store, ast.Attribute, ast.Call, ast.keyword, ast.List, ast.Tuple,
          ast.Dict, ast.BinOp, ast.UnaryOp, ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow,
          ast.USub, ast.UAdd)
_MODULES = {"numpy", "surrogate.effects"}


def checked_source(source: str) -> str:
    """``source`` when it is an effects file of the expected form, else ValueError.

    Every file the package writes as Python passes here: a module docstring, the imports of
    numpy and ``custom_effect``, constants, and one decorated function whose body is a docstring
    and a return of arithmetic on its arguments and those constants. Nothing an input carried
    (a file name, a run id) can add a statement, a call to another function or an import.
    """
    tree = ast.parse(source)
    assigned = {target.id for node in tree.body if isinstance(node, ast.Assign)
                for target in node.targets if isinstance(target, ast.Name)}
    functions = [node for node in tree.body if isinstance(node, ast.FunctionDef)]
    allowed = {"np", "custom_effect", *assigned,
               *(arg.arg for function in functions for arg in function.args.args)}
    for node in ast.walk(tree):
        if not isinstance(node, _NODES):
            raise ValueError(f"an effects file may not hold {type(node).__name__} "
                             f"(line {getattr(node, 'lineno', '?')})")
        if isinstance(node, ast.Name) and node.id not in allowed | {f.name for f in functions}:
            raise ValueError(f"an effects file may not name {node.id!r}")
        if isinstance(node, ast.Attribute) and node.attr.startswith("_"):
            raise ValueError(f"an effects file may not reach {node.attr!r}")
        if isinstance(node, ast.Import | ast.ImportFrom):
            names = [node.module] if isinstance(node, ast.ImportFrom) else \
                [alias.name for alias in node.names]
            if not set(names) <= _MODULES:
                raise ValueError(f"an effects file may not import {', '.join(names)}")
    statements = [type(node) for node in tree.body]
    if statements.count(ast.FunctionDef) != 1 or statements.count(ast.Expr) != 1:
        raise ValueError("an effects file holds a docstring and one function")
    (function,) = functions
    if [type(node) for node in function.body] != [ast.Expr, ast.Return]:
        raise ValueError("an effects file's function holds a docstring and a return")
    return source


def roughness_pull(effect: ShapeFreeEffect) -> float:
    """w [bar]: the shape's roughness penalty at its fitted coefficients c, per residual,
    ‖L·c‖ with L = ``effect.penalty(1)``, so that the penalty on ``scale``·c is n·(w·scale)²
    over n residuals (0 for a shape fitted without one)."""
    matrix = effect.penalty(1)
    if matrix is None:
        return 0.0
    values = np.array([parameter.value for parameter in effect.params.values()])
    names = set(effect.coefficient_names())
    along = np.array([name in names for name in effect.params], float)
    return float(np.linalg.norm(matrix @ (values * along))) / float(to_si(1.0, "bar"))


def write_effect_file(effect: ShapeFreeEffect, path: str | Path, **options) -> Path:
    """Write :func:`effect_source` to ``path`` (all at once); return the path."""
    path = Path(path)
    options.setdefault("name", path.stem if path.stem.isidentifier()
                       and not keyword.iskeyword(path.stem) else None)
    with atomic_file(path) as stream:
        stream.write(effect_source(effect, **options))
    return path


def hand_over(effects, folder: str | Path, *, origin: str = "",
              notes: dict[str, str] | None = None) -> dict[str, str]:
    """Write one effects file per shape-free effect of ``effects`` into ``folder`` (a staging
    folder: the caller publishes it whole); return {effect name: file name}. Other effects are
    skipped: a library or custom effect already has its code."""
    notes = notes or {}
    written = {}
    for effect in effects:
        if not isinstance(effect, ShapeFreeEffect):
            continue
        name = effect_name(effect)
        write_effect_file(effect, Path(folder) / f"{name}.py", origin=origin,
                          note=notes.get(effect.name, ""))
        written[effect.name] = f"{name}.py"
    return written


def _numbers(values: np.ndarray) -> str:
    """A list literal of ``values``, seven to a line, with six significant digits."""
    items = [f"{float(value):.6g}" for value in values]
    lines = [", ".join(items[i:i + 7]) for i in range(0, len(items), 7)]
    return "[" + ",\n    ".join(lines) + "]"


__all__ = ["checked_source", "effect_name", "effect_source", "hand_over", "roughness_pull", "write_effect_file"]
