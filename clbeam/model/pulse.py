"""The transmit pulse: an LFM description or an explicit waveform, and its replica."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError, require


def lfm_replica(*, f0_hz: float, f1_hz: float, duration_s: float, sample_rate_hz: float) -> np.ndarray:
    """Linear-FM transmit replica (unit amplitude, no taper).

    ``x(t) = cos(2π (f0 t + (f1 - f0) t² / (2 T)))`` for ``0 <= t < T``,
    sampled at ``t = k / fs``.

    Parameters
    ----------
    f0_hz, f1_hz : float
        Start and end frequencies (Hz).
    duration_s : float
        Pulse length ``T`` (s).
    sample_rate_hz : float
        Sample rate ``fs`` (Hz).
    """
    require(duration_s > 0 and np.isfinite(duration_s), OptionError, f"pulse_duration must be > 0 s, got {duration_s!r}")
    require(sample_rate_hz > 0, OptionError, f"sample_rate must be > 0 Hz, got {sample_rate_hz!r}")
    require(0 <= f0_hz < sample_rate_hz / 2 and 0 <= f1_hz < sample_rate_hz / 2, OptionError,
            f"pulse band {f0_hz:g}-{f1_hz:g} Hz must lie below the Nyquist frequency {sample_rate_hz / 2:g} Hz")
    n = max(int(round(duration_s * sample_rate_hz)), 1)
    t = np.arange(n) / sample_rate_hz
    return np.cos(2 * np.pi * (f0_hz * t + 0.5 * (f1_hz - f0_hz) / duration_s * t * t))


@dataclass(frozen=True)
class Pulse:
    """Transmit pulse: an LFM description or an explicit waveform.

    Attributes
    ----------
    f0_hz, f1_hz, duration_s : float or None
        LFM start/end frequency (Hz) and length (s).
    waveform : numpy.ndarray or None
        Transmit waveform sampled at the ping's sample rate (takes precedence).
    delay_s : float
        Time (s) of the replica's first sample after transmit start (docs/ping-format.md
        ``tx_delay``; negative for a wavelet centred on transmit start):
        pulse compression puts an echo at its arrival time plus this delay.
    """

    f0_hz: float | None = None
    f1_hz: float | None = None
    duration_s: float | None = None
    waveform: np.ndarray | None = None
    delay_s: float = 0.0

    def __post_init__(self):
        require(np.isfinite(self.delay_s), OptionError, f"tx_delay must be finite, got {self.delay_s!r}")

    def replica(self, sample_rate_hz: float) -> np.ndarray:
        """The transmit replica at ``sample_rate_hz`` (Hz) for pulse compression."""
        if self.waveform is not None:
            return np.asarray(self.waveform, dtype=np.float64)
        return lfm_replica(f0_hz=self.f0_hz, f1_hz=self.f1_hz, duration_s=self.duration_s,
                           sample_rate_hz=sample_rate_hz)

    def band_hz(self, sample_rate_hz: float, *, below_peak_db: float = 10.0) -> tuple[float, float]:
        """The pulse's band (Hz): an LFM's sweep, or where an explicit waveform's power spectrum stands within
        ``below_peak_db`` of its maximum (outermost frequencies)."""
        if self.waveform is None:
            return min(self.f0_hz, self.f1_hz), max(self.f0_hz, self.f1_hz)
        w = np.asarray(self.waveform, dtype=np.float64)
        n = max(8 * w.size, 1024)
        power = np.abs(np.fft.rfft(w, n)) ** 2
        f = np.fft.rfftfreq(n, 1.0 / sample_rate_hz)
        inside = np.flatnonzero(power >= power.max() * 10 ** (-below_peak_db / 10))
        return float(f[inside[0]]), float(f[inside[-1]])

    @property
    def centre_frequency_hz(self) -> float | None:
        """Band centre (Hz) of an LFM pulse, ``None`` for an explicit waveform."""
        if self.f0_hz is None:
            return None
        return 0.5 * (self.f0_hz + self.f1_hz)
