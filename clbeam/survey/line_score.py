"""How much a line is worth: the chance that clutter alone lines up as well.

A-contrario scoring (Desolneux, Moisan & Morel, *From Gestalt Theory to
Image Analysis*, 2008): a line spans ``K`` imaged pings and has a detection
on it in ``h`` of them.  Were the detections around it clutter scattered at
random, a ping would put one inside the line's gates (``2 w`` across by
``2 d`` in burial) with a probability ``p`` measured in the same survey on
copies of the line's path shifted across (:func:`clutter_hit_rate`), and
``h`` of ``K`` pings or more with the binomial tail ``P``, hits and clutter
both counted at several CF levels and the best level kept (:data:`CF_LEVELS`).
The search tries many lines: per km of survey line about

    N = (1000 / spacing) x (swath / 2w) x (burial span / 2d)
        x (2 tan(max angle) K spacing / 2w + 1) x K x levels

(start ping, cross-track offset, burial, heading within the window of
headings, length, CF level), so ``N P`` is the expected number of chance lines as good
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
    y_range_m : tuple of float
        The detections' extent across, least and greatest offset (m): where
        the copies of a line for its clutter may lie (:func:`copy_offsets`).
    """

    spacing_m: float
    swath_m: float
    burial_span_m: float
    y_range_m: tuple[float, float] = (-math.inf, math.inf)


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


#: CF levels a line is scored at (its hits, and the clutter's, counted at CF >= each): the strongest gives the
#: score, the levels' number joins the tests.  0 counts every detection (all are above the map threshold).
CF_LEVELS = (0.0, 0.5, 0.6, 0.7, 0.8)


def line_score(hits, trials: int, p_hit, across_gate_m: float, burial_gate_m: float,
               size: SearchSize, max_angle_deg: float) -> float:
    """Score of a line: ``-log10`` of the expected number of chance lines as good per km.

    With hits and clutter counted at several CF levels (:data:`CF_LEVELS`),
    the best level's score less ``log10`` of the number of levels: a line
    of strong echoes through weak clutter stands out at a high level where
    every detection counted would not (a union bound over the levels tried).

    Parameters
    ----------
    hits : int or sequence of int
        Pings with a detection on the line (per CF level), of ``trials``.
    trials : int
        Imaged pings along the line's extent.
    p_hit : float or sequence of float
        Probability that clutter alone puts a detection inside the line's
        gates in one ping (per CF level; :func:`clutter_hit_rate`).
    across_gate_m, burial_gate_m : float
        Half-widths of the line's gate (m).
    size : SearchSize
    max_angle_deg : float
        Headings searched relative to the track (degree).

    Returns
    -------
    float
        The score (higher: less likely by chance).
    """
    hits, p_hit = np.atleast_1d(hits), np.atleast_1d(p_hit)
    if hits.size != p_hit.size:
        raise ValueError(f"{hits.size} hit counts for {p_hit.size} clutter rates")
    log_p = min(log10_binomial_tail(int(h), trials, float(p)) for h, p in zip(hits, p_hit))
    n = tests_per_km(size, trials, across_gate_m, burial_gate_m, max_angle_deg) * hits.size
    return -(math.log10(n) + log_p)


def copy_offsets(across_gate_m: float, *, half_width_m: float = 50.0) -> np.ndarray:
    """Offsets (m) of the copies of a line's path on which its clutter is counted (:func:`clutter_hit_rate`):
    steps of one gate width (``2 across_gate_m``) from two widths out to ``half_width_m`` (at least four
    widths), on both sides."""
    step = 2 * across_gate_m
    n = max(int(max(half_width_m, 8 * across_gate_m) // step), 2)
    return step * np.r_[-np.arange(2, n + 1), np.arange(2, n + 1)].astype(np.float64)


def clutter_hit_rate(dy: np.ndarray, ping_index: np.ndarray, path_y: np.ndarray, offsets_m: np.ndarray,
                     across_gate_m: float, y_range_m: tuple, *, cf: np.ndarray | None = None,
                     cf_levels=(0.0,), outlier_p: float = 1e-3) -> np.ndarray:
    """Probability that clutter alone puts a detection inside a line's gates in one ping, measured in the survey.

    The line's path is copied across at ``offsets_m`` (:func:`copy_offsets`);
    a copy counts, over the pings where it lies within ``y_range_m`` (the
    detections' extent: beyond it there is no clutter to count), those with
    a detection within ``across_gate_m`` of it (of CF at least each level).
    On each side of the line the rate is the copies' pooled count over their
    pings, less the copies that hold more than clutter (another pipe, the
    nadir echo): those whose count the pooled rate makes less likely than
    ``outlier_p`` (binomial upper tail), dropped until none is; the line
    takes the larger side's (at the edge of a clutter band the clutter at
    the line is that of the side within it).  Measured this way, clutter that
    gathers at the line's burial (peaks moved along their arcs to the burial
    prior, far from nadir) or thickens with range counts as it is, where a
    density averaged over burial and across would understate it.

    Parameters
    ----------
    dy : numpy.ndarray
        ``(n,)`` offsets (m) across of the clutter detections (off the
        line, within its burial gate as its own detections are) from the
        line's path at their pings.
    ping_index : numpy.ndarray
        ``(n,)`` their pings, as indices into ``path_y``.
    path_y : numpy.ndarray
        ``(K,)`` the line's offset (m) at each imaged ping of its extent.
    offsets_m : numpy.ndarray
        The copies' offsets (m).
    across_gate_m : float
        Half-width of the line's gate across (m).
    y_range_m : (float, float)
        Least and greatest offset of the survey's detections (m).
    cf : numpy.ndarray, optional
        ``(n,)`` their CFs, for ``cf_levels`` above 0.
    cf_levels : sequence of float
        CF levels counted at.
    outlier_p : float
        Upper-tail probability below which a copy is not clutter.

    Returns
    -------
    numpy.ndarray
        The probability per level, each at least one over a side's copies'
        pings: one clutter detection is assumed even where none was seen (a
        line in empty water is not infinitely sure).
    """
    strength = np.ones(dy.size) if cf is None else np.asarray(cf, dtype=np.float64)
    counts, trials = _copy_counts(dy, ping_index, path_y, offsets_m, across_gate_m, y_range_m, strength, cf_levels)
    sides = _measuring_sides(np.asarray(offsets_m), trials, path_y.size)
    rates = [[_pooled_rate(counts[side, k], trials[side], outlier_p) for side in sides]
             for k in range(len(cf_levels))]
    if not np.isfinite(rates).any():  # no copy inside the detections' extent
        return np.full(len(cf_levels), 1.0 / max(path_y.size, 1))
    return np.nanmax(np.asarray(rates, dtype=np.float64), axis=1)


def _measuring_sides(offsets_m: np.ndarray, trials: np.ndarray, n_pings: int) -> list:
    """Masks of the copies on each side of a line of ``n_pings`` pings, less a side whose copies lie within the
    detections' extent over fewer pings than the line spans (a line at the swath's edge) while the other's do not:
    its floor of one hit over a few pings would read as clutter in every ping."""
    sides = [offsets_m < 0, offsets_m > 0]
    covered = [trials[side].sum() >= n_pings for side in sides]
    return [side for side, ok in zip(sides, covered) if ok] if any(covered) else sides


def _copy_counts(dy, ping_index, path_y, offsets_m, across_gate_m, y_range_m, strength, cf_levels) -> tuple:
    """Per copy, its pings with a detection inside at each CF level ``(copies, levels)``, and its pings within
    the detections' extent ``(copies,)`` (:func:`clutter_hit_rate`)."""
    counts = np.zeros((len(offsets_m), len(cf_levels)))
    trials = np.zeros(len(offsets_m))
    for i, off in enumerate(offsets_m):
        valid = (path_y + off >= y_range_m[0]) & (path_y + off <= y_range_m[1])
        inside = (np.abs(dy - off) <= across_gate_m) & valid[ping_index]
        best = np.full(path_y.size, -np.inf)  # the strongest detection of each ping inside the copy
        np.maximum.at(best, ping_index[inside], strength[inside])
        counts[i] = [np.count_nonzero(best >= level) for level in cf_levels]
        trials[i] = np.count_nonzero(valid)
    return counts, trials


def _pooled_rate(counts: np.ndarray, trials: np.ndarray, outlier_p: float) -> float:
    """Pooled hit rate of one side's copies with pings, the outlying ones (upper tail below ``outlier_p``)
    left out; at least one over their pings (NaN: no copy with pings)."""
    from scipy.special import bdtrc

    use = trials > 0
    if not use.any():
        return math.nan
    k_least, n_int = np.asarray(counts, dtype=np.int64) - 1, np.asarray(trials, dtype=np.int64)
    for _ in range(len(counts)):
        rate = counts[use].sum() / trials[use].sum()
        # P(X >= count), X ~ Binomial(trials, rate): scipy.stats.binom.sf as a ufunc (1 for a count of 0)
        keep = use & (bdtrc(k_least, n_int, rate) >= outlier_p)
        if keep.sum() == use.sum() or not keep.any():
            break
        use = keep
    return max(float(counts[use].sum() / trials[use].sum()), 1.0 / float(trials[use].sum()))
