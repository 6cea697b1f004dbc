"""The benchmark's measures against closed forms, and one tiny run."""

import numpy as np
import pytest
from scenes import point_ping, polar_point

from clbeam.evaluation.bench import (
    BenchResult,
    BenchRow,
    Case,
    intensity_error_db,
    markdown_table,
    peak_agreement,
    run_benchmark,
    target_rows,
    write_report,
)
from clbeam.model.grid import PolarGrid


def test_intensity_error_of_a_10_percent_gain_error_is_minus_20_db():
    exact = np.random.default_rng(0).uniform(1, 2, (20, 30))
    assert intensity_error_db(1.1 * exact, exact) == pytest.approx(-20.0, abs=1e-9)
    # cells more than 40 dB below the maximum are left out
    exact[0, 0] = 1e-6
    got = 1.1 * exact
    got[0, 0] = 1.0
    assert intensity_error_db(got, exact) == pytest.approx(-20.0, abs=1e-9)


def test_peak_agreement_within_one_cell():
    cf = np.zeros((20, 20))
    cf[5, 5] = cf[12, 14] = 0.9
    shifted = np.roll(cf, 1, axis=1)
    assert peak_agreement(shifted, cf, 0.25) == (1.0, 1.0)
    far = np.roll(cf, 3, axis=0)
    assert peak_agreement(far, cf, 0.25) == (0.0, 0.0)
    half = cf.copy()
    half[12, 14] = 0
    assert peak_agreement(half, cf, 0.25) == (1.0, 0.5)


def test_targets_say_met_or_by_how_much_not():
    auto = BenchRow("lanczos4", 1, "float32", 330.0, 1.7e9, -48.6, 0.003, 1.0, 1.0, x_numpy=182.0, x_numba=9.3,
                    beams="x1.5/8", budget_db=-40.0)
    result = BenchResult([auto], 9.4e6, 1.1e8, {"total_ms": 503.0}, [{"what": "seabed band -5/+40 m",
                                                                       "ms_per_ping": 397.0}],
                         command={"pings": 4, "total_s": 11.5, "s_per_ping": 2.0, "start_up_s": 0.45,
                                  "one_time_s": 3.4},
                         zoo_commands={"bench": {"s_per_ping": 0.5, "one_time_s": 3.0, "start_up_s": 0.4},
                                       "jump": {"s_per_ping": 7.3, "one_time_s": 9.0, "start_up_s": 0.4},
                                       "points": {"s_per_ping": 1.1, "one_time_s": 6.0, "start_up_s": 0.4}})
    targets = {what: (got, target) for what, got, target, _ in target_rows(result)}
    assert targets["default setting: beamforming"] == (330.0, 250.0)
    assert targets["default setting: x numba baseline"] == (9.3, 10.0)
    assert targets["clbeam image, launch to the first ping's work"] == (0.45, 0.5)
    assert "-60 dB setting: beamforming" not in targets   # no such row measured
    table = markdown_table(result)
    assert "| default setting: beamforming | 330 ms | 250 ms | not met: 1.3x the target |" in table
    assert "| default setting: intensity error | -48.6 dB | -40 dB | met |" in table
    assert "| default setting: x NumPy reference | 182 x | 250 x | not met by 68 x |" in table
    assert "| whole ping with the seabed band | 397 ms | 150 ms | not met: 2.6x the target |" in table
    assert "| clbeam image, launch to the first ping's work | 0.45 s | 0.5 s | met |" in table
    assert "start-up (launch to the first ping's work) 0.45 s, one-time costs 3.40 s" in table
    # the zoo's target is its worst scene's
    assert "| clbeam image, per ping, worst zoo scene (jump) | 7.3 s | 0.7 s | not met: 10.4x the target |" in table
    assert "| points | 1.10 | 6.00 | 0.40 |" in table


def test_tiny_benchmark_run_writes_table_csv_and_plot(tmp_path):
    ping = point_ping([polar_point(60, 20), polar_point(70, -30)], record_s=0.1)
    grid = PolarGrid.regular(range_res_m=0.5, angle_res_deg=1, max_range_m=72, angles_deg=(-40, 40))
    window = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.2, min_range_m=55, max_range_m=65, angles_deg=(15, 25))
    res = run_benchmark(ping, grid=grid, accuracy_grid=window, repeats=1, reference_stride=20,
                        cases=(Case("linear"), Case("lanczos8"), Case("auto", budget_db=-40.0)))
    lin, lz, auto = res.rows
    # Lanczos-8 is far closer to the exact band-limited interpolator than linear
    assert lz.intensity_error_db < lin.intensity_error_db - 20
    # the setting --interp auto picks meets its budget, within the error model's 3 dB
    assert auto.label.startswith("auto -40 dB: ") and auto.intensity_error_db <= -40.0 + 3
    assert np.isfinite(lin.predicted_error_db) and lin.intensity_error_db <= lin.predicted_error_db + 3
    assert lin.cells_ch_per_s == pytest.approx(grid.n_cells * 64 / (lin.ms_per_ping / 1e3), rel=1e-9)
    paths = write_report(res, tmp_path)
    assert "| linear |" in markdown_table(res) and paths["plot"].stat().st_size > 10_000
    # each whole-ping row's stages are timed inside it: they add up to most of its time and never exceed it
    for row in res.skipping:
        stages = row["stages_ms"]
        assert {"direct_s"} <= set(stages) or {"beams_s", "to_grid_s", "flagged_s"} <= set(stages)
        assert ({"smooth_s", "peaks_s"} <= set(stages)) == (row["what"] != "intensity only")  # no CF, no peaks
        assert 0.5 * row["ms_per_ping"] <= sum(stages.values()) <= row["ms_per_ping"]
        assert f"- {row['what']}: compress " in markdown_table(res)


def test_the_zoos_point_echoes_image_where_the_points_are():
    """Each point scene of the zoo (built apart from the imaging code) images its echoes at their points:
    the intensity maximum of a window about each point lies within a range cell and 0.1 degree of it,
    through the jump in the sound speed too (exact eigenray delays against the imager's tables)."""
    from clbeam.evaluation.bench import paper_grid
    from clbeam.evaluation.zoo import zoo
    from clbeam.imaging.imager import Imager, ImagingOptions

    scenes = zoo(paper_grid())
    assert list(scenes) == ["bench", "jittered", "jump", "points", "clutter"]
    for name in ("jittered", "jump", "points"):
        ping, points = scenes[name]
        for r, a, _ in points[::2]:
            window = PolarGrid.regular(range_res_m=0.05, angle_res_deg=0.02, min_range_m=r - 1.0,
                                       max_range_m=r + 1.0, angles_deg=(a - 0.5, a + 0.5))
            img = Imager(window, ImagingOptions(interp="lanczos8", upsample=2, beams=None, refine_peaks=False)).image(ping)
            ia, ir = np.unravel_index(np.argmax(img.intensity), img.intensity.shape)
            assert abs(window.ranges_m[ir] - r) <= 0.2 and abs(window.angles_deg[ia] - a) <= 0.1, (name, r, a)
