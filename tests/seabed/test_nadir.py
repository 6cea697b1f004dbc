"""The nadir reflection coefficient from the seabed echo and its first surface multiple (clbeam.seabed.nadir),
against the closed form of the simulated physics.

The simulator's seabed is a fluid half-space: at normal incidence
``R = (m - n) / (m + n)`` (density ratio ``m``, ``n`` the water's over the
sediment's sound speed), ``0.1011`` for Line 1's mud.  Its multiple
(seabed, surface, seabed) carries ``R^2`` and the surface's ``-1``, with
spreading over the unfolded path: the ratio of the two echoes, times the
ratio of their paths, is ``-R``.  The check is of the simulator's multiple
and of the measurement together, against that closed form.
"""

from __future__ import annotations

import math
import tomllib
from importlib.resources import files

import numpy as np
import pytest

from clbeam.errors import OptionError
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.vertical_beam import TraceAxis, VerticalBeam
from clbeam.io.pingfile import pings_from_dataset
from clbeam.seabed.nadir import NadirMeter, coherent_reflection, nadir_echoes, patch_reflection
from clbeam.sim import simulate
from clbeam.sim.catalog import scene_from_mapping

DENSITY, SPEED = 1.25, 0.98                      # Line 1's mud (docs/simulator.md)
R_CLOSED = (DENSITY - 1 / SPEED) / (DENSITY + 1 / SPEED)
BAND_HZ = 7000.0


def scene(slope_deg: float, max_range_m: float = 700.0, pings: int = 2):
    """Line 1 without pipelines: seabed (sloping across by ``slope_deg``), scatterers, horizon, multiples, roll, heave."""
    d = tomllib.loads((files("clbeam.sim.scenes") / "line1.toml").read_text())
    d["target"] = []
    d["seabed"]["slope_across_deg"] = slope_deg
    d["record"]["max_range_m"] = max_range_m
    d["survey"]["pings"] = pings
    return scene_from_mapping(d, name=f"nadir{slope_deg:g}")


@pytest.fixture(scope="module")
def flat():
    pf = pings_from_dataset(simulate(scene(0.0)), "flat")
    return pf, VerticalBeam(TraceAxis.for_file(pf))


def test_multiple_is_minus_r_times_the_primary_over_the_path_ratio(flat):
    """Flat seabed, vertical beam: |R| within 2 % of the closed form, the multiple's sign the surface's -1."""
    pf, vb = flat
    t = vb.axis.times_s
    for i in range(2):
        trace = vb(pf.ping(i)).analytic
        e = nadir_echoes(trace, t, sound_speed_m_s=1500.0, bandwidth_hz=BAND_HZ)
        assert e.reflection == pytest.approx(R_CLOSED, rel=0.02)
        # two-way paths: 2 x 225 m and 2 x 225 + 2 x 230 m (transducers 5 m down)
        assert e.primary_s == pytest.approx(450 / 1500, abs=2e-4)
        assert e.multiple_s == pytest.approx(910 / 1500, abs=2e-4)
        k1, k2 = (int(np.argmin(np.abs(t - x))) for x in (e.primary_s, e.multiple_s))
        assert abs(np.angle(-trace[k2] / trace[k1])) < 0.6  # the ratio is -|R| L1/L2: phase near pi


def test_a_sloping_seabed_is_measured_on_the_beams_that_point_at_each_echo():
    """Seabed sloping 0.8 degree across: the vertical beam alone reads R low
    by the array factor's ratio at 2s and s (closed form at the band's
    centre, 5.5 kHz: 0.84); the fan of beams finds the multiple at -1.6
    degrees, the seabed echo is measured at half that, and R within 6 %."""
    pf = pings_from_dataset(simulate(scene(0.8)), "sloped")
    vb = VerticalBeam(TraceAxis.for_file(pf))
    opts = ImagingOptions(interp="cubic", outputs=("sums",), use_svp=False)
    meter = NadirMeter(lambda g: Imager(g, opts, engine=vb.engine), vb)
    lam_over_l = 1500.0 / 5500.0 / 3.528
    af = [np.sinc(math.sin(math.radians(a)) / lam_over_l) for a in (0.8, 1.6)]
    for i in range(2):
        p = pf.ping(i)
        vertical = nadir_echoes(vb(p).analytic, vb.axis.times_s, sound_speed_m_s=1500.0, bandwidth_hz=BAND_HZ)
        assert vertical.reflection / R_CLOSED == pytest.approx(af[1] / af[0], abs=0.04)
        e = meter(p, bandwidth_hz=BAND_HZ)
        assert e.reflection == pytest.approx(R_CLOSED, rel=0.06)
        # the multiple's direction, refined between the fan's 0.2 degree beams
        assert e.multiple_beam_deg == pytest.approx(-1.6, abs=0.1)


def test_a_multiple_beyond_the_record_is_said_and_gives_no_coefficient():
    pf = pings_from_dataset(simulate(scene(0.0, max_range_m=400.0, pings=1)), "short")
    vb = VerticalBeam(TraceAxis.for_file(pf))
    e = nadir_echoes(vb(pf.ping(0)).analytic, vb.axis.times_s, sound_speed_m_s=1500.0, bandwidth_hz=BAND_HZ)
    assert math.isnan(e.reflection) and "beyond the record" in e.reason
    assert e.primary_s == pytest.approx(0.3, abs=2e-4)


def test_patch_median_and_spread():
    v = [0.10, 0.11, 0.09, np.nan, 0.10]
    med, se, n = patch_reflection(v)
    assert (med, n) == (pytest.approx(0.10), 4)
    assert se == pytest.approx(1.2533 * np.std([0.10, 0.11, 0.09, 0.10], ddof=1) / 2)
    assert patch_reflection([np.nan])[2] == 0


def test_bad_traces_are_refused_in_one_line():
    with pytest.raises(OptionError) as e:
        nadir_echoes(np.zeros(5), np.arange(5.0), sound_speed_m_s=1500.0, bandwidth_hz=BAND_HZ)
    assert "\n" not in str(e.value)
    empty = nadir_echoes(np.zeros(100), np.arange(100) * 1e-4, sound_speed_m_s=1500.0, bandwidth_hz=BAND_HZ)
    assert math.isnan(empty.reflection) and empty.reason == "empty trace"


def _pulse(t, t0, bandwidth=BAND_HZ, fc=5500.0):
    """A compressed pulse: Gaussian envelope of width 1/bandwidth on the carrier, analytic."""
    return np.exp(-0.5 * ((t - t0) * bandwidth) ** 2 * 4) * np.exp(2j * np.pi * fc * (t - t0))


def test_coherent_patch_mean_recovers_r_where_scattering_fills_each_pings_windows():
    """Twenty pings: a specular primary R/L1 and multiple -R^2/L2 (heave left over from its compensation
    moving them by d and 2d, up to 20 microseconds), the
    primary buried in scattered echoes of random phase carrying three times its specular energy (a
    rough sand near normal incidence, as scene avo2's), the multiple in a tenth as much (as the
    simulation shows: its phase stays put from ping to ping).  Ping by ping the energies read R far
    low; the coherent mean of the patch gives R within three of its (jackknife) standard errors, and
    those under 15 %."""
    rng = np.random.default_rng(3)
    dt, c = 25e-6, 1500.0
    t = np.arange(0.2, 0.7, dt)
    r, t1, t2 = 0.1, 0.3, 0.6066
    traces, p1, p2 = [], [], []
    for _ in range(20):
        heave = rng.normal(0, 1e-5)
        tr = r / (c * t1) * _pulse(t, t1 + heave) - r * r / (c * t2) * _pulse(t, t2 + 2 * heave)
        for t0, shift, level in ((t1, heave, r / (c * t1) * math.sqrt(3.0)), (t2, 2 * heave, r * r / (c * t2) * 0.3)):
            n = 60
            delays = t0 + shift + np.abs(rng.normal(0, 4e-4, n))
            amps = level * math.sqrt(1.0 / n) * np.exp(2j * np.pi * rng.random(n))
            tr = tr + sum(a * _pulse(t, d) for a, d in zip(amps, delays))
        e = nadir_echoes(tr, t, sound_speed_m_s=c, bandwidth_hz=BAND_HZ)
        traces.append(tr)
        p1.append(e.primary_s)
        p2.append(e.multiple_s)
    single = [nadir_echoes(x, t, sound_speed_m_s=c, bandwidth_hz=BAND_HZ).reflection for x in traces]
    assert np.median(single) < 0.75 * r
    est, se = coherent_reflection(traces, t, p1, p2, bandwidth_hz=BAND_HZ)
    assert abs(est - r) <= 3 * se and se < 0.15 * r


def test_absorption_and_surface_loss_corrections_are_the_closed_form():
    """An echo pair built with water absorption (2 dB/km over the multiple's extra 460 m of path) and a
    surface losing 1 dB: with the same values given, R comes back; without, it reads low by exactly those."""
    dt, c = 25e-6, 1500.0
    t = np.arange(0.2, 0.7, dt)
    r, t1, t2 = 0.1, 0.3, 0.6066
    extra_db = 2.0 * c * (t2 - t1) / 1000 + 1.0
    tr = r / (c * t1) * _pulse(t, t1) - r * r / (c * t2) * 10 ** (-extra_db / 20) * _pulse(t, t2)
    plain = nadir_echoes(tr, t, sound_speed_m_s=c, bandwidth_hz=BAND_HZ)
    fixed = nadir_echoes(tr, t, sound_speed_m_s=c, bandwidth_hz=BAND_HZ, absorption_db_per_km=2.0,
                         surface_loss_db=1.0)
    assert fixed.reflection == pytest.approx(r, rel=0.01)
    assert 20 * math.log10(fixed.reflection / plain.reflection) == pytest.approx(extra_db, abs=0.05)


def test_patch_reflections_steer_onto_a_sloping_seabeds_echoes(tmp_path):
    """Four pings over Line 1's seabed sloping 0.8 degree across: the patch's coefficient, from beams steered
    onto the seabed echo and the multiple, within 5 % of the closed form (the vertical beam alone reads 15 %
    low, test above), and its calibration within 1 dB of the simulator's (-20 log10(64), G = 1)."""
    from clbeam.io.pingwrite import write_ping_file
    from clbeam.seabed.nadir import patch_reflections

    path = write_ping_file(simulate(scene(0.8, pings=4)), tmp_path / "sloped.nc")
    (r, se, cal, cal_se), = patch_reflections(path, [(0, 4)], bandwidth_hz=BAND_HZ)
    assert r == pytest.approx(R_CLOSED, rel=0.05) and se < 0.05 * R_CLOSED
    assert cal == pytest.approx(-20 * math.log10(64), abs=1.0) and 0 < cal_se < 1.0
