"""Transitional bed with exponential density (Rakotonarivo §3.4, eqs. 9–14, Fig. 6).

Between two homogeneous media a bed of thickness ``dx`` whose density grows
as ``rho(x) = rho_a exp(2 beta0 x)`` from ``rho_a`` (top, ``x = 0``) to
``rho_b`` (bottom, ``x = dx``); sound speed and attenuation are constant in
it.  Inside, ``p'' - 2 beta0 p' + k^2 p = 0``, whose waves are
``exp(beta0 x) exp(-/+ j k* x)``.  The transfer matrix that links the up- and
down-going waves at both ends (Bai et al. 1985) gives

- ``m11 = exp(-beta0 dx) [cos(k* dx) + j k/k* sin(k* dx)]``,
- ``m21 = exp(-beta0 dx) beta0/k* sin(k* dx)``,
- ``R = m21/m11`` (eq. 10), ``T = 1/m11`` (eq. 11),

with ``beta0 = ln(rho_b/rho_a) / (2 dx)`` (the printed factor ``c`` in eq.
14 is dimensionally wrong), ``k* = sqrt(k^2 - beta0^2)`` and
``k = w/c - j alpha`` (``exp(+j w t)`` convention).  These are exact for the
exponential profile: they equal the solution of the boundary-value problem
with continuous pressure and normal velocity at both ends.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from clbeam.errors import OptionError, require
from clbeam.seabed.forward.attenuation import (
    Attenuation,
    PowerLawAttenuation,
    attenuation_np_per_m,
)


def _sin_over(kappa, dx: float):
    """``sin(kappa dx) / kappa`` for complex ``kappa``, finite at 0."""
    return dx * np.sinc(kappa * dx / np.pi)


def transition_coefficients(freq_hz, *, thickness_m: float, density_top_kg_m3: float,
                            density_bottom_kg_m3: float, sound_speed_m_s: float,
                            attenuation: Attenuation | None = None, cos_theta=1.0):
    """Reflection and two transmissions of an exponential-density bed (eqs. 10–14).

    At oblique incidence the wavenumber ``k`` of eqs. 12–14 becomes the
    vertical wavenumber ``k_z = sqrt(k^2 - k_x^2)``, ``k_x = (w/c) sin(theta)``
    (the horizontal wavenumber is conserved and the speed is constant in the
    bed).

    Parameters
    ----------
    freq_hz : array_like
        Frequencies (Hz), ``>= 0``.
    thickness_m : float
        Bed thickness ``dx`` (m), ``> 0``.
    density_top_kg_m3, density_bottom_kg_m3 : float
        Densities at the top and bottom of the bed (kg/m³).
    sound_speed_m_s : float
        Sound speed in the bed (m/s).
    attenuation : PowerLawAttenuation or LinearAttenuation, optional
        Attenuation in the bed (dB/m); lossless by default.
    cos_theta : complex or float
        Cosine of the ray angle in the bed.

    Returns
    -------
    (R, T_down, T_up) : numpy.ndarray
        ``R = m21/m11`` seen from above and referred to the top; ``T_down =
        1/m11`` (top → bottom, eq. 11); ``T_up`` the same for the bed crossed
        upward (``beta0 → -beta0``), so ``T_down T_up = 1/[cos(k* dx) + j
        k/k* sin(k* dx)]^2``.  Pressure coefficients (complex).
    """
    require(math.isfinite(thickness_m) and thickness_m > 0, OptionError,
            f"transition thickness_m must be > 0 m, got {thickness_m!r}")
    require(density_top_kg_m3 > 0 and density_bottom_kg_m3 > 0, OptionError,
            f"transition densities must be > 0 kg/m^3, got {density_top_kg_m3!r} and {density_bottom_kg_m3!r}")
    f = np.abs(np.asarray(freq_hz, dtype=float))
    law = attenuation or PowerLawAttenuation()
    w = 2 * np.pi * f
    k = w / sound_speed_m_s - 1j * attenuation_np_per_m(law, f)
    sin_t2 = 1.0 - complex(cos_theta) ** 2
    kx2 = (w / sound_speed_m_s) ** 2 * sin_t2.real
    kz = np.sqrt(k * k - kx2)
    beta0 = math.log(density_bottom_kg_m3 / density_top_kg_m3) / (2.0 * thickness_m)
    kappa = np.sqrt(kz * kz - beta0 * beta0 + 0j)
    s = _sin_over(kappa, thickness_m)
    c = np.cos(kappa * thickness_m)
    core = c + 1j * kz * s                       # m11 without exp(-beta0 dx)
    m11 = math.exp(-beta0 * thickness_m) * core
    m21 = math.exp(-beta0 * thickness_m) * beta0 * s
    t_up = math.exp(-beta0 * thickness_m) / core  # 1/m11 with beta0 -> -beta0
    return m21 / m11, 1.0 / m11, t_up


def transition_reflection_drop_db(freq_hz, *, thickness_m: float, density_top_kg_m3: float,
                                  density_bottom_kg_m3: float, sound_speed_m_s: float,
                                  attenuation: Attenuation | None = None) -> np.ndarray:
    """Fall of the reflection (dB) caused by spreading a density step over a bed (Fig. 6).

    ``20 log10 |R_step| - 20 log10 |R_bed(f)|`` with ``R_step = (rho_b -
    rho_a)/(rho_b + rho_a)``, the reflection between the two homogeneous
    media bordering the bed (same speed), and ``R_bed`` of
    :func:`transition_coefficients` at normal incidence.

    Parameters
    ----------
    freq_hz : array_like
        Frequencies (Hz).
    thickness_m : float
        Bed thickness (m).
    density_top_kg_m3, density_bottom_kg_m3 : float
        Densities of the media above and below (kg/m³), different.
    sound_speed_m_s : float
        Sound speed, constant through the bed (m/s).
    attenuation : PowerLawAttenuation or LinearAttenuation, optional
        Attenuation in the bed.
    """
    require(density_top_kg_m3 != density_bottom_kg_m3, OptionError,
            "transition densities must differ to define a reflection drop, got equal values "
            f"{density_top_kg_m3!r}")
    r_step = (density_bottom_kg_m3 - density_top_kg_m3) / (density_bottom_kg_m3 + density_top_kg_m3)
    r_bed, _, _ = transition_coefficients(freq_hz, thickness_m=thickness_m, density_top_kg_m3=density_top_kg_m3,
                                          density_bottom_kg_m3=density_bottom_kg_m3,
                                          sound_speed_m_s=sound_speed_m_s, attenuation=attenuation)
    return 20 * np.log10(abs(r_step)) - 20 * np.log10(np.abs(r_bed))


def transition_threshold(drop_db: float, *, freq_hz: float = 5000.0, density_top_kg_m3: float = 1000.0,
                         density_bottom_kg_m3: float = 1500.0, sound_speed_m_s: float = 1500.0,
                         attenuation: Attenuation | None = None) -> float:
    """Wavelength-to-thickness ratio ``lambda/dx`` at which the reflection has fallen by ``drop_db``.

    Solves :func:`transition_reflection_drop_db` ``= drop_db`` for ``dx`` at
    fixed frequency on the first lobe of the response (``2 < lambda/dx <
    100``, before the first zero at ``k* dx = pi``) and returns ``lambda/dx``
    with ``lambda = c/f``.  The defaults are the paper's Fig. 6 medium
    (1000 → 1500 kg/m³, 1500 m/s); pass its ``k_p = 0.3`` dB/m/kHz as
    ``attenuation``.  Paper: 3 dB at ``lambda/dx`` near 4.5, 10 dB near 2.6.

    Parameters
    ----------
    drop_db : float
        Reflection drop (dB), ``0 < drop_db <= 20``.
    freq_hz : float
        Frequency at which the ratio is solved (Hz).
    density_top_kg_m3, density_bottom_kg_m3, sound_speed_m_s : float
        Bed properties (kg/m³, m/s).
    attenuation : PowerLawAttenuation or LinearAttenuation, optional
        Attenuation in the bed.

    Returns
    -------
    float
        ``lambda / dx``.
    """
    require(0 < drop_db <= 20, OptionError, f"drop_db must lie in (0, 20] dB, got {drop_db!r}")
    wavelength = sound_speed_m_s / freq_hz

    def excess(ratio: float) -> float:
        return float(transition_reflection_drop_db(
            freq_hz, thickness_m=wavelength / ratio, density_top_kg_m3=density_top_kg_m3,
            density_bottom_kg_m3=density_bottom_kg_m3, sound_speed_m_s=sound_speed_m_s,
            attenuation=attenuation)) - drop_db

    lo = 2.0 * (1.0 + 1e-6)
    require(excess(lo) > 0, OptionError,
            f"a drop of {drop_db:g} dB is not reached before the first zero of the bed response")
    return float(brentq(excess, lo, 100.0, xtol=1e-10))
