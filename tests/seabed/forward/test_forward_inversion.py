"""Layer parameters from compressed nadir traces (inversion of eqs. 15–19)."""

import math

import numpy as np
import pytest

from clbeam.errors import OptionError
from clbeam.seabed.forward import (
    HIGH_CHIRP,
    LOW_CHIRP,
    Layer,
    Seabed,
    UnresolvableError,
    compress_circular,
    echo_times,
    invert_trace,
    simulate_trace,
    table2_layout,
    water_column,
)

SPEEDS = [1600.0, 1725.0]          # beds 2 and 3 of Table 2, given to turn times into metres


def impedance_contrast(z1, z2):
    return (z2 - z1) / (z2 + z1)


# Layout 1's truth: Rayleigh coefficients of the three interfaces, k_p' of beds 2 and 3 (dB/m/kHz)
TRUE_V = [impedance_contrast(1000 * 1500, 1300 * 1600), impedance_contrast(1300 * 1600, 1800 * 1725),
          impedance_contrast(1800 * 1725, 2000 * 2200)]
TRUE_KP = [0.0, 0.1]


def invert(trace, **kw):
    return invert_trace(trace.compressed, trace.chirp, sample_rate_hz=trace.sample_rate_hz,
                        layer_sound_speeds_m_s=SPEEDS, **kw)


def crlb_delay_s(chirp, fs, amplitude, noise_std):
    """Cramér–Rao bound of one echo's delay: sigma / (|a| sqrt(sum xdot^2)), xdot from the LFM phase."""
    t = np.arange(int(round(chirp.duration_s * fs))) / fs
    phase = 2 * np.pi * (chirp.f0_hz * t + 0.5 * chirp.bandwidth_hz / chirp.duration_s * t * t)
    xdot = -np.sin(phase) * 2 * np.pi * (chirp.f0_hz + chirp.bandwidth_hz * t / chirp.duration_s)
    return noise_std / (abs(amplitude) * math.sqrt(np.sum(xdot ** 2)))


@pytest.mark.parametrize("chirp,snr_db,seed", [(LOW_CHIRP, 30.0, 11), (LOW_CHIRP, 20.0, 12), (LOW_CHIRP, 10.0, 13),
                                               (HIGH_CHIRP, 30.0, 14), (HIGH_CHIRP, 20.0, 15)],
                         ids=["low-30dB", "low-20dB", "low-10dB", "high-30dB", "high-20dB"])
def test_layout1_times_reflections_and_attenuation_are_recovered(chirp, snr_db, seed):
    seabed = table2_layout(1)
    trace = simulate_trace(seabed, chirp, snr_db=snr_db, rng=seed)
    result = invert(trace)
    assert result.resolvable and [e.status for e in result.echoes] == ["smooth"] * 3
    truth_t = echo_times(seabed)
    # Tolerances: 5 standard errors of each estimate (two-sided Gaussian 6e-7 per value).  The standard
    # errors are the Cramér-Rao bounds of the fit; they are checked against closed forms below, so a
    # loose error bar cannot pass unnoticed.
    for e, t, v in zip(result.echoes, truth_t, TRUE_V):
        assert abs(e.time_s - t) <= 5 * e.time_std_s
        assert abs(e.reflection - v) <= 5 * e.reflection_std
    for layer, kp, c in zip(result.layers, TRUE_KP, SPEEDS):
        assert abs(layer.attenuation_db_m_khz - kp) <= 5 * layer.attenuation_std_db_m_khz
        assert layer.thickness_m == pytest.approx(c * layer.two_way_time_s / 2, rel=1e-12)
    # seafloor echo: delay bound sigma/(|a| sqrt(sum xdot^2)) and amplitude bound sigma/sqrt(sum x^2) (scaled
    # to a reflection coefficient by 2 c1 tau / p0).  The fit evaluates them at its own amplitude (off by up
    # to 5 sigma_V / V) on the FFT grid (1 % at most for this band and record)
    e0, amp = result.echoes[0], TRUE_V[0] / (2 * 1500.0 * truth_t[0])
    rel = 5 * e0.reflection_std / e0.reflection + 0.01
    bound = crlb_delay_s(chirp, trace.sample_rate_hz, amp, result.noise_std)
    assert e0.time_std_s == pytest.approx(bound, rel=rel)
    energy = float(np.sum(chirp.replica(trace.sample_rate_hz) ** 2))
    assert e0.reflection_std == pytest.approx(result.noise_std / math.sqrt(energy) * 2 * 1500.0 * e0.time_s, rel=0.01)


def test_error_bars_are_calibrated_over_noise_draws():
    # 20 draws: the z-scores (estimate - truth) / standard error of bed 3's k_p' and echo 3's time should be
    # N(0, 1); a sample standard deviation of 20 N(0,1) values has a spread of 1/sqrt(38) = 0.16, so
    # [0.55, 1.45] is +-2.8 spreads, and their mean lies within 3/sqrt(20) = 0.67 of 0
    seabed = table2_layout(1)
    truth = echo_times(seabed)[2]
    z_kp, z_t = [], []
    for seed in range(20):
        result = invert(simulate_trace(seabed, HIGH_CHIRP, snr_db=20.0, rng=100 + seed))
        layer, echo = result.layers[1], result.echoes[2]
        z_kp.append((layer.attenuation_db_m_khz - 0.1) / layer.attenuation_std_db_m_khz)
        z_t.append((echo.time_s - truth) / echo.time_std_s)
    for z in (np.array(z_kp), np.array(z_t)):
        assert 0.55 <= z.std(ddof=1) <= 1.45
        assert abs(z.mean()) <= 0.67


def rough_seafloor():
    return table2_layout(1).with_interface(1, roughness_m=0.01, roughness_regime="fair")


def test_fairly_rough_seafloor_gives_sigma_when_transitional_beds_are_excluded():
    trace = simulate_trace(rough_seafloor(), HIGH_CHIRP, snr_db=30.0, rng=21)
    result = invert(trace, transitional_beds=False)
    e0 = result.echoes[0]
    assert e0.status == "rough"
    # the f -> 0 reflection is the smooth Rayleigh value; sigma read with the fair factor is the 1 cm
    # of the model (5 standard errors)
    assert abs(e0.reflection - TRUE_V[0]) <= 5 * e0.reflection_std
    assert abs(e0.roughness_fair_m - 0.01) <= 5 * e0.roughness_fair_std_m
    assert e0.roughness_small_m == pytest.approx(4 / 3 * e0.roughness_fair_m, rel=1e-12)
    # transmission through the rough seafloor is hardly affected (§5): bed 3's attenuation is still recovered
    layer = result.layers[1]
    assert abs(layer.attenuation_db_m_khz - 0.1) <= 5 * layer.attenuation_std_db_m_khz


def test_the_same_rough_seafloor_is_unresolvable_when_a_transitional_bed_may_be_present():
    trace = simulate_trace(rough_seafloor(), HIGH_CHIRP, snr_db=30.0, rng=21)
    result = invert(trace)
    e0 = result.echoes[0]
    assert e0.status == "unresolvable"
    assert e0.reflection is None and e0.roughness_fair_m is None and e0.roughness_small_m is None
    assert result.seafloor_models["rough"] and result.seafloor_models["transitional"]
    assert "rough interface and a transitional bed explain it equally well" in e0.reason
    with pytest.raises(UnresolvableError, match="echo 0"):
        result.require_resolved()


@pytest.mark.parametrize("chirp,seed", [(LOW_CHIRP, 31), (HIGH_CHIRP, 32)], ids=["low", "high"])
def test_layout2_rough_seafloor_on_a_transitional_bed_is_reported_unresolvable(chirp, seed):
    # Rakotonarivo §5: "if rugosity is conjugated with intermediate thickness of transitional layer, rugosity
    # is not assessable and reflection loss is sorely calculable" -- no number is returned for it
    result = invert(simulate_trace(table2_layout(2), chirp, snr_db=30.0, rng=seed))
    e0 = result.echoes[0]
    assert e0.status == "unresolvable" and e0.reflection is None and e0.roughness_fair_m is None
    assert "roughness and reflection loss are not resolvable" in e0.reason
    assert not result.resolvable
    with pytest.raises(UnresolvableError, match="echo 0 at"):
        result.require_resolved()
    # the 2 cm fair roughness at the top of bed 3 makes echo 2's spectrum curve (not linear in dB): its
    # reflection and the attenuation of the beds around it are reported as not separable
    e1 = result.echoes[1]
    assert e1.status == "frequency-dependent" and e1.reflection is None
    assert result.layers[0].attenuation_db_m_khz is None and result.layers[1].attenuation_db_m_khz is None
    # the deepest (smooth) interface keeps its reflection coefficient, through approximate stripping
    e2 = result.echoes[2]
    assert e2.status == "smooth" and e2.note and abs(e2.reflection - TRUE_V[2]) <= 5 * e2.reflection_std + 0.01


def test_a_transitional_bed_alone_is_told_from_roughness_but_still_unresolvable():
    seabed = table2_layout(1).with_interface(1, transition_m=0.05)
    result = invert(simulate_trace(seabed, HIGH_CHIRP, snr_db=40.0, rng=41))
    # over 5-15 kHz the 5 cm bed approaches its first zero (lambda/dx = 2.1 at 15 kHz): a Gaussian roughness
    # loss cannot follow that, the bed model can (at 40 dB; at 30 dB one draw in twelve leaves both adequate)
    assert not result.seafloor_models["rough"] and result.seafloor_models["transitional"]
    assert "needs a transitional bed" in result.echoes[0].reason


def test_noise_only_trace_raises():
    rng = np.random.default_rng(5)
    replica = LOW_CHIRP.replica(48000.0)
    yc = compress_circular(rng.normal(0.0, 1e-3, 2400), replica)
    with pytest.raises(UnresolvableError, match="no echo"):
        invert_trace(yc, LOW_CHIRP, sample_rate_hz=48000.0)


def test_short_water_column_needs_a_given_noise_level():
    # the seafloor 5 m below: its echo (6.7 ms) comes before one pulse length: no noise-only samples
    seabed = Seabed((water_column(5.0), Layer(math.inf, 1600.0, 1300.0)))
    trace = simulate_trace(seabed, LOW_CHIRP, snr_db=20.0, rng=2)
    with pytest.raises(OptionError, match="give noise_std"):
        invert_trace(trace.compressed, LOW_CHIRP, sample_rate_hz=48000.0)
    result = invert_trace(trace.compressed, LOW_CHIRP, sample_rate_hz=48000.0, noise_std=trace.noise_std)
    e0 = result.echoes[0]
    assert abs(e0.reflection - TRUE_V[0]) <= 5 * e0.reflection_std
    assert abs(e0.time_s - 10.0 / 1500.0) <= 5 * e0.time_std_s
