"""Per-patch AVO records and their CSV table (one row per patch).

:func:`survey_records` runs the whole AVO chain on a list of stacked
patches: attributes (docs/avo.md), background trend over the survey, fluid
factor and product, and optionally the model inversion; :func:`write_csv`
writes the result.  Columns carry their units in their names.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.io.paths import check_output_path
from clbeam.seabed.avo.attributes import (
    AngularAttributes,
    angular_attributes,
    background_trend,
    fluid_factor,
)
from clbeam.seabed.avo.calibration import Calibration
from clbeam.seabed.avo.inversion import LOG10_SIGMA2_BOUNDS, LOG10_W2_BOUNDS, InversionResult, invert_response
from clbeam.seabed.avo.joint import MZ_RESOLVED_WIDTH_PHI, invert_joint
from clbeam.seabed.avo.sediment import MZ_MAX, MZ_MIN
from clbeam.seabed.avo.stack import Patch


@dataclass(frozen=True)
class PatchRecord:
    """One row of the AVO table.

    ``fluid_factor_db`` and ``product_db2`` depend on the survey's trend
    ``(trend_g, trend_d_db)``; the inversion fields are NaN when no
    inversion was run; ``nadir_reflection`` (and its standard error) is the
    seabed's normal-incidence reflection coefficient of the patch's pings
    from the nadir echo and its surface multiple, and ``nadir_calibration_db``
    (and its error) the constant its primary echo gives the strengths
    (:func:`clbeam.seabed.nadir.patch_reflections`), NaN without the ping file.
    ``calibration_db`` is what was added to every strength of the survey,
    ``calibration_source`` where it came from (``nadir``: the patches'
    estimates combined, :func:`clbeam.seabed.avo.calibration.survey_calibration`;
    ``option``; ``none``: relative strengths).  ``inversion`` is ``joint``
    (nadir coefficient and calibrated response, :mod:`clbeam.seabed.avo.joint`),
    ``response`` or ``none``; ``mz_low_phi``..``mz_high_phi`` the 68 %
    interval of the joint inversion, ``calibration_offset_db`` the offset it
    fitted, ``unresolved`` the parameters either inversion could not resolve
    (``;``-separated; :func:`unresolved_parameters`: ``mz`` also wherever the
    strengths are relative or the fit stopped at a grain-size bound).
    """

    ping_start: int
    ping_stop: int
    side: str
    along_track_m: float
    near_mean_db: float
    near_slope_db_per_deg: float
    near_intercept_db: float
    far_mean_db: float
    far_slope_db_per_deg: float
    far_intercept_db: float
    outer_mean_db: float
    near_incidence_deg: float
    far_incidence_deg: float
    intercept_a_db: float
    gradient_b_db: float
    fluid_factor_db: float
    product_db2: float
    trend_g: float
    trend_d_db: float
    mz_phi: float = math.nan
    mz_std_phi: float = math.nan
    impedance_ratio: float = math.nan
    impedance_std: float = math.nan
    roughness_w2_cm4: float = math.nan
    log10_w2_std: float = math.nan
    volume_sigma2: float = math.nan
    misfit_db: float = math.nan
    nadir_reflection: float = math.nan
    nadir_reflection_error: float = math.nan
    nadir_calibration_db: float = math.nan
    nadir_calibration_error_db: float = math.nan
    calibration_db: float = 0.0
    calibration_error_db: float = math.nan
    calibration_source: str = "none"
    inversion: str = "none"
    mz_low_phi: float = math.nan
    mz_high_phi: float = math.nan
    calibration_offset_db: float = math.nan
    nadir_model_reflection: float = math.nan
    unresolved: str = ""


COLUMNS = tuple(f.name for f in fields(PatchRecord))


def survey_records(patches: list[Patch], *, frequency_hz: float | None = None, invert: bool = True,
                   nadir=None, calibration: Calibration | None = None, **inversion_options) -> list[PatchRecord]:
    """AVO attributes, trend, fluid factor, product and inversion of every patch.

    Parameters
    ----------
    patches : list of Patch
        Stacked responses (:func:`clbeam.seabed.avo.stack.stack_sides`), calibrated by ``calibration``.
    frequency_hz : float, optional
        Sonar centre frequency (Hz); required when ``invert``.
    invert : bool
        Invert each patch: jointly with its nadir coefficient when it has
        one and the strengths are absolute (:func:`clbeam.seabed.avo.joint.invert_joint`),
        else the response alone (:func:`clbeam.seabed.avo.inversion.invert_response`).
    nadir : dict, optional
        ``(ping_start, ping_stop) -> PatchNadir`` (:func:`clbeam.seabed.nadir.patch_reflections`).
    calibration : Calibration, optional
        What was added to the strengths; default none (relative strengths).
    **inversion_options
        Passed to the inversion (``sound_speed_water_m_s``, ``fit_roughness``, ``fit_volume``).

    Returns
    -------
    list of PatchRecord
        In the order of ``patches``.
    """
    require(len(patches) >= 2, OptionError,
            f"the background trend needs at least 2 patches, got {len(patches)}")
    require(not invert or frequency_hz is not None, OptionError,
            "frequency_hz is required when invert is True")
    cal = calibration or Calibration(0.0, math.nan, "none")
    nadir = nadir or {}
    attrs: list[AngularAttributes] = [angular_attributes(p.incidence_deg, p.strength_db) for p in patches]
    a = np.array([x.intercept_a_db for x in attrs])
    b = np.array([x.gradient_b_db for x in attrs])
    g, d = background_trend(a, b)
    ff = fluid_factor(a, b, g, d)
    rows = []
    for p, at, f_ in zip(patches, attrs, ff):
        found = nadir.get((p.ping_start, p.ping_stop))
        extra = _nadir_fields(found, cal)
        if invert:
            extra.update(_inversion_fields(p, found, cal, frequency_hz, inversion_options))
        rows.append(PatchRecord(ping_start=p.ping_start, ping_stop=p.ping_stop, side=p.side,
                                along_track_m=p.along_track_m, fluid_factor_db=float(f_),
                                product_db2=at.intercept_a_db * at.gradient_b_db,
                                trend_g=g, trend_d_db=d, **at.as_dict(), **extra))
    return rows


def _nadir_fields(found, cal: Calibration) -> dict:
    """The nadir and calibration columns of a patch."""
    out = dict(calibration_db=cal.db, calibration_error_db=cal.error_db, calibration_source=cal.source)
    if found is not None:
        out.update(nadir_reflection=found.reflection, nadir_reflection_error=found.reflection_error,
                   nadir_calibration_db=found.calibration_db, nadir_calibration_error_db=found.calibration_error_db)
    return out


def _inversion_fields(p: Patch, found, cal: Calibration, frequency_hz: float, options: dict) -> dict:
    """The inversion columns of a patch: joint when it has a nadir coefficient and absolute strengths."""
    r0 = math.nan if found is None else found.reflection
    if cal.absolute and math.isfinite(cal.error_db) and 0 < r0 < 1:
        j = invert_joint(p.incidence_deg, p.strength_db, frequency_hz, nadir_reflection=r0,
                         nadir_reflection_error=np.nan_to_num(found.reflection_error), calibration_error_db=cal.error_db,
                         **options)
        return dict(inversion="joint", mz_phi=j.mz, mz_std_phi=j.mz_std, mz_low_phi=j.mz_low, mz_high_phi=j.mz_high,
                    impedance_ratio=j.impedance_ratio, impedance_std=j.impedance_std, roughness_w2_cm4=j.w2_cm4,
                    log10_w2_std=j.log10_w2_std, volume_sigma2=j.sigma2, misfit_db=j.misfit_db,
                    calibration_offset_db=j.calibration_offset_db, nadir_model_reflection=j.nadir_model_reflection,
                    unresolved=";".join(unresolved_parameters(j.mz, j.mz_std, absolute=True, joint=j.unresolved)))
    r: InversionResult = invert_response(p.incidence_deg, p.strength_db, frequency_hz, **options)
    return dict(inversion="response", mz_phi=r.mz, mz_std_phi=r.mz_std, impedance_ratio=r.impedance_ratio,
                impedance_std=r.impedance_std, roughness_w2_cm4=r.w2_cm4, log10_w2_std=r.log10_w2_std,
                volume_sigma2=r.sigma2, misfit_db=r.misfit_db,
                unresolved=";".join(unresolved_parameters(r.mz, r.mz_std, absolute=cal.absolute,
                                                          log10_w2_std=r.log10_w2_std,
                                                          log10_sigma2_std=r.log10_sigma2_std)))


#: a grain size this close to a bound of the inversion (phi) stopped there: the data would go further
MZ_BOUND_TOLERANCE_PHI = 1e-3


def unresolved_parameters(mz_phi: float, mz_std_phi: float, *, absolute: bool, joint: tuple | None = None,
                          log10_w2_std: float = 0.0, log10_sigma2_std: float = 0.0) -> tuple:
    """The parameters an inversion did not resolve, in the order ``mz``, ``roughness``, ``volume``.

    ``mz`` is unresolved where the joint inversion says so (its interval,
    :mod:`clbeam.seabed.avo.joint`), where its standard deviation is above
    1 phi or unknown, where the fit stopped within
    :data:`MZ_BOUND_TOLERANCE_PHI` of a bound of the grain sizes (``-1`` or
    ``9`` phi: the bound, not the data, set it), and wherever the strengths
    are relative (no calibration: the level that sets the grain size is
    unknown, so the response's shape alone gives it).  Roughness and volume:
    the joint inversion's, or a standard deviation (log10) above a quarter of
    their bounds' span or unknown.

    Parameters
    ----------
    mz_phi, mz_std_phi : float
        The fitted grain size and its standard deviation (phi).
    absolute : bool
        The strengths were calibrated.
    joint : tuple of str, optional
        The joint inversion's own unresolved parameters.
    log10_w2_std, log10_sigma2_std : float
        The response inversion's standard deviations of log10 roughness and
        volume parameter (0: not fitted).

    Returns
    -------
    tuple of str
    """
    names = set(joint or ())
    at_bound = min(abs(mz_phi - MZ_MIN), abs(mz_phi - MZ_MAX)) <= MZ_BOUND_TOLERANCE_PHI
    if not absolute or at_bound or not mz_std_phi <= MZ_RESOLVED_WIDTH_PHI / 2:
        names.add("mz")
    if joint is None:
        if not log10_w2_std <= (LOG10_W2_BOUNDS[1] - LOG10_W2_BOUNDS[0]) / 4:
            names.add("roughness")
        if not log10_sigma2_std <= (LOG10_SIGMA2_BOUNDS[1] - LOG10_SIGMA2_BOUNDS[0]) / 4:
            names.add("volume")
    return tuple(n for n in ("mz", "roughness", "volume") if n in names)


def write_csv(path, records: list[PatchRecord]) -> Path:
    """Write the AVO table: a header of :data:`COLUMNS`, one row per patch.

    Floats are written with ``repr`` precision (round-trip exact); NaN as
    ``nan``.

    Parameters
    ----------
    path : str or pathlib.Path
        Output file.
    records : list of PatchRecord
        Rows.

    Returns
    -------
    pathlib.Path
    """
    path = check_output_path(path, what="AVO table")
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        for r in records:
            w.writerow([repr(float(v)) if isinstance(v, (float, np.floating)) else v
                        for v in (getattr(r, c) for c in COLUMNS)])
    return path
