"""Seafloor backscattering strength of a rough, lossy fluid half-space.

The model is the APL-UW TR 9407 (1994, section IV) bottom-backscatter
model that Fonseca et al. (2005) invert, in the fluid form of Jackson,
Winebrenner & Ishimaru (1986) and Mourad & Jackson (1989).  All angles
are **grazing** angles ``theta`` (from the horizontal) in degrees; all
cross sections are per unit area per unit solid angle (linear), and the
backscattering strength is ``S_b = 10 log10(sigma_r + sigma_v)`` dB.

Pieces (``k = 2 pi f / c_w``, ``kappa = (1 + i delta)/nu``):

* sediment vertical wavenumber ratio ``P = sqrt(kappa^2 - cos^2 theta)``,
  branch ``Im P >= 0``; Rayleigh coefficient
  ``R = (rho sin theta - P) / (rho sin theta + P)``;
* Kirchhoff term (power-law spectrum ``W(K) = w2 K^-gamma``,
  ``alpha = gamma/2 - 1``)
  ``sigma_kr = |R(90)|^2 / (8 pi sin^2 cos^2) * I(q)``,
  ``I(q) = int_0^inf exp(-q u^(2 alpha)) J0(u) u du``,
  ``q = sin^2 theta cos^(-2 alpha) theta C_h^2 2^(1 - 2 alpha) k^(2 - 2 alpha)``,
  ``C_h^2 = 2 pi w2 Gamma(2 - alpha) 2^(-2 alpha) / (alpha (1 - alpha) Gamma(1 + alpha))``;
* small-roughness perturbation term
  ``sigma_pr = k^4/4 |1 + R|^4 |G|^2 W(2 k cos theta)``,
  ``G = (1/rho - 1)(-cos^2 theta - P^2/rho) + 1 - kappa^2/rho``;
* volume term ``sigma_v = 5 delta sigma2 |1 + R|^4 / (ln 10 nu rho^2 Im P)``
  (the transmitted intensity ``|1 + R|^2 / rho`` each way, integrated over
  depth against the two-way loss ``exp(-4 k Im P z)``; ``sigma2`` is the
  volume-scattering coefficient per dB/m of attenuation, hence
  ``20/ln 10 / 4 = 5/ln 10``);
* joining rule: the lowest-order small-slope approximation
  ``sigma_r = sigma_pr I(q) / (c1 q)``, ``c1 q`` the first term of ``I``
  at small ``q``.  It equals ``sigma_pr`` where the Kirchhoff integral is
  in its small-``q`` regime (away from nadir) and equals ``sigma_kr``
  exactly at nadir, with no switch angle to choose.  The handbook instead
  blends ``sigma_kr`` and ``sigma_pr`` with a logistic weight; see
  ``docs/avo.md`` for the comparison with its published curves.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import interpolate, special

from clbeam.constants import SOUND_SPEED_M_S
from clbeam.errors import OptionError, require
from clbeam.seabed.avo.sediment import SedimentParams, sediment_from_grain_size

#: Water sound speed used by default for the acoustic wavenumber (m/s).
DEFAULT_SOUND_SPEED_M_S = SOUND_SPEED_M_S
#: Lambert parameter of Mackenzie (1961), 10 log10(mu) in dB.
LAMBERT_MU_DB = -27.0

_GL_X, _GL_W = np.polynomial.legendre.leggauss(20)
# Above this scaled frequency b the Kirchhoff integral uses its series.
_B_SERIES = 100.0
_SERIES_TERMS = 20
_TAIL = 40.0  # exp(-40) ~ 4e-18: where the quadrature stops


# --------------------------------------------------------------------------- basics
def _grazing_rad(grazing_deg) -> np.ndarray:
    g = np.asarray(grazing_deg, dtype=np.float64)
    bad = ~((g > 0) & (g <= 90))
    require(not bad.any(), OptionError,
            f"grazing_deg must lie in (0, 90] degrees, got {g[bad].ravel()[0] if bad.any() else 0:g}")
    return np.radians(g)


def _wavenumber(frequency_hz: float, sound_speed_water_m_s: float) -> float:
    require(np.isfinite(frequency_hz) and frequency_hz > 0, OptionError,
            f"frequency_hz must be > 0 Hz, got {frequency_hz!r}")
    require(np.isfinite(sound_speed_water_m_s) and sound_speed_water_m_s > 0, OptionError,
            f"sound_speed_water_m_s must be > 0 m/s, got {sound_speed_water_m_s!r}")
    return 2.0 * math.pi * float(frequency_hz) / float(sound_speed_water_m_s)


def _kappa(sed: SedimentParams) -> complex:
    return (1.0 + 1j * sed.delta) / sed.nu


def vertical_wavenumber_ratio(grazing_deg, sediment: SedimentParams) -> np.ndarray:
    """``P = sqrt(kappa^2 - cos^2 theta)`` on the branch ``Im P >= 0`` (TR 9407).

    ``k P`` is the vertical wavenumber of the transmitted wave; ``Im P >= 0``
    makes it decay downward (below the critical angle it is evanescent).

    Parameters
    ----------
    grazing_deg : array_like
        Grazing angles (deg), in (0, 90].
    sediment : SedimentParams
        Sediment parameters.

    Returns
    -------
    numpy.ndarray
        complex128, shape of ``grazing_deg``.
    """
    t = _grazing_rad(grazing_deg)
    p = np.sqrt(_kappa(sediment) ** 2 - np.cos(t) ** 2 + 0j)
    return np.where(p.imag < 0, -p, p)


def reflection_coefficient(grazing_deg, sediment: SedimentParams) -> np.ndarray:
    """Rayleigh reflection coefficient of a lossy fluid half-space.

    ``R = (rho sin theta - P) / (rho sin theta + P)`` (TR 9407, section IV;
    Brekhovskikh).  At normal incidence and without loss it reduces to
    ``(rho nu - 1) / (rho nu + 1)``.

    Parameters
    ----------
    grazing_deg : array_like
        Grazing angles (deg), in (0, 90].
    sediment : SedimentParams
        Sediment parameters.

    Returns
    -------
    numpy.ndarray
        complex128 pressure reflection coefficient.
    """
    s = np.sin(_grazing_rad(grazing_deg))
    p = vertical_wavenumber_ratio(grazing_deg, sediment)
    return (sediment.rho * s - p) / (sediment.rho * s + p)


def reflection_loss_db(grazing_deg, sediment: SedimentParams) -> np.ndarray:
    """Bottom reflection loss ``-20 log10 |R|`` (dB), TR 9407.

    Parameters
    ----------
    grazing_deg : array_like
        Grazing angles (deg), in (0, 90].
    sediment : SedimentParams
        Sediment parameters.
    """
    return -20.0 * np.log10(np.abs(reflection_coefficient(grazing_deg, sediment)))


def critical_angle_deg(sediment: SedimentParams) -> float:
    """Critical grazing angle ``arccos(1/nu)`` (deg); NaN when ``nu <= 1``.

    Below it a lossless fast seabed reflects totally (Snell's law).

    Parameters
    ----------
    sediment : SedimentParams
        Sediment parameters.
    """
    if sediment.nu <= 1.0:
        return float("nan")
    return math.degrees(math.acos(1.0 / sediment.nu))


# --------------------------------------------------------------------------- Kirchhoff
def _alpha(sed: SedimentParams) -> float:
    return sed.gamma / 2.0 - 1.0


def structure_constant(sediment: SedimentParams) -> float:
    """Structure-function constant ``C_h^2`` (m^(2 - 2 alpha)) of the roughness.

    ``D(r) = <(h(r) - h(0))^2> = C_h^2 r^(2 alpha)`` for the power-law
    spectrum ``W(K) = w2 K^-gamma``:
    ``C_h^2 = 2 pi w2 Gamma(2 - alpha) 2^(-2 alpha) / (alpha (1 - alpha) Gamma(1 + alpha))``
    (TR 9407, section IV).

    Parameters
    ----------
    sediment : SedimentParams
        Sediment parameters (``w2`` taken in SI, :attr:`SedimentParams.w2_si`).
    """
    a = _alpha(sediment)
    return (2.0 * math.pi * sediment.w2_si * math.gamma(2.0 - a) * 2.0 ** (-2.0 * a)
            / (a * (1.0 - a) * math.gamma(1.0 + a)))


def _series_terms(alpha: float) -> tuple[np.ndarray, np.ndarray]:
    n = np.arange(1, _SERIES_TERMS + 1, dtype=np.float64)
    return (2.0 ** (2.0 * alpha * n + 1.0) * special.gamma(1.0 + alpha * n)
            * special.rgamma(-alpha * n) / special.gamma(n + 1.0)), n


def _kirchhoff_series(q: np.ndarray, alpha: float) -> np.ndarray:
    """``I(q)`` from ``sum_n (-q)^n/n! 2^(2 alpha n + 1) Gamma(1 + alpha n)/Gamma(-alpha n)``."""
    coef, n = _series_terms(alpha)
    return np.sum(coef[None, :] * (-q[:, None]) ** n[None, :], axis=1)


def _kirchhoff_scaled(b: float, alpha: float) -> float:
    """``K(b) = int_0^inf exp(-s^(2 alpha)) J0(b s) s ds`` by Gauss-Legendre panels.

    Panels are half a period of ``J0(b s)`` wide (``pi / b``), with a
    geometric ladder towards ``s = 0``, where ``s^(2 alpha)`` is not smooth.
    """
    s_max = _TAIL ** (1.0 / (2.0 * alpha))
    ladder = np.logspace(-4.0, math.log10(s_max), 2 * (4 + int(math.ceil(math.log10(s_max)))) + 1)
    edges = [np.array([0.0, s_max]), ladder]
    if b > 0:
        edges.append(np.arange(1, int(s_max * b / math.pi) + 1) * (math.pi / b))
    e = np.unique(np.concatenate(edges))
    e = e[e <= s_max]
    lo, hi = e[:-1, None], e[1:, None]
    s = 0.5 * (hi - lo) * _GL_X + 0.5 * (hi + lo)
    f = np.exp(-s ** (2.0 * alpha)) * special.j0(b * s) * s
    return float(np.sum(0.5 * (hi - lo)[:, 0] * (f @ _GL_W)))


def kirchhoff_integral(q, alpha: float) -> np.ndarray:
    """``I(q) = int_0^inf exp(-q u^(2 alpha)) J0(u) u du`` (TR 9407 Kirchhoff integral).

    Computed as ``q^(-1/alpha) K(q^(-1/(2 alpha)))`` with
    ``K(b) = int exp(-s^(2 alpha)) J0(b s) s ds`` by Gauss-Legendre panels
    half a period of ``J0(b s)`` wide, and for small ``q`` (``b > 100``) by the
    series ``sum_n (-q)^n / n! 2^(2 alpha n + 1) Gamma(1 + alpha n) / Gamma(-alpha n)``
    (term-wise Hankel transform of the exponential).  Closed forms:
    ``q / (1 + q^2)^(3/2)`` for ``alpha = 1/2``, ``exp(-1/(4q)) / (2q)``
    for ``alpha = 1``.

    Parameters
    ----------
    q : array_like
        Roughness parameter, > 0.
    alpha : float
        Structure-function exponent ``gamma/2 - 1``, in (0, 1].

    Returns
    -------
    numpy.ndarray
        float64, shape of ``q``.
    """
    q = np.asarray(q, dtype=np.float64)
    require(0.0 < alpha <= 1.0, OptionError, f"alpha must lie in (0, 1], got {alpha!r}")
    require(bool(np.all(q > 0)), OptionError, "Kirchhoff parameter q must be > 0")
    flat = q.ravel()
    b = flat ** (-1.0 / (2.0 * alpha))
    out = np.empty_like(flat)
    big = b > _B_SERIES
    if big.any():
        out[big] = _kirchhoff_series(flat[big], alpha)
    for i in np.flatnonzero(~big):
        out[i] = flat[i] ** (-1.0 / alpha) * _kirchhoff_scaled(b[i], alpha)
    return out.reshape(q.shape)


@functools.lru_cache(maxsize=8)
def _scaled_spline(alpha: float) -> interpolate.CubicSpline:
    """Cubic spline of ``ln K(b)`` against ``log10 b`` on ``[1e-3, 100]``.

    ``K`` is a 2-D isotropic stable density up to a constant, positive and
    smooth in ``b``; 501 nodes reproduce the quadrature to about 1e-9.
    """
    lb = np.linspace(-3.0, math.log10(_B_SERIES), 501)
    return interpolate.CubicSpline(lb, np.log([_kirchhoff_scaled(10.0 ** x, alpha) for x in lb]))


def _kirchhoff_shape(t: np.ndarray, sed: SedimentParams, k: float) -> np.ndarray:
    """``sigma_kr / |R(90)|^2``, regular at nadir (grazing ``t`` in rad)."""
    a = _alpha(sed)
    c = structure_constant(sed) * 2.0 ** (1.0 - 2.0 * a) * k ** (2.0 - 2.0 * a)
    s, co = np.sin(t).ravel(), np.cos(t).ravel()
    out = np.empty_like(s)
    b = s ** (-1.0 / a) * co * c ** (-1.0 / (2.0 * a))
    big = b > _B_SERIES
    if big.any():
        q = s[big] ** 2 * co[big] ** (-2.0 * a) * c
        out[big] = _kirchhoff_series(q, a) / (8.0 * math.pi * s[big] ** 2 * co[big] ** 2)
    kb = np.empty(int((~big).sum()))
    bb = b[~big]
    tiny = bb < 1e-3
    kb[~tiny] = np.exp(_scaled_spline(a)(np.log10(bb[~tiny])))
    kb[tiny] = [_kirchhoff_scaled(x, a) for x in bb[tiny]]
    # I(q) / cos^2 = (sin^2 C)^(-1/alpha) K(b): finite at cos = 0.
    out[~big] = (s[~big] ** 2 * c) ** (-1.0 / a) * kb / (8.0 * math.pi * s[~big] ** 2)
    return out.reshape(t.shape)


def kirchhoff_cross_section(grazing_deg, sediment: SedimentParams, frequency_hz: float, *,
                            sound_speed_water_m_s: float = DEFAULT_SOUND_SPEED_M_S) -> np.ndarray:
    """Kirchhoff roughness cross section ``sigma_kr`` (linear), TR 9407.

    ``sigma_kr = |R(90)|^2 / (8 pi sin^2 theta cos^2 theta) I(q)`` with
    ``I`` from :func:`kirchhoff_integral`; at nadir it tends to
    ``|R(90)|^2 / (8 pi) Gamma(1/alpha) / (2 alpha) (C_h^2 2^(1-2 alpha) k^(2-2 alpha))^(-1/alpha)``.

    Parameters
    ----------
    grazing_deg : array_like
        Grazing angles (deg), in (0, 90].
    sediment : SedimentParams
        Sediment parameters.
    frequency_hz : float
        Acoustic frequency (Hz).
    sound_speed_water_m_s : float
        Water sound speed for ``k`` (m/s).
    """
    t = _grazing_rad(grazing_deg)
    k = _wavenumber(frequency_hz, sound_speed_water_m_s)
    r90 = abs((sediment.rho - _kappa(sediment)) / (sediment.rho + _kappa(sediment)))
    return r90 ** 2 * _kirchhoff_shape(t, sediment, k)


def perturbation_cross_section(grazing_deg, sediment: SedimentParams, frequency_hz: float, *,
                               sound_speed_water_m_s: float = DEFAULT_SOUND_SPEED_M_S) -> np.ndarray:
    """Small-roughness perturbation cross section ``sigma_pr`` (linear), TR 9407.

    ``sigma_pr = k^4/4 |1 + R|^4 |G|^2 W(2 k cos theta)`` with
    ``G = (1/rho - 1)(-cos^2 theta - P^2/rho) + 1 - kappa^2/rho`` and
    ``W(K) = w2 K^-gamma``; infinite at nadir, where it does not apply.

    Parameters
    ----------
    grazing_deg : array_like
        Grazing angles (deg), in (0, 90].
    sediment : SedimentParams
        Sediment parameters.
    frequency_hz : float
        Acoustic frequency (Hz).
    sound_speed_water_m_s : float
        Water sound speed for ``k`` (m/s).
    """
    t = _grazing_rad(grazing_deg)
    k = _wavenumber(frequency_hz, sound_speed_water_m_s)
    rho, kap = sediment.rho, _kappa(sediment)
    p = vertical_wavenumber_ratio(grazing_deg, sediment)
    r = reflection_coefficient(grazing_deg, sediment)
    g = (1.0 / rho - 1.0) * (-np.cos(t) ** 2 - p ** 2 / rho) + 1.0 - kap ** 2 / rho
    with np.errstate(divide="ignore"):
        w = sediment.w2_si * (2.0 * k * np.cos(t)) ** (-sediment.gamma)
    return k ** 4 / 4.0 * np.abs(1.0 + r) ** 4 * np.abs(g) ** 2 * w


def perturbation_kernel_ratio(grazing_deg, sediment: SedimentParams) -> np.ndarray:
    """``h(theta) = sin^2 theta |Y(theta)| / |R(90)|``: perturbation over nadir kernel.

    ``Y = ((rho - 1)^2 cos^2 theta + rho^2 - kappa^2) / (rho sin theta + P)^2``
    is the perturbation kernel (``sigma_pr = 4 k^4 sin^4 theta |Y|^2 W``);
    ``h(90) = 1``.  The small-slope roughness term is ``h^2 sigma_kr``.

    Parameters
    ----------
    grazing_deg : array_like
        Grazing angles (deg), in (0, 90].
    sediment : SedimentParams
        Sediment parameters.
    """
    t = _grazing_rad(grazing_deg)
    rho, kap = sediment.rho, _kappa(sediment)
    p = vertical_wavenumber_ratio(grazing_deg, sediment)
    y = ((rho - 1.0) ** 2 * np.cos(t) ** 2 + rho ** 2 - kap ** 2) / (rho * np.sin(t) + p) ** 2
    r90 = abs((rho - kap) / (rho + kap))
    return np.sin(t) ** 2 * np.abs(y) / r90


def roughness_cross_section(grazing_deg, sediment: SedimentParams, frequency_hz: float, *,
                            sound_speed_water_m_s: float = DEFAULT_SOUND_SPEED_M_S) -> np.ndarray:
    """Interface roughness cross section joining Kirchhoff and perturbation (linear).

    Lowest-order small-slope approximation:
    ``sigma_r = sigma_pr I(q) / (c1 q) = (sin^2 theta |Y| )^2 sigma_kr / |R(90)|^2``,
    which is ``sigma_pr`` where ``q -> 0`` (away from nadir) and
    ``sigma_kr`` at nadir (module docstring).

    Parameters
    ----------
    grazing_deg : array_like
        Grazing angles (deg), in (0, 90].
    sediment : SedimentParams
        Sediment parameters.
    frequency_hz : float
        Acoustic frequency (Hz).
    sound_speed_water_m_s : float
        Water sound speed for ``k`` (m/s).
    """
    t = _grazing_rad(grazing_deg)
    k = _wavenumber(frequency_hz, sound_speed_water_m_s)
    r90 = abs((sediment.rho - _kappa(sediment)) / (sediment.rho + _kappa(sediment)))
    # (sin^2 |Y|)^2 = (h |R(90)|)^2 with h the perturbation/nadir kernel ratio
    return (perturbation_kernel_ratio(grazing_deg, sediment) * r90) ** 2 * _kirchhoff_shape(t, sediment, k)


def volume_cross_section(grazing_deg, sediment: SedimentParams) -> np.ndarray:
    """Sediment volume-scattering cross section ``sigma_v`` (linear), TR 9407.

    ``sigma_v = 5 delta sigma2 |1 + R|^4 / (ln(10) nu rho^2 Im P)``
    (module docstring); independent of frequency.

    Parameters
    ----------
    grazing_deg : array_like
        Grazing angles (deg), in (0, 90].
    sediment : SedimentParams
        Sediment parameters (``delta > 0``).
    """
    p = vertical_wavenumber_ratio(grazing_deg, sediment)
    r = reflection_coefficient(grazing_deg, sediment)
    return (5.0 * sediment.delta * sediment.sigma2 * np.abs(1.0 + r) ** 4
            / (math.log(10.0) * sediment.nu * sediment.rho ** 2 * p.imag))


def _resolve(mz, sediment) -> SedimentParams:
    require((mz is None) != (sediment is None), OptionError,
            f"give exactly one of mz and sediment, got mz={mz!r}, sediment={sediment!r}")
    if sediment is None:
        return sediment_from_grain_size(mz)
    require(isinstance(sediment, SedimentParams), OptionError,
            f"sediment must be a SedimentParams, got {type(sediment).__name__}")
    return sediment


def backscatter_cross_section(grazing_deg, frequency_hz: float, *, mz: float | None = None,
                              sediment: SedimentParams | None = None,
                              sound_speed_water_m_s: float = DEFAULT_SOUND_SPEED_M_S) -> np.ndarray:
    """Total seafloor backscattering cross section ``sigma_r + sigma_v`` (linear).

    Parameters
    ----------
    grazing_deg : array_like
        Grazing angles (deg), in (0, 90].
    frequency_hz : float
        Acoustic frequency (Hz).
    mz : float, optional
        Mean grain size (phi); parameters from the TR 9407 regressions.
    sediment : SedimentParams, optional
        Explicit parameters instead of ``mz``.
    sound_speed_water_m_s : float
        Water sound speed for ``k`` (m/s).
    """
    sed = _resolve(mz, sediment)
    return (roughness_cross_section(grazing_deg, sed, frequency_hz, sound_speed_water_m_s=sound_speed_water_m_s)
            + volume_cross_section(grazing_deg, sed))


def backscatter_strength_db(grazing_deg, frequency_hz: float, *, mz: float | None = None,
                            sediment: SedimentParams | None = None,
                            sound_speed_water_m_s: float = DEFAULT_SOUND_SPEED_M_S) -> np.ndarray:
    """Seafloor backscattering strength ``S_b = 10 log10(sigma_r + sigma_v)`` (dB).

    The model of Fonseca et al. (2005) / APL-UW TR 9407 (module
    docstring).  A simulator can give a seabed scatterer at grazing angle
    ``theta`` the intensity ``10^(S_b/10) dA`` per unit incident intensity
    at 1 m.

    Parameters
    ----------
    grazing_deg : array_like
        Grazing angles (deg), in (0, 90].
    frequency_hz : float
        Acoustic frequency (Hz).
    mz : float, optional
        Mean grain size (phi), ``-1 <= Mz <= 9`` (TR 9407 regressions).
    sediment : SedimentParams, optional
        Explicit parameters instead of ``mz`` (e.g. ``sediment_named("rock")``).
    sound_speed_water_m_s : float
        Water sound speed for ``k`` (m/s).

    Returns
    -------
    numpy.ndarray
        dB re 1 m^2 per m^2 per steradian, shape of ``grazing_deg``.
    """
    return 10.0 * np.log10(backscatter_cross_section(
        grazing_deg, frequency_hz, mz=mz, sediment=sediment, sound_speed_water_m_s=sound_speed_water_m_s))


def lambert_strength_db(grazing_deg, *, mu_db: float = LAMBERT_MU_DB) -> np.ndarray:
    """Lambert's law ``S_b = 10 log10(mu) + 10 log10(sin^2 theta)`` (dB).

    Baseline of Mackenzie (1961), ``10 log10 mu = -27 dB``.

    Parameters
    ----------
    grazing_deg : array_like
        Grazing angles (deg), in (0, 90].
    mu_db : float
        ``10 log10(mu)`` (dB).
    """
    t = _grazing_rad(grazing_deg)
    return mu_db + 10.0 * np.log10(np.sin(t) ** 2)
