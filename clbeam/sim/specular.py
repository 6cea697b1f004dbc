"""Specular paths: the nadir echoes of the seabed and the sub-bottom, the first surface multiple and its doublet.

Each path is an image source: the source mirrored in the planes it
reflects at in turn (:class:`~clbeam.sim.geometry.Plane`), with spreading
along the unfolded path.  The sub-bottom is imaged through an equivalent
plane whose normal offset ``d c / c_s`` gives the right vertical two-way
time (the slower sediment replaced by water of the same travel time).  The
echo amplitudes are the flat-interface impedance contrasts
(``seabed.specular_model = "impedance"``: real, frequency independent) or
the layered coherent forward model's nadir factors (``"forward"``,
:func:`clbeam.seabed.forward.specular_echoes`: frequency dependent, with
the sediment's attenuation and the interfaces' roughness loss).  With a
``[water]`` profile the times follow the unfolded rays through it
(:func:`specular_times`).
"""

from __future__ import annotations

import bisect
import logging
import math
from typing import NamedTuple

import numpy as np

from clbeam.model.svp import SoundSpeedProfile
from clbeam.seabed.forward import Interface, Layer, PowerLawAttenuation, water_column
from clbeam.seabed.forward import Seabed as LayeredSeabed
from clbeam.seabed.forward import specular_echoes as forward_echoes
from clbeam.sim.geometry import PingGeometry, Plane, seabed_z
from clbeam.sim.physics import reflection_coefficient
from clbeam.sim.propagation import Propagation
from clbeam.sim.rays import ray_legs, unfold
from clbeam.sim.render import Echoes
from clbeam.sim.scene import Scene

log = logging.getLogger(__name__)

WATER_DENSITY_KG_M3 = 1000.0
"""Density of the water above the seabed in the forward model (kg/m³); the
scene gives the sediment's and the sub-bottom's relative to it."""


class _Path(NamedTuple):
    """A specular path: its label, the planes it reflects at in turn and their
    names, the interfaces whose reflection it carries (0 the seabed, 1 the
    sub-bottom, once per reflection) and its sign (``-1`` per surface
    reflection, times 2 for the doublet's two equal paths)."""

    label: str
    planes: list
    names: list
    rows: tuple
    sign: float


def _paths(scene: Scene, seabed: Plane, surface: Plane) -> list[_Path]:
    """The specular paths the scene asks for."""
    sb, sub = scene.seabed, scene.subbottom
    paths = []
    if sb.specular:
        paths.append(_Path("seabed", [seabed], ["seabed"], (0,), 1.0))
    if sb.multiple:
        paths.append(_Path("multiple", [seabed, surface, seabed], ["seabed", "surface", "seabed"], (0, 0), -1.0))
    if sub is not None:
        # vertical thickness d, normal thickness d cos(slope)
        deep = seabed.shifted(sub.depth_below_seabed_m * seabed.n[2] / sb.sound_speed_ratio)
        if sub.specular:
            paths.append(_Path("subbottom", [deep], ["deep"], (1,), 1.0))
        if sb.multiple and sub.specular:
            paths.append(_Path("multiple-doublet", [seabed, surface, deep], ["seabed", "surface", "deep"],
                               (0, 1), -2.0))
            paths.append(_Path("multiple-subbottom", [deep, surface, deep], ["deep", "surface", "deep"],
                               (1, 1), -1.0))
    return paths


def specular_echoes(prop: Propagation, g: PingGeometry) -> list[Echoes]:
    """The image-source echoes of ping ``g``: seabed, sub-bottom, first multiple and its doublet.

    Parameters
    ----------
    prop : Propagation
        The scene's propagation (a scene with a seabed).
    g : PingGeometry
        The ping.

    Returns
    -------
    list of Echoes
        One set of one image source per path, amplitudes by
        ``seabed.specular_model``.
    """
    sc = prop.scene
    sb, sub = sc.seabed, sc.subbottom
    surface = Plane([0.0, 0.0, -sc.sonar.draft_m], [0.0, 0.0, 1.0])
    paths = _paths(sc, prop.seabed_plane(g), surface)
    if sb.specular_model == "forward":
        return [image_source(prop, g, p.label, p.planes, 1.0, response=_forward_factor(prop, p.rows, p.sign),
                             names=p.names) for p in paths]
    rho, nu = seabed_ratios(sc, g.along_m)
    v1 = float(reflection_coefficient(np.pi / 2, rho, nu))
    v = [v1]
    d = 0.0
    if sub is not None:
        z1 = rho * nu
        z2 = sub.density_ratio * sub.sound_speed_ratio
        v.append((z2 - z1) / (z2 + z1) * (1 - v1 * v1))
        d = sub.depth_below_seabed_m
    sets = []
    for p in paths:
        amp = p.sign
        for i in p.rows:
            amp = amp * v[i]
        path_m = 2 * d * p.rows.count(1)                    # two-way sediment path
        b = np.array([prop.alpha_np * path_m]) if path_m > 0 else None
        sets.append(image_source(prop, g, p.label, p.planes, amp, b_s=b, names=p.names))
    return sets


def seabed_ratios(scene: Scene, along_m: float) -> tuple[float, float]:
    """Density and sound-speed ratios of the seabed that reflects the nadir echoes of a ping ``along_m`` (m)
    along the track: the scene's, or with ``seabed.province_impedance`` the TR 9407 ratios of the grain size
    of the province there."""
    sb = scene.seabed
    if not sb.province_impedance:
        return sb.density_ratio, sb.sound_speed_ratio
    from clbeam.seabed.avo.sediment import density_ratio, sound_speed_ratio

    starts = [p.from_along_track_m for p in sb.province]
    mz = sb.province[max(bisect.bisect_right(starts, along_m) - 1, 0)].mz
    return density_ratio(mz), sound_speed_ratio(mz)


def nadir_reflection(scene: Scene, along_m: float) -> float:
    """The seabed's normal-incidence reflection coefficient under a ping ``along_m`` (m) along the track
    (impedance model, :func:`seabed_ratios`)."""
    return float(reflection_coefficient(np.pi / 2, *seabed_ratios(scene, along_m)))


def _forward_factor(prop: Propagation, rows: tuple, sign: float):
    """The spectral response ``f -> sign · prod V_i(f)`` of a path from the
    forward model's nadir factors (:func:`forward_specular_response`)."""
    so = prop.scene.sonar

    def response(f):
        # the model is evaluated within the band (the band window removes
        # everything more than 2 kHz outside it)
        r = forward_specular_response(prop.scene, prop.c_seabed,
                                      np.clip(f, 0.5 * so.pulse_f0_hz, 2.0 * so.pulse_f1_hz))
        out = sign * np.ones(len(f), dtype=complex)
        for i in rows:
            out = out * r[i]
        return out
    return response


def image_source(prop: Propagation, g: PingGeometry, label: str, planes: list, amp: float, *, b_s=None,
                 response=None, names=None) -> Echoes:
    """The echo of the source mirrored in ``planes`` in turn.

    Parameters
    ----------
    prop : Propagation
        The scene's propagation.
    g : PingGeometry
        The ping.
    label : str
        The echo set's label.
    planes : list of Plane
        The reflecting planes in turn.
    amp : float
        Amplitude (times ``response(f)``); the spreading is along the
        unfolded path.
    b_s : numpy.ndarray, optional
        Attenuation exponent ``(1,)`` (s).
    response : callable, optional
        Spectral response ``f_hz -> H(f)``.
    names : list of str, optional
        The planes' names (``"seabed"``, ``"surface"``, ``"deep"``), for the
        ray-traced times with a ``[water]`` profile (:func:`specular_times`).

    Returns
    -------
    Echoes
        One image source, or none when no unfolded ray reaches an element.
    """
    img = g.source.copy()
    for p in planes:
        img = p.mirror(img)
    rx = g.centre.copy()
    for p in reversed(planes):
        rx = p.mirror(rx)
    ray = rx - g.source
    u = float(ray @ g.column / np.linalg.norm(ray))
    e = Echoes(label=label, pos=img[None, :], amp=np.array([amp]), src_leg=np.zeros(1), spread=np.ones(1),
               extra_s=np.zeros(1), u=np.array([u]), b_s=b_s, response=response)
    if prop.svp is None or names is None:
        return e
    e.times_s = specular_times(prop, g, names, img)
    if not np.all(np.isfinite(e.times_s)):
        log.warning("%s echo: no direct unfolded ray to some element in ping %d; left out", label, g.index)
        return e.subset(np.zeros(1, dtype=bool))
    return e


def specular_times(prop: Propagation, g: PingGeometry, names: list[str], img: np.ndarray) -> np.ndarray:
    """Two-way times (s) ``(1, C)`` of an image-source path through the profile.

    ``names`` are the reflectors in turn (``"seabed"``, ``"surface"``,
    ``"deep"``: the sub-bottom), ``img`` the image source (m).  Flat seabed:
    the exact eigenray of the unfolded path
    (:func:`~clbeam.sim.rays.unfold`) from the source to each element.  A
    sloped seabed: the straight image-source time at the transducers' speed
    plus the profile's correction of the same path with flat reflectors at
    the nadir depths (vertical, source to array centre).
    """
    sc, sb = prop.scene, prop.scene.seabed
    z_sb = float(seabed_z(sc, g.along_m, 0.0))
    d = sc.subbottom.depth_below_seabed_m if sc.subbottom is not None else 0.0
    depth = {"seabed": z_sb, "surface": -sc.sonar.draft_m, "deep": z_sb + d}

    def unfolded_times(medium, turns, ends):
        unf, s_last, z_last = unfold(medium, turns)
        e = np.array(ends, dtype=np.float64)
        e[:, 2] = s_last + (z_last - e[:, 2])
        return ray_legs(unf, g.source[None, :], e, directions=False)["time_s"][0]

    turns = [depth[n] for n in names]
    if prop.svp_sediment is not None:
        return unfolded_times(prop.svp_sediment, turns, g.elements)[None, :]
    t_prof = unfolded_times(prop.with_sediment(z_sb), turns, g.centre[None, :])[0]
    equiv = {**depth, "deep": z_sb + d / sb.sound_speed_ratio}    # the isospeed model's equivalent plane
    t_iso = unfolded_times(SoundSpeedProfile.constant(prop.c), [equiv[n] for n in names], g.centre[None, :])[0]
    straight = np.linalg.norm(g.elements - img, axis=1) / prop.c
    return (straight + (t_prof - t_iso))[None, :]


def forward_seabed(scene: Scene, sound_speed_water_m_s: float, water_m: float = 1.0):
    """The scene's seabed as a :class:`clbeam.seabed.forward.Seabed`.

    Parameters
    ----------
    scene : Scene
        A scene with a seabed.
    sound_speed_water_m_s : float
        The water's speed at the seabed (m/s); the sediment's and the
        sub-bottom's are their ratios times it.
    water_m : float
        Thickness of the (lossless) water layer on top (m).

    Returns
    -------
    clbeam.seabed.forward.Seabed
        Water, the sediment (its speed, density, linear attenuation and the
        seabed roughness) down to the sub-bottom, and the half-space below
        (or the sediment as the half-space).
    """
    # imported on use: scenes with impedance-contrast echoes need not load the forward model
    sb, sub = scene.seabed, scene.subbottom
    rho_w = WATER_DENSITY_KG_M3
    k_p = sb.attenuation_db_per_m / (sb.attenuation_ref_hz / 1000.0)  # dB/m/kHz, linear law
    c_w = sound_speed_water_m_s
    sediment = dict(sound_speed_m_s=sb.sound_speed_ratio * c_w, density_kg_m3=sb.density_ratio * rho_w,
                    attenuation=PowerLawAttenuation(k_p, 1.0), top=Interface(roughness_m=sb.roughness_m),
                    name="sediment")
    layers = [water_column(water_m, sound_speed_m_s=c_w, density_kg_m3=rho_w)]
    if sub is None:
        layers.append(Layer(math.inf, **sediment))
    else:
        layers.append(Layer(sub.depth_below_seabed_m, **sediment))
        layers.append(Layer(math.inf, sub.sound_speed_ratio * c_w, sub.density_ratio * rho_w,
                            top=Interface(roughness_m=sub.roughness_m), name="subbottom"))
    return LayeredSeabed(tuple(layers), name=scene.name)


def forward_specular_response(scene: Scene, sound_speed_water_m_s: float, f_hz) -> np.ndarray:
    """Nadir echo factors of the forward model, without spreading or delay.

    Parameters
    ----------
    scene : Scene
        A scene with a seabed.
    sound_speed_water_m_s : float
        The water's speed at the seabed (m/s).
    f_hz : array_like
        Frequencies (Hz).

    Returns
    -------
    numpy.ndarray
        ``(n_echo, n_freq)`` complex ``V_i prod(T T') prod(H^2)`` of the
        seabed (row 0) and the sub-bottom (row 1)
        (:func:`clbeam.seabed.forward.specular_echoes` at normal incidence).
    """
    seabed = forward_seabed(scene, sound_speed_water_m_s)
    e = forward_echoes(seabed, np.asarray(f_hz, dtype=np.float64), incidence_deg=0.0)
    return e.reflection * e.transmission * e.attenuation
