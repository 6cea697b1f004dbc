"""The file formats in one table: ping files (``ping-1``, SPEC §7) and image
files (``images-1``, SPEC §8).

Every variable a clbeam file may hold is listed here once, with the
dimensions it may have, its units and its long name.  The ping-file reader
checks dimensions against :data:`PING_VARIABLES`; the ping-file and image
writers, the simulator and the tests take units and names from the same
tables, so a variable is added or changed in one place.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: global attribute naming a clbeam file's format
FORMAT_ATTRIBUTE = "clbeam_format"
#: value of :data:`FORMAT_ATTRIBUTE` in a ping file (SPEC §7)
PING_FORMAT = "ping-1"
#: value of :data:`FORMAT_ATTRIBUTE` in an image file (SPEC §8)
IMAGE_FORMAT = "images-1"

#: dimensions of the ping samples
SAMPLE_DIMS = ("ping", "channel", "sample")
#: dimensions of every image array
IMAGE_DIMS = ("ping", "angle", "range")


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
        UDUNITS units (``"1"``: dimensionless).
    long_name : str
        What the variable holds.
    required : bool
        A file without it is refused (SPEC §7).
    """

    name: str
    dims: tuple
    units: str
    long_name: str
    required: bool = False

    def attrs(self) -> dict:
        """The variable's ``units`` and ``long_name`` attributes."""
        return {"units": self.units, "long_name": self.long_name}


def _table(*variables: Variable) -> dict:
    return {v.name: v for v in variables}


_PER_PING = (("ping",), ())

#: the variables of a ping file (SPEC §7); the samples are ``samples`` or the pair ``samples_r``/``samples_i``
PING_VARIABLES: dict[str, Variable] = _table(
    Variable("samples", (SAMPLE_DIMS,), "1",
             "element pressure (kind='raw') or pulse-compressed analytic signal (kind='analytic')"),
    Variable("samples_r", (SAMPLE_DIMS,), "1", "pulse-compressed analytic signal, real part"),
    Variable("samples_i", (SAMPLE_DIMS,), "1", "pulse-compressed analytic signal, imaginary part"),
    Variable("sample_rate", ((),), "Hz", "sample rate", required=True),
    Variable("t0", _PER_PING, "s", "time of sample 0 after transmit start", required=True),
    Variable("element_x", (("channel",),), "m", "receive element x (forward), vessel frame"),
    Variable("element_y", (("channel",),), "m", "receive element y (starboard), vessel frame", required=True),
    Variable("element_z", (("channel",),), "m", "receive element z (down), vessel frame", required=True),
    Variable("source_x", ((),), "m", "transmit acoustic centre x, vessel frame"),
    Variable("source_y", ((),), "m", "transmit acoustic centre y, vessel frame", required=True),
    Variable("source_z", ((),), "m", "transmit acoustic centre z, vessel frame", required=True),
    Variable("sound_speed", _PER_PING, "m/s", "sound speed at the transducers", required=True),
    Variable("roll", _PER_PING, "degree", "roll, positive starboard down"),
    Variable("heave", _PER_PING, "m", "heave, positive up"),
    Variable("pitch", _PER_PING, "degree", "pitch, positive bow up"),
    Variable("heading", _PER_PING, "degree", "heading, clockwise from true north"),
    Variable("latitude", _PER_PING, "degree_north", "latitude of the ping"),
    Variable("longitude", _PER_PING, "degree_east", "longitude of the ping"),
    Variable("ping_time", (("ping",),), "", "time of transmission (UTC)"),
    Variable("pulse_f0", ((),), "Hz", "LFM start frequency"),
    Variable("pulse_f1", ((),), "Hz", "LFM end frequency"),
    Variable("pulse_duration", ((),), "s", "LFM length"),
    Variable("tx_waveform", (("tx_sample",),), "1", "transmit waveform at the sample rate"),
    Variable("tx_delay", ((),), "s", "time of the replica's first sample after transmit start"),
    Variable("svp_depth", (("svp",),), "m",
             "sound-speed profile depth below the array reference point (earth-frame z, positive down)"),
    Variable("svp_speed", (("svp",),), "m/s", "sound-speed profile speed"),
    Variable("channel_valid", (("channel",), ("ping", "channel")), "1", "channel is usable"),
    Variable("element_gain_db", (("channel",),), "dB", "channel gain error: recorded over true amplitude"),
    Variable("element_phase_deg", (("channel",),), "degree", "channel phase error: recorded minus true phase"),
)

#: the image arrays of an image file, ``(ping, angle, range)``, with the dtype they are written in
IMAGE_VARIABLES: dict[str, Variable] = _table(
    Variable("intensity", (IMAGE_DIMS,), "squared input units", "intensity |S|^2 (Holland et al. 2024 eq. 1)"),
    Variable("cf", (IMAGE_DIMS,), "1", "coherence factor |S|^2 / (M Q); |S|^2 / (W Q) with apodization"),
    Variable("cf_smooth", (IMAGE_DIMS,), "1", "coherence factor, 7-point Hann smoothed along range"),
    Variable("s_r", (IMAGE_DIMS,), "input units", "coherent sum S = sum w p, real part"),
    Variable("s_i", (IMAGE_DIMS,), "input units", "coherent sum S, imaginary part"),
    Variable("q", (IMAGE_DIMS,), "squared input units", "incoherent sum Q = sum w |p|^2 (w = 1 without apodization)"),
    Variable("m", (IMAGE_DIMS,), "1", "number of contributing channels M"),
    Variable("w", (IMAGE_DIMS,), "1", "sum W of the contributing channels' apodization weights"),
)
#: dtype each image array is stored in
IMAGE_DTYPES = {name: (np.int16 if name == "m" else np.float32) for name in IMAGE_VARIABLES}

#: per-ping variables of an image file: the grid centre and the ship's navigation
IMAGE_PING_VARIABLES: dict[str, Variable] = _table(
    Variable("centre_y", (("ping",),), "m", "grid centre y (earth frame, starboard)"),
    Variable("centre_z", (("ping",),), "m", "grid centre z (earth frame, down)"),
    Variable("source_y", (("ping",),), "m", "transmit acoustic centre y with roll and heave (earth frame)"),
    Variable("source_z", (("ping",),), "m", "transmit acoustic centre z with roll and heave (earth frame)"),
    Variable("sound_speed", (("ping",),), "m/s", "sound speed the ping was imaged with"),
    Variable("n_channels", (("ping",),), "1", "channels that took part in the ping's image"),
    Variable("latitude", (("ping",),), "degree_north", "latitude of the ping"),
    Variable("longitude", (("ping",),), "degree_east", "longitude of the ping"),
    Variable("heading", (("ping",),), "degree", "heading of the ping"),
)

#: coordinates of an image file
IMAGE_COORDS: dict[str, Variable] = _table(
    Variable("angle", (("angle",),), "degree", "angle from nadir, positive to starboard"),
    Variable("range", (("range",),), "m", "range from the grid centre"),
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
    return dims, arr, var.attrs() if var.units else {"long_name": var.long_name}
