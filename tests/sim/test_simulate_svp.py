"""The simulator propagates through a sound-speed profile (``[water]``).

The checks use values computed here independently of ``clbeam.imaging.raytrace``:
eigenrays by ``scipy.optimize.brentq`` on Snell's ray parameter with the
offset and time integrals ``X(p) = ∫ p c / sqrt(1 - p² c²) dz`` and
``T(p) = ∫ dz / (c sqrt(1 - p² c²))`` done by ``scipy.integrate.quad``, the
isospeed simulator (straight rays, and its own Snell model for buried
points), and the compressed echoes themselves.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np
import pytest
import scipy.fft
import scipy.integrate
import scipy.optimize
import xarray as xr

from clbeam.errors import OptionError
from clbeam.model.svp import SoundSpeedProfile, holland_line1_profile
from clbeam.sim.rays import ray_legs, seabed_ray_legs, unfold
from clbeam.sim.simulator import (
    Simulator,
    Water,
    list_scenes,
    load_scene,
    scene_from_mapping,
    simulate,
    write,
)

FS = 40000.0
PAPER_DEPTHS = [-5.0, 3.0, 225.0, 2000.0]
PAPER_SPEEDS = [1522.0, 1522.0, 1490.0, 1490.0]
SEABED_Z = 225.0
RATIO = 0.98
SEDIMENT = RATIO * 1490.0


# ---------------------------------------------------------------------------
# Independent eigenrays (piecewise-linear profile, quadrature + brentq)
# ---------------------------------------------------------------------------
def speed(z, sediment: float | None = None, seabed_z: float = SEABED_Z):
    """The paper's profile (constant beyond its ends), and the sediment below the seabed."""
    c = np.interp(z, PAPER_DEPTHS, PAPER_SPEEDS)
    if sediment is not None:
        c = np.where(np.asarray(z) > seabed_z, sediment, c)
    return c


def _integrals(p: float, z0: float, z1: float, sediment, seabed_z: float = SEABED_Z):
    """``X(p)`` and ``T(p)`` from ``z0`` down to ``z1``, by quadrature over
    the pieces between the profile's kinks and the seabed."""
    cuts = [z0] + sorted({k for k in (3.0, SEABED_Z, seabed_z) if z0 < k < z1}) + [z1]

    def cos(z):
        s = p * speed(z, sediment)
        return math.sqrt(1.0 - s * s)

    x = t = 0.0
    for a, b in zip(cuts, cuts[1:]):
        # the sediment starts just below the seabed: evaluate inside the piece
        mid = 0.5 * (a + b)

        def c_piece(z, m=mid):
            return speed(z, sediment, seabed_z) if z != seabed_z else speed(m, sediment, seabed_z)

        kw = dict(epsrel=1e-12, limit=200)
        x += scipy.integrate.quad(lambda z: p * c_piece(z) / math.sqrt(1 - (p * c_piece(z)) ** 2), a, b,
                                  epsabs=1e-12, **kw)[0]
        t += scipy.integrate.quad(lambda z: 1.0 / (c_piece(z) * math.sqrt(1 - (p * c_piece(z)) ** 2)), a, b,
                                  epsabs=1e-15, **kw)[0]
    return x, t


def eigen_ray(y: float, legs, sediment: float | None = None, seabed_z: float = SEABED_Z) -> tuple[float, float]:
    """``(time, p)`` of the ray with horizontal offset ``|y|`` over the depth
    intervals ``legs`` (``[(z0, z1), ...]``, each ``z0 < z1``, traversed with
    the same ray parameter: a direct ray, or the legs of a reflected one)."""
    y = abs(y)

    def sums(q):
        xt = [_integrals(q, a, b, sediment, seabed_z) for a, b in legs]
        return sum(v[0] for v in xt), sum(v[1] for v in xt)

    if y == 0.0:
        return sums(0.0)[1], 0.0
    zz = np.concatenate([np.linspace(a, b, 2001) for a, b in legs])
    c_max = float(np.max(speed(zz, sediment, seabed_z)))
    p_hi = next(q for q in ((1.0 - 10.0 ** -k) / c_max for k in range(2, 14)) if sums(q)[0] > y)
    p = scipy.optimize.brentq(lambda q: sums(q)[0] - y, 0.0, p_hi, xtol=1e-22, rtol=1e-15, maxiter=200)
    x, t = sums(p)
    return t + p * (y - x), p          # stationary in p


def eigen_time(y: float, z0: float, z1: float, sediment: float | None = None) -> float:
    """One-way time (s) of the direct ray from depth ``z0`` to ``(y, z1)``, ``z1 > z0``."""
    return eigen_ray(y, [(z0, z1)], sediment)[0]


def expected_two_way(g, target_xyz, sediment=None) -> np.ndarray:
    """Two-way times (s) source -> target -> each element, independently."""
    tx, ty, tz = target_xyz

    def one_way(end):
        return eigen_time(math.hypot(tx - end[0], ty - end[1]), float(end[2]), tz, sediment)

    src = one_way(g.source)
    return np.array([src + one_way(e) for e in g.elements])


def compressed_peak_samples(x: np.ndarray, replica: np.ndarray, expected: float) -> float:
    """Sub-sample lag (samples) of the matched-filter maximum of channel ``x``
    near ``expected``: the envelope's maximum picks the carrier cycle, the
    real part's maximum (64× band-limited upsampling, parabola) the lag."""
    k0 = int(expected) - 2048
    seg = np.asarray(x[k0:k0 + 8192], dtype=np.float64)
    n, up = 16384, 64
    spec = scipy.fft.rfft(seg, n) * np.conj(scipy.fft.rfft(replica, n))
    padded = np.zeros(n * up // 2 + 1, dtype=complex)
    padded[:spec.size] = spec
    corr = scipy.fft.irfft(padded, n * up) * up          # band-limited interpolation of the correlation
    analytic = np.zeros(n * up, dtype=complex)
    analytic[:spec.size] = 2 * spec
    analytic[0] = spec[0]
    envelope = np.abs(scipy.fft.ifft(analytic) * up)
    window = slice(1024 * up, 3072 * up)                 # lags within ±1024 samples of the expectation
    i_env = window.start + int(np.argmax(envelope[window]))
    half_cycle = int(up * FS / 5500.0 / 2)
    lo = i_env - half_cycle
    i = lo + int(np.argmax(corr[lo:i_env + half_cycle]))
    a, b, c = corr[i - 1], corr[i], corr[i + 1]
    frac = 0.5 * (a - c) / (a - 2 * b + c)
    return k0 + (i + frac) / up


# ---------------------------------------------------------------------------
# Scenes
# ---------------------------------------------------------------------------
def iso_scene(**over):
    """Isospeed 1500 m/s: a point in the water, one on the seabed off the
    image plane, a pipe in the water at 10° to the track, a rough seabed
    with its specular echo and multiple, 1.5° of roll and some heave."""
    o = {"seabed": {"depth_m": 120.0, "specular": True, "multiple": True,
                    "scattering": {"strength_db": -30.0, "per_cell": 0.5}},
         "motion.roll_mean_deg": 1.5, "motion.heave_amplitude_m": 0.3, "motion.heave_period_s": 1e9,
         "target": [{"kind": "point", "name": "W", "x_m": 0.0, "y_m": 80.0, "z_m": 60.0},
                    {"kind": "point", "name": "S", "x_m": 3.0, "y_m": -150.0, "z_m": 115.0, "amplitude_m": 2.0},
                    {"kind": "line", "name": "L", "x_m": 0.0, "y_m": -60.0, "angle_deg": 10.0, "z_m": 90.0,
                     "burial_m": None}]}
    o.update(over)
    return load_scene("point", max_range_m=300.0, snr_db=None, overrides=o)


def with_water(scene, depths, speeds):
    water = Water(tuple(depths), tuple(speeds))
    return dataclasses.replace(scene, water=water, sound_speed_m_s=water.transducer_speed_m_s)


def paper_scene(**over):
    """svp1km with only the 1 km target (and no seabed scattering), rolled 4°, heaved 0.4 m."""
    o = {"seabed.scattering": None, "motion.roll_mean_deg": 4.0, "motion.heave_amplitude_m": 0.4 / math.sin(2.0),
         "motion.heave_period_s": 1e9,
         "target": [{"kind": "point", "name": "P1000", "x_m": 0.0, "y_m": 1000.0, "z_m": 225.0}]}
    o.update(over)
    return load_scene("svp1km", overrides=o)


# ---------------------------------------------------------------------------
# A constant profile is the isospeed simulation
# ---------------------------------------------------------------------------
def test_constant_profile_equals_isospeed():
    iso = iso_scene()
    svp = with_water(iso, [0.0], [1500.0])
    a, b = simulate(iso), simulate(svp)
    assert a.samples.shape == b.samples.shape
    x, y = a.samples.values.astype(np.float64), b.samples.values.astype(np.float64)
    # equal but for the last bits of the delays, which can move a pair's
    # delay filter to the neighbouring 1/1024-sample phase (1e-3 of that
    # pair's echo; measured 1e-6 of the largest sample, 0 without the pipe)
    assert np.max(np.abs(x - y)) <= 1e-5 * np.max(np.abs(x))
    # the ray-traced delays are the straight ones to rounding
    sa, sb = Simulator(iso), Simulator(svp)
    g = sa.geometry(0)
    for ea, eb in zip(sa.echoes(g), sb.echoes(g)):
        assert ea.label == eb.label and len(ea) == len(eb)
        straight = (np.linalg.norm(ea.pos[:, None, :] - g.elements[None], axis=2) + ea.src_leg[:, None]) / 1500.0
        assert np.max(np.abs(eb.times_s - straight)) < 1e-12, ea.label
        np.testing.assert_allclose(eb.amp, ea.amp, rtol=1e-12, atol=0)
    # the truth too: where an imager with the (constant) profile shows the
    # echoes is where the straight-ray imager shows them
    for k in ("image_y", "image_z", "u", "x", "y", "z", "angle", "seabed_z"):
        np.testing.assert_allclose(b[f"truth_target_{k}"].values, a[f"truth_target_{k}"].values, rtol=0, atol=1e-9)
    assert float(b.sound_speed[0]) == 1500.0


def test_constant_profile_buried_times_match_the_isospeed_snell_model():
    """Through a constant profile with the sediment below a flat (and a
    sloped) seabed, buried points' times equal the isospeed simulator's
    own two-medium Snell model (``refracted_path`` plus its first-order
    tilt across the array, good to 20 ns)."""
    for slope in (0.0, 1.0):
        iso = load_scene("point", max_range_m=700.0, snr_db=None, overrides={
            "seabed": {"depth_m": 230.0, "specular": True, "multiple": False, "slope_across_deg": slope},
            "subbottom": {"depth_below_seabed_m": 15.0},
            "target": [{"kind": "point", "name": "B", "x_m": 2.0, "y_m": 600.0, "burial_m": 1.5}]})
        svp = with_water(iso, [0.0], [1500.0])
        a, b = Simulator(iso), Simulator(svp)
        g = a.geometry(0)
        ea = {e.label: e for e in a.echoes(g)}
        eb = {e.label: e for e in b.echoes(g)}
        assert set(ea) == set(eb) == {"B", "seabed", "subbottom"}
        for label in ("B", "seabed", "subbottom"):
            x, y = ea[label], eb[label]
            d = np.linalg.norm(x.pos[:, None, :] - g.elements[None], axis=2)
            t_iso = (d + x.src_leg[:, None]) / a.c + x.extra_s[:, None]
            if x.rx_tilt is not None:
                t_iso -= x.rx_tilt @ (g.elements - g.centre).T / a.c
            assert np.max(np.abs(y.times_s - t_iso)) < 20e-9, (slope, label)
        np.testing.assert_allclose(eb["B"].b_s, ea["B"].b_s, rtol=1e-6)
        np.testing.assert_allclose(eb["B"].amp, ea["B"].amp, rtol=1e-3)


# ---------------------------------------------------------------------------
# The paper's profile: echoes at the independently computed eigenray times
# ---------------------------------------------------------------------------
def test_paper_profile_point_echo_arrives_at_the_eigenray_time_on_every_channel():
    scene = paper_scene()
    sim = Simulator(scene)
    g = sim.geometry(0)
    assert abs(g.heave_m - 0.4) < 1e-9 and np.ptp(g.elements[:, 2]) > 0.2   # rolled and heaved positions
    expected = expected_two_way(g, (0.0, 1000.0, 225.0))
    echo = next(e for e in sim.echoes(g) if e.label == "P1000")
    # the raw delays: to 0.1 ns (1/250 000 sample)
    assert np.max(np.abs(echo.times_s[0] - expected)) < 1e-10
    # isospeed straight rays at the transducers' speed would be milliseconds off
    target = np.array([0.0, 1000.0, 225.0])
    straight = (np.linalg.norm(g.source - target) + np.linalg.norm(g.elements - target, axis=1)) / 1522.0
    assert np.min(np.abs(straight - expected)) > 1e-3
    # the samples: the compressed echo peaks there within 1/200 sample
    # (measured: 5e-4; the delay filters are exact to 0.5 % in the band)
    samples = sim.ping(0)
    peaks = np.array([compressed_peak_samples(samples[n], sim.replica, expected[n] * FS)
                      for n in range(0, 64, 3)])
    err = peaks - expected[::3] * FS
    assert np.max(np.abs(err)) < 0.005, err
    # and the truth: an imager with the profile shows it where it is
    tr = sim.truth(g)["target"]
    assert abs(tr["image_y"][0] - 1000.0) < 1e-6 and abs(tr["image_z"][0] - 225.0) < 1e-6


def test_buried_point_below_a_flat_seabed_follows_the_sediment_ray():
    """1 m below the seabed at 500 m: water profile then the sediment
    (0.98 × 1490 m/s) below the seabed, Snell at the jump."""
    scene = paper_scene(target=[{"kind": "point", "name": "B", "x_m": 0.0, "y_m": 500.0, "burial_m": 1.0}])
    sim = Simulator(scene)
    g = sim.geometry(0)
    echo = next(e for e in sim.echoes(g) if e.label == "B")
    expected = expected_two_way(g, (0.0, 500.0, 226.0), sediment=SEDIMENT)
    assert np.max(np.abs(echo.times_s[0] - expected)) < 1e-10
    # water all the way would be earlier by about 1 m × (1/1460 - 1/1490) × 2 / cos
    water = expected_two_way(g, (0.0, 500.0, 226.0))
    assert np.min(expected - water) > 5e-7
    # attenuation over the in-sediment legs from the source and from the
    # array centre, each 1 m / cos θ_s with sin θ_s = p c_s (Snell)
    path = 0.0
    for end in (g.source, g.centre):
        _, p = eigen_ray(math.hypot(end[0], 500.0 - end[1]), [(float(end[2]), 226.0)], SEDIMENT)
        path += 1.0 / math.sqrt(1.0 - (p * SEDIMENT) ** 2)
    assert echo.b_s[0] / sim.alpha_np == pytest.approx(path, rel=1e-7)


def test_buried_point_below_a_sloped_seabed_follows_the_locally_flat_sediment_ray():
    """2° across-track slope: the point 1 m below the seabed at 500 m, whose
    seabed lies 17.5 m deeper than at nadir; the interface is taken as flat
    at that depth (as in the isospeed model), the sediment at 0.98 times the
    water's speed there."""
    z_sb = SEABED_Z + math.tan(math.radians(2.0)) * 500.0
    scene = paper_scene(**{"seabed.slope_across_deg": 2.0,
                           "target": [{"kind": "point", "name": "B", "x_m": 0.0, "y_m": 500.0, "burial_m": 1.0}]})
    sim = Simulator(scene)
    assert sim.svp_sediment is None                                   # not the flat-seabed profile
    g = sim.geometry(0)
    echo = next(e for e in sim.echoes(g) if e.label == "B")
    c_s = RATIO * float(speed(z_sb))

    def one_way(end):
        return eigen_ray(math.hypot(end[0], 500.0 - end[1]), [(float(end[2]), z_sb + 1.0)], c_s, z_sb)[0]

    expected = one_way(g.source) + np.array([one_way(e) for e in g.elements])
    assert np.max(np.abs(echo.times_s[0] - expected)) < 1e-10
    tr = sim.truth(g)["target"]
    assert abs(tr["image_y"][0] - 500.0) < 1e-6 and abs(tr["image_z"][0] - (z_sb + 1.0)) < 1e-6


def test_sloped_seabed_legs_equal_the_flat_sediment_profile_where_flat():
    """The per-point locally flat seabed (Newton on the crossing) is the
    eigenray of ``with_sediment`` when every point has the same seabed depth."""
    water = holland_line1_profile()
    sed = SoundSpeedProfile.with_sediment(water, SEABED_Z, SEDIMENT)
    rng = np.random.default_rng(3)
    pos = np.stack([rng.uniform(-50, 50, 300), rng.uniform(-1100, 1100, 300), SEABED_Z + rng.uniform(0.01, 30, 300)],
                   axis=1)
    ends = np.array([[0.0, -1.7, -0.1], [0.0, 0.3, 0.05], [1.0, 1.7, 0.12]])
    a = ray_legs(sed, ends, pos)
    b = seabed_ray_legs(water, ends, pos, np.full(300, SEABED_Z), np.full(300, SEDIMENT))
    assert np.all(np.isfinite(a["time_s"]))
    np.testing.assert_allclose(b["time_s"], a["time_s"], rtol=0, atol=1e-10)
    np.testing.assert_allclose(b["pos_dir"], a["pos_dir"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(b["end_dir"], a["end_dir"], rtol=0, atol=1e-6)


def test_nadir_specular_echoes_follow_the_vertical_travel_time():
    """The seabed echo and the first multiple: unfolded through the profile,
    the nadir two-way times are 2 ∫ dz / c (not 2 h / c(0))."""
    scene = load_scene("svp1km", overrides={"seabed.scattering": None, "seabed.multiple": True,
                                            "subbottom": {"depth_below_seabed_m": 10.0}, "target": []})
    sim = Simulator(scene)
    g = sim.geometry(0)
    sets = {e.label: e for e in sim.echoes(g)}
    t_w = eigen_time(0.0, 0.0, SEABED_Z)                              # transducers -> seabed
    t_surf = eigen_time(0.0, -5.0, 0.0)                               # surface -> transducers
    t_sed = 10.0 / SEDIMENT
    centre = np.argmin(np.abs(g.elements[:, 1]))                      # 0.03 m off nadir
    for label, t in (("seabed", 2 * t_w), ("subbottom", 2 * (t_w + t_sed)),
                     ("multiple", 4 * t_w + 2 * t_surf), ("multiple-doublet", 4 * t_w + 2 * t_surf + 2 * t_sed)):
        assert abs(sets[label].times_s[0, centre] - t) < 2e-9, label
    assert abs(2 * t_w - 2 * 225.0 / 1522.0) > 2e-3                   # 3 ms from the isospeed time
    # off nadir (the outer elements, 1.76 m across): one ray parameter down
    # to the seabed and back up, and for the multiple also up to the surface
    # and down again
    for n in (0, 63):
        e = g.elements[n]
        y = e[1] - g.source[1]
        down, up = (float(g.source[2]), SEABED_Z), (float(e[2]), SEABED_Z)
        t_seabed = eigen_ray(y, [down, up])[0]
        t_multiple = eigen_ray(y, [down, (-5.0, SEABED_Z), (-5.0, SEABED_Z), up])[0]
        assert abs(sets["seabed"].times_s[0, n] - t_seabed) < 1e-9
        assert abs(sets["multiple"].times_s[0, n] - t_multiple) < 1e-9
    unf, s_last, z_last = unfold(holland_line1_profile(SEDIMENT), [SEABED_Z])
    assert s_last == z_last == SEABED_Z
    np.testing.assert_allclose(unf.speed([100.0, 2 * SEABED_Z - 100.0]), [speed(100.0)] * 2, rtol=1e-15)


# ---------------------------------------------------------------------------
# The file, the scene, the errors
# ---------------------------------------------------------------------------
def test_svp_variables_are_written_and_read(tmp_path):
    ds = simulate(paper_scene(**{"record.max_range_m": 300.0, "target": []}))
    assert ds.svp_depth.dims == ("svp",) and ds.svp_speed.dims == ("svp",)
    np.testing.assert_array_equal(ds.svp_depth.values, PAPER_DEPTHS)
    np.testing.assert_array_equal(ds.svp_speed.values, PAPER_SPEEDS)
    assert ds.svp_depth.attrs["units"] == "m" and ds.svp_speed.attrs["units"] == "m/s"
    assert ds.svp_depth.attrs["long_name"] and ds.svp_speed.attrs["long_name"]
    assert float(ds.sound_speed[0]) == 1522.0                       # the speed at the transducers
    path = write(ds, tmp_path / "svp.nc")
    with xr.open_dataset(path) as back:
        np.testing.assert_array_equal(back.svp_speed.values, PAPER_SPEEDS)
    from clbeam.io.pingfile import PingFile

    with PingFile(path) as f:
        assert f.ping(0).svp == holland_line1_profile()
    # isospeed files carry no profile and their scene_json no [water]
    iso = simulate("point")
    assert "svp_depth" not in iso and "svp_speed" not in iso
    assert '"water"' not in iso.attrs["scene_json"]
    # the scene survives its round trip through the file's plain data
    assert load_scene(paper_scene()).water == paper_scene().water


def test_svp1km_scene():
    assert "svp1km" in list_scenes()
    scene = load_scene("svp1km")
    assert scene.water.profile() == holland_line1_profile()
    assert scene.sound_speed_m_s == 1522.0 and scene.seabed.depth_m - scene.sonar.draft_m == SEABED_Z
    assert scene.motion.roll_mean_deg == 0 and scene.survey.pings == 1
    sim = Simulator(scene)
    assert {t.name: (t.y_m, t.z_m) for t in scene.targets} == {"P500": (500.0, 225.0), "P1000": (1000.0, 225.0)}
    # the whole 1 km echo is recorded
    t_1km = 2 * eigen_time(1000.0, 0.0, 225.0)
    assert sim.n_samples / FS > t_1km + scene.sonar.pulse_duration_s
    tr = sim.truth(sim.geometry(0))["target"]
    np.testing.assert_allclose(tr["image_y"], [500.0, 1000.0])
    np.testing.assert_allclose(tr["image_z"], [225.0, 225.0])


def test_unreachable_scatterers_are_dropped_and_logged(caplog):
    """Speed rising fast with depth: a shallow point far out is in the shadow
    of direct rays; it is left out, never given a wrong time."""
    scene = load_scene("point", max_range_m=1200.0, snr_db=None, overrides={
        "sound_speed_m_s": None, "water": {"svp_depth_m": [0.0, 200.0], "svp_speed_m_s": [1450.0, 1600.0]},
        "target": [{"kind": "point", "name": "far", "x_m": 0.0, "y_m": 1000.0, "z_m": 70.0},
                   {"kind": "point", "name": "near", "x_m": 0.0, "y_m": 100.0, "z_m": 70.0}]})
    sim = Simulator(scene)
    with caplog.at_level(logging.INFO, logger="clbeam.sim"):
        labels = [e.label for e in sim.echoes(sim.geometry(0))]
    assert labels == ["near"]
    assert any("far" in r.getMessage() and "no direct ray" in r.getMessage() for r in caplog.records)
    assert np.all(np.isfinite(sim.ping(0)))


BAD_WATER = [
    ({"svp_depth_m": [0.0, 100.0], "svp_speed_m_s": [1500.0]}, "has 2 depths but"),
    ({"svp_depth_m": [0.0, 100.0, 50.0], "svp_speed_m_s": [1500.0, 1490.0, 1480.0]}, "must increase strictly"),
    ({"svp_depth_m": [0.0, 0.0], "svp_speed_m_s": [1500.0, 1490.0]}, "must increase strictly"),
    ({"svp_depth_m": [0.0, 100.0], "svp_speed_m_s": [1500.0, 1800.0]}, "within 1300-1700 m/s"),
    ({"svp_depth_m": [], "svp_speed_m_s": []}, "at least one value"),
    ({"svp_depth_m": [0.0]}, "at least one value"),
    ({"svp_depth_m": [0.0, "deep"], "svp_speed_m_s": [1500.0, 1490.0]}, "must be a list of numbers"),
    ({"svp_depth_m": 10.0, "svp_speed_m_s": [1500.0]}, "must be a list of numbers"),
    ({"svp_depth_m": [0.0, float("nan")], "svp_speed_m_s": [1500.0, 1490.0]}, "must be finite"),
    ({"svp_depth_m": [0.0], "svp_speed_m_s": [1500.0], "svp_depths": [1.0]}, "unknown scene key 'water.svp_depths'"),
]


@pytest.mark.parametrize("water, message", BAD_WATER)
def test_bad_svp_tables_give_one_line_errors(water, message):
    with pytest.raises(OptionError) as exc:
        scene_from_mapping({"water": water})
    text = str(exc.value)
    assert message in text and "\n" not in text


def test_sound_speed_must_agree_with_the_profile():
    water = {"svp_depth_m": PAPER_DEPTHS, "svp_speed_m_s": PAPER_SPEEDS}
    assert scene_from_mapping({"water": water}).sound_speed_m_s == 1522.0
    assert scene_from_mapping({"water": water, "sound_speed_m_s": 1522.0}).sound_speed_m_s == 1522.0
    with pytest.raises(OptionError) as exc:
        scene_from_mapping({"water": water, "sound_speed_m_s": 1500.0})
    assert "profile's speed at the transducers" in str(exc.value) and "\n" not in str(exc.value)
    with pytest.raises(OptionError, match="must be a table"):
        scene_from_mapping({"water": 3})
