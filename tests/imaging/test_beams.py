"""Beam-sampled imaging against direct imaging, and the error model against measured errors.

The direct image on the same engine is the reference of the interpolation in
angle; the exact band-limited float64 reference is that of the time
interpolation.  Tolerances come from :mod:`clbeam.imaging.engine.errormodel`,
which is itself checked against measurements here, across bands and sample
rates.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scenes import point_ping, polar_point

from clbeam.imaging.engine import INTERP_MODES, get_engine
from clbeam.imaging.engine.beams import BeamSampling, angular_band_limit, beam_plan, interpolate_beams
from clbeam.imaging.engine.common import Sums, interp_mode
from clbeam.imaging.engine.errormodel import (
    INTENSITY_FACTOR,
    angular_spectrum,
    beam_error,
    choose_setting,
    predicted_settings,
    time_error,
)
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.model.grid import PolarGrid
from clbeam.model.pulse import Pulse
from clbeam.model.svp import SoundSpeedProfile

TARGETS = [polar_point(60.0, 20.0), polar_point(75.0, -40.0), polar_point(90.0, 70.0), polar_point(82.0, 0.3)]
GRID = PolarGrid.regular(range_res_m=0.05, angle_res_deg=0.1, min_range_m=55.0, max_range_m=95.0, angles_deg=(-80, 80))


def db(x: float) -> float:
    return 10 * np.log10(x)


def intensity_error_db(got, want) -> float:
    return db(np.sum((got - want) ** 2) / np.sum(want**2))


@pytest.fixture(scope="module")
def f64():
    return get_engine("opencl", precision="float64")


@pytest.fixture(scope="module")
def scene(f64):
    ping = point_ping(TARGETS, record_s=0.16)
    inp = Imager(GRID, ImagingOptions(interp="lanczos8"), engine=f64).beamform_input(ping)
    direct = f64.beamform(inp, GRID, interp="lanczos8", outputs=("intensity", "cf", "sums"))
    return inp, direct


def predicted_beam_db(inp, sampling: BeamSampling, grid: PolarGrid) -> float:
    """The model's intensity error of the angular interpolation, with the step the plan really takes."""
    limit = angular_band_limit(inp.element_offsets_m, inp.source_offset_m, inp.top_frequency_hz,
                               inp.sound_speed_m_s, grid.angles_deg)
    plan = beam_plan(grid, limit, sampling)
    step = np.deg2rad(plan.grid.angles_deg[1] - plan.grid.angles_deg[0])
    across = np.linalg.norm(inp.element_offsets_m[:, 1:], axis=1)
    nu, power = angular_spectrum(across, inp.band_hz, inp.sound_speed_m_s, step)
    return db(INTENSITY_FACTOR * beam_error(sampling, nu, power))


@pytest.mark.parametrize("k, taps", [(1.25, 8), (1.25, 12), (1.5, 8), (2.0, 6)])
def test_beam_sampled_error_is_what_the_model_predicts(scene, f64, k, taps):
    """On four scatterers spread over the swath: measured within the model's prediction (+3 dB: it
    bounds the spectrum by its worst angle) and not more than 12 dB below it (it is not vacuous)."""
    inp, direct = scene
    got = f64.beamform(inp, GRID, interp="lanczos8", outputs=("intensity", "cf", "sums"), beams=BeamSampling(k, taps))
    measured = intensity_error_db(got.intensity, direct.intensity)
    predicted = predicted_beam_db(inp, BeamSampling(k, taps), GRID)
    assert predicted - 12 <= measured <= predicted + 3
    np.testing.assert_array_equal(got.m, direct.m)


def test_every_output_with_apodization_tables_band_and_tiles(f64):
    """Hann weights (W), a sound-speed profile (the beams get their own travel-time tables), a
    seabed-band window and angle tiles: M and W exact, intensity within the model's error."""
    from clbeam.imaging.raytrace import travel_time_tables

    profile = SoundSpeedProfile([0.0, 100.0], [1500.0, 1480.0])
    ping = dataclasses.replace(point_ping(TARGETS, record_s=0.16), svp=profile)
    im = Imager(GRID, ImagingOptions(interp="lanczos8", apodization="hann"), engine=f64)
    inp = im.beamform_input(ping)
    assert inp.table_source is not None and inp.weights is not None
    window = np.column_stack([np.full(GRID.shape[0], 62.0), np.full(GRID.shape[0], 88.0)])
    tiled = type(f64)(precision="float64", max_tile_cells=GRID.shape[1] * 100)
    sampling = BeamSampling(1.5, 12)
    direct = f64.beamform(inp, GRID, interp="lanczos8", outputs=("intensity", "cf", "sums"), range_window_m=window)
    got = tiled.beamform(inp, GRID, interp="lanczos8", outputs=("intensity", "cf", "sums"), range_window_m=window,
                         beams=sampling)
    np.testing.assert_array_equal(got.m, direct.m)
    np.testing.assert_allclose(got.w, direct.w, rtol=1e-12)
    assert intensity_error_db(got.intensity, direct.intensity) <= predicted_beam_db(inp, sampling, GRID) + 3
    # the sums for stacking, read back from the packed cells: S (both planes) and Q near the direct sums (the
    # field's error over every cell, its low sidelobes included, measured -67 dB; a plane or a cell misplaced
    # would be near 0 dB)
    for name in ("s", "q"):
        a, b = getattr(got, name), getattr(direct, name)
        assert db(np.sum(np.abs(a - b) ** 2) / np.sum(np.abs(b) ** 2)) <= -55.0
    outside = (GRID.ranges_m < 62.0) | (GRID.ranges_m > 88.0)
    assert not got.intensity[:, outside].any() and not got.m[:, outside].any()
    assert travel_time_tables  # the tables the beams used come from the same solver (imported for the reader)


def test_cells_of_changing_channel_sets_are_imaged_directly(f64):
    """Skipped samples in one channel and a grid past the record's end: where the channels summed
    change across the interpolation taps the cells are the direct image's, so M is exact everywhere
    and the cells short of channels are as accurate as the rest (within the model's error)."""
    ping = point_ping(TARGETS, record_s=0.125)               # the record ends at 93.75 m
    samples = ping.samples.copy()
    samples[7, 4000:4010] = np.nan
    ping = dataclasses.replace(ping, samples=samples)
    inp = Imager(GRID, ImagingOptions(interp="lanczos8"), engine=f64).beamform_input(ping)
    direct = f64.beamform(inp, GRID, interp="lanczos8", outputs=("intensity", "cf", "sums"))
    sampling = BeamSampling(1.5, 12)
    got = f64.beamform(inp, GRID, interp="lanczos8", outputs=("intensity", "cf", "sums"), beams=sampling)
    np.testing.assert_array_equal(got.m, direct.m)
    short = (direct.m != direct.m.max()) & (direct.m > 0)
    assert short.sum() > 1000                                  # the case is really exercised
    predicted = predicted_beam_db(inp, sampling, GRID)
    assert intensity_error_db(got.intensity[short], direct.intensity[short]) <= predicted + 3
    # the flagged cells, imaged as points, are the direct image's own values (float64: to rounding)
    plan = beam_plan(GRID, angular_band_limit(inp.element_offsets_m, inp.source_offset_m, inp.top_frequency_hz,
                                              inp.sound_speed_m_s, GRID.angles_deg), sampling)
    beam = f64._beamform(inp, plan.grid, interp_mode("lanczos8"), frozenset({"sums", "signature"}), None, 1.0)
    _, flagged = interpolate_beams(plan, beam, frozenset({"intensity"}), np.tile([0, GRID.shape[1]], (GRID.shape[0], 1)),
                                   False)
    assert flagged[0].size > 100
    for name in ("intensity", "cf", "s", "q"):
        np.testing.assert_allclose(getattr(got, name)[flagged], getattr(direct, name)[flagged], rtol=1e-9,
                                   atol=1e-12 * np.abs(getattr(direct, name)).max(), err_msg=name)


def test_kernel_equals_its_numpy_form_with_mismatched_taps(f64):
    rng = np.random.default_rng(4)
    plan = beam_plan(GRID, 10.0, BeamSampling(1.5, 12), granularity=16)   # 16: the beam count rounded up
    nb, nr = plan.grid.shape
    m = np.full((nb, nr), 64, np.int32)
    m[30, 100:200] = 63                                       # a channel missing on one beam
    g = m * 1.5
    g[50, 300:400] += 0.1                                     # as many channels, but another set
    beam = Sums(s=rng.standard_normal((nb, nr)) + 1j * rng.standard_normal((nb, nr)), q=rng.random((nb, nr)) + 2.0,
                m=m, w=m * 0.5, signature=g)
    outs = frozenset({"intensity", "cf", "sums"})
    for win in (np.tile([10, nr - 10], (GRID.shape[0], 1)), np.tile([0, nr], (GRID.shape[0], 1))):  # packed, whole
        _check_against_numpy_form(f64, plan, beam, outs, win)


def _check_against_numpy_form(f64, plan, beam, outs, win):
    """The OpenCL kernel, whole and in tiles, against interpolate_beams on one output window."""
    def as_grid(cells):
        grid = np.zeros(GRID.shape, dtype=bool)
        grid[cells] = True
        assert grid.sum() == cells[0].size                    # each flagged cell once
        return grid

    want, want_cells = interpolate_beams(plan, beam, outs, win, True)
    want_flag = as_grid(want_cells)
    # in tiles of 100 angle rows too: the flagged cells' angle indices count from each tile's first row
    tiled = type(f64)(precision="float64", max_tile_cells=GRID.shape[1] * 100)
    for engine in (f64, tiled):
        got, got_cells = engine._interpolate_beams(plan, beam, outs, win, True)
        np.testing.assert_array_equal(as_grid(got_cells), want_flag)
    assert want_flag.sum() > 0 and not want_flag[:, :10].any()
    on_beam = plan.first_tap[:, None] + np.arange(plan.taps)
    assert want_flag[np.any(on_beam == 50, axis=1)][:, 300:400].all()   # the other set is told apart
    for name in ("intensity", "cf", "q", "w"):
        np.testing.assert_allclose(got[name], want[name], rtol=1e-10, atol=1e-12, err_msg=name)
    np.testing.assert_array_equal(got["m"], want["m"])


@settings(max_examples=4, deadline=None)
@given(f0=st.floats(1000.0, 4000.0), width=st.floats(2000.0, 8000.0), rate=st.sampled_from([2.5, 3.2, 4.0]))
def test_time_error_model_across_bands_and_sample_rates(f64, f0, width, rate):
    """linear, cubic and lanczos4 against the exact band-limited reference, for random bands and
    sample rates: never more than 3 dB worse than predicted (the budget holds) and not more than
    12 dB better (the model is not vacuous; it is conservative where the band nears Nyquist)."""
    f1 = f0 + width
    fs = rate * f1
    pulse = Pulse(f0_hz=f0, f1_hz=f1, duration_s=0.02)
    ping = point_ping(TARGETS[:1], record_s=0.12, pulse=pulse, fs=fs)
    grid = PolarGrid.regular(range_res_m=0.1, angle_res_deg=1.0, min_range_m=58.0, max_range_m=62.0,
                             angles_deg=(0, 40))
    ref = get_engine("reference")
    inp = Imager(grid, ImagingOptions(interp="cubic"), engine=f64).beamform_input(ping)
    exact = ref.beamform(inp, grid, interp="exact", outputs=("intensity",))
    top = exact.intensity.max()
    keep = exact.intensity >= 1e-4 * top
    for mode in ("linear", "cubic", "lanczos4"):
        got = f64.beamform(inp, grid, interp=mode, outputs=("intensity",))
        measured = intensity_error_db(got.intensity[keep], exact.intensity[keep])
        predicted = db(INTENSITY_FACTOR * time_error(INTERP_MODES[mode], (f0, f1), fs, 1, inp.n_channels))
        assert predicted - 12 <= measured <= predicted + 3, (mode, measured, predicted)


def test_auto_setting_meets_the_budget_and_a_forced_mode_stays():
    across = np.abs((np.arange(64) - 31.5) * 3.528 / 64)
    found = predicted_settings(across, (2000.0, 9000.0), 40000.0, 1500.0, n_angles=1601, n_ranges=5501,
                               angle_span_rad=np.deg2rad(160), n_samples=62000)
    for budget in (-30.0, -40.0, -60.0):
        s = choose_setting(found, budget)
        assert s.error_db <= budget
        assert s.cost <= min(x.cost for x in found if x.error_db <= budget)
    forced = choose_setting(found, -60.0, interp="cubic", upsample=1)
    direct = next(x for x in found if x.interp == "cubic" and x.upsample == 1 and x.beams is None)
    assert forced.interp == "cubic" and forced.upsample == 1 and forced.error_db <= direct.error_db + 1.0
    assert choose_setting(found, -40.0, beams=None).beams is None
