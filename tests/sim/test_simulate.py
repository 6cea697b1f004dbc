"""The scene simulator (clbeam.sim.simulator) against closed forms and the paper.

Every echo is measured the way an independent observer would: correlate a
channel with the replica (scipy.signal.correlate), take the envelope of its
analytic signal and fit the peak; or divide the channel's spectrum by the
replica's.  The expected values come from geometry written out here (element
positions rotated by hand, Fermat's principle for refracted paths, the
stationary-phase integral of a line), not from the simulator's helpers.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal
import xarray as xr
from scipy.optimize import minimize_scalar

from clbeam.errors import ClbeamError, OptionError
from clbeam.io.pingfile import PingFile
from clbeam.model.pulse import lfm_replica
from clbeam.sim.simulator import (
    Simulator,
    ka_sin_phi,
    list_scenes,
    load_scene,
    nadir_angle_deg,
    simulate,
    transmit_beamwidth_deg,
    transmit_far_field_m,
    two_way_sediment_path_m,
    write,
)

C = 1500.0
FS = 40000.0
REPLICA = lfm_replica(f0_hz=2000.0, f1_hz=9000.0, duration_s=0.08, sample_rate_hz=FS)

# Timing tolerance of a single echo: the fractional-delay filter's complex
# error is at most 5e-3 in the band, i.e. a phase error of 5e-3 rad, or
# 0.15 us at the 5.5 kHz band centre; the delay table is quantised to 1/1024
# sample (12 ns); the peak fit on a 16x upsampled envelope adds a few ns.
TIME_TOL_S = 0.2e-6
# Amplitude tolerance: the same 5e-3 filter error, doubled for the fit.
AMP_TOL = 1e-2


def element_positions(n=64, width=3.528) -> np.ndarray:
    """Receive elements across-track, as the SBP29 array (independent copy)."""
    pos = np.zeros((n, 3))
    pos[:, 1] = (np.arange(n) - (n - 1) / 2) * width / n
    return pos


def echo_peak(channel: np.ndarray, *, near_s: float | None = None, window_s: float = 2e-3):
    """Arrival time (s) and amplitude of the strongest compressed echo.

    The channel is correlated with the replica (normalised by its energy so
    that an echo ``a · replica`` peaks at ``a``); the envelope of the analytic
    signal is upsampled 16x around its maximum and a parabola through the
    three top samples gives the peak.
    """
    y = scipy.signal.correlate(channel.astype(np.float64), REPLICA, mode="full")[REPLICA.size - 1:]
    y /= REPLICA @ REPLICA
    env = np.abs(scipy.signal.hilbert(y))
    if near_s is not None:
        lo, hi = int((near_s - window_s) * FS), int((near_s + window_s) * FS)
        k = lo + int(np.argmax(env[lo:hi]))
    else:
        k = int(np.argmax(env))
    seg = scipy.signal.hilbert(y)[k - 32:k + 32]
    up = np.abs(scipy.signal.resample(seg, 64 * 16))
    j = int(np.argmax(up))
    d = 0.5 * (up[j - 1] - up[j + 1]) / (up[j - 1] - 2 * up[j] + up[j + 1])
    peak = up[j] - 0.25 * (up[j - 1] - up[j + 1]) * d
    return ((k - 32) + (j + d) / 16) / FS, peak


def spectral_delay(channel: np.ndarray, near_s: float, f_lo_hz: float, f_hi_hz: float) -> float:
    """Group delay (s) of an echo from the phase slope of its transfer function
    ``Y(f) / X(f)`` over ``f_lo..f_hi`` (a band where the echo's phase is
    linear), after removing ``near_s`` so that the phase unwraps."""
    n = channel.size
    f = np.fft.rfftfreq(n, 1 / FS)
    m = (f > f_lo_hz) & (f < f_hi_hz)
    ratio = np.fft.rfft(channel.astype(np.float64), n)[m] / np.fft.rfft(REPLICA, n)[m]
    phase = np.unwrap(np.angle(ratio * np.exp(2j * np.pi * f[m] * near_s)))
    return near_s - np.polyfit(f[m], phase, 1)[0] / (2 * np.pi)


def spectrum_ratio(a: np.ndarray, b: np.ndarray, freqs_hz) -> np.ndarray:
    """``|A(f)| / |B(f)|`` of two channels at the FFT bins nearest ``freqs_hz``."""
    n = max(a.size, b.size)
    fa, fb = np.fft.rfft(a.astype(np.float64), n), np.fft.rfft(b.astype(np.float64), n)
    bins = np.rint(np.asarray(freqs_hz) * n / FS).astype(int)
    return np.abs(fa[bins]) / np.abs(fb[bins])


def point_scene(**overrides):
    """The built-in point scene with dotted-key overrides."""
    return load_scene("point", overrides=overrides)


# -- point scatterer: travel time and spreading, channel by channel ------------
def test_point_echo_arrives_at_closed_form_time_with_spherical_spreading_on_every_channel():
    ds = simulate("point")
    r = np.array([0.0, 150.0, 200.0])  # the scene's target, source at the array centre
    el = element_positions()
    for n in range(64):
        t, a = echo_peak(ds.samples.values[0, n])
        d_src, d_rx = np.linalg.norm(r), np.linalg.norm(r - el[n])
        assert t == pytest.approx((d_src + d_rx) / C, abs=TIME_TOL_S), n
        assert a == pytest.approx(1.0 / (d_src * d_rx), rel=AMP_TOL), n


def test_positive_roll_puts_starboard_elements_deeper_so_they_hear_a_target_below_sooner():
    roll = 5.0
    ds = simulate(point_scene(**{"motion.roll_mean_deg": roll,
                                 "target": [{"kind": "point", "name": "below", "z_m": 200.0}]}))
    assert float(ds["roll"][0]) == pytest.approx(roll)
    el = element_positions()
    phi = math.radians(roll)
    # rotation about x by hand: starboard (y > 0) goes down (z > 0)
    el_earth = np.stack([el[:, 0], el[:, 1] * math.cos(phi), el[:, 1] * math.sin(phi)], axis=1)
    assert el_earth[-1, 2] > 0 > el_earth[0, 2]
    r = np.array([0.0, 0.0, 200.0])
    times = []
    for n in (0, 10, 31, 52, 63):
        t, _ = echo_peak(ds.samples.values[0, n])
        times.append(t)
        assert t == pytest.approx((np.linalg.norm(r) + np.linalg.norm(r - el_earth[n])) / C, abs=TIME_TOL_S), n
    # the starboard end is 3.47 m · sin 5° = 0.30 m deeper than the port end: 0.2 ms sooner
    assert times[0] - times[-1] == pytest.approx(2 * el[-1, 1] * math.sin(phi) / C, rel=0.01)


def test_heave_up_delays_the_echo_by_twice_the_heave():
    heave = 0.8
    base = point_scene(**{"target": [{"kind": "point", "name": "below", "z_m": 200.0}]})
    moved = point_scene(**{"target": [{"kind": "point", "name": "below", "z_m": 200.0}],
                           "motion.heave_amplitude_m": heave, "motion.heave_period_s": 4.0})
    ds0, ds1 = simulate(base), simulate(moved)
    h = float(ds1.heave[0])  # sin(2 rad) of the amplitude at t = 0
    assert h == pytest.approx(heave * math.sin(2.0))
    t0, _ = echo_peak(ds0.samples.values[0, 31])
    t1, _ = echo_peak(ds1.samples.values[0, 31])
    assert t1 - t0 == pytest.approx(2 * h / C, abs=2 * TIME_TOL_S)


# -- transmit beam ---------------------------------------------------------------
def test_off_axis_echo_spectrum_follows_the_line_aperture_beam_pattern():
    """A target 5° ahead of the beam axis: its spectrum over the on-axis one is
    ``sinc(L f u / c)`` (L = 3.5 m) times the spreading ratio."""
    rng_m, elev = 250.0, math.radians(40.0)
    u = math.sin(math.radians(5.0))
    on = np.array([0.0, rng_m * math.sin(elev), rng_m * math.cos(elev)])
    off = np.array([rng_m * u, on[1] * math.sqrt(1 - u * u), on[2] * math.sqrt(1 - u * u)])
    ds_on = simulate(point_scene(target=[{"kind": "point", "name": "on", "x_m": 0.0, "y_m": on[1], "z_m": on[2]}]))
    ds_off = simulate(point_scene(target=[{"kind": "point", "name": "off", "x_m": off[0], "y_m": off[1], "z_m": off[2]}]))
    el = element_positions()
    freqs = np.array([2500.0, 4000.0, 5500.0, 7000.0, 8500.0])
    n = 40
    spread = (rng_m * np.linalg.norm(on - el[n])) / (rng_m * np.linalg.norm(off - el[n]))
    expected = np.abs(np.sinc(3.5 * freqs * u / C)) * spread
    got = spectrum_ratio(ds_off.samples.values[0, n], ds_on.samples.values[0, n], freqs)
    # the 0.5 % filter error of each echo, both ways
    np.testing.assert_allclose(got, expected, rtol=AMP_TOL)
    # the beam's boxcar (0.2 ms long here, too flat-topped for a peak fit) is
    # centred on the travel time from the column's centre: the phase is linear
    # with that delay wherever the sinc is positive (below 4.9 kHz here)
    tau = (np.linalg.norm(off) + np.linalg.norm(off - el[n])) / C
    assert spectral_delay(ds_off.samples.values[0, n], tau, 2200.0, 4500.0) == pytest.approx(tau, abs=TIME_TOL_S)


def test_paper_transmit_far_field_and_beamwidth():
    # Holland et al. (2024) §III: far field 74 m at 9 kHz, beamwidth ~6° at 4 kHz
    assert transmit_far_field_m(3.5, 9000.0, C) == pytest.approx(74.0, abs=0.5)
    assert 5.0 < transmit_beamwidth_deg(3.5, 4000.0, C) < 6.5


# -- buried targets: refraction and sediment attenuation --------------------------
def buried_scene(y_m, burial_m, attenuation_db_per_m=0.15):
    return point_scene(seabed={"depth_m": 230.0, "specular": False, "multiple": False,
                               "sound_speed_ratio": 0.98, "attenuation_db_per_m": attenuation_db_per_m,
                               "attenuation_ref_hz": 5000.0},
                       target=[{"kind": "point", "name": "buried", "y_m": y_m, "burial_m": burial_m}])


def fermat_time(horizontal_m, height_m, depth_m, c1=C, c2=0.98 * C):
    """One-way time by minimising over the interface crossing point (Fermat)."""
    res = minimize_scalar(lambda xi: math.hypot(xi, height_m) / c1 + math.hypot(horizontal_m - xi, depth_m) / c2,
                          bounds=(0.0, horizontal_m), method="bounded", options={"xatol": 1e-10})
    return res.fun, res.x


@pytest.mark.parametrize("y_m, burial_m", [(0.0, 10.0), (300.0, 5.0)])
def test_buried_target_spectrum_is_attenuated_by_exp_of_minus_alpha_f_times_sediment_path(y_m, burial_m):
    h = 225.0  # transducers above the seabed
    lossy = simulate(buried_scene(y_m, burial_m))
    lossless = simulate(buried_scene(y_m, burial_m, attenuation_db_per_m=0.0))
    if y_m == 0:
        path = 2 * burial_m
    else:
        _, xi = fermat_time(y_m, h, burial_m)
        path = 2 * math.hypot(y_m - xi, burial_m)  # one-way in-sediment leg, both ways
    freqs = np.array([2500.0, 4000.0, 5000.0, 6500.0, 8500.0])
    alpha = 0.15 / (20 / math.log(10)) * freqs / 5000.0  # Np/m, linear in frequency
    got = spectrum_ratio(lossy.samples.values[0, 31], lossless.samples.values[0, 31], freqs)
    # same geometry both times, so filter errors cancel; what is left is float32
    # storage (1e-7) and the filter's truncated tails (below 1e-4)
    np.testing.assert_allclose(got, np.exp(-alpha * path), rtol=1e-3)
    # the paper's number at 5 kHz: 0.15 dB per metre of two-way path
    assert -20 * math.log10(got[2]) == pytest.approx(0.15 * path, rel=1e-3)


def test_buried_target_arrives_at_the_refracted_travel_time_on_every_channel():
    y_m, burial_m, h = 300.0, 5.0, 225.0
    ds = simulate(buried_scene(y_m, burial_m))
    t_tx, _ = fermat_time(y_m, h, burial_m)
    el = element_positions()
    for n in (0, 20, 31, 44, 63):
        t_rx, _ = fermat_time(y_m - el[n, 1], h, burial_m)
        t, _ = echo_peak(ds.samples.values[0, n])
        # the simulator's refraction delay is exact at the array centre and
        # first-order across the array: the second-order rest is below 20 ns
        assert t == pytest.approx(t_tx + t_rx, abs=TIME_TOL_S), n


def test_paper_sediment_path_at_920_m_with_a_0p98_speed_ratio():
    # Snell at 920 m in 230 m water (225 m below the transducers), axis 1 m deep
    _, xi = fermat_time(920.0, 225.0, 1.0)
    fermat_path = 2 * math.hypot(920.0 - xi, 1.0)
    assert two_way_sediment_path_m(920.0, 225.0, 1.0, 0.98) == pytest.approx(fermat_path, rel=1e-6)
    # refraction into the slower mud steepens the ray: shorter than the straight
    # line's 2 / sin(13.7°) = 8.4 m; the paper's 5 m (0.75 dB) is for ~0.77 m depth
    assert 6.0 < fermat_path < 7.0
    assert two_way_sediment_path_m(920.0, 225.0, 0.77, 0.98) == pytest.approx(5.0, abs=0.05)


# -- line targets ---------------------------------------------------------------------
def test_line_echo_matches_the_stationary_phase_integral_of_a_cylinder():
    """An omnidirectional source (a 1 cm column) and a pipe in the water parallel
    to the track: the spectrum is ``ρ H(f) sqrt(2π / (k (1/Rs + 1/Rr))) / (Rs Rr)``
    with ``H = sqrt(a f / 2c) G(ka)``, ``G(x) = x^1.5 / sqrt(1 + x^3)``."""
    a, refl, y, z = 0.11, 0.8, 150.0, 200.0
    ds = simulate(point_scene(**{"sonar.tx_length_m": 0.01},
                              target=[{"kind": "line", "name": "pipe", "y_m": y, "z_m": z, "burial_m": None,
                                       "radius_m": a, "reflectivity": refl}]))
    el = element_positions()
    freqs = np.array([3000.0, 5000.0, 7000.0])
    k = 2 * np.pi * freqs / C
    ka = k * a
    h = np.sqrt(a * freqs / (2 * C)) * ka ** 1.5 / np.sqrt(1 + ka ** 3)
    for n in (10, 31, 55):
        rs = math.hypot(y, z)
        rr = math.hypot(y - el[n, 1], z)
        expected = refl * h * np.sqrt(2 * np.pi / (k * (1 / rs + 1 / rr))) / (rs * rr)
        got = spectrum_ratio(ds.samples.values[0, n], REPLICA, freqs)
        # stationary phase is exact to O(1/(k R)) ~ 1e-3; the tapered ends of
        # the line and the filter error add below 1 %
        np.testing.assert_allclose(got, expected, rtol=0.02)


def test_paper_ka_sin_phi_spans_0p9_to_4_for_the_pipe():
    # a = 0.11 m over 2-9 kHz at broadside; the paper quotes 0.9 < ka sin φ < 4
    # to one significant figure (4.15 at 9 kHz in water)
    lo, hi = ka_sin_phi(0.11, [2000.0, 9000.0], 90.0, C)
    assert lo == pytest.approx(0.9, abs=0.05)
    assert hi == pytest.approx(4.0, abs=0.2)
    # the pipes of line 1 run within 10° of the track: φ stays near broadside
    lo10, hi10 = ka_sin_phi(0.11, [2000.0, 9000.0], 80.0, C)
    assert 0.85 < lo10 < lo and 3.9 < hi10 < hi


def test_paper_920_m_in_230_m_water_is_76_degrees_from_nadir_in_line4():
    sim = Simulator("line4", pings=[0])
    tr = sim.truth(sim.geometry(0))["target"]
    k = list(t.name for t in sim.scene.targets).index("C")
    assert tr["y"][k] == pytest.approx(920.0, abs=1.0)
    assert nadir_angle_deg(tr["y"][k], 230.0) == pytest.approx(76.0, abs=0.1)
    assert nadir_angle_deg(tr["y"][k], tr["z"][k]) == pytest.approx(76.0, abs=0.5)


# -- random interfaces ------------------------------------------------------------------
def seabed_only_power(per_cell: float) -> np.ndarray:
    """Mean compressed power of seabed reverberation over 0.45-0.85 s (ranges
    340-640 m) in 20 consecutive windows, every 8th channel, one ping."""
    scene = load_scene("line1", snr_db=None, overrides={
        "target": [], "subbottom": None, "seabed.specular": False, "seabed.multiple": False,
        "seabed.slope_across_deg": 0.0, "motion.roll_amplitude_deg": 0.0, "motion.pitch_amplitude_deg": 0.0,
        "motion.heave_amplitude_m": 0.0, "seabed.scattering.per_cell": per_cell})
    x = Simulator(scene, pings=[0]).ping(0)[::8].astype(np.float64)
    y = scipy.signal.fftconvolve(x, REPLICA[None, ::-1], mode="full", axes=1)[:, REPLICA.size - 1:]
    return (y[:, int(0.45 * FS):int(0.85 * FS)] ** 2).mean(axis=0).reshape(20, -1).mean(axis=1)


def test_seabed_reverberation_level_does_not_depend_on_scatterer_density():
    """Scatterers standing for an area 1/n get amplitude sqrt(σ/n): four times
    as many must give the same mean level (a wrong scaling gives 4 or 1/4)."""
    ratio = seabed_only_power(1.0) / seabed_only_power(4.0)
    # per-window ratios cancel the fall of the level with range; their spread
    # (speckle of a few scatterers per cell) gives the standard error
    stderr = ratio.std(ddof=1) / math.sqrt(ratio.size)
    assert stderr < 0.1
    assert ratio.mean() == pytest.approx(1.0, abs=4 * stderr)


# -- the reference scene --------------------------------------------------------------
def test_line1_places_the_three_pipelines_to_port_buried_1_m():
    sim = Simulator("line1", pings=[0])
    g = sim.geometry(0)
    tr = sim.truth(g)["target"]
    np.testing.assert_allclose(tr["y"], [-275.0, -460.0, -600.0], atol=0.5)
    np.testing.assert_allclose(tr["z"] - tr["seabed_z"], 1.0, atol=1e-9)
    assert sim.truth(g)["seabed_z"] == pytest.approx(225.0)
    # 56 pings, 4 s apart at 4 kn: 8.23 m per ping
    assert sim.scene.survey.pings == 56
    assert sim.scene.survey.step_m == pytest.approx(4 * 4 * 1852 / 3600)


def nadir_arrival(ds, near_s):
    """Arrival (s) of the strongest echo near ``near_s`` in the incoherent sum of
    the channels' envelopes (roll tilts the wavefront; the sum keeps its centre)."""
    y = scipy.signal.correlate(ds.samples.values[0].astype(np.float64), REPLICA[None, :], mode="full")
    y = y[:, REPLICA.size - 1:] / (REPLICA @ REPLICA)
    env = np.abs(scipy.signal.hilbert(y, axis=1)).sum(axis=0)
    lo, hi = int((near_s - 2e-3) * FS), int((near_s + 2e-3) * FS)
    k = lo + int(np.argmax(env[lo:hi]))
    d = 0.5 * (env[k - 1] - env[k + 1]) / (env[k - 1] - 2 * env[k] + env[k + 1])
    return (k + d) / FS


def test_line1_ping_has_seabed_subbottom_and_multiple_at_their_nadir_times():
    scene = load_scene("line1", overrides={"seabed.slope_across_deg": 0.0})
    ds = simulate(scene, pings=[0])
    heave = float(ds.heave[0])
    h = 225.0 + heave  # heave up lifts the transducers away from the seabed
    t_seabed = nadir_arrival(ds, 2 * h / C)
    t_sub = nadir_arrival(ds, 2 * h / C + 2 * 20.0 / (0.98 * C))
    t_mult = nadir_arrival(ds, (2 * h + 2 * 230.0) / C)
    # the parabola through the sampled (25 us) top of the summed envelopes is
    # biased by under 1 us; 2 us still tells a half-sample (12.5 us) error
    tol = 2e-6
    assert t_seabed == pytest.approx(2 * h / C, abs=tol)
    assert t_seabed == pytest.approx(2 * 225.0 / C, abs=2 * abs(heave) / C + tol)
    assert t_sub - t_seabed == pytest.approx(2 * 20.0 / (0.98 * C), abs=tol)
    # source -> seabed -> sea surface -> seabed -> element: near twice the seabed time
    assert t_mult == pytest.approx((2 * h + 2 * 230.0) / C, abs=tol)
    assert t_mult == pytest.approx(2 * t_seabed, abs=2 * (5.0 + abs(heave)) / C + tol)


def test_line1_record_reaches_past_700_m_and_the_noise_is_at_the_stated_snr():
    sim = Simulator("line1", pings=[0])
    assert sim.n_samples / FS >= 2 * 700.0 / C + 0.08
    # SNR re the nadir seabed echo V / (2 h): mud 1.25 × 0.98 gives V = 0.1008
    z = 1.25 * 0.98
    v = (z - 1) / (z + 1)
    assert sim.noise_std == pytest.approx(v / 450.0 * 10 ** (-25 / 20), rel=1e-9)
    x = sim.ping(0)
    before = x[:, :int(0.29 * FS)]  # nothing arrives before the seabed at 0.3 s
    # 64 × 11600 samples: the sample standard deviation is good to 0.1 %
    assert float(before.std()) == pytest.approx(sim.noise_std, rel=0.01)


# -- the file ------------------------------------------------------------------------------
FORMAT_VARIABLES = {
    "samples": (("ping", "channel", "sample"), None),
    "sample_rate": ((), "Hz"), "t0": (("ping",), "s"),
    "element_x": (("channel",), "m"), "element_y": (("channel",), "m"), "element_z": (("channel",), "m"),
    "source_x": ((), "m"), "source_y": ((), "m"), "source_z": ((), "m"),
    "sound_speed": (("ping",), "m/s"), "roll": (("ping",), "degree"), "pitch": (("ping",), "degree"),
    "heave": (("ping",), "m"), "heading": (("ping",), "degree"),
    "latitude": (("ping",), "degree_north"), "longitude": (("ping",), "degree_east"),
    "ping_time": (("ping",), None),
    "pulse_f0": ((), "Hz"), "pulse_f1": ((), "Hz"), "pulse_duration": ((), "s"),
    "channel_valid": (("channel",), None),
    "truth_target_y": (("ping", "target"), "m"), "truth_target_z": (("ping", "target"), "m"),
    "truth_seabed_z": (("ping",), "m"),
}


@pytest.mark.filterwarnings("ignore:Consolidated metadata:UserWarning")
@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
def test_dataset_follows_the_ping_file_schema_and_round_trips(tmp_path, suffix):
    scene = point_scene(**{"survey.pings": 3, "snr_db": 20.0, "record.max_range_m": 260.0,
                           "survey.heading_deg": 110.0})
    ds = simulate(scene)
    assert ds.attrs["clbeam_format"] == "ping-1"
    assert ds.samples.dtype == np.float32 and ds.samples.attrs["kind"] == "raw"
    for name, (dims, units) in FORMAT_VARIABLES.items():
        assert ds[name].dims == dims, name
        if units is not None:
            assert ds[name].attrs["units"] == units, name
        assert "units" in ds[name].attrs or name in ("ping_time", "samples"), name
    assert np.issubdtype(ds.ping_time.dtype, np.datetime64)
    assert np.all(np.diff(ds.ping_time.values) == np.timedelta64(4, "s"))
    # heading 110°: the ship runs east-south-east
    assert np.all(np.diff(ds.longitude.values) > 0) and np.all(np.diff(ds.latitude.values) < 0)
    path = write(ds, tmp_path / f"pings{suffix}")
    with PingFile(path) as f:
        assert len(f) == 3 and f.kind == "raw"
        p = f.ping(2)
        np.testing.assert_array_equal(p.samples, ds.samples.values[2])
        np.testing.assert_allclose(p.element_pos_m[:, 1], element_positions()[:, 1])
        assert p.pulse.f0_hz == 2000.0 and p.pulse.duration_s == 0.08
    back = xr.open_zarr(path) if suffix == ".zarr" else xr.open_dataset(path, engine="h5netcdf")
    with back:
        np.testing.assert_array_equal(back.truth_target_y.values, ds.truth_target_y.values)
        assert list(back.target.values) == ["P"]


def test_a_ping_depends_only_on_scene_seed_and_index():
    alone = Simulator("line1", pings=[3]).ping(3)
    among = Simulator("line1", pings=range(5)).ping(3)
    np.testing.assert_array_equal(alone, among)
    other_seed = Simulator("line1", seed=1, pings=[3]).ping(3)
    assert not np.array_equal(alone, other_seed)


# -- scenes -----------------------------------------------------------------------------------
def test_built_in_scenes_load_and_options_override():
    assert {"line1", "line4", "point"} <= set(list_scenes())
    s = load_scene("line1", pings=5, max_range_m=650.0, snr_db=None,
                   overrides={"seabed.scattering.per_cell": 2.0})
    assert s.survey.pings == 5 and s.record.max_range_m == 650.0 and s.snr_db is None
    assert s.seabed.scattering.per_cell == 2.0
    assert [t.name for t in s.targets] == ["A", "B", "C"]
    assert load_scene(s, pings=7).survey.pings == 7


def test_scene_file_by_path_and_one_line_errors(tmp_path):
    good = tmp_path / "mine.toml"
    good.write_text('[survey]\npings = 2\n[[target]]\nkind = "point"\nz_m = 100.0\n')
    s = load_scene(good)
    assert s.name == "mine" and s.survey.pings == 2
    bad = tmp_path / "bad.toml"
    bad.write_text("[survey]\npingz = 2\n")
    with pytest.raises(OptionError, match="unknown scene key 'survey.pingz'"):
        load_scene(bad)
    with pytest.raises(OptionError, match="not a built-in scene"):
        load_scene("line9")
    with pytest.raises(OptionError, match="burial_m"):
        load_scene("point", overrides={"target": [{"kind": "point", "name": "x", "burial_m": 1.0}]})
    with pytest.raises(ClbeamError, match="grazing_exponent"):
        load_scene("line1", overrides={"seabed.scattering.grazing_exponent": 6.0})
    with pytest.raises(OptionError) as info:
        load_scene("line1", overrides={"sonar.sample_rate_hz": 15000.0})
    assert "sample_rate_hz" in str(info.value) and "\n" not in str(info.value)


def test_a_line_target_in_the_water_loads_from_toml_and_round_trips(tmp_path):
    f = tmp_path / "wire.toml"
    f.write_text('[[target]]\nkind = "line"\nname = "wire"\ny_m = 120.0\nz_m = 150.0\n')
    scene = load_scene(f)
    wire = scene.targets[0]
    assert (wire.z_m, wire.burial_m) == (150.0, None)
    again = load_scene(scene)
    assert (again.targets[0].z_m, again.targets[0].burial_m) == (150.0, None)
    # a line target given neither lies 1 m below the seabed, as the paper's pipes
    f.write_text('[seabed]\ndepth_m = 200.0\n[[target]]\nkind = "line"\nname = "pipe"\ny_m = 120.0\n')
    assert load_scene(f).targets[0].burial_m == 1.0
