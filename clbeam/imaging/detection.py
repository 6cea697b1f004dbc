"""The detection test of a coherence peak: its level above the ping's noise and
the chance that incoherent noise gives its coherence.

**Noise floor.** Where only noise reaches a cell, the coherent sum ``S`` of
``M`` channels of complex Gaussian noise is complex Gaussian, so the
intensity ``|S|^2`` is exponentially distributed about its mean, the noise
floor.  Echoes only add cells above it, so the floor is estimated from the
low tail, which echoes leave alone even when they fill most of the image:
the 10th percentile of the intensity over the cells that have a CF, divided
by ``-ln 0.9`` (the exponential distribution's 10th percentile over its
mean).  The float32 sums carry rounding about 80 dB below the image's
maximum, so the floor is never taken below that (noise-free simulations
otherwise turn every rounding wiggle into a detection).

**Significance.** For such noise the CF of one cell,
``|sum p|^2 / (M sum |p|^2)``, is the squared projection of a random
direction in ``C^M`` on a fixed one: Beta(1, M - 1) distributed, mean
``1/M``, ``P(CF > x) = (1 - x)^(M - 1)``; so ``y = -(M - 1) ln(1 - x)`` is
exactly exponential.  The peaks are picked on the Hann-smoothed CF, a
weighted mean of neighbouring cells along range whose noise is correlated
over the pulse's resolution: the complex noise at two cells a two-way delay
``tau`` apart correlates as ``sinc(B tau)`` for a band ``B``.  A weighted sum
of correlated exponentials is a sum of independent ones weighted by the
eigenvalues of ``W^1/2 R W^1/2`` (``W`` the window, ``R`` that correlation);
its tail comes from the saddlepoint approximation (Lugannani-Rice), applied
to the smoothed CF through the same map ``y(x)`` (exact for one cell).
Checked against simulated noise (32 channels, 2-9 kHz,
``tests/imaging/test_detection.py``): the rates of exceeding the levels
this gives for 0.1 down to 1e-4 are 0.87-1.21 times the nominal, with range
steps above and well below the pulse's resolution.  Apodized (weighted) CF
is given the same distribution, an approximation.

**Clutter contrast.** Above the noise, a ping's image is full of real
echoes: the seabed's and the sub-bottom's scatterers are coherent (CF near
1) and stand tens of dB above the noise floor, and on the simulated Line 1
they are 98 % of the peaks.  A cell-averaging CFAR test tells a target from
that reverberation: the strongest cell about the peak (its echo's, within 10
range resolutions ``c / 2B`` and half a receive beamwidth ``lambda / D``
at the band's centre: a CF peak can sit on its echo's tail) over the mean
of the cells within 100 resolutions and 1.5 beamwidths, less the cross of
the echo's range band and its angle band (a wide band's echo spreads
along its range, the low frequencies' beam being wide, and along its
angle, the pulse's range sidelobes), the *contrast*; for the SBP29 +-1.1 m
and +-2.2 degrees in +-10.7 m and +-6.6 degrees.  Reverberation of fully
developed speckle is exponentially distributed about its local mean, so a
cell exceeds ``T`` times that mean with probability ``exp(-T)``: 12 dB is
``1.3e-7`` per independent cell.  Scatterers that stand out of the seabed
that much are kept: they are targets for this test, whatever made them.
The test applies where the clutter is reverberation, its mean 3 dB or
more above the noise floor; where it is the noise itself, the CF and the
SNR test judge a peak (a weak echo in noise keeps the sensitivity it had).
"""

from __future__ import annotations

import math

import numpy as np

from clbeam.imaging.postprocess import HANN7

#: the quantile of the intensity the noise floor is estimated from, and that quantile of Exp(1)
FLOOR_QUANTILE = 0.10
#: cells the floor's quantile is taken over (a regular subsample of larger images)
FLOOR_SAMPLE_CELLS = 500_000
#: the floor is never below the image maximum by more than this (float32 rounding of the sums, dB)
FLOOR_DYNAMIC_RANGE_DB = 80.0
#: half-sizes of the guard about a peak's echo and of the clutter window about it, in range resolutions
#: ``c / 2B`` and in receive beamwidths ``lambda / D`` at the band's centre (SBP29: 1.1 m and 2.2 degrees,
#: 10.7 m and 6.6 degrees)
CONTRAST_GUARD = (10.0, 0.5)
CONTRAST_WINDOW = (100.0, 1.5)
#: the clutter test applies where the clutter's mean stands this far above the noise floor (dB)
REVERBERATION_MARGIN_DB = 3.0


def contrast_windows(band_hz, array_width_m: float, sound_speed_m_s: float) -> tuple[tuple, tuple]:
    """The clutter window's and the guard's half-sizes (m of range, degree of angle) for a band (Hz), an
    array width (m) and a sound speed (m/s): :data:`CONTRAST_WINDOW` and :data:`CONTRAST_GUARD` in units."""
    lo, hi = (float(b) for b in band_hz)
    resolution_m = sound_speed_m_s / (2 * (hi - lo))
    beam_deg = math.degrees(sound_speed_m_s / (0.5 * (lo + hi)) / array_width_m)
    return tuple((n_r * resolution_m, n_a * beam_deg) for n_r, n_a in (CONTRAST_WINDOW, CONTRAST_GUARD))


def local_contrast(intensity: np.ndarray, ranges_m: np.ndarray, angles_deg: np.ndarray, rows: list, *,
                   window: tuple, guard: tuple) -> tuple[np.ndarray, np.ndarray]:
    """Each row's echo and the clutter around it (module docstring): ``(echo_db, clutter_db)``, ``10 log10``
    of the strongest cell within the guard about the row's cell (its echo: a CF peak can sit on the echo's
    tail, below its maximum; a weak peak beside a stronger echo takes that echo's) and of the mean of the
    window's cells outside the guard's cross (dB re the intensity's unit); the contrast is their difference.

    :func:`contrast_at` of the rows' ``range_m`` and ``angle_deg``.

    Parameters
    ----------
    intensity : numpy.ndarray
        ``(n_angle, n_range)`` intensity of the ping (NaN cells, e.g. outside a seabed band, are left out).
    ranges_m, angles_deg : numpy.ndarray
        The grid's coordinates (m, degree), increasing.
    rows : list of dict
        Peaks with ``range_m`` and ``angle_deg`` (a refined row at its refined point, where the echo is).
    window, guard : tuple of float
        Half-sizes (m of range, degree of angle) of the window and of the guard about the peak's cell.

    Returns
    -------
    tuple of numpy.ndarray
        ``(len(rows),)`` each; the echo NaN where the guard has no finite cell above 0, the clutter NaN where
        the window outside the cross has none (a grid of one angle or one range: the cross is all of it,
        and the test passes every peak).
    """
    return contrast_at(intensity, ranges_m, angles_deg, np.array([row["range_m"] for row in rows], dtype=np.float64),
                       np.array([row["angle_deg"] for row in rows], dtype=np.float64), window=window, guard=guard)


def contrast_at(intensity: np.ndarray, ranges_m: np.ndarray, angles_deg: np.ndarray, range_m: np.ndarray,
                angle_deg: np.ndarray, *, window: tuple, guard: tuple,
                finite: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`local_contrast` of peaks at ``range_m`` (m) and ``angle_deg`` (degree), arrays of one length:
    ``(echo_db, clutter_db)`` (dB re the intensity's unit), each peak at its nearest grid node.

    Many peaks' windows (more cells than :data:`TABLE_CELLS_RATIO` times the band of the image they cover)
    are summed from a summed-area table of that band and their echoes taken from sliding maxima along
    range, a few passes over the band whatever the number of peaks; the clutter then agrees with the
    box-by-box sums to about 1e-10 dB (float64 rounding), and a window the table cannot resolve
    (:data:`TABLE_RELIABLE_FRACTION`) is summed box by box.  Fewer are summed box by box.  ``finite``: that
    the intensity holds no NaN and no +inf, where the caller knows it (``None``: found out).
    """
    x = np.asarray(intensity)
    r, a = np.asarray(ranges_m, dtype=np.float64), np.asarray(angles_deg, dtype=np.float64)
    (wr, wa), (gr, ga) = window, guard
    n = np.size(range_m)
    echo, clutter = np.full(n, np.nan), np.full(n, np.nan)
    if n == 0:
        return echo, clutter
    i, j = _nearest(a, np.asarray(angle_deg, dtype=np.float64)), _nearest(r, np.asarray(range_m, dtype=np.float64))
    # every peak's bounds at once: angle (window, guard) x range (window, guard)
    (aw, ag), (rw, rg) = _bounds(a, i, (wa, ga)), _bounds(r, j, (wr, gr))
    # the window less the cross of the echo's range band and its angle band (inclusion-exclusion)
    boxes = [(aw, rw), (aw, rg), (ag, rw), (ag, rg)]
    total, count, n_g, peak = np.zeros(n), np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64), np.full(n, np.nan)
    alone = np.arange(n)
    a0, a1 = int(min(aw[:, 0].min(), ag[:, 0].min())), int(max(aw[:, 1].max(), ag[:, 1].max()))
    r0, r1 = int(min(rw[:, 0].min(), rg[:, 0].min())), int(max(rw[:, 1].max(), rg[:, 1].max()))
    if np.sum((aw[:, 1] - aw[:, 0]) * (rw[:, 1] - rw[:, 0])) > TABLE_CELLS_RATIO * (a1 - a0) * (r1 - r0):
        band = x[a0:a1, r0:r1]   # the table and the maxima over the band the boxes cover only
        if finite is None:   # no NaN and no +inf (a -inf the table finds itself)
            finite = bool(np.isfinite(band.max()))
        total, count, n_g, reliable = _clutter_from_table(band, [(b_a - a0, b_r - r0) for b_a, b_r in boxes], finite)
        peak = box_maxima(band, ag - a0, rg - r0, finite=finite)
        alone = np.flatnonzero(~reliable)
    for k in alone:  # box by box: few peaks, or a quiet window beside a far brighter echo
        (total_w, n_w), (total_gr, n_gr), (total_ga, n_ga), (total_g, n_g[k], peak[k]) = \
            _box_sums(x, aw[k], ag[k], rw[k], rg[k])
        total[k], count[k] = total_w - total_gr - total_ga + total_g, n_w - n_gr - n_ga + n_g[k]
    has_echo, has_clutter = (n_g > 0) & (peak > 0), (count > 0) & (total > 0)
    echo[has_echo] = 10 * np.log10(peak[has_echo])
    clutter[has_clutter] = 10 * np.log10(total[has_clutter] / count[has_clutter])
    return echo, clutter


#: the peaks' clutter windows come from a summed-area table rather than box by box where they hold more
#: cells than this many times the band of the image they cover (the table costs a few passes over the
#: band; a box, one over its cells and a few dozen microseconds)
TABLE_CELLS_RATIO = 1.0
#: a table's clutter sum stands where it is at least this fraction of the table's values it is made of
#: (their rounding is about 1e-14 of them); a quieter window, beside an echo far brighter (a noise-free
#: image spans 10^20 and more), is summed box by box
TABLE_RELIABLE_FRACTION = 1e-6
#: angle rows per block of the tables' passes
TABLE_BLOCK_ROWS = 64
#: table rows (the corners' angle rows) whose range sums are taken in one call
TABLE_CHUNK_ROWS = 32
#: at most this many angle rows between two corners' rows are added to the running sums one by one (more:
#: a block's sum at a time; NumPy's float64 sum of a few float32 rows costs about three adds)
TABLE_ROW_BY_ROW = 8


def _clutter_from_table(x: np.ndarray, boxes: list, finite: bool) -> tuple:
    """The clutter sums and counts (the first box less the next two plus the last, as in
    :func:`contrast_at`), the last box's counts and whether each sum is reliable
    (:data:`TABLE_RELIABLE_FRACTION`), from a summed-area table of ``x``'s finite cells (``finite``: all are,
    but for -inf cells, which the table shows)."""
    n_r = x.shape[1]
    # the corners (first, first), (first, end), (end, first), (end, end) of every box, flat in the table
    corners = np.concatenate([b_a[:, k] * (n_r + 1) + b_r[:, m] for b_a, b_r in boxes for k in (0, 1) for m in (0, 1)])
    small = corners.size and corners.max() < np.iinfo(np.int32).max   # (int32 sorts faster)
    at, where = np.unique(corners.astype(np.int32) if small else corners, return_inverse=True)
    at = at.astype(np.int64)
    table = _table_at(x, at, finite)
    if finite and not np.isfinite(table).all():   # a box holds a non-finite cell after all: left out
        finite, table = False, _table_at(x, at, False)
    counts = None if finite else np.rint(_table_at(np.isfinite(x), at, True)).astype(np.int64)
    n, sign = len(boxes[0][0]), (1, -1, -1, 1)
    total, scale, count, n_last = np.zeros(n), np.zeros(n), np.zeros(n, dtype=np.int64), None
    for box, ((b_a, b_r), box_sign) in enumerate(zip(boxes, sign)):
        c = where[4 * box * n:4 * (box + 1) * n].reshape(4, n)
        total += box_sign * (table[c[3]] - table[c[1]] - table[c[2]] + table[c[0]])
        scale += np.abs(table[c]).sum(axis=0)
        cells = ((b_a[:, 1] - b_a[:, 0]) * (b_r[:, 1] - b_r[:, 0]) if finite
                 else counts[c[3]] - counts[c[1]] - counts[c[2]] + counts[c[0]])
        count += box_sign * cells
        n_last = cells
    return total, count, n_last, np.abs(total) >= TABLE_RELIABLE_FRACTION * scale


def _table_at(x: np.ndarray, at: np.ndarray, finite: bool) -> np.ndarray:
    """The summed-area table ``T[a, r]`` (the float64 sum of ``x[:a, :r]``, non-finite cells as 0) at the
    sorted flat indices ``at`` of the ``(n_angle + 1, n_range + 1)`` table: running sums of each range over
    the rows, added up along range only at the rows a corner lies on, :data:`TABLE_CHUNK_ROWS` of those
    rows in one call."""
    n_r = x.shape[1]
    width = n_r + 2   # a buffer row: 0, each range's sum over the rows above, 0
    row_of = at // (n_r + 1)
    firsts = np.flatnonzero(np.r_[True, row_of[1:] != row_of[:-1]])   # each corner row's first corner in ``at``
    rows, bounds = row_of[firsts], np.r_[firsts, at.size]
    out = np.empty(at.size)
    buf = np.zeros((min(TABLE_CHUNK_ROWS, rows.size), width))
    columns, done = np.zeros(n_r), 0
    for c0 in range(0, rows.size, TABLE_CHUNK_ROWS):
        chunk, above = rows[c0:c0 + TABLE_CHUNK_ROWS], columns
        for k, row in enumerate(chunk):
            sums = buf[k, 1:-1]
            if finite and done < row <= done + TABLE_ROW_BY_ROW:   # a few rows since the last corner: one by one
                np.add(above, x[done], out=sums)
                for r in range(done + 1, row):
                    np.add(sums, x[r], out=sums)
            else:
                np.copyto(sums, above)
                for b0 in range(done, row, TABLE_BLOCK_ROWS):   # the rows since the last corner, a block at a time
                    block = x[b0:min(b0 + TABLE_BLOCK_ROWS, row)]
                    sums += (block if finite else np.where(np.isfinite(block), block, 0.0)).sum(axis=0, dtype=np.float64)
            done, above = row, sums
        np.copyto(columns, above)
        # T[row, c] = buf[k, :c + 1].sum(): the pieces between a row's corners (from 0) added up along the row
        s, e, m = bounds[c0], bounds[c0 + len(chunk)], np.diff(bounds[c0:c0 + len(chunk) + 1])
        first = bounds[c0:c0 + len(chunk)] - s + np.arange(len(chunk))   # each row's first piece
        ends = np.repeat(np.arange(len(chunk)) * width, m) + (at[s:e] - row_of[s:e] * (n_r + 1)) + 1
        pieces = np.add.reduceat(buf[:len(chunk)].ravel(),
                                 np.insert(ends, bounds[c0:c0 + len(chunk)] - s, np.arange(len(chunk)) * width))
        k_of = np.repeat(np.arange(len(chunk)), m + 1)
        place = np.arange(pieces.size) - first[k_of]
        padded = np.zeros((len(chunk), int(m.max()) + 1))
        padded[k_of, place] = pieces
        np.cumsum(padded, axis=1, out=padded)
        corner = place < m[k_of]   # a row's last piece runs past its last corner
        out[s:e] = padded[k_of[corner], place[corner]]
    return out


def box_maxima(x: np.ndarray, box_a: np.ndarray, box_r: np.ndarray, *, finite: bool | None = None) -> np.ndarray:
    """The largest finite cell of each box (angle rows ``box_a[k, 0]:box_a[k, 1]``, ranges
    ``box_r[k, 0]:box_r[k, 1]`` of ``x``; NaN where it has none), every box at once.

    The boxes of the commonest width (on a regular grid, all but those the image's edges clip) take the
    maxima of that many ranges from their first columns, a block of rows at a time (a few passes over the
    rows they cover), and then the largest over their rows; the others a sparse table of maxima over 2^k
    ranges (:func:`_sparse_box_maxima`).  Maxima are exact in any precision: the values are ``x``'s own.

    Parameters
    ----------
    x : numpy.ndarray
        ``(n_angle, n_range)`` values.
    box_a, box_r : numpy.ndarray
        ``(n, 2)`` first and end angle, and range, index of each box.
    finite : bool, optional
        Whether ``x`` holds no NaN and no +inf (-inf cells are values below any other; ``None``: found out).
    """
    box_a, box_r = np.asarray(box_a, dtype=np.int64), np.asarray(box_r, dtype=np.int64)
    width = box_r[:, 1] - box_r[:, 0]
    height = np.where(width > 0, np.maximum(box_a[:, 1] - box_a[:, 0], 0), 0)
    peak = np.full(len(box_a), np.nan)
    some = np.flatnonzero(height > 0)
    if some.size == 0:
        return peak
    common = int(np.bincount(width[some]).argmax())
    sliding = some[width[some] == common]
    rest = some[width[some] != common]
    if finite is None:
        finite = bool(np.isfinite(x.max())) if x.size else True   # no NaN, no +inf (a -inf is a value here)
    if sliding.size:
        peak[sliding] = _sliding_box_maxima(x, box_a[sliding], box_r[sliding, 0], common, finite)
    if rest.size > BOX_BY_BOX_MAXIMA:
        peak[rest] = _sparse_box_maxima(x, box_a[rest], box_r[rest])
    for k in rest if rest.size <= BOX_BY_BOX_MAXIMA else ():   # a few boxes (the edges'): each on its own
        box = x[box_a[k, 0]:box_a[k, 1], box_r[k, 0]:box_r[k, 1]]
        box = box if finite else box[np.isfinite(box)]
        peak[k] = box.max() if box.size else np.nan
    return peak


#: at most this many boxes of other widths than the commonest are each looked at on their own
BOX_BY_BOX_MAXIMA = 256


def _sliding_box_maxima(x: np.ndarray, box_a: np.ndarray, first: np.ndarray, width: int, finite: bool) -> np.ndarray:
    """:func:`box_maxima` of boxes of one ``width`` of ranges from the columns ``first`` (at least one row
    each), :data:`MAXIMA_GROUP_ROWS` of their first rows at a time: the maximum of ``width`` ranges from
    every column on the rows those boxes cover (the rows the previous group's boxes share kept), then each
    box's largest over its rows (NaN where none is finite)."""
    n_a, n_r = x.shape
    order = np.argsort(box_a[:, 0], kind="stable")   # the boxes by first row: a group is a slice of them
    starts, heights, first = box_a[order, 0], box_a[order, 1] - box_a[order, 0], first[order]
    tallest = int(heights.max())
    along = np.empty((MAXIMA_GROUP_ROWS + tallest - 1, n_r - width + 1), dtype=np.result_type(x.dtype, np.float32))
    # each box's rows from its first (a shorter box repeats its last row), as offsets into ``along``
    row_steps = np.minimum(np.arange(tallest), heights[:, None] - 1).astype(np.intp) * along.shape[1]
    peak = np.full(len(box_a), -np.inf, dtype=along.dtype)
    scratch = np.empty((2, MAXIMA_BLOCK_ROWS, n_r), dtype=along.dtype)
    have = (0, 0)   # the rows whose maxima ``along`` holds, from its first row
    for g0 in range(int(starts[0]), int(box_a[:, 1].max()), MAXIMA_GROUP_ROWS):
        i0, i1 = np.searchsorted(starts, [g0, g0 + MAXIMA_GROUP_ROWS])
        if i0 == i1:
            continue
        g1 = min(g0 + MAXIMA_GROUP_ROWS + tallest - 1, n_a)
        kept = max(0, have[1] - g0) if have[0] <= g0 else 0
        along[:kept] = along[g0 - have[0]:g0 - have[0] + kept]
        _sliding_maxima(x, g0 + kept, g1, width, finite, along[kept:g1 - g0], scratch)
        have = (g0, g1)
        at = row_steps[i0:i1] + ((starts[i0:i1] - g0) * along.shape[1] + first[i0:i1])[:, None]
        peak[i0:i1] = np.take(along, at).max(axis=1)
    peak = np.where(peak > -np.inf, peak.astype(np.float64), np.nan)
    out = np.empty_like(peak)
    out[order] = peak
    return out


#: boxes whose first rows lie within this many angle rows take their maxima together
MAXIMA_GROUP_ROWS = 256
#: angle rows per block of the sliding maxima's passes (blocks in a CPU's cache)
MAXIMA_BLOCK_ROWS = 16


def _sliding_maxima(x: np.ndarray, a0: int, a1: int, width: int, finite: bool, out: np.ndarray,
                    bufs: np.ndarray) -> None:
    """``out[a - a0, c]``: the largest of ``x[a, c:c + width]`` (non-finite cells as -inf unless ``finite``),
    for the rows ``a0:a1``, a block at a time (``bufs``: ``(2, MAXIMA_BLOCK_ROWS, n_range)`` scratch): the
    maximum of 2^k ranges by halves, then of two overlapping such spans."""
    n_r = x.shape[1]
    span = 1 << (width.bit_length() - 1)   # the largest power of 2 not above the width
    for b0 in range(a0, a1, MAXIMA_BLOCK_ROWS):
        b1 = min(b0 + MAXIMA_BLOCK_ROWS, a1)
        cur = x[b0:b1] if finite else np.where(np.isfinite(x[b0:b1]), x[b0:b1], -np.inf).astype(out.dtype, copy=False)
        valid, s, k = n_r, 1, 0
        while s < span:   # cur[:, c]: the maximum of s ranges from c (c < valid)
            nxt = bufs[k, :b1 - b0, :valid - s]
            np.maximum(cur[:, :valid - s], cur[:, s:valid], out=nxt)
            cur, valid, s, k = nxt, valid - s, 2 * s, 1 - k
        np.maximum(cur[:, :n_r - width + 1], cur[:, width - span:width - span + n_r - width + 1],
                   out=out[b0 - a0:b1 - a0])


def _sparse_box_maxima(x: np.ndarray, box_a: np.ndarray, box_r: np.ndarray) -> np.ndarray:
    """:func:`box_maxima` of boxes of any widths: a block of rows at a time holds a sparse table of maxima
    over 2^k ranges; a box row's maximum is then that of two of its entries, whatever the box's width."""
    n_a, n_r = x.shape
    width = box_r[:, 1] - box_r[:, 0]
    height = np.where(width > 0, np.maximum(box_a[:, 1] - box_a[:, 0], 0), 0)
    level = np.floor(np.log2(np.maximum(width, 1))).astype(np.int64)
    peak = np.full(len(box_a), -np.inf)
    by_first = np.argsort(box_a[:, 0], kind="stable")
    firsts = box_a[by_first, 0]
    tallest, top = int(height.max(initial=0)), int(level.max(initial=0))
    table = np.empty((top + 1, TABLE_BLOCK_ROWS, n_r), dtype=np.result_type(x.dtype, np.float32))
    for b0 in range(0, n_a, TABLE_BLOCK_ROWS):
        b1 = min(b0 + TABLE_BLOCK_ROWS, n_a)
        near = by_first[np.searchsorted(firsts, b0 - tallest):np.searchsorted(firsts, b1)]
        near = near[(height[near] > 0) & (box_a[near, 1] > b0)]
        if near.size == 0:
            continue
        t = table[:, :b1 - b0]
        np.copyto(t[0], x[b0:b1])
        t[0][~np.isfinite(t[0])] = -np.inf
        for k in range(1, top + 1):   # t[k][:, c]: the maximum of the 2^k ranges from c
            span = 1 << (k - 1)
            np.maximum(t[k - 1][:, :-span], t[k - 1][:, span:], out=t[k][:, :-span])
        rows = box_a[near, 0, None] + np.arange(tallest)                        # the box's rows ...
        inside = (rows >= b0) & (rows < b1) & (rows < box_a[near, 1, None])      # ... within this block
        r = np.clip(rows - b0, 0, b1 - b0 - 1)
        lv, lo, hi = level[near, None], box_r[near, 0, None], (box_r[near, 1] - (1 << level[near]))[:, None]
        values = np.where(inside, np.maximum(t[lv, r, lo], t[lv, r, hi]), -np.inf)
        peak[near] = np.maximum(peak[near], values.max(axis=1))
    return np.where(peak > -np.inf, peak, np.nan)


def _nearest(axis: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Index of the node of the increasing ``axis`` nearest each value (the first of two equally near)."""
    if axis.size < 2:   # one node: the nearest of every value
        return np.zeros(np.shape(values), dtype=np.int64)
    hi = np.clip(np.searchsorted(axis, values), 1, axis.size - 1)
    lo = hi - 1
    pick_hi = np.abs(axis[hi] - values) < np.abs(values - axis[lo])
    return np.where(pick_hi, hi, lo)


def _bounds(axis: np.ndarray, k: np.ndarray, halves: tuple) -> list[np.ndarray]:
    """Per half-size (units of ``axis``), the ``(n, 2)`` index bounds of the nodes within it of nodes ``k``
    (exact on uneven axes; a millionth of a step of slack)."""
    slack = 1e-6 * (float(axis[-1] - axis[0]) / max(axis.size - 1, 1))
    nodes = axis if k.size > axis.size else axis[k]   # more nodes asked for than the axis has: every node's, taken
    bounds = [np.stack([np.searchsorted(axis, nodes - h - slack, side="left"),
                        np.searchsorted(axis, nodes + h + slack, side="right")], axis=1) for h in halves]
    return [b[k] for b in bounds] if k.size > axis.size else bounds


def _box_sums(x: np.ndarray, aw, ag, rw, rg) -> tuple:
    """Sum and count of the finite cells of the boxes (angle window x range window), (window x guard range),
    (guard angle x window), and of the guard box with its largest cell, from one slice covering them all."""
    a0, a1 = min(aw[0], ag[0]), max(aw[1], ag[1])
    r0, r1 = min(rw[0], rg[0]), max(rw[1], rg[1])
    cover = x[a0:a1, r0:r1]
    finite = math.isfinite(float(cover.sum(dtype=np.float64)))
    if not finite:  # NaN cells (outside a seabed band) or infinities: masked sums
        ok = np.isfinite(cover)
        cover = np.where(ok, cover, 0.0)
    out = []
    for (b0, b1), (c0, c1) in ((aw, rw), (aw, rg), (ag, rw), (ag, rg)):
        box = cover[b0 - a0:b1 - a0, c0 - r0:c1 - r0]
        count = box.size if finite else int(ok[b0 - a0:b1 - a0, c0 - r0:c1 - r0].sum())
        out.append((float(box.sum(dtype=np.float64)), count))
    g = cover[ag[0] - a0:ag[1] - a0, rg[0] - r0:rg[1] - r0]
    if finite:
        peak = float(g.max()) if g.size else math.nan
    else:
        gok = ok[ag[0] - a0:ag[1] - a0, rg[0] - r0:rg[1] - r0]
        peak = float(g[gok].max()) if gok.any() else math.nan
    out[3] = (*out[3], peak)
    return tuple(out)


def noise_floor(intensity: np.ndarray, cf: np.ndarray | None = None, *, maximum: float | None = None) -> float:
    """Mean intensity of the ping's incoherent noise (units of the intensity), from the low tail.

    Parameters
    ----------
    intensity : numpy.ndarray
        ``|S|^2`` of the ping's cells.
    cf : numpy.ndarray, optional
        The CF: only cells with a CF (enough channels) count; without it, cells with intensity > 0.
    maximum : float, optional
        The intensity's largest value but NaN (``numpy.nanmax``) where the caller has it (one pass less).
    """
    x = np.asarray(intensity).ravel()
    # a regular subsample of about half a million cells: the quantile to a fraction of a per cent, 20x faster
    stride = max(1, x.size // FLOOR_SAMPLE_CELLS)
    sample = x[::stride].copy()   # one strided pass, then contiguous ones
    use = np.isfinite(sample) & ((sample > 0) if cf is None else (np.asarray(cf).ravel()[::stride] > 0))
    if not np.any(use):
        return math.nan
    floor = quantile(sample[use], FLOOR_QUANTILE) / -math.log1p(-FLOOR_QUANTILE)
    top = float(np.nanmax(x)) if maximum is None else float(maximum)
    return max(floor, top * 10 ** (-FLOOR_DYNAMIC_RANGE_DB / 10))


def quantile(values: np.ndarray, q: float) -> float:
    """``numpy.quantile(values, q)`` (its default, linear interpolation between the order statistics about
    ``(n - 1) q``) of finite ``values`` from one selection and a minimum: NumPy selects four order statistics
    (the first and last too, for NaNs), several times the cost; the interpolation is NumPy's own, on the two
    values it would interpolate."""
    v = np.asarray(values).ravel()
    position = (v.size - 1) * q
    k = int(math.floor(position))
    part = np.partition(v, k)
    after = part[k + 1:].min() if k + 1 < v.size else part[k]
    return float(np.quantile(np.array([part[k], after], dtype=v.dtype), position - k))


def smoothing_variance_factor(range_step_m: float, bandwidth_hz: float, sound_speed_m_s: float,
                              weights: np.ndarray = HANN7) -> float:
    """``sum_k sum_l w_k w_l sinc^2(2 B (k - l) dr / c)``: the noise variance of the smoothed CF over
    that of one cell (1 for one weight; ``sum w^2`` for cells far apart; 1 for cells much closer than
    the pulse's resolution ``c / 2B``)."""
    w = np.asarray(weights, dtype=np.float64)
    lag = np.arange(w.size)[:, None] - np.arange(w.size)[None, :]
    rho = np.sinc(2.0 * bandwidth_hz * lag * range_step_m / sound_speed_m_s) ** 2
    return float(w @ rho @ w)


def smoothing_eigenvalues(range_step_m: float, bandwidth_hz: float, sound_speed_m_s: float,
                          weights: np.ndarray = HANN7) -> np.ndarray:
    """Eigenvalues of ``W^1/2 R W^1/2``, ``R_kl = sinc(2 B (k - l) dr / c)``: the weights of the
    independent exponentials the smoothed CF of noise is a sum of (they add up to the window's sum, 1)."""
    w = np.asarray(weights, dtype=np.float64)
    w = w[w > 0]
    lag = np.arange(w.size)[:, None] - np.arange(w.size)[None, :]
    r = np.sinc(2.0 * bandwidth_hz * lag * range_step_m / sound_speed_m_s)
    lam = np.linalg.eigvalsh(np.sqrt(w)[:, None] * r * np.sqrt(w)[None, :])
    return lam[lam > 1e-12 * lam.max()]


def exponential_sum_sf(y: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """``P(sum lam_i E_i > y)``, ``E_i`` independent Exp(1), for every value of ``y``: the
    Lugannani-Rice saddlepoint approximation, all values at once.

    The saddlepoint solves ``K'(s) = sum lam / (1 - lam s) = y``; ``K'`` increases and is convex below
    ``1 / max lam``, so Newton's steps from a point above the root (where the largest term alone is ``y``)
    decrease onto it, quadratically near it, until rounding stops them (float64's resolution: what a
    bisection to the end gives, to an ulp or two).
    """
    from scipy.special import ndtr

    y = np.asarray(y, dtype=np.float64)
    mean, var, top = float(lam.sum()), float(np.sum(lam * lam)), 1.0 / float(lam.max())
    yy = np.where(np.isfinite(y) & (y > 0), y, mean)
    col = np.asarray(lam, dtype=np.float64).reshape((-1,) + (1,) * yy.ndim)   # the eigenvalues along a first axis
    s = top - 1.0 / yy   # K'(s) >= y here: its largest term alone is y
    for _ in range(SADDLEPOINT_MAX_STEPS):
        r = col / (1.0 - col * s)
        with np.errstate(invalid="ignore", divide="ignore"):   # 0/0 far below the mean: NaN, no step
            step = (r.sum(axis=0) - yy) / np.sum(r * r, axis=0)
            lower = s - step
        down = lower < s
        if not down.any():   # every one at its root: a further step would not lower it
            break
        s = np.where(down, lower, s)
    k = -np.sum(np.log1p(-col * s), axis=0)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        w = np.sign(s) * np.sqrt(np.maximum(2.0 * (s * yy - k), 0.0))
        u = s * np.sqrt(np.sum(col**2 / (1.0 - col * s) ** 2, axis=0))
        p = ndtr(-w) + np.exp(-0.5 * w * w) / math.sqrt(2 * math.pi) * (1.0 / u - 1.0 / w)
    # at the mean the two terms cancel: their limit, 1/2 - k3 / (6 sqrt(2 pi) k2^1.5) (k2, k3 the cumulants)
    near_mean = np.abs(yy - mean) < 1e-4 * mean
    p = np.where(near_mean, 0.5 - 2.0 * float(np.sum(lam**3)) / (6.0 * math.sqrt(2 * math.pi) * var**1.5), p)
    # far into either tail the saddlepoint's terms underflow (y under about 1e-154 of the mean): the limit there
    p = np.where(np.isfinite(p), p, np.where(yy < mean, 1.0, 0.0))
    p = np.where(np.isfinite(y) & (y > 0), np.clip(p, 0.0, 1.0), np.where(y > 0, 0.0, 1.0))
    return p


#: Newton's steps onto the saddlepoint at most (they converge in well under 20 from any start)
SADDLEPOINT_MAX_STEPS = 100


def false_alarm_probability(cf_smooth, n_channels, eigenvalues: np.ndarray):
    """Probability (per cell) that incoherent noise over ``n_channels`` gives a smoothed CF of at
    least ``cf_smooth`` (NaN below 2 channels); ``eigenvalues`` from :func:`smoothing_eigenvalues`."""
    m = float(n_channels)
    x = np.clip(np.asarray(cf_smooth, dtype=np.float64), 0.0, 1.0)
    if not m >= 2:
        return np.full(x.shape, np.nan)[()]
    with np.errstate(divide="ignore"):
        y = -(m - 1.0) * np.log1p(-x)
    return exponential_sum_sf(y, eigenvalues)[()]


def equivalent_threshold(n_channels, eigenvalues: np.ndarray, probability: float) -> float:
    """The smoothed-CF level incoherent noise over ``n_channels`` exceeds with ``probability``."""
    from scipy.optimize import brentq

    return float(brentq(lambda x: float(false_alarm_probability(x, n_channels, eigenvalues)) - probability,
                        1e-9, 1.0 - 1e-12))


def annotate_and_gate(rows: list, *, floor: float, n_channels: int | None, eigenvalues: np.ndarray,
                      min_snr_db: float | None, contrast=None, min_contrast_db: float | None = None) -> list:
    """Each row with ``snr_db`` (its intensity over the noise floor), ``contrast_db`` (its echo over the
    clutter around it, ``contrast = (echo_db, clutter_db)`` from :func:`local_contrast`; NaN when not given)
    and ``pfa`` (the false-alarm probability of its smoothed CF over ``n_channels``, NaN when unknown); rows
    kept as :func:`gate_peaks` keeps them, updated in place and returned."""
    echo, clutter = (None, None) if contrast is None else contrast
    keep, snr, contrast_db, pfa = gate_peaks(np.array([row["intensity_db"] for row in rows], dtype=np.float64),
                                             np.array([row["cf"] for row in rows], dtype=np.float64), floor=floor,
                                             echo_db=echo, clutter_db=clutter, n_channels=n_channels,
                                             eigenvalues=eigenvalues, min_snr_db=min_snr_db,
                                             min_contrast_db=min_contrast_db)
    kept = [rows[k] for k in keep.tolist()]
    for row, s, c, p in zip(kept, snr.tolist(), contrast_db.tolist(), pfa.tolist()):
        row.update(snr_db=s, contrast_db=c, pfa=p)   # in place: the rows are the caller's own
    return kept


def gate_peaks(level_db: np.ndarray, cf_smooth: np.ndarray, *, floor: float, echo_db=None, clutter_db=None,
               n_channels: int | None, eigenvalues: np.ndarray, min_snr_db: float | None,
               min_contrast_db: float | None = None) -> tuple:
    """The detection test of peaks given as arrays of one length: their intensities ``level_db`` (dB) over
    the noise ``floor`` (intensity units; the SNR), their echoes ``echo_db`` over the clutter ``clutter_db``
    about them (dB, :func:`contrast_at`; ``None``: NaN, unknown) and their smoothed CFs' false-alarm
    probabilities over ``n_channels`` (NaN when unknown; ``eigenvalues`` from :func:`smoothing_eigenvalues`).
    Peaks below ``min_snr_db`` are left out, and peaks below ``min_contrast_db`` where the clutter stands
    :data:`REVERBERATION_MARGIN_DB` or more above the noise floor (where it does not, the clutter is the
    noise, which the CF and the SNR test already judge; ``None``: no test; a NaN value passes).

    Returns
    -------
    tuple of numpy.ndarray
        ``(keep, snr_db, contrast_db, pfa)``: the kept peaks' indices (increasing) and their SNR (dB),
        contrast (dB) and false-alarm probability.
    """
    level = np.asarray(level_db, dtype=np.float64)
    floor_db = 10 * math.log10(floor) if floor > 0 and math.isfinite(floor) else math.nan
    snr = level - floor_db if math.isfinite(floor_db) else np.full(level.shape, np.nan)
    nan = np.full(level.shape, np.nan)
    echo, clutter = (nan if v is None else np.asarray(v, dtype=np.float64) for v in (echo_db, clutter_db))
    contrast = echo - clutter
    keep = np.flatnonzero(snr_tests_pass(snr, min_snr_db) & clutter_tests_pass(contrast, clutter - floor_db,
                                                                               min_contrast_db))
    if n_channels and keep.size:  # every peak's probability in one call
        pfa = np.atleast_1d(false_alarm_probability(np.asarray(cf_smooth, dtype=np.float64)[keep], n_channels,
                                                    eigenvalues))
    else:
        pfa = np.full(keep.size, np.nan)
    return keep, snr[keep], contrast[keep], pfa


def snr_db(rows: list, floor: float) -> list:
    """Each row's ``intensity_db`` over the noise ``floor`` (intensity units), dB; NaN where the floor is not
    positive and finite."""
    floor_db = 10 * math.log10(floor) if floor > 0 and math.isfinite(floor) else math.nan
    return [row["intensity_db"] - floor_db if math.isfinite(floor_db) else math.nan for row in rows]


def snr_test_passes(snr: float, min_snr_db: float | None) -> bool:
    """The SNR test of :func:`annotate_and_gate`: passed at ``min_snr_db`` or more, by NaN and by ``None``."""
    return bool(snr_tests_pass(np.float64(snr), min_snr_db))


def snr_tests_pass(snr: np.ndarray, min_snr_db: float | None) -> np.ndarray:
    """:func:`snr_test_passes` of every value of ``snr`` (dB) at once."""
    snr = np.asarray(snr, dtype=np.float64)
    return np.ones(snr.shape, dtype=bool) if min_snr_db is None else np.isnan(snr) | (snr >= min_snr_db)


def clutter_test_passes(contrast_db: float, clutter_over_floor_db: float, min_contrast_db: float | None) -> bool:
    """The clutter test of a peak: passed at ``min_contrast_db`` or more, or where the clutter stands less than
    :data:`REVERBERATION_MARGIN_DB` above the noise floor (it is the noise); NaN contrasts and ``None`` pass,
    a NaN clutter level (no floor) counts as reverberation."""
    return bool(clutter_tests_pass(np.float64(contrast_db), np.float64(clutter_over_floor_db), min_contrast_db))


def clutter_tests_pass(contrast_db: np.ndarray, clutter_over_floor_db: np.ndarray,
                       min_contrast_db: float | None) -> np.ndarray:
    """:func:`clutter_test_passes` of every peak at once (dB, arrays of one shape)."""
    c, over = np.asarray(contrast_db, dtype=np.float64), np.asarray(clutter_over_floor_db, dtype=np.float64)
    if min_contrast_db is None:
        return np.ones(c.shape, dtype=bool)
    return np.isnan(c) | (c >= min_contrast_db) | (over < REVERBERATION_MARGIN_DB)   # a NaN clutter: reverberation
