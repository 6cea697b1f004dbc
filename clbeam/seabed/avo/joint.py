"""Joint inversion of the nadir reflection coefficient and the calibrated angular response for grain size.

The nadir echo and its surface multiple give the seabed's normal-incidence
reflection coefficient ``R0`` and, through the primary echo, the constant
that makes the image strengths absolute (:mod:`clbeam.seabed.nadir`).  With
them a patch carries three kinds of data, fitted together by bounded least
squares (:func:`scipy.optimize.least_squares`) in units of their own
standard deviations:

* the stacked strengths ``S_i`` at incidence angles from ``incidence_min``
  (default 15 degrees: nearer the normal the specular echo's sidelobes and
  the single-cell seabed levels dominate the bins, up to +10 dB on silt)
  to the swath's edge: ``(S_model(theta_i; p) + dC - S_i) / sigma_S``;
* ``R0``: ``20 log10(|R_model(Mz)| / R0) / sigma_R`` (dB), ``R_model`` the
  lossy Rayleigh coefficient at normal incidence of the TR 9407 sediment of
  grain size ``Mz`` (:func:`clbeam.seabed.avo.model.reflection_coefficient`),
  ``sigma_R`` the measurement's standard error and a model floor (5 %:
  roughness and layering that the half-space leaves out) together;
* the calibration: ``dC / sigma_C``, the offset the fit may add to the
  model (the opposite of what it would add to the strengths: reported as
  ``calibration_offset_db = -dC``) against the calibration's own uncertainty.

The parameters are ``Mz``, ``log10 w2``, ``log10 sigma2`` (each free or tied
to its grain-size regression) and ``dC``; density, sound speed and loss
follow ``Mz`` through the regressions (:mod:`clbeam.seabed.avo.sediment`).
Uncertainties are the linearised covariance ``(J^T J)^-1``, scaled up by the
reduced chi-square when the fit is worse than the errors say.  ``Mz`` gets
a profile-likelihood interval too: where its best fit (the other
parameters re-fitted) rises ``max(1, chi2_red)`` above the best.
A parameter is *unresolved* when that interval is wider than 2 phi or
its standard deviation above 1 phi (``Mz``), or when its standard
deviation is unknown or exceeds a quarter of its bounds' span
(roughness, volume): the TR 9407 regressions give every grain size finer
than about 5.5 phi the same impedance and nearly the same strengths, so
silts and clays come out unresolved by construction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from clbeam.errors import OptionError, require
from clbeam.seabed.avo.inversion import (
    _MZ_GRID,
    LOG10_SIGMA2_BOUNDS,
    LOG10_W2_BOUNDS,
    _model_db,
    _prepare,
    _Problem,
    _sediment,
)
from clbeam.seabed.avo.model import DEFAULT_SOUND_SPEED_M_S, reflection_coefficient
from clbeam.seabed.avo.sediment import MZ_MAX, MZ_MIN, density_ratio, sound_speed_ratio

#: Smallest incidence angle (deg from the normal) of the strengths fitted by default.
DEFAULT_INCIDENCE_MIN_DEG = 15.0
#: Standard deviation of a stacked strength bin about the model (dB): speckle after stacking and the extraction's
#: departures from the model (on the simulated provinces 1-2 dB, up to 4 dB at 10-30 degrees on sand, where the
#: model falls steeply across one receive beam).
DEFAULT_STRENGTH_ERROR_DB = 2.0
#: Relative model error of the nadir coefficient, added to its measured standard error.
NADIR_MODEL_ERROR = 0.05
#: Widest 68 % interval of Mz (phi) still called resolved.
MZ_RESOLVED_WIDTH_PHI = 2.0
_PROFILE_STEP_PHI = 0.25


@dataclass(frozen=True)
class JointResult:
    """Outcome of a joint inversion (module docstring).

    Attributes
    ----------
    mz, mz_std : float
        Grain size and its linearised standard deviation (phi).
    mz_low, mz_high : float
        Its profile-likelihood 68 % interval (phi).
    impedance_ratio, impedance_std : float
        Sediment-to-water impedance ratio ``rho nu`` of ``mz`` and its standard deviation.
    w2_cm4, log10_w2_std : float
        Roughness spectral strength (cm^4) and the standard deviation of its log10 (0 when tied).
    sigma2, log10_sigma2_std : float
        Volume parameter and the standard deviation of its log10 (0 when tied).
    calibration_offset_db, calibration_offset_std_db : float
        The fit's correction to the calibration (dB: added to the strengths it brings them onto the fitted
        model) and its standard deviation.
    nadir_model_reflection : float
        ``|R|`` at normal incidence of the fitted sediment.
    misfit_db : float
        RMS of the strength residuals (dB).
    chi2_reduced : float
        Sum of squared normalised residuals over the degrees of freedom.
    n_data : int
        Strength bins fitted (the nadir coefficient and the calibration come on top).
    unresolved : tuple of str
        Parameters the data cannot resolve (``"mz"``, ``"roughness"``, ``"volume"``).
    converged : bool
        ``least_squares`` reported success.
    """

    mz: float
    mz_std: float
    mz_low: float
    mz_high: float
    impedance_ratio: float
    impedance_std: float
    w2_cm4: float
    log10_w2_std: float
    sigma2: float
    log10_sigma2_std: float
    calibration_offset_db: float
    calibration_offset_std_db: float
    nadir_model_reflection: float
    misfit_db: float
    chi2_reduced: float
    n_data: int
    unresolved: tuple[str, ...]
    converged: bool


def nadir_model_reflection(mz: float, log10_w2: float = -3.0, log10_sigma2: float = -3.0) -> float:
    """``|R|`` at normal incidence of the TR 9407 sediment of grain size ``mz`` (phi); lossy Rayleigh coefficient
    (roughness and volume do not enter it)."""
    return float(abs(reflection_coefficient(90.0, _sediment(mz, log10_w2, log10_sigma2))))


class _JointProblem(_Problem):
    """:class:`_Problem`'s parameters and the calibration offset ``dC`` (dB) last."""

    def __init__(self, fit_roughness: bool, fit_volume: bool, offset_bound_db: float):
        super().__init__(fit_roughness, fit_volume)
        self.offset_bound_db = offset_bound_db

    def bounds(self) -> tuple[list[float], list[float]]:
        lo, hi = super().bounds()
        return lo + [-self.offset_bound_db], hi + [self.offset_bound_db]

    def start(self, mz: float) -> np.ndarray:
        return np.append(super().start(mz), 0.0)


def _residuals(problem: _JointProblem, grazing, data, frequency_hz, c_w, errors):
    """``x -> normalised residuals``: strengths, nadir coefficient (dB), calibration offset."""
    sigma_s, r0, sigma_r_db, sigma_c = errors

    def residual(x):
        mz, lw, ls = problem.full(x)
        s = (_model_db(grazing, frequency_hz, c_w, mz, lw, ls) + x[-1] - data) / sigma_s
        r = 20 * math.log10(nadir_model_reflection(mz, lw, ls) / r0) / sigma_r_db
        return np.concatenate([s, [r, x[-1] / sigma_c]])
    return residual


def _best_fit(residual, problem: _JointProblem, starts) -> optimize.OptimizeResult:
    best = None
    for x0 in starts:
        r = optimize.least_squares(residual, x0, bounds=problem.bounds(), method="trf", diff_step=1e-4)
        if best is None or r.cost < best.cost:
            best = r
    return best


def _mz_profile(residual, problem: _JointProblem, best, scale: float) -> tuple[float, float]:
    """The 68 % profile-likelihood interval of Mz: the re-fitted chi-square (the other parameters started from
    the best fit) on a 0.25-phi grid and at the best fit (0 there); each end where it crosses ``scale`` above the
    best, linearly interpolated between the outermost grain size inside and its neighbour outside (the bound
    when there is none)."""
    lo, hi = problem.bounds()
    mz_best = float(best.x[0])
    grid = np.union1d(np.arange(MZ_MIN, MZ_MAX + 1e-9, _PROFILE_STEP_PHI), [mz_best])
    rise = np.zeros(grid.size)
    for k, mz in enumerate(grid):
        if mz == mz_best:
            continue

        def sub(y, mz=mz):
            return residual(np.concatenate([[mz], y]))
        r = optimize.least_squares(sub, np.clip(best.x[1:], lo[1:], hi[1:]), bounds=(lo[1:], hi[1:]),
                                   method="trf", diff_step=1e-4)
        rise[k] = max(2 * (r.cost - best.cost), 0.0)
    inside = np.flatnonzero(rise <= scale)
    ends = []
    for k, step in ((inside[0], -1), (inside[-1], 1)):
        if not 0 <= k + step < grid.size:
            ends.append(float(grid[k]))
            continue
        frac = (scale - rise[k]) / (rise[k + step] - rise[k])
        ends.append(float(grid[k] + frac * (grid[k + step] - grid[k])))
    return ends[0], ends[1]


def _check_errors(nadir_reflection, nadir_reflection_error, calibration_error_db, strength_error_db) -> None:
    require(math.isfinite(nadir_reflection) and 0 < nadir_reflection < 1, OptionError,
            f"the joint inversion needs a nadir reflection coefficient in (0, 1), got {nadir_reflection!r}")
    for name, v in (("nadir_reflection_error", nadir_reflection_error), ("calibration_error_db", calibration_error_db),
                    ("strength_error_db", strength_error_db)):
        require(math.isfinite(v) and v >= 0, OptionError, f"{name} must be finite and >= 0, got {v!r}")
    require(calibration_error_db > 0 and strength_error_db > 0, OptionError,
            "calibration_error_db and strength_error_db must be > 0 dB")


def invert_joint(incidence_deg, strength_db, frequency_hz: float, *, nadir_reflection: float,
                 nadir_reflection_error: float = 0.0, calibration_error_db: float = 1.0,
                 strength_error_db: float = DEFAULT_STRENGTH_ERROR_DB,
                 incidence_min_deg: float = DEFAULT_INCIDENCE_MIN_DEG,
                 sound_speed_water_m_s: float = DEFAULT_SOUND_SPEED_M_S,
                 fit_roughness: bool = True, fit_volume: bool = True) -> JointResult:
    """Grain size, impedance, roughness and volume term from a patch's nadir coefficient and calibrated response.

    Parameters
    ----------
    incidence_deg, strength_db : array_like
        Stacked response: bin incidence angles (deg) and calibrated strengths (dB); NaN bins skipped.
    frequency_hz : float
        Band centre (Hz).
    nadir_reflection, nadir_reflection_error : float
        The patch's ``|R|`` at normal incidence and its standard error (:mod:`clbeam.seabed.nadir`).
    calibration_error_db : float
        Standard deviation of the calibration applied to the strengths (dB).
    strength_error_db : float
        Standard deviation of one strength bin about the model (dB).
    incidence_min_deg : float
        Bins nearer the normal than this are left out (deg).
    sound_speed_water_m_s : float
        Water sound speed (m/s).
    fit_roughness, fit_volume : bool
        Free ``w2`` / ``sigma2``; when False they follow the regressions.

    Returns
    -------
    JointResult
    """
    _check_errors(nadir_reflection, nadir_reflection_error, calibration_error_db, strength_error_db)
    require(0 <= incidence_min_deg < 89.5, OptionError,
            f"incidence_min_deg must be within 0-89.5 degrees, got {incidence_min_deg!r}")
    inc, bs, keep = _prepare(incidence_deg, strength_db, (0.5, 90.0 - incidence_min_deg))
    problem = _JointProblem(fit_roughness, fit_volume, offset_bound_db=max(10.0, 5 * calibration_error_db))
    n_free = len(problem.start(1.0))
    require(int(keep.sum()) + 2 > n_free, OptionError,
            f"joint inversion needs more data than its {n_free} free parameters, got {int(keep.sum())} strength bins")
    sigma_r = math.hypot(nadir_reflection_error, NADIR_MODEL_ERROR * nadir_reflection)
    errors = (strength_error_db, nadir_reflection, 20 * math.log10(1 + sigma_r / nadir_reflection),
              calibration_error_db)
    residual = _residuals(problem, 90.0 - inc[keep], bs[keep], frequency_hz, sound_speed_water_m_s, errors)
    costs = [float(np.sum(residual(problem.start(mz)) ** 2)) for mz in _MZ_GRID]
    best = _best_fit(residual, problem, [problem.start(_MZ_GRID[i]) for i in np.argsort(costs)[:4]])
    return _result(residual, problem, best, int(keep.sum()), strength_error_db)


def _result(residual, problem: _JointProblem, best, n_data: int, sigma_s: float) -> JointResult:
    """The :class:`JointResult` of the best fit: covariance, profile interval, resolution flags."""
    n_free = best.x.size
    chi2_red = 2 * best.cost / max(n_data + 2 - n_free, 1)
    scale = max(1.0, chi2_red)
    try:
        var = np.diag(np.linalg.inv(best.jac.T @ best.jac)) * scale
    except np.linalg.LinAlgError:
        var = np.full(n_free, np.nan)
    # a negative variance from an ill-conditioned inverse is no information, not a perfect one
    std = np.sqrt(np.where(var >= 0, var, np.nan))
    mz, lw, ls = problem.full(best.x)
    lo, hi = _mz_profile(residual, problem, best, scale)
    std_w = float(std[1]) if problem.fit_roughness else 0.0
    std_s = float(std[n_free - 2]) if problem.fit_volume else 0.0
    unresolved = tuple(name for name, bad in (
        ("mz", hi - lo > MZ_RESOLVED_WIDTH_PHI or not std[0] <= MZ_RESOLVED_WIDTH_PHI / 2),
        ("roughness", problem.fit_roughness and not std_w <= (LOG10_W2_BOUNDS[1] - LOG10_W2_BOUNDS[0]) / 4),
        ("volume", problem.fit_volume and not std_s <= (LOG10_SIGMA2_BOUNDS[1] - LOG10_SIGMA2_BOUNDS[0]) / 4),
    ) if bad)
    h = 1e-4
    a, b = max(mz - h, MZ_MIN), min(mz + h, MZ_MAX)
    dz = (density_ratio(b) * sound_speed_ratio(b) - density_ratio(a) * sound_speed_ratio(a)) / (b - a)
    strengths = best.fun[:n_data] * sigma_s
    return JointResult(
        mz=mz, mz_std=float(std[0]), mz_low=float(lo), mz_high=float(hi),
        impedance_ratio=density_ratio(mz) * sound_speed_ratio(mz), impedance_std=float(abs(dz) * std[0]),
        w2_cm4=10.0 ** lw, log10_w2_std=std_w, sigma2=10.0 ** ls, log10_sigma2_std=std_s,
        calibration_offset_db=-float(best.x[-1]), calibration_offset_std_db=float(std[-1]),
        nadir_model_reflection=nadir_model_reflection(mz, lw, ls),
        misfit_db=float(np.sqrt(np.mean(strengths ** 2))), chi2_reduced=float(chi2_red),
        n_data=n_data, unresolved=unresolved, converged=bool(best.success))
