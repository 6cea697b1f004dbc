"""A smooth pipe's specular echo: where the pipe really crosses each ping's plane, and whether a line's
echoes fade as a specular echo must.

A smooth pipe returns its echo from its point nearest the source.  Where
the pipe meets the ping's plane at a heading ``a`` to the track, that point
lies off the plane, and the echo, moved along its arc to the pipe's depth,
lies at the nearest distance ``h`` from the ship instead of at the crossing
``D``: ``h = D cos a`` for a straight pipe, less or more where the pipe
curves towards or away from the ship.  Two consequences:

* **Position.** :func:`specular_crossing` inverts that geometry, the
  pipe's curvature included (to second order in the heading).
* **Evidence.** The nearest point moves off the plane by ``h sin a`` as
  the heading turns, out of the transmit beam along the track; the
  echo's level falls with it (one way, through the transmit pattern only:
  the receive array has no directivity along the track).  By the envelope
  theorem ``dh/ds = sin a*``, the sine of the heading at the nearest
  point, so along the echoes' own path the level of a specular echo falls
  as ``beta sin^2 a*`` (a Gaussian main lobe), while a rough pipe's diffuse
  echo, from the plane itself, does not.  :func:`fading_fit` fits that
  fall to the echoes' levels corrected for spherical spreading.
"""

from __future__ import annotations

import math

import numpy as np


def local_quadratic(s, y, at, half_width_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local quadratic fit of ``y(s)`` at ``at`` (tricube weights of half-width ``half_width_m``, widened
    where fewer than four points weigh in): the value, first and second derivatives there."""
    s, y, at = (np.asarray(v, dtype=np.float64) for v in (s, y, at))
    d = s[None, :] - at[:, None]
    reach = np.maximum(half_width_m, np.sort(np.abs(d), axis=1)[:, min(3, s.size - 1)] * 1.01)
    u = d / reach[:, None]  # scaled: the normal equations stay well conditioned
    w = np.clip(1 - np.abs(u) ** 3, 0, None) ** 3
    powers = np.stack([np.ones_like(u), u, u * u], axis=-1)            # (k, n, 3)
    gram = np.einsum("kn,kni,knj->kij", w, powers, powers) + 1e-12 * np.eye(3)
    rhs = np.einsum("kn,kni,n->ki", w, powers, y)
    coef = np.linalg.solve(gram, rhs[..., None])[..., 0]
    return coef[:, 0], coef[:, 1] / reach, 2 * coef[:, 2] / reach ** 2


def specular_crossing(echo_y, s_m, centre_y, at_s, half_width_m: float) -> np.ndarray:
    """Where a smooth pipe crosses the pings' planes, from its specular echoes.

    The echoes, moved along their arcs to the pipe's depth, lie at the
    nearest distance ``h`` from the ship.  By the envelope theorem
    ``h' = sin a*``, the heading at the nearest point, and
    ``h'' = k cos^2 a* / (1 + k h)`` for a pipe of curvature ``k`` (positive
    bending away from the ship); the crossing is then at
    ``D = h / cos a* + k h^2 sin^2 a* / 2`` (the nearest point lies
    ``h sin a*`` off the plane and the pipe bends by ``k x^2 / 2`` over
    that stretch).  ``h``, ``h'`` and ``h''`` come from a local quadratic
    fit of the echoes' distances.

    Parameters
    ----------
    echo_y, s_m, centre_y : array_like
        ``(n,)`` the echoes' offsets across the track (m, moved along their
        arcs), their pings' along-track distances (m) and grid centres (m).
    at_s : array_like
        ``(k,)`` along-track distances (m) where the crossing is wanted.
    half_width_m : float
        Half-width of the fit along the track (m).

    Returns
    -------
    numpy.ndarray
        ``(k,)`` the crossings across the track (m, on the echoes' side, from
        the centre interpolated to ``at_s``).
    """
    y, s, c = (np.asarray(v, dtype=np.float64) for v in (echo_y, s_m, centre_y))
    at = np.asarray(at_s, dtype=np.float64)
    side = 1.0 if np.mean(y - c) >= 0 else -1.0
    order = np.argsort(s, kind="stable")
    c_at = np.interp(at, s[order], c[order])
    if np.unique(s).size < 3:
        return c_at + side * np.interp(at, s[order], np.abs(y - c)[order])
    h, h1, h2 = local_quadratic(s, np.abs(y - c), at, half_width_m)
    sin2 = np.clip(h1, -0.95, 0.95) ** 2
    cos2 = 1 - sin2
    kappa = h2 / np.where(np.abs(cos2 - h * h2) > 0.05, cos2 - h * h2, np.nan)
    bend = np.nan_to_num(0.5 * kappa * h ** 2 * sin2, nan=0.0)
    return c_at + side * (h / np.sqrt(cos2) + bend)


def fading_floor_db(beam_width_deg: float) -> float:
    """The least fall (dB per unit ``sin^2 a*``) taken as a transmit beam's: a third of a Gaussian main
    lobe's of that -3 dB width (``12 / width^2``, width in rad; the SBP29's 4.5 degrees: 1,950, of which
    Line 4's smooth pipes show 1,250-2,000).  Lines fading more slowly lose their level for other reasons."""
    return 12.0 / math.radians(beam_width_deg) ** 2 / 3.0


def fading_fit(level_db, range_m, sin_a) -> dict:
    """Fit of echo levels to a specular echo's fall out of the transmit beam.

    ``level_db + 20 log10(range^2)`` (spherical spreading both ways
    removed) fitted as ``L0 - beta sin^2 a`` by least squares, the
    residual scatter estimated from the fit.

    Parameters
    ----------
    level_db : array_like
        ``(n,)`` the echoes' intensities (dB).
    range_m : array_like
        ``(n,)`` their slant ranges (m).
    sin_a : array_like
        ``(n,)`` the sine of the heading at the nearest point (the slope of
        the echoes' path, ``dh/ds``).

    Returns
    -------
    dict
        ``beta_db`` (dB per unit ``sin^2 a``; about 2,600 for the SBP29's
        3.5 m transmitter at its centre frequency), ``beta_error_db`` (its
        standard error; NaN with fewer than four echoes or no spread in
        heading) and ``span_db`` (the fall the fit predicts across the
        line's headings).
    """
    level = np.asarray(level_db, dtype=np.float64) + 40.0 * np.log10(np.maximum(np.asarray(range_m, float), 1e-3))
    x = np.asarray(sin_a, dtype=np.float64) ** 2
    ok = np.isfinite(level) & np.isfinite(x)
    out = {"beta_db": np.nan, "beta_error_db": np.nan, "span_db": np.nan}
    if ok.sum() < 4 or np.ptp(x[ok]) <= 0:
        return out
    a = np.stack([np.ones(ok.sum()), -x[ok]], axis=1)
    coef, *_ = np.linalg.lstsq(a, level[ok], rcond=None)
    resid = level[ok] - a @ coef
    var = float(resid @ resid) / max(ok.sum() - 2, 1)
    cov = var * np.linalg.pinv(a.T @ a)
    out.update(beta_db=float(coef[1]), beta_error_db=float(np.sqrt(max(cov[1, 1], 0.0))),
               span_db=float(coef[1] * np.ptp(x[ok])))
    return out
