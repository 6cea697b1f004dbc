"""Ping files (SPEC §7): the data model, validation, streaming reader, writer.

A :class:`PingFile` opens a NetCDF4 (HDF5) or Zarr ping file lazily, checks
every variable once and then hands out one :class:`Ping` at a time, so files
larger than memory stream.  Every problem is a :class:`PingFileError` whose
one-line message names the file, the variable and what was expected.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from clbeam.errors import ClbeamError, PingFileError, require
from clbeam.imaging.raytrace import SoundSpeedProfile
from clbeam.imaging.signal import lfm_replica

log = logging.getLogger(__name__)

FORMAT = "ping-1"
SOUND_SPEED_RANGE_M_S = (1300.0, 1700.0)
MAX_ABS_ROLL_DEG = 45.0
#: largest distance (m) of an element or the source from the array reference point
MAX_OFFSET_M = 100.0
#: largest channel gain correction (dB) a ping file may give
MAX_ABS_GAIN_DB = 60.0


@dataclass(frozen=True)
class Pulse:
    """Transmit pulse: an LFM description or an explicit waveform.

    Attributes
    ----------
    f0_hz, f1_hz, duration_s : float or None
        LFM start/end frequency (Hz) and length (s).
    waveform : numpy.ndarray or None
        Transmit waveform sampled at the ping's sample rate (takes precedence).
    """

    f0_hz: float | None = None
    f1_hz: float | None = None
    duration_s: float | None = None
    waveform: np.ndarray | None = None

    def replica(self, sample_rate_hz: float) -> np.ndarray:
        """The transmit replica at ``sample_rate_hz`` (Hz) for pulse compression."""
        if self.waveform is not None:
            return np.asarray(self.waveform, dtype=np.float64)
        return lfm_replica(f0_hz=self.f0_hz, f1_hz=self.f1_hz, duration_s=self.duration_s,
                           sample_rate_hz=sample_rate_hz)

    @property
    def centre_frequency_hz(self) -> float | None:
        """Band centre (Hz) of an LFM pulse, ``None`` for an explicit waveform."""
        if self.f0_hz is None:
            return None
        return 0.5 * (self.f0_hz + self.f1_hz)


@dataclass(frozen=True)
class Ping:
    """One ping: element time series, geometry, motion and pulse.

    Attributes
    ----------
    samples : numpy.ndarray
        ``(channel, sample)``: real pressure (``kind="raw"``) or complex
        pulse-compressed analytic signal (``kind="analytic"``).
    kind : str
        ``"raw"`` or ``"analytic"``.
    sample_rate_hz : float
        Sample rate (Hz); sample ``k`` is at ``t0_s + k / sample_rate_hz``.
    t0_s : float
        Time of sample 0 after transmit start (s).
    sound_speed_m_s : float
        Isospeed sound speed (m/s).
    element_pos_m : numpy.ndarray
        ``(channel, 3)`` receive elements ``x, y, z`` in the vessel frame (m).
    source_pos_m : numpy.ndarray
        ``(3,)`` transmit acoustic centre in the vessel frame (m).
    channel_valid : numpy.ndarray
        ``(channel,)`` bool, False for dead channels.
    roll_deg, heave_m : float
        Motion: roll (degrees, starboard down positive), heave (m, up positive).
    svp : clbeam.imaging.raytrace.SoundSpeedProfile or None
        Sound-speed profile from ``svp_depth(svp)`` (m, earth-frame ``z``
        below the array reference point) and ``svp_speed(svp)`` (m/s).
    element_gain_db, element_phase_deg : numpy.ndarray or None
        ``(channel,)`` channel responses (dB, degree): the recorded analytic
        signal is ``10^(g/20) e^(j φ)`` times the true one (removed by
        calibration, :mod:`clbeam.imaging.apodization`).
    """

    samples: np.ndarray
    kind: str
    sample_rate_hz: float
    t0_s: float
    sound_speed_m_s: float
    element_pos_m: np.ndarray
    source_pos_m: np.ndarray
    channel_valid: np.ndarray
    roll_deg: float = 0.0
    heave_m: float = 0.0
    pitch_deg: float | None = None
    heading_deg: float | None = None
    latitude_deg: float | None = None
    longitude_deg: float | None = None
    time: np.datetime64 | None = None
    pulse: Pulse | None = None
    index: int = 0
    element_gain_db: np.ndarray | None = None
    element_phase_deg: np.ndarray | None = None
    svp: SoundSpeedProfile | None = None
    extras: dict = field(default_factory=dict)

    @property
    def n_channels(self) -> int:
        """Number of receive channels."""
        return self.samples.shape[0]

    @property
    def n_samples(self) -> int:
        """Samples per channel."""
        return self.samples.shape[1]

    @property
    def has_navigation(self) -> bool:
        """True when latitude and longitude are known."""
        return self.latitude_deg is not None and self.longitude_deg is not None


def open_dataset(path: str | os.PathLike) -> xr.Dataset:
    """Open a NetCDF4/HDF5 or Zarr file lazily as an :class:`xarray.Dataset`."""
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


class PingFile:
    """A validated ping file (SPEC §7) read one ping at a time.

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
        self.ds = open_dataset(self.path)
        try:
            self._validate()
        except PingFileError:
            self.ds.close()
            raise

    # -- context management -------------------------------------------------
    def __enter__(self) -> "PingFile":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Close the underlying file."""
        self.ds.close()

    def __len__(self) -> int:
        return self.n_pings

    def __iter__(self):
        for i in range(self.n_pings):
            yield self.ping(i)

    # -- validation ---------------------------------------------------------
    def _err(self, message: str) -> PingFileError:
        return PingFileError(f"{self.path.name}: {message}")

    def _need(self, cond: bool, message: str) -> None:
        if not cond:
            raise self._err(message)

    def _var(self, name: str, dims_options: tuple[tuple[str, ...], ...], *, required: bool = True):
        ds = self.ds
        if name not in ds.variables:
            self._need(not required, f"missing variable '{name}' (SPEC §7)")
            return None
        v = ds[name]
        self._need(v.dims in dims_options,
                   f"variable '{name}' has dimensions {v.dims}, expected " + " or ".join(str(d) for d in dims_options))
        return v

    def _numeric(self, name: str, v: xr.DataArray, *, finite: bool = True) -> np.ndarray:
        self._need(np.issubdtype(v.dtype, np.number) and not np.issubdtype(v.dtype, np.complexfloating),
                   f"variable '{name}' has dtype {v.dtype}, expected a real number type")
        a = np.asarray(v.values, dtype=np.float64)
        if finite:
            bad = ~np.isfinite(a)
            self._need(not bad.any(), f"variable '{name}' has {int(bad.sum())} non-finite value(s)")
        return a

    def _validate(self) -> None:
        ds = self.ds
        fmt = ds.attrs.get("clbeam_format")
        self._need(fmt is not None, f"global attribute 'clbeam_format' is missing, expected '{FORMAT}'")
        self._need(str(fmt) == FORMAT, f"global attribute 'clbeam_format' is '{fmt}', expected '{FORMAT}'")

        # samples: complex, real, or the (samples_r, samples_i) pair
        dims3 = (("ping", "channel", "sample"),)
        if "samples" in ds.variables:
            s = self._var("samples", dims3)
            self._split = False
        elif "samples_r" in ds.variables or "samples_i" in ds.variables:
            s = self._var("samples_r", dims3)
            si = self._var("samples_i", dims3)
            self._need(s.dtype == si.dtype, f"'samples_r' ({s.dtype}) and 'samples_i' ({si.dtype}) must share a dtype")
            self._split = True
        else:
            raise self._err("missing variable 'samples' (or the pair 'samples_r', 'samples_i') (SPEC §7)")
        self._need(np.issubdtype(s.dtype, np.number), f"variable '{s.name}' has dtype {s.dtype}, expected numbers")
        self.kind = str(s.attrs.get("kind", "raw"))
        self._need(self.kind in ("raw", "analytic"), f"variable '{s.name}' has kind='{self.kind}', expected 'raw' or 'analytic'")
        is_complex = np.issubdtype(s.dtype, np.complexfloating) or self._split
        self._need(not (self.kind == "raw" and is_complex), f"variable '{s.name}' is complex but kind='raw'; raw pressure must be real")
        self._need(not (self.kind == "analytic" and not is_complex),
                   f"variable '{s.name}' has kind='analytic' but is real; store it complex or as 'samples_r'/'samples_i'")
        self.n_pings, self.n_channels, self.n_samples = (int(ds.sizes[d]) for d in ("ping", "channel", "sample"))
        self._need(self.n_pings > 0, "contains no pings (dimension 'ping' has length 0)")
        self._need(self.n_channels > 0, "has no channels (dimension 'channel' has length 0)")
        self._need(self.n_samples > 1, f"has {self.n_samples} sample(s) per channel, expected at least 2")

        fs = self._numeric("sample_rate", self._var("sample_rate", ((),)))
        self._need(float(fs) > 0, f"variable 'sample_rate' is {float(fs):g} Hz, expected > 0")
        self.sample_rate_hz = float(fs)

        self._t0 = self._numeric("t0", self._var("t0", (("ping",), ())))
        self._need(bool(np.all(self._t0 >= 0)), f"variable 't0' has negative values (min {self._t0.min():g} s), expected >= 0")

        ey = self._numeric("element_y", self._var("element_y", (("channel",),)))
        ez = self._numeric("element_z", self._var("element_z", (("channel",),)))
        exv = self._var("element_x", (("channel",),), required=False)
        ex = self._numeric("element_x", exv) if exv is not None else np.zeros_like(ey)
        self.element_pos_m = np.stack([ex, ey, ez], axis=-1)
        uniq = np.unique(np.round(self.element_pos_m, 9), axis=0)
        self._need(uniq.shape[0] == self.n_channels,
                   f"element positions are duplicated ({self.n_channels - uniq.shape[0]} repeated), expected distinct elements")
        src = []
        for comp, req in (("source_x", False), ("source_y", True), ("source_z", True)):
            v = self._var(comp, ((),), required=req)
            src.append(float(self._numeric(comp, v)) if v is not None else 0.0)
        self.source_pos_m = np.array(src)
        for name, pos in (("element", self.element_pos_m), ("source", self.source_pos_m)):
            reach = float(np.max(np.abs(pos)))
            self._need(reach <= MAX_OFFSET_M, f"{name} positions reach {reach:g} m from the reference point, "
                       f"expected within {MAX_OFFSET_M:g} m (a hull-mounted array)")

        c = self._numeric("sound_speed", self._var("sound_speed", (("ping",), ())))
        lo, hi = SOUND_SPEED_RANGE_M_S
        self._need(bool(np.all((c >= lo) & (c <= hi))),
                   f"variable 'sound_speed' has values in [{c.min():g}, {c.max():g}] m/s, expected within {lo:g}-{hi:g} m/s")
        self._c = c

        self._roll = self._optional_per_ping("roll", 0.0)
        self._need(bool(np.all(np.abs(self._roll) <= MAX_ABS_ROLL_DEG)),
                   f"variable 'roll' reaches {np.abs(self._roll).max():g} degrees, expected within ±{MAX_ABS_ROLL_DEG:g}")
        self._heave = self._optional_per_ping("heave", 0.0)
        self._pitch = self._optional_per_ping("pitch", None)
        self._heading = self._optional_per_ping("heading", None)
        self._lat = self._optional_per_ping("latitude", None)
        self._lon = self._optional_per_ping("longitude", None)
        if self._lat is not None:
            self._need(bool(np.all(np.abs(self._lat) <= 90)), "variable 'latitude' is outside ±90 degrees")
        self._time = None
        if "ping_time" in ds.variables:
            tv = self._var("ping_time", (("ping",),))
            self._need(np.issubdtype(tv.dtype, np.datetime64), f"variable 'ping_time' has dtype {tv.dtype}, expected datetime64")
            self._time = tv.values

        self.pulse = self._read_pulse()
        self._need(self.kind == "analytic" or self.pulse is not None,
                   "missing pulse description: 'pulse_f0', 'pulse_f1', 'pulse_duration' or 'tx_waveform' (needed for kind='raw')")

        self.svp = self._read_svp()
        self.element_gain_db = self._channel_response("element_gain_db", MAX_ABS_GAIN_DB)
        self.element_phase_deg = self._channel_response("element_phase_deg", None)

        self._valid = np.ones(self.n_channels, dtype=bool)
        self._valid_per_ping = None
        if "channel_valid" in ds.variables:
            v = self._var("channel_valid", (("channel",), ("ping", "channel")))
            self._need(v.dtype == bool or np.issubdtype(v.dtype, np.integer),
                       f"variable 'channel_valid' has dtype {v.dtype}, expected bool")
            if v.dims == ("channel",):
                self._valid = np.asarray(v.values).astype(bool)
            else:
                self._valid_per_ping = v

    def _read_svp(self):
        present = [n for n in ("svp_depth", "svp_speed") if n in self.ds.variables]
        if not present:
            return None
        self._need(len(present) == 2, f"variable '{present[0]}' needs its partner "
                   f"'{'svp_speed' if present[0] == 'svp_depth' else 'svp_depth'}' (sound-speed profile)")
        depth = self._numeric("svp_depth", self._var("svp_depth", (("svp",),)))
        speed = self._numeric("svp_speed", self._var("svp_speed", (("svp",),)))
        try:
            return SoundSpeedProfile(depth, speed)
        except ClbeamError as exc:
            raise self._err(f"sound-speed profile 'svp_depth'/'svp_speed': {exc}") from None

    def _channel_response(self, name: str, limit: float | None) -> np.ndarray | None:
        v = self._var(name, (("channel",),), required=False)
        if v is None:
            return None
        a = self._numeric(name, v)
        if limit is not None:
            self._need(bool(np.all(np.abs(a) <= limit)),
                       f"variable '{name}' reaches {np.abs(a).max():g}, expected within ±{limit:g}")
        return a

    def _optional_per_ping(self, name: str, default):
        v = self._var(name, (("ping",), ()), required=False)
        if v is None:
            return None if default is None else np.full(self.n_pings, default, dtype=np.float64)
        return np.broadcast_to(self._numeric(name, v), (self.n_pings,))

    def _read_pulse(self) -> Pulse | None:
        ds = self.ds
        if "tx_waveform" in ds.variables:
            w = self._numeric("tx_waveform", self._var("tx_waveform", (("tx_sample",),)))
            self._need(w.size > 0 and float(np.dot(w, w)) > 0, "variable 'tx_waveform' is empty or all zero")
            self._need(w.size <= self.n_samples, f"variable 'tx_waveform' has {w.size} samples, more than the "
                       f"record's {self.n_samples}")
            return Pulse(waveform=w)
        names = ("pulse_f0", "pulse_f1", "pulse_duration")
        present = [n for n in names if n in ds.variables]
        if not present:
            return None
        missing = [n for n in names if n not in ds.variables]
        self._need(not missing, f"missing variable '{missing[0]}' (the LFM pulse needs {', '.join(names)})" if missing else "")
        f0, f1, dur = (float(self._numeric(n, self._var(n, ((),)))) for n in names)
        nyq = self.sample_rate_hz / 2
        record_s = self.n_samples / self.sample_rate_hz
        self._need(0 < dur <= record_s, f"variable 'pulse_duration' is {dur:g} s, expected > 0 and no longer "
                   f"than the record ({record_s:g} s)")
        self._need(0 <= min(f0, f1) and max(f0, f1) < nyq,
                   f"pulse band {f0:g}-{f1:g} Hz must lie within 0-{nyq:g} Hz (half the sample rate)")
        return Pulse(f0_hz=f0, f1_hz=f1, duration_s=dur)

    def max_record_range_m(self) -> float:
        """Largest one-way range (m) any ping's record reaches: ``c (t0 + n / fs) / 2``."""
        t_end = float(np.max(self._t0)) + self.n_samples / self.sample_rate_hz
        return 0.5 * float(np.max(self._c)) * t_end

    # -- reading ------------------------------------------------------------
    def _samples(self, i: int) -> np.ndarray:
        ds = self.ds
        if self._split:
            re = np.asarray(ds["samples_r"].isel(ping=i).values)
            im = np.asarray(ds["samples_i"].isel(ping=i).values)
            return (re + 1j * im).astype(np.complex128 if re.dtype == np.float64 else np.complex64)
        return np.asarray(ds["samples"].isel(ping=i).values)

    def ping(self, i: int) -> Ping:
        """Read ping ``i`` (0-based) from the file."""
        require(0 <= i < self.n_pings, PingFileError, f"{self.path.name}: ping {i} out of range 0..{self.n_pings - 1}")
        valid = self._valid
        if self._valid_per_ping is not None:
            valid = np.asarray(self._valid_per_ping.isel(ping=i).values).astype(bool)

        def at(a):
            return None if a is None else float(a[i])

        return Ping(
            samples=self._samples(i),
            kind=self.kind,
            sample_rate_hz=self.sample_rate_hz,
            t0_s=float(np.broadcast_to(self._t0, (self.n_pings,))[i]),
            sound_speed_m_s=float(np.broadcast_to(self._c, (self.n_pings,))[i]),
            element_pos_m=self.element_pos_m,
            source_pos_m=self.source_pos_m,
            channel_valid=valid,
            roll_deg=float(self._roll[i]),
            heave_m=float(self._heave[i]),
            pitch_deg=at(self._pitch),
            heading_deg=at(self._heading),
            latitude_deg=at(self._lat),
            longitude_deg=at(self._lon),
            time=None if self._time is None else self._time[i],
            pulse=self.pulse,
            index=i,
            element_gain_db=self.element_gain_db,
            element_phase_deg=self.element_phase_deg,
            svp=self.svp,
        )


def write_ping_file(ds: xr.Dataset, path: str | os.PathLike) -> Path:
    """Write a SPEC §7 dataset to NetCDF4 (HDF5, complex allowed) or to Zarr
    when ``path`` ends in ``.zarr``; the global ``clbeam_format`` is set."""
    p = Path(path)
    ds = ds.copy()
    ds.attrs["clbeam_format"] = FORMAT
    if p.suffix == ".zarr":
        ds.to_zarr(p, mode="w")
    else:
        if any(np.issubdtype(v.dtype, np.complexfloating) for v in ds.data_vars.values()):
            # the netCDF4 library's complex compound type (nc-complex), readable by both engines
            ds.to_netcdf(p, engine="netcdf4", auto_complex=True)
        else:
            ds.to_netcdf(p, engine="h5netcdf")
    return p
