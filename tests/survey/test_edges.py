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
