"""Sub-cell coherence peaks against the scatterers' true positions.

The scenes place point scatterers at random between grid nodes with exact
band-limited delays (``tests/scenes.py``, independent of clbeam's
simulator); a refined peak must sit within a tenth of a cell of the truth
with a smoothed CF of at least 0.98, wherever the point falls between nodes.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scenes import point_ping, polar_point

from clbeam.imaging.engine import interp_mode
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.subcell import RefinedPeaks, lobe_maximum, merge_refined, refine_peaks
from clbeam.model.grid import PolarGrid
from clbeam.model.svp import SoundSpeedProfile

RANGE_STEP, ANGLE_STEP = 0.2, 0.1


def grid_for(ranges_m, angles_deg, shift=(0.0, 0.0)) -> PolarGrid:
    """A paper-resolution grid (0.2 m x 0.1 deg) around the targets, offset by ``shift`` cells."""
    lo = np.floor(min(ranges_m) - 3.0) + shift[0] * RANGE_STEP
    a0 = np.floor(min(angles_deg) - 4.0) + shift[1] * ANGLE_STEP
    return PolarGrid(lo + RANGE_STEP * np.arange(int((max(ranges_m) - lo + 3.0) / RANGE_STEP)),
                     a0 + ANGLE_STEP * np.arange(int((max(angles_deg) - a0 + 4.0) / ANGLE_STEP)))


def refined_near(rows, r, a):
    """The peak row nearest to (r, a), and its distance in cells (range, angle)."""
    d = [max(abs(row["range_m"] - r) / RANGE_STEP, abs(row["angle_deg"] - a) / ANGLE_STEP) for row in rows]
    row = rows[int(np.argmin(d))]
    return row, abs(row["range_m"] - r) / RANGE_STEP, abs(row["angle_deg"] - a) / ANGLE_STEP


@pytest.mark.parametrize("seed", range(3))
def test_points_between_nodes_refine_to_a_tenth_of_a_cell_with_full_cf(seed):
    rng = np.random.default_rng(seed)
    ranges = rng.uniform(60.0, 140.0, 3)
    angles = np.array([-45.0, 5.0, 50.0]) + rng.uniform(-3, 3, 3)
    ping = point_ping([polar_point(r, a) for r, a in zip(ranges, angles)], record_s=0.22)
    grid = grid_for(ranges, angles)
    rows = Imager(grid, ImagingOptions()).image(ping).peaks
    for r, a in zip(ranges, angles):
        row, dr, da = refined_near(rows, r, a)
        assert dr < 0.1 and da < 0.1, (r, a, row)
        assert row["cf"] >= 0.98
        assert {"cell_range_m", "cell_angle_deg", "cell_cf", "cell_peaks"} <= set(row)


def test_off_node_and_on_node_points_give_the_same_peak():
    """The same scatterer on a node and half a cell off it (the grid moved by half a cell in range
    and angle): the grid cells' CF differ, the refined positions and CF do not."""
    r, a = 95.3, 12.4
    ping = point_ping([polar_point(r, a)], record_s=0.16)
    results = []
    for shift in ((0.0, 0.0), (0.5, 0.5)):
        grid = grid_for([r], [a], shift)
        rows = Imager(grid, ImagingOptions()).image(ping).peaks
        results.append(refined_near(rows, r, a)[0])
    on, off = results
    assert abs(on["range_m"] - off["range_m"]) < 0.05 * RANGE_STEP
    assert abs(on["angle_deg"] - off["angle_deg"]) < 0.05 * ANGLE_STEP
    assert on["cf"] == pytest.approx(off["cf"], abs=0.005)
    assert on["intensity_db"] == pytest.approx(off["intensity_db"], abs=0.05)


def test_refinement_through_travel_time_tables_equals_straight_rays():
    """A constant-speed profile sends the refinement through the grid's ray-traced tables
    (interpolated to the points): the same peaks as straight rays."""
    r, a = 88.7, -20.3
    ping = point_ping([polar_point(r, a)], record_s=0.16)
    grid = grid_for([r], [a])
    straight = Imager(grid, ImagingOptions()).image(ping).peaks
    tabled = Imager(grid, ImagingOptions()).image(dataclasses.replace(ping, svp=SoundSpeedProfile.constant(1500.0))).peaks
    row_s, row_t = refined_near(straight, r, a)[0], refined_near(tabled, r, a)[0]
    assert row_t["range_m"] == pytest.approx(row_s["range_m"], abs=0.01 * RANGE_STEP)
    assert row_t["angle_deg"] == pytest.approx(row_s["angle_deg"], abs=0.01 * ANGLE_STEP)
    assert row_t["cf"] == pytest.approx(row_s["cf"], abs=1e-3)


def test_refined_intensity_is_the_sums_maximum():
    """The refined point's intensity is not below any cell of a fine direct image around it."""
    r, a = 70.55, 30.04
    ping = point_ping([polar_point(r, a)], record_s=0.12)
    grid = grid_for([r], [a])
    im = Imager(grid, ImagingOptions(interp="lanczos8"))
    img = im.image(ping)
    row = refined_near(img.peaks, r, a)[0]
    fine = PolarGrid(row["range_m"] + np.linspace(-0.05, 0.05, 21), row["angle_deg"] + np.linspace(-0.05, 0.05, 21))
    inp = im.beamform_input(ping)
    direct = im.engine.beamform(inp.for_grid(fine), fine, interp="lanczos8", outputs=("intensity",)).intensity
    assert 10 * np.log10(direct.max()) <= row["intensity_db"] + 0.01


def test_lobe_maximum_stays_in_the_run_above_the_threshold():
    cf = np.array([[0.1, 0.5, 0.6, 0.2, 0.9, 0.9]])
    intensity = np.array([[9.0, 1.0, 2.0, 8.0, 7.0, 1.0]])
    # the run through cell 1 is cells 1-2 (cell 3 is at 0.2): its most intense cell is 2, not 0, 3 or 4
    np.testing.assert_array_equal(lobe_maximum(cf, intensity, np.array([0]), np.array([1]), 0.25), [2])
    np.testing.assert_array_equal(lobe_maximum(cf, intensity, np.array([0]), np.array([5]), 0.25), [4])


def test_merge_keeps_the_first_of_each_echo_and_counts_the_rest():
    z = np.zeros(4)
    refined = RefinedPeaks(range_m=np.array([10.0, 10.05, 12.0, 10.02]), angle_deg=np.array([1.0, 1.1, 1.0, 3.0]),
                           cf_smooth=z, cf=z, intensity=z, cell=np.zeros((4, 2), dtype=np.int64),
                           n_cells=np.ones(4, dtype=np.int64))
    merged = merge_refined(refined, 0.1, 0.5)
    np.testing.assert_array_equal(merged.range_m, [10.0, 12.0, 10.02])
    np.testing.assert_array_equal(merged.n_cells, [2, 1, 1])


def test_no_peak_refines_to_nothing():
    ping = point_ping([polar_point(50.0, 0.0)], record_s=0.08)
    grid = grid_for([50.0], [0.0])
    im = Imager(grid, ImagingOptions())
    out = refine_peaks(im.engine, im.beamform_input(ping), grid, np.zeros((0, 2), dtype=np.int64), interp_mode("cubic"))
    assert out.range_m.size == 0 and out.cell.shape == (0, 2)


@pytest.mark.parametrize("backend", ["reference", "opencl"])
def test_points_on_nodes_of_ray_traced_tables_are_the_grid_image(backend):
    # a strong gradient over a coarse grid: some cells unreachable, launch directions 20 degrees apart
    from scenes import bandlimited_noise

    from clbeam.imaging.engine import BeamformInput, get_engine
    from clbeam.imaging.raytrace import travel_time_tables
    from clbeam.imaging.subcell import sums_at_points

    grid = PolarGrid.regular(range_res_m=0.4, angle_res_deg=20, max_range_m=4.0, angles_deg=(-80, 80))
    offsets = np.zeros((6, 3))
    offsets[:, 1] = np.linspace(-1.5, 1.5, 6)
    tables = travel_time_tables(SoundSpeedProfile([0.0, 0.5], [1480.0, 1700.0]), grid)
    inp = BeamformInput(bandlimited_noise((6, 160), seed=2), 40000.0, 0.0005, 1500.0, offsets, np.array([0.0, 0.2, 0.1]),
                        tables=tables)
    engine = get_engine(backend)
    image = engine.beamform(inp, grid, interp="cubic", outputs=("intensity",)).intensity
    ia, ir = np.meshgrid(np.arange(grid.shape[0]), np.arange(1, grid.shape[1]), indexing="ij")
    assert not np.all(tables.reachable[ia, ir])  # some nodes beside unreachable cells
    got = sums_at_points(engine, inp, grid.ranges_m[ir], grid.angles_deg[ia], interp="cubic", grid=grid,
                         outputs=("intensity",)).intensity
    np.testing.assert_allclose(got, image[ia, ir], rtol=1e-5, atol=1e-6 * image.max())
    # the points in any order (the evaluator takes them in order of range): each output back at its own point
    sums = engine.beamform(inp, grid, interp="cubic", outputs=("sums",))
    shuffle = np.random.default_rng(3).permutation(ia.size)
    at = sums_at_points(engine, inp, grid.ranges_m[ir].ravel()[shuffle], grid.angles_deg[ia].ravel()[shuffle],
                        interp="cubic", grid=grid, outputs=("sums",))
    np.testing.assert_allclose(at.s, sums.s[ia, ir].ravel()[shuffle], rtol=1e-5, atol=1e-6 * np.sqrt(image.max()))
    np.testing.assert_array_equal(at.m, sums.m[ia, ir].ravel()[shuffle])
    # between nodes both backends agree (the launch direction interpolated and normalised alike)
    other = get_engine("opencl" if backend == "reference" else "reference")
    r, a = np.array([0.7, 1.9, 2.3]), np.array([-50.0, 5.0, 31.0])
    mine = sums_at_points(engine, inp, r, a, interp="cubic", grid=grid, outputs=("intensity",)).intensity
    theirs = sums_at_points(other, inp, r, a, interp="cubic", grid=grid, outputs=("intensity",)).intensity
    np.testing.assert_allclose(mine, theirs, rtol=1e-4, atol=1e-6 * image.max())


@pytest.mark.parametrize("heave_m", [0.0, -0.5, 0.45])
def test_far_points_under_a_heaved_array_refine_along_their_echo_not_the_grid_arc(heave_m):
    """Heave moves the array off the grid centre, so an echo's equal-delay curve leaves the grid's arc of
    constant range by ``h sin(theta)`` per radian (8 mm a degree at 70 degrees for 0.45 m), about what the
    flat far beam loses over a degree: searched along the grid's arc, and kept from whichever grid cell of
    the echo had the largest CF, the refined angles of these points at 65-75 degrees were 0.17-0.93 degree
    off.  Searched along the equal-delay curve, the echo's most intense refinement kept: within 0.03 degree
    and a tenth of a range cell, as without heave, with full CF."""
    rng = np.random.default_rng(7)
    ranges = rng.uniform(100.0, 140.0, 2)
    angles = np.array([66.0, 73.0]) + rng.uniform(-1, 1, 2)
    ping = point_ping([polar_point(r, a) for r, a in zip(ranges, angles)], heave_m=heave_m, record_s=0.22)
    grid = grid_for(ranges, angles)
    rows = Imager(grid, ImagingOptions()).image(ping).peaks
    for r, a in zip(ranges, angles):
        row, dr, da = refined_near(rows, r, a)
        assert dr < 0.1 and da * ANGLE_STEP < 0.03, (r, a, row)
        assert row["cf"] >= 0.98


def test_equal_delay_curve_keeps_the_two_way_path():
    """The first-order equal-delay range against the exact two-way path from a heaved, rolled array."""
    from clbeam.imaging.engine.common import BeamformInput
    from clbeam.imaging.equal_delay import EqualDelay
    from clbeam.imaging.geometry import to_earth_frame

    el = to_earth_frame(np.stack([np.zeros(8), np.linspace(-1.7, 1.7, 8), np.zeros(8)], axis=1), roll_deg=3.0,
                        heave_m=0.45)
    src = to_earth_frame(np.zeros(3), roll_deg=3.0, heave_m=0.45)
    inp = BeamformInput(np.zeros((8, 16), np.complex64), 40000.0, 0.0, 1500.0, el, src)

    def path(r, a):
        p = np.array([0.0, r * np.sin(np.radians(a)), r * np.cos(np.radians(a))])
        return np.linalg.norm(p - src) + np.linalg.norm(p - el.mean(axis=0))

    r1 = EqualDelay(inp)(600.0, 70.0, np.array([66.0, 70.0, 74.0]))
    exact = [path(600.0, 70.0) - path(r, a) for r, a in zip(r1, (66.0, 70.0, 74.0))]
    assert np.max(np.abs(exact)) < 1e-3                       # the grid's arc would be off by 6 cm
    assert abs(path(600.0, 70.0) - path(600.0, 74.0)) > 0.05


@pytest.mark.parametrize("beams", [-0.7, 0.7, 1.2])
def test_a_cell_on_the_shoulder_of_an_echo_climbs_to_its_maximum(beams):
    """A peak cell 0.7-1.2 beam widths along the arc from a point's echo (a CF peak on the main lobe's
    shoulder, as a long pipe's far echo gives): every point of the first window (+-half a beam) is less
    intense toward the cell, so the refinement moves its window on until the intensity falls again, and
    ends on the echo's maximum (within a cell), not at the first window's edge (0.5-1.5 degrees off) where
    it would stand as a second echo beside it."""
    from clbeam.imaging.subcell import beam_width_rad

    r, a = 120.3, 45.04
    ping = point_ping([polar_point(r, a)], record_s=0.2)
    grid = grid_for([r], [a])
    im = Imager(grid, ImagingOptions())
    inp = im.beamform_input(ping)
    start = a + np.degrees(beams * beam_width_rad(inp) / np.cos(np.radians(a)))
    cell = np.array([[int(np.argmin(np.abs(grid.angles_deg - start))), int(np.argmin(np.abs(grid.ranges_m - r)))]])
    out = refine_peaks(im.engine, inp, grid, cell, interp_mode("cubic"))
    assert abs(out.range_m[0] - r) < 0.1 * RANGE_STEP
    assert abs(out.angle_deg[0] - a) < ANGLE_STEP, (start, out.angle_deg[0])


def test_an_echo_just_past_the_grid_edge_refines_to_itself_not_the_edge():
    """A point 0.5 degree beyond the grid's last angle: its edge cell's first search window reaches past the
    edge, and the peak refines onto the point (within a tenth of a cell), not onto the edge."""
    r, a = 100.3, 45.5
    ping = point_ping([polar_point(r, a)], record_s=0.16)
    grid = PolarGrid(np.arange(95.0, 106.0, RANGE_STEP), np.arange(40.0, 45.0 + 1e-9, ANGLE_STEP))
    rows = Imager(grid, ImagingOptions()).image(ping).peaks
    row, dr, da = refined_near(rows, r, a)
    assert dr < 0.1 and da < 0.1, row


@pytest.mark.parametrize("a", [45.3, 70.2])
@pytest.mark.parametrize("offset", [-0.8, -0.45, 0.3, 0.6, 0.9])
def test_an_echo_between_the_patch_middle_and_edge_refines_onto_its_maximum(a, offset):
    """A cell ``offset`` search steps along the arc from a point's echo (snapped to the grid): where the
    search's nearest point lies more than a quarter of a search step from the echo, the patch about it (half a
    search step wide) has its maximum on an edge (half of these cases).  Far from nadir the beam is flat
    (14 degrees wide at 70 degrees) and the peak must still reach the echo's maximum within a tenth of a cell
    (0.01 degree; 0.1 m of depth at 300 m): left on the patch's edge it stood up to a quarter of a search step
    off (about a quarter of a degree at 70 degrees)."""
    from clbeam.imaging.subcell import ANGLE_SEARCH_BEAMS, ANGLE_SEARCH_POINTS, beam_width_rad

    r = 300.1
    ping = point_ping([polar_point(r, a)], record_s=0.42)
    grid = grid_for([r], [a])
    im = Imager(grid, ImagingOptions())
    inp = im.beamform_input(ping)
    search_step = np.degrees(2 * ANGLE_SEARCH_BEAMS * beam_width_rad(inp) / np.cos(np.radians(a))) \
        / (ANGLE_SEARCH_POINTS - 1)
    ia = int(np.argmin(np.abs(grid.angles_deg - (a + offset * search_step))))
    cell = np.array([[ia, int(np.argmin(np.abs(grid.ranges_m - r)))]])
    out = refine_peaks(im.engine, inp, grid, cell, interp_mode("cubic"))
    assert abs(out.range_m[0] - r) < 0.1 * RANGE_STEP
    assert abs(out.angle_deg[0] - a) < 0.1 * ANGLE_STEP, (grid.angles_deg[ia] - a, out.angle_deg[0] - a)


def test_the_last_parabola_reaches_a_lopsided_lobes_maximum_and_climbs_where_it_is_not_concave():
    """The arc's last parabola on a lobe that is not a parabola in log (a Gaussian with a cubic skew, as
    noise leaves a flat far lobe): from 0.03 degree off, within 0.002 degree of its maximum found by a dense
    scan; where the three points rise one way (no vertex), it moves to the highest of them."""
    from types import SimpleNamespace

    from clbeam.imaging.subcell import _arc_polish

    def lobe(a):
        u = np.asarray(a, dtype=np.float64) - 70.0
        return np.exp(-(u / 6.0) ** 2 * np.log(2) + 0.004 * u ** 3)

    def evaluate(r, a):
        return SimpleNamespace(intensity=lobe(a))

    def along(r, a0, a):
        return np.broadcast_to(r, np.shape(a)).copy()

    scan = np.linspace(69.0, 71.0, 200001)
    best = scan[np.argmax(lobe(scan))]
    start = np.array([best + 0.03, best - 0.03])
    r, a = _arc_polish(evaluate, along, np.full(2, 600.0), start, np.full(2, 0.125))
    assert np.all(np.abs(a - best) < 0.002), (a - best, best)
    assert np.all(r == 600.0)
    # a log-convex rise (no vertex between the three): the highest of them, one step on
    def rising(r, a):
        return SimpleNamespace(intensity=np.exp(2.0 * (np.asarray(a) - 70.0) ** 2))
    start = np.array([70.5, 69.5])
    moved = _arc_polish(rising, along, np.full(2, 600.0), start, np.full(2, 0.125))[1]
    assert moved == pytest.approx([70.625, 69.375])


def sequential_merge(refined, r_tol, a_tol):
    """The reference: each entry in order, not yet merged, kept and taking every later one within its
    tolerances not yet merged."""
    n = refined.range_m.size
    r_tol, a_tol = np.broadcast_to(r_tol, (n,)), np.broadcast_to(a_tol, (n,))
    owner = np.full(n, -1)
    for i in range(n):
        if owner[i] < 0:
            owner[i] = i
            same = ((np.abs(refined.range_m - refined.range_m[i]) < r_tol[i])
                    & (np.abs(refined.angle_deg - refined.angle_deg[i]) < a_tol[i]) & (owner < 0))
            owner[same] = i
    kept = np.flatnonzero(owner == np.arange(n))
    return kept, np.bincount(owner, weights=refined.n_cells, minlength=n)[kept]


@pytest.mark.parametrize("seed", range(4))
def test_merge_equals_the_sequential_rule_on_crowded_peaks(seed):
    """Hundreds of refined peaks crowded within a few tolerances (chains of entries each taking the next, ties
    on a rounded range, a NaN position, per-entry and common tolerances): the same entries kept and counts."""
    from clbeam.imaging.subcell import RefinedPeaks, merge_refined

    rng = np.random.default_rng(seed)
    for trial in range(40):
        n = int(rng.integers(0, 400))
        r = np.round(rng.uniform(0, float(rng.choice([1.0, 10.0, 100.0])), n), int(rng.integers(1, 4)))
        a = rng.uniform(-5, 5, n)
        if n > 3:
            a[2] = np.nan
        peaks = RefinedPeaks(r, a, r, r, r, np.zeros((n, 2), dtype=np.int64), rng.integers(1, 4, n))
        r_tol = rng.uniform(0.01, 0.4, n) if trial % 2 else 0.2
        a_tol = rng.uniform(0.1, 2.0, n) if trial % 3 else 0.5
        kept, counts = sequential_merge(peaks, r_tol, a_tol)
        got = merge_refined(peaks, r_tol, a_tol)
        np.testing.assert_array_equal(got.range_m, r[kept])
        np.testing.assert_array_equal(got.n_cells, counts)


@pytest.mark.parametrize("band_hz, length_s, fs, step_m", [((2000.0, 9000.0), 0.08, 40000.0, 0.2),
                                                           ((2000.0, 9000.0), 0.02, 40000.0, 0.4),
                                                           ((1000.0, 20000.0), 0.01, 100000.0, 0.2),
                                                           ((8000.0, 12000.0), 0.005, 48000.0, 0.4)])
def test_node_gain_bounds_the_compressed_lfm_between_nodes(band_hz, length_s, fs, step_m):
    """The matched filter's envelope of the LFM (its autocorrelation, scipy's Hilbert transform, upsampled 16x)
    at its worst offset from the nodes stands at most ``node_gain`` above the largest of the five nodes about
    its peak: within 0.2 dB, the flat band's model against the LFM's rippled spectrum (0.1 dB at most here)."""
    from scipy.signal import hilbert

    from clbeam.imaging.subcell import node_gain
    from clbeam.model.pulse import Pulse

    replica = Pulse(f0_hz=band_hz[0], f1_hz=band_hz[1], duration_s=length_s).replica(fs)
    up, n = 16, 8 * replica.size
    acf = np.roll(np.fft.irfft(np.abs(np.fft.rfft(replica, n)) ** 2, n * up), n * up // 2)
    env = np.abs(hilbert(acf)) ** 2
    peak = int(np.argmax(env))
    node = 2 * step_m / 1500.0 * fs * up                       # one range step in the upsampled samples
    worst = max(env[peak] / np.max(env[peak + np.round((d + np.arange(-2, 3)) * node).astype(int)])
                for d in np.linspace(0.0, 0.5, 101))
    inp = dataclasses.make_dataclass("Inp", ["band_hz", "sound_speed_m_s"])(band_hz, 1500.0)
    grid = PolarGrid(step_m * np.arange(50), np.array([0.0]))
    assert 10 * np.log10(worst) <= 10 * np.log10(node_gain(inp, grid)) + 0.2


def test_peaks_that_cannot_reach_the_snr_test_are_left_out_without_changing_a_kept_one():
    """A noise-free ping: every grid maximum above the CF threshold refined and the SNR test's least intensity
    applied after (the exhaustive rule) keeps the same refined peaks as leaving out, before the searches, those
    the bounds say cannot reach it; most maxima are left out."""
    from clbeam.imaging.postprocess import coherence_peaks, hann_smooth
    from clbeam.imaging.subcell import subcell_peaks

    points = [(70.3, -20.0), (96.1, 15.2), (120.7, 40.4)]
    ping = point_ping([polar_point(r, a) for r, a in points], record_s=0.3)
    # the range sidelobes end 15 m from the echoes: beyond them, maxima on the rounding
    grid = PolarGrid.regular(range_res_m=RANGE_STEP, angle_res_deg=ANGLE_STEP, min_range_m=20.0, max_range_m=200.0,
                             angles_deg=(-45.0, 60.0))
    im = Imager(grid, ImagingOptions(interp="lanczos4"))
    inp = im.beamform_input(ping)
    sums = im.engine.beamform(inp, grid, interp="lanczos4", outputs=("intensity", "cf"))
    cf = hann_smooth(sums.cf)
    cells = coherence_peaks(cf, 0.25)
    least = float(sums.intensity.max()) * 10 ** (-74 / 10)        # the test's floor 80 dB down, 6 dB above it
    common = dict(cf_smooth=cf, intensity=sums.intensity, threshold=0.25)
    every = subcell_peaks(im.engine, inp, grid, cells, interp_mode("lanczos4"), **common)
    every = every.take(np.flatnonzero(every.intensity >= least))
    early = subcell_peaks(im.engine, inp, grid, cells, interp_mode("lanczos4"), least_intensity=least, **common)
    early = early.take(np.flatnonzero(early.intensity >= least))
    searched = refine_peaks(im.engine, inp, grid, cells, interp_mode("lanczos4"), least_intensity=least, **common)
    assert len(early.range_m) >= len(points) and len(cells) > 2 * len(searched.range_m)
    np.testing.assert_array_equal(np.sort(early.range_m), np.sort(every.range_m))
    np.testing.assert_array_equal(np.sort(early.angle_deg), np.sort(every.angle_deg))
    np.testing.assert_array_equal(np.sort(early.intensity), np.sort(every.intensity))
