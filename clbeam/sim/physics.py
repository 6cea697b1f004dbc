"""Closed forms of the simulator's physics, also the paper's numeric checks.

Plain functions of numbers, no scene state: the transmit column's far field
and beamwidth, ``k a sin φ`` of a pipe, the fluid-fluid plane-wave
reflection coefficient, the refracted (Snell) path into the slower sediment
and the sediment's linear attenuation.  The isospeed echo model
(:mod:`clbeam.sim.propagation`) builds on them, and the tests check them
against Holland et al. (2024) §III-IV.
"""

from __future__ import annotations

import math

import numpy as np

from clbeam.constants import SBP29_BAND_HZ, SBP29_TX_LENGTH_M, SOUND_SPEED_M_S
from clbeam.sim.scene import Seabed

DB_PER_NEPER = 20.0 / math.log(10.0)
"""Decibels in one neper (amplitude)."""


def transmit_far_field_m(length_m: float = SBP29_TX_LENGTH_M, frequency_hz: float = SBP29_BAND_HZ[1],
                         sound_speed_m_s: float = SOUND_SPEED_M_S) -> float:
    """Far-field distance ``L² / λ`` of a line aperture of length ``L``.

    Parameters
    ----------
    length_m : float
        Aperture length ``L`` (m).
    frequency_hz : float
        Frequency (Hz).
    sound_speed_m_s : float
        Sound speed (m/s).

    Returns
    -------
    float
        The distance (m); Holland et al. (2024) §III: 74 m for the 3.5 m
        column at 9 kHz.
    """
    return length_m ** 2 * frequency_hz / sound_speed_m_s


def transmit_beamwidth_deg(length_m: float = SBP29_TX_LENGTH_M, frequency_hz: float = 4000.0,
                           sound_speed_m_s: float = SOUND_SPEED_M_S) -> float:
    """Full −3 dB width of a uniform line aperture, ``2 asin(0.443 λ / L)``.

    Parameters
    ----------
    length_m, frequency_hz, sound_speed_m_s : float
        As :func:`transmit_far_field_m` (m, Hz, m/s).

    Returns
    -------
    float
        The width (degree): about 5.4° for 3.5 m at 4 kHz (Holland et al.
        2024: "∼6°").
    """
    return 2 * math.degrees(math.asin(0.4429 * sound_speed_m_s / (frequency_hz * length_m)))


def ka_sin_phi(radius_m: float, frequency_hz, phi_deg=90.0, sound_speed_m_s: float = SOUND_SPEED_M_S):
    """``k a sin φ`` of a cylinder of radius ``a`` (Holland et al. 2024 §IV-A).

    Parameters
    ----------
    radius_m : float
        Cylinder radius ``a`` (m).
    frequency_hz : float or array_like
        Frequency (Hz).
    phi_deg : float or array_like
        Horizontal angle between the incoming wave and the cylinder axis
        (degree; 90 at broadside).
    sound_speed_m_s : float
        Sound speed where the cylinder lies (m/s).

    Returns
    -------
    numpy.ndarray
        ``k a sin φ`` (dimensionless), broadcast over the inputs.
    """
    k = 2 * np.pi * np.asarray(frequency_hz, dtype=np.float64) / sound_speed_m_s
    return k * radius_m * np.sin(np.deg2rad(phi_deg))


def nadir_angle_deg(horizontal_m: float, depth_m: float) -> float:
    """Angle from nadir of a point seen from the transducers along a straight ray.

    Parameters
    ----------
    horizontal_m : float
        Horizontal distance across (m).
    depth_m : float
        Depth below the transducers (m).

    Returns
    -------
    float
        The angle (degree): 76° at 920 m in 230 m of water.
    """
    return math.degrees(math.atan2(horizontal_m, depth_m))


def reflection_coefficient(grazing_rad, density_ratio: float, sound_speed_ratio: float):
    """Plane-wave pressure reflection coefficient of a fluid-fluid interface.

    ``V = (m sin θ − sqrt(n² − cos² θ)) / (m sin θ + sqrt(n² − cos² θ))``,
    ``m`` the density ratio, ``n = c1 / c2`` (lower medium slower: no
    critical angle), ``θ`` grazing in the upper medium.

    Parameters
    ----------
    grazing_rad : float or array_like
        Grazing angle ``θ`` in the upper medium (rad).
    density_ratio : float
        ``ρ2 / ρ1`` of the lower medium.
    sound_speed_ratio : float
        ``c2 / c1`` of the lower medium.

    Returns
    -------
    numpy.ndarray
        ``V`` (dimensionless, real).
    """
    n = 1.0 / sound_speed_ratio
    s = np.sin(grazing_rad)
    root = np.sqrt(np.maximum(n * n - np.cos(grazing_rad) ** 2, 0.0))
    return (density_ratio * s - root) / (density_ratio * s + root)


def refracted_path(horizontal_m, height_m, depth_m, sound_speed_ratio: float) -> dict:
    """Ray from a point ``height_m`` above a flat interface to a point
    ``depth_m`` below it, ``horizontal_m`` away (Snell's law, vectorised).

    Parameters
    ----------
    horizontal_m, height_m, depth_m : array_like
        Horizontal distance, height of the upper end above the interface and
        depth of the lower end below it (m).
    sound_speed_ratio : float
        ``c2 / c1`` of the lower medium (< 1: slower, rays bend to the normal).

    Returns
    -------
    dict
        ``water_m`` and ``sediment_m`` (path lengths, m), ``time_factor_m``
        (``water + sediment / ratio``: the travel time times ``c1``),
        ``grazing_water_rad`` and ``grazing_sediment_rad``.
    """
    rho = np.asarray(horizontal_m, dtype=np.float64)
    h = np.asarray(height_m, dtype=np.float64)
    d = np.maximum(np.asarray(depth_m, dtype=np.float64), 0.0)
    n = float(sound_speed_ratio)
    # unknown: s = sin(angle from vertical) in the upper medium; n s below.
    s = rho / np.maximum(np.hypot(rho, h + d), 1e-300)
    s_max = min(1.0, 1.0 / n) * (1 - 1e-15)
    for _ in range(60):
        cw = np.sqrt(1 - s * s)
        cs = np.sqrt(1 - (n * s) ** 2)
        f = h * s / cw + d * n * s / cs - rho
        fp = h / cw ** 3 + d * n / cs ** 3
        step = f / np.maximum(fp, 1e-300)
        s = np.clip(s - step, 0.0, s_max)
        if np.all(np.abs(f) <= 1e-9 * np.maximum(rho, 1.0)):
            break
    cw = np.sqrt(1 - s * s)
    cs = np.sqrt(1 - (n * s) ** 2)
    water = h / cw
    sediment = d / cs
    return {"water_m": water, "sediment_m": sediment, "time_factor_m": water + sediment / n,
            "grazing_water_rad": np.arcsin(cw), "grazing_sediment_rad": np.arcsin(cs)}


def attenuation_np_per_m_hz(seabed: Seabed) -> float:
    """Sediment attenuation slope ``α / f``, linear in frequency.

    Parameters
    ----------
    seabed : Seabed
        Its ``attenuation_db_per_m`` at ``attenuation_ref_hz``.

    Returns
    -------
    float
        ``α / f`` (Np m⁻¹ Hz⁻¹, amplitude).
    """
    return seabed.attenuation_db_per_m / DB_PER_NEPER / seabed.attenuation_ref_hz


def two_way_sediment_path_m(horizontal_m: float, height_m: float, burial_m: float,
                            sound_speed_ratio: float) -> float:
    """Two-way in-sediment path to a buried point, monostatic (Snell).

    Parameters
    ----------
    horizontal_m : float
        Horizontal distance from the transducers (m).
    height_m : float
        Height of the transducers above the seabed (m).
    burial_m : float
        Depth of the point below the seabed (m).
    sound_speed_ratio : float
        Sediment-to-water sound speed ratio.

    Returns
    -------
    float
        Twice the in-sediment leg of :func:`refracted_path` (m).

    Notes
    -----
    The paper quotes 5 m (0.75 dB at 5 kHz) at 920 m in 230 m water with a
    speed ratio of 0.98; the 1 m burial to the pipe axis gives 6.5 m here
    (see ``docs/simulator.md``).
    """
    return 2 * float(refracted_path(horizontal_m, height_m, burial_m, sound_speed_ratio)["sediment_m"])
