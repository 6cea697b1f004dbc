"""Beams in the frequency domain against closed forms: the zones against the curvature bound, the zone sums
against the band-limited echoes summed at the zones' delays, the images against the calibration's exact
sums (the budget), the OpenCL steering kernel against its float64 NumPy form."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scenes import point_ping, polar_point

from clbeam.errors import GridError, OptionError
from clbeam.imaging.budget import Budget, CalibrationScene, Measured, PulseWavelet, with_margins
from clbeam.imaging.engine import BeamformInput, get_engine
from clbeam.imaging.engine.beams import BeamSampling
from clbeam.imaging.engine.common import channel_signature, interp_mode, range_bases
from clbeam.imaging.engine.fdbeams import (
    DROPPED_ENERGY,
    curvature_constant_m2,
    frequency_beam_sums,
    offset_delays_m,
    steer_numpy,
    zone_delays_samples,
    zone_plan,
)
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.model.grid import PolarGrid
from clbeam.model.pulse import Pulse

FS, C = 40000.0, 1500.0
BAND = (2000.0, 9000.0)
GRID = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.2, max_range_m=600.0, angles_deg=(-60, 60))


def sbp(n=64, width=3.528):
    e = np.zeros((n, 3))
    e[:, 1] = (np.arange(n) - (n - 1) / 2) * width / n
    return e


def jittered(n=48, width=3.0, jitter=0.02, seed=7):
    e = sbp(n, width)
    e[:, 1:] += np.random.default_rng(seed).normal(0.0, jitter, (n, 2))
    return e


#: (elements, roll degree, heave m, source m): the SBP29 rolled and heaved with the source off the array, a
#: jittered 48-element array (2 cm) with the offsets of docs/beams.md's user array, a long sparse array
GEOMETRIES = {
    "sbp-roll-heave-source": (sbp(), 4.0, 0.3, (0.0, 0.3, 0.2)),
    "jittered-roll-source": (jittered(), 3.0, 0.0, (0.0, 0.35, 0.4)),
    "sparse-6m": (sbp(16, 6.0), -8.0, 1.0, (0.0, -0.5, 0.1)),
}


def _input(geometry, n_samples=48000, **kw) -> BeamformInput:
    elements, roll, heave, source = GEOMETRIES[geometry]
    ping = point_ping(polar_point(100.0, 10.0), record_s=n_samples / FS, kind="analytic", roll_deg=roll,
                      heave_m=heave, source_m=source, elements_m=elements)
    inp = Imager(GRID, ImagingOptions(interp="lanczos4", beams=None)).beamform_input(ping)
    return dataclasses.replace(inp, **kw)


@pytest.mark.parametrize("geometry", sorted(GEOMETRIES))
def test_zone_count_and_the_delay_errors_follow_the_curvature_bound(geometry):
    """The zones are the cells of the 1/R lattice the bound asks for that hold rows, and every channel's path
    error (source and element, exact spherical delays at every row of every zone and at angles over +-90
    degrees) is within the bound, which is within the allowed error and not vacuous (the worst path reaches
    half of it); a window of the grid's ranges has the grid's zones there."""
    inp = _input(geometry)
    beams = PolarGrid.beams(GRID.ranges_m, np.linspace(-90.0, 90.0, 91))
    zones = zone_plan(inp, beams)
    r = beams.ranges_m
    first, last = r[zones.bounds[0]], r[zones.bounds[-1] - 1]
    a2 = curvature_constant_m2(inp.element_offsets_m, inp.source_offset_m)
    half = 2.0 * zones.allowed_m / (a2 * zones.kappa)
    assert zones.n_zones == math.floor(1.0 / (2.0 * half * first)) - math.floor(1.0 / (2.0 * half * last)) + 1 > 1
    assert zones.path_error_bound_m <= zones.allowed_m
    worst = 0.0
    for z in range(zones.n_zones):
        rows = np.arange(zones.bounds[z], zones.bounds[z + 1])
        focus = zone_delays_samples(inp, beams.angles_deg, zones.focus_m[z]) / inp.samples_per_m
        for j in rows:
            at_row = (offset_delays_m(inp.source_offset_m, r[j], beams.angles_deg)
                      + offset_delays_m(inp.element_offsets_m, r[j], beams.angles_deg))
            worst = max(worst, float(np.max(np.abs(at_row - focus))))
    assert 0.5 * zones.path_error_bound_m <= worst <= zones.path_error_bound_m
    lo, hi = zones.bounds[1] - 5, zones.bounds[3] + 7
    sub = zone_plan(inp, PolarGrid.beams(r[lo:hi], beams.angles_deg))
    np.testing.assert_array_equal(_row_focus(sub, hi - lo), _row_focus(zones, r.size)[lo:hi])


def _row_focus(zones, n_rows: int) -> np.ndarray:
    """Each row's zone focus (m), NaN for the time domain's rows."""
    out = np.full(n_rows, np.nan)
    for z in range(zones.n_zones):
        out[zones.bounds[z]:zones.bounds[z + 1]] = zones.focus_m[z]
    return out


def _wavelet_scene(geometry, points_rt):
    """Channels holding the compressed 2-9 kHz pulse from points ``(range m, angle degree)`` (exact band-limited
    records: phase ramps on the wavelet's bins) and the wavelet to evaluate them anywhere."""
    inp = _input(geometry, n_samples=24000)
    psi = PulseWavelet.of_replica(Pulse(f0_hz=2000.0, f1_hz=9000.0, duration_s=0.01).replica(FS), FS, 1 << 15)
    data = np.zeros((inp.n_channels, inp.n_samples), np.complex128)
    arrivals = []
    for r, a in points_rt:
        th = np.deg2rad(a)
        t = CalibrationScene.straight_delays(inp, np.array([r * np.sin(th), r * np.cos(th)]))
        data += psi.samples(inp.t0_s, inp.n_samples, t)
        arrivals.append(t)
    return dataclasses.replace(inp, data=data, data_token=None, band_hz=BAND), psi, arrivals


@pytest.mark.parametrize("geometry", ["sbp-roll-heave-source", "jittered-roll-source"])
def test_zone_sums_equal_the_echoes_summed_at_the_zones_delays(geometry):
    """The frequency-domain S and Q (float64 steering, Hann weights w) against the wavelet evaluated at every
    row's time plus each channel's delay at its zone's focus, summed over the channels: the transforms add no
    error beyond the bins left out, whose energy is at most DROPPED_ENERGY of each segment's.  By
    Cauchy-Schwarz |dS|^2 <= sum w^2 sum_n |dp_n|^2 (and |dQ|^2 <= sum w^2 sum_n |d|p_n|^2|^2), so the error
    energy over the rows is at most that fraction of sum w^2 sum |p_n|^2 (of sum w^2 sum |p_n|^4); x10 for
    the rows sampling the segments' energy."""
    inp, psi, arrivals = _wavelet_scene(geometry, [(140.0, 20.0), (150.0, -35.0), (230.0, 5.0)])
    beams = PolarGrid.beams(GRID.ranges_m[600:1300], np.linspace(-50.0, 50.0, 21))
    weights = np.hanning(inp.n_channels + 2)[1:-1]
    inp = dataclasses.replace(inp, weights=weights)
    zones = zone_plan(inp, beams, min_zone_rows=1)     # zones down to the window's first row
    assert zones.bounds[0] == 0 and zones.bounds[-1] == beams.shape[1] and zones.n_zones >= 3

    def no_time_rows(rows):
        raise AssertionError(f"rows {rows.ranges_m} left to the time domain")

    got = frequency_beam_sums(inp, beams, time_domain=no_time_rows, zones=zones)
    t_rows = range_bases(inp, beams) / FS + inp.t0_s
    s_err = s_ref = q_err = q_ref = 0.0
    for z in range(zones.n_zones):
        rows = slice(zones.bounds[z], zones.bounds[z + 1])
        tau = zone_delays_samples(inp, beams.angles_deg, zones.focus_m[z]) / FS          # (beam, channel) s
        p = sum(psi(t_rows[None, None, rows] + tau[:, :, None] - t[None, :, None]) for t in arrivals)
        s = np.einsum("n,bnj->bj", weights, p)
        q = np.einsum("n,bnj->bj", weights, np.abs(p) ** 2)
        s_err += np.sum(np.abs(got.s[:, rows] - s) ** 2)
        q_err += np.sum((got.q[:, rows] - q) ** 2)
        s_ref += np.sum(weights**2) * np.sum(np.abs(p) ** 2)
        q_ref += np.sum(weights**2) * np.sum(np.abs(p) ** 4)
    assert s_err <= 10 * DROPPED_ENERGY * s_ref
    assert q_err <= 10 * DROPPED_ENERGY * q_ref
    np.testing.assert_array_equal(got.m, inp.n_channels)
    np.testing.assert_allclose(got.w, weights.sum())


def _calibration(geometry, **kw):
    elements, roll, heave, source = GEOMETRIES[geometry]
    ping = point_ping(polar_point(100.0, 10.0), record_s=0.85, kind="analytic", roll_deg=roll, heave_m=heave,
                      source_m=source, elements_m=elements)
    inp = dataclasses.replace(Imager(GRID, ImagingOptions(interp="lanczos4", beams=None)).beamform_input(ping), **kw)
    return inp, CalibrationScene(inp, GRID, BAND, Pulse(f0_hz=2000.0, f1_hz=9000.0, duration_s=0.02).replica(FS))


@pytest.mark.parametrize("geometry, apodized", [("sbp-roll-heave-source", False), ("jittered-roll-source", False),
                                                 ("sparse-6m", False), ("sbp-roll-heave-source", True)])
def test_images_hold_the_budget_against_the_exact_sums(geometry, apodized):
    """The calibration's twenty point echoes of the 20 ms pulse (on and off nodes, across the swath, and the
    sweep below the array) imaged from frequency-domain beams (float32 steering on the device) against their
    exact sums in closed form: within the default budget with the calibration's margins (-41 dB, |dCF|
    0.0114, CF 0.9933 on nodes).  The beams are x2 with 16 taps: with x1.5/12 and x2/12 the angular
    interpolation alone leaves |dCF| 0.022 and 0.012 on the sweep (the time-domain beams 0.035 and 0.027 on
    the same cells), where the frequency-domain sums imaged on the cells themselves hold 0.001.  Rows
    nearer than the first zone (below 350 m for the 6 m array) are summed in time, with Lanczos-8 here (with
    Lanczos-4 they alone miss the budget: |dCF| 0.018)."""
    weights = {"weights": np.hanning(len(GEOMETRIES[geometry][0]) + 2)[1:-1]} if apodized else {}
    inp, scene = _calibration(geometry, **weights)
    beams = BeamSampling(2.0, 16, domain="frequency")
    measured = scene.measure_domain(get_engine("opencl"), "lanczos8", beams)
    assert measured.meets(with_margins(Budget())), measured.describe()
    if geometry == "sbp-roll-heave-source" and not apodized:     # a setting is judged on its twin's figures too
        twin = scene.measure_domain(get_engine("opencl"), "lanczos8", dataclasses.replace(beams, domain="time"))
        both = scene.measure(get_engine("opencl"), "lanczos8", beams)
        assert both == Measured(max(measured.error_db, twin.error_db), max(measured.cf_error, twin.cf_error),
                                min(measured.node_cf, twin.node_cf))


def test_opencl_steering_equals_its_numpy_form():
    """float64 kernel to rounding; float32 within its unit roundoff times what the sums accumulate (the
    reduced phase of |bin d| cycles, the eight bins' turns and the channels' additions)."""
    from clbeam.imaging.engine.opencl import device_has_fp64

    rng = np.random.default_rng(3)
    x = rng.standard_normal((37, 1001)) + 1j * rng.standard_normal((37, 1001))
    d = rng.uniform(-60.0, 60.0, (23, 37)) / 8192.0
    first = -137
    want = steer_numpy(x, d, first)
    scale = np.abs(x).sum(axis=0)[None, :]
    f32 = get_engine("opencl")
    got = f32._steering()(x, d, first)
    cycles = np.max(np.abs(d)) * (abs(first) + x.shape[1])
    tol = 2.0**-24 * scale * (4 * 2 * np.pi * (cycles + 1) + 8 * 8 + x.shape[0])
    assert np.all(np.abs(got - want) <= tol)
    if device_has_fp64(f32.device):
        got = get_engine("opencl", precision="float64")._steering()(x, d, first)
        assert np.all(np.abs(got - want) <= 2.0**-52 * scale * (4 * 2 * np.pi * (cycles + 1) + 64 + x.shape[0]))


def test_skipped_samples_and_the_near_rows_are_formed_in_time():
    """A zone whose segment holds a NaN sample, the rows nearer than the first zone and the rows whose delays
    leave the record come from the time-domain sums: M, S and Q equal them there (the reference's own)."""
    inp = _input("sbp-roll-heave-source", n_samples=36000)
    data = inp.data.copy()
    data[5, 28000:28004] = np.nan
    inp = dataclasses.replace(inp, data=data, data_token=None)
    beams = PolarGrid.beams(GRID.ranges_m[::4], np.linspace(-40.0, 40.0, 9))
    ref = get_engine("reference")
    mode = interp_mode("lanczos4")

    def time_domain(rows):
        return ref._beamform(inp, rows, mode, frozenset({"sums", "signature"}), None, 1.0)

    got = frequency_beam_sums(inp, beams, time_domain=time_domain, channel_numbers=channel_signature(inp.n_channels))
    want = time_domain(beams)
    zones = zone_plan(inp, beams)
    in_zones = np.zeros(beams.shape[1], dtype=bool)
    in_zones[zones.bounds[0]:zones.bounds[-1]] = True
    nan_row = int(np.argmin(np.abs(range_bases(inp, beams) - 28000)))
    timed = ~in_zones
    timed[nan_row] = True
    assert in_zones.any() and (~in_zones).sum() > 10 and want.m[:, nan_row].min() < inp.n_channels
    for name in ("s", "q", "m", "signature"):
        np.testing.assert_array_equal(getattr(got, name)[:, timed], getattr(want, name)[:, timed], err_msg=name)


def test_windowed_beams_are_the_full_sums_cleared_outside_and_steer_only_the_beams_they_need():
    """With a range window per beam (the seabed band's), the sums equal the window-free sums zeroed outside
    each window, to rounding; a zone is steered on the beams whose window meets it and one that no window
    meets is not transformed at all (the steering records the beams it is given)."""
    inp = _input("jittered-roll-source", n_samples=36000)
    beams = PolarGrid.beams(GRID.ranges_m[::4], np.linspace(-40.0, 40.0, 9))
    ref = get_engine("reference")
    mode = interp_mode("lanczos4")

    def time_domain(rows):
        return ref._beamform(inp, rows, mode, frozenset({"sums", "signature"}), None, 1.0)

    seen = []

    def recording(x, delays, first):
        seen.append(delays.shape[0])
        return steer_numpy(x, delays, first)

    r = beams.ranges_m
    window = np.stack([np.linspace(r[300], r[560], 9), np.linspace(r[420], r[600], 9)], axis=1)
    window[0] = r[700], r[740]            # one beam's window alone, far out: zones from row 434 on
    full = frequency_beam_sums(inp, beams, time_domain=time_domain)
    got = frequency_beam_sums(inp, beams, time_domain=time_domain, window_m=window, steer=recording)
    outside = (r[None, :] < window[:, :1]) | (r[None, :] > window[:, 1:])
    for name in ("s", "q", "m"):
        want = np.where(outside, 0, getattr(full, name))
        scale = np.max(np.abs(want))
        np.testing.assert_allclose(getattr(got, name), want, rtol=0, atol=1e-9 * scale, err_msg=name)
    n_zones = zone_plan(inp, beams).n_zones
    assert 1 in seen and max(seen) <= beams.shape[0]          # the lone far beam steered on its own
    assert len(seen) < 2 * n_zones                            # S and Q per zone met, some zones skipped


def test_bad_input_is_refused_in_one_line():
    from clbeam.imaging.raytrace import travel_time_tables
    from clbeam.model.svp import SoundSpeedProfile

    with pytest.raises(OptionError, match="beam domain"):
        BeamSampling(1.5, 12, domain="fourier")
    inp = _input("sparse-6m", n_samples=4000)
    uneven = PolarGrid.beams(np.r_[50.0, 50.3, 51.0, 52.0], [0.0, 10.0])
    with pytest.raises(GridError, match="uniformly spaced ranges"):
        frequency_beam_sums(inp, uneven, time_domain=None)
    tables = travel_time_tables(SoundSpeedProfile([0.0, 100.0], [1500.0, 1480.0]), uneven)
    with pytest.raises(OptionError, match="straight rays"):
        frequency_beam_sums(dataclasses.replace(inp, tables=tables), uneven, time_domain=None)
    with pytest.raises(OptionError, match="path error"):
        zone_plan(inp, uneven, path_error_wavelengths=0.0)


@pytest.mark.oclgrind
@pytest.mark.slow
def test_steering_kernel_is_clean_under_oclgrind():
    """tests/oclgrind_fdbeams_run.py under Oclgrind (near rows and rows past the record's end in time, a NaN
    sample, every layout and precision): no invalid, uninitialised or racing access, and the images within
    float32's error of the reference engine's (1e-4, as the delay-and-sum's variants) with M exact."""
    import os
    import re
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    oclgrind = shutil.which("oclgrind")
    assert oclgrind, "oclgrind is not installed (Debian package 'oclgrind'; the set-up script installs it)"
    script = Path(__file__).parents[1] / "oclgrind_fdbeams_run.py"
    r = subprocess.run([oclgrind, "--uninitialized", "--check-api", "--data-races", sys.executable, str(script)],
                       capture_output=True, text=True, env=dict(os.environ, CLBEAM_DEVICE=""), timeout=900)
    assert r.returncode == 0, (r.stdout + r.stderr)[-3000:]
    assert "device: Oclgrind Simulator" in r.stdout, r.stdout[-2000:]
    blocks = [b for b in re.split(r"\n\s*\n", r.stderr) if b.strip()]
    problems = [b for b in blocks if re.search(r"invalid|uninitiali[sz]ed|data race|out-of-bounds|error|fatal", b, re.I)
                and "Function: clGetDeviceInfo" not in b]
    assert not problems, "\n".join(problems[:20])
    variants = [line for line in r.stdout.splitlines() if line.startswith("variant fd-beams")]
    assert len(variants) >= 3
    for line in variants:
        assert float(re.search(r"rel=(\S+)", line).group(1)) < 1e-4 and "m_equal=True" in line, line
        assert "m_range=0-" in line   # cells beyond the record
    zones = re.search(r"zones (\d+) rows (\d+)-(\d+) of (\d+)", r.stdout)
    assert int(zones.group(1)) >= 2 and 0 < int(zones.group(2)) and int(zones.group(3)) < int(zones.group(4))


@pytest.mark.parametrize("beams, named", [(BeamSampling(2.0, 16, domain="frequency"), "x2/16 taps in the frequency domain"),
                                          (BeamSampling(4.0, 16), "x4/16 taps: predicted")])
def test_an_imager_with_given_beams_says_so_and_holds_the_budget(beams, named):
    """Through the Imager (the time interpolation of the near rows measured on the ping's geometry, the beams
    given; x4/16 is none of the error model's own samplings): the setting names the beams, and two points'
    images are within the default budget (-40 dB, |dCF| 0.02 on cells within 40 dB of each window's maximum)
    of the float64 reference's exact images."""
    from clbeam.imaging.budget import intensity_error_db

    elements, roll, heave, source = GEOMETRIES["jittered-roll-source"]
    points = [(150.0, 20.0), (180.4, -30.3)]
    ping = point_ping([polar_point(r, a) for r, a in points], record_s=0.3, kind="analytic", roll_deg=roll,
                      heave_m=heave, source_m=source, elements_m=elements)
    grid = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.2, min_range_m=100.0, max_range_m=200.0,
                             angles_deg=(-50, 50))
    imager = Imager(grid, ImagingOptions(beams=beams, refine_peaks=False), engine=get_engine("opencl"))
    image = imager.image(ping)
    assert named in image.setting and "measured" in image.setting, image.setting
    recorded = Imager(grid, ImagingOptions(interp="lanczos4", upsample=1, beams=None)).beamform_input(ping)
    # the grid centre is the source's: the points' polar positions about it differ a little from the array's
    for r, a in points:
        ia, ir = int(np.argmin(np.abs(grid.angles_deg - a))), int(np.argmin(np.abs(grid.ranges_m - r)))
        sa, sr = slice(ia - 40, ia + 41), slice(ir - 12, ir + 13)
        window = PolarGrid.beams(grid.ranges_m[sr], grid.angles_deg[sa])
        exact = get_engine("reference").beamform(recorded, window, interp="exact", outputs=("intensity", "cf"))
        keep = exact.intensity >= exact.intensity.max() * 1e-4
        assert intensity_error_db(image.intensity[sa, sr].astype(np.float64), exact.intensity) <= -40.0
        assert np.max(np.abs(image.cf[sa, sr] - exact.cf)[keep]) <= 0.02


@pytest.mark.parametrize("positions", [[3.25], [3.25, 7.5]])
def test_evaluation_at_one_or_two_positions_is_the_direct_sum(positions):
    """A zone of one range row is evaluated like any other (its message once raised on the empty step list): the
    sum written out."""
    from clbeam.imaging.engine.fdbeams import evaluate_at

    rng = np.random.default_rng(0)
    spectrum = rng.normal(size=(3, 20)) + 1j * rng.normal(size=(3, 20))
    x = np.asarray(positions, dtype=np.float64)
    k = 5 + np.arange(20)
    want = (spectrum[:, None, :] * np.exp(2j * np.pi * k[None, None, :] * x[None, :, None] / 64)).sum(-1) / 64
    np.testing.assert_allclose(evaluate_at(spectrum, 5, 64, x), want, rtol=1e-9, atol=1e-12)
