"""Hann smoothing of the coherence factor and coherence-peak picking
(Holland et al. 2024, Section III)."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from clbeam.constants import PEAK_THRESHOLD
from clbeam.errors import OptionError, require
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
    one maximum, reported once at its member nearest the plateau's centroid.

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
        by decreasing CF.
    """
    require(0.0 <= threshold <= 1.0, OptionError, f"threshold must be within 0-1, got {threshold!r}")
    img = np.asarray(cf_smooth)
    img = img if img.dtype in (np.float32, np.float64) else img.astype(np.float64)
    require(img.ndim == 2, OptionError, f"coherence peaks need a 2-D (angle, range) image, got shape {img.shape}")
    if img.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    peaks = _isolated_maxima(img, threshold)
    if peaks is None:  # a candidate ties with a neighbour: plateaus need the connected-component search
        peaks = _plateau_maxima(img, threshold)
    return peaks[np.argsort(-img[peaks[:, 0], peaks[:, 1]], kind="stable")]


#: the 8 neighbours' (angle, range) offsets
_NEIGHBOURS = [(da, dr) for da in (-1, 0, 1) for dr in (-1, 0, 1) if da or dr]


def _isolated_maxima(img: np.ndarray, threshold: float) -> np.ndarray | None:
    """Cells above ``threshold`` strictly above their 8 neighbours, in raster order;
    ``None`` when a cell not below any neighbour equals one (a plateau).

    Looks only at the cells above the threshold: a few per cent of a
    sonar image, so this costs a fraction of a full-image search.
    """
    n_a, n_r = img.shape
    flat = np.flatnonzero(img > threshold)
    a, r = np.divmod(flat, n_r)
    value = img.ravel()[flat]
    not_lower = np.ones(flat.size, dtype=bool)
    ties = np.zeros(flat.size, dtype=bool)
    for da, dr in _NEIGHBOURS:
        na, nr = a + da, r + dr
        inside = (na >= 0) & (na < n_a) & (nr >= 0) & (nr < n_r)
        neighbour = np.where(inside, img[np.clip(na, 0, n_a - 1), np.clip(nr, 0, n_r - 1)], -np.inf)
        not_lower &= neighbour <= value
        ties |= neighbour == value
    if np.any(not_lower & ties):
        return None
    return np.stack([a[not_lower], r[not_lower]], axis=1).astype(np.int64)


def _plateau_maxima(img: np.ndarray, threshold: float) -> np.ndarray:
    """Regional maxima above ``threshold`` with plateaus, one cell per plateau (scikit-image)."""
    from skimage.measure import label
    from skimage.morphology import local_maxima

    maxima = local_maxima(img, connectivity=2, allow_borders=True) & (img > threshold)
    labels, n = label(maxima, connectivity=2, return_num=True)
    if n == 0:
        return np.zeros((0, 2), dtype=np.int64)
    idx = np.argwhere(labels > 0)
    lab = labels[idx[:, 0], idx[:, 1]]
    counts = np.bincount(lab, minlength=n + 1)
    cy = np.bincount(lab, weights=idx[:, 0], minlength=n + 1) / np.maximum(counts, 1)
    cx = np.bincount(lab, weights=idx[:, 1], minlength=n + 1) / np.maximum(counts, 1)
    dist = (idx[:, 0] - cy[lab]) ** 2 + (idx[:, 1] - cx[lab]) ** 2
    order = np.lexsort((dist, lab))
    first = order[np.r_[True, lab[order][1:] != lab[order][:-1]]]
    return idx[first]


def peak_row(ping: int, range_m: float, angle_deg: float, centre_yz_m, cf: float, intensity: float,
             navigation: dict | None = None) -> dict:
    """One row of the peaks table (SPEC §3 step 7): position on the grid and in
    the earth frame (m), smoothed CF, intensity (dB), and the ship's navigation
    at the ping (``ship_latitude_deg``, ``ship_longitude_deg``, ``ship_heading_deg``:
    the peak's own geographic position is the survey's job).

    Frames (docs/peaks.md): ``range_m`` and ``angle_deg`` are from the grid
    centre (``centre_y_m``, ``centre_z_m``, also in the row); ``y_m`` (starboard)
    and ``z_m`` (down) are in the earth frame from the array reference point,
    rolled and heaved with the ship (SPEC §2)."""
    th = np.deg2rad(angle_deg)
    row = {"ping": int(ping), "range_m": float(range_m), "angle_deg": float(angle_deg),
           "y_m": float(centre_yz_m[0] + range_m * np.sin(th)), "z_m": float(centre_yz_m[1] + range_m * np.cos(th)),
           "cf": float(cf), "intensity_db": float(10 * np.log10(intensity)) if intensity > 0 else float("-inf"),
           "centre_y_m": float(centre_yz_m[0]), "centre_z_m": float(centre_yz_m[1])}
    for key, value in (navigation or {}).items():
        if value is not None and np.isfinite(value):
            row[f"ship_{key}_deg"] = float(value)
    return row


