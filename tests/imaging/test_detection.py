"""The detection test against simulated noise: the CF distribution of
incoherent noise (closed form for one cell, the moment-matched model for
the smoothed CF), the noise floor and a peak's SNR, and the level gate on
noise-free data."""

import dataclasses
import math

import numpy as np
import pytest
from scenes import bandlimited_noise, point_ping, polar_point

from clbeam.imaging.detection import (
    clutter_test_passes,
    contrast_at,
    contrast_windows,
    equivalent_threshold,
    false_alarm_probability,
    local_contrast,
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


def test_saddlepoint_solved_to_float64_against_the_closed_form_lugannani_rice():
    """Newton's steps onto the saddlepoint against its closed form for one exponential (``s = 1 - 1/y``)
    and for two equal ones (``s = 1/a - 2/y``), from 0.1 to 300 times the mean and at the mean.  The
    exponent ``s y - K(s)`` is stationary in ``s`` at the root, so a root off by an ulp moves the value by
    rounding only: ~1e-16 of ``y`` <= 300, ~1e-13 of ``p``; but ``y`` a fraction ``d`` off the mean,
    ``1/u - 1/w`` cancels terms ``1/d`` times larger than itself, each ``eps / d`` off (``s`` ~ ``d``), so
    ``eps / d^2``: 1e-11 relative for ``d`` >= 0.1, 1e-9 (ten times ``eps / d^2``) down to ``d`` = 2e-3."""
    from scipy.special import ndtr

    from clbeam.imaging.detection import exponential_sum_sf

    def lugannani_rice(s, w2, u):
        w = np.sign(s) * np.sqrt(w2)
        return ndtr(-w) + np.exp(-0.5 * w2) / np.sqrt(2 * np.pi) * (1 / u - 1 / w)

    far = np.r_[np.geomspace(0.1, 0.9, 100), np.geomspace(1.1, 300.0, 300)]
    near = np.r_[np.geomspace(0.98, 0.998, 100), np.geomspace(1.002, 1.02, 100)]
    for y, rtol in ((far, 1e-11), (near, 1e-9)):
        s = 1 - 1 / y   # one exponential: K = -log(1 - s), K'' = 1 / (1 - s)^2
        np.testing.assert_allclose(exponential_sum_sf(y, np.array([1.0])),
                                   lugannani_rice(s, 2 * (y - 1 - np.log(y)), y - 1), rtol=rtol, atol=0)
        a = 0.5   # two of 0.5: K = -2 log(1 - a s), K'' = 2 a^2 / (1 - a s)^2 = y^2 / 2
        s = 1 / a - 2 / y
        np.testing.assert_allclose(exponential_sum_sf(y, np.array([a, a])),
                                   lugannani_rice(s, 2 * (s * y + 2 * np.log(2 * a / y)), s * y / np.sqrt(2)),
                                   rtol=rtol, atol=0)
    # at the mean: the limit of the two terms
    assert exponential_sum_sf(np.array([1.0]), np.array([1.0]))[0] == pytest.approx(0.5 - 2 / (6 * np.sqrt(2 * np.pi)))


def test_saddlepoint_tail_far_below_the_mean_is_one_as_the_closed_form():
    """Below about 1e-154 of the mean the saddlepoint's terms underflow; the exact tail of one exponential,
    ``exp(-y)``, and of three distinct ones (partial fractions) is 1 to float64 there, and so must the
    approximation be (not NaN)."""
    from clbeam.imaging.detection import exponential_sum_sf

    y = np.array([1e-300, 1e-200, 1e-160, 1e-12])
    np.testing.assert_allclose(exponential_sum_sf(y, np.array([1.0])), np.exp(-y), rtol=1e-12)
    lam = np.array([0.5, 0.3, 0.2])
    exact = sum(np.prod([li / (li - lj) for lj in lam if lj != li]) * np.exp(-y / li) for li in lam)
    np.testing.assert_allclose(exponential_sum_sf(y, lam), exact, rtol=1e-12)


def _clutter_grid():
    """The paper's cell size, 0.2 m x 0.1 degree, over 100 m x 40 degrees, and the SBP29's clutter window and
    guard (+-10.7 m and +-6.6 degrees; +-1.07 m and +-2.2 degrees)."""
    window, guard = contrast_windows(BAND, 3.528, C)
    assert window == pytest.approx((10.714, 6.644), abs=1e-3) and guard == pytest.approx((1.0714, 2.2146), abs=1e-4)
    return np.arange(200.0, 300.0, 0.2), np.arange(-20.0, 20.0, 0.1), dict(window=window, guard=guard)


def test_clutter_contrast_of_speckle_follows_the_exponential_tail():
    """Fully developed speckle: intensity exponential about its mean, so a cell's contrast over the mean of
    the ~11,000 cells of its window outside the guard's cross exceeds T with probability exp(-T) (5 dB:
    0.042; 8 dB: 0.0018)."""
    ranges, angles, sizes = _clutter_grid()
    rng = np.random.default_rng(5)
    x = rng.exponential(3.0, size=(angles.size, ranges.size))
    i = rng.integers(70, angles.size - 70, 20_000)
    j = rng.integers(60, ranges.size - 60, 20_000)
    rows = [{"range_m": ranges[b], "angle_deg": angles[a]} for a, b in zip(i, j)]
    x_guard_max = np.array([x[a - 22:a + 23, b - 5:b + 6].max() for a, b in zip(i, j)])
    echo, clutter = local_contrast(x, ranges, angles, rows, **sizes)
    np.testing.assert_allclose(echo, 10 * np.log10(x_guard_max), rtol=1e-12)  # the echo: its guard's strongest
    contrast = 10 * np.log10(x[i, j]) - clutter
    for t_db, tol in ((5.0, 0.08), (8.0, 0.25)):
        assert np.mean(contrast >= t_db) == pytest.approx(np.exp(-10 ** (t_db / 10)), rel=tol)


def test_clutter_window_leaves_out_the_guard_and_cells_without_intensity():
    """The echo's main lobe, its spread along its range (all angles) and along its angle (all ranges), and NaN
    cells (outside a seabed band) do not enter the clutter mean: an echo 100 times a uniform clutter of 1 has
    a contrast of exactly 20 dB, from a CF peak on its tail too."""
    ranges, angles, sizes = _clutter_grid()
    x = np.ones((angles.size, ranges.size))
    i, j = int(np.argmin(np.abs(angles))), int(np.argmin(np.abs(ranges - 250.0)))
    x[:, j - 1:j + 2] = 30.0           # the low frequencies' wide beam along the echo's range
    x[i - 20:i + 21, :] = 5.0          # range sidelobes along its angle
    x[i - 4:i + 5, j - 1:j + 2] = 50.0
    x[:, j + 20:] = np.nan
    x[i, j] = 100.0
    tail = {"range_m": ranges[j + 3], "angle_deg": angles[i]}
    echo, clutter = local_contrast(x, ranges, angles, [tail], **sizes)
    assert echo[0] - clutter[0] == pytest.approx(20.0, abs=1e-9)


def test_clutter_sums_equal_a_brute_force_count_at_edges_corners_and_nans():
    """The window less the guard's cross, by inclusion-exclusion, against counting every cell: peaks on the
    image's edges and corners, NaN cells in an edge band and scattered."""
    rng = np.random.default_rng(11)
    ranges, angles = np.arange(0.0, 8.0, 0.2), np.arange(-2.0, 2.0, 0.1)
    window, guard = (2.1, 0.75), (0.45, 0.25)
    for _ in range(40):
        x = rng.exponential(1.0, size=(angles.size, ranges.size))
        x[:, :3][rng.random((angles.size, 3)) < 0.3] = np.nan
        x[rng.random(x.shape) < 0.05] = np.nan
        i, j = rng.choice([0, 1, angles.size // 2, angles.size - 1]), rng.choice([0, 2, ranges.size // 2, ranges.size - 1])
        echo, clutter = local_contrast(x, ranges, angles, [{"range_m": ranges[j], "angle_deg": angles[i]}],
                                       window=window, guard=guard)
        da, dr = np.abs(angles - angles[i])[:, None], np.abs(ranges - ranges[j])[None, :]
        in_window = (da <= window[1] + 1e-9) & (dr <= window[0] + 1e-9)
        in_cross = in_window & ((da <= guard[1] + 1e-9) | (dr <= guard[0] + 1e-9))
        in_guard = (da <= guard[1] + 1e-9) & (dr <= guard[0] + 1e-9)
        cells = x[in_window & ~in_cross]
        cells = cells[np.isfinite(cells)]
        assert clutter[0] == pytest.approx(10 * np.log10(cells.mean()), abs=1e-9)
        assert echo[0] == pytest.approx(10 * np.log10(np.nanmax(np.where(in_guard, x, np.nan))), abs=1e-12)


def test_the_clutter_test_applies_where_the_clutter_is_reverberation():
    # contrast 8 dB over clutter 12 dB above the noise: reverberation, below 10 dB: out
    assert not clutter_test_passes(8.0, 12.0, 10.0)
    # the same contrast where the clutter is the noise (2 dB above the floor): the SNR test judges it
    assert clutter_test_passes(8.0, 2.0, 10.0)
    assert clutter_test_passes(10.0, 12.0, 10.0) and clutter_test_passes(2.0, 12.0, None)
    assert clutter_test_passes(float("nan"), 12.0, 10.0) and not clutter_test_passes(8.0, float("nan"), 10.0)


def test_an_echo_in_noise_keeps_its_detection_and_reports_its_contrast():
    """A point echo 18.6 dB above noise: its contrast is its SNR (the clutter is the noise), and the clutter
    test removes nothing the noise test kept (noise alone: the clutter's mean is the floor)."""
    g = grid(0.1)
    ping = noise_ping(7, echo=1.5)
    gated = Imager(g, ImagingOptions(interp="lanczos4", refine_peaks=False)).image(ping).peaks
    no_clutter = Imager(g, ImagingOptions(interp="lanczos4", refine_peaks=False, min_contrast_db=None)).image(ping)
    assert len(gated) == len(no_clutter.peaks)
    best = min(gated, key=lambda r: abs(r["range_m"] - 60.0) + abs(r["angle_deg"] - 10.0))
    assert best["contrast_db"] == pytest.approx(best["snr_db"], abs=1.5)


@pytest.mark.slow
def test_line1_clutter_falls_fivefold_and_every_pipeline_detection_stays():
    """One ping of the simulated Line 1 (paper grid to 700 m): the seabed's and sub-bottom's scatterers give
    hundreds of coherent peaks far above the noise; the clutter test leaves a fifth or fewer of the peaks
    near no pipeline, and each pipeline's detection (the demo's rule) stays."""
    from clbeam.evaluation.demo import score_targets, truth_yz
    from clbeam.io.pingfile import pings_from_dataset
    from clbeam.sim import load_scene, simulate

    ds = simulate(load_scene("line1", pings=1, max_range_m=700.0))
    ping = pings_from_dataset(ds, "line1").ping(0)
    g = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, max_range_m=700.0, angles_deg=(-80.0, 80.0))
    truth = truth_yz(ds, 0)
    found = {}
    for label, opts in (("noise", ImagingOptions(min_contrast_db=None)), ("default", ImagingOptions())):
        scores, rest = score_targets(Imager(g, opts).image(ping).peaks, truth[:, 0], truth[:, 1],
                                     ds["target"].values, 0)
        found[label] = ([s.name for s in scores if s.detected], len(rest))
    assert found["default"][0] == found["noise"][0] == ["A", "B", "C"]
    assert found["default"][1] * 5 <= found["noise"][1]


@pytest.mark.parametrize("refine", [False, True])
@pytest.mark.parametrize("noise", [0.0, 3e-5])
def test_rows_and_contrasts_only_where_the_snr_test_can_pass_change_no_row(monkeypatch, refine, noise):
    """peak_rows builds rows, and measures clutter, only about the peaks the SNR test can keep: against every
    peak's row and contrast gated by annotate_and_gate itself, the same rows with the same values, on a
    noise-free ping (most of its maxima lie on the rounding, far below the floor) and a noisy one (the clutter
    box by box in both: the same sums, bit for bit)."""
    import clbeam.imaging.detection as detection
    from clbeam.imaging import peaks as peaks_module
    from clbeam.imaging.detection import annotate_and_gate

    monkeypatch.setattr(detection, "TABLE_CELLS_RATIO", np.inf)

    ping = point_ping([polar_point(60.0, 10.0), polar_point(64.0, -25.0)], record_s=0.1)
    ping.samples[:] += noise * np.random.default_rng(2).standard_normal(ping.samples.shape)
    g = grid(0.1)
    imager = Imager(g, ImagingOptions(interp="lanczos4", refine_peaks=refine))
    img = imager.image(ping)
    context, opts = img.context, imager.options
    refiner = imager._refiner(*imager._prepare(ping), img.cf_smooth, img.intensity) if refine else None
    every = peaks_module._rows(context, img.cf_smooth, img.intensity, g, opts.threshold, False, "lobe", refiner, {})
    window, guard = contrast_windows(context.band_hz, context.array_width_m, context.sound_speed_m_s)
    contrast = local_contrast(img.intensity, g.ranges_m, g.angles_deg, every, window=window, guard=guard)
    lam = smoothing_eigenvalues(float(np.median(np.diff(g.ranges_m))), float(np.diff(context.band_hz)[0]),
                                context.sound_speed_m_s)
    expected = annotate_and_gate(every, floor=noise_floor(img.intensity, img.cf_smooth), n_channels=context.n_channels,
                                 eigenvalues=lam, min_snr_db=opts.min_snr_db, contrast=contrast,
                                 min_contrast_db=opts.min_contrast_db)
    assert len(every) > len(expected) > 0
    assert img.peaks == expected


def brute_force_contrast(x, ranges, angles, i, j, window, guard):
    """Each row's echo and clutter (dB) by masks over the whole image (float64, finite cells only)."""
    echo, clutter = np.full(len(i), np.nan), np.full(len(i), np.nan)
    for k, (a, b) in enumerate(zip(i, j)):
        da, dr = np.abs(angles - angles[a])[:, None], np.abs(ranges - ranges[b])[None, :]
        in_window = (da <= window[1] + 1e-9) & (dr <= window[0] + 1e-9)
        in_cross = in_window & ((da <= guard[1] + 1e-9) | (dr <= guard[0] + 1e-9))
        in_guard = (da <= guard[1] + 1e-9) & (dr <= guard[0] + 1e-9)
        cells = x[in_window & ~in_cross].astype(np.float64)
        cells = cells[np.isfinite(cells)]
        peak = x[in_guard & np.isfinite(x)]
        if cells.size and cells.sum() > 0:
            clutter[k] = 10 * np.log10(cells.mean())
        if peak.size and peak.max() > 0:
            echo[k] = 10 * math.log10(float(peak.max()))
    return echo, clutter


@pytest.mark.parametrize("with_nan", [False, True])
def test_many_rows_clutter_from_the_summed_area_table_equals_counting_every_cell(monkeypatch, with_nan):
    """Hundreds of rows (the table and the sparse table of maxima, forced), on the edges and corners too, an
    uneven range axis, NaN cells in a band and scattered: against masks over the image, the echo exactly and
    the clutter to 1e-9 dB (float64 rounding of sums of a few thousand cells, ~1e-13 relative)."""
    import clbeam.imaging.detection as detection

    monkeypatch.setattr(detection, "TABLE_CELLS_RATIO", 0.0)
    rng = np.random.default_rng(12)
    ranges = np.cumsum(rng.uniform(0.1, 0.3, 150))
    angles = np.arange(-6.0, 6.0, 0.1)
    window, guard = (3.1, 1.55), (0.45, 0.35)
    x = rng.exponential(1.0, size=(angles.size, ranges.size)).astype(np.float32)
    if with_nan:
        x[:, -20:] = np.nan
        x[rng.random(x.shape) < 0.05] = np.nan
    i = np.r_[0, angles.size - 1, rng.integers(0, angles.size, 300)]
    j = np.r_[0, ranges.size - 1, rng.integers(0, ranges.size, 300)]
    rows = [{"range_m": ranges[b], "angle_deg": angles[a]} for a, b in zip(i, j)]
    echo, clutter = local_contrast(x, ranges, angles, rows, window=window, guard=guard)
    ref_echo, ref_clutter = brute_force_contrast(x, ranges, angles, i, j, window, guard)
    # the same cell: its dB to a few ulps of the log (NumPy's log10 and C's may round apart), 1e-12 dB being
    # 2e-13 of the intensity, far inside a float32 cell value's spacing (6e-8)
    np.testing.assert_allclose(echo, ref_echo, rtol=0, atol=1e-12)
    np.testing.assert_allclose(clutter, ref_clutter, rtol=0, atol=1e-9)


def test_a_quiet_window_beside_a_far_brighter_echo_is_summed_box_by_box(monkeypatch):
    """A noise-free image spans 10^20 and more: the table's differences would lose a window of 1e-20 cells
    beside an echo of 1 (its rounding ~1e-14 of the echo); such a window is summed itself, and its clutter is
    the brute force's to 1e-9 dB."""
    import clbeam.imaging.detection as detection

    monkeypatch.setattr(detection, "TABLE_CELLS_RATIO", 0.0)
    rng = np.random.default_rng(13)
    ranges, angles = np.arange(0.0, 30.0, 0.2), np.arange(-6.0, 6.0, 0.1)
    window, guard = (3.1, 1.55), (0.45, 0.35)
    x = 1e-20 * rng.exponential(1.0, size=(angles.size, ranges.size))
    x[:60, :] += rng.exponential(1.0, size=(60, ranges.size))     # bright above, quiet below
    i, j = rng.integers(70, angles.size, 50), rng.integers(0, ranges.size, 50)
    rows = [{"range_m": ranges[b], "angle_deg": angles[a]} for a, b in zip(i, j)]
    _, clutter = local_contrast(x, ranges, angles, rows, window=window, guard=guard)
    _, ref = brute_force_contrast(x, ranges, angles, i, j, window, guard)
    assert np.all(ref < -190)                                       # quiet windows, 10^19 below the echoes
    np.testing.assert_allclose(clutter, ref, rtol=0, atol=1e-9)


def filtered_contrast(x, i, j, window_cells, guard_cells):
    """Each peak's echo and clutter (dB) on a regular grid from whole-image filters (SciPy): the echo the
    guard box's maximum filter at the peak, the clutter the window's sum less the cross's (box sums from
    uniform filters in float64) over their finite cells' count; boxes of half-sizes ``(angle, range)`` cells,
    cut by the image's edges as the filters' constant padding cuts them."""
    from scipy.ndimage import maximum_filter, uniform_filter

    ok = np.isfinite(x)
    values, ones = np.where(ok, x, 0.0).astype(np.float64), ok.astype(np.float64)

    def box_sum(image, half_a, half_r):
        size = (2 * half_a + 1, 2 * half_r + 1)
        return uniform_filter(image, size, mode="constant", cval=0.0)[i, j] * (size[0] * size[1])

    (wa, wr), (ga, gr) = window_cells, guard_cells
    sums = [box_sum(v, *h) for v in (values, ones) for h in ((wa, wr), (wa, gr), (ga, wr), (ga, gr))]
    total, count = sums[0] - sums[1] - sums[2] + sums[3], np.rint(sums[4] - sums[5] - sums[6] + sums[7])
    peak = maximum_filter(np.where(ok, x, -np.inf), (2 * ga + 1, 2 * gr + 1), mode="constant", cval=-np.inf)[i, j]
    with np.errstate(divide="ignore", invalid="ignore"):
        echo = np.where(peak > 0, 10 * np.log10(np.where(peak > 0, peak, 1.0).astype(np.float64)), np.nan)
        clutter = np.where((count > 0) & (total > 0), 10 * np.log10(total / count), np.nan)
    return echo, clutter


@pytest.mark.parametrize("cells", ["finite", "nan-inf", "minus-inf"])
def test_thousands_of_peaks_on_a_regular_grid_equal_whole_image_filters(cells):
    """The fast way of many peaks (a summed-area table over the band the peaks cover, the echoes' maxima of
    the guard's width along range a block of rows at a time, the few boxes the edges cut each on their own)
    against SciPy's maximum and uniform filters over the whole image: the paper's cells and the SBP29's
    windows (+-53 ranges x +-66 angles, +-5 x +-22), 3,000 peaks in the band of 80 degrees a seabed takes
    and on the edges, float32 intensity spanning 10^6; NaN and infinite cells, or -inf ones alone (the
    table finds them itself), left out.  The echo to 1e-12 dB (the same cell), the clutter to 1e-9 dB:
    float64 rounding of sums of 14,000 cells by either way, ~1e-12 relative."""
    rng = np.random.default_rng(21)
    ranges, angles = 100.0 + 0.2 * np.arange(1200), -40.0 + 0.1 * np.arange(800)
    window, guard = (53.5 * 0.2, 66.5 * 0.1), (5.5 * 0.2, 22.5 * 0.1)
    x = (rng.exponential(1.0, (angles.size, ranges.size)) * 10 ** rng.uniform(0, 6, (angles.size, 1))).astype(np.float32)
    if cells == "nan-inf":
        x[:, :40] = np.nan
        x[rng.random(x.shape) < 0.01] = np.nan
        x[rng.random(x.shape) < 0.001] = np.inf
    if cells != "finite":
        x[rng.random(x.shape) < 0.001] = -np.inf
    i = np.r_[0, angles.size - 1, 0, angles.size - 1, rng.integers(200, 600, 3000)]
    j = np.r_[0, 0, ranges.size - 1, ranges.size - 1, rng.integers(0, ranges.size, 3000)]
    echo, clutter = contrast_at(x, ranges, angles, ranges[j], angles[i], window=window, guard=guard)
    ref_echo, ref_clutter = filtered_contrast(x, i, j, (66, 53), (22, 5))
    assert np.isfinite(ref_clutter).sum() > 2900
    np.testing.assert_allclose(echo, ref_echo, rtol=0, atol=1e-12)
    np.testing.assert_allclose(clutter, ref_clutter, rtol=0, atol=1e-9)


def test_box_maxima_of_one_width_and_of_many_equal_a_maximum_filter():
    """Boxes of one width (the sliding maxima) and of many (the sparse table, and on their own), in float32
    and float64, with NaN and infinite cells left out: each box's largest finite cell, as SciPy's maximum
    filter of the box's size gives it at the box's centre."""
    from scipy.ndimage import maximum_filter

    from clbeam.imaging.detection import box_maxima

    rng = np.random.default_rng(22)
    for dtype in (np.float32, np.float64):
        x = rng.standard_normal((300, 400)).astype(dtype)
        x[rng.random(x.shape) < 0.02] = np.nan
        x[rng.random(x.shape) < 0.002] = np.inf
        clean = np.where(np.isfinite(x), x, -np.inf)
        for half_a, half_r in ((22, 5), (3, 0), (0, 7), (40, 16)):
            c_a, c_r = rng.integers(half_a, 300 - half_a, 500), rng.integers(half_r, 400 - half_r, 500)
            box_a, box_r = np.stack([c_a - half_a, c_a + half_a + 1], 1), np.stack([c_r - half_r, c_r + half_r + 1], 1)
            ref = maximum_filter(clean, (2 * half_a + 1, 2 * half_r + 1))[c_a, c_r].astype(np.float64)
            ref[ref == -np.inf] = np.nan
            np.testing.assert_array_equal(box_maxima(x, box_a, box_r), ref)
            # other widths beside: a few (each on its own) and many (the sparse table)
            for extra in (5, 400):
                w = rng.integers(1, 2 * half_r + 2, extra)
                e_a, e_r = rng.integers(half_a, 300 - half_a, extra), rng.integers(0, 400 - w, extra)
                both_a = np.r_[box_a, np.stack([e_a - half_a, e_a + half_a + 1], 1)]
                both_r = np.r_[box_r, np.stack([e_r, e_r + w], 1)]
                boxes = [x[a - half_a:a + half_a + 1, r:r + n] for a, r, n in zip(e_a, e_r, w)]
                want = np.r_[ref, [b[np.isfinite(b)].max() if np.isfinite(b).any() else np.nan for b in boxes]]
                np.testing.assert_array_equal(box_maxima(x, both_a, both_r), want)


@pytest.mark.parametrize("many", [False, True], ids=["box-by-box", "table"])
def test_peak_rows_equal_each_peaks_own_row_tests_and_probability(monkeypatch, many):
    """peak_rows (columns for all peaks, the contrast of the peaks the SNR test keeps, the tests on arrays)
    against each peak on its own: its row (peak_row), its SNR over the floor, its echo and clutter by masks
    over the image, the two tests written out, its false-alarm probability alone; a noisy image with
    echoes, reverberation patches and NaN cells, the clutter summed box by box and from the table.  The same
    peaks in the same order with the same values (the clutter's float64 rounding aside: 1e-9 dB)."""
    import clbeam.imaging.detection as detection
    from clbeam.imaging.peaks import PingContext, peak_rows
    from clbeam.imaging.postprocess import coherence_peaks, peak_row

    monkeypatch.setattr(detection, "TABLE_CELLS_RATIO", 0.0 if many else np.inf)
    rng = np.random.default_rng(23)
    g = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, min_range_m=50.0, max_range_m=110.0,
                          angles_deg=(-15.0, 15.0))
    shape = g.shape
    cf = np.clip(rng.normal(0.2, 0.12, shape), 0, 1).astype(np.float32)
    x = rng.exponential(1.0, shape).astype(np.float32)
    x[100:200, 50:150] *= rng.choice([1.0, 30.0, 300.0])                # reverberation
    x[:, :10] = np.nan
    x[rng.random(shape) < 0.01] = np.nan
    x[rng.random(shape) < 0.002] *= 1e3                                  # echoes
    context = PingContext(index=3, centre_yz_m=(0.5, 1.0), n_channels=24, latitude_deg=50.1, longitude_deg=-4.2,
                          heading_deg=80.0)
    got = peak_rows(context, cf, x, g, threshold=0.35, min_snr_db=6.0, min_contrast_db=12.0)

    floor = noise_floor(x, cf)
    floor_db = 10 * math.log10(floor)
    window, guard = contrast_windows(context.band_hz, context.array_width_m, context.sound_speed_m_s)
    lam = smoothing_eigenvalues(0.2, float(np.diff(context.band_hz)[0]), context.sound_speed_m_s)
    cells = coherence_peaks(cf, 0.35)
    want = []
    for a, r in cells:
        row = peak_row(3, g.ranges_m[r], g.angles_deg[a], (0.5, 1.0), float(cf[a, r]), float(x[a, r]), context.navigation)
        snr = row["intensity_db"] - floor_db
        if not (math.isnan(snr) or snr >= 6.0):
            continue
        (echo,), (clutter,) = brute_force_contrast(x, g.ranges_m, g.angles_deg, [a], [r], window, guard)
        contrast = echo - clutter
        if not (math.isnan(contrast) or contrast >= 12.0 or clutter - floor_db < 3.0):
            continue
        row.update(snr_db=snr, contrast_db=contrast, pfa=float(false_alarm_probability(row["cf"], 24, lam)))
        want.append(row)
    assert 20 < len(want) < len(cells) and len(got) == len(want)
    for mine, theirs in zip(got, want):
        assert list(mine) == list(theirs)
        for key, value in theirs.items():
            assert mine[key] == (pytest.approx(value, abs=1e-9, nan_ok=True) if key == "contrast_db"
                                 else pytest.approx(value, rel=1e-12, nan_ok=True)), key


def test_the_floors_quantile_is_numpys_bit_for_bit():
    """The noise floor's quantile (one selection and a minimum) against numpy.quantile itself: sizes from
    one value up, ties, float32 and float64, quantiles at 0, 1, 0.1 and anywhere; the same float."""
    from clbeam.imaging.detection import quantile

    rng = np.random.default_rng(24)
    for trial in range(2000):
        n = int(rng.integers(1, 3000))
        values = rng.exponential(1.0, n) if trial % 3 else rng.integers(0, 5, n)
        values = values.astype(np.float32 if trial % 2 else np.float64)
        q = float(rng.choice([0.0, 1.0, 0.1, rng.random()]))
        assert quantile(values, q) == float(np.quantile(values, q))


@pytest.mark.parametrize("shape", [(1, 200), (50, 1)])
def test_contrast_on_a_grid_of_one_angle_or_one_range_is_the_guards_echo_and_no_clutter(shape):
    """A grid of one angle (or one range): every window outside the guard's cross is empty, so the clutter
    is NaN, and the echo is the largest cell within the guard along the one axis there is (written out)."""
    rng = np.random.default_rng(4)
    intensity = rng.exponential(1.0, shape)
    ranges = np.arange(shape[1]) * 0.2 + 100.0
    angles = np.arange(shape[0]) * 0.1 - 2.0
    r0, a0 = ranges[shape[1] // 2], angles[shape[0] // 2]
    echo, clutter = local_contrast(intensity, ranges, angles, [{"range_m": r0, "angle_deg": a0}],
                                   window=(10.0, 5.0), guard=(1.0, 2.0))
    near = (np.abs(angles[:, None] - a0) <= 2.0 + 1e-9) & (np.abs(ranges[None, :] - r0) <= 1.0 + 1e-9)
    assert echo[0] == pytest.approx(10 * np.log10(intensity[near].max()), rel=1e-12)
    assert np.isnan(clutter[0])
