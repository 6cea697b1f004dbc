"""Shared definitions of both engine backends: modes, inputs, tables, results."""

from __future__ import annotations

import dataclasses
import logging
import math
import time
import weakref
from dataclasses import dataclass, field

import numpy as np

from clbeam.errors import GeometryError, GridError, OptionError, require
from clbeam.imaging.engine.beams import (
    angular_band_limit,
    beam_plan,
    interpolate_beams,
    probe_grid,
    refracted_band_limit,
)
from clbeam.imaging.engine.points import node_tables
from clbeam.model.grid import PolarGrid

log = logging.getLogger(__name__)
#: messages already logged by :func:`_info_once` (a ping's calibration checks the same plan on every point)
_TOLD: set = set()


def _info_once(message: str) -> None:
    """Log ``message`` at INFO the first time this process sees it."""
    if message in _TOLD or not log.isEnabledFor(logging.INFO):
        return
    if len(_TOLD) < 256:
        _TOLD.add(message)
    log.info("%s", message)

#: outputs a caller may request
OUTPUTS = ("intensity", "cf", "sums")


@dataclass(frozen=True)
class InterpMode:
    """An interpolation mode of the delay-and-sum.

    Attributes
    ----------
    name : str
        Mode name as used by the API and the ``--interp`` option.
    kernel_id : int
        ``INTERP`` macro of ``kernels/interp.h`` (-1: reference only).
    lanczos_a : int
        Lobes of the Lanczos window (mode ``lanczos*``).
    baseband : bool
        Interpolate the basebanded signal and restore the carrier phase.
    taps_before, taps_after : int
        Support around the integer tap ``k``; a sample contributes only when
        ``k - taps_before >= 0`` and ``k + taps_after <= n_samples - 1``.
    """

    name: str
    kernel_id: int
    lanczos_a: int = 0
    baseband: bool = False
    taps_before: int = 0
    taps_after: int = 0
    description: str = ""


#: half-width (lobes) of the windowed-sinc "exact" reference interpolator
EXACT_HALF_WIDTH = 32

INTERP_MODES: dict[str, InterpMode] = {m.name: m for m in (
    InterpMode("nearest", 0, description="nearest sample"),
    InterpMode("linear", 1, taps_after=1, description="linear between two samples"),
    InterpMode("linear-bb", 1, baseband=True, taps_after=1,
               description="linear on the basebanded signal, carrier phase restored"),
    InterpMode("cubic", 2, taps_before=1, taps_after=2, description="Keys cubic (Catmull-Rom), 4 taps"),
    InterpMode("lanczos4", 3, lanczos_a=4, taps_before=3, taps_after=4, description="Lanczos, 4 lobes, 8 taps"),
    InterpMode("lanczos8", 3, lanczos_a=8, taps_before=7, taps_after=8, description="Lanczos, 8 lobes, 16 taps"),
    InterpMode("exact", -1, taps_before=EXACT_HALF_WIDTH - 1, taps_after=EXACT_HALF_WIDTH,
               description="band-limited (Kaiser-windowed sinc, 64 taps), float64 reference only"),
)}


def interp_mode(name: str) -> InterpMode:
    """Look up an interpolation mode by name (one-line error when unknown)."""
    require(name in INTERP_MODES, OptionError,
            f"interpolation mode '{name}' is unknown, expected one of {', '.join(INTERP_MODES)}")
    return INTERP_MODES[name]


@dataclass(frozen=True)
class BeamformInput:
    """Analytic channels and their earth-frame geometry for one ping.

    Attributes
    ----------
    data : numpy.ndarray
        complex ``(n_channel, n_sample)``: pulse-compressed analytic signal of
        the channels that take part (dead channels already removed); NaN marks
        samples to skip.
    sample_rate_hz : float
        Sample rate of ``data`` (Hz), after any upsampling.
    t0_s : float
        Time of sample 0 after transmit start (s).
    sound_speed_m_s : float
        Isospeed sound speed (m/s).
    element_offsets_m : numpy.ndarray
        ``(n_channel, 3)`` element positions ``x, y, z`` minus the grid centre
        ``(0, yc, zc)``, earth frame (m).
    source_offset_m : numpy.ndarray
        ``(3,)`` source position minus the grid centre (m).
    centre_frequency_hz : float
        Band centre (Hz): the carrier removed by the basebanded modes
        (0 = unknown, which those modes refuse).
    weights : numpy.ndarray or None
        ``(n_channel,)`` receive apodization ``w_n >= 0``
        (:mod:`clbeam.imaging.apodization`); ``None``: all 1, the unweighted sums.
    tables : clbeam.imaging.raytrace.TravelTimeTables or None
        Ray-traced one-way times from the grid centre to every cell of the
        grid this input is imaged on (a sound-speed profile); ``None``:
        isospeed straight rays at ``sound_speed_m_s``.  Each point ``o`` (the
        source, an element) then adds ``d(o) = |rho u - o| - rho`` at the
        centre's speed, with ``u`` the ray's launch direction and ``rho`` its
        wavefront radius (:func:`clbeam.imaging.raytrace.offset_time_approx`).
    table_source : callable or None
        ``table_source(grid)`` gives the tables of any grid (the beams of
        beam-sampled imaging need their own); used when ``tables`` is None.
    band_hz : (float, float) or None
        Band of the analytic signal (Hz), for the angular band limit of
        beam-sampled imaging; ``None``: up to half the sample rate.
    data_token : object or None
        A promise: inputs with the same token hold the same, unchanged
        ``data``, so an engine may reuse its scaled device copy of them
        between calls (the beams and directly imaged cells of one call, the
        points of the sub-cell refinement); ``None``: no reuse across calls.
        :func:`dataclasses.replace` keeps it: give a new token (or ``None``)
        with new ``data``.
    min_channels : int
        CF is 0 in cells summed from fewer channels than this (``M`` below
        it): with one channel CF is 1 by definition, with a few it is large
        for noise (default 1: wherever a channel contributes).
    """

    data: np.ndarray
    sample_rate_hz: float
    t0_s: float
    sound_speed_m_s: float
    element_offsets_m: np.ndarray
    source_offset_m: np.ndarray
    centre_frequency_hz: float = 0.0
    weights: np.ndarray | None = None
    tables: object | None = None
    table_source: object | None = None
    band_hz: tuple | None = None
    data_token: object | None = None
    min_channels: int = 1

    def __post_init__(self):
        d = self.data
        require(d.ndim == 2, GeometryError, f"channel data must be 2-D (channel, sample), got shape {d.shape}")
        eo = np.asarray(self.element_offsets_m, dtype=np.float64)
        require(eo.shape == (d.shape[0], 3), GeometryError,
                f"element offsets must be ({d.shape[0]}, 3) for {d.shape[0]} channels, got {eo.shape}")
        require(bool(np.all(np.isfinite(eo))) and bool(np.all(np.isfinite(self.source_offset_m))), GeometryError,
                "element and source positions must be finite")
        require(self.sample_rate_hz > 0 and np.isfinite(self.sample_rate_hz), OptionError,
                f"sample rate must be > 0 Hz, got {self.sample_rate_hz!r}")
        require(self.sound_speed_m_s > 0 and np.isfinite(self.sound_speed_m_s), OptionError,
                f"sound speed must be > 0 m/s, got {self.sound_speed_m_s!r}")
        require(np.isfinite(self.t0_s), OptionError, f"t0 must be finite, got {self.t0_s!r}")
        require(int(self.min_channels) == self.min_channels and self.min_channels >= 1, OptionError,
                f"the minimum of channels for CF must be an integer >= 1, got {self.min_channels!r}")
        if self.weights is not None:
            w = np.asarray(self.weights, dtype=np.float64)
            require(w.shape == (d.shape[0],), OptionError,
                    f"apodization weights must be ({d.shape[0]},) for {d.shape[0]} channels, got {w.shape}")
            require(bool(np.all(np.isfinite(w) & (w >= 0))), OptionError,
                    "apodization weights must be finite and >= 0")

    @property
    def n_channels(self) -> int:
        """Channels taking part."""
        return self.data.shape[0]

    @property
    def n_samples(self) -> int:
        """Samples per channel."""
        return self.data.shape[1]

    def for_grid(self, grid: PolarGrid) -> "BeamformInput":
        """This input with the travel-time tables of ``grid`` (from :attr:`table_source`), when it has a source."""
        if self.table_source is None or (self.tables is not None and self.tables.grid is grid):
            return self
        return dataclasses.replace(self, tables=self.table_source(grid))

    @property
    def top_frequency_hz(self) -> float:
        """Top of the signal band (Hz): :attr:`band_hz`, else half the sample rate."""
        return float(max(self.band_hz)) if self.band_hz is not None else 0.5 * self.sample_rate_hz

    @property
    def samples_per_m(self) -> float:
        """Samples per metre of path, ``fs / c`` (``c`` at the grid centre with tables)."""
        c = self.sound_speed_m_s if self.tables is None else self.tables.centre_speed_m_s
        return self.sample_rate_hz / c

    def check_tables(self, grid: PolarGrid) -> None:
        """Raise :class:`GridError` unless the travel-time tables are those of ``grid``."""
        if self.tables is None:
            return
        g = self.tables.grid
        require(g.shape == grid.shape and np.array_equal(g.ranges_m, grid.ranges_m)
                and np.array_equal(g.angles_deg, grid.angles_deg), GridError,
                f"the travel-time tables are for a {g.shape} grid, not this {grid.shape} one")

    def cell_base_samples(self, grid: PolarGrid) -> np.ndarray:
        """Sample position (float64) of the centre's two-way time to each cell,
        ``(n_angle, n_range)``: ``(2 T - t0) fs`` from the tables (NaN where no
        ray reaches), else ``(2 R / c - t0) fs`` broadcast over angles."""
        if self.tables is None:
            return np.broadcast_to(range_bases(self, grid)[None, :], grid.shape)
        return (2.0 * self.tables.time_s - self.t0_s) * self.sample_rate_hz


@dataclass
class Sums:
    """Per-cell results on a grid, each ``(n_angle, n_range)`` (or ``None``
    when not requested).

    Attributes
    ----------
    intensity : numpy.ndarray
        ``|S|^2`` (squared input units), Holland eq. 1.
    cf : numpy.ndarray
        Coherence factor ``|S|^2 / (M Q)``, 0 where ``M = 0`` or ``Q = 0``;
        with apodization ``|S|^2 / (W Q)`` (:mod:`clbeam.imaging.apodization`).
    s : numpy.ndarray
        complex coherent sum ``S = Σ w p``.
    q : numpy.ndarray
        incoherent sum ``Q = Σ w |p|^2``.
    m : numpy.ndarray
        int32 count ``M`` of contributing channels.
    w : numpy.ndarray or None
        sum ``W = Σ w`` of the contributing channels' weights (apodized
        sums only; ``None`` means ``W = M``).
    signature : numpy.ndarray or None
        ``G = Σ g_n`` over the contributing channels (:func:`channel_signature`):
        equal ``G`` means the same channels contributed (internal output
        ``"signature"`` of beam-sampled imaging).
    timings_s : dict
        Seconds per stage of the call that made them: ``direct_s``, or ``beams_s`` (the sums on the
        beams), ``to_grid_s`` (their interpolation to the grid, read back) and ``flagged_s`` (the cells
        imaged directly).
    """

    intensity: np.ndarray | None = None
    cf: np.ndarray | None = None
    s: np.ndarray | None = None
    q: np.ndarray | None = None
    m: np.ndarray | None = None
    w: np.ndarray | None = None
    signature: np.ndarray | None = None
    timings_s: dict = field(default_factory=dict)

    def rescaled(self, exponent: int) -> "Sums":
        """These sums of data divided by ``2**exponent``, returned to the data's
        units exactly: intensity and ``Q`` times ``4**exponent``, ``S`` times
        ``2**exponent`` (``S`` complex128 and ``Q`` float64 from here on); CF,
        ``M`` and ``W`` do not change."""
        if self.intensity is not None:
            self.intensity = rescale(self.intensity, 2 * exponent)
        if self.s is not None:
            self.s = self.s.astype(np.complex128) * np.ldexp(1.0, exponent)
            self.q = np.ldexp(self.q.astype(np.float64), 2 * exponent)
        return self

    def coherence_denominator(self) -> np.ndarray:
        """``W Q`` (``M Q`` unweighted): the CF denominator, float64, from the raw sums."""
        require(self.q is not None and self.m is not None, OptionError,
                "the CF denominator needs the raw sums: request the 'sums' output")
        w = self.m if self.w is None else self.w
        return np.asarray(w, dtype=np.float64) * np.asarray(self.q, dtype=np.float64)


def min_channels_of(option: float, n_used: int) -> int:
    """The least number of channels a cell's CF needs: ``option`` itself when it is a count (>= 1),
    else that fraction of the ``n_used`` usable channels, rounded up (at least 1)."""
    if option >= 1:
        return int(option)
    return max(1, math.ceil(option * n_used - 1e-9))


def check_outputs(outputs) -> frozenset[str]:
    """Validate a collection of requested outputs."""
    if isinstance(outputs, str):
        outputs = [o.strip() for o in outputs.split(",") if o.strip()]
    out = frozenset(outputs)
    require(len(out) > 0, OptionError, "no outputs requested, expected some of " + ", ".join(OUTPUTS))
    bad = sorted(out - set(OUTPUTS))
    require(not bad, OptionError, f"output '{bad[0] if bad else ''}' is unknown, expected some of {', '.join(OUTPUTS)}")
    return out


def channel_signature(n_channels: int) -> np.ndarray:
    """A distinct number ``g_n`` in [1, 2) per channel (golden-ratio sequence): two sets of channels
    that differ give different sums ``G`` (the smallest difference of two of them is about ``0.4 / n``)."""
    return 1.0 + np.mod((np.arange(n_channels) + 1) * 0.6180339887498949, 1.0)


def check_mode_runs_on(mode: InterpMode, backend: str) -> None:
    """Raise :class:`OptionError` when ``backend`` (``"opencl"``, ``"reference"``) has no kernel for ``mode``."""
    require(backend == "reference" or mode.kernel_id >= 0, OptionError,
            f"interpolation mode '{mode.name}' exists in the reference backend only; use it (--backend reference)")


def check_record_length(inp: BeamformInput, mode: InterpMode) -> None:
    """Raise :class:`GridError` when the record is shorter than the mode's support."""
    taps = mode.taps_before + mode.taps_after + 1
    require(inp.n_samples >= taps, GridError,
            f"the record has {inp.n_samples} samples, fewer than the {taps} taps of interpolation mode '{mode.name}'")


def range_bases(inp: BeamformInput, grid: PolarGrid) -> np.ndarray:
    """Sample position (float64) of the two-way path ``2 R`` for each range:
    ``(2 R / c - t0) fs``."""
    return (2.0 * grid.ranges_m / inp.sound_speed_m_s - inp.t0_s) * inp.sample_rate_hz


def cell_windows(inp: BeamformInput, grid: PolarGrid, mode: InterpMode,
                 range_window_m: np.ndarray | None = None) -> np.ndarray:
    """First and end range index ``(n_angle, 2)`` of the cells worth computing.

    A cell is skipped when it lies outside the caller's per-angle range
    window (metres, ``(n_angle, 2)``) or when no channel's interpolation
    support can lie inside the record: since ``|d(o)| <= |o|`` for every
    offset ``o`` (triangle inequality), a range row whose base position is
    farther than ``(|o_src| + max |o_n|) fs / c + 1`` samples from the record
    cannot contribute.  Skipped cells get zeros, exactly what they would get
    when computed.
    """
    reach = (np.linalg.norm(inp.source_offset_m) + np.max(np.linalg.norm(inp.element_offsets_m, axis=1), initial=0.0))
    reach = reach * inp.samples_per_m + 2.0
    n_a, n_r = grid.shape
    if inp.tables is None:
        win = np.zeros((n_a, 2), dtype=np.int32)
        base = range_bases(inp, grid)
        ok = (base + reach >= mode.taps_before) & (base - reach <= inp.n_samples - 1 - mode.taps_after)
        if not ok.any():
            return win
        win[:, 0], win[:, 1] = int(np.argmax(ok)), int(n_r - np.argmax(ok[::-1]))
    else:  # per angle: the ray-traced time grows with range along an angle
        inp.check_tables(grid)
        win = _table_windows(inp, grid, mode, reach).copy()
    if range_window_m is not None:
        user = user_windows(grid, range_window_m)
        win[:, 0] = np.maximum(win[:, 0], user[:, 0])
        win[:, 1] = np.minimum(win[:, 1], user[:, 1])
    win[:, 1] = np.maximum(win[:, 1], win[:, 0])
    return win


#: (weak reference to the tables, {key: windows}) of the last grid's tables (:func:`_table_windows`): a line's
#: pings through one profile share them; replaced whole, so that a thread never files windows under another's tables
_TABLE_WINDOWS: tuple = (lambda: None, {})


def _table_windows(inp: BeamformInput, grid: PolarGrid, mode: InterpMode, reach: float) -> np.ndarray:
    """The record's windows of :func:`cell_windows` through ``inp.tables`` (read-only).  A paper-size grid's take
    0.1-0.2 s, so the last grid's are kept, per record start, rate, length, taps and reach (a list of points, a
    refinement's, one range and new tables each call, is neither kept nor lets them go)."""
    global _TABLE_WINDOWS
    keep = grid.shape[1] > 1
    key = (inp.t0_s, inp.sample_rate_hz, inp.n_samples, mode.taps_before, mode.taps_after, reach)
    entry = _TABLE_WINDOWS
    if keep and entry[0]() is not inp.tables:
        entry = _TABLE_WINDOWS = (weakref.ref(inp.tables), {})
    found = entry[1].get(key) if keep else None
    if found is not None:
        return found
    n_r = grid.shape[1]
    base = inp.cell_base_samples(grid)
    with np.errstate(invalid="ignore"):
        ok = (base + reach >= mode.taps_before) & (base - reach <= inp.n_samples - 1 - mode.taps_after)
    any_ok = ok.any(axis=1)
    win = np.zeros((grid.shape[0], 2), dtype=np.int32)
    win[:, 0] = np.where(any_ok, np.argmax(ok, axis=1), 0)
    win[:, 1] = np.where(any_ok, n_r - np.argmax(ok[:, ::-1], axis=1), 0)
    win.setflags(write=False)
    if keep:
        entry[1][key] = win
    return win


def user_windows(grid: PolarGrid, range_window_m: np.ndarray) -> np.ndarray:
    """First and end range index ``(n_angle, 2)`` of a per-angle range
    interval ``(n_angle, 2)`` in metres (both ends included)."""
    n_a = grid.shape[0]
    rw = np.asarray(range_window_m, dtype=np.float64)
    require(rw.shape == (n_a, 2), GridError, f"range window must be (n_angle, 2) = ({n_a}, 2), got {rw.shape}")
    require(bool(np.all(~np.isnan(rw))), GridError, "range window has NaN values")
    win = np.empty((n_a, 2), dtype=np.int32)
    win[:, 0] = np.searchsorted(grid.ranges_m, rw[:, 0], side="left")
    win[:, 1] = np.searchsorted(grid.ranges_m, rw[:, 1], side="right")
    win[:, 1] = np.maximum(win[:, 1], win[:, 0])
    return win


def baseband(data: np.ndarray, carrier_hz: float, sample_rate_hz: float) -> np.ndarray:
    """Remove the carrier: ``b[k] = p[k] exp(-2πj fc k / fs)`` (float64 phase)."""
    require(carrier_hz > 0, OptionError, "the basebanded mode needs the band centre frequency (pulse_f0/pulse_f1), none is known")
    k = np.arange(data.shape[-1], dtype=np.float64)
    phase = np.mod(2 * np.pi * carrier_hz / sample_rate_hz * k, 2 * np.pi)
    return data * np.exp(-1j * phase)


def carrier_phase(carrier_hz: float, sample_rate_hz: float, k: np.ndarray) -> np.ndarray:
    """Carrier phase (rad, in [0, 2π)) at integer sample ``k``, exact in float64
    for any record length (``k`` is split so the product keeps its digits)."""
    w = 2 * np.pi * carrier_hz / sample_rate_hz
    k = np.asarray(k, dtype=np.int64)
    hi, lo = np.divmod(k, 1 << 20)
    return np.mod(np.mod(w * (1 << 20), 2 * np.pi) * hi + w * lo, 2 * np.pi)


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


class Engine:
    """What both backends share: checks of the call, and the amplitude
    normalisation that keeps float32 sums of any data in range.

    (:attr:`_exponent_cache` holds the last data token's exponent: one tuple,
    replaced whole, so threads sharing an engine read a consistent pair.)

    A backend sets :attr:`name` and :attr:`precision` and implements
    ``_beamform(inp, grid, mode, outputs, range_window_m, scale) -> Sums``
    on the data times ``scale``, a power of two that brings their largest
    magnitude into ``[0.5, 1)`` (applied where the backend converts the data
    anyway, so it costs no extra pass).
    """

    name = ""
    precision = ""
    _exponent_cache: tuple | None = None

    def beamform(self, inp: BeamformInput, grid: PolarGrid, *, interp: str = "linear",
                 outputs=("intensity", "cf"), range_window_m: np.ndarray | None = None,
                 beams=None) -> Sums:
        """Image one ping: sums ``S, Q, M`` and from them intensity and CF.

        The data are divided by a power of two (:func:`amplitude_exponent`)
        before the sums and the results multiplied back exactly, so 1e-30 and
        1e30 amplitudes image alike in float32.

        Parameters
        ----------
        inp : BeamformInput
            Analytic channels and geometry (earth frame, offsets from the grid centre).
        grid : PolarGrid
            Image grid.
        interp : str
            Interpolation mode (:data:`clbeam.imaging.engine.INTERP_MODES`).
        outputs : iterable of str
            Any of ``"intensity"``, ``"cf"``, ``"sums"``.
        range_window_m : numpy.ndarray, optional
            ``(n_angle, 2)`` range interval (m) to compute per angle; others are 0.
        beams : BeamSampling, optional
            Beam-sampled imaging (:mod:`clbeam.imaging.engine.beams`): the
            sums on the beams the aperture resolves, interpolated to the
            grid; ``None``: every cell directly.

        Returns
        -------
        Sums
            The requested outputs in the units of ``inp.data``.
        """
        mode = interp_mode(interp)
        check_record_length(inp, mode)
        self._check_mode(mode)
        outs = check_outputs(outputs)
        if inp.data_token is None:  # the calls inside this one share the data
            inp = dataclasses.replace(inp, data_token=object())
        exponent = self._exponent(inp)
        scale = np.ldexp(1.0, -exponent)
        plan = None if beams is None else self._beam_plan(inp, grid, beams, range_window_m)
        if plan is None:
            t0 = time.perf_counter()
            sums = self._beamform(inp.for_grid(grid), grid, mode, outs, range_window_m, scale)
            sums.timings_s = {"direct_s": time.perf_counter() - t0}
        else:
            sums = self._beam_sampled(inp, grid, mode, outs, range_window_m, scale, plan)
        return sums.rescaled(exponent)

    def _beam_plan(self, inp: BeamformInput, grid: PolarGrid, beams, range_window_m):
        """The beam plan of ``grid`` for ``inp`` (:func:`beam_plan`), its band limit raised by the travel-time
        tables' angular rates where the input has tables (:func:`refracted_band_limit`); ``None`` (direct
        imaging, logged) when the beams would not save work."""
        limit = angular_band_limit(inp.element_offsets_m, inp.source_offset_m, inp.top_frequency_hz,
                                   inp.sample_rate_hz / inp.samples_per_m, grid.angles_deg)
        if inp.tables is None and inp.table_source is None:
            return beam_plan(grid, limit, beams, range_window_m)
        probe = inp.tables if inp.table_source is None else inp.table_source(probe_grid(grid))
        refracted = refracted_band_limit(limit, probe, inp.top_frequency_hz)
        plan = beam_plan(grid, refracted, beams, range_window_m)
        if plan is None:
            _info_once(f"beams off: the travel times through the sound-speed profile turn the sums at "
                       f"{refracted:.0f} cycles per radian across angles ({limit:.0f} for the array alone), more "
                       f"than beams save on {grid.shape[0]} angles: every cell imaged directly")
        return plan

    def _beam_sampled(self, inp, grid, mode, outs, range_window_m, scale, plan) -> Sums:
        """Sums on the plan's beams, interpolated to ``grid``; flagged cells imaged directly, as points."""
        weighted = inp.weights is not None
        t = [time.perf_counter()]
        beam = self._beam_sums(inp, plan, mode, scale)
        t.append(time.perf_counter())
        out_windows = user_windows(grid, range_window_m) if range_window_m is not None \
            else np.tile([0, grid.shape[1]], (grid.shape[0], 1))
        arrays, flagged = self._interpolate_beams(plan, beam, outs, out_windows, weighted, inp.min_channels)
        t.append(time.perf_counter())
        # flagged cells lie inside the windows; usually a few thousand spread over every angle, so they are
        # imaged as a list of points rather than as the angle rows they fall on
        rows, cols = flagged
        if rows.size:
            tables = node_tables(inp, grid, rows, cols)
            direct = self._beamform(dataclasses.replace(inp, tables=tables, table_source=None), tables.grid, mode,
                                    outs, None, scale)
            for name, value in _sums_arrays(direct).items():
                arrays[name][rows, cols] = value[:, 0]
        sums = _sums_from(arrays)
        sums.timings_s = {"beams_s": t[1] - t[0], "to_grid_s": t[2] - t[1], "flagged_s": time.perf_counter() - t[2]}
        return sums

    def _beam_sums(self, inp: BeamformInput, plan, mode: InterpMode, scale: float) -> Sums:
        """``S, Q, M, G`` (``W``) on the plan's beams: delay-and-sum in time, or in the frequency domain
        (:mod:`clbeam.imaging.engine.fdbeams`, its near rows and the record's ends in time) for a plan of
        that domain."""
        sums_out = frozenset({"sums", "signature"})
        if plan.domain != "frequency":
            return self._beamform(inp.for_grid(plan.grid), plan.grid, mode, sums_out, plan.beam_window_m, scale)
        from clbeam.imaging.engine.fdbeams import frequency_beam_sums

        return frequency_beam_sums(inp, plan.grid, steer=self._steering(), window_m=plan.beam_window_m, scale=scale,
                                   channel_numbers=channel_signature(inp.n_channels),
                                   time_domain=lambda rows: self._beamform(inp, rows, mode, sums_out,
                                                                           plan.beam_window_m, scale))

    def _steering(self):
        """The frequency-domain beams' steering sums (:func:`clbeam.imaging.engine.fdbeams.steer_numpy`'s
        signature): float64 NumPy here, a kernel on a device's engine."""
        from clbeam.imaging.engine.fdbeams import steer_numpy

        return steer_numpy

    def _exponent(self, inp: BeamformInput) -> int:
        """:func:`amplitude_exponent` of the data, kept for the last data token."""
        cached = self._exponent_cache
        if cached is not None and cached[0] is inp.data_token:
            return cached[1]
        exponent = amplitude_exponent(inp.data)
        self._exponent_cache = (inp.data_token, exponent)
        return exponent

    def _interpolate_beams(self, plan, beam: "Sums", outs, out_windows, weighted, min_channels: int = 1):
        """Output arrays and flagged cells from the beam sums (:func:`interpolate_beams`)."""
        return interpolate_beams(plan, beam, outs, out_windows, weighted, min_channels)

    def _check_mode(self, mode: InterpMode) -> None:
        """Raise :class:`OptionError` when this backend cannot run ``mode``."""

    def _beamform(self, inp, grid, mode, outs, range_window_m, scale: float) -> Sums:
        raise NotImplementedError


def _sums_arrays(sums: Sums) -> dict:
    """A :class:`Sums`' arrays by output name (``s`` complex)."""
    return {k: v for k, v in (("intensity", sums.intensity), ("cf", sums.cf), ("s", sums.s), ("q", sums.q),
                              ("m", sums.m), ("w", sums.w)) if v is not None}


def _sums_from(arrays: dict) -> Sums:
    return Sums(**{k: arrays.get(k) for k in ("intensity", "cf", "s", "q", "m", "w")})
