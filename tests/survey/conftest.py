"""Fixtures of the survey tests: Line 1 cut to 12 pings as three files, and its uninterrupted survey."""

from __future__ import annotations

import pytest
from survey_common import GRID, LINES, N_PINGS, PER_FILE, survey_main

from clbeam.io.pingwrite import write_ping_file
from clbeam.sim import load_scene, simulate


@pytest.fixture(scope="package")
def line(tmp_path_factory):
    """Line 1, 12 pings, as three ping files of 4 pings."""
    ds = simulate(load_scene("line1", pings=N_PINGS, max_range_m=380))
    d = tmp_path_factory.mktemp("line")
    paths = [write_ping_file(ds.isel(ping=slice(k, k + PER_FILE)), d / f"line1_{k // PER_FILE}.nc")
             for k in range(0, N_PINGS, PER_FILE)]
    return ds, paths


@pytest.fixture(scope="package")
def reference(line, tmp_path_factory):
    """The uninterrupted single-process survey with images."""
    _, paths = line
    out = tmp_path_factory.mktemp("ref") / "ref.zarr"
    assert survey_main(["survey", *map(str, paths), "-o", str(out), *GRID, *LINES, "--images", "-q"]) == 0
    return out


