"""Differential tests over random scenes: the default setting holds the budget users read.

Each draw is an array (16-128 elements over 1-6 m, 0-3 cm of jitter), roll, heave, a source offset, a
band of 1-20 kHz with at least 30 % fractional bandwidth, a sample rate, raw or analytic input, no
profile, a gradient or a +-80 m/s jump at a random depth, grid steps and spans, and point scatterers on
and off nodes.  The ping is imaged with the default (``--interp auto``) and, on windows around each
point, with the float64 reference's windowed-sinc interpolation (64 taps) of the same channels: the
default must hold the intensity error (-40 dB), the CF error (0.02 on cells within 40 dB of the
point's echo) and CF >= 0.99 at a point on a node, and put each refracted point's refined peak within a
range cell and 0.1 degree of where it is (1 % of a beam width for beams wider than 10 degrees).  The same
draws without a profile are imaged again with beams formed in the frequency domain (x2/16, the near rows'
time interpolation measured on the ping's geometry) and held to the same budget.

The examples pinned with ``@example`` are draws that failed before the budget was measured on the
ping's geometry, and the three scenes a user reported (a jittered, rolled 48-element array with a
source offset; a 64-element array with 1 cm of jitter; a 60 m/s jump 80 m down).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from scenes import point_ping, profile_point_ping

from clbeam.imaging.budget import intensity_error_db
from clbeam.imaging.engine import get_engine
from clbeam.imaging.engine.beams import BeamSampling
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.model.grid import PolarGrid
from clbeam.model.pulse import Pulse
from clbeam.model.svp import SoundSpeedProfile

MAX_ERROR_DB, MAX_CF_ERROR, MIN_NODE_CF, DYNAMIC_RANGE_DB = -40.0, 0.02, 0.99, 40.0
#: the grid's cells at most (the draws coarsen their steps to stay under it)
MAX_CELLS = 150_000
#: the points' ranges as fractions of the grid's: 13 m apart at least, beyond a 10 ms pulse's reach (7.5 m),
#: so that each point's CF on a node is its own
POINT_RANGES = (0.45, 0.68, 0.9)
#: pulse length (s)
PULSE_S = 0.01


@dataclass(frozen=True)
class Draw:
    """One random scene (see the module's description); lengths in m, angles in degree, Hz, s."""

    n_elements: int
    width_m: float
    jitter_m: float
    roll_deg: float
    heave_m: float
    source_yz_m: tuple
    band_hz: tuple
    fs_factor: float
    kind: str
    profile: str
    jump_depth_fraction: float
    jump_m_s: float
    range_step_m: float
    angle_step_deg: float
    half_span_deg: float
    max_range_m: float
    points: tuple        # ((range fraction, angle fraction, on node), ...)
    seed: int


def _band(f0_khz: float, ratio: float) -> tuple:
    f0 = 1000.0 * f0_khz
    return (f0, min(20000.0, f0 * ratio))


draws = st.builds(
    Draw,
    n_elements=st.integers(16, 128), width_m=st.floats(1.0, 6.0), jitter_m=st.floats(0.0, 0.03),
    roll_deg=st.floats(-10.0, 10.0), heave_m=st.floats(-1.0, 1.0),
    source_yz_m=st.tuples(st.floats(-0.5, 0.5), st.floats(-0.5, 0.5)),
    band_hz=st.builds(_band, st.floats(1.0, 14.0), st.floats(1.36, 3.0)).filter(lambda b: b[1] / b[0] >= 1.353),
    fs_factor=st.floats(2.3, 4.5), kind=st.sampled_from(["raw", "analytic"]),
    profile=st.sampled_from(["none", "none", "gradient", "jump"]), jump_depth_fraction=st.floats(0.25, 0.7),
    jump_m_s=st.sampled_from([-80.0, -40.0, 40.0, 80.0]),
    range_step_m=st.sampled_from([0.1, 0.2, 0.3, 0.5]), angle_step_deg=st.sampled_from([0.05, 0.1, 0.2, 0.5]),
    half_span_deg=st.floats(20.0, 75.0), max_range_m=st.floats(60.0, 220.0),
    points=st.tuples(*(st.tuples(st.just(rf), st.floats(-0.9, 0.9), st.booleans()) for rf in POINT_RANGES)),
    seed=st.integers(0, 2**16),
)


def _elements(d: Draw) -> np.ndarray:
    rng = np.random.default_rng(d.seed)
    pos = np.zeros((d.n_elements, 3))
    pos[:, 1] = (np.arange(d.n_elements) - (d.n_elements - 1) / 2) * d.width_m / d.n_elements
    pos[:, 1:] += rng.normal(0.0, d.jitter_m, (d.n_elements, 2))
    return pos


def _grid(d: Draw) -> PolarGrid:
    dr, da = d.range_step_m, d.angle_step_deg
    while (d.max_range_m / dr) * (2 * d.half_span_deg / da) > MAX_CELLS:
        dr, da = dr * 1.5, da * 1.5
    return PolarGrid.regular(range_res_m=dr, angle_res_deg=da, max_range_m=d.max_range_m,
                             angles_deg=(-d.half_span_deg, d.half_span_deg))


def _profile(d: Draw) -> SoundSpeedProfile | None:
    deep = 3.0 * d.max_range_m
    if d.profile == "gradient":
        return SoundSpeedProfile([0.0, deep], [1500.0, 1500.0 + d.jump_m_s])
    if d.profile == "jump":
        z = d.jump_depth_fraction * d.max_range_m
        return SoundSpeedProfile([0.0, z, z, deep], [1500.0, 1500.0, 1500.0 + d.jump_m_s, 1500.0 + d.jump_m_s])
    return None


def _scene(d: Draw):
    """The ping, its grid and the points' (range, angle) from the grid centre."""
    grid = _grid(d)
    f1 = d.band_hz[1]
    pulse = Pulse(f0_hz=d.band_hz[0], f1_hz=f1, duration_s=PULSE_S)
    fs = float(round(d.fs_factor * f1))
    profile = _profile(d)
    source = (0.0,) + tuple(d.source_yz_m) if profile is None else (0.0, 0.0, 0.0)
    centre = np.array(grid.centre(source[1:]))
    polar = []
    for rf, af, on_node in d.points:
        ir = int(round(rf * (grid.shape[1] - 1)))
        ia = int(round((af + 1) / 2 * (grid.shape[0] - 1)))
        r, a = float(grid.ranges_m[ir]), float(grid.angles_deg[ia])
        if not on_node:
            r, a = r + 0.37 * (grid.ranges_m[1] - grid.ranges_m[0]), a + 0.41 * (grid.angles_deg[1] - grid.angles_deg[0])
        polar.append((r, a, on_node))
    record_s = 2.0 * d.max_range_m / 1420.0 + 0.03
    yz = [centre + r * np.array([np.sin(np.deg2rad(a)), np.cos(np.deg2rad(a))]) for r, a, _ in polar]
    if profile is None:
        ping = point_ping([np.r_[0.0, p] for p in yz], roll_deg=d.roll_deg, heave_m=d.heave_m, record_s=record_s,
                          source_m=source, pulse=pulse, fs=fs, kind=d.kind, elements_m=_elements(d))
    else:
        ping = profile_point_ping(np.array(yz), profile, record_s=record_s, pulse=pulse, fs=fs,
                                  elements_m=_elements(d))
    return ping, grid, polar


def _check_budget(d: Draw, beams="auto") -> None:
    ping, grid, polar = _scene(d)
    imager = Imager(grid, ImagingOptions(outputs=("intensity", "cf"), beams=beams))
    img = imager.image(ping)
    inp, _ = imager._prepare(ping)
    reference = get_engine("reference")
    da = float(grid.angles_deg[1] - grid.angles_deg[0])
    dr = float(grid.ranges_m[1] - grid.ranges_m[0])
    for r, a, on_node in polar:
        ia = int(np.argmin(np.abs(grid.angles_deg - a)))
        ir = int(np.argmin(np.abs(grid.ranges_m - r)))
        n_a, n_r = int(round(8.0 / da)), 12
        sa = slice(max(ia - n_a, 0), ia + n_a + 1)
        sr = slice(max(ir - n_r, 0), ir + n_r + 1)
        window = PolarGrid.beams(grid.ranges_m[sr], grid.angles_deg[sa])
        exact = reference.beamform(inp, window, interp="exact", outputs=("intensity", "cf"))
        got_i, got_cf = img.intensity[sa, sr].astype(np.float64), img.cf[sa, sr]
        keep = exact.intensity >= exact.intensity.max() * 10 ** (-DYNAMIC_RANGE_DB / 10)
        where = f"{d} point ({r:.2f} m, {a:.2f} deg), setting {img.setting}"
        assert intensity_error_db(got_i, exact.intensity, DYNAMIC_RANGE_DB) <= MAX_ERROR_DB, where
        assert np.max(np.abs(got_cf[keep] - exact.cf[keep])) <= MAX_CF_ERROR, where
        if on_node:
            assert img.cf[ia, ir] >= MIN_NODE_CF, (where, img.cf[ia, ir])
        if d.profile != "none":
            # refracted points within a range cell and 0.1 degree (or 1 % of a beam width for the widest beams)
            tol_deg = max(0.1, 0.01 * np.degrees(1500.0 / d.band_hz[1] / d.width_m))
            peak = min(img.peaks, key=lambda p: abs(p["range_m"] - r) / dr + abs(p["angle_deg"] - a) / tol_deg)
            assert abs(peak["range_m"] - r) <= dr and abs(peak["angle_deg"] - a) <= tol_deg, (where, peak)


USER_SCENES = [
    # 48 elements over 3.0 m, 2 cm jitter, roll 3 degrees, source offset (0.35, 0.4) m, analytic, on nodes
    Draw(48, 3.0, 0.02, 3.0, 0.0, (0.35, 0.4), (2000.0, 9000.0), 4.44, "analytic", "none", 0.5, 0.0,
         0.2, 0.1, 40.0, 200.0, ((0.45, -0.75, True), (0.68, 0.1, False), (0.9, 0.5, True)), 1),
    # 64 elements, 1 cm jitter, roll -2 degrees, source offset (0.2, 0.3) m
    Draw(64, 3.528, 0.01, -2.0, 0.0, (0.2, 0.3), (2000.0, 9000.0), 4.44, "analytic", "none", 0.5, 0.0,
         0.2, 0.1, 40.0, 200.0, ((0.45, -0.6, True), (0.68, 0.3, False), (0.9, 0.0, True)), 2),
    # 1500 m/s water over 1560 m/s below 80 m, raw pings
    Draw(64, 3.528, 0.0, 0.0, 0.0, (0.0, 0.0), (2000.0, 9000.0), 4.44, "raw", "jump", 0.4, 60.0,
         0.2, 0.1, 40.0, 200.0, ((0.45, 0.55, True), (0.68, -0.8, True), (0.9, 0.2, False)), 3),
]


@pytest.mark.slow
@pytest.mark.parametrize("draw", USER_SCENES, ids=["jittered-48", "jittered-64", "jump-80m"])
def test_user_reported_scenes_hold_the_budget(draw):
    _check_budget(draw)


@pytest.mark.slow
@settings(max_examples=3, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(draws)
def test_random_scenes_hold_the_budget(draw):
    _check_budget(draw)


#: a 16-element array over 1 m (less than a wavelength at 1364 Hz) sampled at 2.375 times its band's top, points
#: at 27-54 m: forced Lanczos-8 near rows measured -37.7 dB here (the model predicts -41.0 dB at this rate), so
#: the near rows' time interpolation is measured with forced beams as with auto's
NARROW_BAND_NEAR = Draw(16, 1.0, 0.0, 0.0, 0.0, (0.0, 0.0), (1000.0, 1364.0), 2.375, "analytic", "none", 0.5, 0.0,
                        0.1, 0.1, 40.0, 60.0, ((0.45, 0.0012, True), (0.68, 0.0012, False), (0.9, 0.0012, True)), 0)
#: the same array, raw, off-node points: its frequency-domain setting measured -45.9 dB on the calibration echoes,
#: which lie beyond the near rows that it forms in time (linear-bb, no upsampling), and -39.4 dB at 27 m; the
#: near rows are now held by the time-domain twin's measurement too
NARROW_BAND_NEAR_RAW = Draw(16, 1.0, 0.0, 0.0, 0.0, (0.0, 0.0), (1000.0, 1375.0), 2.375, "raw", "none", 0.5, -80.0,
                            0.1, 0.05, 20.0, 60.0, ((0.45, 0.0, False), (0.68, 0.0, False), (0.9, 0.0, False)), 0)


@pytest.mark.slow
@settings(max_examples=3, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(draws.map(lambda d: replace(d, profile="none")))
@example(NARROW_BAND_NEAR)
@example(NARROW_BAND_NEAR_RAW)
@example(USER_SCENES[0])
def test_random_scenes_hold_the_budget_with_frequency_domain_beams(draw):
    """Beams x2/16 formed in the frequency domain (straight rays), the near rows' time interpolation measured on
    the ping's geometry: the same budget against the exact sums."""
    _check_budget(draw, beams=BeamSampling(2.0, 16, domain="frequency"))
