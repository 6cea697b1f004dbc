"""Along-track profile: one vertical beam per ping, as SEG-Y and as a figure.

Each ping is imaged on a polar grid of one angle, 0 degrees (nadir), with
the :class:`~clbeam.imaging.imager.Imager`: the grid is earth-referenced, so roll
and heave are compensated (SPEC §2), and its ranges are the trace's sample
times, ``R_k = c t_k / 2`` with ``t_k = delay + k dt`` (``dt`` is the ping
file's sample interval ``1 / fs`` when that is a whole number of
microseconds).  The coherent sum ``S`` over the ``M`` contributing channels
(SPEC §3 step 5) gives the trace: the mean analytic signal ``S / M`` and its
envelope ``|S| / M`` (0 where ``M = 0``).  Dividing by ``M`` keeps the
amplitude of the channels' own scale (an echo of amplitude ``a`` on every
channel gives ``a``) and does not jump where a channel drops out of the
record.

:func:`write_profile` writes the traces as SEG-Y (segyio, IEEE float) with
the ping's navigation, time and pulse in the trace headers, and draws the
profile like Holland et al. (2024) Fig. 1 (:func:`plot_profile`).
``clbeam profile`` (:func:`register_profile`, :func:`cmd_profile`) is the
command; ``docs/profile.md`` lists every header field written.
"""

from __future__ import annotations

import datetime
import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from clbeam import __version__
from clbeam.errors import OptionError, require
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.io.pingfile import PingFile
from clbeam.model.geodesy import along_track_m
from clbeam.model.grid import PolarGrid
from clbeam.model.ping import Ping

log = logging.getLogger(__name__)

#: largest sample count of a SEG-Y rev 1 trace (2-byte unsigned field)
SEGY_MAX_SAMPLES = 65535
#: largest sample interval (microseconds) the 2-byte binary-header field holds
SEGY_MAX_INTERVAL_US = 65535
#: SEG-Y data sample format code of 4-byte IEEE floating point
SEGY_FORMAT_IEEE_FLOAT = 5
#: coordinate scalar: negative means divide, so coordinates are in 1/1000 arc-second
COORDINATE_SCALAR = -1000
#: SEG-Y coordinate units code of seconds of arc
COORDINATE_UNITS_ARCSEC = 2
#: SEG-Y time basis code of UTC
TIME_BASIS_UTC = 4
#: SEG-Y sweep type codes
SWEEP_LINEAR, SWEEP_OTHER = 1, 4
#: the profile figure keeps at most this many rows (max-pooled) of each trace
PLOT_MAX_ROWS = 2000


# -- the trace time axis -------------------------------------------------------
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
        require(0 <= self.delay_ms <= 32767, OptionError,
                f"trace delay {self.delay_ms} ms does not fit SEG-Y's 0-32767 ms")
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


# -- the vertical beam -----------------------------------------------------------
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

    Notes
    -----
    One :class:`~clbeam.imaging.imager.Imager` per sound speed is kept (the grid's
    ranges depend on ``c``), all sharing one engine.
    """

    def __init__(self, axis: TraceAxis, *, interp: str = "cubic", backend: str = "opencl", device=None,
                 engine=None):
        from clbeam.imaging.engine import get_engine

        self.axis = axis
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
            grid = PolarGrid(self.axis.ranges_m(sound_speed_m_s), np.array([0.0]))
            im = self._imagers[sound_speed_m_s] = Imager(grid, self.options, engine=self.engine)
        return im

    def __call__(self, ping: Ping) -> BeamTrace:
        """The vertical beam of ``ping``: ``S / M`` at each trace sample."""
        img = self.imager(ping.sound_speed_m_s).image(ping)
        s = np.asarray(img.sums.s[0], dtype=np.complex128)
        m = np.asarray(img.sums.m[0])
        out = np.zeros_like(s)
        np.divide(s, m, out=out, where=m > 0)
        return BeamTrace(analytic=out, m=m, n_channels_used=img.n_channels_used)


# -- SEG-Y -------------------------------------------------------------------------
def _segyio():
    """The segyio module (the optional ``segy`` extra), or a one-line error saying how to install it."""
    try:
        import segyio
    except ImportError:
        raise OptionError("writing SEG-Y needs segyio: pip install 'clbeam[segy]' (or segyio)") from None
    return segyio


def _fits(value: int, bits: int, name: str) -> int:
    """``value`` when it fits a signed ``bits``-bit header field, else 0 (unknown) with a warning."""
    lim = 2 ** (bits - 1)
    if -lim <= value < lim:
        return int(value)
    log.warning("SEG-Y %s %d does not fit its %d-bit field; written as 0", name, value, bits)
    return 0


def sweep_fields(pulse) -> dict:
    """SEG-Y sweep start/end frequency (Hz), length (ms) and type of a pulse.

    An LFM pulse gives its band and length and type 1 (linear); an explicit
    waveform gives its length only and type 4 (other); no pulse gives zeros.
    Keys are the trace-header names of :class:`segyio.TraceField`.
    """
    if pulse is None:
        return {"SweepFrequencyStart": 0, "SweepFrequencyEnd": 0, "SweepLength": 0, "SweepType": 0}
    if pulse.waveform is not None:
        return {"SweepFrequencyStart": 0, "SweepFrequencyEnd": 0, "SweepType": SWEEP_OTHER,
                "SweepLength": None}  # filled in by the caller, who knows the sample rate
    return {"SweepFrequencyStart": _fits(round(pulse.f0_hz), 16, "sweep start frequency"),
            "SweepFrequencyEnd": _fits(round(pulse.f1_hz), 16, "sweep end frequency"),
            "SweepLength": _fits(round(1e3 * pulse.duration_s), 16, "sweep length"),
            "SweepType": SWEEP_LINEAR}


def time_fields(t) -> dict:
    """SEG-Y year, day of year (1 = 1 January), hour, minute, second of ``t``.

    Parameters
    ----------
    t : numpy.datetime64 or None
        Ping time, taken as UTC; fractions of a second are dropped (SEG-Y
        rev 1 has whole seconds).  ``None`` or NaT gives an empty dict.
    """
    if t is None or np.isnat(np.datetime64(t)):
        return {}
    d = np.datetime64(t, "us").astype(datetime.datetime)
    return {"YearDataRecorded": d.year, "DayOfYear": d.timetuple().tm_yday, "HourOfDay": d.hour,
            "MinuteOfHour": d.minute, "SecondOfMinute": d.second, "TimeBaseCode": TIME_BASIS_UTC}


def coordinate_fields(latitude_deg: float | None, longitude_deg: float | None) -> dict:
    """SEG-Y source, group and CDP coordinates of a ping's position.

    ``X`` is longitude and ``Y`` latitude in arc-seconds (coordinate units 2)
    times 1000 with scalar -1000 (so 1/1000 arc-second, about 3 cm; a
    longitude of 360 degrees is 1.3e9, inside the 4-byte field).  Without
    navigation the coordinates are 0 and the units field is left 0.
    """
    if latitude_deg is None or longitude_deg is None:
        return {}
    x = int(round(longitude_deg * 3600.0 * -COORDINATE_SCALAR))
    y = int(round(latitude_deg * 3600.0 * -COORDINATE_SCALAR))
    return {"SourceGroupScalar": COORDINATE_SCALAR, "CoordinateUnits": COORDINATE_UNITS_ARCSEC,
            "SourceX": x, "SourceY": y, "GroupX": x, "GroupY": y, "CDP_X": x, "CDP_Y": y}


def text_header(lines: list[str]) -> bytes:
    """A 40-line SEG-Y textual header from up to 38 lines (ASCII, 76 characters
    each, longer ones cut); lines 39-40 are the rev 1 ``SEG Y REV1`` and
    ``END TEXTUAL HEADER``."""
    segyio = _segyio()
    body = [ln.encode("ascii", "replace").decode("ascii")[:76] for ln in lines[:38]]
    rows = {i + 1: ln for i, ln in enumerate(body)}
    rows[39], rows[40] = "SEG Y REV1", "END TEXTUAL HEADER"
    return segyio.tools.create_text_header(rows).encode("ascii")


class SegyProfileWriter:
    """Writes profile traces to a SEG-Y rev 1 file, ping by ping.

    Parameters
    ----------
    path : str or path-like
        SEG-Y file to create (overwritten).
    axis : TraceAxis
        Trace time axis (delay, interval, samples).
    n_pings : int
        Pings in the profile; ping ``i`` (0-based) fills traces
        ``i * k .. i * k + k - 1``.
    analytic : bool
        ``k = 2`` traces per ping, real then imaginary part of ``S / M``;
        otherwise ``k = 1``: the envelope ``|S| / M``.
    text_lines : list of str
        Lines of the textual header.
    pulse : Pulse or None
        Transmit pulse, for the sweep fields.
    sample_rate_hz : float
        Sample rate of the ping file (Hz), for the original sample interval.
    n_record_samples : int
        Samples per channel in the ping file.
    """

    def __init__(self, path, axis: TraceAxis, n_pings: int, *, analytic: bool = False, text_lines=(),
                 pulse=None, sample_rate_hz: float = 0.0, n_record_samples: int = 0):
        segyio = _segyio()
        self.path = Path(path)
        self.axis = axis
        self.k = 2 if analytic else 1
        self.n_pings = n_pings
        sweep = sweep_fields(pulse)
        if sweep["SweepLength"] is None:
            sweep["SweepLength"] = _fits(round(1e3 * len(pulse.waveform) / sample_rate_hz), 16, "sweep length")
        self._sweep = sweep
        spec = segyio.spec()
        spec.format = SEGY_FORMAT_IEEE_FLOAT
        spec.samples = axis.times_s * 1e3
        spec.tracecount = n_pings * self.k
        spec.endian = "big"
        try:
            self._f = segyio.create(str(self.path), spec)
        except (OSError, RuntimeError) as exc:
            raise OptionError(f"cannot write SEG-Y file {self.path}: {exc}") from None
        B = segyio.BinField
        interval_orig = int(round(1e6 / sample_rate_hz)) if sample_rate_hz > 0 else axis.interval_us
        self._f.bin.update({
            B.JobID: 1, B.LineNumber: 1, B.ReelNumber: 1, B.Traces: self.k, B.AuxTraces: 0,
            B.Interval: axis.interval_us, B.IntervalOriginal: min(interval_orig, SEGY_MAX_INTERVAL_US),
            B.Samples: axis.n_samples, B.SamplesOriginal: min(int(n_record_samples), SEGY_MAX_SAMPLES),
            B.Format: SEGY_FORMAT_IEEE_FLOAT, B.EnsembleFold: 1, B.SortingCode: 1,
            B.SweepFrequencyStart: sweep["SweepFrequencyStart"], B.SweepFrequencyEnd: sweep["SweepFrequencyEnd"],
            B.SweepLength: sweep["SweepLength"], B.Sweep: sweep["SweepType"],
            B.CorrelatedTraces: 2, B.MeasurementSystem: 1,
            B.SEGYRevision: 1, B.SEGYRevisionMinor: 0, B.TraceFlag: 1, B.ExtendedHeaders: 0,
        })
        self._f.text[0] = text_header(list(text_lines))

    def __enter__(self) -> "SegyProfileWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Flush and close the file."""
        self._f.close()

    def header(self, ping: Ping, component: int, n_channels_used: int) -> dict:
        """Trace header of ping ``ping`` (component 1: envelope or real part, 2: imaginary part)."""
        j = ping.index * self.k + component - 1
        h = {
            "TRACE_SEQUENCE_LINE": j + 1, "TRACE_SEQUENCE_FILE": j + 1,
            "FieldRecord": ping.index + 1, "TraceNumber": component,
            "EnergySourcePoint": ping.index + 1, "CDP": ping.index + 1, "CDP_TRACE": component,
            "TraceIdentificationCode": 1, "NStackedTraces": n_channels_used, "DataUse": 1,
            "DelayRecordingTime": self.axis.delay_ms, "TRACE_SAMPLE_COUNT": self.axis.n_samples,
            "TRACE_SAMPLE_INTERVAL": self.axis.interval_us, "Correlated": 2,
            **self._sweep,
            **coordinate_fields(ping.latitude_deg, ping.longitude_deg),
            **time_fields(ping.time),
        }
        return {getattr(_segyio().TraceField, k): int(v) for k, v in h.items()}

    def write(self, ping: Ping, beam: BeamTrace) -> None:
        """Write the trace(s) of one ping (float32)."""
        require(0 <= ping.index < self.n_pings, OptionError,
                f"ping {ping.index} is outside the profile's 0..{self.n_pings - 1}")
        if self.k == 1:
            data = [beam.envelope]
        else:
            data = [beam.analytic.real, beam.analytic.imag]
        for comp, values in enumerate(data, start=1):
            j = ping.index * self.k + comp - 1
            self._f.header[j] = self.header(ping, comp, beam.n_channels_used)
            self._f.trace[j] = np.ascontiguousarray(values, dtype=np.float32)


# -- the figure --------------------------------------------------------------------
def pool_max(values: np.ndarray, factor: int) -> np.ndarray:
    """Maximum over consecutive groups of ``factor`` samples (the last group may be short)."""
    v = np.asarray(values)
    if factor <= 1:
        return v.copy()
    n = -(-v.size // factor) * factor
    padded = np.zeros(n, dtype=v.dtype)
    padded[:v.size] = v
    return padded.reshape(-1, factor).max(axis=1)


def _interp_linear(x, xp, fp):
    """Piecewise-linear ``fp(xp)`` at ``x``, extended linearly beyond both ends."""
    x = np.asarray(x, dtype=np.float64)
    y = np.interp(x, xp, fp)
    lo, hi = x < xp[0], x > xp[-1]
    y = np.where(lo, fp[0] + (x - xp[0]) * (fp[1] - fp[0]) / (xp[1] - xp[0]), y)
    return np.where(hi, fp[-1] + (x - xp[-1]) * (fp[-1] - fp[-2]) / (xp[-1] - xp[-2]), y)


def plot_profile(envelope: np.ndarray, path, *, t_top_s: float, t_bottom_s: float, sound_speed_m_s: float,
                 along_track_distance_m: np.ndarray | None = None, title: str = "",
                 dynamic_range_db: float = 50.0) -> Path:
    """Draw an along-track profile like Holland et al. (2024) Fig. 1.

    Parameters
    ----------
    envelope : numpy.ndarray
        ``(n_ping, n_rows)`` envelope, rows evenly spaced in two-way time.
    path : str or path-like
        PNG file to write.
    t_top_s, t_bottom_s : float
        Two-way time (s) of the top edge of the first row and the bottom edge
        of the last.
    sound_speed_m_s : float
        Sound speed (m/s) of the depth axis, ``depth = c t / 2`` below the source.
    along_track_distance_m : numpy.ndarray, optional
        Distance of each ping along the track (m), drawn as the top axis when
        it increases strictly.
    title : str
        Figure title.
    dynamic_range_db : float
        Colour range (dB) below the profile's maximum.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    from matplotlib.figure import Figure

    env = np.asarray(envelope, dtype=np.float64)
    top = float(env.max()) if env.size and env.max() > 0 else 1.0
    with np.errstate(divide="ignore"):
        db = 20 * np.log10(env / top)
    n_ping = env.shape[0]
    fig = Figure(figsize=(10, 5.5), layout="constrained")
    ax = fig.add_subplot()
    im = ax.imshow(db.T, extent=(0.5, n_ping + 0.5, 1e3 * t_bottom_s, 1e3 * t_top_s), aspect="auto",
                   cmap="gray_r", vmin=-dynamic_range_db, vmax=0, interpolation="nearest")
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("ping")
    ax.set_ylabel("two-way time (ms)")
    half_c_ms = 0.5 * sound_speed_m_s * 1e-3
    ax.secondary_yaxis("right", functions=(lambda t: t * half_c_ms, lambda d: d / half_c_ms)).set_ylabel(
        f"depth below the source (m, c = {sound_speed_m_s:g} m/s)")
    d = along_track_distance_m
    if d is not None and len(d) == n_ping and n_ping > 1 and np.all(np.diff(d) > 0):
        pings = np.arange(1, n_ping + 1, dtype=np.float64)
        sec = ax.secondary_xaxis("top", functions=(lambda p: _interp_linear(p, pings, d),
                                                   lambda x: _interp_linear(x, d, pings)))
        sec.set_xlabel("along-track distance (m)")
    fig.colorbar(im, ax=ax, label="envelope (dB re maximum)", pad=0.02)
    if title:
        fig.suptitle(title)
    p = Path(path)
    try:
        fig.savefig(p, dpi=120)
    except OSError as exc:
        raise OptionError(f"cannot write figure {p}: {exc}") from None
    return p


# -- the whole profile -------------------------------------------------------------
@dataclass(frozen=True)
class ProfileResult:
    """What :func:`write_profile` wrote.

    Attributes
    ----------
    segy_path : pathlib.Path
        SEG-Y file.
    png_path : pathlib.Path or None
        Figure, if drawn.
    axis : TraceAxis
        Trace time axis.
    n_pings : int
        Pings (one ensemble each).
    traces_per_ping : int
        1 (envelope) or 2 (real, imaginary part of ``S / M``).
    seconds : float
        Wall time (s).
    """

    segy_path: Path
    png_path: Path | None
    axis: TraceAxis
    n_pings: int
    traces_per_ping: int
    seconds: float


def _check_output(path: Path, what: str) -> None:
    require(not path.is_dir(), OptionError, f"cannot write {what} {path}: it is a folder")
    parent = path.parent if str(path.parent) else Path(".")
    require(parent.is_dir(), OptionError, f"cannot write {what} {path}: folder {parent} does not exist")


def _header_lines(source: Path, pings: PingFile, axis: TraceAxis, *, interp: str, analytic: bool) -> list[str]:
    n = pings.n_pings
    c = np.asarray(pings.ds["sound_speed"].values, dtype=np.float64)
    pulse = pings.pulse
    if pulse is None:
        pulse_line = "PULSE: NONE (INPUT ALREADY PULSE-COMPRESSED ANALYTIC)"
    elif pulse.waveform is not None:
        pulse_line = f"PULSE: EXPLICIT WAVEFORM, {len(pulse.waveform)} SAMPLES; SWEEP TYPE 4 (OTHER)"
    else:
        pulse_line = (f"PULSE: LFM {pulse.f0_hz:g}-{pulse.f1_hz:g} HZ, {1e3 * pulse.duration_s:g} MS; "
                      "SWEEP FIELDS SET, TYPE 1 (LINEAR)")
    layout = ("TRACES PER PING 2: REAL(S/M) (TRACE NUMBER 1), IMAG(S/M) (TRACE NUMBER 2)" if analytic
              else "TRACES PER PING 1: ENVELOPE |S|/M (TRACE NUMBER 1)")
    return [
        f"CLBEAM {__version__} ALONG-TRACK PROFILE: ONE VERTICAL BEAM PER PING",
        f"SOURCE FILE: {source.name}",
        f"PINGS: {n}  TRACES: {n * (2 if analytic else 1)}  SAMPLES/TRACE: {axis.n_samples}",
        f"SAMPLE INTERVAL: {axis.interval_us} US  DELAY (T0): {axis.delay_ms} MS  FORMAT 5 IEEE FLOAT",
        "BEAM: 0 DEG FROM NADIR, EARTH-REFERENCED (ROLL, HEAVE COMPENSATED; PITCH IGNORED)",
        f"DELAY-AND-SUM OF PULSE-COMPRESSED ANALYTIC CHANNELS, INTERPOLATION {interp.upper()}",
        "S = COHERENT SUM OVER THE M CONTRIBUTING CHANNELS; TRACE = S/M, 0 WHERE M = 0",
        layout,
        "SAMPLE K: TWO-WAY TIME DELAY + K*INTERVAL; RANGE FROM SOURCE = C*T/2",
        f"SOUND SPEED {c.min():g}-{c.max():g} M/S" if c.min() != c.max() else f"SOUND SPEED {c.min():g} M/S",
        pulse_line,
        "COORDINATES: SOURCE/GROUP/CDP X = LONGITUDE, Y = LATITUDE IN ARC-SECONDS,",
        f"  SCALAR {COORDINATE_SCALAR} (BYTES 71-72), COORDINATE UNITS 2 (BYTES 89-90)",
        "TIME: PING TIME (UTC, TIME BASIS 4), WHOLE SECONDS",
        "FIELD RECORD = CDP = ENERGY SOURCE POINT = PING INDEX IN THE FILE + 1",
        "NSTACKEDTRACES (BYTES 33-34) = CHANNELS USED IN THE PING",
    ]


def write_profile(pings_path, segy_path, *, png_path=None, plot: bool = True, max_range_m: float | None = None,
                  interp: str = "cubic", analytic: bool = False, backend: str = "opencl", device=None,
                  engine=None, progress=None) -> ProfileResult:
    """Form the vertical beam of every ping of a ping file; write SEG-Y and a figure.

    Parameters
    ----------
    pings_path : str or path-like
        Ping file (SPEC §7).
    segy_path : str or path-like
        SEG-Y file to write (see the module notes and ``docs/profile.md``).
    png_path : str or path-like, optional
        Figure to write; default: ``segy_path`` with suffix ``.png``.
    plot : bool
        Draw the figure.
    max_range_m : float, optional
        Largest range (m) of the traces (default: the end of the record).
    interp : str
        Interpolation mode of the delay-and-sum.
    analytic : bool
        Write the real and imaginary parts of ``S / M`` (2 traces per ping)
        instead of the envelope ``|S| / M``.
    backend : {"opencl", "reference"}
        Imaging engine.
    device : str or int, optional
        OpenCL device.
    engine : object, optional
        An existing engine to use.
    progress : callable, optional
        ``progress(iterable, total)`` wraps the ping loop (a progress bar).

    Returns
    -------
    ProfileResult

    Raises
    ------
    ClbeamError
        On a bad ping file, option or output path; a partly written SEG-Y
        file is removed.
    """
    t_start = time.perf_counter()
    segy_path = Path(segy_path)
    png = (Path(png_path) if png_path is not None else segy_path.with_suffix(".png")) if plot else None
    require(png is None or png.resolve() != segy_path.resolve(), OptionError,
            f"the figure and the SEG-Y file are both {segy_path}; give another --png")
    _check_output(segy_path, "SEG-Y file")
    if png is not None:
        _check_output(png, "figure")
    _segyio()  # before any imaging
    pings_path = Path(pings_path)
    with PingFile(pings_path) as pings:
        axis = TraceAxis.for_file(pings, max_range_m=max_range_m)
        beam = VerticalBeam(axis, interp=interp, backend=backend, device=device, engine=engine)
        n = pings.n_pings
        factor = max(1, -(-axis.n_samples // PLOT_MAX_ROWS))
        rows = np.zeros((n, -(-axis.n_samples // factor)), dtype=np.float32) if png is not None else None
        lat, lon = np.full(n, np.nan), np.full(n, np.nan)
        iterable = progress(pings, n) if progress is not None else pings
        writer = SegyProfileWriter(segy_path, axis, n, analytic=analytic,
                                   text_lines=_header_lines(pings_path, pings, axis, interp=interp, analytic=analytic),
                                   pulse=pings.pulse, sample_rate_hz=pings.sample_rate_hz,
                                   n_record_samples=pings.n_samples)
        try:
            with writer:
                for ping in iterable:
                    tr = beam(ping)
                    writer.write(ping, tr)
                    if rows is not None:
                        rows[ping.index] = pool_max(tr.envelope, factor)
                    if ping.has_navigation:
                        lat[ping.index], lon[ping.index] = ping.latitude_deg, ping.longitude_deg
            c_mean = float(np.mean(pings.ds["sound_speed"].values))
        except BaseException:
            segy_path.unlink(missing_ok=True)  # no half-written profile left behind
            raise
    if png is not None:
        dt = 1e-6 * axis.interval_us
        t_top = 1e-3 * axis.delay_ms - 0.5 * dt
        dist = along_track_m(lat, lon) if np.all(np.isfinite(lat)) and n > 1 else None
        plot_profile(rows, png, t_top_s=t_top, t_bottom_s=t_top + rows.shape[1] * factor * dt,
                     sound_speed_m_s=c_mean, along_track_distance_m=dist,
                     title=f"{pings_path.name}: vertical beam, envelope |S|/M")
    return ProfileResult(segy_path=segy_path, png_path=png, axis=axis, n_pings=n,
                         traces_per_ping=2 if analytic else 1, seconds=time.perf_counter() - t_start)


__all__ = ["TraceAxis", "BeamTrace", "VerticalBeam", "SegyProfileWriter", "ProfileResult", "write_profile",
           "plot_profile"]
