"""The learned maps (NN ensembles, Gaussian processes) as ONNX graphs, built with ``onnx.helper``.

Each map kind's own NumPy inference (:mod:`surrogate.maps.network`, :mod:`surrogate.maps.gp`,
:mod:`surrogate.maps.learned`, :mod:`surrogate.features`, :mod:`surrogate.maps.sigma`) is
written out operation by operation, in double precision, so that onnxruntime reproduces the
package to rounding (``tests/export/test_export_onnx.py`` checks 1e-6 relative on 10,000 states):

* ``flow.onnx``: inputs u [m], p_L, p_B [Pa], nu [m^2/s], rho [kg/m^3] (each of shape [N]);
  outputs q [m^3/s] and q_std [m^3/s]. The learned flow map gives Δp(q) in closed form; its
  inverse, q at a given p_L, is found in the graph by 12 safeguarded Newton steps in ln q (a
  finite-difference slope, the step kept inside a bracket that halves when a step leaves it),
  to machine precision (from the orifice's guess it converges in 3 to 5), as the package's
  root finder does;
* ``force.onnx``: the same inputs; outputs f_sim [N] and f_sim_std [N];
* ``onnx.json``: what they are, their inputs and outputs with units, the opset.

The σ are the maps' calibrated standard deviations (the ensemble's spread or the GP's posterior
σ, with the distances from the CFD samples, :mod:`surrogate.maps.sigma`). A GP's posterior
variance needs a triangular solve, which ONNX lacks: the inverse of the Cholesky factor is
computed once at export time (NumPy, double) and the graph multiplies by it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..maps.cfd_error import (CAVITATION_FORCE_ERROR, GAP_FLOW_ERROR, GAP_FORCE_ERROR,
                              SEAT_FLOW_ERROR, SEAT_FORCE_ERROR)
from ..maps.gp import BRIDGE, MATERN, SQRT3, GaussianProcessPredictor
from ..maps.learned import LearnedFlowMap, LearnedForceMap
from ..maps.network import HOLD_SHARPNESS, BridgedNet, NumpyNet, smoothing_matrix
from ..maps.nn import NetworkEnsemble
from ..model import ValveModel
from ..core.units import P_ATM

OPSET = 17
INPUTS = (("u", "m", "piston opening"), ("p_L", "Pa", "load pressure (gauge)"),
          ("p_B", "Pa", "back pressure (gauge)"), ("nu", "m^2/s", "kinematic viscosity"),
          ("rho", "kg/m^3", "density"))
#: Newton steps of the flow map's inversion; from the orifice's guess it converges in 3 to 5,
#: the rest leave room for the bracket's halvings
NEWTON_STEPS = 12
_NEWTON_PROBE = 1e-7  # [ln q] step of the finite-difference slope


@dataclass(frozen=True)
class LearnedMaps:
    """The model's two learned maps and their kind."""

    flow: LearnedFlowMap
    force: LearnedForceMap
    kind: str


def learned_maps_of(model: ValveModel, source: str) -> LearnedMaps:
    """The model's learned maps, or :class:`InputError` naming what it has instead."""
    flow, force = model.flow_map, model.force_map
    if not (isinstance(flow, LearnedFlowMap) and isinstance(force, LearnedForceMap)):
        raise InputError(f"{source}: --format onnx exports learned maps (nn, gp); model "
                         f"{model.name!r} has {flow!r} and {force!r}; add --maps nn or --maps gp")
    return LearnedMaps(flow, force, flow.kind)


class Graph:
    """An ONNX graph under construction: each operation gets a fresh output name."""

    def __init__(self):
        from onnx import helper

        self.helper = helper
        self.nodes, self.initializers, self.count = [], [], 0
        self.constants: dict[tuple, str] = {}

    def name(self, hint: str = "t") -> str:
        self.count += 1
        return f"{hint}_{self.count}"

    def const(self, value, dtype=np.float64) -> str:
        """An initializer holding ``value``; equal values share one (the flow map's Newton
        steps use the same weights dozens of times)."""
        from onnx import numpy_helper

        array = np.array(value, dtype=dtype, order="C")  # (ascontiguousarray makes 0-d 1-d)
        key = (array.dtype.str, array.shape, array.tobytes())
        if key not in self.constants:
            self.constants[key] = self.name("c")
            self.initializers.append(numpy_helper.from_array(array, self.constants[key]))
        return self.constants[key]

    def op(self, kind: str, *inputs: str, **attributes) -> str:
        output = self.name(kind.lower())
        self.nodes.append(self.helper.make_node(kind, list(inputs), [output], **attributes))
        return output

    # arithmetic on names, and on a name and a number
    def _operand(self, value) -> str:
        return value if isinstance(value, str) else self.const(value)

    def add(self, a, b): return self.op("Add", self._operand(a), self._operand(b))
    def sub(self, a, b): return self.op("Sub", self._operand(a), self._operand(b))
    def mul(self, a, b): return self.op("Mul", self._operand(a), self._operand(b))
    def div(self, a, b): return self.op("Div", self._operand(a), self._operand(b))
    def max(self, a, b): return self.op("Max", self._operand(a), self._operand(b))
    def min(self, a, b): return self.op("Min", self._operand(a), self._operand(b))
    def exp(self, a): return self.op("Exp", a)
    def log(self, a): return self.op("Log", a)
    def sqrt(self, a): return self.op("Sqrt", a)
    def tanh(self, a): return self.op("Tanh", a)
    def abs(self, a): return self.op("Abs", a)
    def neg(self, a): return self.op("Neg", a)
    def matmul(self, a, b): return self.op("MatMul", self._operand(a), self._operand(b))
    def where(self, condition, a, b):
        return self.op("Where", condition, self._operand(a), self._operand(b))
    def greater(self, a, b): return self.op("Greater", self._operand(a), self._operand(b))

    def softplus(self, x: str) -> str:
        """log(1 + e^x) without overflow: max(x, 0) + log(1 + e^(-|x|)), as np.logaddexp."""
        return self.add(self.op("Relu", x), self.log(self.add(self.exp(self.neg(self.abs(x))),
                                                               1.0)))

    def column(self, matrix: str, index: int) -> str:
        """Column ``index`` of an [N, k] matrix, as [N]."""
        return self.op("Gather", matrix, self.const(index, np.int64), axis=1)

    def columns(self, matrix: str, indices) -> str:
        """Some columns of an [N, k] matrix, as [N, len(indices)]."""
        return self.op("Gather", matrix, self.const(list(indices), np.int64), axis=1)

    def stack(self, vectors) -> str:
        """[N] vectors side by side, as [N, k]."""
        axis = self.const([1], np.int64)
        return self.op("Concat", *(self.op("Unsqueeze", v, axis) for v in vectors), axis=1)

    def sum_rows(self, matrix: str) -> str:
        """Each row's sum of an [N, k] matrix, as [N]."""
        return self.op("ReduceSum", matrix, self.const([1], np.int64), keepdims=0)

    def min_rows(self, matrix: str) -> str:
        return self.op("ReduceMin", matrix, axes=[1], keepdims=0)

    def square(self, a): return self.mul(a, a)

    def model(self, inputs: dict[str, str], outputs: dict[str, str], name: str, doc: str):
        """The ONNX model with these [N] double inputs and outputs."""
        from onnx import TensorProto, checker

        helper = self.helper
        graph = helper.make_graph(
            self.nodes + [helper.make_node("Identity", [source], [name_])
                          for name_, source in outputs.items()], name,
            [helper.make_tensor_value_info(key, TensorProto.DOUBLE, ["N"]) for key in inputs],
            [helper.make_tensor_value_info(key, TensorProto.DOUBLE, ["N"]) for key in outputs],
            self.initializers)
        model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)],
                                  producer_name="cbv-surrogate", doc_string=doc)
        model.ir_version = 8
        checker.check_model(model)
        return model


# --- features (surrogate.features) -------------------------------------------------------------

_SMALLEST_FLOW, _SMALLEST_OPENING, _SMALLEST_DP, _SMALLEST_MARGIN = 1e-30, 1e-15, 1e-30, 1e2


def _margin(g: Graph, spec, p_B: str) -> str:
    return g.max(g.add(p_B, spec.p_atm - spec.p_sat), _SMALLEST_MARGIN)


def flow_features(g: Graph, spec, q: str, p_B: str, u: str, nu: str, rho: str) -> str:
    """(ln Re_q, ln(u/U), ln σ_q), [N, 3]."""
    q, u = g.max(q, _SMALLEST_FLOW), g.max(u, _SMALLEST_OPENING)
    velocity = g.div(q, g.mul(u, spec.w))
    return g.stack([g.log(g.div(g.mul(q, 2.0), g.mul(nu, spec.w))), g.log(g.div(u, spec.length)),
                    g.log(g.div(_margin(g, spec, p_B),
                                g.mul(g.mul(rho, 0.5), g.square(velocity))))])


def force_features(g: Graph, spec, p_L: str, p_B: str, u: str, nu: str, rho: str,
                   count: int = 3) -> str:
    """The first ``count`` of (ln Re, ln(u/U), ln σ, ln(Δp/p_atm)) built from Δp, [N, count]."""
    dp = g.max(g.sub(p_L, p_B), _SMALLEST_DP)
    reynolds = g.div(g.mul(g.sqrt(g.div(g.mul(dp, 2.0), rho)), spec.length), nu)
    opening = g.div(g.max(u, _SMALLEST_OPENING), spec.length)
    columns = [g.log(reynolds), g.log(opening), g.log(g.div(_margin(g, spec, p_B), dp))]
    if count == 4:
        columns.append(g.log(g.div(dp, spec.p_atm)))
    return g.stack(columns)


# --- predictors -----------------------------------------------------------------------------------

def _hold(g: Graph, z: str, held: dict, width: int) -> str:
    """z with the held columns smoothly clamped (:func:`surrogate.maps.network.hold`)."""
    if not held:
        return z
    columns = []
    c = HOLD_SHARPNESS
    for k in range(width):
        column = g.column(z, k)
        if k in held:
            low, high = held[k]
            column = g.add(g.div(g.sub(g.softplus(g.mul(g.sub(column, low), c)),
                                       g.softplus(g.mul(g.sub(column, high), c))), c), low)
        columns.append(column)
    return g.stack(columns)


def _numpy_net(g: Graph, net: NumpyNet, z: str) -> str:
    total = g.add(g.matmul(z, net.linear), net.offset)
    held = _hold(g, z, net.held, len(net.linear))
    for group, weight, bias, output in net.parts:
        hidden = g.tanh(g.add(g.matmul(g.columns(held, group), weight.T.copy()), bias))
        total = g.add(total, g.matmul(hidden, output))
    if net.transition:
        knee = g.softplus(g.add(g.matmul(z, net.knee), net.knee_start))
        total = g.sub(total, g.mul(knee, net.depth))
    return total


def _bridged_net(g: Graph, net: BridgedNet, z: str, width: int) -> str:
    a, s = net.architecture, net.state
    knots = np.asarray(a.knots, float)
    x_bridge = g.column(z, a.bridge_column)
    held = _hold(g, z, a.held, width)
    x = g.op("Unsqueeze", g.column(held, a.local_column), g.const([1, 2], np.int64))
    # every opening's small network at once: [N, knots, width] -> [N, knots]
    hidden = g.tanh(g.add(g.mul(x, s["local_W"][None]), s["local_b"][None]))
    local = g.op("ReduceSum", g.mul(hidden, s["local_v"][None]), g.const([2], np.int64),
                 keepdims=0)
    x2 = g.op("Unsqueeze", g.column(held, a.local_column), g.const([1], np.int64))
    local = g.add(g.add(local, s["local_c"][None]), g.mul(x2, s["local_l"][None]))
    if a.level_column is not None:  # each opening's slope in the pressure level
        level = g.op("Unsqueeze", g.column(held, a.level_column), g.const([1], np.int64))
        local = g.add(local, g.mul(level, s["local_m"][None]))
    if len(knots) == 1:
        bridged = g.column(local, 0)
    else:  # hat weights of linear interpolation between the knots, held beyond the ends
        clipped = g.op("Unsqueeze", g.op("Clip", x_bridge, g.const(knots[0]),
                                         g.const(knots[-1])), g.const([1], np.int64))
        big = 1e300
        below = np.r_[knots[0] - 1.0, knots[:-1]]
        above = np.r_[knots[1:], knots[-1] + 1.0]
        rising = g.div(g.sub(clipped, below[None]), (knots - below)[None])
        falling = g.div(g.sub(above[None], clipped), (above - knots)[None])
        rising = g.where(g.const(np.r_[True, np.zeros(len(knots) - 1, bool)][None], bool),
                         np.full((1, len(knots)), big), rising)
        falling = g.where(g.const(np.r_[np.zeros(len(knots) - 1, bool), True][None], bool),
                          np.full((1, len(knots)), big), falling)
        weights = g.op("Clip", g.min(rising, falling), g.const(0.0), g.const(1.0))
        if a.smoothing_degree and len(knots) > 2:  # network.bridge_weights
            half_width = float(np.min(np.diff(knots))) / 2
            bump = _bumps(g, clipped, knots, half_width)
            smoothing = smoothing_matrix(knots, a.smoothing_degree)
            weights = g.add(bump, g.matmul(g.sub(weights, bump), smoothing))
        bridged = g.sum_rows(g.mul(weights, local))
    shared_x = g.column(held, a.shared_column)
    x3 = g.op("Unsqueeze", shared_x, g.const([1], np.int64))
    shared = g.sum_rows(g.mul(g.tanh(g.add(g.mul(x3, s["shared_W"][None]),
                                           s["shared_b"][None])), s["shared_v"][None]))
    shared = g.add(shared, g.mul(shared_x, float(s["shared_l"][0])))
    if not a.trend_width:
        return g.add(bridged, shared)
    trend_x = g.columns(_hold(g, z, a.trend_held, width), [a.bridge_column, a.local_column])
    hidden = g.tanh(g.add(g.matmul(trend_x, s["trend_W"].T.copy()), s["trend_b"]))
    trend = g.column(g.add(g.matmul(hidden, s["trend_v"][:, None]),
                           g.matmul(trend_x, s["trend_l"][:, None])), 0)
    return g.add(g.add(bridged, shared), trend)


def _bumps(g: Graph, x: str, knots: np.ndarray, half_width: float) -> str:
    """max(0, 1 − |x − knot|/h) per knot from an [N, 1] column, as [N, knots]
    (:func:`surrogate.maps.network.bump_weights`)."""
    return g.max(g.sub(1.0, g.div(g.abs(g.sub(x, np.asarray(knots, float)[None])), half_width)),
                 0.0)


def _ensemble(g: Graph, ensemble: NetworkEnsemble, features: str) -> tuple[str, str]:
    """(latent mean, spread) of a network ensemble: mean of the members and their standard
    deviation (ddof 1)."""
    z = g.div(g.sub(features, ensemble.feature_mean[None]), ensemble.feature_std[None])
    outputs = [_numpy_net(g, member, z) if isinstance(member, NumpyNet)
               else _bridged_net(g, member, z, ensemble.feature_count)
               for member in ensemble.members]
    stacked = g.stack(outputs)
    mean = g.op("ReduceMean", stacked, axes=[1], keepdims=0)
    if len(outputs) < 2:
        spread = g.mul(mean, 0.0)
    else:
        deviation = g.sub(stacked, g.op("Unsqueeze", mean, g.const([1], np.int64)))
        spread = g.sqrt(g.div(g.sum_rows(g.square(deviation)), float(len(outputs) - 1)))
    offsets = ensemble.opening_offsets
    if offsets is not None:  # Σ_k b_k·max(0, 1 − |x − x_k|/h) (surrogate.maps.opening_offsets)
        x = g.op("Unsqueeze", g.column(features, offsets.column), g.const([1], np.int64))
        bumps = _bumps(g, x, offsets.knots, offsets.half_width)
        mean = g.add(mean, g.matmul(bumps, offsets.offsets.copy()))
    return mean, spread


def _process(g: Graph, predictor: GaussianProcessPredictor, features: str
             ) -> tuple[str, str]:
    """(latent mean, posterior standard deviation) of a Gaussian process
    (:class:`surrogate.maps.gp.NumpyGP`)."""
    from scipy.linalg import solve_triangular

    scaling, kernel = predictor.arrays.features, predictor.arrays.kernel
    training, output = predictor.arrays.training, predictor.arrays.output
    z = g.div(g.sub(features, scaling.mean[None]), scaling.std[None])
    if predictor.gp.held is not None:  # held columns clamped to their training range
        low, high = predictor.gp.held
        z = g.max(g.min(z, high[None]), low[None])
    total, prior = None, None
    for part in predictor.gp._parts:
        if part.rbf:
            query = g.div(g.columns(z, part.rbf), part.scales[None])
            factor = g.sub(g.sub(g.mul(g.matmul(query, part.scaled.T.copy()), 2.0),
                                 g.op("Unsqueeze", g.sum_rows(g.square(query)),
                                      g.const([1], np.int64))),
                           (2.0 * part.half_norms)[None])  # the training norms, exactly
            factor = g.exp(g.mul(g.min(factor, 0.0), 0.5))
        else:
            factor = None
        if part.kind == BRIDGE:
            b = g.sub(g.op("Clip", g.column(z, part.dims[0]),
                           g.const(float(kernel.bridge_range[0])),
                           g.const(float(kernel.bridge_range[1]))), float(kernel.bridge_origin))
            minimum = g.min(g.op("Unsqueeze", b, g.const([1], np.int64)), part.bridge[None])
            factor = minimum if factor is None else g.mul(factor, minimum)
            part_prior = g.mul(b, part.amplitude)
        else:
            part_prior = part.amplitude
        if part.kind == MATERN:  # (1 + √3·r)·exp(−√3·r), r the opening's distance over ℓ
            opening = g.div(g.column(z, part.dims[0]), part.opening_scale)
            r = g.mul(g.abs(g.sub(g.op("Unsqueeze", opening, g.const([1], np.int64)),
                                  part.opening[None])), SQRT3)
            matern = g.mul(g.add(r, 1.0), g.exp(g.neg(r)))
            factor = matern if factor is None else g.mul(factor, matern)
        factor = g.mul(factor, part.amplitude) if factor is not None else None
        total = factor if total is None else g.add(total, factor)
        prior = part_prior if prior is None else (g.add(prior, part_prior)
                                                  if isinstance(part_prior, str)
                                                  or isinstance(prior, str)
                                                  else prior + part_prior)
    mean = g.add(g.add(g.mul(g.matmul(total, training.dual), output.std),
                       output.mean + output.trend[0]),
                 g.matmul(z, output.trend[1:]))
    if len(output.opening_trend):
        mean = g.add(mean, _opening_polynomial(g, g.column(z, output.opening_column), output))
    inverse = solve_triangular(training.cholesky, np.eye(len(training.cholesky)), lower=True)
    v = g.matmul(total, inverse.T.copy())
    prior_vector = prior if isinstance(prior, str) else g.add(g.mul(mean, 0.0), prior)
    variance = g.sub(prior_vector, g.sum_rows(g.square(v)))
    return mean, g.mul(g.sqrt(g.max(variance, 0.0)), output.std)


def _opening_polynomial(g: Graph, x: str, output) -> str:
    """Σ c_k·x^(k+2) inside the opening's training range and its tangent beyond
    (:func:`surrogate.maps.gp.opening_polynomial`)."""
    low, high = (float(bound) for bound in output.opening_range)
    inside = g.op("Clip", x, g.const(low), g.const(high))
    value, slope, power = None, None, inside  # power: inside^(k+1) for the k-th coefficient
    for k, coefficient in enumerate(output.opening_trend):
        term = g.mul(g.mul(power, inside), float(coefficient))
        rate = g.mul(power, float((k + 2) * coefficient))
        value = term if value is None else g.add(value, term)
        slope = rate if slope is None else g.add(slope, rate)
        power = g.mul(power, inside)
    return g.add(value, g.mul(slope, g.sub(x, inside)))


def _latent(g: Graph, predictor, features: str) -> tuple[str, str]:
    if isinstance(predictor, NetworkEnsemble):
        return _ensemble(g, predictor, features)
    if isinstance(predictor, GaussianProcessPredictor):
        return _process(g, predictor, features)
    raise InputError(f"no ONNX export for a {type(predictor).__name__} predictor")


def _target(g: Graph, predictor, latent: str) -> str:
    """The map's target from the latent output (:data:`surrogate.maps.nn.OUTPUTS`,
    :data:`surrogate.maps.gp.TARGETS`)."""
    name = predictor.output if isinstance(predictor, NetworkEnsemble) else predictor.target
    if name in ("log_discharge", "plain_fraction") or (
            name == "fraction" and not isinstance(predictor, NetworkEnsemble)):
        return latent
    if name == "log_negative_fraction":
        return g.neg(g.exp(latent))
    if name == "fraction":  # networks: R = ln(1 + α)
        return g.sub(g.exp(latent), 1.0)
    if name == "closing_fraction":
        return g.sub(g.exp(g.neg(g.softplus(g.neg(latent)))), 1.0)
    raise InputError(f"no ONNX export for the target {name!r}")


# --- calibrated σ (surrogate.maps.sigma) ---------------------------------------------------

def _calibrated(g: Graph, learned_map, features: str, spread: str, p_B: str, u: str) -> str:
    """σ [ln units] against the valve = sqrt(floor² + cfd_error² + (scale·spread)²
    + Σ (slope·d^power)²): the calibrated σ and the CFD's own error (:mod:`..maps.cfd_error`)."""
    calibration = learned_map.calibration
    variance = g.add(g.add(g.square(g.mul(spread, calibration.scale)), calibration.floor ** 2),
                     g.square(_cfd_error(g, learned_map, p_B, u)))
    distances = {}
    if calibration.slopes.get("features", 0.0):
        domain = learned_map.domain
        scaled = g.div(g.sub(features, domain.mean[None]), domain.std[None])
        squared = g.sub(g.add(g.op("Unsqueeze", g.sum_rows(g.square(scaled)),
                                   g.const([1], np.int64)),
                              np.sum(domain.points ** 2, axis=1)[None]),
                        g.mul(g.matmul(scaled, domain.points.T.copy()), 2.0))
        distances["features"] = g.sqrt(g.max(g.min_rows(squared), 0.0))
    if calibration.slopes.get("back pressure", 0.0) and learned_map.coverage is not None:
        pressures = learned_map.coverage.back_pressures + P_ATM
        absolute = g.op("Unsqueeze", g.add(p_B, P_ATM), g.const([1], np.int64))
        distances["back pressure"] = g.min_rows(g.abs(g.log(g.div(absolute, pressures[None]))))
    if calibration.slopes.get("opening", 0.0) and learned_map.coverage is not None:
        log_openings = np.log(learned_map.coverage.openings)
        log_u = g.op("Unsqueeze", g.log(g.max(u, 1e-12)), g.const([1], np.int64))
        distance = g.min_rows(g.abs(g.sub(log_u, log_openings[None])))
        reach = float(np.min(np.diff(log_openings))) / 2 if len(log_openings) > 1 else 1.0
        distances["opening"] = g.min(g.div(distance, reach), 1.0)  # Coverage.opening_distance
    for name, distance in distances.items():
        slope = calibration.slopes[name]
        term = g.mul(g.op("Pow", distance, g.const(calibration.power_of(name))), slope)
        variance = g.add(variance, g.square(term))
    std = g.sqrt(variance)
    if learned_map.coverage is None:
        return std
    if isinstance(learned_map, LearnedFlowMap):  # a floor, as in FlowMap.log_discharge_std
        return g.max(std, _seat_error(g, learned_map.coverage.openings, u, SEAT_FLOW_ERROR))
    return g.max(std, _seat_error(g, learned_map.coverage.openings, u, SEAT_FORCE_ERROR))


def _cfd_error(g: Graph, learned_map, p_B: str, u: str) -> str:
    """The CFD's own σ [ln units] beside a learned map's calibrated one, as
    :func:`..maps.cfd_error.valve_sigma` joins them for a map whose calibration never bridged a
    gap: each mesh's bias as the map bridges it (:meth:`FlowMap.mesh_error_at`,
    :meth:`ForceMap.mesh_error_at`; for the flow force with the cavitation model's share), never
    less than the gap's prior, in the clip-and-sum form of :mod:`..maps.cfd_error`."""
    coverage = learned_map.coverage
    if coverage is None:
        return g.add(g.mul(u, 0.0), learned_map.cfd_error)
    share = g.add(g.mul(u, 0.0), 1.0)
    for low, high in zip(coverage.openings, coverage.openings[1:]):
        t = _position(g, u, low, high)
        bridged = g.sqrt(g.add(g.square(g.sub(1.0, t)), g.square(t)))
        share = g.add(share, g.sub(bridged, 1.0))
    bias = g.mul(share, learned_map.cfd_error)
    if not isinstance(learned_map, LearnedForceMap):
        return g.max(bias, _gap_error(g, coverage.gaps(), u))
    central = coverage.central_back_pressure + P_ATM
    cavitation = g.mul(g.abs(g.log(g.div(g.add(g.max(p_B, 0.0), P_ATM), central))),
                       CAVITATION_FORCE_ERROR)
    return g.max(g.sqrt(g.add(g.square(bias), g.square(cavitation))),
                 _gap_error(g, coverage.gaps(), u, GAP_FORCE_ERROR))


def _gap_error(g: Graph, gaps, u: str, size: float = GAP_FLOW_ERROR) -> str:
    """:func:`..maps.cfd_error.gap_error` at ``u``."""
    error = g.mul(u, 0.0)
    for low, high in gaps:
        error = g.add(error, g.mul(g.op("Sin", g.mul(_position(g, u, low, high), float(np.pi))),
                                   size))
    return error


def _seat_error(g: Graph, openings, u: str, size: float) -> str:
    """:func:`..maps.cfd_error.seat_error` at ``u``."""
    below = g.sub(float(np.log(np.min(openings))), g.log(g.max(u, 1e-12)))
    return g.mul(g.max(below, 0.0), size)


def _position(g: Graph, u: str, low: float, high: float) -> str:
    """:func:`..maps.cfd_error._position`: where ln u lies between ``low`` and ``high``, in
    [0, 1]."""
    t = g.div(g.sub(g.log(g.max(u, 1e-12)), float(np.log(low))), float(np.log(high / low)))
    return g.min(g.max(t, 0.0), 1.0)


# --- the maps ------------------------------------------------------------------------------------

def force_graph(force_map: LearnedForceMap):
    """f_sim and its σ from (u, p_L, p_B, nu, rho)."""
    g, spec = Graph(), force_map.spec
    features = force_features(g, spec, "p_L", "p_B", "u", "nu", "rho", force_map.feature_count)
    latent, spread = _latent(g, force_map.predictor, features)
    fraction = _toward_seat(g, force_map, _target(g, force_map.predictor, latent))
    uniform = g.add(g.mul("p_L", spec.A_L), g.mul("p_B", spec.back_area))
    dp = g.max(g.sub("p_L", "p_B"), 0.0)
    force = g.add(uniform, g.mul(g.mul(fraction, spec.A_L), dp))
    relative = _calibrated(g, force_map, features, spread, "p_B", "u")
    std = g.mul(g.abs(g.sub(force, uniform)), relative)
    return g.model({name: name for name, _, _ in INPUTS}, {"f_sim": force, "f_sim_std": std},
                   "force_map", f"{force_map.kind} force map of cbv-surrogate: f_sim [N] and "
                                "its calibrated standard deviation")


def _toward_seat(g: Graph, force_map: LearnedForceMap, fraction: str) -> str:
    """α below the smallest sampled opening continued as the power of u the two smallest
    openings give, as :meth:`~..maps.learned.LearnedForceMap.toward_seat` does (the predictor
    asked again at both openings, with the query's other features)."""
    coverage, predictor = force_map.coverage, force_map.predictor
    if (not getattr(predictor, "holds_the_smallest_opening", False) or coverage is None
            or len(coverage.openings) < 2):
        return fraction
    smallest, next_one = (float(opening) for opening in np.sort(coverage.openings)[:2])
    edge, beyond = (
        _target(g, predictor, _latent(g, predictor, force_features(
            g, force_map.spec, "p_L", "p_B", g.add(g.mul("u", 0.0), opening), "nu", "rho",
            force_map.feature_count))[0])
        for opening in (smallest, next_one))
    same_sign = g.greater(g.mul(edge, beyond), 0.0)
    ratio = g.where(same_sign, g.div(beyond, edge), 1.0)  # a power of 0 where the signs differ
    power = g.min(g.max(g.div(g.log(ratio), float(np.log(next_one / smallest))), 0.0), 1.0)
    depth = g.log(g.div(g.max("u", 1e-300), smallest))  # ln(u/u₀), negative below
    continued = g.mul(edge, g.exp(g.mul(power, depth)))
    return g.where(g.greater(smallest, "u"), continued, fraction)


def _log_pressure_drop(g: Graph, flow_map: LearnedFlowMap, log_q: str) -> str:
    """ln Δp(q) of the learned flow map at ln q: ln(½ρ(q/(w·u))²) − 2 ln C_d."""
    spec = flow_map.spec
    q = g.exp(log_q)
    features = flow_features(g, spec, q, "p_B", "u", "nu", "rho")
    log_cd = _target(g, flow_map.predictor, _latent(g, flow_map.predictor, features)[0])
    orifice = g.mul(g.mul("rho", 0.5), g.square(g.div(q, g.mul("u", spec.w))))
    return g.sub(g.log(orifice), g.mul(log_cd, 2.0))


def flow_graph(flow_map: LearnedFlowMap):
    """q and its σ from (u, p_L, p_B, nu, rho): the flow map inverted in the graph."""
    g, spec = Graph(), flow_map.spec
    dp = g.max(g.sub("p_L", "p_B"), 0.0)
    target = g.log(g.max(dp, 1e-300))
    # start: the orifice with C_d = 0.6; bracket wide enough for any C_d of 1e-13 to 1e4
    x = g.add(g.log(g.mul(g.mul("u", spec.w), g.sqrt(g.div(g.mul(dp, 2.0), "rho")))),
              float(np.log(0.6)))
    x = g.max(x, -200.0)  # no flow (dp = 0): a finite start, replaced by 0 at the end
    low, high = g.sub(x, 30.0), g.add(x, 10.0)
    for _ in range(NEWTON_STEPS):
        value = g.sub(_log_pressure_drop(g, flow_map, x), target)
        probe = g.sub(_log_pressure_drop(g, flow_map, g.add(x, _NEWTON_PROBE)), target)
        slope = g.max(g.div(g.sub(probe, value), _NEWTON_PROBE), 1e-3)  # Δp rises with q
        above = g.greater(value, 0.0)
        high = g.where(above, x, high)
        low = g.where(above, low, x)
        step = g.sub(x, g.div(value, slope))
        # inclusive: a converged step lands on the end it just set
        inside = g.op("And", g.op("GreaterOrEqual", step, low),
                      g.op("LessOrEqual", step, high))
        x = g.where(inside, step, g.mul(g.add(low, high), 0.5))
    q = g.where(g.greater(dp, 0.0), g.exp(x), 0.0)
    # σ: the calibrated σ of ln C_d at q, turned into the flow's (FlowMap.flow_std)
    features = flow_features(g, spec, q, "p_B", "u", "nu", "rho")
    _, spread = _latent(g, flow_map.predictor, features)
    relative = _calibrated(g, flow_map, features, spread, "p_B", "u")
    step = 1e-3
    log_q = g.log(g.max(q, 1e-300))
    exponent = g.div(g.sub(_log_pressure_drop(g, flow_map, g.add(log_q, step)),
                           _log_pressure_drop(g, flow_map, g.sub(log_q, step))), 2 * step)
    finite = g.op("Not", g.op("Or", g.op("IsNaN", exponent), g.op("IsInf", exponent)))
    exponent = g.where(finite, g.max(exponent, 0.5), 2.0)
    std = g.where(g.greater(q, 0.0), g.div(g.mul(g.mul(q, 2.0), relative), exponent), 0.0)
    return g.model({name: name for name, _, _ in INPUTS}, {"q": q, "q_std": std}, "flow_map",
                   f"{flow_map.kind} flow map of cbv-surrogate: the flow q [m^3/s] through the "
                   "main restriction at p_L, and its calibrated standard deviation")


def write_onnx(maps: LearnedMaps, folder: Path, progress=None) -> list[Path]:
    """``flow.onnx``, ``force.onnx`` and ``onnx.json`` into ``folder``; returns the files."""
    progress = progress or (lambda message: None)
    written = []
    for name, build, learned in (("flow", flow_graph, maps.flow),
                                 ("force", force_graph, maps.force)):
        progress(f"building the ONNX graph of the {maps.kind} {name} map")
        path = folder / f"{name}.onnx"
        path.write_bytes(build(learned).SerializeToString())
        written.append(path)
    document = {
        "kind": maps.kind, "opset": OPSET, "dtype": "float64",
        "inputs": {name: {"unit": unit, "meaning": meaning, "shape": ["N"]}
                   for name, unit, meaning in INPUTS},
        "outputs": {"flow.onnx": {"q": "flow through the main restriction at p_L [m^3/s]",
                                  "q_std": "its calibrated standard deviation [m^3/s]"},
                    "force.onnx": {"f_sim": "fluid force on the piston inside the CFD domain "
                                            "[N], positive opening",
                                   "f_sim_std": "its calibrated standard deviation [N]"}},
        "notes": "SI units; the fluid as viscosity and density, never a temperature; the flow "
                 f"map is inverted in the graph by {NEWTON_STEPS} safeguarded Newton steps in "
                 "ln q; no extrapolation flags (the package's `predict` gives them)"}
    path = folder / "onnx.json"
    path.write_text(json.dumps(document, indent=2) + "\n")
    written.append(path)
    return written


# --- parity with the package ---------------------------------------------------------------------

def random_states(coverage, count: int = 10_000, seed: int = 0) -> dict[str, np.ndarray]:
    """States [SI] spread over the CFD samples' openings, pressure drops, back pressures and
    viscosities (log-uniform where the samples span decades), as the graphs' inputs."""
    rng = np.random.default_rng(seed)
    u = np.exp(rng.uniform(*np.log(coverage.openings[[0, -1]]), count))
    dp = np.exp(rng.uniform(np.log(coverage.dp_low.min()), np.log(coverage.dp_high.max()),
                            count))
    p_B = rng.uniform(*coverage.p_B_range, count)
    nu = np.exp(rng.uniform(*np.log(coverage.nu_range), count))
    rho = rng.uniform(840.0, 880.0, count)
    return {"u": u, "p_L": p_B + dp, "p_B": p_B, "nu": nu, "rho": rho}


def parity(flow_map: LearnedFlowMap, force_map: LearnedForceMap,
           states: dict[str, np.ndarray]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each output of the graphs (q, q_std, f_sim, f_sim_std) as onnxruntime computes it at
    ``states`` [SI], beside the package's own value: {name: (graph's, package's)}."""
    import onnxruntime  # the export extra's

    from ..fluid import FluidState

    query = (states["p_L"], states["p_B"], states["u"], FluidState(states["nu"], states["rho"]))
    expected = {"q": flow_map.flow(*query), "q_std": flow_map.flow_std(*query),
                "f_sim": force_map.force(*query), "f_sim_std": force_map.force_std(*query)}
    found = {}
    for graph in (flow_graph(flow_map), force_graph(force_map)):
        session = onnxruntime.InferenceSession(graph.SerializeToString(),
                                               providers=["CPUExecutionProvider"])
        names = [output.name for output in session.get_outputs()]
        found.update(zip(names, session.run(None, states)))
    return {name: (found[name], value) for name, value in expected.items()}
