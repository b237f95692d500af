"""Neural-network predictors for the learned maps: an ensemble of monotone networks.

Each member is a network of :mod:`.network`, trained in PyTorch and saved as its raw parameters in
one ``.npz`` per map (``flow.npz``: ``0/hidden.0``, ``0/bias.0``, ..., ``1/hidden.0``, ...), read
back with ``allow_pickle=False``: loading never executes code and, like inference, needs NumPy
only. Folders written before (``flow_0.pt``, ...) still load, through ``torch.load`` with
``weights_only=True``. The ensemble averages the members' corrections R; each member obeys the
slope bounds that make the maps monotone, and so does any average of them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.input_files import check_input
from . import package
from .learned import learned_kind
from .network import architecture_from_dict, network
from .opening_offsets import OpeningOffsets
from .registry import register
from .sigma import BACK_PRESSURE_LINEAR

MANIFEST = package.MANIFEST

#: what the network's output R means, and how the map's target follows from it
OUTPUTS = {"log_discharge": lambda r: r,  # flow: R = ln C_d
           "fraction": np.expm1,  # force: R = ln(1 + α)
           "closing_fraction": lambda r: np.expm1(-np.logaddexp(0.0, -r)),  # α in (−1, 0)
           "log_negative_fraction": lambda r: -np.exp(r),  # force: R = ln(−α)
           "plain_fraction": lambda r: r}  # force: R = α


class NetworkEnsemble:
    """Mean correction of several networks, turned into the map's target."""

    #: the members agree between openings about as well as on them, so the calibration also
    #: reads the opening's distance from the sampled ones (:mod:`.sigma`)
    spread_knows_openings = False
    #: below the smallest sampled opening the members' features saturate (ln Re held at its
    #: edge, the correction flat in ln u), so α would stay the smallest opening's down to the
    #: seat: the force map continues it instead (:meth:`.learned.LearnedForceMap.toward_seat`)
    holds_the_smallest_opening = True

    def __init__(self, architecture, states: list[dict[str, np.ndarray]],
                 feature_mean: np.ndarray, feature_std: np.ndarray, output: str,
                 opening_offsets: OpeningOffsets | None = None):
        if output not in OUTPUTS:
            raise ValueError(f"unknown network output {output!r}")
        self.architecture = architecture
        self.states = states
        self.members = [network(architecture, state) for state in states]
        self.feature_mean = np.asarray(feature_mean, float)
        self.feature_std = np.asarray(feature_std, float)
        self.output = output
        #: each sampled opening's own bias, added to the members' mean (:mod:`.opening_offsets`)
        self.opening_offsets = opening_offsets

    @property
    def target(self) -> str:
        return self.output

    @property
    def feature_count(self) -> int:
        """How many feature columns the networks read."""
        return len(self.feature_mean)

    def latent(self, features: np.ndarray, return_std: bool = False):
        """R averaged over the members (and the members' spread: a deep ensemble's
        uncertainty)."""
        z = (features - self.feature_mean) / self.feature_std
        outputs = np.array([member(z) for member in self.members])
        mean = outputs.mean(axis=0)
        if self.opening_offsets is not None:
            mean = mean + self.opening_offsets(features)
        if not return_std:
            return mean
        return mean, (outputs.std(axis=0, ddof=1) if len(outputs) > 1
                      else np.zeros_like(mean))

    def predict(self, features: np.ndarray) -> np.ndarray:
        """The map's target (ln C_d, or α)."""
        return self.from_latent(self.latent(features))

    def from_latent(self, latent: np.ndarray) -> np.ndarray:
        """The map's target from the networks' mean output R."""
        return OUTPUTS[self.output](latent)

    def describe(self) -> dict:
        offsets = ({} if self.opening_offsets is None
                   else {"opening_offsets": self.opening_offsets.to_dict()})
        return {"architecture": self.architecture.to_dict(), "members": len(self.members),
                "parameters": self.architecture.parameter_count * len(self.members),
                "output": self.output, "feature_mean": self.feature_mean.tolist(),
                "feature_std": self.feature_std.tolist(), **offsets}


def save_ensemble(folder: Path, name: str, ensemble: NetworkEnsemble) -> dict:
    """Write the members' raw parameters to ``<name>.npz``; return the manifest entry."""
    path = folder / f"{name}.npz"
    np.savez(path, **{f"{index}/{key}": np.asarray(value) for index, state in
                      enumerate(ensemble.states) for key, value in state.items()})
    return {**ensemble.describe(), "file": path.name}


def load_ensemble(folder: Path, entry: dict, features: int) -> NetworkEnsemble:
    """An ensemble of ``features`` input columns saved by :func:`save_ensemble` (or as PyTorch
    state_dicts, format 1), its entry and weights checked: the architecture, the feature scaling,
    and every member's arrays by name, shape (those of the architecture) and finite value."""
    where = f"{folder / MANIFEST}: the predictor of {_named(entry)}:"
    architecture = _architecture(package.table(entry, "architecture", where),
                                 package.place(where, "architecture"), features)
    mean = package.numbers(entry, "feature_mean", where, (features,))
    std = package.numbers(entry, "feature_std", where, (features,), low=0.0, above=True)
    output = package.text(entry, "output", where, OUTPUTS)
    if "file" in entry:
        path = folder / entry["file"]
        states = _members(package.read_npz(path, "network weights"), path)
    else:
        states = [_load_legacy(folder / name) for name in package.entry_files(entry, where)]
        path = folder / package.entry_files(entry, where)[0]
    shapes = architecture.parameter_shapes()
    for index, state in enumerate(states):
        _check_member(state, shapes, f"{path}: member {index}")
    members = entry.get("members", len(states))
    if isinstance(members, bool) or members != len(states):
        raise InputError(f"{path}: holds {len(states)} member(s), the manifest records another "
                         "number (members)")
    offsets = (OpeningOffsets.from_dict(package.table(entry, "opening_offsets", where),
                                        package.place(where, "opening_offsets"), features)
               if "opening_offsets" in entry else None)
    return NetworkEnsemble(architecture, states, mean, std, output, offsets)


def _architecture(data: dict, where: str, features: int):
    """The architecture a manifest records, checked (its values are not echoed)."""
    try:
        architecture = architecture_from_dict(data)
    except KeyError as error:
        raise InputError(f"{where}: missing key {error.args[0]!r}") from None
    except (TypeError, ValueError, AttributeError, IndexError):
        raise InputError(f"{where}: malformed; it holds numbers, lists of numbers and null as "
                         "training writes them") from None
    problem = architecture.problem(features)
    if problem:
        raise InputError(f"{where}: {problem}")
    return architecture


def _check_member(state: dict[str, np.ndarray], shapes: dict[str, tuple], where: str) -> None:
    """One member's arrays: exactly the architecture's, in its shapes, all finite."""
    missing = [name for name in shapes if name not in state]
    if missing:
        raise InputError(f"{where}: missing array(s) {', '.join(missing)}; the architecture "
                         f"needs {', '.join(shapes)}")
    extra = [name for name in state if name not in shapes]
    if extra:
        raise InputError(f"{where}: unexpected array(s) {', '.join(extra)}; the architecture "
                         f"has {', '.join(shapes)}")
    for name, shape in shapes.items():
        package.check_array(state[name], f"{where}, array {name!r}", shape)


def _members(arrays: dict[str, np.ndarray], path: Path) -> list[dict[str, np.ndarray]]:
    """The members' arrays of an ``.npz`` (keys ``<member>/<name>``), members numbered from 0."""
    members: dict[int, dict[str, np.ndarray]] = {}
    for key, value in arrays.items():
        index, _, name = key.partition("/")
        if not index.isdigit() or not name:
            raise InputError(f"{path}: unexpected array {key!r} (expected '<member>/<name>')")
        members.setdefault(int(index), {})[name] = value
    if sorted(members) != list(range(len(members))) or not members:
        raise InputError(f"{path}: members must be numbered 0, 1, ... without gaps; found "
                         f"{', '.join(map(str, sorted(members))) or 'none'}")
    return [members[index] for index in sorted(members)]


def _load_legacy(path: Path) -> dict[str, np.ndarray]:
    """A member saved as a PyTorch state_dict (folders of format 1)."""
    import torch

    check_input(path, "network weights", "weights")
    try:
        state = torch.load(path, weights_only=True, map_location="cpu")
    except Exception as error:  # missing, truncated, or not plain tensors (pickled code)
        first_line = str(error).strip().splitlines()[0] if str(error).strip() else ""
        raise InputError(f"{path}: cannot load network weights as plain tensors "
                         f"({type(error).__name__}: {first_line})") from None
    if not isinstance(state, dict) or not all(isinstance(value, torch.Tensor)
                                              for value in state.values()):
        raise InputError(f"{path}: not a state_dict of tensors")
    # the sign buffer is the architecture's, not a weight
    return {key: value.numpy() for key, value in state.items() if key != "signs"}


def _named(entry: dict) -> str:
    """The weight file a predictor entry names, for messages (never another value of it)."""
    return entry["file"] if isinstance(entry.get("file"), str) else "a map"


register(learned_kind(
    "nn", "neural-network ensembles on dimensionless features: a monotone flow network, a "
          "force network bridged across openings",
    trainer="surrogate.learn.training:train_networks",
    save_predictor=save_ensemble, load_predictor=load_ensemble,
    calibration_powers=BACK_PRESSURE_LINEAR,
    constraints={
        "flow": "q non-decreasing in p_L and in u by construction: |dlnCd/dlnRe_q| <= 0.98, "
                "|dlnCd/dln(u/U)| <= 0.98, dlnCd/dln(sigma_q) >= 0",
        "force": "alpha < 0 (the flow force closes the valve) by construction when every "
                 "sample's does; ln(-alpha) linear in ln u between sampled openings and held "
                 "beyond them; monotonicity in p_L measured, not guaranteed"}))
