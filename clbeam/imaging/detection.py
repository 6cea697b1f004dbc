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
``1/M``, ``P(CF > x) = (1 - x)^(M - 1)``; so ``y = -(M - 1) ln(1 - x)`` is
exactly exponential.  The peaks are picked on the Hann-smoothed CF, a
weighted mean of neighbouring cells along range whose noise is correlated
over the pulse's resolution: the complex noise at two cells a two-way delay
``tau`` apart correlates as ``sinc(B tau)`` for a band ``B``.  A weighted sum
of correlated exponentials is a sum of independent ones weighted by the
eigenvalues of ``W^1/2 R W^1/2`` (``W`` the window, ``R`` that correlation);
its tail comes from the saddlepoint approximation (Lugannani-Rice), applied
to the smoothed CF through the same map ``y(x)`` (exact for one cell).
Checked against simulated noise (32 channels, 2-9 kHz,
``tests/imaging/test_detection.py``): the rates of exceeding the levels
this gives for 0.1 down to 1e-4 are 0.87-1.21 times the nominal, with range
steps above and well below the pulse's resolution.  Apodized (weighted) CF
is given the same distribution, an approximation.
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


def smoothing_eigenvalues(range_step_m: float, bandwidth_hz: float, sound_speed_m_s: float,
                          weights: np.ndarray = HANN7) -> np.ndarray:
    """Eigenvalues of ``W^1/2 R W^1/2``, ``R_kl = sinc(2 B (k - l) dr / c)``: the weights of the
    independent exponentials the smoothed CF of noise is a sum of (they add up to the window's sum, 1)."""
    w = np.asarray(weights, dtype=np.float64)
    w = w[w > 0]
    lag = np.arange(w.size)[:, None] - np.arange(w.size)[None, :]
    r = np.sinc(2.0 * bandwidth_hz * lag * range_step_m / sound_speed_m_s)
    lam = np.linalg.eigvalsh(np.sqrt(w)[:, None] * r * np.sqrt(w)[None, :])
    return lam[lam > 1e-12 * lam.max()]


def exponential_sum_sf(y: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """``P(sum lam_i E_i > y)``, ``E_i`` independent Exp(1), for every value of ``y``: the
    Lugannani-Rice saddlepoint approximation (its saddlepoint found by bisection, all values at once)."""
    from scipy.special import ndtr

    y = np.asarray(y, dtype=np.float64)
    mean, var, top = float(lam.sum()), float(np.sum(lam * lam)), 1.0 / float(lam.max())
    yy = np.where(np.isfinite(y) & (y > 0), y, mean)[..., None]
    lo = np.where(yy > mean, 0.0, -1e9 * top)
    hi = np.where(yy > mean, top * (1 - 1e-15), 0.0)
    for _ in range(110):  # K'(s) = sum lam / (1 - lam s) increases with s: halve [lo, hi] onto K'(s) = y
        mid = 0.5 * (lo + hi)
        above = np.sum(lam / (1.0 - lam * mid), axis=-1, keepdims=True) > yy
        lo, hi = np.where(above, lo, mid), np.where(above, mid, hi)
    s = 0.5 * (lo + hi)
    k = -np.sum(np.log1p(-lam * s), axis=-1)
    s, yy = s[..., 0], yy[..., 0]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        w = np.sign(s) * np.sqrt(np.maximum(2.0 * (s * yy - k), 0.0))
        u = s * np.sqrt(np.sum(lam**2 / (1.0 - lam * s[..., None]) ** 2, axis=-1))
        p = ndtr(-w) + np.exp(-0.5 * w * w) / math.sqrt(2 * math.pi) * (1.0 / u - 1.0 / w)
    # at the mean the two terms cancel: their limit, 1/2 - k3 / (6 sqrt(2 pi) k2^1.5) (k2, k3 the cumulants)
    near_mean = np.abs(yy - mean) < 1e-4 * mean
    p = np.where(near_mean, 0.5 - 2.0 * float(np.sum(lam**3)) / (6.0 * math.sqrt(2 * math.pi) * var**1.5), p)
    p = np.where(np.isfinite(y) & (y > 0), np.clip(p, 0.0, 1.0), np.where(y > 0, 0.0, 1.0))
    return p


def false_alarm_probability(cf_smooth, n_channels, eigenvalues: np.ndarray):
    """Probability (per cell) that incoherent noise over ``n_channels`` gives a smoothed CF of at
    least ``cf_smooth`` (NaN below 2 channels); ``eigenvalues`` from :func:`smoothing_eigenvalues`."""
    m = float(n_channels)
    x = np.clip(np.asarray(cf_smooth, dtype=np.float64), 0.0, 1.0)
    if not m >= 2:
        return np.full(x.shape, np.nan)[()]
    with np.errstate(divide="ignore"):
        y = -(m - 1.0) * np.log1p(-x)
    return exponential_sum_sf(y, eigenvalues)[()]


def equivalent_threshold(n_channels, eigenvalues: np.ndarray, probability: float) -> float:
    """The smoothed-CF level incoherent noise over ``n_channels`` exceeds with ``probability``."""
    from scipy.optimize import brentq

    return float(brentq(lambda x: float(false_alarm_probability(x, n_channels, eigenvalues)) - probability,
                        1e-9, 1.0 - 1e-12))


def annotate_and_gate(rows: list, *, floor: float, n_channels: int | None, eigenvalues: np.ndarray,
                      min_snr_db: float | None) -> list:
    """Each row with ``snr_db`` (its intensity over the noise floor) and ``pfa`` (the false-alarm
    probability of its smoothed CF over ``n_channels``, NaN when unknown); rows below ``min_snr_db``
    left out (``None``: none)."""
    floor_db = 10 * math.log10(floor) if floor > 0 and math.isfinite(floor) else math.nan
    snr = [row["intensity_db"] - floor_db if math.isfinite(floor_db) else math.nan for row in rows]
    kept = [(row, s) for row, s in zip(rows, snr) if min_snr_db is None or math.isnan(s) or s >= min_snr_db]
    if n_channels and kept:  # every row's probability in one call
        pfa = false_alarm_probability(np.array([row["cf"] for row, _ in kept]), n_channels, eigenvalues)
    else:
        pfa = np.full(len(kept), math.nan)
    return [{**row, "snr_db": float(s), "pfa": float(p)} for (row, s), p in zip(kept, np.atleast_1d(pfa))]
