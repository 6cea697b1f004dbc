"""The Imager: one ping through the whole chain.

compress (analytic signal) → earth frame (roll, heave) → engine (S, Q, M →
intensity, CF) → Hann smoothing → coherence peaks.  Build it once (grid,
mode, device); it compiles the kernels on first use and keeps them and its
device buffers for every later ping, which is what a processing server or a
survey worker holds.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import time
from dataclasses import dataclass, field

import numpy as np

from clbeam.errors import ClbeamError, GeometryError, GridError, OptionError, require
from clbeam.imaging.apodization import (
    calibration_factors,
    parse_window,
    receive_weights,
)
from clbeam.imaging.engine import BeamformInput, Sums, get_engine, interp_mode
from clbeam.imaging.engine.common import cell_windows, check_outputs
from clbeam.imaging.geometry import check_positions, to_earth_frame
from clbeam.imaging.mlh import mlh_peak_rows
from clbeam.imaging.postprocess import (
    DEFAULT_THRESHOLD,
    coherence_peaks,
    hann_smooth,
    peak_row,
)
from clbeam.imaging.raytrace import eigenrays, travel_time_tables
from clbeam.imaging.signal import compress_analytic, upsample_analytic
from clbeam.io.peaks import PEAK_COLUMNS
from clbeam.model.grid import PolarGrid
from clbeam.model.ping import Ping
from clbeam.model.svp import SoundSpeedProfile

log = logging.getLogger(__name__)



@dataclass(frozen=True)
class ImagingOptions:
    """How a ping is imaged.

    Attributes
    ----------
    interp : str
        Interpolation mode (see :data:`clbeam.imaging.engine.INTERP_MODES`).
    upsample : int
        FFT upsampling factor of the analytic signal before interpolation.
    outputs : tuple of str
        Requested outputs: ``"intensity"``, ``"cf"``, ``"sums"``; CF also
        gives the smoothed CF and the coherence peaks.
    threshold : float
        Coherence-peak threshold on the smoothed CF (paper: 0.25).
    sound_speed_m_s : float or None
        Override of the file's sound speed (m/s).
    precision : str
        ``"float32"`` or ``"float64"`` kernel arithmetic (OpenCL backend).
    seabed_band_m : (float, float) or None
        Compute only cells from this far above to this far below the seabed
        (m), e.g. ``(5, 40)``; ``None`` computes the whole grid.
    seabed_depth_m : float or None
        Seabed depth below the grid centre (m) for the band; ``None`` picks it
        per ping from the first strong return at nadir.
    apodization : str
        Receive window across the array: ``"rect"`` (none), ``"hann"``,
        ``"tukey[:alpha]"``, ``"chebyshev[:sidelobe_db]"``
        (:mod:`clbeam.imaging.apodization`; CF becomes the weighted CF).
    calibrate : bool
        Remove the ping file's ``element_gain_db`` / ``element_phase_deg``
        from the channels (when the file has them).
    use_svp : bool
        Ray-trace the travel times through the ping file's sound-speed profile
        (``svp_depth``, ``svp_speed``) when it has one (:mod:`clbeam.imaging.raytrace`);
        ``False`` (or ``sound_speed_m_s``) images with straight rays.
    sediment_speed_m_s : float or None
        Sediment interval velocity (m/s) below a flat seabed at
        ``seabed_depth_m`` (picked per ping when not given): rays refract at
        the seabed (Snell) on their way to sub-bottom cells.
    mlh : bool
        Merge the coherence peaks on one main-lobe arc into one detection
        with a lobe-fitted position (:mod:`clbeam.imaging.mlh`); the peak rows then
        carry ``n_merged``, ``arc_extent_deg`` and ``arc_range_spread_m``.
    """

    interp: str = "cubic"
    upsample: int = 1
    outputs: tuple = ("intensity", "cf")
    threshold: float = DEFAULT_THRESHOLD
    sound_speed_m_s: float | None = None
    precision: str = "float32"
    seabed_band_m: tuple | None = None
    seabed_depth_m: float | None = None
    apodization: str = "rect"
    calibrate: bool = True
    use_svp: bool = True
    sediment_speed_m_s: float | None = None
    mlh: bool = False

    def __post_init__(self):
        interp_mode(self.interp)
        object.__setattr__(self, "apodization", parse_window(self.apodization).label)
        object.__setattr__(self, "outputs", tuple(sorted(check_outputs(self.outputs))))
        require(int(self.upsample) == self.upsample and 1 <= self.upsample <= 16, OptionError,
                f"upsample must be an integer 1-16, got {self.upsample!r}")
        require(0 <= self.threshold <= 1, OptionError, f"threshold must be within 0-1, got {self.threshold!r}")
        if self.seabed_band_m is not None:
            band = tuple(float(v) for v in self.seabed_band_m)
            require(len(band) == 2 and all(np.isfinite(band)) and band[0] + band[1] > 0, OptionError,
                    f"seabed band must be (above, below) metres with a positive width, got {self.seabed_band_m!r}")
            object.__setattr__(self, "seabed_band_m", band)
        if self.sediment_speed_m_s is not None:
            require(1300 <= self.sediment_speed_m_s <= 2000, OptionError,
                    f"sediment speed must be within 1300-2000 m/s, got {self.sediment_speed_m_s!r}")
        if self.sound_speed_m_s is not None:
            require(1300 <= self.sound_speed_m_s <= 1700, OptionError,
                    f"sound speed must be within 1300-1700 m/s, got {self.sound_speed_m_s!r}")


@dataclass
class PingImage:
    """The images and coherence peaks of one ping.

    Attributes
    ----------
    ping : int
        Ping index in its file.
    grid : PolarGrid
        Image grid; every array is ``(n_angle, n_range)``.
    intensity, cf, cf_smooth : numpy.ndarray or None
        ``|S|^2``, coherence factor and its 7-point Hann smoothing along range.
    sums : Sums or None
        Raw sums ``S``, ``Q``, ``M`` (when requested) for stacking pings.
    peaks : list of dict
        One row per coherence peak (:data:`PEAK_COLUMNS`, plus navigation).
    timings_s : dict
        Seconds spent per stage.
    """

    ping: int
    grid: PolarGrid
    intensity: np.ndarray | None
    cf: np.ndarray | None
    cf_smooth: np.ndarray | None
    sums: Sums | None
    peaks: list
    source_yz_m: tuple
    timings_s: dict = field(default_factory=dict)
    n_channels_used: int = 0


class Imager:
    """Images pings on a fixed grid with fixed options.

    Parameters
    ----------
    grid : PolarGrid
        Image grid (earth frame, centre at the source unless given).
    options : ImagingOptions, optional
        Mode, outputs, threshold …
    backend : {"opencl", "reference"}
        Engine backend.
    device : str or int, optional
        OpenCL device (index or name substring).
    engine : object, optional
        An existing engine to share (e.g. one per device in a server).

    Examples
    --------
    >>> imager = Imager(PolarGrid.regular(max_range_m=700))      # doctest: +SKIP
    >>> with PingFile("line1.nc") as f:                           # doctest: +SKIP
    ...     images = [imager.image(p) for p in f]
    """

    def __init__(self, grid: PolarGrid, options: ImagingOptions | None = None, *, backend: str = "opencl",
                 device=None, engine=None):
        self.grid = grid
        self.options = options or ImagingOptions()
        check_grid_fits_memory(grid, self.options)
        self.engine = engine if engine is not None else get_engine(backend, device=device,
                                                                   precision=self.options.precision)
        self._tables: dict = {}

    # -- preparation ------------------------------------------------------
    def analytic_channels(self, ping: Ping) -> tuple[np.ndarray, np.ndarray]:
        """Pulse-compressed analytic signal of the usable channels.

        Returns ``(data, used)``: complex ``(n_used, n_sample)`` and the bool
        mask of the channels used.  Channels flagged invalid, entirely zero or
        entirely non-finite are left out (logged).
        """
        x = ping.samples
        used = np.asarray(ping.channel_valid, dtype=bool).copy()
        finite = np.isfinite(x)
        dead = ~finite.any(axis=1) | ~np.any(np.where(finite, x, 0) != 0, axis=1)
        if (dead & used).any():
            log.warning("ping %d: %d channel(s) all zero or non-finite, left out: %s", ping.index,
                        int((dead & used).sum()), np.flatnonzero(dead & used).tolist())
        used &= ~dead
        n_bad = int((~finite[used]).sum())
        if n_bad:
            log.warning("ping %d: %d non-finite sample(s) skipped", ping.index, n_bad)
        if ping.kind == "raw":
            require(ping.pulse is not None, OptionError, "raw samples need a pulse description to compress")
            data = compress_analytic(x[used], ping.pulse.replica(ping.sample_rate_hz))
        else:
            data = np.where(finite[used], x[used], np.nan).astype(np.complex128)
        factors = calibration_factors(ping.element_gain_db, ping.element_phase_deg, ping.n_channels)
        if self.options.calibrate and factors is not None:
            data *= factors[used, None]
        return data, used

    def beamform_input(self, ping: Ping) -> BeamformInput:
        """Everything the engine needs for ``ping``: analytic channels and
        roll/heave-corrected offsets from the grid centre."""
        check_positions("element positions", ping.element_pos_m)
        check_positions("source position", ping.source_pos_m)
        data, used = self.analytic_channels(ping)
        elements = to_earth_frame(ping.element_pos_m[used], roll_deg=ping.roll_deg, heave_m=ping.heave_m)
        source = to_earth_frame(ping.source_pos_m, roll_deg=ping.roll_deg, heave_m=ping.heave_m)
        centre = np.r_[0.0, self.grid.centre(tuple(ping.source_pos_m[1:]))]
        fs = ping.sample_rate_hz
        if self.options.upsample > 1:
            data = upsample_analytic(data, self.options.upsample)
            fs *= self.options.upsample
        fc = ping.pulse.centre_frequency_hz if ping.pulse is not None else None
        window = parse_window(self.options.apodization)
        weights = None if window.uniform else receive_weights(window, ping.element_pos_m[:, 1])[used]
        inp = BeamformInput(
            data=data, sample_rate_hz=fs, t0_s=ping.t0_s,
            sound_speed_m_s=self.options.sound_speed_m_s or ping.sound_speed_m_s,
            element_offsets_m=elements - centre, source_offset_m=source - centre,
            centre_frequency_hz=fc or 0.0, weights=weights)
        return self._with_tables(ping, inp, float(centre[2]))

    # -- sound-speed profile ----------------------------------------------
    def water_profile(self, ping: Ping):
        """The ping's sound-speed profile when the travel times follow it, else ``None``."""
        if self.options.use_svp and self.options.sound_speed_m_s is None:
            return ping.svp
        return None

    def _with_tables(self, ping: Ping, inp: BeamformInput, centre_z_m: float) -> BeamformInput:
        """``inp`` with the ray-traced travel-time tables of the grid (cached
        per profile and grid centre depth) when a profile or a sediment speed
        applies."""
        profile = self.water_profile(ping)
        c_sed = self.options.sediment_speed_m_s
        if (profile is None and c_sed is None) or inp.n_channels == 0:  # no channel: the image is empty anyway
            return inp
        if profile is None:
            profile = SoundSpeedProfile.constant(inp.sound_speed_m_s)
        if c_sed is not None:
            depth = self.options.seabed_depth_m
            if depth is None:
                depth = pick_seabed_depth_m(inp, profile=profile, centre_depth_m=centre_z_m)
            # 1 cm steps: a picked seabed that moves with heave reuses its tables
            profile = SoundSpeedProfile.with_sediment(profile, round(depth + centre_z_m, 2), c_sed)
        key = (profile, round(centre_z_m, 6))
        tables = self._tables.get(key)
        if tables is None:
            t0 = time.perf_counter()
            tables = travel_time_tables(profile, self.grid, centre_z_m)
            log.info("travel-time tables of a %d x %d grid in %.2f s", *self.grid.shape, time.perf_counter() - t0)
            if len(self._tables) >= 2:  # about 41 bytes per cell each
                self._tables.pop(next(iter(self._tables)))
            self._tables[key] = tables
        return dataclasses.replace(inp, tables=tables)

    # -- imaging ----------------------------------------------------------
    def image(self, ping: Ping, *, range_window_m: np.ndarray | None = None) -> PingImage:
        """Image one ping.

        Parameters
        ----------
        ping : Ping
            The ping (see :class:`clbeam.io.pingfile.PingFile`).
        range_window_m : numpy.ndarray, optional
            ``(n_angle, 2)`` ranges (m) to compute per angle (e.g. a seabed
            band); cells outside are 0.
        """
        t = {}
        t_start = time.perf_counter()
        inp = self.beamform_input(ping)
        t["compress_s"] = time.perf_counter() - t_start
        scale_exp = amplitude_exponent(inp.data)
        if scale_exp:
            inp = dataclasses.replace(inp, data=inp.data * np.ldexp(1.0, -scale_exp))
        if inp.n_channels == 0:
            log.warning("ping %d: no usable channel; the image is empty", ping.index)
        if range_window_m is None and self.options.seabed_band_m is not None:
            depth = self.options.seabed_depth_m
            if depth is None and inp.n_channels:
                depth = pick_seabed_depth_m(inp, profile=self.water_profile(ping),
                                            centre_depth_m=float(self.grid.centre(tuple(ping.source_pos_m[1:]))[1]))
            if depth is None:  # no usable channel: nothing to pick, the image is empty anyway
                depth = float(self.grid.ranges_m[0])
            range_window_m = seabed_window_m(self.grid, depth, self.options.seabed_band_m)
        check_grid_reaches_record(inp, self.grid)
        t0 = time.perf_counter()
        outs = set(self.options.outputs)
        sums = self.engine.beamform(inp, self.grid, interp=self.options.interp, outputs=outs | {"intensity"} if "cf" in outs else outs,
                                    range_window_m=range_window_m)
        t["image_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        # undo the power-of-two normalisation exactly (float64 only where float32 could overflow)
        intensity = None if sums.intensity is None else rescale(sums.intensity, 2 * scale_exp)
        sums.intensity = intensity
        if sums.s is not None:
            sums.s = sums.s.astype(np.complex128) * np.ldexp(1.0, scale_exp)
            sums.q = np.ldexp(sums.q.astype(np.float64), 2 * scale_exp)
        cf = cf_smooth = None
        peaks = []
        source_yz = tuple(self.grid.centre(tuple(ping.source_pos_m[1:])))
        if sums.cf is not None:
            cf = sums.cf
            cf_smooth = hann_smooth(cf)
            peaks = self.peak_rows(ping, cf_smooth, intensity, source_yz)
        t["postprocess_s"] = time.perf_counter() - t0
        return PingImage(ping=ping.index, grid=self.grid,
                         intensity=intensity if "intensity" in self.options.outputs else None,
                         cf=cf, cf_smooth=cf_smooth, sums=sums if "sums" in self.options.outputs else None,
                         peaks=peaks, source_yz_m=source_yz, timings_s=t, n_channels_used=inp.n_channels)

    def peak_rows(self, ping: Ping, cf_smooth: np.ndarray, intensity: np.ndarray | None, centre_yz) -> list:
        """Rows of the peaks table for one ping (SPEC §3 step 7)."""
        g = self.grid
        if self.options.mlh:
            return mlh_peak_rows(ping, cf_smooth, intensity, g, centre_yz, threshold=self.options.threshold,
                                 **mlh_tolerances(ping, g, self.options.sound_speed_m_s or ping.sound_speed_m_s))
        nav = {"latitude": ping.latitude_deg, "longitude": ping.longitude_deg, "heading": ping.heading_deg}
        return [peak_row(ping.index, g.ranges_m[ir], g.angles_deg[ia], centre_yz, cf_smooth[ia, ir],
                         float(intensity[ia, ir]) if intensity is not None else np.nan, nav)
                for ia, ir in coherence_peaks(cf_smooth, self.options.threshold)]


def mlh_tolerances(ping: Ping, grid: PolarGrid, sound_speed_m_s: float) -> dict:
    """Range tolerance (m) and main-lobe width (direction cosine) of the arcs
    of :mod:`clbeam.imaging.mlh` from this ping's pulse band and array width (the
    SBP29 defaults where the pulse is an explicit waveform)."""
    from clbeam.imaging.mlh import SBP29_BAND_HZ, default_range_tolerance_m, main_lobe_u

    pulse = ping.pulse
    band = (min(pulse.f0_hz, pulse.f1_hz), max(pulse.f0_hz, pulse.f1_hz)) \
        if pulse is not None and pulse.f0_hz is not None and pulse.f0_hz != pulse.f1_hz else SBP29_BAND_HZ
    width = float(np.ptp(ping.element_pos_m[:, 1])) * ping.n_channels / max(ping.n_channels - 1, 1)
    return {"range_tolerance_m": default_range_tolerance_m(grid, band_hz=band, sound_speed_m_s=sound_speed_m_s),
            "max_gap_u": main_lobe_u(0.5 * sum(band), max(width, 1e-3), sound_speed_m_s)}


def check_grid_fits_memory(grid: PolarGrid, options: ImagingOptions, *, fraction: float = 0.5) -> None:
    """Raise :class:`GridError` when one ping's output arrays would need more
    than ``fraction`` of this machine's memory (host memory per ping is about
    ``n_cells x`` 8 bytes per output plus 16 for CF smoothing and peaks, plus
    106 for ray-traced travel times when a ping may carry a profile)."""
    per_cell = 8 * (len(options.outputs) + 3 * ("sums" in options.outputs)) + 16
    if options.use_svp or options.sediment_speed_m_s is not None:
        per_cell += 2 * 41 + 24  # two cached travel-time table sets and the kernel's per-cell copy
    need = grid.n_cells * per_cell
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return
    require(need <= fraction * total, GridError,
            f"a grid of {grid.shape[0]} angles x {grid.shape[1]} ranges ({grid.n_cells:.3g} cells) needs "
            f"{need / 2**30:.1f} GiB per ping, more than {fraction:.0%} of this machine's {total / 2**30:.1f} GiB; "
            "use a coarser grid or a smaller window")


def check_grid_reaches_record(inp: BeamformInput, grid: PolarGrid) -> None:
    """Raise :class:`GridError` when no cell of ``grid`` can be imaged from
    the record (every travel time before its first or after its last sample)."""
    win = cell_windows(inp, grid, interp_mode("nearest"))
    if inp.n_channels and not np.any(win[:, 1] > win[:, 0]):
        t_end = inp.t0_s + (inp.n_samples - 1) / inp.sample_rate_hz
        c = inp.sound_speed_m_s
        raise GridError(f"grid ranges {grid.ranges_m[0]:g}-{grid.ranges_m[-1]:g} m lie outside the record, which "
                        f"reaches ranges {0.5 * c * inp.t0_s:g}-{0.5 * c * t_end:g} m")


def pick_seabed_depth_m(inp: BeamformInput, *, below_peak_db: float = 20.0, profile=None,
                        centre_depth_m: float = 0.0) -> float:
    """Seabed depth below the grid centre (m) from the first strong return.

    The channels' envelopes are summed; the first sample within
    ``below_peak_db`` of the strongest is the nadir seabed echo, at two-way
    time ``t`` and so depth ``c t / 2`` (the array spans metres, the water
    hundreds: the offsets' effect is below a range cell).  With a
    sound-speed ``profile`` (depth axis: the grid centre at
    ``centre_depth_m``) the depth is where the vertical ray's one-way time
    from the source is ``t / 2``.
    """
    env = np.nansum(np.abs(inp.data), axis=0)
    require(env.size > 0 and np.max(env) > 0, OptionError,
            "cannot pick the seabed: the ping has no signal; give the seabed depth")
    k = int(np.argmax(env >= np.max(env) * 10 ** (-below_peak_db / 20)))
    one_way_s = 0.5 * (inp.t0_s + k / inp.sample_rate_hz)
    source_z = float(inp.source_offset_m[2])
    if profile is None:  # measured from the (heaved) source, returned below the grid centre
        return inp.sound_speed_m_s * one_way_s + source_z
    z_src = centre_depth_m + source_z
    z = z_src + np.arange(1, 40001) * (float(np.max(profile.speeds_m_s)) * one_way_s / 40000)
    t = eigenrays(profile, z_src, np.zeros_like(z), z).time_s
    return float(np.interp(one_way_s, t, z)) - centre_depth_m


def seabed_window_m(grid: PolarGrid, depth_m: float, band_m: tuple) -> np.ndarray:
    """Per-angle range interval ``(n_angle, 2)`` (m) covering a flat seabed at
    ``depth_m`` below the grid centre, from ``band_m[0]`` above to
    ``band_m[1]`` below it: ``R = z / cos(theta)``."""
    above, below = band_m
    cos_t = np.cos(np.deg2rad(grid.angles_deg))
    lo = np.maximum(depth_m - above, 0.0) / cos_t
    hi = (depth_m + below) / cos_t
    return np.stack([lo, hi], axis=1)


def rescale(values: np.ndarray, exponent: int) -> np.ndarray:
    """``values * 2**exponent`` exactly: in place in float32 when the largest
    result stays within ``2^-60 .. 2^120`` (no overflow, and values down to
    18 orders of magnitude below the largest stay normal), in float64
    otherwise."""
    if exponent == 0 or values.size == 0:
        return values
    if values.dtype == np.float32:
        top = float(np.max(values))
        if top == 0 or (np.isfinite(top) and -60 <= np.frexp(top)[1] + exponent <= 120):
            return np.ldexp(values, np.int32(exponent), out=values)
    return np.ldexp(values.astype(np.float64), exponent)


def amplitude_exponent(data: np.ndarray) -> int:
    """Power-of-two exponent ``e`` with ``max |data| / 2^e`` in [0.5, 1).

    Dividing by ``2^e`` is exact, keeps float32 sums far from overflow
    (|S|^2 of 1e30-amplitude data) and underflow (1e-30), and is undone
    exactly afterwards; 0 for all-zero or empty data.
    """
    if data.size == 0:
        return 0
    peak = np.nanmax(np.abs(data)) if np.isfinite(data).any() else 0.0
    if not np.isfinite(peak) or peak == 0:
        return 0
    return int(np.frexp(peak)[1])


__all__ = ["Imager", "ImagingOptions", "PingImage", "PEAK_COLUMNS", "ClbeamError", "GeometryError"]
