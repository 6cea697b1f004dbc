"""Rough interfaces: the seabed's and the sub-bottom's random scatterers, and the seabed provinces.

A rough interface is a field of random point scatterers fixed in the world
(:func:`scatterer_fields`): every 64 m tile draws its own from a seeded
generator, so a scatterer is where it is whatever pings are asked for.
Their density follows the range resolution across-track so that one range
cell holds ``per_cell`` of them, and along-track a ping keeps a scatterer
with the probability of the transmit beam's energy at its direction cosine
(importance sampling; the amplitude is divided accordingly).  A scatterer
standing for an area ``1/n`` gets amplitude ``g sqrt(σ(θ) / n)``, ``g``
standard normal, ``σ(θ)`` the backscattering cross-section at its grazing
angle: ``10^(strength/10) sin^m θ``, or on the seabed of a scene with
``[[seabed.province]]`` tables the APL-UW TR 9407 model of the province's
grain size (:class:`Provinces`).  :func:`field_echo` gives the echo set of
one ping.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from clbeam.seabed.avo import backscatter_strength_db
from clbeam.sim.geometry import PingGeometry, seabed_z
from clbeam.sim.physics import DB_PER_NEPER
from clbeam.sim.propagation import Propagation
from clbeam.sim.render import Echoes
from clbeam.sim.scene import Province, Scattering

log = logging.getLogger(__name__)

PROVINCE_GRAZING_DEG = np.linspace(0.05, 90.0, 1800)
"""Grazing angles (degree) at which each province's strength is tabulated
(0.05° apart; the model is smooth, linear interpolation in dB)."""
TILE_M = 64.0
"""Side of the world tiles (m) that each draw their scatterers from their own generator."""


class Provinces:
    """Seabed provinces along the track and their AVO backscattering strength.

    Parameters
    ----------
    provinces : tuple of Province
        The scene's ``[[seabed.province]]`` tables, starts increasing.
    frequency_hz : float
        Frequency at which the strength is tabulated (the band centre, Hz).
    sound_speed_water_m_s : float
        Water sound speed at the seabed (m/s).
    """

    def __init__(self, provinces: tuple[Province, ...], *, frequency_hz: float, sound_speed_water_m_s: float):
        # imported on use: scenes without provinces need not load the AVO model
        self.start_m = np.array([p.from_along_track_m for p in provinces])
        self.mz = np.array([p.mz for p in provinces])
        self.strength_table_db = np.stack([
            backscatter_strength_db(PROVINCE_GRAZING_DEG, frequency_hz, mz=p.mz,
                                    sound_speed_water_m_s=sound_speed_water_m_s) for p in provinces])

    def index(self, x_track_m) -> np.ndarray:
        """Index of the province at track-frame along-track positions (m)."""
        start = self.start_m
        return np.clip(np.searchsorted(start, np.asarray(x_track_m), side="right") - 1, 0, start.size - 1)

    def mz_at(self, along_m: float) -> float:
        """Grain size (phi) of the province at ``along_m`` along the track (m)."""
        return float(self.mz[self.index(along_m)])

    def strength_db(self, x_track_m, grazing_rad) -> np.ndarray:
        """AVO backscattering strength (dB) at along-track positions
        ``x_track_m`` (m) and grazing angles ``grazing_rad``, from the province
        there (:func:`clbeam.seabed.avo.backscatter_strength_db`)."""
        k = self.index(x_track_m)
        deg = np.clip(np.degrees(np.asarray(grazing_rad, dtype=np.float64)), PROVINCE_GRAZING_DEG[0], 90.0)
        out = np.empty(deg.shape)
        for j in np.unique(k):
            sel = k == j
            out[sel] = np.interp(deg[sel], PROVINCE_GRAZING_DEG, self.strength_table_db[j])
        return out


@dataclass(frozen=True)
class ScattererField:
    """The random scatterers of one interface, sorted by ``x``.

    Attributes
    ----------
    layer : int
        1 the seabed, 2 the sub-bottom.
    scattering : Scattering
        The interface's scattering law.
    depth_below_seabed_m : float
        Depth of the interface below the seabed (m).
    x, y : numpy.ndarray
        Track-frame position (m).
    zeta : numpy.ndarray
        Vertical jitter about the interface (m).
    g : numpy.ndarray
        Standard normal amplitude factor.
    q : numpy.ndarray
        Uniform score: a ping keeps the scatterer when ``q`` is below the
        beam envelope at its direction cosine.
    n : numpy.ndarray
        Local density (m⁻²).
    """

    layer: int
    scattering: Scattering
    depth_below_seabed_m: float
    x: np.ndarray
    y: np.ndarray
    zeta: np.ndarray
    g: np.ndarray
    q: np.ndarray
    n: np.ndarray


def scatterer_fields(prop: Propagation, *, seed: int, x_window: tuple[float, float]) -> list[ScattererField]:
    """The random scatterer fields of the scene's rough interfaces.

    Parameters
    ----------
    prop : Propagation
        The scene's propagation (beam envelope, reach).
    seed : int
        Seed of the fields.
    x_window : (float, float)
        Track-frame ``x`` interval the prepared pings can see (m).

    Returns
    -------
    list of ScattererField
        The seabed's (layer 1) and the sub-bottom's (layer 2), those that scatter.
    """
    sc = prop.scene
    fields = []
    if sc.seabed is not None and sc.seabed.scattering is not None:
        fields.append(_field(prop, seed, 1, sc.seabed.scattering, 0.0, x_window))
    if sc.subbottom is not None and sc.subbottom.scattering is not None:
        fields.append(_field(prop, seed, 2, sc.subbottom.scattering, sc.subbottom.depth_below_seabed_m, x_window))
    return fields


def _density(prop: Propagation, y_m: np.ndarray, scattering: Scattering, depth_below_seabed_m: float) -> np.ndarray:
    """Scatterers per m² at cross-track ``y`` so that one range cell of the
    strip on one side holds ``per_cell`` (with the envelope weight)."""
    so = prop.scene.sonar
    dr = prop.c / (2 * (so.pulse_f1_hz - so.pulse_f0_hz))
    h = np.maximum(seabed_z(prop.scene, 0.0, y_m) + depth_below_seabed_m, 1.0)
    ay = np.abs(y_m)
    r = np.hypot(ay, h)
    dy = np.sqrt(ay * ay + 2 * r * dr + dr * dr) - ay
    width = r * 2 * np.trapezoid(prop.envelope_weight, prop.envelope_u)
    return scattering.per_cell / (dy * width)


def _field(prop: Propagation, seed: int, layer: int, scattering: Scattering, depth_below_seabed_m: float,
           x_window: tuple[float, float]) -> ScattererField:
    """Random scatterers of one interface over the tiles the pings need.

    Each tile draws a Poisson number of uniform points at the tile's largest
    density and thins them to the local density; each keeps its score ``q``
    relative to the kept fraction.
    """
    sc = prop.scene
    h_mean = sc.seabed.depth_m - sc.sonar.draft_m + depth_below_seabed_m
    y_max = math.sqrt(max((prop.max_range_m + 20) ** 2 - (0.5 * h_mean) ** 2, 1.0))
    x_lo, x_hi = x_window
    ix = np.arange(math.floor(x_lo / TILE_M), math.floor(x_hi / TILE_M) + 1)
    iy = np.arange(math.floor(-y_max / TILE_M), math.floor(y_max / TILE_M) + 1)
    out = {k: [] for k in ("x", "y", "zeta", "g", "q", "n")}
    for jy in iy:
        ys = (jy + np.linspace(0, 1, 17)) * TILE_M
        n_max = 1.02 * float(np.max(_density(prop, ys, scattering, depth_below_seabed_m)))
        for jx in ix:
            rng = np.random.default_rng([seed, 2, layer, int(jx) + (1 << 30), int(jy) + (1 << 30)])
            n = rng.poisson(n_max * TILE_M * TILE_M)
            x = (jx + rng.random(n)) * TILE_M
            y = (jy + rng.random(n)) * TILE_M
            zeta = rng.normal(0.0, scattering.depth_spread_m, n) if scattering.depth_spread_m > 0 else np.zeros(n)
            g = rng.standard_normal(n)
            q = rng.random(n)
            dens = _density(prop, y, scattering, depth_below_seabed_m)
            frac = np.minimum(dens / n_max, 1.0)
            keep = q < frac
            for k, v in (("x", x), ("y", y), ("zeta", zeta), ("g", g), ("q", q / frac), ("n", dens)):
                out[k].append(v[keep])
    arrays = {k: np.concatenate(v) if v else np.zeros(0) for k, v in out.items()}
    order = np.argsort(arrays["x"], kind="stable")
    log.debug("layer %d: %d scatterers stored", layer, arrays["x"].size)
    return ScattererField(layer=layer, scattering=scattering, depth_below_seabed_m=depth_below_seabed_m,
                          **{k: v[order] for k, v in arrays.items()})


def field_echo(prop: Propagation, g: PingGeometry, f: ScattererField, provinces: Provinces | None) -> Echoes:
    """The random scatterers of one interface that ping ``g`` keeps, as an echo set.

    Parameters
    ----------
    prop : Propagation
        The scene's beam (importance envelope, cut) and paths.
    g : PingGeometry
        The ping whose beam selects the scatterers.
    f : ScattererField
        The interface's scatterers.
    provinces : Provinces or None
        The seabed provinces, whose strength replaces the ``sin^m`` law on
        the seabed (layer 1).

    Returns
    -------
    Echoes
        Buried scatterers attenuated by more than ``model.attenuation_cut_db``
        at the band centre are left out.
    """
    lo, hi = np.searchsorted(f.x, [g.along_m - prop.x_ext_m, g.along_m + prop.x_ext_m])
    x_t, y = f.x[lo:hi], f.y[lo:hi]
    z_sb = seabed_z(prop.scene, x_t, y)
    pos = np.stack([x_t - g.along_m, y, z_sb + f.depth_below_seabed_m + f.zeta[lo:hi]], axis=1)
    if prop.svp is not None:
        return _field_echo_traced(prop, g, f, lo, hi, pos, z_sb, provinces)
    dist, u = prop.direction_cosine(g, pos)
    keep, weight = _kept(prop, f, lo, hi, dist, u)
    idx = np.arange(lo, hi)[keep]
    pos, dist, u, weight, z_sb = pos[keep], dist[keep], u[keep], weight[keep], z_sb[keep]
    kw = {}
    trans = 1.0
    if f.depth_below_seabed_m > 0:
        bur = prop.buried(g, pos, pos[:, 2] - z_sb, z_sb)
        sin_graz = np.sin(bur["grazing_sediment_rad"])
        trans = bur["transmission"]
        kw = {"extra_s": bur["extra_s"], "b_s": bur["b_s"], "rx_tilt": bur["rx_tilt"]}
    else:
        normal = prop.seabed_plane(g).n
        sin_graz = np.abs((pos - g.source) @ normal) / dist
    amp = _amplitude(f, idx, weight, sin_graz, trans, provinces)
    e = Echoes(label=f"layer{f.layer}", pos=pos, amp=amp * prop.taper(u), src_leg=dist, spread=dist,
               extra_s=kw.get("extra_s", np.zeros(len(amp))), u=u, b_s=kw.get("b_s"), rx_tilt=kw.get("rx_tilt"))
    if e.b_s is not None:
        cut = e.b_s * prop.fc * DB_PER_NEPER <= prop.scene.model.attenuation_cut_db
        e = e.subset(cut)
    return e


def _field_echo_traced(prop: Propagation, g: PingGeometry, f: ScattererField, lo: int, hi: int, pos: np.ndarray,
                       z_sb: np.ndarray, provinces: Provinces | None) -> Echoes:
    """:func:`field_echo` through the sound-speed profile: the beam and the
    importance weight see the ray's launch direction, the grazing angle is
    the ray's at the scatterer (in the sediment below the seabed), the times
    are ray traced."""
    buried = f.depth_below_seabed_m > 0
    src = prop.source_rays(g, pos, buried=buried, seabed_z_m=z_sb if buried else None)
    dist = np.linalg.norm(pos - g.source, axis=1)
    keep, weight = _kept(prop, f, lo, hi, dist, src["u"])
    idx = np.arange(lo, hi)[keep]
    pos, weight, z_sb = pos[keep], weight[keep], z_sb[keep]
    src = {k: v[keep] for k, v in src.items()}
    b_s = None
    trans = 1.0
    if buried:
        bur = prop.buried_rays(g, pos, z_sb, src)
        sin_graz = np.sin(bur["grazing_sediment_rad"])
        trans, b_s = bur["transmission"], bur["b_s"]
    else:
        sin_graz = np.abs(src["arrival"] @ prop.seabed_plane(g).n)
    amp = _amplitude(f, idx, weight, sin_graz, trans, provinces)
    if b_s is not None:
        # before the element legs are traced: they are the cost
        cut = ~(b_s * prop.fc * DB_PER_NEPER > prop.scene.model.attenuation_cut_db)
        pos, amp, b_s, z_sb = pos[cut], amp[cut], b_s[cut], z_sb[cut]
        src = {k: v[cut] for k, v in src.items()}
    return prop.traced_echoes(f"layer{f.layer}", g, pos, amp, src, buried=buried,
                              seabed_z_m=z_sb if buried else None, b_s=b_s)


def _kept(prop: Propagation, f: ScattererField, lo: int, hi: int, dist: np.ndarray,
          u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which of scatterers ``lo:hi`` a ping keeps (importance sampling on the
    beam envelope, inside the beam and the record) and their envelope weights."""
    weight = prop.envelope(u)
    keep = (f.q[lo:hi] < weight) & (np.abs(u) < prop.u_cut) & (dist < prop.max_range_m + 10)
    return keep, weight


def _amplitude(f: ScattererField, idx: np.ndarray, weight: np.ndarray, sin_graz: np.ndarray, trans,
               provinces: Provinces | None) -> np.ndarray:
    """``g sqrt(σ(θ) / n) T`` of scatterers ``idx`` kept with envelope
    ``weight`` (their density is ``n · weight``), ``T`` the transmission."""
    if f.layer == 1 and provinces is not None:
        sigma = 10 ** (provinces.strength_db(f.x[idx], np.arcsin(np.clip(sin_graz, 0.0, 1.0))) / 10)
    else:
        sc = f.scattering
        sigma = 10 ** (sc.strength_db / 10) * sin_graz ** sc.grazing_exponent
    return f.g[idx] * np.sqrt(sigma / (f.n[idx] * weight)) * trans
