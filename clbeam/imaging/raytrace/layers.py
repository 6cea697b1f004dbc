"""Closed-form layer sums of rays through a stratified ocean.

Per layer, from depth ``a`` (speed ``c_a``, ``cos_a``) down to ``b``
(``h = b - a``), a ray of parameter ``p`` advances ``X``, travels ``T`` and
has length ``L`` (the forms of :mod:`clbeam.imaging.raytrace`, exact for
``g = 0`` and without cancellation for small ``p``, ``g`` or ``h``).  Targets
are grouped by the layers their rays start and end in (:class:`Block`) so
that one group's sums run over the same segments, vectorised over its
targets.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from clbeam.model.svp import Layer

#: floor of cos^2 of the ray angle: keeps 0/0 out of layers a ray does not enter
_COS2_FLOOR = 1e-300


def ray_cos(c, s, cmax, om):
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


class View:
    """Some targets of a :class:`Block` (all, or a sorted subset), contiguous by group."""

    def __init__(self, block: "Block", idx: np.ndarray | None):
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


class Block:
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
        self.view_all = View(self, None)
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

    def sums(self, view: View, p: np.ndarray, om: np.ndarray, *, final: bool = False):
        """``X`` (m), ``dX/dp`` (m^2/s) and with ``final`` ``T`` (s), ``L`` (m)
        of rays ``p`` (``om = 1 - p c_max``) for the targets of ``view``."""
        cmax = view.take(self.cmax)
        outs = [np.empty(view.n) for _ in range(4 if final else 2)]
        for s, e, segs in view.groups:
            for o, r in zip(outs, _group_sums(view, s, e, segs, p[s:e], cmax[s:e], om[s:e], final=final)):
                o[s:e] = r
        return outs


def _group_sums(view: View, s: int, e: int, segs, p, cmax, om, *, final: bool):
    """Closed-form sums over the segments of one group of targets."""
    x = 0.0
    xp = 0.0
    t = 0.0
    length = 0.0
    cos_cache: dict[float, np.ndarray] = {}

    def cos_at(c):
        if isinstance(c, float):
            if c not in cos_cache:
                cos_cache[c] = ray_cos(c, p * c, cmax, om)
            return cos_cache[c]
        return ray_cos(c, p * c, cmax, om)

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
