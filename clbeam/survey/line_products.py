"""The survey's lines: detections placed against their seabed, tracked, scored, described.

:func:`survey_lines` takes what the first reading of the ledger keeps (the
detections, each ping's seabed fitted to its peaks, the navigation) and
returns the line rows of ``OUT.lines.csv`` and ``OUT.lines.geojson`` and the
line of every detection.  The line search is :mod:`clbeam.survey.lines`,
the seabed and the arcs :mod:`clbeam.survey.burial`, the score
:mod:`clbeam.survey.line_score`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from clbeam.io.survey_products import LINE_COLUMNS, LINE_KINDS  # noqa: F401 (LINE_KINDS re-exported)
from clbeam.survey.burial import arc_constrained
from clbeam.survey.georef import SurveyNavigation, peak_positions, to_utm
from clbeam.survey.line_options import LineOptions
from clbeam.survey.line_score import SearchSize, clutter_density, line_score
from clbeam.survey.lines import Track, TrackFrame, find_tracks, line_burial, smooth_path

log = logging.getLogger(__name__)


@dataclass
class LineDetections:
    """The detections of a survey as the line search needs them.

    Attributes
    ----------
    ping : numpy.ndarray
        ``(n,)`` survey pings.
    y, z, cf : numpy.ndarray
        ``(n,)`` cross-track offsets and depths (m, earth frame) and CFs.
    """

    ping: np.ndarray
    y: np.ndarray
    z: np.ndarray
    cf: np.ndarray


@dataclass
class SurveyLines:
    """What :func:`survey_lines` found.

    Attributes
    ----------
    rows : list of dict
        One per kept line (score at least ``min_score``), in line order.
    paths : list of numpy.ndarray
        Per line, ``(k, 2)`` positions of its path ping by ping in the
        association frame (:meth:`SurveyNavigation.frame`): UTM easting and
        northing (m) with navigation, along- and across-track (m) without.
    geo_paths : list of numpy.ndarray or None
        With navigation, per line ``(k, 2)`` ``[longitude, latitude]`` (degree).
    labels : numpy.ndarray
        ``(n,)`` line of each detection (-1: none).
    n_candidates : int
        Tracks found before the score threshold.
    min_score : float
        That threshold.
    """

    rows: list
    paths: list
    labels: np.ndarray
    n_candidates: int
    geo_paths: list | None = None
    min_score: float = math.nan


def smooth_seabed(seabed: np.ndarray, imaged: np.ndarray, half_window: int = 4) -> np.ndarray:
    """Each ping's seabed ``(z0, slope)`` as the running median over ``2 half_window + 1`` imaged pings.

    The seabed changes over hundreds of metres, a ping's fit by a metre from
    one ping to the next: the median steadies it and fills pings with none.
    """
    out = np.full_like(seabed, np.nan)
    idx = np.flatnonzero(imaged)
    vals = seabed[idx]
    for j, k in enumerate(idx):
        win = vals[max(0, j - half_window):j + half_window + 1]
        ok = np.isfinite(win).all(axis=1)
        if ok.any():
            out[k] = np.median(win[ok], axis=0)
    return out


def track_distance_m(nav: SurveyNavigation, pings: np.ndarray) -> tuple[np.ndarray, bool]:
    """Along-track distance of ``pings`` (m) and whether it is known.

    The distance travelled between the navigated positions, or the ship
    speed times the ping time; without either, the ping number (then
    lengths and headings are not reported).
    """
    if nav.all_nav:
        e, n = nav.e[pings], nav.n[pings]
        return np.r_[0.0, np.cumsum(np.hypot(np.diff(e), np.diff(n)))], True
    s = nav.along_m(pings)
    if np.isfinite(s).all():
        return s, True
    return pings.astype(np.float64), False


def survey_lines(det: LineDetections, seabed: np.ndarray, centre_yz: np.ndarray, imaged: np.ndarray,
                 nav: SurveyNavigation, options: LineOptions) -> SurveyLines:
    """Lines of a survey's detections: found, scored, given a kind, described.

    Parameters
    ----------
    det : LineDetections
        The detections (CF above the map threshold).
    seabed : numpy.ndarray
        ``(n_pings, 2)`` each ping's seabed ``(z0, slope)``
        (:func:`clbeam.survey.burial.seabed_line`; NaN: none).
    centre_yz : numpy.ndarray
        ``(n_pings, 2)`` grid centres (m).
    imaged : numpy.ndarray
        ``(n_pings,)`` bool.
    nav : SurveyNavigation
        After :meth:`~SurveyNavigation.finish`.
    options : LineOptions

    Returns
    -------
    SurveyLines
    """
    n = det.ping.size
    pings = np.flatnonzero(imaged)
    if n == 0 or pings.size < 2:
        return SurveyLines([], [], np.full(n, -1, dtype=np.int64), 0, [] if nav.all_nav else None, options.min_score)
    sb = smooth_seabed(seabed, imaged)
    order = np.argsort(det.ping, kind="stable")
    frame = _frame(det, order, sb, centre_yz, pings, nav)
    scaled = track_distance_m(nav, pings)[1]
    tracks = find_tracks(frame, options)
    size = _search_size(frame)
    rows, paths, geo, labels = [], [], [], np.full(n, -1, dtype=np.int64)
    for tr in tracks:
        row, path, lonlat = _describe(frame, tr, options, size, sb, centre_yz, nav, scaled)
        if row["score"] < options.min_score:
            continue
        row["line"] = len(rows)
        labels[order[tr.members]] = row["line"]
        rows.append(row)
        paths.append(path)
        geo.append(lonlat)
    return SurveyLines(rows, paths, labels, len(tracks), geo if nav.all_nav else None, options.min_score)


def _frame(det: LineDetections, order: np.ndarray, sb: np.ndarray, centre_yz: np.ndarray, pings: np.ndarray,
           nav: SurveyNavigation) -> TrackFrame:
    """The detections in the track frame, each moved along its arc against its ping's seabed."""
    p = det.ping[order]
    y, z = det.y[order], det.z[order]
    ya, b, sd, bpost = (np.full(p.size, np.nan) for _ in range(4))
    known = np.isfinite(sb[p]).all(axis=1)
    for g in np.unique(p[known]):
        m = p == g
        ya[m], b[m], sd[m], bpost[m] = arc_constrained(y[m], z[m], centre_yz[g], tuple(sb[g]))
    ya[~known] = y[~known]
    s_ping = track_distance_m(nav, pings)[0]
    s = s_ping[np.searchsorted(pings, p)]
    return TrackFrame(ping=p, s=s, y=ya, b=b, cf=det.cf[order], b_sigma=sd, b_post=bpost,
                      pings=pings, ping_s=s_ping)


def _search_size(frame: TrackFrame) -> SearchSize:
    spacing = float(np.median(np.diff(frame.ping_s))) if frame.ping_s.size > 1 else 1.0
    b = frame.b[np.isfinite(frame.b)]
    return SearchSize(spacing_m=max(spacing, 1e-3), swath_m=float(np.ptp(frame.y)) if frame.y.size else 0.0,
                      burial_span_m=float(np.ptp(b)) if b.size else 0.0)


def _describe(frame: TrackFrame, tr: Track, options: LineOptions, size: SearchSize, sb: np.ndarray,
              centre_yz: np.ndarray, nav: SurveyNavigation, scaled: bool) -> tuple:
    """One line's row, path in the association frame, and ``[longitude, latitude]`` path (``None`` without navigation)."""
    m = tr.members
    path_y = smooth_path(frame, tr, options.fit_length_m / 2)
    ext = frame.pings[tr.first:tr.last + 1]
    burial, burial_se, spread = line_burial(frame.b[m], frame.b_sigma[m])
    resolved = math.isfinite(burial_se) and burial_se <= options.burial_resolution_m
    sig = frame.b_sigma[m][np.isfinite(frame.b_sigma[m])]
    gate_b = max(options.burial_gate_m, 2 * float(np.median(sig))) if sig.size else options.burial_gate_m
    others = np.setdiff1d(np.arange(int(frame.starts[tr.first]), int(frame.starts[tr.last + 1])), m)
    line_y_at = path_y[np.searchsorted(ext, frame.ping[others])]
    density = clutter_density(frame.y[others], frame.b[others], line_y_at, burial if math.isfinite(burial)
                              else math.nan, n_pings=ext.size, across_gate_m=options.across_gate_m,
                              burial_gate_m=gate_b, burial_half_m=max(3.0, 1.5 * gate_b))
    score = line_score(m.size, ext.size, density, options.across_gate_m, gate_b, size, options.max_angle_deg)
    z_line = sb[ext, 0] + sb[ext, 1] * path_y + (burial if math.isfinite(burial) else 0.0)
    angle = np.degrees(np.arctan2(path_y - centre_yz[ext, 0], z_line - centre_yz[ext, 1]))
    row = {"kind": line_kind(burial, resolved, float(np.median(np.abs(angle))), options),
           "n_pings": int(m.size), "first_ping": int(ext[0]), "last_ping": int(ext[-1]),
           "mean_cf": float(np.mean(frame.cf[m])), "score": float(score),
           "burial_m": burial, "burial_std_m": spread, "burial_error_m": burial_se, "burial_resolved": int(resolved),
           "mean_y_m": float(np.mean(path_y)), "mean_z_m": float(np.nanmean(z_line)),
           "detected_fraction": float(m.size / ext.size)}
    return (row, *_world_path(row, ext, path_y, frame.ping_s[tr.first:tr.last + 1], nav, scaled))


def _world_path(row: dict, pings: np.ndarray, y: np.ndarray, s: np.ndarray, nav: SurveyNavigation,
                scaled: bool) -> tuple:
    """The line's paths (association frame; longitude and latitude or ``None``), its length, heading and ends
    (filled in ``row``)."""
    if nav.all_nav:
        lat, lon = peak_positions(nav.lat[pings], nav.lon[pings], nav.heading[pings], y)
        e, n = to_utm(lat, lon, nav.epsg)
        row["length_m"] = float(np.hypot(np.diff(e), np.diff(n)).sum())
        # true azimuth of the chord, modulo 180 (a line has no direction): grid azimuth plus the convergence
        az = math.degrees(math.atan2(e[-1] - e[0], n[-1] - n[0])) + float(np.mean(nav.convergence_at(pings)))
        row["heading_deg"] = az % 180.0
        for tag, k in (("start", 0), ("end", -1)):
            row.update({f"{tag}_latitude_deg": float(lat[k]), f"{tag}_longitude_deg": float(lon[k]),
                        f"{tag}_easting_m": float(e[k]), f"{tag}_northing_m": float(n[k])})
        return np.stack([e, n], axis=1), np.stack([lon, lat], axis=1)
    row["length_m"] = float(np.hypot(np.diff(s), np.diff(y)).sum()) if scaled else math.nan
    # without navigation: relative to the track, positive turning to starboard
    row["heading_deg"] = math.degrees(math.atan2(y[-1] - y[0], s[-1] - s[0])) if scaled and s[-1] > s[0] else math.nan
    row.update({"start_along_track_m": float(s[0]) if scaled else math.nan,
                "end_along_track_m": float(s[-1]) if scaled else math.nan})
    return np.stack([s, y], axis=1), None


def line_rows(lines: SurveyLines, nav: SurveyNavigation) -> tuple:
    """Rows and columns of the line tables, and the GeoJSON paths.

    Returns
    -------
    (list of dict, list of str, list or None)
        Rows; columns (:data:`clbeam.io.survey_products.LINE_COLUMNS`, then
        the ends: WGS84 and UTM (m) with navigation, along-track distances
        (m) without); per line its ``[longitude, latitude]`` path (degree)
        with navigation, else ``None``.
    """
    extra = ("start_latitude_deg", "start_longitude_deg", "end_latitude_deg", "end_longitude_deg",
             "start_easting_m", "start_northing_m", "end_easting_m", "end_northing_m") if nav.all_nav else \
        ("start_along_track_m", "end_along_track_m")
    columns = list(LINE_COLUMNS) + list(extra)
    coords = [[[float(a), float(b)] for a, b in p] for p in lines.geo_paths] if lines.geo_paths is not None else None
    return [{c: r[c] for c in columns} for r in lines.rows], columns, coords


def line_kind(burial_m: float, resolved: bool, nadir_angle_deg: float, options: LineOptions) -> str:
    """The kind of a line from its burial (m), whether that is measured, and its typical angle from nadir (degree).

    ``pipeline``: buried between ``min_burial_m`` and ``max_burial_m``, or
    off nadir with a burial the geometry cannot resolve (near endfire a
    peak slides metres along its arc: ``burial_resolved`` 0 in the table);
    within ``nadir_angle_deg`` of nadir and not buried: ``seabed-nadir``
    (the seabed's specular echo and its pulse's tail), deeper than
    ``max_burial_m``: ``subbottom-nadir`` (a horizon's); else ``seabed``
    (within ``min_burial_m`` of it), ``water`` (above it), ``subbottom``
    (deeper than ``max_burial_m``), ``unknown`` (no seabed).
    """
    if not math.isfinite(burial_m):
        return "unknown"
    nadir = nadir_angle_deg <= options.nadir_angle_deg
    if burial_m > options.max_burial_m and (resolved or nadir):
        return "subbottom-nadir" if nadir else "subbottom"
    if burial_m >= options.min_burial_m and resolved or not (resolved or nadir):
        return "pipeline"
    if nadir:
        return "seabed-nadir"
    return "seabed" if burial_m > -options.min_burial_m else "water"
