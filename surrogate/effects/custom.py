"""Users' own effects: a plain Python function whose parameters are read from its signature.

Like ``lmfit.Model``, the function's keyword arguments with defaults become the effect's
parameters; :func:`custom_effect` declares which stage of the model it acts in, and the units and
bounds of the parameters (defaults and bounds in those units)::

    # my_effects.py
    from surrogate.effects import custom_effect

    @custom_effect("friction", units={"k": "N"}, bounds={"k": (0.0, 50.0)})
    def cold_seal_friction(state, k=1.0):
        \"\"\"Seal friction that grows as the oil cools below 40 °C.\"\"\"
        return k * (state.fluid.nu / 46e-6) ** 2

Then ``python -m surrogate diagnose --effects-file my_effects.py ...`` offers it next to the
built-in ones, and ``fit --add cold_seal_friction`` adds it. The function receives the state in SI
units and its parameters in SI units too (a default of 0.05 "N/bar" arrives as 5e-7 N/Pa).

What the function gets and returns, by kind:

=========  ================================  ==============================================
kind       called as                         returns
=========  ================================  ==============================================
sensor     ``f(points, **params)``           corrected ``OperatingPoints``
flow       ``f(q, state, **params)``         flow the restriction's map sees [m^3/s]
leakage    ``f(dp, state, **params)``        flow bypassing the restriction [m^3/s]
force      ``f(state, **params)``            extra opening force [N]
friction   ``f(state, **params)``            extra friction half-width [N], >= 0
=========  ================================  ==============================================

``state`` is a :class:`~surrogate.effects.base.BalanceState` (force, friction) or a
:class:`~surrogate.effects.base.FlowState` (flow, leakage).
"""

from __future__ import annotations

import importlib.util
import inspect
import sys
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..units import known_units, to_si
from .base import KINDS, Effect, Parameter

_POSITIONAL = {"sensor": 1, "flow": 2, "leakage": 2, "force": 1, "friction": 1}
_HOOKS = {"sensor": "correct_inputs", "flow": "restriction_flow", "leakage": "leakage",
          "force": "force", "friction": "friction"}


def custom_effect(kind: str, *, units: dict[str, str] | None = None,
                  bounds: dict[str, tuple[float, float]] | None = None,
                  title: str | None = None, validity: str = "user-defined"):
    """Decorator: turn a function into an :class:`Effect` class and register it.

    Parameters
    ----------
    kind : str
        One of ``"sensor"``, ``"flow"``, ``"leakage"``, ``"force"``, ``"friction"``.
    units : dict, optional
        Parameter name -> unit (default ``"1"``); defaults and bounds are in these units.
    bounds : dict, optional
        Parameter name -> (min, max) in its unit (default unbounded).
    title : str, optional
        Short name in reports; default the docstring's first line.
    validity : str
        Where the term holds.
    """
    if kind not in KINDS:
        raise InputError(f"custom effect kind {kind!r} is not one of {', '.join(KINDS)}")
    units, bounds = dict(units or {}), dict(bounds or {})

    def make(function):
        from . import register

        cls = effect_from_function(function, kind, units, bounds, title, validity)
        register(cls)
        return function

    return make


def effect_from_function(function, kind: str, units: dict, bounds: dict, title: str | None,
                         validity: str) -> type[Effect]:
    """The :class:`Effect` subclass behind :func:`custom_effect`."""
    name = function.__name__
    where = f"custom effect {name!r}"
    signature = inspect.signature(function)
    arguments = list(signature.parameters.values())
    if len(arguments) < _POSITIONAL[kind]:
        raise InputError(f"{where}: a {kind} effect is called with {_POSITIONAL[kind]} "
                         "positional argument(s) before its parameters")
    specs = []
    for argument in arguments[_POSITIONAL[kind]:]:
        if argument.default is inspect.Parameter.empty or isinstance(argument.default, bool) \
                or not isinstance(argument.default, (int, float)):
            raise InputError(f"{where}: parameter {argument.name!r} needs a numeric default "
                             "(its starting value)")
        unit = units.get(argument.name, "1")
        if unit not in known_units():
            raise InputError(f"{where}: unknown unit {unit!r} for {argument.name!r}; known: "
                             f"{', '.join(known_units())}")
        low, high = bounds.get(argument.name, (-np.inf, np.inf))
        low = -np.inf if not np.isfinite(low) else to_si(low, unit)
        high = np.inf if not np.isfinite(high) else to_si(high, unit)
        default = to_si(argument.default, unit)
        if not low <= default <= high:
            raise InputError(f"{where}: default of {argument.name!r} lies outside its bounds")
        specs.append(Parameter(argument.name, default, unit, min=low, max=high,
                               description=f"parameter of {name}"))
    unknown = (set(units) | set(bounds)) - {spec.name for spec in specs}
    if unknown:
        raise InputError(f"{where}: units or bounds for unknown parameter(s) "
                         f"{', '.join(sorted(unknown))}")
    doc = inspect.getdoc(function) or ""
    names = [spec.name for spec in specs]
    hook = _HOOKS[kind]

    def call(self, *positional):
        result = function(*positional, **{key: self[key] for key in names})
        if kind == "sensor":
            return result
        return np.asarray(result, dtype=float)

    attributes = {
        "name": name, "kind": kind, "title": title or (doc.splitlines()[0] if doc else name),
        "parameter_specs": tuple(specs), "validity": validity, "__doc__": doc or name,
        "__module__": function.__module__, hook: call, "custom": True, "function": function,
    }
    return type(f"Custom_{name}", (Effect,), attributes)


def load_effects_file(path: str | Path) -> list[str]:
    """Import a user's effects file; return the names of the effects it registered.

    The file is the user's own Python code, run because they asked for it (``--effects-file``).
    """
    from . import REGISTRY

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: effects file not found")
    before = set(REGISTRY)
    module_name = f"surrogate_user_effects_{abs(hash(path.resolve()))}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    try:
        spec.loader.exec_module(module)
    except InputError as error:
        raise InputError(f"{path}: {error}") from None
    except Exception as error:  # the user's code: say where it failed
        raise InputError(f"{path}: failed to load ({type(error).__name__}: {error})") from None
    added = [name for name in REGISTRY if name not in before]
    if not added:
        raise InputError(f"{path}: defines no effect; decorate a function with "
                         "@custom_effect(kind, ...) (see surrogate.effects.custom)")
    return added
