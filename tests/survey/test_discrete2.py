"""The survey of a second physics, as a user runs it: the built-in scene ``discrete2`` (a straight line of 24 pings
8.23 m apart in 200 m of water, no motion, sediment as fast as water; the seabed and two rough pipes as 3-D fields
of point scatterers with exact delays and the transmit column's pattern; pipe A 5 degrees to the track 1 m deep
330-350 m to starboard, pipe B -12 degrees 1.5 m deep 420-460 m to port), simulated over three noise seeds none of
the lines' steps was chosen on and surveyed as ``clbeam survey IN -o OUT --max-range 700 --seabed-band 5 40``, its
lines scored against the simulator's truth (:func:`clbeam.evaluation.line_truth.score_survey`) at the targets of
the lines' validation.  Each pipe's echo comes from its whole stretch inside the transmit beam: it smears across
the ping's plane and deepens with its distance from it, which once gave B two parallel lines 6 m apart and a third
one 8.9 m deep, and both pipes burials 0.6-0.7 m too deep."""

from __future__ import annotations

import numpy as np
import pytest
from survey_common import scored_surveys

SEEDS = (10, 11, 12)
PIPES = ("A", "B")
#: the lines' validation targets (bench/lines_eval.py)
ON_LINE, POSITION_M, BURIAL_M = 0.9, 0.5, 0.5


pytestmark = pytest.mark.slow  # three 24-ping discrete surveys: about 1.5 min on two cores


@pytest.fixture(scope="module")
def surveys(tmp_path_factory):
    """Per seed: the truth's rows per pipeline and the false-line summary."""
    return scored_surveys("discrete2", SEEDS, tmp_path_factory.mktemp("discrete2"),
                          ["--max-range", "700", "--seabed-band", "5", "40"])


def test_each_pipe_is_one_line_with_no_parallel_line_ghost_or_false_line(surveys):
    """Every pipe, every seed: seen above chance, with a detection near it in at least 20 of the 24 pings, one
    line over at least 90 % of its detectable pings and no second ``pipeline`` line along it (no parallel
    duplicate, no ghost beneath it), within 1 m RMS of where it crosses each ping's plane; and no ``pipeline``
    line near no pipe."""
    for rows, summary in surveys:
        assert summary["false_lines"] == 0
        for name in PIPES:
            r = rows[name]
            assert r["seen"] and r["detectable_pings"] >= 20, (name, r)
            assert r["on_line_fraction"] >= ON_LINE and r["fragments"] == 1, (name, r)
            assert r["position_rms_m"] <= 2 * POSITION_M, (name, r)


def test_burials_meet_the_validation_target_with_the_smears_deepening_taken_off(surveys):
    """Burial within 0.5 m for at least 90 % of the pipes over the seeds (all six), and within two reported
    standard errors for at least five of the six (95 % nominal)."""
    errors = np.array([[rows[n]["burial_error_m"] for n in PIPES] for rows, _ in surveys])
    se = np.array([[rows[n]["burial_se_m"] for n in PIPES] for rows, _ in surveys])
    assert np.mean(np.abs(errors) <= BURIAL_M) >= 0.9, errors
    assert np.count_nonzero(np.abs(errors) <= 2 * se) >= 5, (errors, se)


@pytest.mark.xfail(strict=True, reason="open: pipe A (5 degrees to the track, 60 degrees from nadir) lies 0.55-0.59 "
                                       "m RMS from its crossings in two of the three seeds, its detections 0.3 m "
                                       "short in range (B within 0.45 m)")
def test_every_pipe_is_within_half_a_metre_of_its_crossings(surveys):
    """The validation target on position: every pipe, every seed, within 0.5 m RMS of its crossings."""
    position = np.array([[rows[n]["position_rms_m"] for n in PIPES] for rows, _ in surveys])
    assert np.all(position <= POSITION_M), position
