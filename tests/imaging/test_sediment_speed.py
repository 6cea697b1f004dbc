"""Sediment interval velocity from the coherence of a sub-bottom reflector:
the scan on a simulated flat reflector of known speed (propagated by exact
eigenrays through the refracting seabed), and its parts against closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from scenes import profile_point_ping

from clbeam import cli
from clbeam.errors import OptionError
from clbeam.imaging.sediment_speed import (
    refine_maximum,
    reflector_coherence,
    scan_sediment_speed,
)
from clbeam.model.grid import PolarGrid
from clbeam.model.svp import SoundSpeedProfile

SEABED_M, BELOW_M, SEDIMENT_M_S = 50.0, 8.0, 1600.0


def test_reflector_coherence_sums_the_cf_of_aligned_detections():
    value, depth = reflector_coherence(np.array([58.0, 58.0, 61.0]), np.array([0.6, 0.9, 0.8]), 0.1)
    # two detections at 58 m add up; the third, 30 sigma away, adds exp(-450) ~ 0
    assert value == pytest.approx(1.5, abs=1e-6) and depth == pytest.approx(58.0, abs=0.011)
    assert reflector_coherence(np.array([]), np.array([]), 0.1)[0] == 0.0


def test_refined_maximum_is_the_vertex_of_a_sampled_parabola():
    x = np.arange(1500.0, 1700.0, 10.0)
    assert refine_maximum(x, -(x - 1603.7) ** 2) == pytest.approx(1603.7, abs=1e-9)
    assert refine_maximum(x, x) == x[-1]  # at an end: no vertex


def test_candidate_speeds_are_checked():
    with pytest.raises(OptionError, match="at least 3"):
        scan_sediment_speed(None, None, seabed_depth_m=50, speeds_m_s=[1500, 1600])
    with pytest.raises(OptionError, match="equally spaced"):
        scan_sediment_speed(None, None, seabed_depth_m=50, speeds_m_s=[1500, 1600, 1650])


@pytest.fixture(scope="module")
def reflector(tmp_path_factory):
    """480 scatterers on a flat horizon 8 m below a 50 m seabed of 1600 m/s sediment."""
    prof = SoundSpeedProfile.with_sediment(SoundSpeedProfile.constant(1500.0), SEABED_M, SEDIMENT_M_S)
    rng = np.random.default_rng(0)
    y = np.arange(-120, 120, 0.5) + rng.uniform(-0.2, 0.2, 480)
    ping = profile_point_ping(np.stack([y, np.full(y.size, SEABED_M + BELOW_M)], axis=1), prof, record_s=0.3)
    z = SEABED_M + BELOW_M
    grid = PolarGrid.regular(range_res_m=0.1, angle_res_deg=0.2, min_range_m=z - 4,
                             max_range_m=(z + 6) / np.cos(np.deg2rad(66)), angles_deg=(-66, 66))
    return ping, grid


@pytest.mark.slow
def test_scan_finds_the_sediment_speed_within_one_percent(reflector):
    ping, grid = reflector
    from dataclasses import replace

    ping = replace(ping, svp=None)  # the imager knows only the water speed and the seabed
    scan = scan_sediment_speed(ping, grid, seabed_depth_m=SEABED_M, speeds_m_s=np.arange(1500.0, 1731.0, 10.0))
    # measured 1601.2 m/s (0.07 %); the reflector at its true depth there
    assert abs(scan.estimate_m_s / SEDIMENT_M_S - 1) < 0.01
    i = int(np.argmax(scan.coherence))
    assert scan.reflector_depth_m[i] == pytest.approx(SEABED_M + BELOW_M, abs=0.2)
    # the coherence falls away from the true speed by more than its scatter
    far = np.abs(scan.speeds_m_s - SEDIMENT_M_S) >= 60
    assert scan.coherence[far].max() < 0.7 * scan.coherence.max()


@pytest.mark.slow
def test_clbeam_sediment_speed_prints_the_estimate_and_writes_the_scan(reflector, tmp_path, capsys):
    from dataclasses import replace

    from scenes import ping_dataset

    from clbeam.io.pingwrite import write_ping_file

    ping, grid = reflector
    path = write_ping_file(ping_dataset(replace(ping, svp=None)), tmp_path / "reflector.nc")
    args = ["sediment-speed", str(path), "--seabed-depth", str(SEABED_M), "--speeds", "1560", "1640", "10",
            "--range-res", "0.1", "--angle-res", "0.2", "--min-range", f"{grid.ranges_m[0]}",
            "--max-range", f"{grid.ranges_m[-1]}", "--angles", "-66", "66", "-o", str(tmp_path / "scan.csv")]
    assert cli.main([*args, "-q"]) == 0
    estimate = float(capsys.readouterr().out.split("estimate:")[1].split()[0])
    assert abs(estimate / SEDIMENT_M_S - 1) < 0.01
    rows = np.loadtxt(tmp_path / "scan.csv", delimiter=",", skiprows=1)
    assert rows.shape == (9, 4) and rows[:, 0].tolist() == list(np.arange(1560.0, 1641.0, 10.0))
    assert cli.main(["sediment-speed", str(path), "-q"]) == 2  # no seabed depth: one-line error


def test_a_scan_without_any_sub_bottom_detection_is_an_error_not_an_estimate(reflector):
    ping, grid = reflector
    from dataclasses import replace

    with pytest.raises(OptionError, match="no coherence detection"):
        # the seabed put below the whole window: nothing can lie under it
        scan_sediment_speed(replace(ping, svp=None), grid, seabed_depth_m=200.0, speeds_m_s=[1590.0, 1600.0, 1610.0])
