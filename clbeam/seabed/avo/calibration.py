"""The survey's calibration: the constant that makes image strengths absolute, from its patches' nadir echoes.

Each patch's primary nadir echo gives the system constant with a standard
error (:func:`clbeam.seabed.nadir.coherent_calibration_db`); the constant
is the same for the whole survey (source level, sensitivities and the
imager's gains do not change along a line), so :func:`survey_calibration`
combines the patches: the inverse-variance weighted mean, its standard
error scaled up by the patches' scatter when that exceeds their errors
(Birge ratio), and a floor for what the measurement leaves out
(:data:`SYSTEMATIC_ERROR_DB`: the simulated seabed without scattering gives
the constant within 0.2 dB).  Patches over a strong reflector weigh most: their
primary stands furthest above the scattering around it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError, require

#: Error floor of a calibration from the nadir echoes (dB).
SYSTEMATIC_ERROR_DB = 0.5
#: Values of :attr:`Calibration.source`.
CALIBRATION_SOURCES = ("nadir", "option", "none")


@dataclass(frozen=True)
class Calibration:
    """The calibration applied to a survey's strengths.

    Attributes
    ----------
    db : float
        Added to every strength (dB).
    error_db : float
        Its standard deviation (dB; NaN when unknown: ``"none"``).
    source : str
        ``"nadir"`` (from the patches' nadir echoes), ``"option"`` (given
        by the user) or ``"none"`` (relative strengths, 0 dB).
    n_patches : int
        Patches the nadir estimate combined (0 otherwise).
    """

    db: float
    error_db: float
    source: str
    n_patches: int = 0

    def __post_init__(self):
        require(self.source in CALIBRATION_SOURCES, OptionError,
                f"calibration source must be one of {', '.join(CALIBRATION_SOURCES)}, got {self.source!r}")
        require(math.isfinite(self.db), OptionError, f"calibration must be finite, got {self.db!r} dB")

    @property
    def absolute(self) -> bool:
        """The strengths are absolute (a calibration was applied)."""
        return self.source != "none"


def survey_calibration(values_db, errors_db) -> Calibration | None:
    """The survey's calibration from its patches' nadir estimates (module docstring); None when no patch has one.

    Parameters
    ----------
    values_db, errors_db : array_like
        Each patch's calibration and standard error (dB); NaN entries and non-positive errors are left out,
        and errors below 0.05 dB count as 0.05 dB (no patch outweighs the rest by more than the floor allows).

    Returns
    -------
    Calibration or None
    """
    v = np.asarray(values_db, dtype=np.float64)
    e = np.asarray(errors_db, dtype=np.float64)
    require(v.shape == e.shape and v.ndim == 1, OptionError,
            f"calibrations and their errors must be 1-D of one length, got {v.shape} and {e.shape}")
    ok = np.isfinite(v) & np.isfinite(e) & (e > 0)
    if not ok.any():
        return None
    v, e = v[ok], np.maximum(e[ok], 0.05)
    w = 1.0 / e ** 2
    mean = float(np.sum(w * v) / np.sum(w))
    se = math.sqrt(1.0 / float(np.sum(w)))
    if v.size > 1:
        birge = math.sqrt(float(np.sum(w * (v - mean) ** 2)) / (v.size - 1))
        se *= max(1.0, birge)
    return Calibration(mean, math.hypot(se, SYSTEMATIC_ERROR_DB), "nadir", int(v.size))
