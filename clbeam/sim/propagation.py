"""How the sound of one scene travels: transmit beam reach, straight or ray-traced paths, echo sets.

:class:`Propagation` holds what every synthesiser (targets, seabed fields,
specular paths, truth) needs about a scene's medium and beam, computed
once: the sound speeds and the ``[water]`` profile, the along-track
transmit beam's cut, taper and importance envelope, the sediment's
attenuation, and the record's reach.  For a scatterer it gives the straight
source leg and direction cosine, the Snell refraction of buried points
(isospeed water), or the ray-traced legs through the profile; and it wraps
scatterers into :class:`~clbeam.sim.render.Echoes` sets ready to render.

A composed object rather than a base class of the simulator: the
synthesisers are plain functions of a :class:`Propagation`, so each reads
what it uses from one place.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from clbeam.model.svp import SoundSpeedProfile
from clbeam.sim.geometry import PingGeometry, Plane, seabed_z
from clbeam.sim.physics import attenuation_np_per_m_hz, reflection_coefficient, refracted_path
from clbeam.sim.rays import ray_legs, seabed_ray_legs
from clbeam.sim.render import Echoes
from clbeam.sim.scene import Scene

log = logging.getLogger(__name__)


class Propagation:
    """Sound paths and transmit beam of a scene.

    Parameters
    ----------
    scene : Scene
        The scene.
    max_range_m : float
        Largest one-way slant range recorded (m).

    Attributes
    ----------
    c : float
        Sound speed at the transducers (m/s): ``sound_speed_m_s``, or the
        ``[water]`` profile's speed at ``z = 0``.
    c_min : float
        Slowest speed of the profile (m/s; record length, pipeline point
        spacing); isospeed: ``c``.
    c_seabed : float
        Water speed at the seabed under the first ping (m/s); the sediment's
        speed is ``sound_speed_ratio`` times it.  Isospeed: ``c``.
    svp : SoundSpeedProfile or None
        The water profile; ``None``: isospeed, straight rays.
    svp_sediment : SoundSpeedProfile or None
        ``svp`` cut at a flat seabed with the sediment's speed below
        (``None`` without a seabed or with a sloped one).
    fc : float
        Band centre frequency (Hz).
    alpha_np : float
        Sediment attenuation slope ``α / f`` (Np m⁻¹ Hz⁻¹; 0 without a seabed).
    u_cut, u_flat : float
        Along-track direction cosines: scatterers beyond ``u_cut`` are left
        out; amplitudes taper from ``u_flat`` to ``u_cut``.
    max_range_m : float
        Largest one-way slant range recorded (m).
    x_ext_m : float
        Along-track reach of the beam at ``max_range_m`` (m).
    """

    def __init__(self, scene: Scene, *, max_range_m: float):
        self.scene = scene
        so = scene.sonar
        self.c = scene.sound_speed_m_s
        self._setup_profile()
        self.fc = so.centre_frequency_hz
        self.alpha_np = attenuation_np_per_m_hz(scene.seabed) if scene.seabed is not None else 0.0
        wl_f0 = self.c / so.pulse_f0_hz
        self.u_cut = min(scene.model.tx_beam_cut * wl_f0 / so.tx_length_m, 0.5)
        self.u_flat = 0.75 * self.u_cut
        self.envelope_u, self.envelope_weight = self._beam_envelope()
        self.max_range_m = max_range_m
        self.x_ext_m = max_range_m * self.u_cut / math.sqrt(1 - self.u_cut ** 2)

    def _setup_profile(self) -> None:
        """Sound speeds and the ``[water]`` profile, if any (see the class attributes)."""
        sc = self.scene
        self.svp = self.svp_sediment = None
        self.c_min = self.c_seabed = self.c
        if sc.water is None:
            return
        self.svp = sc.water.profile()
        self.c = float(self.svp.speed(0.0))
        self.c_min = float(np.min(self.svp.speeds_m_s))
        sb = sc.seabed
        if sb is not None:
            z_sb = sb.depth_m - sc.sonar.draft_m
            self.c_seabed = float(self.svp.speed(z_sb, side="above"))
            if sb.slope_along_deg == 0 and sb.slope_across_deg == 0:
                self.svp_sediment = self.with_sediment(z_sb)

    def with_sediment(self, seabed_z_m: float) -> SoundSpeedProfile:
        """The water profile cut at a flat seabed at ``seabed_z_m`` (m) with
        the sediment below: ``sound_speed_ratio`` times the water's speed there."""
        return SoundSpeedProfile.with_sediment(self.svp, seabed_z_m, self.scene.seabed.sound_speed_ratio
                                               * float(self.svp.speed(seabed_z_m, side="above")))

    # -- the transmit beam ---------------------------------------------------------
    def _beam_envelope(self) -> tuple[np.ndarray, np.ndarray]:
        """Band-averaged transmit beam energy against ``u`` (1 on axis), floored
        at 0.1: the importance weight of the random seabed scatterers."""
        so = self.scene.sonar
        u = np.linspace(0, self.u_cut, 257)
        f = np.linspace(so.pulse_f0_hz, so.pulse_f1_hz, 64)
        energy = np.mean(np.sinc(so.tx_length_m * np.outer(u, f) / self.c) ** 2, axis=1)
        return u, np.maximum(energy / energy[0], 0.1)

    def envelope(self, u: np.ndarray) -> np.ndarray:
        """Importance weight (1 on axis) of a random scatterer at direction cosine ``u``."""
        return np.interp(np.abs(u), self.envelope_u, self.envelope_weight, right=0.0)

    def taper(self, u: np.ndarray) -> np.ndarray:
        """Cull window on ``|u|``: 1 up to ``0.75 u_cut``, cosine to 0 at ``u_cut``."""
        a = np.abs(u)
        x = np.clip((a - self.u_flat) / (self.u_cut - self.u_flat), 0.0, 1.0)
        return 0.5 * (1 + np.cos(np.pi * x))

    # -- straight rays (isospeed) --------------------------------------------------
    def seabed_plane(self, g: PingGeometry) -> Plane:
        """The seabed as a plane in the earth frame of ping ``g``."""
        sb = self.scene.seabed
        gx = math.tan(math.radians(sb.slope_along_deg))
        gy = math.tan(math.radians(sb.slope_across_deg))
        return Plane([0.0, 0.0, float(seabed_z(self.scene, g.along_m, 0.0))], [-gx, -gy, 1.0])

    @staticmethod
    def direction_cosine(g: PingGeometry, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(|r - s|, u)``: straight source distance (m) and direction cosine
        on the transmit column of positions ``(S, 3)``."""
        rel = pos - g.source
        dist = np.sqrt(np.einsum("ij,ij->i", rel, rel))
        return dist, (rel @ g.column) / np.maximum(dist, 1e-12)

    def buried(self, g: PingGeometry, pos: np.ndarray, depth_below_m: np.ndarray, seabed_z_m: np.ndarray) -> dict:
        """Refraction of buried points ``pos`` ``(S, 3)``, ``depth_below_m`` under
        a locally flat seabed at ``seabed_z_m`` (m), isospeed water (Snell).

        Returns
        -------
        dict
            ``extra_s`` the two-way refraction delay (s), ``b_s`` the
            attenuation exponent (s), ``transmission`` the two-way
            ``1 - V²``, ``grazing_sediment_rad``, ``path_m`` the two-way
            in-sediment path and ``rx_tilt`` the refracted minus the straight
            ray direction at the array centre ``(S, 3)``.
        """
        sb = self.scene.seabed
        legs = []
        for end in (g.source, g.centre):
            rho = np.hypot(pos[:, 0] - end[0], pos[:, 1] - end[1])
            legs.append((refracted_path(rho, seabed_z_m - end[2], depth_below_m, sb.sound_speed_ratio),
                         np.sqrt(np.sum((pos - end) ** 2, axis=1))))
        extra = sum(leg["time_factor_m"] - straight for leg, straight in legs) / self.c
        path = sum(leg["sediment_m"] for leg, _ in legs)
        v = reflection_coefficient(legs[0][0]["grazing_water_rad"], sb.density_ratio, sb.sound_speed_ratio)
        # ray directions at the array centre: refracted (it arrives from the
        # crossing point of the interface) and straight
        rel = pos - g.centre
        horiz = np.hypot(rel[:, 0], rel[:, 1])
        graz = legs[1][0]["grazing_water_rad"]
        scale = np.cos(graz) / np.maximum(horiz, 1e-12)
        ray = np.stack([rel[:, 0] * scale, rel[:, 1] * scale, np.sin(graz)], axis=1)
        tilt = ray - rel / legs[1][1][:, None]
        return {"extra_s": extra, "b_s": self.alpha_np * path, "transmission": 1 - v * v,
                "grazing_sediment_rad": legs[0][0]["grazing_sediment_rad"], "path_m": path, "rx_tilt": tilt}

    def scatterers(self, label: str, g: PingGeometry, pos: np.ndarray, amp: np.ndarray, **kw) -> Echoes:
        """An echo set of scatterers ``pos`` ``(S, 3)`` with amplitudes ``amp``
        (m) on straight rays; ``kw`` are further :class:`Echoes` fields."""
        dist, u = self.direction_cosine(g, pos)
        return Echoes(label=label, pos=pos, amp=amp * self.taper(u), src_leg=dist, spread=dist,
                      extra_s=kw.pop("extra_s", np.zeros(len(amp))), u=u, **kw)

    # -- rays through the profile --------------------------------------------------
    def medium(self, *, buried: bool, seabed_z_m: float | None = None) -> SoundSpeedProfile:
        """The profile a ray to a point in the water (or, ``buried``, below a
        flat seabed at ``seabed_z_m``) crosses."""
        if not buried:
            return self.svp
        if self.svp_sediment is not None:
            return self.svp_sediment
        return self.with_sediment(seabed_z_m)

    def legs(self, ends: np.ndarray, pos: np.ndarray, *, buried: bool = False, seabed_z_m=None,
             directions: bool = True) -> dict:
        """Ray-traced legs between ``ends`` ``(P, 3)`` and scatterers ``pos``
        ``(S, 3)`` (:func:`~clbeam.sim.rays.ray_legs`): through the water
        profile, or for ``buried`` scatterers (below the seabed at depths
        ``seabed_z_m`` ``(S,)``) through the profile with the sediment below a
        flat seabed, or past a locally flat seabed at ``seabed_z_m`` when it
        is sloped (:func:`~clbeam.sim.rays.seabed_ray_legs`)."""
        if not buried:
            return ray_legs(self.svp, ends, pos, directions=directions)
        if self.svp_sediment is not None:
            return ray_legs(self.svp_sediment, ends, pos, directions=directions)
        zs = np.asarray(seabed_z_m, dtype=np.float64)
        c_s = self.scene.seabed.sound_speed_ratio * self.svp.speed(zs, side="above")
        return seabed_ray_legs(self.svp, ends, pos, zs, c_s, directions=directions)

    def source_rays(self, g: PingGeometry, pos: np.ndarray, **kw) -> dict:
        """Ray-traced source legs of scatterers ``pos`` ``(S, 3)``: ``time_s``,
        ``p``, ``launch`` (direction leaving the source), ``arrival`` (at the
        scatterer) and ``u``, the launch direction's cosine on the transmit
        column (the transmit beam sees the ray's launch direction); ``kw`` as
        :meth:`legs`."""
        r = {k: v[0] for k, v in self.legs(g.source[None, :], pos, **kw).items()}
        r["launch"], r["arrival"] = r.pop("end_dir"), r.pop("pos_dir")
        r["u"] = r["launch"] @ g.column
        return r

    def buried_rays(self, g: PingGeometry, pos: np.ndarray, seabed_z_m: np.ndarray, src: dict) -> dict:
        """In-sediment path (m), attenuation exponent (s) and transmission of
        buried scatterers from their ray-traced legs (the source's ``src`` and
        the array centre's), as :meth:`buried` does with Snell rays from
        straight water paths."""
        sb = self.scene.seabed
        b = np.maximum(pos[:, 2] - seabed_z_m, 0.0)
        cos_c = self.legs(g.centre[None, :], pos, buried=True, seabed_z_m=seabed_z_m)["pos_dir"][0, :, 2]
        cos_s = src["arrival"][:, 2]
        path = b / cos_s + b / cos_c
        sin_w = np.clip(src["p"] * self.svp.speed(seabed_z_m, side="above"), 0.0, 1.0)
        v = reflection_coefficient(np.arccos(sin_w), sb.density_ratio, sb.sound_speed_ratio)
        return {"b_s": self.alpha_np * path, "transmission": 1 - v * v, "path_m": path,
                "grazing_sediment_rad": np.arcsin(np.clip(cos_s, 0.0, 1.0))}

    def traced_echoes(self, label: str, g: PingGeometry, pos: np.ndarray, amp: np.ndarray, src: dict, *,
                      buried: bool = False, seabed_z_m=None, b_s=None, response=None) -> Echoes:
        """An echo set whose two-way times are ray traced: the source leg
        ``src`` (:meth:`source_rays`) plus each element's leg.  Scatterers
        that a direct ray does not reach (from the source or any element) are
        dropped.  Spreading stays ``1 / (|r - s| |r - e_n|)`` on the straight
        distances."""
        rx = self.legs(g.elements, pos, buried=buried, seabed_z_m=seabed_z_m, directions=False)["time_s"]
        times = src["time_s"][:, None] + rx.T
        ok = np.all(np.isfinite(times), axis=1) & np.isfinite(amp) & np.isfinite(src["u"])
        if b_s is not None:
            ok &= np.isfinite(b_s)
        if not ok.all():
            log.info("%s: %d of %d scatterers have no direct ray to the source or an element; dropped",
                     label, int((~ok).sum()), ok.size)
        dist = np.linalg.norm(pos - g.source, axis=1)
        u = src["u"]
        return Echoes(label=label, pos=pos[ok], amp=(amp * self.taper(u))[ok], src_leg=dist[ok], spread=dist[ok],
                      extra_s=np.zeros(int(ok.sum())), u=u[ok], b_s=None if b_s is None else b_s[ok],
                      response=response, times_s=times[ok])
