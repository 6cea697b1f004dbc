"""What the products carry: the draft from the ping file to the image file's depths, each ping's time,
compressed and packed images read back by xarray's CF decoding within the packing's half step, GeoJSON at
the positions' precision with the depth, one warning per missing roll or navigation, the peaks CSV's fixed
columns, and image files written before any of this still read."""

from __future__ import annotations

import dataclasses
import json
import logging
import math

import h5py
import numpy as np
import pytest
import xarray as xr
import zarr
from scenes import point_ping, polar_point

from clbeam.cli.main import main
from clbeam.errors import OptionError, PingFileError
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.peaks import peaks_from_images
from clbeam.io.conventions import epoch_seconds
from clbeam.io.images import ImageCompression, ImageWriter, open_images
from clbeam.io.peaks import PEAK_CSV_COLUMNS, write_peaks_csv
from clbeam.io.pingfile import PingFile, pings_from_dataset
from clbeam.io.pingwrite import dataset_from_pings, write_ping_file
from clbeam.io.survey_products import PEAK_TABLE, PeakTableWriter, geojson_number
from clbeam.io.survey_store import create_store, product_paths
from clbeam.model.grid import PolarGrid

GRID = PolarGrid.regular(range_res_m=0.5, angle_res_deg=1.0, min_range_m=30, max_range_m=60, angles_deg=(-40, 40))
T0 = np.datetime64("2024-05-01T12:00:00.250", "ns")


def navigated(p, i, draft_m=5.0):
    return dataclasses.replace(p, index=i, latitude_deg=57.1 + 1e-4 * i, longitude_deg=10.2, heading_deg=30.0,
                               draft_m=draft_m, time=T0 + np.timedelta64(4 * i, "s"))


@pytest.fixture(scope="module")
def pings():
    return [navigated(point_ping(polar_point(40 + 5 * i, 10 * i - 15), record_s=0.09), i, 5.0 + 0.5 * i)
            for i in range(3)]


@pytest.fixture(scope="module")
def images(pings):
    imager = Imager(GRID, ImagingOptions(outputs=("intensity", "cf")))
    return [imager.image(p) for p in pings]


def write_images(path, images, **kw):
    with ImageWriter(path, GRID, len(images), ["intensity", "cf", "cf_smooth"], **kw) as w:
        for img in images:
            w.write(img.ping, img)
    return path


# -- the draft -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
def test_the_draft_is_read_per_ping_or_as_one_value(pings, tmp_path, suffix):
    with PingFile(write_ping_file(dataset_from_pings(pings), tmp_path / f"p{suffix}")) as f:
        assert [f.ping(i).draft_m for i in range(3)] == [5.0, 5.5, 6.0]
    ds = dataset_from_pings(pings).assign(draft=((), 4.25))  # one value for every ping
    assert [p.draft_m for p in pings_from_dataset(ds)] == [4.25] * 3
    assert pings_from_dataset(ds.drop_vars("draft")).ping(0).draft_m is None


def test_a_negative_draft_is_one_line(pings):
    ds = dataset_from_pings(pings).assign(draft=((), -1.0))
    with pytest.raises(PingFileError, match=r"^dataset: variable 'draft' reaches -1 m, expected the depth below the "
                                            r"sea surface \(>= 0 m\)$"):
        pings_from_dataset(ds)


@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
def test_image_files_carry_each_pings_time_draft_and_coverage(images, pings, tmp_path, suffix):
    ds = open_images(write_images(tmp_path / f"img{suffix}", images))
    # CF-decoded by xarray; float64 seconds since 1970 hold a time of 2024 to one spacing, 2^-22 s (238 ns)
    error_ns = (ds["ping_time"].values - np.array([p.time for p in pings])).astype(np.int64)
    assert np.all(np.abs(error_ns) <= np.spacing(epoch_seconds(T0)) * 1e9)
    np.testing.assert_array_equal(ds["draft"].values, [p.draft_m for p in pings])
    assert ds["draft"].attrs["standard_name"] == "depth" and ds["draft"].attrs["positive"] == "down"
    assert ds.attrs["time_coverage_start"] == "2024-05-01T12:00:00Z"
    assert ds.attrs["time_coverage_end"] == "2024-05-01T12:00:08Z"
    assert ds.attrs["geospatial_lat_min"] == min(p.latitude_deg for p in pings)
    assert ds.attrs["geospatial_lat_max"] == max(p.latitude_deg for p in pings)
    # the depth below the sea surface of the cell under the first target: the draft plus its earth-frame z
    target = polar_point(40, -15)
    depth = float(ds["draft"][0] + ds["centre_z"][0] + 40 * np.cos(np.deg2rad(-15)))
    assert depth == pytest.approx(pings[0].draft_m + target[2], abs=1e-9)
    ds.close()


def test_a_ping_file_without_draft_images_at_draft_zero_with_one_warning(images, tmp_path, caplog):
    bare = [dataclasses.replace(img, context=dataclasses.replace(img.context, draft_m=None)) for img in images]
    with caplog.at_level(logging.WARNING, logger="clbeam.io.images"):
        ds = open_images(write_images(tmp_path / "img.nc", bare))
    warned = [r.getMessage() for r in caplog.records if "draft" in r.getMessage()]
    assert len(warned) == 1 and "draft 0 m" in warned[0]
    np.testing.assert_array_equal(ds["draft"].values, np.zeros(3))
    ds.close()


# -- compression and packing ------------------------------------------------------------------------------
def test_deflated_images_read_back_exactly_and_packed_cf_within_half_a_step(images, tmp_path):
    plain = write_images(tmp_path / "plain.nc", images)
    small = write_images(tmp_path / "small.nc", images, compression=ImageCompression(level=4, pack_cf=True))
    with h5py.File(small) as f:  # what a NetCDF reader sees: zlib, shuffle, 16-bit CF
        assert f["intensity"].compression == "gzip" and f["intensity"].shuffle
        assert f["cf"].dtype == np.int16 and f["intensity"].dtype == np.float32
    a, b = xr.open_dataset(plain), xr.open_dataset(small)
    np.testing.assert_array_equal(b["intensity"].values, a["intensity"].values)
    # CF unpacking by xarray: cf = q / 65534 + 0.5; the error is half a step plus the float32 rounding of
    # the unpacked value (at most half an ulp of 1)
    half_step = 0.5 / 65534 + 2.0 ** -24
    for name in ("cf", "cf_smooth"):
        assert b[name].dtype == np.float32
        np.testing.assert_allclose(b[name].values, np.clip(a[name].values, 0, 1), rtol=0, atol=half_step)
    assert small.stat().st_size < plain.stat().st_size
    a.close(), b.close()


def test_packed_cf_keeps_zero_one_and_reads_unwritten_pings_as_nan(images, tmp_path):
    img = dataclasses.replace(images[0], cf=np.where(images[0].cf > 0.5, 1.0, 0.0).astype(np.float32))
    with ImageWriter(tmp_path / "img.zarr", GRID, 2, ["cf"], compression=ImageCompression(0, pack_cf=True)) as w:
        w.write(0, img)
    stored = zarr.open_array(str(tmp_path / "img.zarr" / "cf"), mode="r")[0]
    np.testing.assert_array_equal(stored, np.where(img.cf > 0, 32767, -32767))  # the ends of the 16-bit range
    ds = xr.open_zarr(tmp_path / "img.zarr")
    np.testing.assert_allclose(ds["cf"][0].values, img.cf, rtol=0, atol=2.0 ** -52)  # unpacked in float64
    assert np.isnan(ds["cf"][1].values).all()


def test_a_deflate_level_outside_zero_to_nine_is_refused():
    with pytest.raises(OptionError, match="from 0 .* to 9, got 10"):
        ImageCompression(level=10)


def test_clbeam_image_compress_and_pack_cf(pings, tmp_path, capsys):
    src = write_ping_file(dataset_from_pings(pings), tmp_path / "pings.nc")
    grid = ["--max-range", "60", "--min-range", "30", "--angles", "-40", "40", "--angle-res", "1", "--range-res", "0.5",
            "-q"]
    assert main(["image", str(src), "-o", str(tmp_path / "a.nc"), *grid]) == 0
    assert main(["image", str(src), "-o", str(tmp_path / "b.nc"), "--compress", "--pack-cf", *grid]) == 0
    with h5py.File(tmp_path / "b.nc") as f:
        assert f["intensity"].compression_opts == 1 and f["cf"].dtype == np.int16
    a, b = xr.open_dataset(tmp_path / "a.nc"), xr.open_dataset(tmp_path / "b.nc")
    np.testing.assert_array_equal(b["intensity"].values, a["intensity"].values)
    np.testing.assert_allclose(b["cf"].values, a["cf"].values, rtol=0, atol=0.5 / 65534 + 2.0 ** -24)
    a.close(), b.close()
    with pytest.raises(SystemExit) as exit_:
        main(["image", str(src), "-o", str(tmp_path / "c.nc"), "--compress", "12", *grid])
    assert exit_.value.code != 0 and "the deflate level must be an integer from 1 to 9, got '12'" in capsys.readouterr().err


# -- GeoJSON --------------------------------------------------------------------------------------------------
def test_geojson_points_keep_1e7_degree_and_the_depth(tmp_path):
    shapely = pytest.importorskip("shapely.geometry")
    out = tmp_path / "s.zarr"
    create_store(out, grid=GRID, n_pings=2, variables=[], params={}, input_names=["a.nc"])
    files = product_paths(out)
    rng = np.random.default_rng(1)
    n = 50
    cols = {k: rng.uniform(0.1, 0.9, n).astype(dtype) if np.issubdtype(dtype, np.floating) else np.zeros(n, dtype)
            for k, (dtype, _, _) in PEAK_TABLE.items() if k != "depth_m"}
    cols.update(ping=np.repeat([0, 1], n // 2), z_m=rng.uniform(100, 300, n),
                peak_latitude_deg=57.1 + rng.uniform(0, 0.01, n), peak_longitude_deg=10.2 + rng.uniform(0, 0.01, n))
    columns = ["ping", "z_m", "cf", "peak_latitude_deg", "peak_longitude_deg", "time_s"]
    draft = np.array([5.0, 6.5])
    writer = PeakTableWriter(out, {k: files[k] for k in ("peaks_csv", "peaks_geojson")}, columns, True, {}, draft_m=draft)
    writer.add(cols)
    writer.close()
    feats = json.loads(files["peaks_geojson"].read_text())["features"]
    assert len(feats) == n
    for k, f in enumerate(feats):
        point = shapely.shape(f["geometry"])  # a peer reader of GeoJSON geometry: a 3-D point
        assert point.has_z
        assert abs(point.x - cols["peak_longitude_deg"][k]) <= 5e-8 and abs(point.y - cols["peak_latitude_deg"][k]) <= 5e-8
        assert point.z == pytest.approx(-(cols["z_m"][k] + draft[cols["ping"][k]]), abs=0.005)
        assert abs(f["properties"]["z_m"] - cols["z_m"][k]) <= 5e-4
        assert f["properties"]["cf"] == pytest.approx(cols["cf"][k], rel=5e-6)
    ds = xr.open_zarr(out, group="peaks", consolidated=False)
    np.testing.assert_allclose(ds["depth_m"].values, cols["z_m"] + draft[cols["ping"]], rtol=0, atol=1e-12)
    # the CF time decodes to the ping times
    np.testing.assert_array_equal(ds["time_s"].values, (cols["time_s"] * 1e9).astype("datetime64[ns]"))


def test_geojson_numbers_keep_the_decimals_their_columns_need():
    assert geojson_number("peak_latitude_deg", 57.123456789012) == 57.1234568
    assert geojson_number("easting_m", 512345.678912345) == 512345.679
    assert geojson_number("angle_deg", -45.123456789) == -45.1235
    assert geojson_number("pfa", 1.234567891e-12) == 1.23457e-12
    assert geojson_number("cf", math.nan) is None and geojson_number("ping", np.int64(7)) == 7


def test_a_draft_missing_for_the_survey_gives_one_warning_and_depth_z(tmp_path, caplog):
    out = tmp_path / "s.zarr"
    create_store(out, grid=GRID, n_pings=1, variables=[], params={}, input_names=["a.nc"])
    files = product_paths(out)
    cols = {k: np.full(3, 0.5).astype(dtype) for k, (dtype, _, _) in PEAK_TABLE.items() if k != "depth_m"}
    cols["ping"] = np.zeros(3, dtype=np.int64)
    with caplog.at_level(logging.WARNING, logger="clbeam.io.survey_products"):
        writer = PeakTableWriter(out, {k: files[k] for k in ("peaks_csv", "peaks_geojson")}, ["ping"], False, {})
        writer.add(cols)
        writer.add(cols)
        writer.close()
    assert sum("draft 0 m" in r.getMessage() for r in caplog.records) == 1
    np.testing.assert_array_equal(xr.open_zarr(out, group="peaks", consolidated=False)["depth_m"].values, np.full(6, 0.5))


# -- reader warnings and the CSV's columns ------------------------------------------------------------------
def test_a_ping_file_without_roll_or_navigation_gets_one_warning_each(pings, caplog):
    ds = dataset_from_pings(pings)
    with caplog.at_level(logging.WARNING, logger="clbeam.io.pingfile"):
        pings_from_dataset(ds)
    assert not caplog.records
    with caplog.at_level(logging.WARNING, logger="clbeam.io.pingfile"):
        pings_from_dataset(ds.drop_vars(["roll", "latitude", "longitude"]), "bare.nc")
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 2
    assert messages[0] == "bare.nc: no variable 'roll': the pings are imaged without roll correction (roll 0 degrees)"
    assert "no variable 'latitude' or 'longitude'" in messages[1] and "peak_latitude_deg" in messages[1]


def test_the_peaks_csv_has_the_same_columns_with_and_without_navigation(pings, tmp_path):
    imager = Imager(GRID, ImagingOptions(outputs=("intensity", "cf"), min_snr_db=None, min_contrast_db=None))
    bare = dataclasses.replace(pings[0], latitude_deg=None, longitude_deg=None, heading_deg=None)
    headers = []
    for name, ping in (("nav", pings[0]), ("bare", bare)):
        path = write_peaks_csv(imager.image(ping).peaks, tmp_path / f"{name}.csv")
        headers.append(path.read_text().splitlines()[0].split(","))
    assert headers[0] == headers[1]
    assert headers[1][:len(PEAK_CSV_COLUMNS)] == list(PEAK_CSV_COLUMNS)
    rows = (tmp_path / "bare.csv").read_text().splitlines()[1:]
    at = [headers[1].index(c) for c in ("ping_latitude_deg", "peak_latitude_deg", "peak_longitude_deg")]
    assert rows and all(r.split(",")[k] == "" for r in rows for k in at)


def test_an_image_file_written_before_the_conventions_reads_and_gives_the_same_peaks(images, tmp_path):
    new = open_images(write_images(tmp_path / "new.nc", images))
    old = new.drop_vars(["ping_time", "draft"])  # the layout of earlier files: no time, no draft, no CF attributes
    old.attrs = {"clbeam_format": "images-1", "pulse_band_hz": new.attrs["pulse_band_hz"],
                 "array_width_m": new.attrs["array_width_m"]}
    for v in old.variables.values():
        v.attrs = {k: a for k, a in v.attrs.items() if k in ("units", "long_name")}
    old["intensity"].attrs["units"] = "squared input units"
    old.reset_coords(["latitude", "longitude"]).to_netcdf(tmp_path / "old.nc", engine="h5netcdf")
    again = open_images(tmp_path / "old.nc")
    gates = {"min_snr_db": None, "min_contrast_db": None}
    old_rows, new_rows = peaks_from_images(again, **gates), peaks_from_images(new, **gates)
    # the old file has no time and no draft: no time_s, and the depth below the surface takes the draft as 0
    assert [{k: v for k, v in r.items() if k not in ("time_s", "depth_m")} for r in new_rows] == \
        [{k: v for k, v in r.items() if k != "depth_m"} for r in old_rows] != []
    assert all("time_s" not in r and r["depth_m"] == r["z_m"] for r in old_rows)
    drafts = {p.index: p.draft_m for p in (img.context for img in images)}
    assert all(r["depth_m"] == pytest.approx(r["z_m"] + drafts[r["ping"]], abs=1e-12) for r in new_rows)
    new.close(), again.close()
