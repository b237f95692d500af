"""Maps that never saw one of the CFD's openings: where a map kind's own error shows in a log.

The virtual valve of :mod:`.mismatch` wraps the model under test's own maps with the CFD's error
(``own_maps``), so the model errs by the same draws whatever its maps' kind: how well a kind
carries the flow and the force between openings never reaches the diagnosis. Here the model under
test gets maps of its kind trained **without one sampled opening**, while the virtual valve keeps
that kind's maps trained on every sample. Near that opening the model then errs as its kind does
between openings (the grid with its power-law bridge, the NN and the GP with theirs; their
cross-validation leaving an opening out measures the same error on the CFD samples), on top of
the CFD's own error that :mod:`.mismatch` draws. A better map is one that leaves less of the
valve unexplained there, which a diagnosis looking for a weak effect should feel.

A learned kind is retrained on the samples left (the kind's trainer, seconds to a minute) and
keeps the calibration of the σ its committed maps carry; the grid is built from the samples left
and calibrates itself on them as any grid does.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..data.loaders import load_cfd_samples
from ..data.writer import write_cfd_samples
from ..core.errors import InputError
from ..maps.learned import load_learned_maps, trained_folder
from ..maps.registry import MapsSpec, map_kind
from ..core.paths import SHIPPED_CFD_SAMPLES
from ..description.presets import maps
from ..core.units import from_si
from ..valve import load_valve


def maps_without_opening(kind: str, opening: float, folder: str | Path,
                         cfd: str | Path = SHIPPED_CFD_SAMPLES,
                         progress=lambda message: None) -> MapsSpec:
    """Maps of ``kind`` built from the samples of ``cfd`` without those at ``opening`` [m],
    written to ``folder`` (a CFD file for the grid, a trained surrogate's folder for a learned
    kind, which keeps the committed maps' calibration of σ)."""
    cfd, folder = Path(cfd), Path(folder)
    source = map_kind(kind)
    if not source.learned and source.data is None:
        raise InputError(f"{source.name} maps are not built from CFD samples: they have no "
                         "opening to leave out")
    samples = load_cfd_samples(cfd)  # checked: a broken file is refused with its row and column
    u = samples.frame["u"].to_numpy()
    at = np.isclose(u, opening, rtol=1e-6)
    sampled = np.unique(u)
    if not at.any():
        raise InputError(f"{cfd}: no sample at u = {from_si(opening, 'mm'):g} mm to leave out; "
                         f"its openings are {', '.join(f'{v:g}' for v in from_si(sampled, 'mm'))}"
                         " mm")
    if np.isclose(opening, [sampled[0], sampled[-1]], rtol=1e-6).any():
        raise InputError(f"leave out an inner opening, not {from_si(opening, 'mm'):g} mm: without "
                         "an end opening the maps extrapolate, which is not the error between "
                         "openings this asks about")
    folder.mkdir(parents=True, exist_ok=True)
    left = write_cfd_samples(samples.subset(~at),
                             folder / f"{cfd.stem}_without_{from_si(opening, 'mm'):g}mm.csv")
    if not source.learned:  # built from the samples themselves (the grid)
        return maps(source.name, cfd=left)
    from ..learn.training import train_surrogate

    trained = train_surrogate(source.name, load_cfd_samples(left), load_valve(),
                              progress=progress)
    committed_flow, committed_force = load_learned_maps(trained_folder(source.name))
    trained.calibrate(committed_flow.calibration, committed_force.calibration)
    surrogate = folder / f"{source.name}_without_{from_si(opening, 'mm'):g}mm"
    trained.save(surrogate, training={"left_out_opening_mm": from_si(opening, "mm")},
                 metrics={})
    return maps(source.name, folder=surrogate)
