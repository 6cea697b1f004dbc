"""Image files (NetCDF4 or Zarr, SPEC §8) and peak tables (CSV).

Image files hold ``intensity(ping, angle, range)`` and ``cf(ping, angle,
range)`` (plus ``cf_smooth`` and, on request, the raw sums ``s_r``, ``s_i``,
``q``, ``m``, and ``w`` with apodization) with coordinates ``range`` (m) and ``angle`` (degree).  They
are written one ping at a time, so memory stays bounded whatever the count.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

import numpy as np
import xarray as xr

from clbeam.errors import ClbeamError, PingFileError, require
from clbeam.model.grid import PolarGrid

PEAK_COLUMNS = ("ping", "range_m", "angle_deg", "y_m", "z_m", "cf", "intensity_db")

IMAGE_FORMAT = "images-1"

VARIABLES = {
    "intensity": ("intensity |S|^2 (Holland et al. 2024 eq. 1)", "squared input units"),
    "cf": ("coherence factor |S|^2 / (M Q); |S|^2 / (W Q) with apodization", "1"),
    "cf_smooth": ("coherence factor, 7-point Hann smoothed along range", "1"),
    "s_r": ("coherent sum S = sum w p, real part", "input units"),
    "s_i": ("coherent sum S, imaginary part", "input units"),
    "q": ("incoherent sum Q = sum w |p|^2 (w = 1 without apodization)", "squared input units"),
    "m": ("number of contributing channels M", "1"),
    "w": ("sum W of the contributing channels' apodization weights", "1"),
}


def image_arrays(img) -> dict:
    """The arrays of one :class:`~clbeam.imaging.imager.PingImage` by variable name."""
    out = {}
    if img.intensity is not None:
        out["intensity"] = img.intensity.astype(np.float32)
    if img.cf is not None:
        out["cf"] = img.cf.astype(np.float32)
        out["cf_smooth"] = img.cf_smooth.astype(np.float32)
    if img.sums is not None and img.sums.s is not None:
        out["s_r"] = img.sums.s.real.astype(np.float32)
        out["s_i"] = img.sums.s.imag.astype(np.float32)
        out["q"] = img.sums.q.astype(np.float32)
        out["m"] = img.sums.m.astype(np.int16)
        if img.sums.w is not None:
            out["w"] = img.sums.w.astype(np.float32)
    return out


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
        Names from :data:`VARIABLES` to write.
    attrs : dict
        Global attributes (processing parameters).
    """

    def __init__(self, path, grid: PolarGrid, n_pings: int, variables, attrs: dict | None = None):
        self.path = Path(path)
        self.grid = grid
        self.n_pings = n_pings
        self.variables = [v for v in VARIABLES if v in set(variables)]
        n_a, n_r = grid.shape
        coords = {
            "ping": np.arange(n_pings),
            "angle": ("angle", grid.angles_deg, {"units": "degree", "long_name": "angle from nadir, positive to starboard"}),
            "range": ("range", grid.ranges_m, {"units": "m", "long_name": "range from the grid centre"}),
        }
        per_ping = {
            "centre_y": ("grid centre y (earth frame, starboard)", "m"),
            "centre_z": ("grid centre z (earth frame, down)", "m"),
            "latitude": ("latitude of the ping", "degree_north"),
            "longitude": ("longitude of the ping", "degree_east"),
            "heading": ("heading of the ping", "degree"),
        }
        data_vars = {}
        for name in self.variables:
            long_name, units = VARIABLES[name]
            dtype = np.int16 if name == "m" else np.float32
            data_vars[name] = (("ping", "angle", "range"), _lazy_zeros((n_pings, n_a, n_r), dtype),
                               {"long_name": long_name, "units": units})
        for name, (long_name, units) in per_ping.items():
            data_vars[name] = (("ping",), np.full(n_pings, np.nan), {"long_name": long_name, "units": units})
        ds = xr.Dataset(data_vars, coords=coords, attrs={"clbeam_format": IMAGE_FORMAT, **(attrs or {})})
        self._zarr = self.path.suffix == ".zarr"
        if self._zarr:
            enc = {v: {"chunks": (1, n_a, n_r)} for v in self.variables}
            ds.to_zarr(self.path, mode="w", compute=False, encoding=enc)
            self._file = None
        else:
            import h5netcdf

            enc = {v: {"chunksizes": (1, n_a, n_r), "zlib": True, "complevel": 1} for v in self.variables}
            ds.to_netcdf(self.path, engine="h5netcdf", encoding=enc, compute=False)
            self._file = h5netcdf.File(self.path, "a")

    def write(self, index: int, img, *, latitude=None, longitude=None, heading=None) -> None:
        """Write ping ``index``'s images and its grid centre / navigation."""
        arrays = image_arrays(img)
        meta = {"centre_y": img.source_yz_m[0], "centre_z": img.source_yz_m[1],
                "latitude": latitude, "longitude": longitude, "heading": heading}
        if self._zarr:
            dvars = {k: (("ping", "angle", "range"), arrays[k][None]) for k in self.variables}
            dvars.update({k: (("ping",), np.array([np.nan if v is None else v], dtype=np.float64)) for k, v in meta.items()})
            xr.Dataset(dvars).to_zarr(self.path, region={"ping": slice(index, index + 1)})
        else:
            for k in self.variables:
                self._file.variables[k][index, :, :] = arrays[k]
            for k, v in meta.items():
                self._file.variables[k][index] = np.nan if v is None else v

    def close(self) -> None:
        """Flush and close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _lazy_zeros(shape, dtype):
    import dask.array as da

    return da.zeros(shape, dtype=dtype, chunks=(1,) + tuple(shape[1:]))


def open_images(path) -> xr.Dataset:
    """Open an image file written by :class:`ImageWriter` (one-line errors)."""
    from clbeam.io.pingfile import open_dataset

    try:
        ds = open_dataset(path)
    except PingFileError as exc:
        raise ClbeamError(str(exc)) from None
    name = Path(path).name
    require(ds.attrs.get("clbeam_format") == IMAGE_FORMAT, ClbeamError,
            f"{name}: not a clbeam image file (global attribute clbeam_format is {ds.attrs.get('clbeam_format')!r}, expected '{IMAGE_FORMAT}')")
    require("cf" in ds.variables, ClbeamError, f"{name}: missing variable 'cf' (image with --outputs including cf needed)")
    for v in ("angle", "range"):
        require(v in ds.coords, ClbeamError, f"{name}: missing coordinate '{v}'")
    return ds


def write_peaks_csv(rows: list, path: str | os.PathLike) -> Path:
    """Write peak rows to CSV: :data:`PEAK_COLUMNS` first, then any extra columns."""
    p = Path(path)
    extra = sorted({k for r in rows for k in r} - set(PEAK_COLUMNS))
    cols = list(PEAK_COLUMNS) + extra
    with open(p, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=cols, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            # 10 significant digits: latitudes to the centimetre, eastings to the millimetre
            w.writerow({k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in r.items()})
    return p


def read_peaks_csv(path: str | os.PathLike) -> list:
    """Read a peaks CSV back into rows of floats (``ping`` as int)."""
    with open(path, newline="") as fh:
        return [{k: (int(v) if k == "ping" else float(v)) for k, v in r.items() if v != ""} for r in csv.DictReader(fh)]
