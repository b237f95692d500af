"""Users' own effects: a plain Python function whose parameters are read from its signature.

Like ``lmfit.Model``, the function's keyword arguments with defaults become the effect's
parameters; :func:`custom_effect` declares which stage of the model it acts in, and the units and
bounds of the parameters (defaults and bounds in those units), and turns the function into an
:class:`~surrogate.effects.base.Effect` class::

    # my_effects.py
    from surrogate.effects import custom_effect

    @custom_effect("friction", units={"k": "N"}, bounds={"k": (0.0, 50.0)})
    def cold_seal_friction(state, k=1.0):
        \"\"\"Seal friction that grows as the oil cools below 40 °C.\"\"\"
        return k * (state.fluid.nu / 46e-6) ** 2

Then ``python -m surrogate diagnose --effects-file my_effects.py ...`` offers it next to the
built-in ones, and ``fit --add cold_seal_friction`` adds it; in Python,
``LIBRARY + load_effects_file("my_effects.py")`` is the library with it. The function receives the
state in SI units and its parameters in SI units too (a default of 0.05 "N/bar" arrives as
5e-7 N/Pa). A file may also define :class:`~surrogate.effects.base.Effect` subclasses directly.

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
import traceback
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.input_files import check_input
from ..limits import FORCE
from ..core.units import known_units, to_si
from .base import CATEGORIES, KINDS, Effect, Parameter

_POSITIONAL = {"sensor": 1, "flow": 2, "leakage": 2, "force": 1, "friction": 1}
_HOOKS = {"sensor": "correct_inputs", "flow": "restriction_flow", "leakage": "leakage",
          "force": "force", "friction": "friction"}


def custom_effect(kind: str, *, units: dict[str, str] | None = None,
                  bounds: dict[str, tuple[float, float]] | None = None,
                  title: str | None = None, validity: str = "user-defined",
                  category: str | None = None,
                  penalties: dict[str, float] | None = None):
    """Decorator: turn a function into an :class:`Effect` class (named after the function).

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
    category : str, optional
        One of ``"physics"``, ``"map correction"``, ``"sensor"`` (:data:`.base.CATEGORIES`):
        what the effect says if a diagnosis picks it. Default ``"sensor"`` for a sensor effect,
        ``"physics"`` otherwise.
    penalties : dict, optional
        Parameter name -> w [bar per unit of the parameter], >= 0: every fit of n residuals adds
        n·(w·value)² to its sum of squares, a pull towards 0 that weighs the same whatever the
        log's length. A handed-over shape (:mod:`.handover`) carries the roughness it was
        fitted under this way, so that a fit of its ``scale`` is as cautious as the diagnosis.
    """
    if kind not in KINDS:
        raise InputError(f"custom effect kind {kind!r} is not one of {', '.join(KINDS)}")
    category = category or ("sensor" if kind == "sensor" else "physics")
    if category not in CATEGORIES:
        raise InputError(f"custom effect category {category!r} is not one of "
                         f"{', '.join(CATEGORIES)}")
    units, bounds, penalties = dict(units or {}), dict(bounds or {}), dict(penalties or {})
    for key, weight in penalties.items():
        if isinstance(weight, bool) or not isinstance(weight, (int, float)) \
                or not np.isfinite(weight) or weight < 0:
            raise InputError(f"custom effect penalty of {key!r} is {weight!r}; expected a "
                             "finite number >= 0 [bar per unit of the parameter]")

    def make(function) -> type[Effect]:
        return effect_from_function(function, kind, units, bounds, title, validity, category,
                                    penalties)

    return make


def effect_from_function(function, kind: str, units: dict, bounds: dict, title: str | None,
                         validity: str, category: str = "physics",
                         penalties: dict | None = None) -> type[Effect]:
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
    penalties = dict(penalties or {})
    unknown = (set(units) | set(bounds) | set(penalties)) - {spec.name for spec in specs}
    if unknown:
        raise InputError(f"{where}: units, bounds or penalties for unknown parameter(s) "
                         f"{', '.join(sorted(unknown))}")
    # w [bar per display unit] as a row of L [Pa per SI unit] at one residual
    pulls = np.array([to_si(penalties.get(spec.name, 0.0), "bar")
                      / (to_si(1.0, spec.unit) - to_si(0.0, spec.unit)) for spec in specs])
    doc = inspect.getdoc(function) or ""
    names = [spec.name for spec in specs]
    hook = _HOOKS[kind]

    def call(self, *positional):
        values = {key: self[key] for key in names}
        try:
            result = function(*positional, **values)
        except (KeyboardInterrupt, InputError):
            raise
        except BaseException as error:  # the user's code, sys.exit() included: say where
            raise InputError(f"{where} raised {type(error).__name__}: {error} (called with "
                             f"{_shown(values, specs)})") from None
        return checked_result(name, kind, result, positional, values, specs)

    def penalty(self, samples: int) -> np.ndarray | None:
        if not pulls.any():
            return None
        return np.diag(np.sqrt(samples) * pulls)[pulls > 0]

    attributes = {
        "name": name, "kind": kind, "category": category, "title": title or (doc.splitlines()[0] if doc else name),
        "parameter_specs": tuple(specs), "validity": validity, "__doc__": doc or name,
        "__module__": function.__module__, hook: call, "custom": True, "function": function,
        "source": function.__module__, "penalty": penalty,
    }
    return type(f"Custom_{name}", (Effect,), attributes)


def _shown(values: dict, specs: list[Parameter]) -> str:
    """Parameter values in their display units, for messages."""
    return ", ".join(f"{spec.name} = {values[spec.name] / to_si(1.0, spec.unit):.4g} {spec.unit}"
                     if spec.unit != "degC" else f"{spec.name} = {values[spec.name]:.4g} K"
                     for spec in specs) or "no parameters"


def _finite_inputs(kind: str, positional: tuple, shape: tuple) -> np.ndarray:
    """Where the arrays a custom effect of ``kind`` was called with are all finite (the array
    of ``dp`` or ``q`` and the state's)."""
    state = positional[-1]
    arrays = [getattr(state, field) for field in ("u", "q", "p_B", "p_P", "temperature")]
    if kind in ("force", "friction"):
        arrays += [state.p_L]
    else:
        arrays += [positional[0]]
    finite = np.ones(shape, bool)
    for array in arrays:
        finite &= np.broadcast_to(np.isfinite(np.asarray(array, float)), shape)
    return finite


def checked_result(name: str, kind: str, result, positional: tuple, values: dict,
                   specs: list[Parameter]):
    """A custom effect's return value, if it is what its kind promises; else InputError.

    Sensor effects return operating points of the same number; the others an array (or a scalar)
    of finite floats, one per state, with friction >= 0 and forces no larger than a hydraulic
    force can be (:data:`surrogate.limits.FORCE`).
    """
    where = f"custom effect {name!r} ({kind}, called with {_shown(values, specs)})"
    reference = positional[0]
    if kind == "sensor":
        from ..points import OperatingPoints

        if not isinstance(result, OperatingPoints) or len(result) != len(reference):
            raise InputError(f"{where} must return OperatingPoints of the {len(reference)} points "
                             f"it was given (e.g. points.replace(p_P=...)), got "
                             f"{type(result).__name__}")
        for field in ("q", "p_P", "p_B", "temperature"):
            if not np.all(np.isfinite(getattr(result, field))):
                raise InputError(f"{where} returned non-finite {field}")
        return result
    shape = np.shape(reference.u if kind in ("force", "friction") else reference)
    try:
        array = np.asarray(result, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{where} must return numbers (an array of {shape[0] if shape else 1} "
                         f"values), got {type(result).__name__} {str(result)[:40]!r}") from None
    if array.shape not in ((), shape):
        raise InputError(f"{where} must return one value per state (shape {shape}) or a scalar, "
                         f"got shape {array.shape}")
    # a state the solver has no value for yet (a pressure drop of a sample whose flow split
    # failed) may give NaN: only a non-finite value from finite inputs is the function's fault
    bad = ~np.isfinite(array) & _finite_inputs(kind, positional, shape)
    if bad.any():
        raise InputError(f"{where} returned {int(bad.sum())} non-finite value(s) (NaN or inf) "
                         f"of {array.size} from finite inputs; guard the function where it "
                         "divides or takes logs")
    unit = "m^3/s" if kind in ("flow", "leakage") else "N"
    if kind in ("friction", "leakage", "flow") and np.any(array < 0):
        meaning = {"friction": "a half-width of the friction band, >= 0 N",
                   "leakage": "a flow bypassing the restriction, >= 0 m^3/s",
                   "flow": "the flow through the restriction, >= 0 m^3/s"}[kind]
        raise InputError(f"{where} returned {float(np.nanmin(array)):.4g} {unit}; it must be "
                         f"{meaning} (bound its parameters in @custom_effect(bounds=...))")
    if kind in ("force", "friction") and np.any(np.abs(array) > FORCE.high):
        raise InputError(f"{where} returned {float(np.nanmax(np.abs(array))):.4g} N, beyond any "
                         f"hydraulic force on a valve piston ({FORCE.describe()})")
    return array


def load_effects_file(path: str | Path):
    """The effects a user's file defines, as an :class:`~.library.EffectLibrary`.

    The file is the user's own Python code, run because they asked for it (``--effects-file``);
    its effects are the functions decorated with :func:`custom_effect` and any
    :class:`~.base.Effect` subclasses it defines. Nothing outside the returned library changes.
    """
    from .library import EffectLibrary

    path = Path(path)
    if not path.exists() and not path.is_symlink():
        raise InputError(f"{path}: effects file not found")
    check_input(path, "an effects file (Python)")
    if path.suffix != ".py":
        # importlib finds no loader for another suffix and would fail without saying why
        raise InputError(f"{path}: an effects file is Python code; expected a .py file, not "
                         f"{path.suffix or 'a file without a suffix'}")
    module_name = f"surrogate_user_effects_{abs(hash(path.resolve()))}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # while it runs: dataclasses and pickling look it up
    try:
        spec.loader.exec_module(module)
    except InputError as error:
        raise InputError(f"{path}: {error}") from None
    except KeyboardInterrupt:
        raise
    except BaseException as error:  # the user's code, sys.exit() included: say where it failed
        frames = traceback.extract_tb(error.__traceback__)
        line = next((f", line {frame.lineno}" for frame in reversed(frames)
                     if Path(frame.filename).resolve() == path.resolve()), "")
        raise InputError(f"{path}{line}: failed to load ({type(error).__name__}: "
                         f"{error})") from None
    finally:
        sys.modules.pop(module_name, None)
    found = [value for value in vars(module).values()
             if isinstance(value, type) and issubclass(value, Effect) and value.name
             and value.__module__ == module_name]
    if not found:
        raise InputError(f"{path}: defines no effect; decorate a function with "
                         "@custom_effect(kind, ...) (see surrogate.effects.custom)")
    for cls in found:
        cls.source = str(path)
    try:
        return EffectLibrary(found)
    except InputError as error:
        raise InputError(f"{path}: {error}") from None
