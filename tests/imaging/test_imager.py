"""A point scatterer imaged through the whole chain lands where it was put."""

import dataclasses

import numpy as np
import pytest
from scenes import point_ping, polar_point

from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.postprocess import hann_smooth
from clbeam.model.grid import PolarGrid

R0, A0 = 120.0, 23.0
GRID = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, min_range_m=R0 - 4, max_range_m=R0 + 4,
                         angles_deg=(A0 - 3, A0 + 3))


def peak_cell(img):
    ia, ir = np.unravel_index(np.argmax(img.intensity), img.intensity.shape)
    return GRID.angles_deg[ia], GRID.ranges_m[ir], img.cf[ia, ir]


@pytest.mark.parametrize("kind", ["raw", "analytic"])
@pytest.mark.parametrize("backend", ["opencl", "reference"])
def test_point_scatterer_on_a_node_is_imaged_at_that_node(kind, backend):
    ping = point_ping(polar_point(R0, A0), kind=kind, record_s=0.2)
    img = Imager(GRID, ImagingOptions(interp="lanczos8"), backend=backend).image(ping)
    a, r, cf = peak_cell(img)
    assert r == pytest.approx(R0, abs=1e-9)
    assert a == pytest.approx(A0, abs=1e-9)  # accurate mode: on the node
    assert cf >= 0.99


def test_linear_mode_angle_within_one_cell_because_the_lobe_is_flat():
    ping = point_ping(polar_point(R0, A0), record_s=0.2)
    exact = Imager(GRID, ImagingOptions(interp="lanczos8"), backend="reference").image(ping)
    lin = Imager(GRID, ImagingOptions(interp="linear")).image(ping)
    a, r, cf = peak_cell(lin)
    assert r == pytest.approx(R0, abs=1e-9) and cf >= 0.99
    assert abs(a - A0) <= 0.1 + 1e-9
    # why it may move: across one 0.1 degree cell the true angular lobe changes by
    # much less than linear interpolation's amplitude error (up to ~1 - cos(pi f / fs * ...))
    ia0 = np.argmin(np.abs(GRID.angles_deg - A0))
    ir0 = np.argmin(np.abs(GRID.ranges_m - R0))
    lobe_step = 1 - exact.intensity[ia0 + 1, ir0] / exact.intensity[ia0, ir0]
    lin_error = np.max(np.abs(lin.intensity[ia0 - 1:ia0 + 2, ir0] / exact.intensity[ia0 - 1:ia0 + 2, ir0] - 1))
    assert lobe_step < 0.01
    assert lin_error > lobe_step or a == pytest.approx(A0, abs=1e-9)


@pytest.mark.parametrize("roll", [5.0, -5.0])
def test_rolled_array_sees_the_scatterer_where_an_unrolled_one_does(roll):
    target = polar_point(R0, A0)
    img = Imager(GRID, ImagingOptions(interp="cubic")).image(point_ping(target, roll_deg=roll, record_s=0.2))
    a, r, cf = peak_cell(img)
    assert (a, r) == pytest.approx((A0, R0), abs=0.1 + 1e-9) and cf >= 0.99
    # ignoring the roll puts it off by about the roll angle (the sign convention matters)
    ping = point_ping(target, roll_deg=roll, record_s=0.2)
    wrong = dataclasses.replace(ping, roll_deg=0.0)
    wide = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, min_range_m=R0 - 4, max_range_m=R0 + 4,
                             angles_deg=(A0 - 10, A0 + 10))
    bad = Imager(wide, ImagingOptions(interp="cubic")).image(wrong)
    ia, _ = np.unravel_index(np.argmax(bad.intensity), bad.intensity.shape)
    # starboard-down roll tilts the vessel's nadir to port, so in the vessel frame the
    # target sits roll degrees farther to starboard: A0 + roll
    assert wide.angles_deg[ia] == pytest.approx(A0 + roll, abs=0.5)


def test_heave_shifts_the_image_by_the_heave():
    target = polar_point(R0, A0)
    ping = point_ping(target, heave_m=1.5, record_s=0.2)
    img = Imager(GRID, ImagingOptions(interp="cubic")).image(ping)
    a, r, _ = peak_cell(img)
    assert (a, r) == pytest.approx((A0, R0), abs=0.2 + 1e-9)


@pytest.mark.parametrize("scale", [1e-30, 1e30])
def test_extreme_amplitudes_scale_the_intensity_exactly(scale):
    ping = point_ping(polar_point(R0, A0), record_s=0.2)
    loud = dataclasses.replace(ping, samples=ping.samples * scale)
    im = Imager(GRID, ImagingOptions(interp="linear", outputs=("intensity", "cf", "sums")))
    a, b = im.image(ping), im.image(loud)
    # scale is not a power of two: the float32 data round differently, so the
    # results agree to float32 sums over 64 channels (64 eps ~ 8e-6), not exactly
    eps64ch = 64 * np.finfo(np.float32).eps
    np.testing.assert_allclose(b.intensity, a.intensity.astype(np.float64) * scale**2, rtol=2 * eps64ch)
    np.testing.assert_allclose(b.cf, a.cf, atol=eps64ch)
    assert np.isfinite(b.intensity).all() and b.intensity.max() > 0


def test_dead_and_nan_channels_are_left_out_and_cf_stays_bounded():
    ping = point_ping(polar_point(R0, A0), record_s=0.2)
    x = ping.samples.copy()
    x[3] = 0.0          # dead (all zero)
    x[10] = np.nan      # all non-finite
    x[20, 500:600] = np.inf
    valid = np.ones(64, dtype=bool)
    valid[40] = False   # masked in the file
    bad = dataclasses.replace(ping, samples=x, channel_valid=valid)
    img = Imager(GRID, ImagingOptions(interp="lanczos4", outputs=("intensity", "cf", "sums"))).image(bad)
    assert img.n_channels_used == 61
    assert img.sums.m.max() == 61
    assert np.isfinite(img.cf).all() and 0 <= img.cf.min() and img.cf.max() <= 1 + 1e-5
    a, r, cf = peak_cell(img)
    assert (a, r) == pytest.approx((A0, R0), abs=1e-9) and cf >= 0.99


def test_peaks_table_has_the_scatterer_with_its_position():
    ping = point_ping(polar_point(R0, A0), record_s=0.2)
    img = Imager(GRID, ImagingOptions(interp="lanczos4", threshold=0.9)).image(ping)
    best = max(img.peaks, key=lambda p: p["intensity_db"])
    assert best["y_m"] == pytest.approx(R0 * np.sin(np.deg2rad(A0)), abs=0.2)
    assert best["z_m"] == pytest.approx(R0 * np.cos(np.deg2rad(A0)), abs=0.2)
    assert best["cf"] > 0.9


def test_seabed_band_computes_only_the_band_and_keeps_its_values():
    depth = 60.0
    grid = PolarGrid.regular(range_res_m=0.2, angle_res_deg=1, max_range_m=160, angles_deg=(-60, 60))
    # a flat row of scatterers at the seabed depth, strongest echo first in time at nadir
    ys = np.arange(-80, 81, 7.0)
    ping = point_ping([(0, y, depth) for y in ys], record_s=0.25)
    full = Imager(grid, ImagingOptions(interp="cubic")).image(ping)
    band = Imager(grid, ImagingOptions(interp="cubic", seabed_band_m=(5, 10))).image(ping)
    lo = (depth - 5) / np.cos(np.deg2rad(grid.angles_deg))[:, None]
    hi = (depth + 10) / np.cos(np.deg2rad(grid.angles_deg))[:, None]
    r = grid.ranges_m[None, :]
    inside = (r >= lo + 0.5) & (r <= hi - 0.5)  # the picked depth may differ by a range cell
    outside = (r < lo - 0.5) | (r > hi + 0.5)
    np.testing.assert_array_equal(band.intensity[inside], full.intensity[inside])
    np.testing.assert_array_equal(band.cf[inside], full.cf[inside])
    assert np.all(band.intensity[outside] == 0)
    assert outside.mean() > 0.5  # most of the grid was skipped
    # the smoothed CF, computed on the band's cells only, is that of the whole band image
    np.testing.assert_array_equal(band.cf_smooth, hann_smooth(band.cf))
    assert np.all(band.cf[outside] == 0)


def test_grid_outside_the_record_is_an_error_not_an_empty_image():
    from clbeam.errors import GridError

    ping = point_ping(polar_point(R0, A0), record_s=0.2)  # the record reaches c (n - 1) / (2 fs) = 149.98 m
    far = PolarGrid.regular(range_res_m=1, angle_res_deg=1, min_range_m=400, max_range_m=500, angles_deg=(-10, 10))
    with pytest.raises(GridError, match=r"grid ranges 400-500 m lie outside the record, which reaches ranges 0-149.98"):
        Imager(far).image(ping)


def test_absurdly_large_grid_is_refused_before_allocating():
    from clbeam.errors import GridError

    huge = PolarGrid(np.arange(0, 200_000, 0.01), np.linspace(-80, 80, 20_001))
    with pytest.raises(GridError, match="GiB per ping"):
        Imager(huge)


def test_a_raw_ping_without_a_pulse_is_refused_before_its_setting_is_measured(monkeypatch):
    """Raw samples cannot be compressed without the transmitted pulse: one line naming it, raised before
    the auto setting is measured on the ping's geometry (a calibration made with no replica would be
    remembered for the next ping of that geometry)."""
    from clbeam.errors import OptionError
    from clbeam.imaging import imager

    ping = dataclasses.replace(point_ping(polar_point(100.0, 10.0), kind="raw"), pulse=None)
    measured = []
    monkeypatch.setattr(imager, "choose_measured_setting", lambda *a, **k: measured.append(a))
    grid = PolarGrid.regular(range_res_m=0.5, angle_res_deg=1.0, max_range_m=150.0, angles_deg=(-30, 30))
    with pytest.raises(OptionError) as info:
        Imager(grid, ImagingOptions()).image(ping)
    assert "pulse" in str(info.value) and "\n" not in str(info.value) and measured == []
