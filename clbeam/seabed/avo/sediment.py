"""Sediment geoacoustic parameters from mean grain size (APL-UW TR 9407).

The seafloor backscatter model of :mod:`clbeam.seabed.avo.model` needs six
dimensionless or spectral numbers per sediment: density ratio ``rho``,
sound-speed ratio ``nu`` (both relative to the water), loss parameter
``delta``, spectral exponent ``gamma`` and strength ``w2`` of the
interface-roughness spectrum, and volume parameter ``sigma2``.  The
APL-UW High-Frequency Ocean Environmental Acoustic Models Handbook
(TR 9407, 1994, section IV) ties all of them to the mean grain size
``Mz`` (phi units, ``-log2`` of the diameter in mm) by regressions valid
for ``-1 <= Mz <= 9``; for gravel and rock (``Mz < -1``) it gives table
values instead.  Those ties are what make the AVO inversion well posed
(Fonseca et al. 2005: "model parameters constrained by Hamilton
equations").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from clbeam.errors import OptionError, require

#: Mz range covered by the TR 9407 regressions (phi).
MZ_MIN = -1.0
MZ_MAX = 9.0
#: Water sound speed the handbook used to turn k_p into delta (m/s).
HANDBOOK_SOUND_SPEED_M_S = 1528.0
#: Spectral exponent of the roughness spectrum, all sediments.
SPECTRAL_EXPONENT = 3.25


@dataclass(frozen=True)
class SedimentParams:
    """Geoacoustic parameters of a fluid sediment half-space (TR 9407 names).

    Attributes
    ----------
    rho : float
        Sediment-to-water density ratio.
    nu : float
        Sediment-to-water sound-speed ratio.
    delta : float
        Loss parameter: ratio of the imaginary to the real part of the
        sediment wavenumber, ``kappa = (1 + i delta) / nu``.  Must be > 0
        (the volume term divides by the sediment loss).
    w2_cm4 : float
        Spectral strength of the 2-D roughness spectrum
        ``W(K) = w2 / (h0 K)^gamma``, ``h0 = 1 cm`` (cm^4).
    gamma : float
        Spectral exponent, ``2 < gamma < 4`` (TR 9407: 3.25).
    sigma2 : float
        Volume parameter: ratio of the sediment volume-scattering
        coefficient (1/m) to the sediment attenuation (dB/m).
    mz : float or None
        Mean grain size the values came from (phi), when they did.
    name : str
        Short label for plots and tables.
    """

    rho: float
    nu: float
    delta: float
    w2_cm4: float
    gamma: float = SPECTRAL_EXPONENT
    sigma2: float = 0.002
    mz: float | None = None
    name: str = ""

    def __post_init__(self) -> None:
        for field, value in (("rho", self.rho), ("nu", self.nu), ("delta", self.delta),
                             ("w2_cm4", self.w2_cm4), ("sigma2", self.sigma2)):
            require(math.isfinite(value) and value > 0, OptionError,
                    f"sediment {field} must be finite and > 0, got {value!r}")
        require(2.0 < self.gamma < 4.0, OptionError,
                f"sediment gamma must lie in (2, 4), got {self.gamma!r}")

    @property
    def impedance_ratio(self) -> float:
        """Sediment-to-water acoustic impedance ratio ``rho * nu``."""
        return self.rho * self.nu

    @property
    def w2_si(self) -> float:
        """Spectral strength in SI units, m^(4 - gamma).

        ``W(K) = w2 / (h0 K)^gamma`` with ``h0 = 0.01 m`` and ``w2`` in
        cm^4 = 1e-8 m^4 gives ``W(K) = [w2 1e-8 0.01^-gamma] K^-gamma``.
        """
        return self.w2_cm4 * 1e-8 * 0.01 ** (-self.gamma)


def _check_mz(mz: float) -> float:
    mz = float(mz)
    require(math.isfinite(mz) and MZ_MIN <= mz <= MZ_MAX, OptionError,
            f"grain size mz must lie in [{MZ_MIN:g}, {MZ_MAX:g}] phi for the TR 9407 regressions, "
            f"got {mz!r} (use sediment_named('rock'|'cobble'|...) below -1)")
    return mz


def density_ratio(mz: float) -> float:
    """Sediment-to-water density ratio ``rho(Mz)`` (TR 9407 regression).

    Parameters
    ----------
    mz : float
        Mean grain size (phi), ``-1 <= Mz <= 9``.
    """
    mz = _check_mz(mz)
    if mz < 1.0:
        return 2.3139 - 0.17057 * mz + 0.007797 * mz ** 2
    if mz < 5.3:
        return 3.0455 - 1.1069031 * mz + 0.2290201 * mz ** 2 - 0.0165406 * mz ** 3
    return 1.1565 - 0.0012973 * mz


def sound_speed_ratio(mz: float) -> float:
    """Sediment-to-water sound-speed ratio ``nu(Mz)`` (TR 9407 regression).

    Parameters
    ----------
    mz : float
        Mean grain size (phi), ``-1 <= Mz <= 9``.
    """
    mz = _check_mz(mz)
    if mz < 1.0:
        return 1.2778 - 0.056452 * mz + 0.002709 * mz ** 2
    if mz < 5.3:
        return 1.3425 - 0.1382798 * mz + 0.0213937 * mz ** 2 - 0.0014881 * mz ** 3
    return 1.0019 - 0.0024324 * mz


def attenuation_db_per_m_khz(mz: float) -> float:
    """Sediment attenuation coefficient ``k_p(Mz)`` (dB/m/kHz, TR 9407).

    Parameters
    ----------
    mz : float
        Mean grain size (phi), ``-1 <= Mz <= 9``.
    """
    mz = _check_mz(mz)
    if mz < 0.0:
        return 0.4556
    if mz < 2.6:
        return 0.4556 + 0.0245 * mz
    if mz < 4.5:
        return 0.1978 + 0.1245 * mz
    if mz < 6.0:
        return 8.0399 - 2.5228 * mz + 0.20098 * mz ** 2
    return 0.9431 - 0.2041 * mz + 0.0117 * mz ** 2


def loss_parameter(mz: float) -> float:
    """Loss parameter ``delta = k_p nu c_w ln(10) / (40000 pi)`` (TR 9407).

    ``k_p`` in dB/m/kHz becomes nepers per wavelength through
    ``ln(10)/20`` (dB to Np), ``c_w/1000`` (per kHz to per wavelength in
    water) and ``nu/(2 pi)`` (to the sediment wavelength, per radian); the
    handbook evaluates it with ``c_w = 1528 m/s``.

    Parameters
    ----------
    mz : float
        Mean grain size (phi), ``-1 <= Mz <= 9``.
    """
    kp = attenuation_db_per_m_khz(mz)
    return kp * sound_speed_ratio(mz) * HANDBOOK_SOUND_SPEED_M_S * math.log(10.0) / (40000.0 * math.pi)


def spectral_strength_cm4(mz: float) -> float:
    """Roughness spectral strength ``w2(Mz) = 0.00207 (h/h0)^2`` (cm^4, TR 9407).

    ``h/h0 = (2.03846 - 0.26923 Mz) / (1 + 0.076923 Mz)`` for ``Mz < 5``
    and 0.5 from ``Mz = 5`` on.

    Parameters
    ----------
    mz : float
        Mean grain size (phi), ``-1 <= Mz <= 9``.
    """
    mz = _check_mz(mz)
    ratio = (2.03846 - 0.26923 * mz) / (1.0 + 0.076923 * mz) if mz < 5.0 else 0.5
    return 0.00207 * ratio ** 2


def volume_parameter(mz: float) -> float:
    """Volume parameter ``sigma2(Mz)``: 0.002 below Mz = 5.5, 0.001 from it on.

    The step reproduces the handbook's sediment table (sandy silt 0.002,
    medium silt and finer 0.001); it is a table convention, not a
    regression, and the inversion treats ``sigma2`` as a free parameter.

    Parameters
    ----------
    mz : float
        Mean grain size (phi), ``-1 <= Mz <= 9``.
    """
    return 0.002 if _check_mz(mz) < 5.5 else 0.001


def sediment_from_grain_size(mz: float, *, name: str = "") -> SedimentParams:
    """All model parameters of a sediment of mean grain size ``Mz``.

    Parameters
    ----------
    mz : float
        Mean grain size (phi), ``-1 <= Mz <= 9`` (TR 9407 regressions).
    name : str
        Optional label.

    Returns
    -------
    SedimentParams
    """
    mz = _check_mz(mz)
    return SedimentParams(rho=density_ratio(mz), nu=sound_speed_ratio(mz), delta=loss_parameter(mz),
                          w2_cm4=spectral_strength_cm4(mz), gamma=SPECTRAL_EXPONENT,
                          sigma2=volume_parameter(mz), mz=mz, name=name or f"Mz {mz:g}")


#: Table rows of TR 9407 for sediments outside the regressions (Mz < -1).
#: (Mz, rho, nu, delta, w2 cm^4, sigma2).
_TABLE_COARSE = {
    "rough rock": (-9.0, 2.5, 2.5, 0.01374, 0.20693, 0.002),
    "rock": (-7.0, 2.5, 2.5, 0.01374, 0.01862, 0.002),
    "cobble": (-3.0, 2.5, 1.8, 0.01374, 0.016, 0.002),
    "gravel": (-3.0, 2.5, 1.8, 0.01374, 0.016, 0.002),
}
#: Named sediments inside the regressions: their handbook mean grain size.
_NAMED_MZ = {
    "sandy gravel": -1.0, "very coarse sand": -0.5, "muddy sandy gravel": 0.0,
    "coarse sand": 0.5, "gravelly muddy sand": 1.0, "medium sand": 1.5,
    "muddy gravel": 2.0, "fine sand": 2.5, "muddy sand": 3.0,
    "very fine sand": 3.5, "clayey sand": 4.0, "coarse silt": 4.5,
    "sandy silt": 5.0, "medium silt": 5.5, "sandy mud": 6.0, "silt": 6.0,
    "fine silt": 6.5, "sandy clay": 7.0, "very fine silt": 7.5,
    "silty clay": 8.0, "clay": 9.0,
}


def sediment_names() -> list[str]:
    """Names accepted by :func:`sediment_named`."""
    return sorted(set(_TABLE_COARSE) | set(_NAMED_MZ))


def sediment_named(name: str) -> SedimentParams:
    """Parameters of a named handbook sediment (TR 9407 sediment table).

    Sands, silts and clays come from the regressions at the table's mean
    grain size; gravel, cobble and rock (``Mz < -1``) from the table rows
    (``rho = 2.5``, ``nu = 1.8`` or 2.5, ``delta = 0.01374``).

    Parameters
    ----------
    name : str
        One of :func:`sediment_names` (case-insensitive).
    """
    key = str(name).strip().lower()
    if key in _NAMED_MZ:
        return sediment_from_grain_size(_NAMED_MZ[key], name=key)
    require(key in _TABLE_COARSE, OptionError,
            f"sediment name must be one of {', '.join(sediment_names())}; got {name!r}")
    mz, rho, nu, delta, w2, sigma2 = _TABLE_COARSE[key]
    return SedimentParams(rho=rho, nu=nu, delta=delta, w2_cm4=w2, gamma=SPECTRAL_EXPONENT,
                          sigma2=sigma2, mz=mz, name=key)
