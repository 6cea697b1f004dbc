"""Travel times through a horizontally stratified ocean by ray tracing.

The sound speed depends on depth only (:class:`SoundSpeedProfile`: piecewise
linear between points, constant beyond the ends, with optional jumps at
horizontal interfaces such as the seabed).  A ray keeps its ray parameter
``p = sin(theta) / c`` (Snell's law, ``theta`` from nadir) through every
layer and across every jump; in a layer of constant gradient ``g`` it is an
arc of a circle of radius ``1 / (p |g|)``, in a layer of constant speed a
straight line.  Per layer, from depth ``a`` (speed ``c_a``, ``cos_a``) down
to ``b`` (``h = b - a``), the closed forms are written so that they hold for
``g = 0`` too and lose no digits for small ``p``, ``g`` or ``h``::

    X = p h (c_a + c_b) / (cos_a + cos_b)                  horizontal offset
    K = (c_a + c_b) / (c_b cos_a + c_a cos_b)
    L = h K asin(p g h K) / (p g h K)                      arc length
    T = log1p(g h (1 + K) / (c_a (1 + cos_b))) / g         travel time
      = h / (c cos)                                        (g = 0)

(``sin(theta_b - theta_a) = p g h K``; the usual ``(cos_a - cos_b) / (p g)``,
``(theta_b - theta_a) / (p g)`` and ``ln(tan(theta_b/2) / tan(theta_a/2)) / g``
after removing the cancellation.)

Eigenrays (:func:`eigenrays`): for every target at once, a safeguarded
Newton iteration solves ``X(p, z) = |y|``.  The unknown is
``t = tan(chi / 2)``, ``chi`` the elevation above the horizontal of a ray
launched with ``p = cos(chi) / c_max`` (``c_max`` the fastest speed between
source and target, so ``chi`` spans ``[0, pi/2]`` for every direct
downgoing ray; rational in ``t``, exact near the horizontal).  ``X``
increases with ``p``; targets beyond ``X(1 / c_max, z)`` can only be reached
past a turning point and are *unreachable* (NaN), never given a wrong
number; so are targets above their source, and targets level with it
unless the speed just below the source is constant (a horizontal ray).
The time is returned in the stationary (Legendre) form
``T(p) + p (|y| - X(p))``, whose error is second order in the residual.

:func:`travel_time_tables` evaluates this on a :class:`~clbeam.model.grid.PolarGrid`
(the paper's 8.8 M-cell grid in a few seconds), :func:`offset_time_approx`
is the per-element approximation a delay-and-sum kernel can use with those
tables, :func:`offset_time_exact` its exact counterpart,
:func:`element_travel_times` the exact element-to-scatterer times a
simulator needs and :func:`positioning_error` where an isospeed image puts a
target.  ``docs/raytrace.md`` gives the derivations and the measured errors.
"""

from __future__ import annotations

import logging
import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from clbeam.errors import GeometryError, OptionError, require
from clbeam.model.grid import PolarGrid
from clbeam.model.svp import Layer, SoundSpeedProfile

log = logging.getLogger(__name__)

#: eigenray convergence: |X(p) - |y|| at most this times the distance to the
#: target (1e-6 m at 1 km): the first-order time error p |X - y| is then below
#: 1e-9 s at 1.3 km, the returned (stationary) time's error far below, and the
#: launch direction is good to ~1e-9
X_TOL_REL = 1e-9
#: relative residual below which one more Newton step is taken without
#: checking it in the loop (the final evaluation checks it)
LOOSE_TOL_REL = 3e-7
#: Newton (or bisection) iterations before a target is given up as NaN
MAX_ITERATIONS = 80
#: targets per block of the vectorised solver (keeps the work arrays in cache)
BLOCK = 32768
#: a target less than this times its horizontal offset below the source is
#: level with it (a horizontal ray; beyond what the float speed can resolve)
LEVEL_REL = 1e-12
#: floor of cos^2 of the ray angle: keeps 0/0 out of layers a ray does not enter
_COS2_FLOOR = 1e-300


# ---------------------------------------------------------------------------
# Layer sums (the closed forms), on targets grouped by the layers they cross
# ---------------------------------------------------------------------------
def _cos(c, s, cmax, om):
    """``cos(theta) = sqrt(1 - s^2)`` of the ray where the speed is ``c``
    (``s = p c``), from ``1 - s = ((c_max - c) + c (1 - sin(phi))) / c_max``,
    ``om = 1 - sin(phi)``: no cancellation where the ray is near horizontal."""
    one_minus = ((cmax - c) + c * om) / cmax
    return np.sqrt(np.maximum(one_minus * (1.0 + s), _COS2_FLOOR))


def _asinc(v: np.ndarray) -> np.ndarray:
    """``asin(v) / v`` (1 at 0), for ``|v| <= 1``."""
    v = np.minimum(np.abs(v), 1.0)
    v2 = v * v
    with np.errstate(divide="ignore", invalid="ignore"):
        big = np.arcsin(v) / v
    return np.where(v < 1e-4, 1.0 + v2 * (1.0 / 6.0 + v2 * (3.0 / 40.0)), big)


class _Segment(NamedTuple):
    """Part of a layer a group of rays crosses: thickness and end speeds are a
    float (the same for the group) or the name of a per-target array."""

    h: float | str
    ca: float | str
    cb: float | str
    g: float


def _segments(layers, i: int, k: int) -> tuple[_Segment, ...]:
    """Segments of rays starting in layer ``i`` and ending in layer ``k``."""
    def speed_at(lay: Layer, z: float) -> float:
        return lay.c_ref + lay.g * (z - lay.z_ref)

    li, lk = layers[i], layers[k]
    c_start = "c_za" if li.g != 0.0 else li.c_ref
    c_end = "c_zb" if lk.g != 0.0 else lk.c_ref
    if i == k:
        return (_Segment("dz", c_start, c_end, li.g),)
    segs = [_Segment("h0", c_start, speed_at(li, li.bot), li.g)]
    for lay in layers[i + 1:k]:
        segs.append(_Segment(lay.bot - lay.top, speed_at(lay, lay.top), speed_at(lay, lay.bot), lay.g))
    segs.append(_Segment("h1", speed_at(lk, lk.top), c_end, lk.g))
    return tuple(segs)


class _View:
    """Some targets of a :class:`_Block` (all, or a sorted subset), contiguous by group."""

    def __init__(self, block: "_Block", idx: np.ndarray | None):
        self.idx = idx
        self.arr = block.arr if idx is None else {
            k: (v if np.ndim(v) == 0 else v[idx]) for k, v in block.arr.items()}
        key = block.key if idx is None else block.key[idx]
        self.n = key.size
        lo = np.searchsorted(key, block.group_keys, side="left")
        hi = np.searchsorted(key, block.group_keys, side="right")
        self.groups = [(int(a), int(b), segs) for a, b, segs in zip(lo, hi, block.group_segments) if b > a]

    def take(self, values: np.ndarray) -> np.ndarray:
        """``values`` (one per target of the block) for the targets of the view."""
        return values if self.idx is None else values[self.idx]

    def value(self, spec, s: int, e: int):
        """A segment quantity for the targets ``s:e`` of the view."""
        if isinstance(spec, str):
            v = self.arr[spec]
            return v if np.ndim(v) == 0 else v[s:e]
        return spec


def _group_order(key: np.ndarray) -> np.ndarray | None:
    """Permutation sorting the small non-negative ints ``key`` (stable), or
    ``None`` when they are sorted already (a counting sort: a few groups)."""
    if key.size < 2 or bool(np.all(key[1:] >= key[:-1])):
        return None
    present = np.flatnonzero(np.bincount(key))
    return np.concatenate([np.flatnonzero(key == g) for g in present])


class _Block:
    """Targets below their sources, sorted by the layers their rays start and end in.

    Rays of one group (same start layer ``i``, end layer ``k``) cross the same
    segments: layer ``i`` from ``za`` to its bottom (``h0``), layers
    ``i+1 .. k-1`` whole, layer ``k`` from its top to ``zb`` (``h1``); one
    segment ``za .. zb`` (``dz``) when ``i == k``.
    """

    def __init__(self, layers, za, y: np.ndarray, zb: np.ndarray):
        self.layers = layers
        n_l = len(layers)
        bots = np.array([lay.bot for lay in layers])
        tops = np.array([lay.top for lay in layers])
        zref = np.array([lay.z_ref for lay in layers])
        cref = np.array([lay.c_ref for lay in layers])
        grad = np.array([lay.g for lay in layers])
        scalar = np.ndim(za) == 0
        ks = np.searchsorted(bots, zb, side="left")          # top < zb <= bot
        if scalar:
            i0 = int(np.searchsorted(bots, za, side="right"))  # top <= za < bot
            key = ks.astype(np.int64)
        else:
            is_ = np.searchsorted(bots, za, side="right")
            key = is_.astype(np.int64) * n_l + ks
        self.order = order = _group_order(key)
        take = (lambda v: v) if order is None else (lambda v: v[order])
        self.key = take(key)
        ks = take(ks)
        zb_s = take(zb)
        za_s = float(za) if scalar else take(za)
        if scalar:
            h0 = float(bots[i0] - za_s)
            c_za = float(cref[i0] + grad[i0] * (za_s - zref[i0]))
        else:
            is_ = take(is_)
            h0 = bots[is_] - za_s
            c_za = cref[is_] + grad[is_] * (za_s - zref[is_])
        self.arr = {"y": take(y), "zb": zb_s, "dz": zb_s - za_s, "h0": h0, "h1": zb_s - tops[ks],
                    "c_za": c_za, "c_zb": cref[ks] + grad[ks] * (zb_s - zref[ks])}
        self.za = za_s
        self.n = y.size
        self.group_keys = self.key[np.r_[0, np.flatnonzero(np.diff(self.key)) + 1]] if self.key.size else self.key
        self.group_segments = [
            _segments(layers, i0 if scalar else int(gk) // n_l, int(gk) if scalar else int(gk) % n_l)
            for gk in self.group_keys]
        self.view_all = _View(self, None)
        self.cmax = self._max_speed()

    def original(self, idx: np.ndarray) -> np.ndarray:
        """Caller's positions of the block's targets ``idx``."""
        return idx if self.order is None else self.order[idx]

    def _max_speed(self) -> np.ndarray:
        """Fastest speed (m/s) along each target's path: a ray with
        ``p = 1 / c_max`` is horizontal there."""
        v = self.view_all
        cmax = np.empty(self.n)
        for s, e, segs in v.groups:
            m = 0.0
            for seg in segs:
                m = np.maximum(m, np.maximum(v.value(seg.ca, s, e), v.value(seg.cb, s, e)))
            cmax[s:e] = m
        return cmax

    def x_max(self) -> np.ndarray:
        """Horizontal reach (m) of the ray turning where ``c = c_max``: ``inf``
        when that happens in a layer of constant speed."""
        v = self.view_all
        out = np.empty(self.n)
        for s, e, segs in v.groups:
            cm = self.cmax[s:e]
            if any(seg.g == 0.0 and np.all(cm == seg.ca) for seg in segs):
                out[s:e] = np.inf
                continue
            with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
                x, _ = _group_sums(v, s, e, segs, 1.0 / cm, cm, np.zeros(e - s), final=False)
            out[s:e] = x
        return out

    def sums(self, view: _View, p: np.ndarray, om: np.ndarray, *, final: bool = False):
        """``X`` (m), ``dX/dp`` (m^2/s) and with ``final`` ``T`` (s), ``L`` (m)
        of rays ``p`` (``om = 1 - p c_max``) for the targets of ``view``."""
        cmax = view.take(self.cmax)
        outs = [np.empty(view.n) for _ in range(4 if final else 2)]
        for s, e, segs in view.groups:
            for o, r in zip(outs, _group_sums(view, s, e, segs, p[s:e], cmax[s:e], om[s:e], final=final)):
                o[s:e] = r
        return outs


def _group_sums(view: _View, s: int, e: int, segs, p, cmax, om, *, final: bool):
    """Closed-form sums over the segments of one group of targets."""
    x = 0.0
    xp = 0.0
    t = 0.0
    length = 0.0
    cos_cache: dict[float, np.ndarray] = {}

    def cos_at(c):
        if isinstance(c, float):
            if c not in cos_cache:
                cos_cache[c] = _cos(c, p * c, cmax, om)
            return cos_cache[c]
        return _cos(c, p * c, cmax, om)

    for seg in segs:
        h = view.value(seg.h, s, e)
        ca = view.value(seg.ca, s, e)
        cb = view.value(seg.cb, s, e)
        cos_a, cos_b = cos_at(ca), cos_at(cb)
        scos = cos_a + cos_b
        w = h * (ca + cb) / scos
        x = x + p * w
        p2 = p * p
        xp = xp + w * (1.0 + p2 * (ca * ca / cos_a + cb * cb / cos_b) / scos)
        if final:
            if seg.g == 0.0:
                t = t + w / (ca * cb)
                length = length + w * (2.0 / (ca + cb))
            else:
                k = (ca + cb) / (cb * cos_a + ca * cos_b)
                t = t + np.log1p(seg.g * h * (1.0 + k) / (ca * (1.0 + cos_b))) / seg.g
                length = length + h * k * _asinc(p * seg.g * h * k)
    return (x, xp, t, length) if final else (x, xp)


# ---------------------------------------------------------------------------
# Eigenrays
# ---------------------------------------------------------------------------
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
    return Eigenrays(**_eigen_fields(profile, source_depth_m, target_y_m, target_z_m, _FIELDS, workers))


def _eigen_fields(profile, source_depth_m, target_y_m, target_z_m, fields, workers) -> dict:
    """The ``fields`` of :class:`Eigenrays` (and ``reachable``), each of the
    broadcast shape of the inputs."""
    _check_profile(profile)
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
        _solve_block(profile, za, yb[lo:hi], zb[lo:hi], {k: v[lo:hi] for k, v in out.items()})

    _map_blocks(run, yb.size, workers)
    return {k: v.reshape(shape) for k, v in out.items()}


def _check_profile(profile) -> None:
    require(isinstance(profile, SoundSpeedProfile), OptionError,
            f"a SoundSpeedProfile is needed, got {type(profile).__name__}")


def _map_blocks(fn, n: int, workers: int | None, step: int = BLOCK) -> None:
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


def _solve_block(profile: SoundSpeedProfile, za, y: np.ndarray, zb: np.ndarray, out: dict) -> None:
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
        block = _Block(profile.layers, za if np.ndim(za) == 0 else sel(za_arr), np.abs(sel(y)), sel(zb))
        a = block.arr
        t, ok, pending = _newton(block, a["dz"] / (np.hypot(a["dz"], a["y"]) + a["y"]))   # straight line
        idx = np.flatnonzero(ok)
        sub, bad = _fill_rays(block, t, idx, pending, fields)
        if bad.size:
            # a last step taken unchecked fell short: iterate those to the end
            t2, ok2, _ = _newton(block, t, subset=bad, loose=False)
            t[bad] = t2[bad]
            good, failed = bad[ok2[bad]], bad[~ok2[bad]]
            redo, _ = _fill_rays(block, t, good, np.zeros(block.n, dtype=bool), fields)
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


_SIGNED = ("launch_sin", "arrival_sin", "ray_parameter_s_m")


def _ray(t: np.ndarray, cmax: np.ndarray):
    """``p`` and ``1 - sin(phi)`` of the ray whose elevation ``chi = pi/2 - phi``
    (from the horizontal, relative to ``c_max``) has ``t = tan(chi / 2)``, and
    ``1 / (1 + t^2)``: rational in ``t``, so no trigonometry and no
    cancellation near the horizontal (``t -> 0``)."""
    t2 = t * t
    inv = 1.0 / (1.0 + t2)
    return (1.0 - t2) * inv / cmax, 2.0 * t2 * inv, inv


def _newton(block: _Block, t: np.ndarray, *, subset: np.ndarray | None = None, loose: bool = True):
    """``t = tan(chi / 2)`` of the ray with ``X = y`` for the targets of the
    block (or ``subset``), starting from ``t``.

    Returns ``t``, the mask of targets solved and, with ``loose``, the mask of
    those solved by a last Newton step taken without checking its result
    (taken once ``|X - y| <= LOOSE_TOL_REL * distance``, where a step leaves
    a residual orders of magnitude below ``X_TOL_REL * distance``; the
    caller checks it).

    The unknown is (a function of) the elevation from the horizontal so that
    rays close to horizontal keep full precision; ``X`` decreases with ``t``.
    Each step is Newton's on ``tan(atan(X/dz) - atan(y/dz))``, i.e. on
    ``dz (X - y) / (dz^2 + X y)`` (damped where ``X < y``, so a step does not
    run past the horizon), kept inside the bracket, else a bisection.
    """
    a = block.arr
    y, dz, cmax = a["y"], a["dz"], block.cmax
    t = t.copy()
    ok = np.zeros(block.n, dtype=bool)
    pending = np.zeros(block.n, dtype=bool)
    reach = y <= block.x_max()
    live = np.flatnonzero(reach) if subset is None else subset[reach[subset]]
    if live.size == block.n:
        view, tv, cm, yv, dz2 = block.view_all, t.copy(), cmax, y, dz * dz
    else:
        view, tv, cm, yv, dz2 = _View(block, live), t[live], cmax[live], y[live], (dz * dz)[live]
    lo, hi = np.zeros(tv.size), np.ones(tv.size)
    rho = np.sqrt(dz2 + yv * yv)
    it = 0
    for it in range(1, MAX_ITERATIONS + 1):
        if tv.size == 0:
            break
        p, om, inv = _ray(tv, cm)
        x, xp = block.sums(view, p, om)
        r = x - yv
        lo = np.where(r > 0, tv, lo)
        hi = np.where(r < 0, tv, hi)
        conv = (np.abs(r) <= X_TOL_REL * rho) | (hi - lo <= 4e-16 * hi)
        # -dX/dt = X_p |dp/dt| = X_p 4 t inv^2 / c_max
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            new = tv + r * (dz2 + x * yv) * cm / (xp * (4.0 * tv * inv * inv) * (dz2 + yv * yv))
        inside = (new > lo) & (new < hi)
        new = np.where(inside, new, 0.5 * (lo + hi))
        last = (inside & (np.abs(r) <= LOOSE_TOL_REL * rho) & ~conv) if loose else np.zeros(conv.size, dtype=bool)
        done = conv | last
        tv = np.where(conv, tv, new)
        if done.all() or 4 * np.count_nonzero(~done) < done.size:
            t[live] = tv
            ok[live[done]] = True
            pending[live[last]] = True
            keep = ~done
            if not keep.any():
                break
            live = live[keep]
            view = _View(block, live)
            tv, cm, yv, dz2, lo, hi, rho = tv[keep], cm[keep], yv[keep], dz2[keep], lo[keep], hi[keep], rho[keep]
    else:
        t[live] = tv
        ok[live[done]] = True
        pending[live[last]] = True
    log.debug("eigenrays: %d targets, %d iterations", live.size if subset is not None else block.n, it)
    left = np.count_nonzero(reach & ~ok) if subset is None else np.count_nonzero(reach[subset] & ~ok[subset])
    if left:
        log.warning("eigenrays: %d of %d targets did not converge in %d iterations (set to NaN)",
                    left, block.n, MAX_ITERATIONS)
    return t, ok, pending


def _fill_rays(block: _Block, t: np.ndarray, idx: np.ndarray, pending: np.ndarray, fields) -> tuple[dict, np.ndarray]:
    """The ``fields`` of the targets ``idx`` of the block (unsigned, in the
    order of ``idx``), and those of the ``pending`` ones whose residual is
    too large (indices into the block)."""
    view = _View(block, idx)
    cm = block.cmax[idx]
    p, om, _ = _ray(t[idx], cm)
    x, xp, tt, length = block.sums(view, p, om, final=True)
    y = view.arr["y"]
    bad = idx[pending[idx] & ~(np.abs(x - y) <= X_TOL_REL * np.hypot(y, view.arr["dz"]))]
    c0, ct = view.arr["c_za"], view.arr["c_zb"]
    out = {}
    for k in fields:
        if k == "time_s":
            out[k] = tt + p * (y - x)
        elif k == "launch_sin":
            out[k] = np.minimum(p * c0, 1.0)
        elif k == "launch_cos":
            out[k] = _cos(c0, p * c0, cm, om)
        elif k == "arrival_sin":
            out[k] = np.minimum(p * ct, 1.0)
        elif k == "arrival_cos":
            out[k] = _cos(ct, p * ct, cm, om)
        elif k == "path_length_m":
            out[k] = length
        elif k == "ray_parameter_s_m":
            out[k] = p
        elif k == "wavefront_radius_m":
            cos0 = _cos(c0, p * c0, cm, om)
            out[k] = cos0 * cos0 * xp / c0
    return out, bad


# ---------------------------------------------------------------------------
# Tables on a polar grid
# ---------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class TravelTimeTables:
    """Eigenray quantities on a polar grid, each ``(n_angle, n_range)``.

    Cell ``(i, j)`` sits at ``y = R_j sin(theta_i)``, ``z = R_j cos(theta_i)``
    from the grid centre; rays start at the centre (depth
    ``centre_depth_m`` on the profile's axis).  Unreachable cells hold NaN.

    Attributes
    ----------
    time_s : numpy.ndarray
        One-way travel time centre -> cell (s).
    launch_sin, launch_cos : numpy.ndarray
        Ray direction at the centre (from nadir, sine signed as ``y``).
    path_length_m : numpy.ndarray
        Ray length ``L`` (m).
    wavefront_radius_m : numpy.ndarray
        Wavefront radius ``rho`` at the centre (m), see :class:`Eigenrays`:
        the better radius for the per-element approximation.
    reachable : numpy.ndarray
        bool, a direct downgoing ray reaches the cell.
    centre_speed_m_s : float
        Sound speed at the centre (m/s), ``c0`` of the per-element approximation.
    centre_depth_m : float
        Depth of the centre on the profile's axis (m).
    grid : PolarGrid
        The grid the tables belong to.
    """

    time_s: np.ndarray
    launch_sin: np.ndarray
    launch_cos: np.ndarray
    path_length_m: np.ndarray
    wavefront_radius_m: np.ndarray
    reachable: np.ndarray
    centre_speed_m_s: float
    centre_depth_m: float
    grid: PolarGrid


def travel_time_tables(profile: SoundSpeedProfile, grid: PolarGrid, centre_depth_m: float = 0.0, *,
                       workers: int | None = None) -> TravelTimeTables:
    """One-way eigenray travel times from the grid centre to every cell.

    Parameters
    ----------
    profile : SoundSpeedProfile
        The stratified medium.
    grid : PolarGrid
        The image grid; only its ranges and angles are used (the tables are
        relative to the centre, whatever ``grid.centre_yz_m``).
    centre_depth_m : float
        Depth of the grid centre on the profile's depth axis (m): its
        earth-frame ``z`` when the profile is referenced to the transducers.
    workers : int or None
        Threads (``None``: every CPU).

    Returns
    -------
    TravelTimeTables
        ``(n_angle, n_range)`` arrays (s, unitless, m, bool).  The cell at
        ``R = 0`` has ``T = L = 0`` and the cell's direction as launch
        direction; cells at the centre's depth (``theta = +-90``, ``R > 0``)
        are unreachable unless the speed just below the centre is constant
        (a horizontal ray).  The paper's grid (8.8 M cells) takes about 3 s
        on 2 cores.
    """
    _check_profile(profile)
    require(isinstance(grid, PolarGrid), GeometryError, f"a PolarGrid is needed, got {type(grid).__name__}")
    z0 = float(centre_depth_m)
    require(math.isfinite(z0), GeometryError, f"centre depth must be finite, got {centre_depth_m!r}")
    th = np.deg2rad(grid.angles_deg)
    rng = grid.ranges_m
    tabs = _table_cells(profile, z0, th, rng, workers)
    return TravelTimeTables(**tabs, centre_speed_m_s=float(profile.speed(z0, side="below")),
                            centre_depth_m=z0, grid=grid)


_TABLE_FIELDS = ("time_s", "launch_sin", "launch_cos", "path_length_m", "wavefront_radius_m", "reachable")


def _table_cells(profile, z0: float, th: np.ndarray, rng: np.ndarray, workers: int | None) -> dict:
    """``(n_angle, n_range)`` tables of the cells ``(th, rng)``."""
    sin_t, cos_t = np.sin(th), np.cos(th)
    n_r = rng.size
    shape = (th.size, n_r)
    out = {k: np.empty(shape, dtype=bool if k == "reachable" else np.float64) for k in _TABLE_FIELDS}

    def run(a0: int, a1: int) -> None:
        y = (sin_t[a0:a1, None] * rng[None, :]).ravel()
        z = (z0 + cos_t[a0:a1, None] * rng[None, :]).ravel()
        dest = {k: v[a0:a1].reshape(-1) for k, v in out.items()}
        _solve_block(profile, z0, y, z, dest)
        if rng[0] == 0:
            out["launch_sin"][a0:a1, 0] = sin_t[a0:a1]
            out["launch_cos"][a0:a1, 0] = cos_t[a0:a1]

    _map_blocks(run, th.size, workers, step=max(1, BLOCK // n_r))
    return out


# ---------------------------------------------------------------------------
# Per-element (offset) times
# ---------------------------------------------------------------------------
def offset_delay_m(radius_m, sin_u, cos_u, offset_yz_m) -> np.ndarray:
    """``d(o) = |rho u - o| - rho`` (m) without cancellation.

    Parameters
    ----------
    radius_m : array_like
        ``rho`` (m), e.g. ``path_length_m`` or ``wavefront_radius_m``.
    sin_u, cos_u : array_like
        Direction ``u`` from the centre (launch direction), unitless.
    offset_yz_m : array_like
        ``(..., 2)`` offsets ``o = (o_y, o_z)`` from the centre (m).

    Returns
    -------
    numpy.ndarray
        ``d`` (m), of shape ``offset.shape[:-1] + broadcast(radius, u).shape``.
    """
    o = np.asarray(offset_yz_m, dtype=np.float64)
    require(o.shape[-1:] == (2,), GeometryError, f"offsets must be (..., 2) as (y, z) in m, got shape {o.shape}")
    rho = np.asarray(radius_m, dtype=np.float64)
    su, cu = np.asarray(sin_u, dtype=np.float64), np.asarray(cos_u, dtype=np.float64)
    extra = (1,) * np.broadcast(rho, su, cu).ndim
    oy = o[..., 0].reshape(o.shape[:-1] + extra)
    oz = o[..., 1].reshape(o.shape[:-1] + extra)
    dy, dz = rho * su - oy, rho * cu - oz
    den = np.hypot(dy, dz) + rho
    num = oy * oy + oz * oz - 2.0 * rho * (su * oy + cu * oz)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, num / den, 0.0)


def offset_time_approx(tables: TravelTimeTables, offset_yz_m, *, radius: str = "path") -> np.ndarray:
    """Approximate one-way time from a point near the centre to every cell (s).

    ``T + d(o) / c0`` with ``d(o) = |rho u - o| - rho``, ``u`` the launch
    direction, ``c0`` the speed at the centre and ``rho`` the path length
    ``L`` (``radius="path"``) or the wavefront radius (``radius="wavefront"``).
    Exact for a constant profile (either radius).

    Parameters
    ----------
    tables : TravelTimeTables
        From :func:`travel_time_tables`.
    offset_yz_m : array_like
        ``(2,)`` or ``(n, 2)`` offsets ``(o_y, o_z)`` from the grid centre (m).
    radius : {"path", "wavefront"}
        Which per-cell radius to use.

    Returns
    -------
    numpy.ndarray
        ``(n_angle, n_range)`` for one offset, ``(n, n_angle, n_range)`` for
        several (s); NaN where the cell is unreachable.
    """
    require(radius in ("path", "wavefront"), OptionError, f"radius must be 'path' or 'wavefront', got {radius!r}")
    rho = tables.path_length_m if radius == "path" else tables.wavefront_radius_m
    d = offset_delay_m(rho, tables.launch_sin, tables.launch_cos, offset_yz_m)
    return tables.time_s + d / tables.centre_speed_m_s


def offset_time_exact(profile: SoundSpeedProfile, grid: PolarGrid, offset_yz_m, centre_depth_m: float = 0.0, *,
                      workers: int | None = None) -> np.ndarray:
    """Exact eigenray time from a point near the grid centre to every cell (s).

    Parameters
    ----------
    profile : SoundSpeedProfile
        The stratified medium.
    grid : PolarGrid
        The image grid (ranges and angles, relative to its centre).
    offset_yz_m : array_like
        ``(2,)`` or ``(n, 2)`` offsets ``(o_y, o_z)`` of the ray's start from
        the centre (m).
    centre_depth_m : float
        Depth of the grid centre on the profile's axis (m).
    workers : int or None
        Threads (``None``: every CPU).

    Returns
    -------
    numpy.ndarray
        ``(n_angle, n_range)`` or ``(n, n_angle, n_range)`` (s), NaN where no
        direct downgoing ray joins the point and the cell.
    """
    o = np.asarray(offset_yz_m, dtype=np.float64)
    require(o.shape[-1:] == (2,) and o.ndim in (1, 2), GeometryError,
            f"offsets must be (2,) or (n, 2) as (y, z) in m, got shape {o.shape}")
    y, z = grid.cell_yz((0.0, float(centre_depth_m)))
    pts = o.reshape(-1, 2) + np.array([0.0, float(centre_depth_m)])
    out = element_travel_times(profile, pts, np.stack([y.ravel(), z.ravel()], axis=1), workers=workers)
    out = out.reshape((-1,) + grid.shape)
    return out[0] if o.ndim == 1 else out


def element_travel_times(profile: SoundSpeedProfile, points_yz, scatterers_yz, *,
                         workers: int | None = None) -> np.ndarray:
    """Exact one-way eigenray times between points (elements) and scatterers.

    Parameters
    ----------
    profile : SoundSpeedProfile
        The stratified medium.
    points_yz : array_like
        ``(n_points, 2)`` positions ``(y, z)`` (m, earth frame, ``z`` on the
        profile's depth axis), e.g. the receive elements or the source.
    scatterers_yz : array_like
        ``(n_scatterers, 2)`` positions ``(y, z)`` (m).

    Returns
    -------
    numpy.ndarray
        ``(n_points, n_scatterers)`` travel times (s).  Each pair is solved
        from its shallower end (reciprocity); NaN where no direct ray without
        a turning point joins the two (for two distinct points at the same
        depth, unless the speed just below them is constant).

    Raises
    ------
    GeometryError
        When the positions are not ``(n, 2)`` or not finite.
    """
    pts = _yz_array(points_yz, "points")
    sc = _yz_array(scatterers_yz, "scatterers")
    zp, zs = pts[:, 1:2], sc[None, :, 1]
    za = np.minimum(zp, zs)
    zb = np.maximum(zp, zs)
    dy = sc[None, :, 0] - pts[:, 0:1]
    return _eigen_fields(profile, za, dy, zb, ("time_s",), workers)["time_s"]


def _yz_array(values, name: str) -> np.ndarray:
    a = np.asarray(values, dtype=np.float64)
    require(a.ndim == 2 and a.shape[1] == 2, GeometryError,
            f"{name} must be (n, 2) as (y, z) in m, got shape {a.shape}")
    require(bool(np.all(np.isfinite(a))), GeometryError, f"{name} have non-finite coordinates")
    return a


# ---------------------------------------------------------------------------
# Positioning error of an isospeed image
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class PositioningError:
    """Where an isospeed image puts a target seen through a stratified medium.

    All positions ``(y, z)`` in metres relative to the source (``z`` on the
    profile's axis).

    Attributes
    ----------
    true_yz_m : tuple of float
        The target.
    time_s : float
        True one-way travel time (s).
    apparent_yz_m : tuple of float
        Isospeed position along the ray's launch direction at range
        ``c_iso T`` (``c_iso T_two_way / 2``, monostatic).
    apparent_trace_yz_m : tuple of float
        Isospeed position at the same range in the direction a horizontal
        line array steered with ``c_iso`` finds, ``sin = c_iso p`` (its
        phase gradient measures the horizontal slowness ``p``).
    error_m, horizontal_error_m, vertical_error_m : float
        ``|apparent - true|`` and its ``y`` and ``z`` parts (m) for
        ``apparent_yz_m``.
    trace_error_m, trace_horizontal_error_m, trace_vertical_error_m : float
        The same for ``apparent_trace_yz_m``.
    range_only_y_m : float
        Horizontal position at which the isospeed range ``c_iso T`` meets
        the target's (known) depth, as when a seabed pick is positioned from
        its range: ``sqrt((c_iso T)^2 - (z - z0)^2)``, signed like ``y``.
    range_only_horizontal_error_m : float
        ``range_only_y_m - y`` (m).
    """

    true_yz_m: tuple[float, float]
    time_s: float
    apparent_yz_m: tuple[float, float]
    apparent_trace_yz_m: tuple[float, float]
    error_m: float
    horizontal_error_m: float
    vertical_error_m: float
    trace_error_m: float
    trace_horizontal_error_m: float
    trace_vertical_error_m: float
    range_only_y_m: float
    range_only_horizontal_error_m: float


def positioning_error(profile: SoundSpeedProfile, target_yz_m, isospeed_m_s: float, *,
                      source_depth_m: float = 0.0) -> PositioningError:
    """Positioning error of a target imaged with an isospeed ocean.

    Parameters
    ----------
    profile : SoundSpeedProfile
        The true medium.
    target_yz_m : tuple of float
        Target ``(y, z)`` (m), ``y`` from the source, ``z`` on the profile's axis.
    isospeed_m_s : float
        Sound speed of the isospeed imaging (m/s).
    source_depth_m : float
        Depth of the (monostatic) source and receiver (m).

    Returns
    -------
    PositioningError

    Raises
    ------
    GeometryError
        When no direct ray reaches the target.
    """
    c_iso = float(isospeed_m_s)
    require(math.isfinite(c_iso) and c_iso > 0, OptionError, f"isospeed must be > 0 m/s, got {isospeed_m_s!r}")
    ty, tz = (float(v) for v in target_yz_m)
    ray = eigenrays(profile, float(source_depth_m), ty, tz)
    require(bool(ray.reachable), GeometryError,
            f"no direct ray reaches the target at y = {ty:g} m, z = {tz:g} m")
    rng = c_iso * float(ray.time_s)
    app = (rng * float(ray.launch_sin), float(source_depth_m) + rng * float(ray.launch_cos))
    s_tr = min(1.0, abs(c_iso * float(ray.ray_parameter_s_m)))
    s_tr = math.copysign(s_tr, ty)
    tr = (rng * s_tr, float(source_depth_m) + rng * math.sqrt(1.0 - s_tr * s_tr))

    def parts(a):
        return math.hypot(a[0] - ty, a[1] - tz), a[0] - ty, a[1] - tz

    e, eh, ev = parts(app)
    te, teh, tev = parts(tr)
    ro = math.copysign(math.sqrt(max(rng * rng - (tz - float(source_depth_m)) ** 2, 0.0)), ty)
    return PositioningError((ty, tz), float(ray.time_s), app, tr, e, eh, ev, te, teh, tev, ro, ro - ty)
