"""Direct downgoing eigenrays from sources to many targets at once.

:func:`eigenrays` splits the targets into blocks (threads), solves the ones
below their source with the iteration of :mod:`clbeam.imaging.raytrace.newton`
and the ones level with it directly (:mod:`clbeam.imaging.raytrace` gives the
derivation).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from clbeam.errors import GeometryError, OptionError, require
from clbeam.imaging.raytrace.layers import Block
from clbeam.imaging.raytrace.newton import fill_rays, newton_solve
from clbeam.model.svp import SoundSpeedProfile

#: targets per block of the vectorised solver (keeps the work arrays in cache)
BLOCK = 32768
#: a target less than this times its horizontal offset below the source is
#: level with it (a horizontal ray; beyond what the float speed can resolve)
LEVEL_REL = 1e-12


@dataclass(frozen=True, eq=False)
class Eigenrays:
    """Direct downgoing eigenrays from a source to targets, one per target.

    Every array has the broadcast shape of the targets; unreachable targets
    hold NaN (``reachable`` False).  Angles are from nadir, the sines signed
    as the target's ``y`` offset (positive to starboard).

    Attributes
    ----------
    time_s : numpy.ndarray
        One-way travel time (s).
    launch_sin, launch_cos : numpy.ndarray
        Ray direction at the source.
    arrival_sin, arrival_cos : numpy.ndarray
        Ray direction at the target (the ray travels down: ``arrival_cos > 0``).
    path_length_m : numpy.ndarray
        Length of the ray (m).
    ray_parameter_s_m : numpy.ndarray
        ``p = sin(theta) / c`` (s/m), signed like ``y``.
    wavefront_radius_m : numpy.ndarray
        In-plane radius of curvature (m) of the wavefront from the target as
        it reaches the source, ``cos^2(theta_0) dX/dp / c_0``: the radius
        ``rho`` for which ``|rho u - o| - rho`` matches the travel time to
        second order in a horizontal source offset ``o`` (``= L`` when the
        speed is constant).
    reachable : numpy.ndarray
        bool: a direct downgoing ray reaches the target.
    """

    time_s: np.ndarray
    launch_sin: np.ndarray
    launch_cos: np.ndarray
    arrival_sin: np.ndarray
    arrival_cos: np.ndarray
    path_length_m: np.ndarray
    ray_parameter_s_m: np.ndarray
    wavefront_radius_m: np.ndarray
    reachable: np.ndarray


_FIELDS = ("time_s", "launch_sin", "launch_cos", "arrival_sin", "arrival_cos", "path_length_m",
           "ray_parameter_s_m", "wavefront_radius_m")
#: fields whose sign is that of the target's ``y`` (solved for ``|y|``)
_SIGNED = ("launch_sin", "arrival_sin", "ray_parameter_s_m")


def eigenrays(profile: SoundSpeedProfile, source_depth_m, target_y_m, target_z_m, *,
              workers: int | None = None) -> Eigenrays:
    """Direct downgoing eigenrays from sources at ``y = 0`` to many targets at once.

    Parameters
    ----------
    profile : SoundSpeedProfile
        The stratified medium.
    source_depth_m : float or array_like
        Source depth(s) (m, on the profile's depth axis), broadcast with the targets.
    target_y_m : array_like
        Horizontal offset of each target from its source (m, signed).
    target_z_m : array_like
        Target depth (m).  A target is reachable below its source
        (``z > z0``) by a ray without a turning point; a target on the
        source gets ``T = 0``; one level with the source (``z - z0`` at most
        ``LEVEL_REL |y|``) only by a horizontal ray, where the speed just
        below the source is constant; one above the source never (swap the
        ends: the times are reciprocal).
    workers : int or None
        Threads for the blocks (``None``: every CPU).

    Returns
    -------
    Eigenrays
        Arrays of the broadcast shape of the three inputs (s, m, s/m,
        unitless); NaN where unreachable.

    Raises
    ------
    GeometryError
        When a source or target coordinate is not finite.
    """
    return Eigenrays(**eigen_fields(profile, source_depth_m, target_y_m, target_z_m, _FIELDS, workers))


def eigen_fields(profile, source_depth_m, target_y_m, target_z_m, fields, workers) -> dict:
    """The ``fields`` of :class:`Eigenrays` (and ``reachable``), each of the
    broadcast shape of the inputs."""
    check_profile(profile)
    z0, y, z = (np.asarray(v, dtype=np.float64) for v in (source_depth_m, target_y_m, target_z_m))
    for name, v in (("source depth", z0), ("target y", y), ("target z", z)):
        require(bool(np.all(np.isfinite(v))), GeometryError, f"{name} must be finite (m)")
    shape = np.broadcast(z0, y, z).shape
    z0b, yb, zb = (np.broadcast_to(v, shape).ravel() for v in (z0, y, z))
    out = {k: np.empty(yb.size) for k in fields}
    out["reachable"] = np.empty(yb.size, dtype=bool)
    scalar_source = z0.ndim == 0

    def run(lo: int, hi: int) -> None:
        za = float(z0) if scalar_source else z0b[lo:hi]
        solve_block(profile, za, yb[lo:hi], zb[lo:hi], {k: v[lo:hi] for k, v in out.items()})

    map_blocks(run, yb.size, workers)
    return {k: v.reshape(shape) for k, v in out.items()}


def check_profile(profile) -> None:
    require(isinstance(profile, SoundSpeedProfile), OptionError,
            f"a SoundSpeedProfile is needed, got {type(profile).__name__}")


def map_blocks(fn, n: int, workers: int | None, step: int = BLOCK) -> None:
    """``fn(lo, hi)`` over ``range(n)`` in spans of ``step``, on ``workers`` threads."""
    spans = [(s, min(s + step, n)) for s in range(0, n, step)] or [(0, 0)]
    nw = (os.cpu_count() or 1) if workers is None else max(1, int(workers))
    if nw == 1 or len(spans) == 1:
        for s, e in spans:
            fn(s, e)
        return
    with ThreadPoolExecutor(max_workers=nw) as pool:
        for f in [pool.submit(fn, s, e) for s, e in spans]:
            f.result()


def solve_block(profile: SoundSpeedProfile, za, y: np.ndarray, zb: np.ndarray, out: dict) -> None:
    """Eigenrays of one block (``za`` a float or an array like ``y``) into
    ``out``: flat arrays named as the fields of :class:`Eigenrays` (any
    subset) and ``reachable``."""
    fields = [k for k in out if k != "reachable"]
    za_arr = np.broadcast_to(za, y.shape)
    dz = zb - za_arr
    reach = out["reachable"]
    reach[:] = False
    level = dz <= LEVEL_REL * np.abs(y)          # at the source's depth (to rounding)
    below = ~level & (dz > 0)
    todo = np.flatnonzero(below) if not below.all() else np.arange(y.size)
    if todo.size:
        sel = (lambda v: v) if todo.size == y.size else (lambda v: v[todo])
        block = Block(profile.layers, za if np.ndim(za) == 0 else sel(za_arr), np.abs(sel(y)), sel(zb))
        a = block.arr
        t, ok, pending = newton_solve(block, a["dz"] / (np.hypot(a["dz"], a["y"]) + a["y"]))   # straight line
        idx = np.flatnonzero(ok)
        sub, bad = fill_rays(block, t, idx, pending, fields)
        if bad.size:
            # a last step taken unchecked fell short: iterate those to the end
            t2, ok2, _ = newton_solve(block, t, subset=bad, loose=False)
            t[bad] = t2[bad]
            good, failed = bad[ok2[bad]], bad[~ok2[bad]]
            redo, _ = fill_rays(block, t, good, np.zeros(block.n, dtype=bool), fields)
            pos = np.searchsorted(idx, good)
            for k in fields:
                sub[k][pos] = redo[k]
            if failed.size:
                keep = ~np.isin(idx, failed)
                idx = idx[keep]
                sub = {k: v[keep] for k, v in sub.items()}
        where = todo[block.original(idx)]
        for k in fields:
            v = out[k]
            if idx.size != y.size:
                v[:] = np.nan
            v[where] = sub[k] * np.sign(y[where]) if k in _SIGNED else sub[k]
        reach[where] = True
    else:
        for k in fields:
            out[k][:] = np.nan
    if np.any(level & (dz >= 0)):
        _fill_level(profile, za_arr, y, dz, level & (dz >= 0), out, fields)


def _fill_level(profile, za_arr, y, dz, level, out, fields) -> None:
    """Targets level with their source: on it (``T = 0``), or reached by a
    horizontal ray where the speed just below the source is constant."""
    idx = np.flatnonzero(level)
    za = za_arr[idx]
    bots = np.array([lay.bot for lay in profile.layers])
    flat = np.array([lay.g == 0.0 for lay in profile.layers])[np.searchsorted(bots, za, side="right")]
    yy, dd = y[idx], dz[idx]
    ok = flat | (yy == 0)
    idx, yy, dd, za = idx[ok], yy[ok], dd[ok], za[ok]
    rho = np.hypot(yy, dd)
    c0 = profile.speed(za, side="below")
    with np.errstate(invalid="ignore", divide="ignore"):
        su = np.where(rho > 0, yy / rho, 0.0)
        cu = np.where(rho > 0, dd / rho, 1.0)
    vals = {"time_s": rho / c0, "launch_sin": su, "launch_cos": cu, "arrival_sin": su, "arrival_cos": cu,
            "path_length_m": rho, "ray_parameter_s_m": su / c0, "wavefront_radius_m": rho}
    for k in fields:
        out[k][idx] = vals[k]
    out["reachable"][idx] = True

