"""Inversion recovers known sediments from synthetic responses.

Synthetic data: the model itself at 5 kHz (the SBP band centre) on
incidence bins 0..80 deg, with the grain-size regressions for roughness and
volume, plus Gaussian noise in dB.  Truth is therefore known exactly.
"""

import math

import numpy as np
import pytest

from clbeam.errors import OptionError
from clbeam.seabed.avo.inversion import invert_attributes, invert_response
from clbeam.seabed.avo.model import backscatter_strength_db
from clbeam.seabed.avo.sediment import (
    density_ratio,
    sound_speed_ratio,
    spectral_strength_cm4,
    volume_parameter,
)

F_HZ = 5e3
INC = np.arange(0.0, 81.0, 1.0)
SEEDS = range(6)


def _clean(mz):
    return backscatter_strength_db(90.0 - INC, F_HZ, mz=mz)


@pytest.mark.parametrize("invert", [invert_response, invert_attributes])
@pytest.mark.parametrize("mz", [1.0, 3.0, 5.0, 7.0])
def test_noise_free_recovery_is_exact(invert, mz):
    # The optimiser's tolerances (ftol = xtol = 1e-8) bound the error far
    # below 1e-3 in each parameter when the data are the model itself.
    r = invert(INC, _clean(mz), F_HZ)
    assert r.mz == pytest.approx(mz, abs=1e-3)
    assert r.impedance_ratio == pytest.approx(density_ratio(mz) * sound_speed_ratio(mz), abs=1e-4)
    assert math.log10(r.w2_cm4) == pytest.approx(math.log10(spectral_strength_cm4(mz)), abs=1e-3)
    assert math.log10(r.sigma2) == pytest.approx(math.log10(volume_parameter(mz)), abs=1e-3)
    assert r.misfit_db < 1e-4 and r.converged


@pytest.mark.parametrize("mz", [1.0, 3.0, 5.0, 7.0])
@pytest.mark.parametrize("noise_db", [0.5, 1.0, 2.0])
def test_noisy_response_impedance_within_reported_uncertainty(mz, noise_db):
    # Over 6 noise draws the RMS impedance error must stay within 3x the
    # median reported 1-sigma: a calibrated linear estimate gives ~1x; the
    # factor 3 allows for the linearisation at the regressions' breakpoints
    # (Mz = 1 is one, 5.3 lies next to Mz = 5), where measured ratios reach
    # 1.9.  The misfit must match the noise: misfit^2 n / sigma^2 ~
    # chi^2(n - 3), n = 76 bins -> misfit/sigma = 0.98 +- 0.08 per draw;
    # the mean of 6 draws within [0.85, 1.1] (4 sd of that mean, plus the
    # small over-fit of a non-linear model).
    z_true = density_ratio(mz) * sound_speed_ratio(mz)
    err, std, mis = [], [], []
    for seed in SEEDS:
        y = _clean(mz) + np.random.default_rng(seed).normal(0.0, noise_db, INC.size)
        r = invert_response(INC, y, F_HZ)
        err.append(r.impedance_ratio - z_true)
        std.append(r.impedance_std)
        mis.append(r.misfit_db / noise_db)
    assert math.sqrt(np.mean(np.square(err))) <= 3.0 * np.median(std)
    assert 0.85 <= np.mean(mis) <= 1.1


@pytest.mark.parametrize("mz", [3.0])
@pytest.mark.parametrize("noise_db", [1.0, 2.0])
def test_noisy_response_grain_size_of_sand_within_reported_uncertainty(mz, noise_db):
    # Sand (Mz = 3, away from breakpoints): impedance changes fast with Mz,
    # so Mz itself is well constrained; RMS error within 2x the reported
    # 1-sigma (measured 0.7x).  Fine sediments (Mz >= 5) share almost one
    # impedance (rho nu = 1.17..1.12) and their Mz is not resolved.
    err, std = [], []
    for seed in SEEDS:
        y = _clean(mz) + np.random.default_rng(seed).normal(0.0, noise_db, INC.size)
        r = invert_response(INC, y, F_HZ)
        err.append(r.mz - mz)
        std.append(r.mz_std)
    assert math.sqrt(np.mean(np.square(err))) <= 2.0 * np.median(std)
    assert math.sqrt(np.mean(np.square(err))) <= 0.2  # absolute: 0.2 phi at <= 2 dB noise


def test_attribute_inversion_recovers_impedance_with_noise():
    # Attributes average ~30 bins each, so 1 dB bin noise becomes ~0.2 dB
    # on a mean; measured RMS impedance error over the draws is 0.024 at
    # Mz = 3 (impedance 1.447); 0.05 bounds it with margin 2.
    z_true = density_ratio(3.0) * sound_speed_ratio(3.0)
    err = []
    for seed in SEEDS:
        y = _clean(3.0) + np.random.default_rng(seed).normal(0.0, 1.0, INC.size)
        err.append(invert_attributes(INC, y, F_HZ).impedance_ratio - z_true)
    assert math.sqrt(np.mean(np.square(err))) <= 0.05


def test_tied_roughness_and_volume_reduce_to_grain_size_only():
    r = invert_response(INC, _clean(2.0), F_HZ, fit_roughness=False, fit_volume=False)
    assert r.mz == pytest.approx(2.0, abs=1e-3)
    assert r.log10_w2_std == 0.0 and r.log10_sigma2_std == 0.0
    assert r.w2_cm4 == pytest.approx(spectral_strength_cm4(r.mz), rel=1e-12)


def test_too_few_bins_raise():
    with pytest.raises(OptionError, match="more data"):
        invert_response(INC[:3], _clean(2.0)[:3], F_HZ)
    with pytest.raises(OptionError, match="grazing_window_deg"):
        invert_response(INC, _clean(2.0), F_HZ, grazing_window_deg=(50.0, 40.0))
