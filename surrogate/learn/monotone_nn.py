"""A small additive network with sign- and slope-constrained inputs: monotone by construction.

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
import torch
from torch import nn
from torch.nn.functional import softplus


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

    @property
    def parameter_count(self) -> int:
        per_part = [len(g) * self.width + 2 * self.width for g in self.groups]
        knee = 0 if self.transition is None else 1 + len(self.knee_features)  # θ0 and θ
        return sum(per_part) + self.features + 1 + knee


class SignConstrainedNet(nn.Module):
    """R(z) with per-feature sign constraints and slope bounds (see the module docstring)."""

    def __init__(self, architecture: Architecture):
        super().__init__()
        self.architecture = architecture
        width = architecture.width
        self.hidden = nn.ParameterList(
            nn.Parameter(torch.zeros(width, len(g), dtype=torch.float64))
            for g in architecture.groups)
        self.bias = nn.ParameterList(nn.Parameter(torch.zeros(width, dtype=torch.float64))
                                     for _ in architecture.groups)
        self.output = nn.ParameterList(nn.Parameter(torch.zeros(width, dtype=torch.float64))
                                       for _ in architecture.groups)
        self.linear = nn.Parameter(torch.zeros(architecture.features, dtype=torch.float64))
        self.offset = nn.Parameter(torch.zeros(1, dtype=torch.float64))
        self.knee = nn.Parameter(torch.zeros(architecture.features + 1, dtype=torch.float64))
        self.register_buffer("signs", torch.tensor(architecture.signs, dtype=torch.float64))

    def _signed(self, raw: torch.Tensor, columns) -> torch.Tensor:
        signs = self.signs[list(columns)]
        return torch.where(signs == 0, raw, signs * softplus(raw))

    def knee_weights(self) -> torch.Tensor:
        """θ of the transition term with the Reynolds entry replaced by −sd_r (zero if none).

        The term enters R as −s·softplus(θ0 + θ·z'), so its slope along column k is −s·σ·θ_k:
        a column signed +1 needs θ_k <= 0 and one signed −1 needs θ_k >= 0.
        """
        r = self.architecture.transition
        weights = torch.zeros(self.architecture.features, dtype=torch.float64)
        if r is None:
            return weights
        raw = self.knee[1:]
        weights = torch.where(self.signs == 0, raw, -self.signs * softplus(raw))
        moving = torch.zeros(self.architecture.features, dtype=torch.float64)
        moving[list(self.architecture.knee_features)] = 1.0
        return (weights * moving).index_put(
            (torch.tensor(r),), torch.tensor(-self.architecture.scales[r], dtype=torch.float64))

    def effective(self) -> tuple[list, list, list, torch.Tensor, torch.Tensor]:
        """The weights actually used: (W per part, biases, v per part, β, column scales κ)."""
        weights = [self._signed(raw, group) for raw, group in
                   zip(self.hidden, self.architecture.groups)]
        outputs = [softplus(raw) for raw in self.output]
        linear = self._signed(self.linear, range(self.architecture.features))
        if not self.architecture.linear:
            linear = torch.zeros_like(linear)
        elif self.architecture.linear_features is not None:
            keep = torch.zeros_like(linear)
            keep[list(self.architecture.linear_features)] = 1.0
            linear = linear * keep
        depth = 0.0 if self.architecture.transition is None else self.architecture.transition_depth
        bound = linear.abs() + depth * self.knee_weights().abs()
        for weight, output, group in zip(weights, outputs, self.architecture.groups):
            bound = bound.index_add(0, torch.tensor(group), output @ weight.abs())
        scale = torch.ones(self.architecture.features, dtype=torch.float64)
        for k, limit in enumerate(self.architecture.bounds):
            if limit is not None:
                allowed = limit * self.architecture.scales[k]
                scale = scale.index_put((torch.tensor(k),),
                                        torch.clamp(allowed / torch.clamp(bound[k], min=1e-12),
                                                    max=1.0))
        return weights, list(self.bias), outputs, linear, scale

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        weights, biases, outputs, linear, scale = self.effective()
        scaled = z * scale
        held = _hold(z, self.architecture.held, torch) * scale
        total = self.offset + scaled @ linear
        for weight, bias, output, group in zip(weights, biases, outputs,
                                               self.architecture.groups):
            total = total + torch.tanh(held[:, list(group)] @ weight.T + bias) @ output
        if self.architecture.transition is not None:
            total = total - self.architecture.transition_depth * softplus(
                self.knee[0] + scaled @ self.knee_weights())
        return total

    def initialise(self, seed: int, offset: float) -> None:
        generator = torch.Generator().manual_seed(seed)
        with torch.no_grad():
            for tensor in (*self.hidden, *self.bias):
                tensor.copy_(torch.randn(tensor.shape, generator=generator,
                                         dtype=torch.float64))
            for tensor in self.output:
                tensor.copy_(torch.randn(tensor.shape, generator=generator,
                                         dtype=torch.float64) - 3.0)  # small v at the start
            self.linear.zero_()
            self.offset.fill_(offset)
            self.knee.zero_()


_HOLD_SHARPNESS = 4.0


def _hold(z, held: dict, lib):
    """z with the held columns smoothly clamped to their (low, high) range (torch or numpy)."""
    if not held:
        return z
    softplus_ = (lambda x: torch.nn.functional.softplus(x)) if lib is torch else (
        lambda x: np.logaddexp(0.0, x))
    columns = [z[:, k] for k in range(z.shape[1])]
    for k, (low, high) in held.items():
        c = _HOLD_SHARPNESS
        columns[k] = low + (softplus_(c * (z[:, k] - low)) - softplus_(c * (z[:, k] - high))) / c
    return lib.stack(columns, 1) if lib is torch else np.column_stack(columns)


class NumpyNet:
    """A trained :class:`SignConstrainedNet` evaluated with numpy (fast for small batches)."""

    def __init__(self, architecture: Architecture, state: dict[str, np.ndarray]):
        network = SignConstrainedNet(architecture)
        network.load_state_dict({key: torch.as_tensor(value) for key, value in state.items()})
        with torch.no_grad():
            weights, biases, outputs, linear, scale = network.effective()
            self.offset = float(network.offset)
            self.linear = (linear * scale).numpy()
            self.held = architecture.held
            self.scale = scale.numpy()
            self.transition = architecture.transition is not None
            self.depth = architecture.transition_depth
            self.knee_start = float(network.knee[0])
            self.knee = (network.knee_weights() * scale).numpy()
            self.parts = [(list(group), (weight * scale[list(group)]).numpy(), bias.numpy(),
                           output.numpy())
                          for weight, bias, output, group in
                          zip(weights, biases, outputs, architecture.groups)]

    def __call__(self, z: np.ndarray) -> np.ndarray:
        total = self.offset + z @ self.linear
        held = _hold(z, self.held, np)
        for group, weight, bias, output in self.parts:
            total = total + np.tanh(held[:, group] @ weight.T + bias) @ output
        if self.transition:
            total = total - self.depth * np.logaddexp(0.0, self.knee_start + z @ self.knee)
        return total

    def gradient(self, z: np.ndarray) -> np.ndarray:
        """∂R/∂z at each row of z, shape (n, features)."""
        gradient = np.tile(self.linear, (len(z), 1))
        held = _hold(z, self.held, np)
        hold_slope = np.ones_like(z)
        for k, (low, high) in self.held.items():
            c = _HOLD_SHARPNESS
            hold_slope[:, k] = (1.0 / (1.0 + np.exp(-c * (z[:, k] - low)))
                                - 1.0 / (1.0 + np.exp(-c * (z[:, k] - high))))
        for group, weight, bias, output in self.parts:
            slope = 1.0 - np.tanh(held[:, group] @ weight.T + bias) ** 2
            gradient[:, group] += ((slope * output) @ weight) * hold_slope[:, group]
        if self.transition:
            sigmoid = 1.0 / (1.0 + np.exp(-(self.knee_start + z @ self.knee)))
            gradient -= self.depth * sigmoid[:, None] * self.knee
        return gradient


def train(network: SignConstrainedNet, z: np.ndarray, loss_of_output, *, offset: float,
          seed: int = 0, epochs: int = 2500, polish: int = 500, learning_rate: float = 2e-2,
          weight_decay: float = 1e-7, output_decay: float = 0.0, initialise: bool = True,
          progress=None) -> float:
    """Fit the network: Adam with a cosine schedule, then L-BFGS to polish.

    ``loss_of_output(R)`` maps the network's output to a scalar loss. Returns the final loss.
    ``initialise=False`` continues from the network's current weights.
    """
    if initialise:
        network.initialise(seed, offset)
    inputs = torch.as_tensor(z, dtype=torch.float64)

    def objective():
        penalty = sum(torch.sum(weight**2) for weight in network.hidden)
        amplitude = sum(torch.sum(softplus(raw)) for raw in network.output)
        return (loss_of_output(network(inputs)) + weight_decay * penalty
                + output_decay * amplitude)

    adam = torch.optim.Adam(network.parameters(), lr=learning_rate)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(adam, epochs)
    for epoch in range(epochs):
        adam.zero_grad()
        loss = objective()
        loss.backward()
        adam.step()
        schedule.step()
        if progress is not None and (epoch + 1) % max(epochs // 4, 1) == 0:
            progress(f"epoch {epoch + 1}/{epochs}: loss {loss.item():.3e}")
    lbfgs = torch.optim.LBFGS(network.parameters(), max_iter=polish, history_size=50,
                              line_search_fn="strong_wolfe", tolerance_grad=1e-12,
                              tolerance_change=1e-16)

    def closure():
        lbfgs.zero_grad()
        loss = objective()
        loss.backward()
        return loss

    lbfgs.step(closure)
    with torch.no_grad():
        return float(objective())


def widen(narrow: SignConstrainedNet, wide: Architecture, seed: int) -> SignConstrainedNet:
    """A network of architecture ``wide`` that computes exactly what ``narrow`` computes.

    Each part of ``wide`` must contain the features of the corresponding part of ``narrow``; the
    extra input columns start at zero weight (small random for free columns would change the
    function), so training the wide network starts from the narrow one's solution.
    """
    network = SignConstrainedNet(wide)
    network.initialise(seed, float(narrow.offset.detach()))
    with torch.no_grad():
        for part, (small, big) in enumerate(zip(narrow.architecture.groups, wide.groups)):
            columns = [big.index(k) for k in small]
            network.hidden[part].zero_()
            network.hidden[part][:, columns] = narrow.hidden[part]
            free = [i for i, k in enumerate(big) if k not in small and wide.signs[k] != 0]
            network.hidden[part][:, free] = -20.0  # signed columns: softplus(−20) ≈ 0
            network.bias[part].copy_(narrow.bias[part])
            network.output[part].copy_(narrow.output[part])
        for name in ("linear", "offset", "knee"):
            getattr(network, name).copy_(getattr(narrow, name))
    return network
