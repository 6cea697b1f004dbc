"""Positions on the WGS84 ellipsoid: one geodesic for every distance and offset.

Every along-track distance and every point "so many metres along an
azimuth" in clbeam (simulated navigation, georeferenced peaks, profile and
AVO along-track axes, the survey association) comes from the two functions
here, so they agree to the millimetre.  With pyproj installed (the
``survey`` extra) they call :class:`pyproj.Geod` (Karney's algorithm);
without it they solve the same ellipsoidal geodesic by Vincenty's
iterations (Vincenty 1975), which agree with Karney's to well below a
millimetre for the distances a survey spans (tested).

References
----------
T. Vincenty, "Direct and inverse solutions of geodesics on the ellipsoid
with application of nested equations", Survey Review 23 (176), 1975.
C. F. F. Karney, "Algorithms for geodesics", J. Geodesy 87, 2013.
"""

from __future__ import annotations

import numpy as np

from clbeam.constants import WGS84_A_M, WGS84_F

_B_M = WGS84_A_M * (1.0 - WGS84_F)
#: Vincenty iterations stop when the longitude on the auxiliary sphere changes less than this (rad, ~0.06 mm)
_TOLERANCE_RAD = 1e-13
_MAX_ITERATIONS = 200


def _geod():
    """A WGS84 :class:`pyproj.Geod`, or ``None`` without pyproj."""
    try:
        import pyproj
    except ImportError:
        return None
    return pyproj.Geod(ellps="WGS84")


def _floats(*values):
    return np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in values))


def geodesic_direct(latitude_deg, longitude_deg, azimuth_deg, distance_m, *, use_pyproj: bool = True):
    """The point ``distance_m`` from a position along an azimuth (WGS84).

    Parameters
    ----------
    latitude_deg, longitude_deg : array_like
        Start positions (degree).
    azimuth_deg : array_like
        Azimuths at the start, clockwise from true north (degree).
    distance_m : array_like
        Distances along the geodesic (m, >= 0).
    use_pyproj : bool
        Use pyproj when it is installed (default); ``False`` forces the
        built-in solution.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Latitude and longitude (degree) of the end points; NaN where an input is.
    """
    lat, lon, az, s = _floats(latitude_deg, longitude_deg, azimuth_deg, distance_m)
    out_lat, out_lon = np.full(lat.shape, np.nan), np.full(lat.shape, np.nan)
    ok = np.isfinite(lat) & np.isfinite(lon) & np.isfinite(az) & np.isfinite(s)
    geod = _geod() if use_pyproj else None
    if ok.any() and geod is not None:
        lon2, lat2, _ = geod.fwd(lon[ok], lat[ok], az[ok], s[ok])
        out_lat[ok], out_lon[ok] = lat2, lon2
    elif ok.any():
        out_lat[ok], out_lon[ok] = _vincenty_direct(lat[ok], lon[ok], az[ok], s[ok])
    return out_lat, out_lon


def geodesic_inverse(lat1_deg, lon1_deg, lat2_deg, lon2_deg, *, use_pyproj: bool = True):
    """Distance and forward azimuth between two positions (WGS84).

    Parameters
    ----------
    lat1_deg, lon1_deg, lat2_deg, lon2_deg : array_like
        Positions (degree).
    use_pyproj : bool
        Use pyproj when it is installed (default).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Geodesic distance (m) and azimuth at the first point (degree,
        clockwise from true north); NaN where an input is.
    """
    lat1, lon1, lat2, lon2 = _floats(lat1_deg, lon1_deg, lat2_deg, lon2_deg)
    dist, az = np.full(lat1.shape, np.nan), np.full(lat1.shape, np.nan)
    ok = np.isfinite(lat1) & np.isfinite(lon1) & np.isfinite(lat2) & np.isfinite(lon2)
    geod = _geod() if use_pyproj else None
    if ok.any() and geod is not None:
        a12, _, d = geod.inv(lon1[ok], lat1[ok], lon2[ok], lat2[ok])
        dist[ok], az[ok] = d, np.mod(a12, 360.0)
    elif ok.any():
        dist[ok], az[ok] = _vincenty_inverse(lat1[ok], lon1[ok], lat2[ok], lon2[ok])
    return dist, az


def along_track_m(latitude_deg, longitude_deg, *, use_pyproj: bool = True) -> np.ndarray:
    """Cumulative geodesic distance (m) along a track of positions, 0 at the first.

    Parameters
    ----------
    latitude_deg, longitude_deg : array_like
        ``(n,)`` positions in track order (degree); all finite.

    Returns
    -------
    numpy.ndarray
        ``(n,)`` distances (m).
    """
    lat = np.asarray(latitude_deg, dtype=np.float64).ravel()
    lon = np.asarray(longitude_deg, dtype=np.float64).ravel()
    if lat.size < 2:
        return np.zeros(lat.size)
    step, _ = geodesic_inverse(lat[:-1], lon[:-1], lat[1:], lon[1:], use_pyproj=use_pyproj)
    return np.concatenate([[0.0], np.cumsum(step)])


def _reduced_latitude(lat_rad):
    return np.arctan((1.0 - WGS84_F) * np.tan(lat_rad))


def _series(u2):
    """Vincenty's A and B coefficients of the geodesic length series."""
    a = 1 + u2 / 16384 * (4096 + u2 * (-768 + u2 * (320 - 175 * u2)))
    b = u2 / 1024 * (256 + u2 * (-128 + u2 * (74 - 47 * u2)))
    return a, b


def _delta_sigma(b, sin_s, cos_s, cos_2sm):
    return b * sin_s * (cos_2sm + b / 4 * (cos_s * (-1 + 2 * cos_2sm ** 2)
                                          - b / 6 * cos_2sm * (-3 + 4 * sin_s ** 2) * (-3 + 4 * cos_2sm ** 2)))


def _vincenty_direct(lat, lon, az, s):
    f, a, b_ax = WGS84_F, WGS84_A_M, _B_M
    alpha1 = np.deg2rad(az)
    u1 = _reduced_latitude(np.deg2rad(lat))
    sigma1 = np.arctan2(np.tan(u1), np.cos(alpha1))
    sin_alpha = np.cos(u1) * np.sin(alpha1)
    cos2_alpha = 1 - sin_alpha ** 2
    u2 = cos2_alpha * (a * a - b_ax * b_ax) / (b_ax * b_ax)
    big_a, big_b = _series(u2)
    sigma = s / (b_ax * big_a)
    for _ in range(_MAX_ITERATIONS):
        cos_2sm = np.cos(2 * sigma1 + sigma)
        new = s / (b_ax * big_a) + _delta_sigma(big_b, np.sin(sigma), np.cos(sigma), cos_2sm)
        done = np.all(np.abs(new - sigma) < _TOLERANCE_RAD)
        sigma = new
        if done:
            break
    sin_s, cos_s = np.sin(sigma), np.cos(sigma)
    cos_2sm = np.cos(2 * sigma1 + sigma)
    tmp = np.sin(u1) * sin_s - np.cos(u1) * cos_s * np.cos(alpha1)
    lat2 = np.arctan2(np.sin(u1) * cos_s + np.cos(u1) * sin_s * np.cos(alpha1),
                      (1 - f) * np.sqrt(sin_alpha ** 2 + tmp ** 2))
    lam = np.arctan2(sin_s * np.sin(alpha1), np.cos(u1) * cos_s - np.sin(u1) * sin_s * np.cos(alpha1))
    c = f / 16 * cos2_alpha * (4 + f * (4 - 3 * cos2_alpha))
    big_l = lam - (1 - c) * f * sin_alpha * (sigma + c * sin_s * (cos_2sm + c * cos_s * (-1 + 2 * cos_2sm ** 2)))
    lon2 = np.mod(np.deg2rad(lon) + big_l + np.pi, 2 * np.pi) - np.pi
    return np.rad2deg(lat2), np.rad2deg(lon2)


def _vincenty_inverse(lat1, lon1, lat2, lon2):
    f, a, b_ax = WGS84_F, WGS84_A_M, _B_M
    u1, u2 = _reduced_latitude(np.deg2rad(lat1)), _reduced_latitude(np.deg2rad(lat2))
    big_l = np.mod(np.deg2rad(lon2 - lon1) + np.pi, 2 * np.pi) - np.pi
    lam = big_l.copy()
    for _ in range(_MAX_ITERATIONS):
        sin_s = np.hypot(np.cos(u2) * np.sin(lam),
                         np.cos(u1) * np.sin(u2) - np.sin(u1) * np.cos(u2) * np.cos(lam))
        cos_s = np.sin(u1) * np.sin(u2) + np.cos(u1) * np.cos(u2) * np.cos(lam)
        sigma = np.arctan2(sin_s, cos_s)
        with np.errstate(invalid="ignore", divide="ignore"):
            sin_alpha = np.where(sin_s == 0, 0.0, np.cos(u1) * np.cos(u2) * np.sin(lam) / sin_s)
            cos2_alpha = 1 - sin_alpha ** 2
            cos_2sm = np.where(cos2_alpha == 0, 0.0, cos_s - 2 * np.sin(u1) * np.sin(u2) / cos2_alpha)
        c = f / 16 * cos2_alpha * (4 + f * (4 - 3 * cos2_alpha))
        new = big_l + (1 - c) * f * sin_alpha * (sigma + c * sin_s * (cos_2sm + c * cos_s * (-1 + 2 * cos_2sm ** 2)))
        done = np.all(np.abs(new - lam) < _TOLERANCE_RAD)
        lam = new
        if done:
            break
    u_sq = cos2_alpha * (a * a - b_ax * b_ax) / (b_ax * b_ax)
    big_a, big_b = _series(u_sq)
    dist = b_ax * big_a * (sigma - _delta_sigma(big_b, sin_s, cos_s, cos_2sm))
    az = np.arctan2(np.cos(u2) * np.sin(lam), np.cos(u1) * np.sin(u2) - np.sin(u1) * np.cos(u2) * np.cos(lam))
    return dist, np.mod(np.rad2deg(az), 360.0)
