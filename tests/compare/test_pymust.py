"""Cross-checks against PyMUST, an independent ultrasound simulator and beamformer.

A 64-element phased array (PyMUST's P4-2v, 2.72 MHz, 1540 m/s) fires one
element (a diverging wave; the others are off, delay NaN) at eight point
scatterers from 10 to 70 wavelengths and out to ±60 degrees. PyMUST's
``simus`` writes the element signals, which another program's way of
writing ping files turns into a ping file: raw RF, the two-way pulse of
``getpulse`` as ``tx_waveform``, centred, so ``tx_delay`` is minus half its
length. clbeam images it with its defaults; PyMUST's ``dasmtx`` beamforms the
same analytic signal for the envelope comparison.
"""

from __future__ import annotations

import numpy as np
import pymust
import pytest
import xarray as xr

from clbeam.imaging.engine import BeamformInput, get_engine
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.subcell import sums_at_points
from clbeam.io.pingfile import PingFile
from clbeam.model.grid import PolarGrid

C = 1540.0
SOURCE = 31  # the element that transmits
RANGES_LAMBDA = np.array([10, 25, 35, 50, 50, 60, 70, 45])
ANGLES_DEG = np.array([0, -30, 20, -60, 60, 5, -15, 40])


def probe():
    p = pymust.getparam("P4-2v")
    p.c, p.fs = C, 4 * p.getparam("fc") if hasattr(p, "getparam") else 4 * p.fc
    return p


@pytest.fixture(scope="module")
def scene():
    p = pymust.getparam("P4-2v")
    p.c, p.fs = C, 4 * p.fc
    lam = C / p.fc
    x = RANGES_LAMBDA * lam * np.sin(np.deg2rad(ANGLES_DEG))
    z = RANGES_LAMBDA * lam * np.cos(np.deg2rad(ANGLES_DEG))
    delays = np.full((1, p.Nelements), np.nan)
    delays[0, SOURCE] = 0.0
    rf, _ = pymust.simus(x, z, np.ones(x.size), delays, p)
    return p, lam, x, z, delays, rf


def ping_file(path, p, rf):
    """The ping file another program would write from PyMUST's output."""
    pulse, t = pymust.getpulse(p, 2)
    replica = np.interp(np.arange(0.0, t[-1], 1 / p.fs), t, pulse)
    y = (np.arange(p.Nelements) - (p.Nelements - 1) / 2) * p.pitch
    ds = xr.Dataset({
        "samples": (("ping", "channel", "sample"), rf.T[None], {"kind": "raw"}),
        "sample_rate": ((), p.fs), "t0": (("ping",), [0.0]),
        "element_y": (("channel",), y), "element_z": (("channel",), np.zeros(p.Nelements)),
        "source_y": ((), y[SOURCE]), "source_z": ((), 0.0), "sound_speed": (("ping",), [C]),
        "tx_waveform": (("tx_sample",), replica), "tx_delay": ((), -t[-1] / 2),   # PyMUST centres its pulse
    }, attrs={"clbeam_format": "ping-1"})
    ds.to_netcdf(path, engine="h5netcdf")
    return path


def beam_width_deg(p) -> float:
    """lambda / D at the centre frequency (degree): 1.7 for the P4-2v."""
    return float(np.rad2deg(C / p.fc / (p.Nelements * p.pitch)))


def image_peaks(path, lam):
    with PingFile(path) as f:
        ping = f.ping(0)
    grid = PolarGrid.regular(range_res_m=lam / 10, angle_res_deg=0.2, min_range_m=5 * lam, max_range_m=75 * lam,
                             angles_deg=(-75, 75))
    return Imager(grid, ImagingOptions()).image(ping).peaks


def check_peaks(peaks, x, z, lam, *, tolerance_lambda, beam_deg):
    """Every scatterer has exactly one peak within a tenth of a wavelength, the nearest within
    ``tolerance_lambda``; every other peak lies on a scatterer's echo: at its angle (within a beam
    width), within 3 wavelengths of range before or behind it (the two-way pulse's range sidelobes),
    and weaker."""
    y = np.array([r["y_m"] for r in peaks])
    zz = np.array([r["z_m"] for r in peaks])
    own = np.zeros(len(peaks), dtype=bool)
    nearest = []
    for xs, zs in zip(x, z):
        d = np.hypot(y - xs, zz - zs) / lam
        assert np.sum(d < 0.1) == 1, f"scatterer at ({xs:.4f}, {zs:.4f}) m: {np.sum(d < 0.1)} peaks within 0.1 wavelength"
        k = int(np.argmin(d))
        assert d[k] < tolerance_lambda
        own[k] = True
        nearest.append(peaks[k])
    centre = peaks[0]["centre_y_m"]
    for row in (r for r, mine in zip(peaks, own) if not mine):
        ang = np.rad2deg(np.arctan2(row["y_m"] - centre, row["z_m"]))
        rng = np.hypot(row["y_m"] - centre, row["z_m"])
        hosts = [n for n, xs, zs in zip(nearest, x, z)
                 if abs(np.rad2deg(np.arctan2(xs - centre, zs)) - ang) < beam_deg
                 and abs(np.hypot(xs - centre, zs) - rng) < 3 * lam and n["intensity_db"] > row["intensity_db"]]
        assert hosts, f"unexplained peak at {rng / lam:.1f} wavelengths, {ang:.1f} degrees"
    return nearest


def test_every_scatterer_one_peak_within_a_twentieth_of_a_wavelength(scene, tmp_path):
    p, lam, x, z, _, rf = scene
    nearest = check_peaks(image_peaks(ping_file(tmp_path / "pymust.nc", p, rf), lam), x, z, lam,
                          tolerance_lambda=0.1, beam_deg=beam_width_deg(p))
    errors = [np.hypot(n["y_m"] - xs, n["z_m"] - zs) / lam for n, xs, zs in zip(nearest, x, z)]
    assert sum(e < 0.05 for e in errors) >= 7  # the one at -60 degrees, 50 wavelengths: 0.08 wavelength
    # far enough for the aperture (34 wavelengths) and within 20 degrees: CF of an isolated point
    far = (RANGES_LAMBDA >= 60) & (np.abs(ANGLES_DEG) <= 20)
    assert all(n["cf"] >= 0.98 for n, f in zip(nearest, far) if f)
    # the clutter test ran (its windows from the pulse's spectrum, not NaN) and kept every scatterer
    assert all(n["contrast_db"] >= 12.0 for n in nearest)


def test_noisy_scene_keeps_every_scatterer_and_no_noise_peak(scene, tmp_path):
    p, lam, x, z, _, rf = scene
    noisy = rf + 0.05 * np.std(rf) * np.random.default_rng(1).standard_normal(rf.shape)
    peaks = image_peaks(ping_file(tmp_path / "noisy.nc", p, noisy), lam)
    check_peaks(peaks, x, z, lam, tolerance_lambda=0.1, beam_deg=beam_width_deg(p))
    assert all(r["snr_db"] >= 6.0 for r in peaks)


@pytest.mark.parametrize("backend", ["reference", "opencl"])
def test_delay_and_sum_equals_pymust_dasmtx_on_the_same_analytic_signal(scene, backend):
    p, lam, x, z, delays, rf = scene
    iq = pymust.rf2iq(rf, p.fs, p.fc)
    xg, zg = np.meshgrid(np.linspace(x[1] - 4 * lam, x[1] + 4 * lam, 33), np.linspace(z[1] - 2 * lam, z[1] + 2 * lam, 33))
    p.fnumber = 0.0  # the full receive aperture, as clbeam sums
    das = pymust.dasmtx(iq, xg, zg, delays, p, "linear")
    theirs = (das @ iq.flatten(order="F")).reshape(xg.shape, order="F")
    # the same analytic signal: PyMUST's I/Q brought back to the carrier
    t = np.arange(iq.shape[0]) / p.fs
    analytic = (iq * np.exp(2j * np.pi * p.fc * t)[:, None]).T
    y = (np.arange(p.Nelements) - (p.Nelements - 1) / 2) * p.pitch
    offsets = np.stack([np.zeros(p.Nelements), y - y[SOURCE], np.zeros(p.Nelements)], axis=1)
    inp = BeamformInput(analytic, p.fs, 0.0, C, offsets, np.zeros(3), centre_frequency_hz=p.fc)
    r, a = np.hypot(xg - y[SOURCE], zg), np.rad2deg(np.arctan2(xg - y[SOURCE], zg))
    ours = sums_at_points(get_engine(backend), inp, r, a, interp="linear-bb", outputs=("sums",)).s
    assert np.corrcoef(np.abs(ours).ravel(), np.abs(theirs).ravel())[0, 1] >= 0.999
    assert np.median(np.abs(ours) / np.abs(theirs)) == pytest.approx(1.0, rel=1e-3)  # same sum, same scale
