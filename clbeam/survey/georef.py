"""Georeferencing of coherence peaks: ping navigation to WGS84 and UTM positions.

A ping's image plane is vertical and perpendicular to its heading, so a
peak ``y`` metres to starboard lies ``|y|`` metres from the ping along the
azimuth ``heading ± 90`` degrees.  The point is found on the WGS84 ellipsoid
(:func:`clbeam.model.geodesy.geodesic_direct`) and then projected to UTM
with pyproj; the offset is never added in grid coordinates, whose north
differs from true north by the meridian convergence.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from clbeam.model.geodesy import geodesic_direct

log = logging.getLogger(__name__)


def utm_epsg(latitude_deg: float, longitude_deg: float) -> int:
    """EPSG code of the standard UTM zone (WGS84) holding a position.

    326zz north of the equator, 327zz south, zone ``floor((lon + 180) / 6)
    + 1``; the Norway and Svalbard exceptions are not applied.

    Parameters
    ----------
    latitude_deg, longitude_deg : float
        The position (degree).

    Returns
    -------
    int
    """
    zone = int(math.floor((((longitude_deg + 180.0) % 360.0)) / 6.0)) + 1
    return (32600 if latitude_deg >= 0 else 32700) + min(zone, 60)


def peak_positions(latitude_deg, longitude_deg, heading_deg, y_m):
    """Latitude and longitude of points ``y_m`` to starboard of ping positions.

    The cross-track plane of a ping is vertical and perpendicular to its
    heading, so a point ``y`` metres to starboard (docs/ping-format.md) lies at
    horizontal distance ``|y|`` along the azimuth ``heading + 90`` degrees
    (``heading - 90`` for port, ``y < 0``), measured clockwise from true
    north.  The point is found on the WGS84 ellipsoid along that geodesic
    (:func:`clbeam.model.geodesy.geodesic_direct`), which avoids the grid
    convergence of a projected offset (about 1.7 degrees three degrees off
    a UTM central meridian at 34 degrees north: 17 m at 600 m).

    Parameters
    ----------
    latitude_deg, longitude_deg : array_like
        Ping positions (degree).
    heading_deg : array_like
        Ping headings, clockwise from true north (degree).
    y_m : array_like
        Cross-track offsets, positive to starboard (m).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Latitude and longitude (degree) of the points; NaN where an input is.
    """
    lat, lon, hdg, y = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64)
                                             for a in (latitude_deg, longitude_deg, heading_deg, y_m)))
    azimuth = np.where(y >= 0, hdg + 90.0, hdg - 90.0)
    return geodesic_direct(lat, lon, azimuth, np.abs(y))


def to_utm(latitude_deg, longitude_deg, epsg: int):
    """Easting and northing in a UTM zone (pyproj).

    Parameters
    ----------
    latitude_deg, longitude_deg : array_like
        WGS84 positions (degree).
    epsg : int
        The zone (:func:`utm_epsg`).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Easting and northing (m); NaN where a position is not finite.
    """
    import pyproj

    tr = pyproj.Transformer.from_crs("EPSG:4326", f"EPSG:{epsg}", always_xy=True)
    lon, lat = np.asarray(longitude_deg, dtype=np.float64), np.asarray(latitude_deg, dtype=np.float64)
    e, n = tr.transform(lon, lat)
    e, n = np.asarray(e, dtype=np.float64), np.asarray(n, dtype=np.float64)
    bad = ~(np.isfinite(lat) & np.isfinite(lon))
    e[bad] = np.nan
    n[bad] = np.nan
    return e, n


def meridian_convergence_deg(latitude_deg, longitude_deg, epsg: int) -> np.ndarray:
    """Meridian convergence in a UTM zone (pyproj): the angle from grid north to true north.

    Parameters
    ----------
    latitude_deg, longitude_deg : array_like
        WGS84 positions (degree).
    epsg : int
        The zone.

    Returns
    -------
    numpy.ndarray
        Convergence (degree); a true azimuth is the grid azimuth plus it.
    """
    import pyproj

    f = pyproj.Proj(f"EPSG:{epsg}").get_factors(longitude_deg, latitude_deg)
    return np.asarray(f.meridian_convergence, dtype=np.float64)


def course_over_ground_deg(easting_m, northing_m) -> np.ndarray:
    """Course over ground of a track from its grid positions.

    Central differences of consecutive positions (one-sided at the ends).

    Parameters
    ----------
    easting_m, northing_m : array_like
        ``(n,)`` positions in ping order (m); NaN for a ping without one.

    Returns
    -------
    numpy.ndarray
        ``(n,)`` course (degree clockwise from grid north); NaN where a ping
        has no position, or fewer than two pings have one.
    """
    e, n = np.asarray(easting_m, dtype=np.float64), np.asarray(northing_m, dtype=np.float64)
    out = np.full(e.shape, np.nan)
    idx = np.flatnonzero(np.isfinite(e) & np.isfinite(n))
    if idx.size < 2:
        return out
    ee, nn = e[idx], n[idx]
    de, dn = np.gradient(ee), np.gradient(nn)
    out[idx] = np.rad2deg(np.arctan2(de, dn)) % 360.0
    return out


class SurveyNavigation:
    """Per-ping navigation of a survey, and the georeferencing of its peaks.

    Fill :attr:`lat`, :attr:`lon`, :attr:`heading_file` and :attr:`time_s`
    ping by ping, then call :meth:`finish`.

    Parameters
    ----------
    n : int
        Survey pings.
    speed_m_s : float or None
        Ship speed (m/s) for the along-track distance of pings without
        navigation.

    Attributes
    ----------
    lat, lon : numpy.ndarray
        ``(n,)`` ping positions (degree; NaN: none).
    heading_file : numpy.ndarray
        ``(n,)`` headings of the input files (degree; NaN: none).
    heading : numpy.ndarray
        ``(n,)`` headings used: the file's, or the course over ground
        turned to true north (after :meth:`finish`).
    time_s : numpy.ndarray
        ``(n,)`` ping times (POSIX seconds; NaN: none).
    epsg : int or None
        UTM zone of the first navigated ping.
    e, n : numpy.ndarray
        ``(n,)`` UTM ping positions (m), with navigation.
    has_nav : numpy.ndarray
        ``(n,)`` bool: the ping has a position.
    all_nav : bool
        Every imaged ping has a position (and one is imaged).
    """

    def __init__(self, n: int, speed_m_s: float | None):
        self.lat = np.full(n, np.nan)
        self.lon = np.full(n, np.nan)
        self.heading = np.full(n, np.nan)
        self.heading_file = np.full(n, np.nan)
        self.time_s = np.full(n, np.nan)
        self.speed = speed_m_s
        self.epsg = None
        self._conv = None

    def finish(self, imaged: np.ndarray) -> None:
        """Fill the headings and the UTM positions once every record is read.

        Parameters
        ----------
        imaged : numpy.ndarray
            ``(n,)`` bool: the ping is committed.
        """
        nav = np.isfinite(self.lat) & np.isfinite(self.lon)
        self.has_nav = nav
        self.all_nav = bool(imaged.any()) and bool(nav[imaged].all())
        self.heading = self.heading_file.copy()
        if nav.any():
            k = int(np.flatnonzero(nav)[0])
            self.epsg = utm_epsg(self.lat[k], self.lon[k])
            self.e, self.n = to_utm(self.lat, self.lon, self.epsg)
            missing = nav & ~np.isfinite(self.heading)
            if missing.any():
                # course over ground in grid coordinates, turned to true north: add the meridian convergence
                cog = course_over_ground_deg(self.e, self.n)
                conv = meridian_convergence_deg(self.lat[missing], self.lon[missing], self.epsg)
                self.heading[missing] = (cog[missing] + conv) % 360.0
                log.warning("%d navigated ping(s) have no heading: course over ground used", int(missing.sum()))
        t = self.time_s[np.isfinite(self.time_s)]
        self.t_ref = float(t.min()) if t.size else np.nan
        blind = imaged & ~nav
        if blind.any() and (self.speed is None or not t.size):
            log.warning("%d ping(s) have no navigation%s: along-track distance unknown (give the ping times "
                        "and --speed)", int(blind.sum()), "" if t.size else " and no ping times")

    def along_m(self, pings) -> np.ndarray:
        """Along-track distance (m) of ``pings``: speed x (ping time - first ping time); NaN without speed."""
        if self.speed is None:
            return np.full(np.shape(pings), np.nan)
        return self.speed * (self.time_s[pings] - self.t_ref)

    def peak_columns(self, pings: np.ndarray, y_m: np.ndarray) -> dict:
        """Georeferenced columns for peaks of ``pings`` at cross-track offsets ``y_m`` (m).

        Returns
        -------
        dict of str to numpy.ndarray
            ``ping_latitude_deg``, ``ping_longitude_deg``, ``heading_deg``,
            ``peak_latitude_deg``, ``peak_longitude_deg``, ``easting_m``,
            ``northing_m`` and ``along_track_m`` (pings without navigation only).
        """
        plat, plon = peak_positions(self.lat[pings], self.lon[pings], self.heading[pings], y_m)
        cols = {"ping_latitude_deg": self.lat[pings], "ping_longitude_deg": self.lon[pings],
                "heading_deg": self.heading[pings], "peak_latitude_deg": plat, "peak_longitude_deg": plon}
        if self.epsg is not None:
            cols["easting_m"], cols["northing_m"] = to_utm(plat, plon, self.epsg)
        else:
            cols["easting_m"] = cols["northing_m"] = np.full(np.shape(y_m), np.nan)
        cols["along_track_m"] = np.where(self.has_nav[pings], np.nan, self.along_m(pings))
        return cols

    def frame(self, pings: np.ndarray, y_m: np.ndarray, cols: dict) -> tuple:
        """The association frame of peaks (:func:`clbeam.survey.association.associate`).

        Parameters
        ----------
        pings, y_m : numpy.ndarray
            ``(k,)`` survey pings and cross-track offsets (m).
        cols : dict
            Their :meth:`peak_columns`.

        Returns
        -------
        (numpy.ndarray, numpy.ndarray)
            ``(k, 2)`` positions (m): easting and northing when every
            imaged ping is navigated, along- and across-track distance
            otherwise; ``(k, 2)`` starboard unit vectors in the same frame.
        """
        if self.all_nav:
            h = np.deg2rad(self.heading[pings])
            # the starboard direction in grid coordinates: true azimuth heading + 90 less the convergence
            conv = np.deg2rad(self.convergence_at(pings))
            sb = np.stack([np.cos(h - conv), -np.sin(h - conv)], axis=1)
            return np.stack([cols["easting_m"], cols["northing_m"]], axis=1), sb
        return np.stack([self.along_m(pings), y_m], axis=1), np.tile([0.0, 1.0], (len(pings), 1))

    def convergence_at(self, pings) -> np.ndarray:
        """Meridian convergence (degree, grid north to true north) at ``pings``; 0 without navigation."""
        if self._conv is None:
            self._conv = np.zeros(self.lat.size)
            nav = self.has_nav
            if nav.any():
                self._conv[nav] = meridian_convergence_deg(self.lat[nav], self.lon[nav], self.epsg)
        return self._conv[pings]
