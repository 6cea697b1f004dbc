"""Beams in the frequency domain: the beam stage's sums ``S``, ``Q``, ``M`` from phase ramps on the channels' spectra.

A receive element ``o`` (an offset from the grid centre) delays the echo of a cell at range ``R`` and
angle ``theta`` by ``d(o; R, theta) = |R u - o| - R`` (``u = (0, sin theta, cos theta)``), and

    d(o; R, theta) = -u.o + (|o|^2 - (u.o)^2) / (2 R) + ...

depends on ``R`` only through the curvature term.  Over a *zone* of ranges whose ``1/R`` lies within
``h`` of the zone's focus ``1/R_z``, the beam's coherent sum is therefore, up to a bounded error, one
fixed delay per channel and beam:

    S(R, theta) = sum_n w_n p_n(t(R) + tau_n),   tau_n = (d(o_src; R_z, theta) + d(o_n; R_z, theta)) / c,

with ``t(R) = 2 R / c - t0``; on a channel's spectrum that delay is the phase ramp
``exp(i 2 pi f tau_n)``, exact on band-limited data (no time interpolation):

    B(f) = sum_n w_n X_n(f) exp(i 2 pi f tau_n),   S(R) = B's inverse transform at t(R).

``Q = sum w_n |p_n|^2`` is formed the same way from the spectra of the squared envelopes, with the same
delays: a channel kept on bins ``k0 .. k1 - 1`` has an envelope on bins ``-(k1 - k0 - 1) .. k1 - k0 - 1``
exactly, all of which are kept; the envelopes are squared at twice the sample rate, where that band
(twice the channels' width) does not alias.

**The zone bound.**  With ``s = 1/R`` and ``b^2 = |o|^2 - (u.o)^2`` (cells lie in the plane ``x = 0``),
``dd/ds = R^2 b^2 / (D (D + R - u.o))`` with ``D = |R u - o|``; for ``R > |o|`` this is at most
``b^2 kappa / 2`` with ``kappa = (R / (R - |o|))^2``.  So over a zone of half-width ``h`` in ``1/R``, from
the nearest range ``R_nf`` on, the path-length error of a channel is at most

    e = (|o_src|^2 + max_n |o_n|^2) kappa(R_nf) h / 2,      kappa(R) = (R / (R - max |o|))^2,

and zones evenly spaced in ``1/R`` with ``h = 2 e_max / (A kappa)`` (``A`` the bracket) hold ``e <= e_max``:
the cells ``[2 h k, 2 h (k + 1))`` of one lattice in ``1/R``, focused on their centres (so that any grid
over the same ranges has the same zones), ``floor(1/(2 h R_a)) - floor(1/(2 h R_b)) + 1`` of them over
``[R_a, R_b]``.  ``e_max`` is a fraction of the band's top wavelength (:data:`ZONE_PATH_ERROR_WAVELENGTHS`):
a phase error of at most ``2 pi`` times it.

**Segments.**  Each zone takes the stretch of record its rows and delays reach (``|d(o)| <= |o|``), with
:data:`SEGMENT_MARGIN` samples either side tapered to zero (Hann), to the frequency domain; the bins
holding all but :data:`DROPPED_ENERGY` of the segment's energy are kept, and the steered spectrum is
evaluated at the zone's range samples by a chirp-z transform (no interpolation).  Rows whose segment
would leave the record, rows nearer than the nearest zone (:data:`MIN_ZONE_ROWS`) and zones whose segment
holds a non-finite sample are formed in the time domain, by the caller's ``time_domain`` function; on the
others every channel is inside the record, so ``M`` is the number of channels (``W``, ``G`` their sums).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np
import scipy.fft
from scipy.signal import CZT

from clbeam.errors import GeometryError, GridError, OptionError, require
from clbeam.model.grid import PolarGrid

#: the zones' largest path-length error, as a fraction of the wavelength at the band's top.  On the bench
#: ping's calibration echoes (whose windows straddle zone edges as the image's cells do) 0.002 measured
#: -52.7 dB and |dCF| 0.011-0.012 (at the budget's margin, 0.0114), 0.001 -61.5 dB and 0.004-0.005, 0.0005
#: -70 dB (the intensity error falls with its square); a point on a zone's edge 150 m from a jittered array
#: had |dCF| 0.033 with 0.01
ZONE_PATH_ERROR_WAVELENGTHS = 0.001
#: a zone holds at least this many range rows: nearer rows (thinner zones) are formed in the time domain
MIN_ZONE_ROWS = 16
#: samples of record either side of a zone's reach, tapered to zero (Hann): a segment's spectrum then
#: spreads over about ``fs / SEGMENT_MARGIN`` beyond the data's own
SEGMENT_MARGIN = 128
#: fraction of a segment's energy the kept frequency bins may leave out.  The error of a left-out bin is
#: spread over the whole segment at the level of its strongest echo (a time interpolator's error follows the
#: local signal), and CF is measured on cells 40 dB below a point, where a 20 ms pulse's Q is 1e-5 of its
#: peak's: leaving out 1e-7 left errors of 1.6e-4 of the peak in |p| there, 1e-9 leaves 2e-6.  On
#: compressed pulses whose spectrum reaches the Nyquist frequency at that level, nearly every positive
#: frequency is kept.
DROPPED_ENERGY = 1e-9
#: the zones' nearest range is at least this many times the largest offset: ``kappa`` at most (4/3)^2
NEAR_FIELD_OFFSETS = 4.0
#: FFT worker threads
WORKERS = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


@dataclass(frozen=True)
class ZonePlan:
    """Range zones of one beam grid.

    Attributes
    ----------
    bounds : numpy.ndarray
        ``(n_zone + 1,)`` int: zone ``z`` holds range rows ``bounds[z] .. bounds[z + 1] - 1``; rows before
        ``bounds[0]`` and from ``bounds[-1]`` on are the time domain's.
    focus_m : numpy.ndarray
        ``(n_zone,)`` focus range ``R_z`` of each zone (m): ``1/R_z`` the middle of its rows' ``1/R``.
    path_error_bound_m : float
        The bound (m) on any channel's path-length error of these zones (module description).
    allowed_m : float
        The largest path-length error allowed (m), from which the zone width was chosen.
    kappa : float
        The bound's near-field factor at the nearest zone.
    """

    bounds: np.ndarray
    focus_m: np.ndarray
    path_error_bound_m: float
    allowed_m: float
    kappa: float

    @property
    def n_zones(self) -> int:
        """Number of zones."""
        return self.focus_m.size


def curvature_constant_m2(element_offsets_m: np.ndarray, source_offset_m: np.ndarray) -> float:
    """``A = |o_src|^2 + max_n |o_n|^2`` (m^2): twice the largest curvature term's numerator of a two-way path."""
    o = np.asarray(element_offsets_m, dtype=np.float64)
    return float(np.dot(source_offset_m, source_offset_m) + np.max(np.sum(o * o, axis=1), initial=0.0))


def near_field_factor(range_m: float, max_offset_m: float) -> float:
    """``kappa(R) = (R / (R - max |o|))^2``, the bound's factor at range ``R`` (m); ``inf`` within the offsets."""
    return (range_m / (range_m - max_offset_m)) ** 2 if range_m > max_offset_m else math.inf


def zone_plan(inp, grid: PolarGrid, *, path_error_wavelengths: float = ZONE_PATH_ERROR_WAVELENGTHS,
              margin: int = SEGMENT_MARGIN, min_zone_rows: int = MIN_ZONE_ROWS) -> ZonePlan:
    """Range zones of ``grid`` for ``inp`` (straight rays) whose path-length error is at most
    ``path_error_wavelengths`` times the band's top wavelength (module description).

    Parameters
    ----------
    inp : BeamformInput
        Channels and geometry (offsets from the grid centre, m).
    grid : PolarGrid
        The beam grid (ranges increasing, m).
    path_error_wavelengths : float
        ``e_max`` in wavelengths at ``inp.top_frequency_hz``.
    margin : int
        Samples each zone's segment needs beyond its reach inside the record.
    min_zone_rows : int
        Rows a zone holds at least: nearer ranges (thinner zones) are left to the time domain.
    """
    require(math.isfinite(path_error_wavelengths) and 0 < path_error_wavelengths <= 0.25, OptionError,
            f"the zones' path error must be within (0, 0.25] wavelength, got {path_error_wavelengths!r}")
    r = np.asarray(grid.ranges_m, dtype=np.float64)
    require(r.size < 2 or bool(np.all(np.diff(r) > 0)), GridError, "the beam grid's ranges must increase")
    c = inp.sound_speed_m_s
    allowed = path_error_wavelengths * c / inp.top_frequency_hz
    a2 = curvature_constant_m2(inp.element_offsets_m, inp.source_offset_m)
    o_max = max(float(np.linalg.norm(inp.source_offset_m)),
                float(np.max(np.linalg.norm(inp.element_offsets_m, axis=1), initial=0.0)))
    rows = _covered_rows(inp, grid, margin)
    if a2 == 0:   # every offset zero: the delays are range-independent, one zone
        kappa, half = 1.0, math.inf
    else:
        r_floor = NEAR_FIELD_OFFSETS * o_max
        kappa = near_field_factor(r_floor, o_max)
        half = 2.0 * allowed / (a2 * kappa)
        dr = round(float(np.median(np.diff(r))), 9) if r.size > 1 else 1.0   # to 1 nm: any window of a grid alike
        r_nf = max(r_floor, math.sqrt(min_zone_rows * dr / (2.0 * half)))
        kappa = near_field_factor(r_nf, o_max)          # at most the floor's: wider zones from here on
        half = 2.0 * allowed / (a2 * kappa)
        rows &= r >= r_nf
    idx = np.flatnonzero(rows)
    if idx.size == 0:
        return ZonePlan(np.zeros(1, np.int64), np.zeros(0), 0.0, allowed, kappa)
    ja, jb = int(idx[0]), int(idx[-1]) + 1        # the rows in between are covered too (ranges increase)
    s = 1.0 / r[ja:jb]
    if not math.isfinite(half):
        return ZonePlan(np.array([ja, jb], np.int64), np.array([1.0 / (0.5 * (s[0] + s[-1]))]), 0.0, allowed, kappa)
    # zones are the cells [2 h k, 2 h (k + 1)) of one lattice in 1/R, focused on their centres: any grid over
    # the same ranges (a calibration window, a seabed band) has the image's zones
    cell = np.floor(s / (2.0 * half)).astype(np.int64)
    bounds = ja + np.r_[0, np.flatnonzero(np.diff(cell)) + 1, s.size]
    s_focus = (cell[bounds[:-1] - ja] + 0.5) * 2.0 * half
    worst = np.maximum(np.abs(s[bounds[:-1] - ja] - s_focus), np.abs(s[bounds[1:] - 1 - ja] - s_focus))
    bound = 0.5 * a2 * kappa * float(np.max(worst))
    focus = 1.0 / s_focus
    return ZonePlan(bounds.astype(np.int64), focus, bound, allowed, kappa)


def range_bases(inp, grid: PolarGrid) -> np.ndarray:
    """Sample position (float64) of the two-way path ``2 R`` of each range, ``(2 R / c - t0) fs``: the engine's
    :func:`clbeam.imaging.engine.common.range_bases` (not imported: the engine imports this module)."""
    return (2.0 * grid.ranges_m / inp.sound_speed_m_s - inp.t0_s) * inp.sample_rate_hz


@dataclass
class BeamSums:
    """The beam stage's sums, each ``(n_beam, n_range)``: what the beam-to-grid interpolation reads.

    Attributes
    ----------
    s : numpy.ndarray
        complex128 coherent sum ``S`` (data units).
    q : numpy.ndarray
        float64 incoherent sum ``Q`` (squared data units).
    m : numpy.ndarray
        int32 channel count ``M``.
    signature : numpy.ndarray or None
        ``G``, the sum of the contributing channels' numbers ``g_n``.
    w : numpy.ndarray or None
        ``W``, the sum of their weights (apodized sums).
    """

    s: np.ndarray
    q: np.ndarray
    m: np.ndarray
    signature: np.ndarray | None
    w: np.ndarray | None = None


def _covered_rows(inp, grid: PolarGrid, margin: int) -> np.ndarray:
    """Bool per range row: every channel's delay, with ``margin`` samples and a tap either side, is inside the
    record (``|d(o)| <= |o|``)."""
    reach = (np.linalg.norm(inp.source_offset_m) + np.max(np.linalg.norm(inp.element_offsets_m, axis=1),
                                                           initial=0.0)) * inp.samples_per_m
    base = range_bases(inp, grid)
    return (base - reach - margin - 1 >= 0) & (base + reach + margin + 1 <= inp.n_samples - 1)


def offset_delays_m(offsets_m: np.ndarray, range_m: float, angles_deg: np.ndarray) -> np.ndarray:
    """``d(o; R, theta) = |R u - o| - R`` (m) for every angle and offset, ``(n_angle, n_offset)``, without
    cancellation: ``(|o|^2 - 2 R u.o) / (|R u - o| + R)``."""
    o = np.atleast_2d(np.asarray(offsets_m, dtype=np.float64))
    th = np.deg2rad(np.asarray(angles_deg, dtype=np.float64))[:, None]
    uy, uz = np.sin(th), np.cos(th)
    dist = np.sqrt(o[None, :, 0] ** 2 + (range_m * uy - o[None, :, 1]) ** 2 + (range_m * uz - o[None, :, 2]) ** 2)
    return (np.sum(o * o, axis=1)[None, :] - 2.0 * range_m * (uy * o[None, :, 1] + uz * o[None, :, 2])) / (dist + range_m)


def zone_delays_samples(inp, angles_deg: np.ndarray, focus_m: float) -> np.ndarray:
    """Each beam's and channel's delay at a zone's focus (samples), ``(n_beam, n_channel)``:
    ``(d(o_src) + d(o_n)) fs / c``."""
    d_src = offset_delays_m(inp.source_offset_m, focus_m, angles_deg)
    d_el = offset_delays_m(inp.element_offsets_m, focus_m, angles_deg)
    return (d_src + d_el) * inp.samples_per_m


def steer_numpy(spectra: np.ndarray, delays_cycles: np.ndarray, first_bin: int) -> np.ndarray:
    """The steering sums in float64: ``B[b, k] = sum_n X[n, k] exp(i 2 pi (first_bin + k) delays[b, n])``.

    Parameters
    ----------
    spectra : numpy.ndarray
        ``(n_channel, n_bin)`` complex: bins ``first_bin ..`` of each channel (weights applied).
    delays_cycles : numpy.ndarray
        ``(n_beam, n_channel)``: delay over the transform's length (cycles per bin, ``tau / L``).
    first_bin : int
        Index of the first bin in the transform.

    Returns
    -------
    numpy.ndarray
        ``(n_beam, n_bin)`` complex128.
    """
    x = np.asarray(spectra, dtype=np.complex128)
    k = first_bin + np.arange(x.shape[1], dtype=np.float64)
    out = np.empty((delays_cycles.shape[0], x.shape[1]), dtype=np.complex128)
    for b0 in range(0, delays_cycles.shape[0], 8):
        d = np.asarray(delays_cycles[b0:b0 + 8], dtype=np.float64)
        ph = d[:, :, None] * k[None, None, :]
        ph -= np.rint(ph)                          # exact reduction to [-1/2, 1/2] cycle
        out[b0:b0 + 8] = np.einsum("nk,bnk->bk", x, np.exp(2j * np.pi * ph))
    return out


def kept_bins(power: np.ndarray, dropped: float = DROPPED_ENERGY) -> tuple[int, int]:
    """``(first, end)``: the shortest run of bins holding all but ``dropped`` of ``power``'s sum (half of it
    left at each end); ``(0, 0)`` for zero power."""
    total = float(np.sum(power))
    if total <= 0:
        return 0, 0
    cum = np.cumsum(power) / total
    first = int(np.searchsorted(cum, 0.5 * dropped, side="right"))
    end = int(np.searchsorted(cum, 1.0 - 0.5 * dropped, side="left")) + 1
    return first, max(min(end, power.size), first + 1)


def hann_taper(n: int, margin: int) -> np.ndarray:
    """1 inside, Hann ramps over ``margin`` samples at both ends (``n >= 2 margin``)."""
    w = np.ones(n)
    ramp = 0.5 - 0.5 * np.cos(np.pi * (np.arange(margin) + 0.5) / margin)
    w[:margin], w[n - margin:] = ramp, ramp[::-1]
    return w


@dataclass
class _Zone:
    """One zone's rows, segment and transforms."""

    rows: slice
    start: int            # first sample of the segment
    end: int              # end sample of the segment
    length: int           # transform length L (>= end - start)
    positions: np.ndarray  # the rows' sample positions within the segment


def _zone_segment(inp, base: np.ndarray, rows: slice, margin: int) -> _Zone:
    """The stretch of record zone ``rows`` reaches: every channel's delay (``|d(o)| <= |o|``), a tap and
    ``margin`` tapered samples either side."""
    reach = (np.linalg.norm(inp.source_offset_m) + np.max(np.linalg.norm(inp.element_offsets_m, axis=1),
                                                           initial=0.0)) * inp.samples_per_m
    s0 = int(math.floor(base[rows.start] - reach)) - margin - 1
    s1 = int(math.ceil(base[rows.stop - 1] + reach)) + margin + 2
    return _Zone(rows, s0, s1, scipy.fft.next_fast_len(s1 - s0), base[rows] - s0)


def evaluate_at(spectrum: np.ndarray, first_bin: int, length: int, positions: np.ndarray) -> np.ndarray:
    """``(1/L) sum_k B[.., k] exp(i 2 pi (first_bin + k) x_j / L)`` at positions ``x_j`` (samples, uniformly
    spaced), by a chirp-z transform along the last axis."""
    x = np.asarray(positions, dtype=np.float64)
    n_bin, m = spectrum.shape[-1], x.size
    step = float(x[1] - x[0]) if m > 1 else 0.0
    require(m < 3 or bool(np.allclose(np.diff(x), step, rtol=0, atol=1e-9 * max(abs(step), 1.0))), GridError,
            f"frequency-domain beams need uniformly spaced ranges, got steps from {np.min(np.diff(x), initial=step):.6g} to "
            f"{np.max(np.diff(x), initial=step):.6g} samples")
    czt = CZT(n_bin, m, w=np.exp(2j * np.pi * step / length), a=np.exp(-2j * np.pi * x[0] / length))
    carrier = np.exp(2j * np.pi * ((first_bin * x / length) % 1.0))
    with scipy.fft.set_workers(WORKERS):          # the transform's FFTs on every core
        return czt(spectrum, axis=-1) * carrier / length


def frequency_beam_sums(inp, grid: PolarGrid, *, time_domain, steer=steer_numpy,
                        channel_numbers: np.ndarray | None = None, window_m: np.ndarray | None = None,
                        scale: float = 1.0, zones: ZonePlan | None = None, margin: int = SEGMENT_MARGIN) -> BeamSums:
    """``S``, ``Q``, ``M`` (``W`` with apodization) and the channel signature ``G`` on a beam grid, formed in
    the frequency domain zone by zone (module description).

    Parameters
    ----------
    inp : clbeam.imaging.engine.BeamformInput
        Channels and geometry (straight rays: no travel-time tables).
    grid : PolarGrid
        The beams (angles, degree) at uniformly spaced ranges (m).
    time_domain : callable
        ``time_domain(rows_grid)`` -> the engine's sums (``s``, ``q``, ``m``, ``signature``, ``w`` with
        apodization) on a grid of the same beams at some of the ranges: the rows the zones do not hold.
    steer : callable
        ``steer(spectra, delays_cycles, first_bin)`` as :func:`steer_numpy` (an OpenCL kernel's wrapper).
    channel_numbers : numpy.ndarray, optional
        ``(n_channel,)`` ``g_n`` (:func:`clbeam.imaging.engine.common.channel_signature`): ``G`` on the zones'
        rows is their sum; ``None``: no ``G``.
    window_m : numpy.ndarray, optional
        ``(n_beam, 2)`` range interval (m) per beam; cells outside it are 0.
    scale : float
        Factor on the data (a power of two, :meth:`clbeam.imaging.engine.common.Engine.beamform`).
    zones : ZonePlan, optional
        Default :func:`zone_plan` of ``inp`` and ``grid``.
    margin : int
        Tapered samples either side of each segment.
    """
    require(inp.tables is None and inp.table_source is None, OptionError,
            "frequency-domain beams need straight rays; image through a sound-speed profile with time-domain beams")
    require(grid.shape[1] < 3 or bool(np.allclose(np.diff(grid.ranges_m), grid.ranges_m[1] - grid.ranges_m[0])),
            GridError, "frequency-domain beams need uniformly spaced ranges, got steps from "
            f"{np.diff(grid.ranges_m).min():.6g} to {np.diff(grid.ranges_m).max():.6g} m")
    zones = zone_plan(inp, grid, margin=margin) if zones is None else zones
    shape = grid.shape
    out = BeamSums(s=np.zeros(shape, np.complex128), q=np.zeros(shape), m=np.zeros(shape, np.int32),
                   signature=None if channel_numbers is None else np.zeros(shape),
                   w=None if inp.weights is None else np.zeros(shape))
    time_rows = _zones_into(inp, grid, zones, steer, scale, margin, channel_numbers, out, window_m)
    _time_domain_rows(grid, time_rows, time_domain, out)
    if window_m is not None:
        _clear_outside(grid, window_m, out)
    return out


def zone_beams(grid: PolarGrid, rows: slice, window_m: np.ndarray | None) -> np.ndarray:
    """Indices of the beams whose range interval (``window_m``, ``(n_beam, 2)`` m; ``None``: every beam) meets
    the zone's ``rows`` of ``grid``: the only ones a zone's sums are formed on."""
    if window_m is None:
        return np.arange(grid.shape[0])
    rw = np.asarray(window_m, dtype=np.float64)
    require(rw.shape == (grid.shape[0], 2), GeometryError,
            f"beam windows must be (n_beam, 2) = ({grid.shape[0]}, 2), got {rw.shape}")
    r0, r1 = float(grid.ranges_m[rows.start]), float(grid.ranges_m[rows.stop - 1])
    return np.flatnonzero((rw[:, 0] <= r1) & (rw[:, 1] >= r0))


def _zones_into(inp, grid, zones: ZonePlan, steer, scale: float, margin: int, channel_numbers, out: BeamSums,
                window_m: np.ndarray | None = None):
    """Every zone's sums into ``out`` on the beams whose window meets it (:func:`zone_beams`; a zone no window
    meets is not transformed); returns the rows left to the time domain (bool per row)."""
    weights = np.ones(inp.n_channels) if inp.weights is None else np.asarray(inp.weights, dtype=np.float64)
    base = range_bases(inp, grid)
    time_rows = np.ones(grid.shape[1], dtype=bool)
    for z in range(zones.n_zones):
        rows = slice(int(zones.bounds[z]), int(zones.bounds[z + 1]))
        beams = zone_beams(grid, rows, window_m)
        if beams.size == 0:
            time_rows[rows] = False               # outside every window: cleared, nothing to form
            continue
        zone = _zone_segment(inp, base, rows, margin)
        seg = np.asarray(inp.data[:, zone.start:zone.end])
        if not np.all(np.isfinite(seg)):
            continue                              # skipped samples: these rows in the time domain
        _zone_sums(inp, grid, zone, seg * scale, weights, zones.focus_m[z], steer, out, margin, beams)
        out.m[:, rows] = inp.n_channels           # every channel is inside the record on a zone's rows
        if out.signature is not None:
            out.signature[:, rows] = float(np.sum(channel_numbers))
        if out.w is not None:
            out.w[:, rows] = float(np.sum(weights))
        time_rows[rows] = False
    return time_rows


def _zone_sums(inp, grid, zone: _Zone, seg: np.ndarray, weights: np.ndarray, focus_m: float, steer,
               out: BeamSums, margin: int, beams: np.ndarray) -> None:
    """One zone's ``S`` and ``Q`` on ``beams`` (indices) into ``out``: the tapered segment's kept bins steered
    and evaluated at the rows; ``Q`` from the squared envelopes of the same band-limited channels at twice the
    rate (the envelope's band, twice the channels' width, would alias at their rate)."""
    taper = hann_taper(seg.shape[1], margin)
    n_fft = zone.length
    spec = scipy.fft.fft(seg * taper, n_fft, axis=-1, workers=WORKERS)
    delays = zone_delays_samples(inp, grid.angles_deg[beams], focus_m) / n_fft     # cycles per bin (either rate)
    k0, k1 = kept_bins(np.fft.fftshift(np.sum(weights[:, None] ** 2 * np.abs(spec) ** 2, axis=0)))
    if k1 <= k0:
        return
    first = k0 - n_fft // 2                       # bins from -L/2 on: negative frequencies kept where present
    bins = np.arange(first, first + k1 - k0)
    kept = np.take(spec, bins % n_fft, axis=1)
    out.s[beams, zone.rows] = evaluate_at(steer(weights[:, None] * kept, delays, first), first, n_fft,
                                          zone.positions)
    up = np.zeros((seg.shape[0], 2 * n_fft), np.complex128)
    up[:, bins % (2 * n_fft)] = kept
    envelope = np.abs(2.0 * scipy.fft.ifft(up, axis=-1, workers=WORKERS)) ** 2
    env_spec = scipy.fft.rfft(envelope * weights[:, None], axis=-1, workers=WORKERS)
    # |p|^2 of a signal on bins k0 .. k1 - 1 lies on bins -(k1 - k0 - 1) .. k1 - k0 - 1: all of them, exactly
    env_spec = env_spec[:, :k1 - k0]              # from DC on (a real signal's two-sided spectrum)
    env_spec[:, 0] *= 0.5                         # the DC bin once in 2 Re(...)
    out.q[beams, zone.rows] = 2.0 * evaluate_at(steer(env_spec, delays, 0), 0, 2 * n_fft, 2.0 * zone.positions).real


def _time_domain_rows(grid: PolarGrid, rows: np.ndarray, time_domain, out: BeamSums) -> None:
    """The rows the zones do not hold, from ``time_domain``."""
    idx = np.flatnonzero(rows)
    if idx.size == 0:
        return
    sub = time_domain(PolarGrid.beams(grid.ranges_m[idx], grid.angles_deg))
    out.s[:, idx], out.q[:, idx], out.m[:, idx] = sub.s, sub.q, sub.m
    if out.signature is not None:
        out.signature[:, idx] = sub.signature
    if out.w is not None:
        out.w[:, idx] = sub.w


def _clear_outside(grid: PolarGrid, window_m: np.ndarray, out: BeamSums) -> None:
    """Zero every output outside each beam's range interval (m), as the time-domain beam stage leaves them."""
    rw = np.asarray(window_m, dtype=np.float64)
    require(rw.shape == (grid.shape[0], 2), GeometryError,
            f"beam windows must be (n_beam, 2) = ({grid.shape[0]}, 2), got {rw.shape}")
    r = grid.ranges_m[None, :]
    outside = (r < rw[:, :1]) | (r > rw[:, 1:])
    for a in (out.s, out.q, out.m, out.signature, out.w):
        if a is not None:
            a[outside] = 0
