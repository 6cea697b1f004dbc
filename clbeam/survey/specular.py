"""A smooth pipe's specular echo: where the pipe really crosses each ping's plane, and whether a line's
echoes fade as a specular echo must.

A smooth pipe returns its echo from its point nearest the source.  Where
the pipe meets the ping's plane at a heading ``a`` to the track, that point
lies off the plane, and the echo, moved along its arc to the pipe's depth,
lies at the nearest distance ``h`` from the ship instead of at the crossing
``D``: ``h = D cos a`` for a straight pipe, less or more where the pipe
curves towards or away from the ship.  Two consequences:

* **Position.** :func:`specular_crossing` inverts that geometry, the
  pipe's curvature included.
* **Evidence.** The nearest point moves off the plane by ``h sin a`` as
  the heading turns, out of the transmit beam along the track; the
  echo's level falls with it (one way, through the transmit pattern only:
  the receive array has no directivity along the track).  By the envelope
  theorem ``dh/ds = sin a*``, the sine of the heading at the nearest
  point, seen from the source at ``(h / R) sin a*`` off the plane, so along
  the echoes' own path the level of a specular echo falls as
  ``beta ((h / R) sin a*)^2`` (a Gaussian main lobe), while a rough pipe's
  diffuse echo, from the plane itself, does not.  :func:`fading_fit` fits
  that fall to the echoes' levels corrected for a line's spreading.
"""

from __future__ import annotations

import math

import numpy as np


def local_quadratic(s, y, at, half_width_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local quadratic fit of ``y(s)`` at ``at`` (tricube weights of half-width ``half_width_m``, widened
    to 1.5 times the fourth nearest point's distance where fewer weigh in): the value, first and second
    derivatives there.  Each fit uses only the points inside its window (memory and time grow with the
    points, not their square)."""
    s, y, at = (np.asarray(v, dtype=np.float64) for v in (s, y, at))
    order = np.argsort(s, kind="stable")
    s, y = s[order], y[order]
    out = np.full((3, at.size), np.nan)
    k = min(4, s.size)
    for i, a in enumerate(at):
        lo, hi = np.searchsorted(s, a - half_width_m, side="left"), np.searchsorted(s, a + half_width_m, side="right")
        reach = half_width_m
        if hi - lo < k:  # the k nearest points set the window
            near = np.sort(np.abs(s - a))[k - 1]
            reach = max(half_width_m, 1.5 * near)
            lo, hi = np.searchsorted(s, a - reach, side="left"), np.searchsorted(s, a + reach, side="right")
        u = (s[lo:hi] - a) / reach  # scaled: the normal equations stay well conditioned
        w = np.clip(1 - np.abs(u) ** 3, 0, None) ** 3
        basis = np.stack([np.ones_like(u), u, u * u], axis=1)
        gram = (basis * w[:, None]).T @ basis + 1e-12 * np.eye(3)
        coef = np.linalg.lstsq(gram, (basis * w[:, None]).T @ y[lo:hi], rcond=None)[0]
        out[:, i] = coef[0], coef[1] / reach, 2 * coef[2] / reach ** 2
    return out[0], out[1], out[2]


def specular_crossing(echo_y, s_m, centre_y, at_s, half_width_m: float) -> np.ndarray:
    """Where a smooth pipe crosses the pings' planes, from its specular echoes.

    The echoes, moved along their arcs to the pipe's depth, lie at the
    nearest horizontal point of the pipe, offset ``u`` across the track from
    the ship (signed).  By the envelope theorem ``|u|' = sin a*``, the
    heading at the nearest point, and ``u'' = k cos^2 a* / (1 + k u)`` for
    a pipe of curvature ``k`` (signed like ``u''``); the crossing lies
    ``u tan a*`` along the pipe from the nearest point, where the pipe has
    bent by ``k (u tan a*)^2 / 2``, so that
    ``D = u / cos a* + u'' u^2 sin^2 a* / (2 cos^3 a* (cos^2 a* - u u''))``.
    ``u`` and its derivatives come from a local quadratic fit of the
    echoes' offsets less their grid centres, the centre from the same fit
    (a centre that moves from ping to ping does not enter twice).

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
        ``(k,)`` the crossings across the track (m).
    """
    y, s, c = (np.asarray(v, dtype=np.float64) for v in (echo_y, s_m, centre_y))
    at = np.asarray(at_s, dtype=np.float64)
    if np.unique(s).size < 3:
        order = np.argsort(s, kind="stable")
        return np.interp(at, s[order], y[order])
    u, u1, u2 = local_quadratic(s, y - c, at, half_width_m)
    centre = local_quadratic(s, c, at, half_width_m)[0]
    return centre + crossing_offset(u, u1, u2)


def specular_image(crossing_y, crossing_z, slope, centre_yz) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where a straight, level smooth pipe's specular echo is imaged in the ping's plane, from where it
    crosses it, and how far off the plane its nearest point lies.

    The pipe crosses the plane ``D`` across and ``d`` below the grid centre
    at a heading ``a`` to the track, level (at one depth along its length);
    its nearest point lies ``u = D cos a`` from the ship horizontally,
    ``x = D sin a cos a`` off the plane, at range ``R = sqrt(u^2 + d^2)``.
    The array reads its direction cosine across, ``D cos^2 a / R``, so the
    echo is imaged ``D cos^2 a`` across (``D sin^2 a`` nearer the ship) and
    ``sqrt(d^2 + x^2)`` down, ``sqrt(d^2 + x^2) - d`` deeper than the pipe.

    Parameters
    ----------
    crossing_y, crossing_z : array_like
        ``(n,)`` the crossing's offset across the track and depth (m).
    slope : array_like
        ``(n,)`` ``tan a``, the pipe's offset change per metre along the track.
    centre_yz : array_like
        ``(n, 2)`` the pings' grid centres (m).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        ``(n,)`` the image's offset across and depth (m), and ``|x| / R``, the sine of the angle off the
        ping's plane at which the source sees the nearest point.
    """
    y, z, t = (np.asarray(v, dtype=np.float64) for v in (crossing_y, crossing_z, slope))
    c = np.asarray(centre_yz, dtype=np.float64).reshape(-1, 2)
    cos2 = 1.0 / (1.0 + t * t)
    big_d, d = y - c[:, 0], z - c[:, 1]
    x = big_d * t * cos2
    return c[:, 0] + big_d * cos2, c[:, 1] + np.sqrt(d * d + x * x), np.abs(x) / np.sqrt(big_d * big_d * cos2 + d * d)


def offsets_at_depth(range_m, y_m, centre_yz_m, seabed, burial_m: float) -> np.ndarray:
    """Echoes moved along their arcs to a pipe's depth, from their slant ranges alone.

    A smooth pipe's echo lies at the slant range ``r`` of the pipe's point
    nearest the grid centre; at the pipe's depth ``Z`` below the centre that
    point lies ``u = sqrt(r^2 - Z^2)`` across from it, whatever angle the
    echo was imaged at.  The range is measured to a few centimetres in every
    ping while the depth's error (the line's burial) is one for the whole
    line, so ``u`` changes from ping to ping as smoothly as the pipe does:
    its derivatives along the track are what :func:`specular_crossing`
    needs.  The seabed is read at the echo's offset (imaged, or moved part
    of the way along its arc: within metres of the nearest point's offset
    across, which the imaging's cone angle keeps).

    Parameters
    ----------
    range_m, y_m : array_like
        ``(n,)`` the echoes' slant ranges from their grid centres and
        their offsets across the track (m): these give the side and where
        the seabed is read.
    centre_yz_m, seabed : array_like
        ``(n, 2)`` grid centres (m) and the pings' seabeds ``(z0, slope)``.
    burial_m : float
        The pipe's burial below the seabed (m).

    Returns
    -------
    numpy.ndarray
        ``(n,)`` offsets across the track (m), on the side of the imaged
        offset; NaN where the range does not reach the pipe's depth.
    """
    r, y = (np.asarray(v, dtype=np.float64) for v in (range_m, y_m))
    c = np.asarray(centre_yz_m, dtype=np.float64).reshape(-1, 2)
    sb = np.asarray(seabed, dtype=np.float64).reshape(-1, 2)
    depth = sb[:, 0] + sb[:, 1] * y + burial_m - c[:, 1]
    across_sq = r ** 2 - depth ** 2
    side = np.where(y >= c[:, 0], 1.0, -1.0)
    return c[:, 0] + side * np.sqrt(np.where(across_sq > 0, across_sq, np.nan))


def crossing_offset(u, u1, u2) -> np.ndarray:
    """The crossing's offset from the ship (m) of the pipe whose nearest point lies at the signed offset
    ``u`` with derivatives ``u1``, ``u2`` along the track: on the pipe's osculating circle (centre on the
    normal through the nearest point, radius ``1 / k``), where it meets the ping's plane; ``u / cos a*`` for
    a straight pipe or where the circle misses the plane."""
    u, u1, u2 = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (u, u1, u2)))
    side = np.where(u >= 0, 1.0, -1.0)
    h, sin_a = np.abs(u), np.clip(side * u1, -0.95, 0.95)
    cos_a = np.sqrt(1 - sin_a ** 2)
    straight = side * h / cos_a
    den = cos_a ** 2 - h * side * u2
    curved = np.abs(den) > 0.05
    kappa = np.where(curved, side * u2 / np.where(curved, den, 1.0), 0.0)
    curved &= np.abs(kappa) > 1e-9
    rho = 1.0 / np.where(curved, kappa, 1.0)
    dx = sin_a * (h + rho)                     # the ping's plane from the circle's centre, along the track
    centre_y = side * cos_a * (h + rho)        # and the centre's offset across
    disc = rho ** 2 - dx ** 2
    root = np.sqrt(np.where(disc > 0, disc, 0.0))
    near = np.where(np.abs(centre_y - root - straight) < np.abs(centre_y + root - straight),
                    centre_y - root, centre_y + root)
    return np.where(curved & (disc > 0), near, straight)


#: least spread of ``sin^2`` of the angle off the plane for a fading fit (0.18 degree at the plane): below it, near
#: nadir where the source sees every nearest point in the plane, the fit has nothing to measure
MIN_SPREAD = 1e-5


def fading_floor_db(beam_width_deg: float) -> float:
    """The least fall (dB per unit ``sin^2 a*``) taken as a transmit beam's: a third of a Gaussian main
    lobe's of that -3 dB width (``12 / width^2``, width in rad; the SBP29's 4.5 degrees: 1,950, of which
    Line 4's smooth pipes show 1,250-2,000).  Lines fading more slowly lose their level for other reasons."""
    if not beam_width_deg > 0:
        return math.inf  # no beam width: no fading test
    return 12.0 / math.radians(beam_width_deg) ** 2 / 3.0


def fading_fit(level_db, range_m, sin_a) -> dict:
    """Fit of echo levels to a specular echo's fall out of the transmit beam.

    ``level_db + 30 log10(range)`` (the spreading of a long pipe's echo
    removed) fitted as ``L0 - beta sin^2 a`` by least squares, the
    residual scatter estimated from the fit.

    Parameters
    ----------
    level_db : array_like
        ``(n,)`` the echoes' intensities (dB).
    range_m : array_like
        ``(n,)`` their slant ranges (m).
    sin_a : array_like
        ``(n,)`` the sine of the angle off the ping's plane at which the
        source sees the nearest point: ``(h / range) sin a*``, ``sin a*``
        the slope of the echoes' path ``dh/ds``.

    Returns
    -------
    dict
        ``beta_db`` (dB per unit ``sin^2 a``; about 2,600 for the SBP29's
        3.5 m transmitter at its centre frequency), ``beta_error_db`` (its
        standard error; NaN with fewer than four echoes or a spread of
        ``sin^2 a`` under :data:`MIN_SPREAD`) and ``span_db`` (the fall the fit predicts across the
        line's headings).
    """
    level = np.asarray(level_db, dtype=np.float64) + 30.0 * np.log10(np.maximum(np.asarray(range_m, float), 1e-3))
    x = np.asarray(sin_a, dtype=np.float64) ** 2
    ok = np.isfinite(level) & np.isfinite(x)
    out = {"beta_db": np.nan, "beta_error_db": np.nan, "span_db": np.nan}
    if ok.sum() < 4 or np.ptp(x[ok]) < MIN_SPREAD:
        return out
    a = np.stack([np.ones(ok.sum()), -x[ok]], axis=1)
    coef, *_ = np.linalg.lstsq(a, level[ok], rcond=None)
    resid = level[ok] - a @ coef
    var = float(resid @ resid) / max(ok.sum() - 2, 1)
    cov = var * np.linalg.pinv(a.T @ a)
    out.update(beta_db=float(coef[1]), beta_error_db=float(np.sqrt(max(cov[1, 1], 0.0))),
               span_db=float(coef[1] * np.ptp(x[ok])))
    return out
