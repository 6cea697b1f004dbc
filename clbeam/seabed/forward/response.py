"""Coherent response of a layered seabed (Rakotonarivo eqs. 15–18, spherical spreading of eq. 2).

``p_r(w) = p0/(2 c1) sum_i exp(-j w tau_i)/tau_i V_i prod_k H_k^2 T_{k-1,k} T_{k,k-1}``

one term per interface ``i`` (echo ``i`` is the reflection at the top of
``layers[i]``):

- ``tau_i`` the two-way time to the interface.  The ``1/tau_i`` spreading is
  the paper's spherical spreading with the sediment speeds replaced by the
  water speed (§3.1, eq. 2 with ``n_s = 1``): the echo of a smooth interface
  at two-way time ``tau`` has amplitude ``p0 V / (2 c1 tau)``;
- ``H_k = 10^(-alpha_k h_k / 20)`` the one-way loss through layer ``k``
  (eq. 16, ``alpha`` in dB/m along the ray path ``h_k / cos(theta_k)``);
- ``V_i = r_1 + t_1 t_1' r_t + t_1 t_1' t_t t_t' r_2`` (eq. 17): sharp top,
  transitional bed (:mod:`.transition`) and its base; roughness multiplies
  ``r_1`` and ``t_1, t_1'`` (:mod:`.roughness`).  The bed of a
  :class:`~.layers.Layer` ends at the layer's density, so ``r_2 = 0`` here;
- ``T_{i-1,i} = t_1 t_t t_2`` and ``T_{i,i-1} = t_1' t_t' t_2'`` (eq. 18)
  the crossings of each interface above.

Oblique incidence follows the specular ray with Snell angles (``tau_i = sum
2 h_k / (c_k cos theta_k)``): the echo a receiver placed at the mirror
point of the ray would see.  Time convention ``exp(+j w t)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.seabed.forward.attenuation import DB_TO_NP
from clbeam.seabed.forward.layers import Seabed
from clbeam.seabed.forward.reflection import fluid_interface, snell_cosines
from clbeam.seabed.forward.roughness import (
    reflection_roughness_factor,
    transmission_roughness_factor,
)
from clbeam.seabed.forward.transition import transition_coefficients


@dataclass(frozen=True)
class EchoSet:
    """The terms of eq. 15, one row per interface.

    Attributes
    ----------
    freq_hz : numpy.ndarray
        Frequencies (Hz), ``(n_freq,)``.
    times_s : numpy.ndarray
        Two-way time to the top of each interface (s), ``(n_echo,)``; NaN for
        an interface below a post-critical one (no echo).
    delays_s : numpy.ndarray
        Delays used in ``exp(-j w tau)`` (s): ``times_s`` less the crossings
        of transitional beds above, whose delay the bed transmissions carry.
    reflection : numpy.ndarray
        ``V_i(f)`` (eq. 17), ``(n_echo, n_freq)`` complex.
    transmission : numpy.ndarray
        ``prod_k T_{k-1,k} T_{k,k-1}`` over the interfaces above (eq. 18).
    attenuation : numpy.ndarray
        ``prod_k H_k^2`` over the layers above (eq. 16), real.
    spreading : numpy.ndarray
        ``p0 / (2 c1 tau_i)`` (Pa), ``(n_echo,)``.
    cos_theta : numpy.ndarray
        Cosine of the ray angle in each layer (complex when evanescent).
    incidence_deg : float
        Incidence angle in the water (degree from the vertical).
    """

    freq_hz: np.ndarray
    times_s: np.ndarray
    delays_s: np.ndarray
    reflection: np.ndarray
    transmission: np.ndarray
    attenuation: np.ndarray
    spreading: np.ndarray
    cos_theta: np.ndarray
    incidence_deg: float

    @property
    def amplitudes(self) -> np.ndarray:
        """``A_i(f) = p0/(2 c1 tau_i) V_i prod H^2 T T'`` without the delay phase (Pa)."""
        return self.spreading[:, None] * self.reflection * self.transmission * self.attenuation

    def spectra(self) -> np.ndarray:
        """Each echo's term of eq. 15, ``A_i(f) exp(-j w tau_i)``, ``(n_echo, n_freq)``."""
        phase = np.exp(-2j * np.pi * np.outer(self.delays_s, self.freq_hz))
        return self.amplitudes * phase

    def transfer(self) -> np.ndarray:
        """The seabed transfer function ``p_r(w)`` (eq. 15), ``(n_freq,)`` complex (Pa)."""
        return self.spectra().sum(axis=0)


def layer_echoes(seabed: Seabed, freq_hz, *, incidence_deg: float = 0.0, p0: float = 1.0) -> EchoSet:
    """Echo terms of the coherent layered model (eqs. 15–18) at given frequencies.

    Parameters
    ----------
    seabed : Seabed
        Water column, layers and half-space.
    freq_hz : array_like
        Frequencies (Hz), ``>= 0``.
    incidence_deg : float
        Incidence angle of the specular ray in the water (degree from the
        vertical); 0 is the paper's normal incidence.
    p0 : float
        Source amplitude of eq. 15 (Pa m).

    Returns
    -------
    EchoSet
    """
    require(math.isfinite(p0), OptionError, f"p0 must be finite, got {p0!r}")
    f = np.atleast_1d(np.asarray(freq_hz, dtype=float))
    require(bool(np.all(np.isfinite(f))) and bool(np.all(f >= 0)), OptionError,
            "freq_hz must be finite and >= 0 Hz")
    layers = seabed.layers
    n_echo = seabed.n_interfaces
    cos = snell_cosines([lay.sound_speed_m_s for lay in layers], incidence_deg)
    c1 = layers[0].sound_speed_m_s

    times = np.full(n_echo, np.nan)
    delays = np.zeros(n_echo)
    refl = np.zeros((n_echo, f.size), complex)
    trans = np.zeros((n_echo, f.size), complex)
    att = np.zeros((n_echo, f.size))
    spread = np.zeros(n_echo)

    t_full = t_phase = 0.0
    two_way_t = np.ones(f.size, complex)
    two_way_h = np.ones(f.size)
    for j in range(1, n_echo + 1):
        above, below, top = layers[j - 1], layers[j], layers[j].top
        cos_a, cos_b = cos[j - 1], cos[j]
        if abs(cos_a.imag) > 0:       # the ray never reached this layer: no deeper echoes
            break
        path = above.thickness_m / cos_a.real
        leg = 2 * path / above.sound_speed_m_s
        t_full += leg
        t_phase += leg
        two_way_h = two_way_h * np.exp(-2 * DB_TO_NP * above.attenuation.db_per_m(f) * path)

        v, t_down, t_up, bed_time = _interface_terms(f, above, below, top, cos_a, cos_b)
        i = j - 1
        times[i], delays[i] = t_full, t_phase
        spread[i] = p0 / (2 * c1 * t_full)
        refl[i], trans[i], att[i] = v, two_way_t, two_way_h
        two_way_t = two_way_t * t_down * t_up
        t_full += bed_time
    return EchoSet(f, times, delays, refl, trans, att, spread, cos, float(incidence_deg))


def _interface_terms(f: np.ndarray, above, below, top, cos_a, cos_b) -> tuple:
    """Reflection ``V`` of an interface seen from above, its down- and up-going
    transmissions and the extra two-way time of a transitional bed under it
    (eqs. 16-18, roughness and transition included), each per frequency."""
    rho_top = (top.transition_top_density_kg_m3 or above.density_kg_m3) if top.has_transition \
        else below.density_kg_m3
    r1, t1, t1p = fluid_interface(above.density_kg_m3, above.sound_speed_m_s, cos_a,
                                  rho_top, below.sound_speed_m_s, cos_b)
    r1 = r1 * np.ones(f.size)
    if top.is_rough:
        r1 = r1 * reflection_roughness_factor(f, top.roughness_m, above.sound_speed_m_s, cos_a,
                                              top.roughness_regime)
        tf = transmission_roughness_factor(f, top.roughness_m, above.sound_speed_m_s, cos_a,
                                           below.sound_speed_m_s, cos_b, top.roughness_regime)
        t1, t1p = t1 * tf, t1p * tf
    if not top.has_transition:
        return r1, t1 * np.ones(f.size), t1p * np.ones(f.size), 0.0
    rt, tt, ttp = transition_coefficients(f, thickness_m=top.transition_m, density_top_kg_m3=rho_top,
                                          density_bottom_kg_m3=below.density_kg_m3,
                                          sound_speed_m_s=below.sound_speed_m_s,
                                          attenuation=below.attenuation, cos_theta=cos_b)
    # base of the bed: same density and speed on both sides, so r2 = 0 and t2 = t2' = 1
    bed_time = (2 * top.transition_m / (below.sound_speed_m_s * cos_b.real)) if cos_b.imag == 0 else 0.0
    return r1 + t1 * t1p * rt, t1 * tt, t1p * ttp, bed_time


def transfer_function(seabed: Seabed, freq_hz, *, incidence_deg: float = 0.0, p0: float = 1.0) -> np.ndarray:
    """Seabed transfer function ``p_r(w)`` (eq. 15) at given frequencies.

    Parameters
    ----------
    seabed : Seabed
    freq_hz : array_like
        Frequencies (Hz).
    incidence_deg : float
        Incidence of the specular ray (degree from the vertical).
    p0 : float
        Source amplitude (Pa m).

    Returns
    -------
    numpy.ndarray
        complex128 (Pa per unit emitted spectrum).
    """
    return layer_echoes(seabed, freq_hz, incidence_deg=incidence_deg, p0=p0).transfer()


def specular_echoes(seabed: Seabed, freq_hz, *, incidence_deg: float | None = None,
                    grazing_deg: float | None = None, p0: float = 1.0) -> EchoSet:
    """Echoes of the specular ray at a given angle, for layers seen away from nadir.

    The ray leaves the water at ``incidence_deg`` from the vertical (or
    ``grazing_deg = 90 - incidence_deg`` from the horizontal), bends at each
    interface by Snell's law and comes back along the mirror path; each
    term of eq. 15 then uses the oblique Rayleigh coefficients, the
    roughness parameters with ``cos(theta)`` (eqs. 5–8), the path
    ``h_k / cos(theta_k)`` in eq. 16 and ``tau_i = sum 2 h_k / (c_k
    cos(theta_k))``.  Below a post-critical interface there is no echo
    (time NaN, amplitude 0).

    Parameters
    ----------
    seabed : Seabed
    freq_hz : array_like
        Frequencies (Hz).
    incidence_deg : float, optional
        Incidence from the vertical (degree), ``[0, 90)``.
    grazing_deg : float, optional
        Grazing angle from the horizontal (degree), ``(0, 90]``; give exactly
        one of the two.
    p0 : float
        Source amplitude (Pa m).

    Returns
    -------
    EchoSet
    """
    require((incidence_deg is None) != (grazing_deg is None), OptionError,
            f"give exactly one of incidence_deg and grazing_deg, got {incidence_deg!r} and {grazing_deg!r}")
    if grazing_deg is not None:
        require(math.isfinite(grazing_deg) and 0 < grazing_deg <= 90, OptionError,
                f"grazing_deg must lie in (0, 90] degree, got {grazing_deg!r}")
        incidence_deg = 90.0 - grazing_deg
    return layer_echoes(seabed, freq_hz, incidence_deg=float(incidence_deg), p0=p0)


def echo_times(seabed: Seabed, *, incidence_deg: float = 0.0) -> np.ndarray:
    """Two-way times of the echoes (s), NaN below a post-critical interface.

    Parameters
    ----------
    seabed : Seabed
    incidence_deg : float
        Incidence of the specular ray (degree from the vertical).
    """
    return layer_echoes(seabed, [0.0], incidence_deg=incidence_deg).times_s
