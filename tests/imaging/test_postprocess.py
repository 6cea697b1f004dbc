"""Hann smoothing and coherence peaks against scipy and a brute-force
regional-maximum search (MATLAB imregionalmax semantics)."""

import math

import numpy as np
import pytest
import scipy.signal

from clbeam.imaging.postprocess import HANN7, coherence_peaks, hann_smooth, hann_smooth_in_windows


def test_hann7_is_the_papers_window_normalised():
    np.testing.assert_allclose(HANN7 * 3.0, [0, 0.25, 0.75, 1, 0.75, 0.25, 0])
    w = scipy.signal.windows.hann(7)
    np.testing.assert_allclose(HANN7, w / w.sum())


def test_hann_smoothing_is_a_zero_padded_convolution_along_range():
    rng = np.random.default_rng(0)
    cf = rng.uniform(0, 1, (5, 40))
    got = hann_smooth(cf)
    for row in range(5):
        np.testing.assert_allclose(got[row], np.convolve(cf[row], HANN7, mode="same"), atol=1e-15)
    assert got.max() <= 1.0 and got.min() >= 0.0


def test_a_large_image_is_smoothed_in_blocks_of_rows_with_the_same_values(monkeypatch):
    """Above the block size the rows are smoothed in parallel blocks: the values are those of one block, bit
    for bit, and the convolution's (scipy.ndimage, zero padding)."""
    from scipy.ndimage import correlate1d

    import clbeam.imaging.postprocess as postprocess

    cf = np.random.default_rng(3).uniform(0, 1, (37, 901)).astype(np.float32)
    monkeypatch.setattr(postprocess, "SMOOTHING_BLOCK_CELLS", 4000)
    monkeypatch.setattr(postprocess.os, "sched_getaffinity", lambda pid: {0, 1, 2, 3})
    blocks = hann_smooth(cf)
    monkeypatch.setattr(postprocess, "MAX_SMOOTHING_THREADS", 1)
    whole = hann_smooth(cf)
    assert np.array_equal(blocks, whole)
    np.testing.assert_allclose(blocks, correlate1d(cf.astype(np.float64), HANN7, axis=1, mode="constant"), atol=1e-6)
    # a 3-D input in Fortran order (its rows are no view of it) and an empty range axis
    cube = np.asfortranarray(np.random.default_rng(4).uniform(0, 1, (4, 30, 120)))
    np.testing.assert_allclose(hann_smooth(cube), correlate1d(cube, HANN7, axis=-1, mode="constant"), atol=1e-12)
    assert hann_smooth(np.zeros((5, 0))).shape == (5, 0)


def brute_force_regional_maxima(img):
    """Connected (8-neighbour) plateaus strictly above every neighbour."""
    n_a, n_r = img.shape
    seen = np.zeros(img.shape, dtype=bool)
    plateaus = []
    for i in range(n_a):
        for j in range(n_r):
            if seen[i, j]:
                continue
            v = img[i, j]
            stack, members, is_max = [(i, j)], [], True
            seen[i, j] = True
            while stack:
                a, b = stack.pop()
                members.append((a, b))
                for da in (-1, 0, 1):
                    for db in (-1, 0, 1):
                        x, y = a + da, b + db
                        if (da or db) and 0 <= x < n_a and 0 <= y < n_r:
                            if img[x, y] == v and not seen[x, y]:
                                seen[x, y] = True
                                stack.append((x, y))
                            elif img[x, y] > v:
                                is_max = False
            if is_max:
                plateaus.append(members)
    return plateaus


@pytest.mark.parametrize("seed", range(5))
def test_peaks_are_regional_maxima_one_per_plateau(seed):
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 6, (12, 15)) / 5.0  # coarse levels: many plateaus and ties
    threshold = 0.25
    expected = [p for p in brute_force_regional_maxima(img) if img[p[0]] > threshold]
    got = coherence_peaks(img, threshold)
    assert len(got) == len(expected)
    members = [set(p) for p in expected]
    for a, r in got:  # each reported peak lies on a distinct expected plateau
        hits = [k for k, m in enumerate(members) if (a, r) in m]
        assert len(hits) == 1
        members[hits[0]] = set()


@pytest.mark.parametrize("seed", range(3))
def test_isolated_peaks_match_brute_force_and_scikit_image(seed):
    """Continuous values (no ties: the search over the cells above the threshold) against the
    brute-force plateaus and scikit-image's regional maxima, in the order of decreasing CF."""
    from scipy.ndimage import uniform_filter
    from skimage.morphology import local_maxima

    rng = np.random.default_rng(seed)
    img = uniform_filter(rng.random((60, 90)), 3)  # smooth enough for maxima, well above 0.5 in places
    threshold = 0.5
    expected = sorted((p[0] for p in brute_force_regional_maxima(img) if img[p[0]] > threshold),
                      key=lambda p: -img[p])
    got = [tuple(p) for p in coherence_peaks(img, threshold)]
    assert got == expected and len(got) > 5
    sk = np.argwhere(local_maxima(img, connectivity=2, allow_borders=True) & (img > threshold))
    assert {tuple(p) for p in sk} == set(got)


def test_hand_made_plateau_counts_once_and_ties_apart_count_twice():
    img = np.zeros((7, 9))
    img[1:3, 1:4] = 0.8           # a 2 x 3 plateau: one peak
    img[5, 2] = img[5, 6] = 0.6   # two separate equal maxima: two peaks
    img[3, 7] = 0.2               # below the threshold
    peaks = coherence_peaks(img, 0.25)
    assert len(peaks) == 3
    assert tuple(peaks[0]) in {(1, 2), (2, 2)}  # plateau member nearest its centroid (1.5, 2)
    assert {tuple(p) for p in peaks[1:]} == {(5, 2), (5, 6)}


def test_plateau_touching_a_higher_neighbour_is_not_a_peak():
    img = np.zeros((5, 5))
    img[1:4, 1:4] = 0.5
    img[2, 4] = 0.9
    peaks = coherence_peaks(img, 0.25)
    assert [tuple(p) for p in peaks] == [(2, 4)]


def test_a_constant_image_has_no_regional_maximum_as_in_scikit_image():
    from skimage.morphology import local_maxima

    img = np.full((5, 7), 0.8)
    assert not local_maxima(img, connectivity=2, allow_borders=True).any()
    assert len(coherence_peaks(img, 0.25)) == 0


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_smoothing_in_windows_equals_the_whole_grids_bit_for_bit(dtype):
    """A CF that is 0 outside a band of range cells per angle (some bands at the grid's ends, some empty):
    smoothed on the bands' cells only, every cell equals hann_smooth of the whole grid exactly."""
    rng = np.random.default_rng(2)
    n_a, n_r = 40, 90
    first = rng.integers(0, n_r, n_a)
    end = np.minimum(first + rng.integers(0, 30, n_a), n_r)
    first[:3], end[:3] = 0, [n_r, 5, 0]       # the whole row, a band at the start, an empty one
    first[3], end[3] = n_r - 4, n_r             # a band at the end
    cf = rng.random((n_a, n_r)).astype(dtype)
    cf[np.arange(n_r)[None, :] < first[:, None]] = 0
    cf[np.arange(n_r)[None, :] >= end[:, None]] = 0
    got = hann_smooth_in_windows(cf, np.stack([first, end], axis=1))
    assert got.dtype == dtype
    np.testing.assert_array_equal(got, hann_smooth(cf))


def scikit_image_peaks(img, threshold):
    """The reference: scikit-image's regional maxima and plateau labels, each plateau's member nearest its
    centroid (the first in raster order of equally near ones), by decreasing CF, equal CFs in the order of
    the plateaus' labels (the raster order of their first cells)."""
    from skimage.measure import label
    from skimage.morphology import local_maxima

    maxima = local_maxima(img, connectivity=2, allow_borders=True) & (img > threshold)
    labels, n = label(maxima, connectivity=2, return_num=True)
    if n == 0:
        return np.zeros((0, 2), dtype=np.int64)
    idx = np.argwhere(labels > 0)
    lab = labels[idx[:, 0], idx[:, 1]]
    counts = np.bincount(lab)
    cy = np.bincount(lab, weights=idx[:, 0]) / np.maximum(counts, 1)
    cx = np.bincount(lab, weights=idx[:, 1]) / np.maximum(counts, 1)
    dist = (idx[:, 0] - cy[lab]) ** 2 + (idx[:, 1] - cx[lab]) ** 2
    order = np.lexsort((dist, lab))
    peaks = idx[order[np.r_[True, lab[order][1:] != lab[order][:-1]]]]
    return peaks[np.argsort(-img[peaks[:, 0], peaks[:, 1]], kind="stable")]


@pytest.mark.parametrize("sparse", [0.0, 1.0], ids=["maximum-filter", "cell-by-cell"])
@pytest.mark.parametrize("seed", range(6))
def test_whole_image_search_equals_scikit_image_on_plateaus_and_ties(monkeypatch, seed, sparse):
    """Random images of a few levels (large plateaus, ties between separate maxima of one value, plateaus on
    the edges and touching higher cells), of any shape down to one row or column, in float32 and float64,
    through the maximum filter and through the cell-by-cell look of sparse images: the same cells in the
    same order as scikit-image's regional maxima."""
    from scipy.ndimage import uniform_filter

    import clbeam.imaging.postprocess as postprocess

    monkeypatch.setattr(postprocess, "SPARSE_ABOVE_FRACTION", sparse)
    monkeypatch.setattr(postprocess, "ABOVE_BLOCK_CELLS", 64)   # the cells above the threshold a few rows at a time

    rng = np.random.default_rng(100 + seed)
    for trial in range(60):
        shape = (int(rng.integers(1, 30)), int(rng.integers(1, 45)))
        levels = int(rng.integers(2, 7))
        img = rng.integers(0, levels, shape) / (levels - 1)
        if trial % 2:  # smooth, then quantised: broad plateaus around maxima
            img = np.round(uniform_filter(rng.random(shape), 3) * levels) / levels
        img = img.astype(np.float32 if trial % 3 else np.float64)
        threshold = float(rng.choice([0.0, 0.25, 0.5]))
        got = coherence_peaks(img, threshold)
        if img.size > 1:  # scikit-image finds no maximum in one cell (a constant image); the search keeps it
            np.testing.assert_array_equal(got, scikit_image_peaks(img, threshold))


@pytest.mark.parametrize("blocks", [False, True], ids=["as-set", "cell-by-cell-in-blocks"])
def test_whole_image_search_equals_scikit_image_on_a_sonar_like_image(monkeypatch, blocks):
    """A smooth image with thousands of maxima, rounded to steps of 2^-10 so that neighbours tie (as a
    noise-free ping's smoothed CF does): the same cells in the same order, as the module is set and with
    the cells above the threshold looked at one by one, found in blocks of a few rows."""
    from scipy.ndimage import gaussian_filter

    import clbeam.imaging.postprocess as postprocess

    if blocks:
        monkeypatch.setattr(postprocess, "ABOVE_BLOCK_CELLS", 3000)
        monkeypatch.setattr(postprocess, "SPARSE_ABOVE_FRACTION", 1.0)

    rng = np.random.default_rng(8)
    img = gaussian_filter(rng.random((300, 700)), 1.2)
    img = ((img - img.min()) / np.ptp(img)).astype(np.float32)
    img = np.round(img * 2**10) / 2**10   # ties: about 300 cells of the maxima's 6,000 candidates
    got = coherence_peaks(img, 0.25)
    ref = scikit_image_peaks(img, 0.25)
    assert len(ref) > 1000 and len(np.unique(img[ref[:, 0], ref[:, 1]])) < len(ref) / 2  # many equal CFs
    np.testing.assert_array_equal(got, ref)


@pytest.mark.parametrize("navigation", [None, {"latitude": 34.29, "longitude": -119.77, "heading": 290.0,
                                                "time_s": 1.66e9, "draft_m": 5.0},
                                        {"latitude": float("nan"), "longitude": None, "heading": 12.0}])
def test_rows_of_many_peaks_at_once_hold_each_peaks_position_level_and_navigation(navigation):
    """The peak rows built for all peaks at once: each peak's earth-frame position from the grid centre
    (closed form), depth with the draft, intensity in dB (0 at -inf), the navigation columns, and with a
    position the peak's own one ``|y|`` across the heading (the WGS84 inverse gives that distance and
    azimuth back); one peak's row (:func:`peak_row`) is the same."""
    from clbeam.imaging.postprocess import peak_row, peak_rows_at
    from clbeam.model.geodesy import geodesic_inverse

    rng = np.random.default_rng(4)
    r, a = rng.uniform(0, 1100, 300), rng.uniform(-80, 80, 300)
    cf, inten = rng.uniform(0, 1, 300), rng.exponential(1.0, 300).astype(np.float32)
    inten[:3] = 0.0
    got = peak_rows_at(7, r, a, (0.4, 1.2), cf, inten, navigation)
    assert len(got) == 300 and peak_rows_at(7, [], [], (0.0, 0.0), [], [], navigation) == []
    nav = {k: v for k, v in (navigation or {}).items() if v is not None and np.isfinite(v)}
    y = 0.4 + r * np.sin(np.radians(a))
    z = 1.2 + r * np.cos(np.radians(a))
    for k, row in enumerate(got):
        assert (row["ping"], row["range_m"], row["angle_deg"], row["cf"]) == (7, r[k], a[k], cf[k])
        assert row["y_m"] == pytest.approx(y[k], abs=1e-9) and row["z_m"] == pytest.approx(z[k], abs=1e-9)
        assert row["depth_m"] == pytest.approx(z[k] + nav.get("draft_m", 0.0), abs=1e-9)
        want_db = 10 * math.log10(float(inten[k])) if inten[k] > 0 else -math.inf
        assert row["intensity_db"] == pytest.approx(want_db, rel=1e-12)
        assert row.get("heading_deg") == nav.get("heading") and row.get("time_s") == nav.get("time_s")
        assert ("peak_latitude_deg" in row) == ({"latitude", "longitude", "heading"} <= nav.keys())
        if "peak_latitude_deg" in row:
            dist, azimuth = geodesic_inverse(nav["latitude"], nav["longitude"], row["peak_latitude_deg"],
                                             row["peak_longitude_deg"])
            assert float(dist) == pytest.approx(abs(y[k]), abs=1e-3)
            if abs(y[k]) > 1.0:
                turn = (float(azimuth) - nav["heading"]) % 360
                assert turn == pytest.approx(90.0 if y[k] >= 0 else 270.0, abs=1e-3)
    assert peak_row(7, r[5], a[5], (0.4, 1.2), cf[5], float(inten[5]), navigation) == got[5]
