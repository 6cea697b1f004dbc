"""A coherence peak's slide along its arc (clbeam.survey.burial.peak_slide_rad): the receive beam's width
from the sonar, and the noise term against a Monte Carlo of an array's beamformed peak."""

from __future__ import annotations

import math

import numpy as np
import pytest

from clbeam.survey.burial import (
    ARC_SIGMA_RAD,
    SLIDE_FLOOR_RAD,
    SLIDE_PER_STEP,
    arc_constrained,
    peak_slide_rad,
    receive_beam_width_rad,
)


def test_receive_beam_width_is_the_wavelength_at_the_band_centre_over_the_array():
    # the paper's SBP29: 2-9 kHz, 3.528 m
    assert receive_beam_width_rad((2000.0, 9000.0), 3.528) == pytest.approx(1500.0 / 5500.0 / 3.528, rel=1e-12)
    assert receive_beam_width_rad((2000.0, 9000.0), 3.528, 1480.0) == pytest.approx(1480.0 / 5500.0 / 3.528)
    for band, width in ((None, 3.5), ((2000.0, 9000.0), None), ((0.0, 0.0), 3.5), ((2000.0, 9000.0), -1.0)):
        assert math.isnan(receive_beam_width_rad(band, width))


def test_unknown_snr_or_beam_falls_back_and_coarse_grids_raise_the_floor():
    beam = 0.0773
    assert peak_slide_rad([np.nan], beam)[0] == ARC_SIGMA_RAD
    assert peak_slide_rad([20.0], math.nan)[0] == ARC_SIGMA_RAD
    # at very high SNR only the floor is left: the fixed one on fine grids, SLIDE_PER_STEP steps on coarse ones
    assert peak_slide_rad([120.0], beam)[0] == pytest.approx(SLIDE_FLOOR_RAD, rel=1e-6)
    step = math.radians(2.0)
    assert peak_slide_rad([120.0], beam, step)[0] == pytest.approx(SLIDE_PER_STEP * step, rel=1e-6)
    # a per-peak slide in arc_constrained is each peak's scalar one
    y, z = np.array([300.0, 300.0]), np.array([240.0, 240.0])
    slides = peak_slide_rad([15.0, 35.0], beam)
    both = arc_constrained(y, z, (0.0, 0.0), (239.0, 0.0), arc_sigma_rad=slides)
    for k in range(2):
        one = arc_constrained(y[k:k + 1], z[k:k + 1], (0.0, 0.0), (239.0, 0.0), arc_sigma_rad=float(slides[k]))
        assert [v[k] for v in both] == pytest.approx([v[0] for v in one], rel=1e-12)


@pytest.mark.parametrize("snr_db", [12.0, 20.0])
def test_noise_term_bounds_an_arrays_beamformed_peak_from_above(snr_db):
    """A 64-element array at its band centre, a plane wave at broadside in
    complex Gaussian noise of the given beamformed SNR; the peak of the
    delay-and-sum power, refined by a parabola, scatters in angle with a
    standard deviation of ``sqrt(6) / (2 pi)`` beams over ``sqrt(SNR)``
    (the Cramer-Rao bound).  The model's noise term (its slide less the
    floor) must cover that scatter without overstating it by more than 1.6."""
    rng = np.random.default_rng(3)
    n, width, wavelength, trials = 64, 3.528, 1500.0 / 5500.0, 4000
    x = (np.arange(n) - (n - 1) / 2) * width / n
    snr = 10 ** (snr_db / 10)
    noise = (rng.normal(size=(trials, n)) + 1j * rng.normal(size=(trials, n))) / math.sqrt(2)
    data = math.sqrt(snr / n) + noise  # beamformed: signal power n^2 snr / n, noise power n
    u = np.linspace(-0.04, 0.04, 321)
    steer = np.exp(-2j * np.pi * x[None, :] * u[:, None] / wavelength)
    power = np.abs(data @ steer.T) ** 2
    k = np.clip(np.argmax(power, axis=1), 1, u.size - 2)
    p0, p1, p2 = (power[np.arange(trials), k + d] for d in (-1, 0, 1))
    peak = u[k] + 0.5 * (p0 - p2) / (p0 - 2 * p1 + p2) * (u[1] - u[0])
    scatter = float(np.std(np.arcsin(peak)))
    beam = receive_beam_width_rad((2000.0, 9000.0), width)
    assert scatter == pytest.approx(math.sqrt(6) / (2 * math.pi) * beam / math.sqrt(snr), rel=0.15)
    noise_term = math.sqrt(peak_slide_rad([snr_db], beam)[0] ** 2 - SLIDE_FLOOR_RAD ** 2)
    assert scatter <= noise_term <= 1.6 * scatter
