"""Echo sum of eqs. 15–18, traces of eq. 19, oblique specular echoes, layouts and grain sizes."""

import math

import numpy as np
import pytest

from clbeam.errors import OptionError
from clbeam.imaging.signal import compress_analytic
from clbeam.seabed.forward import (
    HIGH_CHIRP,
    LOW_CHIRP,
    Chirp,
    Interface,
    Layer,
    LayoutFileError,
    PowerLawAttenuation,
    Seabed,
    compress_circular,
    echo_times,
    layer_echoes,
    layer_from_grain_size,
    load_seabed,
    rayleigh_reflection,
    seabed_from_dict,
    simulate_trace,
    specular_echoes,
    table2_layout,
    water_column,
)


def stack(*layers, depth=20.0):
    return Seabed((water_column(depth),) + tuple(layers))


def rayleigh(z1, z2):
    return (z2 - z1) / (z2 + z1)


def test_echo_times_are_sums_of_two_way_layer_times():
    seabed = table2_layout(1)
    # 2*20/1500, + 2*2/1600, + 2*4/1725 (Table 2 layout 1 with this package's thicknesses)
    expected = np.cumsum([40 / 1500, 4 / 1600, 8 / 1725])
    np.testing.assert_allclose(echo_times(seabed), expected, rtol=1e-15)


def test_oblique_echo_times_follow_snell_ray_paths():
    seabed = table2_layout(1)
    theta1 = math.radians(12.0)
    s = math.sin(theta1) / 1500.0
    legs = [2 * h / (c * math.sqrt(1 - (s * c) ** 2)) for h, c in ((20.0, 1500.0), (2.0, 1600.0), (4.0, 1725.0))]
    np.testing.assert_allclose(echo_times(seabed, incidence_deg=12.0), np.cumsum(legs), rtol=1e-14)


def test_echo_below_a_lossy_layer_is_rayleigh_times_two_way_transmission_and_exp_minus_2_alpha_h():
    k_p, h = 0.5, 3.0
    seabed = stack(Layer(h, 1600.0, 1300.0, PowerLawAttenuation(k_p, 1.0)), Layer(math.inf, 1800.0, 1700.0))
    freq = np.array([1e3, 4e3, 9e3])
    e = layer_echoes(seabed, freq)
    z0, z1, z2 = 1.5e6, 1300 * 1600.0, 1700 * 1800.0
    tau = 2 * 20 / 1500 + 2 * h / 1600
    alpha = k_p * freq / 1000 * math.log(10) / 20          # Np/m
    expected = 1 / (2 * 1500 * tau) * rayleigh(z1, z2) * (1 - rayleigh(z0, z1) ** 2) * np.exp(-2 * alpha * h)
    np.testing.assert_allclose(e.amplitudes[1], expected, rtol=1e-13)


def test_specular_echo_at_an_angle_uses_the_oblique_rayleigh_coefficient():
    seabed = table2_layout(1)
    e = specular_echoes(seabed, [3000.0], grazing_deg=70.0)
    assert e.incidence_deg == pytest.approx(20.0)
    v = rayleigh_reflection(1000, 1500, 1300, 1600, 20.0)
    tau = e.times_s[0]
    assert tau == pytest.approx(2 * 20 / (1500 * math.cos(math.radians(20))), rel=1e-14)
    assert complex(e.amplitudes[0, 0]) == pytest.approx(v / (2 * 1500 * tau), rel=1e-13)


def test_beyond_the_critical_angle_the_seafloor_reflects_totally_and_deeper_echoes_vanish():
    critical = math.degrees(math.asin(1500 / 1600))
    e = specular_echoes(table2_layout(1), [2000.0, 5000.0], incidence_deg=critical + 2.0)
    np.testing.assert_allclose(np.abs(e.reflection[0]), 1.0, atol=1e-12)
    assert np.isnan(e.times_s[1:]).all() and np.all(e.amplitudes[1:] == 0)


def test_received_trace_is_the_sum_of_delayed_scaled_pulses():
    # delays on the sample grid: 15 m / 1500 m/s -> 20 ms = 960 samples, 1.6 m / 1600 m/s -> 2 ms = 96
    seabed = stack(Layer(1.6, 1600.0, 1300.0), Layer(math.inf, 1800.0, 1700.0), depth=15.0)
    fs = 48000.0
    tr = simulate_trace(seabed, LOW_CHIRP, sample_rate_hz=fs)
    x = LOW_CHIRP.replica(fs)
    z0, z1, z2 = 1.5e6, 1300 * 1600.0, 1700 * 1800.0
    expected = np.zeros(tr.received.size)
    for k, tau, v in ((960, 0.020, rayleigh(z0, z1)), (1056, 0.022, rayleigh(z1, z2) * (1 - rayleigh(z0, z1) ** 2))):
        expected[k:k + x.size] += v / (2 * 1500 * tau) * x
    # FFT round-off on a 0.002 Pa signal
    np.testing.assert_allclose(tr.received, expected, atol=1e-15)


def test_compressed_echo_peaks_at_its_amplitude_and_time():
    # one interface 15 m below: echo at 20 ms = sample 960; compression normalised by the pulse energy
    # gives the autocorrelation peak 1 times the echo amplitude R / (2 c1 tau)
    tr = simulate_trace(stack(Layer(math.inf, 1600.0, 1300.0), depth=15.0), LOW_CHIRP, sample_rate_hz=48000.0)
    amp = rayleigh(1.5e6, 1300 * 1600.0) / (2 * 1500 * 0.020)
    assert tr.compressed.real[960] == pytest.approx(amp, rel=1e-12)
    assert int(np.argmax(np.abs(tr.compressed))) == 960


def test_circular_compression_equals_the_linear_compression_of_the_signal_module():
    tr = simulate_trace(table2_layout(2), HIGH_CHIRP)
    linear = compress_analytic(tr.received, tr.replica)
    # the record ends more than one pulse after the last echo, so the correlations (real parts) agree up
    # to what the circular one folds in from the record's start: the tails of the sub-sample-delayed,
    # band-limited echoes (measured 1.1e-7 of the peak; bound 1e-6)
    np.testing.assert_allclose(tr.compressed.real, linear.real, atol=1e-6 * np.abs(linear).max())
    # the Hilbert parts are taken over different periods (N and N + pulse - 1): the 1/(pi t) kernel's
    # periodic images differ by ~1/(pi N) of the peak, 1e-4 for N = 2800; measured 4e-7
    np.testing.assert_allclose(np.abs(tr.compressed), np.abs(linear), atol=1e-4 * np.abs(linear).max())
    np.testing.assert_allclose(compress_circular(tr.received, tr.replica), tr.compressed, rtol=0, atol=0)


def test_noise_level_follows_the_snr_definition():
    tr = simulate_trace(table2_layout(1), LOW_CHIRP, snr_db=10.0, rng=7)
    clean = simulate_trace(table2_layout(1), LOW_CHIRP)
    a = np.abs(clean.received).max()
    assert tr.noise_std == pytest.approx(a / math.sqrt(2 * 10.0), rel=1e-12)
    # sample standard deviation of n = 2600 normal samples: relative spread 1/sqrt(2n) = 1.4 %; 5 sigma = 7 %
    assert np.std(tr.received - clean.received) == pytest.approx(tr.noise_std, rel=0.07)


def test_fig9_echo3_spectra_with_and_without_seafloor_roughness_superimpose():
    # Fig. 9: echo 3 of layout 2 with sigma1 = 1 cm and 0: the only difference is the fair-roughness
    # transmission t t' = exp(-(5/2 P_T)^2) through the seafloor, P_T = sigma w (1/1500 - 1/1600):
    # 0.08 dB at 15 kHz, invisible on the figure
    rough, smooth = table2_layout(2), table2_layout(2).with_interface(1, roughness_m=0.0)
    f = np.linspace(1e3, 15e3, 57)
    ratio = layer_echoes(rough, f).amplitudes[2] / layer_echoes(smooth, f).amplitudes[2]
    pt = 2.5 * 0.01 * 2 * np.pi * f * (1 / 1500 - 1 / 1600)
    np.testing.assert_allclose(ratio, np.exp(-pt ** 2), rtol=1e-12)
    assert -20 * np.log10(np.abs(ratio)).min() < 0.1


def test_fig9_echo1_the_transitional_bed_prevails_over_the_roughness():
    # "impact of transitional layer with intermediate thickness prevails rugosity's influence" (Fig. 9)
    f = np.array([5e3, 10e3, 15e3])
    v1 = abs(rayleigh(1.5e6, 1300 * 1600.0))
    drop = lambda seabed: -20 * np.log10(np.abs(layer_echoes(seabed, f).reflection[0]) / v1)  # noqa: E731
    rough_only = drop(table2_layout(2).with_interface(1, transition_m=0.0))
    bed_only = drop(table2_layout(2).with_interface(1, roughness_m=0.0))
    # roughness alone: the closed form of eq. 7, 8.686 (4/3 P)^2 / 2 dB, P = 2 k sigma (5.42 dB at 10 kHz)
    p = 2 * (2 * np.pi * f / 1500.0) * 0.01
    np.testing.assert_allclose(rough_only, 20 / np.log(10) * (4 * p / 3) ** 2 / 2, rtol=1e-12)
    assert np.all(bed_only > rough_only)


def test_fig8_echo3_is_less_absorbed_with_the_low_chirp():
    # bed 3 (4 m, k_p = 0.1 dB/m/kHz) takes 0.8 f_kHz dB two-way: at the chirp centres 3.45 and 10 kHz,
    # 2.76 and 8 dB; the rest of echo 3's amplitude is frequency independent in layout 1
    e = layer_echoes(table2_layout(1), [LOW_CHIRP.centre_hz, HIGH_CHIRP.centre_hz])
    loss = -20 * np.log10(e.attenuation[2])
    np.testing.assert_allclose(loss, [0.8 * 3.45, 0.8 * 10.0], rtol=1e-12)


def test_table2_layouts_carry_the_printed_properties():
    one, two = table2_layout(1), table2_layout(2)
    for seabed in (one, two):
        rho = [la.density_kg_m3 for la in seabed.layers]
        c = [la.sound_speed_m_s for la in seabed.layers]
        assert rho == [1000.0, 1300.0, 1800.0, 2000.0] and c == [1500.0, 1600.0, 1725.0, 2200.0]
        assert seabed.layers[2].attenuation == PowerLawAttenuation(0.1, 1.0)
    assert two.layers[1].top == Interface(0.01, "fair", 0.05, None)
    assert two.layers[2].top == Interface(0.02, "fair")


# Handbook table (reference notes): Mz, rho ratio, nu ratio, delta (APL-UW TR 9407).
GRAIN_TABLE = [(0.5, 2.2306, 1.2503, 0.01638), (1.5, 1.8446, 1.1782, 0.01624), (2.5, 1.4512, 1.1073, 0.01602),
               (5.0, 1.1689, 0.9999, 0.01261), (6.0, 1.1487, 0.9873, 0.00386), (9.0, 1.1448, 0.9800, 0.00148)]


@pytest.mark.parametrize("mz,rho,nu,delta", GRAIN_TABLE)
def test_grain_size_layer_reproduces_the_handbook_table(mz, rho, nu, delta):
    layer = layer_from_grain_size(mz, 1.0, water_sound_speed_m_s=1528.0, water_density_kg_m3=1000.0)
    # printed to 4 decimals (ratios) and 5 (delta): half a unit of the last digit
    assert layer.density_kg_m3 / 1000.0 == pytest.approx(rho, abs=5e-5)
    assert layer.sound_speed_m_s / 1528.0 == pytest.approx(nu, abs=5e-5)
    # the layer's k_p (dB/m/kHz, n = 1) gives the handbook loss parameter delta = k_p nu c_w ln10 / (40000 pi)
    k_p = layer.attenuation.k_p_db_m_khz
    assert layer.attenuation.n == 1.0
    assert k_p * nu * 1528.0 * math.log(10) / (40000 * math.pi) == pytest.approx(delta, abs=5e-6)


def test_layout_files_accept_grain_sizes_and_linear_attenuation():
    seabed = seabed_from_dict({
        "water": {"depth_m": 10.0},
        "layers": [{"thickness_m": 1.0, "grain_size_phi": 2.5},
                   {"thickness_m": 2.0, "sound_speed_m_s": 1650.0, "density_kg_m3": 1700.0,
                    "attenuation": {"slope_db_m_khz": 0.25, "intercept_db_m": -0.226}},
                   {"sound_speed_m_s": 1800.0, "density_kg_m3": 1900.0}]})
    assert seabed.layers[1].density_kg_m3 == pytest.approx(1451.2, abs=0.05)   # fine sand, rho 1.4512
    assert seabed.layers[2].attenuation.db_per_m(4000.0) == pytest.approx(0.25 * 4 - 0.226, rel=1e-14)
    assert math.isinf(seabed.layers[3].thickness_m)


@pytest.mark.parametrize("data,message", [
    ({"water": {"depth_m": 10.0}, "layers": [{"sound_speed_m_s": 1600.0, "density_kg_m3": 1300.0, "thicknes": 1}]},
     "unknown key 'thicknes'"),
    ({"water": {}, "layers": [{"sound_speed_m_s": 1600.0, "density_kg_m3": 1300.0}]}, "depth_m is required"),
    ({"water": {"depth_m": 10.0}, "layers": [{"thickness_m": 2.0, "sound_speed_m_s": 1600.0, "density_kg_m3": 1.3e3}]},
     "half-space"),
    ({"water": {"depth_m": 10.0}, "layers": [{"grain_size_phi": 2.0, "density_kg_m3": 1300.0}]}, "grain_size_phi"),
    ({"water": {"depth_m": 10.0}, "layers": [{"sound_speed_m_s": 1600.0, "density_kg_m3": 1300.0,
                                              "top": {"roughness_regime": "huge"}}]}, "roughness_regime"),
    ({"water": {"depth_m": -1.0}, "layers": [{"sound_speed_m_s": 1600.0, "density_kg_m3": 1300.0}]}, "thickness_m"),
])
def test_bad_layout_files_raise_one_line_errors_naming_the_key(data, message):
    with pytest.raises(LayoutFileError, match=message) as info:
        seabed_from_dict(data, source="site.toml")
    assert "\n" not in str(info.value)


def test_layout_loader_reads_files_and_reports_missing_ones(tmp_path):
    path = tmp_path / "site.toml"
    path.write_text('[water]\ndepth_m = 12.0\n[[layers]]\nsound_speed_m_s = 1600.0\ndensity_kg_m3 = 1300.0\n')
    seabed = load_seabed(path)
    assert echo_times(seabed)[0] == pytest.approx(24.0 / 1500.0, rel=1e-15)
    with pytest.raises(LayoutFileError, match="not found"):
        load_seabed(tmp_path / "missing.toml")
    (tmp_path / "bad.toml").write_text("[water\n")
    with pytest.raises(LayoutFileError, match="not valid TOML"):
        load_seabed(tmp_path / "bad.toml")


def test_chirp_parsing_and_bad_inputs():
    assert Chirp.parse("low") == Chirp(1700.0, 5200.0, 0.01)
    assert Chirp.parse("2000,9000,0.02") == Chirp(2000.0, 9000.0, 0.02)
    with pytest.raises(OptionError, match="F0,F1,DUR"):
        Chirp.parse("2000-9000")
    with pytest.raises(OptionError, match="record_s"):
        simulate_trace(table2_layout(1), LOW_CHIRP, record_s=0.03)
    with pytest.raises(OptionError, match="sample_rate_hz"):
        simulate_trace(table2_layout(1), HIGH_CHIRP, sample_rate_hz=20000.0)
