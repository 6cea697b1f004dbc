"""The beams beside the echo's in the detection model (docs/detectability.md) against the element-by-element
sums they stand for, the echo's own beam alone, and an imaged ping."""

import math

import numpy as np
import pytest

from clbeam.evaluation.detectability import Environment, Pipe, band, channel_model, detections, search_beams
from clbeam.evaluation.detectability_beams import (
    MEAN_STEP_S,
    Beams,
    EchoBeside,
    _covariance,
    array_factor,
    heave_draws,
    noise_operator,
)
from clbeam.sim import load_scene

M, PITCH, C = 64, 3.528 / 64, 1500.0
X = (np.arange(M) - (M - 1) / 2) * PITCH


@pytest.fixture(scope="module")
def env():
    return Environment(load_scene("line4"), absorption_db_per_km=0.0)


def test_array_factor_is_the_mean_over_the_elements():
    f, d = np.array([2000.0, 5500.0, 9000.0])[:, None], np.array([0.0, 0.003, 0.02, -0.047, 0.3])[None, :]
    direct = np.mean(np.exp(2j * np.pi * f[..., None] * X * d[..., None] / C), axis=-1)
    np.testing.assert_allclose(array_factor(f, d, M, PITCH, C), direct.real, atol=1e-12)
    np.testing.assert_allclose(direct.imag, 0.0, atol=1e-12)


def test_the_echo_beside_is_the_channels_read_at_their_delays(env):
    """Mean and energy over the channels against ``s(t + x_n Δ / c)`` summed element by element: the mean
    within its table's linear reading, ``(2π b h)² / 8`` of the peak (``b`` the band's reach from its centre),
    the energy within that twice plus the midpoint rule's ``(Δ_τ / T)²``."""
    f, w = band(env)
    model, _ = channel_model(env, Pipe(burial_m=1.0), 900.0)
    spec = (model.echo * w)[None]
    beams = Beams(np.array([-0.04, 0.01, 0.03]), M, PITCH, C)
    t = np.linspace(-4e-4, 4e-4, 23)
    echo = EchoBeside(beams, f, w, spec, t.min() - 1e-4, t.max() + 1e-4)
    shifts = np.array([0.0, 2e-5, -3e-5])
    tt = (t[None, :] + shifts[:, None])[None]                                     # (1, J, L)
    mean, energy = echo.at(tt, np.array([0]))
    s = np.exp(2j * np.pi * (tt[0][:, :, None, None] + X[None, None, :, None] * beams.offsets_sin[:, None, None, None] / C)
               * f) @ spec[0]                                                     # (J, L, M)
    peak = abs(spec.sum())
    b = float(np.max(np.abs(f - np.sum(w * f))))
    tol = (2 * math.pi * b * MEAN_STEP_S) ** 2 / 8
    np.testing.assert_allclose(mean[0], s.mean(axis=-1), atol=tol * peak)
    np.testing.assert_allclose(energy[0], np.sum(np.abs(s) ** 2, axis=-1), atol=M * (2 * tol + 1e-3) * peak ** 2)


def test_the_conditional_noise_has_the_element_by_element_covariance(env):
    """``gain C_oo gain^H + root root^H`` (the beams beside) and ``gain C_oo`` (with the own beam) against the
    covariance of the channels' noise summed at their delays, ``Σ_n R(t₁ − t₂ + x_n (Δ₁ − Δ₂) / c)``."""
    f, w = band(env)
    beams = search_beams(env, 3)
    lags = 2 * 0.2 * np.arange(-5, 6) / C
    gain, root = noise_operator(beams, f, w, lags)
    pts = [(t, d) for d in beams.offsets_sin for t in lags]

    def direct(p, q):
        return np.array([[np.sum(np.exp(2j * np.pi * (a - b + X[:, None] * (da - db) / C) * f) @ w)
                          for b, db in q] for a, da in p])

    own = [(t, 0.0) for t in lags]
    c_oo, c_bo, c_bb = direct(own, own), direct(pts, own), direct(pts, pts)
    scale = float(np.max(np.abs(c_bb)))
    np.testing.assert_allclose(gain @ c_oo, c_bo, atol=1e-8 * scale)
    np.testing.assert_allclose(gain @ c_oo @ gain.conj().T + root @ root.conj().T, c_bb, atol=1e-8 * scale)
    closed = _covariance(beams, f, w, np.array([p[0] for p in pts]), np.array([p[1] for p in pts]),
                         np.array([p[0] for p in pts]), np.array([p[1] for p in pts]))
    np.testing.assert_allclose(closed, c_bb, atol=1e-10 * scale)


def test_the_beams_beside_only_add_to_the_echos_own_beam(env):
    """The echo's own beam gets the same draws with the beams beside as without (its Pd exactly), and a
    ping it detects stays detected."""
    pipe, ranges = Pipe(burial_m=1.0), [900.0, 1300.0, 1700.0]
    alone = detections(env, pipe, ranges, draws=512, beside=0)
    both = detections(env, pipe, ranges, draws=512)
    for a, b in zip(alone, both):
        assert a["pd"] == b["pd_own_beam"] == a["pd_own_beam"]
        assert b["pd"] >= b["pd_own_beam"]


def test_heave_draws_follow_the_arcsine_law():
    from scipy import stats

    h = heave_draws(0.6, 0, 4096)
    assert stats.kstest(h, stats.arcsine(loc=-0.6, scale=1.2).cdf).pvalue > 1e-3
    np.testing.assert_array_equal(heave_draws(0.6, 100, 10), h[100:110])


@pytest.mark.slow
def test_the_echo_beside_matches_an_imaged_ping():
    """A ping at 60 dB SNR, its grid's nodes halfway between the echo's range (mud, 1 m, 1000 m; the ship
    heaved 0.55 m): the imaged intensity at the nodes about the echo, in beams 1-6 degrees either side,
    against the model's echo slid by the heave (:meth:`EchoBeside.at`), within 3 dB wherever the image
    stands above -20 dB of the echo's maximum (the Lanczos-8 reading and the model's Fresnel sum differ
    by about 1 dB there)."""
    from clbeam.evaluation import detectability_validation as dv
    from clbeam.imaging.imager import Imager, ImagingOptions
    from clbeam.io.pingfile import pings_from_dataset
    from clbeam.sim import simulate

    scene = dv.validation_scene("mud", (1000.0,), pings=1, snr_db=60.0)
    ds = simulate(scene, pings=[0], seed=7)
    ping = list(pings_from_dataset(ds))[0]
    e = dv._echoes(ds)[0]["S1000"]
    images = {frac: Imager(dv._grid(e, frac), ImagingOptions(interp="lanczos8", upsample=1)).image(ping)
              for frac in (0.0, 0.5)}
    top = float(np.max(images[0.0].intensity))
    menv = Environment(scene, absorption_db_per_km=0.0)
    model, _ = channel_model(menv, Pipe(burial_m=1.0), 1000.0)
    spec = (model.echo * model.weight)[None]
    peak = abs(spec.sum()) ** 2
    th = math.radians(e["angle_deg"])
    grid = dv._grid(e, 0.5)
    ir = int(np.argmin(np.abs(grid.ranges_m - e["range_m"])))
    ia = int(np.argmin(np.abs(grid.angles_deg - e["angle_deg"])))
    for da in (-60, -30, -10, 10, 30, 60):
        du = math.sin(math.radians(grid.angles_deg[ia + da])) - math.sin(th)
        echo = EchoBeside(Beams(np.array([du]), M, PITCH, C), model.frequency_hz, model.weight, spec, -3e-3, 3e-3)
        cells = grid.ranges_m[ir - 2:ir + 3] - e["range_m"]
        t = (2 * cells / C - 2 * ping.heave_m * math.tan(th) * du / C)[None, None, :]
        want = 10 * np.log10(np.abs(echo.at(t, np.array([0]))[0][0, 0]) ** 2 / peak)
        got = 10 * np.log10(images[0.5].intensity[ia + da, ir - 2:ir + 3] / top)
        shown = got > -20
        assert shown.any()
        np.testing.assert_allclose(got[shown], want[shown], atol=3.0)
