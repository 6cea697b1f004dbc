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
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from clbeam.io.survey_products import LINE_COLUMNS, LINE_KINDS  # noqa: F401 (LINE_KINDS re-exported)
from clbeam.survey.burial import ARC_SIGMA_RAD, BURIAL_MODEL_SE_M, SEABED_SE_M, SPECULAR_K_SIGMA, arc_constrained, specular_fit
from clbeam.survey.edges import edges_from_nearest_point
from clbeam.survey.georef import SurveyNavigation, peak_positions, to_utm
from clbeam.survey.line_duplicates import effective_gates, extended_path, without_duplicates
from clbeam.survey.line_joins import joined_end_to_end
from clbeam.survey.line_options import LineOptions
from clbeam.survey.line_score import CF_LEVELS, SearchSize, clutter_hit_rate, copy_offsets, line_score
from clbeam.survey.lines import Track, TrackFrame, across_gate, burial_ok, find_tracks, line_burial, line_path
from clbeam.survey.specular import fading_fit, fading_floor_db, offsets_at_depth, specular_crossing

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
    intensity_db : numpy.ndarray or None
        ``(n,)`` intensities (dB): with them a line whose echoes fade as a
        smooth pipe's specular echo does is moved to where it crosses the
        pings' planes (:mod:`clbeam.survey.specular`).
    slide_rad : numpy.ndarray or None
        ``(n,)`` each peak's slide along its arc: the standard deviation of
        its angle at broadside (rad, :func:`clbeam.survey.burial.peak_slide_rad`);
        ``None``: :data:`clbeam.survey.burial.ARC_SIGMA_RAD` for all.
    smear_m : numpy.ndarray or None
        ``(n,)`` how much deeper each peak would lie than a line's crossing
        were it an echo of the line's stretch inside the transmit beam (m,
        :func:`clbeam.survey.burial.smear_deepening_m`): a diffuse line at a
        heading is raised by its mean (:func:`diffuse_shift`); ``None``: no
        such correction.
    edge_probe : callable or None
        ``edge_probe(index) -> u``: the direction cosine off the ping's plane
        that the echoes of detections ``index`` came from, read from their two
        edges (:class:`clbeam.survey.edges.EdgeProbe`; NaN: none seen); with
        it a line the other tests leave undecided is taken as a smooth pipe's
        specular echo when its echoes come from its nearest point
        (:func:`_edges_from_nearest_point`).
    """

    ping: np.ndarray
    y: np.ndarray
    z: np.ndarray
    cf: np.ndarray
    intensity_db: np.ndarray | None = None
    slide_rad: np.ndarray | None = None
    smear_m: np.ndarray | None = None
    edge_probe: Callable | None = None


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
    ping_paths : list of (numpy.ndarray, numpy.ndarray)
        Per line, the survey pings of its extent and its cross-track offset
        at each (m, smoothed, earth frame of each ping).
    labels : numpy.ndarray
        ``(n,)`` line of each detection (-1: none).
    n_candidates : int
        Tracks found before the score threshold, with those carried from an
        earlier search.
    min_score : float
        That threshold.
    too_few_pings : str or None
        Why no line could be found (the survey imaged fewer pings than a
        line needs to be seeded), in words; ``None`` otherwise.
    score_path : callable or None
        ``score_path(pings, y, burial=None) -> float``: the score a line
        would have that followed a given path (:func:`path_score`), in the
        frame the lines were found in; ``None`` where none was searched.
    tracks : list of Track
        The kept lines' tracks before their end-to-end joins, members in the
        frame's detection order (the detections sorted by ping): a search of
        the same detections over another seabed takes them as candidates.
    """

    rows: list
    paths: list
    labels: np.ndarray
    n_candidates: int
    geo_paths: list | None = None
    min_score: float = math.nan
    ping_paths: list = field(default_factory=list)
    too_few_pings: str | None = None
    score_path: Callable | None = None
    tracks: list = field(default_factory=list)


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


def track_distance_m(nav: SurveyNavigation, pings: np.ndarray, nominal_spacing_m: float = 8.2) -> tuple:
    """Along-track distance of ``pings`` (m) and whether it is known.

    The distance travelled between the navigated positions, or the ship
    speed times the ping time; without either, ``nominal_spacing_m`` per
    ping (then lengths and headings are not reported).  Never decreasing,
    and a ship at rest still moves a millimetre a ping (the line fits need
    distinct distances).
    """
    if nav.all_nav:
        e, n = nav.e[pings], nav.n[pings]
        s, known = np.r_[0.0, np.cumsum(np.hypot(np.diff(e), np.diff(n)))], True
    else:
        s = nav.along_m(pings)
        known = bool(np.isfinite(s).all())
        if not known:
            s = np.arange(pings.size) * nominal_spacing_m
    s = np.maximum.accumulate(s) + 1e-3 * np.arange(pings.size)
    return s, known


def survey_lines(det: LineDetections, seabed: np.ndarray, centre_yz: np.ndarray, imaged: np.ndarray,
                 nav: SurveyNavigation, options: LineOptions, carried: list | None = None) -> SurveyLines:
    """Lines of a survey's detections: found, scored, given a kind, described.

    Parameters
    ----------
    det : LineDetections
        The detections (CF above the map threshold).
    seabed : numpy.ndarray
        ``(n_pings, 2)`` each ping's seabed ``(z0, slope)``
        (:func:`clbeam.survey.burial.pooled_seabed_lines`; NaN: none).
    centre_yz : numpy.ndarray
        ``(n_pings, 2)`` grid centres (m).
    imaged : numpy.ndarray
        ``(n_pings,)`` bool.
    nav : SurveyNavigation
        After :meth:`~SurveyNavigation.finish`.
    options : LineOptions
    carried : list of Track, optional
        Tracks an earlier search of the same detections kept over another seabed (:attr:`SurveyLines.tracks`):
        judged after those found here, kept only where no line kept here lies along them.

    Returns
    -------
    SurveyLines
    """
    n = det.ping.size
    pings = np.flatnonzero(imaged)
    few = None
    if pings.size < options.seed_hits:
        few = (f"the survey imaged {pings.size} ping(s), fewer than the {options.seed_hits} with detections a "
               "line needs to be seeded: no line can be found (clbeam docs lines)")
        log.warning("%s", few)
    if n == 0 or pings.size < max(2, options.seed_hits):
        return SurveyLines([], [], np.full(n, -1, dtype=np.int64), 0, [] if nav.all_nav else None, options.min_score,
                           too_few_pings=few)
    sb = smooth_seabed(seabed, imaged)
    order = np.argsort(det.ping, kind="stable")
    s_ping, scaled = track_distance_m(nav, pings, options.nominal_spacing_m)
    if not scaled:
        log.warning("no along-track distance (navigation, or ping times and --speed): lines searched with pings "
                    "%.1f m apart; their lengths and headings are not reported", options.nominal_spacing_m)
    frame = _frame(det, order, sb, centre_yz, pings, s_ping)
    rank = line_ranker(frame, options)
    level = None if det.intensity_db is None else np.asarray(det.intensity_db, dtype=np.float64)[order]
    probe = None if det.edge_probe is None else (lambda members: det.edge_probe(order[members]))
    described, late = _candidates(frame, options, rank, carried or [], (sb, centre_yz, level, probe), (nav, scaled))
    kept = without_duplicates([d for d in described if d[1]["score"] >= options.min_score], frame, options,
                              (rank, level), (sb, centre_yz, scaled),
                              lambda line, crossing: _moved_to_crossing(frame, line, crossing, (sb, nav, scaled), options),
                              lambda line, path_y: _recentred(frame, line, path_y, (sb, centre_yz, nav, scaled)),
                              carried=late)
    unjoined = [line[0] for line in kept]
    kept = joined_end_to_end(kept, frame, options,
                             lambda first, second: _joined(frame, first, second, (sb, centre_yz, nav, scaled), options))
    rows, paths, geo, ping_paths, labels = _numbered(kept, order, n)
    return SurveyLines(rows, paths, labels, len(described), geo if nav.all_nav else None, options.min_score, ping_paths,
                       score_path=lambda p, y, burial=None: path_score(frame, p, y, options, rank.size, burial),
                       tracks=unjoined)


def _candidates(frame: TrackFrame, options: LineOptions, rank, carried: list, pings_info: tuple,
                where: tuple) -> tuple[list, int]:
    """The tracks the search finds in ``frame`` and the ``carried`` ones whose detections none of those holds
    exactly, each described (:func:`_describe`, ``pings_info`` as there, ``where``: the navigation and whether
    the along-track distance is known), and how many of those scoring at least ``min_score`` were carried
    (they come last)."""
    found = find_tracks(frame, options, rank=rank)
    held = {tr.members.tobytes() for tr in found}
    tracks = found + [tr for tr in carried if tr.members.tobytes() not in held]
    described = [(tr, *_describe(frame, tr, options, rank, pings_info, *where)) for tr in tracks]
    return described, sum(d[1]["score"] >= options.min_score for d in described[len(found):])


def _numbered(kept: list, order: np.ndarray, n: int) -> tuple:
    """The kept lines numbered in order: their rows, paths, geographic paths, ping paths, and each of the ``n``
    detections' line (-1: none); ``order``: the frame's detection order."""
    rows, paths, geo, ping_paths, labels = [], [], [], [], np.full(n, -1, dtype=np.int64)
    for tr, row, ping_path, path, lonlat in kept:
        row["line"] = len(rows)
        labels[order[tr.members]] = row["line"]
        rows.append(row)
        paths.append(path)
        geo.append(lonlat)
        ping_paths.append(ping_path)
    return rows, paths, geo, ping_paths, labels


def path_score(frame: TrackFrame, pings: np.ndarray, path_y: np.ndarray, options: LineOptions, size: SearchSize,
               burial: float | None = None) -> float:
    """The score (:func:`_score`) of a line that follows ``path_y`` (m across) at survey ``pings`` (NaN: off the
    path, any order), taking in each imaged ping the strongest detection within the across gate and the burial
    gate, the line spanning them (the best of their runs that bridge ``max_gap_pings`` at most): what the best
    tracking of that path could report, for the evaluation's question whether a target's own path stands above
    the clutter as the search must have it (``-inf``: fewer than three detections on it).

    ``burial`` (m below the seabed): a burial gate's centre to try beside the detections' own along the path at
    each CF level (:func:`~clbeam.survey.lines.line_burial`), the best kept.  Across, the path is interpolated to
    the imaged pings between its first and last, the gate the lines' (:func:`~clbeam.survey.lines.across_gate`)."""
    pings, path_y = np.asarray(pings), np.asarray(path_y, dtype=np.float64)
    ok = np.isfinite(path_y) & np.isin(pings, frame.pings)
    if np.count_nonzero(ok) < 3:
        return -math.inf
    order = np.argsort(pings[ok], kind="stable")
    pings, path_y = pings[ok][order], path_y[ok][order]
    first, last = (int(k) for k in np.searchsorted(frame.pings, pings[[0, -1]]))
    ext = frame.pings[first:last + 1]
    y_ext = np.interp(ext, pings, path_y)
    idx = np.arange(int(frame.starts[first]), int(frame.starts[last + 1]))  # burials unknown (NaN) pass the gate
    at = np.searchsorted(ext, frame.ping[idx])
    slope = np.gradient(y_ext, frame.ping_s[first:last + 1]) if ext.size > 1 else np.zeros(1)
    near = idx[np.abs(frame.y[idx] - y_ext[at]) <= across_gate(frame, idx, slope[at], options)]
    if near.size < 3:
        return -math.inf
    # burials to try: the one given and the detections' own at each CF level (in dense clutter the strong echoes'
    # burial is the line's, where every detection's median is the clutter's; far out the detections' burials
    # stray from the target's)
    burials = [] if burial is None else [burial]
    for strong in (near[frame.cf[near] >= level] for level in CF_LEVELS):
        if strong.size >= 3:
            burials.append(line_burial(frame.b[strong], frame.b_sigma[strong])[0])
    return max((_path_score_at(frame, near, (first, last), y_ext, float(b), options, size) for b in burials),
               default=-math.inf)


def _path_score_at(frame: TrackFrame, near: np.ndarray, extent: tuple, y_ext: np.ndarray, burial: float,
                   options: LineOptions, size: SearchSize) -> float:
    """:func:`path_score` at one burial (m): the strongest detection of each ping among ``near`` within the
    burial gate makes the track of pings ``extent`` (first, last: indices into ``frame.pings``)."""
    near = near[burial_ok(frame.b[near], frame.b_sigma[near], burial, options)]
    near = near[np.lexsort((-frame.cf[near], frame.ping[near]))]  # by ping, the strongest first
    members = near[np.r_[True, np.diff(frame.ping[near]) > 0]] if near.size else near
    # a line spans its members and bridges at most max_gap_pings imaged pings without one, as a found one does:
    # the path's pings beyond the swath or its echoes are no misses, a stray far along it starts another run
    k = np.searchsorted(frame.pings, frame.ping[members])
    runs = np.split(np.arange(members.size), np.flatnonzero(np.diff(k) > options.max_gap_pings + 1) + 1)
    best = -math.inf
    for run in (r for r in runs if r.size >= 3):
        lo, hi = int(k[run[0]]), int(k[run[-1]])
        best = max(best, _score(frame, Track(members[run], lo, hi), y_ext[lo - extent[0]:hi - extent[0] + 1], burial,
                                options, size))
    return best


#: a smooth pipe whose nearest point lies up to this many beam widths off the ping's plane (the pattern's second
#: null) is still seen, through the main lobe's edge or the first sidelobe, its echo ``dz`` deeper than the pipe:
#: a line at such a heading that its burials do not show to be rough has ``dz / 2`` added to its burial's error
#: (:func:`diffuse_shift`)
SMOOTH_SEEN_BEAMS = 2.0
#: passes of a specular line's burial fit and its echoes moved by range to the pipe's depth
#: (:func:`_specular_burial`): the first fit reads the extra depths from echoes moved only part of the way
SPECULAR_PASSES = 2



def _frame(det: LineDetections, order: np.ndarray, sb: np.ndarray, centre_yz: np.ndarray, pings: np.ndarray,
           s_ping: np.ndarray) -> TrackFrame:
    """The detections in the track frame, each moved along its arc against its ping's seabed."""
    p = det.ping[order]
    y, z = det.y[order], det.z[order]
    ya, b, sd, bpost, sy = (np.full(p.size, np.nan) for _ in range(5))
    known = np.isfinite(sb[p]).all(axis=1)
    k = known
    slide = np.full(p.size, ARC_SIGMA_RAD) if det.slide_rad is None else np.asarray(det.slide_rad)[order]
    ya[k], b[k], sd[k], bpost[k], sy[k] = arc_constrained(y[k], z[k], centre_yz[p[k]], sb[p[k]],
                                                          arc_sigma_rad=slide[k])
    ya[~known] = y[~known]
    sy[~known] = 0.0
    r = np.hypot(y - centre_yz[p, 0], z - centre_yz[p, 1])
    s = s_ping[np.searchsorted(pings, p)]
    smear = None if det.smear_m is None else np.asarray(det.smear_m, dtype=np.float64)[order]
    echo = None if det.intensity_db is None else echo_strength(np.asarray(det.intensity_db, dtype=np.float64)[order], r)
    return TrackFrame(ping=p, s=s, y=ya, b=b, cf=det.cf[order], b_sigma=sd, b_post=bpost,
                      pings=pings, ping_s=s_ping, y_sigma=sy, r=r, smear=smear, echo=echo)


def echo_strength(intensity_db: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Each detection's echo strength relative to the median of them (linear, dimensionless): its intensity
    (dB) with the two-way spherical spreading over its slant range ``r`` (m) taken out; 1 where either is
    unknown."""
    good = np.isfinite(intensity_db) & np.isfinite(r) & (r > 0)
    out = np.ones(intensity_db.size)
    if not good.any():
        return out
    level = intensity_db[good] + 40.0 * np.log10(r[good])
    out[good] = 10.0 ** ((level - np.median(level)) / 10.0)
    return out


def _search_size(frame: TrackFrame) -> SearchSize:
    """The extent searched: the median ping spacing and the 1-99 % spans of the offsets and burials (a stray
    detection far out moves no score)."""
    spacing = float(np.median(np.diff(frame.ping_s))) if frame.ping_s.size > 1 else 1.0
    b = frame.b[np.isfinite(frame.b)]
    y_lo, y_hi = (float(v) for v in np.percentile(frame.y, [1, 99])) if frame.y.size else (0.0, 0.0)

    def span(v):
        return float(np.subtract(*np.percentile(v, [99, 1]))) if v.size else 0.0
    return SearchSize(spacing_m=max(spacing, 1e-3), swath_m=y_hi - y_lo, burial_span_m=span(b), y_range_m=(y_lo, y_hi))


def _describe(frame: TrackFrame, tr: Track, options: LineOptions, rank, pings_info: tuple, nav: SurveyNavigation,
              scaled: bool) -> tuple:
    """One line's row, ``(pings, y)``, path in the association frame, and ``[longitude, latitude]`` path (``None``
    without navigation); ``rank``: :func:`line_ranker`'s scorer; ``pings_info``: the pings' seabeds and grid
    centres, the detections' levels (or ``None``) and the edge probe (or ``None``, :class:`LineDetections`)."""
    sb, centre_yz, level, probe = pings_info
    m = tr.members
    path_y = line_path(frame, tr, options, reported=True, ranked=rank.path(tr))
    ext = frame.pings[tr.first:tr.last + 1]
    burial, burial_se, spread = line_burial(frame.b[m], frame.b_sigma[m])
    score = rank(tr)
    # the probe images the channels again: only for lines that are kept
    spec = _specular(frame, tr, path_y, sb, centre_yz, (level, probe if score >= options.min_score else None),
                     options)
    measured = (burial, burial_se)  # what the kind is judged by unless the line is specular
    if spec is not None and spec["path_y"] is None:
        # diffuse_shift: undecided, a buried line's burial halfway (a smooth pipe's echo never lies above the
        # seabed: a line at or above it is left as it is); a diffuse line at a heading raised by its smear
        if spec["always"] or options.min_burial_m <= burial <= options.max_burial_m:
            burial, burial_se = burial + spec["burial_shift_m"], math.hypot(burial_se, spec["burial_extra_error_m"])
        if spec["always"]:
            measured = (burial, burial_se)
        spec = None
    if spec is not None:  # a smooth pipe's migrated echo: back to where the pipe crosses each ping's plane
        path_y = spec["path_y"]
        if math.isfinite(spec["burial_m"]):
            burial, burial_se = spec["burial_m"], spec["burial_error_m"]
    # the seabed's own error at the line and the reading's model error add to the burial's (measured, kind and
    # resolution alike)
    floor = math.hypot(SEABED_SE_M, BURIAL_MODEL_SE_M)
    measured = (measured[0], math.hypot(measured[1], floor))
    burial_se = math.hypot(burial_se, floor)
    resolved = math.isfinite(burial_se) and burial_se <= options.burial_resolution_m
    z_line, nadir_angle = _line_depth(sb, centre_yz, ext, path_y, burial)
    seabed_known = math.isfinite(nadir_angle)
    row = {"kind": line_kind(*(measured if spec is None else (burial, burial_se)), nadir_angle, options),
           "n_pings": int(m.size), "first_ping": int(ext[0]), "last_ping": int(ext[-1]),
           "mean_cf": float(np.mean(frame.cf[m])), "score": float(score),
           "burial_m": burial, "burial_std_m": spread, "burial_se_m": burial_se, "burial_resolved": int(resolved),
           "mean_y_m": float(np.mean(path_y)), "mean_z_m": float(np.nanmean(z_line)) if seabed_known else math.nan,
           "detected_fraction": float(m.size / ext.size), "specular": int(spec is not None)}
    return (row, (ext, path_y), *_world_path(row, ext, path_y, frame.ping_s[tr.first:tr.last + 1], nav, scaled))


def _line_depth(sb: np.ndarray, centre_yz: np.ndarray, ext: np.ndarray, path_y: np.ndarray, burial: float) -> tuple:
    """A line's depth at each ping of its extent ``ext`` (m, below the transducers; NaN where the ping has no
    seabed) along ``path_y`` at ``burial`` (m; an unknown one taken as 0), and its median angle from nadir
    (degree; NaN where no ping has a seabed)."""
    z_line = sb[ext, 0] + sb[ext, 1] * path_y + (burial if math.isfinite(burial) else 0.0)
    angle = np.degrees(np.arctan2(path_y - centre_yz[ext, 0], z_line - centre_yz[ext, 1]))
    return z_line, float(np.nanmedian(np.abs(angle))) if np.isfinite(angle).any() else math.nan


def _moved_to_crossing(frame: TrackFrame, line: tuple, crossing: tuple, where: tuple,
                       options: LineOptions) -> tuple | None:
    """A line that is a pipe's specular image moved to the pipe's ``crossing`` line (both as :func:`_describe`
    gives them, with their tracks): its path shifted across by the median offset of the crossing's path from
    its own over the pings both span (where they share fewer than three, the crossing's path extended out to
    ``max_gap_pings + 1`` pings beyond its ends, :func:`~clbeam.survey.line_duplicates.extended_path`), the
    crossing's burial (the echoes of the pipe itself, not of its nearest
    point off the plane, deeper by an amount that depends on the transmit pattern over it) and kind, taken as
    specular; ``None`` where they share fewer than three pings.  ``where``: the pings' seabeds, the
    navigation, and whether the along-track distance is known."""
    sb, nav, scaled = where
    tr, row, (ext, path_y), *_ = line
    tr_c, row_c, (ext_c, path_c), *_ = crossing
    _, a, b = np.intersect1d(ext, ext_c, return_indices=True)
    if a.size < 3:  # the image takes up where the crossing's line stops
        ext_c, _, path_c = extended_path(frame, tr_c, path_c, options.max_gap_pings + 1)
        _, a, b = np.intersect1d(ext, ext_c, return_indices=True)
    if a.size < 3:
        return None
    path_y = path_y + float(np.median(path_c[b] - path_y[a]))
    row = {**row, **{k: row_c[k] for k in ("kind", "burial_m", "burial_std_m", "burial_se_m", "burial_resolved")},
           "specular": 1, "mean_y_m": float(np.mean(path_y))}
    if math.isfinite(row["burial_m"]):
        row["mean_z_m"] = float(np.nanmean(sb[ext, 0] + sb[ext, 1] * path_y + row["burial_m"]))
    return _with_path(frame, tr, row, path_y, nav, scaled)


def _recentred(frame: TrackFrame, line: tuple, path_y: np.ndarray, where: tuple) -> tuple:
    """A line (as :func:`_describe` gives it, with its track) reported along ``path_y`` (m across, at each ping of
    its extent; :func:`~clbeam.survey.line_duplicates.smear_centre`): its mean offset and depth, and its world
    path, length and heading, again; its score, burial and kind are its track's (the path moves by metres at
    most, its angle from nadir by a fraction of a degree).  ``where``: the pings' seabeds and grid centres, the
    navigation, and whether the along-track distance is known."""
    sb, centre_yz, nav, scaled = where
    tr, row, (ext, _), *_ = line
    z_line, _ = _line_depth(sb, centre_yz, ext, path_y, row["burial_m"])
    row = {**row, "mean_y_m": float(np.mean(path_y)),
           "mean_z_m": float(np.nanmean(z_line)) if np.isfinite(z_line).any() else math.nan}
    return _with_path(frame, tr, row, path_y, nav, scaled)


def _with_path(frame: TrackFrame, tr: Track, row: dict, path_y: np.ndarray, nav: SurveyNavigation,
               scaled: bool) -> tuple:
    """A line as :func:`_describe` gives it, with its track: ``(track, row, (pings, path_y), path, lonlat)``, its
    world path, length, heading and ends filled in ``row`` (:func:`_world_path`); ``path_y`` (m across) at each
    ping of the track's extent."""
    ext = frame.pings[tr.first:tr.last + 1]
    return (tr, row, (ext, path_y), *_world_path(row, ext, path_y, frame.ping_s[tr.first:tr.last + 1], nav, scaled))


def _joined(frame: TrackFrame, first: tuple, second: tuple, where: tuple, options: LineOptions) -> tuple:
    """Two lines end to end (:func:`clbeam.survey.line_joins.end_to_end`) as one: the first's detections up to
    the second's first one, then the second's; each one's path over its own pings (the second's where they
    overlap), interpolated across a gap; their burials' weighted mean, their own errors combined and the
    common seabed and model errors added once; the higher score.  ``where``: the pings' seabeds and grid
    centres, the navigation, and whether the along-track distance is known."""
    sb, centre_yz, nav, scaled = where
    (tr1, row1, (ext1, y1), *_), (tr2, row2, (ext2, y2), *_) = first, second
    members = np.concatenate([tr1.members[frame.ping[tr1.members] < frame.ping[tr2.members[0]]], tr2.members])
    tr = Track(members, tr1.first, tr2.last)
    ext = frame.pings[tr.first:tr.last + 1]
    before = ext1 < ext2[0]
    path_y = np.interp(ext, np.r_[ext1[before], ext2], np.r_[y1[before], y2])
    floor = math.hypot(SEABED_SE_M, BURIAL_MODEL_SE_M)
    own = np.sqrt(np.maximum(np.array([row1["burial_se_m"], row2["burial_se_m"]]) ** 2 - floor ** 2, 1e-6))
    w = own ** -2.0
    burial = float(np.dot(w, [row1["burial_m"], row2["burial_m"]]) / w.sum())
    se = math.hypot(w.sum() ** -0.5, floor)
    z_line, nadir_angle = _line_depth(sb, centre_yz, ext, path_y, burial)
    row = {**row1, "kind": line_kind(burial, se, nadir_angle, options), "n_pings": int(members.size),
           "first_ping": int(ext[0]), "last_ping": int(ext[-1]), "mean_cf": float(np.mean(frame.cf[members])),
           "score": max(row1["score"], row2["score"]), "burial_m": burial,
           "burial_std_m": max(row1["burial_std_m"], row2["burial_std_m"]), "burial_se_m": se,
           "burial_resolved": int(se <= options.burial_resolution_m), "mean_y_m": float(np.mean(path_y)),
           "mean_z_m": float(np.nanmean(z_line)) if math.isfinite(nadir_angle) else math.nan,
           "detected_fraction": float(members.size / ext.size),
           "specular": int(row1["specular"] or row2["specular"])}
    return _with_path(frame, tr, row, path_y, nav, scaled)


def line_ranker(frame: TrackFrame, options: LineOptions):
    """``rank(track) -> score``: a track's score (:func:`_score` on its path, :func:`~clbeam.survey.lines.
    line_path`, and burial, against the search's extent in ``frame``, ``rank.size``), remembered by its detections
    with the path (``rank.path(track)``); what :func:`~clbeam.survey.lines.find_tracks` chooses tracks by."""
    size = _search_size(frame)
    memo = {}

    def scored(tr: Track) -> tuple:
        key = tr.members.tobytes()
        if key not in memo:
            path_y = line_path(frame, tr, options)
            burial = line_burial(frame.b[tr.members], frame.b_sigma[tr.members])[0]
            memo[key] = (_score(frame, tr, path_y, burial, options, size), path_y)
        return memo[key]

    def rank(tr: Track) -> float:
        return scored(tr)[0]
    rank.path = lambda tr: scored(tr)[1].copy()
    rank.size = size
    return rank


def _score(frame: TrackFrame, tr: Track, path_y: np.ndarray, burial: float, options: LineOptions,
           size: SearchSize) -> float:
    """The line's score (:func:`clbeam.survey.line_score.line_score`) in the frame its detections were found in:
    the hits are the members within the (narrowed) gates, the clutter the other detections of its pings, counted
    on copies of its path (:func:`clbeam.survey.line_score.clutter_hit_rate`), both at each CF level."""
    m = tr.members
    ext = frame.pings[tr.first:tr.last + 1]
    gate_y, gate_b = effective_gates(frame, tr, path_y, options)
    at = np.searchsorted(ext, frame.ping[m])
    # hits and clutter pass the same tests: within the gate across, and the track's own burial gate
    on = (np.abs(frame.y[m] - path_y[at]) <= gate_y) & burial_ok(frame.b[m], frame.b_sigma[m], burial, options)
    hits = [int(np.count_nonzero(on & (frame.cf[m] >= level))) for level in CF_LEVELS]  # one member a ping
    lo, hi = int(frame.starts[tr.first]), int(frame.starts[tr.last + 1])
    mine = np.zeros(hi - lo, dtype=bool)
    mine[m - lo] = True
    others = lo + np.flatnonzero(~mine)
    others = others[burial_ok(frame.b[others], frame.b_sigma[others], burial, options)]
    at_others = np.searchsorted(ext, frame.ping[others])
    p_hit = clutter_hit_rate(frame.y[others] - path_y[at_others], at_others, path_y, copy_offsets(gate_y), gate_y,
                             size.y_range_m, cf=frame.cf[others], cf_levels=CF_LEVELS)
    return line_score(hits, ext.size, p_hit, gate_y, gate_b, size, options.max_angle_deg)


def _specular(frame: TrackFrame, tr: Track, path_y: np.ndarray, sb: np.ndarray, centre_yz: np.ndarray,
              echoes: tuple, options: LineOptions) -> dict | None:
    """The line as a smooth pipe's specular echo, moved to where the pipe crosses each ping's plane
    (:func:`clbeam.survey.specular.specular_crossing`), when its burials say so (:func:`clbeam.survey.burial.
    specular_fit`: ``k`` within two standard errors of 1 and more than two from 0), or the burials do not say
    otherwise (``k`` more than three standard errors below 1) and its echoes fade as a specular echo's over the
    pings with a seabed (:func:`_fades`) or come from the pipe's nearest point, off the plane
    (:func:`_edges_from_nearest_point`); else ``None``.  Its burial, and its echoes moved to the pipe's depth
    that the crossings are found from, are then :func:`_specular_burial`'s.  ``echoes``: the detections'
    levels (dB, or ``None``) and the edge probe (or ``None``)."""
    level, probe = echoes
    m = tr.members
    ext = frame.pings[tr.first:tr.last + 1]
    s_ext = frame.ping_s[tr.first:tr.last + 1]
    if ext.size < 3 or np.ptp(s_ext) <= 0:
        return None
    slope = np.gradient(path_y, s_ext)
    k = np.searchsorted(ext, frame.ping[m])
    g = frame.ping[m]
    fit = specular_fit(frame.y[m], frame.b[m], frame.b_sigma[m], slope[k], centre_yz[g], sb[g])
    finite = math.isfinite(fit["k"])
    by_burial = finite and abs(fit["k"] - 1) <= 2 * fit["k_error"] and fit["k"] > 2 * fit["k_error"]
    # k's error is wide where dz spans a few tenths along the line: at two, smooth pipes seen through the beam's
    # edge (k 0.06-0.21 +- 0.3-0.4) were called rough
    not_specular = finite and fit["k"] + 3 * fit["k_error"] < 1
    # the fading alone decides only over pings with a seabed: elsewhere the echoes were not moved along their arcs
    moved = np.isfinite(frame.b[m])
    fades = _fades(frame, m[moved], slope[k[moved]], centre_yz[g[moved], 0], level, options)
    if moved.sum() < 3 or not (by_burial or (not not_specular and (
            fades or _edges_from_nearest_point(frame, m[moved], slope[k[moved]], centre_yz[g[moved], 0], probe)))):
        return diffuse_shift(fit, frame.smear[m], not_specular, options)
    fit, y_echo = _specular_burial(frame, m, slope[k], centre_yz[g], sb[g], options)
    y_c = specular_crossing(y_echo[moved], frame.s[m][moved], centre_yz[g[moved], 0], s_ext, options.fit_length_m)
    return {"path_y": y_c, "burial_m": fit["burial_m"], "burial_error_m": fit["burial_error_m"]}


def _edges_from_nearest_point(frame: TrackFrame, members: np.ndarray, slope: np.ndarray, centre_y: np.ndarray,
                              probe) -> bool:
    """Whether the line's echoes came from its nearest point off the plane, as a smooth pipe's do
    (:func:`clbeam.survey.edges.edges_from_nearest_point` on the direction cosines ``probe`` reads from their
    edges against the nearest point's, ``(h / R) sin a*`` at each detection's offset ``h`` from its grid centre
    and slant range ``R``, ``sin a*`` the slope of the echoes' path, as :func:`_fades` has it); ``False``
    without a probe."""
    if probe is None or frame.r is None or members.size == 0:
        return False
    u_nearest = np.abs(_offplane_cosine(frame, members, slope, centre_y))
    return edges_from_nearest_point(lambda pick: probe(members[pick]), u_nearest)


def _offplane_cosine(frame: TrackFrame, members: np.ndarray, sin_a: np.ndarray, centre_y: np.ndarray) -> np.ndarray:
    """The direction cosine off the ping's plane at which the source sees a smooth pipe's nearest point,
    ``(h / R) sin a*``: each detection's offset ``h`` from its grid centre ``centre_y`` (m), its slant range
    ``R`` and ``sin a*``, the slope of the echoes' path (signed)."""
    r = frame.r[members]
    h_over_r = np.abs(frame.y[members] - centre_y) / np.where(r > 0, r, np.nan)
    return np.clip(sin_a, -1, 1) * np.clip(h_over_r, 0, 1)


def _specular_burial(frame: TrackFrame, m: np.ndarray, slope: np.ndarray, centre_yz: np.ndarray, sb: np.ndarray,
                     options: LineOptions) -> tuple[dict, np.ndarray]:
    """A specular line's burial and its echoes at the pipe's depth, found together: whatever the free fit's
    ``k``, the burial with ``k`` drawn towards the geometry's 1 (:data:`~clbeam.survey.burial.SPECULAR_K_SIGMA`)
    from the echoes whose nearest point lies inside the transmit beam (half its width: as the undecided
    gate's), then the echoes moved by range to that depth (:func:`clbeam.survey.specular.offsets_at_depth`,
    where the range reaches it), which sets the extra depths of the next fit (:data:`SPECULAR_PASSES` passes).
    Returns the last fit (:func:`clbeam.survey.burial.specular_fit`) and the members' offsets (m)."""
    y_echo = frame.y[m].copy()
    for _ in range(SPECULAR_PASSES):
        fit = specular_fit(y_echo, frame.b[m], frame.b_sigma[m], slope, centre_yz, sb, k_prior_sigma=SPECULAR_K_SIGMA,
                           max_offplane_rad=0.5 * math.radians(options.beam_width_deg))
        if frame.r is None or not math.isfinite(fit["burial_m"]):
            break
        at_depth = offsets_at_depth(frame.r[m], frame.y[m], centre_yz, sb, fit["burial_m"])
        y_echo = np.where(np.isfinite(at_depth) & np.isfinite(frame.b[m]), at_depth, frame.y[m])
    return fit, y_echo


def diffuse_shift(fit: dict, smear_m: np.ndarray, not_specular: bool, options: LineOptions) -> dict | None:
    """How a line that is not taken as a smooth pipe's specular echo has its burial read: a dict with
    ``path_y`` None, ``burial_shift_m`` (added to its measured burial, m), ``burial_extra_error_m`` (added to its
    standard error in quadrature, m) and ``always`` (the shift holds at any burial and for the kind), or
    ``None``: as measured.

    * **Nearest point inside the beam, undecided** (``not_specular`` false: a steady heading shows no spread
      of the extra depth and no fading), were it smooth (within half of ``beam_width_deg``, ``lambda / L``
      at the band's centre: about the main lobe's -4 dB point): a smooth pipe's echo would lie ``dz`` deeper
      than the pipe, a rough one's at it.  Halfway, ``dz / 2`` shallower than measured, with ``dz /
      sqrt(12)`` (a uniform spread over the two) in its error; for buried lines only.
    * **Nearest point outside the beam**: the echo comes from the whole stretch of the pipe inside the
      transmit beam (a rough or discrete-scatterer pipe at a heading; a smooth one's would be weaker).  Its
      range has no stationary point there, so the echo's energy spreads along the stretch, and a scatterer
      ``x`` off the ping's plane images ``sqrt(z^2 + x^2) - z`` deeper (as the seabed's peaks do, raised by
      :func:`clbeam.survey.burial.offplane_deepening_m`): the line is raised by the mean of its detections'
      ``smear_m`` (m, :func:`clbeam.survey.burial.smear_deepening_m`, over the stretch its gates hold).
      Undecided and out to :data:`SMOOTH_SEEN_BEAMS` beam widths, a smooth pipe would still be seen, its echo
      ``dz`` deeper than the pipe: ``dz / 2`` is added to the error in quadrature (the tuning surveys' smooth
      pipes at 6-10 degrees read 0.7-3.1 m deep, their reported errors 0.17-0.19 m).

    ``fit``: :func:`clbeam.survey.burial.specular_fit`'s (``extra_depth_m``, ``offplane_rad``).
    """
    dz, off = fit.get("extra_depth_m", math.nan), fit.get("offplane_rad", math.nan)
    half = 0.5 * math.radians(options.beam_width_deg)
    if not not_specular and dz > 0 and off < half:
        return {"path_y": None, "burial_shift_m": -0.5 * dz, "burial_extra_error_m": dz / math.sqrt(12.0),
                "always": False}
    smear = np.asarray(smear_m, dtype=np.float64)
    smear = smear[np.isfinite(smear)]
    shift = max(float(smear.mean()), 0.0) if off >= half and smear.size else 0.0
    # were it smooth, its nearest point within SMOOTH_SEEN_BEAMS beam widths: still seen, weaker, dz deeper
    ambiguous = not not_specular and dz > 0 and half <= off < 2 * SMOOTH_SEEN_BEAMS * half
    if shift > 0 or ambiguous:
        return {"path_y": None, "burial_shift_m": -shift, "burial_extra_error_m": 0.5 * dz if ambiguous else 0.0,
                "always": shift > 0}
    return None


def _fades(frame: TrackFrame, members: np.ndarray, sin_a: np.ndarray, centre_y: np.ndarray,
           level: np.ndarray | None, options: LineOptions) -> bool:
    """Whether the line's echoes fade out of the transmit beam as it turns (:func:`clbeam.survey.specular.
    fading_fit` on the angle off the plane ``(h / R) sin a*``): ``beta`` more than three standard errors above
    0 and at least :func:`~clbeam.survey.specular.fading_floor_db`, a predicted fall of at least 3 dB."""
    if level is None or members.size < 4:
        return False
    fading = fading_fit(level[members], frame.r[members], _offplane_cosine(frame, members, sin_a, centre_y))
    beta, error = fading["beta_db"], fading["beta_error_db"]
    return bool(np.isfinite(beta) and np.isfinite(error) and beta > 3 * error
                and beta >= fading_floor_db(options.beam_width_deg) and fading["span_db"] >= 3.0)



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


def line_kind(burial_m: float, burial_se_m: float, nadir_angle_deg: float, options: LineOptions) -> str:
    """The kind of a line from its burial and that burial's standard error (m), and its typical angle from nadir
    (degree).

    A pipeline lies from ``max_exposure_m`` above the seabed (an exposed
    pipe's axis a radius above it, a free span's up to a metre more) to
    ``max_burial_m`` below it.  A line is a ``pipeline`` when its burial is
    within that range, reached by its standard error above it (a line
    higher than that by more than its error is in the water) and, below
    it, by three standard errors when the burial is not resolved (above
    ``burial_resolution_m``: near endfire a peak slides metres along its
    arc) and ``3 se * se / burial_resolution_m`` when it is (0.9 m at
    0.39 m, 0.5 m at 0.29 m, the least a line reports; no jump at the
    resolution).  Otherwise
    ``water`` (above) or ``subbottom`` (deeper).  Within
    ``nadir_angle_deg`` of nadir a line is never a pipeline: a buried
    line there cannot be told from a horizon's specular echo and its
    pulse's tail (``subbottom-nadir``, buried more than ``min_burial_m``;
    ``seabed-nadir`` otherwise).  A burial without a standard error (NaN)
    is judged by its estimate; ``unknown`` without a seabed.
    """
    if not math.isfinite(burial_m):
        return "unknown"
    if nadir_angle_deg <= options.nadir_angle_deg:
        return "subbottom-nadir" if burial_m > options.min_burial_m else "seabed-nadir"
    se = 0.0 if math.isnan(burial_se_m) else burial_se_m  # no error: judged by the estimate
    deeper = 3 * se * min(1.0, se / options.burial_resolution_m)
    if -options.max_exposure_m - se <= burial_m <= options.max_burial_m + deeper:
        return "pipeline"
    return "subbottom" if burial_m > options.max_burial_m else "water"
