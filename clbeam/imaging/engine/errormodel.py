"""How far an imaging setting's coherent sum is from the exact one: a model, and the cheapest setting within a budget.

Two interpolations stand between the record and the image, and each is a
linear filter whose error on a complex exponential is known in closed form:

* **in time** (the interpolation mode, on the raw or upsampled analytic
  signal): a sample at fractional position ``x`` is ``sum_m w_m(x) p[k+m]``;
  on ``exp(2 pi i phi k)`` (``phi = f / fs``) the relative error is
  ``H_t(x, phi) - 1`` with ``H_t = sum_m w_m(x) exp(2 pi i phi (m - x))``.
  The basebanded modes see ``phi = (f - f_c) / fs``;
* **in angle** (beam sampling, :mod:`clbeam.imaging.engine.beams`): the sum
  ``S(theta)`` of a point scatterer holds, from element ``n`` and frequency
  ``f``, a component of ``f o_n / c`` cycles per radian; interpolated from
  beams ``d theta`` apart, its error is ``H_b(x, nu) - 1`` at
  ``nu = f o_n d theta / c`` cycles per beam step.

The model averages ``|H - 1|^2`` over the fractional position and over the
signal's spectrum: the band (flat, a compressed LFM) for the time
interpolation; for the angular one, the spectrum of ``S`` itself, whose
amplitude at ``nu`` is the sum of the elements' and frequencies'
contributions there (they add coherently at a scatterer).  The two errors
are independent and add.  An error ``dS`` of the sum changes the intensity
by ``2 Re(S* dS)``, so the intensity's relative error power is about
``2 (E_t + E_b)``: the prediction in decibels is ``10 log10(2 (E_t + E_b))``
(:data:`INTENSITY_FACTOR`).  ``tests/imaging/test_errormodel.py`` checks it
against measured errors across bands and sample rates.

:func:`cheapest_setting` picks, for a budget in dB, the setting of least
predicted cost among the modes, upsampling factors and beam samplings, with
the relative costs :data:`MODE_COST` measured by ``clbeam bench``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.imaging.engine.beams import BeamSampling, kaiser_sinc
from clbeam.imaging.engine.common import INTERP_MODES, InterpMode

#: fractional positions averaged over
N_POSITIONS = 64
#: frequencies of the band averaged over
N_FREQUENCIES = 48
#: time per cell and channel of each mode relative to nearest, from ``clbeam bench`` (README table)
MODE_COST = {"nearest": 1.0, "linear": 1.0, "linear-bb": 2.3, "cubic": 1.4, "lanczos4": 3.6, "lanczos8": 5.4}
#: extra cost factor of an upsampled record (its gathers leave the cache): measured ratios of ``x2``/``x4`` rows
UPSAMPLE_COST = {1: 1.0, 2: 1.9, 4: 3.5}
#: cost of one interpolation tap of the beam-to-grid step per output cell, relative to one cell-channel of nearest
TAP_COST = 1.0
#: cost of the FFT upsampling per sample and log2(length), relative to one cell-channel of nearest
FFT_COST = 0.5
#: intensity error power over the sum's: dI = 2 Re(S* dS), between 2 (random phase) and 4 (in phase)
INTENSITY_FACTOR = 2.0
#: the beam samplings considered (oversampling, taps)
BEAM_CHOICES = tuple(BeamSampling(k, t) for k in (1.25, 1.5, 2.0) for t in (6, 8, 12, 16))


def tap_weights(mode: InterpMode, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tap offsets ``m`` and weights ``w[m, x]`` of ``mode`` at fractions ``x`` in [0, 1)
    (the kernels' interpolators, ``kernels/interp.h``)."""
    if mode.name == "nearest":
        m = np.array([0, 1])
        return m, np.stack([x < 0.5, x >= 0.5]).astype(np.float64)
    if mode.name in ("linear", "linear-bb"):
        return np.array([0, 1]), np.stack([1 - x, x])
    if mode.name == "cubic":  # Keys (1981), a = -0.5
        m = np.array([-1, 0, 1, 2])
        d = np.abs(x[None, :] - m[:, None])
        w = np.where(d <= 1, 1.5 * d**3 - 2.5 * d**2 + 1, np.where(d < 2, -0.5 * d**3 + 2.5 * d**2 - 4 * d + 2, 0.0))
        return m, w
    a = mode.lanczos_a
    require(a > 0, OptionError, f"no error model for interpolation mode '{mode.name}'")
    m = np.arange(-(a - 1), a + 1)
    d = x[None, :] - m[:, None]
    return m, np.sinc(d) * np.sinc(d / a)


def time_error(mode: InterpMode, band_hz: tuple, sample_rate_hz: float, upsample: int = 1,
               n_channels: int = 1) -> float:
    """Relative error power of the coherent sum from interpolating the channels in time.

    The error ``H_t - 1`` splits into its mean over the fractional position
    (a bias, the same in every channel, so it adds coherently across the
    array like the signal) and its fluctuation (the channels' fractional
    positions differ, so it adds incoherently: divided by ``M``).

    Parameters
    ----------
    mode : InterpMode
    band_hz : (float, float)
        Signal band (Hz), flat.
    sample_rate_hz : float
        Sample rate of the record (Hz), before upsampling.
    upsample : int
        FFT upsampling factor.
    n_channels : int
        Channels summed.
    """
    fs = sample_rate_hz * upsample
    f = np.linspace(band_hz[0], band_hz[1], N_FREQUENCIES)
    if mode.baseband:
        f = f - 0.5 * (band_hz[0] + band_hz[1])
    x = (np.arange(N_POSITIONS) + 0.5) / N_POSITIONS
    m, w = tap_weights(mode, x)
    phase = np.exp(2j * np.pi * (f[None, None, :] / fs) * (m[:, None, None] - x[None, :, None]))
    h = np.einsum("mx,mxf->xf", w, phase)
    bias = np.abs(np.mean(h - 1.0, axis=0)) ** 2
    fluctuation = np.mean(np.abs(h - np.mean(h, axis=0)) ** 2, axis=0)
    return float(np.mean(bias + fluctuation / max(n_channels, 1)))


def angular_spectrum(offsets_m: np.ndarray, band_hz: tuple, sound_speed_m_s: float, step_rad: float,
                     n_bins: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """Spectrum of a point scatterer's sum across angle, in cycles per beam step.

    Element ``n`` (offset ``o_n`` across the beam) and frequency ``f``
    contribute at ``nu = f o_n step / c``; contributions in one frequency
    bin add coherently.  Returns the bin centres and the normalised power.
    """
    o = np.asarray(offsets_m, dtype=np.float64)
    f = np.linspace(band_hz[0], band_hz[1], N_FREQUENCIES)
    nu = (f[:, None] * o[None, :] * step_rad / sound_speed_m_s).ravel()
    top = max(float(np.max(np.abs(nu))), 1e-12)
    amp, edges = np.histogram(nu, bins=n_bins, range=(-top, top))
    power = amp.astype(np.float64) ** 2
    return 0.5 * (edges[1:] + edges[:-1]), power / power.sum()


def beam_error(sampling: BeamSampling, nu: np.ndarray, power: np.ndarray) -> float:
    """Mean relative error power of the angular interpolation on a spectrum ``power(nu)``
    (cycles per beam step), with the weights of :func:`clbeam.imaging.engine.beams.beam_plan`."""
    half = sampling.taps // 2
    x = (np.arange(N_POSITIONS) + 0.5) / N_POSITIONS
    k = np.arange(-half + 1, half + 1)
    w = kaiser_sinc(x[:, None] - k[None, :], half)
    w /= w.sum(axis=1, keepdims=True)
    phase = np.exp(2j * np.pi * nu[None, None, :] * (k[None, :, None] - x[:, None, None]))
    h = np.einsum("xk,xkn->xn", w, phase)
    return float(np.sum(np.mean(np.abs(h - 1.0) ** 2, axis=0) * power))


@dataclass(frozen=True)
class Setting:
    """One imaging setting with its predicted error and cost.

    Attributes
    ----------
    interp : str
        Interpolation mode.
    upsample : int
        FFT upsampling.
    beams : BeamSampling or None
        Beam sampling, or every cell directly.
    error_db : float
        Predicted error power of the intensity relative to it (dB).
    cost : float
        Predicted time, in cell-channels of ``nearest`` per output cell and channel.
    measured : str
        The errors measured on the ping's own geometry (:mod:`clbeam.imaging.budget`), where they were.
    """

    interp: str
    upsample: int
    beams: BeamSampling | None
    error_db: float
    cost: float
    measured: str = ""

    def describe(self) -> str:
        """One line: mode, upsampling, beams, predicted error (and what was measured on the ping's geometry)."""
        beams = f"beams x{self.beams.oversampling:g}/{self.beams.taps} taps" if self.beams else "direct"
        if self.beams and self.beams.domain == "frequency":
            beams += " in the frequency domain"
        up = f" x{self.upsample}" if self.upsample > 1 else ""
        measured = f"; measured {self.measured}" if self.measured else ""
        return f"{self.interp}{up}, {beams}: predicted {self.error_db:.1f} dB{measured}"


def predicted_settings(offsets_m: np.ndarray, band_hz: tuple, sample_rate_hz: float, sound_speed_m_s: float, *,
                       n_angles: int, n_ranges: int, angle_span_rad: float, n_samples: int,
                       samplings: tuple = BEAM_CHOICES) -> list[Setting]:
    """Every candidate setting with its predicted error and cost, for one array, band and grid.

    Parameters
    ----------
    offsets_m : numpy.ndarray
        Element offsets across the beam from the grid centre (m) (the ``y`` offsets for a horizontal array).
    band_hz : (float, float)
        Signal band (Hz).
    sample_rate_hz : float
        Record's sample rate (Hz).
    sound_speed_m_s : float
        Sound speed (m/s).
    n_angles, n_ranges : int
        Output angles and ranges.
    angle_span_rad : float
        Output angle span (rad).
    n_samples : int
        Samples per channel of the record.
    samplings : tuple of BeamSampling
        The beam samplings to predict (time domain).
    """
    n_channels = len(offsets_m)
    limit = band_hz[1] * float(np.max(np.abs(offsets_m))) / sound_speed_m_s   # cycles per radian
    beams = []
    for sampling in samplings:
        step = 1.0 / (2.0 * limit * sampling.oversampling)
        nu, power = angular_spectrum(offsets_m, band_hz, sound_speed_m_s, step)
        n_beams = angle_span_rad / step + sampling.taps + 1
        beams.append((sampling, beam_error(sampling, nu, power), min(1.0, n_beams / n_angles),
                      TAP_COST * sampling.taps / n_channels))
    out = []
    for name, mode in INTERP_MODES.items():
        if name not in MODE_COST:
            continue
        for up in (1, 2, 4):
            e_t = time_error(mode, band_hz, sample_rate_hz, up, n_channels)
            cost_cell = MODE_COST[name] * UPSAMPLE_COST[up]
            fft = 0.0 if up == 1 else FFT_COST * up * n_samples * math.log2(up * n_samples) / (n_angles * n_ranges)
            out.append(Setting(name, up, None, _db(e_t), cost_cell + fft))
            out.extend(Setting(name, up, sampling, _db(e_t + e_b), cost_cell * fraction + taps + fft)
                       for sampling, e_b, fraction, taps in beams)
    return out


def _db(error_power: float) -> float:
    return 10 * math.log10(max(INTENSITY_FACTOR * error_power, 1e-30))


def cheapest_setting(max_error_db: float, settings: list[Setting]) -> Setting:
    """The setting of least cost whose predicted error is within ``max_error_db`` (dB)."""
    ok = [s for s in settings if s.error_db <= max_error_db]
    require(bool(ok), OptionError, f"no setting reaches {max_error_db:g} dB (best: "
            f"{min(s.error_db for s in settings):.1f} dB); allow a larger error")
    return min(ok, key=lambda s: (s.cost, s.error_db))


def choose_setting(settings: list[Setting], max_error_db: float, *, interp: str | None = None,
                   upsample: int | None = None, beams="auto") -> Setting:
    """The setting an Imager uses: the cheapest within the budget, under the options the user fixed.

    Parameters
    ----------
    settings : list of Setting
        :func:`predicted_settings` of the ping.
    max_error_db : float
        Error budget of the intensity (dB).
    interp : str, optional
        A forced mode: it is used even when it alone exceeds the budget, and
        beam sampling may then add at most 1 dB to its own error.
    upsample : int, optional
        A forced upsampling factor.
    beams : "auto", None or BeamSampling
        Beam sampling chosen by the budget, off, or forced.
    """
    # frequency-domain beams are chosen as their time-domain twin (the model's bound: they add no time
    # interpolation), the time interpolation then serving the rows they leave to the time domain
    twin = beams if not isinstance(beams, BeamSampling) or beams.domain == "time" else \
        dataclasses.replace(beams, domain="time")
    if twin is not beams:
        return dataclasses.replace(choose_setting(settings, max_error_db, interp=interp, upsample=upsample,
                                                  beams=twin), beams=beams)

    def fits(s: Setting) -> bool:
        return ((interp is None or s.interp == interp) and (upsample is None or s.upsample == upsample)
                and (beams == "auto" or s.beams == beams))

    candidates = [s for s in settings if fits(s)]
    if interp is not None and not candidates:   # a mode the model does not cover ("exact"): as forced
        return Setting(interp, upsample or 1, None if beams == "auto" else beams, math.nan, math.nan)
    if interp is not None:
        own = min(s.error_db for s in candidates if s.beams is None) if any(s.beams is None for s in candidates) \
            else min(s.error_db for s in candidates)
        max_error_db = max(max_error_db, own + 1.0)
        candidates = [s for s in candidates if s.error_db <= max_error_db] or candidates
    return cheapest_setting(max_error_db, candidates)
