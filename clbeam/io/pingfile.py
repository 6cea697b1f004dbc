"""Ping files (docs/ping-format.md): validation and a streaming reader, from disk or memory.

A :class:`PingFile` opens a NetCDF4 (HDF5) or Zarr ping file lazily, checks
every variable once against :data:`clbeam.io.schema.PING_VARIABLES` and then
hands out one :class:`~clbeam.model.ping.Ping` at a time, so files larger
than memory stream.  :func:`pings_from_dataset` does the same for a dataset
in memory (a simulation, a conversion), with the same checks.  Every
problem is a :class:`PingFileError` whose one-line message names the file,
the variable and what was expected.  Writing is :mod:`clbeam.io.pingwrite`.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from clbeam.constants import (
    MAX_ABS_GAIN_DB,
    MAX_ABS_ROLL_DEG,
    MAX_OFFSET_M,
    WATER_SPEED_RANGE_M_S,
)
from clbeam.errors import ClbeamError, PingFileError, require
from clbeam.io.schema import FORMAT_ATTRIBUTE, PING_FORMAT, PING_VARIABLES
from clbeam.model.ping import Ping
from clbeam.model.pulse import Pulse
from clbeam.model.svp import SoundSpeedProfile

if TYPE_CHECKING:
    import xarray as xr

log = logging.getLogger(__name__)


def open_dataset(path: str | os.PathLike) -> xr.Dataset:
    """Open a NetCDF4/HDF5 or Zarr file lazily as an :class:`xarray.Dataset`."""
    import xarray as xr

    p = Path(path)
    require(p.exists(), PingFileError, f"{p}: no such file")
    if p.is_dir() or p.suffix == ".zarr":
        try:
            return xr.open_zarr(p, consolidated=None)
        except Exception as exc:  # zarr raises many types for a bad store
            raise PingFileError(f"{p}: not a readable Zarr store ({type(exc).__name__}: {exc})") from None
    require(p.stat().st_size > 0, PingFileError, f"{p}: file is empty")
    errors = []
    for engine, kwargs in (("h5netcdf", {}), ("netcdf4", {"auto_complex": True})):
        try:
            return xr.open_dataset(p, engine=engine, **kwargs)
        except Exception as exc:  # try the next engine (NetCDF3 files need netcdf4)
            errors.append(f"{type(exc).__name__}: {exc}")
    raise PingFileError(f"{p}: not a readable NetCDF4/HDF5 file ({errors[-1].splitlines()[0]})")


class PingDataset:
    """A validated ping dataset (docs/ping-format.md) read one ping at a time.

    Parameters
    ----------
    ds : xarray.Dataset
        The dataset (lazily opened or in memory).
    name : str
        Name used in error messages (the file name).

    Attributes
    ----------
    n_pings, n_channels, n_samples : int
        Sizes of the ``ping``, ``channel`` and ``sample`` dimensions.
    kind : str
        ``"raw"`` or ``"analytic"``.
    sample_rate_hz : float
        Sample rate (Hz).
    pulse : Pulse or None
        Transmit pulse (required for raw samples).
    """

    def __init__(self, ds: xr.Dataset, name: str = "dataset"):
        self.ds = ds
        self.name = name
        self._validate()

    def __len__(self) -> int:
        return self.n_pings

    def __iter__(self):
        for i in range(self.n_pings):
            yield self.ping(i)

    def close(self) -> None:
        """Close the underlying dataset."""
        self.ds.close()

    # -- helpers of the checks --------------------------------------------------
    def _err(self, message: str) -> PingFileError:
        return PingFileError(f"{self.name}: {message}")

    def _need(self, cond: bool, message: str) -> None:
        if not cond:
            raise self._err(message)

    def _var(self, name: str, *, required: bool | None = None):
        """The variable ``name`` with its dimensions checked against the schema
        (``None`` when it is optional and absent)."""
        spec = PING_VARIABLES[name]
        if name not in self.ds.variables:
            self._need(not (spec.required if required is None else required),
                       f"missing variable '{name}' (see docs/ping-format.md)")
            return None
        v = self.ds[name]
        self._need(v.dims in spec.dims,
                   f"variable '{name}' has dimensions {v.dims}, expected " + " or ".join(str(d) for d in spec.dims))
        return v

    def _numeric(self, name: str, v: xr.DataArray, *, finite: bool = True) -> np.ndarray:
        self._need(np.issubdtype(v.dtype, np.number) and not np.issubdtype(v.dtype, np.complexfloating),
                   f"variable '{name}' has dtype {v.dtype}, expected a real number type")
        a = np.asarray(v.values, dtype=np.float64)
        if finite:
            bad = ~np.isfinite(a)
            self._need(not bad.any(), f"variable '{name}' has {int(bad.sum())} non-finite value(s)")
        return a

    def _real(self, name: str, *, required: bool | None = None) -> np.ndarray | None:
        v = self._var(name, required=required)
        return None if v is None else self._numeric(name, v)

    # -- the checks, one group of variables each ----------------------------------
    def _validate(self) -> None:
        fmt = self.ds.attrs.get(FORMAT_ATTRIBUTE)
        self._need(fmt is not None, f"global attribute '{FORMAT_ATTRIBUTE}' is missing, expected '{PING_FORMAT}'")
        self._need(str(fmt) == PING_FORMAT, f"global attribute '{FORMAT_ATTRIBUTE}' is '{fmt}', expected '{PING_FORMAT}'")
        self._read_layout()
        self._read_sampling()
        self._read_geometry()
        self._read_motion()
        self.pulse = self._read_pulse()
        self._need(self.kind == "analytic" or self.pulse is not None,
                   "missing pulse description: 'pulse_f0', 'pulse_f1', 'pulse_duration' or 'tx_waveform' (needed for kind='raw')")
        self.svp = self._read_svp()
        self.element_gain_db = self._channel_response("element_gain_db", MAX_ABS_GAIN_DB)
        self.element_phase_deg = self._channel_response("element_phase_deg", None)
        self._read_channel_mask()

    def _read_layout(self) -> None:
        """Samples: complex, real, or the ``(samples_r, samples_i)`` pair; the sizes."""
        ds = self.ds
        if "samples" in ds.variables:
            s = self._var("samples", required=True)
            self._split = False
        elif "samples_r" in ds.variables or "samples_i" in ds.variables:
            s = self._var("samples_r", required=True)
            si = self._var("samples_i", required=True)
            self._need(s.dtype == si.dtype, f"'samples_r' ({s.dtype}) and 'samples_i' ({si.dtype}) must share a dtype")
            self._split = True
        else:
            raise self._err("missing variable 'samples' (or the pair 'samples_r', 'samples_i') (see docs/ping-format.md)")
        self._need(np.issubdtype(s.dtype, np.number), f"variable '{s.name}' has dtype {s.dtype}, expected numbers")
        self.kind = self._read_kind(s)
        is_complex = np.issubdtype(s.dtype, np.complexfloating) or self._split
        self._need(not (self.kind == "raw" and is_complex),
                   f"variable '{s.name}' is complex but kind='raw'; raw pressure must be real (set kind='analytic' "
                   "if it is the pulse-compressed analytic signal)")
        self._need(not (self.kind == "analytic" and not is_complex),
                   f"variable '{s.name}' has kind='analytic' but is real; store it complex or as 'samples_r'/'samples_i'")
        self.n_pings, self.n_channels, self.n_samples = (int(ds.sizes[d]) for d in ("ping", "channel", "sample"))
        self._need(self.n_pings > 0, "contains no pings (dimension 'ping' has length 0)")
        self._need(self.n_channels > 0, "has no channels (dimension 'channel' has length 0)")
        self._need(self.n_samples > 1, f"has {self.n_samples} sample(s) per channel, expected at least 2")

    def _read_kind(self, s) -> str:
        """``kind`` of the samples: on ``samples`` (or the dataset), default raw; a ``samples_r``/``samples_i``
        pair is analytic, ``kind`` on either half or the dataset may say so and nothing else."""
        ds = self.ds
        places = [(f"variable '{v}'", ds[v].attrs["kind"]) for v in
                  (("samples_r", "samples_i") if self._split else ("samples",)) if "kind" in ds[v].attrs]
        if "kind" in ds.attrs:
            places.append(("the dataset", ds.attrs["kind"]))
        for where, kind in places:
            self._need(str(kind) in ("raw", "analytic"), f"{where} has kind='{kind}', expected 'raw' or 'analytic'")
        kinds = {str(k) for _, k in places}
        if self._split:
            raw = [where for where, k in places if str(k) == "raw"]
            self._need(not raw, f"the pair 'samples_r'/'samples_i' is the analytic signal (see docs/ping-format.md) but "
                       f"{raw[0] if raw else ''} has kind='raw': store raw pressure as one real 'samples', or set "
                       "kind='analytic'")
            return "analytic"
        self._need(len(kinds) <= 1, f"variable '{s.name}' and the dataset disagree on kind ({' and '.join(sorted(kinds))})")
        return kinds.pop() if kinds else "raw"

    def _read_sampling(self) -> None:
        """Sample rate, ``t0`` and sound speed."""
        fs = float(self._real("sample_rate"))
        self._need(fs > 0, f"variable 'sample_rate' is {fs:g} Hz, expected > 0")
        self.sample_rate_hz = fs
        self._t0 = self._real("t0")
        self._need(bool(np.all(self._t0 >= 0)), f"variable 't0' has negative values (min {self._t0.min():g} s), expected >= 0")
        c = self._real("sound_speed")
        lo, hi = WATER_SPEED_RANGE_M_S
        self._need(bool(np.all((c >= lo) & (c <= hi))),
                   f"variable 'sound_speed' has values in [{c.min():g}, {c.max():g}] m/s, expected within {lo:g}-{hi:g} m/s")
        self._c = c

    def _read_geometry(self) -> None:
        """Element and source positions (vessel frame)."""
        ey, ez = self._real("element_y"), self._real("element_z")
        ex = self._real("element_x")
        self.element_pos_m = np.stack([np.zeros_like(ey) if ex is None else ex, ey, ez], axis=-1)
        uniq = np.unique(np.round(self.element_pos_m, 9), axis=0)
        self._need(uniq.shape[0] == self.n_channels,
                   f"element positions are duplicated ({self.n_channels - uniq.shape[0]} repeated), expected distinct elements")
        src = [self._real(name) for name in ("source_x", "source_y", "source_z")]
        self.source_pos_m = np.array([0.0 if v is None else float(v) for v in src])
        for name, pos in (("element", self.element_pos_m), ("source", self.source_pos_m)):
            reach = float(np.max(np.abs(pos)))
            self._need(reach <= MAX_OFFSET_M, f"{name} positions reach {reach:g} m from the reference point, "
                       f"expected within {MAX_OFFSET_M:g} m (a hull-mounted array)")

    def _read_motion(self) -> None:
        """Roll, heave, pitch, heading, navigation, draft and ping times."""
        self._roll = self._per_ping("roll", 0.0)
        self._need(bool(np.all(np.abs(self._roll) <= MAX_ABS_ROLL_DEG)),
                   f"variable 'roll' reaches {np.abs(self._roll).max():g} degrees, expected within ±{MAX_ABS_ROLL_DEG:g}")
        self._heave = self._per_ping("heave", 0.0)
        self._pitch = self._per_ping("pitch", None)
        self._heading = self._per_ping("heading", None)
        self._lat = self._per_ping("latitude", None)
        self._lon = self._per_ping("longitude", None)
        if self._lat is not None:
            self._need(bool(np.all(np.abs(self._lat) <= 90)), "variable 'latitude' is outside ±90 degrees")
        self._draft = self._per_ping("draft", None)
        if self._draft is not None:
            self._need(bool(np.all(self._draft >= 0)), f"variable 'draft' reaches {self._draft.min():g} m, expected "
                       "the depth below the sea surface (>= 0 m)")
        self._warn_defaults()
        self._time = None
        tv = self._var("ping_time")
        if tv is not None:
            self._need(np.issubdtype(tv.dtype, np.datetime64), f"variable 'ping_time' has dtype {tv.dtype}, expected datetime64")
            self._time = tv.values

    def _warn_defaults(self) -> None:
        """One warning for each optional variable whose absence changes the products: roll, navigation."""
        if "roll" not in self.ds.variables:
            log.warning("%s: no variable 'roll': the pings are imaged without roll correction (roll 0 degrees)",
                        self.name)
        missing = [n for n in ("latitude", "longitude") if n not in self.ds.variables]
        if missing:
            log.warning("%s: no variable %s: the pings have no position (the peaks' "
                        "ping_latitude_deg and peak_latitude_deg, ..._longitude_deg are empty; a survey places them by "
                        "ping time and --speed)",
                        self.name, " or ".join(f"'{n}'" for n in missing))

    def _per_ping(self, name: str, default):
        a = self._real(name)
        if a is None:
            return None if default is None else np.full(self.n_pings, default, dtype=np.float64)
        return np.broadcast_to(a, (self.n_pings,))

    def _read_pulse(self) -> Pulse | None:
        d = self._real("tx_delay")
        self._need(d is None or (d.size == 1 and bool(np.isfinite(d).all())),
                   "variable 'tx_delay' must be one finite number of seconds")
        delay = 0.0 if d is None else float(d.reshape(-1)[0])
        w = self._real("tx_waveform")
        if w is not None:
            self._need(w.size > 0 and float(np.dot(w, w)) > 0, "variable 'tx_waveform' is empty or all zero")
            self._need(w.size <= self.n_samples, f"variable 'tx_waveform' has {w.size} samples, more than the "
                       f"record's {self.n_samples}")
            return Pulse(waveform=w, delay_s=delay)
        names = ("pulse_f0", "pulse_f1", "pulse_duration")
        present = [n for n in names if n in self.ds.variables]
        if not present:
            return None
        missing = [n for n in names if n not in self.ds.variables]
        self._need(not missing, f"missing variable '{missing[0]}' (the LFM pulse needs {', '.join(names)})" if missing else "")
        f0, f1, dur = (float(self._real(n)) for n in names)
        nyq = self.sample_rate_hz / 2
        record_s = self.n_samples / self.sample_rate_hz
        self._need(0 < dur <= record_s, f"variable 'pulse_duration' is {dur:g} s, expected > 0 and no longer "
                   f"than the record ({record_s:g} s)")
        self._need(0 <= min(f0, f1) and max(f0, f1) < nyq,
                   f"pulse band {f0:g}-{f1:g} Hz must lie within 0-{nyq:g} Hz (half the sample rate)")
        return Pulse(f0_hz=f0, f1_hz=f1, duration_s=dur, delay_s=delay)

    def _read_svp(self) -> SoundSpeedProfile | None:
        present = [n for n in ("svp_depth", "svp_speed") if n in self.ds.variables]
        if not present:
            return None
        self._need(len(present) == 2, f"variable '{present[0]}' needs its partner "
                   f"'{'svp_speed' if present[0] == 'svp_depth' else 'svp_depth'}' (sound-speed profile)")
        depth, speed = self._real("svp_depth"), self._real("svp_speed")
        try:
            return SoundSpeedProfile(depth, speed)
        except ClbeamError as exc:
            raise self._err(f"sound-speed profile 'svp_depth'/'svp_speed': {exc}") from None

    def _channel_response(self, name: str, limit: float | None) -> np.ndarray | None:
        a = self._real(name)
        if a is not None and limit is not None:
            self._need(bool(np.all(np.abs(a) <= limit)),
                       f"variable '{name}' reaches {np.abs(a).max():g}, expected within ±{limit:g}")
        return a

    def _read_channel_mask(self) -> None:
        self._valid = np.ones(self.n_channels, dtype=bool)
        self._valid_per_ping = None
        v = self._var("channel_valid")
        if v is None:
            return
        self._need(v.dtype == bool or np.issubdtype(v.dtype, np.integer),
                   f"variable 'channel_valid' has dtype {v.dtype}, expected bool")
        if v.dims == ("channel",):
            self._valid = np.asarray(v.values).astype(bool)
        else:
            self._valid_per_ping = v

    # -- reading ------------------------------------------------------------------
    def max_record_range_m(self) -> float:
        """Largest one-way range (m) any ping's record reaches: ``c (t0 + n / fs) / 2``."""
        t_end = float(np.max(self._t0)) + self.n_samples / self.sample_rate_hz
        return 0.5 * float(np.max(self._c)) * t_end

    def _samples(self, i: int) -> np.ndarray:
        ds = self.ds
        if self._split:
            re = np.asarray(ds["samples_r"].isel(ping=i).values)
            im = np.asarray(ds["samples_i"].isel(ping=i).values)
            return (re + 1j * im).astype(np.complex128 if re.dtype == np.float64 else np.complex64)
        return np.asarray(ds["samples"].isel(ping=i).values)

    def ping(self, i: int) -> Ping:
        """Read ping ``i`` (0-based)."""
        require(0 <= i < self.n_pings, PingFileError, f"{self.name}: ping {i} out of range 0..{self.n_pings - 1}")
        valid = self._valid
        if self._valid_per_ping is not None:
            valid = np.asarray(self._valid_per_ping.isel(ping=i).values).astype(bool)

        def at(a):
            return None if a is None else float(a[i])

        return Ping(
            samples=self._samples(i), kind=self.kind, sample_rate_hz=self.sample_rate_hz,
            t0_s=float(np.broadcast_to(self._t0, (self.n_pings,))[i]),
            sound_speed_m_s=float(np.broadcast_to(self._c, (self.n_pings,))[i]),
            element_pos_m=self.element_pos_m, source_pos_m=self.source_pos_m, channel_valid=valid,
            roll_deg=float(self._roll[i]), heave_m=float(self._heave[i]), pitch_deg=at(self._pitch),
            heading_deg=at(self._heading), latitude_deg=at(self._lat), longitude_deg=at(self._lon),
            time=None if self._time is None else self._time[i], pulse=self.pulse, index=i,
            element_gain_db=self.element_gain_db, element_phase_deg=self.element_phase_deg, svp=self.svp,
            draft_m=at(self._draft),
        )


def _open_plain(path: Path):
    """A plain NetCDF4 ping file through h5py alone (a quarter of a second sooner than xarray, whose
    imports and decoding it skips); ``None`` for Zarr stores and files that need xarray."""
    if path.is_dir() or path.suffix == ".zarr" or not path.is_file() or path.stat().st_size == 0:
        return None
    from clbeam.io.h5file import open_plain

    return open_plain(path)


class PingFile(PingDataset):
    """A validated ping file (docs/ping-format.md) read one ping at a time.

    Parameters
    ----------
    path : str or path-like
        NetCDF4 (``.nc``) or Zarr (``.zarr`` directory) file.

    Examples
    --------
    >>> with PingFile("line1.nc") as pings:          # doctest: +SKIP
    ...     for ping in pings:
    ...         ...
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        ds = _open_plain(self.path) or open_dataset(self.path)
        try:
            super().__init__(ds, self.path.name)
        except PingFileError:
            ds.close()
            raise

    def __enter__(self) -> "PingFile":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def pings_from_dataset(ds: xr.Dataset, name: str = "dataset") -> PingDataset:
    """The pings of a ping dataset (docs/ping-format.md) in memory, with the checks of :class:`PingFile`.

    Parameters
    ----------
    ds : xarray.Dataset
        A ping dataset, e.g. from :func:`clbeam.sim.simulate` or
        :func:`clbeam.io.pingwrite.dataset_from_pings`.
    name : str
        Name used in error messages.

    Returns
    -------
    PingDataset
        Indexable (``.ping(i)``) and iterable over :class:`~clbeam.model.ping.Ping`.
    """
    return PingDataset(ds, name)
