"""Image files (NetCDF4 or Zarr; docs/cli.md).

Image files hold ``intensity(ping, angle, range)`` and ``cf(ping, angle,
range)`` (and, on request, the smoothed CF ``cf_smooth`` and the raw sums ``s_r``,
``s_i``, ``q``, ``m``, and ``w`` with apodization: :data:`clbeam.io.schema.IMAGE_VARIABLES`)
with coordinates ``range`` (m) and ``angle`` (degree), and per ping its time,
grid centre, source, sound speed, navigation and draft
(:data:`clbeam.io.schema.IMAGE_PING_VARIABLES`).  They follow the CF and ACDD
conventions (:mod:`clbeam.io.conventions`).  They are written one ping at a
time straight into the file's chunks (one chunk per ping and variable), so
memory stays bounded whatever the count and nothing beyond h5netcdf and zarr
is needed.  :class:`ImageCompression` makes them smaller: deflate with
shuffle, and the coherence factor packed in 16 bits (CF §8.1).
"""

from __future__ import annotations

import logging
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from clbeam.errors import ClbeamError, OptionError, PingFileError, require
from clbeam.io.conventions import coverage_attributes, discovery_attributes, epoch_seconds
from clbeam.io.pingfile import open_dataset
from clbeam.io.schema import (
    FORMAT_ATTRIBUTE,
    IMAGE_COORDS,
    IMAGE_DIMS,
    IMAGE_DTYPES,
    IMAGE_FORMAT,
    IMAGE_PING_VARIABLES,
    IMAGE_VARIABLES,
    PACKABLE_IMAGE_VARIABLES,
)
from clbeam.model.grid import PolarGrid

if TYPE_CHECKING:
    import xarray as xr

log = logging.getLogger(__name__)

#: packed CF (CF §8.1): ``cf = q * CF_SCALE_FACTOR + CF_ADD_OFFSET`` with ``q`` in -32767..32767
CF_SCALE_FACTOR = np.float32(1.0 / 65534.0)
#: the offset of packed CF: exactly 0.5
CF_ADD_OFFSET = np.float32(0.5)
#: the stored value of packed CF in chunks no ping was written to (read as NaN)
CF_FILL = np.int16(-32768)


@dataclass(frozen=True)
class ImageCompression:
    """How an image file's arrays are stored.

    Attributes
    ----------
    level : int
        Deflate (zlib) level, 1 (fast) to 9 (small); 0: no deflate.
    shuffle : bool
        Byte-shuffle before deflate (groups the floats' exponent bytes:
        smaller files at the same level).
    pack_cf : bool
        Store ``cf`` and ``cf_smooth`` as 16-bit integers with
        ``scale_factor`` 1/65534 and ``add_offset`` 0.5 (CF §8.1), read
        back as float32 by any CF reader; the error is at most half a
        step, 7.7e-6, far below the 0.02 the coherence factor needs.
    """

    level: int = 4
    shuffle: bool = True
    pack_cf: bool = False

    def __post_init__(self):
        require(isinstance(self.level, int | np.integer) and 0 <= self.level <= 9, OptionError,
                f"the deflate level must be an integer from 0 (none) to 9, got {self.level!r}")


def pack_cf(values: np.ndarray) -> np.ndarray:
    """Coherence factors (0..1) as the int16 of a packed ``cf`` (values outside 0..1 clipped)."""
    v = np.clip(np.asarray(values, dtype=np.float64), 0.0, 1.0)
    return (np.rint(v * 65534.0) - 32767.0).astype(np.int16)


def _packing_attrs() -> dict:
    return {"scale_factor": CF_SCALE_FACTOR, "add_offset": CF_ADD_OFFSET}


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
        Global attributes (processing parameters; ``source_file`` names the
        ping file in the history).
    background : bool
        Create the file and write each ping in a worker thread while the
        caller images the next (at most one ping in flight; an error of the
        creation or a write is raised by the next :meth:`write` or by
        :meth:`close`).
    compression : ImageCompression, optional
        Deflate, shuffle and packed CF; default none (NetCDF) or Zarr's
        default codec (Zarr).
    time_variable : str
        Name of the per-ping time (``ping_time``; the survey store's is ``time``).
    """

    def __init__(self, path, grid: PolarGrid, n_pings: int, variables, attrs: dict | None = None,
                 background: bool = False, *, compression: ImageCompression | None = None,
                 time_variable: str = "ping_time"):
        self.path = Path(path)
        self.grid = grid
        self.n_pings = int(n_pings)
        unknown = sorted(set(variables) - set(IMAGE_VARIABLES))
        require(not unknown, ClbeamError, f"image variable '{unknown[0] if unknown else ''}' is unknown, "
                f"expected some of {', '.join(IMAGE_VARIABLES)}")
        self.variables = [v for v in IMAGE_VARIABLES if v in set(variables)]
        attrs = dict(attrs or {})
        history = "images" + (f" of {attrs['source_file']}" if attrs.get("source_file") else "")
        self.attrs = {FORMAT_ATTRIBUTE: IMAGE_FORMAT, **attrs,
                      **discovery_attributes(attrs, title="clbeam cross-track sonar images", history=history,
                                             summary="Cross-track images of multibeam sub-bottom sonar pings: "
                                                     "intensity and coherence factor on a polar grid (range, "
                                                     "angle from nadir) per ping (Holland et al. 2024).")}
        self.compression = compression
        self.time_variable = str(time_variable)
        self._packed = {v for v in self.variables if compression is not None and compression.pack_cf
                        and v in PACKABLE_IMAGE_VARIABLES}
        self._zarr = self.path.suffix == ".zarr"
        self._file = None
        self._sonar_written = False
        self._warned_draft = False
        self._coverage = {"time": np.full(self.n_pings, np.datetime64("NaT", "ns")),
                          "lat": np.full(self.n_pings, np.nan), "lon": np.full(self.n_pings, np.nan)}
        self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="clbeam-image-writer") if background else None
        self._pending = None
        if self._worker is None:
            self._create()
        else:  # created while the first ping is imaged; an error is raised by the first write or close
            self._pending = self._worker.submit(self._create)

    def _create(self) -> None:
        self._file = self._create_zarr() if self._zarr else self._create_netcdf()

    def _ping_variables(self) -> dict:
        """:data:`IMAGE_PING_VARIABLES` by the name they get in this file (the time's may differ)."""
        return {(self.time_variable if name == "ping_time" else name): var for name, var in IMAGE_PING_VARIABLES.items()}

    def _array_attrs(self, name: str) -> dict:
        """The CF attributes of image array ``name``: the table's, its auxiliary coordinates, its packing."""
        out = {**IMAGE_VARIABLES[name].attrs(), "coordinates": f"{self.time_variable} latitude longitude"}
        if name in self._packed:
            out.update(_packing_attrs())
        return out

    def _dtype(self, name: str):
        return np.int16 if name in self._packed else IMAGE_DTYPES[name]

    def _template(self):
        """Coordinates and per-ping variables (NaN until written), as an :class:`xarray.Dataset`."""
        import xarray as xr

        coords = {"ping": ("ping", np.arange(self.n_pings), {"long_name": "ping number"})}
        for name, values in (("angle", self.grid.angles_deg), ("range", self.grid.ranges_m)):
            coords[name] = (name, values, IMAGE_COORDS[name].attrs())
        data = {name: (("ping",), np.full(self.n_pings, np.nan), var.attrs())
                for name, var in self._ping_variables().items()}
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
            f.variables["ping"].attrs["long_name"] = "ping number"
            for name, values in (("angle", self.grid.angles_deg), ("range", self.grid.ranges_m)):
                f.create_variable(name, (name,), np.float64, data=np.asarray(values, np.float64))
                f.variables[name].attrs.update(IMAGE_COORDS[name].attrs())
            for name, var in self._ping_variables().items():
                v = f.create_variable(name, ("ping",), np.float64, data=np.full(self.n_pings, np.nan), fillvalue=np.nan)
                v.attrs.update(var.attrs())
            f.attrs.update(self.attrs)
            c = self.compression
            deflate = {"compression": "gzip", "compression_opts": c.level, "shuffle": c.shuffle} \
                if c is not None and c.level > 0 else {}
            for name in self.variables:
                fill = {"fillvalue": CF_FILL} if name in self._packed else {}
                v = f.create_variable(name, IMAGE_DIMS, self._dtype(name), chunks=(1, n_a, n_r), **deflate, **fill)
                v.attrs.update(self._array_attrs(name))
        except Exception:
            f.close()
            raise
        return f

    def _zarr_codecs(self) -> dict:
        """``compressors`` of the image arrays: Blosc's zlib with shuffle (ImageCompression), else Zarr's default."""
        c = self.compression
        if c is None:
            return {}
        if c.level == 0:
            return {"compressors": None}
        from zarr.codecs import BloscCodec

        return {"compressors": BloscCodec(cname="zlib", clevel=c.level, shuffle="shuffle" if c.shuffle else "noshuffle")}

    def _create_zarr(self):
        import zarr

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # consolidated metadata is not in the Zarr v3 spec: zarr says so
            # CF §2.5.1: coordinate variables have no fill value (xarray would give the floats one)
            self._template().to_zarr(self.path, mode="w", consolidated=False,
                                     encoding={c: {"_FillValue": None} for c in ("angle", "range")})
            root = zarr.open_group(str(self.path), mode="a")
            n_a, n_r = self.grid.shape
            for name in self.variables:
                packed = name in self._packed
                attributes = self._array_attrs(name)
                if packed:  # JSON numbers: a CF reader unpacks a Zarr store's CF as float64
                    attributes.update(scale_factor=1.0 / 65534.0, add_offset=0.5, _FillValue=int(CF_FILL))
                root.create_array(name, shape=(self.n_pings, n_a, n_r), chunks=(1, n_a, n_r),
                                  dtype=self._dtype(name), fill_value=CF_FILL if packed else 0,
                                  dimension_names=IMAGE_DIMS, attributes=attributes, **self._zarr_codecs())
            zarr.consolidate_metadata(str(self.path))
        return zarr.open_group(str(self.path), mode="r+", use_consolidated=False)

    def write(self, index: int, img) -> None:
        """Write ping ``index``'s images, time, grid centre, source, sound speed, navigation and draft.

        ``img`` is a :class:`~clbeam.imaging.imager.PingImage`; its
        ``context`` (a :class:`~clbeam.imaging.peaks.PingContext`) gives the
        per-ping values, and the first ping the file's pulse band, array
        width and imaging setting (global attributes ``pulse_band_hz``,
        ``array_width_m``, ``imaging_setting``: mode, upsampling, beams and
        predicted error).  A ping without a draft is written with draft 0 m
        (the transducers at the sea surface), with one warning per file.
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

    def _draft(self, ctx) -> float:
        draft = getattr(ctx, "draft_m", None)
        if draft is not None:
            return float(draft)
        if not self._warned_draft:
            log.warning("%s: the ping file gives no draft: depths below the sea surface take the array reference "
                        "point at the surface (draft 0 m)", self.path.name)
            self._warned_draft = True
        return 0.0

    def _ping_values(self, index: int, ctx) -> dict:
        """The per-ping variables of ping ``index`` from its context (``None``: unknown)."""
        source = ctx.source_yz_m or (np.nan, np.nan)
        time = getattr(ctx, "time", None)
        if 0 <= index < self.n_pings:
            self._coverage["time"][index] = np.datetime64("NaT", "ns") if time is None else time
            self._coverage["lat"][index] = np.nan if ctx.latitude_deg is None else ctx.latitude_deg
            self._coverage["lon"][index] = np.nan if ctx.longitude_deg is None else ctx.longitude_deg
        return {self.time_variable: epoch_seconds(time), "centre_y": ctx.centre_yz_m[0],
                "centre_z": ctx.centre_yz_m[1], "source_y": source[0], "source_z": source[1],
                "sound_speed": ctx.sound_speed_m_s, "latitude": ctx.latitude_deg, "longitude": ctx.longitude_deg,
                "heading": ctx.heading_deg, "n_channels": ctx.n_channels, "draft": self._draft(ctx)}

    def _write(self, index: int, img) -> None:
        arrays = image_arrays(img)
        missing = [v for v in self.variables if v not in arrays]
        require(not missing, ClbeamError, f"ping {index}: the image lacks '{missing[0] if missing else ''}'")
        ctx = img.context
        meta = self._ping_values(index, ctx)
        target = self._file if self._zarr else self._file.variables
        for k in self.variables:
            target[k][index, :, :] = pack_cf(arrays[k]) if k in self._packed else arrays[k]
        for k, v in meta.items():
            target[k][index] = np.nan if v is None else v
        if not self._sonar_written:
            self._file.attrs["pulse_band_hz"] = [float(b) for b in ctx.band_hz]
            self._file.attrs["array_width_m"] = float(ctx.array_width_m)
            if getattr(img, "setting", ""):
                self._file.attrs["imaging_setting"] = img.setting
            self._sonar_written = True

    def close(self) -> None:
        """Finish the ping in flight, write the time and area covered, flush and close the file (a Zarr
        store's metadata consolidated again: the pings added attributes)."""
        try:
            self._wait()
        finally:
            if self._worker is not None:
                self._worker.shutdown(wait=True)
                self._worker = None
            self._close_file()

    def _close_file(self) -> None:
        if self._file is None:
            return
        cov = coverage_attributes(self._coverage["time"], self._coverage["lat"], self._coverage["lon"])
        try:
            if cov:
                self._file.attrs.update(cov)
        finally:
            if not self._zarr:
                self._file.close()
            else:
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
