"""The CFD maps calibrated to the bench within the CFD's own error: a correction per opening.

A real valve differs from its CFD: each mesh carries its own error (the paper's Table 4 moved Δp
by up to 1.9 % with refinement), and where the CFD has no openings the valve follows its own
curve. A diagnosis allows for that error as penalised discrepancy terms
(:mod:`surrogate.fitting.discrepancy`) and adds only what they cannot explain. Once nothing more
is found, what the discrepancy did explain is itself worth keeping: it is the maps' error that
this bench measured. These two effects carry it into the model, as map corrections:

* :class:`CalibratedFlowForce`: the force map's flow force times 1 + m(u);
* :class:`CalibratedDischarge`: the flow map's discharge coefficient times 1 + d(u);

m and d are piecewise linear in ln u through their values at the knots of the discrepancy (the
CFD's sampled openings, points inside its unsampled gaps, one below its smallest opening), and
held beyond the end knots: an error shared by nearby openings, not by far ones. Their values are
fitted with a prior, each N(0, σ²) with σ the maps' relative error near that knot (their
calibrated σ and the CFD's own error in quadrature), so that the maps move as far as their own
uncertainty allows and no further (:mod:`surrogate.workbench.bench_calibration`). The workflow fits
them last, after the physics, and keeps them only when they predict held-out runs better.
"""

from __future__ import annotations

import numpy as np

from .shapes import KNOTS, VARIABLES, ShapeFreeEffect


def hat_basis(knots: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(n, len(knots)) hat functions in ln u through ``knots`` [m] at ``u`` [m], held beyond the
    end knots: row i weighs the knots around u_i linearly in ln u and sums to one."""
    grid = np.log(np.asarray(knots, float))
    x = np.log(np.clip(np.asarray(u, float), knots[0], knots[-1]))
    index = np.clip(np.searchsorted(grid, x) - 1, 0, len(grid) - 2)
    t = (x - grid[index]) / (grid[index + 1] - grid[index])
    basis = np.zeros((x.size, len(grid)))
    rows = np.arange(x.size)
    basis[rows, index] = 1.0 - t
    basis[rows, index + 1] = t
    return basis


class _PerOpening(ShapeFreeEffect):
    """A relative map correction of the opening, piecewise linear in ln u through one value per
    knot; the knots are the discrepancy's (:func:`surrogate.fitting.discrepancy.knots`)."""

    shape_free = False
    candidate = False  # no diagnosis candidate: the workflow fits it once, last, with its prior
    smoothed = False  # its prior is the calibration's (surrogate.workbench.bench_calibration)
    category = "map correction"
    variable = VARIABLES["u"]
    value_unit = "1"
    value_limit = 0.5
    validity = ("Between the knots the maps' error is taken as linear in ln u, and held beyond "
                "the end knots; fitted within the maps' own uncertainty.")

    def __init__(self, knots=None, **values: float):
        """The correction off on ``knots`` [m] (default: spread evenly in ln u over the valve's
        stroke, to be replaced by :meth:`on_knots`); ``values`` [1] by parameter name."""
        super().__init__(np.geomspace(0.01e-3, 1e-3, KNOTS) if knots is None else knots,
                         **values)

    @classmethod
    def for_parameters(cls, names: list[str]) -> "_PerOpening":
        count = sum(1 for name in names if name.startswith("knot_"))
        return cls(np.geomspace(0.01e-3, 1e-3, count or KNOTS))

    @classmethod
    def basis_size(cls, knots: int) -> int:
        return knots

    def basis(self, x: np.ndarray) -> np.ndarray:
        return hat_basis(self.knots, x)

    def shape(self, x: np.ndarray) -> np.ndarray:
        knots, log_knots, coefficients = self._lines()
        return np.interp(np.log(np.clip(np.asarray(x, float), knots[0], knots[-1])),
                         log_knots, coefficients)

    def _lines(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The knots [m], their logarithms and the values at them, found again only when a
        parameter has changed (as :meth:`.shapes.ShapeFreeEffect._spline` keeps its spline): a
        replay asks the shape at every balance, and sorting the knots each time cost more than
        the interpolation."""
        values = tuple(parameter.value for parameter in self.params.values())
        cached = getattr(self, "_lines_cached", None)
        if cached is None or cached[0] != values:
            knots = self.knots
            cached = self._lines_cached = (values, (knots, np.log(knots), self.coefficients))
        return cached[1]

    def roughness(self) -> np.ndarray:
        """Each value on its own: the fit's prior is a ridge (σ per knot), not a smoothness."""
        return np.eye(len(self.coefficients))


class CalibratedFlowForce(_PerOpening):
    """The force map's flow force times 1 + m(u): the CFD's flow force corrected per opening by
    what the bench measured, within the CFD's own error."""

    name = "calibrated_flow_force"
    kind = "force"
    title = "the flow force calibrated to the bench per opening"
    quantity = "flow-force change"
    formula = "{shape} * state.flow_force"

    def force(self, state) -> np.ndarray:
        return self.shape(state.u) * state.flow_force


class CalibratedDischarge(_PerOpening):
    """The flow map's discharge coefficient times 1 + d(u): the CFD's flow corrected per opening
    by what the bench measured, within the CFD's own error."""

    name = "calibrated_discharge"
    kind = "flow"
    title = "the discharge coefficient calibrated to the bench per opening"
    quantity = "discharge change"
    formula = "q / (1.0 + {shape})"

    def restriction_flow(self, q: np.ndarray, state) -> np.ndarray:
        return q / (1.0 + self.shape(state.u))


#: the calibration's effects, in the order the workflow fits them
CALIBRATIONS = (CalibratedFlowForce, CalibratedDischarge)
