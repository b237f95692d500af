"""The map interface every flow and force map implements, whatever is behind it.

A *flow map* is the paper's q_sim(p_L, p_B, u) (eq. 5) or the orifice equation (eq. 4): the flow
through the main restriction at a given pressure drop and opening, and its inverse, the pressure
drop a given flow needs. A *force map* is f_sim(p_L, p_B, u) (eq. 7): the axial fluid force on the
piston surfaces inside the CFD domain, i.e. everything except the pilot chamber (p_P·A_P) and the
main spring chamber (−p_B·A_s3).

All arguments are numpy arrays (broadcast together) in SI units, with the fluid given as a
:class:`~surrogate.fluid.FluidState`, never as a temperature, so a map can serve another oil.

A subclass implements one direction of the flow map, :meth:`FlowMap.flow` or
:meth:`FlowMap.pressure_drop`; the base class inverts it for the other, because both are monotone.
Every map built from data says where, and why, a query lies outside that data
(``extrapolation_reasons``, bit flags of :mod:`.coverage`; ``extrapolating`` where any is set),
and how uncertain it is (``log_discharge_std`` and ``flow_std``; ``force_std``): a subclass gives
``calibration_inputs`` and a ``calibration`` fitted on cross-validation (:mod:`.sigma`),
which measures how well it reproduces the CFD; the CFD's own error against the valve
(``cfd_error``, :mod:`.cfd_error`: the meshes' biases, what no mesh says across an unsampled
gap, the cavitation model's share) is added in quadrature, and σ is never below what no mesh
says below the smallest opening. Maps without data (the orifice equation) have neither.
"""

from __future__ import annotations

from abc import ABC
from dataclasses import dataclass

import numpy as np

from ..fluid import FluidState, broadcast_query
from ..numerics.roots import invert_increasing
from ..core.units import BAR, LPM
from .cfd_error import (FLOW_CFD_ERROR, FORCE_CFD_ERROR, GAP_FORCE_ERROR, SEAT_FORCE_ERROR,
                        cavitation_error, gap_error, mesh_bias_share, seat_error, valve_sigma)


@dataclass(frozen=True)
class MapResult:
    """A map's answer at a batch of query points.

    Attributes
    ----------
    value : numpy.ndarray
        Flow [m^3/s] or force [N].
    extrapolating : numpy.ndarray of bool
        True where the query lies outside the data the map was built from.
    std : numpy.ndarray or None
        Predictive standard deviation in the units of ``value``, for maps that have one.
    """

    value: np.ndarray
    extrapolating: np.ndarray
    std: np.ndarray | None = None


class FlowMap(ABC):
    """Flow through the main restriction, q(p_L, p_B, u, fluid), and its inverse Δp(q, ...).

    Subclasses implement :meth:`flow` or :meth:`pressure_drop` (or both); the other is found by
    inverting it. q must be non-decreasing in p_L at fixed p_B, u and fluid.
    """

    #: short name used in reports and files
    kind = "flow map"
    #: where the samples are (maps built from data); None for maps without data
    coverage = None
    #: turns :meth:`calibration_inputs` into a standard deviation (:mod:`.sigma`)
    calibration = None
    #: σ of ln C_d that the CFD itself adds, each opening's mesh biased its own way [1]
    cfd_error = FLOW_CFD_ERROR
    #: True for a map whose calibrated σ was measured across spans as wide as an unsampled gap
    #: (the grid's: its calibration leaves openings out of the bridge it draws): the gap's prior
    #: is then a floor under σ, not a term beside it (:func:`.cfd_error.valve_sigma`)
    calibration_spans_gaps = False
    #: True for a map smooth (C⁴ or better) in the flow at a fixed opening: a fit's tables may
    #: then read it at another flow than a sample's own from a polynomial about it
    #: (:mod:`surrogate.solver.map_tables`)
    smooth = False

    def flow(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        """Flow [m^3/s] at load pressure ``p_L`` [Pa], back pressure ``p_B`` [Pa], opening ``u`` [m].

        No flow where p_L <= p_B: in its relief mode the valve passes flow from load to back port
        only.
        """
        self._require_implemented("pressure_drop")
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        shape = p_L.shape
        dp, p_B, u, fluid = np.maximum(p_L - p_B, 0.0).ravel(), p_B.ravel(), u.ravel(), fluid.ravel()
        roots = invert_increasing(lambda q, i: self.pressure_drop(q, p_B[i], u[i], fluid[i]),
                                  dp, np.full(dp.shape, 1.0 * LPM), xatol=1e-15)
        return np.where(dp > 0, roots.x, 0.0).reshape(shape)

    def pressure_drop(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        """Pressure drop Δp = p_L − p_B [Pa] that pushes flow ``q`` [m^3/s] through opening ``u`` [m]."""
        self._require_implemented("flow")
        q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
        shape = q.shape
        q, p_B, u, fluid = np.maximum(q, 0.0).ravel(), p_B.ravel(), u.ravel(), fluid.ravel()
        roots = invert_increasing(lambda dp, i: self.flow(p_B[i] + dp, p_B[i], u[i], fluid[i]),
                                  q, np.full(q.shape, 10.0 * BAR), xatol=1e-6)
        return np.where(q > 0, roots.x, 0.0).reshape(shape)

    def at_openings(self, p_B, u, fluid: FluidState):
        """``pressure_drop(q, index)``: :meth:`pressure_drop` at the flows ``q`` [m^3/s] of the
        points ``index`` (all by default) of these back pressures [Pa], openings [m] and fluid
        states (1-D, one per point): a leak's split asks the restriction about the same
        openings at many flows (:func:`surrogate.leakage.shared_pressure_drop`). A map may
        prepare what does not depend on the flow once; here it is asked afresh each time."""
        def pressure_drop(q, index=slice(None)):
            return self.pressure_drop(q, p_B[index], u[index], fluid[index])
        return pressure_drop

    def at_flows(self, q, p_B, fluid: FluidState):
        """``pressure_drop(u, index)``: :meth:`pressure_drop` of the points ``index``
        (positions) of these flows [m^3/s], back pressures [Pa] and fluid states (1-D, one per
        point) at openings ``u`` [m]: a fit's tables ask each sample's flow at many openings
        (:mod:`surrogate.solver.map_tables`). A map may prepare what does not depend on the
        opening once; here it is asked afresh each time."""
        q, p_B = np.asarray(q, float), np.asarray(p_B, float)

        def pressure_drop(u, index):
            return self.pressure_drop(q[index], p_B[index], u, fluid[index])
        return pressure_drop

    def opening_knots(self) -> np.ndarray:
        """Openings [m] where the map has a kink along u (at a fixed flow, or Δp): none for a
        smooth map. A fit's tables of the map put nodes there
        (:mod:`surrogate.solver.map_tables`)."""
        return np.empty(0)

    def _require_implemented(self, method: str) -> None:
        if getattr(type(self), method) is getattr(FlowMap, method):
            raise NotImplementedError(f"{type(self).__name__} must implement flow() or "
                                      "pressure_drop()")

    def reasons_at_flow(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        """Why a query given by its flow ``q`` [m^3/s] lies outside the map's data: bit flags of
        :mod:`.coverage`, 0 inside. Maps without data: 0."""
        q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
        if self.coverage is None:
            return np.zeros(q.shape, dtype=np.int64)
        dp = self.pressure_drop(q, p_B, u, fluid)
        return self.coverage.reasons(dp, q, p_B, u, fluid.nu)

    def extrapolation_reasons(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        """Why a query lies outside the map's data (bit flags of :mod:`.coverage`, 0 inside)."""
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        if self.coverage is None:
            return np.zeros(p_L.shape, dtype=np.int64)
        return self.reasons_at_flow(self.flow(p_L, p_B, u, fluid), p_B, u, fluid)

    def extrapolating(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        """True where the query lies outside the map's data. Maps without data: never."""
        return self.extrapolation_reasons(p_L, p_B, u, fluid) != 0

    def extrapolating_at_flow(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        """:meth:`extrapolating` for a query given by its flow ``q`` [m^3/s] instead of p_L."""
        return self.reasons_at_flow(q, p_B, u, fluid) != 0

    def calibration_inputs(self, q, p_B, u, fluid: FluidState):
        """What the map's standard deviation of ln C_d at flow ``q`` [m^3/s] is computed from:
        (own spread or None, distance to the data, back-pressure distance), see
        :mod:`.sigma`; None for maps without data."""
        return None

    def log_discharge_std(self, q, p_B, u, fluid: FluidState) -> np.ndarray | None:
        """Standard deviation of ln C_d at flow ``q`` [m^3/s] against the valve: the relative
        uncertainty of the flow the restriction passes at a given pressure drop [-], the
        calibrated one and the CFD's own error (:func:`.cfd_error.valve_sigma`); None if the map
        has none."""
        if self.calibration is None:
            return None
        q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
        calibrated = self.calibration.std(*self.calibration_inputs(q, p_B, u, fluid))
        if self.coverage is None:
            return np.reshape(np.hypot(calibrated, self.cfd_error), q.shape)
        std = valve_sigma(calibrated, self.mesh_error_at(u), gap_error(self.coverage.gaps(), u),
                          gap_is_floor=self.calibration_spans_gaps)
        std = np.maximum(std, seat_error(self.coverage.openings, u))  # a floor toward the seat
        return np.reshape(std, q.shape)

    def mesh_error_at(self, u) -> np.ndarray:
        """σ of ln C_d [1] that the CFD's meshes put on the map at openings ``u`` [m]:
        :attr:`cfd_error`, the meshes' biases as the map bridges them
        (:func:`.cfd_error.mesh_bias_share`)."""
        if self.coverage is None:
            return np.full(np.shape(u), self.cfd_error)
        return self.cfd_error * mesh_bias_share(self.coverage.openings, u)

    def flow_std(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray | None:
        """Standard deviation of the flow [m^3/s] at load pressure ``p_L``, or None.

        With Δp = ½ρ(q/(C_d·A))², a relative error δ of C_d moves the flow at a given Δp by
        q·2δ/n, n = d ln Δp/d ln q the map's local flow exponent (2 for a turbulent orifice, 1
        for laminar flow), taken by a central difference.
        """
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        q = self.flow(p_L, p_B, u, fluid)
        relative = self.log_discharge_std(q, p_B, u, fluid)
        if relative is None:
            return None
        step = 1e-3
        with np.errstate(divide="ignore", invalid="ignore"):
            exponent = np.log(self.pressure_drop(q * np.exp(step), p_B, u, fluid)
                              / self.pressure_drop(q * np.exp(-step), p_B, u, fluid)) / (2 * step)
        exponent = np.where(np.isfinite(exponent), np.maximum(exponent, 0.5), 2.0)
        return np.where(q > 0, q * 2.0 * relative / exponent, 0.0)

    def query(self, p_L, p_B, u, fluid: FluidState) -> MapResult:
        """Flow, extrapolation flags and (if any) standard deviation at the query points."""
        return MapResult(self.flow(p_L, p_B, u, fluid), self.extrapolating(p_L, p_B, u, fluid),
                         self.flow_std(p_L, p_B, u, fluid))


class ForceMap(ABC):
    """Fluid force f_sim(p_L, p_B, u, fluid) [N] on the piston surfaces inside the CFD domain."""

    kind = "force map"
    coverage = None
    calibration = None
    #: relative σ of the flow force that the CFD itself adds (:mod:`.cfd_error`) [1]
    cfd_error = FORCE_CFD_ERROR
    #: as :attr:`FlowMap.calibration_spans_gaps`
    calibration_spans_gaps = False
    #: True for a map smooth (C⁴ or better) in Δp at a fixed opening (as :attr:`FlowMap.smooth`)
    smooth = False

    def force(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        """f_sim [N], positive in the opening direction."""
        raise NotImplementedError

    def opening_knots(self) -> np.ndarray:
        """Openings [m] where the map has a kink along u (at a fixed flow, or Δp): none for a
        smooth map. A fit's tables of the map put nodes there
        (:mod:`surrogate.solver.map_tables`)."""
        return np.empty(0)

    def extrapolation_reasons(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        """Why a query lies outside the map's data (bit flags of :mod:`.coverage`, 0 inside)."""
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        if self.coverage is None:
            return np.zeros(p_L.shape, dtype=np.int64)
        return self.coverage.reasons(p_L - p_B, np.full(p_L.shape, np.nan), p_B, u, fluid.nu)

    def extrapolating(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        """True where the query lies outside the map's data. Maps without data: never."""
        return self.extrapolation_reasons(p_L, p_B, u, fluid) != 0

    def flow_force(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        """The flow force [N]: f_sim less what a uniform pressure would give (p_L on the seat
        area, p_B on the back area), the part a map learns."""
        raise NotImplementedError

    def calibration_inputs(self, p_L, p_B, u, fluid: FluidState):
        """What the map's relative standard deviation of the flow force is computed from (as
        :meth:`FlowMap.calibration_inputs`); None for maps without data."""
        return None

    def relative_force_std(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray | None:
        """Standard deviation of the flow force against the valve, relative to it [-]: the
        calibrated one and :attr:`cfd_error` in quadrature; None if the map has none."""
        if self.calibration is None:
            return None
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        calibrated = self.calibration.std(*self.calibration_inputs(p_L, p_B, u, fluid))
        return np.reshape(self.against_valve(calibrated, p_B, u), p_L.shape)

    def against_valve(self, calibrated, p_B, u) -> np.ndarray:
        """Relative σ of the flow force against the valve [1] (flat) from the ``calibrated`` one
        at back pressures ``p_B`` [Pa] and openings ``u`` [m]: with the CFD's own error
        (:func:`.cfd_error.valve_sigma`), and never below what no mesh says below the smallest
        opening (a floor, as the flow's)."""
        if self.coverage is None:
            return np.hypot(calibrated, self.cfd_error)
        u = np.ravel(u)
        std = valve_sigma(calibrated, self.mesh_error_at(p_B, u),
                          gap_error(self.coverage.gaps(), u, GAP_FORCE_ERROR),
                          gap_is_floor=self.calibration_spans_gaps)
        return np.maximum(std, seat_error(self.coverage.openings, u, SEAT_FORCE_ERROR))

    def mesh_error_at(self, p_B, u) -> np.ndarray:
        """Relative σ of the flow force [1] that the CFD's meshes and cavitation model put on
        the map at back pressures ``p_B`` [Pa] and openings ``u`` [m] (flat): :attr:`cfd_error`,
        the meshes' biases as the map bridges them (:func:`.cfd_error.mesh_bias_share`), and
        away from the samples' central back pressure what the cavitation model may miss
        (:func:`.cfd_error.cavitation_error`)."""
        p_B, u = np.ravel(p_B), np.ravel(u)
        if self.coverage is None:
            return np.full(p_B.shape, self.cfd_error)
        bias = self.cfd_error * mesh_bias_share(self.coverage.openings, u)
        return np.hypot(bias, cavitation_error(self.coverage.central_back_pressure, p_B))

    def force_std(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray | None:
        """Standard deviation of f_sim [N] against the valve (that of its flow force), or None if
        the map has none."""
        relative = self.relative_force_std(p_L, p_B, u, fluid)
        if relative is None:
            return None
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        return np.abs(self.flow_force(p_L, p_B, u, fluid)) * relative

    def query(self, p_L, p_B, u, fluid: FluidState) -> MapResult:
        """Force, extrapolation flags and (if any) standard deviation at the query points."""
        return MapResult(self.force(p_L, p_B, u, fluid), self.extrapolating(p_L, p_B, u, fluid),
                         self.force_std(p_L, p_B, u, fluid))
