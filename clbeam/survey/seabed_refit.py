"""The seabed fitted again without the echoes of lines lying on or above it.

A ping's seabed is the upper edge of its peaks (:func:`clbeam.survey.burial.seabed_line`).  A pipe lying
exposed on the seabed, or spanning free above it, is that upper edge wherever it crosses: in every ping
the two shallowest peaks of its bin are the pipe's, its echoes pull the fit up there, and a straight fit
across the whole swath tilts by a milliradian or two.  At 500 m across that is half a metre to a metre in
the seabed, and so in the burial of every line on that ping, not only the pipe's (a discrete-scatterer
tuning survey, ``family:17``: a pipe spanning 1.2 m above the seabed at 351 m to port put the seabed 0.7
m high under it, 1.1 m high at 589 m to port and 0.7 m low at 589 m to starboard).  Once the lines are
known, the peaks along those whose echoes lie within the seabed fit's tolerance below the seabed, or
above it, are left out and each ping's fit refined again from where it was (family:17: within 0.1 m at
every pipe); where that changes the seabed, the lines are found again over it (:func:`seabed_off_lines`).
A new search of the planes is not made: under a weak seabed over a bright horizon, the peaks left out
can be what held the first fit on the seabed (``family:44``: it took the horizon, 6 m off).
"""

from __future__ import annotations

import math

import numpy as np

from clbeam.survey.burial import refined_seabed_lines
from clbeam.survey.georef import SurveyNavigation
from clbeam.survey.line_options import LineOptions
from clbeam.survey.line_products import SurveyLines, smooth_seabed, track_distance_m
from clbeam.survey.lines import smear_half_width

#: a line whose echoes lie less than this below the seabed (m; the seabed fit's inlier tolerance), or above
#: it, can hold its pings' upper edge
SEABED_EDGE_BURIAL_M = 1.0
#: the refit stands (and the lines are found again over it) where leaving the lines' peaks out moves some ping's
#: seabed, steadied over pings, this much (m) at an end of its peaks; less, and the first fit stands
REFIT_MIN_CHANGE_M = 0.05
#: the kinds of line whose echoes may lie in the seabed's upper edge (a seabed-nadir line is the seabed itself)
EDGE_KINDS = ("pipeline", "water")


def seabed_off_lines(peaks: list, seabed: np.ndarray, lines: SurveyLines, det_pyz: tuple, centre_yz: np.ndarray,
                     nav: SurveyNavigation, options: LineOptions) -> np.ndarray | None:
    """Each ping's seabed ``(z0, slope)`` (m, 1): the first fit refined again
    (:func:`clbeam.survey.burial.refined_seabed_lines`) without the peaks along the lines that lie in the
    seabed's upper edge: ``pipeline`` or ``water`` lines
    whose echoes lie less than :data:`SEABED_EDGE_BURIAL_M` below the first fit (:func:`echo_burial_m`: a
    smooth pipe's specular echo lies deeper than the pipe, and the fit sees the echoes); ``None`` when there
    is none, or leaving their peaks out moves no ping's seabed, steadied over pings as the lines take it
    (:func:`~clbeam.survey.line_products.smooth_seabed`), by :data:`REFIT_MIN_CHANGE_M` at either end of its
    peaks (against the same refinement of every peak: the first fit stands).

    Along such a line, a ping's peaks within :func:`edge_half_width_m` across of its path, or of its
    detections there, are left out (a smooth pipe's specular line is moved to where the pipe crosses the
    pings' planes, its echoes lie at its image, metres off).

    Parameters
    ----------
    peaks : list
        Per survey ping ``(y, z)`` arrays of the seabed's peaks (m, earth frame), or ``None`` (not imaged).
    seabed : numpy.ndarray
        ``(n_pings, 2)`` the first fit, that ``lines`` were found over (NaN: none).
    lines : SurveyLines
        The lines found over the first fit.
    det_pyz : tuple
        ``(ping, y, z)`` of the detections ``lines.labels`` labels (survey ping, m, m).
    centre_yz : numpy.ndarray
        ``(n_pings, 2)`` grid centres (m).
    nav : SurveyNavigation
        After :meth:`~SurveyNavigation.finish` (the along-track distance of the pings).
    options : LineOptions
        ``across_gate_m`` and ``beam_width_deg``.
    """
    members = {k: lines.labels == k for k, row in enumerate(lines.rows) if row["kind"] in EDGE_KINDS}
    edge = [k for k, mine in members.items() if echo_burial_m(mine, det_pyz, seabed) < SEABED_EDGE_BURIAL_M]
    if not edge:
        return None
    kept = [None if p is None else np.ones(len(p[0]), dtype=bool) for p in peaks]
    for k in edge:
        pings, path_y, mine = *lines.ping_paths[k], members[k]
        if pings.size == 0:
            continue
        # a ping without a grid centre: the two gates alone
        half = np.nan_to_num(edge_half_width_m(pings, path_y, seabed, centre_yz, nav, options),
                             nan=2 * options.across_gate_m)
        at = np.clip(np.searchsorted(pings, det_pyz[0][mine]), 0, pings.size - 1)
        for g, y, h in zip(np.r_[pings, det_pyz[0][mine]], np.r_[path_y, det_pyz[1][mine]], np.r_[half, half[at]]):
            if peaks[g] is not None:
                kept[g] &= np.abs(peaks[g][0] - y) > h
    # the first fit refined without them: held near where it was, where a new search of the planes could take
    # a horizon under a weak seabed whose fit those peaks held up
    refit = refined_seabed_lines([None if p is None else (p[0][m], p[1][m]) for p, m in zip(peaks, kept)], seabed)
    # against the same refinement with every peak, both steadied as the lines take them: what leaving the lines'
    # peaks out changed
    imaged = np.array([p is not None for p in peaks])
    change = largest_change_m(smooth_seabed(refined_seabed_lines(peaks, seabed), imaged),
                              smooth_seabed(refit, imaged), peaks)
    return refit if change >= REFIT_MIN_CHANGE_M else None


def echo_burial_m(mine: np.ndarray, det_pyz: tuple, seabed: np.ndarray) -> float:
    """The median depth (m) below the ``seabed`` (``(n_pings, 2)``) of the detections ``mine`` (bool over
    ``det_pyz``'s ``(ping, y, z)``); NaN where none has a seabed."""
    g, y, z = (np.asarray(a)[mine] for a in det_pyz)
    below = z - (seabed[g, 0] + seabed[g, 1] * y)
    below = below[np.isfinite(below)]
    return float(np.median(below)) if below.size else math.nan


def largest_change_m(first: np.ndarray, second: np.ndarray, peaks: list) -> float:
    """The largest difference in depth (m) between two seabed fits ``(n_pings, 2)`` at either end of each ping's
    peaks (``peaks`` as :func:`seabed_off_lines` has them); infinite where a ping has one fit and not the
    other, 0 where neither."""
    worst = 0.0
    for g, p in enumerate(peaks):
        if p is None or not len(p[0]):
            continue
        a, b = np.isfinite(first[g]).all(), np.isfinite(second[g]).all()
        if a != b:
            return math.inf
        if a:
            ends = np.array([np.min(p[0]), np.max(p[0])])
            diff = (second[g, 0] - first[g, 0]) + (second[g, 1] - first[g, 1]) * ends
            worst = max(worst, float(np.max(np.abs(diff))))
    return worst


def edge_half_width_m(pings: np.ndarray, path_y: np.ndarray, seabed: np.ndarray, centre_yz: np.ndarray,
                      nav: SurveyNavigation, options: LineOptions) -> np.ndarray:
    """Half the width across (m) of a line's echoes at each of its ``pings``: its smear over the stretch
    inside the transmit beam (:func:`~clbeam.survey.lines.smear_half_width`) at the slant range from the grid centre to its
    path ``path_y`` (m) on the ``seabed`` (``(n_pings, 2)``; where unknown, the offset from the centre),
    plus twice ``across_gate_m``."""
    s, _ = track_distance_m(nav, pings, options.nominal_spacing_m)
    slope = np.gradient(path_y, s) if pings.size > 1 else np.zeros(pings.size)
    dy = path_y - centre_yz[pings, 0]
    dz = np.nan_to_num(seabed[pings, 0] + seabed[pings, 1] * path_y - centre_yz[pings, 1], nan=0.0)
    r = np.hypot(dy, dz)
    return smear_half_width(r, slope, options) + 2 * options.across_gate_m
