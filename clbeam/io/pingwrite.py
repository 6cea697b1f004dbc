"""Writing ping files (SPEC §7): pings to a dataset, a dataset to disk.

:func:`dataset_from_pings` is the inverse of
:func:`clbeam.io.pingfile.pings_from_dataset`: a sequence of
:class:`~clbeam.model.ping.Ping` sharing one array and one sampling becomes
one SPEC §7 dataset, every variable with the units and long name of
:data:`clbeam.io.schema.PING_VARIABLES`.  :func:`write_ping_file` stores a
dataset as NetCDF4 or Zarr.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import xarray as xr

from clbeam.errors import ClbeamError, require
from clbeam.io.schema import FORMAT_ATTRIBUTE, PING_FORMAT, ping_variable


def write_ping_file(ds: xr.Dataset, path: str | os.PathLike) -> Path:
    """Write a SPEC §7 dataset to NetCDF4 (HDF5, complex allowed) or to Zarr
    when ``path`` ends in ``.zarr``; the global ``clbeam_format`` is set."""
    p = Path(path)
    ds = ds.copy()
    ds.attrs[FORMAT_ATTRIBUTE] = PING_FORMAT
    if p.suffix == ".zarr":
        ds.to_zarr(p, mode="w")
    elif any(np.issubdtype(v.dtype, np.complexfloating) for v in ds.data_vars.values()):
        # the netCDF4 library's complex compound type (nc-complex), readable by both engines
        ds.to_netcdf(p, engine="netcdf4", auto_complex=True)
    else:
        ds.to_netcdf(p, engine="h5netcdf")
    return p


def _equal(a, b) -> bool:
    """Equality of ping attributes: arrays by value, dataclasses field by field."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return a is not None and b is not None and np.array_equal(a, b)
    if dataclasses.is_dataclass(a) and type(a) is type(b):
        return all(_equal(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a) if f.compare)
    return bool(a == b)


def _same(pings, attr: str, what: str):
    first = getattr(pings[0], attr)
    for p in pings[1:]:
        require(_equal(getattr(p, attr), first), ClbeamError, f"ping {p.index} has another {what} than ping {pings[0].index}; "
                "one ping file holds one array and one sampling")
    return first


def _per_ping(pings, attr: str) -> np.ndarray | None:
    """``(n_pings,)`` float values of ``attr``, ``None`` when no ping has one (NaN where one lacks it)."""
    values = [getattr(p, attr) for p in pings]
    if all(v is None for v in values):
        return None
    return np.array([np.nan if v is None else float(v) for v in values])


def _pulse_variables(pulse) -> dict:
    if pulse is None:
        return {}
    delay = {"tx_delay": float(pulse.delay_s)} if pulse.delay_s else {}
    if pulse.waveform is not None:
        return {"tx_waveform": np.asarray(pulse.waveform, dtype=np.float64), **delay}
    return {"pulse_f0": pulse.f0_hz, "pulse_f1": pulse.f1_hz, "pulse_duration": pulse.duration_s, **delay}


def _optional_variables(pings) -> dict:
    """The optional SPEC §7 variables the pings carry: navigation, times, channel mask, profile, responses."""
    values = {}
    for name, attr in (("pitch", "pitch_deg"), ("heading", "heading_deg"), ("latitude", "latitude_deg"),
                       ("longitude", "longitude_deg")):
        per = _per_ping(pings, attr)
        if per is not None:
            values[name] = per
    if any(p.time is not None for p in pings):
        values["ping_time"] = np.array([np.datetime64("NaT", "ns") if p.time is None else p.time for p in pings],
                                       dtype="datetime64[ns]")
    valid = np.stack([np.asarray(p.channel_valid, dtype=bool) for p in pings])
    if not valid.all():
        values["channel_valid"] = valid[0] if (valid == valid[0]).all() else valid
    svp = _same(pings, "svp", "sound-speed profile")
    if svp is not None:
        values["svp_depth"], values["svp_speed"] = svp.depths_m, svp.speeds_m_s
    for name in ("element_gain_db", "element_phase_deg"):
        value = _same(pings, name, name.replace("_", " "))
        if value is not None:
            values[name] = value
    return values


def dataset_from_pings(pings, *, samples_dtype=None, attrs: dict | None = None) -> xr.Dataset:
    """One SPEC §7 dataset holding ``pings``.

    Parameters
    ----------
    pings : sequence of Ping
        Pings of one array: the same kind, sample rate, record length,
        element and source positions, pulse and sound-speed profile.
    samples_dtype : numpy dtype, optional
        Store the samples in this dtype (e.g. ``float32``); default theirs.
    attrs : dict, optional
        Extra global attributes.

    Returns
    -------
    xarray.Dataset
        ``samples(ping, channel, sample)`` (``kind`` attribute), the geometry,
        the sampling, the motion and navigation the pings carry, the pulse,
        the profile, the channel mask and responses; ``ping`` numbered by
        :attr:`Ping.index`.

    Raises
    ------
    ClbeamError
        When there is no ping or the pings do not share one array and sampling.
    """
    pings = list(pings)
    require(len(pings) > 0, ClbeamError, "no pings to write")
    kind = _same(pings, "kind", "kind of samples")
    _same(pings, "n_samples", "record length")
    pos = _same(pings, "element_pos_m", "element layout")
    samples = np.stack([p.samples for p in pings])
    if samples_dtype is not None:
        samples = samples.astype(samples_dtype)
    values = {
        "sample_rate": _same(pings, "sample_rate_hz", "sample rate"),
        "t0": np.array([p.t0_s for p in pings]),
        "element_x": pos[:, 0], "element_y": pos[:, 1], "element_z": pos[:, 2],
        "sound_speed": np.array([p.sound_speed_m_s for p in pings]),
        "roll": np.array([p.roll_deg for p in pings]), "heave": np.array([p.heave_m for p in pings]),
        **_pulse_variables(_same(pings, "pulse", "pulse")),
    }
    for name, value in zip(("source_x", "source_y", "source_z"), _same(pings, "source_pos_m", "source position")):
        values[name] = float(value)
    values.update(_optional_variables(pings))
    data = {name: ping_variable(name, v) for name, v in values.items()}
    dims, arr, var_attrs = ping_variable("samples", samples)
    data["samples"] = (dims, arr, {**var_attrs, "kind": kind})
    return xr.Dataset(data, coords={"ping": [p.index for p in pings]},
                      attrs={FORMAT_ATTRIBUTE: PING_FORMAT, **(attrs or {})})
