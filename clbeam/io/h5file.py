"""A light reader of plain NetCDF4 files through h5py, for fast start-up.

Opening a ping file through xarray costs about a second on a small machine
(xarray, pandas and dask imported, every variable CF-decoded).  The ping
reader needs little of that: variable names, dimensions, dtypes,
attributes, whole small arrays and one ping of samples.  :func:`open_plain`
gives exactly that for NetCDF4 files that need no decoding beyond what it
does itself (NaN fill values, xarray's ``dtype='bool'`` flag, complex
compounds, ``UNIT since DATE`` times in the standard calendar); for any
other file (packed or masked integers, other calendars, unknown filters,
NetCDF3) it returns ``None`` and the caller opens it with xarray, which
decodes everything the CF conventions allow.
"""

from __future__ import annotations

import re

import numpy as np

_NOT_A_VARIABLE = b"This is a netCDF dimension but not a netCDF variable"
_HIDDEN_ATTRS = {"DIMENSION_LIST", "REFERENCE_LIST", "CLASS", "NAME", "_Netcdf4Dimid", "_Netcdf4Coordinates",
                 "_NCProperties", "_FillValue", "dtype"}
_NEEDS_DECODING = {"scale_factor", "add_offset", "missing_value", "_Unsigned"}
_TIME_UNITS_NS = {"days": 86_400_000_000_000, "hours": 3_600_000_000_000, "minutes": 60_000_000_000,
                  "seconds": 1_000_000_000, "milliseconds": 1_000_000, "microseconds": 1_000, "nanoseconds": 1}
_STANDARD_CALENDARS = {"standard", "gregorian", "proleptic_gregorian"}
_TIME_UNITS = re.compile(r"^\s*(\w+)\s+since\s+(\d{4}-\d{2}-\d{2}(?:[ T]\d{2}:\d{2}(?::\d{2}(?:\.\d+)?)?)?)\s*$")


def _text(value):
    """An attribute as Python: bytes decoded, one-element arrays as scalars."""
    if isinstance(value, np.ndarray) and value.size == 1:
        value = value.reshape(-1)[0]
        value = value.item() if hasattr(value, "item") else value
    if isinstance(value, bytes | np.bytes_):
        return value.decode("utf-8", "replace")
    return value


def _time_decoder(attrs: dict):
    """A function turning stored numbers into datetime64[ns], ``None`` when the variable is no time,
    ``False`` when it is one this reader does not decode."""
    units = attrs.get("units")
    if not isinstance(units, str) or " since " not in units:
        return None
    m = _TIME_UNITS.match(units)
    calendar = str(attrs.get("calendar", "standard")).lower()
    if m is None or m.group(1).lower() not in _TIME_UNITS_NS or calendar not in _STANDARD_CALENDARS:
        return False
    step_ns = _TIME_UNITS_NS[m.group(1).lower()]
    origin = np.datetime64(m.group(2).replace(" ", "T"), "ns")

    def decode(values: np.ndarray) -> np.ndarray:
        if np.issubdtype(values.dtype, np.integer):
            offsets = values.astype(np.int64) * step_ns
            return origin + offsets.astype("timedelta64[ns]")
        v = values.astype(np.float64)
        offsets = np.round(np.where(np.isfinite(v), v, 0.0) * step_ns).astype(np.int64)
        return np.where(np.isfinite(v), origin + offsets.astype("timedelta64[ns]"), np.datetime64("NaT", "ns"))

    return decode


def _times_representable(variable: "PlainVariable") -> bool:
    """Whether the variable's times all fit datetime64[ns] (years 1678-2261) and decode without overflow:
    xarray turns the others into cftime objects (and the ping reader's dtype check explains)."""
    raw = np.asarray(variable._var[()])
    if raw.dtype.kind == "u":
        return False
    finite = raw[np.isfinite(raw)] if raw.dtype.kind == "f" else raw
    if finite.size == 0:
        return True
    units = _TIME_UNITS.match(variable.raw_units)
    step_ns = _TIME_UNITS_NS[units.group(1).lower()]
    origin_ns = 1e9 * float(np.datetime64(units.group(2).replace(" ", "T"), "s").astype(np.int64))
    extreme = origin_ns + np.array([finite.min(), finite.max()], dtype=np.float64) * step_ns
    return bool(np.all(np.abs(extreme) < 2.0 ** 63 * 0.999))


class PlainVariable:
    """One variable of a :class:`PlainDataset`: ``name``, ``dims``, ``dtype``, ``attrs``, ``values``
    and ``isel`` as on an :class:`xarray.DataArray`, read on demand."""

    def __init__(self, name: str, h5var, dims: tuple):
        self.name = name
        self._var = h5var
        self.dims = dims
        raw = {k: h5var.attrs[k] for k in h5var.attrs}
        self.attrs = {k: _text(v) for k, v in raw.items() if k not in _HIDDEN_ATTRS}
        self._bool = _text(raw.get("dtype")) == "bool"
        self._time = _time_decoder(self.attrs)
        self.raw_units = str(self.attrs.get("units", ""))
        if self._time is not None:
            for key in ("units", "calendar"):
                self.attrs.pop(key, None)
        stored = h5var.dtype.newbyteorder("=") if h5var.dtype.kind in "iufc" else h5var.dtype
        self.dtype = np.dtype(bool) if self._bool else (np.dtype("datetime64[ns]") if self._time else stored)

    def _decode(self, values) -> np.ndarray:
        values = np.asarray(values)
        if values.dtype.byteorder not in ("=", "|") and values.dtype.kind in "iufc":
            values = values.astype(values.dtype.newbyteorder("="))
        if self._bool:
            return values.astype(bool)
        return self._time(values) if self._time else values

    @property
    def values(self) -> np.ndarray:
        """The whole array, decoded."""
        return self._decode(self._var[()])

    def isel(self, **indexers) -> "_Selection":
        """The selection of integer positions along named dimensions (``.values`` reads it)."""
        index = tuple(indexers.pop(d, slice(None)) for d in self.dims)
        if indexers:
            raise KeyError(f"variable '{self.name}' has no dimension {next(iter(indexers))!r}")
        return _Selection(self, index)


class _Selection:
    def __init__(self, variable: PlainVariable, index: tuple):
        self._variable, self._index = variable, index

    @property
    def values(self) -> np.ndarray:
        return self._variable._decode(self._variable._var[self._index])


class PlainDataset:
    """The root group of a plain NetCDF4 file as much of an :class:`xarray.Dataset` as the ping
    reader uses: ``attrs``, ``sizes``, ``variables`` (names), ``ds[name]`` and ``close()``."""

    def __init__(self, h5file, variables: dict, sizes: dict):
        self._file = h5file
        self._variables = variables
        self.variables = tuple(variables)
        self.sizes = sizes
        self.attrs = {k: _text(h5file.attrs[k]) for k in h5file.attrs if k not in _HIDDEN_ATTRS}

    def __getitem__(self, name: str) -> PlainVariable:
        return self._variables[name]

    def close(self) -> None:
        """Close the file."""
        self._file.close()


def _dims(name: str, var) -> tuple | None:
    """A variable's dimension names from its dimension scales (``None`` when one is unnamed)."""
    if var.attrs.get("CLASS") == b"DIMENSION_SCALE":
        return (name,)
    dims = []
    for axis in var.dims:
        if len(axis) != 1:
            return None
        dims.append(axis[0].name.rsplit("/", 1)[-1])
    return tuple(dims)


def _plain(var) -> bool:
    """Whether h5py alone reads this variable as xarray would decode it."""
    import h5py

    keys = set(var.attrs)
    if keys & _NEEDS_DECODING:
        return False
    if "_FillValue" in keys:
        fill = np.asarray(var.attrs["_FillValue"])
        if not (fill.dtype.kind == "f" and np.all(np.isnan(fill))):
            return False
    plist = var.id.get_create_plist()
    filters = [plist.get_filter(k)[0] for k in range(plist.get_nfilters())]
    return var.dtype.kind in "biufcOS" and all(h5py.h5z.filter_avail(f) for f in filters)


def open_plain(path) -> PlainDataset | None:
    """``path`` as a :class:`PlainDataset`, or ``None`` when it is not HDF5, has groups in use or
    holds a variable that needs xarray's decoding."""
    import h5py

    try:
        f = h5py.File(path, "r")
    except OSError:
        return None
    try:
        variables, sizes = {}, {}
        for name, var in f.items():
            if isinstance(var, h5py.Datatype):  # a named type (complex numbers in NetCDF-4.9)
                continue
            if not isinstance(var, h5py.Dataset):
                return _close(f)
            if name.startswith("_nc4_non_coord_"):  # netCDF-C's name for a variable named like a dimension
                return _close(f)
            if var.attrs.get("CLASS") == b"DIMENSION_SCALE":
                if var.maxshape and var.maxshape[0] is None:
                    # unlimited: netCDF-C leaves a dimension without a variable at length 0 and variables may
                    # be shorter than the dimension (xarray pads them)
                    return _close(f)
                sizes[name] = int(var.shape[0])
                if bytes(var.attrs.get("NAME", b"")).startswith(_NOT_A_VARIABLE):
                    continue
            dims = _dims(name, var)
            if dims is None or not _plain(var):
                return _close(f)
            variable = PlainVariable(name, var, dims)
            if variable._time is False or (variable._time and not _times_representable(variable)):
                return _close(f)
            variables[name] = variable
        return PlainDataset(f, variables, sizes)
    except Exception:  # anything unexpected in the layout: xarray reads it or explains why not
        return _close(f)


def _close(f) -> None:
    f.close()
    return None
