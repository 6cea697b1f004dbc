"""A survey too short for lines says so; the store carries the ping files' drafts."""

from __future__ import annotations

import logging

import numpy as np
from survey_common import TINY, survey_main

from clbeam.io.pingwrite import write_ping_file
from clbeam.io.survey_store import open_survey, product_paths
from clbeam.sim import load_scene, simulate
from clbeam.survey.line_options import LineOptions


def test_five_pings_with_truth_say_that_a_line_needs_more_pings(tmp_path, capsys, caplog):
    sc = load_scene("line1", pings=5, max_range_m=380)
    pings = write_ping_file(simulate(sc), tmp_path / "five.nc")
    out = tmp_path / "five.zarr"
    with caplog.at_level(logging.WARNING):
        assert survey_main(["survey", str(pings), "-o", str(out), *TINY, "--truth"]) == 0
    said = capsys.readouterr().out
    need = LineOptions().seed_hits
    assert need > 5
    expected = f"the survey imaged 5 ping(s), fewer than the {need} with detections a line needs"
    assert sum(expected in r.getMessage() for r in caplog.records) == 1
    assert f"lines: none: {expected}" in said
    assert f"truth: no line to score the targets on: {expected}" in said
    # the drafts of the ping file (the scene's) in the store and in the peaks' depths below the surface
    root = open_survey(out)
    np.testing.assert_array_equal(root["draft"].values, np.full(5, sc.sonar.draft_m))
    peaks = open_survey(out, "peaks").load()
    assert peaks.sizes["peak"] > 0
    np.testing.assert_allclose(peaks["depth_m"].values, peaks["z_m"].values + sc.sonar.draft_m, atol=1e-12)
    header = product_paths(out)["lines_csv"].read_text().splitlines()[0].split(",")
    assert "burial_se_m" in header and "burial_error_m" not in header
