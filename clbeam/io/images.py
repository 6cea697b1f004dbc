"""Image files (NetCDF4 or Zarr, SPEC §8).

Image files hold ``intensity(ping, angle, range)`` and ``cf(ping, angle,
range)`` (and, on request, the smoothed CF ``cf_smooth`` and the raw sums ``s_r``,
``s_i``, ``q``, ``m``, and ``w`` with apodization: :data:`clbeam.io.schema.IMAGE_VARIABLES`)
with coordinates ``range`` (m) and ``angle`` (degree).  They are written one
ping at a time straight into the file's chunks (one chunk per ping and
variable), so memory stays bounded whatever the count and nothing beyond
h5netcdf and zarr is needed.
"""

from __future__ import annotations

import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from clbeam.errors import ClbeamError, PingFileError, require
from clbeam.io.pingfile import open_dataset
from clbeam.io.schema import (
    FORMAT_ATTRIBUTE,
    IMAGE_COORDS,
    IMAGE_DIMS,
    IMAGE_DTYPES,
    IMAGE_FORMAT,
    IMAGE_PING_VARIABLES,
    IMAGE_VARIABLES,
)
from clbeam.model.grid import PolarGrid

if TYPE_CHECKING:
    import xarray as xr


def image_arrays(img) -> dict:
    """The arrays of one :class:`~clbeam.imaging.imager.PingImage` by variable
    name, in the dtypes of :data:`clbeam.io.schema.IMAGE_DTYPES`."""
    out = {}
    if img.intensity is not None:
        out["intensity"] = img.intensity
    if img.cf is not None:
        out["cf"] = img.cf
        out["cf_smooth"] = img.cf_smooth
    if img.sums is not None and img.sums.s is not None:
        out["s_r"] = img.sums.s.real
        out["s_i"] = img.sums.s.imag
        out["q"] = img.sums.q
        out["m"] = img.sums.m
        if img.sums.w is not None:
            out["w"] = img.sums.w
    return {k: np.asarray(v).astype(IMAGE_DTYPES[k], copy=False) for k, v in out.items()}


class ImageWriter:
    """Writes pings' images into one NetCDF4 (h5netcdf) or Zarr file.

    Parameters
    ----------
    path : path-like
        ``.nc`` (NetCDF4/HDF5) or ``.zarr``.
    grid : PolarGrid
        The grid every ping is imaged on.
    n_pings : int
        Pings the file will hold.
    variables : iterable of str
        Names from :data:`clbeam.io.schema.IMAGE_VARIABLES` to write.
    attrs : dict
        Global attributes (processing parameters).
    background : bool
        Create the file and write each ping in a worker thread while the
        caller images the next (at most one ping in flight; an error of the
        creation or a write is raised by the next :meth:`write` or by
        :meth:`close`).
    """

    def __init__(self, path, grid: PolarGrid, n_pings: int, variables, attrs: dict | None = None,
                 background: bool = False):
        self.path = Path(path)
        self.grid = grid
        self.n_pings = int(n_pings)
        unknown = sorted(set(variables) - set(IMAGE_VARIABLES))
        require(not unknown, ClbeamError, f"image variable '{unknown[0] if unknown else ''}' is unknown, "
                f"expected some of {', '.join(IMAGE_VARIABLES)}")
        self.variables = [v for v in IMAGE_VARIABLES if v in set(variables)]
        self.attrs = {FORMAT_ATTRIBUTE: IMAGE_FORMAT, **(attrs or {})}
        self._zarr = self.path.suffix == ".zarr"
        self._file = None
        self._sonar_written = False
        self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="clbeam-image-writer") if background else None
        self._pending = None
        if self._worker is None:
            self._create()
        else:  # created while the first ping is imaged; an error is raised by the first write or close
            self._pending = self._worker.submit(self._create)

    def _create(self) -> None:
        self._file = self._create_zarr() if self._zarr else self._create_netcdf()

    def _template(self):
        """Coordinates and per-ping variables (NaN until written), as an :class:`xarray.Dataset`."""
        import xarray as xr

        coords = {"ping": np.arange(self.n_pings)}
        for name, values in (("angle", self.grid.angles_deg), ("range", self.grid.ranges_m)):
            coords[name] = (name, values, IMAGE_COORDS[name].attrs())
        data = {name: (("ping",), np.full(self.n_pings, np.nan), var.attrs())
                for name, var in IMAGE_PING_VARIABLES.items()}
        return xr.Dataset(data, coords=coords, attrs=self.attrs)

    def _create_netcdf(self):
        """The file with its coordinates, per-ping variables and image variables, written through
        h5netcdf alone (xarray's writer costs half a second of imports at start-up)."""
        import h5netcdf

        n_a, n_r = self.grid.shape
        f = h5netcdf.File(self.path, "w")
        try:
            f.dimensions = {"ping": self.n_pings, "angle": n_a, "range": n_r}
            f.create_variable("ping", ("ping",), np.int64, data=np.arange(self.n_pings))
            for name, values in (("angle", self.grid.angles_deg), ("range", self.grid.ranges_m)):
                f.create_variable(name, (name,), np.float64, data=np.asarray(values, np.float64))
                f.variables[name].attrs.update(IMAGE_COORDS[name].attrs())
            for name, var in IMAGE_PING_VARIABLES.items():
                v = f.create_variable(name, ("ping",), np.float64, data=np.full(self.n_pings, np.nan), fillvalue=np.nan)
                v.attrs.update(var.attrs())
            f.attrs.update(self.attrs)
            for name in self.variables:
                # uncompressed: deflate shrinks these float images by under a fifth at about 1 s per variable and ping
                v = f.create_variable(name, IMAGE_DIMS, IMAGE_DTYPES[name], chunks=(1, n_a, n_r))
                v.attrs.update(IMAGE_VARIABLES[name].attrs())
        except Exception:
            f.close()
            raise
        return f

    def _create_zarr(self):
        import zarr

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # consolidated metadata is not in the Zarr v3 spec: zarr says so
            self._template().to_zarr(self.path, mode="w", consolidated=False)
            root = zarr.open_group(str(self.path), mode="a")
            n_a, n_r = self.grid.shape
            for name in self.variables:
                root.create_array(name, shape=(self.n_pings, n_a, n_r), chunks=(1, n_a, n_r),
                                  dtype=IMAGE_DTYPES[name], fill_value=0, dimension_names=IMAGE_DIMS,
                                  attributes=IMAGE_VARIABLES[name].attrs())
            zarr.consolidate_metadata(str(self.path))
        return zarr.open_group(str(self.path), mode="r+", use_consolidated=False)

    def write(self, index: int, img) -> None:
        """Write ping ``index``'s images, grid centre, source, sound speed and navigation.

        ``img`` is a :class:`~clbeam.imaging.imager.PingImage`; its
        ``context`` (a :class:`~clbeam.imaging.peaks.PingContext`) gives the
        per-ping values, and the first ping the file's pulse band, array
        width and imaging setting (global attributes ``pulse_band_hz``,
        ``array_width_m``, ``imaging_setting``: mode, upsampling, beams and
        predicted error).
        """
        if self._worker is None:
            self._write(index, img)
            return
        self._wait()
        self._pending = self._worker.submit(self._write, index, img)

    def _wait(self) -> None:
        """Wait for the ping in flight (raising its error)."""
        pending, self._pending = self._pending, None
        if pending is not None:
            pending.result()

    def _write(self, index: int, img) -> None:
        arrays = image_arrays(img)
        missing = [v for v in self.variables if v not in arrays]
        require(not missing, ClbeamError, f"ping {index}: the image lacks '{missing[0] if missing else ''}'")
        ctx = img.context
        source = ctx.source_yz_m or (np.nan, np.nan)
        meta = {"centre_y": ctx.centre_yz_m[0], "centre_z": ctx.centre_yz_m[1], "source_y": source[0],
                "source_z": source[1], "sound_speed": ctx.sound_speed_m_s, "latitude": ctx.latitude_deg,
                "longitude": ctx.longitude_deg, "heading": ctx.heading_deg, "n_channels": ctx.n_channels}
        target = self._file if self._zarr else self._file.variables
        for k in self.variables:
            target[k][index, :, :] = arrays[k]
        for k, v in meta.items():
            target[k][index] = np.nan if v is None else v
        if not self._sonar_written:
            self._file.attrs["pulse_band_hz"] = [float(b) for b in ctx.band_hz]
            self._file.attrs["array_width_m"] = float(ctx.array_width_m)
            if getattr(img, "setting", ""):
                self._file.attrs["imaging_setting"] = img.setting
            self._sonar_written = True

    def close(self) -> None:
        """Finish the ping in flight, flush and close the file (a Zarr store's metadata consolidated
        again: the first ping added attributes)."""
        try:
            self._wait()
        finally:
            if self._worker is not None:
                self._worker.shutdown(wait=True)
                self._worker = None
            self._close_file()

    def _close_file(self) -> None:
        if self._file is not None and not self._zarr:
            self._file.close()
        elif self._file is not None:
            import zarr

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # consolidated metadata is not in the Zarr v3 spec: zarr says so
                zarr.consolidate_metadata(str(self.path))
        self._file = None

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        try:
            self.close()
        except Exception:
            if exc_type is None:
                raise  # else the error in flight (the imaging's) is the one to report


def open_images(path) -> xr.Dataset:
    """Open an image file written by :class:`ImageWriter` (one-line errors)."""
    try:
        ds = open_dataset(path)
    except PingFileError as exc:
        raise ClbeamError(str(exc)) from None
    name = Path(path).name
    fmt = ds.attrs.get(FORMAT_ATTRIBUTE)
    require(fmt == IMAGE_FORMAT, ClbeamError, f"{name}: not a clbeam image file (global attribute "
            f"{FORMAT_ATTRIBUTE} is {fmt!r}, expected '{IMAGE_FORMAT}')")
    require("cf" in ds.variables, ClbeamError, f"{name}: missing variable 'cf' (image with --outputs including cf "
            "needed; a survey store holds images only when written with clbeam survey --images)")
    for v in IMAGE_COORDS:
        require(v in ds.coords, ClbeamError, f"{name}: missing coordinate '{v}'")
    return ds
