"""Sharp fluid interfaces (Rayleigh, Snell) and rough-interface factors (Rakotonarivo eqs. 5–8)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clbeam.errors import OptionError
from clbeam.seabed.forward import (
    Interface,
    Layer,
    Seabed,
    fluid_interface,
    layer_echoes,
    rayleigh_parameter,
    rayleigh_reflection,
    reflection_roughness_factor,
    snell_cosines,
    transmission_parameter,
    transmission_roughness_factor,
    water_column,
)

densities = st.floats(800.0, 3000.0)
speeds = st.floats(1300.0, 3000.0)


def two_media(rho2, c2, *, sigma=0.0, regime="small", depth=20.0):
    return Seabed((water_column(depth), Layer(math.inf, c2, rho2, top=Interface(sigma, regime))))


def test_rayleigh_coefficient_at_normal_incidence_is_the_impedance_contrast():
    # (Z2 - Z1)/(Z2 + Z1) with Z = rho c: (2.08e6 - 1.5e6)/(3.58e6) = 0.16201 (Table 2 seafloor)
    assert rayleigh_reflection(1000, 1500, 1300, 1600) == pytest.approx((2.08e6 - 1.5e6) / 3.58e6, rel=1e-15)


@settings(max_examples=60, deadline=None)
@given(rho1=densities, c1=speeds, rho2=densities, c2=speeds, angle=st.floats(0.0, 89.0))
def test_energy_flux_is_conserved_below_the_critical_angle(rho1, c1, rho2, c2, angle):
    cos = snell_cosines([c1, c2], angle)
    r, t, tp = fluid_interface(rho1, c1, cos[0], rho2, c2, cos[1])
    if cos[1].imag == 0:
        # r^2 + (Z1 cos2 / (Z2 cos1)) t^2 = 1: the normal energy flux is conserved
        flux = abs(r) ** 2 + (rho1 * c1 * cos[1].real) / (rho2 * c2 * cos[0].real) * abs(t) ** 2
        assert flux == pytest.approx(1.0, abs=1e-12)
    else:
        assert abs(r) == pytest.approx(1.0, abs=1e-12)   # total reflection beyond the critical angle
    # t t' = 1 - r^2 holds on both sides of the critical angle (algebraic identity of the coefficients)
    assert complex(t * tp) == pytest.approx(complex(1 - r * r), abs=1e-12)


@settings(max_examples=40, deadline=None)
@given(c1=speeds, c2=speeds, angle=st.floats(0.0, 89.0))
def test_snell_angles_keep_the_horizontal_slowness(c1, c2, angle):
    cos = snell_cosines([c1, c2], angle)
    s1 = math.sin(math.radians(angle)) / c1
    if cos[1].imag == 0:
        theta2 = math.asin(min(c2 * s1, 1.0))   # the refraction angle itself, then its cosine
        assert cos[1].real == pytest.approx(math.cos(theta2), abs=1e-9)
    else:
        # evanescent: cos = -j sqrt(s^2 - 1), s = c2 sin(theta1)/c1 (decays downward with exp(+j w t))
        assert cos[1].real == 0.0 and cos[1].imag < 0
        assert -cos[1].imag == pytest.approx(math.sqrt((c2 * s1) ** 2 - 1), rel=1e-9)


def test_critical_angle_separates_partial_and_total_reflection():
    critical = math.degrees(math.asin(1500 / 1600))
    below = rayleigh_reflection(1000, 1500, 1300, 1600, critical - 0.5)
    above = rayleigh_reflection(1000, 1500, 1300, 1600, critical + 0.5)
    assert abs(below) < 0.99 and abs(above) == pytest.approx(1.0, abs=1e-12)


def test_eckart_and_fair_reflection_factors_against_the_closed_forms():
    f, sigma, c, cos = 10e3, 0.01, 1500.0, math.cos(math.radians(20.0))
    k = 2 * math.pi * f / c
    p = 2 * k * sigma * cos                                  # eq. 5: 0.787 here
    assert rayleigh_parameter(f, sigma, c, cos) == pytest.approx(p, rel=1e-14)
    # V_rough / V_smooth = exp(-P^2/2) (minus sign restored, docs/forward.md) and exp(-(4/3 P)^2/2) (eq. 7)
    assert reflection_roughness_factor(f, sigma, c, cos, "small") == pytest.approx(math.exp(-p * p / 2), rel=1e-14)
    assert reflection_roughness_factor(f, sigma, c, cos, "fair") == pytest.approx(math.exp(-(4 * p / 3) ** 2 / 2),
                                                                                rel=1e-14)
    # numbers at normal incidence, sigma = 1 cm, 10 kHz: P = 0.8378, -3.05 dB (small) and -5.42 dB (fair)
    assert 20 * math.log10(reflection_roughness_factor(f, sigma, c)) == pytest.approx(-3.048, abs=5e-4)
    assert 20 * math.log10(reflection_roughness_factor(f, sigma, c, 1.0, "fair")) == pytest.approx(-5.419, abs=5e-4)


def test_transmission_factors_against_the_closed_forms_and_reciprocity():
    f, sigma, c1, c2 = 8e3, 0.02, 1500.0, 1700.0
    cos = snell_cosines([c1, c2], 25.0)
    k1, k2 = 2 * math.pi * f / c1, 2 * math.pi * f / c2
    # eq. 6: P_T = k2 sigma (c2/c1 cos1 - cos2) = sigma (k1 cos1 - k2 cos2)
    pt = sigma * (k1 * cos[0].real - k2 * cos[1].real)
    assert transmission_parameter(f, sigma, c1, cos[0], c2, cos[1]) == pytest.approx(pt, rel=1e-12)
    # crossing back gives -P_T: the same factor both ways (reciprocity of the coherent loss)
    assert transmission_parameter(f, sigma, c2, cos[1], c1, cos[0]) == pytest.approx(-pt, rel=1e-12)
    assert transmission_roughness_factor(f, sigma, c1, cos[0], c2, cos[1], "small") == pytest.approx(
        math.exp(-pt * pt / 2), rel=1e-13)
    assert transmission_roughness_factor(f, sigma, c1, cos[0], c2, cos[1], "fair") == pytest.approx(
        math.exp(-(2.5 * pt) ** 2 / 2), rel=1e-13)
    # the transmission loss is far smaller than the reflection loss at normal incidence:
    # P_T / P = (1/c1 - 1/c2) / (2/c1) = (1 - c1/c2) / 2 = 0.059 here
    ratio = transmission_parameter(f, sigma, c1, 1.0, c2, 1.0) / rayleigh_parameter(f, sigma, c1)
    assert ratio == pytest.approx((1 - c1 / c2) / 2, rel=1e-12)


def test_single_smooth_interface_echo_is_rayleigh_over_spherical_spreading():
    freq = np.array([1e3, 5e3, 12e3])
    echoes = layer_echoes(two_media(1300.0, 1600.0, depth=20.0), freq, p0=2.0)
    tau = 2 * 20.0 / 1500.0
    expected = 2.0 / (2 * 1500.0 * tau) * (2.08e6 - 1.5e6) / 3.58e6   # p0/(2 c1 tau) R (eqs. 2, 15)
    np.testing.assert_allclose(echoes.amplitudes[0], expected, rtol=1e-14)
    assert echoes.times_s[0] == pytest.approx(tau, rel=1e-15)


@pytest.mark.parametrize("regime,gain", [("small", 1.0), ("fair", 4.0 / 3.0)])
def test_rough_seafloor_echo_is_the_smooth_echo_times_the_roughness_factor(regime, gain):
    freq = np.linspace(1e3, 15e3, 15)
    smooth = layer_echoes(two_media(1300.0, 1600.0), freq).amplitudes[0]
    rough = layer_echoes(two_media(1300.0, 1600.0, sigma=0.01, regime=regime), freq).amplitudes[0]
    p = 2 * (2 * np.pi * freq / 1500.0) * 0.01
    np.testing.assert_allclose(rough / smooth, np.exp(-(gain * p) ** 2 / 2), rtol=1e-13)


def test_echo_below_a_rough_interface_loses_exp_minus_p_t_squared_both_ways():
    freq = np.linspace(1e3, 15e3, 15)

    def layers(sigma):
        return Seabed((water_column(20.0), Layer(3.0, 1600.0, 1300.0, top=Interface(sigma, "fair")),
                       Layer(math.inf, 1800.0, 1700.0)))

    ratio = layer_echoes(layers(0.01), freq).amplitudes[1] / layer_echoes(layers(0.0), freq).amplitudes[1]
    pt = 2.5 * 0.01 * 2 * np.pi * freq * (1 / 1500.0 - 1 / 1600.0)     # eq. 8 at normal incidence
    np.testing.assert_allclose(ratio, np.exp(-pt ** 2), rtol=1e-13)   # t and t' each exp(-P_T^2/2)


def test_bad_regime_and_angles_raise_option_errors():
    with pytest.raises(OptionError, match="roughness_regime"):
        Interface(0.01, "moderate")
    with pytest.raises(OptionError, match="incidence_deg"):
        snell_cosines([1500.0, 1600.0], 95.0)
    with pytest.raises(OptionError, match="regime"):
        reflection_roughness_factor(1e3, 0.01, 1500.0, 1.0, "large")
