"""Imaging through a sound-speed profile: ray-traced travel-time tables in the
kernel and the reference, against the isospeed image (constant profile),
the float64 reference, a point target propagated by exact eigenrays, and the
ping file's svp variables."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from scenes import FS, bandlimited_noise, ping_dataset, profile_point_ping

from clbeam import cli
from clbeam.errors import OptionError, PingFileError
from clbeam.imaging.engine import BeamformInput, get_engine
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.raytrace import travel_time_tables
from clbeam.imaging.seabed_band import pick_seabed_depth_m
from clbeam.io.pingfile import PingFile
from clbeam.io.pingwrite import write_ping_file
from clbeam.model.grid import PolarGrid
from clbeam.model.svp import SoundSpeedProfile, holland_line1_profile

# float32 sums of 8 channels: a few float32 epsilons per channel, x10 margin
F32_REL = 1e-4
SMALL = PolarGrid.regular(range_res_m=0.5, angle_res_deg=2, max_range_m=70.0, angles_deg=(-80, 80))


def noise_input(tables, weights=None):
    data = bandlimited_noise((8, 4000), seed=3)
    data[2, 500:520] = np.nan
    eo = np.zeros((8, 3))
    eo[:, 1] = np.linspace(-1.5, 1.5, 8)
    eo[:, 0] = 0.05  # an along-track offset too
    return BeamformInput(data, FS, 0.0005, 1500.0, eo, np.array([0.0, 0.2, 0.1]), centre_frequency_hz=5500.0,
                         weights=weights, tables=tables)


@pytest.mark.parametrize("mode", ["nearest", "cubic", "lanczos4", "linear-bb"])
def test_constant_profile_tables_reproduce_the_isospeed_image(mode):
    tables = travel_time_tables(SoundSpeedProfile.constant(1500.0), SMALL)
    ref = get_engine("reference")
    iso = ref.beamform(noise_input(None), SMALL, interp=mode, outputs=("intensity", "cf"))
    tab = ref.beamform(noise_input(tables), SMALL, interp=mode, outputs=("intensity", "cf"))
    # float64: the tables' times equal R / c to rounding (1e-12 s is 4e-8 sample)
    np.testing.assert_allclose(tab.intensity, iso.intensity, rtol=1e-7, atol=1e-9 * iso.intensity.max())
    got = get_engine("opencl").beamform(noise_input(tables), SMALL, interp=mode, outputs=("intensity", "cf"))
    assert np.max(np.abs(got.intensity - iso.intensity)) <= F32_REL * iso.intensity.max()
    assert np.max(np.abs(got.cf - iso.cf)) <= F32_REL


@pytest.mark.parametrize("mode, weights", [("cubic", None), ("lanczos8", None), ("linear-bb", None),
                                           ("cubic", np.linspace(0.2, 1.0, 8))])
def test_profile_tables_on_opencl_equal_the_float64_reference(mode, weights):
    tables = travel_time_tables(holland_line1_profile(), SMALL)
    inp = noise_input(tables, weights)
    want = get_engine("reference").beamform(inp, SMALL, interp=mode, outputs=("intensity", "cf", "sums"))
    got = get_engine("opencl").beamform(inp, SMALL, interp=mode, outputs=("intensity", "cf", "sums"))
    assert np.max(np.abs(got.intensity - want.intensity)) <= F32_REL * want.intensity.max()
    assert np.max(np.abs(got.cf - want.cf)) <= F32_REL
    np.testing.assert_array_equal(got.m, want.m)
    # the profile changes the image (1522 m/s near the array against 1500 m/s straight rays)
    iso = get_engine("reference").beamform(noise_input(None, weights), SMALL, interp=mode, outputs=("intensity",))
    assert np.linalg.norm(iso.intensity - want.intensity) > 0.1 * np.linalg.norm(want.intensity)



def test_a_large_grids_kept_cell_tables_follow_the_record_start_and_the_tables(monkeypatch):
    """The engine keeps a large grid's per-cell tables for the next call: a call with another record start,
    or other tables of the same grid, images as a fresh engine does (the float64 reference)."""
    from clbeam.imaging.engine import opencl

    monkeypatch.setattr(opencl, "CACHED_TABLE_CELLS", SMALL.n_cells)   # SMALL counts as large
    engine = get_engine("opencl")
    line1, constant = (travel_time_tables(p, SMALL) for p in (holland_line1_profile(), SoundSpeedProfile.constant(1500.0)))
    first = noise_input(line1)
    engine.beamform(first, SMALL, interp="cubic", outputs=("intensity",))
    assert engine._cell_tables[1] is not None
    later = noise_input(line1)
    later = BeamformInput(later.data, FS, 0.0007, 1500.0, later.element_offsets_m, later.source_offset_m,
                          centre_frequency_hz=5500.0, tables=line1)
    for inp in (later, noise_input(constant), first):
        want = get_engine("reference").beamform(inp, SMALL, interp="cubic", outputs=("intensity",))
        got = engine.beamform(inp, SMALL, interp="cubic", outputs=("intensity",))
        assert np.max(np.abs(got.intensity - want.intensity)) <= F32_REL * want.intensity.max()
    # the same tables again: their tiles stay on the device, none padded or uploaded anew, the same image
    padded, pad = [], opencl._padded_table
    monkeypatch.setattr(opencl, "_padded_table", lambda *a: padded.append(a) or pad(*a))
    again = engine.beamform(first, SMALL, interp="cubic", outputs=("intensity",))
    assert padded == [] and engine._table_tiles
    np.testing.assert_array_equal(again.intensity, got.intensity)

def test_unreachable_cells_are_skipped_not_imaged():
    # 1480 m/s at the centre over much faster water: near-horizontal rays turn
    # back up within metres, so cells far out at 85-89 degrees are in the shadow
    prof = SoundSpeedProfile([0.0, 10.0], [1480.0, 1700.0])
    grid = PolarGrid.regular(range_res_m=0.5, angle_res_deg=1, max_range_m=70.0, angles_deg=(-89, 89))
    tables = travel_time_tables(prof, grid)
    assert (~tables.reachable).any() and tables.reachable.any()
    inp = noise_input(tables)
    for eng in (get_engine("reference"), get_engine("opencl")):
        res = eng.beamform(inp, grid, interp="cubic", outputs=("sums", "cf"))
        assert np.all(res.m[~tables.reachable] == 0)
        assert np.all(np.isfinite(res.cf)) and res.cf.max() <= 1 + F32_REL
        assert res.m[tables.reachable].max() == 8


@pytest.fixture(scope="module")
def seabed_target():
    """A point on the seabed at 1 km across, 224 m below the transducers, in
    the paper's profile, propagated by exact eigenrays."""
    truth = np.array([1000.0, 224.0])
    ping = profile_point_ping([truth], holland_line1_profile(), record_s=1.45)
    r, a = np.hypot(*truth), np.degrees(np.arctan2(*truth))
    grid = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.05, min_range_m=r - 40, max_range_m=r + 40,
                             angles_deg=(a - 4, a + 4))
    return ping, grid, truth


def peak_position(img, grid):
    ia, ir = np.unravel_index(np.argmax(img.intensity), img.intensity.shape)
    r, a = grid.ranges_m[ir], np.deg2rad(grid.angles_deg[ia])
    return np.array([r * np.sin(a), r * np.cos(a)]), float(img.cf[ia, ir])


def test_a_target_at_1_km_is_imaged_in_place_with_the_profile_and_misplaced_with_straight_rays(seabed_target):
    ping, grid, truth = seabed_target
    with_profile, cf = peak_position(Imager(grid, ImagingOptions(interp="cubic")).image(ping), grid)
    straight, _ = peak_position(Imager(grid, ImagingOptions(interp="cubic", use_svp=False)).image(ping), grid)
    # one cell: 0.2 m in range, 0.05 degree (0.9 m) across the arc
    assert np.hypot(*(with_profile - truth)) <= 1.0 and cf > 0.99
    # straight rays at the transducers' 1522 m/s follow the array's arrival
    # direction (80 degrees from nadir) instead of the bent ray: measured
    # +19.5 m across and -44.7 m in depth
    err = straight - truth
    assert err[0] > 10 and err[1] < -30


def test_seabed_pick_with_the_profile_inverts_the_vertical_travel_time():
    prof = holland_line1_profile()
    ping = profile_point_ping([[0.0, 224.0]], prof, record_s=0.4)
    inp = Imager(SMALL, ImagingOptions()).beamform_input(ping)
    # the first strong return starts a little before the echo's peak (20 dB down): within 0.5 m
    assert pick_seabed_depth_m(inp, profile=prof) == pytest.approx(224.0, abs=0.5)
    # with straight rays at 1522 m/s the same time reads ~2 m deeper (harmonic mean 1505 m/s)
    assert pick_seabed_depth_m(inp) > 225.5


def test_a_sediment_speed_without_a_seabed_depth_picks_the_seabed_from_the_ping():
    """A sediment speed alone: the seabed is picked from the ping's own compressed channels, before the
    setting is chosen, and the image equals the one made with that pick given as the seabed depth."""
    prof = holland_line1_profile()
    ping = profile_point_ping([[0.0, 224.0]], prof, record_s=0.4)
    grid = PolarGrid.regular(range_res_m=0.5, angle_res_deg=1.0, min_range_m=210.0, max_range_m=260.0,
                             angles_deg=(-10, 10))
    opts = dict(interp="cubic", upsample=2, beams=None, refine_peaks=False)
    inp = Imager(SMALL, ImagingOptions(interp="cubic", upsample=1, beams=None)).beamform_input(ping)
    centre_z = float(SMALL.centre(tuple(ping.source_pos_m[1:]))[1])
    depth = pick_seabed_depth_m(inp, profile=prof, centre_depth_m=centre_z)
    assert depth == pytest.approx(224.0 - centre_z, abs=0.5)
    picked = Imager(grid, ImagingOptions(sediment_speed_m_s=1600.0, **opts)).image(ping)
    given = Imager(grid, ImagingOptions(sediment_speed_m_s=1600.0, seabed_depth_m=depth, **opts)).image(ping)
    assert picked.intensity.max() > 0
    np.testing.assert_array_equal(picked.intensity, given.intensity)
    np.testing.assert_array_equal(picked.cf, given.cf)


def test_ping_file_svp_is_read_validated_and_used_by_clbeam_image(seabed_target, tmp_path):
    ping, grid, truth = seabed_target
    prof = ping.svp
    ds = ping_dataset(ping)
    path = write_ping_file(ds, tmp_path / "svp.nc")
    with PingFile(path) as f:
        assert f.ping(0).svp == prof
    r0, r1 = grid.ranges_m[[0, -1]]
    a0, a1 = grid.angles_deg[[0, -1]]
    args = ["--min-range", f"{r0}", "--max-range", f"{r1}", "--angles", f"{a0}", f"{a1}", "--angle-res", "0.05", "-q"]
    for flag, near in (([], True), (["--isospeed"], False)):
        out = tmp_path / f"img{len(flag)}.nc"
        assert cli.main(["image", str(path), "-o", str(out), *args, *flag]) == 0
        with xr.open_dataset(out) as img:
            ia, ir = np.unravel_index(int(np.argmax(img["intensity"].values[0])), img["intensity"].shape[1:])
            r, a = float(img["range"][ir]), np.deg2rad(float(img["angle"][ia]))
            assert (np.hypot(r * np.sin(a) - truth[0], r * np.cos(a) - truth[1]) <= 1.0) == near
    fast = prof.speeds_m_s.copy()
    fast[-1] = 2500.0
    for bad, words in ((ds.assign(svp_speed=("svp", fast)), "sound-speed profile 'svp_depth'/'svp_speed'"),
                       (ds.assign(svp_depth=("svp", prof.depths_m[::-1])), "sound-speed profile"),
                       (ds.drop_vars("svp_speed"), "needs its partner 'svp_speed'")):
        with pytest.raises(PingFileError, match=words):
            PingFile(write_ping_file(bad, tmp_path / "bad.nc"))


def test_sediment_speed_option_is_checked():
    with pytest.raises(OptionError, match="sediment speed"):
        ImagingOptions(sediment_speed_m_s=900.0)


def test_a_ping_without_usable_channels_images_empty_with_a_sediment_speed(seabed_target):
    import dataclasses

    ping, grid, _ = seabed_target
    dead = dataclasses.replace(ping, channel_valid=np.zeros(ping.n_channels, dtype=bool))
    img = Imager(grid, ImagingOptions(sediment_speed_m_s=1600.0)).image(dead)
    assert img.n_channels_used == 0 and np.all(img.intensity == 0) and np.all(img.cf == 0)
