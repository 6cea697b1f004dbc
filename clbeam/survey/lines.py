"""Linear features across a survey: buried pipelines found as lines in plan view.

A pipeline gives a coherence detection in ping after ping, at a cross-track
offset that drifts steadily when it is not parallel to the track and at a
nearly constant depth below the seabed; clutter (seabed and sub-bottom
scatterers, noise) does not line up.  :func:`find_lines` works in the track
frame: along-track distance ``s`` of each ping, cross-track offset ``y`` and
burial ``b`` (depth below the seabed picked in the same ping) of each
detection.  On a straight survey line that frame is plan view itself; on a
curved track it bends with the track, and the products map the lines back
to the world ping by ping.

1. **Seeds** (a Hough transform): windows of ``window_pings`` pings, half
   overlapping; in each, every detection votes for the lines through it
   whose heading relative to the track is within ``max_angle_deg``, binned
   by heading (spaced so that adjacent headings part by less than the gate
   over the window), by cross-track offset at the window's centre and by
   burial (bins the gate's width and four times it, each in four staggered
   grids).  A cell holding
   detections from at least ``seed_hits`` distinct pings is a seed.  Once
   the tracks of those seeds are chosen, a second transform over the
   detections they left (and those of tracks scoring under ``min_score``)
   widens the cells to the smear of a line crossing at each heading, and
   keeps the cells its clutter would fill as well by chance at most once
   in a million: a rough pipe at a steep heading spreads its echoes over a
   dozen of the first cells.
2. **Tracks**: from the strongest seed down, a line is followed ping by
   ping in both directions: a local straight-line fit to its last hits
   (over at most ``fit_length_m``) predicts the offset and the burial, the
   nearest unused detection within ``across_gate_m`` of it (across the
   line: ``1 / cos`` of its heading wider in ``y``, at most twice) and
   ``burial_gate_m`` joins, and the track bridges up to ``max_gap_pings``
   imaged pings in a row without one.  The local fit follows curved lines (30°/km
   bends 0.3 m from a straight line over 100 m).  Each seed that the
   candidates so far do not mostly hold grows a candidate; the best by
   score is kept, and one that shared its detections grows again without
   them; then the seeds skipped at first grow if still at most half used
   and not mostly held by the tracks or the seeds grown before them.
   Detections are used once.  (Kept seed by seed in the seeds' order,
   a seed that strayed off a crossing pipeline in dense clutter took the
   detections of the seed that followed it: the boulder field's pipeline.)
   A line that stops where another begins, within ``max_gap_pings`` and
   the gates (the other's first detections where the first's end would
   predict them), is joined to it when both score as lines on their own
   (:func:`_joined`): the first stopped only because the other held the
   detections that continue it.
3. **Scores** (:mod:`clbeam.survey.line_score`): how unlikely the line is as
   a chance alignment of the clutter measured around it; and a **kind**
   from its burial and position (:func:`line_kind`).
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field

import numpy as np

from clbeam.survey.burial import MIN_SCATTER_N
from clbeam.survey.line_options import LineOptions

#: Hough cells kept per window and grid, the most pings first
MAX_SEEDS_PER_GRID = 200
#: a seed of which candidates already hold more than this share grows no candidate of its own (they cost a
#: follow each; at one half the boulder field's pipeline seeds were all skipped)
SKIP_CLAIMED = 0.7
#: the chance that the window's clutter fills a Hough cell widened to a smear as well, at most (:func:`_beyond_chance`:
#: the windows hold hundreds of thousands of wide cells)
WIDE_CELL_P = 1e-6
#: a Hough cell is widened to a smear where the smear reaches this many of the gate's cells (narrower smears span
#: two cells of the first seeds at most)
SMEAR_CELL_MIN = 2.0
#: a line whose members' RMS distance from its path is at least this share of the smear's half-width
#: (``r beam |tan a| / 2``) is smeared (a rough crossing pipe: about 0.25-0.6; a tight line at a heading: 0.02)
SMEARED_SPREAD = 0.15
#: for the path tracks are ranked by, a smeared line whose mean smear half-width is at least this (m) is a wide
#: smear: a few detections a ping scattered uniformly over it, whose centre a fit of ``fit_length_m`` averages too
#: few of (Cross's X: 1.8 m RMS); the path a line reports has its own, :data:`REPORTED_WIDE_SMEAR_M`
WIDE_SMEAR_M = 4.0
#: the ranking path's wide smear is fitted over this many times ``fit_length_m`` (a pipe is straight over a few
#: hundred metres; at 2 the fit drifted 5 m along a tuning pipe, at 3-5 Cross's X came within 0.7-1.0 m)
WIDE_SMEAR_LENGTH = 3.0
#: passes of the gated fit: 2, or for a wide smear 6 (its gate is about the smear, so each pass moves the
#: window only part of the way to the detections' centre; 12 gave the same paths)
PATH_PASSES, WIDE_SMEAR_PASSES = 2, 6
#: the path a line reports (``line_path(..., reported=True)``), not the one its tracks are ranked by, treats a
#: smear from this half-width (m) as wide (its passes and echo weights) and fits it over this many times
#: ``fit_length_m``: one detection's
#: scatter over a smear of half-width ``h``, ``h / sqrt(3)``, reaches the 0.5 m position target near 0.9 m, and
#: neighbouring pings see the same stretch of pipe, so their errors do not average out within one fit length;
#: two, not three, for pipes that curve (20 degrees/km bends a 180 m half-width fit 0.8 m off, a 120 m one
#: 0.4 m).  Chosen on the tuning draws (discrete: position RMS <= 0.5 m 50 -> 63 of 101, one line 85 -> 88);
#: the same for the ranking path lost lines whose score fell under the threshold (``docs/lines.md``)
REPORTED_WIDE_SMEAR_M, REPORTED_WIDE_SMEAR_LENGTH = 1.0, 2.0
#: a track is joined to one that continues it only when both score at least this on their own (the default
#: ``min_score``, fixed: at any threshold the lines are then those a build without one counts by score)
JOIN_MIN_SCORE = 4.0


@dataclass
class TrackFrame:
    """Detections in the track frame, grouped by ping.

    Attributes
    ----------
    ping : numpy.ndarray
        ``(n,)`` survey ping of each detection (sorted).
    s : numpy.ndarray
        ``(n,)`` along-track distance of the detection's ping (m).
    y, b, cf : numpy.ndarray
        ``(n,)`` cross-track offset (m), burial below the seabed (m; NaN
        where the ping has no seabed: the burial gate then lets it pass) and CF.
    b_sigma : numpy.ndarray
        ``(n,)`` standard deviation of each burial (m): the burial gate
        widens to twice it (:func:`clbeam.survey.burial.arc_constrained`).
    b_post : numpy.ndarray
        ``(n,)`` burial of the peak moved along its arc under the prior
        (:func:`clbeam.survey.burial.arc_constrained`): what the Hough
        transform bins, so that a far peak's slide does not scatter its votes.
    y_sigma : numpy.ndarray or None
        ``(n,)`` standard deviation of each offset (m): the cross-track gate
        widens to twice it.
    r : numpy.ndarray or None
        ``(n,)`` slant range of each detection from its grid centre (m): a
        line crossing the track at a heading ``a`` smears over
        ``r beam tan(a)`` across in each ping (:func:`across_gate`).
    smear : numpy.ndarray or None
        ``(n,)`` how much deeper each detection would lie than a line's crossing
        were it an echo of the line's stretch inside the transmit beam (m,
        :func:`clbeam.survey.burial.smear_deepening_m`; zeros: none).
    echo : numpy.ndarray or None
        ``(n,)`` echo strength of each detection: its linear intensity with the
        two-way spherical spreading (``r**4``) taken out, relative to the
        frame's median (ones: none known).  Weighs a wide smear's detections:
        the transmit beam's main lobe makes its centre the brightest.
    pings : numpy.ndarray
        ``(k,)`` every imaged survey ping, sorted (those without detections too).
    ping_s : numpy.ndarray
        ``(k,)`` their along-track distance (m).
    """

    ping: np.ndarray
    s: np.ndarray
    y: np.ndarray
    b: np.ndarray
    cf: np.ndarray
    b_sigma: np.ndarray
    b_post: np.ndarray
    pings: np.ndarray
    ping_s: np.ndarray
    y_sigma: np.ndarray | None = None
    r: np.ndarray | None = None
    smear: np.ndarray | None = None
    echo: np.ndarray | None = None
    starts: np.ndarray = field(init=False)

    def __post_init__(self):
        for name in ("y_sigma", "r", "smear"):
            if getattr(self, name) is None:
                setattr(self, name, np.zeros(self.y.size))
        if self.echo is None:
            self.echo = np.ones(self.y.size)
        pos = np.searchsorted(self.ping, self.pings)
        self.starts = np.r_[pos, self.ping.size]

    def at(self, k: int) -> slice:
        """Detections of the ``k``-th imaged ping."""
        return slice(int(self.starts[k]), int(self.starts[k + 1]))


@dataclass
class Track:
    """One line: its detections and its smoothed path.

    Attributes
    ----------
    members : numpy.ndarray
        ``(h,)`` indices of its detections in the :class:`TrackFrame` (one per ping, ping order).
    first, last : int
        Indices of its first and last ping in ``TrackFrame.pings``.
    """

    members: np.ndarray
    first: int
    last: int


def find_tracks(frame: TrackFrame, options: LineOptions, rank=None) -> list[Track]:
    """Lines of detections (steps 1 and 2 of the module): every track of at least ``options.min_hits`` pings.

    Each seed of which earlier candidates hold at most ``SKIP_CLAIMED`` grows
    a candidate track, the detections shared between candidates; the best candidate by
    ``rank`` is kept and takes its detections, and a candidate that shared
    some grows again from its seed without them (a lazy greedy choice: in
    dense clutter a seed that strays off a line must not take the line's
    detections from the seed that follows it).  Once the candidates are
    spent, the seeds skipped at first that are still at most half used grow
    and are chosen the same way (the candidates that held them may have
    regrown elsewhere), but for those the tracks and the seeds grown before
    them in this round hold more than ``SKIP_CLAIMED`` of.

    Parameters
    ----------
    frame : TrackFrame
    options : LineOptions
    rank : callable, optional
        ``rank(track) -> float``, higher first (the line's score,
        :func:`clbeam.survey.line_products.line_ranker`); by default its
        number of pings.

    Returns
    -------
    list of Track
        In order of their first ping.
    """
    rank = rank or (lambda tr: float(tr.members.size))
    used = np.zeros(frame.ping.size, dtype=bool)
    heap, skipped = _candidates(frame, enumerate(hough_seeds(frame, options)), used, options, rank)
    tracks = _choose(frame, heap, used, options, rank)
    # a seed skipped for candidates that then regrew elsewhere or lost out would be lost: it grows now, unless
    # the tracks or the seeds grown before it in this round hold most of it (as in the first round)
    heap, _ = _candidates(frame, skipped, used, options, rank)
    tracks += _choose(frame, heap, used, options, rank)
    tracks += _smeared_tracks(frame, tracks, used, options, rank)
    tracks = _joined(frame, tracks, options, rank)
    tracks.sort(key=lambda t: (t.first, float(np.mean(frame.y[t.members]))))
    return tracks


def _joined(frame: TrackFrame, tracks: list, options: LineOptions, rank) -> list[Track]:
    """The tracks with each that another continues joined to it (the lines in order of their first ping, then
    the others).  A line (``rank`` at least :data:`JOIN_MIN_SCORE`) continues one that ends at most
    ``max_gap_pings + 1`` pings before it begins when their ends agree (:func:`_continues`); of several, the
    one that begins first, then the nearest in offset (a piece between the two must not be left inside the
    joined track's extent).  A track grown towards another stops at the first of its detections, which that
    track holds: a smooth pipe's specular echo drifts in burial as the pipe turns (its echo's extra depth
    grows with the heading), and two seeds along it grow two such halves.  Both must be lines on their own:
    two chance tracks of the clutter joined end to end would score as one line what neither is.  With
    :func:`find_tracks`' default ``rank`` (a track's pings) every track counts as a line."""
    is_line = [bool(rank(t) >= JOIN_MIN_SCORE) for t in tracks]
    weak = [t for t, line in zip(tracks, is_line) if not line]
    tracks = sorted([t for t, line in zip(tracks, is_line) if line], key=lambda t: t.first)
    firsts = np.array([t.first for t in tracks], dtype=np.int64)
    for i, a in enumerate(tracks):
        if a is None:
            continue
        while True:
            lo, hi = np.searchsorted(firsts, [a.last + 1, a.last + options.max_gap_pings + 2])
            mismatch = {j: _continues(frame, a, tracks[j], options) for j in range(lo, hi) if tracks[j] is not None}
            mismatch = {j: m for j, m in mismatch.items() if m is not None}
            if not mismatch:
                break
            j = min(mismatch, key=lambda j: (tracks[j].first, mismatch[j]))
            a = Track(members=np.r_[a.members, tracks[j].members], first=a.first, last=tracks[j].last)
            tracks[j] = None
        tracks[i] = a
    return [t for t in tracks if t is not None] + weak


def _continues(frame: TrackFrame, a: Track, b: Track, options: LineOptions) -> float | None:
    """Whether track ``b`` continues ``a`` (``a`` ending before ``b`` begins): one end's straight-line fit
    over its last (first) ``fit_hits`` detections (:func:`_local_fit`, as a growing track predicts its next
    ping) predicts the other's nearest detection within :func:`across_gate` (either way: a track's end may
    hold a few stray detections, a pipe's gap bridged through its clutter), and the two ends' burials
    (:func:`burial_estimate`) agree within ``burial_gate_m``, at least twice their detections' median
    standard deviation.  Returns the smaller of the two predictions' misses over the gate, or ``None``."""
    end_a, end_b = a.members[::-1][:options.fit_hits], b.members[:options.fit_hits]
    misses = []
    for ends, to in ((end_a, end_b[0]), (end_b, end_a[0])):
        icpt, slope, _ = _local_fit(frame, ends, options)
        gate = float(across_gate(frame, np.array([to]), slope, options)[0])
        misses.append(abs(frame.y[to] - (icpt + slope * frame.s[to])) / gate)
    b_a = burial_estimate(frame.b[end_a], frame.b_sigma[end_a])
    b_b = burial_estimate(frame.b[end_b], frame.b_sigma[end_b])
    sigma = np.r_[frame.b_sigma[end_a], frame.b_sigma[end_b]]
    sigma = float(np.median(sigma[np.isfinite(sigma)])) if np.isfinite(sigma).any() else 0.0
    if abs(b_a - b_b) > max(options.burial_gate_m, 2 * sigma) or min(misses) > 1.0:
        return None
    return min(misses)


def _smeared_tracks(frame: TrackFrame, tracks: list, used: np.ndarray, options: LineOptions, rank) -> list[Track]:
    """The lines smeared too widely for the gate's Hough cells (a rough pipe at a heading), seeded in widened cells
    (:func:`hough_seeds` ``widened``) among the detections not taken by ``tracks`` that score at least
    ``min_score``: a chance track of the clutter gives way to them, and keeps the rest of its detections while at
    least ``min_hits`` (``tracks`` is changed in place, ``used`` updated)."""
    weak = [i for i, tr in enumerate(tracks) if rank(tr) < options.min_score]
    held = used.copy()  # the detections of the tracks that score: they do not vote
    for i in weak:
        held[tracks[i].members] = False
    heap, _ = _candidates(frame, enumerate(hough_seeds(frame, options, widened=True, taken=held)), held, options,
                          rank)
    new = _choose(frame, heap, held, options, rank)
    if not new:
        return []
    by_new = np.zeros(used.size, dtype=bool)
    for tr in new:
        by_new[tr.members] = True
    for i in sorted(weak, reverse=True):
        left = tracks[i].members[~by_new[tracks[i].members]]
        if left.size == tracks[i].members.size:
            continue
        if left.size < options.min_hits:
            del tracks[i]
            continue
        k = np.searchsorted(frame.pings, frame.ping[left])
        tracks[i] = Track(members=left, first=int(k[0]), last=int(k[-1]))
    used |= by_new
    return new


def _candidates(frame: TrackFrame, seeds, used: np.ndarray, options: LineOptions, rank) -> tuple[list, list]:
    """Candidate tracks grown among the detections not ``used`` from the seeds ``(index, seed)``, in order, but
    for those more than half used or of which the used detections and the candidates before them hold more than
    ``SKIP_CLAIMED``: the candidates' heap and the seeds skipped."""
    claimed = used.copy()
    heap, skipped = [], []
    for i, seed in seeds:
        if used[seed].sum() > seed.size // 2 or claimed[seed].mean() > SKIP_CLAIMED:
            skipped.append((i, seed))
            continue
        track = _grow(frame, seed, used, options)
        if track is not None:
            claimed[track.members] = True
        _push(heap, track, i, seed, rank)
    return heap, skipped


def _push(heap: list, track: Track | None, i: int, seed: np.ndarray, rank) -> None:
    """A grown candidate onto the heap, best rank first (``None``: nothing)."""
    if track is not None:
        heapq.heappush(heap, (-rank(track), i, seed, track))


def _choose(frame: TrackFrame, heap: list, used: np.ndarray, options: LineOptions, rank) -> list[Track]:
    """Tracks taken from the candidates' heap until it is empty: the best is kept when none of its detections is
    ``used`` (then marked used); else it grows again from its seed without them (if at most half the seed is
    used)."""
    tracks = []
    while heap:
        _, i, seed, track = heapq.heappop(heap)
        if not used[track.members].any():
            used[track.members] = True
            tracks.append(track)
        elif used[seed].sum() <= seed.size // 2:
            _push(heap, _grow(frame, seed, used, options), i, seed, rank)
    return tracks


def _grow(frame: TrackFrame, seed: np.ndarray, used: np.ndarray, options: LineOptions) -> Track | None:
    """The track a seed grows into among the detections not ``used`` (``None``: under ``min_hits`` pings)."""
    members = _prune(frame, _follow(frame, seed[~used[seed]], used, options), options)
    if members.size < options.min_hits:
        return None
    k = np.searchsorted(frame.pings, frame.ping[members])
    return Track(members=members, first=int(k[0]), last=int(k[-1]))


def hough_seeds(frame: TrackFrame, options: LineOptions, *, widened: bool = False,
                taken: np.ndarray | None = None) -> list[np.ndarray]:
    """Seeds of lines: detection index sets from the windowed Hough transform, most pings first.  ``widened``: the
    cells widened to a crossing line's smear (:func:`_smear_cells`), and only the widened ones that hold more than
    chance seed (:func:`_beyond_chance`); ``taken``: a mask of the detections that do not vote."""
    n_win = max(1, int(options.window_pings))
    step = max(1, n_win // 2)
    seeds = []
    for k0 in range(0, max(1, frame.pings.size - n_win // 2), step):
        k1 = min(frame.pings.size, k0 + n_win)
        sl = slice(int(frame.starts[k0]), int(frame.starts[k1]))
        seeds.extend(_window_seeds(frame, sl, k0, k1, options, widened, taken))
    seeds.sort(key=lambda t: -t[0])
    return [idx for _, idx in seeds]


def _window_seeds(frame: TrackFrame, sl: slice, k0: int, k1: int, options: LineOptions,
                  widened: bool = False, taken: np.ndarray | None = None) -> list:
    """``(distinct pings, detection indices)`` of the Hough cells of one window that reach ``seed_hits``
    (``widened``, ``taken``: :func:`hough_seeds`')."""
    idx = np.arange(sl.start, sl.stop)
    if taken is not None:
        idx = idx[~taken[idx]]
    if idx.size < options.seed_hits:
        return []
    y, b = frame.y[idx], np.nan_to_num(frame.b_post[idx], nan=0.0)
    ping_local = np.searchsorted(frame.pings[k0:k1], frame.ping[idx])
    n_local = k1 - k0
    n_tans, cell_y, width_m = _window_cells(frame, idx, k0, k1, options, widened)
    out = []
    # burial bins of the gate's width, and four times wider for peaks away from nadir whose burial wanders
    grids = [(oy, ob, w) for w in (2 * options.burial_gate_m, 8 * options.burial_gate_m)
             for oy, ob in ((0.0, 0.0), (0.5, 0.0), (0.0, 0.5), (0.5, 0.5))]
    wandering = np.nan_to_num(frame.b_sigma[idx], nan=np.inf) > options.burial_gate_m
    # burials far outside any line of interest (water-column noise, the multiples) vote nowhere: they would
    # only stretch the cell index
    plausible = (b >= -2 * options.max_burial_m) & (b <= 3 * options.max_burial_m)
    for oy, ob, width_b in grids:
        # only the peaks whose burial wanders vote in the wide burial bins (all vote in the fine ones)
        voters = (wandering if width_b > 2 * options.burial_gate_m else np.ones(idx.size, dtype=bool)) & plausible
        if voters.sum() < options.seed_hits:
            continue
        iy = np.floor(cell_y[:, voters] + oy).astype(np.int64)
        ib = np.floor(b[voters] / width_b + ob).astype(np.int64)
        iy -= iy.min()
        ib -= ib.min()
        ny, nb = int(iy.max() + 1), int(ib.max() + 1)
        # one integer per (heading, offset, burial) cell; detections counted first, distinct pings for the few
        cell = (np.arange(n_tans)[:, None] * ny + iy) * nb + ib[None, :]
        counts = np.bincount(cell.ravel())
        full = np.flatnonzero(counts >= options.seed_hits)
        if not full.size:
            continue
        jj, dv = np.nonzero(np.isin(cell, full))
        c, dd = cell[jj, dv], np.flatnonzero(voters)[dv]
        # distinct pings per cell, all cells at once
        pairs = np.unique(c * n_local + ping_local[dd])
        cells, hits = np.unique(pairs // n_local, return_counts=True)
        good = hits >= options.seed_hits
        if widened:
            good[good] = _beyond_chance(cells[good], hits[good], c, width_m[jj, dv], ib, n_local, np.ptp(y[voters]),
                                        nb, options)
        if good.any():
            out.extend(_strongest_cells(cells[good], hits[good], c, idx[dd]))
    return out


def _window_cells(frame: TrackFrame, idx: np.ndarray, k0: int, k1: int, options: LineOptions, widened: bool
                  ) -> tuple:
    """The window's headings' count, and per heading and detection ``idx`` the Hough cells' coordinate across
    (the gate's cells, or widened to a smear: :func:`_smear_cells`) and their widths (m; ``None`` for the gate's)."""
    s, y = frame.s[idx], frame.y[idx]
    s_mid = 0.5 * (frame.ping_s[k0] + frame.ping_s[k1 - 1])
    half = max(0.5 * (frame.ping_s[k1 - 1] - frame.ping_s[k0]), options.across_gate_m)
    # adjacent headings part by 1.5 gates at the window's ends: three quarters of a bin (of the narrowest widened
    # bin, for a smear's)
    t_max = math.tan(math.radians(options.max_angle_deg))
    part = 1.5 * options.across_gate_m * (SMEAR_CELL_MIN if widened else 1.0)
    tans = np.linspace(-t_max, t_max, 2 * int(math.ceil(t_max * half / part)) + 1)
    icpt = y[None, :] - tans[:, None] * (s - s_mid)[None, :]
    if not widened:
        return tans.size, icpt / (2 * options.across_gate_m), None
    return (tans.size, *_smear_cells(icpt, tans, frame.r[idx], y, options))


def _strongest_cells(cells: np.ndarray, hits: np.ndarray, pair_cell: np.ndarray, pair_det: np.ndarray) -> list:
    """``(hits, detection indices)`` of the :data:`MAX_SEEDS_PER_GRID` cells with the most ``hits`` (in dense
    clutter the rest are chance and cost a follow each); ``pair_cell``, ``pair_det``: each vote's cell and
    detection."""
    best = np.argsort(-hits, kind="stable")[:MAX_SEEDS_PER_GRID]
    keep_cells, keep_hits = cells[best], hits[best]
    sel = np.isin(pair_cell, keep_cells)
    c, members = pair_cell[sel], pair_det[sel]
    order = np.argsort(c, kind="stable")
    c, members = c[order], members[order]
    bounds = np.r_[0, np.flatnonzero(np.diff(c)) + 1, c.size]
    by_cell = dict(zip(keep_cells.tolist(), keep_hits.tolist()))
    return [(by_cell[int(c[a])], members[a:b]) for a, b in zip(bounds[:-1], bounds[1:])]


def _smear_cells(icpt: np.ndarray, tans: np.ndarray, r: np.ndarray, y: np.ndarray, options: LineOptions
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The Hough cells' coordinate across (cells one unit wide) of the intercepts ``icpt`` ``(headings, n)`` (m),
    and the cells' widths there (m).

    Cells ``W = 2 across_gate_m`` wide, widened at a heading ``a`` to the
    smear of a line crossing there, ``k sqrt(y^2 + D^2)`` with ``k = beam
    |tan a|`` (the slant range at offset ``y`` from the window's depth ``D``
    below the track, the median of ``sqrt(r^2 - y^2)`` over its detections of
    slant range ``r``), where it reaches :data:`SMEAR_CELL_MIN` ``W``: a rough
    pipe at a heading spreads its echoes over the smear, and one cell holds
    them.  The coordinate is the integral of ``dy`` over the cell's width:
    ``y / W`` out to ``y_c``, where the smear reaches that width, then
    ``y_c / W + (asinh(y / D) - asinh(y_c / D)) / k`` (odd in ``y``).
    """
    width = 2 * options.across_gate_m
    depth = max(float(np.median(np.sqrt(np.maximum(r * r - y * y, 0.0)))) if r.size else 0.0, 1.0)
    k = (math.radians(options.beam_width_deg) * np.abs(tans))[:, None]
    ratio = np.divide(SMEAR_CELL_MIN * width, k, out=np.full(k.shape, np.inf), where=k > 0)
    y_c = np.sqrt(np.maximum(ratio * ratio - depth * depth, 0.0))
    a = np.abs(icpt)
    beyond = np.divide(np.arcsinh(a / depth) - np.arcsinh(np.minimum(y_c, a) / depth), k,
                       out=np.zeros(icpt.shape), where=k > 0)
    smear = np.where(a > y_c, k * np.hypot(icpt, depth), width)
    return np.sign(icpt) * (np.minimum(a, y_c) / width + beyond), smear


def _beyond_chance(cells: np.ndarray, hits: np.ndarray, pair_cell: np.ndarray, pair_width_m: np.ndarray,
                   ib: np.ndarray, n_local: int, span_m: float, nb: int, options: LineOptions) -> np.ndarray:
    """Which Hough cells of ``hits`` distinct pings (of ``n_local``) hold more than chance: a cell widened to a
    smear (:func:`_smear_cells`; a cell of the gate's width is left to the first seeds) when the window's clutter
    would fill as many of its pings with a chance of at most :data:`WIDE_CELL_P`.  Binomial, a ping's chance
    ``1 - exp(-rho w)`` at the density ``rho`` (per m across and ping) of its burial bin's voters (``ib``, spread
    over ``span_m`` m) and its width ``w`` (m: the mean of its detections' ``pair_width_m``, ``pair_cell`` their
    cells).  A wide cell in dense clutter fills by chance: each such seed would cost a follow."""
    from scipy.special import bdtrc

    if not cells.size:
        return np.zeros(0, dtype=bool)
    pos = np.searchsorted(cells, pair_cell)
    inside = (pos < cells.size) & (cells[np.minimum(pos, cells.size - 1)] == pair_cell)
    width = np.bincount(pos[inside], pair_width_m[inside], cells.size) / np.maximum(
        np.bincount(pos[inside], minlength=cells.size), 1)
    wide = width > 2 * options.across_gate_m * (1 + 1e-9)  # widened: at least SMEAR_CELL_MIN gate cells
    rho = np.bincount(ib, minlength=nb)[cells % nb] / (n_local * max(span_m, 1.0))
    p_ping = -np.expm1(-rho * width)
    # P(X >= hits), X ~ Binomial(n_local, p_ping)
    return wide & (bdtrc(hits - 1, n_local, p_ping) <= WIDE_CELL_P)


def _follow(frame: TrackFrame, seed: np.ndarray, used: np.ndarray, options: LineOptions) -> np.ndarray:
    """A track grown from a seed in both directions; its detections, one per ping, in ping order."""
    hits = _best_per_ping(frame, seed)
    for direction in (1, -1):
        hits = _extend(frame, hits, used, options, direction)
    return np.asarray(sorted(hits.values(), key=lambda i: frame.ping[i]), dtype=np.int64)


def _prune(frame: TrackFrame, members: np.ndarray, options: LineOptions) -> np.ndarray:
    """The members that lie within the gates of the whole track: burial within the gate of the track's, offset
    within the gate of its smoothed path without them (a seed's detections join before any gate is applied)."""
    for _ in range(2):
        if members.size < 3:
            return members
        b_hat = burial_estimate(frame.b[members], frame.b_sigma[members])
        ok = burial_ok(frame.b[members], frame.b_sigma[members], b_hat, options)
        s_m = frame.s[members]
        path = local_linear(s_m, frame.y[members], s_m, options.fit_length_m / 2, leave_out=True)
        slope = np.gradient(path, s_m) if np.ptp(s_m) > 0 else 0.0
        gate = across_gate(frame, members, slope, options)
        ok &= np.abs(frame.y[members] - path) <= gate
        if ok.all():
            break
        members = members[ok]
    return members


def _best_per_ping(frame: TrackFrame, idx: np.ndarray) -> dict:
    """One detection per ping of a seed: the one nearest the seed's straight-line fit."""
    s, y = frame.s[idx], frame.y[idx]
    fit = np.polyfit(s - s.mean(), y, 1) if np.ptp(s) > 0 else np.array([0.0, y.mean()])
    resid = np.abs(y - np.polyval(fit, s - s.mean()))
    best = {}
    for i, r in zip(idx, resid):
        k = int(np.searchsorted(frame.pings, frame.ping[i]))
        if k not in best or r < best[k][1]:
            best[k] = (int(i), float(r))
    return {k: v[0] for k, v in best.items()}


def _extend(frame: TrackFrame, hits: dict, used: np.ndarray, options: LineOptions, direction: int) -> dict:
    """Grow a track ping by ping in one direction until ``max_gap_pings`` imaged pings in a row miss."""
    ks = sorted(hits, reverse=direction > 0)
    recent = [hits[q] for q in ks[:options.fit_hits]]  # nearest the growing end first
    k = ks[0]
    misses = 0
    fit = _local_fit(frame, np.asarray(recent), options)  # refitted after each hit only
    while 0 <= k + direction < frame.pings.size and misses <= options.max_gap_pings:
        k += direction
        sl = frame.at(k)
        if sl.start == sl.stop:
            misses += 1
            continue
        icpt, slope, b_hat = fit
        y_hat = icpt + slope * frame.ping_s[k]
        cand = np.arange(sl.start, sl.stop)
        cand = cand[~used[cand]]
        dy = np.abs(frame.y[cand] - y_hat)
        ok = (dy <= across_gate(frame, cand, slope, options)) & burial_ok(frame.b[cand], frame.b_sigma[cand], b_hat,
                                                                            options)
        if ok.any():
            # of several (a steep line's echo smears across the gate) the one nearest their CF-weighted centre
            inside = cand[ok]
            centre = float(np.dot(frame.y[inside], frame.cf[inside]) / frame.cf[inside].sum())
            hits[k] = int(inside[np.argmin(np.abs(frame.y[inside] - centre))])
            recent = [hits[k]] + recent[:options.fit_hits - 1]
            fit = _local_fit(frame, np.asarray(recent), options)
            misses = 0
        else:
            misses += 1
    return hits


def across_gate(frame: TrackFrame, idx: np.ndarray, slope, options: LineOptions) -> np.ndarray:
    """Half-width (m) of the gate across the track for detections ``idx`` of a line of slope ``dy/ds``.

    The gate is across the line: a line at heading ``a`` sweeps ``y``
    ``1/cos(a)`` faster (at most twice the gate); at least twice the
    detection's offset uncertainty; and at least half the smear of a line
    crossing the track, whose echo comes from the stretch of it inside the
    transmit beam: ``r beam |tan a|`` across at slant range ``r``.
    """
    slope = np.abs(np.asarray(slope, dtype=np.float64))
    base = options.across_gate_m * np.minimum(np.hypot(1.0, slope), 2.0)
    return np.maximum(np.maximum(base, 2 * frame.y_sigma[idx]), smear_half_width(frame.r[idx], slope, options))


def smear_half_width(r, slope, options: LineOptions) -> np.ndarray:
    """Half the smear (m) across of a line of slope ``dy/ds`` crossing the track at slant range ``r`` (m; a
    detection's from its grid centre): its echo comes from the stretch of it inside the transmit beam,
    ``r beam |tan a|`` across."""
    return 0.5 * math.radians(options.beam_width_deg) * np.asarray(r) * np.abs(np.asarray(slope, dtype=np.float64))


def burial_ok(b: np.ndarray, sigma: np.ndarray, b_hat: float, options: LineOptions) -> np.ndarray:
    """Whether detections of burials ``b`` (m, NaN: unknown, passes) and standard deviations ``sigma`` (m) lie
    within a line's burial gate about ``b_hat`` (m; NaN: every one does): ``burial_gate_m``, at least twice
    ``sigma``."""
    if not math.isfinite(b_hat):
        return np.ones(b.shape, dtype=bool)
    return ~(np.abs(b - b_hat) > np.maximum(options.burial_gate_m, 2 * sigma))


def _local_fit(frame: TrackFrame, recent: np.ndarray, options: LineOptions) -> tuple:
    """``(intercept, slope, burial)``: a straight line ``y = intercept + slope s`` through the track's
    nearest hits (within ``fit_length_m`` of the newest) and their burial."""
    s, y = frame.s[recent], frame.y[recent]
    near = np.abs(s - s[0]) <= options.fit_length_m
    s, y = s[near], y[near]
    b_hat = burial_estimate(frame.b[recent], frame.b_sigma[recent])
    if s.size < 3:
        return float(y[0]), 0.0, b_hat
    # sums, not means: this runs once a hit, on a few points
    sm, ym = s.sum() / s.size, y.sum() / y.size
    ds = s - sm
    var = float(np.dot(ds, ds))
    if var <= 0:
        return float(ym), 0.0, b_hat
    slope = float(np.dot(ds, y - ym)) / var
    return float(ym - slope * sm), slope, b_hat


def burial_estimate(b: np.ndarray, sigma: np.ndarray) -> float:
    """A line's burial from its detections' (m): the median of those measured best.

    Only the detections whose burial standard deviation is at most twice
    the smallest of them count (near nadir the angle, and so the depth, is
    sharp; near endfire it slides metres along the arc); NaN when none has one.
    """
    ok = np.isfinite(b) & np.isfinite(sigma)
    if not ok.any():
        return math.nan
    b, sigma = b[ok], sigma[ok]
    v = np.sort(b[sigma <= 2 * max(float(sigma.min()), 0.1)])
    return 0.5 * float(v[(v.size - 1) // 2] + v[v.size // 2])  # the median


def line_burial(b: np.ndarray, sigma: np.ndarray, floor_m: float = 0.3) -> tuple[float, float, float]:
    """A line's burial from its detections': ``(estimate, standard error, spread)`` (m).

    The mean weighted by ``1 / sigma^2`` (``sigma`` at least ``floor_m``:
    a peak's depth is never better than a fraction of the pulse), with
    detections more than three of their ``sigma`` from it dropped (up to
    three passes); the weighted standard deviation of the kept burials (the
    line's depth consistency, ``spread``); the standard error from the
    burials' own scatter, ``spread / sqrt(n - 1)`` over the ``n`` kept when
    there are at least :data:`~clbeam.survey.burial.MIN_SCATTER_N` (``1 / sqrt(sum w)`` times the
    Birge ratio ``sqrt(chi^2 / (n - 1))``: the slides' ``sigma`` run 2-3
    times the burials' scatter far from nadir), else ``1 / sqrt(sum w)``.
    All NaN without a measured burial.
    """
    ok = np.isfinite(b) & np.isfinite(sigma)
    if not ok.any():
        return math.nan, math.nan, math.nan
    b, sig = b[ok], np.maximum(sigma[ok], floor_m)
    keep = np.ones(b.size, dtype=bool)
    for _ in range(3):
        w = 1 / sig[keep] ** 2
        mean = float((w * b[keep]).sum() / w.sum())
        new = np.abs(b - mean) <= 3 * sig
        if not new.any() or (new == keep).all():
            break
        keep = new
    w = 1 / sig[keep] ** 2
    mean = float((w * b[keep]).sum() / w.sum())
    spread = float(np.sqrt((w * (b[keep] - mean) ** 2).sum() / w.sum()))
    n = int(keep.sum())
    return mean, spread / math.sqrt(n - 1) if n >= MIN_SCATTER_N else float(1 / np.sqrt(w.sum())), spread


def smooth_path(frame: TrackFrame, track: Track, half_width_m: float) -> np.ndarray:
    """The track's offset at each ping of its extent: a local straight-line fit (tricube weights).

    Parameters
    ----------
    frame : TrackFrame
    track : Track
    half_width_m : float
        Half-width of the weights along the track (m).

    Returns
    -------
    numpy.ndarray
        ``(last - first + 1,)`` cross-track offsets (m) at ``frame.pings[first:last + 1]``.
    """
    s, y = frame.s[track.members], frame.y[track.members]
    return local_linear(s, y, frame.ping_s[track.first:track.last + 1], half_width_m)


def line_path(frame: TrackFrame, track: Track, options: LineOptions, *, reported: bool = False,
              ranked: np.ndarray | None = None) -> np.ndarray:
    """The line's offset at each ping of its extent (m): :func:`smooth_path` of its members, then
    :data:`PATH_PASSES` times a local straight-line fit of every detection inside its gates about that path,
    weighted by CF (a wide smear, :data:`WIDE_SMEAR_M`: :data:`WIDE_SMEAR_PASSES` fits over
    :data:`WIDE_SMEAR_LENGTH` times ``fit_length_m``, weighted by CF times the echo strength).  Across, the gate
    is :func:`across_gate` at the path's slope, narrowed to 2.5 times the members' RMS distance from the path
    (at least ``across_gate_m``) unless they spread over ``SMEARED_SPREAD`` of the smear: a tight line at a
    heading takes in no clutter or neighbour the smear's width away; in burial, :func:`burial_ok` about the
    line's.  A crossing line's echo smears over the stretch of pipe inside
    the transmit beam, several detections a ping across the gate, of which the track holds one; their centre
    is where the pipe crosses.  ``reported``: the path the line reports rather than the one its tracks are
    ranked by (a wide smear from :data:`REPORTED_WIDE_SMEAR_M`, over :data:`REPORTED_WIDE_SMEAR_LENGTH` times
    ``fit_length_m``); ``ranked``: the ranking path, already fitted, returned as it is where the reported one
    would repeat it (a line that is no wide smear by either rule)."""
    half = options.fit_length_m / 2
    path = smooth_path(frame, track, half)
    s_ext = frame.ping_s[track.first:track.last + 1]
    if path.size < 2 or np.ptp(s_ext) <= 0:
        return path
    idx = np.arange(int(frame.starts[track.first]), int(frame.starts[track.last + 1]))
    k = np.searchsorted(frame.pings, frame.ping[idx]) - track.first
    b_hat = burial_estimate(frame.b[track.members], frame.b_sigma[track.members])
    near_burial = burial_ok(frame.b[idx], frame.b_sigma[idx], b_hat, options)
    m = track.members
    km = np.searchsorted(frame.pings, frame.ping[m]) - track.first
    spread = float(np.sqrt(np.mean((frame.y[m] - path[km]) ** 2)))
    smear = float(np.mean(smear_half_width(frame.r[m], np.gradient(path, s_ext)[km], options)))
    # members spread over a good part of the smear: the line is smeared, its gate holds the smear; else a tight
    # line at a heading, whose gate is its members' spread (a neighbour or clutter the smear's width away stays out)
    smeared = spread >= SMEARED_SPREAD * smear
    widest = np.inf if smeared else max(options.across_gate_m, 2.5 * spread)
    wide_m, length = (REPORTED_WIDE_SMEAR_M, REPORTED_WIDE_SMEAR_LENGTH) if reported else (WIDE_SMEAR_M, WIDE_SMEAR_LENGTH)
    wide = smeared and smear >= wide_m
    if reported and ranked is not None and not (smeared and smear >= min(REPORTED_WIDE_SMEAR_M, WIDE_SMEAR_M)):
        return ranked  # a wide smear by neither rule: the same fit
    fit_half = half * length if wide else half
    for _ in range(WIDE_SMEAR_PASSES if wide else PATH_PASSES):
        slope = np.gradient(path, s_ext)
        gate = np.minimum(across_gate(frame, idx, slope[k], options), widest)
        inside = idx[near_burial & (np.abs(frame.y[idx] - path[k]) <= gate)]
        if inside.size < 3:
            break
        # a wide smear's centre is where the beam's main lobe lies: its detections weigh by their echo too
        weights = frame.cf[inside] * (frame.echo[inside] if wide else 1.0)
        path = local_linear(frame.s[inside], frame.y[inside], s_ext, fit_half, weights=weights)
    return path


def local_linear(s: np.ndarray, y: np.ndarray, at: np.ndarray, half_width_m: float, *,
                 leave_out: bool = False, weights: np.ndarray | None = None) -> np.ndarray:
    """Local straight-line fit of ``y(s)`` evaluated at ``at`` (tricube weights of half-width ``half_width_m``,
    times ``weights`` when given; at least the three nearest points weigh in).  ``leave_out``: ``at`` is ``s``
    and each point's own weight is 0 (its leave-one-out prediction, for outliers at the ends of a track)."""
    d = (s[None, :] - at[:, None]) / max(half_width_m, 1e-9)
    w = np.clip(1 - np.abs(d) ** 3, 0, None) ** 3
    if weights is not None:
        w = w * np.asarray(weights, dtype=np.float64)[None, :]
    far = np.abs(d)
    if leave_out:
        np.fill_diagonal(far, np.inf)
    nearest = np.argsort(far, axis=1)[:, :3]
    np.put_along_axis(w, nearest, np.maximum(np.take_along_axis(w, nearest, axis=1), 1e-3), axis=1)
    if leave_out:
        np.fill_diagonal(w, 0.0)
    sw, sd, sy = w.sum(1), (w * d).sum(1), (w * y).sum(1)
    sdd, sdy = (w * d * d).sum(1), (w * d * y).sum(1)
    det = sw * sdd - sd ** 2
    flat = det <= 1e-12 * np.maximum(sw ** 2, 1e-30)
    return np.where(flat, sy / np.maximum(sw, 1e-30), (sdd * sy - sd * sdy) / np.where(flat, 1.0, det))
