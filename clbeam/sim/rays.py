"""Rays through a horizontally stratified ocean, for scenes with a ``[water]`` profile.

Where the isospeed simulator uses straight distances, a scene with a
sound-speed profile needs ray-traced legs: :func:`ray_legs` solves the
direct eigenrays between array positions and scatterers
(:func:`clbeam.imaging.raytrace.eigenrays`), :func:`seabed_ray_legs` the
rays that cross a locally flat seabed into the sediment, :func:`unfold`
turns a path reflected at horizontal planes (seabed, surface, sub-bottom)
into one downgoing ray, and :func:`ray_point` follows a ray for a given
time (where a ray-tracing imager puts an echo).  Functions of a profile and
positions only; :class:`clbeam.sim.propagation.Propagation` applies them to
a scene.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np
import scipy.optimize

from clbeam.imaging.raytrace import eigenrays
from clbeam.model.svp import SoundSpeedProfile

log = logging.getLogger(__name__)

RAY_PAIRS = 1 << 18
"""End-scatterer pairs per call of the eigenray solver (memory bound)."""
SEABED_RAY_TOL_REL = 1e-9
"""Seabed crossing of a ray to a point below a sloped seabed: converged when
the horizontal miss is below this times the distance (1 µm at 1 km)."""


def ray_legs(profile: SoundSpeedProfile, ends: np.ndarray, pos: np.ndarray, *, directions: bool = True) -> dict:
    """Direct eigenrays between array positions and scatterers in a stratified medium.

    Each pair's ray lies in their vertical plane and is solved from the
    shallower end (:func:`clbeam.imaging.raytrace.eigenrays`).

    Parameters
    ----------
    profile : SoundSpeedProfile
        The medium, on the earth-frame ``z`` axis.
    ends : array_like
        ``(P, 3)`` positions of the source or the elements, earth frame (m).
    pos : array_like
        ``(S, 3)`` scatterer positions, earth frame (m).
    directions : bool
        Also return the ray parameter and the directions.

    Returns
    -------
    dict
        ``time_s`` ``(P, S)`` one-way times (s), NaN where no direct ray joins
        the pair; with ``directions`` also ``p`` ``(P, S)`` the magnitude of the
        ray parameter (s/m), ``end_dir`` and ``pos_dir`` ``(P, S, 3)`` the
        unit propagation directions at the end (leaving it) and at the
        position (arriving there from the end).
    """
    ends = np.asarray(ends, dtype=np.float64)
    pos = np.asarray(pos, dtype=np.float64)
    n_e, n_s = len(ends), len(pos)
    out = {"time_s": np.full((n_e, n_s), np.nan)}
    if directions:
        out.update(p=np.full((n_e, n_s), np.nan), end_dir=np.full((n_e, n_s, 3), np.nan),
                   pos_dir=np.full((n_e, n_s, 3), np.nan))
    step = max(1, RAY_PAIRS // max(n_e, 1))
    for a in range(0, n_s, step):
        sl = slice(a, min(a + step, n_s))
        d = pos[None, sl, :] - ends[:, None, :]
        rho = np.hypot(d[..., 0], d[..., 1])
        z_end = np.broadcast_to(ends[:, None, 2], rho.shape)
        z_pos = np.broadcast_to(pos[None, sl, 2], rho.shape)
        down = z_pos >= z_end
        r = eigenrays(profile, np.where(down, z_end, z_pos), rho, np.where(down, z_pos, z_end))
        out["time_s"][:, sl] = r.time_s
        if not directions:
            continue
        out["p"][:, sl] = np.abs(r.ray_parameter_s_m)
        h = d[..., :2] / np.maximum(rho, 1e-300)[..., None]
        # a ray solved from the position down to the end runs backwards
        for key, s_, c_ in (("end_dir", np.where(down, r.launch_sin, r.arrival_sin),
                             np.where(down, r.launch_cos, -r.arrival_cos)),
                            ("pos_dir", np.where(down, r.arrival_sin, r.launch_sin),
                             np.where(down, r.arrival_cos, -r.launch_cos))):
            out[key][:, sl, :2] = h * np.abs(s_)[..., None]
            out[key][:, sl, 2] = c_
    return out


def seabed_ray_legs(water: SoundSpeedProfile, ends: np.ndarray, pos: np.ndarray, seabed_z: np.ndarray,
                    sediment_speed_m_s: np.ndarray, *, directions: bool = True) -> dict:
    """Like :func:`ray_legs` for positions below a locally flat seabed.

    Position ``j`` lies below a horizontal interface at ``seabed_z[j]`` with
    the constant sediment speed ``sediment_speed_m_s[j]`` below it and the
    ``water`` profile above; the ends lie above it.  The ray is the water
    eigenray from the end to the seabed crossing plus a straight sediment
    segment at Snell's angle (:func:`_seabed_crossing`).  For one seabed
    depth this is the eigenray of
    :meth:`~clbeam.model.svp.SoundSpeedProfile.with_sediment`; per position
    it handles a sloped seabed taken as locally flat.

    Parameters
    ----------
    water : SoundSpeedProfile
        The water column (earth-frame ``z``).
    ends : array_like
        ``(P, 3)`` positions above the seabed, earth frame (m).
    pos : array_like
        ``(S, 3)`` positions below it, earth frame (m).
    seabed_z : array_like
        ``(S,)`` seabed depth above each position (m).
    sediment_speed_m_s : array_like
        ``(S,)`` sediment sound speed below it (m/s).
    directions : bool
        Also return the ray parameter and the directions.

    Returns
    -------
    dict
        As :func:`ray_legs`.
    """
    ends = np.asarray(ends, dtype=np.float64)
    pos = np.asarray(pos, dtype=np.float64)
    d = pos[None, :, :] - ends[:, None, :]
    rho = np.hypot(d[..., 0], d[..., 1])
    z0 = np.broadcast_to(ends[:, None, 2], rho.shape)
    zs = np.broadcast_to(np.asarray(seabed_z, dtype=np.float64)[None, :], rho.shape)
    b = np.maximum(np.broadcast_to(pos[None, :, 2], rho.shape) - zs, 0.0)
    cs = np.broadcast_to(np.asarray(sediment_speed_m_s, dtype=np.float64)[None, :], rho.shape)
    r, yw, sin_s, cos_s = _seabed_crossing(water, rho, z0, zs, b, cs)
    time = r.time_s + np.hypot(b, rho - yw) / cs
    out = {"time_s": time}
    if directions:
        h = d[..., :2] / np.maximum(rho, 1e-300)[..., None]
        end_dir = np.empty(rho.shape + (3,))
        pos_dir = np.empty(rho.shape + (3,))
        end_dir[..., :2] = h * np.abs(r.launch_sin)[..., None]
        end_dir[..., 2] = r.launch_cos
        pos_dir[..., :2] = h * sin_s[..., None]
        pos_dir[..., 2] = np.where(np.isfinite(time), cos_s, np.nan)
        out.update(p=np.abs(r.ray_parameter_s_m), end_dir=end_dir, pos_dir=pos_dir)
    return out


def _seabed_crossing(water: SoundSpeedProfile, rho, z0, zs, b, cs):
    """Where rays from depths ``z0`` cross the seabed at ``zs`` to reach
    points ``b`` below it, ``rho`` away (all m; sediment speed ``cs``, m/s).

    Newton's method on the horizontal distance ``y_w`` of the crossing makes
    the water eigenray to it and the straight sediment segment at Snell's
    angle (``sin θ_s = p c_s``) meet (``y_w + b tan θ_s = ρ``); the time
    through the crossing is the Fermat time, stationary in ``y_w``.  Returns
    the water eigenrays (NaN times where Newton did not converge), ``y_w``
    (m), ``sin θ_s`` and ``cos θ_s``.
    """
    c_end = water.speed(z0)
    tol = SEABED_RAY_TOL_REL * np.hypot(rho, zs + b - z0)
    yw = rho * (zs - z0) / np.maximum(zs + b - z0, 1e-300)       # the straight line's crossing
    for _ in range(40):
        r = eigenrays(water, z0, yw, zs)
        p = np.abs(r.ray_parameter_s_m)
        sin_s = p * cs
        cos_s = np.sqrt(np.maximum(1.0 - sin_s * sin_s, 1e-300))
        miss = yw + b * sin_s / cos_s - rho
        if not np.any(np.abs(miss) > tol):          # NaN (no water ray) counts as done
            break
        # d(miss)/d(yw) = 1 + b c_s / cos^3 · dp/dX, dX/dp = rho_wf c_end / cos_end^2
        dxdp = r.wavefront_radius_m * c_end / np.maximum(r.launch_cos ** 2, 1e-300)
        slope = 1.0 + b * cs / cos_s ** 3 / np.maximum(dxdp, 1e-300)
        yw = np.where(np.isfinite(miss), np.clip(yw - miss / slope, 0.0, rho), yw)
    else:
        bad = np.abs(miss) > tol
        log.warning("%d rays to points below the seabed did not converge; they are dropped", int(bad.sum()))
        r = dataclasses.replace(r, time_s=np.where(bad, np.nan, r.time_s))
    return r, yw, sin_s, cos_s


def _ray_offset_time(profile: SoundSpeedProfile, p: float, z0: float, z1: float) -> tuple[float, float]:
    """Horizontal offset (m) and time (s) of a downgoing ray of ray parameter
    ``p >= 0`` from depth ``z0`` to ``z1 >= z0``; NaN where it turns before.

    Per piece of constant gradient ``g`` from ``a`` to ``b`` (``h = b - a``):
    ``X = p h (c_a + c_b) / (cos_a + cos_b)`` and
    ``T = ln(c_b (1 + cos_a) / (c_a (1 + cos_b))) / g`` (``h / (c cos)`` when
    ``g h`` is negligible).
    """
    cuts = [z0] + [float(z) for z in np.unique(profile.depths_m) if z0 < z < z1] + [z1]
    x = t = 0.0
    for a, b in zip(cuts, cuts[1:]):
        h = b - a
        if h <= 0:
            continue
        ca, cb = float(profile.speed(a, side="below")), float(profile.speed(b, side="above"))
        sa, sb = p * ca, p * cb
        if sa >= 1.0 or sb >= 1.0:
            return math.nan, math.nan
        cos_a, cos_b = math.sqrt(1.0 - sa * sa), math.sqrt(1.0 - sb * sb)
        x += p * h * (ca + cb) / (cos_a + cos_b)
        g = (cb - ca) / h
        if abs(g * h) <= 1e-9 * ca:
            t += 2.0 * h / (ca * cos_a + cb * cos_b)
        else:
            t += math.log(cb * (1.0 + cos_a) / (ca * (1.0 + cos_b))) / g
    return x, t


def _turning_depth(profile: SoundSpeedProfile, p: float, z0: float) -> float:
    """Depth (m) below ``z0`` where a ray of ray parameter ``p`` turns
    (``p c = 1``), ``inf`` if it never does."""
    if p <= 0:
        return math.inf
    cuts = [z0] + [float(z) for z in np.unique(profile.depths_m) if z > z0]
    for a, b in zip(cuts, cuts[1:] + [math.inf]):
        ca = float(profile.speed(a, side="below"))
        if p * ca >= 1.0:
            return a
        if math.isfinite(b):
            cb = float(profile.speed(b, side="above"))
            if p * cb >= 1.0:
                return a + (1.0 / p - ca) * (b - a) / (cb - ca)
    return math.inf


def ray_point(profile: SoundSpeedProfile, z0: float, sin0: float, time_s: float) -> tuple[float, float]:
    """Where a downgoing ray is after a given travel time.

    Parameters
    ----------
    profile : SoundSpeedProfile
        The medium.
    z0 : float
        Depth the ray leaves (m).
    sin0 : float
        Sine of its launch angle from nadir, signed (positive: towards ``+y``).
    time_s : float
        Travel time (s).

    Returns
    -------
    (float, float)
        Horizontal offset from the launch point (m, the sign of ``sin0``) and
        depth (m); NaN if the ray turns first.
    """
    p = abs(sin0) / float(profile.speed(z0))
    z_hi = z0 + float(np.max(profile.speeds_m_s)) * time_s * 1.000001
    z_turn = _turning_depth(profile, p, z0)
    if z_turn < z_hi:
        z_hi = z0 + (z_turn - z0) * (1.0 - 1e-12)

    def late(z):
        return _ray_offset_time(profile, p, z0, z)[1] - time_s

    if not late(z_hi) >= 0:
        return math.nan, math.nan
    z = scipy.optimize.brentq(late, z0, z_hi, xtol=1e-10, rtol=1e-14, maxiter=200)
    return math.copysign(_ray_offset_time(profile, p, z0, z)[0], sin0), z


def unfold(medium: SoundSpeedProfile, turns: list[float]) -> tuple[SoundSpeedProfile, float, float]:
    """A ray reflected at horizontal planes, unfolded into a downgoing one.

    Parameters
    ----------
    medium : SoundSpeedProfile
        The medium the ray crosses.
    turns : list of float
        Depths of the reflections in turn (m): the ray leaves downward,
        reflects at ``turns[0]`` (a bottom, from above), then ``turns[1]`` (a
        top, from below), and so on alternately.

    Returns
    -------
    (SoundSpeedProfile, float, float)
        The profile along the unfolded depth ``s`` (``s = z`` before the
        first turn), the unfolded depth ``S`` of the last turn and its depth
        ``R`` (m): after an odd number of turns a point at depth ``z`` on the
        last (upgoing) leg is at ``s = S + (R - z)``.
    """
    d, c = medium.depths_m, medium.speeds_m_s
    pts: list[tuple[float, float]] = [(float(z), float(v)) for z, v in zip(d, c) if z < turns[0]]
    pts.append((turns[0], float(medium.speed(turns[0], side="above"))))
    s_turn, z_turn = turns[0], turns[0]
    legs = list(turns[1:]) + [None]
    for i, nxt in enumerate(legs):
        up = i % 2 == 0                         # after a bottom the ray goes up
        if up:
            inside = [(z, v) for z, v in zip(d[::-1], c[::-1]) if z < z_turn and (nxt is None or z > nxt)]
            pts.extend((s_turn + (z_turn - z), float(v)) for z, v in inside)
        else:
            inside = [(z, v) for z, v in zip(d, c) if z > z_turn and (nxt is None or z < nxt)]
            pts.extend((s_turn + (z - z_turn), float(v)) for z, v in inside)
        if nxt is None:
            break
        s_next = s_turn + abs(z_turn - nxt)
        pts.append((s_next, float(medium.speed(nxt, side="below" if up else "above"))))
        s_turn, z_turn = s_next, nxt
    uniq = [pts[0]]
    for q in pts[1:]:
        if q != uniq[-1]:
            uniq.append(q)
    s_arr, c_arr = (np.array(v) for v in zip(*uniq))
    return SoundSpeedProfile(s_arr, c_arr), float(s_turn), float(z_turn)
