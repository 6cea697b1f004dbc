"""Main-lobe highlight (MLH) suppression of coherence peaks (Holland et al. 2024, Section IV C).

A strong compact scatterer (a pipe) is not one coherence peak but several:
its echo arrives at one two-way travel time, so it lights up the *arc* of
cells at that range from the source across the receive array's main lobe,
and the coherence factor fluctuates along the arc (noise, clutter on the
same arc), leaving regional maxima on its flanks.  The paper calls them
main-lobe highlights and notes that the object is at or near the arc's
maximum, or at the peak of a function fitted to the main lobe.

:func:`suppress_main_lobe_highlights` groups the coherence peaks of one ping
into arcs, strongest first: a peak joins the arc of a stronger one when it
is within ``range_tolerance_m`` of its range from the source and the arc's
peaks are contiguous in angle (no gap wider than one main lobe).  Each arc
is one :class:`ArcDetection`: the kept maximum with a sub-cell position
(3-point parabolic fit of the smoothed CF in range and in angle), a lobe fit
of the CF along the arc, and the arc's extent as a quality measure.

Default tolerances (SBP29: 2-9 kHz LFM, 3.528 m receive array, c = 1500 m/s):

- range: the compressed pulse resolves ``c / (2 B)`` = 0.107 m; the 7-point
  Hann smoothing of CF along range (non-zero taps at ``±2`` cells) spreads a
  ridge so that its crest, and the regional maxima on it, can sit anywhere
  within ``±2`` cells; so ``c / (2 B) + 2 dr`` = 0.51 m on the paper's 0.2 m
  grid.  Ranges are measured from the (heaved, rolled) source rather than
  the grid centre, which removes the arc's curvature on the grid (``h
  sin(theta)`` per radian for heave ``h``: up to 0.1 m over a 10 degree arc).
- angle: a line array's beam pattern is shift-invariant in the direction
  cosine ``u = sin(theta)``; its main lobe at the band centre reaches
  ``|du| = lambda_c / L`` = 0.077 (first null): 4.4 degrees at nadir,
  ``lambda_c / (L cos(theta))`` elsewhere, 10 degrees at 64 degrees.
  Neighbouring peaks of one arc are at most one main lobe apart in ``u``.
- lobe fit: a least-squares parabola in ``u`` to the arc's CF profile where
  it stays above :data:`LOBE_LEVEL` (0.7, -1.5 dB) of its peak.  There the
  main lobe ``sinc^2(L u / lambda)`` departs from its osculating parabola by
  less than 0.05 of the peak, while the fit averages over tens of cells
  instead of trusting the one cell a fluctuation made the maximum.

:mod:`clbeam.evaluation.scoring` scores detections against a simulation's
truth, with and without suppression.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from clbeam.constants import SBP29_ARRAY_WIDTH_M, SBP29_BAND_HZ, SOUND_SPEED_M_S
from clbeam.errors import OptionError, require
from clbeam.imaging.postprocess import peak_row
from clbeam.model.grid import PolarGrid

log = logging.getLogger(__name__)

#: half-support of the non-zero taps of the 7-point Hann window (cells)
HANN_HALF_SUPPORT_CELLS = 2
#: the lobe fit uses the arc's CF profile down to this fraction of its peak (-1.5 dB)
LOBE_LEVEL = 0.7
#: where a detection is reported: the lobe fit along its arc, or its sub-cell maximum
POSITIONS = ("lobe", "peak")
#: extra columns :func:`detection_rows` adds to :func:`clbeam.imaging.postprocess.peak_row`
MLH_COLUMNS = ("n_merged", "arc_extent_deg", "arc_range_spread_m")


# ---------------------------------------------------------------------------
# Physics of the default tolerances
# ---------------------------------------------------------------------------
def pulse_range_resolution_m(band_hz: tuple[float, float] = SBP29_BAND_HZ,
                             sound_speed_m_s: float = SOUND_SPEED_M_S) -> float:
    """Range resolution ``c / (2 B)`` (m) of a compressed pulse of bandwidth ``B`` (Hz).

    Parameters
    ----------
    band_hz : (float, float)
        Lowest and highest frequency of the pulse (Hz).
    sound_speed_m_s : float
        Sound speed (m/s).
    """
    f0, f1 = (float(v) for v in band_hz)
    require(0 <= f0 < f1, OptionError, f"pulse band must satisfy 0 <= f0 < f1, got {band_hz!r} Hz")
    return sound_speed_m_s / (2.0 * (f1 - f0))


def main_lobe_u(frequency_hz: float = 0.5 * sum(SBP29_BAND_HZ), array_width_m: float = SBP29_ARRAY_WIDTH_M,
                sound_speed_m_s: float = SOUND_SPEED_M_S) -> float:
    """Half-width ``lambda / L`` of a line array's main lobe in direction cosine (first null).

    Parameters
    ----------
    frequency_hz : float
        Frequency (Hz); default the SBP29 band centre, 5.5 kHz.
    array_width_m : float
        Array length ``L`` (m).
    sound_speed_m_s : float
        Sound speed (m/s).

    Returns
    -------
    float
        ``|du|`` from the beam axis to the first null (dimensionless); in
        angle ``lambda / (L cos(theta))`` radians near steering angle ``theta``.
    """
    require(frequency_hz > 0 and array_width_m > 0, OptionError,
            f"frequency and array width must be > 0, got {frequency_hz!r} Hz, {array_width_m!r} m")
    return sound_speed_m_s / (frequency_hz * array_width_m)


def default_range_tolerance_m(grid: PolarGrid, *, band_hz: tuple[float, float] = SBP29_BAND_HZ,
                              sound_speed_m_s: float = SOUND_SPEED_M_S) -> float:
    """Range tolerance (m) of one arc: ``c / (2 B)`` plus the Hann half-support ``2 dr``.

    Parameters
    ----------
    grid : PolarGrid
        The image grid; ``dr`` is its median range step (m).
    band_hz : (float, float)
        Pulse band (Hz).
    sound_speed_m_s : float
        Sound speed (m/s).
    """
    dr = float(np.median(np.diff(grid.ranges_m))) if grid.ranges_m.size > 1 else 0.0
    return pulse_range_resolution_m(band_hz, sound_speed_m_s) + HANN_HALF_SUPPORT_CELLS * dr


def arc_tolerances(grid: PolarGrid, *, band_hz: tuple[float, float] = SBP29_BAND_HZ,
                   array_width_m: float = SBP29_ARRAY_WIDTH_M, sound_speed_m_s: float = SOUND_SPEED_M_S) -> dict:
    """Range tolerance (m) and main-lobe width (direction cosine) of the arcs
    of a ping with this pulse band (Hz), array width (m) and sound speed (m/s):
    the ``range_tolerance_m`` and ``max_gap_u`` of
    :func:`suppress_main_lobe_highlights`."""
    return {"range_tolerance_m": default_range_tolerance_m(grid, band_hz=band_hz, sound_speed_m_s=sound_speed_m_s),
            "max_gap_u": main_lobe_u(0.5 * sum(band_hz), max(array_width_m, 1e-3), sound_speed_m_s)}


# ---------------------------------------------------------------------------
# Sub-cell vertex
# ---------------------------------------------------------------------------
def parabolic_vertex(f_minus, f_centre, f_plus, *, kind: str = "parabola", max_offset: float = 0.5):
    """Sub-cell offset of a peak from three equally spaced samples (closed form).

    The parabola through ``(-1, f_minus), (0, f_centre), (1, f_plus)`` has its
    vertex at ``(f_minus - f_plus) / (2 (f_minus - 2 f_centre + f_plus))``.
    ``kind="gaussian"`` fits the parabola to the logarithms, which is exact
    for a Gaussian lobe (needs positive samples; else the plain parabola).

    Parameters
    ----------
    f_minus, f_centre, f_plus : float or numpy.ndarray
        Samples at offsets -1, 0 and +1 cell.
    kind : {"parabola", "gaussian"}
        Fit of the samples or of their logarithms.
    max_offset : float
        Clamp of the offset (cells).

    Returns
    -------
    float or numpy.ndarray
        Offset of the vertex in cells, within ``±max_offset``; 0 where the
        samples are not strictly concave (no vertex) or not finite.
    """
    require(kind in ("parabola", "gaussian"), OptionError, f"sub-cell fit must be 'parabola' or 'gaussian', got {kind!r}")
    fm, f0, fp = (np.asarray(v, dtype=np.float64) for v in (f_minus, f_centre, f_plus))
    if kind == "gaussian":
        positive = (fm > 0) & (f0 > 0) & (fp > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            fm, f0, fp = (np.where(positive, np.log(np.where(positive, v, 1.0)), v) for v in (fm, f0, fp))
    curvature = fm - 2.0 * f0 + fp
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.where(curvature < 0, (fm - fp) / (2.0 * curvature), 0.0)
    delta = np.clip(np.where(np.isfinite(delta), delta, 0.0), -max_offset, max_offset)
    return float(delta) if delta.ndim == 0 else delta


def _axis_offset(values: np.ndarray, i: int, kind: str) -> float:
    """Parabolic offset (cells) at index ``i`` of a 1-D profile; 0 at its ends."""
    if i <= 0 or i >= values.size - 1:
        return 0.0
    return parabolic_vertex(values[i - 1], values[i], values[i + 1], kind=kind)


def _at_fractional_index(coords: np.ndarray, index: float) -> float:
    """Coordinate at a fractional index (linear between nodes)."""
    return float(np.interp(index, np.arange(coords.size), coords))


# ---------------------------------------------------------------------------
# Arcs
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class ArcFrame:
    """Where the arcs of a ping are centred, in the grid's earth frame.

    Attributes
    ----------
    centre_yz_m : numpy.ndarray
        Grid centre ``(y, z)`` (m): cell ``(i, j)`` is at
        ``centre + R_j (sin(theta_i), cos(theta_i))``.
    source_yz_m : numpy.ndarray
        Source ``(y, z)`` (m): the centre of every arc of constant two-way
        travel time (the receive array spans metres, the ranges hundreds).
    """

    centre_yz_m: np.ndarray
    source_yz_m: np.ndarray

    def about_source(self, grid_range_m, grid_angle_deg) -> tuple[np.ndarray, np.ndarray]:
        """Range (m) and angle from nadir (radian) about the source of grid points."""
        th = np.deg2rad(grid_angle_deg)
        dy = self.centre_yz_m[0] + grid_range_m * np.sin(th) - self.source_yz_m[0]
        dz = self.centre_yz_m[1] + grid_range_m * np.cos(th) - self.source_yz_m[1]
        return np.hypot(dy, dz), np.arctan2(dy, dz)

    def grid_range_of_arc(self, source_range_m: float, grid_angle_deg) -> np.ndarray:
        """Grid range (m) where the arc ``|r - s| = source_range_m`` crosses each grid angle.

        With ``d = centre - source`` and the ray direction ``e``, the root of
        ``|d + R e| = R_s``: ``R = -d.e + sqrt((d.e)^2 - |d|^2 + R_s^2)``
        (NaN where the arc misses the ray).
        """
        th = np.deg2rad(grid_angle_deg)
        d = self.centre_yz_m - self.source_yz_m
        b = d[0] * np.sin(th) + d[1] * np.cos(th)
        disc = b * b - float(d @ d) + source_range_m ** 2
        with np.errstate(invalid="ignore"):
            return np.where(disc >= 0, -b + np.sqrt(np.maximum(disc, 0.0)), np.nan)

    def point(self, source_range_m: float, source_angle_rad: float) -> tuple[float, float]:
        """Earth-frame ``(y, z)`` (m) of a point given about the source."""
        return (float(self.source_yz_m[0] + source_range_m * math.sin(source_angle_rad)),
                float(self.source_yz_m[1] + source_range_m * math.cos(source_angle_rad)))

    def grid_polar(self, y_m: float, z_m: float) -> tuple[float, float]:
        """Range (m) and angle (degree) about the grid centre of an earth-frame point."""
        dy, dz = y_m - self.centre_yz_m[0], z_m - self.centre_yz_m[1]
        return math.hypot(dy, dz), math.degrees(math.atan2(dy, dz))


def make_frame(grid: PolarGrid, centre_yz_m=None, source_yz_m=None) -> ArcFrame:
    """:class:`ArcFrame` of a grid: its centre (given, the grid's own, or
    ``(0, 0)`` for a source-centred grid) and the source (default the centre)."""
    centre = np.asarray(grid.centre((0.0, 0.0)) if centre_yz_m is None else centre_yz_m, dtype=np.float64)
    source = centre if source_yz_m is None else np.asarray(source_yz_m, dtype=np.float64)
    require(centre.shape == (2,) and source.shape == (2,) and bool(np.all(np.isfinite(np.r_[centre, source]))),
            OptionError, f"grid centre and source must be finite (y, z) pairs in m, got {centre_yz_m!r}, {source_yz_m!r}")
    return ArcFrame(centre, source)


def arc_profile(cf_smooth: np.ndarray, grid: PolarGrid, frame: ArcFrame, source_range_m: float, angle_index: int,
                range_tolerance_m: float) -> tuple[float, float]:
    """Smoothed CF on an arc at one grid angle: the largest within ``±range_tolerance_m``.

    Parameters
    ----------
    cf_smooth : numpy.ndarray
        ``(n_angle, n_range)`` smoothed CF.
    grid : PolarGrid
        The image grid.
    frame : ArcFrame
        Grid centre and source.
    source_range_m : float
        The arc's range from the source (m).
    angle_index : int
        Grid angle row.
    range_tolerance_m : float
        Half-width of the arc in range (m).

    Returns
    -------
    (float, float)
        The CF (NaN where the arc misses the grid at that angle) and the
        direction cosine ``sin(theta)`` about the source where the arc crosses.
    """
    angle = grid.angles_deg[angle_index]
    r = float(frame.grid_range_of_arc(source_range_m, angle))
    if not np.isfinite(r):
        return float("nan"), float("nan")
    lo, hi = np.searchsorted(grid.ranges_m, [r - range_tolerance_m, r + range_tolerance_m + 1e-9 * max(r, 1.0)])
    if hi <= lo:
        return float("nan"), float("nan")
    _, a = frame.about_source(r, angle)
    return float(np.max(cf_smooth[angle_index, lo:hi])), float(np.sin(a))


def lobe_fit(cf_smooth: np.ndarray, grid: PolarGrid, frame: ArcFrame, source_range_m: float, angle_index: int, *,
             range_tolerance_m: float, level: float = LOBE_LEVEL, max_half_width_u: float | None = None) -> float:
    """Direction of the main lobe along an arc: vertex of a parabola in ``u = sin(theta)``.

    From the grid angle ``angle_index`` the arc's CF profile (:func:`arc_profile`)
    is followed both ways while it stays at or above ``level`` times its value
    there (and within ``max_half_width_u`` of it); a least-squares parabola in
    ``u`` through those samples gives the vertex.

    Parameters
    ----------
    cf_smooth : numpy.ndarray
        ``(n_angle, n_range)`` smoothed CF.
    grid : PolarGrid
        The image grid.
    frame : ArcFrame
        Grid centre and source.
    source_range_m : float
        The arc's range from the source (m).
    angle_index : int
        Grid angle row of the arc's maximum.
    range_tolerance_m : float
        Half-width of the arc in range (m).
    level : float
        Lowest fraction (0-1) of the starting value fitted (default 0.7).
    max_half_width_u : float, optional
        Farthest ``|du|`` followed; default one main lobe, :func:`main_lobe_u`.

    Returns
    -------
    float
        Angle from nadir (radian) about the source of the vertex; NaN with
        fewer than 3 samples, no concave fit or a vertex outside the samples.
    """
    require(0 < level < 1, OptionError, f"lobe level must be within 0-1, got {level!r}")
    half = main_lobe_u() if max_half_width_u is None else float(max_half_width_u)
    p0, u0 = arc_profile(cf_smooth, grid, frame, source_range_m, angle_index, range_tolerance_m)
    if not (np.isfinite(p0) and p0 > 0):
        return float("nan")
    us, ps = [u0], [p0]
    for step in (-1, 1):
        ia = angle_index + step
        while 0 <= ia < grid.angles_deg.size:
            p, u = arc_profile(cf_smooth, grid, frame, source_range_m, ia, range_tolerance_m)
            if not (np.isfinite(p) and p >= level * p0 and abs(u - u0) <= half):
                break
            us.append(u)
            ps.append(p)
            ia += step
    if len(us) < 3:
        return float("nan")
    x = np.asarray(us) - u0
    c2, c1, _ = np.polyfit(x, np.asarray(ps), 2)
    if not c2 < 0:
        return float("nan")
    xv = -c1 / (2.0 * c2)
    if not x.min() <= xv <= x.max():
        return float("nan")
    return float(np.arcsin(np.clip(u0 + xv, -1.0, 1.0)))


@dataclass(frozen=True)
class ArcDetection:
    """One object: the strongest coherence peak of a main-lobe arc.

    Attributes
    ----------
    angle_index, range_index : int
        Grid indices ``(ia, ir)`` of the kept maximum.
    range_m, angle_deg : float
        Sub-cell range (m) and angle (degree) of the maximum about the grid
        centre: the cell's plus the 3-point parabolic offsets of the smoothed
        CF along each axis (within half a cell).
    y_m, z_m : float
        Earth-frame position of the sub-cell maximum (m).
    cf : float
        Smoothed CF at the kept cell.
    lobe_range_m, lobe_angle_deg : float
        Range (m) and angle (degree) about the grid centre of the lobe fit
        (:func:`lobe_fit`): the vertex on the arc through the sub-cell
        maximum; NaN where the lobe cannot be fitted.
    lobe_y_m, lobe_z_m : float
        Earth-frame position (m) of that vertex; NaN likewise.
    n_merged : int
        Coherence peaks on the arc, the kept one included (1: isolated).
    arc_extent_deg : float
        Angular extent of the arc's peaks seen from the source (degree).
    arc_range_spread_m : float
        Spread of their ranges from the source (m).
    members : tuple of (int, int)
        ``(ia, ir)`` of every peak on the arc, the kept one first.
    """

    angle_index: int
    range_index: int
    range_m: float
    angle_deg: float
    y_m: float
    z_m: float
    cf: float
    lobe_range_m: float
    lobe_angle_deg: float
    lobe_y_m: float
    lobe_z_m: float
    n_merged: int
    arc_extent_deg: float
    arc_range_spread_m: float
    members: tuple = field(default=(), repr=False)

    def position(self, which: str = "lobe") -> tuple[float, float, float, float]:
        """``(range_m, angle_deg, y_m, z_m)`` of the ``"peak"`` (sub-cell
        maximum) or of the ``"lobe"`` fit (the peak where there is none)."""
        require(which in POSITIONS, OptionError, f"position must be one of {POSITIONS}, got {which!r}")
        if which == "lobe" and np.isfinite(self.lobe_angle_deg):
            return self.lobe_range_m, self.lobe_angle_deg, self.lobe_y_m, self.lobe_z_m
        return self.range_m, self.angle_deg, self.y_m, self.z_m


def group_arcs(range_m: np.ndarray, angle_rad: np.ndarray, cf: np.ndarray, *, range_tolerance_m: float,
               max_angle_gap_deg: float | None = None, max_gap_u: float | None = None) -> list[np.ndarray]:
    """Group peaks into main-lobe arcs, strongest first.

    The strongest peak not yet grouped seeds an arc; the ungrouped peaks
    within ``range_tolerance_m`` of its range are ordered by angle, and the
    arc is the run of them around the seed with no gap between neighbours
    wider than the angular tolerance.

    Parameters
    ----------
    range_m, angle_rad : numpy.ndarray
        Range (m) and angle from nadir (radian) of each peak about the source.
    cf : numpy.ndarray
        Peak strength (smoothed CF); ties keep the input order.
    range_tolerance_m : float
        Largest ``|R - R_seed|`` on one arc (m).
    max_angle_gap_deg : float, optional
        Largest angular gap between neighbours on an arc (degree).
    max_gap_u : float, optional
        Used when ``max_angle_gap_deg`` is None: largest gap in direction
        cosine ``sin(theta)`` (default :func:`main_lobe_u`).

    Returns
    -------
    list of numpy.ndarray
        Peak indices of each arc, the seed (maximum) first, arcs by
        decreasing CF of their maximum.
    """
    require(range_tolerance_m >= 0, OptionError, f"range tolerance must be >= 0 m, got {range_tolerance_m!r}")
    if max_angle_gap_deg is not None:
        require(max_angle_gap_deg >= 0, OptionError, f"angle gap must be >= 0 degrees, got {max_angle_gap_deg!r}")
        coord, gap = np.degrees(angle_rad), float(max_angle_gap_deg)
    else:
        gap = main_lobe_u() if max_gap_u is None else float(max_gap_u)
        require(gap >= 0, OptionError, f"direction-cosine gap must be >= 0, got {max_gap_u!r}")
        coord = np.sin(angle_rad)
    free = np.ones(range_m.size, dtype=bool)
    arcs = []
    for seed in np.argsort(-np.asarray(cf, dtype=np.float64), kind="stable"):
        if not free[seed]:
            continue
        cand = np.flatnonzero(free & (np.abs(range_m - range_m[seed]) <= range_tolerance_m))
        cand = cand[np.argsort(coord[cand], kind="stable")]
        pos = int(np.flatnonzero(cand == seed)[0])
        close = np.diff(coord[cand]) <= gap
        lo = pos
        while lo > 0 and close[lo - 1]:
            lo -= 1
        hi = pos
        while hi < cand.size - 1 and close[hi]:
            hi += 1
        members = cand[lo:hi + 1]
        members = np.r_[seed, members[members != seed]]
        free[members] = False
        arcs.append(members)
    return arcs


def suppress_main_lobe_highlights(peaks_idx: np.ndarray, cf_smooth: np.ndarray, grid: PolarGrid, *,
                                  range_tolerance_m: float | None = None, max_angle_gap_deg: float | None = None,
                                  max_gap_u: float | None = None, centre_yz_m=None, source_yz_m=None,
                                  subcell: str = "parabola", lobe_level: float = LOBE_LEVEL) -> list[ArcDetection]:
    """Merge the coherence peaks of one ping that lie on one main-lobe arc.

    Parameters
    ----------
    peaks_idx : numpy.ndarray
        ``(n, 2)`` ``(angle index, range index)`` of the coherence peaks
        (:func:`clbeam.imaging.postprocess.coherence_peaks`).
    cf_smooth : numpy.ndarray
        ``(n_angle, n_range)`` smoothed CF the peaks were picked on.
    grid : PolarGrid
        The image grid.
    range_tolerance_m : float, optional
        Largest range difference (m) from the arc's maximum, measured from
        the source; default :func:`default_range_tolerance_m` (0.51 m on a
        0.2 m grid).
    max_angle_gap_deg : float, optional
        Largest angular gap (degree) between neighbouring peaks of an arc; by
        default the gap is measured in direction cosine (``max_gap_u``).
    max_gap_u : float, optional
        Largest gap in ``sin(theta)`` when ``max_angle_gap_deg`` is None, and
        the half-width of the lobe fit; default one main lobe at the band
        centre, :func:`main_lobe_u` (0.077).
    centre_yz_m : (float, float), optional
        Earth-frame grid centre (m) for ``y, z``; default the grid's own
        centre, or ``(0, 0)`` when it is the (vessel-frame) source.
    source_yz_m : (float, float), optional
        Earth-frame source (m), the centre of the arcs (it moves with heave
        and roll); default the grid centre.
    subcell : {"parabola", "gaussian"}
        Three-point vertex fit (:func:`parabolic_vertex`) in each axis.
    lobe_level : float
        Fraction of the maximum down to which :func:`lobe_fit` fits the arc.

    Returns
    -------
    list of ArcDetection
        One per arc, by decreasing CF.
    """
    cf = np.asarray(cf_smooth)
    require(cf.shape == grid.shape, OptionError, f"cf_smooth has shape {cf.shape}, the grid {grid.shape}")
    idx = np.asarray(peaks_idx, dtype=np.int64).reshape(-1, 2)
    if idx.size == 0:
        return []
    require(bool(np.all((idx >= 0) & (idx < np.asarray(grid.shape)))), OptionError,
            "peak indices lie outside the grid")
    frame = make_frame(grid, centre_yz_m, source_yz_m)
    tol = default_range_tolerance_m(grid) if range_tolerance_m is None else float(range_tolerance_m)
    r_src, a_src = frame.about_source(grid.ranges_m[idx[:, 1]], grid.angles_deg[idx[:, 0]])
    values = cf[idx[:, 0], idx[:, 1]].astype(np.float64)
    arcs = group_arcs(r_src, a_src, values, range_tolerance_m=tol, max_angle_gap_deg=max_angle_gap_deg,
                      max_gap_u=max_gap_u)
    out = [_detection(members, idx, cf, grid, frame, r_src, a_src, subcell=subcell, tol=tol, level=lobe_level,
                      half_u=max_gap_u) for members in arcs]
    log.debug("MLH suppression: %d coherence peaks -> %d detections", len(idx), len(out))
    return out


def _detection(members: np.ndarray, idx: np.ndarray, cf: np.ndarray, grid: PolarGrid, frame: ArcFrame,
               r_src: np.ndarray, a_src: np.ndarray, *, subcell: str, tol: float, level: float,
               half_u: float | None) -> ArcDetection:
    """The :class:`ArcDetection` of one arc (``members[0]`` is its maximum)."""
    ia, ir = (int(v) for v in idx[members[0]])
    angle = _at_fractional_index(grid.angles_deg, ia + _axis_offset(cf[:, ir], ia, subcell))
    rng = _at_fractional_index(grid.ranges_m, ir + _axis_offset(cf[ia, :], ir, subcell))
    th = math.radians(angle)
    y, z = (float(frame.centre_yz_m[0] + rng * math.sin(th)), float(frame.centre_yz_m[1] + rng * math.cos(th)))
    r_peak_src = float(frame.about_source(rng, angle)[0])
    a_lobe = lobe_fit(cf, grid, frame, r_peak_src, ia, range_tolerance_m=tol, level=level, max_half_width_u=half_u)
    if np.isfinite(a_lobe):
        ly, lz = frame.point(r_peak_src, a_lobe)
        lr, la = frame.grid_polar(ly, lz)
    else:
        ly = lz = lr = la = float("nan")
    return ArcDetection(
        angle_index=ia, range_index=ir, range_m=rng, angle_deg=angle, y_m=y, z_m=z, cf=float(cf[ia, ir]),
        lobe_range_m=lr, lobe_angle_deg=la, lobe_y_m=ly, lobe_z_m=lz, n_merged=int(members.size),
        arc_extent_deg=float(np.degrees(np.ptp(a_src[members]))),
        arc_range_spread_m=float(np.ptp(r_src[members])),
        members=tuple((int(a), int(r)) for a, r in idx[members]))


# ---------------------------------------------------------------------------
# Peak rows (the Imager's table)
# ---------------------------------------------------------------------------
def detection_rows(detections: list[ArcDetection], ping: int, intensity: np.ndarray | None = None,
                   centre_yz_m=(0.0, 0.0), navigation: dict | None = None, *, position: str = "lobe") -> list[dict]:
    """Peak-table rows of :func:`clbeam.imaging.postprocess.peak_row` plus :data:`MLH_COLUMNS`.

    ``range_m``, ``angle_deg``, ``y_m``, ``z_m`` are the detection's
    :meth:`ArcDetection.position`; ``cf`` and ``intensity_db`` the kept cell's.

    Parameters
    ----------
    detections : list of ArcDetection
        One ping's detections.
    ping : int
        Ping index.
    intensity : numpy.ndarray, optional
        ``(n_angle, n_range)`` intensity ``|S|^2``; NaN in the rows without it.
    centre_yz_m : (float, float)
        Earth-frame grid centre (m), as :func:`clbeam.imaging.postprocess.peak_row` takes it.
    navigation : dict, optional
        ``latitude``, ``longitude``, ``heading`` of the ship (degree).
    position : {"lobe", "peak"}
        Report the lobe fit (default) or the sub-cell maximum.
    """
    rows = []
    for d in detections:
        inten = float(intensity[d.angle_index, d.range_index]) if intensity is not None else np.nan
        rng, ang, _, _ = d.position(position)
        row = peak_row(ping, rng, ang, centre_yz_m, d.cf, inten, navigation)
        row.update(n_merged=d.n_merged, arc_extent_deg=d.arc_extent_deg, arc_range_spread_m=d.arc_range_spread_m)
        rows.append(row)
    return rows


__all__ = ["ArcDetection", "ArcFrame", "LOBE_LEVEL", "MLH_COLUMNS", "POSITIONS", "arc_profile",
           "default_range_tolerance_m", "detection_rows", "group_arcs", "lobe_fit", "main_lobe_u", "make_frame",
           "arc_tolerances", "parabolic_vertex", "pulse_range_resolution_m", "suppress_main_lobe_highlights"]
