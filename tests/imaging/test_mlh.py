"""Main-lobe highlight (MLH) suppression: arcs of coherence peaks are one object.

Hand-made CF arrays check the grouping (one arc, two ranges, angular gaps,
arcs about a heaved source), the closed-form sub-cell vertex and the lobe
fit; a simulated Line 1 with seabed clutter checks that precision rises and
recall does not fall.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from clbeam.evaluation.scoring import (
    DetectionScore,
    compare_on_simulation,
    score_detections,
)
from clbeam.imaging.mlh import (
    MLH_COLUMNS,
    default_range_tolerance_m,
    detection_rows,
    main_lobe_u,
    parabolic_vertex,
    pulse_range_resolution_m,
    suppress_main_lobe_highlights,
)
from clbeam.imaging.peaks import PingContext, peak_rows
from clbeam.imaging.postprocess import coherence_peaks, hann_smooth
from clbeam.io.peaks import PEAK_COLUMNS
from clbeam.model.grid import PolarGrid

# a window at 40 degrees, 95-110 m, on the paper's 0.2 m x 0.1 degree cells
GRID = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, min_range_m=95.0, max_range_m=110.0,
                         angles_deg=(25.0, 55.0))
U = np.sin(np.deg2rad(GRID.angles_deg))[:, None]
R = GRID.ranges_m[None, :]


def ring(r0_m: float, width_m: float = 0.3) -> np.ndarray:
    """Gaussian ridge along range centred on ``r0_m``."""
    return np.exp(-((R - r0_m) ** 2) / (2 * width_m**2))


def rippled_lobe(u0: float, *, peak: float = 0.9, width_u: float = 0.03, ripple_u: float = 0.02) -> np.ndarray:
    """A main lobe in direction cosine with a ripple that leaves regional maxima
    on its flanks (the paper's MLH: CF fluctuating along the arc)."""
    x = U - u0
    return peak * np.exp(-(x**2) / (2 * width_u**2)) * (1 + 0.08 * np.cos(2 * np.pi * x / ripple_u)) / 1.08


def bump(angle_deg: float, r0_m: float, peak: float = 0.8) -> np.ndarray:
    """A compact CF bump at one cell."""
    th = np.deg2rad(GRID.angles_deg)[:, None]
    return peak * np.exp(-((th - np.deg2rad(angle_deg)) ** 2) / (2 * np.deg2rad(0.2) ** 2)) * ring(r0_m, 0.2)


def idx_of(cf: np.ndarray) -> tuple[int, int]:
    ia, ir = np.unravel_index(np.argmax(cf), cf.shape)
    return int(ia), int(ir)


# ---------------------------------------------------------------------------
# defaults from the physics
# ---------------------------------------------------------------------------
def test_defaults_follow_the_sbp29_physics():
    # 2-9 kHz: c / (2 B) = 1500 / 14000
    assert pulse_range_resolution_m() == pytest.approx(0.107142857, rel=1e-8)
    # lambda at 5.5 kHz over 3.528 m: 0.272727 / 3.528
    assert main_lobe_u() == pytest.approx(0.0773036, rel=1e-5)
    # 4.43 degrees at nadir, about 10.3 degrees at 64.5 (pipeline B): lambda / (L cos theta)
    assert math.degrees(main_lobe_u()) == pytest.approx(4.429, abs=1e-3)
    assert math.degrees(main_lobe_u() / math.cos(math.radians(64.5))) == pytest.approx(10.29, abs=0.01)
    # range tolerance: c / (2 B) plus the Hann's two non-zero taps of 0.2 m
    assert default_range_tolerance_m(GRID) == pytest.approx(0.107142857 + 0.4, rel=1e-8)


# ---------------------------------------------------------------------------
# grouping on hand-made arrays
# ---------------------------------------------------------------------------
def test_peaks_on_one_arc_become_one_detection_at_the_maximum():
    u0 = math.sin(math.radians(40.0))
    cf = rippled_lobe(u0) * ring(100.3)
    peaks = coherence_peaks(cf, 0.25)
    assert len(peaks) >= 3  # the ripple leaves highlights on the lobe's flanks
    dets = suppress_main_lobe_highlights(peaks, cf, GRID)
    assert len(dets) == 1
    d = dets[0]
    assert (d.angle_index, d.range_index) == idx_of(cf)
    assert d.cf == pytest.approx(cf.max(), rel=1e-12)
    assert d.n_merged == len(peaks)
    angles = GRID.angles_deg[peaks[:, 0]]
    assert d.arc_extent_deg == pytest.approx(np.ptp(angles), abs=1e-9)
    assert d.arc_range_spread_m == pytest.approx(np.ptp(GRID.ranges_m[peaks[:, 1]]), abs=1e-9)
    assert sorted(d.members) == sorted(map(tuple, peaks.tolist()))


def test_two_targets_at_different_ranges_stay_two():
    u0 = math.sin(math.radians(40.0))
    a, b = rippled_lobe(u0) * ring(100.3), 0.9 * rippled_lobe(u0) * ring(103.1)
    cf = np.maximum(a, b)
    peaks = coherence_peaks(cf, 0.25)
    dets = suppress_main_lobe_highlights(peaks, cf, GRID)
    assert len(dets) == 2
    assert [d.range_index for d in dets] == [idx_of(a)[1], idx_of(b)[1]]
    assert dets[0].range_m == pytest.approx(100.3, abs=0.01) and dets[1].range_m == pytest.approx(103.1, abs=0.01)
    assert sum(d.n_merged for d in dets) == len(peaks) and min(d.n_merged for d in dets) >= 3


def test_range_tolerance_splits_beyond_it():
    """Two bumps 1 degree apart: 0.4 m apart in range they are one arc (default
    0.51 m), 0.6 m apart two."""
    near = np.maximum(bump(40.0, 100.0), bump(41.0, 100.4, 0.6))
    far = np.maximum(bump(40.0, 100.0), bump(41.0, 100.6, 0.6))
    for cf, n in ((near, 1), (far, 2)):
        peaks = coherence_peaks(cf, 0.25)
        assert len(peaks) == 2
        assert len(suppress_main_lobe_highlights(peaks, cf, GRID)) == n


def test_angular_gap_larger_than_the_tolerance_splits():
    cf = np.maximum.reduce([bump(30.0, 100.0), bump(32.0, 100.0, 0.7), bump(34.0, 100.0, 0.6),
                            bump(38.0, 100.0, 0.5)])
    peaks = coherence_peaks(cf, 0.25)
    assert len(peaks) == 4
    # gaps 2, 2, 4 degrees: with 2.5 the chain 30-32-34 is contiguous (30 and 34
    # are 4 apart, linked through 32), 38 is split off
    dets = suppress_main_lobe_highlights(peaks, cf, GRID, max_angle_gap_deg=2.5)
    assert [d.n_merged for d in dets] == [3, 1]
    assert dets[0].angle_deg == pytest.approx(30.0, abs=0.05) and dets[1].angle_deg == pytest.approx(38.0, abs=0.05)
    assert dets[0].arc_extent_deg == pytest.approx(4.0, abs=1e-9)
    assert [d.n_merged for d in suppress_main_lobe_highlights(peaks, cf, GRID, max_angle_gap_deg=1.5)] == [1, 1, 1, 1]
    assert [d.n_merged for d in suppress_main_lobe_highlights(peaks, cf, GRID, max_angle_gap_deg=4.5)] == [4]


def test_default_gap_is_one_main_lobe_in_direction_cosine():
    """At 45 degrees, a second peak just inside ``lambda_c / L`` in ``sin(theta)``
    joins the arc; just outside, it stays separate."""
    a0 = 45.0
    ia0 = int(np.argmin(np.abs(GRID.angles_deg - a0)))
    u = np.sin(np.deg2rad(GRID.angles_deg))
    du = u - u[ia0]
    inside = int(np.flatnonzero(du <= 0.97 * main_lobe_u())[-1])
    outside = int(np.flatnonzero(du >= 1.03 * main_lobe_u())[0])
    for ia, n in ((inside, 1), (outside, 2)):
        cf = np.maximum(bump(GRID.angles_deg[ia0], 100.0), bump(GRID.angles_deg[ia], 100.0, 0.6))
        peaks = coherence_peaks(cf, 0.25)
        assert len(peaks) == 2
        assert len(suppress_main_lobe_highlights(peaks, cf, GRID)) == n
    # in degrees that gap is wider than at nadir: lambda / (L cos 45)
    assert GRID.angles_deg[inside] - a0 > math.degrees(main_lobe_u())


def test_arcs_are_centred_on_the_heaved_source():
    """With the source 0.6 m above the grid centre (heave), the arc of one
    two-way time crosses the grid at range ``R_s - 0.6 cos(theta)`` (closed
    form below): peaks on it at 10 and 50 degrees are one object about the
    source but 0.205 m apart in grid range, two with a 0.15 m tolerance."""
    grid = PolarGrid.regular(range_res_m=0.02, angle_res_deg=0.1, min_range_m=98.5, max_range_m=100.5,
                             angles_deg=(0.0, 60.0))
    h, r_s = 0.6, 100.0

    def grid_range(theta_deg):  # |(0, h) + R e| = r_s
        b = h * math.cos(math.radians(theta_deg))
        return -b + math.sqrt(b * b - h * h + r_s * r_s)

    cf = np.zeros(grid.shape)
    for theta, value in ((10.0, 0.8), (50.0, 0.6)):
        ia = int(np.argmin(np.abs(grid.angles_deg - theta)))
        ir = int(np.argmin(np.abs(grid.ranges_m - grid_range(theta))))
        cf[ia, ir] = value
    peaks = coherence_peaks(cf, 0.25)
    assert len(peaks) == 2
    opts = {"range_tolerance_m": 0.15, "max_angle_gap_deg": 45.0}
    assert [d.n_merged for d in suppress_main_lobe_highlights(peaks, cf, grid, source_yz_m=(0.0, -h), **opts)] == [2]
    assert len(suppress_main_lobe_highlights(peaks, cf, grid, **opts)) == 2
    # the peak rows take the source from the ping's context (heave is positive up)
    ping = SimpleNamespace(index=7, latitude_deg=34.3, longitude_deg=-119.8, heading_deg=110.0, roll_deg=0.0,
                           heave_m=h, source_pos_m=np.zeros(3), pulse=None, n_channels=64,
                           element_pos_m=np.c_[np.zeros(64), np.linspace(-1.75, 1.75, 64), np.zeros(64)],
                           sound_speed_m_s=1500.0)
    context = PingContext.of_ping(ping, grid)
    assert context.source_yz_m == (0.0, -h) and context.centre_yz_m == (0.0, 0.0)
    rows = peak_rows(context, cf, None, grid, mlh=True, **opts)
    assert [r["n_merged"] for r in rows] == [2] and rows[0]["ping_latitude_deg"] == 34.3 and rows[0]["ping"] == 7
    unheaved = PingContext(index=7, centre_yz_m=(0.0, 0.0))
    assert len(peak_rows(unheaved, cf, None, grid, mlh=True, **opts)) == 2


# ---------------------------------------------------------------------------
# sub-cell position
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("x0", [-0.45, -0.2, 0.0, 0.13, 0.4])
def test_parabolic_vertex_of_a_sampled_parabola_is_exact(x0):
    f = 0.9 - 0.3 * (np.array([-1.0, 0.0, 1.0]) - x0) ** 2
    assert parabolic_vertex(*f) == pytest.approx(x0, abs=1e-12)


@pytest.mark.parametrize("x0", [-0.4, -0.1, 0.3])
def test_parabolic_vertex_of_a_sampled_gaussian_lobe(x0):
    """Exact in the logarithms; the plain parabola is biased towards the
    centre cell, by less than 0.015 cell for a lobe 2 cells wide (sigma), and
    by less than 0.05 cell for 1 cell."""
    for sigma, tol in ((2.0, 0.015), (1.0, 0.05)):
        f = np.exp(-((np.array([-1.0, 0.0, 1.0]) - x0) ** 2) / (2 * sigma**2))
        assert parabolic_vertex(*f, kind="gaussian") == pytest.approx(x0, abs=1e-12)
        err = parabolic_vertex(*f) - x0
        assert abs(err) <= tol
        assert err * x0 < 0  # pulled towards the centre sample


def test_parabolic_vertex_is_clamped_and_zero_without_a_vertex():
    assert parabolic_vertex(0.5, 0.6, 0.7) == 0.0  # monotonic: no vertex
    assert parabolic_vertex(0.5, 0.5, 0.5) == 0.0  # plateau
    assert parabolic_vertex(0.0, 1.0, 0.999) == pytest.approx(0.999 / 2.002, abs=1e-12)
    assert parabolic_vertex(0.5, 0.9, 1.0, max_offset=0.5) == 0.5  # vertex at +1.5 cells: clamped
    got = parabolic_vertex(np.array([0.0, 0.5]), np.array([1.0, 0.6]), np.array([0.5, 0.7]))
    assert got[0] == pytest.approx(1 / 6, abs=1e-12) and got[1] == 0.0  # (f- - f+) / (2 (f- - 2 f0 + f+))


def test_detection_sits_at_the_closed_form_vertex_in_range_and_angle():
    """A CF that is a paraboloid around cell (ia0, ir0) with its vertex
    (+0.3, -0.2) cells away: the detection is there, and y, z follow."""
    ia0, ir0 = 150, 30
    ia = np.arange(GRID.shape[0])[:, None]
    ir = np.arange(GRID.shape[1])[None, :]
    cf = np.clip(0.9 - 0.01 * (ia - ia0 - 0.3) ** 2 - 0.02 * (ir - ir0 + 0.2) ** 2, 0, None)
    dets = suppress_main_lobe_highlights(coherence_peaks(cf, 0.25), cf, GRID)
    assert len(dets) == 1
    d = dets[0]
    angle = GRID.angles_deg[ia0] + 0.3 * 0.1
    rng = GRID.ranges_m[ir0] - 0.2 * 0.2
    assert d.angle_deg == pytest.approx(angle, abs=1e-9) and d.range_m == pytest.approx(rng, abs=1e-9)
    assert d.y_m == pytest.approx(rng * math.sin(math.radians(angle)), abs=1e-9)
    assert d.z_m == pytest.approx(rng * math.cos(math.radians(angle)), abs=1e-9)


def test_subcell_range_of_a_hann_smoothed_echo():
    """An echo ridge at 100.13 m (between cells), Hann-smoothed as the Imager
    does: symmetric about 100.13 m, so the parabola finds it within 0.02 cell."""
    cf = hann_smooth(rippled_lobe(math.sin(math.radians(40.0))) * ring(100.13, 0.3))
    d = suppress_main_lobe_highlights(coherence_peaks(cf, 0.25), cf, GRID)[0]
    assert d.range_m == pytest.approx(100.13, abs=0.02 * 0.2)


def test_lobe_fit_finds_the_vertex_of_a_lobe_in_direction_cosine():
    """CF parabolic in ``sin(theta)`` with its vertex between grid angles: the
    lobe fit recovers it exactly; the arc's maximum cell is up to half a cell off."""
    u0 = math.sin(math.radians(40.037))
    cf = np.clip(0.9 - ((U - u0) / 0.05) ** 2, 0, None) * ring(100.2)
    d = suppress_main_lobe_highlights(coherence_peaks(cf, 0.25), cf, GRID)[0]
    assert d.lobe_angle_deg == pytest.approx(40.037, abs=1e-7)
    assert d.lobe_range_m == pytest.approx(100.2, abs=1e-9)
    assert d.lobe_y_m == pytest.approx(100.2 * math.sin(math.radians(40.037)), abs=1e-6)
    assert abs(GRID.angles_deg[d.angle_index] - 40.037) <= 0.05 + 1e-9
    assert d.position("lobe")[1] == d.lobe_angle_deg and d.position("peak")[1] == d.angle_deg


def test_lobe_fit_is_absent_for_a_one_cell_spike():
    cf = np.zeros(GRID.shape)
    cf[100, 20] = 0.8
    d = suppress_main_lobe_highlights(coherence_peaks(cf, 0.25), cf, GRID)[0]
    assert math.isnan(d.lobe_angle_deg)
    assert d.position("lobe") == d.position("peak") == (GRID.ranges_m[20], GRID.angles_deg[100], d.y_m, d.z_m)


def test_rows_have_the_peak_columns_and_the_arc_measures():
    cf = rippled_lobe(math.sin(math.radians(40.0))) * ring(100.3)
    intensity = np.full(GRID.shape, 1e-3)
    ia, ir = idx_of(cf)
    intensity[ia, ir] = 2.5e4
    dets = suppress_main_lobe_highlights(coherence_peaks(cf, 0.25), cf, GRID)
    (row,) = detection_rows(dets, 3, intensity, (1.0, -0.5), position="peak")
    assert set(PEAK_COLUMNS) | set(MLH_COLUMNS) | {"centre_y_m", "centre_z_m", "depth_m"} == set(row)
    assert (row["centre_y_m"], row["centre_z_m"]) == (1.0, -0.5)
    assert row["intensity_db"] == pytest.approx(10 * math.log10(2.5e4), abs=1e-9)
    th = math.radians(row["angle_deg"])
    assert row["y_m"] == pytest.approx(1.0 + row["range_m"] * math.sin(th), abs=1e-9)
    assert row["z_m"] == pytest.approx(-0.5 + row["range_m"] * math.cos(th), abs=1e-9)
    assert row["depth_m"] == row["z_m"]  # no draft given: the array reference point at the surface
    assert row["n_merged"] == len(coherence_peaks(cf, 0.25)) and row["arc_extent_deg"] > 1.0


# ---------------------------------------------------------------------------
# scoring
# ---------------------------------------------------------------------------
def test_score_counts_one_to_one_matches():
    truth = [(0.0, 0.0), (10.0, 0.0), (np.nan, np.nan)]
    dets = [(0.5, 0.0), (1.0, 0.0), (10.0, 6.0), (30.0, 0.0)]
    s = score_detections(dets, truth)
    # (0.5, 0) hits the first truth, (1, 0) is its duplicate, (10, 6) is 6 m
    # off vertically (window 5 m), (30, 0) is clutter; the second truth is missed
    assert (s.true_positives, s.false_positives, s.false_negatives) == (1, 3, 1)
    assert s.precision == 0.25 and s.recall == 0.5
    # nearest pairs first: (1.6, 0) takes the truth at 3 m (1.4 m away), (-1, 0) the one at 0
    s2 = score_detections([(1.6, 0.0), (-1.0, 0.0)], [(0.0, 0.0), (3.0, 0.0)])
    assert (s2.true_positives, s2.false_positives, s2.false_negatives) == (2, 0, 0)
    total = s + s2
    assert (total.true_positives, total.false_positives, total.false_negatives) == (3, 3, 1)
    assert math.isnan(DetectionScore().precision) and math.isnan(score_detections([], []).recall)


# ---------------------------------------------------------------------------
# simulated pipelines with seabed clutter
# ---------------------------------------------------------------------------
def test_precision_rises_without_losing_recall_on_line1(cl_engine):
    """The first three pings of Line 1 (three pipelines buried 1 m in 230 m of
    water, rough seabed and sub-bottom, noise, roll and heave), imaged on a
    320-660 m, -80 to -35 degree window.  A detection hits a pipeline within
    2 m horizontally and 5 m vertically of where the imager should show it;
    second peaks on one pipe and all clutter are false positives."""
    res = compare_on_simulation("line1", pings=3, engine=cl_engine)
    print("\n" + "\n".join(res.lines()))
    assert res.n_pings == 3 and res.n_detections < res.n_peaks
    assert res.without.recall >= 0.6  # the scene shows its pipelines at all
    assert res.lobe.precision > res.without.precision
    assert res.lobe.recall >= res.without.recall
    # each merged arc removes a false positive, never a hit
    assert res.lobe.false_positives < res.without.false_positives


def test_clbeam_image_mlh_merges_every_coherence_peak_into_one_detection(tmp_path):
    """Through the command line: each raw coherence peak of the image lands
    in exactly one detection (the n_merged add up to the raw peak count)."""
    from clbeam import cli
    from clbeam.io.images import open_images
    from clbeam.io.peaks import read_peaks_csv
    from clbeam.io.pingwrite import write_ping_file
    from clbeam.sim import load_scene, simulate

    ping_file = write_ping_file(simulate(load_scene("line1", pings=1, max_range_m=520)), tmp_path / "p.nc")
    # every raw peak counted: the clutter test (a separate gate) off
    grid = ["--min-range", "420", "--max-range", "520", "--angles", "-75", "-55", "--min-contrast-db", "off"]
    assert cli.main(["image", str(ping_file), "-o", str(tmp_path / "a.nc"), *grid, "--peaks",
                     str(tmp_path / "a.csv"), "--no-refine", "-q"]) == 0
    assert cli.main(["image", str(ping_file), "-o", str(tmp_path / "b.nc"), *grid, "--mlh", "--peaks",
                     str(tmp_path / "b.csv"), "--outputs", "intensity,cf,cf_smooth", "-q"]) == 0
    raw, merged = read_peaks_csv(tmp_path / "a.csv"), read_peaks_csv(tmp_path / "b.csv")
    with open_images(tmp_path / "b.nc") as ds:
        n_raw = len(coherence_peaks(ds["cf_smooth"].values[0], 0.25))
    assert len(raw) == n_raw > len(merged) > 0
    assert sum(int(r["n_merged"]) for r in merged) == n_raw
    assert all(set(MLH_COLUMNS) <= set(r) for r in merged)
