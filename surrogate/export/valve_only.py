"""The fitted model's valve physics: what leaves the workbench when the valve does.

A model fitted to a bench log may hold terms that belong to that bench, not to the valve: sensor
corrections (a transducer offset, a flowmeter gain) and terms with a parameter per bench run.
A system simulation feeds the valve true pressures and flows, so an export leaves those terms
out and says which (:class:`ValvePhysics`).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..core.errors import InputError
from ..model import ValveModel


@dataclass(frozen=True)
class ValvePhysics:
    """The model to export and the terms left out of it.

    Attributes
    ----------
    model : ValveModel
        The fitted model without its bench terms.
    left_out : dict of str to str
        Each term left out, with why.
    """

    model: ValveModel
    left_out: dict[str, str]


def valve_physics(model: ValveModel, source: str = "the model") -> ValvePhysics:
    """``model`` without its sensor terms and per-run terms.

    Raises
    ------
    InputError
        When every term of the model belongs to the bench: there is no fitted valve to export
        beyond the bare maps, and exporting them as "the fitted valve" would mislead.
    """
    kept, left_out = [], {}
    for effect in model.effects:
        if effect.category == "sensor":
            left_out[effect.name] = "a sensor correction: a property of the bench, not the valve"
        elif any(parameter.scope is not None for parameter in effect.params.values()):
            left_out[effect.name] = ("a term with a parameter per bench run: the runs of the log "
                                     "it was fitted to, not the valve")
        else:
            kept.append(effect)
    if model.effects and not kept:
        raise InputError(f"{source}: every term of model {model.name!r} belongs to the bench "
                         f"({', '.join(left_out)}), so there is no fitted valve to export; "
                         "export the model these terms were fitted beside")
    return ValvePhysics(model.with_effects(kept, name=model.name), left_out)
