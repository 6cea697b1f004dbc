"""Lines of pipes whose echo comes from their whole stretch inside the transmit beam (discrete scatterers): the
smear's deepening taken off their burial, the shadow a transmit sidelobe casts beside them, and a line an
earlier search kept carried to a search over another seabed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from clbeam.survey.burial import smear_deepening_m
from clbeam.survey.georef import SurveyNavigation
from clbeam.survey.line_duplicates import SHADOW_BEAMS
from clbeam.survey.line_options import LineOptions
from clbeam.survey.line_products import LineDetections, diffuse_shift, survey_lines

C, LENGTH, F_C = 1500.0, 3.5, 5500.0
BEAM = C / F_C / LENGTH  # lambda / L at the band's centre (rad)


def _lines(det: LineDetections, depth: float, n: int, timed: bool = False, carried: list | None = None,
           seabed: np.ndarray | None = None):
    """:func:`survey_lines` without navigation, the grid centres at the surface, a flat seabed ``depth`` deep
    (or ``seabed``, ``(n, 2)``); ``timed``: pings 4 s apart at 2.05 m/s (8.2 m: the along-track distance known);
    ``carried``: an earlier search's tracks."""
    nav = SurveyNavigation(n, 2.05 if timed else None)
    if timed:
        nav.time_s[:] = 4.0 * np.arange(n)
    imaged = np.ones(n, dtype=bool)
    nav.finish(imaged)
    seabed = np.tile([depth, 0.0], (n, 1)) if seabed is None else seabed
    return survey_lines(det, seabed, np.zeros((n, 2)), imaged, nav, LineOptions(), carried=carried)


def _main_lobe_offsets(rng, r: float, size: int) -> np.ndarray:
    """Distances off the ping's plane (m) at range ``r`` of echoes drawn from the energy of a column's one-way
    main lobe at the band's centre, ``sinc^2(L sin(phi) / lambda)``, over half its width either side of the
    plane (the stretch a line's gates hold; inverse CDF on a fine grid)."""
    phi = np.linspace(-0.5 * BEAM, 0.5 * BEAM, 4001)
    cdf = np.cumsum(np.sinc(LENGTH * np.sin(phi) / (C / F_C)) ** 2)
    return r * np.sin(np.interp(rng.random(size), cdf / cdf[-1], phi))


def _discrete_pipe(rng, heading_deg: float, n: int = 60, y0: float = 340.0, depth: float = 200.0,
                   burial: float = 1.0, smear: bool = True, echoes: int = 1) -> LineDetections:
    """A pipe of scatterers at ``heading_deg`` to the track, ``burial`` below a flat seabed ``depth`` deep: in
    each ping ``echoes`` echoes from the stretch inside the beam, each ``x`` off the plane imaged at ``y_c + x
    tan a`` across and ``sqrt(z^2 + x^2)`` deep (its exact image; the peaks a ping keeps, their echoes anywhere
    in the beam), with seabed clutter; ``smear``: with each
    detection's :func:`offplane_deepening_m` (the band's centre only)."""
    a = math.radians(heading_deg)
    ping, y, z, cf = [], [], [], []
    for k in range(n):
        y_c, z_p = y0 + 8.2 * k * math.tan(a), depth + burial
        x = _main_lobe_offsets(rng, math.hypot(y_c, z_p), echoes)
        n_c = rng.poisson(0.01 * 800)
        ping += [k] * (echoes + n_c)
        y += list(y_c + x * math.tan(a)) + list(rng.uniform(-800, 800, n_c))
        z += list(np.hypot(z_p, x)) + list(depth + rng.uniform(-2, 25, n_c))
        cf += list(rng.uniform(0.6, 0.8, echoes)) + list(rng.uniform(0.4, 0.6, n_c))
    ping, y, z, cf = (np.asarray(v) for v in (ping, y, z, cf))
    deeper = smear_deepening_m(np.hypot(y, z), np.arctan2(y, z), BEAM) if smear else None
    return LineDetections(ping=ping, y=y, z=z, cf=cf, smear_m=deeper)


@pytest.mark.parametrize("seed", range(3))
def test_a_discrete_pipe_at_a_heading_is_raised_by_its_smears_mean_deepening(seed):
    """A pipe of scatterers at 5 degrees, 340 m across in 200 m of water, 1 m deep: its echoes image
    ``sqrt(z^2 + x^2) - z`` deeper, on average ``R E[phi^2] / (2 cos theta)`` over the main lobe's energy
    within half the beam either side of the plane (here by numerical integration, ``quad``).  Read as
    measured its burial is that much too deep; raised by its detections' smear it lies within three standard
    errors of the smear's sample mean (the detections' own spread over the square root of their number) of
    the truth."""
    rng = np.random.default_rng(seed)
    n = 60
    y_c = 340.0 + 8.2 * np.arange(n) * math.tan(math.radians(5.0))
    weight = lambda p: np.sinc(LENGTH * math.sin(p) * F_C / C) ** 2  # noqa: E731
    half = 0.5 * BEAM
    mean_square = quad(lambda p: p * p * weight(p), -half, half)[0] / quad(weight, -half, half)[0]
    # R / (2 cos theta) = R^2 / (2 z) at each ping's crossing, averaged over the pings
    expected = float(np.mean((y_c ** 2 + 201.0 ** 2) * mean_square / (2 * 201.0)))
    assert 0.15 < expected < 0.3
    plain = _lines(_discrete_pipe(np.random.default_rng(seed), 5.0, n, smear=False), 200.0, n)
    fixed = _lines(_discrete_pipe(rng, 5.0, n), 200.0, n)
    # the longest pipeline line (one echo a ping anywhere in the smear, 2.6 m across: a line may break once)
    p, f = (max((row for row in lines.rows if row["kind"] == "pipeline"), key=lambda row: row["n_pings"])
            for lines in (plain, fixed))
    tolerance = 3 * max(f["burial_std_m"], 0.3) / math.sqrt(f["n_pings"])
    assert f["burial_m"] == pytest.approx(1.0, abs=tolerance)
    assert p["burial_m"] - f["burial_m"] == pytest.approx(expected, rel=0.05)


def test_a_smeared_pipes_line_reports_the_path_averaged_over_two_fit_lengths(monkeypatch):
    """Pipes of scatterers at 10 and 14 degrees, 340 m across (one echo a ping anywhere in the stretch inside
    the beam: smears of 2.7 and 3.9 m half-width, under the search's ``WIDE_SMEAR_M``): the path
    :func:`survey_lines` reports for the pipeline line is the wide fit of ``line_path(..., reported=True)``.
    Over 12 surveys its RMS distance from the crossings is on average within 0.85 of the plain fit's, the path
    the tracks are ranked by where their smear is under ``WIDE_SMEAR_M`` (``REPORTED_WIDE_SMEAR_M`` out of
    reach; 0.73-0.75 over 8 seeds a heading), and nearer in at least 10 of them (15 of 16 measured)."""
    import clbeam.survey.lines as lines

    def error(seed: int, heading: float) -> float:
        n = 60
        found = _lines(_discrete_pipe(np.random.default_rng(seed), heading, n), 200.0, n)
        k = max((i for i, row in enumerate(found.rows) if row["kind"] == "pipeline"),
                key=lambda i: found.rows[i]["n_pings"])
        pings, y = found.ping_paths[k]
        return float(np.sqrt(np.mean((y - (340.0 + 8.2 * pings * math.tan(math.radians(heading)))) ** 2)))
    cases = [(seed, heading) for seed in range(6) for heading in (10.0, 14.0)]
    reported = np.array([error(*c) for c in cases])
    monkeypatch.setattr(lines, "REPORTED_WIDE_SMEAR_M", math.inf)
    ranked = np.array([error(*c) for c in cases])
    assert reported.mean() < 0.85 * ranked.mean(), (reported, ranked)
    assert np.count_nonzero(reported < ranked) >= 10, (reported, ranked)


def test_a_wide_smear_holding_several_lines_reports_their_centre(monkeypatch):
    """Pipes of scatterers at 25 degrees, 500 m across in 200 m of water, with eight echoes a ping anywhere in
    the stretch inside the beam (a smear of 9 m half-width, several tracks side by side in it, the way a pipe
    far out at a heading holds them in the discrete survey draws): the pipeline line's path is the median of
    the paths of the lines in its smear (``SMEAR_TRACKS``), its row's mean offset that path's.  Against
    the crossings, its RMS error over six surveys is on average within 0.8 of the path of the line the search
    keeps (``SMEAR_TRACKS`` out of reach: 0.56 measured), nearer in at least two of them and further in none
    by more than 5 cm (measured over three other sets of six seeds: 0.49-0.71, further in none of 18)."""
    import clbeam.survey.line_duplicates as duplicates

    def error(seed: int) -> float:
        n, a = 40, math.radians(25.0)
        found = _lines(_discrete_pipe(np.random.default_rng(seed), 25.0, n, y0=500.0, echoes=8), 200.0, n,
                       timed=True)
        k = max((i for i, row in enumerate(found.rows) if row["kind"] == "pipeline"),
                key=lambda i: found.rows[i]["n_pings"])
        pings, y = found.ping_paths[k]
        assert found.rows[k]["mean_y_m"] == pytest.approx(float(np.mean(y)), abs=1e-9)
        return float(np.sqrt(np.mean((y - (500.0 + 8.2 * pings * math.tan(a))) ** 2)))
    centred = np.array([error(seed) for seed in range(6)])
    monkeypatch.setattr(duplicates, "SMEAR_TRACKS", math.inf)
    kept = np.array([error(seed) for seed in range(6)])
    assert centred.mean() < 0.8 * kept.mean(), (centred, kept)
    assert np.count_nonzero(centred < kept - 0.05) >= 2, (centred, kept)
    assert not np.any(centred > kept + 0.05), (centred, kept)


def _along_pipe(found, truth_y: np.ndarray) -> list:
    """The pipeline lines of ``found`` whose path lies within 3 m of the pipe (``truth_y``, m across at each
    ping) over half their pings: ``(pings, RMS error m, burial m)``."""
    out = []
    for row, (pings, y) in zip(found.rows, found.ping_paths):
        err = np.abs(y - truth_y[pings])
        if row["kind"] == "pipeline" and np.count_nonzero(err <= 3.0) >= 0.5 * pings.size:
            out.append((pings, float(np.sqrt(np.mean(err ** 2))), row["burial_m"]))
    return out


def test_a_line_the_first_search_kept_is_not_lost_by_the_second(monkeypatch):
    """The search over the seabed fitted again takes the first search's tracks as candidates (four surveys).
    Where it finds nothing along the pipe (its search made to lose it) over a seabed fitted again 0.3 m
    shallower, the carried track is the pipe's one line over every ping, described over that seabed: within
    0.5 m RMS of its crossings and 0.15 m of its 1.3 m burial below it (0.18-0.31 m and 1.26-1.33 m measured;
    over the first seabed the line reads 0.96-1.03 m); without it there is none.  Where it finds the pipe
    again, over a seabed 4 m wrong over 14 pings, the lines along the pipe are those it finds without the
    carried tracks (no second line), and in at least one survey the carried tracks are not the ones it found
    (they were judged, not merely recognised)."""
    import clbeam.survey.line_products as line_products

    n, judged = 40, 0
    truth = 340.0 + 8.2 * np.arange(n) * math.tan(math.radians(3.0))
    for seed in range(4):
        det = _discrete_pipe(np.random.default_rng(seed), 3.0, n)
        first = _lines(det, 200.0, n, timed=True)
        refit, wrong = np.tile([199.7, 0.0], (n, 1)), np.tile([200.0, 0.0], (n, 1))
        wrong[14:28, 0] -= 4.0
        second = _lines(det, 200.0, n, timed=True, carried=first.tracks, seabed=wrong)
        own = _lines(det, 200.0, n, timed=True, seabed=wrong)
        extents = [[(p[0], p[-1]) for p, _, _ in _along_pipe(found, truth)] for found in (second, own)]
        assert extents[0] and extents[0] == extents[1], extents
        carried = {tr.members.tobytes() for tr in first.tracks}
        judged += any(tr.members.tobytes() not in carried for tr in second.tracks)
        with monkeypatch.context() as patch:
            patch.setattr(line_products, "find_tracks", lambda *a, **k: [])
            assert not _along_pipe(_lines(det, 200.0, n, timed=True, seabed=refit), truth)
            (pings, rms, burial), = _along_pipe(_lines(det, 200.0, n, timed=True, carried=first.tracks,
                                                       seabed=refit), truth)
        assert pings.size == n and rms < 0.5 and abs(burial - 1.3) < 0.15, (seed, pings, rms, burial)
    assert judged >= 1


def test_a_pipe_along_the_track_is_not_raised():
    """Nearest point in the beam (a pipe at 0.5 degrees, its nearest point 3 m off the plane at 400 m): the echo
    concentrates where its range is stationary and the smear's correction does not apply; undecided, it takes
    the halfway shift of a smooth pipe's extra depth, ``dz / 2`` (closed form ``sqrt(z^2 + x^2) - z``)."""
    half = 0.5 * math.radians(LineOptions().beam_width_deg)
    x = 350.0 * math.sin(math.radians(0.5)) * math.cos(math.radians(0.5))
    dz = math.hypot(201.0, x) - 201.0
    fit = {"extra_depth_m": dz, "offplane_rad": x / math.hypot(350.0, 201.0)}
    assert fit["offplane_rad"] < half
    shift = diffuse_shift(fit, np.full(10, 0.3), False, LineOptions())
    assert shift["burial_shift_m"] == pytest.approx(-0.5 * dz) and not shift["always"]
    outside = diffuse_shift({"extra_depth_m": dz, "offplane_rad": 1.1 * half}, np.array([0.2, 0.4, np.nan]), True,
                            LineOptions())
    assert outside["burial_shift_m"] == pytest.approx(-0.3) and outside["always"]
    assert diffuse_shift({"extra_depth_m": dz, "offplane_rad": 1.1 * half}, np.zeros(0), True, LineOptions()) is None


def _side_by_side(rng, offset_m: float, extra_burial_m: float, weaker_db: float, n: int = 24):
    """A rough pipe at 5 degrees 340 m across (200 m of water, 1 m deep) and a second line ``offset_m`` further
    out, ``extra_burial_m`` deeper and ``weaker_db`` weaker, in 20 of the pings; seabed clutter."""
    a, depth = math.tan(math.radians(5.0)), 200.0
    ping, y, z, cf, level = [], [], [], [], []
    for k in range(n):
        y_c = 340.0 + 8.2 * k * a
        second = 2 <= k < 22
        n_c = rng.poisson(0.01 * 800)
        ping += [k] * (1 + second + n_c)
        y += [y_c + rng.normal(0, 0.3)] + [y_c + offset_m + rng.normal(0, 0.3)] * second
        y += list(rng.uniform(-800, 800, n_c))
        z += [depth + 1.0 + rng.normal(0, 0.1)] + [depth + 1.0 + extra_burial_m + rng.normal(0, 0.1)] * second
        z += list(depth + rng.uniform(-2, 25, n_c))
        cf += list(rng.uniform(0.6, 0.8, 1 + second)) + list(rng.uniform(0.4, 0.6, n_c))
        level += [-70.0] + [-70.0 - weaker_db] * second + list(rng.uniform(-95, -85, n_c))
    ping, y, z, cf, level = (np.asarray(v) for v in (ping, y, z, cf, level))
    return _lines(LineDetections(ping=ping, y=y, z=z, cf=cf, intensity_db=level), depth, n)


@pytest.mark.parametrize("weaker_db, extra_burial_m", [(15.0, 2.0), (7.0, 1.5)])
def test_a_transmit_sidelobes_shadow_beside_a_pipe_is_no_second_line(weaker_db, extra_burial_m):
    """The stretch of a pipe at 5 degrees seen through the first transmit sidelobe (44 m off the plane at
    394 m: 15 dB weaker, 2 m deeper) or the main lobe's edge (7 dB, 1.5 m), 7 m further out, within two gates
    plus the smear's reach out to :data:`SHADOW_BEAMS` beam widths (``2 SHADOW_BEAMS (0.5 beam r tan a)``,
    5.4 m here): one pipeline line, on the pipe."""
    reach = SHADOW_BEAMS * math.radians(4.5) * math.hypot(345.0, 201.0) * math.tan(math.radians(5.0))
    assert 5.0 < reach < 7.0 < reach + 2 * LineOptions().across_gate_m
    lines = _side_by_side(np.random.default_rng(1), 7.0, extra_burial_m, weaker_db)
    pipes = [r for r in lines.rows if r["kind"] == "pipeline"]
    assert len(pipes) == 1
    assert pipes[0]["burial_m"] == pytest.approx(1.0, abs=0.2)


@pytest.mark.parametrize("offset_m, extra_burial_m, weaker_db", [(7.0, 0.0, 3.0), (7.0, 2.0, 3.0), (7.0, -0.5, 15.0),
                                                                 (12.0, 2.0, 15.0)])
def test_two_real_pipes_side_by_side_stay_two_lines(offset_m, extra_burial_m, weaker_db):
    """Two pipes 7 m apart: as loud or 3 dB apart (a shadow is 6 dB and more down), or a fainter one
    shallower (a shadow lies deeper), or one beyond the smear's reach (12 m): two pipeline lines, each at its
    own burial and within a gate of its own offset (the deeper one's path, moved along its arcs towards the
    prior's burial, lies up to a metre further out)."""
    lines = _side_by_side(np.random.default_rng(2), offset_m, extra_burial_m, weaker_db)
    pipes = sorted((r for r in lines.rows if r["kind"] == "pipeline"), key=lambda r: r["mean_y_m"])
    assert len(pipes) == 2
    mean_y = 340.0 + np.mean(8.2 * np.arange(24)) * math.tan(math.radians(5.0))
    assert pipes[0]["burial_m"] == pytest.approx(1.0, abs=0.2)
    assert pipes[1]["burial_m"] == pytest.approx(1.0 + extra_burial_m, abs=0.2)
    assert pipes[1]["mean_y_m"] - pipes[0]["mean_y_m"] == pytest.approx(offset_m, abs=LineOptions().across_gate_m)
    assert pipes[0]["mean_y_m"] == pytest.approx(mean_y, abs=0.5)


def _nearest_point_image(y_c: float, z_c: float, heading_rad: float) -> tuple[float, float]:
    """A straight pipe's specular echo as the array images it, by brute force: the pipe's point nearest the source
    (at the origin) found on a 1 mm grid along it, imaged at its range and its direction cosine across."""
    t = np.arange(-200.0, 200.0, 0.001)
    px, py = t * math.cos(heading_rad), y_c + t * math.sin(heading_rad)
    i = int(np.argmin(px * px + py * py))
    r = math.sqrt(px[i] ** 2 + py[i] ** 2 + z_c ** 2)
    return float(py[i]), math.sqrt(r * r - py[i] ** 2)


def _crossing_and_second(rng, second, present=range(5, 15), timed: bool = True, n: int = 30,
                         heading_deg: float = 13.5, depth: float = 80.0, cfs=((0.6, 0.8), (0.6, 0.8)),
                         crossing_present=range(30)):
    """A rough pipe at ``heading_deg`` crossing 120 m out, 0.5 m below a flat seabed ``depth`` deep: its diffuse
    echo where it crosses each ping's plane, and in the pings ``present`` a second echo ``second(y_c, z_c, a)
    -> (y, z)`` (2 dB weaker, 0.3 m of depth noise); seabed clutter.  ``timed``: the along-track distance known;
    ``cfs``: the CFs' ranges of the crossing's and the second echo's detections, the crossing's echo in the
    pings ``crossing_present``."""
    a = math.radians(heading_deg)
    ping, y, z, cf, level = [], [], [], [], []
    for k in range(n):
        y_c, z_c = 120.0 + 8.2 * k * math.tan(a), depth + 0.5
        y_2, z_2 = second(y_c, z_c, a)
        one, two = k in crossing_present, k in present
        n_c = rng.poisson(0.01 * 300)
        ping += [k] * (one + two + n_c)
        y += [y_c + rng.normal(0, 0.3)] * one + [y_2 + rng.normal(0, 0.3)] * two + list(rng.uniform(-300, 300, n_c))
        z += [z_c + rng.normal(0, 0.1)] * one + [z_2 + rng.normal(0, 0.3)] * two + list(depth + rng.uniform(-2, 25, n_c))
        cf += [rng.uniform(*cfs[0])] * one + [rng.uniform(*cfs[1])] * two + list(rng.uniform(0.4, 0.6, n_c))
        level += [-70.0] * one + [-72.0] * two + list(rng.uniform(-95, -85, n_c))
    ping, y, z, cf, level = (np.asarray(v) for v in (ping, y, z, cf, level))
    return _lines(LineDetections(ping=ping, y=y, z=z, cf=cf, intensity_db=level), depth, n, timed=timed)


def _image_moved(shift_m: float):
    """The second echo: the pipe's specular image (:func:`_nearest_point_image`) moved ``shift_m`` outwards."""
    def second(y_c, z_c, a):
        y_i, z_i = _nearest_point_image(y_c, z_c, a)
        return y_i + shift_m, z_i
    return second


@pytest.mark.parametrize("seed", range(3))
def test_a_rough_pipes_specular_image_is_no_second_line(seed):
    """A rough pipe at 13.5 degrees, 120 m out in 80 m of water, echoes where it crosses the plane and, in 10
    pings, from its nearest point 29-34 m off it (2.5-2.6 beam widths: through the transmit pattern's second
    sidelobe), imaged 7-8 m nearer the ship and 5-7 m deeper (brute force), too few and too noisy for the
    burials' fit to call specular: one pipeline line, at the crossing and its burial (without the image rule,
    two); the same second track 6 m further out (no image there) stays a line, and so does the image itself
    where the along-track distance is unknown (no heading to place an image by)."""
    pipes = [r for r in _crossing_and_second(np.random.default_rng(seed), _image_moved(0.0)).rows
             if r["kind"] == "pipeline"]
    assert len(pipes) == 1
    mean_y = 120.0 + np.mean(8.2 * np.arange(30)) * math.tan(math.radians(13.5))
    assert pipes[0]["mean_y_m"] == pytest.approx(mean_y, abs=0.5)
    assert pipes[0]["burial_m"] == pytest.approx(0.5, abs=0.2)
    for lines in (_crossing_and_second(np.random.default_rng(seed), _image_moved(6.0)),
                  _crossing_and_second(np.random.default_rng(seed), _image_moved(0.0), timed=False)):
        assert sum(r["kind"] == "pipeline" for r in lines.rows) == 2


@pytest.mark.parametrize("seed", range(4))
def test_a_specular_image_stronger_than_its_crossing_is_moved_to_it(seed):
    """The same pipe, its specular image (brute force) in pings 4-17 with CFs 0.8-0.95, too few for the burials'
    fit to call specular, and its crossing's diffuse echo only in pings 10-19 with CFs 0.5-0.6: the image, 7-8 m
    nearer the ship and 5-7 m deeper, is the better line (about 20 against 10-16).  One pipeline line, over the
    image's pings, at the crossing (within the detections' 0.3 m noise across) and at the crossing's burial
    (its 0.1 m noise: 0.5 m); without the move, two.  The same second track 6 m further out (no image there)
    stays a second line, as deep as it lies."""
    def lines(shift_m):
        return _crossing_and_second(np.random.default_rng(seed), _image_moved(shift_m), present=range(4, 18),
                                    cfs=((0.5, 0.6), (0.8, 0.95)), crossing_present=range(10, 20))
    pipes = [r for r in lines(0.0).rows if r["kind"] == "pipeline"]
    assert len(pipes) == 1
    assert (pipes[0]["first_ping"], pipes[0]["last_ping"], pipes[0]["specular"]) == (4, 17, 1)
    mean_y = 120.0 + np.mean(8.2 * np.arange(4, 18)) * math.tan(math.radians(13.5))
    assert pipes[0]["mean_y_m"] == pytest.approx(mean_y, abs=0.3)
    assert pipes[0]["burial_m"] == pytest.approx(0.5, abs=0.1)
    apart = sorted((r for r in lines(6.0).rows if r["kind"] == "pipeline"), key=lambda r: r["burial_m"])
    assert len(apart) == 2
    assert apart[0]["burial_m"] == pytest.approx(0.5, abs=0.1) and apart[1]["burial_m"] > 4.0


#: (image's pings, CF ranges of the crossing and the image, crossing's pings, tolerance of the mean offset, m)
JOINED_CASES = {
    # the crossing better over pings 8-29, the image over 0-13 only: moved by the six pings both span (within
    # the detections' 0.3 m noise across)
    "overlapping": (range(0, 14), ((0.5, 0.6), (0.8, 0.95)), range(8, 30), 0.3),
    # the crossing over pings 0-14, the image as strong over 17-29, no ping with both: the crossing's path
    # carried straight on over max_gap_pings + 1 meets the image's first pings (extrapolated over up to 13 pings)
    "apart": (range(17, 30), ((0.6, 0.8), (0.6, 0.8)), range(0, 15), 0.6),
}


@pytest.mark.parametrize("case", sorted(JOINED_CASES))
@pytest.mark.parametrize("seed", range(4))
def test_an_image_beyond_its_crossings_pings_is_moved_and_joined_to_it(seed, case):
    """The same pipe, its crossing's echo over some pings and its specular image (brute force) over others
    (:data:`JOINED_CASES`): the image is moved to the crossing and takes up where the crossing's line starts or
    stops.  One pipeline line over all 30 pings, at the crossing and its burial; without the join (or, apart,
    without the carried-on path), two."""
    present, cfs, crossing_present, tolerance = JOINED_CASES[case]
    lines = _crossing_and_second(np.random.default_rng(seed), _image_moved(0.0), present=present, cfs=cfs,
                                 crossing_present=crossing_present)
    pipes = [r for r in lines.rows if r["kind"] == "pipeline"]
    assert len(pipes) == 1
    assert (pipes[0]["first_ping"], pipes[0]["last_ping"]) == (0, 29)
    mean_y = 120.0 + np.mean(8.2 * np.arange(30)) * math.tan(math.radians(13.5))
    assert pipes[0]["mean_y_m"] == pytest.approx(mean_y, abs=tolerance)
    assert pipes[0]["burial_m"] == pytest.approx(0.5, abs=0.1)


@pytest.mark.parametrize("seed", range(3))
def test_a_pipe_along_the_track_keeps_its_own_burial_beside_a_weaker_track_below_it(seed):
    """A pipe along the track is its own specular image: a weaker track at its place, 0.8 m deeper (a pulse's
    tail, CFs 0.5-0.6 against 0.8-0.95), does not take the line over.  One pipeline line at the pipe's
    burial, 0.5 m, not the tail's 1.3 m."""
    lines = _crossing_and_second(np.random.default_rng(seed), lambda y_c, z_c, a: (y_c, z_c + 0.8),
                                 present=range(30), heading_deg=0.0, cfs=((0.8, 0.95), (0.5, 0.6)))
    pipes = [r for r in lines.rows if r["kind"] == "pipeline"]
    assert len(pipes) == 1
    assert pipes[0]["burial_m"] == pytest.approx(0.5, abs=0.1)


@pytest.mark.parametrize("seed", range(3))
def test_a_second_pipe_along_the_image_as_long_as_the_first_stays_a_line(seed):
    """A real pipe beside the first over its whole length, 7.5 m nearer the ship and 6 m deeper (where the
    first one's image lies at mid-line, its burial 5-7 m there along the line): as good a line as the first,
    so no image of it; two pipeline lines, each at its burial."""
    second = _crossing_and_second(np.random.default_rng(seed), lambda y_c, z_c, a: (y_c - 7.5, z_c + 6.0),
                                  present=range(30))
    pipes = sorted((r for r in second.rows if r["kind"] == "pipeline"), key=lambda r: r["mean_y_m"])
    assert len(pipes) == 2
    assert pipes[0]["burial_m"] == pytest.approx(6.5, abs=0.3)
    assert pipes[1]["burial_m"] == pytest.approx(0.5, abs=0.2)
