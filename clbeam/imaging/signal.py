"""Transmit replica, pulse compression with analytic signal, resampling.

Holland et al. (2024) eq. 1 sums ``p_n^H``: the match-filtered element time
series turned into analytic signals.  Both steps are one FFT pass here:
multiply the channel spectrum by the conjugate replica spectrum, keep the
positive frequencies and double them.
"""

from __future__ import annotations

import numpy as np

from clbeam.errors import OptionError, require


def compress_analytic(samples: np.ndarray, replica: np.ndarray, precision: str = "float64",
                      upsample: int = 1) -> np.ndarray:
    """Pulse compression and analytic signal of real channels in one FFT pass.

    ``y[k] = Σ_m x[k + m] r[m] / Σ_m r[m]²`` (the cross-correlation of the
    channel with the replica, normalised so that an echo ``a · r`` starting at
    sample ``k0`` compresses to a peak of real part ``a`` at ``k0``), returned
    as its analytic signal ``y + j H{y}``.

    Non-finite input samples are replaced by zero and every output sample
    whose correlation window touched one is set to NaN, so the imager skips
    the samples they corrupted; outside that mask the result is that of the
    zeroed record (the Hilbert transform's tail spreads a small, decaying
    difference beyond it).

    Parameters
    ----------
    samples : numpy.ndarray
        Real samples, ``(..., n_sample)``.
    replica : numpy.ndarray
        Real transmit replica at the same sample rate.
    precision : {"float64", "float32"}
        Arithmetic of the FFTs: float32 (for a float32 engine) moves half the
        memory and is 2-10x faster, within 3e-7 of float64.
    upsample : int
        Output samples per input sample: the compressed spectrum is
        zero-padded before its one inverse transform (band-limited
        interpolation of the whole correlation, so no wrap-around at the
        record's ends), output sample ``k`` at input time ``k / upsample``.

    Returns
    -------
    numpy.ndarray
        complex128 (complex64 with float32), shape of ``samples`` with
        ``upsample`` times the samples.
    """
    require(int(upsample) == upsample and upsample >= 1, OptionError,
            f"upsampling factor must be a positive integer, got {upsample!r}")
    up = int(upsample)
    real = np.float32 if precision == "float32" else np.float64
    x = np.asarray(samples, dtype=real)
    r = np.asarray(replica, dtype=np.float64)
    n, m = x.shape[-1], r.size
    energy = float(np.dot(r, r))
    require(energy > 0, OptionError, "transmit replica has zero energy")
    bad = ~np.isfinite(x)
    any_bad = bool(bad.any())
    if any_bad:
        x = np.where(bad, real(0), x)
    import scipy.fft  # here, not at the top: analytic pings never need it (0.2-0.3 s of start-up)

    nfft = scipy.fft.next_fast_len(n + m - 1)
    # the analytic spectrum: the real FFT's half (DC and Nyquist once, the rest doubled), zeros above
    half = scipy.fft.rfft(x, nfft, axis=-1, workers=-1)
    weights = analytic_weights(nfft)[:half.shape[-1]] * (up / energy)    # up: the longer inverse's 1/L
    half *= (np.conj(scipy.fft.rfft(r, nfft)) * weights).astype(half.dtype)
    y = scipy.fft.ifft(_padded_spectrum(half, nfft, up), axis=-1, workers=-1, overwrite_x=True)[..., :up * n]
    if any_bad:
        mark_corrupted(y, _touched_by(bad, m), up)
    return y


def _padded_spectrum(half: np.ndarray, nfft: int, up: int) -> np.ndarray:
    """The analytic spectrum ``half`` (the ``nfft``-point transform's non-negative bins) zero-padded to
    ``up nfft`` bins; an even transform's Nyquist bin split between its two ends."""
    spec = np.zeros(half.shape[:-1] + (up * nfft,), dtype=half.dtype)
    spec[..., :half.shape[-1]] = half
    if up > 1 and nfft % 2 == 0:
        spec[..., half.shape[-1] - 1] *= 0.5
        spec[..., up * nfft - nfft // 2] = spec[..., half.shape[-1] - 1]
    return spec


def _touched_by(bad: np.ndarray, m: int) -> np.ndarray:
    """Whether the correlation window ``x[k .. k + m - 1]`` of each output sample ``k`` holds a bad sample."""
    n = bad.shape[-1]
    padded = np.concatenate([np.zeros(bad.shape[:-1] + (1,)), bad, np.zeros(bad.shape[:-1] + (m,))], axis=-1)
    hits = np.cumsum(padded, axis=-1)
    return (hits[..., m:m + n] - hits[..., :n]) > 0


def mark_corrupted(out: np.ndarray, bad: np.ndarray, factor: int) -> None:
    """Set to NaN every sample of ``out`` (``factor`` samples per sample of ``bad``'s rate) within one input
    sample of a True entry of ``bad`` (``(..., n)`` bool)."""
    idx = np.nonzero(bad)
    n_out = out.shape[-1]
    for offset in range(-factor + 1, factor):
        k = np.clip(idx[-1] * factor + offset, 0, n_out - 1)
        out[idx[:-1] + (k,)] = np.nan


def analytic_weights(nfft: int) -> np.ndarray:
    """FFT weights turning a real signal's spectrum into its analytic signal's:
    1 at DC (and Nyquist for even ``nfft``), 2 at positive, 0 at negative frequencies."""
    w = np.zeros(nfft)
    w[0] = 1.0
    if nfft % 2 == 0:
        w[1:nfft // 2] = 2.0
        w[nfft // 2] = 1.0
    else:
        w[1:(nfft + 1) // 2] = 2.0
    return w


def upsample_analytic(signal: np.ndarray, factor: int) -> np.ndarray:
    """Band-limited (FFT) upsampling of analytic channels by an integer factor.

    The spectrum is zero-padded at the negative-frequency end, which is exact
    for an analytic signal whose band lies inside ``(0, fs/2)``.  Output sample
    ``k`` is at input time ``k / factor`` (samples); complex64 channels stay
    complex64 (within 4e-7 of complex128, 4-5x faster on every CPU), others
    are complex128.
    """
    require(int(factor) == factor and factor >= 1, OptionError, f"upsampling factor must be a positive integer, got {factor!r}")
    factor = int(factor)
    if factor == 1:
        return np.asarray(signal)
    import scipy.fft

    x = np.asarray(signal)
    x = x if x.dtype in (np.complex64, np.complex128) else x.astype(np.complex128)
    n = x.shape[-1]
    bad = ~np.isfinite(x)
    spec = scipy.fft.fft(np.where(bad, 0, x) if bad.any() else x, axis=-1, workers=-1)
    half = (n + 1) // 2
    padded = np.zeros(x.shape[:-1] + (n * factor,), dtype=x.dtype)
    padded[..., :half] = spec[..., :half]
    padded[..., n * factor - (n - half):] = spec[..., half:]
    out = scipy.fft.ifft(padded, axis=-1, workers=-1, overwrite_x=True)
    out *= factor
    if bad.any():
        mark_corrupted(out, bad, factor)
    return out


def apply_channel_response(samples: np.ndarray, gain_db: np.ndarray, phase_deg: np.ndarray) -> np.ndarray:
    """Real channels ``(channel, sample)`` as recorded through a channel
    response of gain ``gain_db`` (dB) and phase ``phase_deg`` (degree) per
    channel: ``10^(g/20) Re{a(t) e^(j φ)}`` with ``a`` the analytic signal,
    so the analytic signal of the result is ``10^(g/20) e^(j φ) a`` (what
    :func:`clbeam.imaging.apodization.calibration_factors` removes)."""
    x = np.asarray(samples, dtype=np.float64)
    n = x.shape[-1]
    a = np.fft.ifft(np.fft.fft(x, axis=-1) * analytic_weights(n), axis=-1)
    g = 10.0 ** (np.asarray(gain_db, dtype=np.float64) / 20.0) * np.exp(1j * np.deg2rad(phase_deg))
    return (g[:, None] * a).real


def pulse_band_hz(pulse, sample_rate_hz: float, level_db: float = 40.0) -> tuple[float, float] | None:
    """The band (Hz) of a transmit pulse: an LFM's sweep, or where an explicit
    waveform's spectrum is within ``level_db`` of its peak; ``None`` without a pulse.

    Parameters
    ----------
    pulse : Pulse or None
        The ping's pulse (:class:`clbeam.model.pulse.Pulse`).
    sample_rate_hz : float
        Sample rate of the waveform (Hz).
    level_db : float
        Spectrum level below the peak that bounds the band (dB).
    """
    if pulse is None:
        return None
    if pulse.waveform is None:
        return (min(pulse.f0_hz, pulse.f1_hz), max(pulse.f0_hz, pulse.f1_hz))
    w = np.asarray(pulse.waveform, dtype=np.float64)
    nfft = 1 << int(np.ceil(np.log2(max(8 * w.size, 256))))
    spectrum = np.abs(np.fft.rfft(w, nfft))
    f = np.fft.rfftfreq(nfft, 1.0 / sample_rate_hz)
    inband = f[spectrum >= spectrum.max() * 10 ** (-level_db / 20)]
    return (float(inband.min()), float(inband.max()))
