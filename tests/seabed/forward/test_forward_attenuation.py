"""Attenuation laws and the linearisation of Rakotonarivo Table 1 (eqs. 3–4)."""

import numpy as np
import pytest

from clbeam.errors import OptionError
from clbeam.seabed.forward import (
    LinearAttenuation,
    PowerLawAttenuation,
    attenuation_np_per_m,
    linearise_attenuation,
)

# Table 1 rows whose printed linear coefficients are the 1-10 kHz least-squares fit of k_p f^n:
# (label, k_p dB/m/kHz^n, n, printed k_p', decimals of k_p', printed b, decimals of b).
REPRODUCED = [
    ("medium sand [6]", 0.41, 1.00, 0.41, 2, 0.0, 3),
    ("fine sand [7]", 0.13, 1.26, 0.25, 2, -0.226, 3),
    ("fine sand [6]", 0.45, 1.04, 0.50, 2, -0.084, 3),
    ("very fine sand [7] n=1.00", 0.56, 1.00, 0.56, 2, 0.0, 3),
    ("silt [7]", 0.30, 1.05, 0.34, 2, -0.071, 3),
    ("clayey silt [6]", 0.19, 0.94, 0.16, 2, 0.046, 3),
]


def half_unit(decimals):
    """Half a unit in the last printed digit: the rounding error of a correctly printed value."""
    return 0.5 * 10.0 ** -decimals


def test_power_law_and_linear_law_give_the_printed_units():
    # eq. 3 with f in kHz: 0.1 dB/m/kHz at 5 kHz is 0.5 dB/m; eq. 4: 0.4*5 - 0.1 = 1.9 dB/m.
    assert PowerLawAttenuation(0.1, 1.0).db_per_m(5000.0) == pytest.approx(0.5, rel=1e-15)
    assert PowerLawAttenuation(0.2, 0.5).db_per_m(4000.0) == pytest.approx(0.2 * 2.0, rel=1e-15)
    assert LinearAttenuation(0.4, -0.1).db_per_m(5000.0) == pytest.approx(1.9, rel=1e-15)
    # a fitted line with b < 0 would be a gain below -b/k_p' = 250 Hz: clipped at 0 dB/m
    assert LinearAttenuation(0.4, -0.1).db_per_m(100.0) == 0.0
    # dB to nepers: 20 log10(e) = 8.686 dB per neper
    assert attenuation_np_per_m(PowerLawAttenuation(8.685889638, 1.0), 1000.0) == pytest.approx(1.0, rel=1e-9)


@pytest.mark.parametrize("k_p,n", [(0.93, 0.96), (1.46, 0.63), (0.055, 1.12), (2.6, 0.57), (1.0, 0.4), (1.0, 1.4)])
def test_closed_form_fit_equals_dense_numpy_polyfit(k_p, n):
    f = np.linspace(1.0, 10.0, 200001)
    slope, intercept = np.polyfit(f, k_p * f ** n, 1)
    line = linearise_attenuation(k_p, n)
    # polyfit on N uniform samples is a Riemann sum of the continuous normal equations: its error is
    # O(1/N) relative, 1e-5 k_p for N = 2e5 (measured 1.1e-5 at worst); 5e-5 k_p leaves room for the constant.
    assert line.slope_db_m_khz == pytest.approx(slope, abs=5e-5 * k_p)
    assert line.intercept_db_m == pytest.approx(intercept, abs=5e-5 * k_p)


def test_an_exactly_linear_law_is_its_own_fit():
    line = linearise_attenuation(0.37, 1.0)
    assert line.slope_db_m_khz == pytest.approx(0.37, abs=1e-14)
    assert line.intercept_db_m == pytest.approx(0.0, abs=1e-13)


@pytest.mark.parametrize("label,k_p,n,slope,slope_dec,b,b_dec", REPRODUCED, ids=[r[0] for r in REPRODUCED])
def test_table1_rows_reproduce_to_their_printed_digits(label, k_p, n, slope, slope_dec, b, b_dec):
    line = linearise_attenuation(k_p, n)
    assert abs(line.slope_db_m_khz - slope) <= half_unit(slope_dec) + 1e-12
    assert abs(line.intercept_db_m - b) <= half_unit(b_dec) + 1e-12


@pytest.mark.parametrize("k_p,n,printed_b", [(0.27, 1.17, -0.265), (0.38, 1.11, -0.219), (1.18, 0.57, 1.147),
                                             (1.46, 0.63, 1.337), (0.055, 1.12, -0.035)])
def test_table1_intercepts_of_the_other_rows_reproduce(k_p, n, printed_b):
    # very fine sand [7] and [6], relatively homogeneous sand (k_p = 1.18 end), poorly sorted,
    # fine-grained unconsolidated: b to 3 decimals
    assert abs(linearise_attenuation(k_p, n).intercept_db_m - printed_b) <= half_unit(3) + 1e-12


@pytest.mark.parametrize("k_p,n,printed,decimals,which", [
    (0.27, 1.17, 0.41, 2, "slope"),      # fit 0.4174: printed 0.41 (truncated, not rounded)
    (0.38, 1.11, 0.51, 2, "slope"),      # fit 0.5049: printed 0.51
    (2.60, 0.57, 2.526, 3, "intercept"),  # fit 2.5273: printed 2.526
    (0.055, 1.12, 0.076, 3, "slope"),     # fit 0.0750: printed 0.076
])
def test_table1_last_digit_slips(k_p, n, printed, decimals, which):
    line = linearise_attenuation(k_p, n)
    value = line.slope_db_m_khz if which == "slope" else line.intercept_db_m
    # outside the rounding interval of the printed digit, but within one and a half units of it:
    # a slip in the last digit, not a different fit
    assert half_unit(decimals) < abs(value - printed) <= 3 * half_unit(decimals)


def test_table1_coarse_sand_row_is_the_fit_of_k_p_0_53_not_0_93():
    printed_slope, printed_b = 0.477, 0.087
    fit = linearise_attenuation(0.93, 0.96)
    # the printed row k_p = 0.93 does not give the printed line: 0.837 and 0.153
    assert abs(fit.slope_db_m_khz - printed_slope) > 0.3 and abs(fit.intercept_db_m - printed_b) > 0.05
    # the fit is linear in k_p, so a wrong k_p scales slope and intercept by one factor; a different
    # band or exponent would not.  Both printed/fitted ratios are 0.570: the rounding of the printed
    # values (+-0.0005) bounds the ratios' spread by 0.0005/0.477 + 0.0005/0.087 = 0.0068 (relative)
    r_slope, r_b = printed_slope / fit.slope_db_m_khz, printed_b / fit.intercept_db_m
    assert r_slope == pytest.approx(r_b, rel=0.0068)
    assert 0.93 * r_slope == pytest.approx(0.53, abs=0.005)
    # and k_p = 0.53 reproduces the printed line to its three decimals
    line = linearise_attenuation(0.53, 0.96)
    assert abs(line.slope_db_m_khz - printed_slope) <= half_unit(3)
    assert abs(line.intercept_db_m - printed_b) <= half_unit(3)
    # the row's own measurement band (7-14 kHz) scales the two coefficients differently: not the cause
    band = linearise_attenuation(0.93, 0.96, band_khz=(7.0, 14.0))
    assert abs(printed_slope / band.slope_db_m_khz - printed_b / band.intercept_db_m) > 0.1


def test_table1_poorly_sorted_row_slope_does_not_match_its_own_intercept():
    # printed: k_p = 1.46, n = 0.63 +- 0.33  ->  k_p' = 0.79 +- 0.64, b = 1.337
    fit = linearise_attenuation(1.46, 0.63)
    assert abs(fit.intercept_db_m - 1.337) <= half_unit(3)          # the intercept is the n = 0.63 fit ...
    assert abs(fit.slope_db_m_khz - 0.79) > 0.25                     # ... whose slope is 0.511, not 0.79
    lo = linearise_attenuation(1.46, 0.63 - 0.33).slope_db_m_khz
    hi = linearise_attenuation(1.46, 0.63 + 0.33).slope_db_m_khz
    # the printed interval [0.15, 1.43] starts at the n = 0.30 fit (0.147) but the n = 0.96 fit ends
    # at 1.314, and the interval's centre would be 0.73: the centre 0.79 reproduces neither reading
    assert abs(lo - (0.79 - 0.64)) <= half_unit(2)
    assert abs(hi - (0.79 + 0.64)) > 0.1
    assert abs(0.5 * (lo + hi) - 0.79) > 0.05


@pytest.mark.parametrize("k_p,n,dn,printed_pm", [(0.13, 1.26, 0.13, 0.08), (0.45, 1.04, 0.07, 0.09),
                                                 (0.38, 1.11, 0.06, 0.08)])
def test_table1_plus_minus_is_half_the_slope_range_over_n_plus_minus_dn(k_p, n, dn, printed_pm):
    lo = linearise_attenuation(k_p, n - dn).slope_db_m_khz
    hi = linearise_attenuation(k_p, n + dn).slope_db_m_khz
    assert abs(0.5 * (hi - lo) - printed_pm) <= half_unit(2)


def test_table1_relatively_homogeneous_sand_slope_range_spans_k_p_and_n():
    # "1.18 to 2.6, n = 0.57 +- 0.05" -> "0.29 to 0.88": the ends are k_p = 1.18 with n = 0.52 and
    # k_p = 2.6 with n = 0.62
    assert abs(linearise_attenuation(1.18, 0.52).slope_db_m_khz - 0.29) <= half_unit(2)
    assert abs(linearise_attenuation(2.60, 0.62).slope_db_m_khz - 0.88) <= half_unit(2)


def test_bad_attenuation_parameters_raise_option_errors():
    with pytest.raises(OptionError, match="k_p"):
        PowerLawAttenuation(-0.1, 1.0)
    with pytest.raises(OptionError, match="exponent"):
        PowerLawAttenuation(0.1, float("nan"))
    with pytest.raises(OptionError, match="band"):
        linearise_attenuation(0.1, 1.0, band_khz=(10.0, 1.0))
