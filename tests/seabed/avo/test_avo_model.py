"""Backscatter model pieces against closed forms, scipy and the validation tables."""

import math

import numpy as np
import pytest
from scipy import integrate, special

from clbeam.errors import OptionError
from clbeam.seabed.avo import model as m
from clbeam.seabed.avo.sediment import SedimentParams, sediment_from_grain_size

MEDIUM_SAND, FINE_SAND, SILT = 1.5, 2.5, 6.0


# ----------------------------------------------------------------- reflection
def test_rayleigh_normal_incidence_lossless_closed_form():
    # (rho nu - 1)/(rho nu + 1); delta = 1e-12 makes the loss negligible.
    s = SedimentParams(rho=1.8, nu=1.2, delta=1e-12, w2_cm4=0.004)
    r = m.reflection_coefficient(90.0, s)
    assert r.real == pytest.approx((1.8 * 1.2 - 1) / (1.8 * 1.2 + 1), abs=1e-9)
    assert abs(r.imag) < 1e-9


def test_rayleigh_normal_incidence_lossy_closed_form():
    # At nadir P = kappa: R = (rho - kappa)/(rho + kappa) = (rho nu - 1 - i delta)/(rho nu + 1 + i delta).
    s = sediment_from_grain_size(MEDIUM_SAND)
    expect = (s.rho * s.nu - 1 - 1j * s.delta) / (s.rho * s.nu + 1 + 1j * s.delta)
    assert m.reflection_coefficient(90.0, s) == pytest.approx(expect, abs=1e-14)


def test_total_reflection_below_critical_angle_lossless():
    s = SedimentParams(rho=1.8446, nu=1.1782, delta=1e-12, w2_cm4=0.004)
    # arccos(1/1.1782) = arccos(0.848752) = 31.924 deg.
    assert m.critical_angle_deg(s) == pytest.approx(math.degrees(math.acos(1 / 1.1782)), abs=1e-12)
    assert m.critical_angle_deg(s) == pytest.approx(31.924, abs=0.0005)
    below = np.array([5.0, 15.0, 30.0])
    assert np.abs(m.reflection_coefficient(below, s)) == pytest.approx(1.0, abs=1e-9)
    assert np.isnan(m.critical_angle_deg(sediment_from_grain_size(SILT)))  # nu < 1


# Reflection loss -20 log|R| (dB) at grazing 90/60/30/20/10 deg (notes).
LOSS_ANGLES = [90, 60, 30, 20, 10]
LOSS_TABLE = {
    # Printed to 0.01 dB: rounding 0.005; rho, nu, delta from the regressions
    # agree with the table to its last decimal -> 0.01 dB covers both.
    MEDIUM_SAND: ([8.64, 7.97, 1.15, 0.56, 0.37], 0.01),
    FINE_SAND: ([12.66, 12.00, 6.50, 1.35, 0.66], 0.01),
    # Silt: rho nu - 1 = 0.134 makes the loss change by 8.686*2/(x^2-1) = 61 dB
    # per unit of rho nu (0.02 dB per 0.03 %); the table sits 0.02 dB below
    # us at every steep angle, i.e. it used rho nu higher by ~0.03 % (input
    # rounding in the source).  Tolerance 0.03 dB.
    SILT: ([24.01, 24.30, 26.89, 32.55, 20.49], 0.03),
}


@pytest.mark.parametrize("mz", sorted(LOSS_TABLE))
def test_reflection_loss_matches_table(mz):
    table, tol = LOSS_TABLE[mz]
    got = m.reflection_loss_db(LOSS_ANGLES, sediment_from_grain_size(mz))
    assert np.max(np.abs(got - table)) <= tol


# ----------------------------------------------------------------- Kirchhoff
@pytest.mark.parametrize("q", [1e-4, 1e-2, 0.3, 1.0, 10.0, 1e3])
def test_kirchhoff_integral_closed_form_alpha_half(q):
    # alpha = 1/2: -d/dq of the Laplace transform 1/sqrt(1+q^2) of J0.
    assert m.kirchhoff_integral(q, 0.5) == pytest.approx(q / (1 + q * q) ** 1.5, rel=1e-9)


@pytest.mark.parametrize("q", [0.05, 0.3, 1.0, 10.0, 1e3])
def test_kirchhoff_integral_closed_form_alpha_one(q):
    # alpha = 1: Hankel transform of a Gaussian, exp(-1/(4q))/(2q).
    assert m.kirchhoff_integral(q, 1.0) == pytest.approx(math.exp(-1 / (4 * q)) / (2 * q), rel=1e-9, abs=1e-15)


@pytest.mark.parametrize("q", [0.02, 0.2, 2.0, 50.0])
def test_kirchhoff_integral_matches_scipy_quad_for_handbook_exponent(q):
    # alpha = 0.625 (gamma = 3.25): adaptive quadrature over the scaled
    # integrand, split where it changes character; both agree to ~1e-10.
    a = 0.625
    b = q ** (-1 / (2 * a))
    pts = np.logspace(-4, math.log10(40 ** (1 / (2 * a))), 25)
    ref = sum(integrate.quad(lambda s: math.exp(-s ** (2 * a)) * special.j0(b * s) * s, lo, hi,
                             limit=2000, epsabs=0, epsrel=1e-12)[0]
              for lo, hi in zip(np.r_[0, pts[:-1]], pts)) * q ** (-1 / a)
    assert m.kirchhoff_integral(q, a) == pytest.approx(ref, rel=1e-8)


def test_kirchhoff_series_and_quadrature_agree_at_switch():
    # Just above and below b = 100 the two evaluations must agree (series
    # truncation and quadrature error are both < 1e-8 there).
    a = 0.625
    for b in (90.0, 110.0):
        q = b ** (-2 * a)
        series = m._kirchhoff_series(np.array([q]), a)[0]
        quad = q ** (-1 / a) * m._kirchhoff_scaled(b, a)
        assert series == pytest.approx(quad, rel=1e-8)


def test_structure_constant_matches_structure_function_integral():
    # D(r) = 2 int W(K) (1 - cos K.r) d^2K = 4 pi w2 int K^(1-gamma) (1 - J0(K r)) dK
    # must equal C_h^2 r^(2 alpha).
    s = sediment_from_grain_size(MEDIUM_SAND)
    r = 0.3
    f = lambda x: x ** (1 - s.gamma) * (1 - special.j0(x))  # noqa: E731  (K r = x)
    integral = sum(integrate.quad(f, lo, hi, limit=500)[0] for lo, hi in [(0, 1), (1, 50)])
    integral += integrate.quad(lambda x: x ** (1 - s.gamma), 50, np.inf)[0]  # J0 tail ~ 0 on average
    tail_j0 = integrate.quad(lambda x: -x ** (1 - s.gamma) * special.j0(x), 50, 2000, limit=4000)[0]
    d = 4 * math.pi * s.w2_si * r ** (s.gamma - 2) * (integral + tail_j0)
    assert m.structure_constant(s) * r ** (s.gamma - 2) == pytest.approx(d, rel=1e-4)


def test_kirchhoff_nadir_closed_form():
    # sigma_kr(90) = |R(90)|^2/(8 pi) Gamma(1/a)/(2a) (C_h^2 2^(1-2a) k^(2-2a))^(-1/a).
    s = sediment_from_grain_size(MEDIUM_SAND)
    f, a = 20e3, 0.625
    k = 2 * math.pi * f / 1500
    c = m.structure_constant(s) * 2 ** (1 - 2 * a) * k ** (2 - 2 * a)
    r90 = abs(m.reflection_coefficient(90.0, s))
    expect = r90 ** 2 / (8 * math.pi) * math.gamma(1 / a) / (2 * a) * c ** (-1 / a)
    assert m.kirchhoff_cross_section(90.0, s, f) == pytest.approx(expect, rel=1e-7)
    # ... and it is continuous there: 89.99 deg within 1e-4.
    assert m.kirchhoff_cross_section(89.99, s, f) == pytest.approx(expect, rel=1e-4)


def test_kirchhoff_cross_section_spline_path_matches_direct_integral():
    # Inside the model, I(q) comes from a cached spline of the scaled
    # integral; here the definition |R90|^2/(8 pi sin^2 cos^2) I(q) with
    # the direct quadrature of kirchhoff_integral, 1e-7 (spline ~1e-9).
    s = sediment_from_grain_size(MEDIUM_SAND)
    f, a = 9e3, 0.625
    k = 2 * math.pi * f / 1500
    ang = np.array([25.0, 40.0, 55.0, 70.0, 85.0, 89.0])
    t = np.radians(ang)
    q = np.sin(t) ** 2 * np.cos(t) ** (-2 * a) * m.structure_constant(s) * 2 ** (1 - 2 * a) * k ** (2 - 2 * a)
    r90 = abs(m.reflection_coefficient(90.0, s))
    expect = r90 ** 2 / (8 * math.pi * np.sin(t) ** 2 * np.cos(t) ** 2) * m.kirchhoff_integral(q, a)
    assert m.kirchhoff_cross_section(ang, s, f) == pytest.approx(expect, rel=1e-7)


def test_kirchhoff_small_q_limit_is_perturbation_with_nadir_reflection():
    # For q -> 0, I(q) -> c1 q and sigma_kr -> 4 k^4 |R(90)|^2 W(2k cos theta)
    # (Gamma(2-a) = a(1-a)|Gamma(-a)| makes the constants cancel).  At 8 deg
    # grazing in silt q ~ 1e-5, so the next series term is ~1e-4 relative.
    s = sediment_from_grain_size(SILT)
    f = 5e3
    k = 2 * math.pi * f / 1500
    th = math.radians(8.0)
    r90 = abs(m.reflection_coefficient(90.0, s))
    w = s.w2_si * (2 * k * math.cos(th)) ** (-s.gamma)
    assert m.kirchhoff_cross_section(8.0, s, f) == pytest.approx(4 * k ** 4 * r90 ** 2 * w, rel=1e-3)


# ----------------------------------------------------------------- perturbation and join
def test_perturbation_g_form_equals_jackson_y_form():
    # k^4/4 |1+R|^4 |G|^2 W  ==  4 k^4 sin^4 |Y|^2 W (Jackson et al. 1986),
    # an algebraic identity; checked at arbitrary angles.
    s = sediment_from_grain_size(FINE_SAND)
    ang = np.array([3.0, 17.0, 25.4, 41.0, 77.0])
    f = 12e3
    k = 2 * math.pi * f / 1500
    h = m.perturbation_kernel_ratio(ang, s)
    r90 = abs(m.reflection_coefficient(90.0, s))
    w = s.w2_si * (2 * k * np.cos(np.radians(ang))) ** (-s.gamma)
    y_form = 4 * k ** 4 * (h * r90) ** 2 * w
    assert m.perturbation_cross_section(ang, s, f) == pytest.approx(y_form, rel=1e-10)


def test_roughness_join_is_kirchhoff_at_nadir_and_perturbation_at_low_slope():
    s = sediment_from_grain_size(MEDIUM_SAND)
    f = 20e3
    # Nadir: h(90) = 1 exactly, so the join equals sigma_kr.
    assert m.roughness_cross_section(90.0, s, f) == pytest.approx(m.kirchhoff_cross_section(90.0, s, f), rel=1e-12)
    # 10 deg grazing: q = sin^2 cos^-1.25 C = 0.0301*1.02*0.0364 ~ 1.1e-3, and
    # I(q)/(c1 q) = 1 - O(q^(...)): within 1 % of sigma_pr.
    assert m.roughness_cross_section(10.0, s, f) == pytest.approx(m.perturbation_cross_section(10.0, s, f), rel=0.01)
    # Everywhere: sigma_r = h^2 sigma_kr (the small-slope identity).
    ang = np.array([20.0, 50.0, 70.0, 85.0])
    h = m.perturbation_kernel_ratio(ang, s)
    expect = h ** 2 * m.kirchhoff_cross_section(ang, s, f)
    assert m.roughness_cross_section(ang, s, f) == pytest.approx(expect, rel=1e-12)


def test_volume_term_hand_computation_at_nadir():
    # At nadir P = kappa, Im P = delta/nu, so
    # sigma_v = 5 delta sigma2 |1+R|^4 / (ln10 nu rho^2 delta/nu) = 5 sigma2 |1+R|^4 / (ln10 rho^2),
    # 1 + R = 2 rho / (rho + kappa).
    s = sediment_from_grain_size(SILT)
    kappa = (1 + 1j * s.delta) / s.nu
    t = abs(2 * s.rho / (s.rho + kappa))
    expect = 5 * s.sigma2 * t ** 4 / (math.log(10) * s.rho ** 2)
    assert m.volume_cross_section(90.0, s) == pytest.approx(expect, rel=1e-12)


# ----------------------------------------------------------------- validation table
ANGLES = [5, 10, 20, 30, 45, 60, 80, 90]
# Total S_b (dB), Jackson's model, 20 kHz, c_w = 1500 m/s (notes), and the
# tolerance per cell.  The table is printed to 0.1 dB (rounding 0.05 dB).
SB_TABLE = {
    MEDIUM_SAND: [-48.0, -38.1, -29.7, -25.7, -23.6, -21.8, -11.0, -1.1],
    FINE_SAND: [-50.3, -39.8, -30.1, -25.4, -24.3, -23.3, -16.3, -1.7],
    SILT: [-41.4, -35.7, -31.8, -30.0, -28.4, -27.5, -26.5, -1.5],
}
SB_TOL = {
    # Sands below the critical angle (31.9 / 25.4 deg): the table's roughness
    # part sits under the perturbation result (0.4-0.7 dB in medium sand,
    # 1.4-3 dB in fine sand, where the volume term carries 70 % of S_b); the
    # notes report ~0.5 dB for the roughness part.  Measured totals: medium
    # sand <= 0.53 dB, fine sand <= 0.76 dB -> 0.6 and 0.8 dB.
    # 30-60 deg: volume >= 60 % of S_b; rounding 0.05 + volume-term offset
    # 0.1 dB (silt row) + roughness share -> 0.2 dB.
    # 80 deg: notes allow 1-2 dB near 80 deg (join rule); measured <= 0.12.
    # 90 deg: Kirchhoff nadir closed form; rounding 0.05 + 0.05 -> 0.1 dB.
    MEDIUM_SAND: [0.6, 0.6, 0.6, 0.2, 0.2, 0.2, 2.0, 0.1],
    FINE_SAND: [0.8, 0.8, 0.8, 0.2, 0.2, 0.2, 2.0, 0.1],
    # Silt (no critical angle): volume >= 95 % of S_b up to 60 deg; measured
    # <= 0.10 dB, i.e. rounding 0.05 plus a 0.05-0.1 dB volume offset of the
    # same sign as the reflection-loss row -> 0.15 dB.
    SILT: [0.15, 0.15, 0.15, 0.15, 0.15, 0.15, 2.0, 0.1],
}


@pytest.mark.parametrize("mz", sorted(SB_TABLE))
def test_total_backscatter_matches_validation_table(mz):
    got = m.backscatter_strength_db(ANGLES, 20e3, mz=mz, sound_speed_water_m_s=1500.0)
    diff = np.abs(got - np.array(SB_TABLE[mz]))
    assert np.all(diff <= np.array(SB_TOL[mz])), dict(zip(ANGLES, np.round(diff, 2)))


def test_mz_and_sediment_inputs_agree():
    s = sediment_from_grain_size(3.3)
    a = m.backscatter_strength_db([12.0, 50.0], 7e3, mz=3.3)
    b = m.backscatter_strength_db([12.0, 50.0], 7e3, sediment=s)
    assert np.array_equal(a, b)


def test_lambert_law_hand_values():
    # -27 + 10 log10(sin^2 30) = -27 + 20 log10(0.5) = -27 - 6.0206 = -33.0206.
    assert m.lambert_strength_db(30.0) == pytest.approx(-33.0206, abs=1e-4)
    assert m.lambert_strength_db(90.0) == pytest.approx(-27.0, abs=1e-12)


@pytest.mark.parametrize("bad", [0.0, -5.0, 90.5, float("nan")])
def test_grazing_angle_outside_range_raises(bad):
    with pytest.raises(OptionError, match="grazing_deg"):
        m.backscatter_strength_db([bad], 5e3, mz=2.0)


def test_both_or_neither_parameter_source_raises():
    with pytest.raises(OptionError, match="exactly one"):
        m.backscatter_strength_db([30.0], 5e3)
    with pytest.raises(OptionError, match="exactly one"):
        m.backscatter_strength_db([30.0], 5e3, mz=2.0, sediment=sediment_from_grain_size(2.0))
    with pytest.raises(OptionError, match="frequency_hz"):
        m.backscatter_strength_db([30.0], 0.0, mz=2.0)
