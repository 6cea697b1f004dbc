"""Hann smoothing of the coherence factor and coherence-peak picking
(Holland et al. 2024, Section III)."""

from __future__ import annotations

import numpy as np
from skimage.measure import label
from skimage.morphology import local_maxima

from .errors import OptionError, require

#: 7-point Hann window of the paper, normalised to sum 1
HANN7 = np.array([0.0, 0.25, 0.75, 1.0, 0.75, 0.25, 0.0]) / 3.0

#: CF threshold for coherence peaks (paper: 0.25; 0.4 for persistence maps)
DEFAULT_THRESHOLD = 0.25


def hann_smooth(cf: np.ndarray, weights: np.ndarray = HANN7) -> np.ndarray:
    """Smooth CF along the range axis (last axis) with the 7-point Hann window.

    Cells beyond the grid count as zero (MATLAB ``conv(..., 'same')``), so the
    smoothed CF stays within [0, 1] wherever CF does.

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
    h = w.size // 2
    n = x.shape[-1]
    # shifted adds (a zero-padded correlation; the window is symmetric, so a
    # convolution) skipping zero taps: much faster than a general filter
    out = w[h] * x
    for k in range(1, h + 1):
        if w[h + k] == 0 and w[h - k] == 0:
            continue
        if k < n:
            out[..., :-k] += w[h + k] * x[..., k:]
            out[..., k:] += w[h - k] * x[..., :-k]
    return out


def coherence_peaks(cf_smooth: np.ndarray, threshold: float = DEFAULT_THRESHOLD) -> np.ndarray:
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
    maxima = regional_maxima_above(img, threshold)
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
    peaks = idx[first]
    return peaks[np.argsort(-img[peaks[:, 0], peaks[:, 1]], kind="stable")]


def regional_maxima_above(img: np.ndarray, threshold: float) -> np.ndarray:
    """Mask of the regional maxima (``imregionalmax``, 8-connectivity, the
    image border counting as lower) whose value exceeds ``threshold``.

    Equal to ``skimage.morphology.local_maxima(img, connectivity=2,
    allow_borders=True) & (img > threshold)``, computed fast: a cell above
    the threshold and strictly above its 8 neighbours is a maximum outright;
    only cells with an equal neighbour (plateaus) go to the exact plateau
    analysis of scikit-image, on the bounding box of their connected set
    padded by one cell (a plateau lies wholly in one such set, its rim in
    the padding).
    """
    from scipy import ndimage

    if img.size and np.all(img == img.flat[0]):  # a constant image has no regional maximum (scikit-image)
        return np.zeros(img.shape, dtype=bool)
    above = img > threshold
    padded = np.pad(img, 1, constant_values=-np.inf)
    n_a, n_r = img.shape
    strict = above.copy()
    equal = np.zeros_like(above)
    for da in (-1, 0, 1):
        for dr in (-1, 0, 1):
            if da == 0 and dr == 0:
                continue
            nb = padded[1 + da:1 + da + n_a, 1 + dr:1 + dr + n_r]
            strict &= img > nb
            equal |= img == nb
    tied = above & equal
    if tied.any():
        sets, _ = ndimage.label(tied, structure=np.ones((3, 3), dtype=bool))
        for k, box in enumerate(ndimage.find_objects(sets), start=1):
            a0, a1 = max(box[0].start - 1, 0), min(box[0].stop + 1, n_a)
            r0, r1 = max(box[1].start - 1, 0), min(box[1].stop + 1, n_r)
            crop = img[a0:a1, r0:r1]
            # the crop's own edges are not the image border: pad them with the
            # real neighbours where they exist, -inf beyond the image
            ea0, ea1 = a0 - max(a0 - 1, 0), min(a1 + 1, n_a) - a1
            er0, er1 = r0 - max(r0 - 1, 0), min(r1 + 1, n_r) - r1
            ctx = img[a0 - ea0:a1 + ea1, r0 - er0:r1 + er1]
            ctx = np.pad(ctx, ((1 - ea0, 1 - ea1), (1 - er0, 1 - er1)), constant_values=-np.inf)
            local = local_maxima(ctx, connectivity=2, allow_borders=False)[1:-1, 1:-1]
            member = sets[a0:a1, r0:r1] == k
            strict[a0:a1, r0:r1] |= local & member & (crop > threshold)
    return strict


def peak_row(ping: int, range_m: float, angle_deg: float, centre_yz_m, cf: float, intensity: float,
             navigation: dict | None = None) -> dict:
    """One row of the peaks table (SPEC §3 step 7): position on the grid and in
    the earth frame (m), smoothed CF, intensity (dB), and the ship's navigation
    at the ping (``ship_latitude_deg``, ``ship_longitude_deg``, ``ship_heading_deg``:
    the peak's own geographic position is the survey's job)."""
    th = np.deg2rad(angle_deg)
    row = {"ping": int(ping), "range_m": float(range_m), "angle_deg": float(angle_deg),
           "y_m": float(centre_yz_m[0] + range_m * np.sin(th)), "z_m": float(centre_yz_m[1] + range_m * np.cos(th)),
           "cf": float(cf), "intensity_db": float(10 * np.log10(intensity)) if intensity > 0 else float("-inf")}
    for key, value in (navigation or {}).items():
        if value is not None and np.isfinite(value):
            row[f"ship_{key}_deg"] = float(value)
    return row


def peaks_from_images(ds, threshold: float = DEFAULT_THRESHOLD) -> list:
    """Coherence-peak rows for every ping of an image dataset."""
    ranges, angles = ds["range"].values, ds["angle"].values
    rows = []
    for i in range(ds.sizes["ping"]):
        cf_s = hann_smooth(ds["cf"].isel(ping=i).values)
        inten = ds["intensity"].isel(ping=i).values if "intensity" in ds.variables else None
        centre = tuple(float(ds[v].values[i]) if v in ds.variables else 0.0 for v in ("centre_y", "centre_z"))
        nav = {k: float(ds[k].values[i]) for k in ("latitude", "longitude", "heading") if k in ds.variables}
        for ia, ir in coherence_peaks(cf_s, threshold):
            rows.append(peak_row(int(ds["ping"].values[i]), ranges[ir], angles[ia], centre, cf_s[ia, ir],
                                 float(inten[ia, ir]) if inten is not None else np.nan, nav))
    return rows
