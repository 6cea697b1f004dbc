"""A survey line none of the line search's steps but the edges test were chosen on, as a user runs it: the built-in
scene ``heading245`` (180 m of mud over a horizon 20 m down, heading 245 degrees, roll 3 degrees, heave 0.6 m; S1
smooth at 8 degrees to the track, S2 smooth 2 m deep at -4 degrees curving 10 degrees/km, P3 rough at 25 degrees, a
row of five boulders along the track), simulated over three noise seeds and surveyed as ``clbeam survey IN -o OUT
--max-range 650 --seabed-band 5 40``, its lines scored against the simulator's truth
(:func:`clbeam.evaluation.line_truth.score_survey`) at the targets of the lines' validation: one line over 90 % of a
pipe's detectable pings, position RMS within 0.5 m, burial within 0.5 m, no false ``pipeline`` line (the boulder row
among them: a row of point targets is no line target)."""

from __future__ import annotations

import numpy as np
import pytest
from survey_common import scored_surveys

SEEDS = (0, 1, 2)
#: the lines' validation targets (bench/lines_eval.py)
ON_LINE, POSITION_M, BURIAL_M = 0.9, 0.5, 0.5


pytestmark = pytest.mark.slow  # three 40-ping surveys: about 2.5 min on two cores


@pytest.fixture(scope="module")
def surveys(tmp_path_factory):
    """Per seed: the truth's rows per pipeline and the false-line summary."""
    return scored_surveys("heading245", SEEDS, tmp_path_factory.mktemp("heading245"),
                          ["--max-range", "650", "--seabed-band", "5", "40"])


def test_every_pipeline_is_one_line_and_no_line_is_false(surveys):
    """Every pipe, every seed: seen above chance in at least 30 of the 40 pings, one line over at least 90 % of
    its detectable pings, no second line along it, within 1 m RMS of where it crosses each ping's plane (or of
    its specular image); and no ``pipeline`` line near no pipe, the boulder row's included."""
    for rows, summary in surveys:
        assert summary["false_lines"] == 0
        for name in ("S1", "S2", "P3"):
            r = rows[name]
            assert r["seen"] and r["detectable_pings"] >= 30, name
            assert r["on_line_fraction"] >= ON_LINE and r["fragments"] == 1, name
            assert r["position_rms_m"] <= 2 * POSITION_M, name


def test_the_rough_pipe_and_the_smooth_one_at_8_degrees_read_their_burials(surveys):
    """P3 (rough, 1 m deep, 25 degrees to the track: its echo comes from where it crosses the plane) within 0.5 m
    of its burial in every seed; S1 (smooth, 0.5 m deep, 8 degrees: its echo comes from its nearest point, 6
    degrees off the plane, 2.8 m deeper) within 1 m in every seed, the extra depth taken off (its echoes' two
    edges, clbeam.survey.edges)."""
    p3 = np.array([rows["P3"]["burial_error_m"] for rows, _ in surveys])
    s1 = np.array([rows["S1"]["burial_error_m"] for rows, _ in surveys])
    assert np.all(np.abs(p3) <= BURIAL_M), p3
    assert np.all(np.abs(s1) <= 2 * BURIAL_M), s1


@pytest.mark.xfail(strict=True, reason="open: in seed 0 S2 reads -0.74 m in burial, beyond 0.5 m (within two "
                                       "standard errors, 1.01 m; S2, 420 m out in 180 m of water, lies 67 degrees "
                                       "from nadir, beyond the burial target's 60); S1 +0.41 m")
def test_positions_and_burials_meet_the_validation_targets(surveys):
    """The validation targets over the three pipes and three seeds: position RMS within 0.5 m for every one,
    burial within 0.5 m for at least 90 % (all nine), and within two reported standard errors for at least
    eight of the nine (95 % nominal)."""
    names = ("S1", "S2", "P3")
    position = np.array([[rows[n]["position_rms_m"] for n in names] for rows, _ in surveys])
    errors = np.array([[rows[n]["burial_error_m"] for n in names] for rows, _ in surveys])
    se = np.array([[rows[n]["burial_se_m"] for n in names] for rows, _ in surveys])
    assert np.all(position <= POSITION_M), position
    assert np.mean(np.abs(errors) <= BURIAL_M) >= 0.9, errors
    assert np.count_nonzero(np.abs(errors) <= 2 * se) >= 8, (errors, se)
