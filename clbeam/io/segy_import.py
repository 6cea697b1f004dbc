"""Multichannel SEG-Y to a ping file (docs/ping-format.md): what a sonar exports, made imageable.

A sonar's element-level SEG-Y export holds one trace per receive element and
one ensemble of traces per ping.  :func:`read_segy_pings` reads such a file
into a ping dataset (docs/ping-format.md): the trace headers give each ping's time axis,
motion, navigation and sound speed and each element's position, as the
:class:`~clbeam.io.segy_mapping.SegyMapping` says; what the headers cannot
carry (the pulse, the source position, the replica's delay) comes from
:class:`SegyImportOptions`, from ``name=value`` lines of the textual header
(as :mod:`clbeam.io.segy_export` writes them) or, for the pulse, from the
binary header's sweep fields.  :func:`import_segy` writes the dataset with
:func:`clbeam.io.pingwrite.write_ping_file` after the ping-file reader's own
checks.  Every problem of the file is a one-line
:class:`~clbeam.errors.PingFileError` naming the file; ``docs/import.md``
has the mapping table.
"""

from __future__ import annotations

import logging
import math
import os
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from clbeam.errors import OptionError, PingFileError, require
from clbeam.io.pingfile import pings_from_dataset
from clbeam.io.pingwrite import write_ping_file
from clbeam.io.schema import FORMAT_ATTRIBUTE, PING_FORMAT, ping_variable
from clbeam.io.segy import segyio_module
from clbeam.io.segy_mapping import (
    COORDINATE_UNITS_ARCSEC,
    COORDINATE_UNITS_DEGREES,
    COORDINATE_UNITS_DMS,
    TIME_BASE_GMT,
    TIME_BASE_UTC,
    TIME_FIELDS,
    TRACE_FIELDS,
    TRACE_ID_DEAD,
    HeaderEntry,
    SegyMapping,
    apply_scale,
    as_unsigned,
)

log = logging.getLogger(__name__)

#: ping-file scalars the textual header may give as ``name=value`` (clbeam's exporter writes them)
TEXT_VARIABLES = ("pulse_f0", "pulse_f1", "pulse_duration", "tx_delay", "source_x", "source_y", "source_z")
_TEXT_VALUE = re.compile(r"\b(" + "|".join(TEXT_VARIABLES) + r")\s*=\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)",
                         re.IGNORECASE)
#: per-ping variables of the mapping (one value per ensemble) and per-element ones (one value per channel)
PER_PING = ("t0", "sample_interval", "sound_speed", "roll", "pitch", "heave", "heading", "draft", "latitude",
            "longitude")
PER_CHANNEL = ("element_x", "element_y", "element_z")


@dataclass(frozen=True)
class SegyImportOptions:
    """What the trace headers cannot carry, or values that replace theirs.

    Attributes
    ----------
    pulse : (float, float, float) or None
        LFM start and end frequency (Hz) and length (s); default: the
        textual header's ``pulse_f0``/``pulse_f1``/``pulse_duration``, else
        the binary header's sweep fields (whole Hz and ms).
    tx_delay_s : float or None
        Time of the replica's first sample after transmit start (s); default
        the textual header's ``tx_delay``, else 0.
    source_m : (float, float, float) or None
        Transmit acoustic centre ``x, y, z`` in the vessel frame (m); default
        the textual header's ``source_x/y/z``, else the array reference point.
    sound_speed_m_s : float or None
        Sound speed of every ping (m/s), replacing the headers'.
    element_pitch_m : float or None
        Elements evenly spaced across-track by this pitch (m), centred on the
        reference point, in channel order; replaces the headers' positions.
    """

    pulse: tuple | None = None
    tx_delay_s: float | None = None
    source_m: tuple | None = None
    sound_speed_m_s: float | None = None
    element_pitch_m: float | None = None

    def __post_init__(self):
        for name in ("tx_delay_s", "sound_speed_m_s", "element_pitch_m"):
            v = getattr(self, name)
            require(v is None or math.isfinite(v), OptionError, f"{name} must be finite, got {v!r}")
        require(self.element_pitch_m is None or self.element_pitch_m > 0, OptionError,
                f"element pitch must be > 0 m, got {self.element_pitch_m!r}")
        require(self.pulse is None or (len(self.pulse) == 3 and all(math.isfinite(v) for v in self.pulse)),
                OptionError, f"pulse must be three finite numbers F0 F1 DURATION, got {self.pulse!r}")
        require(self.source_m is None or (len(self.source_m) == 3 and all(math.isfinite(v) for v in self.source_m)),
                OptionError, f"source position must be three finite numbers X Y Z (m), got {self.source_m!r}")


@dataclass(frozen=True)
class SegyImportResult:
    """What :func:`import_segy` wrote.

    Attributes
    ----------
    path : pathlib.Path
        The ping file.
    n_pings, n_channels, n_samples : int
        Its sizes.
    sample_rate_hz : float
        Its sample rate (Hz).
    origins : dict
        Where each value not read from the trace headers came from
        (``{"pulse": "textual header", "source": "option", ...}``).
    seconds : float
        Wall-clock time of the import (s).
    """

    path: Path
    n_pings: int
    n_channels: int
    n_samples: int
    sample_rate_hz: float
    origins: dict = field(default_factory=dict)
    seconds: float = 0.0


# -- opening and the layout ------------------------------------------------------------
def open_segy(path: str | os.PathLike):
    """Open a SEG-Y file for reading (segyio, geometry ignored), or raise a one-line error.

    Parameters
    ----------
    path : str or path-like
        SEG-Y file.

    Returns
    -------
    segyio.SegyFile
        The open file (a context manager).

    Raises
    ------
    PingFileError
        Missing, empty, not SEG-Y, or without traces.
    """
    segyio = segyio_module()
    p = Path(path)
    require(p.is_file(), PingFileError, f"{p}: no such file")
    require(p.stat().st_size > 0, PingFileError, f"{p}: file is empty")
    try:
        f = segyio.open(str(p), "r", ignore_geometry=True)
    except (RuntimeError, ValueError, OSError, IndexError) as exc:
        raise PingFileError(f"{p}: not a SEG-Y file segyio can read ({exc})") from None
    if f.tracecount == 0 or len(f.samples) == 0:
        f.close()
        raise PingFileError(f"{p}: SEG-Y file holds no trace samples")
    return f


def _header(f, name: str) -> np.ndarray:
    """One trace-header field of every trace, int64 (unsigned where SEG-Y rev 2 says so)."""
    return as_unsigned(name, f.attributes(TRACE_FIELDS[name])[:])


def ensemble_layout(f, mapping: SegyMapping, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The traces of each ping, in channel order.

    Parameters
    ----------
    f : segyio.SegyFile
        The open file.
    mapping : SegyMapping
        Its ``ensemble`` and ``channel`` entries.
    name : str
        File name for messages.

    Returns
    -------
    traces : numpy.ndarray
        ``(n_pings, n_channels)`` trace indices (0-based): ping ``i`` in order
        of its first trace, channels sorted by channel number.
    ensembles : numpy.ndarray
        ``(n_pings,)`` ensemble numbers.
    channels : numpy.ndarray
        ``(n_channels,)`` channel numbers.

    Raises
    ------
    PingFileError
        Ensembles of unequal trace counts, repeated or differing channel numbers.
    """
    ens_field, ch_field = mapping.get("ensemble").field, mapping.get("channel").field
    ens, ch = _header(f, ens_field), _header(f, ch_field)
    sorted_keys, first, inverse, counts = np.unique(ens, return_index=True, return_inverse=True, return_counts=True)
    appearance = np.argsort(first)  # the ensembles in the order of their first trace
    rank = np.empty_like(appearance)
    rank[appearance] = np.arange(appearance.size)
    keys, counts = sorted_keys[appearance], counts[appearance]
    n_ch = int(counts[0])
    odd = np.flatnonzero(counts != n_ch)
    require(odd.size == 0, PingFileError,
            f"{name}: ensemble {keys[odd[0]] if odd.size else 0} ({ens_field}) has {counts[odd[0]] if odd.size else 0} "
            f"traces, ensemble {keys[0]} has {n_ch}; every ping needs one trace per receive element "
            "(another ensemble field: --mapping)")
    traces = np.lexsort((ch, rank[inverse.reshape(-1)])).reshape(keys.size, n_ch)
    channels = ch[traces[0]]
    repeated = np.flatnonzero(np.diff(channels) == 0)
    require(repeated.size == 0, PingFileError,
            f"{name}: ensemble {keys[0]} ({ens_field}) has channel {channels[repeated[0]] if repeated.size else 0} "
            f"({ch_field}) twice; each trace of a ping must be one element")
    differ = np.flatnonzero((ch[traces] != channels).any(axis=1))
    require(differ.size == 0, PingFileError,
            f"{name}: ensemble {keys[differ[0]] if differ.size else 0} ({ens_field}) has other channel numbers "
            f"({ch_field}) than ensemble {keys[0]}; every ping needs the same elements")
    return traces, keys, channels


# -- header values ------------------------------------------------------------------
def _coordinate_degrees(f, entry: HeaderEntry, traces: np.ndarray, name: str, what: str) -> np.ndarray | None:
    """Latitude or longitude (degrees) per trace from a coordinate field whose units ``CoordinateUnits`` says;
    ``None`` where the file holds lengths (no geographic position)."""
    raw = _header(f, entry.field)[traces]
    if not raw.any():
        return np.zeros(traces.shape)
    scalar = _header(f, entry.scalar)[traces] if entry.scalar else None
    value = apply_scale(raw, scalar, 1.0)
    units = np.unique(_header(f, "CoordinateUnits")[traces])
    require(units.size == 1, PingFileError, f"{name}: CoordinateUnits differ between traces ({units.tolist()})")
    code = int(units[0])
    if code in (0, COORDINATE_UNITS_ARCSEC):
        if code == 0:
            log.warning("%s: CoordinateUnits is 0 (unspecified); %s taken as arc-seconds", name, what)
        return value / 3600.0
    if code == COORDINATE_UNITS_DEGREES:
        return value
    if code == COORDINATE_UNITS_DMS:  # +-DDDMMSS.ss
        sign, v = np.sign(value), np.abs(value)
        deg, rest = np.floor(v / 10000.0), v % 10000.0
        return sign * (deg + np.floor(rest / 100.0) / 60.0 + (rest % 100.0) / 3600.0)
    log.warning("%s: CoordinateUnits %d (lengths) give no latitude or longitude; navigation left out", name, code)
    return None


def _entry_values(f, entry: HeaderEntry, traces: np.ndarray) -> np.ndarray:
    """An entry's values (ping-file units), ``traces``-shaped."""
    raw = _header(f, entry.field)[traces]
    scalar = _header(f, entry.scalar)[traces] if entry.scalar else None
    return apply_scale(raw, scalar, entry.scale)


def _one_per(values: np.ndarray, axis: int, label: str, entry: HeaderEntry, keys: np.ndarray, name: str) -> np.ndarray:
    """The values constant along ``axis`` of ``(n_pings, n_channels)``, or a one-line error naming where not."""
    first = np.take(values, [0], axis=axis)
    bad = np.flatnonzero(~(values == first).all(axis=axis))
    if bad.size:
        where = f"ensemble {keys[bad[0]]}" if axis == 1 else f"channel {bad[0] + 1}"
        other = "its traces" if axis == 1 else "pings"
        raise PingFileError(f"{name}: {label} ({entry.describe()}) differs between {other} of {where}; "
                            f"a ping file holds one {label} per {'ping' if axis == 1 else 'element'}")
    return np.take(first, 0, axis=axis)


def header_variables(f, mapping: SegyMapping, traces: np.ndarray, keys: np.ndarray, name: str) -> dict:
    """The mapped variables of every ping and channel.

    Parameters
    ----------
    f : segyio.SegyFile
        The open file.
    mapping : SegyMapping
        Where each variable sits.
    traces, keys : numpy.ndarray
        From :func:`ensemble_layout`.
    name : str
        File name for messages.

    Returns
    -------
    dict
        Entry name -> ``(n_pings,)`` (per ping) or ``(n_channels,)`` (per
        element) float64 values, in the ping file's units; entries whose
        field is 0 in every trace (an optional variable the file does not
        give) and unmapped ones are absent.
    """
    out = {}
    for label, entry in mapping.mapped().items():
        if label in ("ensemble", "channel"):
            continue
        if label in ("latitude", "longitude") and entry.scale is None:
            values = _coordinate_degrees(f, entry, traces, name, label)
            if values is None:
                continue
        else:
            values = _entry_values(f, entry, traces)
        if label not in ("t0", "sample_interval") and not values.any():
            continue
        out[label] = _one_per(values, 1 if label in PER_PING else 0, label, entry, keys, name)
    if "latitude" in out and "longitude" not in out:  # a ping at longitude 0 exactly on every trace
        out["longitude"] = np.zeros_like(out["latitude"])
    if "longitude" in out and "latitude" not in out:
        out["latitude"] = np.zeros_like(out["longitude"])
    return out


def sample_interval_s(f, values: dict, name: str) -> float:
    """The sample interval (s): the trace headers', else the binary header's (microseconds).

    Raises
    ------
    PingFileError
        Zero in both, or differing between pings.
    """
    dt = values["sample_interval"]
    if not dt.any():
        binary = int(f.bin[segyio_module().BinField.Interval]) % 65536
        require(binary > 0, PingFileError, f"{name}: sample interval is 0 in the trace headers and the binary "
                "header; a SEG-Y file needs its sample interval (a mapping with another field: --mapping)")
        log.info("%s: trace headers give no sample interval; the binary header's %d us is used", name, binary)
        dt = np.full_like(dt, binary * 1e-6)
    require(bool((dt > 0).all()), PingFileError, f"{name}: sample interval is 0 or negative in some traces")
    require(bool(np.all(dt == dt[0])), PingFileError,
            f"{name}: sample interval differs between pings ({dt.min():g} to {dt.max():g} s); a ping file has one")
    return float(dt[0])


def ping_times(f, traces: np.ndarray, keys: np.ndarray, name: str) -> np.ndarray | None:
    """``(n_pings,)`` datetime64[ns] ping times from the rev 1 time fields (whole seconds), ``None`` without."""
    year, day, hour, minute, second = (_header(f, fname)[traces] for fname in TIME_FIELDS)
    if not year.any():
        return None
    for label, v in zip(TIME_FIELDS, (year, day, hour, minute, second)):
        _one_per(v.astype(np.float64), 1, label, HeaderEntry(label), keys, name)
    year, day, hour, minute, second = (v[:, 0] for v in (year, day, hour, minute, second))
    require(bool(np.all((day >= 1) & (day <= 366) & (hour < 24) & (minute < 60) & (second < 61))), PingFileError,
            f"{name}: time fields (bytes 157-166) out of range (day 1-366, hour 0-23, minute 0-59, second 0-60)")
    base = (year - 1970).astype("datetime64[Y]").astype("datetime64[D]")
    times = (base + (day - 1).astype("timedelta64[D]")).astype("datetime64[ns]")
    times += (hour * 3600 + minute * 60 + second).astype("timedelta64[s]")
    codes = set(np.unique(_header(f, "TimeBaseCode")[traces[:, 0]]).tolist()) - {0, TIME_BASE_UTC, TIME_BASE_GMT}
    if codes:
        log.warning("%s: TimeBaseCode %s is not UTC; the ping times are taken as UTC", name, sorted(codes))
    return times


def text_values(f) -> dict:
    """``name=value`` numbers of :data:`TEXT_VARIABLES` in the textual header(s), the first of each."""
    out = {}
    blocks = [f.text[i] for i in range(1 + max(int(getattr(f, "ext_headers", 0) or 0), 0))]
    for block in blocks:
        text = bytes(block).decode("ascii", errors="replace")
        for key, value in _TEXT_VALUE.findall(text):
            out.setdefault(key.lower(), float(value))
    return out


def _pulse(f, options: SegyImportOptions, text: dict, name: str) -> tuple[dict, str]:
    """The pulse variables and where they came from."""
    if options.pulse is not None:
        f0, f1, dur = options.pulse
        return {"pulse_f0": f0, "pulse_f1": f1, "pulse_duration": dur}, "option"
    names = ("pulse_f0", "pulse_f1", "pulse_duration")
    if all(n in text for n in names):
        return {n: text[n] for n in names}, "textual header"
    B = segyio_module().BinField
    f0, f1, length_ms = (int(f.bin[k]) for k in (B.SweepFrequencyStart, B.SweepFrequencyEnd, B.SweepLength))
    if length_ms > 0 and max(f0, f1) > 0:
        return {"pulse_f0": float(f0), "pulse_f1": float(f1), "pulse_duration": length_ms * 1e-3}, "binary header sweep"
    raise PingFileError(f"{name}: no pulse description (no pulse_f0/pulse_f1/pulse_duration in the textual header, "
                        "no sweep in the binary header); give --pulse F0 F1 DURATION")


def _scalars(options: SegyImportOptions, text: dict, name: str) -> tuple[dict, dict]:
    """Source position and replica delay, and where they came from."""
    values, origins = {}, {}
    if options.source_m is not None:
        values.update(zip(("source_x", "source_y", "source_z"), map(float, options.source_m)))
        origins["source"] = "option"
    elif any(k in text for k in ("source_x", "source_y", "source_z")):
        values.update({k: text.get(k, 0.0) for k in ("source_x", "source_y", "source_z")})
        origins["source"] = "textual header"
    else:
        values.update(source_x=0.0, source_y=0.0, source_z=0.0)
        origins["source"] = "default (array reference point)"
        log.warning("%s: no source position in the file; the transmitter is taken at the array reference point "
                    "(give --source X Y Z)", name)
    if options.tx_delay_s is not None:
        values["tx_delay"], origins["tx_delay"] = float(options.tx_delay_s), "option"
    elif "tx_delay" in text:
        values["tx_delay"], origins["tx_delay"] = text["tx_delay"], "textual header"
    return values, origins


def _read_samples(f, traces: np.ndarray, progress) -> np.ndarray:
    """``(n_pings, n_channels, n_samples)`` float32 samples, ping by ping."""
    n_p, n_c = traces.shape
    out = np.empty((n_p, n_c, len(f.samples)), dtype=np.float32)
    rows = range(n_p) if progress is None else progress(range(n_p), n_p)
    for i in rows:
        idx = traces[i]
        if idx[-1] - idx[0] == n_c - 1 and np.all(np.diff(idx) == 1):
            out[i] = f.trace.raw[int(idx[0]):int(idx[-1]) + 1]
        else:
            for j, t in enumerate(idx):
                out[i, j] = f.trace.raw[int(t)]
    return out


def _element_positions(values: dict, n_channels: int, options: SegyImportOptions, name: str) -> dict:
    """``element_x/y/z`` (m): the option's even spacing, else the headers' (0 where a coordinate is absent)."""
    if options.element_pitch_m is not None:
        y = (np.arange(n_channels) - (n_channels - 1) / 2) * options.element_pitch_m
        return {"element_x": np.zeros(n_channels), "element_y": y, "element_z": np.zeros(n_channels)}
    require("element_y" in values, PingFileError,
            f"{name}: no element positions (the element_y field is 0 in every trace or not mapped); "
            "give --element-pitch M or a mapping (--mapping) naming the field")
    return {k: values.get(k, np.zeros(n_channels)) for k in PER_CHANNEL}


def _sound_speed(values: dict, mapping: SegyMapping, options: SegyImportOptions, n_pings: int, name: str) -> np.ndarray:
    """``(n_pings,)`` sound speed (m/s): the option's, else the headers'."""
    if options.sound_speed_m_s is not None:
        return np.full(n_pings, float(options.sound_speed_m_s))
    entry = mapping.get("sound_speed")
    require("sound_speed" in values, PingFileError, f"{name}: no sound speed in the trace headers "
            f"({entry.describe() + ' is 0 in every trace' if entry else 'not mapped'}); give --sound-speed M/S")
    return values["sound_speed"]


def _channel_valid(f, traces: np.ndarray) -> np.ndarray | None:
    """``(n_pings, n_channels)`` False for dead traces (TraceIdentificationCode 2); ``None`` if none is dead."""
    dead = _header(f, "TraceIdentificationCode")[traces] == TRACE_ID_DEAD
    return ~dead if dead.any() else None


def read_segy_pings(path: str | os.PathLike, *, mapping: SegyMapping | None = None,
                    options: SegyImportOptions | None = None, progress=None) -> tuple[xr.Dataset, dict]:
    """Read a multichannel SEG-Y file (one trace per element, one ensemble per ping) into a ping dataset.

    Parameters
    ----------
    path : str or path-like
        SEG-Y file (any byte order and sample format segyio reads).
    mapping : SegyMapping, optional
        Where the trace headers keep each variable (default
        :class:`~clbeam.io.segy_mapping.SegyMapping`: ``docs/import.md``).
    options : SegyImportOptions, optional
        Pulse, source, replica delay, sound speed and element spacing that
        the headers lack or that replace theirs.
    progress : callable, optional
        ``progress(iterable, total)`` wraps the loop over pings (a progress bar).

    Returns
    -------
    dataset : xarray.Dataset
        ``samples(ping, channel, sample)`` float32, ``kind="raw"``; ``ping``
        numbered by the ensemble field; every variable the headers and
        options give, checked by the ping-file reader.
    origins : dict
        Where the pulse, the source position and the replica delay came from.

    Raises
    ------
    PingFileError
        The file is not SEG-Y, empty, or its layout or values do not make a ping file.
    OptionError
        An option out of range.
    """
    mapping, options = mapping or SegyMapping(), options or SegyImportOptions()
    name = Path(path).name
    with open_segy(Path(path)) as f:
        traces, keys, _ = ensemble_layout(f, mapping, name)
        values = header_variables(f, mapping, traces, keys, name)
        dt = sample_interval_s(f, values, name)
        times = ping_times(f, traces, keys, name) if mapping.ping_time else None
        valid = _channel_valid(f, traces) if mapping.channel_valid else None
        text = text_values(f)
        pulse, pulse_origin = _pulse(f, options, text, name)
        scalars, origins = _scalars(options, text, name)
        samples = _read_samples(f, traces, progress)
    data = {"sample_rate": 1.0 / dt, "t0": values["t0"],
            **_element_positions(values, traces.shape[1], options, name), **pulse, **scalars,
            "sound_speed": _sound_speed(values, mapping, options, traces.shape[0], name),
            **{k: values[k] for k in ("roll", "pitch", "heave", "heading", "draft", "latitude", "longitude")
               if k in values}}
    if times is not None:
        data["ping_time"] = times
    if valid is not None:
        data["channel_valid"] = valid[0] if (valid == valid[0]).all() else valid
    ds = xr.Dataset({k: ping_variable(k, v) for k, v in data.items()}, coords={"ping": keys},
                    attrs={FORMAT_ATTRIBUTE: PING_FORMAT, "source": f"multichannel SEG-Y {name}"})
    dims, arr, attrs = ping_variable("samples", samples)
    ds["samples"] = (dims, arr, {**attrs, "kind": "raw"})
    pings_from_dataset(ds, name)  # the ping-file reader's checks, before anything is written
    return ds, {"pulse": pulse_origin, **origins}


def import_segy(segy_path: str | os.PathLike, ping_path: str | os.PathLike, *, mapping: SegyMapping | None = None,
                options: SegyImportOptions | None = None, progress=None) -> SegyImportResult:
    """Convert a multichannel SEG-Y file into a ping file (NetCDF4, or Zarr for ``.zarr``).

    Parameters
    ----------
    segy_path : str or path-like
        SEG-Y file (see :func:`read_segy_pings`).
    ping_path : str or path-like
        Ping file to write (overwritten).
    mapping, options, progress
        As :func:`read_segy_pings`.

    Returns
    -------
    SegyImportResult
        Sizes, sample rate and where the values the headers lack came from.
    """
    t0 = time.perf_counter()
    ds, origins = read_segy_pings(segy_path, mapping=mapping, options=options, progress=progress)
    out = write_ping_file(ds, ping_path)
    return SegyImportResult(out, ds.sizes["ping"], ds.sizes["channel"], ds.sizes["sample"],
                            float(ds["sample_rate"]), origins, time.perf_counter() - t0)


__all__ = ["SegyImportOptions", "SegyImportResult", "ensemble_layout", "header_variables", "import_segy",
           "open_segy", "read_segy_pings", "text_values"]
