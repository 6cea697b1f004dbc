"""The vertical beam: one earth-referenced nadir trace per ping.

Each ping is imaged on a polar grid of one angle, 0 degrees (nadir), with
the :class:`~clbeam.imaging.imager.Imager`: the grid is earth-referenced, so roll
and heave are compensated (docs/ping-format.md), and its ranges are the trace's sample
times, ``R_k = c t_k / 2`` with ``t_k = delay + k dt`` (:class:`TraceAxis`;
``dt`` is the ping file's sample interval ``1 / fs`` when that is a whole
number of microseconds).  The coherent sum ``S`` over the ``M``
contributing channels (docs/imaging.md) gives the trace (:class:`BeamTrace`):
the mean analytic signal ``S / M`` and its envelope ``|S| / M`` (0 where
``M = 0``).  Dividing by ``M`` keeps the amplitude of the channels' own
scale (an echo of amplitude ``a`` on every channel gives ``a``) and does not
jump where a channel drops out of the record.

The time axis holds whole milliseconds of delay and whole microseconds of
interval, as SEG-Y stores them (:mod:`clbeam.io.segy`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.imaging.engine import get_engine
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.io.pingfile import PingFile
from clbeam.io.segy import SEGY_MAX_DELAY_MS, SEGY_MAX_INTERVAL_US, SEGY_MAX_SAMPLES
from clbeam.model.grid import PolarGrid
from clbeam.model.ping import Ping

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TraceAxis:
    """The common time axis of every trace of a profile.

    Sample ``k`` is at two-way time ``t_k = delay_ms / 1e3 + k interval_us / 1e6``
    (s) after transmit start, and so at range ``c t_k / 2`` (m) from the source
    on the vertical beam.  Both numbers are whole, as SEG-Y stores them.

    Attributes
    ----------
    delay_ms : int
        Time of sample 0 after transmit start (ms): SEG-Y "delay recording time".
    interval_us : int
        Sample interval (microseconds).
    n_samples : int
        Samples per trace.
    """

    delay_ms: int
    interval_us: int
    n_samples: int

    def __post_init__(self):
        require(0 <= self.delay_ms <= SEGY_MAX_DELAY_MS, OptionError,
                f"trace delay {self.delay_ms} ms does not fit SEG-Y's 0-{SEGY_MAX_DELAY_MS} ms")
        require(1 <= self.interval_us <= SEGY_MAX_INTERVAL_US, OptionError,
                f"sample interval {self.interval_us} us does not fit SEG-Y's 1-{SEGY_MAX_INTERVAL_US} us")
        require(2 <= self.n_samples <= SEGY_MAX_SAMPLES, OptionError,
                f"a trace of {self.n_samples} samples does not fit SEG-Y's 2-{SEGY_MAX_SAMPLES}; "
                "use a smaller --max-range")

    @property
    def times_s(self) -> np.ndarray:
        """Two-way time of each sample after transmit start (s)."""
        return 1e-3 * self.delay_ms + 1e-6 * self.interval_us * np.arange(self.n_samples)

    def ranges_m(self, sound_speed_m_s: float) -> np.ndarray:
        """Range of each sample from the source on the vertical beam, ``c t / 2`` (m)."""
        return 0.5 * sound_speed_m_s * self.times_s

    @classmethod
    def for_record(cls, *, sample_rate_hz: float, t0_s, n_record_samples: int, sound_speed_m_s,
                   max_range_m: float | None = None) -> "TraceAxis":
        """The axis that holds every ping's record, or up to ``max_range_m``.

        Parameters
        ----------
        sample_rate_hz : float
            Sample rate of the ping file (Hz); the interval is ``1 / fs``
            rounded to whole microseconds.
        t0_s : float or array_like
            Time of sample 0 of each ping after transmit start (s); the delay
            is the earliest, rounded down to whole milliseconds.
        n_record_samples : int
            Samples per channel in the ping file.
        sound_speed_m_s : float or array_like
            Sound speed of each ping (m/s).
        max_range_m : float, optional
            Largest range (m): the trace ends at ``2 M / c`` with the slowest
            ping's ``c``, so it reaches ``M`` on every ping.  Default: the end
            of the latest record.

        Returns
        -------
        TraceAxis
            Delay (ms), interval (us) and samples, at least 2.
        """
        t0 = np.atleast_1d(np.asarray(t0_s, dtype=np.float64))
        c = np.atleast_1d(np.asarray(sound_speed_m_s, dtype=np.float64))
        require(np.isfinite(sample_rate_hz) and sample_rate_hz > 0, OptionError,
                f"sample rate must be > 0 Hz, got {sample_rate_hz!r}")
        interval_us = max(1, int(round(1e6 / sample_rate_hz)))
        if abs(interval_us - 1e6 / sample_rate_hz) > 1e-6 * interval_us:
            log.info("sample interval 1/%g Hz is not a whole number of microseconds; traces use %d us",
                     sample_rate_hz, interval_us)
        delay_ms = int(math.floor(1e3 * float(t0.min()) + 1e-9))
        t_end = float(np.max(t0)) + (n_record_samples - 1) / sample_rate_hz
        if max_range_m is not None:
            require(np.isfinite(max_range_m) and max_range_m > 0, OptionError,
                    f"--max-range must be a positive number of metres, got {max_range_m!r}")
            t_end = 2.0 * float(max_range_m) / float(c.min())
            require(t_end > 1e-3 * delay_ms, OptionError,
                    f"--max-range {max_range_m:g} m ends before the record starts "
                    f"({0.5 * float(c.min()) * 1e-3 * delay_ms:g} m at {delay_ms} ms)")
        n = int(math.floor((t_end - 1e-3 * delay_ms) / (1e-6 * interval_us) + 1e-9)) + 1
        return cls(delay_ms=delay_ms, interval_us=interval_us, n_samples=max(n, 2))

    @classmethod
    def for_file(cls, pings: PingFile, *, max_range_m: float | None = None) -> "TraceAxis":
        """:meth:`for_record` from a validated ping file's ``t0`` and ``sound_speed``."""
        n = pings.n_pings
        t0 = np.broadcast_to(np.asarray(pings.ds["t0"].values, dtype=np.float64), (n,))
        c = np.broadcast_to(np.asarray(pings.ds["sound_speed"].values, dtype=np.float64), (n,))
        return cls.for_record(sample_rate_hz=pings.sample_rate_hz, t0_s=t0, n_record_samples=pings.n_samples,
                              sound_speed_m_s=c, max_range_m=max_range_m)


@dataclass(frozen=True)
class BeamTrace:
    """The vertical beam of one ping on a :class:`TraceAxis`.

    Attributes
    ----------
    analytic : numpy.ndarray
        complex128 ``(n_samples,)``: mean analytic signal ``S / M`` of the
        pulse-compressed channels (the file's sample units), 0 where ``M = 0``.
    m : numpy.ndarray
        int ``(n_samples,)``: channels contributing to each sample.
    n_channels_used : int
        Channels that took part in the ping (dead ones left out).
    """

    analytic: np.ndarray
    m: np.ndarray
    n_channels_used: int

    @property
    def envelope(self) -> np.ndarray:
        """``|S| / M`` (the file's sample units), 0 where ``M = 0``."""
        return np.abs(self.analytic)


class VerticalBeam:
    """Forms the vertical (nadir, 0 degree, earth-referenced) beam of pings.

    Parameters
    ----------
    axis : TraceAxis
        Times (and so ranges ``c t / 2``) of the trace samples.
    interp : str
        Interpolation mode of the delay-and-sum (see
        :data:`clbeam.imaging.engine.INTERP_MODES`).
    backend : {"opencl", "reference"}
        Imaging engine.
    device : str or int, optional
        OpenCL device (index or name substring).
    engine : object, optional
        An existing engine to use instead of creating one.
    angle_deg : float
        Steer the beam this far from nadir (degree, earth frame, starboard
        positive; 0: the vertical beam), e.g. onto the normal of a sloping
        seabed.

    Notes
    -----
    One :class:`~clbeam.imaging.imager.Imager` per sound speed is kept (the grid's
    ranges depend on ``c``), all sharing one engine.
    """

    def __init__(self, axis: TraceAxis, *, interp: str = "cubic", backend: str = "opencl", device=None,
                 engine=None, angle_deg: float = 0.0):
        self.axis = axis
        self.angle_deg = float(angle_deg)
        # trace sample k is at range c t_k / 2: straight rays, whatever profile the file has
        self.options = ImagingOptions(interp=interp, outputs=("sums",), use_svp=False)
        self.engine = engine if engine is not None else get_engine(backend, device=device)
        self._imagers: dict[float, Imager] = {}

    def imager(self, sound_speed_m_s: float) -> Imager:
        """The imager of the one-angle grid for sound speed ``sound_speed_m_s`` (m/s)."""
        im = self._imagers.get(sound_speed_m_s)
        if im is None:
            if len(self._imagers) >= 8:
                self._imagers.clear()
            grid = PolarGrid(self.axis.ranges_m(sound_speed_m_s), np.array([self.angle_deg]))
            im = self._imagers[sound_speed_m_s] = Imager(grid, self.options, engine=self.engine)
        return im

    def setting(self, ping: Ping) -> str:
        """The mode, upsampling and beams ``ping`` is imaged with (``auto`` resolved), in one line."""
        return self.imager(ping.sound_speed_m_s).setting_of(ping).describe()

    def __call__(self, ping: Ping) -> BeamTrace:
        """The vertical beam of ``ping``: ``S / M`` at each trace sample."""
        img = self.imager(ping.sound_speed_m_s).image(ping)
        s = np.asarray(img.sums.s[0], dtype=np.complex128)
        m = np.asarray(img.sums.m[0])
        out = np.zeros_like(s)
        np.divide(s, m, out=out, where=m > 0)
        return BeamTrace(analytic=out, m=m, n_channels_used=img.n_channels_used)



def pool_max(values: np.ndarray, factor: int) -> np.ndarray:
    """Maximum over consecutive groups of ``factor`` samples (the last group may be short).

    Parameters
    ----------
    values : numpy.ndarray
        ``(n,)`` samples, e.g. a trace's envelope (any units).
    factor : int
        Samples per group; 1 or less returns a copy.

    Returns
    -------
    numpy.ndarray
        ``(ceil(n / factor),)`` maxima, in the units of ``values``; the short
        last group is padded with zeros (meant for non-negative values).
    """
    v = np.asarray(values)
    if factor <= 1:
        return v.copy()
    n = -(-v.size // factor) * factor
    padded = np.zeros(n, dtype=v.dtype)
    padded[:v.size] = v
    return padded.reshape(-1, factor).max(axis=1)


__all__ = ["BeamTrace", "TraceAxis", "VerticalBeam", "pool_max"]
