"""A smooth pipe's specular echo: the crossing recovered from the echoes' nearest distances against the
exact geometry of a circular pipe, the fading test against the levels it was built from, and a survey's
lines telling a turning smooth pipe (moved to its crossings) from a rough one (left where it is)."""

from __future__ import annotations

import numpy as np
import pytest

from clbeam.survey.georef import SurveyNavigation
from clbeam.survey.line_options import LineOptions
from clbeam.survey.line_products import LineDetections, survey_lines
from clbeam.survey.specular import (
    fading_fit,
    fading_floor_db,
    local_quadratic,
    offsets_at_depth,
    specular_crossing,
    specular_image,
)

SPACING_M = 8.2  # the along-track distance of pings without navigation (LineOptions.nominal_spacing_m)


def circle_pipe(s, crossing_m: float, radius_m: float, bends_away: bool):
    """A pipe of constant curvature crossing the plane at ``s = 0`` at ``crossing_m`` across, parallel to the
    track there: its crossings ``D(s)`` and the exact nearest distances ``h(s)`` from a ship on the track."""
    centre = crossing_m + radius_m if bends_away else crossing_m - radius_m
    crossing = centre - np.sqrt(radius_m ** 2 - s ** 2) if bends_away else centre + np.sqrt(radius_m ** 2 - s ** 2)
    nearest = np.abs(np.hypot(s, centre) - radius_m)
    return crossing, nearest


def test_local_quadratic_gives_a_quadratics_value_and_derivatives_as_numpy_polyfit():
    rng = np.random.default_rng(1)
    s = np.sort(rng.uniform(-150, 150, 40))
    y = 600 + 0.08 * s - 2e-4 * s ** 2 + rng.normal(0, 0.3, s.size)
    at = 20.0
    v, d1, d2 = local_quadratic(s, y, np.array([at]), 200.0)
    tricube = np.clip(1 - np.abs((s - at) / 200.0) ** 3, 0, None) ** 3
    c = np.polyfit(s - at, y, 2, w=np.sqrt(tricube))  # polyfit's weights multiply the residuals
    assert v[0] == pytest.approx(c[2], abs=1e-6) and d1[0] == pytest.approx(c[1], abs=1e-9)
    assert d2[0] == pytest.approx(2 * c[0], abs=1e-11)


@pytest.mark.parametrize("bends_away", [True, False])
@pytest.mark.parametrize("crossing_m, radius_m", [(920.0, 2600.0), (600.0, 1900.0), (-600.0, 2600.0)])
def test_crossing_from_nearest_distances_of_a_curved_pipe(crossing_m, radius_m, bends_away):
    """Noise-free echoes of pipes turning 22-30 degrees per km (headings up to 6 degrees): the crossing within
    0.3 m where the nearest distance alone is metres off."""
    s = np.arange(-200.0, 200.1, SPACING_M)
    crossing, nearest = circle_pipe(s, crossing_m, radius_m, bends_away)
    echo = np.sign(crossing_m) * nearest
    got = specular_crossing(echo, s, np.zeros_like(s), s, 120.0)
    assert np.max(np.abs(echo - crossing)) > 1.4
    assert np.max(np.abs(got - crossing)) < 0.3


@pytest.mark.parametrize("bends_away", [True, False])
def test_crossing_of_a_curved_pipe_at_larger_headings(bends_away):
    """Headings up to 14 degrees (a 2 km radius, 500 m either side): the pipe's bend between the nearest
    point and the plane, projected on the plane (1 / cos^3 a*), matters there."""
    s = np.arange(-500.0, 500.1, SPACING_M)
    crossing, nearest = circle_pipe(s, 900.0, 2000.0, bends_away)
    heading = np.degrees(np.arctan(np.abs(np.gradient(crossing, s))))
    assert heading.max() > 13
    got = specular_crossing(nearest, s, np.zeros_like(s), s, 120.0)
    inner = np.abs(s) < 380  # a fit's half-width from the ends, where the local fits are one-sided
    assert np.max(np.abs(got - crossing)[inner]) < 0.3


def test_a_pipe_crossing_under_the_track_and_a_swaying_centre():
    """A straight pipe at 8 degrees from 10 m to port to 25 m to starboard keeps its sign; a grid centre
    swaying 0.3 m from ping to ping (the echoes, fixed on the seabed, barely move) does not enter the
    crossing."""
    rng = np.random.default_rng(5)
    s = np.arange(0.0, 250.0, SPACING_M)
    a = np.radians(8.0)
    crossing = -10.0 + s * np.tan(a)
    sway = rng.normal(0, 0.3, s.size)
    echo = sway + (crossing - sway) * np.cos(a)  # nearest point of a straight pipe, seen from the ship
    got = specular_crossing(echo, s, sway, s, 60.0)
    assert np.max(np.abs(got - crossing)) < 0.05


def test_straight_pipe_crossing_is_the_nearest_distance_over_cos_a():
    s = np.arange(0.0, 300.0, SPACING_M)
    a = np.radians(8.0)
    crossing = 700.0 + s * np.tan(a)
    echo = crossing * np.cos(a)
    np.testing.assert_allclose(specular_crossing(echo, s, np.zeros_like(s), s, 60.0), crossing, atol=1e-6)


def straight_pipe_echo(crossing_m, heading_rad, pipe_depth_m):
    """A straight pipe's specular echo as imaged from a grid centre at the origin (depth down): the slant
    range of its nearest point, the echo's offset across (cone angle kept: ``h cos a``, ``h = D cos a``),
    its imaged depth, and ``h``."""
    nearest = np.asarray(crossing_m, dtype=np.float64) * np.cos(heading_rad)
    r = np.hypot(nearest, pipe_depth_m)
    y = nearest * np.cos(heading_rad)
    return r, y, np.sqrt(r ** 2 - y ** 2), nearest


@pytest.mark.parametrize("heading_deg", [3.0, 10.2, 20.0])
def test_echoes_moved_to_the_pipes_depth_by_range_lie_at_its_nearest_distance(heading_deg):
    """An exposed smooth pipe 231 m down images ``dz`` deeper and ``h (1 - cos a)`` nearer than its nearest
    point; moved along the arc to its depth it lies at ``h`` whatever angle noise slid it along the arc,
    and the crossing follows as ``h / cos a``."""
    rng = np.random.default_rng(7)
    a = np.radians(heading_deg)
    s = np.arange(0.0, 320.0, SPACING_M)
    crossing = 280.0 + s * np.tan(a)
    r, y, z, nearest = straight_pipe_echo(crossing, a, 231.0)
    slide = rng.normal(0.0, np.radians(0.3), s.size)  # the imaged angle's noise, along the arc
    theta = np.arctan2(y, z) + slide
    y_img = r * np.sin(theta)
    seabed = np.tile([230.0, 0.0], (s.size, 1))
    centre = np.zeros((s.size, 2))
    moved = offsets_at_depth(r, y_img, centre, seabed, 1.0)
    np.testing.assert_allclose(moved, nearest, atol=1e-6)
    assert np.max(np.abs(y_img - nearest)) > 0.5  # the image itself is off
    np.testing.assert_allclose(specular_crossing(moved, s, centre[:, 0], s, 60.0), crossing, atol=1e-6)
    # to port, and a range that cannot reach the depth
    np.testing.assert_allclose(offsets_at_depth(r, -y_img, centre, seabed, 1.0), -nearest, atol=1e-6)
    assert np.isnan(offsets_at_depth([200.0], [10.0], [[0.0, 0.0]], [[230.0, 0.0]], 1.0)).all()


def test_echoes_moved_by_range_against_a_sloping_seabed_and_a_grid_centre_off_the_track():
    """The pipe's depth is the seabed's under the echo plus the burial, from a grid centre that is not the
    origin: the offset is the centre's plus the horizontal leg of the slant range."""
    centre = np.array([[1.5, 4.0], [-0.8, 3.0]])
    seabed = np.array([[230.0, 0.02], [228.0, -0.01]])
    across = np.array([300.0, -450.0])  # the nearest points' offsets from the track
    depth = seabed[:, 0] + seabed[:, 1] * across + 2.0
    r = np.hypot(across - centre[:, 0], depth - centre[:, 1])
    np.testing.assert_allclose(offsets_at_depth(r, across, centre, seabed, 2.0), across, atol=1e-9)


def test_fading_fit_recovers_the_fall_and_finds_none_in_a_diffuse_echo():
    rng = np.random.default_rng(2)
    sin_a = np.linspace(0.0, 0.1, 30)
    rng_m = np.linspace(940, 960, 30)
    spreading = -40 * np.log10(rng_m)
    specular = -30 - 2600 * sin_a ** 2 + spreading + rng.normal(0, 1.0, 30)
    fit = fading_fit(specular, rng_m, sin_a)
    assert abs(fit["beta_db"] - 2600) < 3 * fit["beta_error_db"]
    assert fit["beta_db"] > 3 * fit["beta_error_db"] and fit["span_db"] == pytest.approx(26, abs=5)
    diffuse = fading_fit(-30 + spreading + rng.normal(0, 1.0, 30), rng_m, sin_a)
    assert abs(diffuse["beta_db"]) < 3 * diffuse["beta_error_db"]
    assert np.isnan(fading_fit(specular, rng_m, np.full(30, 0.05))["beta_error_db"])  # no spread in heading
    assert np.isnan(fading_fit(specular[:3], rng_m[:3], sin_a[:3])["beta_db"])
    assert np.isnan(fading_fit(specular, rng_m, np.linspace(0, 0.003, 30))["beta_db"])  # near nadir: no spread
    # a Gaussian main lobe of -3 dB width w falls 3 dB at sin a = w / 2: 12 / w^2 per unit sin^2, a third of it
    w = np.radians(4.5)
    assert fading_floor_db(4.5) == pytest.approx(3.0 / (w / 2) ** 2 / 3)


def _survey(kind: str, seed: int = 3):
    """30 pings of a pipe 920 m to starboard (a flat seabed 230 m down, burial 1 m) turning 30 degrees per
    km, with clutter: a smooth pipe's echoes at their nearest distances and fading out of the transmit beam;
    a rough pipe's at the crossings at a steady level; or a rough pipe at 2-9 degrees to the track whose
    level falls 400 dB per unit sin^2 a (significant, but slower than the transmit beam's fall; its burials
    lack the specular echo's extra depth, k = 0.0 +- 0.3)."""
    rng = np.random.default_rng(seed)
    n = 30
    s = (np.arange(n) - 5) * SPACING_M
    crossing, nearest = circle_pipe(s, 920.0, 1900.0, bends_away=True)
    fade_db = {"smooth": 2600.0, "rough": 0.0, "rough, oblique": 400.0}[kind]
    if kind == "rough, oblique":
        crossing = 920.0 + s * np.tan(np.radians(3.0)) + s ** 2 / (2 * 1900.0)
    echo = nearest if kind == "smooth" else crossing
    slope = np.gradient(echo, s)
    level = -30 - 40 * np.log10(np.hypot(echo, 231.0)) - fade_db * slope ** 2
    return _lines_in_clutter(rng, echo + rng.normal(0, 0.3, n), np.full(n, 231.0), level), crossing


def _lines_in_clutter(rng, echo_y, echo_z, level_db):
    """The lines of one echo a ping (offsets, depths in m, levels in dB; ``(n,)``, or ``(n, e)`` for ``e``
    echoes a ping) among six clutter peaks a ping, over a flat seabed 230 m down, pings 8.2 m apart."""
    echo_y, echo_z, level_db = (np.asarray(v, dtype=np.float64).reshape(len(echo_y), -1)
                                for v in (echo_y, echo_z, level_db))
    n, e = echo_y.shape
    ping, y, depth, cf, inten = [], [], [], [], []
    for k in range(n):
        clutter = rng.uniform(-900, 900, 6)
        ping += [k] * (e + 6)
        y += list(echo_y[k]) + list(clutter)
        depth += list(echo_z[k]) + list(230 + rng.uniform(0, 25, 6))
        cf += [0.6] * e + list(rng.uniform(0.4, 0.6, 6))
        inten += list(level_db[k] + rng.normal(0, 1.0, e)) + list(rng.uniform(-110, -90, 6))
    det = LineDetections(*(np.asarray(v, dtype=np.float64) for v in (ping, y, depth, cf, inten)))
    det.ping = det.ping.astype(np.int64)
    nav = SurveyNavigation(n, None)
    imaged = np.ones(n, dtype=bool)
    nav.finish(imaged)
    return survey_lines(det, np.tile([230.0, 0.0], (n, 1)), np.zeros((n, 2)), imaged, nav, LineOptions())


@pytest.mark.parametrize("kind", ["smooth", "rough", "rough, oblique"])
def test_a_turning_smooth_pipe_is_moved_to_its_crossings_and_a_rough_one_is_not(kind):
    lines, crossing = _survey(kind)
    pipes = [(row, path) for row, path in zip(lines.rows, lines.ping_paths)
             if row["kind"] == "pipeline" or np.any(np.abs(path[1] - crossing[path[0]]) < 30)]
    assert len(pipes) == 1
    row, (pings, path_y) = pipes[0]
    assert row["specular"] == int(kind == "smooth")
    assert np.sqrt(np.mean((path_y - crossing[pings]) ** 2)) < 0.5


def test_a_specular_lines_burial_is_fitted_inside_half_the_transmit_beam_and_its_verdict_over_all(monkeypatch):
    """The turning smooth pipe of the survey above: the fit that decides whether the line is specular takes
    all its echoes (free ``k``), the one that gives its burial (``k`` drawn to 1) only those whose nearest
    point lies within half of ``beam_width_deg`` of the plane (2.25 degrees for the SBP29's 4.5), and the
    line reports that fit's burial."""
    import clbeam.survey.line_products as line_products
    from clbeam.survey.burial import specular_fit

    calls = []

    def spy(*args, **kwargs):
        out = specular_fit(*args, **kwargs)
        calls.append((kwargs, out))
        return out
    monkeypatch.setattr(line_products, "specular_fit", spy)
    lines, _ = _survey("smooth")
    row = [r for r in lines.rows if r["specular"] == 1]
    assert len(row) == 1
    deciding = [c for c in calls if c[0].get("k_prior_sigma") is None]
    burying = [c for c in calls if c[0].get("k_prior_sigma") is not None]
    assert deciding and all(c[0].get("max_offplane_rad") is None for c in deciding)
    assert burying and all(c[0]["max_offplane_rad"] == pytest.approx(np.radians(2.25)) for c in burying)
    assert any(c[1]["burial_m"] == row[0]["burial_m"] for c in burying)


def test_fading_verdict_needs_a_beams_fall_not_just_a_significant_one():
    """:func:`_fades` on echoes 920 m out whose level falls 2600 or 400 dB per unit sin^2 of the angle off the
    plane: the 4.5 degree beam's floor is 650 (400 fails although significant); a 9 degree beam's is 163."""
    from types import SimpleNamespace

    from clbeam.survey.line_products import _fades

    rng = np.random.default_rng(4)
    n = 30
    sin_a = np.linspace(0.02, 0.14, n)
    y, r = np.full(n, 920.0), np.full(n, 948.5)
    frame = SimpleNamespace(y=y, r=r)
    members = np.arange(n)

    def level(beta):
        return -30 - 30 * np.log10(r) - beta * (sin_a * y / r) ** 2 + rng.normal(0, 1.0, n)

    narrow, wide = LineOptions(), LineOptions(beam_width_deg=9.0)
    assert _fades(frame, members, sin_a, np.zeros(n), level(2600.0), narrow)
    slow = level(400.0)
    assert fading_fit(slow, r, sin_a * y / r)["beta_db"] > 3 * fading_fit(slow, r, sin_a * y / r)["beta_error_db"]
    assert not _fades(frame, members, sin_a, np.zeros(n), slow, narrow)
    assert _fades(frame, members, sin_a, np.zeros(n), slow, wide)
    assert not _fades(frame, members, sin_a, np.zeros(n), None, narrow)


def _steady_pipe(heading_deg: float, smooth: bool, seed: int = 5, z_pipe: float = 226.0):
    """40 pings of a straight pipe 1 m under a flat seabed 225 m down, crossing the planes 553 m to port at a
    steady ``heading_deg`` to the track, its echoes at a steady level (no fading) with clutter: a smooth
    pipe's where the imager shows its nearest point (``y_c cos^2 a`` across, ``sqrt(z^2 + x^2)`` down,
    ``x = y_c sin a cos a`` off the plane), a rough pipe's at the crossing.  The line and the extra depth
    ``dz = sqrt(z^2 + x^2) - z`` at the pipe's mean crossing."""
    rng = np.random.default_rng(seed)
    n, a = 40, np.radians(heading_deg)
    s = np.arange(n) * SPACING_M
    crossing = -553.0 - s * np.tan(a)
    x = crossing * np.sin(a) * np.cos(a)
    echo_y = crossing * np.cos(a) ** 2 if smooth else crossing
    echo_z = np.hypot(z_pipe, x) if smooth else np.full(n, z_pipe)
    ping, y, depth, cf, inten = [], [], [], [], []
    for k in range(n):
        clutter = rng.uniform(-700, 700, 6)
        ping += [k] * 7
        y += [echo_y[k] + rng.normal(0, 0.1)] + list(clutter)
        depth += [echo_z[k] + rng.normal(0, 0.05)] + list(225 + rng.uniform(0, 25, 6))
        cf += [0.6] + list(rng.uniform(0.4, 0.6, 6))
        inten += [-140.0 + rng.normal(0, 1.0)] + list(rng.uniform(-170, -150, 6))
    det = LineDetections(*(np.asarray(v, dtype=np.float64) for v in (ping, y, depth, cf, inten)))
    det.ping = det.ping.astype(np.int64)
    det.slide_rad = np.full(det.ping.size, np.radians(0.01))  # strong peaks: their burials good to centimetres
    nav = SurveyNavigation(n, None)
    imaged = np.ones(n, dtype=bool)
    nav.finish(imaged)
    lines = survey_lines(det, np.tile([225.0, 0.0], (n, 1)), np.zeros((n, 2)), imaged, nav, LineOptions())
    rows = [r for r, path in zip(lines.rows, lines.ping_paths) if np.all(np.abs(path[1] - crossing[path[0]]) < 20)]
    x_mean = np.mean(crossing) * np.sin(a) * np.cos(a)
    return rows, float(np.hypot(z_pipe, x_mean) - z_pipe)


@pytest.mark.parametrize("smooth", [True, False])
def test_a_pipe_at_a_steady_small_heading_neither_test_can_call_gets_its_burial_halfway(smooth):
    """At 2 degrees a smooth pipe's nearest point lies 19 m off the plane, inside the 4.5 degree transmit
    beam: its echo images dz = 0.8 m deeper than the pipe, a rough pipe's at it, and with no spread of dz
    and no fading neither test tells them apart.  The burial is reported halfway, 1 + dz/2 measured from a
    smooth pipe's echoes and 1 - dz/2 from a rough one's (within 0.5 m of the truth either way, against
    1.8 m for a smooth one reported as measured), with dz / sqrt(12) in its standard error."""
    rows, dz = _steady_pipe(2.0, smooth)
    assert len(rows) == 1 and rows[0]["specular"] == 0
    assert 0.7 < dz < 0.9
    expected = 1.0 + (0.5 if smooth else -0.5) * dz
    assert rows[0]["burial_m"] == pytest.approx(expected, abs=0.06)
    floor = np.hypot(0.15, 0.25)  # the seabed's error and the reading's model error
    assert np.hypot(0.9 * dz / np.sqrt(12), floor) <= rows[0]["burial_se_m"] < np.hypot(dz / np.sqrt(12) + 0.1, floor)


@pytest.mark.parametrize("heading_deg", [0.0, 40.0])
def test_a_rough_pipe_along_the_track_or_far_across_it_keeps_its_measured_burial(heading_deg):
    """Along the track there is no extra depth; at 40 degrees a smooth pipe's echo would lie 127 m deeper,
    by an amount that changes along the line, and the burials' fit puts k well below 1: rough, no halfway
    burial."""
    rows, dz = _steady_pipe(heading_deg, smooth=False)
    assert len(rows) == 1
    assert rows[0]["burial_m"] == pytest.approx(1.0, abs=0.06)
    # 40 burials scattering by centimetres: the error is the seabed's and the reading's model error in quadrature
    # with the scatter's spread / sqrt(n - 1) (closed form, from the line's own spread and count)
    spread, n = rows[0]["burial_std_m"], rows[0]["n_pings"]
    expected = np.sqrt(0.15 ** 2 + 0.25 ** 2 + spread ** 2 / (n - 1))
    assert rows[0]["burial_se_m"] == pytest.approx(expected, rel=1e-6)


def test_a_chain_on_the_seabed_at_a_steady_heading_is_an_exposed_pipeline_at_its_burial():
    """Scatterers on the seabed lined up at 3 degrees to the track (a pipe lying exposed on it): undecided like
    a buried pipe at that heading, but a smooth pipe's echo never lies above the seabed, so the line keeps its
    burial of 0 (halfway it would read -0.9 +- 0.5 m) and is a pipeline: an exposed one."""
    rows, dz = _steady_pipe(3.0, smooth=False, z_pipe=225.0)
    assert len(rows) == 1 and dz > 1.5
    assert rows[0]["kind"] == "pipeline"
    assert rows[0]["burial_m"] == pytest.approx(0.0, abs=0.06)


def test_the_halfway_burial_needs_a_smooth_pipes_nearest_point_inside_the_beam():
    """The gate on the angle off the plane at which a smooth pipe's nearest point would lie: inside half the
    beam width (4.5 degrees: 0.039 rad) the burial moves by dz / 2 with dz / sqrt(12) more error; beyond it,
    out to SMOOTH_SEEN_BEAMS beam widths, it stays and dz / 2 is added to its error (a smooth pipe there is
    still seen, dz deeper); beyond that, shown rough by its burials, or without extra depth, nothing."""
    from clbeam.survey.line_products import SMOOTH_SEEN_BEAMS, diffuse_shift

    def undecided(fit, options):
        return diffuse_shift(fit, np.zeros(0), False, options)
    half = 0.5 * np.radians(LineOptions().beam_width_deg)
    inside = undecided({"extra_depth_m": 0.8, "offplane_rad": 0.95 * half}, LineOptions())
    assert inside["burial_shift_m"] == pytest.approx(-0.4) and inside["burial_extra_error_m"] == pytest.approx(
        0.8 / np.sqrt(12))
    edge = undecided({"extra_depth_m": 0.8, "offplane_rad": 1.05 * half}, LineOptions())
    assert edge["burial_shift_m"] == 0.0 and edge["burial_extra_error_m"] == pytest.approx(0.4)
    sidelobe = undecided({"extra_depth_m": 2.8, "offplane_rad": 2.83 * half}, LineOptions())  # heading245's S1
    assert sidelobe["burial_extra_error_m"] == pytest.approx(1.4)
    beyond = 2 * SMOOTH_SEEN_BEAMS * half
    assert undecided({"extra_depth_m": 0.8, "offplane_rad": 1.01 * beyond}, LineOptions()) is None
    assert diffuse_shift({"extra_depth_m": 0.8, "offplane_rad": 1.05 * half}, np.zeros(0), True, LineOptions()) is None
    assert undecided({"extra_depth_m": 0.0, "offplane_rad": 0.0}, LineOptions()) is None
    assert undecided({"extra_depth_m": np.nan, "offplane_rad": np.nan}, LineOptions()) is None
    narrow = LineOptions(beam_width_deg=2.0)
    narrower = undecided({"extra_depth_m": 0.8, "offplane_rad": 0.95 * half}, narrow)  # 2.1 of its half-widths
    assert narrower["burial_shift_m"] == 0.0 and narrower["burial_extra_error_m"] == pytest.approx(0.4)


@pytest.mark.parametrize("louder_deeper", [False, True])
def test_of_two_equal_lines_one_above_the_other_the_louder_is_kept(louder_deeper):
    """An echo and its range sidelobe 1 m above it, 20 dB down, in every one of 40 pings at 150 m across (as
    the seabed's nadir echo has): two tracks with the same score, one a duplicate of the other; the one kept
    is the louder's, at its burial, whichever of the two is found first."""
    rng = np.random.default_rng(2)
    n = 40
    ping, y, depth, cf, inten = [], [], [], [], []
    for k in range(n):
        ping += [k, k]
        y += list(150.0 + rng.normal(0, 0.05, 2))
        depth += [226.0, 227.0]
        cf += [0.9, 0.9]
        inten += [-160.0, -140.0] if louder_deeper else [-140.0, -160.0]
    det = LineDetections(*(np.asarray(v, dtype=np.float64) for v in (ping, y, depth, cf, inten)))
    det.ping = det.ping.astype(np.int64)
    det.slide_rad = np.full(det.ping.size, np.radians(0.01))
    nav = SurveyNavigation(n, None)
    imaged = np.ones(n, dtype=bool)
    nav.finish(imaged)
    lines = survey_lines(det, np.tile([225.0, 0.0], (n, 1)), np.zeros((n, 2)), imaged, nav, LineOptions())
    assert len(lines.rows) == 1
    assert lines.rows[0]["burial_m"] == pytest.approx(2.0 if louder_deeper else 1.0, abs=0.02)


def _exposed_pipe_at_10_degrees(rng):
    """A smooth pipe on a seabed 230 m down, 280-330 m out at 10.2 degrees, 36 pings: its crossings, nearest
    distances, and its specular echoes' slant ranges, imaged angles (0.1 degree noise) and levels (dB,
    falling 2600 dB per unit sin^2 of the angle off the plane)."""
    n, a = 36, np.radians(10.2)
    s = np.arange(n) * SPACING_M
    crossing = 280.0 + s * np.tan(a)
    r, y, z, nearest = straight_pipe_echo(crossing, a, 230.0)
    theta = np.arctan2(y, z) + rng.normal(0, np.radians(0.1), n)
    level = -30 - 40 * np.log10(r) - 2600 * (np.gradient(nearest, s) * nearest / r) ** 2
    return crossing, nearest, r, theta, level


@pytest.mark.parametrize("seed", range(6))
def test_a_smooth_exposed_pipe_at_10_degrees_is_moved_to_its_crossings_by_range(seed):
    """A smooth pipe on a seabed 230 m down, 280-330 m out at 10.2 degrees, imaged where a specular echo
    lies: ``dz`` (5-9 m) deeper and ``h (1 - cos a)`` nearer than its nearest point, its angle noisy
    (0.1 degree).  Moved only part of the way along their arcs, the echoes put the path 2.2 m short of the
    crossing; moved by range to the burial the line reports, its path's error is the one that burial's
    error sets (``(Z / h) / cos a`` per metre) and under 1 m."""
    rng = np.random.default_rng(seed)
    crossing, nearest, r, theta, level = _exposed_pipe_at_10_degrees(rng)
    lines = _lines_in_clutter(rng, r * np.sin(theta), r * np.cos(theta), level)
    (row, (pings, path_y)), = [(row, path) for row, path in zip(lines.rows, lines.ping_paths)
                               if np.any(np.abs(path[1] - crossing[path[0]]) < 30)]
    assert row["kind"] == "pipeline" and row["specular"] == 1 and pings.size == crossing.size
    error = path_y - crossing[pings]
    from_burial = -row["burial_m"] * np.mean(230.0 / nearest) / np.cos(np.radians(10.2))
    assert np.sqrt(np.mean(error ** 2)) < 1.0
    assert abs(np.mean(error) - from_burial) < 0.2


def test_a_specular_lines_pulse_tail_along_its_echoes_is_no_second_line():
    """The exposed pipe above with its pulse's tail, 0.5 m further along each echo's ray and 8 dB down (a range
    sidelobe): moved along its arc the tail lies 0.6-0.7 m further out than the echo, inside the line's
    gate, so the two are found as two tracks (or mixed in one).  Compared only with the specular line's path
    moved to the crossings (5-9 m further out) the tail's track was a second pipeline line in five of six seeds;
    the echoes' own path and burial show it a duplicate in every seed.  A track that mixes echo and tail
    (seed 5's) is not judged specular: at most one of the six lines may miss the crossing."""
    missed = 0
    for seed in range(6):
        rng = np.random.default_rng(seed)
        crossing, nearest, r, theta, level = _exposed_pipe_at_10_degrees(rng)
        ray = np.stack([r, r + 0.5], axis=1)
        lines = _lines_in_clutter(rng, ray * np.sin(theta)[:, None], ray * np.cos(theta)[:, None],
                                  np.stack([level, level - 8.0], axis=1))
        near = [(row, path) for row, path in zip(lines.rows, lines.ping_paths)
                if np.any(np.abs(path[1] - crossing[path[0]]) < 30)]
        assert len(near) == 1
        (row, (pings, path_y)), = near
        missed += not (row["specular"] == 1 and np.sqrt(np.mean((path_y - crossing[pings]) ** 2)) < 1.0)
    assert missed <= 1


@pytest.mark.parametrize("seed", range(3))
def test_the_specular_image_is_where_the_array_sees_the_nearest_point(seed):
    """:func:`specular_image` against brute force: a straight pipe at a random heading and crossing, its point
    nearest the source found on a 1 mm grid along it, imaged at its range and its direction cosine across,
    and its angle off the plane (grid centres off the origin)."""
    rng = np.random.default_rng(seed)
    for _ in range(5):
        a, cy, cz = rng.uniform(-0.6, 0.6), rng.uniform(-5, 5), rng.uniform(2, 8)
        y_c, z_c = rng.uniform(-400, 400), rng.uniform(50, 300)
        t = np.arange(-300.0, 300.0, 0.001)
        px, py = t * np.cos(a), y_c - cy + t * np.sin(a)
        i = int(np.argmin(px * px + py * py))
        r = np.sqrt(px[i] ** 2 + py[i] ** 2 + (z_c - cz) ** 2)
        y_i, z_i, off = specular_image([y_c], [z_c], [np.tan(a)], [[cy, cz]])
        # a 1 mm grid puts the nearest point at most 0.5 mm along the pipe from the true one
        assert y_i[0] == pytest.approx(cy + py[i], abs=1e-3)
        assert z_i[0] == pytest.approx(cz + np.sqrt(r * r - py[i] ** 2), abs=1e-3)
        assert off[0] == pytest.approx(abs(px[i]) / r, abs=1e-5)
