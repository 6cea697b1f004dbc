"""Constrained inversion of the backscatter model for grain size, impedance, roughness.

Fonseca et al. (2005) invert the APL-UW / Williams backscatter model "with
the model parameters constrained by Hamilton equations".  Here the
unknowns are

* mean grain size ``Mz`` (phi) in [-1, 9]: it fixes the density ratio,
  sound-speed ratio and loss through the TR 9407 regressions
  (:mod:`clbeam.seabed.avo.sediment`), hence the impedance ratio ``rho nu``;
* ``log10 w2`` (roughness spectral strength, cm^4) in [-4.5, -1];
* ``log10 sigma2`` (volume parameter) in [-4, -2];

fitted by bounded least squares (:func:`scipy.optimize.least_squares`,
trust-region reflective) either to the stacked angular response (dB per
bin) or to the AVO attributes of :mod:`clbeam.seabed.avo.attributes` computed the
same way on the model response.  Roughness and volume may instead be tied
to their grain-size regressions (``fit_roughness=False``,
``fit_volume=False``).  The search starts from the best point of a grid in
``Mz`` to avoid the local minima the piecewise regressions create.

Uncertainty: the linearised covariance ``s^2 (J^T J)^-1`` at the optimum,
``J`` the Jacobian of the residuals and ``s^2`` the residual variance per
degree of freedom; the impedance uncertainty follows through
``d(rho nu)/dMz``.  It is a local (Gauss–Newton) estimate: it ignores the
regressions' own scatter and any calibration offset of the data.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from clbeam.errors import OptionError, require
from clbeam.seabed.avo.attributes import (
    FAR_RANGE_DEG,
    NEAR_RANGE_DEG,
    angular_attributes,
)
from clbeam.seabed.avo.model import DEFAULT_SOUND_SPEED_M_S, backscatter_strength_db
from clbeam.seabed.avo.sediment import (
    MZ_MAX,
    MZ_MIN,
    SedimentParams,
    density_ratio,
    loss_parameter,
    sound_speed_ratio,
    spectral_strength_cm4,
    volume_parameter,
)

#: Bounds of log10(w2 / cm^4) and log10(sigma2).
LOG10_W2_BOUNDS = (-4.5, -1.0)
LOG10_SIGMA2_BOUNDS = (-4.0, -2.0)
#: Grazing angles (deg) of the response used by default: nadir excluded.
DEFAULT_GRAZING_WINDOW_DEG = (5.0, 85.0)
_MZ_GRID = np.arange(MZ_MIN, MZ_MAX + 1e-9, 0.25)
_N_STARTS = 4


@dataclass(frozen=True)
class InversionResult:
    """Outcome of one inversion.

    Attributes
    ----------
    mz : float
        Mean grain size (phi).
    impedance_ratio : float
        Sediment-to-water impedance ratio ``rho nu``.
    w2_cm4 : float
        Roughness spectral strength (cm^4).
    sigma2 : float
        Volume parameter.
    misfit_db : float
        RMS residual (dB; for attributes, slopes count as dB over half a range).
    mz_std, impedance_std, log10_w2_std, log10_sigma2_std : float
        One-sigma linearised uncertainties (0 for a tied parameter; NaN when
        the data cannot constrain the parameters).
    n_data : int
        Number of residuals fitted.
    target : str
        ``"response"`` or ``"attributes"``.
    converged : bool
        ``least_squares`` reported success.
    """

    mz: float
    impedance_ratio: float
    w2_cm4: float
    sigma2: float
    misfit_db: float
    mz_std: float
    impedance_std: float
    log10_w2_std: float
    log10_sigma2_std: float
    n_data: int
    target: str
    converged: bool

    def sediment(self) -> SedimentParams:
        """The fitted parameters as a :class:`SedimentParams`."""
        return _sediment(self.mz, math.log10(self.w2_cm4), math.log10(self.sigma2))


def _sediment(mz: float, log10_w2: float, log10_sigma2: float) -> SedimentParams:
    return SedimentParams(rho=density_ratio(mz), nu=sound_speed_ratio(mz), delta=loss_parameter(mz),
                          w2_cm4=10.0 ** log10_w2, sigma2=10.0 ** log10_sigma2, mz=mz)


class _Problem:
    """Maps the free parameters to full ``(Mz, log10 w2, log10 sigma2)``."""

    def __init__(self, fit_roughness: bool, fit_volume: bool):
        self.fit_roughness = fit_roughness
        self.fit_volume = fit_volume

    def full(self, x: np.ndarray) -> tuple[float, float, float]:
        mz = float(np.clip(x[0], MZ_MIN, MZ_MAX))
        i = 1
        if self.fit_roughness:
            lw = float(x[i])
            i += 1
        else:
            lw = math.log10(spectral_strength_cm4(mz))
        ls = float(x[i]) if self.fit_volume else math.log10(volume_parameter(mz))
        return mz, lw, ls

    def bounds(self) -> tuple[list[float], list[float]]:
        lo, hi = [MZ_MIN], [MZ_MAX]
        for flag, (a, b) in ((self.fit_roughness, LOG10_W2_BOUNDS), (self.fit_volume, LOG10_SIGMA2_BOUNDS)):
            if flag:
                lo.append(a)
                hi.append(b)
        return lo, hi

    def start(self, mz: float) -> np.ndarray:
        x = [mz]
        if self.fit_roughness:
            x.append(float(np.clip(math.log10(spectral_strength_cm4(mz)), *LOG10_W2_BOUNDS)))
        if self.fit_volume:
            x.append(float(np.clip(math.log10(volume_parameter(mz)), *LOG10_SIGMA2_BOUNDS)))
        return np.array(x)


def _model_db(grazing: np.ndarray, frequency_hz: float, c_w: float, mz: float, lw: float, ls: float):
    return backscatter_strength_db(grazing, frequency_hz, sediment=_sediment(mz, lw, ls),
                                   sound_speed_water_m_s=c_w)


_ATTR_SCALE = {  # slope (dB/deg) times half the range width (deg) -> dB
    "near_mean_db": 1.0, "near_intercept_db": 1.0,
    "near_slope_db_per_deg": (NEAR_RANGE_DEG[1] - NEAR_RANGE_DEG[0]) / 2.0,
    "far_mean_db": 1.0, "far_intercept_db": 1.0,
    "far_slope_db_per_deg": (FAR_RANGE_DEG[1] - FAR_RANGE_DEG[0]) / 2.0,
    "outer_mean_db": 1.0,
}


def _attribute_vector(incidence_deg: np.ndarray, strength_db: np.ndarray) -> np.ndarray:
    a = angular_attributes(incidence_deg, strength_db).as_dict()
    return np.array([a[k] * s for k, s in _ATTR_SCALE.items()])


def _solve(residual, problem: _Problem, n_data: int, target: str) -> InversionResult:
    n_free = 1 + int(problem.fit_roughness) + int(problem.fit_volume)
    require(n_data > n_free, OptionError,
            f"inversion needs more data than its {n_free} free parameters, got {n_data} usable values")
    costs = [float(np.sum(residual(problem.start(mz)) ** 2)) for mz in _MZ_GRID]
    best = None
    for i in np.argsort(costs)[:_N_STARTS]:
        r = optimize.least_squares(residual, problem.start(_MZ_GRID[i]), bounds=problem.bounds(),
                                   method="trf", x_scale=1.0, diff_step=1e-4)
        if best is None or r.cost < best.cost:
            best = r
    mz, lw, ls = problem.full(best.x)
    dof = n_data - n_free
    s2 = 2.0 * best.cost / dof
    jtj = best.jac.T @ best.jac
    try:
        cov = s2 * np.linalg.inv(jtj)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        std = np.full(n_free, np.nan)
    std_w = std[1] if problem.fit_roughness else 0.0
    std_s = std[-1] if problem.fit_volume else 0.0
    h = 1e-4
    lo_mz, hi_mz = max(mz - h, MZ_MIN), min(mz + h, MZ_MAX)
    dz = (density_ratio(hi_mz) * sound_speed_ratio(hi_mz)
          - density_ratio(lo_mz) * sound_speed_ratio(lo_mz)) / (hi_mz - lo_mz)
    return InversionResult(
        mz=mz, impedance_ratio=density_ratio(mz) * sound_speed_ratio(mz), w2_cm4=10.0 ** lw,
        sigma2=10.0 ** ls, misfit_db=float(np.sqrt(2.0 * best.cost / n_data)),
        mz_std=float(std[0]), impedance_std=float(abs(dz) * std[0]), log10_w2_std=float(std_w),
        log10_sigma2_std=float(std_s), n_data=int(n_data), target=target, converged=bool(best.success))


def _prepare(incidence_deg, strength_db, grazing_window_deg):
    inc = np.abs(np.asarray(incidence_deg, dtype=np.float64))
    bs = np.asarray(strength_db, dtype=np.float64)
    require(inc.ndim == 1 and bs.shape == inc.shape, OptionError,
            f"incidence_deg and strength_db must be 1-D of equal length, got {inc.shape} and {bs.shape}")
    g = 90.0 - inc
    lo, hi = grazing_window_deg
    require(0 < lo < hi <= 90, OptionError,
            f"grazing_window_deg must satisfy 0 < low < high <= 90, got {grazing_window_deg!r}")
    keep = np.isfinite(bs) & (g >= lo) & (g <= hi)
    return inc, bs, keep


def invert_response(incidence_deg, strength_db, frequency_hz: float, *,
                    sound_speed_water_m_s: float = DEFAULT_SOUND_SPEED_M_S,
                    grazing_window_deg: tuple[float, float] = DEFAULT_GRAZING_WINDOW_DEG,
                    fit_roughness: bool = True, fit_volume: bool = True) -> InversionResult:
    """Invert a stacked angular response for grain size, impedance and roughness.

    Minimises ``sum (S_model(theta_i) - S_i)^2`` over the bins whose grazing
    angle lies in ``grazing_window_deg`` (module docstring; Fonseca et al.
    2005, "constrained iterative inversion").

    Parameters
    ----------
    incidence_deg : array_like
        Bin incidence angles (deg from vertical).
    strength_db : array_like
        Stacked backscatter strength (dB), calibrated; NaN bins skipped.
    frequency_hz : float
        Centre frequency of the sonar (Hz).
    sound_speed_water_m_s : float
        Water sound speed (m/s).
    grazing_window_deg : tuple of float
        Grazing angles used (deg); the default drops the nadir bins.
    fit_roughness, fit_volume : bool
        Free ``w2`` / ``sigma2``; when False they follow the regressions.

    Returns
    -------
    InversionResult
    """
    inc, bs, keep = _prepare(incidence_deg, strength_db, grazing_window_deg)
    grazing = 90.0 - inc[keep]
    data = bs[keep]
    problem = _Problem(fit_roughness, fit_volume)

    def residual(x):
        return _model_db(grazing, frequency_hz, sound_speed_water_m_s, *problem.full(x)) - data

    return _solve(residual, problem, data.size, "response")


def invert_attributes(incidence_deg, strength_db, frequency_hz: float, *,
                      sound_speed_water_m_s: float = DEFAULT_SOUND_SPEED_M_S,
                      fit_roughness: bool = True, fit_volume: bool = True) -> InversionResult:
    """Invert the AVO attributes of a stacked response (Fonseca et al. 2005).

    The residuals are the seven attributes (near/far mean, intercept and
    slope, outer mean) of the model response at the same bins minus those
    of the data; slopes are scaled to dB by half their range width (12.5°
    near, 15° far).  Fonseca also fits the fluid factor, which needs the
    survey trend; it is left out here.

    Parameters
    ----------
    incidence_deg : array_like
        Bin incidence angles (deg from vertical).
    strength_db : array_like
        Stacked backscatter strength (dB); NaN bins skipped.
    frequency_hz : float
        Centre frequency (Hz).
    sound_speed_water_m_s : float
        Water sound speed (m/s).
    fit_roughness, fit_volume : bool
        Free ``w2`` / ``sigma2``; when False they follow the regressions.

    Returns
    -------
    InversionResult
    """
    inc, bs, keep = _prepare(incidence_deg, strength_db, (0.5, 90.0))
    inc, bs = inc[keep], bs[keep]
    data = _attribute_vector(inc, bs)
    ok = np.isfinite(data)
    require(int(ok.sum()) >= 3, OptionError,
            f"attribute inversion needs at least 3 finite attributes, got {int(ok.sum())}")
    grazing = 90.0 - inc
    problem = _Problem(fit_roughness, fit_volume)

    def residual(x):
        model = _model_db(grazing, frequency_hz, sound_speed_water_m_s, *problem.full(x))
        return (_attribute_vector(inc, model) - data)[ok]

    return _solve(residual, problem, int(ok.sum()), "attributes")
