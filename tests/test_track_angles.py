"""Angle wrapping stays in its half-open range, even for angles a rounding error off a bound."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from aeromag._core.angles import wrap360_deg, wrap_deg, wrap_rad

_finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)


def test_just_below_the_lower_bound_wraps_to_it_not_to_the_upper():
    # np.mod(-2.8e-14, 360) is 360.0: the old wrap gave +180.0 for -180 - 2.8e-14
    assert wrap_deg(-180.0 - 2.8e-14) == -180.0
    assert wrap_deg(np.nextafter(-180.0, -200.0)) == -180.0
    assert wrap_rad(np.nextafter(-np.pi, -4.0)) == -np.pi
    assert wrap360_deg(-1e-14) == 0.0
    assert wrap_deg(180.0) == -180.0 and wrap_deg(-180.0) == -180.0


@settings(max_examples=300, deadline=None)
@given(_finite, st.floats(min_value=-1e-9, max_value=1e-9, allow_nan=False))
def test_wrap_ranges_half_open_and_angle_preserved(a, eps):
    for x in (a, a + eps, -180.0 + eps, 180.0 + eps, 540.0 + eps, eps):
        d = float(wrap_deg(x))
        assert -180.0 <= d < 180.0
        assert abs(np.sin(np.radians(d)) - np.sin(np.radians(x))) < 1e-6
        assert abs(np.cos(np.radians(d)) - np.cos(np.radians(x))) < 1e-6
        h = float(wrap360_deg(x))
        assert 0.0 <= h < 360.0
        assert abs(np.cos(np.radians(h)) - np.cos(np.radians(x))) < 1e-6
        r = float(wrap_rad(np.radians(x)))
        assert -np.pi <= r < np.pi
        assert abs(np.sin(r) - np.sin(np.radians(x))) < 1e-6


def test_arrays_keep_shape():
    x = np.array([[-180.0 - 1e-14, 179.9999], [360.0, -720.0]])
    assert wrap_deg(x).shape == (2, 2)
    assert np.all((wrap_deg(x) >= -180) & (wrap_deg(x) < 180))
