"""Unit conversions round-trip and agree with the textbook factors."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from surrogate.core.units import from_si, known_units, to_si

finite = st.floats(min_value=-1e12, max_value=1e12, allow_nan=False, allow_infinity=False)


@given(value=finite, unit=st.sampled_from(known_units()))
def test_scalar_round_trip(value, unit):
    assert math.isclose(from_si(to_si(value, unit), unit), value, rel_tol=1e-12, abs_tol=1e-9)


@given(values=arrays(np.float64, st.integers(1, 20), elements=finite),
       unit=st.sampled_from(known_units()))
def test_array_round_trip(values, unit):
    np.testing.assert_allclose(from_si(to_si(values, unit), unit), values, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("value, unit, si", [
    (1.0, "bar", 1e5), (12.0, "L/min", 2e-4), (0.63, "mm", 6.3e-4), (10.7, "mm^2", 1.07e-5),
    (46.0, "cSt", 4.6e-5), (20.0, "degC", 293.15), (5e-2, "N/bar", 5e-7),
    # the units a bench log may come in: NIST SP 811 factors
    (1.0, "psi", 6894.757), (100.0, "kPa", 1e5), (10.0, "MPa", 1e7), (1.0, "gpm", 6.30902e-5),
    (32.0, "degF", 273.15), (212.0, "degF", 373.15), (-40.0, "degF", 233.15)])
def test_textbook_factors(value, unit, si):
    assert to_si(value, unit) == pytest.approx(si)


def test_unknown_unit_is_named():
    with pytest.raises(ValueError, match="unknown unit 'furlong'"):
        to_si(1.0, "furlong")
