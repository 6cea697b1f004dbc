"""Writing ping files (docs/ping-format.md): pings to a dataset, a dataset to disk.

:func:`dataset_from_pings` is the inverse of
:func:`clbeam.io.pingfile.pings_from_dataset`: a sequence of
:class:`~clbeam.model.ping.Ping` sharing one array and one sampling becomes
one ping dataset, every variable with the units, long name and standard
name of :data:`clbeam.io.schema.PING_VARIABLES`.  :func:`write_ping_file`
stores a dataset as NetCDF4 or Zarr, CF- and ACDD-compliant
(:mod:`clbeam.io.conventions`).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import xarray as xr

from clbeam.errors import ClbeamError, require
from clbeam.io.conventions import coverage_attributes, discovery_attributes
from clbeam.io.schema import FORMAT_ATTRIBUTE, PING_FORMAT, PING_VARIABLES, ping_variable


def write_ping_file(ds: xr.Dataset, path: str | os.PathLike, *, split_complex: bool = True) -> Path:
    """Write a ping dataset to NetCDF4 (HDF5) or to Zarr when ``path`` ends in ``.zarr``.

    Parameters
    ----------
    ds : xarray.Dataset
        A ping dataset (:func:`dataset_from_pings`, a simulation, an import).
    path : str or path-like
        ``.nc`` or ``.zarr``.
    split_complex : bool
        Store complex ``samples`` (the analytic signal) as the pair
        ``samples_r``, ``samples_i`` (docs/ping-format.md; CF has no complex type);
        ``False`` keeps one complex variable (netCDF-C's complex compound in
        NetCDF4, readable by both engines).

    Returns
    -------
    pathlib.Path
        ``path``.  The file has the global ``clbeam_format``, the CF and ACDD
        attributes (:func:`clbeam.io.conventions.discovery_attributes`, the
        time and area the pings cover) and every ping-file variable its units,
        long name and standard name where it had none.
    """
    p = Path(path)
    ds = with_cf_attributes(_split_samples(ds) if split_complex else ds.copy())
    ds.attrs[FORMAT_ATTRIBUTE] = PING_FORMAT
    if p.suffix == ".zarr":
        ds.to_zarr(p, mode="w")
    elif any(np.issubdtype(v.dtype, np.complexfloating) for v in ds.data_vars.values()):
        # the netCDF4 library's complex compound type (nc-complex), readable by both engines
        ds.to_netcdf(p, engine="netcdf4", auto_complex=True)
    else:
        ds.to_netcdf(p, engine="h5netcdf")
    return p


def _split_samples(ds: xr.Dataset) -> xr.Dataset:
    """``ds`` with complex ``samples`` as the pair ``samples_r``, ``samples_i`` (its ``kind`` on both)."""
    if "samples" not in ds.variables or not np.issubdtype(ds["samples"].dtype, np.complexfloating):
        return ds.copy()
    s = ds["samples"]
    kind = s.attrs.get("kind", "analytic")
    pair = {f"samples_{part}": (s.dims, getattr(s, attr).values, {**PING_VARIABLES[f"samples_{part}"].attrs(), "kind": kind})
            for part, attr in (("r", "real"), ("i", "imag"))}
    return ds.drop_vars("samples").assign(pair)


def with_cf_attributes(ds: xr.Dataset) -> xr.Dataset:
    """A copy of a ping dataset with the CF and ACDD attributes of a clbeam ping file.

    Every variable of :data:`clbeam.io.schema.PING_VARIABLES` gets the
    table's units, long name and standard name where it has none of its own
    (a time keeps the units xarray encodes it with); the ``ping`` coordinate a
    long name; the dataset the global attributes of
    :func:`clbeam.io.conventions.discovery_attributes` and
    :func:`clbeam.io.conventions.coverage_attributes`.

    Parameters
    ----------
    ds : xarray.Dataset
        A ping dataset.

    Returns
    -------
    xarray.Dataset
        The copy (the arrays shared, not copied).
    """
    ds = ds.copy()
    for name in ds.variables:
        spec = PING_VARIABLES.get(name)
        if spec is None:
            continue
        own = dict(ds[name].attrs)
        table = {k: v for k, v in spec.attrs().items()
                 if not (k == "units" and np.issubdtype(ds[name].dtype, np.datetime64))}
        ds[name].attrs = {**table, **own}
    if "ping" in ds.variables and "long_name" not in ds["ping"].attrs:
        ds["ping"].attrs["long_name"] = "ping number"
    def values(name: str, kind: str):
        ok = name in ds.variables and ds[name].dtype.kind == kind
        return ds[name].values if ok else None

    cover = coverage_attributes(values("ping_time", "M"), values("latitude", "f"), values("longitude", "f"))
    ds.attrs.update(discovery_attributes(ds.attrs, title="clbeam ping file",
                                         summary="Element-level time series of multibeam sub-bottom sonar pings with "
                                                 "their array geometry, motion, navigation and pulse (clbeam ping-1 "
                                                 "format).", history="ping file written"), **cover)
    return ds


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
    """The optional ping-file variables the pings carry: navigation, draft, times, channel mask, profile, responses."""
    values = {}
    for name, attr in (("pitch", "pitch_deg"), ("heading", "heading_deg"), ("latitude", "latitude_deg"),
                       ("longitude", "longitude_deg"), ("draft", "draft_m")):
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
    """One ping dataset (docs/ping-format.md) holding ``pings``.

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
