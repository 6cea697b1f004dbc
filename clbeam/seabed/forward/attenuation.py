"""Sediment attenuation laws and their linearisation (Rakotonarivo eqs. 3–4, Table 1).

Attenuation in marine sediment is written ``alpha = k_p f^n`` (dB/m, ``f`` in
kHz, eq. 3).  The coherent model needs attenuation linear in frequency, so the
paper replaces it by the least-squares line ``alpha' = k_p' f + b`` over the
profiler band 1–10 kHz (eq. 4, Table 1).  Both laws are frozen dataclasses
with the same interface: :meth:`db_per_m` gives the attenuation at
frequencies in hertz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError, require

#: dB to nepers: an amplitude loss of ``a`` dB is ``a * DB_TO_NP`` Np.
DB_TO_NP = math.log(10.0) / 20.0
#: Band of the paper's linearisation (kHz).
LINEARISATION_BAND_KHZ = (1.0, 10.0)


def _finite(name: str, value: float) -> float:
    value = float(value)
    require(math.isfinite(value), OptionError, f"{name} must be finite, got {value!r}")
    return value


@dataclass(frozen=True)
class PowerLawAttenuation:
    """Attenuation ``alpha = k_p f^n`` (eq. 3).

    Attributes
    ----------
    k_p_db_m_khz : float
        Coefficient ``k_p`` (dB/m/kHz^n), ``>= 0``.
    n : float
        Frequency exponent, ``>= 0`` (1 for Hamilton's linear law).
    """

    k_p_db_m_khz: float = 0.0
    n: float = 1.0

    def __post_init__(self) -> None:
        require(_finite("attenuation k_p", self.k_p_db_m_khz) >= 0, OptionError,
                f"attenuation k_p must be >= 0 dB/m/kHz^n, got {self.k_p_db_m_khz!r}")
        require(_finite("attenuation exponent n", self.n) >= 0, OptionError,
                f"attenuation exponent n must be >= 0, got {self.n!r}")

    def db_per_m(self, freq_hz) -> np.ndarray:
        """Attenuation ``k_p f^n`` (dB/m) at ``freq_hz`` (Hz; ``f`` in kHz in eq. 3)."""
        f_khz = np.abs(np.asarray(freq_hz, dtype=float)) / 1000.0
        if self.n == 0:
            return np.full_like(f_khz, self.k_p_db_m_khz)
        return self.k_p_db_m_khz * f_khz ** self.n

    @property
    def is_zero(self) -> bool:
        """True when the medium is lossless."""
        return self.k_p_db_m_khz == 0.0


@dataclass(frozen=True)
class LinearAttenuation:
    """Attenuation ``alpha' = k_p' f + b`` (eq. 4), clipped at 0 dB/m.

    A fitted line with ``b < 0`` goes negative below ``f = -b/k_p'`` (a few
    hundred hertz for Table 1's rows); a gain is unphysical, so
    :meth:`db_per_m` returns ``max(k_p' f + b, 0)``.  In the chirp bands
    the clip never acts.

    Attributes
    ----------
    slope_db_m_khz : float
        ``k_p'`` (dB/m/kHz).
    intercept_db_m : float
        ``b`` (dB/m).
    """

    slope_db_m_khz: float = 0.0
    intercept_db_m: float = 0.0

    def __post_init__(self) -> None:
        _finite("attenuation slope k_p'", self.slope_db_m_khz)
        _finite("attenuation intercept b", self.intercept_db_m)

    def db_per_m(self, freq_hz) -> np.ndarray:
        """Attenuation ``max(k_p' f + b, 0)`` (dB/m) at ``freq_hz`` (Hz)."""
        f_khz = np.abs(np.asarray(freq_hz, dtype=float)) / 1000.0
        return np.maximum(self.slope_db_m_khz * f_khz + self.intercept_db_m, 0.0)

    @property
    def is_zero(self) -> bool:
        """True when the medium is lossless."""
        return self.slope_db_m_khz == 0.0 and self.intercept_db_m == 0.0


Attenuation = PowerLawAttenuation | LinearAttenuation


def _moment(j: float, lo: float, hi: float) -> float:
    """``∫_lo^hi f^j df`` for ``j > -1``."""
    return (hi ** (j + 1) - lo ** (j + 1)) / (j + 1)


def linearise_attenuation(k_p_db_m_khz: float, n: float, *,
                          band_khz: tuple[float, float] = LINEARISATION_BAND_KHZ) -> LinearAttenuation:
    """Least-squares line ``k_p' f + b`` through ``k_p f^n`` over a band (eq. 4, Table 1).

    Minimises ``∫ (k_p f^n - k_p' f - b)^2 df`` over ``band_khz`` (the
    continuous least-squares fit; the paper's Table 1 uses 1–10 kHz).  The
    normal equations use the closed-form moments ``∫ f^j df``:

    ``[M2 M1; M1 M0] [k_p'; b] = k_p [M(n+1); M(n)]``,  ``Mj = ∫ f^j df``.

    Parameters
    ----------
    k_p_db_m_khz : float
        ``k_p`` (dB/m/kHz^n), ``>= 0``.
    n : float
        Exponent, ``>= 0``.
    band_khz : (float, float)
        Fit band (kHz), ``0 <= lo < hi``.

    Returns
    -------
    LinearAttenuation
    """
    law = PowerLawAttenuation(k_p_db_m_khz, n)
    lo, hi = (float(b) for b in band_khz)
    require(math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi, OptionError,
            f"linearisation band must satisfy 0 <= lo < hi kHz, got {band_khz!r}")
    m0, m1, m2 = _moment(0, lo, hi), _moment(1, lo, hi), _moment(2, lo, hi)
    rhs1, rhs0 = law.k_p_db_m_khz * _moment(law.n + 1, lo, hi), law.k_p_db_m_khz * _moment(law.n, lo, hi)
    det = m2 * m0 - m1 * m1
    slope = (rhs1 * m0 - rhs0 * m1) / det
    intercept = (m2 * rhs0 - m1 * rhs1) / det
    return LinearAttenuation(slope, intercept)


def as_linear(law: Attenuation, *, band_khz: tuple[float, float] = LINEARISATION_BAND_KHZ) -> LinearAttenuation:
    """The linear form of an attenuation law (itself when already linear).

    Parameters
    ----------
    law : PowerLawAttenuation or LinearAttenuation
    band_khz : (float, float)
        Band of the fit for a power law (kHz), default 1–10 kHz.
    """
    if isinstance(law, LinearAttenuation):
        return law
    return linearise_attenuation(law.k_p_db_m_khz, law.n, band_khz=band_khz)


def attenuation_np_per_m(law: Attenuation, freq_hz) -> np.ndarray:
    """Amplitude attenuation in nepers per metre, ``alpha_dB ln(10) / 20``.

    Parameters
    ----------
    law : PowerLawAttenuation or LinearAttenuation
    freq_hz : array_like
        Frequencies (Hz).
    """
    return law.db_per_m(freq_hz) * DB_TO_NP
