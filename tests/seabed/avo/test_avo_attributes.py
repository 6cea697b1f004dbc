"""AVO attributes (docs/avo.md) against hand computations and scipy."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from clbeam.errors import OptionError
from clbeam.seabed.avo import attributes as at

INC = np.arange(0.5, 85.0, 1.0)  # bins 0.5 ... 84.5 deg incidence (grazing 89.5 ... 5.5)


def test_ranges_select_the_spec_grazing_bins():
    # near: grazing (65, 90] = incidence [0, 25) -> bins 0.5..24.5 (25 bins);
    # far: (35, 65] -> incidence [25, 55) -> 25.5..54.5 (30 bins);
    # outer: [5, 35] -> incidence [55, 85] -> 55.5..84.5 (30 bins).
    near = at.range_mask(INC, at.NEAR_RANGE_DEG)
    far = at.range_mask(INC, at.FAR_RANGE_DEG)
    outer = at.range_mask(INC, at.OUTER_RANGE_DEG)
    assert (INC[near].min(), INC[near].max(), near.sum()) == (0.5, 24.5, 25)
    assert (INC[far].min(), INC[far].max(), far.sum()) == (25.5, 54.5, 30)
    assert (INC[outer].min(), INC[outer].max(), outer.sum()) == (55.5, 84.5, 30)


@settings(max_examples=200, deadline=None)
@given(st.floats(min_value=5.0, max_value=90.0))
def test_ranges_partition_grazing_5_to_90(grazing):
    inc = np.array([90.0 - grazing])
    hits = sum(int(at.range_mask(inc, r)[0]) for r in (at.NEAR_RANGE_DEG, at.FAR_RANGE_DEG, at.OUTER_RANGE_DEG))
    assert hits == 1


def test_linear_response_gives_exact_slopes_intercepts_and_means():
    # S = -20 + 0.3 * grazing (dB), grazing = 90 - incidence.
    s = -20.0 + 0.3 * (90.0 - INC)
    a = at.angular_attributes(INC, s)
    assert a.near_slope_db_per_deg == pytest.approx(0.3, abs=1e-10)
    assert a.far_slope_db_per_deg == pytest.approx(0.3, abs=1e-10)
    assert a.near_intercept_db == pytest.approx(-20 + 0.3 * 80, abs=1e-10)  # 4.0 dB
    assert a.far_intercept_db == pytest.approx(-20 + 0.3 * 55, abs=1e-10)  # -3.5 dB
    # Means: mean incidence 12.5 / 40 / 70 -> grazing 77.5 / 50 / 20.
    assert a.near_mean_db == pytest.approx(-20 + 0.3 * 77.5, abs=1e-10)  # 3.25
    assert a.far_mean_db == pytest.approx(-20 + 0.3 * 50, abs=1e-10)  # -5.0
    assert a.outer_mean_db == pytest.approx(-20 + 0.3 * 20, abs=1e-10)  # -14.0
    assert (a.near_incidence_deg, a.far_incidence_deg) == pytest.approx((12.5, 40.0))


def test_gradient_intercept_hand_example():
    # Near = -12 dB at 12.5 deg, Far = -20 dB at 40 deg.
    # sin^2 12.5 = 0.046846, sin^2 40 = 0.413176;
    # B = (-20 + 12)/(0.413176 - 0.046846) = -8/0.366330 = -21.8382 dB,
    # A = (-32)/2 - B (0.460022)/2 = -16 + 5.02301 = -10.97699 dB.
    a, b = at.gradient_intercept(-12.0, -20.0, 12.5, 40.0)
    assert b == pytest.approx(-21.8382, abs=1e-4)
    assert a == pytest.approx(-10.9770, abs=1e-4)
    # Equivalent reading: the line A + B sin^2 phi passes through both means.
    assert a + b * math.sin(math.radians(12.5)) ** 2 == pytest.approx(-12.0, abs=1e-12)
    assert a + b * math.sin(math.radians(40.0)) ** 2 == pytest.approx(-20.0, abs=1e-12)


def test_attributes_use_range_means_and_mean_incidence():
    s = -30.0 + 15.0 * np.cos(np.radians(INC)) ** 4
    a = at.angular_attributes(INC, s)
    near, far = INC < 25, (INC > 25) & (INC < 55)
    a_ref, b_ref = at.gradient_intercept(s[near].mean(), s[far].mean(), INC[near].mean(), INC[far].mean())
    assert (a.intercept_a_db, a.gradient_b_db) == pytest.approx((a_ref, b_ref), abs=1e-12)


def test_nan_bins_are_skipped_and_sparse_ranges_give_nan():
    s = -20.0 + 0.3 * (90.0 - INC)
    s[INC < 24] = np.nan  # near range left with one bin (24.5)
    a = at.angular_attributes(INC, s)
    assert math.isnan(a.near_mean_db) and math.isnan(a.near_slope_db_per_deg)
    assert math.isnan(a.intercept_a_db)
    assert a.far_mean_db == pytest.approx(-5.0, abs=1e-10)


def test_background_trend_matches_scipy_linregress():
    rng = np.random.default_rng(3)
    a = rng.uniform(-30, -10, 40)
    b = 0.8 * a + 5 + rng.normal(0, 1, 40)
    g, d = at.background_trend(a, b)
    ref = stats.linregress(a, b)
    assert (g, d) == pytest.approx((ref.slope, ref.intercept), rel=1e-10)


def test_fluid_factor_is_signed_orthogonal_distance():
    g, d = 0.8, 5.0
    pts = np.array([[-20.0, -8.0], [-12.0, -9.0], [-25.0, -15.0]])
    ff = at.fluid_factor(pts[:, 0], pts[:, 1], g, d)
    # Independent: distance to the line through (0, d) with direction (1, g),
    # via the 2-D cross product, signed + above the line.
    p0, u = np.array([0.0, d]), np.array([1.0, g]) / math.hypot(1.0, g)
    for (x, y), f in zip(pts, ff):
        v = np.array([x, y]) - p0
        dist = u[0] * v[1] - u[1] * v[0]
        assert f == pytest.approx(dist, abs=1e-12)
    assert at.fluid_factor(-10.0, g * -10.0 + d, g, d) == pytest.approx(0.0, abs=1e-12)
    assert at.product(-10.0, 2.5) == -25.0


def test_errors_are_one_line_option_errors():
    with pytest.raises(OptionError, match="equal length"):
        at.angular_attributes(INC, INC[:-1])
    with pytest.raises(OptionError, match="background trend"):
        at.background_trend([1.0], [2.0])
