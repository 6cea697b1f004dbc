"""The clutter a line is scored against, measured on copies of its path: against the closed form of Poisson
clutter (uniform in burial, or gathered at one burial as far-angle peaks moved to the burial prior are), robust
to a copy over another line, and a survey of persistent far-angle seabed scatterers with one pipe in it: the
pipe is the only pipeline line."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import erf
from scipy.stats import binom

from clbeam.evaluation.line_truth import LineTruth, score_lines
from clbeam.survey.georef import SurveyNavigation
from clbeam.survey.line_options import LineOptions
from clbeam.survey.line_products import LineDetections, survey_lines
from clbeam.survey.line_score import CF_LEVELS, SearchSize, clutter_hit_rate, copy_offsets, line_score
from clbeam.survey.line_score import tests_per_km as n_tests_per_km

N_PINGS = 100
GATE_Y, GATE_B = 1.5, 0.5


def poisson_clutter(per_m: float, y_range: tuple, burials, rng):
    """Clutter of ``N_PINGS`` pings: per ping a Poisson number of detections (``per_m`` per metre across),
    uniform across ``y_range``, burials drawn by ``burials(n)``; ``(ping, y, b)``."""
    ping, y = [], []
    for k in range(N_PINGS):
        n = rng.poisson(per_m * (y_range[1] - y_range[0]))
        ping += [k] * n
        y += list(rng.uniform(*y_range, n))
    ping, y = np.asarray(ping), np.asarray(y)
    return ping, y, burials(ping.size)


def measured_rate(ping, y, b, path_y, line_b, span=(-700.0, 700.0)):
    """The clutter rate on the line's copies, the clutter within its burial gate; and the copies' number."""
    near = np.abs(b - line_b) <= GATE_B
    offsets = copy_offsets(GATE_Y)
    p = clutter_hit_rate(y[near] - path_y[ping[near]], ping[near], path_y, offsets, GATE_Y, span)
    return p[0], offsets.size


@pytest.mark.parametrize("gathered", [False, True])
def test_hit_rate_of_poisson_clutter_is_the_closed_form(gathered):
    """Uniform in burial over 27 m, the gate holds 1/27 of the clutter; gathered as N(1, 0.3) m, erf(0.5 /
    (0.3 sqrt 2)) of it (89 %, where a density averaged over 6 m of burial would see a sixth)."""
    rng = np.random.default_rng(3)
    per_m = 0.3
    if gathered:
        burials, share = (lambda n: rng.normal(1.0, 0.3, n)), erf(GATE_B / (0.3 * math.sqrt(2)))
    else:
        burials, share = (lambda n: rng.uniform(-2, 25, n)), 2 * GATE_B / 27
    ping, y, b = poisson_clutter(per_m, (200.0, 500.0), burials, rng)
    path_y = 350 + 0.05 * np.arange(N_PINGS)  # a line slowly leaving the track
    p, copies = measured_rate(ping, y, b, path_y, 1.0)
    expected = -math.expm1(-per_m * 2 * GATE_Y * share)
    assert copies == 30
    assert p == pytest.approx(expected, abs=4 * math.sqrt(expected * (1 - expected) / (copies * N_PINGS)))


def test_sparse_clutter_rate_is_not_understated():
    """Under one clutter detection per line on average (K p = 0.4): the mean over 40 surveys of the rate is
    not below the closed form by more than 3 standard errors (a trimmed mean of the copies' counts gave half
    of it) and, the larger side's taken, above it by less than half."""
    rng = np.random.default_rng(8)
    per_m = 0.0004 / (2 * GATE_Y)  # p = 0.0004 a gate a ping
    expected = -math.expm1(-per_m * 2 * GATE_Y)
    rates = []
    for _ in range(40):
        ping, y, b = poisson_clutter(per_m * 10, (200.0, 500.0), lambda n: rng.uniform(0.5, 1.5, n), rng)
        rates.append(measured_rate(ping, y, b, np.full(N_PINGS, 350.0), 1.0)[0])
    se = math.sqrt(expected * 10 / (30 * N_PINGS) / 40)
    assert expected * 10 - 3 * se <= np.mean(rates) <= 1.5 * expected * 10


def test_a_copy_over_another_line_or_beyond_the_swath_does_not_count_as_clutter():
    rng = np.random.default_rng(4)
    ping, y, b = poisson_clutter(0.05, (-700.0, 700.0), lambda n: rng.uniform(-2, 25, n), rng)
    path_y = np.full(N_PINGS, -400.0)
    clean, copies = measured_rate(ping, y, b, path_y, 1.0)
    # another pipe 9 m away, on one of the copies, in every ping: that copy is left out
    with_pipe = measured_rate(np.r_[ping, np.arange(N_PINGS)], np.r_[y, np.full(N_PINGS, -391.0)],
                              np.r_[b, np.full(N_PINGS, 1.0)], path_y, 1.0)[0]
    assert with_pipe == pytest.approx(clean, rel=0.05)  # a plain mean of one side moves by 1 / 15 (100 %)
    # a line running off the swath's edge: its copies count only the pings where they lie inside it
    dense, _ = poisson_clutter(0.3, (400.0, 700.0), lambda n: rng.uniform(0.5, 1.5, n), rng)[:2], None
    ping_d, y_d = dense
    edge_path = np.linspace(640.0, 760.0, N_PINGS)
    p_edge = measured_rate(ping_d, y_d, np.ones(ping_d.size), edge_path, 1.0, span=(400.0, 700.0))[0]
    expected = -math.expm1(-0.3 * 2 * GATE_Y)
    assert p_edge == pytest.approx(expected, abs=0.05)
    # no clutter at all: one detection is assumed over a side's copies' pings
    assert measured_rate(ping[:0], y[:0], b[:0], path_y, 1.0)[0] == pytest.approx(2 / (copies * N_PINGS))


def test_hit_rate_at_each_cf_level_is_the_closed_form_and_strong_echoes_score_by_the_best_level():
    """Clutter with CF uniform over 0.4-0.9: at level c a share (0.9 - c) / 0.5 of it counts (0.4 and below:
    all).  A line hit in 95 of 100 pings, 80 of them at CF >= 0.8, through clutter that hits a gate in 83 %
    of the pings: counted at every CF it is chance, at 0.8 it is not; the score is the best level's less
    log10 of the levels."""
    rng = np.random.default_rng(5)
    per_m = 0.6
    ping, y, b = poisson_clutter(per_m, (200.0, 500.0), lambda n: rng.uniform(0.5, 1.5, n), rng)
    cf = rng.uniform(0.4, 0.9, ping.size)
    path_y = np.full(N_PINGS, 350.0)
    offsets = copy_offsets(GATE_Y)
    levels = (0.0, 0.5, 0.6, 0.7, 0.8)
    p = clutter_hit_rate(y - path_y[ping], ping, path_y, offsets, GATE_Y, (-700.0, 700.0), cf=cf, cf_levels=levels)
    expected = -np.expm1(-per_m * 2 * GATE_Y * np.minimum((0.9 - np.asarray(levels)) / 0.5, 1.0))
    assert p == pytest.approx(expected, abs=4 * math.sqrt(0.25 / (offsets.size * N_PINGS)))
    size = SearchSize(spacing_m=8.0, swath_m=1000.0, burial_span_m=20.0)
    hits = [95, 95, 93, 88, 80]
    score = line_score(hits, N_PINGS, p, GATE_Y, GATE_B, size, 60.0)
    n = n_tests_per_km(size, N_PINGS, GATE_Y, GATE_B, 60.0)
    by_level = [-(math.log10(n) + binom.logsf(h - 1, N_PINGS, q) / math.log(10)) for h, q in zip(hits, p)]
    assert score == pytest.approx(max(by_level) - math.log10(len(levels)))
    assert by_level[0] < 4 < score and int(np.argmax(by_level)) == 4


def lines_without_navigation(det, seabed):
    """:func:`survey_lines` of detections over every ping of a survey without navigation, the grid centres at
    the surface; ``seabed``: ``(n_pings, 2)``."""
    n = seabed.shape[0]
    nav = SurveyNavigation(n, None)
    imaged = np.ones(n, dtype=bool)
    nav.finish(imaged)
    return survey_lines(det, seabed, np.zeros((n, 2)), imaged, nav, LineOptions())


def far_angle_survey(rng, n_pings: int = 120, spacing_m: float = 8.2):
    """Seabed scatterers 250-450 m out on both sides, each seen for the pings whose 4.5 degree transmit beam
    holds it (about three), its peak slid along its arc by 0.3 deg / cos(theta) as the imager's are, and a pipe
    1.5 m deep at -350 m in 95 % of the pings (its stronger echo slides 0.1 deg / cos(theta); CF 0.6-0.8 where
    the clutter's is 0.4-0.6, as Boulders' P and the clutter around it); water 230 m
    deep, the grid centre at the surface."""
    depth, beam = 230.0, math.radians(4.5)
    n_scat = rng.poisson(0.014 * 400 * (n_pings * spacing_m + 60))
    s_sc, y_sc = rng.uniform(-30, n_pings * spacing_m + 30, n_scat), rng.uniform(250, 450, n_scat)
    y_sc *= rng.choice([-1, 1], n_scat)
    z_sc = depth + rng.uniform(-0.3, 0.3, n_scat)
    ping, y, z, cf = [], [], [], []
    for k in range(n_pings):
        seen = (np.abs(s_sc - k * spacing_m) <= 0.5 * beam * np.hypot(y_sc, z_sc)) & (rng.random(n_scat) < 0.8)
        yk, zk = list(y_sc[seen]), list(z_sc[seen])
        slide, cf_k = np.full(len(yk), 0.3), list(rng.uniform(0.4, 0.6, len(yk)))
        if rng.random() < 0.95:  # a strong echo: its peak slides less and is more coherent
            yk.append(-350.0)
            zk.append(depth + 1.5)
            slide = np.r_[slide, 0.1]
            cf_k.append(rng.uniform(0.6, 0.8))
        r, theta = np.hypot(yk, zk), np.arctan2(yk, zk)
        theta = theta + np.radians(slide) / np.cos(theta) * rng.normal(size=theta.size)
        ping += [k] * r.size
        y += list(r * np.sin(theta))
        z += list(r * np.cos(theta))
        cf += cf_k
    ping, cf = np.asarray(ping), np.asarray(cf)
    return LineDetections(ping=ping, y=np.asarray(y), z=np.asarray(z), cf=cf), np.tile([depth, 0.0], (n_pings, 1))


@pytest.mark.slow
def test_persistent_far_angle_seabed_scatterers_make_no_pipeline_line_and_the_pipe_among_them_one():
    """The clutter of the simulated surveys' false lines (docs/lines.md): scatterers in the beam for several
    pings, their peaks moved to the burial prior's depth, so their burials gather at about 1 m."""
    rng = np.random.default_rng(7)
    det, seabed = far_angle_survey(rng)
    n = seabed.shape[0]
    lines = lines_without_navigation(det, seabed)
    pipes = [r for r in lines.rows if r["kind"] == "pipeline"]
    # the score is what is tested here (the positions against the truth are the evaluation's): the pipe's line
    # is the only pipeline line, near the pipe, over most of its pings
    assert len(pipes) == 1 and abs(pipes[0]["mean_y_m"] + 350) < 5 and pipes[0]["n_pings"] >= 0.85 * n


def smeared_survey(rng, n_pings: int = 60, spacing_m: float = 8.2, heading_deg: float = 40.0):
    """A rough pipe 1 m deep crossing the track at ``heading_deg``, 300 m out at the first ping: each ping
    sees the stretch of it inside the 4.5 degree transmit beam, 2-4 detections spread uniformly over
    ``r beam tan(a)`` across (26 m at 40 degrees); sparse clutter; water 230 m deep."""
    depth, beam, a = 230.0, math.radians(4.5), math.radians(heading_deg)
    ping, y, z, cf = [], [], [], []
    for k in range(n_pings):
        y_c = 300.0 + k * spacing_m * math.tan(a)
        half = 0.5 * beam * math.hypot(y_c, depth) * math.tan(a)
        n = int(rng.integers(2, 5))
        n_c = rng.poisson(0.01 * 800)
        ping += [k] * (n + n_c)
        y += list(y_c + rng.uniform(-half, half, n)) + list(rng.uniform(-800, 800, n_c))
        z += [depth + 1.0] * n + list(depth + rng.uniform(-2, 25, n_c))
        cf += list(rng.uniform(0.6, 0.8, n)) + list(rng.uniform(0.4, 0.6, n_c))
    return (LineDetections(ping=np.asarray(ping), y=np.asarray(y), z=np.asarray(z), cf=np.asarray(cf)),
            np.tile([depth, 0.0], (n_pings, 1)))


@pytest.mark.parametrize("seed", range(3))
def test_a_crossing_pipe_smeared_over_the_beam_is_one_pipeline_line(seed):
    """The tracks that a crossing pipe's smear holds (several detections a ping, 26 m across) run side by
    side: one pipeline line remains, on the pipe (the others shadow it within two of its gates, which hold
    the smear), within half the smear's half-width (RMS); two fixed 1.5 m gates kept two to four lines here,
    and two of the simulated Cross scene's crossing pipe."""
    rng = np.random.default_rng(seed)
    det, seabed = smeared_survey(rng)
    n = seabed.shape[0]
    lines = lines_without_navigation(det, seabed)
    pipes = [(r, lines.ping_paths[k]) for k, r in enumerate(lines.rows) if r["kind"] == "pipeline"]
    assert len(pipes) == 1
    pings, path = pipes[0][1]
    truth = 300.0 + pings * 8.2 * math.tan(math.radians(40.0))
    half = 0.5 * math.radians(4.5) * np.hypot(truth, 230.0) * math.tan(math.radians(40.0))
    assert np.sqrt(np.mean((path - truth) ** 2)) < 0.5 * half.mean() and pings.size >= 0.8 * n


def test_two_tight_pipes_side_by_side_at_a_heading_stay_two_lines():
    """Two pipes 30 m apart, both at 40 degrees to the track, their detections within 0.2 m: two pipeline
    lines (a line shadows another within two of its gates as narrowed to its detections' spread, not the
    smear a crossing line could have there, 30-60 m across at these ranges)."""
    rng = np.random.default_rng(4)
    n, depth, a = 60, 230.0, math.radians(40.0)
    ping, y, z, cf = [], [], [], []
    for k in range(n):
        for y0 in (300.0, 330.0):
            ping.append(k)
            y.append(y0 + k * 8.2 * math.tan(a) + rng.normal(0, 0.2))
            z.append(depth + 1.0 + rng.normal(0, 0.1))
            cf.append(rng.uniform(0.6, 0.8))
        n_c = rng.poisson(0.01 * 800)
        ping += [k] * n_c
        y += list(rng.uniform(-800, 800, n_c))
        z += list(depth + rng.uniform(-2, 25, n_c))
        cf += list(rng.uniform(0.4, 0.6, n_c))
    det = LineDetections(ping=np.asarray(ping), y=np.asarray(y), z=np.asarray(z), cf=np.asarray(cf))
    lines = lines_without_navigation(det, np.tile([depth, 0.0], (n, 1)))
    pipes = sorted(r["mean_y_m"] - np.mean(np.arange(n) * 8.2 * math.tan(a)) for r in lines.rows
                   if r["kind"] == "pipeline")
    assert len(pipes) == 2 and abs(pipes[0] - 300.0) < 1.0 and abs(pipes[1] - 330.0) < 1.0


def test_a_side_whose_copies_barely_reach_the_detections_does_not_set_the_clutter_rate():
    """A line 1 m inside the detections' edge: its copies beyond the edge lie within the extent in one ping
    only, where the floor of one hit over their pings would read as clutter in every ping (rate 1).  The rate
    is the other side's, the closed form ``1 - exp(-2 w rho)`` of Poisson clutter."""
    rng = np.random.default_rng(8)
    per_m = 0.02
    ping, y, _ = poisson_clutter(per_m, (-600.0, 400.0), lambda n: np.zeros(n), rng)
    path_y = np.full(N_PINGS, -598.0)
    path_y[0] = -590.0  # the nearest copy on the outer side (6 m out) lies inside the extent in this ping only
    offsets = copy_offsets(GATE_Y)
    p = clutter_hit_rate(y - path_y[ping], ping, path_y, offsets, GATE_Y, (-600.0, 400.0))
    expected = -math.expm1(-per_m * 2 * GATE_Y)
    assert p[0] == pytest.approx(expected, abs=4 * math.sqrt(expected / (offsets.size // 2 * N_PINGS)))


def straight_survey(rng, hit_rate: float, clutter_per_m: float, n_pings: int = 60, depth: float = 230.0):
    """A pipe 1 m deep drifting 0.3 m a ping from -350 m, detected in a share ``hit_rate`` of the pings (CF
    0.6-0.8, 0.2 m scatter across), in Poisson clutter of ``clutter_per_m`` a metre across -500 to -200 m
    (CF 0.4-0.6, burials uniform over 27 m); ``(detections, seabed, the pipe's path)``."""
    path = -350.0 + 0.3 * np.arange(n_pings)
    ping, y, z, cf = [], [], [], []
    for k in range(n_pings):
        n = rng.poisson(clutter_per_m * 300)
        yk, zk, ck = list(rng.uniform(-500, -200, n)), list(depth + rng.uniform(-2, 25, n)), list(rng.uniform(0.4, 0.6, n))
        if rng.random() < hit_rate:
            yk.append(path[k] + rng.normal(0, 0.2))
            zk.append(depth + 1.0)
            ck.append(rng.uniform(0.6, 0.8))
        ping += [k] * len(yk)
        y, z, cf = y + yk, z + zk, cf + ck
    det = LineDetections(ping=np.asarray(ping), y=np.asarray(y), z=np.asarray(z), cf=np.asarray(cf))
    return det, np.tile([depth, 0.0], (n_pings, 1)), path


@pytest.mark.parametrize("seed", range(3))
def test_a_line_on_the_true_path_scores_as_the_line_found_on_it_and_a_copy_off_it_as_chance(seed):
    """``score_path``, the evaluation's question whether a target could be reported at all: on a pipe detected in
    90 % of the pings the line the search finds scores within 5 % of its true path; the path moved 20 m into the
    clutter scores below zero (a chance line a km or more); a pipe detected in 30 % of the pings, its echoes above
    every clutter CF, scores above the lines' threshold and at most the closed form of its hits at CF 0.6 against
    one clutter hit over the copies' pings (the floor :func:`clutter_hit_rate` keeps), five CF levels tried."""
    pings = np.arange(60)
    det, seabed, path = straight_survey(np.random.default_rng(seed), 0.9, 0.05)
    lines = lines_without_navigation(det, seabed)
    found = [r["score"] for r in lines.rows if r["kind"] == "pipeline" and abs(r["mean_y_m"] + 341) < 3]
    assert len(found) == 1
    assert lines.score_path(pings, path) == pytest.approx(found[0], rel=0.05)
    assert lines.score_path(pings, path + 20.0) < 0
    det, seabed, path = straight_survey(np.random.default_rng(seed), 0.3, 0.3)
    lines = lines_without_navigation(det, seabed)
    on = det.cf >= 0.6
    hits = np.unique(det.ping[on]).size
    copies_pings = copy_offsets(GATE_Y).size // 2 * 60  # one side's copies, every ping within the swath
    size = SearchSize(8.2, 300.0, 27.0)
    closed = line_score([hits], 60, [1.0 / copies_pings], GATE_Y, GATE_B, size, LineOptions().max_angle_deg)
    # at most the closed form at the narrowest gate (the frame's swath and burial span are the detections' 1-99 %
    # spans, about 294 m and 26.5 m: 0.1 more); a gate widened by the detections' offset uncertainty takes fewer
    # copies (a higher floor) and more tests, so less: still a line
    score = lines.score_path(pings, path)
    assert lines.min_score <= score <= closed - math.log10(len(CF_LEVELS)) + 0.5


def test_the_evaluation_calls_a_target_trackable_by_the_better_of_its_two_places():
    """:func:`score_lines`' ``path_score`` is the better of the line on the target's crossing (at its own
    burial) and on its image: a target whose image is the pipe's path (its crossing 15 m off, in the clutter)
    takes the image's score, reaches the threshold and is trackable; one whose both places lie in the clutter
    is not."""
    det, seabed, path = straight_survey(np.random.default_rng(5), 0.9, 0.05)
    lines = lines_without_navigation(det, seabed)
    n = path.size
    truth = LineTruth(["T", "U"], np.c_[path + 15, path + 40], np.ones((n, 2)), np.c_[path, path + 25])
    scored, _ = score_lines(lines, truth, det.ping, det.y, 1.0)
    own = lines.score_path(np.arange(n), path)
    assert own >= lines.min_score and lines.score_path(np.arange(n), path + 15, 1.0) < 0
    assert scored[0]["path_score"] == pytest.approx(own) and scored[0]["trackable"]
    assert scored[1]["path_score"] < 0 and not scored[1]["trackable"]


@pytest.mark.parametrize("case", ["no seabed", "stops at ping 20", "pings shuffled"])
def test_a_true_path_scores_as_its_found_line_without_a_seabed_past_its_echoes_and_in_any_order(case):
    """The path score of a pipe detected in 90 % of the pings stays within 5 % of the line the search finds on it
    where the pings have no seabed (burials unknown pass the gate, for the search and the path alike), where the
    pipe's echoes stop at ping 20 while its path runs on (the line spans its members: the pings beyond are no
    misses), and with the path's pings given in any order."""
    det, seabed, path = straight_survey(np.random.default_rng(2), 0.9, 0.05)
    pings = np.arange(path.size)
    if case == "no seabed":
        seabed = np.full_like(seabed, np.nan)
    if case == "stops at ping 20":
        keep = (det.ping < 20) | (np.abs(det.y - path[det.ping]) > 1.0)
        det = LineDetections(ping=det.ping[keep], y=det.y[keep], z=det.z[keep], cf=det.cf[keep])
    lines = lines_without_navigation(det, seabed)
    found = [r["score"] for r in lines.rows if abs(r["mean_y_m"] + 345) < 8]
    if case == "pings shuffled":
        shuffle = np.random.default_rng(0).permutation(path.size)
        pings, path = pings[shuffle], path[shuffle]
    assert len(found) == 1
    assert lines.score_path(pings, path) == pytest.approx(found[0], rel=0.05)
