"""How much a line is worth: the chance that clutter alone lines up as well.

A-contrario scoring (Desolneux, Moisan & Morel, *From Gestalt Theory to
Image Analysis*, 2008): a line spans ``K`` imaged pings and has a detection
on it in ``h`` of them.  Were the detections around it clutter scattered at
random, with the density ``lambda`` measured around the line in the same
survey (detections per metre across, per metre of burial, per ping),
a ping would put one inside the line's gate (``2 w`` across by ``2 d`` in
burial) with probability ``p = 1 - exp(-lambda 2w 2d)``, and ``h`` of ``K``
pings or more with the binomial tail ``P``.  The search tries many lines:
per km of survey line about

    N = (1000 / spacing) x (swath / 2w) x (burial span / 2d)
        x (2 tan(max angle) K spacing / 2w + 1) x K

(start ping, cross-track offset, burial, heading within the window of
headings, length), so ``N P`` is the expected number of chance lines as good
per km, and the score is ``-log10(N P)``: a score of 1 is one false line in
10 km, if the clutter were independent from ping to ping.  It is not quite
(a seabed scatterer stays in the beam for several pings), so the default
threshold is set from clutter-only scenes (``docs/lines.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SearchSize:
    """The extent of the line search, for the number of tests.

    Attributes
    ----------
    spacing_m : float
        Mean along-track distance between pings (m).
    swath_m : float
        Cross-track extent of the detections (m).
    burial_span_m : float
        Burial (or depth) extent of the detections (m).
    """

    spacing_m: float
    swath_m: float
    burial_span_m: float


def tests_per_km(size: SearchSize, n_pings: int, across_gate_m: float, burial_gate_m: float,
                 max_angle_deg: float) -> float:
    """Number of line hypotheses of ``n_pings`` pings per km of survey line (module docstring)."""
    spacing = max(size.spacing_m, 1e-3)
    length = n_pings * spacing
    headings = 2 * math.tan(math.radians(max_angle_deg)) * length / (2 * across_gate_m) + 1
    return ((1000.0 / spacing) * max(size.swath_m / (2 * across_gate_m), 1.0)
            * max(size.burial_span_m / (2 * burial_gate_m), 1.0) * headings * max(n_pings, 1))


def log10_binomial_tail(hits: int, trials: int, p: float) -> float:
    """``log10 P(X >= hits)`` for ``X ~ Binomial(trials, p)``, summed in logs (exact far into the tail)."""
    from scipy.special import gammaln

    if hits <= 0:
        return 0.0
    if hits > trials or p <= 0:
        return -math.inf
    if p >= 1:
        return 0.0
    j = np.arange(hits, trials + 1, dtype=np.float64)
    terms = (gammaln(trials + 1) - gammaln(j + 1) - gammaln(trials - j + 1) + j * math.log(p)
             + (trials - j) * math.log1p(-p))
    top = float(terms.max())
    return (top + math.log(float(np.exp(terms - top).sum()))) / math.log(10)


def line_score(hits: int, trials: int, density: float, across_gate_m: float, burial_gate_m: float,
               size: SearchSize, max_angle_deg: float) -> float:
    """Score of a line: ``-log10`` of the expected number of chance lines as good per km.

    Parameters
    ----------
    hits, trials : int
        Pings with a detection on the line, and imaged pings along its extent.
    density : float
        Clutter around it: detections per metre across, per metre of
        burial, per ping.
    across_gate_m, burial_gate_m : float
        Half-widths of the line's gate (m).
    size : SearchSize
    max_angle_deg : float
        Headings searched relative to the track (degree).

    Returns
    -------
    float
        The score (higher: less likely by chance); ``inf`` without clutter.
    """
    p = -math.expm1(-density * 2 * across_gate_m * 2 * burial_gate_m)
    log_p = log10_binomial_tail(hits, trials, p)
    n = tests_per_km(size, trials, across_gate_m, burial_gate_m, max_angle_deg)
    return -(math.log10(n) + log_p)


def clutter_density(y: np.ndarray, b: np.ndarray, line_y: np.ndarray, line_b: float, *, n_pings: int,
                    across_gate_m: float, burial_gate_m: float, half_width_m: float = 50.0,
                    burial_half_m: float = 3.0) -> float:
    """Detections per metre across, per metre of burial, per ping around a line, off it.

    Parameters
    ----------
    y, b : numpy.ndarray
        ``(n,)`` offsets and burials (m) of the detections of the line's
        pings that are not on it.
    line_y : numpy.ndarray
        ``(n,)`` the line's offset at each of those detections' pings (m).
    line_b : float
        The line's burial (m; NaN: burial not used).
    n_pings : int
        Imaged pings along the line.
    across_gate_m, burial_gate_m : float
        The line's gate (m), left out of the count.
    half_width_m, burial_half_m : float
        Half-extent of the neighbourhood counted (m; across, at least four gates).
    """
    half_width_m = max(half_width_m, 4 * across_gate_m)  # the neighbourhood always reaches beyond the gate
    dy = np.abs(y - line_y)
    near = (dy <= half_width_m) & (dy > across_gate_m)
    if math.isfinite(line_b):
        near &= np.abs(b - line_b) <= burial_half_m
        burial_extent = 2 * burial_half_m
    else:
        burial_extent = 2 * burial_gate_m  # depth not used: one burial cell
    area = max(n_pings, 1) * 2 * (half_width_m - across_gate_m) * burial_extent
    # one clutter detection is assumed present even where none was seen: a line in empty water is not infinitely sure
    return max(int(near.sum()), 1) / area
