"""Beam-sampled imaging: the sums on the beams the aperture resolves, interpolated to the grid.

At one range the coherent sum ``S(R, theta)`` of an array is band-limited in
angle: element ``n`` contributes a phase ``2 pi f d_n(theta) / c`` whose rate
of change with ``theta`` is at most ``2 pi f |o_n| / c`` (``o_n`` its offset
from the grid centre, the source likewise), so ``S`` holds at most

    B = f_top (|o_src| + max |o_n|) / c        cycles per radian

(``f_top`` the top of the pulse band).  Sampled every ``1 / (2 B K)``
radians (``K`` >= 1 the oversampling), ``S`` and the slower ``Q = sum |p|^2``
are recovered at any angle by a windowed-sinc interpolation with ``T``
taps; intensity ``|S|^2`` and ``CF = |S|^2 / (M Q)`` are formed from the
interpolated sums, never interpolated themselves.  On the paper's grid
(0.1 degree over +-80 degrees, 64 elements over 3.5 m, 2-9 kHz) about 100
beams carry what 1601 angles hold.

The beams are uniform in angle (the band limit in ``theta`` is largest at
nadir and shrinks with ``cos theta`` elsewhere) and may extend beyond +-90
degrees: the delay-and-sum is defined there too (points above the array),
so output angles near the swath edge keep their full two-sided support.

``M`` (and ``W`` with apodization) is piecewise constant in angle: it
changes only where a channel's delay leaves the record or meets a skipped
sample.  A cell is interpolated only when every tap beam at its range has
the same ``M`` (and ``W``): then ``M`` and ``W`` are exact, and ``S``,
``Q`` sums of the same channels (a per-channel signature summed with them,
:func:`clbeam.imaging.engine.common.channel_signature`, must agree too, so
that two different sets of as many channels are told apart).  The other cells (thin shells at the
record's ends, unreachable rays, skipped samples) are flagged and imaged
directly, so the result equals the direct image there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.model.grid import PolarGrid

#: Kaiser window shape of the angular interpolator (sidelobes about -60 dB)
KAISER_BETA = 8.0
#: a beam grid is used only when it has fewer beams than this fraction of the output angles
MIN_SAVING = 0.7
#: channel signatures closer than this are the same channels: above float32 rounding of a sum of
#: 64 numbers in [1, 2) (4e-4), below the smallest difference of two channels' numbers (0.006 for 64)
SIGNATURE_TOLERANCE = 2e-3


@dataclass(frozen=True)
class BeamSampling:
    """How finely the beams sample the aperture's band limit, and how they are interpolated.

    Attributes
    ----------
    oversampling : float
        ``K >= 1``: beams every ``1 / (2 B K)`` rad (``B`` the angular band limit).
    taps : int
        Even number of beams each output angle is interpolated from (Kaiser-windowed sinc).
    domain : {"time", "frequency"}
        How the beams' sums are formed: delay-and-sum with the setting's time interpolation, or phase
        ramps on the channels' spectra zone by zone (:mod:`clbeam.imaging.engine.fdbeams`; straight rays).
    """

    oversampling: float = 1.5
    taps: int = 12
    domain: str = "time"

    def __post_init__(self):
        require(self.domain in ("time", "frequency"), OptionError,
                f"beam domain must be 'time' or 'frequency', got {self.domain!r}")
        require(math.isfinite(self.oversampling) and 1.0 <= self.oversampling <= 16.0, OptionError,
                f"beam oversampling must be within 1-16, got {self.oversampling!r}")
        require(int(self.taps) == self.taps and self.taps >= 2 and self.taps % 2 == 0 and self.taps <= 64, OptionError,
                f"beam taps must be an even integer 2-64, got {self.taps!r}")


def angular_band_limit(offsets_m: np.ndarray, source_offset_m: np.ndarray, top_frequency_hz: float,
                       sound_speed_m_s: float, angles_deg: np.ndarray) -> float:
    """Highest angular frequency (cycles per radian) of the coherent sum over the given angles.

    A point ``o`` (offset from the grid centre) delays a cell at angle
    ``theta`` by ``-(o_y sin(theta) + o_z cos(theta)) / c`` (plane-wave
    term), which turns at ``(o_y cos(theta) - o_z sin(theta)) / c`` per
    radian: the sum of the source's and the largest element's rate, times
    ``f_top``, maximised over the angles.
    """
    th = np.deg2rad(np.asarray(angles_deg, dtype=np.float64))
    c, s = np.cos(th)[:, None], np.sin(th)[:, None]
    o = np.asarray(offsets_m, dtype=np.float64)
    rate_el = np.max(np.abs(c * o[None, :, 1] - s * o[None, :, 2]), axis=1, initial=0.0)
    so = np.asarray(source_offset_m, dtype=np.float64)
    rate_src = np.abs(c[:, 0] * so[1] - s[:, 0] * so[2])
    return top_frequency_hz * float(np.max(rate_el + rate_src)) / sound_speed_m_s


#: the angular rates of ray-traced tables are measured on a probe grid this fine in angle (degree) and
#: with this many ranges, and raised by this factor: the probe's finite differences sample the rates'
#: maxima, they do not bound them
PROBE_ANGLE_STEP_DEG = 0.25
PROBE_RANGES = 64
REFRACTION_MARGIN = 1.25


def probe_grid(grid: PolarGrid) -> PolarGrid:
    """A coarse grid over ``grid``'s ranges and angles on which :func:`refracted_band_limit` measures the
    travel-time tables' rates (``PROBE_RANGES`` ranges, ``PROBE_ANGLE_STEP_DEG`` apart in angle at most)."""
    a0, a1 = float(grid.angles_deg[0]), float(grid.angles_deg[-1])
    n_a = max(3, math.ceil((a1 - a0) / PROBE_ANGLE_STEP_DEG) + 1)
    r = grid.ranges_m
    ranges = np.linspace(float(r[0]), float(r[-1]), min(PROBE_RANGES, r.size)) if r.size > 1 else r.copy()
    return PolarGrid.beams(ranges, np.linspace(a0, a1, n_a))


def refracted_band_limit(base_limit: float, tables, top_frequency_hz: float,
                         margin: float = REFRACTION_MARGIN) -> float:
    """Angular band limit (cycles per radian) of the coherent sum with ray-traced travel times.

    With a sound-speed profile the centre's two-way time ``2 T(R, theta)`` changes along an arc of
    constant range (in isospeed water it does not), and the rays leave the array at a launch angle
    ``phi(R, theta)`` that turns faster or slower than ``theta``.  A channel's delay then turns at most at
    ``2 |dT/dtheta| + |d delta/dphi| |dphi/dtheta|`` seconds per radian, so

        B = margin * (B_0 max(1, max |dphi/dtheta|) + 2 f_top max |dT/dtheta|)

    with ``B_0`` the isospeed limit of the array (:func:`angular_band_limit`), the rates measured on the
    tables by finite differences along angle (``margin`` covers their sampling).

    Parameters
    ----------
    base_limit : float
        ``B_0`` (cycles per radian).
    tables : clbeam.imaging.raytrace.TravelTimeTables
        Tables of a grid with at least two angles (e.g. :func:`probe_grid`'s).
    top_frequency_hz : float
        Top of the signal band (Hz).
    margin : float
        Factor >= 1 on the result.

    Returns
    -------
    float
        ``B`` (cycles per radian).  Cells no ray reaches are left out: the beams' interpolation flags
        the cells whose tap beams summed different channels there, and those are imaged directly.
    """
    th = np.deg2rad(np.asarray(tables.grid.angles_deg, dtype=np.float64))
    if th.size < 2:
        return base_limit
    dth = np.diff(th)[:, None]
    t = np.where(tables.reachable, tables.time_s, np.nan)
    phi = np.arctan2(tables.launch_sin, tables.launch_cos)
    both = tables.reachable[1:] & tables.reachable[:-1]
    if not both.any():
        return base_limit
    time_rate = float(np.max(np.abs(np.diff(t, axis=0))[both] / np.broadcast_to(dth, both.shape)[both]))
    launch_rate = float(np.max(np.abs(np.diff(phi, axis=0))[both] / np.broadcast_to(dth, both.shape)[both]))
    return margin * (base_limit * max(1.0, launch_rate) + 2.0 * top_frequency_hz * time_rate)


def kaiser_sinc(x: np.ndarray, half_width: int, beta: float = KAISER_BETA) -> np.ndarray:
    """Kaiser-windowed sinc at offsets ``x`` (samples), zero for ``|x| >= half_width``."""
    arg = np.clip(1.0 - (x / half_width) ** 2, 0.0, None)
    return np.where(np.abs(x) < half_width, np.sinc(x) * np.i0(beta * np.sqrt(arg)) / np.i0(beta), 0.0)


@dataclass(frozen=True)
class BeamPlan:
    """The beam grid of one call and the interpolation from it to the output grid.

    Attributes
    ----------
    grid : PolarGrid
        Beams (uniform in angle, possibly beyond +-90 degrees) at the output's ranges.
    first_tap : numpy.ndarray
        ``(n_angle,)`` int: the first beam of each output angle's support.
    weights : numpy.ndarray
        ``(n_angle, taps)`` interpolation weights (each row sums to 1).
    beam_window_m : numpy.ndarray or None
        ``(n_beam, 2)`` range interval (m) to compute per beam: what the
        output windows need; ``None`` for every range.
    domain : str
        :attr:`BeamSampling.domain` of the sampling it was made for.
    """

    grid: PolarGrid
    first_tap: np.ndarray
    weights: np.ndarray
    beam_window_m: np.ndarray | None
    domain: str = "time"

    @property
    def taps(self) -> int:
        """Beams per output angle."""
        return self.weights.shape[1]


def beam_plan(grid: PolarGrid, band_limit_cycles_per_rad: float, sampling: BeamSampling,
              range_window_m: np.ndarray | None = None, *, granularity: int = 1) -> BeamPlan | None:
    """The beam grid for ``grid``, or ``None`` when it would not save work.

    Parameters
    ----------
    grid : PolarGrid
        The output grid.
    band_limit_cycles_per_rad : float
        :func:`angular_band_limit` of the ping.
    sampling : BeamSampling
        Oversampling and taps.
    range_window_m : numpy.ndarray, optional
        ``(n_angle, 2)`` output range windows (m).
    granularity : int
        Round the beam count up to a multiple of this, the beams made denser
        to fill it (engines call with 1, so every backend images on the same
        beams and gives the same result).
    """
    if band_limit_cycles_per_rad <= 0:
        return None
    step = 1.0 / (2.0 * band_limit_cycles_per_rad * sampling.oversampling)  # rad, at most
    half = sampling.taps // 2
    theta = np.deg2rad(grid.angles_deg)
    span = float(theta[-1] - theta[0])
    n_beams = math.ceil(span / step) + 2 * half + 1
    n_beams = -(-n_beams // granularity) * granularity
    if n_beams >= MIN_SAVING * theta.size:
        return None
    step = span / (n_beams - 2 * half - 1) if span > 0 else step
    beam_theta = theta[0] + step * (np.arange(n_beams) - half)
    beams = PolarGrid.beams(grid.ranges_m, np.rad2deg(beam_theta))
    pos = (theta - beam_theta[0]) / step                      # output angles in beam steps
    first = np.clip(np.floor(pos).astype(np.int64) - half + 1, 0, n_beams - sampling.taps)
    offsets = pos[:, None] - (first[:, None] + np.arange(sampling.taps)[None, :])
    w = kaiser_sinc(offsets, half)
    w /= w.sum(axis=1, keepdims=True)
    window = None if range_window_m is None else _beam_windows(range_window_m, first, sampling.taps, n_beams)
    return BeamPlan(beams, first.astype(np.int32), w, window, sampling.domain)


def _beam_windows(range_window_m: np.ndarray, first: np.ndarray, taps: int, n_beams: int) -> np.ndarray:
    """Per beam, the union of the range windows of the output angles it serves (m)."""
    rw = np.asarray(range_window_m, dtype=np.float64)
    out = np.column_stack([np.full(n_beams, np.inf), np.full(n_beams, -np.inf)])
    for k in range(taps):
        np.minimum.at(out[:, 0], first + k, rw[:, 0])
        np.maximum.at(out[:, 1], first + k, rw[:, 1])
    unused = ~np.isfinite(out[:, 0])
    out[unused] = (0.0, -1.0)  # an empty interval: the beam serves no output angle
    return out


def interpolate_beams(plan: BeamPlan, beam, outputs: frozenset, out_windows: np.ndarray, weighted: bool,
                      min_channels: int = 1):
    """Output sums from the beam sums (the float64 oracle of the OpenCL kernel).

    Parameters
    ----------
    plan : BeamPlan
    beam : Sums
        ``s``, ``q``, ``m`` (and ``w`` when ``weighted``) on the beam grid.
    outputs : frozenset of str
        Requested outputs.
    out_windows : numpy.ndarray
        ``(n_angle, 2)`` first and end range index of the cells to compute.
    weighted : bool
        Apodized sums (``W`` given).
    min_channels : int
        CF is 0 where ``M`` is below it.

    Returns
    -------
    (dict, (numpy.ndarray, numpy.ndarray))
        The output arrays by name (``intensity``, ``cf``, ``s``, ``q``,
        ``m``, ``w``) and the angle and range indices of the cells that could
        not be interpolated (their taps disagree on ``M`` or ``W``).
    """
    idx = plan.first_tap[:, None] + np.arange(plan.taps)[None, :]          # (n_angle, taps)
    s = np.einsum("atr,at->ar", beam.s[idx], plan.weights)
    q = np.einsum("atr,at->ar", beam.q[idx].astype(np.float64), plan.weights)
    m_taps = beam.m[idx]
    ok = consistent_supports(beam, plan.taps, weighted)[plan.first_tap]
    n_r = beam.s.shape[1]
    j = np.arange(n_r)[None, :]
    inside = (j >= out_windows[:, :1]) & (j < out_windows[:, 1:])
    flagged = inside & ~ok
    keep = inside & ok
    m = np.where(keep, m_taps[:, 0], 0)
    w_out = np.where(keep, beam.w[idx][:, 0], 0.0) if weighted else None
    s, q = np.where(keep, s, 0), np.where(keep, q, 0.0)
    return _outputs(s, q, m, w_out, outputs, min_channels), np.nonzero(flagged)


def consistent_supports(beam, taps: int, weighted: bool) -> np.ndarray:
    """Bool ``(n_beam, n_range)``: the ``taps`` beams from this one on have the same
    channels (``M`` equal, signature ``G`` within :data:`SIGNATURE_TOLERANCE`, ``W``
    within a relative 1e-6 with apodization), so a support starting here can be
    interpolated.  Computed once per ping on the beam grid, so that each output
    cell reads one value instead of comparing its taps."""
    n = beam.m.shape[0] - taps + 1
    ok = np.zeros(beam.m.shape, dtype=bool)
    if n <= 0:
        return ok
    good = ok[:n]
    good[...] = True
    m0, g0 = beam.m[:n], None if beam.signature is None else beam.signature[:n]
    w0 = beam.w[:n] if weighted else None
    for k in range(1, taps):
        good &= beam.m[k:k + n] == m0
        if g0 is not None:
            good &= np.abs(beam.signature[k:k + n] - g0) <= SIGNATURE_TOLERANCE
        if w0 is not None:
            good &= np.abs(beam.w[k:k + n] - w0) <= 1e-6 * np.abs(w0)
    return ok


def _outputs(s, q, m, w, outputs, min_channels: int = 1) -> dict:
    inten = np.abs(s) ** 2
    out = {}
    if "intensity" in outputs:
        out["intensity"] = inten
    if "cf" in outputs:
        denom = (m if w is None else w) * q
        with np.errstate(invalid="ignore", divide="ignore"):
            out["cf"] = np.where((denom > 0) & (m >= min_channels), np.minimum(inten / denom, 1.0), 0.0)
    if "sums" in outputs:
        out.update(s=s, q=q, m=m.astype(np.int32))
        if w is not None:
            out["w"] = w
    return out


def interpolation_error(sampling: BeamSampling, n: int = 64) -> float:
    """Mean relative error power of the angular interpolation, ``E = <|H(x, nu) - 1|^2>``.

    ``H(x, nu) = sum_k w_k(x) exp(2 pi i nu (k - x))`` is the interpolator's
    response to a complex exponential of ``nu`` cycles per beam step at a
    fractional position ``x``; averaged over ``x`` in [0, 1) and over the
    band ``|nu| <= 1 / (2 K)`` (the sum's angular spectrum filling its band
    limit), with the weights of :func:`beam_plan`.  The intensity's relative
    error power is about ``2 E`` (``dI = 2 Re(S* dS)``).
    """
    half = sampling.taps // 2
    x = (np.arange(n) + 0.5) / n
    nu = np.linspace(-0.5, 0.5, n) / sampling.oversampling
    k = np.arange(-half + 1, half + 1)
    offsets = x[:, None] - k[None, :]                                 # (x, tap)
    w = kaiser_sinc(offsets, half)
    w /= w.sum(axis=1, keepdims=True)
    phase = np.exp(2j * np.pi * nu[None, None, :] * (k[None, :, None] - x[:, None, None]))
    h = np.einsum("xk,xkn->xn", w, phase)
    return float(np.mean(np.abs(h - 1.0) ** 2))
