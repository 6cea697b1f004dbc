"""A ping file (docs/ping-format.md) to multichannel SEG-Y: one trace per element, one ensemble per ping.

:func:`export_segy` is the inverse of :func:`clbeam.io.segy_import.import_segy`
with the same :class:`~clbeam.io.segy_mapping.SegyMapping`: every ping
becomes an ensemble (the mapping's ``ensemble`` field numbered by the ping
file's ``ping`` coordinate) of one 4-byte IEEE float trace per channel (its
``channel`` field numbered from 1), the mapped variables in their fields,
scaled by the finest SEG-Y scalar (-10000 ... 10000) that lets every value of
the trace fit; the pulse and the source position, which no trace-header
field holds, go in the textual header as ``name=value`` lines (and the pulse
also in the sweep fields, whole Hz and ms).  A value the mapping's field
cannot hold exactly (a sound speed of 1522.4 m/s in whole m/s, a time to the
second) is rounded and logged once per variable with its largest error;
one that does not fit at all, a sample interval that is not a whole number
of the field's units, or an analytic ping file is a one-line error.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from clbeam import __version__
from clbeam.errors import OptionError, require
from clbeam.io.pingfile import PingDataset, PingFile
from clbeam.io.segy import SEGY_FORMAT_IEEE_FLOAT, SEGY_MAX_SAMPLES, segyio_module, sweep_fields, text_header
from clbeam.io.segy_mapping import (
    COORDINATE_UNITS_ARCSEC,
    SCALAR_CHOICES,
    TIME_BASE_UTC,
    TIME_FIELDS,
    TRACE_ID_DEAD,
    TRACE_ID_LIVE,
    HeaderEntry,
    SegyMapping,
    field_limits,
)

log = logging.getLogger(__name__)

#: ping attribute of each per-ping mapping entry
_PING_ATTRS = {"t0": "t0_s", "sound_speed": "sound_speed_m_s", "roll": "roll_deg", "pitch": "pitch_deg",
               "heave": "heave_m", "heading": "heading_deg", "draft": "draft_m", "latitude": "latitude_deg",
               "longitude": "longitude_deg"}
_ELEMENT_COLUMNS = {"element_x": 0, "element_y": 1, "element_z": 2}


def _units(entry: HeaderEntry) -> float:
    """Ping-file units per header unit before the scalar (latitude and longitude: arc-seconds, in degrees)."""
    return 1.0 / 3600.0 if entry.scale is None else entry.scale


class _Rounding:
    """The largest rounding error of each variable, logged once at the end."""

    def __init__(self):
        self.worst: dict[str, tuple[float, float]] = {}

    def add(self, name: str, error: np.ndarray, resolution: float) -> None:
        """Record the errors ``|value - stored|`` of ``name`` stored at ``resolution``."""
        error = np.abs(error)
        rounded = error > 1e-6 * abs(resolution)
        if rounded.any():
            worst = float(error[rounded].max())
            if worst > self.worst.get(name, (0.0, 0.0))[0]:
                self.worst[name] = (worst, abs(resolution))

    def report(self, mapping: SegyMapping, path: Path) -> None:
        """Log one warning per rounded variable."""
        for name, (err, res) in self.worst.items():
            entry = mapping.get(name)
            where = entry.describe() if entry else "the time fields (bytes 157-166)"
            log.warning("%s: %s rounded to the %g resolution of %s (largest error %g); map it to a finer field "
                        "(--mapping) for an exact copy", path.name, name, res, where, err)


def _fit(values: np.ndarray, entry: HeaderEntry, scalar: int | None) -> tuple[np.ndarray, np.ndarray] | None:
    """``(header integers, stored values)`` of ``values`` at ``scalar``, ``None`` where they do not fit the field."""
    unit = _units(entry)
    if scalar is None or scalar > 0:
        step = unit * (1 if scalar is None else scalar)
        raw = np.rint(values / step)
        stored = raw * step
    else:
        raw = np.rint(values * -scalar / unit)
        stored = raw / -scalar * unit
    lo, hi = field_limits(entry.field)
    if raw.min(initial=0) < lo or raw.max(initial=0) > hi:
        return None
    return raw.astype(np.int64), stored


def encode_group(items: list, rounding: _Rounding, what: str) -> dict:
    """Header integers of variables that share one scalar field (or none), at the finest scalar they all fit.

    Parameters
    ----------
    items : list of (str, numpy.ndarray, HeaderEntry)
        Entry name, values (ping-file units, one per trace) and entry; all
        entries name the same ``scalar`` (or none).
    rounding : _Rounding
        Collects the rounding errors.
    what : str
        Where the values are (``"ping 3"``), for messages.

    Returns
    -------
    dict
        ``{field: int64 array}``, and ``{scalar field: int}`` (the first of
        :data:`~clbeam.io.segy_mapping.SCALAR_CHOICES` that fits every value).

    Raises
    ------
    OptionError
        When no scalar lets the values fit their fields.
    """
    scalar_field = items[0][2].scalar
    for scalar in (SCALAR_CHOICES if scalar_field else (None,)):
        fits = [_fit(np.asarray(v, dtype=np.float64), e, scalar) for _, v, e in items]
        if all(f is not None for f in fits):
            out = {}
            for (name, values, entry), (raw, stored) in zip(items, fits):
                res = _units(entry) * (1 if scalar is None else (scalar if scalar > 0 else 1 / -scalar))
                rounding.add(name, np.asarray(values, dtype=np.float64) - stored, res)
                out[entry.field] = raw
            if scalar_field:
                out[scalar_field] = scalar
            return out
    name, values, entry = max(items, key=lambda it: float(np.max(np.abs(it[1]))))
    raise OptionError(f"{what}: {name} {float(values[np.argmax(np.abs(values))]):g} does not fit "
                      f"{entry.describe()} ({entry.n_bytes}-byte field) at any scalar; choose another field or "
                      "scale (--mapping)")


def encode(items: list, rounding: _Rounding, what: str) -> dict:
    """Header integers of mapped variables, each group sharing a scalar field encoded together (:func:`encode_group`)."""
    groups: dict = {}
    for item in items:
        key = item[2].scalar or f"-{item[0]}"  # entries without a scalar are encoded alone
        groups.setdefault(key, []).append(item)
    out: dict = {}
    for group in groups.values():
        out.update(encode_group(group, rounding, what))
    return out


def _time_fields(t) -> dict:
    """The rev 1 time fields of a datetime64: year, day of year (1 = 1 January), hour, minute, whole second, UTC."""
    t = np.datetime64(t, "ns")
    seconds = t.astype("datetime64[s]")
    day = seconds.astype("datetime64[D]")
    year = day.astype("datetime64[Y]")
    of_day = int((seconds - day) / np.timedelta64(1, "s"))
    values = (int(year.astype(int)) + 1970, int((day - year.astype("datetime64[D]")) / np.timedelta64(1, "D")) + 1,
              of_day // 3600, of_day % 3600 // 60, of_day % 60)
    return {**dict(zip(TIME_FIELDS, values)), "TimeBaseCode": TIME_BASE_UTC}


class _Exporter:
    """Writes the pings of one ping file as the ensembles of one SEG-Y file."""

    def __init__(self, pings: PingDataset, path: Path, mapping: SegyMapping, ping_numbers: np.ndarray):
        self.pings, self.path, self.mapping = pings, path, mapping
        self.ping_numbers = ping_numbers
        self.rounding = _Rounding()
        self.n_ch, self.n_s = pings.n_channels, pings.n_samples
        self.segyio = segyio_module()
        self._check(pings)
        self.interval = self._sample_interval(pings.sample_rate_hz)
        self.elements = [(name, pings.element_pos_m[:, col], mapping.get(name))
                         for name, col in _ELEMENT_COLUMNS.items() if mapping.get(name) is not None]
        self.sweep = sweep_fields(pings.pulse, pings.sample_rate_hz)

    def _check(self, pings: PingDataset) -> None:
        require(pings.kind == "raw", OptionError,
                f"{pings.name}: samples are kind='{pings.kind}'; multichannel SEG-Y holds real element pressure "
                "(kind='raw') only")
        require(self.n_s <= SEGY_MAX_SAMPLES, OptionError,
                f"{pings.name}: {self.n_s} samples per channel exceed SEG-Y rev 1's {SEGY_MAX_SAMPLES}")
        m, present = self.mapping, set(pings.ds.variables)
        dropped = [name for name, col in _ELEMENT_COLUMNS.items()
                   if m.get(name) is None and np.any(pings.element_pos_m[:, col] != 0)]
        dropped += [name for name in _PING_ATTRS if m.get(name) is None and name in present]
        dropped += [name for name, on in (("ping_time", m.ping_time), ("channel_valid", m.channel_valid))
                    if not on and name in present]
        dropped += [n for n in ("element_gain_db", "element_phase_deg", "svp_depth") if n in present]
        if pings.pulse is not None and pings.pulse.waveform is not None:
            dropped.append("tx_waveform (give --pulse on import)")
        if dropped:
            log.warning("%s: not written to SEG-Y (the mapping gives them no field): %s", self.path.name,
                        ", ".join(dropped))

    def _sample_interval(self, fs: float) -> dict:
        entry = self.mapping.get("sample_interval")
        raw = 1.0 / (fs * entry.scale)
        lo, hi = field_limits(entry.field)
        require(abs(raw - round(raw)) <= 1e-6 * raw and lo < round(raw) <= hi, OptionError,
                f"{self.pings.name}: sample interval {1 / fs:g} s is not a whole number of the "
                f"{entry.scale:g} s units of {entry.describe()} (at most {hi}); map sample_interval with a finer "
                "scale (--mapping)")
        return {entry.field: int(round(raw))}

    def _ping_items(self, ping) -> list:
        """``(name, per-trace values, entry)`` of the mapped per-ping variables this ping has."""
        items = []
        for name, attr in _PING_ATTRS.items():
            entry, value = self.mapping.get(name), getattr(ping, attr)
            if entry is not None and value is not None and np.isfinite(value):
                items.append((name, np.full(self.n_ch, float(value)), entry))
        return items

    def _bookkeeping(self, ping, number: int) -> dict:
        """Ensemble and channel numbers, sequence numbers, sample count, trace codes, sweep and time."""
        channels = np.arange(1, self.n_ch + 1)
        fields = {self.mapping.get("ensemble").field: number, self.mapping.get("channel").field: channels,
                  "TRACE_SAMPLE_COUNT": self.n_s, **self.interval}
        if self.mapping.channel_valid:
            fields["TraceIdentificationCode"] = np.where(np.asarray(ping.channel_valid, dtype=bool), TRACE_ID_LIVE,
                                                         TRACE_ID_DEAD)
        if self.mapping.ping_time and ping.time is not None and not np.isnat(np.datetime64(ping.time)):
            t = np.datetime64(ping.time, "ns")
            fields.update(_time_fields(t))
            self.rounding.add("ping_time", np.array([(t - t.astype("datetime64[s]")) / np.timedelta64(1, "s")]), 1.0)
        sequence = ping.index * self.n_ch + channels
        extra = {"TRACE_SEQUENCE_LINE": sequence, "TRACE_SEQUENCE_FILE": sequence, "EnergySourcePoint": number,
                 "CDP": number, "CDP_TRACE": channels, "DataUse": 1, "Correlated": 1, **self.sweep}
        used = set(fields) | {f for e in self.mapping.mapped().values() for f in (e.field, e.scalar) if f}
        fields.update({k: v for k, v in extra.items() if k not in used})
        return fields

    def headers(self, ping, number: int) -> list[dict]:
        """The trace headers of one ping (ensemble ``number``), ``{segyio.TraceField: int}`` per channel."""
        items = self._ping_items(ping)
        fields = encode(items + self.elements, self.rounding, f"ping {number}")
        if any(e.scale is None for _, _, e in items):
            fields["CoordinateUnits"] = COORDINATE_UNITS_ARCSEC
        fields.update(self._bookkeeping(ping, number))
        T = self.segyio.TraceField
        keys = [(getattr(T, k), np.broadcast_to(np.asarray(v, dtype=np.int64), (self.n_ch,))) for k, v in fields.items()]
        return [{key: int(v[j]) for key, v in keys} for j in range(self.n_ch)]

    def text_lines(self) -> list[str]:
        """The textual header: what the file is, the values no trace field holds, the mapping."""
        p = self.pings
        lines = [f"CLBEAM {__version__} MULTICHANNEL SONAR ELEMENT DATA FROM {Path(p.name).name}",
                 "ONE TRACE PER RECEIVE ELEMENT, ONE ENSEMBLE PER PING, IEEE FLOAT SAMPLES",
                 f"{p.n_pings} PINGS x {self.n_ch} ELEMENTS x {self.n_s} SAMPLES AT {p.sample_rate_hz:g} HZ",
                 "VESSEL FRAME: X FORWARD, Y STARBOARD, Z DOWN (M); ROLL STARBOARD DOWN (DEG)"]
        pulse = p.pulse
        if pulse is not None and pulse.waveform is None:
            lines += [f"pulse_f0={pulse.f0_hz!r}", f"pulse_f1={pulse.f1_hz!r}", f"pulse_duration={pulse.duration_s!r}"]
        if pulse is not None and pulse.delay_s:
            lines.append(f"tx_delay={float(pulse.delay_s)!r}")
        lines += [f"{k}={float(v)!r}" for k, v in zip(("source_x", "source_y", "source_z"), p.source_pos_m)]
        return lines + self.mapping.text_lines()

    def binary_header(self) -> dict:
        """The binary file header, ``{segyio.BinField: int}``."""
        B, sweep = self.segyio.BinField, self.sweep
        us = 1e6 / self.pings.sample_rate_hz
        interval = int(round(us)) if abs(us - round(us)) < 1e-6 and round(us) <= 65535 else 0
        return {B.JobID: 1, B.LineNumber: 1, B.ReelNumber: 1, B.Traces: self.n_ch, B.AuxTraces: 0,
                B.Interval: interval, B.IntervalOriginal: interval, B.Samples: self.n_s, B.SamplesOriginal: self.n_s,
                B.Format: SEGY_FORMAT_IEEE_FLOAT, B.EnsembleFold: self.n_ch, B.SortingCode: 1,
                B.SweepFrequencyStart: sweep["SweepFrequencyStart"], B.SweepFrequencyEnd: sweep["SweepFrequencyEnd"],
                B.SweepLength: sweep["SweepLength"], B.Sweep: sweep["SweepType"], B.CorrelatedTraces: 1,
                B.MeasurementSystem: 1, B.SEGYRevision: 1, B.SEGYRevisionMinor: 0, B.TraceFlag: 1,
                B.ExtendedHeaders: 0}

    def write(self, progress=None) -> None:
        """Create the file and write every ping."""
        spec = self.segyio.spec()
        spec.format = SEGY_FORMAT_IEEE_FLOAT
        spec.samples = np.arange(self.n_s) * 1e3 / self.pings.sample_rate_hz
        spec.tracecount = self.pings.n_pings * self.n_ch
        spec.endian = "big"
        try:
            f = self.segyio.create(str(self.path), spec)
        except (OSError, RuntimeError) as exc:
            raise OptionError(f"cannot write SEG-Y file {self.path}: {exc}") from None
        with f:
            f.bin.update(self.binary_header())
            f.text[0] = text_header(self.text_lines())
            pings = iter(self.pings) if progress is None else progress(iter(self.pings), self.pings.n_pings)
            for ping in pings:
                first = ping.index * self.n_ch
                for j, h in enumerate(self.headers(ping, int(self.ping_numbers[ping.index]))):
                    f.header[first + j] = h
                samples = np.ascontiguousarray(ping.samples, dtype=np.float32)
                for j in range(self.n_ch):
                    f.trace[first + j] = samples[j]
        self.rounding.report(self.mapping, self.path)


def _ping_numbers(ds, n_pings: int) -> np.ndarray:
    """The ensemble number of each ping: the ``ping`` coordinate where it is whole numbers, else 0, 1, ..."""
    if "ping" in ds.variables:
        v = np.asarray(ds["ping"].values)
        if np.issubdtype(v.dtype, np.integer) or (np.issubdtype(v.dtype, np.floating) and np.all(v == np.round(v))):
            lo, hi = -(2 ** 31), 2 ** 31 - 1
            if v.size == n_pings and v.min() >= lo and v.max() <= hi:
                return v.astype(np.int64)
    return np.arange(n_pings)


def export_segy(pings: str | os.PathLike | PingDataset, segy_path: str | os.PathLike, *,
                mapping: SegyMapping | None = None, progress=None) -> Path:
    """Write a ping file as multichannel SEG-Y rev 1 (one trace per element, one ensemble per ping).

    Parameters
    ----------
    pings : str, path-like or PingDataset
        Ping file (NetCDF4 or Zarr) or a validated dataset
        (:func:`clbeam.io.pingfile.pings_from_dataset`); raw samples only.
    segy_path : str or path-like
        SEG-Y file to create (overwritten): big-endian, 4-byte IEEE floats.
    mapping : SegyMapping, optional
        Where each variable goes (default: ``docs/import.md``).
    progress : callable, optional
        ``progress(iterable, total)`` wraps the loop over pings.

    Returns
    -------
    pathlib.Path
        The SEG-Y file.

    Raises
    ------
    OptionError
        Analytic samples, more than 65535 samples, a sample interval or a
        value the mapping's fields cannot hold.
    """
    mapping = mapping or SegyMapping()
    out = Path(segy_path)
    own = not isinstance(pings, PingDataset)
    ds = PingFile(pings) if own else pings
    try:
        _Exporter(ds, out, mapping, _ping_numbers(ds.ds, ds.n_pings)).write(progress)
    finally:
        if own:
            ds.close()
    return out


__all__ = ["encode", "export_segy"]
