"""Nadir specular echoes from the layered coherent forward model.

With ``seabed.specular_model = "forward"`` the seabed and sub-bottom echoes
carry the forward model's frequency-dependent factors (reflection,
transmission through the seabed both ways, attenuation in the sediment,
Eckart roughness loss).  Each echo is measured on single channels: compress
with the replica, gate the compressed echo and divide its spectrum by the
equally gated compressed replica's.  The expectation is built here from
:mod:`clbeam.seabed.forward` directly: ``|A_i(f)| = spreading × |V_i T T' H²|``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from clbeam.errors import OptionError
from clbeam.model.pulse import lfm_replica
from clbeam.seabed.forward import (
    Interface,
    Layer,
    PowerLawAttenuation,
    Seabed,
    specular_echoes,
    water_column,
)
from clbeam.sim import load_scene, simulate

C, FS = 1500.0, 40000.0
REPLICA = lfm_replica(f0_hz=2000.0, f1_hz=9000.0, duration_s=0.08, sample_rate_hz=FS)
H, D = 225.0, 20.0             # transducers above the seabed, sediment thickness (m)
CS, RHO = 0.98, 1.25           # sediment speed and density ratios
CB, RHOB = 1.05, 1.6           # below the sub-bottom
SIGMA1, SIGMA2 = 0.02, 0.03    # RMS roughness of seabed and sub-bottom (m)
FREQS = np.array([3000.0, 5500.0, 8000.0])


def scene(model: str):
    return load_scene("point", snr_db=None, overrides={
        "target": [],
        "seabed": {"depth_m": H + 5.0, "sound_speed_ratio": CS, "density_ratio": RHO, "attenuation_db_per_m": 0.15,
                   "attenuation_ref_hz": 5000.0, "specular": True, "multiple": False, "specular_model": model,
                   "roughness_m": SIGMA1},
        "subbottom": {"depth_below_seabed_m": D, "sound_speed_ratio": CB, "density_ratio": RHOB, "specular": True,
                      "roughness_m": SIGMA2}})


def expected_amplitudes(freqs_hz) -> np.ndarray:
    """``(2, n_freq)`` echo amplitudes of seabed and sub-bottom at the array
    centre: the forward model's ``|V_i prod(T T') prod(H^2)|`` times the
    spherical spreading ``1 / (c tau_i)`` of the unfolded path (the
    simulator's samples are pressure re the source pressure at 1 m; the
    forward model's own spreading term ``p0 / (2 c tau)`` is this with
    ``p0 = 1/2`` in those units)."""
    seabed = Seabed((water_column(H, sound_speed_m_s=C),
                     Layer(D, CS * C, RHO * 1000.0, PowerLawAttenuation(0.15 / 5.0, 1.0), Interface(SIGMA1)),
                     Layer(math.inf, CB * C, RHOB * 1000.0, top=Interface(SIGMA2))))
    e = specular_echoes(seabed, freqs_hz, incidence_deg=0.0)
    assert np.allclose(e.times_s, [2 * H / C, 2 * H / C + 2 * D / (CS * C)])
    return np.abs(e.reflection * e.transmission * e.attenuation) / (C * e.times_s[:, None])


def echo_amplitudes(channel: np.ndarray) -> np.ndarray:
    """``|Y(f)| / |X(f)|`` at :data:`FREQS`: the amplitude of the single echo
    in ``channel`` (a record holding one echo of the replica ``X``)."""
    n = 1 << 16
    bins = np.rint(FREQS * n / FS).astype(int)
    return np.abs(np.fft.rfft(channel.astype(np.float64), n)[bins]) / np.abs(np.fft.rfft(REPLICA, n)[bins])


def test_forward_specular_echoes_carry_the_forward_model_amplitudes_per_frequency():
    # one echo per simulation, so that the spectrum of the whole record is
    # that echo's (the two overlap: 27 ms apart, 80 ms long)
    seabed_only = simulate(load_scene(scene("forward"), overrides={"subbottom.specular": False}))
    sub_only = simulate(load_scene(scene("forward"), overrides={"seabed.specular": False}))
    want = expected_amplitudes(FREQS)
    # the spreading above is the array centre's; element n is sqrt((c tau)^2 + y_n^2) from the image source
    y_el = (np.arange(64) - 31.5) * 3.528 / 64
    ctau = np.array([2 * H, 2 * (H + D / CS)])
    for n in (0, 31, 63):
        got = np.array([echo_amplitudes(seabed_only.samples.values[0, n]),
                        echo_amplitudes(sub_only.samples.values[0, n])])
        scale = ctau / np.hypot(ctau, y_el[n])
        # Tolerance: the fractional-delay filter's complex error is below
        # 5e-3 in the band; the echo filter's band window is 1 there and its
        # 512-sample blocks hold the whole 1024-sample response of the smooth
        # factors; float32 storage adds 1e-7.  1 % covers these with margin.
        np.testing.assert_allclose(got, want * scale[:, None], rtol=1e-2)
    # the roughness makes the echoes frequency dependent (Eckart: exp(-2 k^2 sigma^2)
    # on the seabed: 0.88 at 3 kHz, 0.51 at 8 kHz), which impedance contrasts do not
    assert want[0, 2] / want[0, 0] < 0.65


def test_impedance_model_stays_the_default_and_the_forward_model_agrees_without_roughness():
    assert load_scene("line1").seabed.specular_model == "impedance"
    smooth = {"seabed.roughness_m": 0.0, "subbottom.roughness_m": 0.0}
    for only in ({"subbottom.specular": False}, {"seabed.specular": False}):
        a = simulate(load_scene(scene("impedance"), overrides=smooth | only)).samples.values[0, 31]
        b = simulate(load_scene(scene("forward"), overrides=smooth | only)).samples.values[0, 31]
        # normal incidence on smooth fluid interfaces: the forward model's V
        # is the impedance contrast and T T' = 1 - V^2, with the same linear
        # attenuation, so the echoes agree in amplitude and phase across the
        # band.  Outside it they differ: the forward echo passes the band
        # window (1 over 1-10 kHz, cosine to 0 over another 1 kHz), the
        # impedance seabed echo is deposited unfiltered.
        n = 1 << 16
        bins = np.rint(np.linspace(2200.0, 8800.0, 34) * n / FS).astype(int)
        ratio = np.fft.rfft(b.astype(np.float64), n)[bins] / np.fft.rfft(a.astype(np.float64), n)[bins]
        # the delay filter's error (5e-3) is the same in both: it cancels
        # except for float32 storage (1e-7 of the peak) and the truncated
        # tails of the block filter (below 1e-4)
        np.testing.assert_allclose(ratio, 1.0, atol=1e-3)
    with pytest.raises(OptionError, match="specular_model"):
        load_scene("line1", overrides={"seabed.specular_model": "kirchhoff"})
    with pytest.raises(OptionError, match="roughness_m"):
        load_scene("line1", overrides={"subbottom.roughness_m": -1.0})
