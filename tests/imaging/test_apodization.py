"""Receive apodization (weighted sums and weighted CF) and element calibration.

Independent checks: the float64 reference engine, closed forms of the
windows (Hann, Dolph-Chebyshev equiripple sidelobes), the broadband array
pattern of a point target computed from the replica spectrum and the
weights alone, and the coherence of randomly phased channels.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import xarray as xr
from scenes import (
    FS,
    PULSE,
    C,
    bandlimited_noise,
    ping_dataset,
    point_ping,
    polar_point,
    sbp_elements,
)

from clbeam.errors import OptionError, PingFileError
from clbeam.imaging.apodization import (
    calibration_factors,
    parse_window,
    receive_weights,
    sidelobe_level_db,
)
from clbeam.imaging.engine import BeamformInput, get_engine
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.signal import apply_channel_response
from clbeam.io.pingfile import PingFile
from clbeam.io.pingwrite import write_ping_file
from clbeam.model.grid import PolarGrid

# float32 sums of a few channels: relative errors of a few float32 epsilons
# per channel; 1e-4 leaves a factor ~10 over what 64 channels accumulate
F32_REL = 1e-4


def random_input(weights, n=8, seed=3):
    data = bandlimited_noise((n, 400), seed=seed)
    data[1, 100:110] = np.nan
    eo = np.zeros((n, 3))
    eo[:, 1] = np.linspace(-1.5, 1.5, n)
    return BeamformInput(data, FS, 0.0005, C, eo, np.array([0.0, 0.2, 0.1]), centre_frequency_hz=5500.0,
                         weights=weights)


SMALL = PolarGrid.regular(range_res_m=0.2, angle_res_deg=5, max_range_m=8.0, angles_deg=(-80, 80))


@pytest.mark.parametrize("mode", ["linear", "cubic", "lanczos4", "linear-bb"])
def test_weighted_sums_on_opencl_equal_the_float64_reference(mode):
    w = np.random.default_rng(1).uniform(0, 1, 8)
    inp = random_input(w)
    want = get_engine("reference").beamform(inp, SMALL, interp=mode, outputs=("intensity", "cf", "sums"))
    got = get_engine("opencl").beamform(inp, SMALL, interp=mode, outputs=("intensity", "cf", "sums"))
    scale = want.intensity.max()
    assert np.max(np.abs(got.intensity - want.intensity)) <= F32_REL * scale
    assert np.max(np.abs(got.cf - want.cf)) <= F32_REL
    assert np.max(np.abs(got.w - want.w)) <= F32_REL * w.sum()
    assert np.array_equal(got.m, want.m)
    # W counts only the contributing channels: the NaN samples of channel 1 are left out somewhere
    assert np.any(want.w < w.sum() - 1e-9) and np.all(want.w <= w.sum() + 1e-12)


def test_unit_weights_give_the_unweighted_image_and_cf():
    ref = get_engine("reference")
    plain = ref.beamform(random_input(None), SMALL, interp="cubic", outputs=("intensity", "cf", "sums"))
    ones = ref.beamform(random_input(np.ones(8)), SMALL, interp="cubic", outputs=("intensity", "cf", "sums"))
    np.testing.assert_allclose(ones.intensity, plain.intensity, rtol=1e-12, atol=0)
    np.testing.assert_allclose(ones.cf, plain.cf, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(ones.w, plain.m)


@pytest.mark.parametrize("window", ["rect", "hann", "tukey:0.5", "chebyshev:40"])
def test_weighted_cf_is_one_for_identical_channels_and_within_zero_one_for_noise(window):
    w = receive_weights(window, sbp_elements(16)[:, 1])
    eo = np.zeros((16, 3))  # every channel at the centre: identical delays, identical samples
    row = bandlimited_noise((1, 300), seed=4)[0]
    same = BeamformInput(np.repeat(row[None], 16, axis=0), FS, 0.0, C, eo, np.zeros(3), weights=w)
    grid = PolarGrid.regular(range_res_m=0.5, angle_res_deg=20, min_range_m=0.5, max_range_m=5.0, angles_deg=(-60, 60))
    cf = get_engine("opencl").beamform(same, grid, interp="cubic", outputs=("cf",)).cf
    inside = cf > 0
    assert inside.mean() > 0.5
    np.testing.assert_allclose(cf[inside], 1.0, atol=F32_REL)
    noisy = get_engine("opencl").beamform(random_input(receive_weights(window, np.linspace(-1.5, 1.5, 8))),
                                          SMALL, interp="cubic", outputs=("cf",)).cf
    assert np.all(np.isfinite(noisy)) and noisy.min() >= 0 and noisy.max() <= 1 + F32_REL


def test_window_weights_against_their_closed_forms():
    y = sbp_elements(64)[:, 1]
    n = np.arange(64)
    hann = 0.5 * (1 - np.cos(2 * np.pi * (n + 1) / 65))  # no zero end: every element weighs
    np.testing.assert_allclose(receive_weights("hann", y), hann / hann.max(), atol=1e-12)
    assert np.all(receive_weights("hann", y[:2]) > 0) and np.all(receive_weights("tukey:0.5", y[:3]) > 0)
    np.testing.assert_allclose(receive_weights("tukey:0", y), 1.0)
    np.testing.assert_allclose(receive_weights("tukey:1", y), receive_weights("hann", y), atol=1e-12)
    # elements listed in any order get the weight of their position
    perm = np.random.default_rng(0).permutation(64)
    np.testing.assert_allclose(receive_weights("chebyshev:40", y[perm]), receive_weights("chebyshev:40", y)[perm])
    # Dolph-Chebyshev: every sidelobe of the array factor at the design level
    af = np.abs(np.fft.fft(receive_weights("chebyshev:40", y), 1 << 16))
    af_db = 20 * np.log10(af / af[0] + 1e-300)
    assert sidelobe_level_db(np.fft.fftshift(af) ** 2, (1 << 15)) == pytest.approx(-40.0, abs=0.05)
    assert af_db.max() == pytest.approx(0.0)


def test_window_names_are_checked_in_one_line():
    for bad, words in (("kaiser", "unknown"), ("tukey:2", "0-1"), ("chebyshev:x", "not a number"),
                       ("hann:3", "no parameter"), ("chebyshev:5", "10-200")):
        with pytest.raises(OptionError, match=words):
            parse_window(bad)
    assert parse_window("Chebyshev").label == "chebyshev:40"
    with pytest.raises(OptionError, match="apodization"):
        ImagingOptions(apodization="kaiser")


def broadband_pattern_db(weights, y_m, angles_deg, target_deg):
    """Far-field angular response of the compressed pulse: Σ_f |X(f)|^2 Σ_n w_n
    exp(2πj f y_n (sin θ − sin θ0) / c), intensity re its maximum (dB)."""
    rep = PULSE.replica(FS)
    # a spectrum of at least twice the replica's length holds its whole autocorrelation:
    # finer frequency steps change the pattern by under 1e-3 dB
    nfft = 1 << int(np.ceil(np.log2(2 * len(rep))))
    f = np.fft.rfftfreq(nfft, 1 / FS)
    psd = np.abs(np.fft.rfft(rep, nfft)) ** 2
    ds = np.sin(np.deg2rad(angles_deg)) - np.sin(np.deg2rad(target_deg))
    s = np.array([psd @ (weights @ np.exp(2j * np.pi * np.outer(y_m * d, f) / C)) for d in ds])
    i = np.abs(s) ** 2
    return i / i.max()


@pytest.fixture(scope="module")
def point_target():
    r, a = 500.0, 20.0
    ping = point_ping([polar_point(r, a)], record_s=0.72)
    grid = PolarGrid.regular(range_res_m=0.1, angle_res_deg=0.1, min_range_m=r - 0.3, max_range_m=r + 0.3,
                             angles_deg=(a - 30, a + 30))
    return ping, grid, r, a


@pytest.mark.parametrize("window, max_db", [("rect", -26.0), ("hann", -50.0), ("tukey:0.5", -30.0),
                                            ("chebyshev:40", -50.0)])
def test_point_target_sidelobes_follow_the_windows_broadband_array_pattern(point_target, window, max_db):
    ping, grid, r, a = point_target
    img = Imager(grid, ImagingOptions(interp="lanczos8", apodization=window)).image(ping)
    ir = int(np.argmin(np.abs(grid.ranges_m - r)))
    profile = img.intensity[:, ir].astype(np.float64)
    ia = int(np.argmax(profile))
    assert abs(grid.angles_deg[ia] - a) <= 0.1 + 1e-9
    got = sidelobe_level_db(profile, ia)
    w = receive_weights(window, ping.element_pos_m[:, 1])
    want_profile = broadband_pattern_db(w, ping.element_pos_m[:, 1], grid.angles_deg, a)
    want = sidelobe_level_db(want_profile, int(np.argmax(want_profile)))
    # broadband sidelobes at the peak range (rect about -29 dB, Hann -58 dB);
    # near field (500 m, Fresnel phase < 0.1 rad at the array edge) and
    # the grid's 0.1 degree sampling of the lobes: 1.5 dB
    assert got == pytest.approx(want, abs=1.5)
    assert got <= max_db


def test_a_miscalibrated_array_is_restored_by_its_calibration(point_target, tmp_path):
    ping, grid, r, a = point_target
    rng = np.random.default_rng(7)
    gain_db = rng.uniform(-3, 3, ping.n_channels)
    phase_deg = rng.uniform(-90, 90, ping.n_channels)
    bad = apply_channel_response(ping.samples, gain_db, phase_deg)
    ds = ping_dataset(dataclasses.replace(ping, samples=bad), element_gain_db=("channel", gain_db),
                      element_phase_deg=("channel", phase_deg))
    with PingFile(write_ping_file(ds, tmp_path / "miscal.nc")) as f:
        stored = f.ping(0)
    np.testing.assert_allclose(stored.element_gain_db, gain_db)
    opts = dict(interp="lanczos8")
    clean = Imager(grid, ImagingOptions(**opts)).image(ping)
    fixed = Imager(grid, ImagingOptions(**opts)).image(stored)
    raw = Imager(grid, ImagingOptions(**opts, calibrate=False)).image(stored)
    ir = int(np.argmin(np.abs(grid.ranges_m - r)))
    ia = int(np.argmin(np.abs(grid.angles_deg - a)))
    # calibrated = clean, to float32 storage of the samples and float32 sums
    np.testing.assert_allclose(fixed.intensity, clean.intensity, rtol=0, atol=1e-3 * clean.intensity.max())
    assert abs(fixed.cf[ia, ir] - clean.cf[ia, ir]) < 1e-3
    # uncalibrated: the target's CF is that of the channel responses themselves,
    # |Σ g_n|^2 / (N Σ |g_n|^2) with g = 10^(gain/20) e^(j phase) (a closed form)
    g = 1 / calibration_factors(gain_db, phase_deg, ping.n_channels)
    cf_closed = abs(g.sum()) ** 2 / (g.size * np.sum(np.abs(g) ** 2))
    assert raw.cf[ia, ir] == pytest.approx(cf_closed, abs=0.03)
    assert raw.cf[ia, ir] < clean.cf[ia, ir] - 0.2


def test_channel_response_variables_are_validated(tmp_path):
    n = 4
    base = {"samples": (("ping", "channel", "sample"), np.zeros((1, n, 64), np.float32)),
            "sample_rate": FS, "t0": 0.0, "sound_speed": C, "element_y": ("channel", np.arange(n) * 0.05),
            "element_z": ("channel", np.zeros(n)), "source_y": 0.0, "source_z": 0.0,
            "pulse_f0": 2000.0, "pulse_f1": 9000.0, "pulse_duration": 0.001}
    for extra, words in ((("element_gain_db", ("channel", np.full(n, 80.0))), "element_gain_db' reaches 80"),
                         (("element_phase_deg", ("channel", [0, np.nan, 0, 0])), "element_phase_deg' has 1 non-finite"),
                         (("element_gain_db", ("ping", [1.0])), "element_gain_db' has dimensions")):
        ds = xr.Dataset({**base, extra[0]: extra[1]})
        with pytest.raises(PingFileError, match=words):
            PingFile(write_ping_file(ds, tmp_path / "bad.nc"))
