"""Hann smoothing of the coherence factor and coherence-peak picking
(Holland et al. 2024, Section III)."""

from __future__ import annotations

import functools
import os
from concurrent.futures import ThreadPoolExecutor
from itertools import repeat

import numpy as np

from clbeam.constants import PEAK_THRESHOLD
from clbeam.errors import OptionError, require
from clbeam.model.geodesy import geodesic_direct
from clbeam.model.grid import window_cells

#: cells per block of rows at least, and threads at most, of a large image's smoothing
SMOOTHING_BLOCK_CELLS = 1 << 20
MAX_SMOOTHING_THREADS = 8

#: 7-point Hann window of the paper, normalised to sum 1
HANN7 = np.array([0.0, 0.25, 0.75, 1.0, 0.75, 0.25, 0.0]) / 3.0



def hann_smooth(cf: np.ndarray, weights: np.ndarray = HANN7) -> np.ndarray:
    """Smooth CF along the range axis (last axis) with the 7-point Hann window.

    Cells beyond the grid count as zero (MATLAB ``conv(..., 'same')``), so the
    smoothed CF stays within [0, 1] wherever CF does.  A large image is done in
    blocks of rows on every CPU (the same values: each row's arithmetic is
    unchanged).

    Parameters
    ----------
    cf : numpy.ndarray
        Coherence factor ``(..., n_range)``.
    weights : numpy.ndarray
        Odd-length window along range, summing to 1.
    """
    x = np.asarray(cf)
    x = x if x.dtype in (np.float32, np.float64) else x.astype(np.float64)
    w = np.asarray(weights, dtype=x.dtype)
    if x.size == 0:
        return x.copy()
    rows = x.reshape(-1, x.shape[-1])
    out = np.empty(rows.shape, dtype=x.dtype)  # C order whatever the input's, so that the blocks are views
    blocks = min(len(os.sched_getaffinity(0)), MAX_SMOOTHING_THREADS, max(1, x.size // SMOOTHING_BLOCK_CELLS),
                 len(rows))
    if blocks <= 1:
        _smooth_rows(rows, w, out)
        return out.reshape(x.shape)
    edges = np.linspace(0, len(rows), blocks + 1).astype(int)
    # NumPy's ufuncs release the GIL: the blocks run in parallel
    with ThreadPoolExecutor(max_workers=blocks) as pool:
        list(pool.map(lambda k: _smooth_rows(rows[edges[k]:edges[k + 1]], w, out[edges[k]:edges[k + 1]]),
                      range(blocks)))
    return out.reshape(x.shape)


def _smooth_rows(x: np.ndarray, w: np.ndarray, out: np.ndarray) -> None:
    """:func:`hann_smooth` of the rows of ``x`` (2-D) into ``out``."""
    h = w.size // 2
    n = x.shape[-1]
    # shifted adds (a zero-padded correlation; the window is symmetric, so a
    # convolution) skipping zero taps: much faster than a general filter
    np.multiply(x, w[h], out=out)
    tmp = np.empty_like(out)  # one scratch array: a temporary per product costs more than the adds
    for k in range(1, h + 1):
        if w[h + k] == 0 and w[h - k] == 0:
            continue
        if k < n:
            part = tmp[..., : n - k]
            np.multiply(x[..., k:], w[h + k], out=part)
            out[..., :-k] += part
            np.multiply(x[..., :-k], w[h - k], out=part)
            out[..., k:] += part


def hann_smooth_in_windows(cf: np.ndarray, windows: np.ndarray, weights: np.ndarray = HANN7) -> np.ndarray:
    """:func:`hann_smooth` of a CF that is 0 outside a window of range cells per angle (a seabed band),
    computed on the windows' cells only: the same values, bit for bit, at a fraction of the cost (the
    grid's other cells are 0 and never touched).

    Parameters
    ----------
    cf : numpy.ndarray
        ``(n_angle, n_range)`` coherence factor, 0 outside the windows.
    windows : numpy.ndarray
        ``(n_angle, 2)`` first and end range index of each angle's window.
    weights : numpy.ndarray
        Odd-length window along range, summing to 1.
    """
    x = np.asarray(cf)
    x = x if x.dtype in (np.float32, np.float64) else x.astype(np.float64)
    n_a, n = x.shape
    h = np.asarray(weights).size // 2
    # the cells whose smoothed value can differ from 0, packed row after row with h zeros either side
    lo = np.clip(np.asarray(windows[:, 0], dtype=np.int64) - h, 0, n)
    hi = np.clip(np.asarray(windows[:, 1], dtype=np.int64) + h, lo, n)
    src, dst = window_cells(lo, hi - lo, n, pad=h)
    packed = np.zeros((1, src.size + 2 * h * n_a), dtype=x.dtype)
    packed[0, dst] = x.reshape(-1)[src]
    out = np.zeros(x.shape, dtype=x.dtype)  # calloc: the pages outside the band are never written (zeros_like fills them)
    out.reshape(-1)[src] = hann_smooth(packed, weights)[0, dst]
    return out


def coherence_peaks(cf_smooth: np.ndarray, threshold: float = PEAK_THRESHOLD) -> np.ndarray:
    """Coherence peaks: regional maxima of the smoothed CF above a threshold.

    Regional maxima follow MATLAB ``imregionalmax`` (8-connectivity): a
    connected plateau of equal values strictly above all its neighbours is
    one maximum, reported once at its member nearest the plateau's centroid
    (the first in raster order of equally near ones).  The search runs over
    the whole image at once (a 3 x 3 maximum filter); only the cells it finds
    not below any neighbour are looked at one by one, so its cost does not
    grow with the number of maxima.

    Parameters
    ----------
    cf_smooth : numpy.ndarray
        ``(n_angle, n_range)`` smoothed coherence factor.
    threshold : float
        Keep maxima with CF strictly above this value (0–1).

    Returns
    -------
    numpy.ndarray
        ``(n_peaks, 2)`` int array of ``(angle index, range index)``, ordered
        by decreasing CF, equal CFs in the raster order of their plateaus'
        first cells.
    """
    require(0.0 <= threshold <= 1.0, OptionError, f"threshold must be within 0-1, got {threshold!r}")
    img = np.asarray(cf_smooth)
    img = img if img.dtype in (np.float32, np.float64) else img.astype(np.float64)
    require(img.ndim == 2, OptionError, f"coherence peaks need a 2-D (angle, range) image, got shape {img.shape}")
    if img.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    flat = _cells_above(img, threshold, int(SPARSE_ABOVE_FRACTION * img.size))
    if flat is not None:  # few cells to look at: each one's neighbours
        not_below, tied = _neighbour_tests(img, flat)
        flat, tied = flat[not_below], tied[not_below]
    else:
        flat = np.flatnonzero(_above_and_not_below_neighbours(img, threshold))
        tied = _neighbour_tests(img, flat)[1]
    cells, first = flat[~tied], flat[~tied]
    if tied.any():  # plateaus: one cell each, where every member is not below any neighbour
        top = np.zeros(img.shape, dtype=bool)
        top.ravel()[flat] = True
        plateau_cells, plateau_first = _plateau_maxima(img, top, flat[tied])
        cells, first = np.concatenate([cells, plateau_cells]), np.concatenate([first, plateau_first])
    order = np.lexsort((first, -img.ravel()[cells]))
    return np.stack(np.divmod(cells[order], img.shape[1]), axis=1).astype(np.int64)


#: the 8 neighbours' (angle, range) offsets
_NEIGHBOURS = [(da, dr) for da in (-1, 0, 1) for dr in (-1, 0, 1) if da or dr]


#: at most this fraction of the image above the threshold, its cells are compared with their neighbours one
#: by one (8 look-ups a cell); more, and the whole image goes through the maximum filter (a few passes)
SPARSE_ABOVE_FRACTION = 1 / 16
#: angle rows per block of the maximum filter (blocks that stay in the CPU's cache: 3-4x faster than whole passes)
MAXIMUM_FILTER_BLOCK_ROWS = 32


def _above_and_not_below_neighbours(img: np.ndarray, threshold: float) -> np.ndarray:
    """Cells above ``threshold`` equal to the maximum of their 3 x 3 neighbourhood (cells beyond the image
    left out; a NaN cell or neighbour: False), block of rows by block of rows."""
    n_a, n_r = img.shape
    out = np.empty(img.shape, dtype=bool)
    rows = MAXIMUM_FILTER_BLOCK_ROWS
    along = np.empty((rows + 2, n_r), dtype=img.dtype)   # the maximum of three along range, a row either side
    block = np.empty((rows, n_r), dtype=img.dtype)
    for a0 in range(0, n_a, rows):
        a1 = min(a0 + rows, n_a)
        lo, hi = max(a0 - 1, 0), min(a1 + 1, n_a)
        near = _max_of_three_along_range(img[lo:hi], along[:hi - lo])
        k, c = a1 - a0, a0 - lo   # rows of the block, and its first row's in ``near``
        m = block[:k]
        np.copyto(m, near[c:c + k])
        np.maximum(m[1 - c:], near[:k - 1 + c], out=m[1 - c:])              # the row before (none at the top)
        below = near[c + 1:c + 1 + k]
        np.maximum(m[:below.shape[0]], below, out=m[:below.shape[0]])       # the row after (none at the bottom)
        np.equal(m, img[a0:a1], out=out[a0:a1])
        out[a0:a1] &= img[a0:a1] > threshold
    return out


def _max_of_three_along_range(x: np.ndarray, out: np.ndarray) -> np.ndarray:
    """``out``: the maximum of each cell of ``x`` and its two neighbours along range (one at the ends)."""
    if x.shape[1] < 2:
        np.copyto(out, x)
        return out
    np.maximum(x[:, :-1], x[:, 1:], out=out[:, :-1])   # with the next
    out[:, -1] = x[:, -1]
    np.maximum(out[:, 1:], x[:, :-1], out=out[:, 1:])  # with the previous
    return out


def _cells_above(img: np.ndarray, threshold: float, most: int) -> np.ndarray | None:
    """Flat indices of the cells above ``threshold`` (increasing), a block of rows at a time (the comparison
    stays in the CPU's cache); ``None`` once there are more than ``most``."""
    n_a, n_r = img.shape
    rows = max(1, ABOVE_BLOCK_CELLS // max(n_r, 1))
    found, count = [], 0
    for a0 in range(0, n_a, rows):
        flat = np.flatnonzero(img[a0:a0 + rows] > threshold)
        count += flat.size
        if count > most:
            return None
        found.append(flat + a0 * n_r)
    return np.concatenate(found) if found else np.zeros(0, dtype=np.int64)


#: cells per block of the comparison with the threshold
ABOVE_BLOCK_CELLS = 1 << 18


def _neighbour_tests(img: np.ndarray, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whether each cell ``flat`` is not below any of its neighbours (cells beyond the image left out; a NaN
    neighbour: False), as :func:`_above_and_not_below_neighbours` decides, and whether it has a neighbour of
    its own value."""
    values = img.ravel()
    own = values[flat]
    ok, tied = np.ones(flat.size, dtype=bool), np.zeros(flat.size, dtype=bool)
    for index, inside in _neighbours(img.shape, flat):
        near = values[index]
        ok &= ~inside | (near <= own)
        tied |= inside & (near == own)
    return ok, tied


def _neighbours(shape: tuple, flat: np.ndarray):
    """For each of the 8 neighbour offsets, the flat indices of the neighbours of cells ``flat`` and whether
    each lies inside the image."""
    n_a, n_r = shape
    a, r = np.divmod(flat, n_r)
    for da, dr in _NEIGHBOURS:
        na, nr = a + da, r + dr
        inside = (na >= 0) & (na < n_a) & (nr >= 0) & (nr < n_r)
        yield np.where(inside, flat + da * n_r + dr, flat), inside


def _plateau_maxima(img: np.ndarray, top: np.ndarray, tied: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flat index of the member nearest the centroid of each plateau that is a regional maximum, and of its
    first member, from the cells ``tied`` of ``top`` (the cells above the threshold not below any neighbour)
    that have a neighbour of their own value.

    Two neighbours of ``top`` are equal (each is not below the other), so ``top``'s connected pieces are
    equal-valued; a piece is a maximum unless one of its members has a neighbour of its value outside
    ``top`` (the plateau goes on there, and beyond that cell rises)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    values, in_top = img.ravel(), top.ravel()
    tail, head, spoilt = [], [], np.zeros(tied.size, dtype=bool)
    for index, inside in _neighbours(img.shape, tied):
        same = inside & (values[index] == values[tied])
        spoilt |= same & ~in_top[index]
        tail.append(np.flatnonzero(same & in_top[index]))
        head.append(index[tail[-1]])
    tail, head = np.concatenate(tail), np.searchsorted(tied, np.concatenate(head))  # both ``top`` cells: tied
    n, label = connected_components(coo_matrix((np.ones(tail.size), (tail, head)), shape=(tied.size,) * 2),
                                    directed=False)
    # a piece that is the whole image (a constant one) has no neighbour below it: no maximum (scikit-image's)
    kept = (np.bincount(label, weights=spoilt, minlength=n)[label] == 0) & (np.bincount(label)[label] < img.size)
    cells, lab = tied[kept], label[kept]
    # the centroid as before: sums in raster order (``tied`` is in raster order), the nearest, first of equals
    row, col = np.divmod(cells, img.shape[1])
    counts = np.bincount(lab, minlength=n)
    cy = np.bincount(lab, weights=row, minlength=n) / np.maximum(counts, 1)
    cx = np.bincount(lab, weights=col, minlength=n) / np.maximum(counts, 1)
    dist = (row - cy[lab]) ** 2 + (col - cx[lab]) ** 2
    order = np.lexsort((cells, dist, lab))
    head_of = np.r_[True, lab[order][1:] != lab[order][:-1]][:order.size]
    first_member = np.full(n, np.iinfo(np.int64).max)
    np.minimum.at(first_member, lab, cells)
    return cells[order[head_of]], first_member[lab[order[head_of]]]


def peak_row(ping: int, range_m: float, angle_deg: float, centre_yz_m, cf: float, intensity: float,
             navigation: dict | None = None) -> dict:
    """One row of the peaks table (docs/peaks.md), the same in every table
    (:data:`clbeam.io.peaks.PEAK_CSV_COLUMNS`).

    Frames (docs/peaks.md): ``range_m`` and ``angle_deg`` are from the grid
    centre (``centre_y_m``, ``centre_z_m``, also in the row); ``y_m`` (starboard)
    and ``z_m`` (down) are in the earth frame from the array reference point,
    rolled and heaved with the ship (docs/ping-format.md); ``depth_m`` is
    ``z_m`` plus the ping's draft (m; 0 where not given).

    Parameters
    ----------
    ping : int
        Ping index.
    range_m, angle_deg : float
        Position from the grid centre (m, degree from nadir, positive to starboard).
    centre_yz_m : (float, float)
        Earth-frame grid centre (m).
    cf, intensity : float
        Smoothed CF and intensity ``|S|^2`` (NaN: none) at the peak.
    navigation : dict, optional
        The ping's ``latitude``, ``longitude``, ``heading`` (degree), ``time_s``
        (s since 1970-01-01 UTC) and ``draft_m`` (m) (:attr:`clbeam.imaging.peaks.PingContext.navigation`);
        a value ``None`` or NaN leaves its column out (an empty cell).

    Returns
    -------
    dict
        The row; with latitude, longitude and heading, the peak's own position
        ``peak_latitude_deg``, ``peak_longitude_deg`` (degree, WGS84): ``|y_m|``
        along the azimuth ``heading ± 90`` degrees from the ping's.
    """
    return peak_rows_at(ping, [range_m], [angle_deg], centre_yz_m, [cf], [intensity], navigation)[0]


def peak_rows_at(ping: int, range_m, angle_deg, centre_yz_m, cf, intensity, navigation: dict | None = None,
                 extra: dict | None = None) -> list[dict]:
    """:func:`peak_row` of every entry of ``range_m``, ``angle_deg``, ``cf`` and ``intensity`` (arrays of one
    length; the rest as :func:`peak_row`), their positions computed for all entries at once (the one builder
    of the rows: :func:`peak_row` is this for one peak); ``extra`` (column name: values, one a row) appends
    columns to each row, in its order."""
    r, a = np.asarray(range_m, dtype=np.float64).ravel(), np.asarray(angle_deg, dtype=np.float64).ravel()
    c, inten = np.asarray(cf, dtype=np.float64).ravel(), np.asarray(intensity, dtype=np.float64).ravel()
    nav = {k: float(v) for k, v in (navigation or {}).items() if v is not None and np.isfinite(v)}
    th = np.deg2rad(a)
    y, z = centre_yz_m[0] + r * np.sin(th), centre_yz_m[1] + r * np.cos(th)
    depth = z + nav.get("draft_m", 0.0)
    common = {"centre_y_m": float(centre_yz_m[0]), "centre_z_m": float(centre_yz_m[1])}
    if "time_s" in nav:
        common["time_s"] = nav["time_s"]
    common.update({column: nav[key] for key, column in (("latitude", "ping_latitude_deg"),
                                                         ("longitude", "ping_longitude_deg"),
                                                         ("heading", "heading_deg")) if key in nav})
    per_peak = {"range_m": r, "angle_deg": a, "y_m": y, "z_m": z, "depth_m": depth, "cf": c,
                "intensity_db": intensity_db(inten)}
    position = {}
    if {"latitude", "longitude", "heading"} <= nav.keys() and r.size:
        position["peak_latitude_deg"], position["peak_longitude_deg"] = geodesic_direct(
            nav["latitude"], nav["longitude"], nav["heading"] + np.where(y >= 0, 90.0, -90.0), np.abs(y))
    extra = extra or {}
    # one dict a peak, its keys in the tables' order: the peak's, the ping's, its position's, the extra ones
    names = ("ping", *per_peak, *common, *position, *extra)
    values = (repeat(int(ping)), *(v.tolist() for v in per_peak.values()), *(repeat(v) for v in common.values()),
              *(v.tolist() for v in position.values()), *(np.asarray(v).tolist() for v in extra.values()))
    return list(map(_row_builder(names), *values))


@functools.lru_cache(maxsize=64)
def _row_builder(names: tuple):
    """A function of ``len(names)`` values that returns the dict of ``names`` to them: a dict display with
    these keys (as :mod:`dataclasses` writes its ``__init__``), which CPython builds 1.6-1.8x faster than
    ``dict(zip(names, values))``, the most of a large table's rows."""
    if not all(isinstance(name, str) for name in names):
        raise TypeError(f"row columns must be str, got {names!r}")
    args = ", ".join(f"v{k}" for k in range(len(names)))
    namespace: dict = {}
    exec(f"def row({args}):\n    return {{{', '.join(f'{name!r}: v{k}' for k, name in enumerate(names))}}}", namespace)
    return namespace["row"]


def intensity_db(intensity) -> np.ndarray:
    """``10 log10`` of an intensity (dB re its unit; -inf at 0 and below), float64."""
    inten = np.asarray(intensity, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(inten > 0, 10 * np.log10(np.where(inten > 0, inten, 1.0)), -np.inf)
