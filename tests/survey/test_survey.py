"""Whole surveys (clbeam.survey): resume after kill -9, Dask equals one
process, georeferencing against hand-computed positions, association,
bad inputs, parameter locking.

The line is the simulator's Line 1 (docs/simulator.md) cut to 12 pings recorded to
380 m, split over three files; the grid (0.5 m x 0.25 degree, 200-380 m,
±60 degrees) holds the seabed, pipeline A (y = -273 m, 51 degrees) and the
seabed scatterers, at about 0.25 s a ping.
"""

from __future__ import annotations

import fcntl
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from survey_common import GRID, LINES, N_PINGS, PER_FILE, RUN_CLI, TINY, survey_main

from clbeam import survey
from clbeam.constants import KNOT_M_S
from clbeam.errors import ClbeamError
from clbeam.io import survey_products
from clbeam.io.peaks import read_peaks_csv
from clbeam.io.pingfile import PingFile
from clbeam.io.pingwrite import write_ping_file
from clbeam.io.survey_store import LEDGER_DIR
from clbeam.survey import (
    AssociationOptions,
    SurveyError,
    associate,
    describe_objects,
    finalize_survey,
    open_survey,
    peak_positions,
    product_paths,
    to_utm,
    utm_epsg,
)

#: WGS84 ellipsoid, for positions computed by hand
A_M, F = 6378137.0, 1 / 298.257223563
E2 = F * (2 - F)


def meridian_radius_m(lat_deg):
    s = math.sin(math.radians(lat_deg))
    return A_M * (1 - E2) / (1 - E2 * s * s) ** 1.5


def prime_vertical_radius_m(lat_deg):
    s = math.sin(math.radians(lat_deg))
    return A_M / math.sqrt(1 - E2 * s * s)


def ledger_count(out: Path) -> int:
    d = out / LEDGER_DIR
    return sum(1 for n in os.listdir(d) if n.endswith(".json") and not n.startswith(".")) if d.is_dir() else 0


def assert_same_survey(a: Path, b: Path, *, images: bool = True) -> None:
    """Peak for peak, image for image, equal (the CSV byte for byte)."""
    pa, pb = open_survey(a, "peaks").load(), open_survey(b, "peaks").load()
    xr.testing.assert_identical(pa, pb)
    ra, rb = open_survey(a).load(), open_survey(b).load()
    xr.testing.assert_equal(ra, rb)
    if images:
        assert {"intensity", "cf", "cf_smooth"} <= set(ra.data_vars)
    xr.testing.assert_identical(open_survey(a, "objects").load(), open_survey(b, "objects").load())
    assert product_paths(a)["peaks_csv"].read_bytes() == product_paths(b)["peaks_csv"].read_bytes()


# ---------------------------------------------------------------------------
# The survey against the imager, one ping at a time
# ---------------------------------------------------------------------------
def test_survey_peaks_equal_the_imagers_peaks_of_each_ping(line, reference):
    from clbeam.imaging.imager import Imager, ImagingOptions
    from clbeam.model.grid import PolarGrid

    _, paths = line
    peaks = open_survey(reference, "peaks").load()
    root = open_survey(reference)
    assert bool(root["imaged"].all()) and root.attrs["survey_complete"]
    assert int(root["n_peaks"].sum()) == peaks.sizes["peak"]
    # the survey's default: no clutter test
    imager = Imager(PolarGrid.regular(range_res_m=0.5, angle_res_deg=0.25, min_range_m=200, max_range_m=380,
                                      angles_deg=(-60, 60)), ImagingOptions(min_contrast_db=None), backend="opencl")
    for survey_ping, (k, i) in ((1, (0, 1)), (6, (1, 2)), (11, (2, 3))):
        with PingFile(paths[k]) as f:
            expected = imager.image(f.ping(i)).peaks
        got = peaks.where(peaks["ping"] == survey_ping, drop=True)
        assert got.sizes["peak"] == len(expected) > 0
        for col in ("range_m", "angle_deg", "y_m", "z_m", "cf", "intensity_db", "snr_db", "pfa"):
            np.testing.assert_array_equal(got[col].values, [r[col] for r in expected])
        assert set(got["file_index"].values.tolist()) == {k} and set(got["file_ping"].values.tolist()) == {i}
    # the CSV beside the store holds the same rows, readable by clbeam.io.peaks.read_peaks_csv
    rows = read_peaks_csv(product_paths(reference)["peaks_csv"])
    assert len(rows) == peaks.sizes["peak"]
    np.testing.assert_array_equal([r["cf"] for r in rows], peaks["cf"].values)
    for name in ("peaks_geojson", "objects_csv", "objects_geojson"):
        assert product_paths(reference)[name].stat().st_size > 0
    for name in ("map_png", "persistence_png"):
        assert product_paths(reference)[name].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_peaks_of_the_survey_store_equal_those_of_an_image_file_of_the_same_pings(line, reference, tmp_path):
    """``clbeam peaks`` reads a survey written with --images as an image file.  With --mlh (which
    needs each ping's source, sound speed and the sonar's band and array width) its rows for the
    pings of the first input equal, digit for digit, those of ``clbeam image`` + ``clbeam peaks`` on
    that file; without --mlh, those of ``clbeam peaks`` on the file.  The survey's own peaks are
    refined (docs/peaks.md) like those of ``clbeam image --peaks`` on the same file, to the 10
    significant digits of the CSV (a relative difference of at most 5e-10)."""
    from clbeam.io.images import open_images

    _, paths = line
    img, img_peaks = tmp_path / "first.nc", tmp_path / "first_peaks.csv"
    assert survey_main(["image", str(paths[0]), "-o", str(img), *GRID, "--peaks", str(img_peaks),
                        "--min-contrast-db", "off", "-q"]) == 0  # the survey's default
    store_mlh, file_mlh, store_plain = tmp_path / "store_mlh.csv", tmp_path / "file_mlh.csv", tmp_path / "store.csv"
    assert survey_main(["peaks", str(reference), "-o", str(store_mlh), "--mlh", "-q"]) == 0
    assert survey_main(["peaks", str(img), "-o", str(file_mlh), "--mlh", "-q"]) == 0
    expected = read_peaks_csv(file_mlh)
    got = [r for r in read_peaks_csv(store_mlh) if r["ping"] < PER_FILE]
    assert len(got) == len(expected) > 0 and "n_merged" in got[0]
    assert got == expected
    # the per-ping values and the sonar attributes are those of the image file
    root, ds = open_survey(reference), open_images(img)
    try:
        for v in ("centre_y", "centre_z", "source_y", "source_z", "sound_speed", "latitude", "longitude", "heading"):
            assert np.isfinite(ds[v].values).all()
            np.testing.assert_array_equal(root[v].values[:PER_FILE], ds[v].values)
        for a in ("pulse_band_hz", "array_width_m"):
            np.testing.assert_array_equal(root.attrs[a], ds.attrs[a])
    finally:
        ds.close()
    file_plain = tmp_path / "file.csv"
    assert survey_main(["peaks", str(reference), "-o", str(store_plain), "-q"]) == 0
    assert survey_main(["peaks", str(img), "-o", str(file_plain), "-q"]) == 0
    got = [r for r in read_peaks_csv(store_plain) if r["ping"] < PER_FILE]
    assert got == read_peaks_csv(file_plain) and len(got) > 0
    own = [r for r in read_peaks_csv(product_paths(reference)["peaks_csv"]) if r["ping"] < PER_FILE]
    refined = read_peaks_csv(img_peaks)
    assert len(own) == len(refined) > 0
    for a, b in zip(sorted(own, key=_row_key), sorted(refined, key=_row_key)):
        assert a["ping"] == b["ping"]
        for col in ("range_m", "angle_deg", "y_m", "z_m", "cf", "intensity_db"):
            assert a[col] == pytest.approx(b[col], rel=5e-10, abs=0), col


def _row_key(row: dict) -> tuple:
    return row["ping"], round(row["range_m"], 6), round(row["angle_deg"], 6)


# ---------------------------------------------------------------------------
# Resume after kill -9
# ---------------------------------------------------------------------------
def test_survey_killed_twice_with_sigkill_resumes_to_the_uninterrupted_result(line, reference, tmp_path):
    _, paths = line
    out = tmp_path / "killed.zarr"
    argv = ["survey", *map(str, paths), "-o", str(out), *GRID, *LINES, "--images", "-q"]
    at_kill = []
    # the first kill right after a commit, the second partway through a ping (about 0.25 s each)
    for target, delay_s in ((2, 0.0), (6, 0.13)):
        proc = subprocess.Popen([sys.executable, "-c", RUN_CLI, *argv], stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE)
        deadline = time.monotonic() + 120
        while ledger_count(out) < target and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.002)
        time.sleep(delay_s)
        assert proc.poll() is None, f"the survey ended before the kill: {proc.stderr.read().decode()[-500:]}"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        proc.stderr.close()
        assert proc.returncode == -signal.SIGKILL
        at_kill.append(ledger_count(out))
    # both kills landed mid-survey, after some pings were committed
    assert 2 <= at_kill[0] < N_PINGS and at_kill[0] <= at_kill[1] < N_PINGS
    assert survey_main(argv) == 0
    assert ledger_count(out) == N_PINGS
    assert not [p for p in (out / LEDGER_DIR).iterdir() if p.name.startswith(".")]
    assert_same_survey(out, reference)
    peaks = open_survey(out, "peaks")
    # no ping missing, none twice
    counts = np.bincount(peaks["ping"].values, minlength=N_PINGS)
    np.testing.assert_array_equal(counts, open_survey(out)["n_peaks"].values)


def test_unreadable_ledger_file_and_stray_temporary_are_redone_not_trusted(line, reference, tmp_path):
    """What a machine crash can leave: a truncated ledger file (its ping is
    imaged again) and a temporary file (removed)."""
    import zarr

    _, paths = line
    out = tmp_path / "crashed.zarr"
    shutil.copytree(reference, out)
    rec = out / LEDGER_DIR / f"{5:09d}.json"
    rec.write_bytes(rec.read_bytes()[:40])
    stray = out / LEDGER_DIR / f".{6:09d}.json.tmp-1-deadbeef"
    stray.write_text("{")
    # the image chunk of ping 5 is garbage too: it must be rewritten
    zarr.open_group(str(out), mode="r+")["cf"][5] = np.full(open_survey(out)["cf"].shape[1:], 7.0, np.float32)
    res = survey.run_survey(paths, out, _survey_options())
    assert res.n_imaged == 1 and res.n_done_before == N_PINGS - 1
    assert not stray.exists()
    assert_same_survey(out, reference)


def _survey_options():
    """The options ``GRID`` and ``--images`` give on the command line."""
    from clbeam.imaging.imager import ImagingOptions
    from clbeam.model.grid import PolarGrid

    grid = PolarGrid.regular(range_res_m=0.5, angle_res_deg=0.25, min_range_m=200, max_range_m=380,
                             angles_deg=(-60, 60))
    # the command line's defaults (clbeam survey: no clutter test)
    return survey.SurveyOptions(grid=grid, imaging=ImagingOptions(min_contrast_db=None), images=True,
                                lines=survey.LineOptions(min_score=float(LINES[1])))


def test_products_streamed_in_small_blocks_equal_the_products_in_one_block(reference, tmp_path, monkeypatch):
    out = tmp_path / "again.zarr"
    shutil.copytree(reference, out)
    monkeypatch.setattr(survey_products, "PEAK_BLOCK_ROWS", 7)
    prod = finalize_survey(out, _survey_options())
    assert prod.n_peaks > 7 * 10
    assert_same_survey(out, reference)


def test_each_detections_slide_follows_its_snr_and_the_sonar(reference, tmp_path, monkeypatch):
    """The line search gets each detection's slide along its arc from its
    SNR in the ledger, the sonar's band and width and the grid's step: the
    closed form ``sqrt((0.5 c / f_c / W)^2 / SNR + floor^2)`` recomputed here
    from the peaks table (floor 0.3 steps of the 0.25 degree grid: more
    than the fixed 0.05 degree)."""
    import csv

    import clbeam.survey.products as products_module
    out = tmp_path / "again.zarr"
    shutil.copytree(reference, out)
    seen = {}
    original = products_module.survey_lines

    def spy(det, *args, **kwargs):
        seen["det"] = det
        return original(det, *args, **kwargs)
    monkeypatch.setattr(products_module, "survey_lines", spy)
    options = _survey_options()
    finalize_survey(out, options)
    with open(survey.product_paths(out)["peaks_csv"], newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if float(r["cf"]) > options.association.threshold]
    snr = np.array([float(r["snr_db"]) for r in rows])
    attrs = xr.open_zarr(out).attrs
    beam = 1500.0 / np.mean(attrs["pulse_band_hz"]) / attrs["array_width_m"]
    expected = np.hypot(0.5 * beam / np.sqrt(10 ** (snr / 10)), 0.3 * math.radians(0.25))
    det = seen["det"]
    assert det.ping.size == len(rows) > 20
    assert np.allclose(det.y, [float(r["y_m"]) for r in rows]) and np.all(np.isfinite(snr))
    assert det.slide_rad == pytest.approx(expected, rel=1e-3)


# ---------------------------------------------------------------------------
# Dask
# ---------------------------------------------------------------------------
def test_dask_local_cluster_of_two_worker_processes_equals_the_single_process_run(line, reference, tmp_path):
    """Worker processes (not threads): each builds its own OpenCL context, as
    on a real cluster, and nothing but the task description is pickled."""
    _, paths = line
    out = tmp_path / "dask.zarr"
    rc = survey_main(["survey", *map(str, paths), "-o", str(out), *GRID, *LINES, "--images", "--workers", "2",
                      "--block-pings", "3", "-q"])
    assert rc == 0
    assert_same_survey(out, reference)


def test_dask_scheduler_address_with_two_thread_workers_equals_the_single_process_run(line, reference, tmp_path):
    """Two workers in one process: each worker thread owns its imager."""
    from distributed import LocalCluster

    _, paths = line
    out = tmp_path / "sched.zarr"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        rc = survey_main(["survey", *map(str, paths), "-o", str(out), *GRID, *LINES, "--images",
                          "--scheduler", cluster.scheduler_address, "--block-pings", "2", "-q"])
    assert rc == 0
    assert_same_survey(out, reference)


# ---------------------------------------------------------------------------
# Georeferencing
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("heading_deg, y_m, north_m, east_m", [
    (0.0, 100.0, 0.0, 100.0),            # heading north: starboard is east
    (90.0, 100.0, -100.0, 0.0),          # heading east: starboard is south
    (45.0, 100.0, -100 / math.sqrt(2), 100 / math.sqrt(2)),   # heading north-east: starboard south-east
    (0.0, -100.0, 0.0, -100.0),          # port is west
    (180.0, 100.0, 0.0, -100.0),         # heading south: starboard is west
    (270.0, 50.0, 50.0, 0.0),            # heading west: starboard is north
])
def test_peak_position_equals_the_hand_computed_offset(heading_deg, y_m, north_m, east_m):
    """Offsets on the local plane: north = dlat M, east = dlon N cos(lat),
    with the WGS84 radii of curvature M (meridian) and N (prime vertical).
    Over 100 m the plane departs from the ellipsoid by d^2 tan(lat) / 2N
    = 0.5 mm; 1 cm is the tolerance."""
    lat0, lon0 = 34.3, -119.8
    lat, lon = peak_positions(lat0, lon0, heading_deg, y_m)
    north = math.radians(float(lat) - lat0) * meridian_radius_m(lat0)
    east = math.radians(float(lon) - lon0) * prime_vertical_radius_m(lat0) * math.cos(math.radians(lat0))
    assert north == pytest.approx(north_m, abs=0.01)
    assert east == pytest.approx(east_m, abs=0.01)


def test_starboard_offset_on_the_central_meridian_is_scale_factor_times_offset_in_easting():
    """On a UTM central meridian the scale factor is exactly 0.9996 and grid
    north is true north: 100 m east is 99.96 m of easting and no northing
    (terms of order (dlon)^3 are below a micrometre)."""
    lat0, lon0 = 34.3, -117.0
    epsg = utm_epsg(lat0, lon0)
    assert epsg == 32611
    lat, lon = peak_positions(lat0, lon0, 0.0, 100.0)
    e0, n0 = to_utm(lat0, lon0, epsg)
    e1, n1 = to_utm(lat, lon, epsg)
    assert float(e0) == pytest.approx(500000.0, abs=1e-6)
    assert float(e1 - e0) == pytest.approx(0.9996 * 100.0, abs=0.002)
    assert float(n1 - n0) == pytest.approx(0.0, abs=0.002)


@pytest.mark.parametrize("lat, lon, epsg", [(34.3, -119.8, 32611), (-33.9, 151.2, 32756), (0.0, 179.99, 32660),
                                            (51.5, -0.1, 32630), (10.0, -180.0, 32601)])
def test_utm_zone_of_a_position(lat, lon, epsg):
    assert utm_epsg(lat, lon) == epsg


def test_survey_places_every_peak_by_its_pings_heading_and_offset(line, reference):
    """Line 1 heads 110 degrees: a peak y metres to starboard is at azimuth
    200 degrees (port: 20).  Hand-computed on the local plane; up to 380 m
    the plane departs from the ellipsoid by d^2 tan(lat) / 2N <= 8 mm, the
    tolerance is 2 cm."""
    p = open_survey(reference, "peaks").load()
    assert np.all(p["heading_deg"].values == 110.0)
    lat0, lon0 = p["ping_latitude_deg"].values, p["ping_longitude_deg"].values
    y, h = p["y_m"].values, np.deg2rad(p["heading_deg"].values)
    north_expected, east_expected = -y * np.sin(h), y * np.cos(h)
    m = np.array([meridian_radius_m(v) for v in lat0])
    n = np.array([prime_vertical_radius_m(v) for v in lat0])
    north = np.deg2rad(p["peak_latitude_deg"].values - lat0) * m
    east = np.deg2rad(p["peak_longitude_deg"].values - lon0) * n * np.cos(np.deg2rad(lat0))
    np.testing.assert_allclose(north, north_expected, atol=0.02)
    np.testing.assert_allclose(east, east_expected, atol=0.02)
    # the ping positions are the file's navigation
    ds, _ = line
    np.testing.assert_array_equal(open_survey(reference)["latitude"].values, ds["latitude"].values)


def test_pings_without_heading_use_the_course_over_ground(line, tmp_path):
    """The heading variable removed: the course between consecutive pings,
    by hand on the local plane, is atan2(dlon N cos(lat), dlat M) (the
    simulator moves the ship along a WGS84 geodesic launched at 110 degrees,
    whose azimuth turns by dlon sin(lat), 1e-4 degree over these pings)."""
    ds, _ = line
    f = write_ping_file(ds.isel(ping=slice(0, 4)).drop_vars("heading"), tmp_path / "nohead.nc")
    out = tmp_path / "nohead.zarr"
    assert survey_main(["survey", str(f), "-o", str(out), *TINY, "-q"]) == 0
    lat, lon = ds["latitude"].values[:4], ds["longitude"].values[:4]
    dn = np.deg2rad(np.diff(lat)) * meridian_radius_m(lat[0])
    de = np.deg2rad(np.diff(lon)) * prime_vertical_radius_m(lat[0]) * np.cos(np.deg2rad(lat[0]))
    course = np.rad2deg(np.arctan2(de, dn))
    assert np.ptp(course) < 1e-3
    heading = open_survey(out)["heading"].values
    np.testing.assert_allclose(heading, course[0], atol=0.01)


def test_without_navigation_the_along_track_distance_is_ping_time_times_speed(line, tmp_path, capsys):
    ds, _ = line
    f = write_ping_file(ds.isel(ping=slice(0, 4)).drop_vars(["latitude", "longitude", "heading"]),
                        tmp_path / "nonav.nc")
    out = tmp_path / "nonav.zarr"
    assert survey_main(["survey", str(f), "-o", str(out), *TINY, "--speed", "2.0"]) == 0
    assert "no navigation: no GeoJSON" in capsys.readouterr().out
    rows = read_peaks_csv(product_paths(out)["peaks_csv"])
    assert rows and "along_track_m" in rows[0] and "peak_latitude_deg" not in rows[0]
    # pings 4 s apart (docs/simulator.md): 2 m/s gives 8 m a ping
    for r in rows:
        assert r["along_track_m"] == pytest.approx(8.0 * r["ping"], abs=1e-9)
    assert not product_paths(out)["peaks_geojson"].exists()
    assert not product_paths(out)["objects_geojson"].exists()


# ---------------------------------------------------------------------------
# Association
# ---------------------------------------------------------------------------
def _detections_on_track(heading_deg, spacing_m, items):
    """Positions in easting/northing of (ping, y, z) detections on a straight track."""
    h = math.radians(heading_deg)
    fwd, stb = np.array([math.sin(h), math.cos(h)]), np.array([math.cos(h), -math.sin(h)])
    ping = np.array([i[0] for i in items])
    y, z = np.array([i[1] for i in items], float), np.array([i[2] for i in items], float)
    pos = ping[:, None] * spacing_m * fwd + y[:, None] * stb
    return ping, pos, np.tile(stb, (len(items), 1)), y, z


def test_association_groups_a_pipeline_into_one_object_and_leaves_isolated_peaks_alone():
    rng = np.random.default_rng(3)
    spacing = 4 * 4.0 * KNOT_M_S                                     # 8.23 m: 4 kn, 4 s (docs/simulator.md)
    pipe = [(k, -120 + rng.uniform(-0.3, 0.3), 226 + rng.uniform(-0.2, 0.2)) for k in range(20) if k not in (7, 8)]
    crossing = [(k, 40 + k * spacing * math.tan(math.radians(12)), 226.0) for k in range(3, 15)]  # 1.75 m a ping
    isolated = [(int(k), y, 225.0) for k, y in zip(rng.integers(0, 20, 12), np.linspace(-300, 300, 12) + 7)]
    short = [(k, 200.0, 226.0) for k in (10, 11, 12)]                 # persists 3 pings: below min_pings 5
    items = pipe + crossing + isolated + short
    ping, pos, stb, y, z = _detections_on_track(30.0, spacing, items)
    labels = associate(ping, pos, stb, z, AssociationOptions())
    kinds = np.repeat([0, 1, 2, 3], [len(pipe), len(crossing), len(isolated), len(short)])
    assert set(labels[kinds == 0]) == {0}                             # a 2-ping gap (7, 8) is bridged
    assert set(labels[kinds == 1]) == {1}
    assert set(labels[kinds >= 2]) == {-1}
    objs = describe_objects(labels, ping, pos, np.full(len(items), 0.6), y, z)
    assert [o["n_pings"] for o in objs] == [18, 12]
    # the polyline through jittered points: each segment sqrt(L^2 + dy^2) exceeds L by at most
    # dy^2 / 2L with |dy| <= 0.6 m, i.e. 0.03 m over 8 m and 0.01 m over the 24.7 m gap
    assert objs[0]["length_m"] == pytest.approx(19 * spacing, abs=17 * 0.03)
    assert objs[1]["length_m"] == pytest.approx(11 * spacing / math.cos(math.radians(12)), rel=1e-9)


def test_association_keeps_parallel_lines_apart_and_splits_at_a_longer_gap():
    spacing = 8.0
    a = [(k, -100.0, 226.0) for k in range(10)]
    b = [(k, -90.0, 226.0) for k in range(10)]                      # 10 m away: beyond the 3 m link
    c = [(k, 50.0, 226.0) for k in list(range(6)) + list(range(9, 15))]   # 3 missing pings: two objects
    d = [(k, -100.0, 246.0) for k in range(10)]                     # under line a, 20 m deeper
    ping, pos, stb, y, z = _detections_on_track(110.0, spacing, a + b + c + d)
    labels = associate(ping, pos, stb, z, AssociationOptions())
    groups = [set(labels[s]) for s in (slice(0, 10), slice(10, 20), slice(20, 26), slice(26, 32), slice(32, 42))]
    assert all(len(g) == 1 and -1 not in g for g in groups)
    assert len({g.pop() for g in groups}) == 5


def test_simulated_pipeline_is_one_object_along_its_true_position(line, reference):
    """Pipeline A of Line 1 runs along the track 273 m to port.  A detection
    is on the pipe when CF > 0.4, its range is within 1.5 m of the echo's
    true image position (the 7-point Hann smoothing spans +-1.5 m on the
    0.5 m grid) and its angle within 2.2 degrees (half the array's main lobe
    lambda / 2D at the 5.5 kHz band centre).  The pipe is detected in most
    pings (paper Fig. 9), and its associated detections form one object,
    not several, spanning most of the line."""
    ds, _ = line
    truth_y = ds["truth_target_image_y"].values[:, 0]
    truth_z = ds["truth_target_image_z"].values[:, 0]
    truth_r, truth_a = np.hypot(truth_y, truth_z), np.rad2deg(np.arctan2(truth_y, truth_z))
    p = open_survey(reference, "peaks").load()
    k = p["ping"].values
    on_pipe = (p["cf"].values > 0.4) & (np.abs(p["range_m"].values - truth_r[k]) <= 1.5) \
        & (np.abs(p["angle_deg"].values - truth_a[k]) <= 0.5 * 1500 / 5500 / 3.528 * 180 / np.pi)
    assert np.unique(k[on_pipe]).size >= 2 / 3 * N_PINGS
    obj = p["object"].values[on_pipe]
    assert len(set(obj[obj >= 0])) == 1
    ob = open_survey(reference, "objects").load().sel(object=int(obj[obj >= 0][0]))
    linked = np.unique(k[on_pipe][obj >= 0])
    assert int(ob["first_ping"]) <= linked[0] and int(ob["last_ping"]) >= linked[-1]
    assert int(ob["last_ping"]) - int(ob["first_ping"]) + 1 >= N_PINGS / 2
    step = 4 * 4.0 * KNOT_M_S                                         # 4 kn, 4 s (docs/simulator.md)
    assert float(ob["length_m"]) >= (int(ob["last_ping"]) - int(ob["first_ping"])) * step - 1e-6
    assert np.all(p["object"].values[p["cf"].values <= 0.4] == -1)


# ---------------------------------------------------------------------------
# Bad inputs
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def bad_inputs(line, tmp_path_factory):
    """A good file, random bytes, a truncated NetCDF, a Zarr ping file whose
    ping 1 chunk is corrupt, and another good file."""
    ds, paths = line
    d = tmp_path_factory.mktemp("bad")
    junk = d / "junk.nc"
    junk.write_bytes(np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    trunc = d / "trunc.nc"
    data = paths[1].read_bytes()
    trunc.write_bytes(data[: len(data) // 2])
    zs = d / "chunky.zarr"
    sub = ds.isel(ping=slice(0, 3)).copy()
    sub.attrs["clbeam_format"] = "ping-1"
    with warnings.catch_warnings():  # zarr notes that consolidated metadata is outside the v3 specification
        warnings.simplefilter("ignore")
        sub.to_zarr(zs, encoding={"samples": {"chunks": (1, ds.sizes["channel"], ds.sizes["sample"])}})
    for f in (zs / "samples" / "c" / "1").rglob("*"):
        if f.is_file():
            f.write_bytes(b"not a zstd frame" * 8)
    return [paths[0], junk, trunc, zs, paths[2]]


def test_unreadable_files_and_pings_are_reported_by_name_skipped_and_retried(bad_inputs, tmp_path, capsys):
    out = tmp_path / "bad.zarr"
    argv = ["survey", *map(str, bad_inputs), "-o", str(out), *TINY]
    assert survey_main(argv) == 1
    text = capsys.readouterr().out
    assert "skipped: junk.nc: not a readable NetCDF4/HDF5 file" in text
    assert "skipped: trunc.nc: not a readable NetCDF4/HDF5 file" in text
    assert "skipped: chunky.zarr: 1 ping(s) not imaged (ping 1:" in text
    root = open_survey(out)
    # readable: line1_0.nc (4 pings), chunky.zarr (3), line1_2.nc (4); survey ping 5 is chunky.zarr ping 1
    assert root.sizes["ping"] == 11
    np.testing.assert_array_equal(root["imaged"].values, [True] * 5 + [False] + [True] * 5)
    assert json.loads(root.attrs["input_files"]) == ["line1_0.nc", "chunky.zarr", "line1_2.nc"]
    assert not root.attrs["survey_complete"]
    assert 5 not in set(open_survey(out, "peaks")["ping"].values.tolist())
    # a rerun tries again and reports again: never dropped silently
    assert survey_main(argv) == 1
    assert "skipped: chunky.zarr: 1 ping(s) not imaged (ping 1:" in capsys.readouterr().out


def test_stop_on_error_stops_at_the_first_bad_file_with_one_line(bad_inputs, tmp_path, capsys):
    out = tmp_path / "stop.zarr"
    rc = survey_main(["survey", *map(str, bad_inputs), "-o", str(out), *TINY, "--stop-on-error", "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert err[0].startswith("clbeam: error: junk.nc: not a readable NetCDF4/HDF5 file")
    assert not out.exists()


def test_stop_on_error_stops_at_a_bad_ping_and_a_rerun_continues(bad_inputs, tmp_path, capsys):
    out = tmp_path / "stop_ping.zarr"
    argv = ["survey", str(bad_inputs[3]), "-o", str(out), *TINY, "-q"]
    assert survey_main([*argv, "--stop-on-error"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "stopped at chunky.zarr ping 1: RuntimeError" in err[0]
    assert ledger_count(out) == 1
    assert survey_main(argv) == 1
    assert ledger_count(out) == 2                                       # ping 2 done, ping 1 still reported


# ---------------------------------------------------------------------------
# Parameters, restart, concurrent runs, progress
# ---------------------------------------------------------------------------
def test_rerun_with_other_parameters_is_refused_in_one_line_unless_restart(line, tmp_path, capsys):
    _, paths = line
    out = tmp_path / "params.zarr"
    base = ["survey", str(paths[0]), "-o", str(out), *TINY]
    assert survey_main(base) == 0
    summary = capsys.readouterr().out
    assert "pings/s" in summary and "time per ping (ms): read" in summary
    before = open_survey(out, "peaks").load()
    for extra, what in ((["--interp", "linear"], "imaging.interp"), (["--threshold", "0.3"], "imaging.threshold"),
                        (["--images"], "images")):
        assert survey_main([*base, *extra, "-q"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and what in err[0] and "--restart" in err[0], err
    xr.testing.assert_identical(open_survey(out, "peaks").load(), before)
    # the product options may change freely: objects are rebuilt, nothing is imaged again
    assert survey_main([*base, "--min-pings", "2"]) == 0
    assert "0 imaged now, 4 done before" in capsys.readouterr().out
    assert survey_main([*base, "--interp", "linear", "--restart", "-q"]) == 0
    assert json.loads(open_survey(out).attrs["survey_parameters"])["imaging"]["interp"] == "linear"
    assert ledger_count(out) == 4


def test_an_existing_folder_that_is_not_a_survey_is_never_deleted(line, tmp_path, capsys):
    _, paths = line
    out = tmp_path / "precious.zarr"
    out.mkdir()
    (out / "data.txt").write_text("keep me")
    assert survey_main(["survey", str(paths[0]), "-o", str(out), *TINY, "--restart", "-q"]) == 2
    assert "not a clbeam survey store" in capsys.readouterr().err
    assert (out / "data.txt").read_text() == "keep me"


def test_a_second_run_on_the_same_output_is_refused_while_the_first_holds_it(line, tmp_path):
    _, paths = line
    out = tmp_path / "busy.zarr"
    assert survey_main(["survey", str(paths[0]), "-o", str(out), *TINY, "-q"]) == 0
    with open(out / "survey_state" / "lock", "a+") as fh:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(SurveyError, match="in use by another clbeam survey"):
            survey.run_survey([paths[0]], out, _survey_options())


def test_survey_options_refuse_outputs_without_cf():
    from clbeam.imaging.imager import ImagingOptions
    from clbeam.model.grid import PolarGrid

    with pytest.raises(ClbeamError, match="lack 'cf'"):
        survey.SurveyOptions(grid=PolarGrid.regular(max_range_m=10), imaging=ImagingOptions(outputs=("intensity",)))


def test_an_input_given_twice_is_refused(line):
    _, paths = line
    with pytest.raises(SurveyError, match="given twice"):
        survey.scan_inputs([paths[0], paths[1], str(paths[0])])


def test_progress_bar_counts_every_pending_ping_once(line, tmp_path):
    from clbeam.imaging.imager import ImagingOptions
    from clbeam.model.grid import PolarGrid

    _, paths = line
    bars = []

    class Bar:
        def __init__(self, total):
            self.total, self.n, self.closed = total, 0, False
            bars.append(self)

        def update(self, n):
            self.n += n

        def close(self):
            self.closed = True

    opts = survey.SurveyOptions(grid=PolarGrid.regular(range_res_m=0.5, angle_res_deg=0.5, min_range_m=300,
                                                       max_range_m=380, angles_deg=(-60, -40)),
                                imaging=ImagingOptions(), block_pings=3)
    out = tmp_path / "bar.zarr"
    res = survey.run_survey(paths[:2], out, opts, progress=Bar)
    assert (bars[0].total, bars[0].n, bars[0].closed) == (8, 8, True)
    assert res.n_imaged == res.n_timed == 8 and res.pings_per_s > 0
    assert set(res.time_per_ping_s) == set(survey.STAGES) and all(v > 0 for v in res.time_per_ping_s.values())
    survey.run_survey(paths[:2], out, opts, progress=Bar)
    assert (bars[1].total, bars[1].n) == (0, 0)
