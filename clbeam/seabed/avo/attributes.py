"""AVO attributes of a stacked backscatter angular response (Fonseca et al. 2005).

Conventions (docs/avo.md): the angular response is backscatter strength (dB)
against **incidence** angle ``phi`` from the vertical; the ranges are
defined by **grazing** angle ``theta = 90 - phi``:

* near  range: grazing 90–65° (incidence 0–25°);
* far   range: grazing 65–35° (incidence 25–55°);
* outer range: grazing 35–5°  (incidence 55–85°).

Per range the mean (dB), and for near and far a least-squares line in
grazing angle, its slope (dB per degree of grazing angle, positive when
the strength rises toward nadir) and its value at 80° (near) or 55° (far)
grazing.  Then Fonseca's equations 1–2, with ``phi`` the mean incidence
angle of each range and ``Near``, ``Far`` the range means:

``B = (Far - Near) / (sin^2 phi_far - sin^2 phi_near)`` (gradient),
``A = (Far + Near)/2 - B (sin^2 phi_far + sin^2 phi_near)/2`` (intercept),

i.e. the line ``S(phi) = A + B sin^2 phi`` through the two range means.
(The paper's symbol list swaps the words gradient and intercept; the
equations are right.)  Over a survey, the background trend is the
least-squares line ``B = g A + d`` (equation 3), the fluid factor the
signed orthogonal distance ``(-g A + B - d)/sqrt(g^2 + 1)`` (equation 4)
and the product ``A B``.

Range membership is half-open on the nadir side: a bin at exactly 65°
grazing belongs to the far range, one at 35° to the outer range.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from clbeam.errors import OptionError, require

#: Grazing-angle ranges (deg): (low, high), low exclusive except at 5°.
NEAR_RANGE_DEG = (65.0, 90.0)
FAR_RANGE_DEG = (35.0, 65.0)
OUTER_RANGE_DEG = (5.0, 35.0)
#: Grazing angles (deg) at which the near and far lines are evaluated.
NEAR_INTERCEPT_DEG = 80.0
FAR_INTERCEPT_DEG = 55.0
#: Fewest valid angle bins for a range mean; a line needs two distinct angles.
MIN_BINS = 2


@dataclass(frozen=True)
class AngularAttributes:
    """AVO attributes of one patch (Fonseca et al. 2005; docs/avo.md).

    Strengths in dB, slopes in dB per degree of grazing angle, angles in
    degrees.  A value is NaN when its range holds fewer than two valid bins.
    """

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

    def as_dict(self) -> dict[str, float]:
        """Field name → value."""
        return asdict(self)


def _validated(incidence_deg, strength_db) -> tuple[np.ndarray, np.ndarray]:
    inc = np.asarray(incidence_deg, dtype=np.float64)
    bs = np.asarray(strength_db, dtype=np.float64)
    require(inc.ndim == 1 and bs.shape == inc.shape, OptionError,
            f"incidence_deg and strength_db must be 1-D of equal length, got shapes {inc.shape} and {bs.shape}")
    require(bool(np.all(np.isfinite(inc))), OptionError, "incidence_deg must be finite")
    return inc, bs


def range_mask(incidence_deg, grazing_range_deg: tuple[float, float]) -> np.ndarray:
    """Bins whose grazing angle ``90 - |incidence|`` lies in a range.

    ``(low, high]`` in grazing angle (closed at ``low`` when ``low`` is 5°),
    so the three ranges partition grazing angles 5–90°.

    Parameters
    ----------
    incidence_deg : array_like
        Incidence angles from the vertical (deg); sign (port/starboard) ignored.
    grazing_range_deg : tuple of float
        ``(low, high)`` grazing angles (deg).
    """
    g = 90.0 - np.abs(np.asarray(incidence_deg, dtype=np.float64))
    low, high = grazing_range_deg
    lower_ok = g >= low if low <= OUTER_RANGE_DEG[0] else g > low
    return lower_ok & (g <= high)


def _line(grazing: np.ndarray, bs: np.ndarray, at_deg: float) -> tuple[float, float]:
    """Least-squares ``bs = c + s (grazing - at)``: returns (slope s, value c)."""
    if grazing.size < MIN_BINS or np.ptp(grazing) == 0:
        return math.nan, math.nan
    x = grazing - at_deg
    slope, value = np.polyfit(x, bs, 1)
    return float(slope), float(value)


def gradient_intercept(near_db, far_db, near_incidence_deg, far_incidence_deg):
    """Gradient ``B`` and intercept ``A`` (dB), Fonseca et al. (2005) eqs. 1–2.

    ``B = (Far - Near) / (sin^2 phi_far - sin^2 phi_near)``,
    ``A = (Far + Near)/2 - B (sin^2 phi_far + sin^2 phi_near)/2``.

    Parameters
    ----------
    near_db, far_db : array_like
        Mean strengths of the near and far ranges (dB).
    near_incidence_deg, far_incidence_deg : array_like
        Mean incidence angles of those ranges (deg from vertical).

    Returns
    -------
    (A, B) : tuple of numpy.ndarray or float
    """
    s_n = np.sin(np.radians(near_incidence_deg)) ** 2
    s_f = np.sin(np.radians(far_incidence_deg)) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        b = (np.asarray(far_db) - np.asarray(near_db)) / (s_f - s_n)
    a = (np.asarray(far_db) + np.asarray(near_db)) / 2.0 - b * (s_f + s_n) / 2.0
    return a, b


def angular_attributes(incidence_deg, strength_db) -> AngularAttributes:
    """AVO attributes of one stacked angular response (docs/avo.md).

    Parameters
    ----------
    incidence_deg : array_like
        Incidence angle of each bin (deg from vertical), 1-D.
    strength_db : array_like
        Backscatter strength of each bin (dB); NaN bins are skipped.

    Returns
    -------
    AngularAttributes
    """
    inc, bs = _validated(incidence_deg, strength_db)
    ok = np.isfinite(bs)
    out = {}
    thetas = {}
    for name, rng, at in (("near", NEAR_RANGE_DEG, NEAR_INTERCEPT_DEG),
                          ("far", FAR_RANGE_DEG, FAR_INTERCEPT_DEG),
                          ("outer", OUTER_RANGE_DEG, None)):
        m = range_mask(inc, rng) & ok
        enough = int(m.sum()) >= MIN_BINS
        out[f"{name}_mean_db"] = float(np.mean(bs[m])) if enough else math.nan
        thetas[name] = float(np.mean(np.abs(inc[m]))) if enough else math.nan
        if at is not None:
            slope, value = _line(90.0 - np.abs(inc[m]), bs[m], at)
            out[f"{name}_slope_db_per_deg"] = slope
            out[f"{name}_intercept_db"] = value
    a, b = gradient_intercept(out["near_mean_db"], out["far_mean_db"], thetas["near"], thetas["far"])
    return AngularAttributes(near_incidence_deg=thetas["near"], far_incidence_deg=thetas["far"],
                             intercept_a_db=float(a), gradient_b_db=float(b), **out)


def background_trend(intercept_a_db, gradient_b_db) -> tuple[float, float]:
    """Background trend ``B = g A + d`` by least squares over all patches (eq. 3).

    Ordinary least squares of ``B`` on ``A`` over the finite pairs.

    Parameters
    ----------
    intercept_a_db, gradient_b_db : array_like
        ``A`` and ``B`` of every patch of the survey (dB).

    Returns
    -------
    (g, d) : tuple of float
        Slope (dB/dB) and intercept (dB) of the trend.
    """
    a = np.asarray(intercept_a_db, dtype=np.float64).ravel()
    b = np.asarray(gradient_b_db, dtype=np.float64).ravel()
    require(a.shape == b.shape, OptionError,
            f"intercept_a_db and gradient_b_db must have equal length, got {a.size} and {b.size}")
    ok = np.isfinite(a) & np.isfinite(b)
    require(int(ok.sum()) >= 2 and np.ptp(a[ok]) > 0, OptionError,
            f"background trend needs >= 2 patches with distinct finite A, got {int(ok.sum())}")
    g, d = np.polyfit(a[ok], b[ok], 1)
    return float(g), float(d)


def fluid_factor(intercept_a_db, gradient_b_db, g: float, d: float):
    """Fluid factor ``(-g A + B - d) / sqrt(g^2 + 1)`` (dB), eq. 4.

    The signed orthogonal distance of ``(A, B)`` from the trend line
    ``B = g A + d``: positive above the line.

    Parameters
    ----------
    intercept_a_db, gradient_b_db : array_like
        ``A`` and ``B`` (dB).
    g, d : float
        Background trend from :func:`background_trend`.
    """
    return (-g * np.asarray(intercept_a_db) + np.asarray(gradient_b_db) - d) / math.sqrt(g * g + 1.0)


def product(intercept_a_db, gradient_b_db):
    """AVO product ``A * B`` (dB^2), Fonseca et al. (2005)."""
    return np.asarray(intercept_a_db) * np.asarray(gradient_b_db)
