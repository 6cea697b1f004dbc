"""Two pipeline lines end to end joined into one (clbeam.survey.line_joins): which pairs are one pipe, and the
joined line's path, burial and error."""

from __future__ import annotations

import math

import numpy as np
import pytest

from clbeam.survey.burial import BURIAL_MODEL_SE_M, SEABED_SE_M
from clbeam.survey.georef import SurveyNavigation
from clbeam.survey.line_options import LineOptions
from clbeam.survey.line_products import LineDetections, survey_lines

FLOOR = math.hypot(SEABED_SE_M, BURIAL_MODEL_SE_M)
DEFAULTS = LineOptions()


def _pieces(rng, second_shift_m: float = 0.0, second_burial_m: float = 0.5, n: int = 30, depth: float = 80.0,
            heading_deg: float = 8.0, silent: range = range(0), options: LineOptions = DEFAULTS):
    """A pipe at ``heading_deg`` 150 m out, 0.5 m below a flat seabed ``depth`` deep: its echo in pings 0-13 at the
    crossing, and in pings 14-29 ``second_shift_m`` further out and ``second_burial_m`` deep, the second
    piece's detections 2 dB weaker, none in the pings ``silent`` (a gap in its echoes); seabed clutter.  Pings
    4 s apart at 2.05 m/s (8.2 m)."""
    a = math.radians(heading_deg)
    ping, y, z, cf, level = [], [], [], [], []
    for k in range(n):
        second, echo = k >= 14, k not in silent
        y_c = 150.0 + 8.2 * k * math.tan(a) + (second_shift_m if second else 0.0)
        z_c = depth + (second_burial_m if second else 0.5)
        n_c = rng.poisson(0.01 * 300)
        ping += [k] * (int(echo) + n_c)
        y += ([y_c + rng.normal(0, 0.3)] if echo else []) + list(rng.uniform(-300, 300, n_c))
        z += ([z_c + rng.normal(0, 0.1)] if echo else []) + list(depth + rng.uniform(-2, 25, n_c))
        cf += ([rng.uniform(0.6, 0.8)] if echo else []) + list(rng.uniform(0.4, 0.6, n_c))
        level += ([-72.0 if second else -70.0] if echo else []) + list(rng.uniform(-95, -85, n_c))
    nav = SurveyNavigation(n, 2.05)
    nav.time_s[:] = 4.0 * np.arange(n)
    imaged = np.ones(n, dtype=bool)
    nav.finish(imaged)
    det = LineDetections(ping=np.asarray(ping), y=np.asarray(y), z=np.asarray(z), cf=np.asarray(cf),
                         intensity_db=np.asarray(level))
    return survey_lines(det, np.tile([depth, 0.0], (n, 1)), np.zeros((n, 2)), imaged, nav, options)


@pytest.mark.parametrize("seed", range(3))
def test_a_pipe_in_one_piece_is_one_line(seed):
    """Without a break the search's own track spans the pipe: one pipeline line over the 30 pings at 0.5 m,
    its standard error at least the seabed's and the model's (the joins add none below it)."""
    pipes = [r for r in _pieces(np.random.default_rng(seed)).rows if r["kind"] == "pipeline"]
    assert len(pipes) == 1
    assert (pipes[0]["first_ping"], pipes[0]["last_ping"]) == (0, 29)
    assert pipes[0]["burial_m"] == pytest.approx(0.5, abs=0.1)
    assert pipes[0]["burial_se_m"] >= FLOOR - 1e-9


@pytest.mark.parametrize("seed", range(3))
def test_pieces_apart_across_or_in_burial_stay_two_lines(seed):
    """The second piece 8 m further out at 8 degrees (beyond two gates across), or, along the track (no image
    to doubt the burials by: errors of 0.29 m), 5 m deeper (beyond twice the pieces' combined error, 0.8 m):
    two lines, each at its own burial.  (Less deep, the search's own track takes both pieces.)"""
    for shift, burial, heading in ((8.0, 0.5, 8.0), (0.0, 5.0, 0.0)):
        pipes = sorted((r for r in _pieces(np.random.default_rng(seed), shift, burial, heading_deg=heading).rows
                        if r["kind"] == "pipeline"), key=lambda r: r["first_ping"])
        assert len(pipes) == 2
        assert pipes[0]["burial_m"] == pytest.approx(0.5, abs=0.1)
        assert pipes[1]["burial_m"] == pytest.approx(burial, abs=0.1)


@pytest.mark.parametrize("seed", range(3))
def test_pieces_either_side_of_a_gap_are_one_line_up_to_the_join_gap(seed):
    """Over 40 pings the pipe silent over 10 (12-21), beyond the search's own bridge of ``max_gap_pings`` (6):
    its pieces, 11 pings (90.2 m) apart along the track, within ``join_gap_m`` (100 m), are one pipeline line
    over pings 0-39 at 0.5 m; silent over 13 (11-23: 14 pings, 114.8 m apart), two lines; with ``join_gap_m``
    at 80 m the first two lines as well (the pieces lie on one path and at one burial either way)."""
    def pipes(silent, options=DEFAULTS):
        rows = _pieces(np.random.default_rng(seed), n=40, silent=silent, options=options).rows
        return sorted((r for r in rows if r["kind"] == "pipeline"), key=lambda r: r["first_ping"])
    one = pipes(range(12, 22))
    assert [(r["first_ping"], r["last_ping"]) for r in one] == [(0, 39)]
    assert one[0]["burial_m"] == pytest.approx(0.5, abs=0.1)
    assert [(r["first_ping"], r["last_ping"]) for r in pipes(range(11, 24))] == [(0, 10), (24, 39)]
    assert [(r["first_ping"], r["last_ping"]) for r in pipes(range(12, 22), LineOptions(join_gap_m=80.0))] == \
        [(0, 11), (22, 39)]
