"""The detection test of a coherence peak: its level above the ping's noise and
the chance that incoherent noise gives its coherence.

**Noise floor.** Where only noise reaches a cell, the coherent sum ``S`` of
``M`` channels of complex Gaussian noise is complex Gaussian, so the
intensity ``|S|^2`` is exponentially distributed about its mean, the noise
floor.  Echoes only add cells above it, so the floor is estimated from the
low tail, which echoes leave alone even when they fill most of the image:
the 10th percentile of the intensity over the cells that have a CF, divided
by ``-ln 0.9`` (the exponential distribution's 10th percentile over its
mean).  The float32 sums carry rounding about 80 dB below the image's
maximum, so the floor is never taken below that (noise-free simulations
otherwise turn every rounding wiggle into a detection).

**Significance.** For such noise the CF of one cell,
``|sum p|^2 / (M sum |p|^2)``, is the squared projection of a random
direction in ``C^M`` on a fixed one: Beta(1, M - 1) distributed, mean
``1/M``, so ``P(CF > x) = (1 - x)^(M - 1)``.  The peaks are picked on the
Hann-smoothed CF, a weighted mean of neighbouring cells along range whose
noise is correlated over the pulse's resolution: the correlation of the
noise's intensity at a two-way delay ``tau`` is ``sinc^2(B tau)`` for a band
``B``.  The smoothed CF keeps the mean ``1/M`` and has the variance
``var_1 * sum_k sum_l w_k w_l rho(k - l)``; a Beta distribution with these
two moments gives the false-alarm probability of a peak (per cell), and the
CF threshold that corresponds to a chosen one.  Checked against simulated
noise (32 channels, 2-9 kHz, ``tests/imaging/test_detection.py``): the
variance factor to 2 %, the rate of exceeding the 0.1 and 0.01 levels to
10-20 %; beyond, the smoothed CF's tail is heavier than the Beta's (the
largest weight dominates it), so ``pfa`` is optimistic there: measured
rates 1.4-2 times 1e-3 and 2-3.4 times 1e-4 (the larger with range steps
well below the pulse's resolution).  Apodized (weighted) CF is given the
same distribution, an approximation.
"""

from __future__ import annotations

import math

import numpy as np

from clbeam.imaging.postprocess import HANN7

#: the quantile of the intensity the noise floor is estimated from, and that quantile of Exp(1)
FLOOR_QUANTILE = 0.10
#: cells the floor's quantile is taken over (a regular subsample of larger images)
FLOOR_SAMPLE_CELLS = 500_000
#: the floor is never below the image maximum by more than this (float32 rounding of the sums, dB)
FLOOR_DYNAMIC_RANGE_DB = 80.0


def noise_floor(intensity: np.ndarray, cf: np.ndarray | None = None) -> float:
    """Mean intensity of the ping's incoherent noise (units of the intensity), from the low tail.

    Parameters
    ----------
    intensity : numpy.ndarray
        ``|S|^2`` of the ping's cells.
    cf : numpy.ndarray, optional
        The CF: only cells with a CF (enough channels) count; without it, cells with intensity > 0.
    """
    x = np.asarray(intensity).ravel()
    # a regular subsample of about half a million cells: the quantile to a fraction of a per cent, 20x faster
    stride = max(1, x.size // FLOOR_SAMPLE_CELLS)
    sample = x[::stride]
    use = np.isfinite(sample) & ((sample > 0) if cf is None else (np.asarray(cf).ravel()[::stride] > 0))
    if not np.any(use):
        return math.nan
    floor = float(np.quantile(sample[use], FLOOR_QUANTILE)) / -math.log1p(-FLOOR_QUANTILE)
    return max(floor, float(np.nanmax(x)) * 10 ** (-FLOOR_DYNAMIC_RANGE_DB / 10))


def smoothing_variance_factor(range_step_m: float, bandwidth_hz: float, sound_speed_m_s: float,
                              weights: np.ndarray = HANN7) -> float:
    """``sum_k sum_l w_k w_l sinc^2(2 B (k - l) dr / c)``: the noise variance of the smoothed CF over
    that of one cell (1 for one weight; ``sum w^2`` for cells far apart; 1 for cells much closer than
    the pulse's resolution ``c / 2B``)."""
    w = np.asarray(weights, dtype=np.float64)
    lag = np.arange(w.size)[:, None] - np.arange(w.size)[None, :]
    rho = np.sinc(2.0 * bandwidth_hz * lag * range_step_m / sound_speed_m_s) ** 2
    return float(w @ rho @ w)


def _beta_parameters(n_channels, variance_factor: float):
    m = np.asarray(n_channels, dtype=np.float64)
    mean = 1.0 / m
    var = (m - 1.0) / (m * m * (m + 1.0)) * variance_factor
    common = mean * (1.0 - mean) / var - 1.0
    return mean * common, (1.0 - mean) * common


def false_alarm_probability(cf_smooth, n_channels, variance_factor: float):
    """Probability (per cell) that incoherent noise over ``n_channels`` gives a smoothed CF of at
    least ``cf_smooth`` (NaN where fewer than 2 channels)."""
    from scipy.special import betaincc

    m = np.asarray(n_channels, dtype=np.float64)
    a, b = _beta_parameters(np.maximum(m, 2.0), variance_factor)
    p = betaincc(a, b, np.clip(np.asarray(cf_smooth, dtype=np.float64), 0.0, 1.0))
    return np.where(m >= 2, p, np.nan)


def equivalent_threshold(n_channels, variance_factor: float, probability: float):
    """The smoothed-CF level incoherent noise over ``n_channels`` exceeds with ``probability``."""
    from scipy.special import betainccinv

    a, b = _beta_parameters(np.maximum(np.asarray(n_channels, dtype=np.float64), 2.0), variance_factor)
    return betainccinv(a, b, probability)


def annotate_and_gate(rows: list, *, floor: float, n_channels: int | None, variance_factor: float,
                      min_snr_db: float | None) -> list:
    """Each row with ``snr_db`` (its intensity over the noise floor) and ``pfa`` (the false-alarm
    probability of its smoothed CF over ``n_channels``, NaN when unknown); rows below ``min_snr_db``
    left out (``None``: none)."""
    floor_db = 10 * math.log10(floor) if floor > 0 and math.isfinite(floor) else math.nan
    out = []
    for row in rows:
        snr = row["intensity_db"] - floor_db if math.isfinite(floor_db) else math.nan
        if min_snr_db is not None and math.isfinite(snr) and snr < min_snr_db:
            continue
        pfa = float(false_alarm_probability(row["cf"], n_channels, variance_factor)) if n_channels else math.nan
        out.append({**row, "snr_db": float(snr), "pfa": pfa})
    return out
