"""One peak table: ``clbeam image --peaks``, ``clbeam peaks`` and ``clbeam survey`` on the same pings."""

from __future__ import annotations

import csv
import logging

import numpy as np
import pytest
import xarray as xr

from clbeam.cli.main import main
from clbeam.io.peaks import PEAK_CSV_COLUMNS, REFINE_COLUMNS
from clbeam.io.pingwrite import write_ping_file
from clbeam.sim import load_scene, simulate

#: a window around Line 1's pipeline A: a few echoes a ping, quick to image
GRID = ["--range-res", "0.5", "--angle-res", "0.25", "--min-range", "300", "--max-range", "380",
        "--angles", "-60", "-40", "--min-contrast-db", "off"]


def _table(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    d = tmp_path_factory.mktemp("schema")
    scene = load_scene("line1", pings=3, max_range_m=380)
    pings = write_ping_file(simulate(scene), d / "pings.nc")
    assert main(["image", str(pings), "-o", str(d / "img.nc"), "--peaks", str(d / "image.csv"), *GRID, "-q"]) == 0
    assert main(["peaks", str(d / "img.nc"), "-o", str(d / "refined.csv"), "--pings", str(pings),
                 "--min-contrast-db", "off", "-q"]) == 0
    assert main(["peaks", str(d / "img.nc"), "-o", str(d / "cells.csv"), "--min-contrast-db", "off", "-q"]) == 0
    assert main(["survey", str(pings), "-o", str(d / "s.zarr"), *GRID, "-q"]) == 0
    return {"scene": scene, "pings": pings, "dir": d,
            **{k: _table(d / f"{k}.csv") for k in ("image", "refined", "cells")}, "survey": _table(d / "s.peaks.csv")}


def test_the_three_commands_write_one_header(tables):
    head = list(PEAK_CSV_COLUMNS) + list(REFINE_COLUMNS)
    assert tables["image"][0] == head and tables["refined"][0] == head
    assert tables["survey"][0][:len(head)] == head  # then the survey's own: file, UTM, object, line
    assert tables["cells"][0] == list(PEAK_CSV_COLUMNS)  # not refined: no cell_* columns


def test_peaks_with_the_pings_and_the_survey_give_images_rows(tables):
    head, rows = tables["image"]
    assert len(rows) > 3
    assert tables["refined"][1] == rows  # the same refinement from the image file's CF: the same text
    survey = [r[:len(head)] for r in tables["survey"][1]]
    assert len(survey) == len(rows)
    for a, b in zip(rows, survey):
        assert [float(x) if x else None for x in a] == [float(x) if x else None for x in b]


def test_the_rows_carry_time_depth_and_the_peaks_position(tables):
    from pyproj import Geod

    head, rows = tables["image"]
    col = {c: np.array([float(r[head.index(c)]) for r in rows]) for c in head}
    with xr.open_dataset(tables["pings"]) as ds:
        t = (ds["ping_time"].values - np.datetime64(0, "ns")) / np.timedelta64(1, "s")
        draft = ds["draft"].values
    p = col["ping"].astype(int)
    np.testing.assert_array_equal(col["time_s"], t[p])
    np.testing.assert_allclose(draft, tables["scene"].sonar.draft_m)  # the simulator writes the scene's draft
    np.testing.assert_allclose(col["depth_m"], col["z_m"] + draft[p], atol=1e-12)
    # the peak lies |y| from the ping along the azimuth heading +- 90 (WGS84 geodesic, pyproj's own)
    az, _, dist = Geod(ellps="WGS84").inv(col["ping_longitude_deg"], col["ping_latitude_deg"],
                                         col["peak_longitude_deg"], col["peak_latitude_deg"])
    np.testing.assert_allclose(dist, np.abs(col["y_m"]), atol=1e-6)
    expect = col["heading_deg"] + np.where(col["y_m"] >= 0, 90.0, -90.0)
    np.testing.assert_allclose((az - expect + 180) % 360 - 180, 0.0, atol=1e-6)


def test_peaks_without_the_pings_are_the_grid_cells_and_say_so(tables, caplog):
    head, rows = tables["cells"]
    ranges = {float(r[head.index("range_m")]) for r in rows}
    with xr.open_dataset(tables["dir"] / "img.nc") as ds:
        assert ranges <= set(ds["range"].values.tolist())  # every row on a grid node
    # the refined rows lie off the nodes (their echoes), where the grid cells' rows cannot
    refined_head, refined = tables["image"]
    assert any(float(r[refined_head.index("range_m")]) not in ranges for r in refined)
    with caplog.at_level(logging.WARNING):
        main(["peaks", str(tables["dir"] / "img.nc"), "-o", str(tables["dir"] / "again.csv"), "-q"])
    assert any("no --pings" in r.getMessage() and "grid cells" in r.getMessage() for r in caplog.records)


def test_image_peaks_without_cf_is_refused_in_one_line(tables, capsys):
    out = tables["dir"] / "intensity.nc"
    rc = main(["image", str(tables["pings"]), "-o", str(out), "--outputs", "intensity", "--peaks",
               str(tables["dir"] / "none.csv"), *GRID, "-q"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "--peaks needs the cf output" in err
    assert not out.exists() and not (tables["dir"] / "none.csv").exists()
