"""Coherent reflection and transmission losses of rough interfaces (Rakotonarivo eqs. 5–8).

Gaussian interface heights of standard deviation ``sigma``.  Eckart's small
roughness (``P << 1``):

- reflection ``V_rough = V_smooth exp(-P^2 / 2)``, ``P = 2 k_i sigma cos(theta_i)``
  (eq. 5; the minus sign is lost in print);
- transmission ``T_rough = T_smooth exp(-P_T^2 / 2)``,
  ``P_T = k_{i+1} sigma (c_{i+1}/c_i cos(theta_i) - cos(theta_{i+1}))`` (eq. 6,
  Nagy & Adler), i.e. ``sigma`` times the jump of the vertical wavenumber.

Fair roughness (``P`` near 1, ``lambda >> sigma``, the paper's tank
measurements): the same with ``4/3 P`` (eq. 7) and ``5/2 P_T`` (eq. 8).
"""

from __future__ import annotations

import numpy as np

from clbeam.errors import OptionError, require

#: Factors applied to P (reflection) and P_T (transmission) per regime (eqs. 5–8).
REFLECTION_GAIN = {"small": 1.0, "fair": 4.0 / 3.0}
TRANSMISSION_GAIN = {"small": 1.0, "fair": 5.0 / 2.0}


def _regime(regime: str) -> str:
    require(regime in REFLECTION_GAIN, OptionError,
            f"roughness regime must be 'small' or 'fair', got {regime!r}")
    return regime


def rayleigh_parameter(freq_hz, sigma_m: float, sound_speed_m_s: float, cos_theta=1.0) -> np.ndarray:
    """Rayleigh roughness parameter ``P = 2 k sigma cos(theta)`` (eq. 5).

    Parameters
    ----------
    freq_hz : array_like
        Frequency (Hz); ``k = 2 pi f / c``.
    sigma_m : float
        Roughness standard deviation (m).
    sound_speed_m_s : float
        Sound speed of the medium of incidence (m/s).
    cos_theta : complex or float
        Cosine of the incidence angle in that medium.
    """
    k = 2 * np.pi * np.abs(np.asarray(freq_hz, dtype=float)) / sound_speed_m_s
    return 2 * k * sigma_m * np.real(cos_theta)


def transmission_parameter(freq_hz, sigma_m: float, sound_speed1_m_s: float, cos1,
                           sound_speed2_m_s: float, cos2) -> np.ndarray:
    """Transmission roughness parameter ``P_T`` (eq. 6).

    ``P_T = k2 sigma (c2/c1 cos1 - cos2) = sigma (k1 cos1 - k2 cos2)``.  The
    reverse crossing (2 → 1) has ``-P_T``, so both directions lose the same
    ``exp(-P_T^2/2)``.

    Parameters
    ----------
    freq_hz : array_like
        Frequency (Hz).
    sigma_m : float
        Roughness standard deviation (m).
    sound_speed1_m_s, sound_speed2_m_s : float
        Sound speeds of the medium of incidence and of transmission (m/s).
    cos1, cos2 : complex or float
        Cosines of the angles in both media (real parts are used).
    """
    w = 2 * np.pi * np.abs(np.asarray(freq_hz, dtype=float))
    k2 = w / sound_speed2_m_s
    return k2 * sigma_m * (sound_speed2_m_s / sound_speed1_m_s * np.real(cos1) - np.real(cos2))


def reflection_roughness_factor(freq_hz, sigma_m: float, sound_speed_m_s: float, cos_theta=1.0,
                                regime: str = "small") -> np.ndarray:
    """Coherent reflection factor ``exp(-(g P)^2 / 2)`` (eq. 5, ``g = 1``; eq. 7, ``g = 4/3``).

    Parameters
    ----------
    freq_hz : array_like
        Frequency (Hz).
    sigma_m : float
        Roughness standard deviation (m).
    sound_speed_m_s : float
        Sound speed of the medium of incidence (m/s).
    cos_theta : complex or float
        Cosine of the incidence angle.
    regime : {"small", "fair"}
        Eckart (eq. 5) or the paper's fair roughness (eq. 7).

    Returns
    -------
    numpy.ndarray
        Factor in (0, 1] that multiplies the smooth coefficient.
    """
    p = REFLECTION_GAIN[_regime(regime)] * rayleigh_parameter(freq_hz, sigma_m, sound_speed_m_s, cos_theta)
    return np.exp(-0.5 * p * p)


def transmission_roughness_factor(freq_hz, sigma_m: float, sound_speed1_m_s: float, cos1,
                                  sound_speed2_m_s: float, cos2, regime: str = "small") -> np.ndarray:
    """Coherent transmission factor ``exp(-(g P_T)^2 / 2)`` (eq. 6, ``g = 1``; eq. 8, ``g = 5/2``).

    Parameters
    ----------
    freq_hz : array_like
        Frequency (Hz).
    sigma_m : float
        Roughness standard deviation (m).
    sound_speed1_m_s, sound_speed2_m_s : float
        Sound speeds on the incidence and transmission sides (m/s).
    cos1, cos2 : complex or float
        Cosines of the angles on both sides.
    regime : {"small", "fair"}
        Eckart (eq. 6) or the paper's fair roughness (eq. 8).
    """
    pt = TRANSMISSION_GAIN[_regime(regime)] * transmission_parameter(freq_hz, sigma_m, sound_speed1_m_s, cos1,
                                                                      sound_speed2_m_s, cos2)
    return np.exp(-0.5 * pt * pt)
