"""The file formats in one table: ping files (``ping-1``, docs/ping-format.md) and image
files (``images-1``, docs/cli.md).

Every variable a clbeam file may hold is listed here once, with the
dimensions it may have, its units (UDUNITS, as the CF conventions ask), its
long name and, where the CF standard-name table has one, its standard name.
The ping-file reader checks dimensions against :data:`PING_VARIABLES`; the
ping-file and image writers, the simulator and the tests take units and
names from the same tables, so a variable is added or changed in one place.
Levels in decibels carry ``units = "1"`` (UDUNITS has no decibel) and say
"dB" in their long name.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

#: global attribute naming a clbeam file's format
FORMAT_ATTRIBUTE = "clbeam_format"
#: value of :data:`FORMAT_ATTRIBUTE` in a ping file (docs/ping-format.md)
PING_FORMAT = "ping-1"
#: value of :data:`FORMAT_ATTRIBUTE` in an image file (docs/cli.md)
IMAGE_FORMAT = "images-1"

#: dimensions of the ping samples
SAMPLE_DIMS = ("ping", "channel", "sample")
#: dimensions of every image array
IMAGE_DIMS = ("ping", "angle", "range")

#: units of the times clbeam writes as numbers (CF: UTC, the standard calendar; NaN where unknown)
TIME_UNITS = "seconds since 1970-01-01 00:00:00"
#: calendar of :data:`TIME_UNITS`
TIME_CALENDAR = "standard"


@dataclass(frozen=True)
class Variable:
    """One variable of a clbeam file.

    Attributes
    ----------
    name : str
        Variable name in the file.
    dims : tuple of tuple of str
        The dimension tuples a file may use, the one writers use first
        (e.g. ``(("ping",), ())``: per ping, or one scalar for every ping).
    units : str
        UDUNITS units (``"1"``: dimensionless; ``""``: none written, e.g. a
        time whose units the writer sets).
    long_name : str
        What the variable holds.
    required : bool
        A file without it is refused (docs/ping-format.md).
    standard_name : str
        Name from the CF standard-name table (``""``: the table has none).
    extra : tuple of (str, str)
        Further CF attributes (``positive``, ``comment``, ``calendar``).
    content : str
        ACDD ``coverage_content_type`` (ISO 19115-1: ``physicalMeasurement``,
        ``coordinate``, ``image``, ``referenceInformation``, ``qualityInformation``,
        ``auxiliaryInformation``).
    """

    name: str
    dims: tuple
    units: str
    long_name: str
    required: bool = False
    standard_name: str = ""
    extra: tuple = ()
    content: str = ""

    def attrs(self) -> dict:
        """The variable's CF and ACDD attributes: ``units`` (unless empty), ``long_name``,
        ``standard_name`` and ``coverage_content_type`` (where it has them) and :attr:`extra`."""
        out = {"units": self.units} if self.units else {}
        out["long_name"] = self.long_name
        if self.standard_name:
            out["standard_name"] = self.standard_name
        if self.content:
            out["coverage_content_type"] = self.content
        out.update(self.extra)
        return out


def _table(*variables: Variable, content: str) -> dict:
    """Variables by name; ``content`` the coverage content type of those that give none, and
    ``coordinate`` that of times, latitudes and longitudes."""
    def kind(v: Variable) -> str:
        return v.content or ("coordinate" if v.standard_name in ("time", "latitude", "longitude") else content)

    return {v.name: replace(v, content=kind(v)) for v in variables}


_PER_PING = (("ping",), ())
_MEASURED = "physicalMeasurement"
_QUALITY = "qualityInformation"
#: the unit note of image arrays in the squared units of the samples (a ping file's samples have units "1")
_SQUARED = (("comment", "in the square of the ping file's sample units"),)
_SAMPLE_UNITS = (("comment", "in the ping file's sample units"),)

#: the variables of a ping file (docs/ping-format.md); the samples are ``samples`` or the pair ``samples_r``/``samples_i``
PING_VARIABLES: dict[str, Variable] = _table(
    Variable("samples", (SAMPLE_DIMS,), "1",
             "element pressure (kind='raw') or pulse-compressed analytic signal (kind='analytic')", content=_MEASURED),
    Variable("samples_r", (SAMPLE_DIMS,), "1", "pulse-compressed analytic signal, real part", content=_MEASURED),
    Variable("samples_i", (SAMPLE_DIMS,), "1", "pulse-compressed analytic signal, imaginary part", content=_MEASURED),
    Variable("sample_rate", ((),), "Hz", "sample rate", required=True),
    Variable("t0", _PER_PING, "s", "time of sample 0 after transmit start", required=True),
    Variable("element_x", (("channel",),), "m", "receive element x (forward), vessel frame"),
    Variable("element_y", (("channel",),), "m", "receive element y (starboard), vessel frame", required=True),
    Variable("element_z", (("channel",),), "m", "receive element z (down), vessel frame", required=True),
    Variable("source_x", ((),), "m", "transmit acoustic centre x, vessel frame"),
    Variable("source_y", ((),), "m", "transmit acoustic centre y, vessel frame", required=True),
    Variable("source_z", ((),), "m", "transmit acoustic centre z, vessel frame", required=True),
    Variable("sound_speed", _PER_PING, "m/s", "sound speed at the transducers", required=True,
             standard_name="speed_of_sound_in_sea_water", content=_MEASURED),
    Variable("roll", _PER_PING, "degree", "roll, positive starboard down", standard_name="platform_roll_starboard_down",
             content=_MEASURED),
    Variable("heave", _PER_PING, "m", "heave, positive up", standard_name="platform_heave_up", content=_MEASURED),
    Variable("pitch", _PER_PING, "degree", "pitch, positive bow up", standard_name="platform_pitch_fore_up",
             content=_MEASURED),
    Variable("heading", _PER_PING, "degree", "heading, clockwise from true north", standard_name="platform_orientation",
             content=_MEASURED),
    Variable("latitude", _PER_PING, "degree_north", "latitude of the ping", standard_name="latitude"),
    Variable("longitude", _PER_PING, "degree_east", "longitude of the ping", standard_name="longitude"),
    Variable("ping_time", (("ping",),), "", "time of transmission (UTC)", standard_name="time"),
    Variable("draft", _PER_PING, "m", "depth of the array reference point below the sea surface (transducer draft)",
             standard_name="depth", extra=(("positive", "down"),), content=_MEASURED),
    Variable("pulse_f0", ((),), "Hz", "LFM start frequency"),
    Variable("pulse_f1", ((),), "Hz", "LFM end frequency"),
    Variable("pulse_duration", ((),), "s", "LFM length"),
    Variable("tx_waveform", (("tx_sample",),), "1", "transmit waveform at the sample rate"),
    Variable("tx_delay", ((),), "s", "time of the replica's first sample after transmit start"),
    Variable("svp_depth", (("svp",),), "m",
             "sound-speed profile depth below the array reference point (earth-frame z, positive down)",
             content=_MEASURED),
    Variable("svp_speed", (("svp",),), "m/s", "sound-speed profile speed", standard_name="speed_of_sound_in_sea_water",
             content=_MEASURED),
    Variable("channel_valid", (("channel",), ("ping", "channel")), "1", "channel is usable", content=_QUALITY),
    Variable("element_gain_db", (("channel",),), "1", "channel gain error (dB): recorded over true amplitude",
             content=_QUALITY),
    Variable("element_phase_deg", (("channel",),), "degree", "channel phase error: recorded minus true phase",
             content=_QUALITY),
    content="referenceInformation",
)

#: the image arrays of an image file, ``(ping, angle, range)``, with the dtype they are written in
IMAGE_VARIABLES: dict[str, Variable] = _table(
    Variable("intensity", (IMAGE_DIMS,), "1", "intensity |S|^2 (Holland et al. 2024 eq. 1)", extra=_SQUARED),
    Variable("cf", (IMAGE_DIMS,), "1", "coherence factor |S|^2 / (M Q); |S|^2 / (W Q) with apodization"),
    Variable("cf_smooth", (IMAGE_DIMS,), "1", "coherence factor, 7-point Hann smoothed along range"),
    Variable("s_r", (IMAGE_DIMS,), "1", "coherent sum S = sum w p, real part", extra=_SAMPLE_UNITS),
    Variable("s_i", (IMAGE_DIMS,), "1", "coherent sum S, imaginary part", extra=_SAMPLE_UNITS),
    Variable("q", (IMAGE_DIMS,), "1", "incoherent sum Q = sum w |p|^2 (w = 1 without apodization)", extra=_SQUARED),
    Variable("m", (IMAGE_DIMS,), "1", "number of contributing channels M"),
    Variable("w", (IMAGE_DIMS,), "1", "sum W of the contributing channels' apodization weights"),
    content="image",
)
#: dtype each image array is stored in
IMAGE_DTYPES = {name: (np.int16 if name == "m" else np.float32) for name in IMAGE_VARIABLES}
#: image arrays in 0..1 that may be stored packed in 16 bits (CF §8.1)
PACKABLE_IMAGE_VARIABLES = ("cf", "cf_smooth")

#: per-ping variables of an image file: the ping's time, the grid centre, the ship's navigation and draft
IMAGE_PING_VARIABLES: dict[str, Variable] = _table(
    Variable("ping_time", (("ping",),), TIME_UNITS, "time of transmission (UTC)", standard_name="time",
             extra=(("calendar", TIME_CALENDAR),)),
    Variable("centre_y", (("ping",),), "m", "grid centre y (earth frame, starboard)"),
    Variable("centre_z", (("ping",),), "m", "grid centre z (earth frame, down, from the array reference point)"),
    Variable("source_y", (("ping",),), "m", "transmit acoustic centre y with roll and heave (earth frame)"),
    Variable("source_z", (("ping",),), "m", "transmit acoustic centre z with roll and heave (earth frame)"),
    Variable("sound_speed", (("ping",),), "m/s", "sound speed the ping was imaged with",
             standard_name="speed_of_sound_in_sea_water", content=_MEASURED),
    Variable("n_channels", (("ping",),), "1", "channels that took part in the ping's image"),
    Variable("latitude", (("ping",),), "degree_north", "latitude of the ping", standard_name="latitude"),
    Variable("longitude", (("ping",),), "degree_east", "longitude of the ping", standard_name="longitude"),
    Variable("heading", (("ping",),), "degree", "heading of the ping, clockwise from true north",
             standard_name="platform_orientation"),
    Variable("draft", (("ping",),), "m", "depth of the array reference point below the sea surface (transducer draft)",
             standard_name="depth",
             extra=(("positive", "down"),
                    ("comment", "an image cell lies draft + centre_z + range * cos(angle) below the sea surface; "
                                "0 where the ping file gives no draft"))),
    content="auxiliaryInformation",
)

#: coordinates of an image file
IMAGE_COORDS: dict[str, Variable] = _table(
    Variable("angle", (("angle",),), "degree", "angle from nadir, positive to starboard"),
    Variable("range", (("range",),), "m", "range from the grid centre"),
    content="coordinate",
)


def image_variables(outputs, *, apodized: bool = False) -> list[str]:
    """The image arrays written for the requested engine outputs.

    Parameters
    ----------
    outputs : iterable of str
        Engine outputs: ``"intensity"``, ``"cf"``, ``"sums"`` (``s_r``,
        ``s_i``, ``q``, ``m``, and ``w`` when ``apodized``); and
        ``"cf_smooth"``, written only when asked (it is ``cf`` smoothed
        along range with the 7-point Hann window: a third of a file's bytes
        that :func:`clbeam.imaging.postprocess.hann_smooth` gives back).
    apodized : bool
        The sums are weighted (a receive window other than ``rect``).

    Returns
    -------
    list of str
        Names from :data:`IMAGE_VARIABLES`, in its order.
    """
    out = set(outputs)
    if "sums" in out:
        out |= {"s_r", "s_i", "q", "m"} | ({"w"} if apodized else set())
    return [name for name in IMAGE_VARIABLES if name in out]


def ping_variable(name: str, values, *, dims: tuple | None = None):
    """``(dims, values, attrs)`` of a ping-file variable, ready for :class:`xarray.Dataset`.

    Parameters
    ----------
    name : str
        A name from :data:`PING_VARIABLES`.
    values : array_like
        The values; their number of dimensions picks the first matching
        dimension tuple of the table unless ``dims`` is given.
    dims : tuple of str, optional
        Dimensions to use (one of the table's).
    """
    var = PING_VARIABLES[name]
    arr = np.asarray(values)
    if dims is None:
        dims = next((d for d in var.dims if len(d) == arr.ndim), None)
    if dims not in var.dims:
        raise ValueError(f"variable '{name}' takes dimensions {var.dims}, got {arr.ndim}-D values")
    return dims, arr, var.attrs()
