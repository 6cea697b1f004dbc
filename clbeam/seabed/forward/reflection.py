"""Plane-wave reflection and transmission at a sharp fluid–fluid interface.

Rayleigh's coefficients for the acoustic pressure with Snell–Descartes angles,
the building blocks ``r``, ``t``, ``t'`` of Rakotonarivo eqs. 17–18.  Time
convention ``exp(+j w t)``: a wave going down is ``exp(-j k_z z)``, so a
post-critical (evanescent) medium has ``cos(theta) = -j sqrt(s^2 - 1)``
and decays downward.
"""

from __future__ import annotations

import math

import numpy as np

from clbeam.errors import OptionError, require


def snell_cosines(sound_speeds_m_s, incidence_deg: float) -> np.ndarray:
    """Cosines of the ray angle in each medium for a ray leaving medium 0 at ``incidence_deg``.

    Snell–Descartes: ``sin(theta_m) / c_m = sin(theta_0) / c_0``.  Beyond a
    critical angle ``sin(theta_m) > 1`` and the cosine is
    ``-j sqrt(sin^2 - 1)`` (evanescent, ``exp(+j w t)`` convention).

    Parameters
    ----------
    sound_speeds_m_s : array_like
        Sound speed of each medium (m/s), medium 0 first.
    incidence_deg : float
        Incidence angle from the vertical in medium 0 (degree), ``0 <= . < 90``.

    Returns
    -------
    numpy.ndarray
        complex128 cosines, one per medium.
    """
    require(math.isfinite(incidence_deg) and 0 <= incidence_deg < 90, OptionError,
            f"incidence_deg must lie in [0, 90) degree from the vertical, got {incidence_deg!r}")
    c = np.asarray(sound_speeds_m_s, dtype=float)
    s = np.sin(np.radians(incidence_deg)) * c / c[0]
    s2 = s * s
    return np.where(s2 <= 1.0, np.sqrt(np.maximum(1.0 - s2, 0.0)) + 0j, -1j * np.sqrt(np.maximum(s2 - 1.0, 0.0)))


def fluid_interface(density1_kg_m3: float, sound_speed1_m_s: float, cos1,
                    density2_kg_m3: float, sound_speed2_m_s: float, cos2):
    """Pressure reflection and transmission coefficients of a sharp fluid interface.

    With ``Z = rho c`` and ``theta`` the ray angles (Snell):

    ``r = (Z2 cos1 - Z1 cos2) / (Z2 cos1 + Z1 cos2)``,
    ``t = 2 Z2 cos1 / (Z2 cos1 + Z1 cos2)`` (1 → 2),
    ``t' = 2 Z1 cos2 / (Z2 cos1 + Z1 cos2)`` (2 → 1),

    so that ``t t' = 1 - r^2`` and, for real angles,
    ``r^2 + (Z1 cos2 / (Z2 cos1)) t^2 = 1`` (energy flux).  These are the
    ``r_{1,i}``, ``t_{1,i}``, ``t'_{1,i}`` of Rakotonarivo eqs. 17–18 for a
    smooth interface.

    Parameters
    ----------
    density1_kg_m3, sound_speed1_m_s : float
        Medium of incidence (kg/m³, m/s).
    cos1 : complex or array_like
        Cosine of the angle in medium 1.
    density2_kg_m3, sound_speed2_m_s : float
        Medium of transmission (kg/m³, m/s).
    cos2 : complex or array_like
        Cosine of the angle in medium 2 (:func:`snell_cosines`).

    Returns
    -------
    (r, t, t_prime) : complex
    """
    z1 = density1_kg_m3 * sound_speed1_m_s
    z2 = density2_kg_m3 * sound_speed2_m_s
    a, b = z2 * np.asarray(cos1), z1 * np.asarray(cos2)
    den = a + b
    return (a - b) / den, 2 * a / den, 2 * b / den


def rayleigh_reflection(density1_kg_m3: float, sound_speed1_m_s: float, density2_kg_m3: float,
                        sound_speed2_m_s: float, incidence_deg: float = 0.0) -> complex:
    """Rayleigh reflection coefficient of a smooth fluid interface at one incidence angle.

    ``(Z2 cos1 - Z1 cos2) / (Z2 cos1 + Z1 cos2)``; at normal incidence
    ``(Z2 - Z1) / (Z2 + Z1)``.

    Parameters
    ----------
    density1_kg_m3, sound_speed1_m_s : float
        Upper medium (kg/m³, m/s).
    density2_kg_m3, sound_speed2_m_s : float
        Lower medium (kg/m³, m/s).
    incidence_deg : float
        Incidence from the vertical in the upper medium (degree).
    """
    cos = snell_cosines([sound_speed1_m_s, sound_speed2_m_s], incidence_deg)
    r, _, _ = fluid_interface(density1_kg_m3, sound_speed1_m_s, cos[0], density2_kg_m3, sound_speed2_m_s, cos[1])
    return complex(r)
