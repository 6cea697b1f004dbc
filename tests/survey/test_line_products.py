"""The survey's lines as products: tables, GeoJSON, the peaks' line column,
scoring against the simulator's truth, reruns, and the bad cases (no
detections, one ping, no navigation).

The survey is the 12-ping cut of Line 1 of the other survey tests
(``conftest.py``): pipeline A runs along the track 275 m to port, 1 m
below a seabed 225 m below the transducers.
"""

from __future__ import annotations

import csv
import json
import math
import shutil

import numpy as np
import pytest
from survey_common import GRID, LINES, TINY, survey_main

from clbeam.evaluation.line_truth import LineTruth, score_lines
from clbeam.io.pingwrite import write_ping_file
from clbeam.io.survey_products import LINE_COLUMNS, LINE_KINDS
from clbeam.survey import open_survey, product_paths
from clbeam.survey.line_products import SurveyLines, echo_strength


def read_csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_pipeline_a_is_one_pipeline_line_at_its_true_place_in_every_product(line, reference):
    """Pipeline A is one line of kind pipeline, within 1 m across the track of
    where it crosses each ping's plane (truth_target_y), its burial within
    three of its standard errors of the truth (on this coarse grid, at 50
    degrees from nadir, not resolved to 0.5 m); the CSV, the GeoJSON, the
    group ``lines`` and the peaks' ``line`` column say the same."""
    ds, _ = line
    files = product_paths(reference)
    rows = read_csv(files["lines_csv"])
    assert list(rows[0])[:len(LINE_COLUMNS)] == list(LINE_COLUMNS)
    pipes = [r for r in rows if r["kind"] == "pipeline"]
    assert len(pipes) == 1
    a = pipes[0]
    truth_y = ds["truth_target_y"].values[:, 0]
    truth_burial = ds["truth_target_z"].values[:, 0] - ds["truth_target_seabed_z"].values[:, 0]
    assert abs(float(a["mean_y_m"]) - truth_y.mean()) < 1.0
    assert abs(float(a["burial_m"]) - truth_burial.mean()) < max(3 * float(a["burial_se_m"]), 0.5)
    assert int(a["n_pings"]) >= 2 / 3 * len(truth_y)
    # the peaks on the line: one per ping, all detections, as many as n_pings
    peaks = open_survey(reference, "peaks").load()
    on = peaks["line"].values == int(a["line"])
    assert np.all(peaks["cf"].values[on] > 0.4)
    assert np.unique(peaks["ping"].values[on]).size == on.sum() == int(a["n_pings"])
    assert np.all(np.abs(peaks["y_m"].values[on] - truth_y[peaks["ping"].values[on]]) < 6.0)
    # GeoJSON: one LineString per row, its ends those of the CSV
    gj = json.loads(files["lines_geojson"].read_text())
    assert len(gj["features"]) == len(rows)
    f = gj["features"][int(a["line"])]
    assert f["geometry"]["type"] == "LineString" and f["properties"]["kind"] == "pipeline"
    # the GeoJSON's positions are rounded to 1e-7 degree (1.1 cm)
    assert f["geometry"]["coordinates"][0] == pytest.approx([float(a["start_longitude_deg"]),
                                                             float(a["start_latitude_deg"])], abs=5e-8)
    # the Zarr group: kinds coded with CF flags
    g = open_survey(reference, "lines").load()
    meanings = g["kind"].attrs["flag_meanings"].split()
    assert meanings == list(LINE_KINDS)
    assert [meanings[int(k)] for k in g["kind"].values] == [r["kind"] for r in rows]


def test_truth_report_of_the_command_line(line, reference, tmp_path, capsys):
    """``--truth`` on a rerun (nothing imaged again) reports pipeline A on one
    line over at least 80 % of its detectable pings, 1 fragment, no false line."""
    out = tmp_path / "copy.zarr"
    shutil.copytree(reference, out)
    _, paths = line
    assert survey_main(["survey", *map(str, paths), "-o", str(out), *GRID, *LINES, "--images", "--truth"]) == 0
    text = capsys.readouterr().out
    assert "0 imaged now, 12 done before" in text
    report = [s for s in text.splitlines() if s.startswith("truth A:")][0]
    on, detectable = (int(v) for v in report.split(" in ")[1].split(" detectable")[0].split(" of "))
    assert on >= 0.8 * detectable and "1 fragment(s)" in report
    assert "truth: 0 false pipeline line(s)" in text


def test_rerun_with_other_line_options_rebuilds_the_lines_without_imaging(reference, line, tmp_path, capsys):
    out = tmp_path / "copy.zarr"
    shutil.copytree(reference, out)
    _, paths = line
    assert survey_main(["survey", *map(str, paths), "-o", str(out), *GRID, "--images", "--line-min-score",
                        "1000"]) == 0
    text = capsys.readouterr().out
    assert "0 imaged now" in text and "lines: 0 pipeline(s) among 0 line(s)" in text
    assert read_csv(product_paths(out)["lines_csv"]) == []
    assert np.all(open_survey(out, "peaks")["line"].values == -1)


def test_no_detection_one_ping_and_no_navigation_give_empty_or_unscaled_lines(line, tmp_path, capsys):
    ds, paths = line
    # no detection: every CF below a map threshold of 1
    out = tmp_path / "none.zarr"
    assert survey_main(["survey", str(paths[0]), "-o", str(out), *TINY, "--map-threshold", "1.0"]) == 0
    assert "lines: 0 pipeline(s) among 0 line(s)" in capsys.readouterr().out
    assert list(csv.reader(open(product_paths(out)["lines_csv"])))[0][:len(LINE_COLUMNS)] == list(LINE_COLUMNS)
    # one ping: no line
    one = write_ping_file(ds.isel(ping=slice(0, 1)), tmp_path / "one.nc")
    assert survey_main(["survey", str(one), "-o", str(tmp_path / "one.zarr"), *TINY]) == 0
    assert "among 0 line(s)" in capsys.readouterr().out
    # no navigation and no speed: lines in pings, lengths and headings unknown, no GeoJSON
    f = write_ping_file(ds.drop_vars(["latitude", "longitude", "heading"]), tmp_path / "nonav.nc")
    out = tmp_path / "nonav.zarr"
    assert survey_main(["survey", str(f), "-o", str(out), *TINY, *LINES]) == 0
    rows = read_csv(product_paths(out)["lines_csv"])
    assert not product_paths(out)["lines_geojson"].exists()
    assert rows and all(r["length_m"] == "" and r["heading_deg"] == "" for r in rows)
    assert "start_along_track_m" in rows[0]


def test_truth_scoring_counts_fragments_false_lines_and_errors_by_hand():
    """Two pipeline lines on target 0 (pings 0-9 and 12-19, 0.5 m off), one on
    no target: 2 fragments, the longer one chosen, RMS 0.5 m, one false line
    over 2 km."""
    n = 20
    truth = LineTruth(["T"], np.full((n, 1), -100.0), np.full((n, 1), 1.0), np.full((n, 1), -100.0))
    rows = [{"line": 0, "kind": "pipeline", "burial_m": 1.3}, {"line": 1, "kind": "pipeline", "burial_m": 0.9},
            {"line": 2, "kind": "pipeline", "burial_m": 1.0}, {"line": 3, "kind": "water", "burial_m": 0.0}]
    p0, p1 = np.arange(0, 10), np.arange(12, 20)
    paths = [(p0, np.full(p0.size, -99.5)), (p1, np.full(p1.size, -100.5)), (p0, np.full(p0.size, 50.0)),
             (p0, np.full(p0.size, -100.0))]
    lines = SurveyLines(rows, [None] * 4, np.zeros(0), 4, None, 1.0, paths)
    det_ping = np.r_[p0, p1]
    det_y = np.full(det_ping.size, -100.2)
    scored, summary = score_lines(lines, truth, det_ping, det_y, 2.0)
    r = scored[0]
    assert r["detectable_pings"] == 18 and r["pings_on_line"] == 10 and r["fragments"] == 2 and r["line"] == 0
    assert r["position_rms_m"] == pytest.approx(0.5) and r["burial_error_m"] == pytest.approx(0.3)
    assert summary["false_lines"] == 1 and summary["false_lines_per_km"] == pytest.approx(0.5)
    assert math.isclose(r["on_line_fraction"], 10 / 18)


def _clutter_pings(rng, n: int, lam: float, own: dict) -> tuple:
    """Detections of ``n`` pings: uniform clutter of ``lam`` per metre across over +-400 m, and ``own[k]``
    (a list of offsets, m) in ping ``k``."""
    ping, y = [], []
    for k in range(n):
        extra = list(own.get(k, []))
        clutter = list(rng.uniform(-400, 400, rng.poisson(lam * 800)))
        ping += [k] * (len(clutter) + len(extra))
        y += clutter + extra
    return np.asarray(ping), np.asarray(y)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_target_is_seen_above_chance_only_where_its_detections_outnumber_the_clutters(seed):
    """Uniform clutter of density ``lam`` per metre across and ping puts a detection within 2 m of any place in
    a ping with probability ``1 - exp(-4 lam)`` (Poisson): the copies' mean count is that fraction of the
    pings, within three binomial standard deviations of the four copies' mean, for a target whose specular
    image lies 15 m nearer the track with a detection of its own there in every ping (the copies clear its
    span: none of them counts those); that target is seen, one with nothing but the clutter is not."""
    rng = np.random.default_rng(seed)
    n, lam = 60, 0.05
    y = np.tile([-100.0, 200.0], (n, 1))
    image = np.tile([-85.0, 200.0], (n, 1))
    truth = LineTruth(["T", "U"], y, np.ones((n, 2)), image)
    ping, det_y = _clutter_pings(rng, n, lam, {k: [-85.0 + rng.normal(0, 0.3)] for k in range(n)})
    lines = SurveyLines([], [], np.zeros(0), 0, None, 1.0, [])
    scored, _ = score_lines(lines, truth, ping, det_y, 1.0)
    p = 1 - np.exp(-4 * lam)
    for r in scored:
        assert abs(r["chance_pings"] - n * p) < 3 * np.sqrt(n * p * (1 - p) / 4)
    assert scored[0]["seen"] and scored[0]["detectable_pings"] == n
    assert not scored[1]["seen"]


def test_a_pipe_with_two_places_in_dense_clutter_is_not_seen_for_having_two_windows():
    """Clutter of 0.2 detections per metre across and ping, nothing else: each 4 m window holds a detection in
    ``1 - exp(-0.8)`` = 55 % of the pings, and either of a target's two places (crossing and image 15 m
    apart) in ``1 - exp(-1.6)`` = 80 %; over 40 pings that union count would be improbable under the copies'
    single-window rate (scipy's tail below 1e-3 in most draws), but each place alone is not, and the target is
    seen in at most one of ten draws (a one-sided test at 5e-4 twice)."""
    from scipy.stats import binom

    n, lam, seen = 40, 0.2, 0
    union_improbable = 0
    for seed in range(10):
        rng = np.random.default_rng(100 + seed)
        truth = LineTruth(["T"], np.full((n, 1), -100.0), np.ones((n, 1)), np.full((n, 1), -85.0))
        ping, det_y = _clutter_pings(rng, n, lam, {})
        r = score_lines(SurveyLines([], [], np.zeros(0), 0, None, 1.0, []), truth, ping, det_y, 1.0)[0][0]
        seen += r["seen"]
        union_improbable += binom.sf(r["detectable_pings"] - 1, n, r["chance_pings"] / n) < 1e-3
    assert seen <= 1 and union_improbable >= 5


def test_seen_above_chance_is_the_binomial_tail_against_the_copies_rate():
    """No clutter but one detection at each copy in the first ``c`` pings: the chance rate is ``c / n``, and a
    target with ``m`` detectable pings of ``n`` is seen exactly when scipy's binomial tail P(X >= m) is below
    1e-3 (its crossing and image one place: the full threshold; checked on both sides of it); a target
    crossing 3 pings is seen in none of them against a rate of half a ping (the floor), since P(X >= 3) =
    (0.5/3)^3 is above it."""
    from scipy.stats import binom

    from clbeam.evaluation.line_truth import CHANCE_OFFSETS_M, SEEN_P_VALUE

    n, c = 40, 4
    rate = c / n
    m_seen = next(m for m in range(n + 1) if binom.sf(m - 1, n, rate) < SEEN_P_VALUE)
    for m, seen in ((m_seen, True), (m_seen - 1, False)):
        truth = LineTruth(["T"], np.full((n, 1), 0.0), np.ones((n, 1)), np.full((n, 1), 0.0))
        own = {k: [0.0] for k in range(m)}
        for k in range(c):
            own.setdefault(k, []).extend(CHANCE_OFFSETS_M)
        ping, det_y = _clutter_pings(np.random.default_rng(0), n, 0.0, own)
        r = score_lines(SurveyLines([], [], np.zeros(0), 0, None, 1.0, []), truth, ping, det_y, 1.0)[0][0]
        assert r["chance_pings"] == c and r["detectable_pings"] == m and r["seen"] is seen
    few = np.full((n, 1), np.nan)
    few[:3] = 50.0
    ping, det_y = _clutter_pings(np.random.default_rng(0), n, 0.0, {k: [50.0] for k in range(3)})
    r = score_lines(SurveyLines([], [], np.zeros(0), 0, None, 1.0, []), LineTruth(["F"], few, np.ones((n, 1)), few),
                    ping, det_y, 1.0)[0][0]
    assert (0.5 / 3) ** 3 > SEEN_P_VALUE and r["detectable_pings"] == 3 and not r["seen"]


def test_echo_strength_takes_the_two_way_spreading_out_of_the_intensity():
    """Equal intensities at 100 and 200 m: the farther echo is 2**4 = 16 times the stronger once the two-way
    spherical spreading (r**4 in intensity) is out; 10 dB more is 10 times; relative to the median; an unknown
    intensity or range weighs 1."""
    level = np.array([-30.0, -30.0, -20.0, np.nan, -30.0])
    r = np.array([100.0, 200.0, 100.0, 150.0, np.nan])
    echo = echo_strength(level, r)
    assert echo[1] / echo[0] == pytest.approx(16.0, rel=1e-12)
    assert echo[2] / echo[0] == pytest.approx(10.0, rel=1e-12)
    assert np.median(echo[:3]) == pytest.approx(1.0, rel=1e-12)
    assert echo[3] == echo[4] == 1.0
