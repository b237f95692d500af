"""Training the monotone networks of the learned NN maps, in PyTorch.

The network, its constraints and why they make the maps monotone are described in
:mod:`surrogate.maps.network`, which evaluates trained networks with NumPy. This module holds the
same network as a PyTorch module, to fit its raw parameters; :func:`state_arrays` hands them over
as plain arrays.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn
from torch.nn.functional import softplus

from ..maps.network import HOLD_SHARPNESS, Architecture

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
        held = _hold(z, self.architecture.held) * scale
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


def _hold(z: torch.Tensor, held: dict) -> torch.Tensor:
    """z with the held columns smoothly clamped (:func:`surrogate.maps.network.hold`)."""
    if not held:
        return z
    columns = [z[:, k] for k in range(z.shape[1])]
    for k, (low, high) in held.items():
        c = HOLD_SHARPNESS
        columns[k] = low + (softplus(c * (z[:, k] - low)) - softplus(c * (z[:, k] - high))) / c
    return torch.stack(columns, 1)


def state_arrays(network: SignConstrainedNet) -> dict[str, np.ndarray]:
    """The network's raw parameters as NumPy arrays, keyed as in its state_dict."""
    return {key: value.detach().numpy().copy() for key, value in network.state_dict().items()
            if key != "signs"}


def train(network: SignConstrainedNet, z: np.ndarray, loss_of_output, *, offset: float,
          seed: int = 0, epochs: int = 2500, polish: int = 500, learning_rate: float = 2e-2,
          weight_decay: float = 1e-7, output_decay: float = 0.0,
          feature_decay: dict[int, float] | None = None, initialise: bool = True,
          progress=None) -> float:
    """Fit the network: Adam with a cosine schedule, then L-BFGS to polish.

    ``loss_of_output(R)`` maps the network's output to a scalar loss. Returns the final loss.
    ``feature_decay`` {feature: weight} adds a decay on the hidden weights that read that
    feature, on top of ``weight_decay``: the parts vary more slowly along it.
    ``initialise=False`` continues from the network's current weights.
    """
    if initialise:
        network.initialise(seed, offset)
    inputs = torch.as_tensor(z, dtype=torch.float64)
    # (part, position of the feature in it, weight) of every decayed column
    decayed = [(part, group.index(feature), weight)
               for feature, weight in (feature_decay or {}).items()
               for part, group in enumerate(network.architecture.groups) if feature in group]

    def objective():
        penalty = sum(torch.sum(weight**2) for weight in network.hidden)
        amplitude = sum(torch.sum(softplus(raw)) for raw in network.output)
        along = sum(weight * torch.sum(network.hidden[part][:, position] ** 2)
                    for part, position, weight in decayed)
        return (loss_of_output(network(inputs)) + weight_decay * penalty
                + output_decay * amplitude + along)

    minimise(network, objective, epochs=epochs, learning_rate=learning_rate, polish=polish,
             progress=progress, tolerance_grad=1e-12, tolerance_change=1e-16)
    with torch.no_grad():
        return float(objective())


def minimise(network: nn.Module, objective, *, epochs: int, learning_rate: float, polish: int,
             progress=None, **lbfgs_options) -> None:
    """Adam with a cosine learning-rate schedule for ``epochs`` steps, then ``polish`` L-BFGS
    iterations (strong-Wolfe line search; ``lbfgs_options`` its tolerances): every network of the
    package is trained this way. ``objective()`` returns the loss to minimise."""
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
                              line_search_fn="strong_wolfe", **lbfgs_options)

    def closure():
        lbfgs.zero_grad()
        loss = objective()
        loss.backward()
        return loss

    lbfgs.step(closure)


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
