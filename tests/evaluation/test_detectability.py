"""The detection-performance model (docs/detectability.md) against closed forms, direct Monte Carlo of
the channels and, slowly, simulated surveys."""

import math
from dataclasses import replace

import numpy as np
import pytest

from clbeam.errors import OptionError
from clbeam.evaluation.detectability import (
    Environment,
    Pipe,
    absorption_db_per_m,
    band,
    channel_model,
    detection,
    echo_spectrum,
    line_response,
    pipe_geometry,
    reverberation,
)
from clbeam.evaluation.detectability_stats import ChannelModel, Tests, cf_exceedance, monte_carlo_tests
from clbeam.evaluation.detectability_sweep import crossing_range, line_spacing, parse_ranges, predict, sweep
from clbeam.imaging.detection import false_alarm_probability, smoothing_eigenvalues
from clbeam.sim import load_scene
from clbeam.sim.physics import attenuation_np_per_m_hz

M = 64


@pytest.fixture(scope="module")
def env():
    return Environment(load_scene("line4"), absorption_db_per_km=0.0)


def _binomial_tol(p: float, n: int, k: float = 4.0) -> float:
    return k * math.sqrt(max(p * (1 - p), 1.0 / n) / n)


def _direct_cf(snr: float, n: int, rng) -> np.ndarray:
    """CF of one cell drawn channel by channel: a fixed coherent part in complex Gaussian noise."""
    w = (rng.standard_normal((n, M)) + 1j * rng.standard_normal((n, M))) / math.sqrt(2)
    p = math.sqrt(snr) + w
    return np.abs(p.sum(axis=1)) ** 2 / (M * np.sum(np.abs(p) ** 2, axis=1))


def test_cf_of_pure_noise_is_beta_1_m_minus_1():
    t = np.array([0.01, 0.03, 0.06, 0.1])
    np.testing.assert_allclose(cf_exceedance(t, M, 0.0), (1 - t) ** (M - 1), rtol=1e-6)


def test_cf_of_a_pure_echo_is_one():
    assert float(cf_exceedance(0.999, M, 1e9)) == pytest.approx(1.0, abs=1e-9)
    assert float(cf_exceedance(1.0, M, 1e9)) == 0.0


@pytest.mark.parametrize("snr_db, t", [(-6.0, 0.15), (0.0, 0.4), (3.0, 0.6)])
def test_cf_of_echo_in_noise_matches_direct_draws(snr_db, t):
    n = 40000
    cf = _direct_cf(10 ** (snr_db / 10), n, np.random.default_rng(1))
    p = float(np.mean(cf > t))
    assert float(cf_exceedance(t, M, 10 ** (snr_db / 10))) == pytest.approx(p, abs=_binomial_tol(p, n))


def _noise_model(env, echo_scale: float = 0.0) -> ChannelModel:
    f, w = band(env)
    return ChannelModel(f, w, np.full(f.size, echo_scale, complex), 1.0, (), M, float(f[1] - f[0]))


@pytest.mark.parametrize("exact", [True, False])
def test_smoothed_cf_of_noise_matches_the_saddlepoint_tail(env, exact):
    """The channel model's noise (correlated along range as the compressed replica) against the
    Lugannani-Rice tail of :mod:`clbeam.imaging.detection` (within its 5 % and the draws' error)."""
    so = env.scene.sonar
    lam = smoothing_eigenvalues(0.2, so.pulse_f1_hz - so.pulse_f0_hz, env.c)
    res = monte_carlo_tests(_noise_model(env), Tests(), clutter=1.0, sound_speed_m_s=env.c, draws=8000, seed=2,
                            exact=exact)
    cf = res["cf_refined"]
    for q in (0.5, 0.1, 0.02):
        x = float(np.quantile(cf, 1 - q))
        pfa = float(false_alarm_probability(x, M, lam))
        assert pfa == pytest.approx(q, abs=0.05 * q + _binomial_tol(q, cf.size))


def test_fast_channel_sums_match_the_channel_by_channel_draws(env):
    """Pd of an echo at a middle SNR, with reverberation off the echo's direction, both ways."""
    f, w = band(env)
    echo = np.full(f.size, 0.55, complex)
    rev = ((np.full(f.size, 0.5 * f[1] - 0.5 * f[0]) / np.sum(w ** 2), 0.02),)
    model = ChannelModel(f, w, echo, 1.0, rev, M, float(f[1] - f[0]))
    fast = monte_carlo_tests(model, Tests(), clutter=1.0, sound_speed_m_s=env.c, draws=4000, seed=3)
    exact = monte_carlo_tests(model, Tests(), clutter=1.0, sound_speed_m_s=env.c, draws=4000, seed=4, exact=True)
    assert 0.1 < exact["pd"] < 0.9
    assert fast["pd"] == pytest.approx(exact["pd"], abs=_binomial_tol(exact["pd"], 4000, 5.0))


def test_broadside_echo_is_the_stationary_phase_cylinder_echo(env):
    """``ρ T H sqrt(λR/2) / R² e^(−αfℓ)``: spherical spreading to ``R^-1.5``, Snell path, cylinder."""
    pipe = Pipe(burial_m=1.0)
    f = np.array([3000.0, 5500.0, 8000.0])
    for r in (400.0, 920.0):
        geo = pipe_geometry(env, pipe, r)
        sb = env.scene.seabed
        h = env.height_m
        slant = math.sqrt(r * r + (h + 1.0) ** 2)
        assert geo["slant_m"] == pytest.approx(slant, rel=1e-12)
        expected = (0.8 * geo["transmission"] * line_response(pipe, f, env.c * sb.sound_speed_ratio)
                    * np.sqrt(env.c / f * slant / 2) / slant ** 2
                    * np.exp(-attenuation_np_per_m_hz(sb) * f * geo["sediment_m"]))
        np.testing.assert_allclose(np.abs(echo_spectrum(env, pipe, r, f, method="stationary")), expected, rtol=1e-9)


def test_numerical_integral_along_the_pipe_equals_stationary_phase_at_broadside(env):
    pipe = Pipe(burial_m=1.0)
    f = np.linspace(2500.0, 8500.0, 7)
    sp = echo_spectrum(env, pipe, 700.0, f, method="stationary")
    num = echo_spectrum(env, pipe, 700.0, f, method="integral")
    np.testing.assert_allclose(np.abs(num), np.abs(sp), rtol=0.03)
    np.testing.assert_allclose(np.angle(num / sp), 0.0, atol=0.05)


def test_large_cylinder_target_strength_is_urick_with_the_fresnel_length(env):
    """``ka >> 1``: ``|G|² R⁴ / (ρ T)² = a L² / (2λ)`` with ``L² = λ R / 2`` (Urick's broadside cylinder over
    the first Fresnel zone)."""
    pipe = Pipe(radius_m=5.0, burial_m=1e-6)
    f = np.array([6000.0])
    geo = pipe_geometry(env, pipe, 500.0)
    r, lam = geo["slant_m"], env.c / f[0]
    g = abs(echo_spectrum(env, pipe, 500.0, f, method="stationary")[0])
    # in water (burial ~0): k a uses the sediment's speed; G(ka) -> 1 within (ka)^-3 / 2
    sigma = g ** 2 * r ** 4 / (0.8 * geo["transmission"]) ** 2
    urick = pipe.radius_m * (lam * r / 2) / (2 * lam) * (env.c / (env.c * env.scene.seabed.sound_speed_ratio))
    assert sigma == pytest.approx(urick, rel=1e-4)


def test_water_absorption_matches_ainslie_mccolm_and_enters_twice_the_range():
    sc = load_scene("line4")
    fg = Environment(sc, absorption_db_per_km=None, temperature_c=10.0, salinity_psu=35.0)
    f = np.array([2000.0, 5000.0, 9000.0])
    # Ainslie & McColm (1998), pH 8, depth in km
    fk, t, s, z = f / 1000, 10.0, 35.0, 0.5 * sc.seabed.depth_m / 1000
    f1, f2 = 0.78 * math.sqrt(s / 35) * math.exp(t / 26), 42 * math.exp(t / 17)
    am = (0.106 * f1 * fk ** 2 / (f1 ** 2 + fk ** 2) + 0.52 * (1 + t / 43) * (s / 35) * math.exp(-z / 6) * f2 * fk ** 2
          / (f2 ** 2 + fk ** 2) + 0.00049 * fk ** 2 * math.exp(-(t / 27 + z / 17))) / 1000
    np.testing.assert_allclose(absorption_db_per_m(fg, f), am, rtol=0.1)
    pipe, r = Pipe(), 900.0
    ratio = np.abs(echo_spectrum(fg, pipe, r, f, method="stationary")
                   / echo_spectrum(Environment(sc, absorption_db_per_km=0.0), pipe, r, f, method="stationary"))
    np.testing.assert_allclose(20 * np.log10(ratio), -absorption_db_per_m(fg, f) * 2 * pipe_geometry(fg, pipe, r)["slant_m"],
                               rtol=1e-9)


def test_seabed_reverberation_of_a_narrow_beam_is_the_ring_closed_form(env):
    """Lambert seabed, beam narrow: ``σ c / (2 R² ρ) ∫ b² du`` per unit delay; ``∫ sinc²(L f u / c) du =
    c / (L f)`` when the cut is far beyond the main lobe (here the high band, the taper's edge left in
    as a bound)."""
    f = np.array([9000.0])
    pipe = Pipe(burial_m=0.0 + 1e-9)
    r = 800.0
    rev = {x["name"]: x for x in reverberation(env, pipe, r, f)}
    geo = pipe_geometry(env, pipe, r)
    slant, h = geo["delay_range_m"], env.height_m
    rho = math.sqrt(slant ** 2 - h ** 2)
    sc = env.scene.seabed.scattering
    sigma = 10 ** (sc.strength_db / 10) * (h / slant) ** sc.grazing_exponent
    closed = sigma * env.c / (2 * slant ** 2 * rho) * env.c / (env.scene.sonar.tx_length_m * f[0])
    assert float(rev["seabed"]["density"][0]) == pytest.approx(closed, rel=0.03)


def test_crossing_range_and_line_spacing_on_known_curves():
    r = np.array([100.0, 200.0, 300.0, 400.0])
    assert crossing_range(r, [1.0, 1.0, 0.6, 0.2], 0.9) == pytest.approx(225.0)
    assert crossing_range(r, [1.0, 1.0, 0.6, 0.2], 0.5) == pytest.approx(325.0)
    assert math.isinf(crossing_range(r, [1, 1, 1, 1], 0.5)) and math.isnan(crossing_range(r, [0.1] * 4, 0.5))
    # Pd 1 out to 300 m then 0: a pipe anywhere between two lines 600 m apart is within 300 m of one
    rr = np.arange(50.0, 1001.0, 1.0)
    step = np.where(rr <= 300.0, 1.0, 0.0)
    assert line_spacing(rr, step) == pytest.approx(600.0, abs=2.5)
    # Pd 0.7 everywhere: two lines give 1 - 0.3² = 0.91 over the whole gap out to the sweep's end
    assert line_spacing(rr, np.full(rr.size, 0.7)) == pytest.approx(1000.0, abs=2.5)


def test_bad_input_is_one_line():
    with pytest.raises(OptionError, match="radius"):
        Pipe(radius_m=-0.1)
    with pytest.raises(OptionError, match="no pipelines"):
        predict("point")
    with pytest.raises(OptionError, match="beyond the record"):
        predict("line4", ranges_m=[500.0, 2000.0])
    with pytest.raises(OptionError, match="START:STOP:STEP"):
        parse_ranges("100:200")


def test_pd_falls_with_range_and_with_noise(env):
    """More noise, shorter range; the default and a looser threshold order as they must."""
    r = np.array([900.0, 1800.0, 2400.0])
    pipe = Pipe()

    loud = replace(env, noise_offset_db=6.0)
    quiet = [row["pd"] for row in sweep(env, pipe, r, draws=512)]
    noisy = [row["pd"] for row in sweep(loud, pipe, r, draws=512)]
    assert quiet[0] > 0.95 and quiet[-1] < quiet[0]
    assert all(n <= q + 0.05 for n, q in zip(noisy, quiet))
    loose = [row["pd"] for row in sweep(replace(env, tests=Tests(threshold=0.2)), pipe, r, draws=512)]
    assert all(lo >= q - 0.05 for lo, q in zip(loose, quiet))


@pytest.mark.slow
def test_predicted_pd_matches_a_small_simulated_survey():
    """Mud, 1 m and 2 m burial, three ranges, a few pings: measured fraction within 0.15 of the prediction
    plus its binomial error."""
    from clbeam.evaluation.detectability_validation import measure, validation_scene

    ranges, pings = (450.0, 1100.0, 1450.0), 6
    scene = validation_scene("mud", ranges, pings=pings)
    counts = measure(scene, seed=5)
    env = Environment(scene, absorption_db_per_km=0.0)
    for name, (hits, n) in counts.items():
        b = 1.0 if name[0] == "S" else 2.0
        pd = detection(env, Pipe(burial_m=b), float(name[1:]), draws=2048)["pd"]
        assert hits / n == pytest.approx(pd, abs=0.15 + 2 * math.sqrt(max(pd * (1 - pd), 0.02) / n)), name


# -- the fast paths against the straightforward computation ------------------------------------------------
def test_lattice_sum_matches_the_direct_sum_within_the_kernels_bound():
    """The non-uniform FFT against ``Σ w_p e^(−2πi f_k t_p)`` term by term: within ``10^(1 − W)`` of
    ``Σ |w_p|`` (the exponential-of-semicircle kernel's error at twice oversampling)."""
    from clbeam.evaluation.detectability_nufft import KERNEL_WIDTH, lattice_sum

    rng = np.random.default_rng(7)
    t = rng.uniform(0.05, 0.09, 3000)
    w = rng.standard_normal((t.size, 2)) + 1j * rng.standard_normal((t.size, 2))
    f0, df, k = 225.0, 50.0, 313
    direct = np.exp(-2j * np.pi * (f0 + df * np.arange(k))[:, None] * t[None, :]) @ w
    fast = lattice_sum(t, w, f0, df, k)
    bound = 10.0 ** (1 - KERNEL_WIDTH) * np.sum(np.abs(w), axis=0)
    assert np.all(np.abs(fast - direct) <= bound)
    np.testing.assert_array_equal(lattice_sum(t, w[:, 0], f0, df, k), fast[:, 0])


def _pair_bound(env, pipe, r, f):
    """The fast integral's error bound: the kernel's ``10^(1 − W)`` of the pairs' ``Σ |w_p|`` (each point
    ``Δs taper / R² / (4π f x)`` twice, its absorption series at most ``e^(γ̂ |ΔR|)``), and the series'
    truncation, :data:`ABSORPTION_TERM_TOL` of the points' sum."""
    from clbeam.evaluation import detectability as d
    from clbeam.evaluation.detectability_nufft import KERNEL_WIDTH

    geo = pipe_geometry(env, pipe, r)
    u, slant, _, step = d._pipe_points(env, pipe, r, geo)
    x = np.maximum(np.abs(env.scene.sonar.tx_length_m * u / (2 * env.c)), 1e-6 / (2 * np.pi * f.min()))
    g = absorption_db_per_m(env, f) * math.log(10) / 10
    spread = np.exp(-g.min() * slant.min()) * np.exp(np.ptp(g) * np.ptp(slant))
    pairs = 2 * np.sum(step / slant ** 2 / x) / (4 * np.pi * f) * spread
    return 10.0 ** (1 - KERNEL_WIDTH) * pairs + d.ABSORPTION_TERM_TOL * np.sum(step / slant ** 2) * spread


@pytest.mark.parametrize("absorption", [None, 0.0])
@pytest.mark.parametrize("heading", [-2.0, -3.5, -5.0, -20.0])
def test_fast_integral_along_the_pipe_matches_the_sum_term_by_term(absorption, heading):
    from clbeam.evaluation import detectability as d

    env = Environment(load_scene("line4", overrides={"record.max_range_m": 2700.0}), absorption_db_per_km=absorption)
    f, _ = band(env)
    pipe = Pipe(heading_deg=heading)
    for r in (300.0, 1300.0, 2600.0):
        geo = pipe_geometry(env, pipe, r)
        direct = d._along_pipe(env, pipe, r, f, geo)
        fast = d._along_pipe_fast(env, pipe, r, f, geo)
        assert np.all(np.abs(fast - direct) <= _pair_bound(env, pipe, r, f)), r


def _line4_env():
    return Environment(load_scene("line4", overrides={"record.max_range_m": 2700.0}), absorption_db_per_km=None)


def test_a_sweeps_batch_gives_each_range_the_draws_it_gets_alone():
    """Line 4's pipeline B (3.5 degrees off broadside: the echo integrated along the pipe): the ranges drawn
    together equal each drawn alone, to rounding."""
    from clbeam.evaluation.detectability import detections

    env, pipe = _line4_env(), Pipe(heading_deg=-3.5)
    ranges = [300.0, 450.0, 1200.0]
    together = detections(env, pipe, ranges, draws=256)
    for r, res in zip(ranges, together):
        alone = detection(env, pipe, r, draws=256)
        assert res["pd"] == alone["pd"] and res["echo_db"] == alone["echo_db"]
        np.testing.assert_allclose(res["cf_refined"], alone["cf_refined"], rtol=1e-9)


def test_draws_are_continuous_in_the_covariances():
    """Common random numbers: the reverberation's spectrum changed by parts in 1e12 (rounding) moves every
    draw's smoothed CF by about as little (the principal root is continuous; eigenvectors scaled jump
    where eigenvalues meet, as they do here)."""
    env, pipe = _line4_env(), Pipe(heading_deg=-3.5)
    model, levels = channel_model(env, pipe, 1200.0)
    wobble = 1 + 1e-12 * np.random.default_rng(1).standard_normal(model.frequency_hz.size)
    nudged = replace(model, reverberation=tuple((dens * wobble, step) for dens, step in model.reverberation))
    kw = dict(clutter=levels["clutter"], sound_speed_m_s=env.c, draws=512, seed=0)
    a = monte_carlo_tests(model, env.tests, **kw)["cf_refined"]
    b = monte_carlo_tests(nudged, env.tests, **kw)["cf_refined"]
    np.testing.assert_allclose(b, a, rtol=1e-8)


def test_fast_integral_gives_the_pd_of_the_sum_term_by_term(monkeypatch):
    """Line 4's pipelines at their headings: the same draws give the same Pd with the echo integrated
    along the pipe either way (the two differ by far less than any draw's distance to a threshold)."""
    from clbeam.evaluation import detectability as d

    env = _line4_env()
    ranges = [250.0, 500.0, 1000.0]
    fast = {h: d.detections(env, Pipe(heading_deg=h), ranges, draws=256) for h in (-3.5, -5.0)}
    d._ALONG_CACHE.clear()
    monkeypatch.setattr(d, "_along_pipe_fast", d._along_pipe)
    for h, rows in fast.items():
        for a, b in zip(rows, d.detections(env, Pipe(heading_deg=h), ranges, draws=256)):
            assert a["pd"] == b["pd"] and a["echo_db"] == pytest.approx(b["echo_db"], abs=1e-6)
    d._ALONG_CACHE.clear()


def test_an_echo_on_a_node_passes_the_grid_whenever_it_passes_at_the_echo():
    """``offsets=1`` puts the echo on a node: the grid's central cell is the refined point, its smoothed CF
    the same draw's, so the grid passes wherever the refined point does (at 2000 m, on the four offsets'
    plateau of Pd 0.5, where the ±3/8 pair misses)."""
    env = _line4_env()
    model, levels = channel_model(env, Pipe(), 2000.0)
    on_node = monte_carlo_tests(model, env.tests, clutter=levels["clutter"], sound_speed_m_s=env.c, draws=512,
                                offsets=1)
    assert on_node["p_cf"] >= np.mean(on_node["cf_refined"] > env.tests.threshold)


def test_the_default_offsets_give_the_pd_of_an_echo_uniform_over_a_cell():
    """Line 4 broadside at 1500 m, where an echo near halfway between nodes is missed: the default's 64
    offsets against a four times finer midpoint rule (256) within four standard errors of the difference of
    two binomial estimates; the four offsets of before differ from it by more (the echo's own beam: the
    beams beside are left out on both sides)."""
    env = _line4_env()
    model, levels = channel_model(env, Pipe(), 1500.0)
    n = 4096

    def pd(g):
        return monte_carlo_tests(model, env.tests, clutter=levels["clutter"], sound_speed_m_s=env.c, draws=n,
                                 offsets=g)["pd"]

    fine = pd(256)
    tol = 4 * math.sqrt(2 * max(fine * (1 - fine), 1.0 / n) / n)
    assert detection(env, Pipe(), 1500.0, draws=n, beside=0)["pd"] == pytest.approx(fine, abs=tol)
    assert abs(pd(4) - fine) > tol
