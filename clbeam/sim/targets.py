"""Point and line targets: where they are, the pipeline's points, and their echoes.

A :class:`~clbeam.sim.scene.PointTarget` is one omnidirectional scatterer;
a :class:`~clbeam.sim.scene.LineTarget` (a pipeline) is a circular arc
sampled as points every ``Δs`` (:func:`line_points`, fixed in the world so
that a ping does not depend on which other pings are made), each standing
for its length of pipe with the ``ka`` response of
:meth:`~clbeam.sim.scene.LineTarget.response`.  :func:`point_echo` and
:func:`line_echo` turn them into the echo set of one ping, on straight rays
with Snell refraction into the sediment or ray traced through a ``[water]``
profile (:class:`~clbeam.sim.propagation.Propagation`).
"""

from __future__ import annotations

import functools
import logging
import math
import zlib

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.sim.geometry import PingGeometry, seabed_z
from clbeam.sim.propagation import Propagation
from clbeam.sim.render import Echoes
from clbeam.sim.scene import LineTarget, PointTarget, Scene

log = logging.getLogger(__name__)


# -- where the targets are -------------------------------------------------------
def target_world(scene: Scene, t: PointTarget) -> tuple[float, float, float]:
    """World (track-frame) position ``(x, y, z)`` of a point target (m)."""
    z = t.z_m if t.z_m is not None else float(seabed_z(scene, t.x_m, t.y_m)) + t.burial_m
    return t.x_m, t.y_m, z


def arc(t: LineTarget, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Track-frame ``x``, ``y`` (m) and heading (rad) of a line at arc lengths ``s`` (m)."""
    d0 = math.radians(t.angle_deg)
    kappa = math.radians(t.curvature_deg_per_km) / 1000.0
    d = d0 + kappa * s
    if abs(kappa) < 1e-12:
        return t.x_m + s * math.cos(d0), t.y_m + s * math.sin(d0), d
    return t.x_m + (np.sin(d) - math.sin(d0)) / kappa, t.y_m - (np.cos(d) - math.cos(d0)) / kappa, d


def arc_extent(t: LineTarget, x_lo: float, x_hi: float) -> tuple[float, float]:
    """Arc-length interval (m) whose points lie within ``x_lo..x_hi`` (m) with heading within ±80°."""
    span = 2 * (abs(x_hi - t.x_m) + abs(x_lo - t.x_m)) + 100.0
    s = np.arange(-span, span, 0.5)
    x, _, d = arc(t, s)
    # heading linear in s: |d| < 80° is one interval, on which x grows
    # monotonically, so the points kept form one stretch
    ok = (x >= x_lo) & (x <= x_hi) & (np.abs(d) < np.radians(80))
    require(bool(ok.any()), OptionError, f"target '{t.name}' never comes near the track")
    idx = np.flatnonzero(ok)
    return float(s[idx[0]]), float(s[idx[-1]])


def line_crossing(scene: Scene, t: LineTarget, along_m: float) -> tuple[float, float, float]:
    """Where a line crosses the plane ``x = along_m`` (m, track frame).

    Returns
    -------
    (float, float, float)
        ``y`` and ``z`` (m) and the heading to the track (degree); NaN if it
        never crosses.
    """
    s0, s1 = arc_extent(t, along_m - 5000.0, along_m + 5000.0)
    s = np.linspace(s0, s1, 4001)
    x, y, d = arc(t, s)
    if not (x.min() <= along_m <= x.max()):
        return math.nan, math.nan, math.nan
    yc = float(np.interp(along_m, x, y))
    dc = float(np.interp(along_m, x, d))
    if t.z_m is not None:
        zc = t.z_m
    else:
        zc = float(seabed_z(scene, along_m, yc)) + t.burial_m
    return yc, zc, math.degrees(dc)


def line_points(prop: Propagation, t: LineTarget, *, x_window: tuple[float, float], track_m: float) -> dict:
    """Points along a line every ``Δs`` over the stretch the pings can see.

    Parameters
    ----------
    prop : Propagation
        The scene's propagation (beam reach, slowest sound speed).
    t : LineTarget
        The line.
    x_window : (float, float)
        Track-frame ``x`` interval the prepared pings can see (m).
    track_m : float
        Length of the whole line (m).  The default spacing
        (``model.line_spacing_m = None``) follows from the stretch the whole
        line can see, not the pings asked for, so that a ping is the same
        whichever pings are made.

    Returns
    -------
    dict
        ``x``, ``y``, ``z`` (m, track frame, sorted by ``x``), ``weight``
        (each point's echo over the smooth pipe's: 1 plus the roughness
        times a fixed unit noise) and ``spacing`` (m).
    """
    spacing = prop.scene.model.line_spacing_m
    if spacing is None:
        a0, a1 = arc_extent(t, -prop.x_ext_m - 10.0, track_m + prop.x_ext_m + 10.0)
        _, _, d = arc(t, np.linspace(a0, a1, 1025))
        wl_min = prop.c_min / (1.05 * prop.scene.sonar.pulse_f1_hz)
        max_cos = min(1.0, prop.u_cut + float(np.max(np.abs(np.sin(d)))))
        spacing = wl_min / (4 * max_cos)
    x_lo, x_hi = x_window
    s0, s1 = arc_extent(t, x_lo - 10.0, x_hi + 10.0)
    # points at whole multiples of the spacing from the reference point
    s = np.arange(math.floor(s0 / spacing), math.ceil(s1 / spacing) + 1) * spacing
    x, y, d = arc(t, s)
    order = np.argsort(x, kind="stable")
    z = np.full(s.size, t.z_m) if t.z_m is not None else seabed_z(prop.scene, x, y) + t.burial_m
    weight = 1 + t.roughness * _unit_noise(np.rint(s / spacing).astype(np.int64), t.name)
    x, y, z, weight = x[order], y[order], z[order], weight[order]
    if t.gap_x_m:  # the stretch with no pipe
        keep = ~((x >= t.gap_x_m[0]) & (x <= t.gap_x_m[1]))
        x, y, z, weight = x[keep], y[keep], z[keep], weight[keep]
    log.debug("line %s: %d points, spacing %.3f m", t.name, x.size, spacing)
    return {"x": x, "y": y, "z": z, "weight": weight, "spacing": spacing}


def _unit_noise(index: np.ndarray, name: str) -> np.ndarray:
    """Zero-mean, unit-variance noise that is a fixed function of a point's index along its line
    (the same point gets the same value whichever pings are made)."""
    key = zlib.crc32(name.encode()) % 100003
    frac = np.mod(np.sin(index * 12.9898 + key * 78.233) * 43758.5453, 1.0)
    return (frac - 0.5) * math.sqrt(12.0)


# -- echoes ------------------------------------------------------------------------
def point_echo(prop: Propagation, g: PingGeometry, t: PointTarget) -> Echoes:
    """The echo set of a point target in ping ``g`` (amplitude ``a``, m)."""
    x, y, z = target_world(prop.scene, t)
    pos = np.array([[x - g.along_m, y, z]])
    amp = np.array([t.amplitude_m])
    if prop.svp is not None:
        buried = t.burial_m is not None
        zsb = np.array([z - t.burial_m]) if buried else None
        src = prop.source_rays(g, pos, buried=buried, seabed_z_m=zsb)
        b_s = None
        if buried:
            bur = prop.buried_rays(g, pos, zsb, src)
            amp, b_s = amp * bur["transmission"], bur["b_s"]
        e = prop.traced_echoes(t.name, g, pos, amp, src, buried=buried, seabed_z_m=zsb, b_s=b_s)
        if not len(e):
            log.warning("target '%s': no direct ray reaches it in ping %d; left out", t.name, g.index)
        return e
    if t.burial_m is None:
        return prop.scatterers(t.name, g, pos, amp)
    bur = prop.buried(g, pos, np.array([t.burial_m]), np.array([z - t.burial_m]))
    return prop.scatterers(t.name, g, pos, amp * bur["transmission"], extra_s=bur["extra_s"], b_s=bur["b_s"],
                           rx_tilt=bur["rx_tilt"])


def line_echo(prop: Propagation, g: PingGeometry, t: LineTarget, pts: dict) -> Echoes | None:
    """The echo set of a line's points ``pts`` (:func:`line_points`) inside
    the transmit beam of ping ``g``; ``None`` when none is near."""
    lo, hi = np.searchsorted(pts["x"], [g.along_m - prop.x_ext_m, g.along_m + prop.x_ext_m])
    if hi <= lo:
        return None
    pos = np.stack([pts["x"][lo:hi] - g.along_m, pts["y"][lo:hi], pts["z"][lo:hi]], axis=1)
    if prop.svp is not None:
        return _line_echo_traced(prop, g, t, pts, pos, pts["weight"][lo:hi])
    _, u = prop.direction_cosine(g, pos)
    keep = np.abs(u) < prop.u_cut
    pos = pos[keep]
    amp = t.reflectivity * pts["spacing"] * pts["weight"][lo:hi][keep]
    medium_c = prop.c
    kw = {}
    if t.burial_m is not None:
        medium_c = prop.c * prop.scene.seabed.sound_speed_ratio
        bur = prop.buried(g, pos, np.full(len(pos), t.burial_m), pos[:, 2] - t.burial_m)
        amp = amp * bur["transmission"]
        kw = {"extra_s": bur["extra_s"], "b_s": bur["b_s"], "rx_tilt": bur["rx_tilt"]}
    return prop.scatterers(t.name, g, pos, amp, response=functools.partial(t.response, sound_speed_m_s=medium_c),
                           **kw)


def _line_echo_traced(prop: Propagation, g: PingGeometry, t: LineTarget, pts: dict, pos: np.ndarray,
                      weight: np.ndarray) -> Echoes:
    """:func:`line_echo` through the sound-speed profile."""
    buried = t.burial_m is not None
    zsb = pos[:, 2] - t.burial_m if buried else None
    src = prop.source_rays(g, pos, buried=buried, seabed_z_m=zsb)
    keep = np.abs(src["u"]) < prop.u_cut             # NaN: no ray, out
    pos, src = pos[keep], {k: v[keep] for k, v in src.items()}
    zsb = zsb[keep] if buried else None
    amp = t.reflectivity * pts["spacing"] * weight[keep]
    b_s = None
    if buried:
        medium_c = prop.c_seabed * prop.scene.seabed.sound_speed_ratio
        bur = prop.buried_rays(g, pos, zsb, src)
        amp, b_s = amp * bur["transmission"], bur["b_s"]
    else:
        medium_c = float(prop.svp.speed(np.median(pos[:, 2]))) if len(pos) else prop.c
    return prop.traced_echoes(t.name, g, pos, amp, src, buried=buried, seabed_z_m=zsb, b_s=b_s,
                              response=functools.partial(t.response, sound_speed_m_s=medium_c))
