"""The two edges of an echo from off the ping's plane (clbeam.survey.edges): a profile built from the pulse's
band and the transmit column's pattern at every frequency, a simulated point scatterer off the plane, and the
rule that takes a line's echoes as its nearest point's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from clbeam.io.pingwrite import write_ping_file
from clbeam.model.grid import PolarGrid
from clbeam.sim import load_scene, simulate
from clbeam.survey.edges import EDGE_RATIO, EdgeProbe, edge_spacing_m, edges_from_nearest_point

C, F0, F1, L = 1500.0, 2000.0, 9000.0, 3.5
STEP = 0.01


def _profile(delays_m: np.ndarray, amplitudes: np.ndarray, u: float, half_m: float = 0.8) -> np.ndarray:
    """Intensity along range (every ``STEP`` m) of echoes at ``delays_m`` (range, m) through a flat 2-9 kHz band
    (the compressed pulse) and the column's pattern ``sinc(L f u / c)`` with its delay ``L u / 2c`` at every
    frequency (a box ``L u / c`` long): numpy's sum over the band, nothing of clbeam's imaging."""
    f = np.linspace(F0, F1, 1401)
    r = np.arange(-half_m, half_m + STEP / 2, STEP)
    pattern = np.sinc(L * f * u / C) * np.exp(-1j * np.pi * f * L * u / C)
    t = 2 * (r[:, None] - np.asarray(delays_m)[None, :]) / C                 # (range, echo) two-way time
    s = np.einsum("ref,e,f->r", np.exp(2j * np.pi * f[None, None, :] * t[:, :, None]), amplitudes, pattern)
    return np.abs(s) ** 2


@pytest.mark.parametrize("u", [0.11, 0.14, 0.18, 0.24, 0.3])
def test_an_echo_off_the_plane_shows_two_edges_about_l_u_over_2_apart(u):
    """Beyond the main lobe (``u`` above ``lambda / L`` at the band's top) the box is longer than the pulse: two
    peaks of equal height, ``L u / 2`` apart to within a third of the pulse's 0.1 m resolution (its sidelobes
    push close edges apart), which the rule's ratio :data:`EDGE_RATIO` holds; profiled +-0.6 m about one edge,
    as the probe does."""
    profile = _profile(np.zeros(1), np.ones(1), u, half_m=1.0)
    top = int(np.argmax(profile))
    spacing = edge_spacing_m(profile[top - 60:top + 61], STEP)
    assert abs(spacing - L * u / 2) <= 0.1 / 3
    assert EDGE_RATIO[0] <= spacing / (L * u / 2) <= EDGE_RATIO[1]


def test_an_echo_from_the_plane_and_speckle_show_no_two_edges():
    """An echo from the plane (``u`` = 0) has one peak: NaN.  Speckle, 12 scatterers of random complex
    amplitude over 0.7 m of range from the plane (the pulse placed at each, to the profile's step), shows two
    clean edges in at most a quarter of 200 draws."""
    pulse = _profile(np.zeros(1), np.ones(1), 0.0, half_m=1.6)   # |pulse|^2; the complex pulse below
    assert math.isnan(edge_spacing_m(pulse, STEP))
    f = np.linspace(F0, F1, 1401)
    r = np.arange(-1.6, 1.6 + STEP / 2, STEP)
    kernel = np.exp(2j * np.pi * np.outer(2 * r / C, f)).sum(axis=1)
    rng = np.random.default_rng(0)
    clean = 0
    for _ in range(200):
        train = np.zeros(81, dtype=complex)                      # +-0.4 m of scatterers every STEP
        np.add.at(train, rng.integers(5, 76, 12), rng.normal(size=12) + 1j * rng.normal(size=12))
        profile = np.abs(np.convolve(train, kernel, mode="same"))[80:-80] ** 2
        clean += np.isfinite(edge_spacing_m(profile, STEP))
    assert clean <= 50, clean


def test_the_rule_asks_its_detections_off_the_plane_and_wants_a_third_to_agree():
    """Of the detections whose nearest point lies at ``u`` of at least 0.07, up to 12 are probed; the line's echoes
    are its nearest point's when at least 3 and a third of them read ``u`` within the ratio."""
    u = np.r_[np.full(5, 0.03), np.full(24, 0.12)]
    asked = []

    def probe(agreeing):
        def read(index):
            asked.append(np.asarray(index))
            out = np.full(len(index), np.nan)
            out[:agreeing] = 1.1 * u[index[:agreeing]]
            return out
        return read
    assert edges_from_nearest_point(probe(4), u)
    assert np.all(u[asked[-1]] >= 0.07) and asked[-1].size == 12
    assert not edges_from_nearest_point(probe(3), u)          # 3 of 12: under a third
    assert not edges_from_nearest_point(probe(12), np.full(29, 0.03))
    assert not edges_from_nearest_point(lambda index: 2.0 * u[index], u)   # twice the nearest point's: no


@pytest.fixture(scope="module")
def points_off_the_plane(tmp_path_factory):
    """The built-in one-point scene (150 m across, 200 m down) with its point 0, 30 and 45 m off the plane."""
    d = tmp_path_factory.mktemp("edges")
    paths = []
    for x in (0.0, 30.0, 45.0):
        scene = load_scene("point", overrides={"target": [{"kind": "point", "name": "P", "x_m": x, "y_m": 150.0,
                                                          "z_m": 200.0, "amplitude_m": 1.0}]})
        paths.append(write_ping_file(simulate(scene), d / f"point_{x:.0f}.nc"))
    return paths


def test_the_probe_reads_how_far_off_the_plane_a_simulated_point_lies(points_off_the_plane):
    """The probe, at the point's range and angle, reads ``u`` within :data:`EDGE_RATIO` of its ``x / R`` at 30
    and 45 m off the plane (the simulator's box at every frequency), and nothing from the point on the plane."""
    grid = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, max_range_m=300.0, min_range_m=150.0,
                             angles_deg=(0.0, 60.0))
    for path, x in zip(points_off_the_plane, (0.0, 30.0, 45.0)):
        r = math.sqrt(150.0 ** 2 + 200.0 ** 2 + x ** 2)
        probe = EdgeProbe([path], np.zeros(1, dtype=int), np.zeros(1, dtype=int), L, grid=grid)
        u = probe(np.zeros(1, dtype=int), np.array([r]), np.array([math.degrees(math.asin(150.0 / r))]))[0]
        if x == 0:
            assert math.isnan(u)
        else:
            assert EDGE_RATIO[0] <= u / (x / r) <= EDGE_RATIO[1], (x, u, x / r)


def test_the_probe_is_asked_about_the_lines_own_detections_in_the_callers_order(monkeypatch):
    """Detections given in shuffled order (a buried line 0.8 m deep at 200 m across over 30 pings, and clutter):
    whatever the line search asks of the probe about a line's members, the probe receives the indices of those
    same detections in the order it was given them (their pings, offsets and CFs are the members')."""
    from clbeam.survey import line_products
    from clbeam.survey.georef import SurveyNavigation
    from clbeam.survey.line_options import LineOptions
    from clbeam.survey.line_products import LineDetections, survey_lines

    rng = np.random.default_rng(3)
    n = 30
    ping = np.r_[np.arange(n), rng.integers(0, n, 300)]
    y = np.r_[200.0 + rng.normal(0, 0.1, n), rng.uniform(-400, 400, 300)]
    z = np.r_[230.8 + rng.normal(0, 0.05, n), 230.0 + rng.uniform(0, 5, 300)]
    cf = np.r_[np.full(n, 0.9), rng.uniform(0.4, 0.6, 300)]
    shuffle = rng.permutation(ping.size)
    ping, y, z, cf = ping[shuffle], y[shuffle], z[shuffle], cf[shuffle]
    received = []

    def probe(index):
        received.append(np.asarray(index))
        return np.full(len(index), np.nan)
    asked = []

    def specular(frame, tr, path_y, sb, centre_yz, echoes, options):   # asks the probe about every member
        if echoes[1] is not None:
            echoes[1](tr.members)
            asked.append((frame.ping[tr.members], frame.cf[tr.members]))
        return None
    monkeypatch.setattr(line_products, "_specular", specular)
    nav = SurveyNavigation(n, None)
    imaged = np.ones(n, dtype=bool)
    nav.finish(imaged)
    lines = survey_lines(LineDetections(ping, y, z, cf, edge_probe=probe), np.tile([230.0, 0.0], (n, 1)),
                         np.zeros((n, 2)), imaged, nav, LineOptions())
    assert any(r["kind"] == "pipeline" for r in lines.rows) and asked and len(asked) == len(received)
    for (frame_ping, frame_cf), index in zip(asked, received):
        np.testing.assert_array_equal(ping[index], frame_ping)
        np.testing.assert_array_equal(cf[index], frame_cf)
    line = next(k for k, r in enumerate(lines.rows) if r["kind"] == "pipeline")
    assert any(set(index) == set(np.flatnonzero(lines.labels == line)) for index in received)


def test_a_survey_probes_its_own_inputs_at_each_detections_range_and_angle(monkeypatch, caplog):
    """``_edge_probe``: the probe reads the store's own inputs (others, a missing pulse band or a zero beam width:
    no probe, the first with a warning), with ``L`` the band centre's wavelength over the beam width (1500 m/s,
    2-9 kHz, 4.5 degrees: 3.47 m), at each detection's range ``hypot(dy, dz)`` and angle ``atan2(dy, dz)`` from
    its ping's grid centre."""
    import dataclasses
    import json
    from types import SimpleNamespace

    from clbeam.survey import products
    from clbeam.survey.line_options import LineOptions

    made = {}

    class Recorder:
        def __init__(self, paths, file_index, file_ping, column_length_m, **kw):
            made["column_m"] = column_length_m

        def __call__(self, pings, range_m, angle_deg):
            made["args"] = (pings, range_m, angle_deg)
            return np.zeros(len(pings))
    monkeypatch.setattr(products, "EdgeProbe", Recorder)
    monkeypatch.setattr(products, "read_root_attrs", lambda output: {"input_files": json.dumps(["a.nc", "b.nc"])})
    first = SimpleNamespace(sonar={"pulse_band_hz": [2000.0, 9000.0]},
                            per_ping={"sound_speed": np.full(2, 1500.0), "file_index": np.zeros(2, dtype=int),
                                      "file_ping": np.arange(2)})
    det = SimpleNamespace(ping=np.array([0, 1]), y=np.array([10.0, 103.0]), z=np.array([200.0, 204.0]))
    centre = np.array([[0.0, 0.0], [3.0, 4.0]])
    options = SimpleNamespace(lines=LineOptions(), grid=None, imaging=None, backend=None, device=None)
    probe = products._edge_probe("s.zarr", ["/x/a.nc", "/y/b.nc"], first, det, centre, options)
    probe(np.array([1]))
    assert made["column_m"] == pytest.approx(1500.0 / 5500.0 / math.radians(4.5))
    pings, r, a = made["args"]
    assert pings.tolist() == [1] and r[0] == pytest.approx(math.hypot(100.0, 200.0))
    assert a[0] == pytest.approx(math.degrees(math.atan2(100.0, 200.0)))
    with caplog.at_level("WARNING"):
        assert products._edge_probe("s.zarr", ["/x/b.nc", "/y/a.nc"], first, det, centre, options) is None
    assert "not the store's" in caplog.text
    assert products._edge_probe("s.zarr", None, first, det, centre, options) is None
    assert products._edge_probe("s.zarr", ["a.nc", "b.nc"], SimpleNamespace(**{**vars(first), "sonar": {}}), det,
                                centre, options) is None
    flat = SimpleNamespace(**{**vars(options), "lines": dataclasses.replace(LineOptions(), beam_width_deg=0.0)})
    assert products._edge_probe("s.zarr", ["a.nc", "b.nc"], first, det, centre, flat) is None


def test_the_probe_images_a_detection_once_and_tries_a_failed_one_again(monkeypatch):
    """Asked twice about the same detections (a line described again as a duplicate or a join), the probe
    profiles each once and reads the same ``u`` (two peaks ``s`` apart give ``2 s / L``); a detection whose
    ping could not be profiled is tried again each time it is asked about."""
    calls = []
    spacing = 0.5
    profile = np.zeros(121)
    profile[[10, 10 + int(round(spacing / 0.01))]] = 1.0

    def fake_profile(self, ping, range_m, angle_deg):
        calls.append(ping)
        return None if ping == 2 else profile

    monkeypatch.setattr(EdgeProbe, "_profile", fake_profile)
    probe = EdgeProbe([], np.zeros(3, dtype=int), np.arange(3), L, grid=None)
    pings, ranges, angles = np.array([0, 1, 2]), np.array([100.0, 200.0, 300.0]), np.array([10.0, 20.0, 30.0])
    first = probe(pings, ranges, angles)
    again = probe(pings, ranges, angles)
    np.testing.assert_allclose(first[:2], 2 * spacing / L, rtol=0.05)
    np.testing.assert_array_equal(first, again)
    assert math.isnan(first[2])
    assert sorted(calls) == [0, 1, 2, 2]
