"""CF only where enough channels contribute: the minimum of channels in every
engine path against the closed form CF = |S|^2 / (M Q) from the sums, peaks
near the record's end, and the warning when the grid runs past the record."""

import dataclasses
import logging

import numpy as np
import pytest
from scenes import bandlimited_noise, point_ping, polar_point

from clbeam.errors import OptionError
from clbeam.imaging.engine import get_engine
from clbeam.imaging.engine.beams import BeamSampling
from clbeam.imaging.imager import Imager, ImagingOptions, min_channels_of
from clbeam.model.grid import PolarGrid

C = 1500.0
#: a record that ends at 75 m; the grid runs 0.9 m past it
GRID = PolarGrid.regular(range_res_m=0.1, angle_res_deg=0.5, min_range_m=66.0, max_range_m=75.9, angles_deg=(-60, 60))


@pytest.fixture(scope="module")
def noisy_ping():
    ping = point_ping([polar_point(70.0, 20.0)], record_s=0.1)
    noise = bandlimited_noise(ping.samples.shape, seed=3).real * 0.3 * np.max(np.abs(ping.samples))
    return dataclasses.replace(ping, samples=ping.samples + noise)


def test_the_option_is_a_count_or_a_fraction_of_the_usable_channels():
    assert min_channels_of(0.5, 64) == 32 and min_channels_of(0.5, 63) == 32 and min_channels_of(0.01, 5) == 1
    assert min_channels_of(8, 64) == 8
    for bad in (0, -1, 1.5, float("nan")):
        with pytest.raises(OptionError, match="minimum of channels"):
            ImagingOptions(min_channels=bad)


@pytest.mark.parametrize("backend, beams", [("reference", None), ("opencl", None), ("opencl", BeamSampling(1.5, 8))])
def test_cf_is_the_closed_form_where_enough_channels_sum_and_zero_elsewhere(noisy_ping, backend, beams):
    engine = get_engine(backend)
    inp = Imager(GRID, ImagingOptions(interp="cubic"), engine=engine).beamform_input(noisy_ping)
    assert inp.min_channels == 32  # half of 64 by default
    got = engine.beamform(inp, GRID, interp="cubic", outputs=("intensity", "cf", "sums"), beams=beams)
    m = got.m
    assert m.min() < 32 <= m.max()  # the grid holds cells of both kinds
    with np.errstate(invalid="ignore", divide="ignore"):
        closed = np.where(m > 0, np.abs(got.s) ** 2 / (m * got.q), 0.0)
    enough = m >= 32
    np.testing.assert_allclose(got.cf[enough], np.minimum(closed[enough], 1.0), rtol=2e-4, atol=1e-6)
    assert np.all(got.cf[~enough] == 0)
    # with the minimum at one channel the same cells carry the plain CF, large for noise near the end
    loose = engine.beamform(dataclasses.replace(inp, min_channels=1), GRID, interp="cubic", outputs=("cf",),
                            beams=beams)
    np.testing.assert_allclose(loose.cf[enough], got.cf[enough], rtol=1e-6, atol=1e-7)
    assert np.max(loose.cf[(m > 0) & (m < 4)]) > 0.5


def test_no_peak_from_a_few_channels_at_the_record_end(noisy_ping):
    sums = Imager(GRID, ImagingOptions(interp="cubic", outputs=("sums",))).image(noisy_ping).sums
    m = sums.m

    def peak_channels(opts):
        peaks = Imager(GRID, opts).image(noisy_ping).peaks
        ia = np.searchsorted(GRID.angles_deg, [p["angle_deg"] - 1e-6 for p in peaks])
        ir = np.searchsorted(GRID.ranges_m, [p["range_m"] - 1e-6 for p in peaks])
        return m[ia, ir], peaks

    # the level and clutter gates off: they remove most of these too (their intensity is at the noise floor)
    loose_m, _ = peak_channels(ImagingOptions(interp="cubic", refine_peaks=False, min_channels=1, min_snr_db=None,
                                              min_contrast_db=None))
    strict_m, peaks = peak_channels(ImagingOptions(interp="cubic", refine_peaks=False, min_snr_db=None,
                                                   min_contrast_db=None))
    assert np.sum(loose_m < 32) >= 3       # without the minimum, noise summed over a few channels gives peaks
    assert np.all(strict_m >= 32)          # with it, none
    # the scatterer is still found
    assert any(abs(p["range_m"] - 70.0) < 0.3 and abs(p["angle_deg"] - 20.0) < 1.0 for p in peaks)


def test_a_grid_past_the_record_is_reported_once_with_how_far(noisy_ping, caplog):
    imager = Imager(GRID, ImagingOptions(interp="cubic", refine_peaks=False))
    end_m = 0.5 * C * noisy_ping.samples.shape[1] / noisy_ping.sample_rate_hz
    with caplog.at_level(logging.WARNING, logger="clbeam"):
        imager.image(noisy_ping)
        imager.image(noisy_ping)
    lines = [r.getMessage() for r in caplog.records if "beyond the end of the record" in r.getMessage()]
    assert len(lines) == 1
    assert f"reaches {GRID.ranges_m[-1] - end_m:.2f} m beyond" in lines[0] and "at least 32 of 64" in lines[0]
    inside = PolarGrid.regular(range_res_m=0.1, angle_res_deg=0.5, min_range_m=66.0, max_range_m=74.9,
                               angles_deg=(-60, 60))
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="clbeam"):
        Imager(inside, ImagingOptions(interp="cubic", refine_peaks=False)).image(noisy_ping)
    assert not [r for r in caplog.records if "beyond the end" in r.getMessage()]
