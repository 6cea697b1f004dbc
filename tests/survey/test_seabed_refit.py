"""The seabed fitted again without the echoes of a pipe spanning free above it (clbeam.survey.seabed_refit).

The truth is the drawn seabed itself: flat, so any tilt of a fit is its error.
"""

import logging

import numpy as np
import pytest

from clbeam.survey.burial import REFINE_ITERATIONS, _refine, pooled_seabed_lines, refined_seabed_lines
from clbeam.survey.georef import SurveyNavigation
from clbeam.survey.line_options import LineOptions
from clbeam.survey.line_products import SurveyLines
from clbeam.survey.seabed_refit import SEABED_EDGE_BURIAL_M, edge_half_width_m, largest_change_m, seabed_off_lines

SEABED_Z = 300.0
PIPE_Y, PIPE_ABOVE = -351.0, 1.2   # a free span 1.2 m above the seabed, 351 m to port
FAR = np.array([-589.0, 589.0])    # where the tilt is read
PINGS = 30


def _peaks(seed: int) -> list:
    """Per ping: 60 seabed peaks over +-650 m whose depth spreads more far out (the angle's slide) with a
    deeper tail (the sediment), and six of the spanning pipe."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(PINGS):
        y = rng.uniform(-650, 650, 60)
        z = (SEABED_Z + rng.normal(0, 0.1 + np.abs(y) / 700, y.size)
             + rng.exponential(0.5, y.size) * (rng.uniform(size=y.size) < 0.5))
        out.append((np.r_[y, PIPE_Y + rng.normal(0, 2.0, 6)],
                    np.r_[z, SEABED_Z - PIPE_ABOVE + rng.normal(0, 0.1, 6)]))
    return out


def _lines(kind: str, echo_below_m: float | None = -PIPE_ABOVE, path_y: float = PIPE_Y,
           echo_y: float = PIPE_Y) -> tuple:
    """One line of ``kind`` along ``path_y`` (m), and its detections: one a ping at ``echo_y`` (m),
    ``echo_below_m`` below the seabed (``None``: no detection), as ``seabed_off_lines`` takes them."""
    pings = np.arange(PINGS)
    row = {"kind": kind, "burial_m": np.nan, "line": 0}
    if echo_below_m is None:
        labels, dets = np.zeros(0, dtype=np.int64), (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0))
    else:
        labels = np.zeros(PINGS, dtype=np.int64)
        dets = (pings, np.full(PINGS, echo_y), np.full(PINGS, SEABED_Z + echo_below_m))
    return SurveyLines([row], [None], labels, 1, ping_paths=[(pings, np.full(PINGS, path_y))]), dets


def _refit(peaks: list, first: np.ndarray, lines: tuple):
    return seabed_off_lines(peaks, first, *lines, np.zeros((PINGS, 2)), _nav(), LineOptions())


def _nav() -> SurveyNavigation:
    nav = SurveyNavigation(PINGS, 2.05)
    nav.time_s[:] = 4.0 * np.arange(PINGS)
    nav.finish(np.ones(PINGS, dtype=bool))
    return nav


def _tilt_m(fit: np.ndarray) -> float:
    """The median over pings of the fit's depth at +589 m less that at -589 m (m; the truth: 0)."""
    z = fit[:, :1] + fit[:, 1:] * FAR[None, :]
    return float(np.median(z[:, 1] - z[:, 0]))


def test_a_spanning_pipes_peaks_no_longer_tilt_the_seabed():
    """The pipe is its bin's upper edge in every ping: fitted with it, the seabed tilts (0.1-0.6 m over the
    1178 m between the two far points, 0.45 m in the median of 20 draws); fitted again without the peaks
    along its line, the tilt is that of the seabed's peaks alone: RMS 0.10 m over the 20 draws about the truth's
    0, smaller than the first fit's in all but the odd draw."""
    first, refit = [], []
    for seed in range(20):
        peaks = _peaks(seed)
        fit = pooled_seabed_lines(peaks)
        first.append(_tilt_m(fit))
        refit.append(_tilt_m(_refit(peaks, fit, _lines("pipeline"))))
    first, refit = np.abs(first), np.abs(refit)
    assert np.median(first) > 0.35
    assert np.sqrt(np.mean(refit ** 2)) < 0.15
    assert np.mean(refit < first) >= 0.9


def test_a_specular_lines_echoes_are_left_out_where_they_lie_off_its_path():
    """A smooth pipe's line is moved to its crossings, 8 m from its echoes (its image): the peaks about its
    detections go too, and the fit is as level as without the pipe.  The same line with its echoes 30 m
    off the pipe's leaves only seabed peaks out: the pipe's still tilt the fit (0.45 m in the median)."""
    crossing, refit, path_only = PIPE_Y - 8.0, [], []
    for seed in range(10):
        peaks = _peaks(seed)
        fit = pooled_seabed_lines(peaks)
        refit.append(_tilt_m(_refit(peaks, fit, _lines("pipeline", path_y=crossing))))
        elsewhere = _refit(peaks, fit, _lines("pipeline", path_y=crossing, echo_y=PIPE_Y + 30))
        path_only.append(_tilt_m(fit if elsewhere is None else elsewhere))
    assert np.sqrt(np.mean(np.square(refit))) < 0.15
    assert np.median(np.abs(path_only)) > 0.3


@pytest.mark.parametrize("kind, echo_below", [("pipeline", SEABED_EDGE_BURIAL_M + 0.5), ("subbottom", -PIPE_ABOVE),
                                              ("seabed-nadir", -PIPE_ABOVE), ("pipeline", None)])
def test_lines_below_the_seabeds_edge_or_of_the_seabed_itself_leave_the_fit_alone(kind, echo_below):
    """Echoes deeper than the edge's tolerance (a specular line's, whatever its burial), a line that is
    not a pipeline's or the water's, or a line without detections: the first fit stands."""
    peaks = _peaks(0)
    assert _refit(peaks, pooled_seabed_lines(peaks), _lines(kind, echo_below)) is None


def test_the_width_left_out_is_the_smear_across_plus_two_gates():
    """A line at 30 degrees to the track from 400 m across a seabed 300 m down: ``r beam tan(a) / 2`` (r from
    500 to 537 m along it, the beam 4.5 degrees) plus twice the 1.5 m gate, against the closed form."""
    options = LineOptions()
    pings = np.arange(PINGS)
    path = 400.0 + np.tan(np.radians(30.0)) * 2.05 * 4.0 * pings
    seabed = np.tile([SEABED_Z, 0.0], (PINGS, 1))
    half = edge_half_width_m(pings, path, seabed, np.zeros((PINGS, 2)), _nav(), options)
    r = np.hypot(path, SEABED_Z)
    expected = 0.5 * np.radians(options.beam_width_deg) * r * np.tan(np.radians(30.0)) + 2 * options.across_gate_m
    np.testing.assert_allclose(half, expected, rtol=1e-3)  # the track distance adds 1 mm a ping


def test_the_change_is_read_at_the_ends_of_each_pings_peaks():
    """``dz0 + dslope y`` at the ping's outermost peaks (closed form), and infinite where one fit is missing."""
    first = np.array([[300.0, 0.0], [300.0, 0.0]])
    second = np.array([[300.1, 0.001], [300.0, 0.0]])
    peaks = [(np.array([-500.0, 0.0, 400.0]), np.zeros(3)), (np.array([10.0]), np.zeros(1))]
    assert largest_change_m(first, second, peaks) == pytest.approx(0.5)
    second[1] = np.nan
    assert largest_change_m(first, second, peaks) == np.inf
    assert largest_change_m(first, second, [peaks[0], None]) == pytest.approx(0.5)


def test_the_refinement_converges_on_the_seabed_and_never_takes_the_horizon():
    """From a start tilted by 1 m at 600 m and 0.3 m deep, over a flat seabed's 100 peaks (sd 0.1 m) and a
    horizon 8 m down holding three times as many: on the true seabed at both ends within three times the
    standard error of a least-squares line through its peaks (0.019 m at 589 m), nowhere near the horizon; a
    ping without a fit or without peaks keeps what it had."""
    rng = np.random.default_rng(5)
    y = rng.uniform(-650, 650, 400)
    z = np.r_[SEABED_Z + rng.normal(0, 0.1, 100), SEABED_Z + 8.0 + rng.normal(0, 0.1, 300)]
    start = np.array([[SEABED_Z + 0.3, 1.0 / 600.0]])
    refit = refined_seabed_lines([(y, z)], start)
    np.testing.assert_allclose(refit[0, 0] + refit[0, 1] * FAR, SEABED_Z, atol=3 * 0.019)
    assert np.isnan(refined_seabed_lines([(y, z)], np.full((1, 2), np.nan))).all()
    np.testing.assert_array_equal(refined_seabed_lines([None], start), start)


def test_the_lines_searched_twice_say_each_warning_once(caplog):
    """The search runs over the first seabed and again over the refit: what it warns of is said once."""
    from clbeam.survey.products import _said_once

    logger = logging.getLogger("clbeam.survey.line_products")
    with caplog.at_level(logging.WARNING, logger=logger.name):
        with _said_once(logger):
            for message in ("no along-track distance", "no along-track distance", "another"):
                logger.warning(message)
        logger.warning("no along-track distance")
    assert [r.getMessage() for r in caplog.records] == ["no along-track distance", "another",
                                                        "no along-track distance"]


def test_another_threads_warnings_pass_while_one_thread_says_each_once(caplog):
    """Two surveys finalized side by side: while one thread is within ``_said_once``, a second thread's
    repeated warnings are all said, and the first thread's repeat is dropped."""
    import threading

    from clbeam.survey.products import _said_once

    logger = logging.getLogger("clbeam.survey.line_products")
    with caplog.at_level(logging.WARNING, logger=logger.name):
        with _said_once(logger):
            logger.warning("repeated")
            other = threading.Thread(target=lambda: [logger.warning("repeated") for _ in range(2)])
            other.start()
            other.join()
            logger.warning("repeated")
    assert [r.getMessage() for r in caplog.records] == ["repeated"] * 3
    assert [r.thread for r in caplog.records].count(threading.get_ident()) == 1


def test_a_horizon_just_under_a_weak_seabed_does_not_draw_the_refinement_down():
    """A seabed of 40 peaks (sd 0.3 m) over a horizon 2.5 m down holding 360, inside the reweighting's reach:
    20 reweightings from the seabed reach the horizon in some draws (8 of 50 here); the refinement keeps
    the first fit there, and every draw's refined seabed lies within 1 m of the truth at nadir."""
    drawn_down, kept_up = 0, 0
    for seed in range(50):
        rng = np.random.default_rng(seed)
        y = rng.uniform(-650, 650, 400)
        z = np.r_[SEABED_Z + rng.normal(0, 0.3, 40), SEABED_Z + 2.5 + rng.normal(0, 0.3, 360)]
        start = np.array([[SEABED_Z, 0.0]])
        refit = refined_seabed_lines([(y, z)], start)
        kept_up += abs(refit[0, 0] - SEABED_Z) <= 1.0
        drawn_down += abs(_refine(y, z, SEABED_Z, 0.0, 1.0, REFINE_ITERATIONS)[0] - SEABED_Z) > 1.0
    assert drawn_down >= 3
    assert kept_up == 50
