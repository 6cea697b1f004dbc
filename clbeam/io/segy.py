"""SEG-Y rev 1 profile files: trace-header fields and a ping-by-ping writer.

The traces are 4-byte IEEE floats (format 5), big-endian, written with
segyio (the optional ``segy`` extra).  Every ping fills one ensemble of
``k`` traces (``k = 1``: an envelope; ``k = 2``: real and imaginary part of
an analytic trace) with the ping's navigation, time and transmit pulse in
the trace headers; ``docs/profile.md`` lists every field written.
"""

from __future__ import annotations

import datetime
import logging
import textwrap
from pathlib import Path
from typing import Protocol

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.model.ping import Ping

log = logging.getLogger(__name__)

#: largest sample count of a SEG-Y rev 1 trace (2-byte unsigned field)
SEGY_MAX_SAMPLES = 65535
#: largest sample interval (microseconds) the 2-byte binary-header field holds
SEGY_MAX_INTERVAL_US = 65535
#: largest "delay recording time" (ms) of the 2-byte signed trace-header field
SEGY_MAX_DELAY_MS = 32767
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
#: columns of text on a textual-header card after its ``C nn `` prefix (80 in all)
CARD_TEXT_COLUMNS = 76
#: textual-header cards free for text (39 and 40 are rev 1's own)
TEXT_CARDS = 38


class TraceTimes(Protocol):
    """The time axis the writer needs, e.g. :class:`clbeam.imaging.vertical_beam.TraceAxis`."""

    @property
    def delay_ms(self) -> int:
        """Time of sample 0 after transmit start (ms)."""

    @property
    def interval_us(self) -> int:
        """Sample interval (microseconds)."""

    @property
    def n_samples(self) -> int:
        """Samples per trace."""

    @property
    def times_s(self) -> np.ndarray:
        """Two-way time of each sample after transmit start (s)."""


def segyio_module():
    """The segyio module, or a one-line :class:`~clbeam.errors.OptionError` saying how to install it.

    Returns
    -------
    module
        ``segyio``.
    """
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


def sweep_fields(pulse, sample_rate_hz: float = 0.0) -> dict:
    """SEG-Y sweep start/end frequency (Hz), length (ms) and type of a pulse.

    Parameters
    ----------
    pulse : Pulse or None
        Transmit pulse.
    sample_rate_hz : float
        Sample rate (Hz) of an explicit waveform, for its length.

    Returns
    -------
    dict
        Keyed by the trace-header names of :class:`segyio.TraceField`.  An
        LFM pulse gives its band and length and type 1 (linear); an explicit
        waveform gives its length only (``len / fs``, ms) and type 4 (other);
        no pulse gives zeros.
    """
    if pulse is None:
        return {"SweepFrequencyStart": 0, "SweepFrequencyEnd": 0, "SweepLength": 0, "SweepType": 0}
    if pulse.waveform is not None:
        length_ms = 1e3 * len(pulse.waveform) / sample_rate_hz if sample_rate_hz > 0 else 0.0
        return {"SweepFrequencyStart": 0, "SweepFrequencyEnd": 0, "SweepType": SWEEP_OTHER,
                "SweepLength": _fits(round(length_ms), 16, "sweep length")}
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
        rev 1 has whole seconds).

    Returns
    -------
    dict
        Trace-header names to values; empty for ``None`` or NaT.
    """
    if t is None or np.isnat(np.datetime64(t)):
        return {}
    d = np.datetime64(t, "us").astype(datetime.datetime)
    return {"YearDataRecorded": d.year, "DayOfYear": d.timetuple().tm_yday, "HourOfDay": d.hour,
            "MinuteOfHour": d.minute, "SecondOfMinute": d.second, "TimeBaseCode": TIME_BASIS_UTC}


def coordinate_fields(latitude_deg: float | None, longitude_deg: float | None) -> dict:
    """SEG-Y source, group and CDP coordinates of a ping's position.

    Parameters
    ----------
    latitude_deg, longitude_deg : float or None
        Position (degrees, WGS84).

    Returns
    -------
    dict
        Trace-header names to values.  ``X`` is longitude and ``Y`` latitude
        in arc-seconds (coordinate units 2) times 1000 with scalar -1000 (so
        1/1000 arc-second, about 3 cm; a longitude of 360 degrees is 1.3e9,
        inside the 4-byte field).  Empty without navigation: coordinates and
        units are then left 0.
    """
    if latitude_deg is None or longitude_deg is None:
        return {}
    x = int(round(longitude_deg * 3600.0 * -COORDINATE_SCALAR))
    y = int(round(latitude_deg * 3600.0 * -COORDINATE_SCALAR))
    return {"SourceGroupScalar": COORDINATE_SCALAR, "CoordinateUnits": COORDINATE_UNITS_ARCSEC,
            "SourceX": x, "SourceY": y, "GroupX": x, "GroupY": y, "CDP_X": x, "CDP_Y": y}


def card_lines(lines) -> list[str]:
    """Lines of text wrapped by words into the 76 columns a textual-header card holds after ``C nn``.

    Parameters
    ----------
    lines : iterable of str
        Lines of any length (non-ASCII characters become ``?``).

    Returns
    -------
    list of str
        The card texts: each line broken at spaces into pieces of at most
        :data:`CARD_TEXT_COLUMNS` characters, its continuations indented by
        two spaces; a word is cut only when it is longer than a card.
    """
    out = []
    for line in lines:
        text = line.encode("ascii", "replace").decode("ascii").rstrip()
        out += textwrap.wrap(text, width=CARD_TEXT_COLUMNS, subsequent_indent="  ", break_on_hyphens=False) or [""]
    return out


def text_header(lines: list[str]) -> bytes:
    """A 40-card SEG-Y rev 1 textual header of 80-column cards ``C 1 ...`` to ``C40 ...``.

    Parameters
    ----------
    lines : list of str
        Lines of text, wrapped by words onto cards 1-38 (:func:`card_lines`);
        cards past the 38th are dropped with a warning.  Cards 39 and 40 are
        rev 1's ``SEG Y REV1`` and ``END TEXTUAL HEADER``.

    Returns
    -------
    bytes
        3200 ASCII bytes.
    """
    segyio = segyio_module()
    cards = card_lines(lines)
    if len(cards) > TEXT_CARDS:
        log.warning("the SEG-Y textual header holds %d cards of text; %d dropped", TEXT_CARDS, len(cards) - TEXT_CARDS)
    rows = {i + 1: card for i, card in enumerate(cards[:TEXT_CARDS])}
    rows[39], rows[40] = "SEG Y REV1", "END TEXTUAL HEADER"
    return segyio.tools.create_text_header(rows).encode("ascii")


class SegyProfileWriter:
    """Writes profile traces to a SEG-Y rev 1 file, ping by ping.

    Parameters
    ----------
    path : str or path-like
        SEG-Y file to create (overwritten).
    axis : TraceTimes
        Trace time axis (delay, interval, samples), e.g.
        :class:`clbeam.imaging.vertical_beam.TraceAxis`.
    n_pings : int
        Pings in the profile; ping ``i`` (0-based) fills traces
        ``i * k .. i * k + k - 1``.
    analytic : bool
        ``k = 2`` traces per ping, real then imaginary part of the analytic
        trace; otherwise ``k = 1``: its envelope.
    text_lines : list of str
        Lines of the textual header.
    pulse : Pulse or None
        Transmit pulse, for the sweep fields.
    sample_rate_hz : float
        Sample rate of the ping file (Hz), for the original sample interval.
    n_record_samples : int
        Samples per channel in the ping file.
    """

    def __init__(self, path, axis: TraceTimes, n_pings: int, *, analytic: bool = False, text_lines=(),
                 pulse=None, sample_rate_hz: float = 0.0, n_record_samples: int = 0):
        segyio = segyio_module()
        self.path = Path(path)
        self.axis = axis
        self.k = 2 if analytic else 1
        self.n_pings = n_pings
        self._sweep = sweep_fields(pulse, sample_rate_hz)
        spec = segyio.spec()
        spec.format = SEGY_FORMAT_IEEE_FLOAT
        spec.samples = axis.times_s * 1e3
        spec.tracecount = n_pings * self.k
        spec.endian = "big"
        try:
            self._f = segyio.create(str(self.path), spec)
        except (OSError, RuntimeError) as exc:
            raise OptionError(f"cannot write SEG-Y file {self.path}: {exc}") from None
        self._f.bin.update(self._binary_header(segyio.BinField, sample_rate_hz, n_record_samples))
        self._f.text[0] = text_header(list(text_lines))

    def _binary_header(self, B, sample_rate_hz: float, n_record_samples: int) -> dict:
        """The binary file header (``B``: :class:`segyio.BinField`)."""
        axis, sweep = self.axis, self._sweep
        interval_orig = int(round(1e6 / sample_rate_hz)) if sample_rate_hz > 0 else axis.interval_us
        return {
            B.JobID: 1, B.LineNumber: 1, B.ReelNumber: 1, B.Traces: self.k, B.AuxTraces: 0,
            B.Interval: axis.interval_us, B.IntervalOriginal: min(interval_orig, SEGY_MAX_INTERVAL_US),
            B.Samples: axis.n_samples, B.SamplesOriginal: min(int(n_record_samples), SEGY_MAX_SAMPLES),
            B.Format: SEGY_FORMAT_IEEE_FLOAT, B.EnsembleFold: 1, B.SortingCode: 1,
            B.SweepFrequencyStart: sweep["SweepFrequencyStart"], B.SweepFrequencyEnd: sweep["SweepFrequencyEnd"],
            B.SweepLength: sweep["SweepLength"], B.Sweep: sweep["SweepType"],
            B.CorrelatedTraces: 2, B.MeasurementSystem: 1,
            B.SEGYRevision: 1, B.SEGYRevisionMinor: 0, B.TraceFlag: 1, B.ExtendedHeaders: 0,
        }

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
        return {getattr(segyio_module().TraceField, k): int(v) for k, v in h.items()}

    def write(self, ping: Ping, analytic: np.ndarray, n_channels_used: int) -> None:
        """Write the trace(s) of one ping (float32).

        Parameters
        ----------
        ping : Ping
            The ping (its index, navigation and time go in the headers).
        analytic : numpy.ndarray
            complex ``(n_samples,)`` analytic trace (the ping file's sample
            units); its envelope ``|analytic|`` is written when ``k = 1``.
        n_channels_used : int
            Channels that took part in the ping (``NStackedTraces``).
        """
        require(0 <= ping.index < self.n_pings, OptionError,
                f"ping {ping.index} is outside the profile's 0..{self.n_pings - 1}")
        data = [np.abs(analytic)] if self.k == 1 else [analytic.real, analytic.imag]
        for comp, values in enumerate(data, start=1):
            j = ping.index * self.k + comp - 1
            self._f.header[j] = self.header(ping, comp, n_channels_used)
            self._f.trace[j] = np.ascontiguousarray(values, dtype=np.float32)


__all__ = ["CARD_TEXT_COLUMNS", "SegyProfileWriter", "TEXT_CARDS", "TraceTimes", "card_lines", "coordinate_fields",
           "segyio_module", "sweep_fields", "text_header", "time_fields"]
