"""Monotone networks evaluated with NumPy: the inference side of the learned NN maps.

Training happens in PyTorch (:mod:`surrogate.learn.monotone_nn`); a trained network is saved as
plain arrays (its raw parameters, ``.npz``), and this module turns them into the weights the
network actually uses (signs through softplus, the slope-bounding column scales) and evaluates it.
Loading and evaluating a saved network therefore needs NumPy only, never PyTorch.

A small additive network with sign- and slope-constrained inputs: monotone by construction.

The learned maps write their output as a physical baseline plus a learned correction R:

    flow:   Δp    = ½ρ·(q / (w·u·e^R))²                        (R = ln C_d, flow features)
    force:  f_sim = p_L·A_L + p_B·(A_s3 − A_B) + α·A_L·Δp,  1 + α = e^R   (force features)

(or 1 + α = e^(−softplus(−R)) when every sample's flow force closes the valve, which keeps α in
(−1, 0); softplus rises, so the argument below is unchanged)

with the features of :mod:`surrogate.features`. Flow features: A = ln Re_q (rises by 1 per unit
of ln q), B = ln(u/U), C = ln σ_q (falls by 2 per unit of ln q, rises by 2 per unit of ln u).
Force features: a = ln Re (rises by 1/2 per unit of ln Δp), b = ln(u/U), c = ln σ (falls by 1).

Network
-------
    R(z) = c0 + β·z' + Σ_g Σ_j v_gj·tanh(W_gj·z'_g + b_gj) − s·softplus(θ0 + θ·z' − sd_r·z'_r),
    z' = κ ∘ z,

a sum of one-hidden-layer tanh parts on subsets of the standardised features z (the additive
structure of :mod:`surrogate.features`), a linear term, and optionally a *transition* term on the
Reynolds feature r: the laminar–turbulent blend of orifice flow,
ln C_d = ln C_∞ − s·ln(1 + Re_t/Re), with the knee Re_t free to move with the other features (the
opening) and the depth s fixed by physics: s = 1/2 for C_d(Re_q), whose laminar limit is
C_d ∝ Re_q^½ (Δp ∝ q). Below the samples' Reynolds numbers the transition term keeps C_d falling
the way laminar flow does, and the tanh parts see the Reynolds number through a smooth clamp to
the training range (``held``), so their correction holds its edge value there instead of bending
the trend: physics extrapolates, corrections do not. That is what lets the map reach colder oil.

The flow networks are trained in two stages (:mod:`surrogate.learn.training`): first the physics
alone (C_d = C_∞(u, σ)·(1 + Re_t(u)/Re)^(−½)), then, starting from that solution (:func:`widen`),
with the Reynolds number added to the first tanh part to learn what the blend misses.
All v >= 0. Each input column k has a *sign*: +1 or −1 forces W_jk and β_k to that sign (through a
softplus), 0 leaves them free; and optionally a *slope bound* B_k on |∂R/∂f_k| in raw feature units.
The bound is enforced by the column scale κ_k = min(1, B_k·sd_k/S_k), recomputed from the weights at
every evaluation, where S_k = |β_k| + Σ_g Σ_j v_gj·|W_gjk| + s·|θ_k| (+ s·sd_r for k = r) bounds
|∂R/∂z_k| because 0 < tanh' <= 1 and 0 < softplus' < 1. The transition's θ_k obey the column
signs too (θ_k of the opposite sign, as the term enters with a minus). For a signed column every
term of S_k has the same sign, so the bound is tight, not conservative.

Why that makes the maps monotone
--------------------------------
Flow (q non-decreasing in p_L and in u), with A and B free in sign but |∂R/∂·| <= 0.98, and C
with sign +1:

    ∂ln Δp/∂ln q       = 2·(1 − ∂R/∂A + 2·∂R/∂C) >= 2·(1 − 0.98) > 0,
    ∂ln Δp/∂ln u at q  = −2·(1 + ∂R/∂B + 2·∂R/∂C) <= −2·(1 − 0.98) < 0,

so the pressure drop rises with the flow and falls with the opening: the flow through the valve
rises with p_L and with u.

Force (f_sim non-decreasing in p_L), with a of sign +1, c of sign −1 and b free:

    ∂ln(A_L·Δp·e^R)/∂ln Δp = 1 + (1/2)·∂R/∂a − ∂R/∂c >= 1 > 0.

The signs are physics, stated so they can be checked: the discharge coefficient does not fall as
the cavitation number rises (a cavitating jet chokes the flow), and it grows more slowly than the
Reynolds number (in laminar flow C_d ∝ Re^½); the flow force is a smaller fraction of the uniform
load force at low Reynolds numbers and shrinks as the jet cavitates.
The guarantees hold for any weights, inside the data and far outside it; they are properties of
the architecture, not of training. tanh keeps the maps C^∞, so the solver never meets a kink.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.special import expit

#: sharpness of the smooth clamp of the held columns (see :attr:`Architecture.held`)
HOLD_SHARPNESS = 4.0
#: softplus switches to the identity above this, as ``torch.nn.functional.softplus`` does, so
#: that NumPy and PyTorch compute the same weights
_SOFTPLUS_THRESHOLD = 20.0


@dataclass(frozen=True)
class Architecture:
    """What is needed to rebuild a network from its state_dict.

    Attributes
    ----------
    groups : tuple of tuple of int
        Feature indices of each additive part.
    width : int
        Hidden units per part.
    signs : tuple of int
        Per feature: +1 (R non-decreasing in it), −1 (non-increasing) or 0 (free).
    bounds : tuple of float or None
        Per feature: largest |∂R/∂f| in raw feature units, or None.
    scales : tuple of float
        Per feature: the standard deviation sd_k used to standardise it.
    transition : int or None
        Index of the Reynolds feature of the transition term; None for no such term.
    transition_depth : float
        Its depth s: the slope of R in ln Re far below the knee (1/2 for C_d(Re_q)).
    knee_features : tuple of int
        Features the transition's knee may move with (the opening: Re_t(u)); the others do not
        enter it.
    linear : bool
        Whether R has the linear term β·z. Without it R saturates beyond the data (it holds its
        edge values), which suits a quantity that must stay bounded, like a force fraction.
    linear_features : tuple of int or None
        Features of the linear term; None for all.
    held : dict
        Feature -> (low, high) in standardised units: the tanh parts see that feature through a
        smooth clamp to [low, high], so beyond the training data their correction holds its edge
        value while the transition and linear terms carry the trend. The clamp rises with slope
        in (0, 1), so signs and slope bounds are kept.
    """

    groups: tuple[tuple[int, ...], ...]
    width: int
    signs: tuple[int, ...]
    bounds: tuple[float | None, ...]
    scales: tuple[float, ...]
    transition: int | None = None
    transition_depth: float = 0.5
    knee_features: tuple[int, ...] = ()
    linear: bool = True
    linear_features: tuple[int, ...] | None = None
    held: dict[int, tuple[float, float]] = field(default_factory=dict)

    def __post_init__(self):
        if self.transition is not None and self.signs[self.transition] == -1:
            raise ValueError("the transition term rises with its Reynolds feature; that column "
                             "cannot have sign −1")

    def to_dict(self) -> dict:
        return {"groups": [list(g) for g in self.groups], "width": self.width,
                "signs": list(self.signs), "bounds": list(self.bounds),
                "scales": list(self.scales), "transition": self.transition,
                "transition_depth": self.transition_depth,
                "knee_features": list(self.knee_features), "linear": self.linear,
                "linear_features": None if self.linear_features is None
                else list(self.linear_features),
                "held": {str(k): list(v) for k, v in self.held.items()}}

    @classmethod
    def from_dict(cls, data: dict) -> "Architecture":
        return cls(tuple(tuple(int(i) for i in g) for g in data["groups"]), int(data["width"]),
                   tuple(int(s) for s in data["signs"]),
                   tuple(None if b is None else float(b) for b in data["bounds"]),
                   tuple(float(s) for s in data["scales"]), data.get("transition"),
                   float(data.get("transition_depth", 0.5)),
                   tuple(int(k) for k in data.get("knee_features", ())),
                   bool(data.get("linear", True)),
                   None if data.get("linear_features") is None
                   else tuple(int(k) for k in data["linear_features"]),
                   {int(k): (float(v[0]), float(v[1])) for k, v in data.get("held", {}).items()})

    @property
    def features(self) -> int:
        return len(self.signs)

    def parameter_shapes(self) -> dict[str, tuple[int, ...]]:
        """The raw parameters of a network of this architecture (its saved arrays), by name."""
        shapes = {}
        for i, group in enumerate(self.groups):
            shapes.update({f"hidden.{i}": (self.width, len(group)), f"bias.{i}": (self.width,),
                           f"output.{i}": (self.width,)})
        return {**shapes, "linear": (self.features,), "offset": (1,),
                "knee": (self.features + 1,)}

    def problem(self, features: int) -> str | None:
        """What makes this architecture unusable on ``features`` input columns (None: nothing):
        the checks a manifest's architecture passes before a network is built from it."""
        columns = range(features)
        if self.features != features or not len(self.bounds) == len(self.scales) == features:
            return (f"signs, bounds and scales must each have {features} entries (one per "
                    "feature)")
        if self.width < 1 or not self.groups or any(not group for group in self.groups):
            return "needs width >= 1 and at least one non-empty group"
        used = [i for group in self.groups for i in group] + list(self.knee_features) + \
            list(self.linear_features or ()) + list(self.held) + \
            ([] if self.transition is None else [self.transition])
        if any(i not in columns for i in used):
            return f"a feature index lies outside 0 to {features - 1}"
        if any(sign not in (-1, 0, 1) for sign in self.signs):
            return "signs must be -1, 0 or 1"
        if not all(np.isfinite(s) and s > 0 for s in self.scales) or not all(
                b is None or (np.isfinite(b) and b > 0) for b in self.bounds):
            return "scales and bounds must be finite and > 0"
        if not (np.isfinite(self.transition_depth) and self.transition_depth >= 0) or not all(
                np.isfinite(low) and np.isfinite(high) and low <= high
                for low, high in self.held.values()):
            return "transition_depth must be finite and >= 0, held ranges finite (low, high)"
        return None

    @property
    def parameter_count(self) -> int:
        per_part = [len(g) * self.width + 2 * self.width for g in self.groups]
        knee = 0 if self.transition is None else 1 + len(self.knee_features)  # θ0 and θ
        return sum(per_part) + self.features + 1 + knee


def softplus(x):
    """log(1 + e^x), the identity above 20 (as PyTorch's softplus)."""
    x = np.asarray(x, float)
    with np.errstate(over="ignore"):
        return np.where(x > _SOFTPLUS_THRESHOLD, x, np.log1p(np.exp(np.minimum(x, 50.0))))


def hold(z: np.ndarray, held: dict) -> np.ndarray:
    """z with the held columns smoothly clamped to their (low, high) range."""
    if not held:
        return z
    columns = [z[:, k] for k in range(z.shape[1])]
    for k, (low, high) in held.items():
        c = HOLD_SHARPNESS
        columns[k] = low + (np.logaddexp(0.0, c * (z[:, k] - low))
                            - np.logaddexp(0.0, c * (z[:, k] - high))) / c
    return np.column_stack(columns)


def _signed(raw: np.ndarray, signs: np.ndarray) -> np.ndarray:
    """Weights of signed columns through softplus (sign ±1), free ones as they are (sign 0)."""
    return np.where(signs == 0, raw, signs * softplus(raw))


def knee_weights(architecture: Architecture, knee: np.ndarray) -> np.ndarray:
    """θ of the transition term (zero if none), its Reynolds entry replaced by −sd_r.

    The term enters R as −s·softplus(θ0 + θ·z'), so its slope along column k is −s·σ·θ_k: a
    column signed +1 needs θ_k <= 0 and one signed −1 needs θ_k >= 0.
    """
    r = architecture.transition
    features = architecture.features
    if r is None:
        return np.zeros(features)
    signs = np.asarray(architecture.signs, float)
    weights = np.where(signs == 0, knee[1:], -signs * softplus(knee[1:]))
    moving = np.zeros(features)
    moving[list(architecture.knee_features)] = 1.0
    weights = weights * moving
    weights[r] = -architecture.scales[r]
    return weights


def effective_weights(architecture: Architecture, state: dict[str, np.ndarray]):
    """The weights a network with raw parameters ``state`` uses.

    Returns (W per part, biases, v per part, β, κ): the signs applied, and the column scales
    κ_k = min(1, B_k·sd_k/S_k) that enforce the slope bounds (module docstring).
    """
    groups = architecture.groups
    signs = np.asarray(architecture.signs, float)
    weights = [_signed(np.asarray(state[f"hidden.{i}"], float), signs[list(group)])
               for i, group in enumerate(groups)]
    biases = [np.asarray(state[f"bias.{i}"], float) for i in range(len(groups))]
    outputs = [softplus(np.asarray(state[f"output.{i}"], float)) for i in range(len(groups))]
    linear = _signed(np.asarray(state["linear"], float), signs)
    if not architecture.linear:
        linear = np.zeros_like(linear)
    elif architecture.linear_features is not None:
        keep = np.zeros_like(linear)
        keep[list(architecture.linear_features)] = 1.0
        linear = linear * keep
    depth = 0.0 if architecture.transition is None else architecture.transition_depth
    knee = knee_weights(architecture, np.asarray(state["knee"], float))
    bound = np.abs(linear) + depth * np.abs(knee)
    for weight, output, group in zip(weights, outputs, groups):
        np.add.at(bound, list(group), output @ np.abs(weight))
    scale = np.ones(architecture.features)
    for k, limit in enumerate(architecture.bounds):
        if limit is not None:
            scale[k] = min(limit * architecture.scales[k] / max(bound[k], 1e-12), 1.0)
    return weights, biases, outputs, linear, scale


class NumpyNet:
    """A trained network R(z), evaluated with NumPy from its raw parameters."""

    def __init__(self, architecture: Architecture, state: dict[str, np.ndarray]):
        weights, biases, outputs, linear, scale = effective_weights(architecture, state)
        self.offset = float(np.asarray(state["offset"]).ravel()[0])
        self.linear = linear * scale
        self.held = architecture.held
        self.scale = scale
        self.transition = architecture.transition is not None
        self.depth = architecture.transition_depth
        knee = np.asarray(state["knee"], float)
        self.knee_start = float(knee[0])
        self.knee = knee_weights(architecture, knee) * scale
        self.parts = [(list(group), weight * scale[list(group)], bias, output)
                      for weight, bias, output, group in
                      zip(weights, biases, outputs, architecture.groups)]

    def __call__(self, z: np.ndarray) -> np.ndarray:
        total = self.offset + z @ self.linear
        held = hold(z, self.held)
        for group, weight, bias, output in self.parts:
            total = total + np.tanh(held[:, group] @ weight.T + bias) @ output
        if self.transition:
            total = total - self.depth * np.logaddexp(0.0, self.knee_start + z @ self.knee)
        return total

    def gradient(self, z: np.ndarray) -> np.ndarray:
        """∂R/∂z at each row of z, shape (n, features)."""
        gradient = np.tile(self.linear, (len(z), 1))
        held = hold(z, self.held)
        hold_slope = np.ones_like(z)
        for k, (low, high) in self.held.items():
            c = HOLD_SHARPNESS
            hold_slope[:, k] = expit(c * (z[:, k] - low)) - expit(c * (z[:, k] - high))
        for group, weight, bias, output in self.parts:
            slope = 1.0 - np.tanh(held[:, group] @ weight.T + bias) ** 2
            gradient[:, group] += ((slope * output) @ weight) * hold_slope[:, group]
        if self.transition:
            sigmoid = expit(self.knee_start + z @ self.knee)
            gradient -= self.depth * sigmoid[:, None] * self.knee
        return gradient


# --- the bridged network of the flow-force maps -----------------------------------------------------

@dataclass(frozen=True)
class BridgedArchitecture:
    """A network that bridges openings linearly, as the grid maps do, for the flow force.

    R(z) = Σ_k φ_k(z_u)·(g_k(z_r) + m_k·z_p) + h(z_s): one small network g_k of the Reynolds
    feature per sampled opening ``knots[k]`` (standardised ln(u/U)), blended by the hat functions
    φ_k of linear interpolation between neighbouring openings (held beyond the end ones), plus
    one network h of the cavitation feature shared by all openings. Sharing h is the physics: the
    flow force's cavitation factor depends on σ alone (the samples collapse on it across
    openings and back pressures), so the force at a back pressure the CFD did not run follows
    from openings where it did reach those σ. Each small network is c + l·x + Σ_j v_j·tanh(W_j·x
    + b_j) on one standardised column.

    With a ``level_column`` (the pressure level ln(Δp/p_atm)) each opening also has a slope m_k
    in it: along one temperature's sweep the level and the Reynolds number rise together, across
    temperatures they part, and the CFD's flow-force fraction follows the level there more than
    the Reynolds number alone carries (leaving a temperature out: 2.5 % error with the slope,
    3.5 % without). Training keeps neighbouring openings' slopes close (a sweep left out leaves an
    opening with a hole in Δp, where a free slope ran off).

    With a ``trend_width`` R also has a trend t(z_u, z_r) = Σ_j v_j·tanh(W_j·(z_u, z_r) + b_j) +
    l·(z_u, z_r), one small network of the opening and the Reynolds number shared by all
    openings, which sees both through holds of its own (``trend_held``: the end knots, the
    sampled Reynolds numbers), so that beyond them it keeps its edge value. Training keeps
    the per-opening networks close to one another, so the trend carries how the flow force
    changes from opening to opening, smoothly, and the per-opening networks only what each
    opening departs from it by: between two sampled openings the force bends as the trend does
    instead of following the straight bridge.

    With a ``smoothing_degree`` the bridge treats each opening's network as carrying its mesh's
    own bias: on (and near) a sampled opening R is that opening's network, but halfway between
    two openings it interpolates the openings' networks smoothed across all openings by a
    least-squares polynomial of that degree in z_u (:func:`bridge_weights`), fitted at the
    query's own inputs, so that one opening's bias does not bend the force across the gap next
    to it. The weights stay linear in the networks' outputs.

    Attributes
    ----------
    knots : tuple of float
        Sampled openings, standardised, increasing.
    width : int
        Hidden units of each small network.
    bridge_column, local_column, shared_column : int
        Feature columns of the opening, the Reynolds number and the cavitation number.
    held : dict
        {column: (low, high)}: standardised ranges beyond which the local and shared networks
        see their input smoothly held (:func:`hold`), so that the flow-force fraction stays what
        the data say at their edge instead of running off along the networks' linear terms.
    level_column : int or None
        Feature column of the pressure level, whose slope m_k each opening has (None: no slope;
        networks saved before it read three columns).
    trend_width : int
        Hidden units of the trend t(z_u, z_r) (0: no trend, as networks saved before it).
    trend_held : dict
        {column: (low, high)}: standardised ranges of the bridge and local columns beyond which
        the trend sees them smoothly held (:func:`hold`, applied to the raw features).
    smoothing_degree : int
        Degree of the polynomial the bridge smooths the openings' networks by between openings
        (0: the straight bridge, as networks saved before it).
    """

    knots: tuple[float, ...]
    width: int = 8
    bridge_column: int = 1
    local_column: int = 0
    shared_column: int = 2
    held: dict = field(default_factory=dict)
    level_column: int | None = None
    trend_width: int = 0
    trend_held: dict = field(default_factory=dict)
    smoothing_degree: int = 0

    def to_dict(self) -> dict:
        level = {} if self.level_column is None else {"level_column": self.level_column}
        trend = {"trend_width": self.trend_width,
                 "trend_held": {str(k): list(v) for k, v in self.trend_held.items()}
                 } if self.trend_width else {}
        smoothing = ({"smoothing_degree": self.smoothing_degree} if self.smoothing_degree
                     else {})
        return {"type": "bridged", "knots": list(self.knots), "width": self.width,
                "bridge_column": self.bridge_column, "local_column": self.local_column,
                "shared_column": self.shared_column, **level, **trend, **smoothing,
                "held": {str(k): list(v) for k, v in self.held.items()}}

    @classmethod
    def from_dict(cls, data: dict) -> "BridgedArchitecture":
        level = data.get("level_column")
        return cls(tuple(float(k) for k in data["knots"]), int(data["width"]),
                   int(data["bridge_column"]), int(data["local_column"]),
                   int(data["shared_column"]),
                   {int(k): (float(v[0]), float(v[1])) for k, v in data.get("held", {}).items()},
                   None if level is None else int(level), int(data.get("trend_width", 0)),
                   {int(k): (float(v[0]), float(v[1]))
                    for k, v in data.get("trend_held", {}).items()},
                   int(data.get("smoothing_degree", 0)))

    @property
    def parameter_count(self) -> int:
        return sum(int(np.prod(shape)) for shape in self.parameter_shapes().values())

    def parameter_shapes(self) -> dict[str, tuple[int, ...]]:
        """The raw parameters of a network of this architecture (its saved arrays), by name."""
        knots, width = len(self.knots), self.width
        level = {} if self.level_column is None else {"local_m": (knots,)}
        trend_width = self.trend_width
        trend = {"trend_W": (trend_width, 2), "trend_b": (trend_width,),
                 "trend_v": (trend_width,), "trend_l": (2,)} if trend_width else {}
        return {"local_W": (knots, width), "local_b": (knots, width), "local_v": (knots, width),
                "local_c": (knots,), "local_l": (knots,), **level, "shared_W": (width,),
                "shared_b": (width,), "shared_v": (width,), "shared_l": (1,), **trend}

    def problem(self, features: int) -> str | None:
        """What makes this architecture unusable on ``features`` input columns (None: nothing)."""
        knots = np.asarray(self.knots, float)
        if len(knots) < 1 or not np.all(np.isfinite(knots)) or np.any(np.diff(knots) <= 0):
            return "knots must be finite and increasing, at least one"
        if self.width < 1:
            return "needs width >= 1"
        if isinstance(self.trend_width, bool) or self.trend_width < 0:
            return "trend_width must be 0 (no trend) or more"
        if isinstance(self.smoothing_degree, bool) or not 0 <= self.smoothing_degree <= 5:
            return "smoothing_degree must be 0 (the straight bridge) to 5"
        level = () if self.level_column is None else (self.level_column,)
        columns = (self.bridge_column, self.local_column, self.shared_column, *level, *self.held)
        if any(isinstance(c, bool) or c not in range(features) for c in columns):
            return f"a feature index lies outside 0 to {features - 1}"
        if not all(np.isfinite(low) and np.isfinite(high) and low <= high
                   for low, high in (*self.held.values(), *self.trend_held.values())):
            return "held ranges must be finite (low, high)"
        if any(c not in (self.bridge_column, self.local_column) for c in self.trend_held):
            return "the trend holds only the bridge and local columns"
        return None


def hat_weights(x: np.ndarray, knots) -> np.ndarray:
    """Weights of linear interpolation between ``knots`` at ``x`` (held beyond the ends), shape
    (n, knots)."""
    lower, weight = hat_bracket(x, knots)
    weights = np.zeros((len(x), len(knots)))
    rows = np.arange(len(x))
    weights[rows, lower] = 1.0 - weight
    weights[rows, np.minimum(lower + 1, len(knots) - 1)] += weight
    return weights


def smoothing_matrix(knots, degree: int) -> np.ndarray:
    """H (knots × knots): the values at ``knots`` of the least-squares polynomial of ``degree``
    (at most one less than the knots) through values given there, as H @ values."""
    knots = np.asarray(knots, float)
    vander = np.vander(knots - knots.mean(), min(degree, len(knots) - 1) + 1)
    return vander @ np.linalg.pinv(vander)


def bump_weights(x: np.ndarray, knots, half_width: float | None = None) -> np.ndarray:
    """max(0, 1 − |x − knot|/h) per knot (n, knots), h by default half the closest spacing of two
    knots: 1 on a knot, 0 halfway to the closest neighbour."""
    knots = np.asarray(knots, float)
    if half_width is None:
        half_width = np.min(np.diff(knots)) / 2
    return np.maximum(0.0, 1.0 - np.abs(np.asarray(x, float)[:, None] - knots[None]) / half_width)


def bridge_weights(x: np.ndarray, knots, smoothing_degree: int = 0) -> np.ndarray:
    """The weights of the openings' networks at ``x`` (n, knots): linear interpolation between
    neighbouring knots (:func:`hat_weights`) or, with a ``smoothing_degree``, each opening's own
    network on (and near) its knot and, halfway between knots, linear interpolation of the
    openings' networks smoothed across all openings by a polynomial of that degree
    (:class:`BridgedArchitecture`)."""
    hat = hat_weights(x, knots)
    if not smoothing_degree or len(knots) < 3:
        return hat
    bump = bump_weights(np.clip(x, knots[0], knots[-1]), knots)
    return bump + (hat - bump) @ smoothing_matrix(knots, smoothing_degree)


def hat_bracket(x: np.ndarray, knots) -> tuple[np.ndarray, np.ndarray]:
    """The lower knot of each ``x`` and the weight of the one above it (held beyond the ends;
    a single knot has weight 0 above)."""
    knots = np.asarray(knots, float)
    if len(knots) == 1:
        return np.zeros(len(x), dtype=np.intp), np.zeros(len(x))
    x = np.clip(x, knots[0], knots[-1])
    lower = np.clip(np.searchsorted(knots, x) - 1, 0, len(knots) - 2)
    return lower, (x - knots[lower]) / (knots[lower + 1] - knots[lower])


class BridgedNet:
    """A trained :class:`BridgedArchitecture` network, evaluated with NumPy from its parameters
    (``local_W``, ``local_b``, ``local_v`` (knots × width), ``local_c``, ``local_l`` and, with a
    level column, ``local_m`` (knots), ``shared_W``, ``shared_b``, ``shared_v`` (width),
    ``shared_l`` (1) and, with a trend, ``trend_W`` (trend width × 2), ``trend_b``, ``trend_v``
    (trend width), ``trend_l`` (2))."""

    def __init__(self, architecture: BridgedArchitecture, state: dict[str, np.ndarray]):
        self.architecture = architecture
        self.state = {key: np.asarray(value, float) for key, value in state.items()}

    def __call__(self, z: np.ndarray) -> np.ndarray:
        a, s = self.architecture, self.state
        lower, weight = hat_bracket(z[:, a.bridge_column], a.knots)
        raw, z = z, hold(z, a.held)
        x = z[:, a.local_column]
        level = None if a.level_column is None else z[:, a.level_column]

        def local(k):  # the small network of opening k (one per row, or every opening: k = :)
            x_, level_ = (x, level) if isinstance(k, np.ndarray) else (
                x[:, None], None if level is None else level[:, None])
            hidden = np.tanh(x_[..., None] * s["local_W"][k] + s["local_b"][k])
            value = (hidden * s["local_v"][k]).sum(-1) + s["local_c"][k] + x_ * s["local_l"][k]
            return value if level is None else value + level_ * s["local_m"][k]

        if a.smoothing_degree and len(a.knots) > 2:  # every opening carries weight
            weights = bridge_weights(raw[:, a.bridge_column], a.knots, a.smoothing_degree)
            bridged = np.sum(weights * local(slice(None)), axis=1)
        else:  # only the two openings around each query carry weight
            upper = np.minimum(lower + 1, len(a.knots) - 1)
            bridged = (1.0 - weight) * local(lower) + weight * local(upper)
        shared_x = z[:, a.shared_column]
        shared = (np.tanh(shared_x[:, None] * s["shared_W"][None] + s["shared_b"][None])
                  * s["shared_v"][None]).sum(-1) + s["shared_l"][0] * shared_x
        if not a.trend_width:
            return bridged + shared
        trend_x = hold(raw, a.trend_held)[:, [a.bridge_column, a.local_column]]
        trend = (np.tanh(trend_x @ s["trend_W"].T + s["trend_b"]) @ s["trend_v"]
                 + trend_x @ s["trend_l"])
        return bridged + shared + trend


def architecture_from_dict(data: dict):
    """The architecture a manifest describes (additive monotone or bridged)."""
    if data.get("type") == "bridged":
        return BridgedArchitecture.from_dict(data)
    return Architecture.from_dict(data)


def network(architecture, state):
    """The NumPy network of an architecture and its parameters."""
    if isinstance(architecture, BridgedArchitecture):
        return BridgedNet(architecture, state)
    return NumpyNet(architecture, state)
