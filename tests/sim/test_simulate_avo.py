"""Seabed provinces: scattering follows the AVO backscatter model per grain size.

The built-in ``avo2`` line has medium sand (Mz 1.5) for its first 160 m and
medium silt (Mz 6) after.  The seabed reverberation level of a ping in each
province is measured the way an independent observer would (correlate with
the replica, envelope of the analytic signal, mean power in a slant-range
window) and the sand-to-silt ratio at the same grazing angles compared with
:func:`clbeam.seabed.avo.backscatter_strength_db`.  Geometry, spreading and the
scatterer density are the same in both provinces, so they cancel in the
ratio; with the ``sin^m`` law the ratio would be 0 dB.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal

from clbeam.errors import OptionError
from clbeam.model.pulse import lfm_replica
from clbeam.seabed.avo import backscatter_strength_db
from clbeam.sim.simulator import Simulator, list_scenes, load_scene, simulate

C, FS, F0, F1 = 1500.0, 40000.0, 2000.0, 9000.0
REPLICA = lfm_replica(f0_hz=F0, f1_hz=F1, duration_s=0.08, sample_rate_hz=FS)
H = 225.0  # transducers above the flat seabed (230 m water, 5 m draft)
STEP = 4.0 * 1852.0 / 3600.0 * 4.0  # 8.23 m between pings
# pings whose whole footprint (±110 m along-track at 500 m slant, the beam cut
# u = 0.214) lies in one province: sand before 160 m, silt after it
SAND_PINGS, SILT_PINGS = (0, 5), (34, 39)
WINDOWS_DEG = ((45.0, 55.0), (27.5, 33.0))  # grazing-angle windows (degree)


def quiet_avo2():
    """avo2 without motion, noise, specular echoes or multiples: only the
    seabed reverberation, at grazing ``asin(H / R)`` at slant range ``R``."""
    return load_scene("avo2", snr_db=None, overrides={
        "motion.roll_amplitude_deg": 0.0, "motion.pitch_amplitude_deg": 0.0, "motion.heave_amplitude_m": 0.0,
        "seabed.specular": False, "seabed.multiple": False})


def compressed_power(samples: np.ndarray) -> np.ndarray:
    """Mean over channels of the compressed envelope power against sample."""
    x = samples.astype(np.float64)
    y = scipy.signal.fftconvolve(x, REPLICA[None, ::-1], mode="full", axes=1)[:, REPLICA.size - 1:]
    y /= REPLICA @ REPLICA
    return (np.abs(scipy.signal.hilbert(y, axis=1)) ** 2).mean(axis=0)


def window_ranges_m(lo_deg: float, hi_deg: float) -> np.ndarray:
    return H / np.sin(np.radians([hi_deg, lo_deg]))


def test_avo2_seabed_level_follows_the_model_difference_between_sand_and_silt():
    sim = Simulator(quiet_avo2(), pings=SAND_PINGS + SILT_PINGS)
    assert [sim.province_mz(i * STEP) for i in SAND_PINGS + SILT_PINGS] == [1.5, 1.5, 6.0, 6.0]
    power = {p: compressed_power(sim.ping(p)) for p in SAND_PINGS + SILT_PINGS}
    r_sample = 0.5 * C * np.arange(sim.n_samples) / FS
    fc = 0.5 * (F0 + F1)
    for lo, hi in WINDOWS_DEG:
        r0, r1 = window_ranges_m(lo, hi)
        sel = (r_sample >= r0) & (r_sample <= r1)
        sand = np.mean([power[p][sel].mean() for p in SAND_PINGS])
        silt = np.mean([power[p][sel].mean() for p in SILT_PINGS])
        got_db = 10 * math.log10(sand / silt)
        # expected: the model's cross sections over the window, weighted by the
        # mean intensity's geometry (area per range cell R dR / y, spreading
        # R^-4), which is the same in both provinces
        r = np.linspace(r0, r1, 400)
        graz = np.degrees(np.arcsin(H / r))
        w = r / (np.sqrt(r * r - H * H) * r ** 4)
        sig = {mz: 10 ** (backscatter_strength_db(graz, fc, mz=mz) / 10) for mz in (1.5, 6.0)}
        want_db = 10 * math.log10(np.sum(sig[1.5] * w) / np.sum(sig[6.0] * w))
        # Speckle: the mean of N independent exponential intensities has a
        # relative standard deviation 1/sqrt(N).  Independent samples: one per
        # range-resolution cell c / 2B = 0.107 m of the window, counted once
        # per province (conservatively: the two pings and the port and
        # starboard halves add independent speckle but are not counted).  The
        # sand/silt ratio in dB then has std 4.34 sqrt(2 / N); allow 4 std.
        n_indep = (r1 - r0) / (C / (2 * (F1 - F0)))
        tol_db = 4 * 10 * math.log10(math.e) * math.sqrt(2 / n_indep)
        assert tol_db < 0.5 * want_db  # the test can tell the model from the sin^m law (0 dB)
        assert got_db == pytest.approx(want_db, abs=tol_db), (lo, hi, n_indep)


def test_provinces_in_scene_files_truth_and_errors():
    assert "avo2" in list_scenes()
    scene = load_scene("avo2")
    assert [(p.from_along_track_m, p.mz) for p in scene.seabed.province] == [(0.0, 1.5), (160.0, 6.0)]
    assert scene.survey.pings == 40 and scene.record.max_range_m == 500.0 and not scene.targets
    # round trip through the scene's plain data (the scene_json attribute)
    assert load_scene(scene).seabed.province == scene.seabed.province
    ds = simulate(load_scene("avo2", max_range_m=300.0, snr_db=None), pings=[0, 19, 20, 39])
    # 160 m lies between ping 19 (156.4 m) and ping 20 (164.6 m)
    np.testing.assert_array_equal(ds["truth_province_mz"].values, [1.5, 1.5, 6.0, 6.0])
    assert ds["truth_province_mz"].attrs["units"] == "phi"
    assert "truth_province_mz" not in simulate(load_scene("point"), pings=1)
    with pytest.raises(OptionError, match="must increase"):
        load_scene("avo2", overrides={"seabed.province": [{"from_along_track_m": 10.0, "mz": 1.0},
                                                          {"from_along_track_m": 0.0, "mz": 2.0}]})
    with pytest.raises(OptionError, match="mz must be within"):
        load_scene("avo2", overrides={"seabed.province": [{"mz": 12.0}]})
    with pytest.raises(OptionError, match="needs a \\[seabed.scattering\\]"):
        load_scene("avo2", overrides={"seabed.scattering": None})
    with pytest.raises(OptionError, match="unknown scene key 'seabed.province\\[0\\].grain'"):
        load_scene("avo2", overrides={"seabed.province": [{"grain": 1.0}]})


def closed_form_r(mz: float) -> float:
    """Normal-incidence coefficient ``(rho nu - 1) / (rho nu + 1)`` of the TR 9407 regressions' ratios."""
    from clbeam.seabed.avo.sediment import density_ratio, sound_speed_ratio

    z = density_ratio(mz) * sound_speed_ratio(mz)
    return (z - 1) / (z + 1)


def test_nadir_echo_and_multiple_reflect_with_each_provinces_impedance():
    """avo2 without motion, noise or (almost) scatterers: on the mean of the channels (the vertical beam,
    compressed independently of clbeam's imager) the seabed echo's peak times its path is ``R`` of the
    province under the ship (the replica's amplitude is 1 at 1 m), and the multiple's over the primary's,
    times their paths' ratio, is ``-R`` (seabed, surface -1, seabed): sand's 0.370 and silt's 0.063."""
    scene = load_scene("avo2", snr_db=None, overrides={
        "motion.roll_amplitude_deg": 0.0, "motion.pitch_amplitude_deg": 0.0, "motion.heave_amplitude_m": 0.0,
        "seabed.scattering.per_cell": 1e-4})
    ds = simulate(scene, pings=[0, 39])
    expected = [closed_form_r(1.5), closed_form_r(6.0)]
    np.testing.assert_allclose(ds["truth_nadir_reflection"].values, expected, rtol=1e-9)
    l1, l2 = 2 * H, 2 * H + 2 * (H + 5.0)  # unfolded paths: transducers 5 m below the surface
    for i, r in enumerate(expected):
        x = ds["samples"].values[i].astype(np.float64).mean(axis=0)
        y = scipy.signal.fftconvolve(x, REPLICA[::-1], mode="full")[REPLICA.size - 1:] / (REPLICA @ REPLICA)
        a = scipy.signal.hilbert(y)
        k1, k2 = (int(round((lp / C - float(ds["t0"].values[i])) * FS)) for lp in (l1, l2))
        p1 = a[k1 - 40:k1 + 40][np.argmax(np.abs(a[k1 - 40:k1 + 40]))]
        p2 = a[k2 - 40:k2 + 40][np.argmax(np.abs(a[k2 - 40:k2 + 40]))]
        # the replica has amplitude 1 at 1 m: the compressed primary's peak times its path is R itself
        assert abs(p1) * l1 == pytest.approx(r, rel=0.03)
        assert abs(p2 / p1) * l2 / l1 == pytest.approx(r, rel=0.02)
        assert abs(np.angle(-p2 / p1)) < 0.6
    with pytest.raises(OptionError, match="province_impedance needs"):
        load_scene("line1", overrides={"seabed.province_impedance": True})
