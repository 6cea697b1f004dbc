"""Beam-sampled imaging and sub-cell peaks through sound-speed profiles with jumps and gradients.

Echoes are propagated by exact eigenrays (``scenes.profile_point_ping``); the beam-sampled default must
give the image that direct imaging gives with the same tables, within the error budget, and put every
point's refined peak within a range cell and 0.1 degree of where it is.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest
from scenes import profile_point_ping

from clbeam.imaging.engine import BeamformInput
from clbeam.imaging.engine.beams import BeamSampling, angular_band_limit, refracted_band_limit
from clbeam.imaging.equal_delay import EqualDelay, TableEqualDelay
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.raytrace import element_travel_times, travel_time_tables
from clbeam.model.grid import PolarGrid
from clbeam.model.svp import SoundSpeedProfile

GRID = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, max_range_m=300.0, angles_deg=(-40, 40))
POINTS_YZ = np.array([[60.0, 150.0], [-120.0, 180.0], [140.0, 210.0], [20.0, 240.0], [-45.0, 255.0]])
PROFILES = {
    "jump +60 m/s at 80 m": SoundSpeedProfile([0.0, 80.0, 80.0, 400.0], [1500.0, 1500.0, 1560.0, 1560.0]),
    "jump -80 m/s at 120 m": SoundSpeedProfile([0.0, 120.0, 120.0, 400.0], [1530.0, 1530.0, 1450.0, 1450.0]),
    "gradient 1540 -> 1480 m/s": SoundSpeedProfile([0.0, 300.0], [1540.0, 1480.0]),
}
#: the default budget: intensity error (dB of the image's peak power) and CF error, on cells within 40 dB
MAX_ERROR_DB, MAX_CF_ERROR, DYNAMIC_RANGE_DB = -40.0, 0.02, 40.0


@pytest.fixture(scope="module", params=list(PROFILES))
def refracted(request):
    profile = PROFILES[request.param]
    ping = profile_point_ping(POINTS_YZ, profile, record_s=0.45)
    imager = Imager(GRID, ImagingOptions(outputs=("intensity", "cf")))
    default, setting = imager.image(ping), imager.setting_of(ping)
    # direct imaging with the default's own time interpolation: the difference is the beams' alone
    direct = Imager(GRID, ImagingOptions(outputs=("intensity", "cf"), beams=None, interp=setting.interp,
                                         upsample=setting.upsample, refine_peaks=False)).image(ping)
    return request.param, default, direct


def test_beam_sampled_image_through_a_profile_equals_the_direct_image_within_the_budget(refracted):
    name, default, direct = refracted
    assert "beams" in default.setting and "direct" in direct.setting, (default.setting, direct.setting)
    top = direct.intensity.max()
    err_db = 10 * np.log10(np.mean((np.sqrt(default.intensity) - np.sqrt(direct.intensity)) ** 2) /
                           np.mean(direct.intensity))
    assert err_db <= MAX_ERROR_DB, (name, err_db)
    bright = direct.intensity >= top * 10 ** (-DYNAMIC_RANGE_DB / 10)
    assert np.max(np.abs(default.cf[bright] - direct.cf[bright])) <= MAX_CF_ERROR, name


def test_refracted_points_are_imaged_within_a_cell_and_a_tenth_of_a_degree(refracted):
    name, default, _ = refracted
    for y, z in POINTS_YZ:
        r, th = np.hypot(y, z), np.degrees(np.arctan2(y, z))
        peak = min(default.peaks, key=lambda p: abs(p["range_m"] - r) / 0.2 + abs(p["angle_deg"] - th) / 0.1)
        assert abs(peak["range_m"] - r) <= 0.2 and abs(peak["angle_deg"] - th) <= 0.1, (name, r, th, peak)
        assert peak["cf"] >= 0.99, (name, r, th, peak["cf"])


def _input(profile, grid):
    offsets = np.zeros((16, 3))
    offsets[:, 1] = np.linspace(-1.75, 1.75, 16)
    tables = travel_time_tables(profile, grid)
    return BeamformInput(np.zeros((16, 100), complex), 40000.0, 0.0, 1500.0, offsets, np.zeros(3),
                         band_hz=(2000.0, 9000.0), tables=tables), tables


def test_refracted_band_limit_covers_the_eikonal_rate_of_the_centre_time():
    """dT/dtheta at fixed R is R sin(phi_c - theta) / c(z) (the slowness along the arc), phi_c from Snell's
    law with the eigenray's launch angle; the probe's finite differences times its margin must bound it."""
    profile = PROFILES["jump +60 m/s at 80 m"]
    fine = PolarGrid.beams(np.linspace(90.0, 300.0, 43), np.linspace(-40.0, 40.0, 321))
    _, tables = _input(profile, fine)
    r = fine.ranges_m[None, :]
    th = np.deg2rad(fine.angles_deg)[:, None]
    z = r * np.cos(th)
    c = profile.speed(z)
    sin_c = np.clip(tables.launch_sin * c / tables.centre_speed_m_s, -1, 1)
    rate = np.abs(r * np.sin(np.arcsin(sin_c) - th) / c)
    coarse = PolarGrid.beams(np.linspace(90.0, 300.0, 8), np.linspace(-40.0, 40.0, 81))
    _, probe = _input(profile, coarse)
    f_top = 9000.0
    limit = refracted_band_limit(0.0, probe, f_top)
    assert limit >= 2 * f_top * rate.max()
    assert limit <= 1.6 * 2 * f_top * rate.max()  # the margin, not more


def test_refracted_band_limit_of_isospeed_tables_is_the_arrays():
    profile = SoundSpeedProfile.constant(1500.0)
    inp, tables = _input(profile, GRID)
    base = angular_band_limit(inp.element_offsets_m, inp.source_offset_m, 9000.0, 1500.0, GRID.angles_deg)
    got = refracted_band_limit(base, tables, 9000.0)
    # isospeed: T = R / c does not turn with angle, the launch angle is the cell's
    np.testing.assert_allclose(got, 1.25 * base, rtol=1e-6)


def test_a_profile_whose_rates_leave_no_saving_images_directly(caplog, monkeypatch):
    """A strong shallow jump over a wide swath: the beams would be as many as the angles, so the engine
    images every cell directly and the setting says so; the log says why once, not at every ping."""
    from clbeam.imaging.engine import common

    monkeypatch.setattr(common, "_TOLD", set())
    caplog.set_level(logging.INFO, logger="clbeam")
    profile = SoundSpeedProfile([0.0, 20.0, 20.0, 200.0], [1450.0, 1450.0, 1650.0, 1650.0])
    grid = PolarGrid.regular(range_res_m=1.0, angle_res_deg=1.0, max_range_m=120.0, angles_deg=(-60, 60))
    ping = profile_point_ping(np.array([[30.0, 80.0]]), profile, record_s=0.2)
    options = dict(outputs=("intensity", "cf"), interp="lanczos4", refine_peaks=False)
    img = Imager(grid, ImagingOptions(beams=BeamSampling(1.5, 8), **options)).image(ping)
    direct = Imager(grid, ImagingOptions(beams=None, **options)).image(ping)
    assert "beams off" in img.setting and "beams off" not in direct.setting
    Imager(grid, ImagingOptions(beams=BeamSampling(1.5, 8), **options)).image(ping)
    told = [r for r in caplog.records if r.getMessage().startswith("beams off")]
    assert len(told) == 1 and "cycles per radian" in told[0].getMessage()
    np.testing.assert_array_equal(img.intensity, direct.intensity)
    np.testing.assert_array_equal(img.cf, direct.cf)


def test_table_equal_delay_keeps_the_exact_two_way_time():
    """The curve's range at another angle has the exact eigenray two-way time of the start point (source and
    elements from ``element_travel_times``) to first order in their offsets: within 1 mm of path."""
    profile = PROFILES["jump +60 m/s at 80 m"]
    grid = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, max_range_m=300.0, angles_deg=(20, 40))
    inp, tables = _input(profile, grid)
    curve = TableEqualDelay(inp, tables, grid)
    r0, a0 = 252.0, 33.0
    to = np.array([31.0, 32.0, 34.0, 35.0])
    r1 = curve(r0, a0, to)

    def two_way(r, a):
        yz = np.stack([r * np.sin(np.deg2rad(a)), r * np.cos(np.deg2rad(a))], axis=-1).reshape(-1, 2)
        t_src = element_travel_times(profile, np.zeros((1, 2)), yz)[0]
        t_rx = element_travel_times(profile, inp.element_offsets_m[:, 1:], yz).mean(axis=0)
        return t_src + t_rx

    np.testing.assert_allclose(two_way(r1, to), two_way(np.array([r0]), np.array([a0]))[0], atol=1e-3 / 1500)
    # the straight-ray curve is the grid's arc here: it misses the delay by metres of path
    straight = EqualDelay(inp)(r0, a0, to)
    assert np.max(np.abs(two_way(straight, to) - two_way(np.array([r0]), np.array([a0])))) * 1500 > 0.05


def test_a_profile_that_stops_above_the_grid_is_refused_in_one_line(tmp_path, capsys):
    """A cast that ends at 200 m while the grid reaches 300 m: the speed below would be a guess."""
    from scenes import ping_dataset

    from clbeam import cli
    from clbeam.errors import GridError

    short = SoundSpeedProfile([0.0, 80.0, 80.0, 200.0], [1500.0, 1500.0, 1560.0, 1560.0])
    ping = profile_point_ping(POINTS_YZ[:1], short, record_s=0.45)
    with pytest.raises(GridError, match=r"ends at 200 m but the grid reaches 300\.0 m"):
        Imager(GRID, ImagingOptions(outputs=("intensity", "cf"))).image(ping)
    # the grid's deepest cell is at its smallest |angle|: a starboard-only swath reaches R cos(20 deg)
    side = PolarGrid.regular(range_res_m=0.5, angle_res_deg=0.5, max_range_m=210.0, angles_deg=(20, 40))
    img = Imager(side, ImagingOptions(outputs=("intensity", "cf"), refine_peaks=False)).image(ping)
    assert img.cf.shape == side.shape
    ping_dataset(ping).to_netcdf(tmp_path / "p.nc")
    rc = cli.main(["image", str(tmp_path / "p.nc"), "-o", str(tmp_path / "i.nc"), "--max-range", "300",
                   "--angles", "-40", "40", "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "svp_depth" in err[0], err
    # --isospeed ignores the profile
    assert cli.main(["image", str(tmp_path / "p.nc"), "-o", str(tmp_path / "i.nc"), "--max-range", "300",
                     "--angles", "-40", "40", "-q", "--isospeed"]) == 0
