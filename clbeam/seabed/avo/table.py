"""Per-patch AVO records and their CSV table (one row per patch).

:func:`survey_records` runs the whole AVO chain on a list of stacked
patches: attributes (SPEC §5), background trend over the survey, fluid
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
from clbeam.seabed.avo.inversion import InversionResult, invert_response
from clbeam.seabed.avo.stack import Patch


@dataclass(frozen=True)
class PatchRecord:
    """One row of the AVO table.

    ``fluid_factor_db`` and ``product_db2`` depend on the survey's trend
    ``(trend_g, trend_d_db)``; the inversion fields are NaN when no
    inversion was run; ``nadir_reflection`` (and its standard error) is the
    seabed's normal-incidence reflection coefficient of the patch's pings
    from the nadir echo and its surface multiple, and ``nadir_calibration_db``
    the constant its primary echo gives the strengths (reported, not applied;
    :func:`clbeam.seabed.nadir.patch_reflections`), NaN without the ping file.
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


COLUMNS = tuple(f.name for f in fields(PatchRecord))


def survey_records(patches: list[Patch], *, frequency_hz: float | None = None,
                   invert: bool = True, **inversion_options) -> list[PatchRecord]:
    """AVO attributes, trend, fluid factor, product and inversion of every patch.

    Parameters
    ----------
    patches : list of Patch
        Stacked responses (:func:`clbeam.seabed.avo.stack.stack_sides`).
    frequency_hz : float, optional
        Sonar centre frequency (Hz); required when ``invert``.
    invert : bool
        Run :func:`clbeam.seabed.avo.inversion.invert_response` on each patch.
    **inversion_options
        Passed to :func:`~clbeam.seabed.avo.inversion.invert_response`.

    Returns
    -------
    list of PatchRecord
        In the order of ``patches``.
    """
    require(len(patches) >= 2, OptionError,
            f"the background trend needs at least 2 patches, got {len(patches)}")
    require(not invert or frequency_hz is not None, OptionError,
            "frequency_hz is required when invert is True")
    attrs: list[AngularAttributes] = [angular_attributes(p.incidence_deg, p.strength_db) for p in patches]
    a = np.array([x.intercept_a_db for x in attrs])
    b = np.array([x.gradient_b_db for x in attrs])
    g, d = background_trend(a, b)
    ff = fluid_factor(a, b, g, d)
    rows = []
    for p, at, f_ in zip(patches, attrs, ff):
        extra = {}
        if invert:
            r: InversionResult = invert_response(p.incidence_deg, p.strength_db, frequency_hz, **inversion_options)
            extra = dict(mz_phi=r.mz, mz_std_phi=r.mz_std, impedance_ratio=r.impedance_ratio,
                         impedance_std=r.impedance_std, roughness_w2_cm4=r.w2_cm4,
                         log10_w2_std=r.log10_w2_std, volume_sigma2=r.sigma2, misfit_db=r.misfit_db)
        rows.append(PatchRecord(ping_start=p.ping_start, ping_stop=p.ping_stop, side=p.side,
                                along_track_m=p.along_track_m, fluid_factor_db=float(f_),
                                product_db2=at.intercept_a_db * at.gradient_b_db,
                                trend_g=g, trend_d_db=d, **at.as_dict(), **extra))
    return rows


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
