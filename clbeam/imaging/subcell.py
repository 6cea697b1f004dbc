"""Sub-cell coherence peaks: each peak moved to its echo's intensity maximum on the exact sums.

A coherence peak of the grid sits on a node: its range is off by up to half
a range step (the 2-9 kHz pulse's envelope, about 0.1 m, is narrower than
the paper's 0.2 m cells), and where CF is flat across a lobe the node with
the largest smoothed CF can lie part of a beam width along the arc, or down
the pulse's tail, from the echo.  Refinement evaluates the delay-and-sum
itself at points around each peak (the imager's engine, each point a cell
with its own travel-time table entry):

0. on the grid: the cell of largest intensity along the peak's range row
   within its coherent lobe (the run of cells whose smoothed CF stays above
   the threshold, at most 16 cells either side), because with a long
   compressed pulse CF stays high down its tails;
1. along range at the peak's angle, +-2 range steps around that cell every
   1/4 step (half the envelope's width on the paper's grid: the nodes sample
   the envelope so coarsely that the most intense one can sit on a
   sidelobe 1.5 steps from the echo);
2. along the echo's equal-delay curve through that point, +-half the
   array's beam width at the band top (at least +-2 angle steps), 9 points:
   the grid's arc of constant range only when the source and the array sit
   at the grid centre; heave and roll move them off it, and far from nadir,
   where the beam is flat, a search along the arc then slides by tenths of a
   degree (:class:`~clbeam.imaging.equal_delay.EqualDelay`; through a sound-speed
   profile the curve follows the travel-time tables,
   :class:`~clbeam.imaging.equal_delay.TableEqualDelay`).  Where the best point is the window's edge
   the intensity still rises there (the cell sat on the shoulder of the
   echo's main lobe, as a long pipe's far echo leaves CF peaks a beam width
   from its maximum): the window moves to it, up to four windows, so that
   the peak reaches the maximum and merges with the echo's other cells
   instead of standing as a second echo beside it;
3. a 3 x 3 patch around the best point at half those steps (its range
   offsets along equal-delay curves), and a parabola through the logarithms
   of the best point and its neighbours on each axis (exact for a Gaussian
   peak), or of the patch's middle three where the best point is on its
   edge (the echo lies within a search step of the patch's middle; far from
   nadir, where the beam is flat, noise often makes an edge the best point);
4. a parabola along the equal-delay curve through three points a quarter of
   the patch's step apart: over the patch's span a noisy flat lobe is not a
   parabola, and its vertex was a few hundredths of a degree off;
5. at the refined point and +-1, +-2 range steps: intensity, CF, and the
   7-point Hann-smoothed CF of the grid's range step there.

The range search (1) interpolates the samples with the cubic (its
intensity errors, about -35 dB, move the envelope's sharp maximum by well
under a millimetre); the rest with Lanczos-8 (-70 dB; or "exact" when the
ping is imaged with it), because the beam's lobe is so flat along the arc
(0.4 dB over 1 degree at 45 degrees) that Lanczos-4's -45 dB ripple moves
its maximum by 0.015 degree, a seventh of a 0.1 degree cell.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError
from clbeam.imaging.engine.common import BeamformInput, InterpMode, Sums, interp_mode
from clbeam.imaging.engine.points import bilinear_tables, point_grid, point_tables, straight_ray_values
from clbeam.imaging.equal_delay import equal_delay_curve
from clbeam.imaging.postprocess import HANN7
from clbeam.model.grid import PolarGrid

#: range searched either side of the cell, in range steps, and the search's step in range steps
RANGE_SEARCH_STEPS = 2.0
RANGE_SEARCH_STEP = 1.0 / 4.0
#: angle searched either side of the cell, in beam widths at the band top (at least 2 angle steps)
ANGLE_SEARCH_BEAMS = 0.5
ANGLE_SEARCH_POINTS = 9
#: windows searched along the curve at most, each moved to the last's edge while the intensity still rises there
ARC_SEARCH_ROUNDS = 4
#: interpolation of the search along range, and of the rest (unless the ping is imaged with "exact")
SEARCH_MODE = interp_mode("cubic")
ARC_MODE = interp_mode("lanczos8")
#: how far (dB) the searches after the range search may climb above its maximum, beyond ``1 / threshold``: along its
#: equal-delay curve one echo's channels hold the same envelope samples, so its coherent sum there is at most
#: ``M Q`` where a peak above the CF threshold holds about ``threshold M Q``; the smoothing and overlapping echoes
#: took the climb to 13.7 dB (6 dB for ``1 / threshold``) on the zoo's noise-free scenes (:func:`refine_peaks`)
SEARCH_CLIMB_MARGIN_DB = 20.0
#: cells either side of a peak searched on the grid for its lobe's intensity maximum
LOBE_MAX_CELLS = 16
#: the final patch: points per axis and its step as a fraction of the search's
PATCH_POINTS = 3
PATCH_STEP = 0.5
#: the last parabola along the arc: its step as a fraction of the patch's
POLISH_STEP = 0.25


@dataclass(frozen=True)
class RefinedPeaks:
    """Refined peaks, one entry per input peak (arrays of shape ``(n_peaks,)``).

    Attributes
    ----------
    range_m, angle_deg : numpy.ndarray
        Position of the intensity maximum from the grid centre (m, degree).
    cf_smooth : numpy.ndarray
        7-point Hann-smoothed CF along range (the grid's range step) at that point.
    cf : numpy.ndarray
        CF at that point (unsmoothed).
    intensity : numpy.ndarray
        ``|S|^2`` at that point (input units squared).
    cell : numpy.ndarray
        ``(n_peaks, 2)`` (angle index, range index) of the grid peak refined.
    n_cells : numpy.ndarray
        Grid peaks each entry stands for (:func:`merge_refined`).
    """

    range_m: np.ndarray
    angle_deg: np.ndarray
    cf_smooth: np.ndarray
    cf: np.ndarray
    intensity: np.ndarray
    cell: np.ndarray
    n_cells: np.ndarray

    def take(self, index: np.ndarray, n_cells: np.ndarray | None = None) -> "RefinedPeaks":
        """The entries ``index`` (with new counts ``n_cells``)."""
        return RefinedPeaks(self.range_m[index], self.angle_deg[index], self.cf_smooth[index], self.cf[index],
                            self.intensity[index], self.cell[index],
                            self.n_cells[index] if n_cells is None else np.asarray(n_cells))


def subcell_peaks(engine, inp: BeamformInput, grid: PolarGrid, peaks: np.ndarray, mode: InterpMode, *,
                  cf_smooth: np.ndarray, intensity: np.ndarray | None, threshold: float,
                  least_intensity: float = 0.0) -> RefinedPeaks:
    """Peaks refined (:func:`refine_peaks`, those that cannot reach ``least_intensity`` left out) and one
    entry kept per echo, its most intense refinement (:func:`merge_refined`: within half a range step (at
    least a quarter of the pulse's range resolution) and a quarter of the band top's beam width), by
    decreasing refined CF."""
    refined = refine_peaks(engine, inp, grid, peaks, mode, cf_smooth=cf_smooth, intensity=intensity, threshold=threshold,
                           least_intensity=least_intensity)
    if refined.range_m.size == 0:
        return refined
    # half a range step, or a quarter of the pulse's range resolution c / 2B on grids finer than it
    resolution_m = inp.sound_speed_m_s / (2.0 * (inp.band_hz[1] - inp.band_hz[0])) if inp.band_hz else 0.0
    r_tol = np.maximum(0.5 * _local_step(grid.ranges_m, refined.cell[:, 1]), 0.25 * resolution_m)
    a_tol = np.rad2deg(0.25 * beam_width_rad(inp) / np.maximum(np.cos(np.deg2rad(refined.angle_deg)), 0.1))
    # the most intense refinement of an echo stands for it: two searches from different cells of one echo can
    # end apart along its flat far beam, and the echo's maximum is the more intense end
    order = np.argsort(-refined.intensity, kind="stable")
    merged = merge_refined(refined.take(order), r_tol[order], a_tol[order])
    return merged.take(np.argsort(-merged.cf_smooth, kind="stable"))


def beam_width_rad(inp: BeamformInput) -> float:
    """Beam width ``lambda_top / D`` in direction sine at the band top (``D`` the array's across-track extent)."""
    offsets = np.asarray(inp.element_offsets_m, dtype=np.float64)
    extent = float(np.ptp(offsets[:, 1])) if len(offsets) > 1 else 0.0
    wavelength = inp.sound_speed_m_s / max(inp.top_frequency_hz, 1.0)
    return wavelength / extent if extent > 0 else np.pi


def refine_peaks(engine, inp: BeamformInput, grid: PolarGrid, peaks: np.ndarray, mode: InterpMode, *,
                 cf_smooth: np.ndarray | None = None, intensity: np.ndarray | None = None,
                 threshold: float = 0.25, least_intensity: float = 0.0) -> RefinedPeaks:
    """Refine coherence peaks of ``grid`` to the intensity maximum of their echo (with ``least_intensity``, those
    that cannot reach it left out: :func:`_reaching`).

    Parameters
    ----------
    engine : Engine
        The engine that evaluates the sums at the points (the imager's).
    inp : BeamformInput
        The ping's analytic channels as the engine imaged them (tables through ``inp.table_source``).
    grid : PolarGrid
        The image grid.
    peaks : numpy.ndarray
        ``(n_peaks, 2)`` (angle index, range index) of the peaks.
    mode : InterpMode
        Interpolation of the samples (the ping's setting).
    cf_smooth, intensity : numpy.ndarray, optional
        The grid's smoothed CF and intensity: with both, each search starts at
        the most intense cell of the peak's coherent lobe along range.
    threshold : float
        The peaks' CF threshold (bounds the lobe and the climb).
    least_intensity : float
        Intensity (input units squared) the SNR test needs (0: every peak refined).
    """
    peaks = np.asarray(peaks, dtype=np.int64).reshape(-1, 2)
    ia, ir = peaks[:, 0], peaks[:, 1]
    if cf_smooth is not None and intensity is not None:
        ir = lobe_maximum(cf_smooth, intensity, ia, ir, threshold)
    climb = search_climb(threshold)
    if least_intensity > 0 and intensity is not None and cf_smooth is not None:
        # the lobe's most intense node, raised by the most an echo can stand above its nodes, then the climb
        peaks, ia, ir = _reaching(intensity[ia, ir] * node_gain(inp, grid) * climb, least_intensity, peaks, ia, ir)
    if len(peaks) == 0:
        return _no_peaks()
    evaluate = _Evaluator(engine, inp, grid, SEARCH_MODE)
    r0, a0, dr, da, r_step, r1, level = _range_search(evaluate, grid, ia, ir)   # 1. along range at the cell's angle
    if least_intensity > 0:
        peaks, r0, a0, r1, dr, da, r_step = _reaching(level * climb, least_intensity, peaks, r0, a0, r1, dr, da, r_step)
    if len(peaks) == 0:
        return _no_peaks()
    # the beam's lobe is flat along the arc: a -45 dB interpolation ripple would move its maximum
    evaluate.mode = mode if mode.name == "exact" else ARC_MODE
    # 2. along the echo's equal-delay curve through that point (the grid's arc when the array sits at the centre)
    along = equal_delay_curve(inp, evaluate.tables, grid)
    half = np.maximum(np.rad2deg(ANGLE_SEARCH_BEAMS * beam_width_rad(inp) / np.maximum(np.cos(np.deg2rad(a0)), 0.1)),
                      2 * da)
    a_step = half * 2.0 / (ANGLE_SEARCH_POINTS - 1)
    r1, a1 = _arc_search(evaluate, along, r1, a0, half, (grid.angles_deg.min(), grid.angles_deg.max()))
    # 3. a patch around it, its range offsets along equal-delay curves, and a parabola on each axis
    r2, a2 = _patch_peak(evaluate, along, r1, a1, PATCH_STEP * r_step, PATCH_STEP * a_step)
    r2, a2 = _arc_polish(evaluate, along, r2, a2, POLISH_STEP * PATCH_STEP * a_step)
    # 4. the refined point and the smoothed CF's range taps
    taps = np.arange(HANN7.size) - HANN7.size // 2
    used = HANN7 > 0
    final = evaluate(r2[:, None] + taps[used] * dr[:, None], np.broadcast_to(a2[:, None], (len(a2), int(used.sum()))))
    centre = int(np.flatnonzero(taps[used] == 0)[0])
    return RefinedPeaks(range_m=r2, angle_deg=a2, cf_smooth=final.cf @ HANN7[used], cf=final.cf[:, centre],
                        intensity=final.intensity[:, centre], cell=peaks, n_cells=np.ones(len(peaks), dtype=np.int64))


def _range_search(evaluate, grid: PolarGrid, ia: np.ndarray, ir: np.ndarray) -> tuple:
    """The cells' range and angle, the grid's steps there, the search's range step, and the range and intensity
    of the most intense of the points ``RANGE_SEARCH_STEPS`` either side along range at the cell's angle."""
    r0, a0 = grid.ranges_m[ir], grid.angles_deg[ia]
    dr, da = _local_step(grid.ranges_m, ir), _local_step(grid.angles_deg, ia)
    r_step = RANGE_SEARCH_STEP * dr
    k = np.arange(-RANGE_SEARCH_STEPS / RANGE_SEARCH_STEP, RANGE_SEARCH_STEPS / RANGE_SEARCH_STEP + 1)
    r1, _, level = _best(evaluate, r0[:, None] + k * r_step[:, None], np.broadcast_to(a0[:, None], (len(a0), k.size)))
    return r0, a0, dr, da, r_step, r1, level


def _reaching(bound: np.ndarray, least_intensity: float, *columns: np.ndarray) -> tuple:
    """The ``columns`` of the peaks whose intensity ``bound`` reaches ``least_intensity``: a noise-free ping holds
    tens of thousands of maxima above the CF threshold on its rounding, a hundred dB under its echoes, which the
    SNR test drops after the refinement; the searches leave them out first (the result has fewer entries)."""
    live = np.flatnonzero(~(bound < least_intensity))
    return tuple(c[live] for c in columns)


def search_climb(threshold: float) -> float:
    """The most (a factor) the searches along the arc may raise a peak's intensity above its range search's:
    ``1 / threshold`` (a CF threshold in 0-1) and ``SEARCH_CLIMB_MARGIN_DB``."""
    return 10 ** ((10 * np.log10(1 / min(max(threshold, 1e-3), 1.0)) + SEARCH_CLIMB_MARGIN_DB) / 10)


def node_gain(inp: BeamformInput, grid: PolarGrid) -> float:
    """The most (a factor >= 1) an echo's intensity maximum can stand above the most intense of the grid nodes
    within two range steps of it along range: the compressed pulse's envelope ``sinc(2 B r / c)`` (a flat band
    ``B`` wide, the matched filter's output for the LFM) sampled every range step at the worst offset;
    infinite without a band (nothing bounds it) or on a grid of one range."""
    band = inp.band_hz
    if band is None or grid.shape[1] < 2 or not band[1] > band[0]:
        return np.inf
    step = float(np.max(np.diff(grid.ranges_m)))
    scaled = 2.0 * (band[1] - band[0]) * step / inp.sound_speed_m_s     # one range step in the envelope's units
    offsets = np.linspace(0.0, 0.5, 257)[:, None] + np.arange(-2, 3)[None, :]     # the echo from its nodes
    nearest = np.max(np.sinc(offsets * scaled) ** 2, axis=1)
    return float(1.0 / max(np.min(nearest), 1e-30))


def _no_peaks() -> RefinedPeaks:
    """No refined peak."""
    empty = np.zeros(0)
    return RefinedPeaks(empty, empty, empty, empty, empty, np.zeros((0, 2), dtype=np.int64), np.zeros(0, dtype=np.int64))


def lobe_maximum(cf_smooth: np.ndarray, intensity: np.ndarray, ia: np.ndarray, ir: np.ndarray,
                 threshold: float, max_cells: int = LOBE_MAX_CELLS) -> np.ndarray:
    """Range index of the most intense cell in each peak's run of smoothed CF above
    ``threshold`` along its range row (at most ``max_cells`` either side)."""
    n_r = cf_smooth.shape[1]
    k = np.arange(-max_cells, max_cells + 1)
    cols = ir[:, None] + k[None, :]
    inside = (cols >= 0) & (cols < n_r)
    cc = np.clip(cols, 0, n_r - 1)
    above = inside & (cf_smooth[ia[:, None], cc] > threshold)
    above[:, max_cells] = True
    # the run through the peak: cells reached from it without crossing one at or below the threshold
    right = np.cumprod(above[:, max_cells:], axis=1).astype(bool)
    left = np.cumprod(above[:, max_cells::-1], axis=1).astype(bool)[:, ::-1]
    run = np.concatenate([left[:, :-1], right], axis=1)
    level = np.where(run, intensity[ia[:, None], cc], -np.inf)
    return cc[np.arange(len(ir)), np.argmax(level, axis=1)]


def merge_refined(refined: RefinedPeaks, range_tol_m: np.ndarray | float,
                  angle_tol_deg: np.ndarray | float) -> RefinedPeaks:
    """One entry per echo: refined peaks closer than the tolerances (m, degree) to an
    earlier one in the given order (:func:`subcell_peaks` gives them by decreasing refined
    intensity) are merged into it; ``n_cells`` counts the grid peaks each kept entry stands for.

    In order, an entry not yet merged is kept and takes every later entry within its tolerances not yet
    merged.  The pairs within tolerance come from a grid of buckets the size of the largest tolerances, and
    the entries are settled in rounds: kept when every earlier entry that would take it is merged, merged
    into the first kept one that takes it (rounds as many as the longest chain of entries taking the next)."""
    n = refined.range_m.size
    r_tol = np.broadcast_to(np.asarray(range_tol_m, dtype=np.float64), (n,))
    a_tol = np.broadcast_to(np.asarray(angle_tol_deg, dtype=np.float64), (n,))
    src, dst = _pairs_within(refined.range_m, refined.angle_deg, r_tol, a_tol)
    kept = np.zeros(n, dtype=bool)
    settled = np.zeros(n, dtype=bool)
    owner = np.arange(n)
    while not settled.all():
        # an entry is taken by a kept earlier one, or kept when all earlier ones that would take it are merged
        taken = np.zeros(n, dtype=bool)
        taken[dst[kept[src]]] = True
        waiting = np.zeros(n, dtype=bool)
        waiting[dst[~settled[src]]] = True
        newly_kept = ~settled & ~taken & ~waiting
        kept |= newly_kept
        settled |= newly_kept | (taken & ~settled)
    by_kept = kept[src]
    first = np.full(n, n)
    np.minimum.at(first, dst[by_kept], src[by_kept])
    owner = np.where(kept, owner, first)
    index = np.flatnonzero(kept)
    return refined.take(index, np.bincount(owner, weights=refined.n_cells, minlength=n)[index].astype(np.int64))


def _pairs_within(range_m: np.ndarray, angle_deg: np.ndarray, r_tol: np.ndarray,
                  a_tol: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pairs ``(i, j)``, ``i < j``, with ``j`` within ``i``'s tolerances (strictly), from buckets of the
    largest tolerances (each entry's neighbours in its own and the 8 buckets about it)."""
    n = range_m.size
    if n < 2:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    size_r, size_a = max(float(r_tol.max()), 1e-12), max(float(a_tol.max()), 1e-12)
    # a non-finite position's bucket is 0: the exact test below never finds it near another
    br = np.nan_to_num(np.floor((range_m - np.nanmin(range_m)) / size_r), nan=0, posinf=0, neginf=0).astype(np.int64)
    ba = np.nan_to_num(np.floor((angle_deg - np.nanmin(angle_deg)) / size_a), nan=0, posinf=0, neginf=0).astype(np.int64)
    width = int(ba.max()) + 3
    key = (br + 1) * width + (ba + 1)
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    src, dst = [], []
    for dr in (-1, 0, 1):
        for da in (-1, 0, 1):
            want = key + dr * width + da
            lo, hi = np.searchsorted(sorted_key, want, "left"), np.searchsorted(sorted_key, want, "right")
            count = hi - lo
            i = np.repeat(np.arange(n), count)
            j = order[np.repeat(lo - np.cumsum(count) + count, count) + np.arange(count.sum())]
            src.append(i)
            dst.append(j)
    i, j = np.concatenate(src), np.concatenate(dst)
    near = (i < j) & (np.abs(range_m[j] - range_m[i]) < r_tol[i]) & (np.abs(angle_deg[j] - angle_deg[i]) < a_tol[i])
    return i[near], j[near]


def _local_step(axis: np.ndarray, index: np.ndarray) -> np.ndarray:
    """The grid's spacing around ``index`` (its one step for a single-node axis)."""
    if axis.size < 2:
        return np.ones(index.shape)
    return np.gradient(axis)[index]


def _best(evaluate, ranges_m: np.ndarray, angles_deg: np.ndarray):
    """Range, angle and intensity of each row's largest intensity."""
    values = evaluate(ranges_m, angles_deg).intensity
    k = np.argmax(values, axis=1)
    rows = np.arange(len(k))
    return ranges_m[rows, k], angles_deg[rows, k], values[rows, k]


def _arc_search(evaluate, along, r1, a0, half, bounds):
    """Range and angle of the most intense of ``ANGLE_SEARCH_POINTS`` points within ``+-half`` (degree) of each
    ``a0`` along the equal-delay curves ``along`` through ``(r1, a0)``; where that point is on the window's edge
    and inside the grid's angle ``bounds`` the window moves to it and searches again, within the bounds (up to
    ``ARC_SEARCH_ROUNDS`` windows)."""
    j = np.linspace(-1.0, 1.0, ANGLE_SEARCH_POINTS)
    r, a = np.array(r1, dtype=np.float64), np.array(a0, dtype=np.float64)
    todo = np.arange(r.size)
    for round_ in range(ARC_SEARCH_ROUNDS):
        arc_a = a[todo, None] + j * half[todo, None]
        if round_:  # a moved window stays inside the grid; the first may reach past its edge, to an echo beyond it
            arc_a = np.clip(arc_a, *bounds)
        arc_r = along(r[todo, None], a[todo, None], arc_a)
        k = np.argmax(evaluate(arc_r, arc_a).intensity, axis=1)
        rows = np.arange(todo.size)
        r[todo], a[todo] = arc_r[rows, k], arc_a[rows, k]
        # the intensity still rises at the edge: the cell sat on the shoulder of a stronger echo along the curve
        # (its maximum, or another lobe's), which the window must reach for the two to merge as one echo
        on_edge = ((k == 0) | (k == j.size - 1)) & (arc_a[rows, k] > bounds[0]) & (arc_a[rows, k] < bounds[1])
        todo = todo[on_edge]
        if todo.size == 0:
            break
    return r, a


def _patch_peak(evaluate, along, r1, a1, step_r, step_a):
    """Range and angle of each point's maximum on a patch about ``(r1, a1)`` (its range offsets along the
    equal-delay curves ``along``), moved by a parabola on each axis."""
    p = np.arange(PATCH_POINTS) - PATCH_POINTS // 2
    rho = r1[:, None, None] + p[None, :, None] * step_r[:, None, None]   # ranges at a1
    aa = a1[:, None, None] + p[None, None, :] * step_a[:, None, None]
    rho, aa = np.broadcast_arrays(rho, aa)
    values = evaluate(along(rho, a1[:, None, None], aa), aa).intensity
    rho2, a2 = _parabolic_peak(values, rho, aa, step_r, step_a)
    return along(rho2, a1, a2), a2


def _arc_polish(evaluate, along, r, a, step_a):
    """``(r, a)`` moved along their equal-delay curves by a parabola through three points ``step_a`` apart
    (degree) about them (at most one step): the patch's parabola spans a flat lobe whose shape, where noise
    or clutter adds to the echo, is not a parabola's, and leaves its maximum a few hundredths of a degree
    off (a quarter of the step: a sixteenth of that error)."""
    aa = a[:, None] + np.array([-1.0, 0.0, 1.0]) * step_a[:, None]
    values = evaluate(along(np.broadcast_to(r[:, None], aa.shape), a[:, None], aa), aa).intensity
    d = _log_parabola_shift(values[:, 0], values[:, 1], values[:, 2])
    # not concave (the three rise one way): the best of them
    d = np.where(np.isfinite(d), d, np.argmax(values, axis=1) - 1.0)
    a2 = a + d * step_a
    return along(r, a, a2), a2


def _log_parabola_shift(lo, mid, hi):
    """Vertex of the parabola through the logarithms of three equally spaced values, in steps from the middle
    (at most one; NaN where it is not concave): exact for a Gaussian peak, close for the envelope and the beam."""
    with np.errstate(invalid="ignore", divide="ignore"):
        lo, mid, hi = np.log(lo), np.log(mid), np.log(hi)
        den = lo - 2 * mid + hi
        d = np.where(den < 0, 0.5 * (lo - hi) / den, np.nan)
    return np.clip(d, -1.0, 1.0)


def _parabolic_peak(values, rr, aa, step_r, step_a):
    """The maximum of each ``(n, P, P)`` patch moved by a parabola along each axis through the three points
    about it along its row and column (where it lies on the patch's edge, the three nearest that edge: the
    middle three of a 3-point patch), at most one step from their middle.

    Where the maximum lies on the patch's edge the echo's peak lies between it and the middle (the search's
    window puts it within a step of the middle): far from nadir the beam is so flat along the arc that a
    patch half a search step wide often has its maximum on an edge, and a peak left there stands up to a
    quarter of a search step (0.25 degree at 70 degrees, 2.7 m of depth at 640 m) off its echo."""
    n, pts = values.shape[0], values.shape[1]
    flat = np.argmax(values.reshape(n, -1), axis=1)
    i, j = np.divmod(flat, pts)
    rows = np.arange(n)
    ic, jc = np.clip(i, 1, pts - 2), np.clip(j, 1, pts - 2)
    di = _log_parabola_shift(values[rows, ic - 1, j], values[rows, ic, j], values[rows, ic + 1, j])
    dj = _log_parabola_shift(values[rows, i, jc - 1], values[rows, i, jc], values[rows, i, jc + 1])
    r = np.where(np.isfinite(di), rr[rows, ic, j] + np.nan_to_num(di) * step_r, rr[rows, i, j])
    a = np.where(np.isfinite(dj), aa[rows, i, jc] + np.nan_to_num(dj) * step_a, aa[rows, i, j])
    return r, a


class _Evaluator:
    """Intensity and CF at points: the engine's delay-and-sum with per-point travel-time tables
    (a point's two-way time from the centre, its ray's direction and wavefront radius: straight rays,
    or the grid's ray-traced tables interpolated to it), on a grid of one range and one angle per point."""

    def __init__(self, engine, inp: BeamformInput, grid: PolarGrid, mode: InterpMode):
        self.engine, self.grid, self.mode = engine, grid, mode
        self.tables = inp.table_source(grid) if inp.table_source is not None else inp.tables
        # one data token: the engine uploads the channels once for every stage of the search
        self.inp = dataclasses.replace(inp, table_source=None, tables=None, data_token=inp.data_token or object())

    def __call__(self, ranges_m: np.ndarray, angles_deg: np.ndarray, outputs=("intensity", "cf")) -> Sums:
        # in order of range: neighbouring points read neighbouring samples of each channel (a refinement's points
        # in the peaks' order took 1.4-1.5x as long on a CPU, each peak's samples fetched anew from memory)
        r = np.asarray(ranges_m, dtype=np.float64).ravel()
        order = np.argsort(r, kind="stable")
        r = r[order]
        a = np.broadcast_to(np.asarray(angles_deg, dtype=np.float64), np.shape(ranges_m)).ravel()[order]
        points = point_grid(r.size)
        tables = _point_tables(self.tables, self.grid, r, a, self.inp.sound_speed_m_s, points)
        sums = self.engine.beamform(dataclasses.replace(self.inp, tables=tables), points, interp=self.mode.name,
                                    outputs=outputs)
        shape = np.shape(ranges_m)

        def unsorted(v):
            out = np.empty_like(v)
            out[order] = v
            return out.reshape(shape)

        return Sums(**{k: None if v is None else unsorted(v.reshape(-1)) for k, v in vars(sums).items()
                       if k != "timings_s"})


def sums_at_points(engine, inp: BeamformInput, ranges_m: np.ndarray, angles_deg: np.ndarray, *,
                   interp: str = "linear", grid: PolarGrid | None = None,
                   outputs=("intensity", "cf")) -> Sums:
    """The delay-and-sum at arbitrary points, each a cell with its own travel-time table entry.

    Parameters
    ----------
    engine : Engine
        Either backend.
    inp : BeamformInput
        The ping's channels; with ray-traced tables (``inp.table_source`` or
        ``inp.tables``) those of ``grid`` are interpolated to the points.
    ranges_m, angles_deg : numpy.ndarray
        The points' range (m) and angle (degree) from the grid centre, any same shape.
    interp : str
        Interpolation mode.
    grid : PolarGrid, optional
        The grid whose tables apply (needed only with tables).
    outputs : iterable of str
        As :meth:`Engine.beamform`.
    """
    has_tables = inp.table_source is not None or inp.tables is not None
    if has_tables and grid is None:
        raise OptionError("sums at points with ray-traced travel times need the grid whose tables apply")
    return _Evaluator(engine, inp, grid, interp_mode(interp))(ranges_m, angles_deg, outputs)


def _point_tables(tables, grid: PolarGrid, ranges_m: np.ndarray, angles_deg: np.ndarray, sound_speed_m_s: float,
                  points: PolarGrid):
    """Travel-time tables of the points (one per angle of ``points``): straight rays at
    ``sound_speed_m_s``, or ``tables`` of ``grid`` interpolated bilinearly."""
    if tables is None:
        return point_tables(straight_ray_values(ranges_m, angles_deg, sound_speed_m_s), sound_speed_m_s, 0.0, points)
    return point_tables(bilinear_tables(tables, grid, ranges_m, angles_deg), tables.centre_speed_m_s,
                        tables.centre_depth_m, points)
