"""Where a multichannel SEG-Y file keeps each ping-file variable: the trace-header mapping.

A sonar's multichannel SEG-Y export holds one trace per receive element and
one ensemble of traces per ping.  :class:`SegyMapping` says, for each ping
file variable (docs/ping-format.md) that varies by trace or by ping, which trace-header
field holds it, which SEG-Y scalar field (if any) scales it, and the factor
from the scaled header value to the ping file's units::

    value = header * scalar_factor * scale        (scalar_factor = s if s > 0, 1/|s| if s < 0, 1 if 0)

:data:`DEFAULT_ENTRIES` follows SEG-Y rev 1 usage where the standard has a
field (the sample interval in microseconds, the delay recording time in
milliseconds with the rev 1 time scalar, source coordinates with the
coordinate scalar and units, elevations with the elevation scalar, the
water velocity, the UTC time fields, the trace identification code) and
names clbeam's choice, documented in ``docs/import.md``, where it has none
(the element's position across the array, roll, heading).  A TOML file
(:func:`load_mapping`) replaces entries one by one.  The importer
(:mod:`clbeam.io.segy_import`) and the exporter (:mod:`clbeam.io.segy_export`)
use the same mapping, so a file exported with a mapping imports with it.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from clbeam.errors import OptionError, require

#: trace-header layout of SEG-Y rev 1 (as segyio names its fields): field name -> first byte (1-based)
TRACE_FIELDS: dict[str, int] = {
    "TRACE_SEQUENCE_LINE": 1, "TRACE_SEQUENCE_FILE": 5, "FieldRecord": 9, "TraceNumber": 13,
    "EnergySourcePoint": 17, "CDP": 21, "CDP_TRACE": 25, "TraceIdentificationCode": 29, "NSummedTraces": 31,
    "NStackedTraces": 33, "DataUse": 35, "offset": 37, "ReceiverGroupElevation": 41, "SourceSurfaceElevation": 45,
    "SourceDepth": 49, "ReceiverDatumElevation": 53, "SourceDatumElevation": 57, "SourceWaterDepth": 61,
    "GroupWaterDepth": 65, "ElevationScalar": 69, "SourceGroupScalar": 71, "SourceX": 73, "SourceY": 77,
    "GroupX": 81, "GroupY": 85, "CoordinateUnits": 89, "WeatheringVelocity": 91, "SubWeatheringVelocity": 93,
    "SourceUpholeTime": 95, "GroupUpholeTime": 97, "SourceStaticCorrection": 99, "GroupStaticCorrection": 101,
    "TotalStaticApplied": 103, "LagTimeA": 105, "LagTimeB": 107, "DelayRecordingTime": 109, "MuteTimeStart": 111,
    "MuteTimeEND": 113, "TRACE_SAMPLE_COUNT": 115, "TRACE_SAMPLE_INTERVAL": 117, "GainType": 119,
    "InstrumentGainConstant": 121, "InstrumentInitialGain": 123, "Correlated": 125, "SweepFrequencyStart": 127,
    "SweepFrequencyEnd": 129, "SweepLength": 131, "SweepType": 133, "SweepTraceTaperLengthStart": 135,
    "SweepTraceTaperLengthEnd": 137, "TaperType": 139, "AliasFilterFrequency": 141, "AliasFilterSlope": 143,
    "NotchFilterFrequency": 145, "NotchFilterSlope": 147, "LowCutFrequency": 149, "HighCutFrequency": 151,
    "LowCutSlope": 153, "HighCutSlope": 155, "YearDataRecorded": 157, "DayOfYear": 159, "HourOfDay": 161,
    "MinuteOfHour": 163, "SecondOfMinute": 165, "TimeBaseCode": 167, "TraceWeightingFactor": 169,
    "GeophoneGroupNumberRoll1": 171, "GeophoneGroupNumberFirstTraceOrigField": 173,
    "GeophoneGroupNumberLastTraceOrigField": 175, "GapSize": 177, "OverTravel": 179, "CDP_X": 181, "CDP_Y": 185,
    "INLINE_3D": 189, "CROSSLINE_3D": 193, "ShotPoint": 197, "ShotPointScalar": 201,
    "TraceValueMeasurementUnit": 203, "TransductionConstantMantissa": 205, "TransductionConstantPower": 209,
    "TransductionUnit": 211, "TraceIdentifier": 213, "ScalarTraceHeader": 215, "SourceType": 217,
    "SourceEnergyDirectionMantissa": 219, "SourceEnergyDirectionExponent": 223, "SourceMeasurementMantissa": 225,
    "SourceMeasurementExponent": 229, "SourceMeasurementUnit": 231, "UnassignedInt1": 233, "UnassignedInt2": 237,
}
#: trace-header length (bytes)
TRACE_HEADER_BYTES = 240
_STARTS = sorted(TRACE_FIELDS.values())
#: size (bytes) of each field: up to the next field's first byte
FIELD_BYTES: dict[str, int] = {name: (_STARTS + [TRACE_HEADER_BYTES + 1])[_STARTS.index(b) + 1] - b
                               for name, b in TRACE_FIELDS.items()}
_BY_BYTE = {b: name for name, b in TRACE_FIELDS.items()}
_BY_LOWER = {name.lower(): name for name in TRACE_FIELDS}
#: fields SEG-Y rev 2 declares unsigned (sample count and interval): read modulo 2**16
UNSIGNED_FIELDS = frozenset({"TRACE_SAMPLE_COUNT", "TRACE_SAMPLE_INTERVAL"})

#: SEG-Y scalar values the exporter may write, finest first (negative divides, positive multiplies)
SCALAR_CHOICES = (-10000, -1000, -100, -10, 1, 10, 100, 1000, 10000)

#: CoordinateUnits codes (trace bytes 89-90) and the degrees per scaled coordinate they mean
COORDINATE_UNITS_LENGTH, COORDINATE_UNITS_ARCSEC, COORDINATE_UNITS_DEGREES, COORDINATE_UNITS_DMS = 1, 2, 3, 4
#: TraceIdentificationCode (bytes 29-30) of a live data trace and of a dead one
TRACE_ID_LIVE, TRACE_ID_DEAD = 1, 2
#: TimeBaseCode (bytes 167-168) of UTC (rev 1: 4; rev 0: 2 = GMT)
TIME_BASE_UTC, TIME_BASE_GMT = 4, 2
#: the time fields of a trace (bytes 157-166), whole seconds
TIME_FIELDS = ("YearDataRecorded", "DayOfYear", "HourOfDay", "MinuteOfHour", "SecondOfMinute")


def field_name(spec, *, entry: str = "") -> str:
    """The segyio field name of ``spec``: a field name (any case) or the number of its first byte.

    Parameters
    ----------
    spec : str or int
        ``"DelayRecordingTime"``, ``"delayrecordingtime"``, ``109`` or ``"109"``.
    entry : str
        The mapping entry, for the message.

    Raises
    ------
    OptionError
        One line naming the entry and the unknown field.
    """
    where = f"SEG-Y mapping '{entry}': " if entry else ""
    text = str(spec).strip()
    if text.isdigit():
        name = _BY_BYTE.get(int(text))
        require(name is not None, OptionError, f"{where}byte {text} does not start a SEG-Y rev 1 trace-header field "
                f"(fields start at bytes {', '.join(map(str, _STARTS[:6]))}, ... {_STARTS[-1]})")
        return name
    name = _BY_LOWER.get(text.lower())
    require(name is not None, OptionError, f"{where}unknown trace-header field '{text}'; expected a segyio "
            "TraceField name (e.g. DelayRecordingTime) or the number of the field's first byte (e.g. 109)")
    return name


@dataclass(frozen=True)
class HeaderEntry:
    """Where one ping-file variable sits in the trace header.

    Attributes
    ----------
    field : str
        segyio trace-header field name (:data:`TRACE_FIELDS`).
    scale : float or None
        Ping-file units per scaled header unit (e.g. ``1e-3``: the header
        holds milliseconds and the file seconds).  ``None`` only for latitude
        and longitude: the file's ``CoordinateUnits`` decide (arc-seconds,
        degrees or DMS).
    scalar : str or None
        A SEG-Y scalar field (e.g. ``ElevationScalar``) applied first:
        positive multiplies, negative divides, 0 means 1.
    """

    field: str
    scale: float | None = 1.0
    scalar: str | None = None

    def __post_init__(self):
        require(self.scale is None or (math.isfinite(self.scale) and self.scale != 0), OptionError,
                f"SEG-Y mapping of field {self.field}: scale must be a finite non-zero number, got {self.scale!r}")

    @property
    def byte(self) -> int:
        """First byte of the field (1-based)."""
        return TRACE_FIELDS[self.field]

    @property
    def n_bytes(self) -> int:
        """Size of the field (2 or 4 bytes)."""
        return FIELD_BYTES[self.field]

    def describe(self) -> str:
        """``"DelayRecordingTime (bytes 109-110) x ScalarTraceHeader x 0.001"``."""
        text = f"{self.field} (bytes {self.byte}-{self.byte + self.n_bytes - 1})"
        if self.scalar:
            text += f" x {self.scalar}"
        return text + ("" if self.scale is None else f" x {self.scale:g}")


#: the ensemble and channel keys, and the variables, a mapping may name
REQUIRED_ENTRIES = ("ensemble", "channel", "sample_interval", "t0")
OPTIONAL_ENTRIES = ("element_x", "element_y", "element_z", "sound_speed", "roll", "pitch", "heave", "heading",
                    "draft", "latitude", "longitude")
#: entries that are switches (True: read/write the standard fields; False: leave them out)
SWITCH_ENTRIES = ("ping_time", "channel_valid")
#: units of each mapped quantity in the ping file (for the documentation and messages)
UNITS = {"ensemble": "", "channel": "", "sample_interval": "s", "t0": "s", "element_x": "m", "element_y": "m",
         "element_z": "m", "sound_speed": "m/s", "roll": "degree", "pitch": "degree", "heave": "m",
         "heading": "degree", "draft": "m", "latitude": "degree", "longitude": "degree"}

#: the default mapping (``docs/import.md`` explains each choice)
DEFAULT_ENTRIES: dict[str, HeaderEntry | None] = {
    "ensemble": HeaderEntry("FieldRecord"),
    "channel": HeaderEntry("TraceNumber"),
    "sample_interval": HeaderEntry("TRACE_SAMPLE_INTERVAL", 1e-6),
    "t0": HeaderEntry("DelayRecordingTime", 1e-3, "ScalarTraceHeader"),
    "element_x": None,
    # SEG-Y's offset is whole metres and has no scalar: clbeam keeps the element's y in 0.1 micrometre
    "element_y": HeaderEntry("offset", 1e-7),
    "element_z": HeaderEntry("ReceiverGroupElevation", -1.0, "ElevationScalar"),  # elevation is up, z down
    "sound_speed": HeaderEntry("WeatheringVelocity", 1.0),
    "roll": HeaderEntry("UnassignedInt1", 1e-6),
    "pitch": None,
    "heave": HeaderEntry("SourceSurfaceElevation", 1.0, "ElevationScalar"),
    "heading": HeaderEntry("UnassignedInt2", 1e-6),
    "draft": HeaderEntry("SourceDepth", 1.0, "ElevationScalar"),  # rev 1: source depth below surface
    "latitude": HeaderEntry("SourceY", None, "SourceGroupScalar"),
    "longitude": HeaderEntry("SourceX", None, "SourceGroupScalar"),
}


@dataclass(frozen=True)
class SegyMapping:
    """The trace-header mapping of a multichannel SEG-Y ping file.

    Attributes
    ----------
    entries : dict
        Entry name (:data:`REQUIRED_ENTRIES`, :data:`OPTIONAL_ENTRIES`) ->
        :class:`HeaderEntry`, or ``None`` where the variable is not in the
        headers.
    ping_time : bool
        Read and write the ping time in the rev 1 time fields (bytes 157-168).
    channel_valid : bool
        Dead channels are traces of TraceIdentificationCode 2 (bytes 29-30).
    """

    entries: dict = field(default_factory=lambda: dict(DEFAULT_ENTRIES))
    ping_time: bool = True
    channel_valid: bool = True

    def __post_init__(self):
        for name in REQUIRED_ENTRIES:
            require(self.entries.get(name) is not None, OptionError,
                    f"SEG-Y mapping '{name}' cannot be switched off: every file needs it")
        lat, lon = self.entries.get("latitude"), self.entries.get("longitude")
        set_, unset = ("latitude", "longitude") if lon is None else ("longitude", "latitude")
        require((lat is None) == (lon is None), OptionError,
                f"SEG-Y mapping '{set_}' is set but '{unset}' is not; map both or neither")
        for name, entry in self.entries.items():
            if entry is not None and entry.scale is None:
                require(name in ("latitude", "longitude"), OptionError,
                        f"SEG-Y mapping '{name}' needs a scale (only latitude and longitude follow CoordinateUnits)")
        self._check_fields_distinct()

    def _check_fields_distinct(self) -> None:
        """No two entries in one field, no entry in a scalar field or the bookkeeping fields it would clash with."""
        used: dict[str, str] = {}
        reserved = {"TRACE_SAMPLE_COUNT": "the sample count"}
        if self.ping_time:
            reserved.update({f: "the ping time" for f in (*TIME_FIELDS, "TimeBaseCode")})
        if self.channel_valid:
            reserved["TraceIdentificationCode"] = "the dead-channel flag"
        if self.entries.get("latitude") is not None:
            reserved["CoordinateUnits"] = "the coordinate units"
        scalars = {e.scalar: name for name, e in self.entries.items() if e is not None and e.scalar}
        for name, entry in self.mapped().items():
            require(entry.field not in used, OptionError,
                    f"SEG-Y mapping '{name}' and '{used.get(entry.field)}' both name field {entry.field}")
            require(entry.field not in reserved, OptionError,
                    f"SEG-Y mapping '{name}' names field {entry.field}, which holds {reserved.get(entry.field)}")
            require(entry.field not in scalars, OptionError,
                    f"SEG-Y mapping '{name}' names field {entry.field}, the scalar of '{scalars.get(entry.field)}'")
            used[entry.field] = name

    def mapped(self) -> dict:
        """The entries that name a field, ``{name: HeaderEntry}``."""
        return {name: e for name, e in self.entries.items() if e is not None}

    def get(self, name: str) -> HeaderEntry | None:
        """The entry of ``name`` (``None``: not in the headers)."""
        return self.entries.get(name)

    def text_lines(self) -> list[str]:
        """One line per mapped entry, for the textual header (``"map t0 = DelayRecordingTime ..."``)."""
        return [f"map {name} = {entry.describe()}" for name, entry in self.mapped().items()]


def _entry_from_toml(name: str, value) -> HeaderEntry | None:
    """One mapping entry from its TOML value: ``false``, a field (name or byte) or a table."""
    if value is False:
        return None
    if isinstance(value, (str, int)) and not isinstance(value, bool):
        return HeaderEntry(field_name(value, entry=name))
    require(isinstance(value, dict), OptionError,
            f"SEG-Y mapping '{name}': expected false, a field name, a byte number or a table, got {value!r}")
    unknown = set(value) - {"field", "byte", "scale", "scalar"}
    require(not unknown, OptionError, f"SEG-Y mapping '{name}': unknown key(s) {', '.join(sorted(unknown))}; "
            "expected field (or byte), scale, scalar")
    require(("field" in value) != ("byte" in value), OptionError,
            f"SEG-Y mapping '{name}': give one of 'field' and 'byte'")
    scale = value.get("scale", None if name in ("latitude", "longitude") else 1.0)
    require(scale is None or (isinstance(scale, (int, float)) and not isinstance(scale, bool)), OptionError,
            f"SEG-Y mapping '{name}': scale must be a number, got {scale!r}")
    scalar = value.get("scalar")
    return HeaderEntry(field_name(value.get("field", value.get("byte")), entry=name),
                       None if scale is None else float(scale),
                       None if scalar in (None, False) else field_name(scalar, entry=name))


def mapping_from_dict(table: dict, base: SegyMapping | None = None) -> SegyMapping:
    """A mapping from ``base`` (default :class:`SegyMapping`) with the entries of ``table`` replaced.

    Parameters
    ----------
    table : dict
        Entry name -> ``false`` (not in the headers), a field name or first
        byte (scale 1, no scalar), or a table ``{field|byte, scale, scalar}``
        that replaces the default entry whole; ``ping_time`` and
        ``channel_valid`` take ``true`` or ``false``.
    base : SegyMapping, optional
        The mapping to start from.

    Raises
    ------
    OptionError
        An unknown entry, field or key, in one line.
    """
    base = base or SegyMapping()
    entries, switches = dict(base.entries), {"ping_time": base.ping_time, "channel_valid": base.channel_valid}
    known = (*REQUIRED_ENTRIES, *OPTIONAL_ENTRIES, *SWITCH_ENTRIES)
    for name, value in table.items():
        require(name in known, OptionError, f"SEG-Y mapping: unknown entry '{name}'; expected one of {', '.join(known)}")
        if name in SWITCH_ENTRIES:
            require(isinstance(value, bool), OptionError, f"SEG-Y mapping '{name}': expected true or false, got {value!r}")
            switches[name] = value
        else:
            entries[name] = _entry_from_toml(name, value)
    return replace(base, entries=entries, **switches)


def load_mapping(path: str | os.PathLike | None) -> SegyMapping:
    """The mapping of a TOML file (entries replacing the defaults), or the default mapping for ``None``.

    Parameters
    ----------
    path : str, path-like or None
        TOML file, e.g. ``roll = {field = "UnassignedInt1", scale = 1e-6}``
        or ``pitch = 237``; ``docs/import.md`` has a full example.

    Raises
    ------
    OptionError
        A missing or malformed file, or an unknown entry or field, in one line.
    """
    if path is None:
        return SegyMapping()
    p = Path(path)
    require(p.is_file(), OptionError, f"SEG-Y mapping {p}: no such file")
    try:
        table = tomllib.loads(p.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise OptionError(f"SEG-Y mapping {p}: not valid TOML ({exc})") from None
    try:
        return mapping_from_dict(table)
    except OptionError as exc:
        raise OptionError(f"{p}: {exc}") from None


# -- scalars and values ---------------------------------------------------------------
def scalar_factor(scalar) -> np.ndarray:
    """Multipliers of SEG-Y scalar values: ``s`` for ``s > 0``, ``1 / |s|`` for ``s < 0``, 1 for 0.

    Parameters
    ----------
    scalar : array_like of int
        Values of a scalar field.

    Returns
    -------
    numpy.ndarray
        float64 multipliers.
    """
    s = np.asarray(scalar, dtype=np.float64)
    return np.where(s > 0, s, np.where(s < 0, 1.0 / np.where(s < 0, -s, 1.0), 1.0))


def apply_scale(raw, scalar, scale: float) -> np.ndarray:
    """``raw x scalar_factor(scalar) x scale`` as float64, dividing where a factor is a reciprocal integer
    (``275625 / 1e7`` rather than ``275625 * 1e-7``: the correctly rounded decimal).

    Parameters
    ----------
    raw : array_like of int
        Header values.
    scalar : array_like of int or None
        Values of the entry's scalar field (``None``: no scalar).
    scale : float
        Ping-file units per scaled header unit.

    Returns
    -------
    numpy.ndarray
        The values in the ping file's units.
    """
    value = np.asarray(raw, dtype=np.float64)
    if scalar is not None:
        s = np.asarray(scalar, dtype=np.float64)
        value = np.where(s < 0, value / np.where(s < 0, -s, 1.0), value * np.where(s > 0, s, 1.0))
    inverse = 1.0 / abs(scale)
    if abs(scale) < 1 and inverse == round(inverse):
        return value / (math.copysign(round(inverse), scale))
    return value * scale


def field_limits(entry_field: str) -> tuple[int, int]:
    """The smallest and largest integer a field holds (signed, or unsigned for :data:`UNSIGNED_FIELDS`)."""
    bits = 8 * FIELD_BYTES[entry_field]
    if entry_field in UNSIGNED_FIELDS:
        return 0, 2 ** bits - 1
    return -(2 ** (bits - 1)), 2 ** (bits - 1) - 1


def as_unsigned(entry_field: str, raw: np.ndarray) -> np.ndarray:
    """Header values of ``entry_field`` as SEG-Y rev 2 reads them (unsigned for :data:`UNSIGNED_FIELDS`)."""
    raw = np.asarray(raw, dtype=np.int64)
    if entry_field in UNSIGNED_FIELDS:
        return raw % (2 ** (8 * FIELD_BYTES[entry_field]))
    return raw


__all__ = ["DEFAULT_ENTRIES", "FIELD_BYTES", "HeaderEntry", "SCALAR_CHOICES", "SegyMapping", "TRACE_FIELDS",
           "apply_scale", "as_unsigned", "field_limits", "field_name", "load_mapping", "mapping_from_dict",
           "scalar_factor"]
