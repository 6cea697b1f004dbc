"""The validation surveys' scoring (docs/detectability.md): the arc window against the geometry written
out, the threshold-level echo's SNR and direction bound against direct draws of the channels, the grids'
sub-cell offsets against the uniform distribution."""

import math

import numpy as np
import pytest
import xarray as xr
from scipy import stats

from clbeam.errors import OptionError
from clbeam.evaluation.detectability_stats import Tests as DetectionTests
from clbeam.evaluation.detectability_validation import (
    ANGLE_STEP_DEG,
    CLUTTER_HALF,
    RANGE_STEP_M,
    ArcWindow,
    _echoes,
    _grid,
    arc_window,
    direction_sigma,
    grid_fraction,
    score,
    threshold_snr,
    validation_scene,
)
from clbeam.imaging.geometry import roll_matrix
from clbeam.imaging.postprocess import HANN7

M = 64
H = 226.0  # the validation scenes' transducer-to-pipe height for a 1 m burial (m)


@pytest.fixture(scope="module")
def scene():
    return validation_scene("mud", (1000.0,), pings=2)


def _polar(range_m: float, angle_deg: float) -> dict:
    a = math.radians(angle_deg)
    return {"range_m": range_m, "angle_deg": angle_deg, "y_m": range_m * math.sin(a), "z_m": range_m * math.cos(a)}


def _echo(horizontal_m: float, roll_deg: float = 0.0) -> dict:
    return {**_polar(math.hypot(horizontal_m, H), math.degrees(math.atan2(horizontal_m, H))), "roll_deg": roll_deg}


def _along_arc(echo: dict, metres: float, d_range_m: float = 0.0) -> dict:
    return _polar(echo["range_m"] + d_range_m, echo["angle_deg"] + math.degrees(metres / echo["range_m"]))


def test_a_peak_10_m_along_the_arc_counts_and_one_3_m_off_it_in_range_does_not(scene):
    """At 1000 m: 10 m along the arc is ``cos θ · 10 / R`` in the sine (0.002), inside the window (0.006);
    3 m in range is beyond its 0.6 m; 100 m along the arc (0.02 in the sine) is beyond it too.  Only the
    peak 1 m along the arc lies within 2 m across and 5 m down of the image (10 m along is 2.2 m across)."""
    window = arc_window(scene)
    echo = _echo(1000.0)
    cos_t = math.cos(math.radians(echo["angle_deg"]))
    assert cos_t * 10 / echo["range_m"] < window.sin_half < cos_t * 100 / echo["range_m"]
    peaks = {"on10": [(echo, [_along_arc(echo, 10.0)])], "on1": [(echo, [_along_arc(echo, 1.0)])],
             "off3": [(echo, [_along_arc(echo, 0.0, 3.0)])], "far": [(echo, [_along_arc(echo, 100.0)])],
             "two": [(echo, [_along_arc(echo, 0.0, 3.0), _along_arc(echo, -10.0)]), (echo, [])]}
    got = score(peaks, window)
    assert got["on10"] == {"arc": (1, 1), "placed": (0, 1)}
    assert got["on1"] == {"arc": (1, 1), "placed": (1, 1)}
    assert got["off3"]["arc"] == got["far"]["arc"] == (0, 1)
    assert got["two"] == {"arc": (1, 2), "placed": (0, 2)}


@pytest.mark.parametrize("roll_deg", [-3.0, 3.0])
def test_the_window_is_in_the_arrays_sine_with_roll(roll_deg):
    """The array's axis after roll (:func:`roll_matrix` applied to the starboard unit vector) dotted with the
    peak's direction: a peak at 0.9 of the window's half-width in that sine is in, at 1.1 it is out."""
    window = ArcWindow(0.6, 0.006)
    echo = _echo(1300.0, roll_deg)
    axis = roll_matrix(roll_deg) @ np.array([0.0, 1.0, 0.0])

    def sine(angle_deg):
        a = math.radians(angle_deg)
        return float(axis @ np.array([0.0, math.sin(a), math.cos(a)]))

    u0 = sine(echo["angle_deg"])
    for frac, inside in ((0.9, True), (1.1, False)):
        angle = math.degrees(math.asin(u0 + frac * window.sin_half)) - roll_deg
        assert window.admits(echo, _polar(echo["range_m"], angle)) is inside


def test_the_range_tolerance_is_the_models_search_and_resolves_more_than_the_pulse(scene):
    """Two search cells and the half cell of refinement either side of a node within half a cell: 0.6 m,
    over the compressed pulse's ``c / 2B`` (0.107 m) and under the 3 m of a peak off the arc."""
    so = scene.sonar
    tol = arc_window(scene).range_m
    assert tol == pytest.approx(3 * DetectionTests().range_step_m, rel=1e-12)
    assert scene.sound_speed_m_s / (2 * (so.pulse_f1_hz - so.pulse_f0_hz)) < tol < 3.0


def test_the_threshold_level_echo_gives_its_cell_the_cf_that_the_centre_tap_needs():
    """Direct draws of the channels at :func:`threshold_snr`: the mean single-cell CF is ``t / w₀``
    within four standard errors and the ratio of means' second-order delta-method term."""
    t = DetectionTests()
    x = threshold_snr(t, M)
    n = 20000
    rng = np.random.default_rng(3)
    w = (rng.standard_normal((n, M)) + 1j * rng.standard_normal((n, M))) / math.sqrt(2)
    p = math.sqrt(x) + w
    cf = np.abs(p.sum(axis=1)) ** 2 / (M * np.sum(np.abs(p) ** 2, axis=1))
    mu_a, mu_s = M * x + 1, M * x + M
    var_a, var_s = 2 * M * x + 1, 2 * M * x + M
    delta = abs(mu_a * var_s / mu_s ** 3 - var_a / mu_s ** 2)
    target = t.threshold / float(np.max(HANN7))
    assert float(np.mean(cf)) == pytest.approx(target, abs=delta + 4 * float(np.std(cf)) / math.sqrt(n))


def test_the_direction_bound_is_the_spread_of_the_maximum_likelihood_estimate(scene):
    """The phase step per element of a plane wave at the threshold's SNR, estimated by the periodogram's
    peak over 3000 draws: its standard deviation is the bound within the standard deviation's sampling
    error (four of them) and the 2 % of the grid the peak is read on; the sine's scale ``c / 2π f d`` with
    the band's rms frequency from a fine sum over the band."""
    so = scene.sonar
    x = threshold_snr(DetectionTests(), M)
    f = np.linspace(so.pulse_f0_hz, so.pulse_f1_hz, 200001)
    scale = scene.sound_speed_m_s / (2 * math.pi * math.sqrt(np.mean(f ** 2)) * so.array_width_m / M)
    sigma_step = direction_sigma(scene, x) / scale
    n, psi0 = 3000, 0.3
    idx = np.arange(M) - 0.5 * (M - 1)
    rng = np.random.default_rng(11)
    p = math.sqrt(x) * np.exp(1j * psi0 * idx) + (rng.standard_normal((n, M)) + 1j * rng.standard_normal((n, M))) / math.sqrt(2)
    steps = psi0 + np.linspace(-8, 8, 3201) * sigma_step
    est = steps[np.argmax(np.abs(p @ np.exp(-1j * np.outer(idx, steps))), axis=1)]
    assert float(np.std(est)) == pytest.approx(sigma_step, rel=4 / math.sqrt(2 * n) + 0.02)


def test_grid_fractions_are_uniform_and_repeatable():
    """Kolmogorov-Smirnov against U(0, 1) over 2000 targets (p > 0.001); the same arguments, the same draw."""
    u = np.array([grid_fraction(2, 0, j) for j in range(2000)])
    assert stats.kstest(u, "uniform").pvalue > 1e-3
    assert grid_fraction(2, 1, 5) == grid_fraction(2, 1, 5) != grid_fraction(3, 1, 5)


def test_each_pipes_grid_lies_its_fraction_of_a_step_off_the_echo():
    """A ping's grid puts the echo its fraction of a step short of a node (to rounding), the window
    ``±CLUTTER_HALF`` about it, from the truth's image position (the echo's range and angle written out)."""
    y, z = np.array([[640.0, -1020.0], [640.5, -1019.5]]), np.array([[226.0, 227.0], [225.5, 227.5]])
    ds = xr.Dataset({"truth_target_image_y": (("ping", "target"), y), "truth_target_image_z": (("ping", "target"), z),
                     "roll": (("ping",), np.array([1.5, -2.0]))}, coords={"target": ["S640", "P1020"]})
    echoes = _echoes(ds)
    for k in range(2):
        for j, name in enumerate(("S640", "P1020")):
            echo = echoes[k][name]
            r, a = math.hypot(y[k, j], z[k, j]), math.degrees(math.atan2(y[k, j], z[k, j]))
            assert (echo["range_m"], echo["angle_deg"], echo["roll_deg"]) == pytest.approx((r, a, ds["roll"].values[k]))
            frac = grid_fraction(4, k, j)
            grid = _grid(echo, frac)
            assert grid.ranges_m[0] - (r - CLUTTER_HALF[0]) == pytest.approx(frac * RANGE_STEP_M, abs=1e-9)
            nearest = grid.ranges_m[np.argmin(np.abs(grid.ranges_m - r))]
            assert nearest - r == pytest.approx(frac * RANGE_STEP_M if frac <= 0.5 else (frac - 1) * RANGE_STEP_M, abs=1e-9)
            assert np.diff(grid.ranges_m) == pytest.approx(RANGE_STEP_M, abs=1e-9)
            assert np.diff(grid.angles_deg) == pytest.approx(ANGLE_STEP_DEG, abs=1e-9)
            assert grid.angles_deg[0] == pytest.approx(a - CLUTTER_HALF[1], abs=1e-9)


def test_sides_keeps_one_sides_pipes_and_both_by_default():
    names = lambda sc: sorted(t.name for t in sc.targets)  # noqa: E731
    assert names(validation_scene("mud", (250.0, 450.0), pings=1)) == ["P250", "P450", "S250", "S450"]
    assert names(validation_scene("mud", (250.0, 450.0), pings=1, sides="S")) == ["S250", "S450"]
    assert names(validation_scene("sand", (250.0,), pings=1, sides="P")) == ["P250"]
    with pytest.raises(OptionError):
        validation_scene("mud", (250.0,), sides="PS ")


def _channel_ranges(inp, echo: dict) -> np.ndarray:
    """Each channel's delay to ``echo`` (range, angle from the grid centre), as a range: half the two-way
    straight path (m)."""
    a = math.radians(echo["angle_deg"])
    cell = np.array([0.0, echo["range_m"] * math.sin(a), echo["range_m"] * math.cos(a)])
    return 0.5 * (np.linalg.norm(cell - inp.source_offset_m) + np.linalg.norm(cell[None] - inp.element_offsets_m, axis=1))


def test_the_port_pipes_echo_meets_the_starboard_pipes_on_a_few_channels_and_lowers_its_cf_off_the_peak():
    """At 250 m the two pipes' echoes come from opposite sides 0.67 m apart in range, while either echo's
    arrival spreads 1.29 m across the array: on the channels where they meet, the port pipe's echo enters
    the starboard echo's incoherent sum.  Noise-free and without the seabeds' scattering, the starboard
    echo's CF half a range step (0.1 m, the compressed pulse's first null) off its peak is then 0.2; with the
    starboard pipe alone it is 1 (docs/detectability.md, "Near ranges")."""
    import clbeam.sim.catalog as catalog
    from clbeam.imaging.imager import Imager, ImagingOptions
    from clbeam.io.pingfile import pings_from_dataset
    from clbeam.model.grid import PolarGrid
    from clbeam.sim import simulate

    real = catalog.scene_from_mapping

    def unscattered(d, name=None):
        for layer in ("seabed", "subbottom"):
            d[layer]["scattering"]["strength_db"] = -300.0
        return real(d, name=name)

    cf_off = {}
    for sides in ("SP", "S"):
        catalog.scene_from_mapping = unscattered
        try:
            sc = validation_scene("mud", (250.0,), pings=1, snr_db=300.0, sides=sides)
        finally:
            catalog.scene_from_mapping = real
        ds = simulate(sc, pings=[0], seed=7)
        ping, echoes = next(iter(pings_from_dataset(ds))), _echoes(ds)[0]
        echo = echoes["S250"]
        imager = Imager(PolarGrid(echo["range_m"] + np.array([0.0, 0.1]), np.array([echo["angle_deg"]])),
                        ImagingOptions(interp="lanczos8", upsample=1, outputs=("intensity", "cf")))
        cf = imager.image(ping).cf[0]
        assert cf[0] > 0.95
        cf_off[sides] = float(cf[1])
        if sides == "SP":
            inp, _ = imager._prepare(ping)
            gap = _channel_ranges(inp, echoes["P250"]) - _channel_ranges(inp, echo)
            assert gap.max() > 0 > gap.min()                 # they cross on the array
            assert 3 <= np.sum(np.abs(gap) < 0.11) <= 12      # within the pulse's resolution c / 2B on a few channels
    assert cf_off["SP"] < 0.4
    assert cf_off["S"] > 0.99
