"""Lines that are another line's echo: a better line's shadow, or a pipe's specular image.

A pipe can leave more than one track: a stretch of it seen through a
transmit sidelobe beside and below its crossing (a *shadow*), and, where it
crosses the pings' planes at a heading, its specular echo from its point
nearest the source, nearer the ship and deeper (its *image*).
:func:`without_duplicates` keeps one line per pipe; the gates it compares
lines with are :func:`effective_gates`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from clbeam.survey.line_options import LineOptions
from clbeam.survey.lines import Track, TrackFrame, across_gate, line_burial, smear_half_width
from clbeam.survey.specular import specular_image

#: a weaker line alongside a better one within the reach of the better one's transmit smear out to this many
#: beam widths (``lambda / L``) off the ping's plane (the pattern's second null) is its shadow: a stretch of the
#: same pipe seen through the transmit pattern's first sidelobe, imaged beside it and deeper
SHADOW_BEAMS = 2.0
#: and it is that shadow only when its echoes are at least this much weaker (dB; the first sidelobe of a uniform
#: column lies 13.3 dB down, the main lobe's edge less: at 10 two tracks 6.4-6.6 dB down, 1.3-3.4 m deeper and
#: 8-11 m beside crossing pipes of the discrete tuning draws family:1 and family:6 were false pipeline lines)
SHADOW_DB = 6.0
#: a line whose detections lie within this much of another line's specular image in burial (m), and within two
#: gates across, is that image (:func:`_on_image`; the tuning draw family:24's B: 0.2 m on average)
IMAGE_DEPTH_M = 1.0
#: ... where the image's nearest point lies within this many beam widths (``lambda / L``) of the ping's plane: a
#: smooth pipe's specular echo, far stronger than a diffuse one, is seen through the transmit pattern's second
#: sidelobe (17.8 dB down, 2.46 widths off), out to its third null (family:24's B: 2.1-2.3 widths)
IMAGE_SEEN_BEAMS = 3.0
#: a line's path beyond its ends, and its two pieces' paths at a junction (:mod:`clbeam.survey.line_joins`), are
#: straight lines through this many of its pings nearest the end
END_PINGS = 6
#: a line's smear that holds at least this many paths (its own and those of the lines that shadow it at its
#: depth, within two gates) is reported along their median, the smear's centre: a wide smear (a pipe at a heading
#: far out) holds several tracks side by side, and the best-scoring one can run along a side of it (the discrete
#: tuning draws family:36's A, 20 tracks over a 9 m smear: the best one 2.6 m RMS off the pipe, their median 0.9
#: m; family:13's B, 7 tracks: 1.7 and 0.7 m); fewer, and one or two on a side move the median off it
#: (family:41's B, 3 tracks: 0.5 and 2.4 m)
SMEAR_TRACKS = 5


def without_duplicates(described: list, frame: TrackFrame, options: LineOptions, ranked: tuple,
                       geometry: tuple, to_crossing: Callable[[tuple, tuple], tuple | None],
                       recentred: Callable[[tuple, np.ndarray], tuple], carried: int = 0) -> list:
    """The lines less those that shadow a better one (:func:`_shadows`), in line order.  A line that lies on
    another line's specular image is that pipe's specular echo, the other one its crossing
    (:func:`_imaged_crossing`): it is first moved there, ``to_crossing(line, crossing) -> line`` (or ``None``:
    left as it is), and then shadows the crossing if the crossing is the better line, or the crossing shadows
    it; what reaches beyond the crossing's pings stays, to be joined to it (:mod:`clbeam.survey.line_joins`).
    ``ranked``: the ``line_ranker`` the lines were found with and the detections' intensities (dB, or
    ``None``); ``geometry``: the pings' seabeds and grid centres and whether the along-track distance is known
    (without it no heading, no image).  Better: the higher score, and of equal scores (long lines with a
    detection in every ping reach the same) the higher mean level: the echo, not its range sidelobes (the
    seabed's nadir echo has peaks 0.26 and 1.26 m above it, 18 and 31 dB down, with CF near 1).  Each line is
    compared as reported and as its echoes lie (:func:`_faces`): a specular line's detections are not where its
    moved path is.  A kept line whose smear holds :data:`SMEAR_TRACKS` paths or more (:func:`smear_centre`) is
    reported along their centre, ``recentred(line, path_y) -> line``, and the weaker lines are compared with
    that path and its image.  The last ``carried`` lines, those an earlier search of the same detections kept
    (over another seabed), are judged after all the others: one stays only where it shadows none kept and
    none kept shadows it, a line that search found and this one lost; nor does it count in a smear's
    centre.  (A line judged before may still be moved onto a carried line's crossing, as onto any weaker
    line's, which then shadows it.  A carried line kept can share detections with a kept line that lies along
    under half of it; each detection is labelled with one of them.)"""
    rank, level = ranked
    loud = [_mean_level(level, d[0].members) for d in described]
    late = len(described) - carried
    order = sorted(range(len(described)), key=lambda i: (i >= late, -described[i][1]["score"], -loud[i]))
    faces = [_faces(frame, d, rank, options) for d in described]
    images = [_image_face(frame, d, faces[i][0], geometry, options) for i, d in enumerate(described)]
    described = list(described)
    kept = []
    for i in order:
        crossing = _imaged_crossing(frame, described, i, faces, images, kept)
        moved = None if crossing is None else to_crossing(described[i], described[crossing])
        if moved is not None:
            described[i] = moved
            faces[i], images[i] = _faces(frame, moved, rank, options), None
        if any(_shadows(faces[i], faces[j], loud[j] - loud[i]) for j in kept):
            continue
        if i >= late and any(_shadows(faces[j], faces[i], loud[i] - loud[j]) for j in kept):
            continue
        kept.append(i)
        centre = smear_centre(described[:late], faces, i, kept) if i < late else None
        if centre is not None:  # the weaker lines are compared with it as it is reported
            described[i] = recentred(described[i], centre)
            faces[i] = _faces(frame, described[i], rank, options)
            images[i] = _image_face(frame, described[i], faces[i][0], geometry, options)
    return [described[i] for i in sorted(kept, key=lambda i: (described[i][0].first, described[i][1]["mean_y_m"]))]


def smear_centre(described: list, faces: list, i: int, kept: list) -> np.ndarray | None:
    """The centre of a diffuse ``pipeline`` line ``i``'s smear (m across, at each of its pings): the median of
    the paths of the line and of the diffuse lines not ``kept`` that shadow it at its depth within two gates
    (:func:`_shadows` as reported, its first rule), each where it reaches; ``None`` where fewer than
    :data:`SMEAR_TRACKS` lie in the smear, or for another line.  Tracks whose gates hold the same detections
    fit the same path: a path the search found more often weighs more.  The median is taken at every ping, also
    where fewer than ``SMEAR_TRACKS`` paths reach it (keeping the line's own path there lost a pipe's line on
    the discrete tuning draws, family:13's B, 0.69 -> 1.43 m, and a join, 15's A)."""
    def diffuse(d):
        return d[1]["kind"] == "pipeline" and not d[1]["specular"]
    if not diffuse(described[i]):
        return None
    pings, path_y = described[i][2]
    side = [j for j, d in enumerate(described) if j != i and j not in kept and diffuse(d)
            and _shadows(faces[j][:1], faces[i][:1], -math.inf)]
    stack = np.full((1 + len(side), pings.size), np.nan)
    stack[0] = path_y
    for row, j in enumerate(side, start=1):
        p, y = described[j][2]
        _, a, b = np.intersect1d(pings, p, return_indices=True)
        stack[row, a] = y[b]
    if stack.shape[0] < SMEAR_TRACKS:
        return None
    return np.nanmedian(stack, axis=0)


def _imaged_crossing(frame: TrackFrame, described: list, i: int, faces: list, images: list,
                     kept: list) -> int | None:
    """The line whose specular image (:func:`_image_face`) line ``i`` lies on (:func:`_on_image`, over the
    other's pings), among the better lines kept and the weaker ones, the best of them, or ``None``.  A rough
    pipe at a heading echoes both where it crosses the plane and from its nearest point off it, and either can
    be the stronger (the tuning draw family:17's B, 10 degrees to the track 218 m out in 322 m of water: its
    image 5 m nearer the ship and 1.4 m deeper, scoring 26 against the crossing's 10).  Only an image that
    lies apart from its line (:func:`_image_apart`): a pipe along the track is its own image, and a line beside
    it its shadow.  A line taken as specular already has been moved."""
    tr, row, *_ = described[i]
    if row["specular"]:
        return None
    others = [j for j, d in enumerate(described) if (j in kept or d[1]["score"] < row["score"])
              and images[j] is not None and _image_apart(images[j], faces[j][0][2])]
    on = [j for j in others if _on_image(frame, tr.members, faces[i][0][3], images[j], over_image=True)]
    return max(on, key=lambda j: described[j][1]["score"], default=None)


def _image_apart(image: tuple, burial: float) -> bool:
    """Whether a line's specular image (:func:`_image_face`) lies apart from the line (at ``burial``, m): where
    the image is seen, the median distance across more than two gates, or its median burial more than
    :data:`IMAGE_DEPTH_M` deeper."""
    _, y_img, b_img, gate, seen, y = image
    if not seen.any():
        return False
    return bool(np.median(np.abs(y_img - y)[seen]) > 2 * gate or np.median(b_img[seen]) - burial > IMAGE_DEPTH_M)


def _faces(frame: TrackFrame, line: tuple, rank, options: LineOptions) -> tuple:
    """A described line's ``(pings, y, burial, gate, reach)`` as reported and, for a specular line, as its
    echoes lie: the path through its detections (``rank.path``) and their own burial, before the move to the
    crossings.  ``gate``: the gate across as narrowed for the score about that path (:func:`effective_gates`),
    ``reach``: its smear's reach (:func:`_smear_reach`), m."""
    tr, row, (pings, y), *_ = line

    def face(path_y, burial):
        return (pings, path_y, burial, effective_gates(frame, tr, path_y, options)[0],
                _smear_reach(frame, tr, path_y, options))
    reported = face(y, row["burial_m"])
    if not row["specular"]:
        return (reported,)
    return reported, face(rank.path(tr), line_burial(frame.b[tr.members], frame.b_sigma[tr.members])[0])


def _image_face(frame: TrackFrame, line: tuple, reported: tuple, geometry: tuple, options: LineOptions
                ) -> tuple | None:
    """Where a ``pipeline`` line that is not taken as specular would show its specular image, were its pipe
    smooth (:func:`clbeam.survey.specular.specular_image`, from its path's heading and depth): ``(pings, y,
    burial, gate, seen, path_y)`` per ping of its extent and ``max_gap_pings + 1`` imaged pings either side
    (:func:`extended_path`: a pipe's image can take up where its crossing's line stops), ``seen`` where the
    nearest point lies within :data:`IMAGE_SEEN_BEAMS` beam widths of the ping's plane (further out the echo is
    not seen), ``path_y`` the line's own path there.  ``None`` for other lines (a specular line's echoes' face
    is its image), without a seabed or an along-track distance."""
    tr, row, *_ = line
    _, y, burial, gate, _ = reported
    sb, centre_yz, scaled = geometry
    s_ext = frame.ping_s[tr.first:tr.last + 1]
    if (not scaled or row["kind"] != "pipeline" or row["specular"] or not math.isfinite(burial)
            or y.size < 2 or np.ptp(s_ext) <= 0):
        return None
    pings, s, y = extended_path(frame, tr, y, options.max_gap_pings + 1)
    z = sb[pings, 0] + sb[pings, 1] * y + burial
    y_img, z_img, off = specular_image(y, z, np.gradient(y, s), centre_yz[pings])
    seen = off <= math.sin(IMAGE_SEEN_BEAMS * math.radians(options.beam_width_deg))
    return pings, y_img, z_img - (sb[pings, 0] + sb[pings, 1] * y_img), gate, seen, y


def extended_path(frame: TrackFrame, tr: Track, path_y: np.ndarray, reach: int) -> tuple:
    """A line's path over its extent and ``reach`` imaged pings either side: ``(pings, s, y)``, survey pings,
    along-track distances (m) and offsets across (m), beyond its ends the straight line through its
    :data:`END_PINGS` pings nearest each (:func:`end_value`)."""
    lo, hi = max(tr.first - reach, 0), min(tr.last + reach, frame.pings.size - 1)
    s = frame.ping_s[lo:hi + 1]
    s_ext = frame.ping_s[tr.first:tr.last + 1]
    y = np.interp(s, s_ext, path_y)
    before, after = s < s_ext[0], s > s_ext[-1]
    y[before] = end_value(s_ext[:END_PINGS], path_y[:END_PINGS], s[before])
    y[after] = end_value(s_ext[-END_PINGS:], path_y[-END_PINGS:], s[after])
    return frame.pings[lo:hi + 1], s, y


def end_value(s: np.ndarray, y: np.ndarray, at):
    """A path's offset across (m) at along-track distances ``at`` (m), from a straight line through ``(s, y)``
    (one point, or all at one distance: its last offset)."""
    if s.size < 2 or np.ptp(s) <= 0:
        return np.full(np.shape(at), float(y[-1]))
    slope, intercept = np.polyfit(s, y, 1)
    return slope * np.asarray(at, dtype=np.float64) + intercept


def _on_image(frame: TrackFrame, members: np.ndarray, gate: float, image: tuple | None,
              over_image: bool = False) -> bool:
    """Whether a line's detections (``members``; ``gate``, its gate across, m) lie on another line's specular
    image (:func:`_image_face`): at least half of them where the image is seen, within two gates of it across
    the track and within :data:`IMAGE_DEPTH_M` of its burial in their own pings.  A rough pipe at a heading
    echoes both where it crosses the plane and, specularly, from its nearest point off the plane (nearer the
    ship and deeper): one pipe, two tracks.  ``over_image``: half of those in the image's pings, at least three
    (a line that reaches beyond a weaker crossing)."""
    if image is None:
        return False
    pings, y_img, b_img, gate_img, seen, _ = image
    k = np.clip(np.searchsorted(pings, frame.ping[members]), 0, pings.size - 1)
    inside = pings[k] == frame.ping[members]
    on = inside & seen[k]
    with np.errstate(invalid="ignore"):
        near = on & (np.abs(frame.y[members] - y_img[k]) <= 2 * max(gate, gate_img)) \
            & (np.abs(frame.b[members] - b_img[k]) <= IMAGE_DEPTH_M)
    if over_image:
        return bool(np.count_nonzero(inside) >= 3 and np.count_nonzero(near) >= 0.5 * np.count_nonzero(inside))
    return bool(np.count_nonzero(near) >= 0.5 * members.size)


def _shadows(line: tuple, better: tuple, weaker_db: float) -> bool:
    """Whether ``line`` shadows ``better`` (both :func:`_faces`) as reported, or as their echoes lie: over at
    least half its pings within two gates of it across the track (the wider line's gate, as narrowed for the
    score, :func:`effective_gates`: a crossing line's smear holds more than one track, while tight lines side
    by side at a heading are two) and within 3 m in burial (a pulse's tail or a sidelobe of the same pipe); or
    within two gates plus the better line's reach (its smear out to :data:`SHADOW_BEAMS`, :func:`_smear_reach`),
    deeper than it and at least :data:`SHADOW_DB` weaker (``weaker_db``: the better one's mean level less its,
    dB): the same pipe's stretch seen through a transmit sidelobe, off the plane, so further along its range."""
    pairs = [(line[0], better[0])] + ([(line[-1], better[-1])] if len(line) + len(better) > 2 else [])
    for (pings, y, burial, gate, _), (p2, y2, burial2, gate2, reach_m) in pairs:
        _, a, b = np.intersect1d(pings, p2, return_indices=True)
        dist = np.abs(y[a] - y2[b])
        two_gates = 2 * max(gate, gate2)
        same_depth = not (abs(burial - burial2) > 3.0)
        if np.count_nonzero(dist <= two_gates) >= 0.5 * pings.size and same_depth:
            return True
        deeper = burial >= burial2
        if deeper and weaker_db >= SHADOW_DB and np.count_nonzero(dist <= two_gates + reach_m) >= 0.5 * pings.size:
            return True
    return False


def _mean_level(level: np.ndarray | None, members: np.ndarray) -> float:
    """Mean intensity of a line's detections (dB; -inf without levels)."""
    loud = level[members][np.isfinite(level[members])] if level is not None else np.zeros(0)
    return float(np.mean(loud)) if loud.size else -math.inf


def _smear_reach(frame: TrackFrame, tr: Track, path_y: np.ndarray, options: LineOptions) -> float:
    """How far across (m) a line's transmit smear reaches out to :data:`SHADOW_BEAMS` beam widths off the
    ping's plane: ``SHADOW_BEAMS r beam |tan a|``, the median over its detections (slant range ``r``, the path's
    slope ``tan a``)."""
    m = tr.members
    s_ext = frame.ping_s[tr.first:tr.last + 1]
    if path_y.size < 2 or np.ptp(s_ext) <= 0:
        return 0.0
    k = np.searchsorted(frame.pings, frame.ping[m]) - tr.first
    slope = np.gradient(path_y, s_ext)[k]
    return float(np.median(2 * SHADOW_BEAMS * smear_half_width(frame.r[m], slope, options)))


def track_gate(frame: TrackFrame, tr: Track, path_y: np.ndarray, options: LineOptions) -> float:
    """The mean half-width (m) of the gate across that the track's detections were taken with
    (:func:`~clbeam.survey.lines.across_gate` at its path's slope: wider with its heading, its peaks' slide
    along their arcs and a crossing line's smear)."""
    m = tr.members
    s_ext = frame.ping_s[tr.first:tr.last + 1]
    slope = np.gradient(path_y, s_ext) if path_y.size > 1 and np.ptp(s_ext) > 0 else np.zeros(path_y.size)
    k = np.searchsorted(frame.pings, frame.ping[m]) - tr.first
    return float(np.mean(across_gate(frame, m, slope[k], options)))


def effective_gates(frame: TrackFrame, tr: Track, path_y: np.ndarray, options: LineOptions) -> tuple[float, float]:
    """The half-widths (m) across and in burial that a chance line must match, for the score.

    The gates the track's detections were taken with, on average
    (:func:`track_gate`), narrowed to 2.5 times the RMS distance of the
    detections from the line's path where they lie closer than that (a line
    tighter than its gate is less likely by chance), never below
    ``across_gate_m``.
    """
    m = tr.members
    k = np.searchsorted(frame.pings, frame.ping[m]) - tr.first
    fit = 2.5 * float(np.sqrt(np.mean((frame.y[m] - path_y[k]) ** 2)))
    sig = frame.b_sigma[m]
    gb = np.maximum(options.burial_gate_m, 2 * np.where(np.isfinite(sig), sig, 0.0))
    return min(track_gate(frame, tr, path_y, options), max(options.across_gate_m, fit)), float(np.mean(gb))
