"""The discrete-scatterer physics: seabed, sub-bottom and pipes as 3-D fields of point scatterers.

Chosen per scene by ``model.physics = "discrete"`` (:class:`~clbeam.sim.scene.Model`), with the
statistics of the ``[discrete]`` table (:class:`~clbeam.sim.scene.Discrete`).  It shares nothing with
the specular pipe model (a smooth cylinder's coherent echo, :mod:`clbeam.sim.targets`) or the
importance-sampled interfaces (:mod:`clbeam.sim.seabed`) but the scene's geometry and the paths:

- an interface (the seabed; the sub-bottom horizon below it) is a Poisson field of ``n`` scatterers
  per m², uniform in ``x, y``, spread uniformly ``±h`` in depth about the interface
  (:class:`InterfaceField`);
- a pipe is a line of scatterers every ``Δs`` on its axis, at whole multiples of ``Δs`` of arc length
  from its reference point, along the scene's arc (heading, curvature, burial or depth, gaps)
  (:func:`pipe_scatterers`);
- a point target is one scatterer of amplitude ``a``;
- every scatterer has a complex amplitude ``A = s w``: ``w`` circular complex Gaussian (``E|w|² = 1``:
  a Rayleigh magnitude and a uniform phase), ``s² = σ(θ)/n`` on an interface (``σ`` its scattering
  law at the grazing angle ``θ``: in the water for the seabed, refracted in the sediment for the
  sub-bottom), ``s² = ρ² 2a μ_p Δs`` on a pipe.

Each scatterer's echo on element ``n`` is ``Re{A P / (|r - s| |r - e_n|) x_a(t - τ_n)}`` with the
exact 3-D two-way delay ``τ_n = (|r - s| + |r - e_n|)/c`` (Snell refraction into a slower sediment
as for the other model's buried targets; ray traced through a ``[water]`` profile), ``x_a`` the
analytic pulse and ``P`` the transmit column's along-track pattern ``sinc(L f u / c)`` at every
frequency (``tx_pattern = "band"``) or at the band centre (``"centre"``), ``u`` the ray's direction
cosine on the column.  The renderer (:class:`~clbeam.sim.render.Renderer`) deposits the delays as
band-limited fractional-delay taps and convolves once with the pulse.

The fields are fixed in the world: an interface is drawn in 64 m tiles, each from its own generator
keyed on the seed, the layer and the tile, only where a ping's footprint (the transmit beam's cut
``|u| < u_cut`` within the record's slant range) needs it; a pipe's scatterer ``k`` draws its
amplitude from a generator keyed on the seed, the pipe's name and ``k``.  Successive pings see the
same scatterers, and a ping does not depend on which other pings are made.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import zlib

import numpy as np

from clbeam.sim.geometry import PingGeometry, seabed_z
from clbeam.sim.physics import DB_PER_NEPER
from clbeam.sim.propagation import Propagation
from clbeam.sim.render import Echoes
from clbeam.sim.scene import Discrete, LineTarget, PointTarget, Scattering, Scene
from clbeam.sim.targets import arc, arc_extent, target_world

log = logging.getLogger(__name__)

TILE_M = 64.0
"""Side of the world tiles (m) that each draw their interface scatterers from their own generator."""
PIPE_BLOCK = 4096
"""Pipe scatterers per amplitude generator (indices ``k`` of one block share one)."""
MAX_TILES = 4096
"""Interface tiles kept in memory; the cache is emptied when it grows beyond."""
RAY_MARGIN = 1.1
"""With a sound-speed profile, scatterers whose straight-ray direction cosine is within this factor of
the beam's cut are traced (the launch direction's horizontal part differs from the chord's by about 1 %)."""


def unit_amplitudes(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` circular complex Gaussian amplitudes with ``E|w|² = 1`` (Rayleigh magnitude, uniform phase)."""
    return (rng.standard_normal(n) + 1j * rng.standard_normal(n)) * math.sqrt(0.5)


def pipe_power_per_m(discrete: Discrete, t: LineTarget) -> float:
    """Mean backscattering cross-section per unit length of a pipe, ``ρ² 2a μ_p`` (m²/m)."""
    return t.reflectivity ** 2 * 2 * t.radius_m * 10 ** (discrete.pipe_strength_db / 10)


class InterfaceField:
    """The point scatterers of one interface, drawn tile by tile in the world (track frame).

    Parameters
    ----------
    scene : Scene
        The scene (its seabed plane).
    seed : int
        Seed of the field.
    layer : int
        1 the seabed, 2 the sub-bottom.
    scattering : Scattering
        The interface's law ``σ(θ) = 10^(strength_db/10) sin^m θ`` (its ``per_cell`` and
        ``depth_spread_m`` belong to the other model and are not used).
    density_per_m2 : float
        Scatterers per m² (Poisson).
    half_depth_m : float
        Half-width of the uniform depth spread about the interface (m).
    depth_below_seabed_m : float
        Depth of the interface below the seabed (m).
    """

    def __init__(self, scene: Scene, *, seed: int, layer: int, scattering: Scattering, density_per_m2: float,
                 half_depth_m: float, depth_below_seabed_m: float):
        self.scene, self.seed, self.layer = scene, int(seed), int(layer)
        self.scattering = scattering
        self.density_per_m2 = float(density_per_m2)
        self.half_depth_m = float(half_depth_m)
        self.depth_below_seabed_m = float(depth_below_seabed_m)
        self._tiles: dict = {}

    def tile(self, jx: int, jy: int) -> dict:
        """The scatterers of tile ``(jx, jy)`` (``x`` in ``[jx, jx + 1) · TILE_M``, m).

        Returns
        -------
        dict
            ``x``, ``y`` (m, track frame), ``zeta`` (depth offset from the interface, m) and ``w``
            (complex unit amplitudes); the same arrays for the same seed, layer and tile.
        """
        key = (int(jx), int(jy))
        if key not in self._tiles:
            if len(self._tiles) >= MAX_TILES:
                self._tiles.clear()
            rng = np.random.default_rng([self.seed, 35, self.layer, key[0] + (1 << 30), key[1] + (1 << 30)])
            n = int(rng.poisson(self.density_per_m2 * TILE_M * TILE_M))
            x = (key[0] + rng.random(n)) * TILE_M
            y = (key[1] + rng.random(n)) * TILE_M
            zeta = rng.uniform(-self.half_depth_m, self.half_depth_m, n)
            self._tiles[key] = {"x": x, "y": y, "zeta": zeta, "w": unit_amplitudes(rng, n)}
        return self._tiles[key]

    def within(self, x_lo: float, x_hi: float, y_lo: float, y_hi: float) -> dict:
        """The scatterers with ``x_lo <= x < x_hi`` and ``y_lo <= y < y_hi`` (m, track frame).

        Returns
        -------
        dict
            As :meth:`tile`, plus ``z``: the depth below the transducers' mean depth (m): the
            interface's (the seabed plane plus ``depth_below_seabed_m``) plus ``zeta``.
        """
        parts = [self.tile(jx, jy)
                 for jx in range(math.floor(x_lo / TILE_M), math.floor(x_hi / TILE_M) + 1)
                 for jy in range(math.floor(y_lo / TILE_M), math.floor(y_hi / TILE_M) + 1)]
        out = {k: np.concatenate([p[k] for p in parts]) for k in ("x", "y", "zeta", "w")}
        keep = (out["x"] >= x_lo) & (out["x"] < x_hi) & (out["y"] >= y_lo) & (out["y"] < y_hi)
        out = {k: v[keep] for k, v in out.items()}
        out["z"] = seabed_z(self.scene, out["x"], out["y"]) + self.depth_below_seabed_m + out["zeta"]
        return out

    def sigma(self, sin_grazing: np.ndarray) -> np.ndarray:
        """Backscattering cross-section per unit area and solid angle at ``sin θ`` (grazing)."""
        sc = self.scattering
        return 10 ** (sc.strength_db / 10) * np.clip(sin_grazing, 0.0, 1.0) ** sc.grazing_exponent


def pipe_scatterers(scene: Scene, t: LineTarget, *, seed: int, x_window: tuple[float, float]) -> dict:
    """The scatterers of a pipe over the stretch a set of pings can see.

    Parameters
    ----------
    scene : Scene
        The scene (its seabed, for a buried pipe; its ``[discrete]`` statistics).
    t : LineTarget
        The pipe: arc, burial or depth, gap, radius and reflectivity.
    seed : int
        Seed of the amplitudes.
    x_window : (float, float)
        Track-frame ``x`` interval the pings can see (m).

    Returns
    -------
    dict
        ``s`` (arc length from the reference point, whole multiples of ``discrete.pipe_spacing_m``),
        ``x``, ``y``, ``z`` (m: on the axis, track frame, sorted by ``x``), ``amp`` (complex, m: ``w``
        times ``sqrt(ρ² 2a μ_p Δs)``) and ``spacing`` (m).  None in the gap ``gap_x_m``.
    """
    d = scene.discrete
    spacing = d.pipe_spacing_m
    s0, s1 = arc_extent(t, x_window[0] - 10.0, x_window[1] + 10.0)
    k = np.arange(math.floor(s0 / spacing), math.ceil(s1 / spacing) + 1, dtype=np.int64)
    s = k * spacing
    x, y, _ = arc(t, s)
    z = np.full(s.size, t.z_m) if t.z_m is not None else seabed_z(scene, x, y) + t.burial_m
    amp = _pipe_unit_amplitudes(seed, t.name, k) * math.sqrt(pipe_power_per_m(d, t) * spacing)
    keep = np.ones(s.size, dtype=bool)
    if t.gap_x_m:
        keep = ~((x >= t.gap_x_m[0]) & (x <= t.gap_x_m[1]))
    order = np.argsort(np.where(keep, x, np.inf), kind="stable")[:int(keep.sum())]
    return {"s": s[order], "x": x[order], "y": y[order], "z": z[order], "amp": amp[order], "spacing": spacing}


def _pipe_unit_amplitudes(seed: int, name: str, k: np.ndarray) -> np.ndarray:
    """Complex unit amplitudes of a pipe's scatterers ``k``: a fixed function of the seed, the name and ``k``."""
    key = zlib.crc32(name.encode())
    out = np.empty(k.size, dtype=np.complex128)
    block = np.floor_divide(k, PIPE_BLOCK)
    for b in np.unique(block):
        rng = np.random.default_rng([int(seed), 36, key, int(b) + (1 << 40)])
        w = unit_amplitudes(rng, PIPE_BLOCK)
        sel = block == b
        out[sel] = w[k[sel] - b * PIPE_BLOCK]
    return out


def scatterer_echo(prop: Propagation, g: PingGeometry, label: str, pos: np.ndarray, amp: np.ndarray, *,
                   burial_m: np.ndarray | None = None, sigma=None) -> Echoes | None:
    """The echo set of discrete scatterers in ping ``g``.

    Parameters
    ----------
    prop : Propagation
        The scene's paths and beam.
    g : PingGeometry
        The ping (earth frame).
    label : str
        Name of the set.
    pos : numpy.ndarray
        ``(S, 3)`` positions in the ping's earth frame (m).
    amp : numpy.ndarray
        ``(S,)`` complex amplitudes (m).
    burial_m : numpy.ndarray, optional
        ``(S,)`` depths below a locally flat seabed (m) of buried scatterers: the paths refract at
        the seabed, the amplitude takes the two-way transmission ``1 - V²`` and the sediment's
        attenuation; ``None``: in the water.
    sigma : callable, optional
        ``sin θ -> σ``: the amplitude is multiplied by ``sqrt(σ)`` at the grazing angle ``θ`` (in
        the water at the seabed plane, or in the sediment for buried scatterers).

    Returns
    -------
    Echoes or None
        Scatterers inside the transmit beam's cut and the record (and, buried, attenuated by at most
        ``model.attenuation_cut_db`` at the band centre), with the cut's taper and the transmit
        pattern of ``discrete.tx_pattern``; ``None`` when none is left.
    """
    dist, u = prop.direction_cosine(g, pos)
    margin = RAY_MARGIN if prop.svp is not None else 1.0
    keep = (np.abs(u) < margin * prop.u_cut) & (dist < prop.max_range_m + 10.0)
    if not keep.any():
        return None
    pos, amp, dist = pos[keep], amp[keep], dist[keep]
    buried = burial_m is not None
    zsb = pos[:, 2] - burial_m[keep] if buried else None
    if prop.svp is not None:
        e = _traced(prop, g, label, pos, amp, zsb, sigma)
    else:
        e = _straight(prop, g, label, pos, amp, dist, zsb, sigma)
    if e is None or not len(e):
        return None
    if e.b_s is not None:
        e = e.subset(e.b_s * prop.fc * DB_PER_NEPER <= prop.scene.model.attenuation_cut_db)
    e = e.subset(np.abs(e.u) < prop.u_cut)
    if prop.scene.discrete.tx_pattern == "centre":
        # one real weight at the band centre, and no boxcar (an impulse) in the renderer
        weight = np.sinc(prop.scene.sonar.tx_length_m * e.u * prop.fc / prop.c)
        e = dataclasses.replace(e, amp=e.amp * weight, u=np.zeros(len(e)))
    return e if len(e) else None


def _straight(prop: Propagation, g: PingGeometry, label: str, pos: np.ndarray, amp: np.ndarray, dist: np.ndarray,
              zsb: np.ndarray | None, sigma) -> Echoes:
    """:func:`scatterer_echo` on straight rays, Snell-refracted into the sediment below a locally flat seabed."""
    if zsb is None:
        if sigma is not None:
            normal = prop.seabed_plane(g).n
            amp = amp * np.sqrt(sigma(np.abs((pos - g.source) @ normal) / dist))
        return prop.scatterers(label, g, pos, amp)
    bur = prop.buried(g, pos, pos[:, 2] - zsb, zsb)
    amp = amp * bur["transmission"]
    if sigma is not None:
        amp = amp * np.sqrt(sigma(np.sin(bur["grazing_sediment_rad"])))
    return prop.scatterers(label, g, pos, amp, extra_s=bur["extra_s"], b_s=bur["b_s"], rx_tilt=bur["rx_tilt"])


def _traced(prop: Propagation, g: PingGeometry, label: str, pos: np.ndarray, amp: np.ndarray,
            zsb: np.ndarray | None, sigma) -> Echoes:
    """:func:`scatterer_echo` ray traced through the ``[water]`` profile (and the sediment below the seabed)."""
    buried = zsb is not None
    src = prop.source_rays(g, pos, buried=buried, seabed_z_m=zsb)
    inside = np.abs(src["u"]) < prop.u_cut            # NaN (no ray): out
    pos, amp, src = pos[inside], amp[inside], {k: v[inside] for k, v in src.items()}
    zsb = zsb[inside] if buried else None
    b_s = None
    if buried:
        bur = prop.buried_rays(g, pos, zsb, src)
        amp, b_s = amp * bur["transmission"], bur["b_s"]
        sin_graz = np.sin(bur["grazing_sediment_rad"])
    else:
        sin_graz = np.abs(src["arrival"] @ prop.seabed_plane(g).n) if sigma is not None else None
    if sigma is not None:
        amp = amp * np.sqrt(sigma(sin_graz))
    return prop.traced_echoes(label, g, pos, amp, src, buried=buried, seabed_z_m=zsb, b_s=b_s)


class DiscreteModel:
    """The discrete scatterers of a scene and their echo sets, ping by ping.

    Parameters
    ----------
    prop : Propagation
        The scene's paths, beam and record reach (``prop.scene.model.physics == "discrete"``).
    seed : int
        Seed of the interface fields and the pipes' amplitudes.
    x_window : (float, float)
        Track-frame ``x`` interval the prepared pings can see (m): the pipes' scatterers are laid
        out over it once; the interfaces' tiles are drawn when a ping's footprint needs them.
    """

    def __init__(self, prop: Propagation, *, seed: int, x_window: tuple[float, float]):
        self.prop = prop
        sc = prop.scene
        d = sc.discrete
        self.fields = []
        if sc.seabed is not None and sc.seabed.scattering is not None:
            self.fields.append(InterfaceField(sc, seed=seed, layer=1, scattering=sc.seabed.scattering,
                                              density_per_m2=d.seabed_density_per_m2,
                                              half_depth_m=d.seabed_depth_m, depth_below_seabed_m=0.0))
        if sc.subbottom is not None and sc.subbottom.scattering is not None:
            self.fields.append(InterfaceField(sc, seed=seed, layer=2, scattering=sc.subbottom.scattering,
                                              density_per_m2=d.subbottom_density_per_m2,
                                              half_depth_m=d.subbottom_depth_m,
                                              depth_below_seabed_m=sc.subbottom.depth_below_seabed_m))
        self.pipes = [pipe_scatterers(sc, t, seed=seed, x_window=x_window) if isinstance(t, LineTarget) else None
                      for t in sc.targets]

    def footprint(self, g: PingGeometry) -> tuple[float, float, float, float]:
        """Track-frame box ``(x_lo, x_hi, y_lo, y_hi)`` (m) holding every point of ping ``g``'s beam
        cut within the record's slant range."""
        y_max = self.prop.max_range_m + 10.0
        return g.along_m - self.prop.x_ext_m, g.along_m + self.prop.x_ext_m, -y_max, y_max

    def echoes(self, g: PingGeometry) -> list[Echoes]:
        """The echo sets of ping ``g``: the targets (pipes, points) and the interfaces."""
        sets = [self.target_echo(g, k) for k in range(len(self.pipes))]
        sets += [self.field_echo(g, f) for f in self.fields]
        return [e for e in sets if e is not None]

    def target_echo(self, g: PingGeometry, k: int) -> Echoes | None:
        """The echo set of target ``k`` in ping ``g`` (a pipe's scatterers in the beam, or a point)."""
        sc = self.prop.scene
        t = sc.targets[k]
        if isinstance(t, PointTarget):
            x, y, z = target_world(sc, t)
            pos = np.array([[x - g.along_m, y, z]])
            amp = np.array([complex(t.amplitude_m)])
            burial = None if t.burial_m is None else np.array([t.burial_m])
        else:
            p = self.pipes[k]
            lo, hi = np.searchsorted(p["x"], [g.along_m - self.prop.x_ext_m, g.along_m + self.prop.x_ext_m])
            if hi <= lo:
                return None
            pos = np.stack([p["x"][lo:hi] - g.along_m, p["y"][lo:hi], p["z"][lo:hi]], axis=1)
            amp = p["amp"][lo:hi]
            burial = None if t.burial_m is None else np.full(hi - lo, t.burial_m)
        e = scatterer_echo(self.prop, g, t.name, pos, amp, burial_m=burial)
        if e is None and isinstance(t, PointTarget):
            log.debug("target '%s' is outside the beam or the record in ping %d", t.name, g.index)
        return e

    def field_echo(self, g: PingGeometry, f: InterfaceField) -> Echoes | None:
        """The echo set of interface ``f``'s scatterers in ping ``g``'s footprint, ``A = w sqrt(σ(θ)/n)``."""
        pts = f.within(*self.footprint(g))
        pos = np.stack([pts["x"] - g.along_m, pts["y"], pts["z"]], axis=1)
        amp = pts["w"] / math.sqrt(f.density_per_m2)
        burial = None
        if f.depth_below_seabed_m > 0:
            burial = pts["z"] - seabed_z(self.prop.scene, pts["x"], pts["y"])
        return scatterer_echo(self.prop, g, f"layer{f.layer}", pos, amp, burial_m=burial, sigma=f.sigma)
