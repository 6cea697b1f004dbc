"""The discrete-scatterer physics (clbeam.sim.discrete) against closed forms and its own statistics.

A single scatterer's compressed echo on every element is compared with the closed form written out
here: the exact 3-D two-way delay, spherical spreading and the transmit column's along-track pattern
``sinc(L f u / c)`` (per frequency, weighted by the pulse's spectrum; or at the band centre).  The
fields' statistics are tested against their laws (Poisson counts, Rayleigh magnitudes and uniform
phases by chi-square, uniform depths) over several seeds, with bounds from the laws' own spreads.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np
import pytest
import scipy.optimize
import scipy.stats

from clbeam.errors import OptionError
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.io.pingfile import PingFile
from clbeam.model.grid import PolarGrid
from clbeam.model.pulse import lfm_replica
from clbeam.sim.discrete import InterfaceField, pipe_scatterers, scatterer_echo
from clbeam.sim.scene import LineTarget, Scattering
from clbeam.sim.simulator import Simulator, load_scene, simulate, write

C, FS, L, F0, F1 = 1500.0, 40000.0, 3.5, 2000.0, 9000.0
FC = 0.5 * (F0 + F1)
REPLICA = lfm_replica(f0_hz=F0, f1_hz=F1, duration_s=0.08, sample_rate_hz=FS)
# The renderer's fractional-delay filter has a complex error of at most 5e-3 in the band (its
# design target); with the 1/1024-sample phase table (0.3 % at 9 kHz) the compressed value at the
# true delay is within 1e-2 of the echo's peak.  A delay error of one sample would move its phase
# by 0.9 rad at the band centre.
ECHO_TOL = 1e-2
SEEDS = range(8)


def elements(n=64, width=3.528) -> np.ndarray:
    """The SBP29 receive elements, written out independently."""
    pos = np.zeros((n, 3))
    pos[:, 1] = (np.arange(n) - (n - 1) / 2) * width / n
    return pos


def compressed_at(channels: np.ndarray, t_s: np.ndarray, t0_s: float = 0.0) -> np.ndarray:
    """The analytic pulse-compressed signal of each channel at ``t_s[n]`` (exact band-limited
    evaluation of its spectrum), scaled so that an echo ``A x(t - τ)`` gives ``A`` at ``τ``."""
    n = channels.shape[1] + REPLICA.size
    spec = np.fft.rfft(channels, n, axis=1) * np.conj(np.fft.rfft(REPLICA, n))[None, :]
    f = np.fft.rfftfreq(n, 1 / FS)
    spec[:, 0] = 0.0
    phase = np.exp(2j * np.pi * np.outer(t_s - t0_s, f))
    return 2 * np.sum(spec * phase, axis=1) / n / (REPLICA @ REPLICA)


def band_pattern(u: float) -> float:
    """The compressed echo's value at its delay under the pattern ``sinc(L f u / c)`` at every
    frequency: the pattern averaged over the pulse's energy spectrum."""
    spec = np.abs(np.fft.rfft(REPLICA, 1 << 16)) ** 2
    f = np.fft.rfftfreq(1 << 16, 1 / FS)
    return float(np.sum(spec * np.sinc(L * f * u / C)) / np.sum(spec))


def point_scene(x_m: float, pattern: str, **target):
    """One discrete point scatterer at ``(x, 150, 200)`` m, no seabed, motion or noise."""
    t = {"kind": "point", "name": "P", "x_m": x_m, "y_m": 150.0, "z_m": 200.0, "amplitude_m": 1.0} | target
    return load_scene("point", snr_db=None, overrides={"model.physics": "discrete", "discrete.tx_pattern": pattern,
                                                       "target": [t]})


def closed_form(pos: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Two-way delay (s) and spreading ``1 / (|r - s| |r - e_n|)`` on every element, and ``u``
    (the source at the array centre, the origin)."""
    source = np.zeros(3)
    d_src = np.linalg.norm(pos - source)
    d_el = np.linalg.norm(pos[None, :] - elements(), axis=1)
    return (d_src + d_el) / C, 1.0 / (d_src * d_el), float((pos - source)[0] / d_src)


@pytest.mark.parametrize("pattern, along_m", [("band", 0.0), ("band", 6.0), ("band", 14.0), ("band", 30.0),
                                              ("centre", 0.0), ("centre", 9.0), ("centre", 19.5)])
def test_a_point_scatterers_echo_has_the_closed_form_delay_spreading_and_pattern_on_every_element(pattern, along_m):
    sim = Simulator(point_scene(along_m, pattern))
    samples = sim.ping(0).astype(np.float64)
    tau, spread, u = closed_form(np.array([along_m, 150.0, 200.0]))
    assert abs(u) < 0.75 * (C / F0) / L          # inside the cut's flat part: no taper
    weight = band_pattern(u) if pattern == "band" else float(np.sinc(L * u * FC / C))
    got = compressed_at(samples, tau)
    want = spread * weight
    # at u = 0.0779 the band-centre pattern has its first null (along_m = 19.5)
    assert np.max(np.abs(got - want)) <= ECHO_TOL * np.max(spread), (pattern, u, np.max(np.abs(got - want)))
    if weight > 0.5:  # the delay: the compressed envelope peaks at tau (within 1/20 sample)
        late = np.abs(compressed_at(samples, tau + 1.25e-6))
        early = np.abs(compressed_at(samples, tau - 1.25e-6))
        assert np.all(np.abs(got) > late) and np.all(np.abs(got) > early)


def fermat_leg(start: np.ndarray, end: np.ndarray, seabed_z: float, ratio: float) -> tuple[float, float]:
    """Travel time (s) of the leg from ``start`` in the water to ``end`` below a flat seabed at
    ``seabed_z`` (sediment speed ``ratio · c``), by Fermat's principle on the crossing point, and the
    grazing angle in the water (rad)."""
    horiz = math.hypot(*(end - start)[:2])
    a, b = seabed_z - start[2], end[2] - seabed_z
    res = scipy.optimize.minimize_scalar(lambda xi: math.hypot(xi, a) / C + math.hypot(horiz - xi, b) / (ratio * C),
                                         bounds=(0.0, horiz), method="bounded", options={"xatol": 1e-10})
    return float(res.fun), math.atan2(a, res.x)


@pytest.mark.parametrize("profile", [False, True])
def test_a_buried_scatterer_is_refracted_transmitted_and_delayed_as_fermat_says(profile):
    """A discrete scatterer 2 m below a flat seabed of speed ratio 0.98 (no attenuation), in isospeed
    water (Snell, first order across the array) or through a one-speed ``[water]`` profile (ray traced):
    the compressed echo at the Fermat two-way time on every element is ``A P (1 - V²) / (|r-s||r-e_n|)``,
    ``V`` the fluid-fluid reflection coefficient at the source ray's grazing angle (written out here)."""
    seabed, burial, ratio, rho = 225.0, 2.0, 0.98, 2.0
    over = {"model.physics": "discrete", "discrete.tx_pattern": "centre",
            "seabed": {"depth_m": seabed + 5.0, "specular": False, "multiple": False, "sound_speed_ratio": ratio,
                       "density_ratio": rho, "attenuation_db_per_m": 0.0},
            "target": [{"kind": "point", "name": "P", "x_m": 4.0, "y_m": 260.0, "burial_m": burial,
                        "amplitude_m": 1.0}]}
    if profile:
        over["water"] = {"svp_depth_m": [0.0], "svp_speed_m_s": [C]}
    sc = load_scene("point", snr_db=None, max_range_m=400.0, overrides=over)
    samples = Simulator(sc).ping(0).astype(np.float64)
    r = np.array([4.0, 260.0, seabed + burial])
    t_tx, graz = fermat_leg(np.zeros(3), r, seabed, ratio)
    t_rx = np.array([fermat_leg(e, r, seabed, ratio)[0] for e in elements()])
    sin_t = math.sqrt(ratio ** -2 - math.cos(graz) ** 2)
    v = (rho * math.sin(graz) - sin_t) / (rho * math.sin(graz) + sin_t)
    _, spread, u = closed_form(r)
    want = spread * (1 - v * v) * float(np.sinc(L * u * FC / C))
    got = compressed_at(samples, t_tx + t_rx)
    assert 0.05 < v * v < 0.2      # the transmission matters (10 times the tolerance)
    assert np.max(np.abs(got - want)) <= ECHO_TOL * np.max(spread)


def test_a_constant_sound_speed_profile_renders_the_discrete_field_as_straight_rays_do():
    """The ray-traced path of the discrete model (a ``[water]`` profile of one speed) gives the isospeed
    samples of a rolled ping's seabed field, nadir echoes, an exposed pipe and a point: the same times to
    1e-15 s, so the same samples but where a time's last bits switch a delay filter's phase (1/1024
    sample: 1e-6 of the largest sample)."""
    over = {"model.physics": "discrete", "subbottom": None, "motion.roll_amplitude_deg": 2.0,
            "target": [{"kind": "line", "name": "A", "x_m": 0.0, "y_m": -150.0, "angle_deg": 10.0, "z_m": 224.8},
                       {"kind": "point", "name": "P", "x_m": 3.0, "y_m": 120.0, "z_m": 224.0}]}
    iso = Simulator(load_scene("line1", pings=1, max_range_m=300.0, snr_db=None, overrides=over)).ping(0)
    over |= {"water": {"svp_depth_m": [0.0], "svp_speed_m_s": [1500.0]}}
    traced = Simulator(load_scene("line1", pings=1, max_range_m=300.0, snr_db=None, overrides=over)).ping(0)
    assert np.max(np.abs(traced - iso)) <= 1e-6 * np.max(np.abs(iso))


def test_a_complex_amplitude_rotates_the_compressed_echo_by_its_phase():
    sim = Simulator(point_scene(0.0, "centre"))
    g = sim.geometry(0)
    pos = np.array([[0.0, 150.0, 200.0], [0.0, -220.0, 180.0]])
    amp = np.array([0.7 * np.exp(1.1j), 1.3 * np.exp(-2.5j)])
    out = sim.render(g, [scatterer_echo(sim.propagation, g, "two", pos, amp)])
    for p, a in zip(pos, amp):
        tau, spread, _ = closed_form(p)
        got = compressed_at(out, tau)
        assert np.max(np.abs(got - a * spread)) <= ECHO_TOL * abs(a) * np.max(spread)


def test_interface_fields_are_poisson_uniform_with_rayleigh_amplitudes_and_uniform_phases():
    """Over several seeds: counts in a 1 km square within 4 Poisson sigmas; the counts in 100 cells, the
    magnitudes (|w|² against Exp(1)) and the phases (against uniform) by chi-square, the number of seeds
    failing at 1 % within the binomial 99.9 % bound; depths uniform within ±h (mean and variance)."""
    density, half = 0.06, 0.05
    area = 1024.0 ** 2
    p_cells, p_power, p_phase, powers = [], [], [], []
    for seed in SEEDS:
        f = InterfaceField(load_scene("line1"), seed=seed, layer=1, scattering=Scattering(), density_per_m2=density,
                           half_depth_m=half, depth_below_seabed_m=0.0)
        pts = f.within(-512.0, 512.0, 0.0, 1024.0)
        n = pts["x"].size
        assert abs(n - density * area) <= 4 * math.sqrt(density * area)
        cells, _, _ = np.histogram2d(pts["x"], pts["y"], bins=10, range=[[-512, 512], [0, 1024]])
        mu = density * area / 100
        p_cells.append(scipy.stats.chi2.sf(np.sum((cells - mu) ** 2) / mu, 99))
        power = np.abs(pts["w"]) ** 2
        powers.append(power)
        edges = -np.log1p(-np.linspace(0, 1, 21)[:-1])          # 20 equiprobable bins of Exp(1)
        p_power.append(scipy.stats.chisquare(np.bincount(np.searchsorted(edges, power) - 1, minlength=20)).pvalue)
        p_phase.append(scipy.stats.chisquare(np.histogram(np.angle(pts["w"]), bins=20, range=(-np.pi, np.pi))[0]).pvalue)
        zeta = pts["zeta"]
        assert np.all(np.abs(zeta) <= half)
        assert abs(zeta.mean()) <= 4 * half / math.sqrt(3 * n)
        assert abs(np.mean(zeta ** 2) - half ** 2 / 3) <= 4 * math.sqrt(4 * half ** 4 / 45 / n)
    bound = scipy.stats.binom.ppf(0.999, len(SEEDS), 0.01)
    for p in (p_cells, p_power, p_phase):
        assert np.sum(np.array(p) < 0.01) <= bound, p
    pooled = np.concatenate(powers)
    assert abs(pooled.mean() - 1.0) <= 4 / math.sqrt(pooled.size)      # E|w|² = 1, sd of |w|² is 1


@pytest.mark.parametrize("layer", [1, 2])
def test_a_pings_interface_echoes_hold_every_scatterer_in_its_beam_with_power_sigma_over_density(layer):
    """The seabed's (layer 1) or the sub-bottom's (layer 2, under a sediment as fast as the water and twice as dense: straight
    rays, transmission ``1 - V²`` with ``V = (ρ - 1)/(ρ + 1)`` at every angle) scatterers of one ping in the
    beam's flat part: their number against the density times the area (integrated here on a fine grid),
    and ``|A|² n / (σ(θ) T²)`` against Exp(1) (mean within 4 sigmas, chi-square at 0.1 %), over seeds;
    ``σ = μ sin² θ`` with ``θ`` the grazing angle computed here."""
    sc = load_scene("line1", pings=1, snr_db=None, overrides={
        "model.physics": "discrete", "seabed.slope_across_deg": 0.0, "seabed.sound_speed_ratio": 1.0,
        "seabed.density_ratio": 2.0,
        "seabed.attenuation_db_per_m": 0.0, "target": [], "motion.roll_amplitude_deg": 0.0,
        "motion.heave_amplitude_m": 0.0, "motion.pitch_amplitude_deg": 0.0})
    rho = sc.seabed.density_ratio
    transmission = 1.0 if layer == 1 else 1 - ((rho - 1) / (rho + 1)) ** 2
    interface = sc.seabed if layer == 1 else sc.subbottom
    density = sc.discrete.seabed_density_per_m2 if layer == 1 else sc.discrete.subbottom_density_per_m2
    mu, h = 10 ** (interface.scattering.strength_db / 10), 225.0 + (layer - 1) * sc.subbottom.depth_below_seabed_m
    u_max, r_lo, r_hi = 0.1, h + 35.0, 600.0
    x, y = np.meshgrid(np.arange(-80, 80, 0.25) + 0.125, np.arange(-700, 700, 0.25) + 0.125)
    dist = np.sqrt(x ** 2 + y ** 2 + h ** 2)
    area = 0.25 ** 2 * np.count_nonzero((np.abs(x) / dist < u_max) & (dist > r_lo) & (dist < r_hi))
    ratios = []
    for seed in SEEDS[:4]:
        sim = Simulator(sc, seed=seed)
        g = sim.geometry(0)
        e = sim._discrete.field_echo(g, sim._discrete.fields[layer - 1])
        d = np.linalg.norm(e.pos - g.source, axis=1)
        sel = (np.abs(e.pos[:, 0]) / d < u_max) & (d > r_lo) & (d < r_hi)
        assert abs(sel.sum() - density * area) <= 4 * math.sqrt(density * area)
        sin_graz = (e.pos[sel, 2] - g.source[2]) / d[sel]
        ratios.append(np.abs(e.amp[sel]) ** 2 * density / (mu * sin_graz ** 2 * transmission ** 2))
    r = np.concatenate(ratios)
    assert abs(r.mean() - 1.0) <= 4 / math.sqrt(r.size)
    edges = -np.log1p(-np.linspace(0, 1, 21)[:-1])
    assert scipy.stats.chisquare(np.bincount(np.searchsorted(edges, r) - 1, minlength=20)).pvalue > 1e-3


@pytest.mark.parametrize("curvature", [0.0, 20.0])
def test_a_pipes_scatterers_lie_on_its_axis_at_its_burial_every_spacing(curvature):
    sc = load_scene("line1", overrides={"model.physics": "discrete", "seabed.slope_along_deg": 0.5,
                                        "seabed.slope_across_deg": -0.8})
    t = LineTarget(name="A", x_m=100.0, y_m=340.0, angle_deg=5.0, curvature_deg_per_km=curvature, burial_m=1.0,
                   radius_m=0.2, reflectivity=0.7, gap_x_m=(150.0, 180.0))
    p = pipe_scatterers(sc, t, seed=3, x_window=(-50.0, 250.0))
    ds = sc.discrete.pipe_spacing_m
    assert np.allclose(p["s"] / ds, np.rint(p["s"] / ds), atol=1e-9)
    assert p["x"].min() < -50 and p["x"].max() > 250 and np.all(np.diff(p["x"]) > 0)
    assert not np.any((p["x"] >= 150.0) & (p["x"] <= 180.0))
    d0 = math.radians(5.0)
    if curvature == 0:   # the straight axis through (100, 340) at 5 degrees
        assert np.allclose(p["y"], 340.0 + (p["x"] - 100.0) * math.tan(d0), atol=1e-9)
    else:                # the circle of radius 1/κ through (100, 340) tangent to the heading
        radius = 1000.0 / math.radians(curvature)
        cx, cy = 100.0 - radius * math.sin(d0), 340.0 + radius * math.cos(d0)
        assert np.allclose(np.hypot(p["x"] - cx, p["y"] - cy), radius, atol=1e-6)
    steps = np.hypot(np.diff(p["x"]), np.diff(p["y"]))
    whole = np.isclose(np.diff(p["s"]), ds)
    assert np.allclose(steps[whole], ds, atol=1e-7)     # chord of a 0.1 m arc on a 2.9 km radius: 1e-11 m shorter
    seabed = (230.0 - 5.0) + math.tan(math.radians(0.5)) * p["x"] + math.tan(math.radians(-0.8)) * p["y"]
    assert np.allclose(p["z"], seabed + 1.0, atol=1e-9)
    power = np.abs(p["amp"]) ** 2 / (0.7 ** 2 * 2 * 0.2 * 10 ** (sc.discrete.pipe_strength_db / 10) * ds)
    assert abs(power.mean() - 1.0) <= 4 / math.sqrt(power.size)


def test_the_same_seed_draws_the_same_world_fixed_field_whichever_pings_are_made():
    sc = load_scene("line1", pings=4, max_range_m=320.0, overrides={
        "model.physics": "discrete", "target": [{"kind": "line", "name": "A", "x_m": 0.0, "y_m": 150.0,
                                                 "angle_deg": 20.0, "burial_m": 1.0}]})
    whole, alone = Simulator(sc, seed=5), Simulator(sc, seed=5, pings=[3])
    assert np.array_equal(whole.ping(3), alone.ping(3))
    assert not np.array_equal(whole.ping(3), Simulator(sc, seed=6, pings=[3]).ping(3))
    # successive pings see the same scatterers where their footprints overlap
    f1, f2 = (InterfaceField(sc, seed=5, layer=1, scattering=sc.seabed.scattering, density_per_m2=0.06,
                             half_depth_m=0.05, depth_below_seabed_m=0.0) for _ in range(2))
    a, b = f1.within(0.0, 100.0, -300.0, 300.0), f2.within(8.23, 108.23, -300.0, 300.0)
    key_a = {(round(x, 9), round(y, 9)): w for x, y, w in zip(a["x"], a["y"], a["w"])}
    shared = [(key_a[(round(x, 9), round(y, 9))], w) for x, y, w in zip(b["x"], b["y"], b["w"])
              if (round(x, 9), round(y, 9)) in key_a]
    assert len(shared) == np.count_nonzero((a["x"] >= 8.23)) and all(wa == wb for wa, wb in shared)
    t = sc.targets[0]
    p1 = pipe_scatterers(sc, t, seed=5, x_window=(0.0, 50.0))
    p2 = pipe_scatterers(sc, t, seed=5, x_window=(25.0, 90.0))
    common, i1, i2 = np.intersect1d(p1["s"], p2["s"], return_indices=True)
    assert common.size > 100 and np.array_equal(p1["amp"][i1], p2["amp"][i2])


def test_a_discrete_point_is_imaged_where_it_is_within_a_range_cell_and_a_tenth_of_a_degree(tmp_path):
    range_res, angle_res = 0.1, 0.05
    ds = simulate(point_scene(0.0, "band", y_m=-260.0, z_m=210.0))
    path = write(ds, tmp_path / "discrete.nc")
    r0, a0 = math.hypot(-260.0, 210.0), math.degrees(math.atan2(-260.0, 210.0))
    grid = PolarGrid.regular(range_res_m=range_res, angle_res_deg=angle_res, min_range_m=r0 - 3.0,
                             max_range_m=r0 + 3.0, angles_deg=(a0 - 2.0, a0 + 2.0))
    with PingFile(path) as f:
        img = Imager(grid, ImagingOptions(interp="lanczos8")).image(f.ping(0))
    ia, ir = np.unravel_index(np.argmax(img.intensity), img.intensity.shape)
    assert abs(grid.ranges_m[ir] - r0) <= range_res and abs(grid.angles_deg[ia] - a0) <= 0.1
    assert ds.attrs["scene_json"].count('"physics": "discrete"') == 1


def test_discrete_scene_keys_are_checked_with_one_line_errors():
    with pytest.raises(OptionError, match="model.physics"):
        load_scene("point", overrides={"model.physics": "rough"})
    with pytest.raises(OptionError, match=r"\[discrete\] table needs model.physics"):
        load_scene("point", overrides={"discrete.pipe_spacing_m": 0.2})
    with pytest.raises(OptionError, match="discrete.tx_pattern"):
        load_scene("point", overrides={"model.physics": "discrete", "discrete.tx_pattern": "middle"})
    with pytest.raises(OptionError, match="discrete.seabed_density_per_m2"):
        load_scene("point", overrides={"model.physics": "discrete", "discrete.seabed_density_per_m2": 0.0})
    with pytest.raises(OptionError, match="subbottom_depth_m"):
        load_scene("line1", overrides={"model.physics": "discrete", "discrete.subbottom_depth_m": 25.0})
    with pytest.raises(OptionError, match="seabed_depth_m must be within 0-0.5 m") as info:
        load_scene("line1", overrides={"model.physics": "discrete", "discrete.seabed_depth_m": 2.0})
    assert "\n" not in str(info.value)
    with pytest.raises(OptionError) as info:
        load_scene("avo2", overrides={"model.physics": "discrete"})
    assert "\n" not in str(info.value) and "province" in str(info.value)


def test_the_built_in_discrete2_scene_is_the_two_pipe_survey_it_describes():
    """24 pings 8.23 m apart over 200 m of water, no motion, sediment as fast as water; pipe A 5° to the
    track crossing 330-350 m to starboard 1 m deep, B -12° crossing 420-460 m to port 1.5 m deep."""
    sc = load_scene("discrete2")
    assert sc.model.physics == "discrete" and sc.discrete.tx_pattern == "centre"
    assert sc.survey.pings == 24 and sc.survey.step_m == pytest.approx(8.23, abs=0.005)
    assert sc.seabed.depth_m == 200.0 and sc.seabed.sound_speed_ratio == 1.0 and sc.motion == type(sc.motion)()
    assert sc.discrete.seabed_density_per_m2 == 0.06 and sc.discrete.seabed_depth_m == 0.05
    assert sc.discrete.pipe_spacing_m == 0.1
    ds = simulate(sc, pings=[0, 23])
    y, z, sz = (ds[f"truth_target_{k}"].values for k in ("y", "z", "seabed_z"))
    assert 330.0 <= y[0, 0] < y[1, 0] <= 350.0 and -460.5 <= y[1, 1] < y[0, 1] <= -420.0
    assert np.allclose(z - sz, [[1.0, 1.5], [1.0, 1.5]]) and np.allclose(ds.truth_target_angle.values, [5.0, -12.0])


def test_keys_the_discrete_physics_does_not_use_are_named_in_one_warning(caplog):
    """Set away from their defaults, a pipe's roughness, an interface's per_cell and depth_spread_m and
    model.line_spacing_m are named in one warning when the scene is simulated under the discrete physics; at
    their defaults nothing is said."""
    from clbeam.sim.simulator import unused_under_discrete

    plain = load_scene("discrete2")
    assert [t.roughness for t in plain.targets if isinstance(t, LineTarget)] and unused_under_discrete(plain) == []
    name = next(t.name for t in plain.targets if isinstance(t, LineTarget))
    scene = load_scene("discrete2", overrides={"seabed.scattering.per_cell": 2.0, "model.line_spacing_m": 0.05})
    rough = [dataclasses.replace(t, roughness=1.5) if t.name == name else t for t in scene.targets]
    scene = dataclasses.replace(scene, targets=type(scene.targets)(rough))
    expected = [f"target '{name}' roughness", "seabed.scattering.per_cell", "model.line_spacing_m"]
    assert unused_under_discrete(scene) == expected
    with caplog.at_level(logging.WARNING, logger="clbeam.sim.simulator"):
        Simulator(scene, seed=0)
    warned = [r.getMessage() for r in caplog.records if "does not use" in r.getMessage()]
    assert len(warned) == 1 and all(key in warned[0] for key in expected) and "\n" not in warned[0]


def test_a_discrete_pipes_image_is_its_crossing_not_a_specular_point():
    """Under the discrete physics a pipe's echoes are incoherent, so the truth's image of a line is where its
    crossing images (with the sediment as fast as the water, the crossing itself), while the specular model's
    twin images its nearest point, ``y sin^2 a`` nearer the track (closed form, straight rays, flat seabed)."""
    disc = load_scene("discrete2")
    spec = dataclasses.replace(disc, model=dataclasses.replace(disc.model, physics="specular"), discrete=None)
    for scene, specular in ((disc, False), (spec, True)):
        sim = Simulator(scene, seed=0)
        t = sim.truth(sim.geometry(3))["target"]
        lines = [k for k, tg in enumerate(scene.targets) if isinstance(tg, LineTarget) and np.isfinite(t["y"][k])]
        assert lines
        for k in lines:
            a = math.radians(scene.targets[k].angle_deg)
            shift = abs(t["y"][k]) * math.sin(a) ** 2
            if specular:
                assert abs(abs(t["y"][k]) - abs(t["image_y"][k]) - shift) < 0.05 * shift + 0.2
            else:
                assert abs(t["image_y"][k] - t["y"][k]) < 1e-6 and abs(t["image_z"][k] - t["z"][k]) < 1e-6
