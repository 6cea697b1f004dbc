"""The detection test against simulated noise: the CF distribution of
incoherent noise (closed form for one cell, the moment-matched model for
the smoothed CF), the noise floor and a peak's SNR, and the level gate on
noise-free data."""

import dataclasses

import numpy as np
import pytest
from scenes import bandlimited_noise, point_ping, polar_point

from clbeam.imaging.detection import (
    equivalent_threshold,
    false_alarm_probability,
    noise_floor,
    smoothing_eigenvalues,
    smoothing_variance_factor,
)
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.model.grid import PolarGrid

C, BAND = 1500.0, (2000.0, 9000.0)
M = 32


def noise_ping(seed: int, *, echo: float = 0.0, n_channels: int = M, sigma: float = 1.0):
    """Analytic (compressed) complex noise of unit power per channel, band 2-9 kHz, and optionally a
    point echo of peak amplitude ``echo`` per channel at 60 m, 10 degrees."""
    base = point_ping([polar_point(60.0, 10.0)], kind="analytic", n_channels=n_channels, record_s=0.2)
    noise = bandlimited_noise(base.samples.shape, f_lo=BAND[0], f_hi=BAND[1], seed=seed)
    noise *= sigma / np.sqrt(np.mean(np.abs(noise) ** 2))
    signal = base.samples / np.max(np.abs(base.samples)) * echo if echo else 0.0
    return dataclasses.replace(base, samples=(noise + signal).astype(np.complex128))


def grid(step_m: float) -> PolarGrid:
    return PolarGrid.regular(range_res_m=step_m, angle_res_deg=0.5, min_range_m=20.0, max_range_m=20.0 + 600 * step_m,
                             angles_deg=(-60, 60))


@pytest.mark.parametrize("step_m", [0.2, 0.05])
def test_noise_cf_follows_the_beta_model_before_and_after_smoothing(step_m):
    g = grid(step_m)
    imager = Imager(g, ImagingOptions(interp="lanczos4", outputs=("cf", "sums"), refine_peaks=False, min_snr_db=None))
    cf, cf_s, m = [], [], []
    for seed in range(3):
        img = imager.image(noise_ping(seed))
        cf.append(img.cf[:, 4:-4]), cf_s.append(img.cf_smooth[:, 4:-4]), m.append(img.sums.m[:, 4:-4])
    cf, cf_s, m = np.concatenate(cf), np.concatenate(cf_s), np.concatenate(m)
    assert np.all(m == M)  # every cell inside the record for every channel
    # one cell: Beta(1, M - 1), mean 1/M and P(CF > x) = (1 - x)^(M - 1)
    assert cf.mean() == pytest.approx(1 / M, rel=0.03)
    for x, tol in ((0.1, 0.15), (0.2, 0.3)):
        assert np.mean(cf > x) == pytest.approx((1 - x) ** (M - 1), rel=tol)
    # smoothed: the variance from the window and the range correlation of the band ...
    factor = smoothing_variance_factor(step_m, BAND[1] - BAND[0], C)
    var_one = (M - 1) / (M * M * (M + 1))
    assert cf_s.var() == pytest.approx(var_one * factor, rel=0.15)
    lam = smoothing_eigenvalues(step_m, BAND[1] - BAND[0], C)
    assert np.sum(lam**2) == pytest.approx(factor, rel=1e-9) and np.sum(lam) == pytest.approx(1.0, rel=1e-9)
    # ... and the tail, down to 1e-4 per cell
    for p, tol in ((0.1, 0.2), (0.01, 0.25), (1e-3, 0.3), (1e-4, 0.4)):
        level = equivalent_threshold(M, lam, p)
        assert np.mean(cf_s > level) == pytest.approx(p, rel=tol)
        assert false_alarm_probability(level, M, lam) == pytest.approx(p, rel=1e-6)
    # one cell: the closed form itself
    assert false_alarm_probability(0.2, M, np.array([1.0])) == pytest.approx(0.8 ** (M - 1), rel=0.02)


def test_noise_floor_and_snr_of_an_echo():
    g = grid(0.1)
    echo = 1.5  # per-channel peak amplitude over a noise of unit power: image SNR = M echo^2 = 72 (18.6 dB)
    img = Imager(g, ImagingOptions(interp="lanczos4", refine_peaks=True)).image(noise_ping(7, echo=echo))
    # the floor: the noise's mean intensity, M sigma^2 (measured on the noise alone)
    alone = Imager(g, ImagingOptions(interp="lanczos4", refine_peaks=False, min_snr_db=None)).image(noise_ping(7))
    assert noise_floor(img.intensity, img.cf_smooth) == pytest.approx(np.mean(alone.intensity), rel=0.1)
    assert np.mean(alone.intensity) == pytest.approx(M, rel=0.1)
    best = min(img.peaks, key=lambda r: np.hypot(r["y_m"] - 60 * np.sin(np.deg2rad(10)),
                                                  r["z_m"] - 60 * np.cos(np.deg2rad(10))))
    assert abs(best["range_m"] - 60.0) < 0.1
    assert best["snr_db"] == pytest.approx(10 * np.log10(M * echo**2), abs=1.5)
    assert best["pfa"] < 1e-6
    # every reported peak clears the default 6 dB above the floor
    assert all(r["snr_db"] >= 6.0 for r in img.peaks)


def test_noise_free_data_keep_only_the_echoes_not_the_rounding():
    ping = point_ping([polar_point(60.0, 10.0), polar_point(64.0, -25.0)], record_s=0.1)
    g = grid(0.1)
    loose = Imager(g, ImagingOptions(interp="lanczos4", refine_peaks=False, min_snr_db=None)).image(ping).peaks
    gated = Imager(g, ImagingOptions(interp="lanczos4", refine_peaks=False)).image(ping)
    top = 10 * np.log10(np.nanmax(gated.intensity))
    assert len(loose) > 2 * len(gated.peaks)            # rounding noise is "coherent" without a level gate
    assert min(r["intensity_db"] for r in loose) < top - 100
    assert all(r["intensity_db"] > top - 80 for r in gated.peaks)
    for r, a in ((60.0, 10.0), (64.0, -25.0)):           # both scatterers still detected
        assert any(abs(p["range_m"] - r) < 0.2 and abs(p["angle_deg"] - a) < 1.0 for p in gated.peaks)


def test_saddlepoint_tail_of_a_sum_of_exponentials_against_closed_forms():
    from clbeam.imaging.detection import exponential_sum_sf

    y = np.array([0.2, 0.5, 1.0, 2.0, 5.0, 20.0])
    # one exponential; two equal ones (a gamma); three distinct (hypoexponential, partial fractions)
    np.testing.assert_allclose(exponential_sum_sf(y, np.array([1.0])), np.exp(-y), rtol=0.05)
    np.testing.assert_allclose(exponential_sum_sf(y, np.array([0.5, 0.5])), np.exp(-2 * y) * (1 + 2 * y), rtol=0.05)
    lam = np.array([0.5, 0.3, 0.2])
    exact = sum(np.prod([li / (li - lj) for lj in lam if lj != li]) * np.exp(-y / li) for li in lam)
    np.testing.assert_allclose(exponential_sum_sf(y, lam), exact, rtol=0.05)
