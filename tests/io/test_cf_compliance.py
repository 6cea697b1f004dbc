"""Every kind of file clbeam writes passes the IOOS compliance checker's CF suite without an error or a
warning, and carries the ACDD discovery attributes: ping files (raw and analytic, and a simulation with its
truth), image files (plain, and deflated with the coherence factor packed), both as NetCDF and as Zarr, and
the survey store with its groups of peaks, objects and lines.  The checker reads NetCDF only: a Zarr store
is checked as the NetCDF file of its metadata and arrays as stored (no CF decoding), a group with the
root's global attributes (CF §2.7)."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
import xarray as xr
from scenes import point_ping, polar_point

from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.io.conventions import CONVENTIONS
from clbeam.io.images import ImageCompression, ImageWriter
from clbeam.io.pingwrite import dataset_from_pings, write_ping_file
from clbeam.io.schema import IMAGE_COORDS, IMAGE_PING_VARIABLES, IMAGE_VARIABLES, PING_VARIABLES
from clbeam.io.survey_products import (
    LINE_COLUMNS,
    LINE_INTEGERS,
    LINE_KINDS,
    OBJECT_COLUMNS,
    PEAK_TABLE,
    PeakTableWriter,
    write_feature_tables,
)
from clbeam.io.survey_store import create_store, product_paths, read_root_attrs, update_store
from clbeam.model.grid import PolarGrid
from clbeam.model.svp import holland_line1_profile

pytest.importorskip("compliance_checker")

GRID = PolarGrid.regular(range_res_m=0.5, angle_res_deg=1.0, min_range_m=30, max_range_m=60, angles_deg=(-40, 40))
HIGH, MEDIUM = 3, 2


def full_pings(kind="raw", n=2):
    """Pings with every optional ping-file variable: navigation, draft, time, profile, mask, channel responses."""
    out = []
    for i in range(n):
        p = point_ping(polar_point(40 + 5 * i, 10 * i), record_s=0.09, roll_deg=i, heave_m=0.1 * i, kind=kind)
        valid = np.ones(p.n_channels, dtype=bool)
        valid[3 + i] = False
        out.append(dataclasses.replace(
            p, index=i, latitude_deg=57.1 + 1e-4 * i, longitude_deg=10.2, heading_deg=30.0, pitch_deg=0.5, draft_m=5.0,
            time=np.datetime64("2024-05-01T12:00:00", "ns") + np.timedelta64(4 * i, "s"), channel_valid=valid,
            svp=holland_line1_profile(), element_gain_db=np.full(p.n_channels, 0.1), element_phase_deg=np.zeros(p.n_channels)))
    return out


def _failures(path, suite: str, monkeypatch) -> list:
    """``(weight, name, messages)`` of the checks of ``suite`` that ``path`` fails."""
    from compliance_checker.cf import util as cf_util
    from compliance_checker.runner import CheckSuite

    def offline(*_):  # a table other than the packaged one is never fetched: the test runs offline
        raise OSError("offline")

    monkeypatch.setattr(cf_util, "download_cf_standard_name_table", offline)
    cs = CheckSuite()
    cs.load_all_available_checkers()
    ds = cs.load_dataset(str(path))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            results = cs.run_all(ds, [suite], [], [])[suite][0]
    finally:
        ds.close()
    out = []
    for r in results:
        passed = r.value if isinstance(r.value, bool) else r.value[0] == r.value[1]
        if not passed:
            out.append((r.weight, r.name, list(r.msgs)))
    return out


def assert_cf_clean(path, monkeypatch) -> None:
    """No CF error (high priority) and no warning (medium) on ``path``."""
    bad = [f for f in _failures(path, "cf:1.10", monkeypatch) if f[0] >= MEDIUM]
    assert not bad, bad


def assert_acdd_discoverable(path, monkeypatch) -> None:
    """The ACDD suite's highly recommended checks pass, but for the standard names of variables the CF
    table has none for (clbeam's tables give every name the table has)."""
    tables = {**PING_VARIABLES, **IMAGE_VARIABLES, **IMAGE_PING_VARIABLES, **IMAGE_COORDS}
    for weight, name, msgs in _failures(path, "acdd:1.3", monkeypatch):
        if weight < HIGH:
            continue
        variable = name.split('"')[1] if name.startswith("variable ") else None
        assert variable is not None and msgs == ["standard_name"], (name, msgs)
        assert variable in tables and not tables[variable].standard_name, (name, msgs)


def zarr_as_netcdf(store, path, group=None):
    """The Zarr ``store`` (its ``group``) as a NetCDF file of its metadata and arrays as stored."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = xr.open_zarr(store, decode_cf=False, consolidated=None, group=group)
    if group is not None:
        ds.attrs = {**read_root_attrs(store), **ds.attrs}
    ds.attrs = {k: int(v) if isinstance(v, bool) else v for k, v in ds.attrs.items()}  # NetCDF has no booleans
    for name, v in ds.variables.items():
        if v.dtype == bool:  # NetCDF has no booleans: int8, as xarray writes them
            ds[name] = v.astype(np.int8)
        for key in ("valid_min", "valid_max", "flag_values"):  # a JSON number has no width: the variable's
            if key in v.attrs:
                ds[name].attrs[key] = np.asarray(v.attrs[key], dtype=v.dtype)
        ds[name].encoding = {} if "_FillValue" in v.attrs else {"_FillValue": None}
    ds.to_netcdf(path, engine="h5netcdf")
    return path


@pytest.mark.parametrize("kind", ["raw", "analytic"])
@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
def test_ping_files_pass_the_cf_checker(tmp_path, monkeypatch, kind, suffix):
    path = write_ping_file(dataset_from_pings(full_pings(kind)), tmp_path / f"pings{suffix}")
    checked = zarr_as_netcdf(path, tmp_path / "z.nc") if suffix == ".zarr" else path
    assert_cf_clean(checked, monkeypatch)
    assert_acdd_discoverable(checked, monkeypatch)


def test_a_simulated_ping_file_with_its_truth_passes_the_cf_checker(tmp_path, monkeypatch):
    from clbeam.sim import simulate

    path = write_ping_file(simulate("point", pings=2), tmp_path / "sim.nc")
    assert_cf_clean(path, monkeypatch)


@pytest.fixture(scope="module")
def images():
    imager = Imager(GRID, ImagingOptions(outputs=("intensity", "cf", "sums")))
    return [imager.image(p) for p in full_pings()]


@pytest.mark.parametrize("compression", [None, ImageCompression(level=4, pack_cf=True)], ids=["plain", "packed"])
@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
def test_image_files_pass_the_cf_checker(images, tmp_path, monkeypatch, compression, suffix):
    path = tmp_path / f"img{suffix}"
    with ImageWriter(path, GRID, len(images), ["intensity", "cf", "cf_smooth", "s_r", "s_i", "q", "m"],
                     {"source_file": "pings.nc"}, compression=compression) as w:
        for img in images:
            w.write(img.ping, img)
    checked = zarr_as_netcdf(path, tmp_path / "z.nc") if suffix == ".zarr" else path
    assert_cf_clean(checked, monkeypatch)
    assert_acdd_discoverable(checked, monkeypatch)


def peak_columns(n: int, ping: int) -> dict:
    """``n`` peak rows of survey ping ``ping`` with every column of the group ``peaks``."""
    rng = np.random.default_rng(ping)
    cols = {k: rng.uniform(0.1, 0.9, n).astype(dtype) if np.issubdtype(dtype, np.floating) else np.zeros(n, dtype)
            for k, (dtype, _, _) in PEAK_TABLE.items() if k != "depth_m"}
    cols["ping"] = np.full(n, ping)
    cols["time_s"] = np.full(n, 1.7e9 + 4.0 * ping)
    cols["peak_latitude_deg"] = 57.1 + 1e-5 * rng.uniform(size=n)
    cols["peak_longitude_deg"] = 10.2 + 1e-5 * rng.uniform(size=n)
    return cols


def test_the_survey_store_and_its_peaks_objects_and_lines_pass_the_cf_checker(tmp_path, monkeypatch):
    out = tmp_path / "survey.zarr"
    create_store(out, grid=GRID, n_pings=3, variables=["cf"], params={"threshold": 0.25}, input_names=["a.nc"])
    files = product_paths(out)
    writer = PeakTableWriter(out, {k: files[k] for k in ("peaks_csv", "peaks_geojson")}, ["ping", "z_m", "cf"],
                             True, {"peak_threshold": 0.25}, draft_m=np.full(3, 5.0))
    for g in range(3):
        writer.add(peak_columns(4, g))
    writer.close()
    extra = ["start_latitude_deg", "start_longitude_deg", "end_easting_m"]
    objects = [{**{c: 1.5 for c in OBJECT_COLUMNS + tuple(extra)}, "object": k, "n_pings": 2} for k in range(2)]
    write_feature_tables(out, (files["objects_csv"], files["objects_geojson"]), "objects", objects,
                         list(OBJECT_COLUMNS) + extra, OBJECT_COLUMNS[:5], [[[10.2, 57.1]], [[10.2, 57.1]]], "objects")
    lines = [{**{c: 1.5 for c in LINE_COLUMNS + tuple(extra)}, **{c: 1 for c in LINE_INTEGERS}, "kind": "pipeline"}]
    write_feature_tables(out, (files["lines_csv"], files["lines_geojson"]), "lines", lines, list(LINE_COLUMNS) + extra,
                         LINE_INTEGERS, [[[10.2, 57.1], [10.21, 57.1]]], "lines", {"kind": LINE_KINDS})
    update_store(out, {"time": 1.7e9 + 4.0 * np.arange(3), "latitude": np.full(3, 57.1), "longitude": np.full(3, 10.2)},
                 {"speed_m_s": None, "survey_complete": True})
    for group in (None, "peaks", "objects", "lines"):
        checked = zarr_as_netcdf(out, tmp_path / f"{group}.nc", group)
        assert_cf_clean(checked, monkeypatch)
    attrs = read_root_attrs(out)
    assert attrs["Conventions"] == CONVENTIONS and attrs["time_coverage_end"] == "2023-11-14T22:13:28Z"
    assert "speed_m_s" not in attrs
