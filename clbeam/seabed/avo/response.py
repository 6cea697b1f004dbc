"""Per-ping backscatter angular responses from clbeam image files (docs/avo.md).

For every ping of an image file (``intensity(ping, angle, range)`` on a
polar grid centred on the source, angle from nadir positive to starboard)
:func:`angular_responses` returns the backscatter strength (dB) per
incidence-angle bin and side, and the along-track position of the ping.

Steps, per ping
---------------
1. **Seabed pick.**  The nadir depth ``h`` is the first range, over the beams
   within 2° of nadir, where the range-smoothed intensity comes within
   ``below_peak_db`` of its maximum (the first strong return).  In a band
   around the flat seabed through ``h`` (widened by ``|y| tan 10°`` for
   slopes up to 10°) every beam's pick is the range of the strongest
   range-smoothed intensity (refined to a fraction of a cell by the parabola
   through the maximum and its two neighbours).  A straight seabed ``z = z0 + s y`` is fitted to
   the picks by iteratively trimmed least squares (points further than
   ``3 x 1.4826 MAD`` (at least 1 m) from the line are dropped, five passes),
   and the picks are repeated in a narrow band around the line and refitted.
   The fitted line, not the individual picks, gives the seabed range of each
   beam, ``R(a) = z0 / (cos a - s sin a)``: speckle then moves neither the
   range nor the slope much.
2. **True incidence.**  With the across-track slope ``tan(phi) = s`` (deeper
   to starboard positive), the incidence angle from the seabed normal of the
   beam at angle ``a`` is ``i = |a + phi|`` (:func:`incidence_angle_deg`).
3. **Level.**  The intensity of a beam is the mean of the image cells within
   ``+-w`` of the seabed range (the nearest cell when none is), ``w = E/8`` with
   ``E = R tan(i) lambda / (D cos a)`` the range extent of the seabed echo in
   that beam (receive beamwidth ``lambda / (D cos a)``, array width ``D``).
   Within ``E/8`` of the beam axis the receive pattern costs under 0.1 dB.
   Near nadir ``E`` is below a range step; the level is then one cell, and
   a range grid coarser than the compressed pulse (``c / 2B``, 0.11 m for
   the SBP29) samples the echo's peak only by chance: the bins within about
   10° of nadir are less reliable than the rest.
4. **Corrections** (:func:`strength_from_intensity_db`)::

       S = 10 log10 I + 40 log10 R + 2 alpha R - 10 log10 A + calibration_db

   ``40 log10 R``: two-way spherical spreading of the intensity scattered
   by a point; ``alpha``: water absorption (dB/m); ``A``: insonified area
   (:func:`insonified_area_m2`).  Source level, receive sensitivity, the
   array and pulse-compression gains of the imager and the image's
   normalisation are one unknown constant; without ``calibration_db`` the
   strengths are relative dB (that constant left in), with it they are
   ``S + calibration_db``.
5. **Binning.**  Beams are binned by incidence angle (bin edges halfway
   between the given centres); a bin's strength is the linear-intensity mean
   of its beams; NaN where no beam falls.  Port: beams with ``a < 0``.

Along-track position: cumulative distance between consecutive pings'
latitude/longitude (local tangent plane, mean Earth radius), or ping index x
``ping_spacing_m`` when the file has no navigation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter1d

from clbeam.constants import (
    SBP29_ARRAY_WIDTH_M,
    SBP29_BAND_HZ,
    SBP29_CENTRE_FREQUENCY_HZ,
    SBP29_TX_LENGTH_M,
    SOUND_SPEED_M_S,
)
from clbeam.errors import ClbeamError, OptionError, require
from clbeam.io.images import open_images
from clbeam.model.geodesy import along_track_m

DEFAULT_INCIDENCE_DEG = np.arange(0.5, 85.0, 1.0)
"""Default bin centres: 1° bins from 0 to 85° incidence."""
MAX_SLOPE_DEG = 10.0
"""Largest across-track seabed slope the first pick band allows for (deg)."""


@dataclass(frozen=True)
class ResponseOptions:
    """Sonar and processing parameters of the angular-response extraction.

    Attributes
    ----------
    frequency_hz : float
        Band centre (Hz): wavelength of the beamwidths and of absorption.
        SBP29 LFM 2–9 kHz: 5500 Hz.
    bandwidth_hz : float
        Pulse bandwidth (Hz); compressed pulse length ``T_eff = 1 / B``.
    sound_speed_m_s : float
        Water sound speed (m/s).
    tx_length_m : float
        Along-track length ``L`` of the transmit column (m); along-track
        beamwidth ``beta = lambda / L`` (rad).
    rx_width_m : float
        Across-track width ``D`` of the receive array (m); receive beamwidth
        ``lambda / (D cos a)`` (rad) at steering angle ``a``.
    absorption_db_per_km : float or None
        Water absorption (dB/km); None: Francois–Garrison at ``frequency_hz``
        for ``temperature_c``, ``salinity_psu``, 0 m depth, pH 8.
    temperature_c, salinity_psu : float
        Water temperature (°C) and salinity (PSU) for Francois–Garrison.
    calibration_db : float
        Added to every strength (dB): the negative of the source level and
        gains, when known.
    below_peak_db : float
        First strong return: within this many dB of the strongest (dB).
    band_m : float
        Half-width of the refined pick band around the first seabed line (m).
    smooth_m : float
        Length of the moving mean along range used for picking (m).
    """

    frequency_hz: float = SBP29_CENTRE_FREQUENCY_HZ
    bandwidth_hz: float = SBP29_BAND_HZ[1] - SBP29_BAND_HZ[0]
    sound_speed_m_s: float = SOUND_SPEED_M_S
    tx_length_m: float = SBP29_TX_LENGTH_M
    rx_width_m: float = SBP29_ARRAY_WIDTH_M
    absorption_db_per_km: float | None = None
    temperature_c: float = 10.0
    salinity_psu: float = 35.0
    calibration_db: float = 0.0
    below_peak_db: float = 20.0
    band_m: float = 5.0
    smooth_m: float = 2.0

    def __post_init__(self):
        for name in ("frequency_hz", "bandwidth_hz", "sound_speed_m_s", "tx_length_m", "rx_width_m",
                     "band_m", "smooth_m", "below_peak_db"):
            v = getattr(self, name)
            require(np.isfinite(v) and v > 0, OptionError, f"{name} must be a finite number > 0, got {v!r}")
        require(self.absorption_db_per_km is None or (np.isfinite(self.absorption_db_per_km)
                                                       and self.absorption_db_per_km >= 0),
                OptionError, f"absorption_db_per_km must be >= 0 dB/km, got {self.absorption_db_per_km!r}")
        require(np.isfinite(self.calibration_db), OptionError,
                f"calibration_db must be finite, got {self.calibration_db!r}")

    @property
    def wavelength_m(self) -> float:
        """Wavelength at the band centre (m)."""
        return self.sound_speed_m_s / self.frequency_hz

    @property
    def absorption_db_per_m(self) -> float:
        """Water absorption used (dB/m, one way)."""
        if self.absorption_db_per_km is not None:
            return self.absorption_db_per_km / 1000.0
        return francois_garrison_db_per_km(self.frequency_hz, temperature_c=self.temperature_c,
                                           salinity_psu=self.salinity_psu) / 1000.0


@dataclass(frozen=True)
class SeabedLine:
    """The seabed of one ping: the fitted line and the beams' seabed ranges.

    Attributes
    ----------
    z0_m : float
        Depth of the fitted seabed below the grid centre at ``y = 0`` (m).
    slope : float
        ``dz/dy`` (positive: deeper to starboard).
    range_m : numpy.ndarray
        Range of the fitted seabed along each beam (m); NaN where the beam
        does not reach it within the grid.
    picks_m : numpy.ndarray
        Per-beam picked ranges of the last pass (m); NaN where rejected.
    """

    z0_m: float
    slope: float
    range_m: np.ndarray
    picks_m: np.ndarray

    @property
    def slope_deg(self) -> float:
        """Across-track seabed slope ``atan(dz/dy)`` (deg)."""
        return math.degrees(math.atan(self.slope))


@dataclass(frozen=True)
class AngularResponse:
    """Per-ping angular responses of a survey line.

    Attributes
    ----------
    incidence_deg : numpy.ndarray
        Bin centres (deg from the seabed normal), ``(n_bin,)``.
    port_db, starboard_db : numpy.ndarray
        Backscatter strength (dB, relative unless calibrated), ``(n_ping, n_bin)``.
    along_track_m : numpy.ndarray
        Along-track position of each ping (m), ``(n_ping,)``.
    seabed_slope_deg : numpy.ndarray
        Across-track seabed slope of each ping (deg, deeper to starboard > 0).
    seabed_depth_m : numpy.ndarray
        Depth of the fitted seabed below the source at ``y = 0`` (m).
    options : ResponseOptions
        Parameters used.
    """

    incidence_deg: np.ndarray
    port_db: np.ndarray
    starboard_db: np.ndarray
    along_track_m: np.ndarray
    seabed_slope_deg: np.ndarray
    seabed_depth_m: np.ndarray
    options: ResponseOptions = field(default_factory=ResponseOptions)


# ---------------------------------------------------------------------------
# Physics of the corrections
# ---------------------------------------------------------------------------
def francois_garrison_db_per_km(frequency_hz, *, temperature_c: float = 10.0, salinity_psu: float = 35.0,
                                depth_m: float = 0.0, ph: float = 8.0):
    """Sea-water absorption after Francois & Garrison (1982) (dB/km).

    Boric acid and magnesium sulphate relaxations plus pure-water viscosity
    (J. Acoust. Soc. Am. 72, 896 and 1879).

    Parameters
    ----------
    frequency_hz : float or array_like
        Frequency (Hz).
    temperature_c : float
        Temperature (°C).
    salinity_psu : float
        Salinity (PSU).
    depth_m : float
        Depth (m).
    ph : float
        pH.

    Returns
    -------
    float or numpy.ndarray
        Absorption (dB/km).
    """
    f = np.asarray(frequency_hz, dtype=np.float64) / 1000.0  # kHz
    t, s, d = float(temperature_c), float(salinity_psu), float(depth_m)
    theta = t + 273.0
    c = 1412.0 + 3.21 * t + 1.19 * s + 0.0167 * d
    a1 = 8.86 / c * 10.0 ** (0.78 * ph - 5.0)
    f1 = 2.8 * math.sqrt(s / 35.0) * 10.0 ** (4.0 - 1245.0 / theta)
    a2 = 21.44 * s / c * (1.0 + 0.025 * t)
    p2 = 1.0 - 1.37e-4 * d + 6.2e-9 * d * d
    f2 = 8.17 * 10.0 ** (8.0 - 1990.0 / theta) / (1.0 + 0.0018 * (s - 35.0))
    p3 = 1.0 - 3.83e-5 * d + 4.9e-10 * d * d
    if t <= 20.0:
        a3 = 4.937e-4 - 2.59e-5 * t + 9.11e-7 * t ** 2 - 1.50e-8 * t ** 3
    else:
        a3 = 3.964e-4 - 1.146e-5 * t + 1.45e-7 * t ** 2 - 6.5e-10 * t ** 3
    f_sq = f * f
    out = a1 * f1 * f_sq / (f1 * f1 + f_sq) + a2 * p2 * f2 * f_sq / (f2 * f2 + f_sq) + a3 * p3 * f_sq
    return float(out) if np.ndim(out) == 0 else out


def insonified_area_m2(range_m, incidence_deg, options: ResponseOptions, *, steering_deg=None):
    """Seabed area that returns the intensity of one image cell (m²).

    ``A = W_across x R beta_along`` with ``beta_along = lambda / L`` and

    * pulse-limited ``W = (c T_eff / 2) / sin(i)``, ``T_eff = 1 / B``
      (the compressed pulse; ``sin(i) = cos(grazing)``), away from nadir;
    * beam-limited ``W = R beta_rx / cos(i)``, ``beta_rx = lambda / (D cos a)``,
      near nadir,

    whichever is smaller (the crossing is where ``tan i = c T_eff / (2 R beta_rx)``,
    below 1° for the SBP29 at 100 m).

    Parameters
    ----------
    range_m : array_like
        Slant range (m).
    incidence_deg : array_like
        Incidence angle from the seabed normal (deg).
    options : ResponseOptions
        Frequency, bandwidth, sound speed and array dimensions.
    steering_deg : array_like, optional
        Beam angle from nadir ``a`` (deg); default: the incidence angle.

    Returns
    -------
    numpy.ndarray
        Area (m²).
    """
    r = np.asarray(range_m, dtype=np.float64)
    inc = np.deg2rad(np.abs(np.asarray(incidence_deg, dtype=np.float64)))
    steer = inc if steering_deg is None else np.deg2rad(np.asarray(steering_deg, dtype=np.float64))
    lam = options.wavelength_m
    beta_along = lam / options.tx_length_m
    beta_rx = lam / (options.rx_width_m * np.cos(steer))
    half_pulse = options.sound_speed_m_s / (2.0 * options.bandwidth_hz)
    with np.errstate(divide="ignore"):
        pulse = half_pulse / np.sin(inc)
    beam = r * beta_rx / np.cos(inc)
    return np.minimum(pulse, beam) * r * beta_along


def strength_from_intensity_db(intensity, range_m, incidence_deg, options: ResponseOptions, *, steering_deg=None):
    """Backscatter strength from image intensity (dB).

    ``S = 10 log10 I + 40 log10 R + 2 alpha R - 10 log10 A + calibration_db``
    (module docstring); NaN where ``I <= 0`` or not finite.

    Parameters
    ----------
    intensity : array_like
        Image intensity (squared input units).
    range_m : array_like
        Slant range (m).
    incidence_deg : array_like
        Incidence angle (deg).
    options : ResponseOptions
        Parameters of the corrections.
    steering_deg : array_like, optional
        Beam angle from nadir (deg), for the beam-limited area.

    Returns
    -------
    numpy.ndarray
        Strength (dB re the unknown constant, or calibrated).
    """
    i = np.asarray(intensity, dtype=np.float64)
    r = np.asarray(range_m, dtype=np.float64)
    area = insonified_area_m2(r, incidence_deg, options, steering_deg=steering_deg)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (10.0 * np.log10(i) + 40.0 * np.log10(r) + 2.0 * options.absorption_db_per_m * r
             - 10.0 * np.log10(area) + options.calibration_db)
    return np.where((i > 0) & np.isfinite(s), s, np.nan)


def incidence_angle_deg(angle_deg, slope_deg: float):
    """Incidence angle on a seabed tilted across-track (deg).

    A beam at ``a`` from nadir (starboard positive) meets a seabed sloping by
    ``phi`` (deeper to starboard positive) at ``i = |a + phi|`` from its
    normal.

    Parameters
    ----------
    angle_deg : array_like
        Beam angles from nadir (deg).
    slope_deg : float
        Across-track seabed slope (deg).
    """
    return np.abs(np.asarray(angle_deg, dtype=np.float64) + slope_deg)


# ---------------------------------------------------------------------------
# Seabed
# ---------------------------------------------------------------------------
def _line_ranges(angles_rad, z0, slope):
    """Range along each beam to the line ``z = z0 + slope y`` (m); NaN if never."""
    den = np.cos(angles_rad) - slope * np.sin(angles_rad)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = z0 / den
    return np.where((den > 1e-6) & (r > 0), r, np.nan)


def _fit_line(y, z):
    """Trimmed least-squares line ``z = z0 + s y`` -> ``(z0, s, kept mask)``."""
    keep = np.isfinite(y) & np.isfinite(z)
    z0 = s = float("nan")
    for _ in range(5):
        if keep.sum() < 3:
            break
        s, z0 = np.polyfit(y[keep], z[keep], 1)
        res = z - (z0 + s * y)
        mad = np.median(np.abs(res[keep] - np.median(res[keep])))
        new = np.isfinite(res) & (np.abs(res) <= max(3.0 * 1.4826 * mad, 1.0))
        if np.array_equal(new, keep):
            break
        keep = new
    return float(z0), float(s), keep


def _pick_in_band(smooth, ranges, lo, hi):
    """Per beam, the range of the largest value of ``smooth`` within ``[lo, hi]``."""
    inside = (ranges[None, :] >= lo[:, None]) & (ranges[None, :] <= hi[:, None])
    vals = np.where(inside, smooth, -np.inf)
    k = np.argmax(vals, axis=1)
    rows = np.arange(len(k))
    ok = inside.any(axis=1) & np.isfinite(vals[rows, k]) & (vals[rows, k] > 0)
    # sub-cell peak: vertex of the parabola through the maximum and its neighbours
    km, kp = np.clip(k - 1, 0, len(ranges) - 1), np.clip(k + 1, 0, len(ranges) - 1)
    y0, y1, y2 = smooth[rows, km], smooth[rows, k], smooth[rows, kp]
    curv = y0 - 2.0 * y1 + y2
    with np.errstate(divide="ignore", invalid="ignore"):
        shift = np.where((km < k) & (kp > k) & (curv < 0), 0.5 * (y0 - y2) / curv, 0.0)
    step = ranges[kp] - ranges[km]
    return np.where(ok, ranges[k] + np.clip(shift, -0.5, 0.5) * 0.5 * step, np.nan)


def pick_seabed(intensity, angles_deg, ranges_m, options: ResponseOptions | None = None) -> SeabedLine:
    """Seabed of one ping: first strong return, per-beam picks, fitted line.

    Parameters
    ----------
    intensity : array_like
        One ping's intensity ``(n_angle, n_range)``.
    angles_deg : array_like
        Beam angles from nadir, starboard positive (deg).
    ranges_m : array_like
        Ranges from the grid centre (m), increasing.
    options : ResponseOptions, optional
        Picking parameters (``below_peak_db``, ``band_m``, ``smooth_m``).

    Returns
    -------
    SeabedLine

    Raises
    ------
    ClbeamError
        No beam within 2° of nadir, or no seabed found.
    """
    o = options or ResponseOptions()
    inten = np.nan_to_num(np.asarray(intensity, dtype=np.float64), nan=0.0)
    ang = np.asarray(angles_deg, dtype=np.float64)
    rng = np.asarray(ranges_m, dtype=np.float64)
    a_rad = np.deg2rad(ang)
    dr = float(np.median(np.diff(rng))) if rng.size > 1 else 1.0
    # odd length: a centred mean, so the smoothing shifts no pick
    smooth = uniform_filter1d(inten, size=2 * int(round(o.smooth_m / (2 * dr))) + 1, axis=1, mode="nearest")
    near = np.abs(ang) <= max(2.0, float(np.min(np.abs(ang))))
    require(near.any(), ClbeamError, "cannot pick the seabed: no beam within 2 degrees of nadir")
    profile = smooth[near].mean(axis=0)
    require(profile.size > 0 and np.max(profile) > 0, ClbeamError,
            "cannot pick the seabed: the ping's image has no intensity near nadir")
    k = int(np.argmax(profile >= np.max(profile) * 10 ** (-o.below_peak_db / 10)))
    h = float(rng[k])
    # first pass: a flat seabed at h, widened for slopes up to MAX_SLOPE_DEG
    y_flat = h * np.tan(np.abs(a_rad))
    widen = o.band_m + y_flat * math.tan(math.radians(MAX_SLOPE_DEG))
    cos_a = np.cos(a_rad)
    picks = _pick_in_band(smooth, rng, np.maximum(h - widen, 0.0) / cos_a, (h + widen) / cos_a)
    z0, s, keep = _fit_line(picks * np.sin(a_rad), picks * cos_a)
    require(np.isfinite(z0) and z0 > 0, ClbeamError, "cannot pick the seabed: fewer than 3 beams have a seabed echo")
    # second pass: a narrow band around the fitted line
    line = _line_ranges(a_rad, z0, s)
    picks = _pick_in_band(smooth, rng, line - o.band_m, line + o.band_m)
    z0b, sb, keep = _fit_line(picks * np.sin(a_rad), picks * cos_a)
    if np.isfinite(z0b) and z0b > 0:
        z0, s = z0b, sb
    line = _line_ranges(a_rad, z0, s)
    line = np.where((line >= rng[0]) & (line <= rng[-1]), line, np.nan)
    return SeabedLine(z0_m=z0, slope=s, range_m=line, picks_m=np.where(keep, picks, np.nan))


# ---------------------------------------------------------------------------
# One ping, a whole file
# ---------------------------------------------------------------------------
def _bin_edges(centres):
    c = np.asarray(centres, dtype=np.float64)
    require(c.ndim == 1 and c.size >= 2 and np.all(np.diff(c) > 0), OptionError,
            "incidence_deg must be at least 2 increasing bin centres")
    mid = 0.5 * (c[1:] + c[:-1])
    return np.concatenate([[c[0] - (mid[0] - c[0])], mid, [c[-1] + (c[-1] - mid[-1])]])


def _bin_linear(values_db, x, edges):
    """Linear-intensity mean of ``values_db`` in bins of ``x``; NaN if empty."""
    out = np.full(edges.size - 1, np.nan)
    ok = np.isfinite(values_db) & np.isfinite(x)
    idx = np.searchsorted(edges, x[ok], side="right") - 1
    inside = (idx >= 0) & (idx < out.size)
    idx, v = idx[inside], 10.0 ** (values_db[ok][inside] / 10.0)
    total = np.bincount(idx, weights=v, minlength=out.size)
    count = np.bincount(idx, minlength=out.size)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(count > 0, 10.0 * np.log10(total / count), np.nan)
    return out


def beam_strengths(intensity, angles_deg, ranges_m, seabed: SeabedLine, options: ResponseOptions):
    """Strength (dB) and incidence (deg) of every beam of one ping.

    Parameters
    ----------
    intensity : array_like
        One ping's intensity ``(n_angle, n_range)``.
    angles_deg, ranges_m : array_like
        Grid coordinates (deg, m).
    seabed : SeabedLine
        From :func:`pick_seabed`.
    options : ResponseOptions
        Correction parameters.

    Returns
    -------
    strength_db, incidence_deg : numpy.ndarray
        ``(n_angle,)`` each; NaN strength where the beam has no seabed.
    """
    inten = np.asarray(intensity, dtype=np.float64)
    ang = np.asarray(angles_deg, dtype=np.float64)
    rng = np.asarray(ranges_m, dtype=np.float64)
    inc = incidence_angle_deg(ang, seabed.slope_deg)
    r0 = seabed.range_m
    beam = options.wavelength_m / (options.rx_width_m * np.cos(np.deg2rad(ang)))
    extent = r0 * np.tan(np.deg2rad(np.minimum(inc, 89.0))) * beam
    half = extent / 8.0
    level = np.full(ang.size, np.nan)
    for j in np.flatnonzero(np.isfinite(r0)):
        lo, hi = np.searchsorted(rng, [r0[j] - half[j], r0[j] + half[j]], side="left")
        if hi <= lo:  # no cell centre within +-w: the nearest cell
            lo = int(np.argmin(np.abs(rng - r0[j])))
            hi = lo + 1
        cells = inten[j, lo:hi]
        cells = cells[np.isfinite(cells)]
        if cells.size:
            level[j] = cells.mean()
    return strength_from_intensity_db(level, r0, inc, options, steering_deg=ang), inc


def ping_response(intensity, angles_deg, ranges_m, incidence_deg=DEFAULT_INCIDENCE_DEG,
                  options: ResponseOptions | None = None):
    """Angular response of one ping, per side.

    Parameters
    ----------
    intensity : array_like
        Intensity ``(n_angle, n_range)``.
    angles_deg, ranges_m : array_like
        Grid coordinates (deg from nadir, starboard positive; m from the source).
    incidence_deg : array_like
        Bin centres (deg).
    options : ResponseOptions, optional
        Parameters.

    Returns
    -------
    port_db, starboard_db : numpy.ndarray
        Strength per bin (dB), ``(n_bin,)`` each.
    seabed : SeabedLine
    """
    o = options or ResponseOptions()
    edges = _bin_edges(incidence_deg)
    seabed = pick_seabed(intensity, angles_deg, ranges_m, o)
    s, inc = beam_strengths(intensity, angles_deg, ranges_m, seabed, o)
    ang = np.asarray(angles_deg, dtype=np.float64)
    port = _bin_linear(np.where(ang < 0, s, np.nan), inc, edges)
    stbd = _bin_linear(np.where(ang >= 0, s, np.nan), inc, edges)
    return port, stbd, seabed


def along_track_positions_m(latitude_deg, longitude_deg, *, ping_spacing_m: float = 1.0) -> np.ndarray:
    """Along-track position of each ping (m) from navigation.

    Cumulative geodesic distance between consecutive positions on the
    WGS84 ellipsoid (:func:`clbeam.model.geodesy.along_track_m`).
    When any position is missing: ping index x ``ping_spacing_m``.

    Parameters
    ----------
    latitude_deg, longitude_deg : array_like
        Per-ping navigation (deg).
    ping_spacing_m : float
        Spacing used without navigation (m).

    Returns
    -------
    numpy.ndarray
        ``(n_ping,)``, 0 at the first ping.
    """
    lat = np.asarray(latitude_deg, dtype=np.float64)
    lon = np.asarray(longitude_deg, dtype=np.float64)
    if lat.size == 0 or not (np.all(np.isfinite(lat)) and np.all(np.isfinite(lon))):
        return np.arange(lat.size, dtype=np.float64) * float(ping_spacing_m)
    return along_track_m(lat, lon)


def angular_responses(images, incidence_deg=DEFAULT_INCIDENCE_DEG, options: ResponseOptions | None = None, *,
                      ping_spacing_m: float = 1.0) -> AngularResponse:
    """Angular responses of every ping of an image file.

    Parameters
    ----------
    images : str, pathlib.Path or xarray.Dataset
        Image file written by ``clbeam image`` (or the opened dataset).
    incidence_deg : array_like
        Incidence bin centres (deg).
    options : ResponseOptions, optional
        Sonar and correction parameters.
    ping_spacing_m : float
        Along-track spacing used when the file has no navigation (m).

    Returns
    -------
    AngularResponse

    Raises
    ------
    ClbeamError
        Not an image file, no ``intensity`` variable, no pings, or a ping
        whose seabed cannot be picked.
    """
    o = options or ResponseOptions()
    inc_bins = np.asarray(incidence_deg, dtype=np.float64)
    _bin_edges(inc_bins)
    own = not hasattr(images, "data_vars")
    ds = open_images(images) if own else images
    name = Path(images).name if own else "image dataset"
    try:
        require("intensity" in ds.variables, ClbeamError,
                f"{name}: no variable 'intensity' (image with --outputs including intensity needed)")
        n = int(ds.sizes.get("ping", 0))
        require(n >= 1, ClbeamError, f"{name}: holds no pings")
        ang = np.asarray(ds["angle"].values, dtype=np.float64)
        rng = np.asarray(ds["range"].values, dtype=np.float64)
        port = np.full((n, inc_bins.size), np.nan)
        stbd = np.full((n, inc_bins.size), np.nan)
        slope = np.full(n, np.nan)
        depth = np.full(n, np.nan)
        var = ds["intensity"]
        for p in range(n):
            try:
                port[p], stbd[p], sb = ping_response(np.asarray(var[p].values), ang, rng, inc_bins, o)
            except ClbeamError as exc:
                raise ClbeamError(f"{name}: ping {p}: {exc}") from None
            slope[p], depth[p] = sb.slope_deg, sb.z0_m
        lat = ds["latitude"].values if "latitude" in ds.variables else np.full(n, np.nan)
        lon = ds["longitude"].values if "longitude" in ds.variables else np.full(n, np.nan)
        along = along_track_positions_m(lat, lon, ping_spacing_m=ping_spacing_m)
    finally:
        if own:
            ds.close()
    return AngularResponse(incidence_deg=inc_bins, port_db=port, starboard_db=stbd, along_track_m=along,
                           seabed_slope_deg=slope, seabed_depth_m=depth, options=o)
