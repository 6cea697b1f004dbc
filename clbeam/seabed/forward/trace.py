"""Emitted chirp, received and compressed traces (Rakotonarivo eq. 19, Figs. 8–9).

``y(w) = p_r(w) x(w)`` (eq. 19) and ``y_c = IFFT(y(w) conj(x(w)))`` (Fig. 8).
The record of ``N`` samples is treated as one period of the FFT: the
received trace is ``irfft(p_r X)`` and the compression is the circular
correlation with the replica over ``N`` samples, normalised by the replica
energy ``sum x^2`` so that a smooth echo of amplitude ``a`` compresses to a
peak of ``a``.  With a record that ends more than one pulse length after
the last echo nothing wraps, and the result equals the linear correlation of
:func:`clbeam.imaging.signal.compress_analytic`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.fft

from clbeam.errors import OptionError, require
from clbeam.imaging.signal import analytic_weights
from clbeam.model.pulse import lfm_replica
from clbeam.seabed.forward.layers import Seabed
from clbeam.seabed.forward.response import EchoSet, layer_echoes

#: Guard added after the last echo's compressed support (s).
RECORD_MARGIN_S = 0.005


@dataclass(frozen=True)
class Chirp:
    """Linear-FM emission ``x(t)`` (unit amplitude, no taper; eq. 19).

    Attributes
    ----------
    f0_hz, f1_hz : float
        Start and end frequencies (Hz).
    duration_s : float
        Pulse length (s).
    """

    f0_hz: float
    f1_hz: float
    duration_s: float

    def __post_init__(self) -> None:
        require(all(math.isfinite(v) for v in (self.f0_hz, self.f1_hz, self.duration_s)), OptionError,
                f"chirp parameters must be finite, got {self.f0_hz!r}, {self.f1_hz!r}, {self.duration_s!r}")
        require(0 < self.f0_hz < self.f1_hz, OptionError,
                f"chirp band must satisfy 0 < f0 < f1 Hz, got {self.f0_hz:g}-{self.f1_hz:g} Hz")
        require(self.duration_s > 0, OptionError, f"chirp duration must be > 0 s, got {self.duration_s!r}")

    @property
    def bandwidth_hz(self) -> float:
        """``f1 - f0`` (Hz)."""
        return self.f1_hz - self.f0_hz

    @property
    def centre_hz(self) -> float:
        """``(f0 + f1) / 2`` (Hz)."""
        return 0.5 * (self.f0_hz + self.f1_hz)

    def replica(self, sample_rate_hz: float) -> np.ndarray:
        """Sampled emission ``x[k]`` (:func:`clbeam.model.pulse.lfm_replica`)."""
        return lfm_replica(f0_hz=self.f0_hz, f1_hz=self.f1_hz, duration_s=self.duration_s,
                           sample_rate_hz=sample_rate_hz)

    @classmethod
    def parse(cls, text: str) -> "Chirp":
        """``"low"``, ``"high"`` (the paper's two 10 ms chirps) or ``"F0,F1,DUR"`` (Hz, Hz, s)."""
        key = str(text).strip().lower()
        if key in CHIRPS:
            return CHIRPS[key]
        parts = key.split(",")
        require(len(parts) == 3, OptionError,
                f"chirp must be 'low', 'high' or 'F0,F1,DUR' (Hz, Hz, s), got {text!r}")
        try:
            f0, f1, dur = (float(p) for p in parts)
        except ValueError:
            raise OptionError(f"chirp must be 'low', 'high' or 'F0,F1,DUR' (Hz, Hz, s), got {text!r}") from None
        return cls(f0, f1, dur)


#: The paper's two emissions (§4): 10 ms, 1.7–5.2 kHz and 5–15 kHz.
LOW_CHIRP = Chirp(1700.0, 5200.0, 0.010)
HIGH_CHIRP = Chirp(5000.0, 15000.0, 0.010)
CHIRPS = {"low": LOW_CHIRP, "high": HIGH_CHIRP}


def compress_circular(received: np.ndarray, replica: np.ndarray) -> np.ndarray:
    """Pulse compression ``y_c = IFFT(y conj(x)) / sum x^2`` over the record, as an analytic signal.

    The circular correlation over the record length ``N`` (the IFFT of
    Fig. 8), normalised by the replica energy; the real part is ``y_c``.

    Parameters
    ----------
    received : numpy.ndarray
        Real trace ``(..., N)``.
    replica : numpy.ndarray
        Emitted pulse, at most ``N`` samples.

    Returns
    -------
    numpy.ndarray
        complex128 analytic compressed trace, same shape as ``received``.
    """
    y = np.asarray(received, dtype=float)
    x = np.asarray(replica, dtype=float)
    n = y.shape[-1]
    require(0 < x.size <= n, OptionError, f"replica length {x.size} must lie in 1..{n} (the record length)")
    energy = float(np.dot(x, x))
    require(energy > 0, OptionError, "replica has zero energy")
    spec = scipy.fft.fft(y, axis=-1) * np.conj(scipy.fft.fft(x, n)) * analytic_weights(n) / energy
    return scipy.fft.ifft(spec, axis=-1)


@dataclass(frozen=True)
class ForwardTrace:
    """A modelled nadir (or specular) trace.

    Attributes
    ----------
    sample_rate_hz : float
        Sample rate (Hz).
    time_s : numpy.ndarray
        Sample times from the start of transmission (s), ``(N,)``.
    received : numpy.ndarray
        Received pressure ``y(t)`` (eq. 19), noise included, ``(N,)``.
    compressed : numpy.ndarray
        Analytic compressed trace; its real part is ``y_c`` (Fig. 8).
    replica : numpy.ndarray
        Emitted pulse.
    freq_hz : numpy.ndarray
        Frequencies of the record's real FFT (Hz).
    transfer : numpy.ndarray
        ``p_r(w)`` (eq. 15) at ``freq_hz``.
    emitted_spectrum : numpy.ndarray
        ``x(w)`` at ``freq_hz`` (record-length FFT of the pulse).
    echoes : EchoSet
        Terms of eq. 15 at ``freq_hz``.
    chirp : Chirp
    noise_std : float
        Standard deviation of the white noise added to ``received`` (Pa).
    """

    sample_rate_hz: float
    time_s: np.ndarray
    received: np.ndarray
    compressed: np.ndarray
    replica: np.ndarray
    freq_hz: np.ndarray
    transfer: np.ndarray
    emitted_spectrum: np.ndarray
    echoes: EchoSet
    chirp: Chirp
    noise_std: float

    def echo_spectrum(self, index: int) -> np.ndarray:
        """Spectrum of echo ``index`` in the received trace, ``A_i(w) x(w)`` (Fig. 9), complex."""
        require(0 <= index < self.echoes.times_s.size, OptionError,
                f"echo index must lie in 0..{self.echoes.times_s.size - 1}, got {index!r}")
        return self.echoes.spectra()[index] * self.emitted_spectrum


def _noise_sigma(received: np.ndarray, snr_db: float | None, noise_std: float | None) -> float:
    """Noise standard deviation (Pa) from ``snr_db`` (strongest echo's power ``A^2/2`` over the
    noise power) or given directly; 0 without either."""
    if snr_db is not None:
        require(math.isfinite(snr_db), OptionError, f"snr_db must be finite, got {snr_db!r}")
        return float(np.max(np.abs(received))) / math.sqrt(2.0 * 10 ** (snr_db / 10.0))
    if noise_std is not None:
        require(math.isfinite(noise_std) and noise_std >= 0, OptionError,
                f"noise_std must be finite and >= 0, got {noise_std!r}")
        return float(noise_std)
    return 0.0


def simulate_trace(seabed: Seabed, chirp: Chirp, *, sample_rate_hz: float = 48000.0, incidence_deg: float = 0.0,
                   p0: float = 1.0, record_s: float | None = None, snr_db: float | None = None,
                   noise_std: float | None = None, rng=None) -> ForwardTrace:
    """Received and compressed trace of a layered seabed for one emission (eqs. 15–19).

    Parameters
    ----------
    seabed : Seabed
    chirp : Chirp
        Emission (eq. 19).
    sample_rate_hz : float
        Sample rate (Hz), above twice the chirp's top frequency.
    incidence_deg : float
        Incidence of the specular ray (degree); 0 for the nadir trace.
    p0 : float
        Source amplitude of eq. 15 (Pa m).
    record_s : float, optional
        Record length (s); default: last echo + two pulse lengths + 5 ms, so
        that no echo's compressed response wraps around the record.
    snr_db : float, optional
        Adds white Gaussian noise of standard deviation ``A / sqrt(2 *
        10^(snr_db/10))``, ``A`` the largest absolute sample of the
        noise-free trace: the strongest echo's mean power ``A^2/2`` over the
        noise power, before compression.
    noise_std : float, optional
        Noise standard deviation (Pa) instead of ``snr_db``.
    rng : numpy.random.Generator or int, optional
        Noise generator or seed.

    Returns
    -------
    ForwardTrace
    """
    require(math.isfinite(sample_rate_hz) and sample_rate_hz > 2 * chirp.f1_hz, OptionError,
            f"sample_rate_hz must exceed twice the chirp's top frequency ({2 * chirp.f1_hz:g} Hz), "
            f"got {sample_rate_hz!r}")
    require(snr_db is None or noise_std is None, OptionError, "give snr_db or noise_std, not both")
    times = layer_echoes(seabed, [chirp.centre_hz], incidence_deg=incidence_deg).times_s
    last = float(np.nanmax(times))
    needed = last + chirp.duration_s
    if record_s is None:
        record_s = needed + chirp.duration_s + RECORD_MARGIN_S
    require(math.isfinite(record_s) and record_s > needed, OptionError,
            f"record_s must exceed the last echo's end, {needed:.6g} s, got {record_s!r}")
    n = int(math.ceil(record_s * sample_rate_hz))
    replica = chirp.replica(sample_rate_hz)
    freq = scipy.fft.rfftfreq(n, 1.0 / sample_rate_hz)
    x_spec = scipy.fft.rfft(replica, n)
    echoes = layer_echoes(seabed, freq, incidence_deg=incidence_deg, p0=p0)
    p_r = echoes.transfer()
    received = scipy.fft.irfft(p_r * x_spec, n)
    sigma = _noise_sigma(received, snr_db, noise_std)
    if sigma > 0:
        received = received + np.random.default_rng(rng).normal(0.0, sigma, n)
    return ForwardTrace(float(sample_rate_hz), np.arange(n) / sample_rate_hz, received,
                        compress_circular(received, replica), replica, freq, p_r, x_spec, echoes, chirp, sigma)
