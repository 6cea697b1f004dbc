"""The truth of a simulation: where the targets are and where an imager should show them.

For each ping and target, :func:`ping_truth` gives the target's position in
the ping's earth frame (lines where they cross the image plane ``x = 0``)
and where a 2-D imager puts the echo of its point nearest the source
(:func:`image_position`: same range and cone angle; buried targets appear
later and refracted; with a ``[water]`` profile, where an imager tracing
rays through it shows the echo).  :func:`truth_dataset` stores them as the
``truth_*`` variables of a simulated ping file, for scoring detections.
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from clbeam.sim.geometry import PingGeometry, seabed_z
from clbeam.sim.propagation import Propagation
from clbeam.sim.rays import ray_point
from clbeam.sim.scene import PointTarget
from clbeam.sim.targets import line_crossing, target_world

TRUTH_VARIABLES = {
    "x": ("m", "target along-track offset from the image plane (0 for lines)"),
    "y": ("m", "target horizontal range, earth frame, starboard positive"),
    "z": ("m", "target depth below the transducers' mean depth"),
    "angle": ("degree", "line heading relative to the track at the image plane"),
    "seabed_z": ("m", "seabed depth above the target"),
    "image_y": ("m", "expected image y of the echo (nearest point, same range and cone angle)"),
    "image_z": ("m", "expected image z of the echo (nearest point, same range and cone angle)"),
    "u": ("1", "along-track direction cosine of the target's nearest point"),
}
"""Per-target truth of :func:`ping_truth`, stored as ``truth_target_<key>``: units and long name."""
TRUTH_KEYS = tuple(TRUTH_VARIABLES)


def _array_axes(g: PingGeometry) -> tuple[np.ndarray, np.ndarray]:
    """The (rolled) receive-array axis and the image plane's down direction perpendicular to it."""
    phi = math.radians(g.roll_deg)
    return np.array([0.0, math.cos(phi), math.sin(phi)]), np.array([0.0, -math.sin(phi), math.cos(phi)])


def image_position(g: PingGeometry, r: np.ndarray, *, extra_m: float = 0.0,
                   rx_tilt: np.ndarray | None = None) -> tuple[float, float]:
    """Where a 2-D straight-ray imager puts an echo from ``r`` (earth frame, m).

    The point of the plane ``x = 0`` at the echo's apparent range from the
    source and apparent direction cosine on the (rolled) receive-array
    axis.  For an echo in the water these are ``|r - s|`` and the straight
    ray's direction.  A buried echo arrives later and from a slightly
    different direction (refraction at the seabed,
    :meth:`~clbeam.sim.propagation.Propagation.buried`).

    Parameters
    ----------
    g : PingGeometry
        The ping.
    r : array_like
        Scatterer position ``(3,)``, earth frame (m).
    extra_m : float
        One-way range added by refraction (m): half the refraction delay
        times the water sound speed.
    rx_tilt : array_like, optional
        Refracted minus straight unit ray direction at the array ``(3,)``.

    Returns
    -------
    (float, float)
        ``(y, z)`` of the image point, earth frame (m).
    """
    q = np.asarray(r, dtype=np.float64) - g.source
    dist = float(np.linalg.norm(q))
    rng = dist + extra_m
    ray = q / max(dist, 1e-12)
    if rx_tilt is not None:
        ray = ray + np.asarray(rx_tilt, dtype=np.float64)
        ray /= np.linalg.norm(ray)
    axis, down = _array_axes(g)
    along = rng * float(ray @ axis)
    p = g.source + along * axis + math.sqrt(max(rng * rng - along * along, 0.0)) * down
    return float(p[1]), float(p[2])


def ping_truth(prop: Propagation, g: PingGeometry, lines: list) -> dict:
    """Target positions in the earth frame of ping ``g`` and the seabed depth.

    Parameters
    ----------
    prop : Propagation
        The scene's paths: straight with Snell refraction, or ray traced.
    g : PingGeometry
        The ping, whose earth frame the positions are in.
    lines : list
        Per target, the line's points (:func:`~clbeam.sim.targets.line_points`)
        or ``None`` for a point target.

    Returns
    -------
    dict
        ``target``: per key of :data:`TRUTH_VARIABLES` an array over the
        targets.  ``x, y, z``: lines where they cross the image plane
        ``x = 0``, points where they are; ``z`` is below the transducers'
        mean depth (heave is in the source and element positions, not in the
        frame) (m).  ``image_y, image_z``: where the imager should show the
        echo, from the point of the target nearest the source (of a line
        under the discrete physics, from its crossing: its scatterers'
        echoes are incoherent, with no specular point)
        (:func:`image_position`; with a sound-speed profile, where an imager
        using that profile shows it) (m).  ``u``: that point's direction
        cosine on the transmit column (the beam's −3 dB half-width is about
        0.02 at 9 kHz, 0.09 at 2 kHz).  ``seabed_z``: the seabed depth at
        nadir (m; NaN without a seabed).
    """
    sc = prop.scene
    n = len(sc.targets)
    out = {k: np.full(n, np.nan) for k in TRUTH_KEYS}
    for k, (t, pts) in enumerate(zip(sc.targets, lines)):
        if isinstance(t, PointTarget):
            x, y, z = target_world(sc, t)
            out["x"][k], out["y"][k], out["z"][k] = x - g.along_m, y, z
            nearest = np.array([x - g.along_m, y, z])
        else:
            y, z, ang = line_crossing(sc, t, g.along_m)
            if t.gap_x_m and t.gap_x_m[0] <= g.along_m <= t.gap_x_m[1] or not len(pts["x"]):
                continue  # no pipe crosses this ping's plane: NaN
            out["x"][k], out["y"][k], out["z"][k], out["angle"][k] = 0.0, y, z, ang
            if sc.model.physics == "discrete":  # an incoherent pipe's echo is centred on its crossing
                nearest = np.array([0.0, y, z])
            else:
                rel = np.stack([pts["x"] - g.along_m, pts["y"], pts["z"]], axis=1) - g.source
                nearest = rel[np.argmin(np.einsum("ij,ij->i", rel, rel))] + g.source
        if prop.svp is not None:
            out["image_y"][k], out["image_z"][k], out["u"][k] = _traced_image(prop, g, t, nearest)
        else:
            out["image_y"][k], out["image_z"][k], out["u"][k] = _straight_image(prop, g, t, nearest)
        if sc.seabed is not None and np.isfinite(out["y"][k]):
            out["seabed_z"][k] = float(seabed_z(sc, g.along_m + out["x"][k], out["y"][k]))
    seabed = float(seabed_z(sc, g.along_m, 0.0)) if sc.seabed is not None else np.nan
    return {"target": out, "seabed_z": seabed}


def _straight_image(prop: Propagation, g: PingGeometry, t, nearest: np.ndarray) -> tuple[float, float, float]:
    """``(image_y, image_z, u)`` of a target's nearest point, straight rays."""
    refraction = {}
    if t.burial_m is not None:
        # the apparent position: the refracted echo arrives later and from
        # the refracted ray's direction at the array
        bur = prop.buried(g, nearest[None, :], np.array([t.burial_m]), np.array([nearest[2] - t.burial_m]))
        refraction = {"extra_m": 0.5 * prop.c * float(bur["extra_s"][0]), "rx_tilt": bur["rx_tilt"][0]}
    image_y, image_z = image_position(g, nearest, **refraction)
    return image_y, image_z, float(prop.direction_cosine(g, nearest[None, :])[1][0])


def _traced_image(prop: Propagation, g: PingGeometry, t, nearest: np.ndarray) -> tuple[float, float, float]:
    """``(image_y, image_z, u)`` of a target's nearest point with a profile.

    Where a 2-D imager that traces rays through the same profile (and
    the same sediment below the seabed) shows the echo: the point of the
    plane ``x = 0`` at the echo's travel time from the source along the
    ray whose launch direction has the echo's direction cosine on the
    (rolled) receive-array axis (:func:`image_position`'s range and cone
    angle, ray traced).  A scatterer in the plane is shown where it is.
    ``u`` is the launch direction's cosine on the transmit column.
    """
    buried = t.burial_m is not None
    zsb = np.array([nearest[2] - t.burial_m]) if buried else None
    src = prop.source_rays(g, nearest[None, :], buried=buried, seabed_z_m=zsb)
    u = float(src["u"][0])
    if not math.isfinite(u):
        return math.nan, math.nan, math.nan
    axis, down = _array_axes(g)
    kappa = float(np.clip(src["launch"][0] @ axis, -1.0, 1.0))
    d = kappa * axis + math.sqrt(1.0 - kappa * kappa) * down     # launch direction in the plane
    medium = prop.medium(buried=buried, seabed_z_m=float(zsb[0]) if buried else None)
    dy, z = ray_point(medium, float(g.source[2]), float(d[1]), float(src["time_s"][0]))
    return float(g.source[1]) + dy, z, u


def truth_dataset(truth: list, *, target_names: list[str], pings: np.ndarray, noise_std: float,
                  province_mz: np.ndarray | None = None, nadir_reflection: np.ndarray | None = None) -> xr.Dataset:
    """The truth of the prepared pings as dataset variables.

    Parameters
    ----------
    truth : list of dict
        :func:`ping_truth` of each ping.
    target_names : list of str
        The targets' names.
    pings : numpy.ndarray
        The ping indices.
    noise_std : float
        Standard deviation of the added noise per sample.
    province_mz : numpy.ndarray, optional
        Grain size (phi) of the seabed province under the ship per ping.
    nadir_reflection : numpy.ndarray, optional
        The seabed's normal-incidence reflection coefficient under the ship per ping.

    Returns
    -------
    xarray.Dataset
        ``truth_target_<key>(ping, target)`` (:data:`TRUTH_VARIABLES`),
        ``truth_seabed_z(ping)``, ``noise_std`` and, with provinces,
        ``truth_province_mz(ping)`` and ``truth_nadir_reflection(ping)``; earth frame, units in the attributes.
    """
    n_t = len(target_names)
    tt = {k: np.array([tr["target"][k] for tr in truth], dtype=np.float64).reshape(len(truth), n_t)
          for k in TRUTH_KEYS}
    data = {f"truth_target_{k}": (("ping", "target"), tt[k], {"units": units, "long_name": long_name})
            for k, (units, long_name) in TRUTH_VARIABLES.items()}
    data["truth_seabed_z"] = (("ping",), np.array([tr["seabed_z"] for tr in truth], dtype=np.float64),
                              {"units": "m", "long_name": "seabed depth at nadir below the transducers' mean depth"})
    data["noise_std"] = ((), noise_std, {"units": "1", "long_name": "standard deviation of the added noise per sample"})
    if province_mz is not None:
        data["truth_province_mz"] = (("ping",), province_mz, {"units": "phi", "long_name":
                                                              "grain size of the seabed province under the ship"})
    if nadir_reflection is not None:
        data["truth_nadir_reflection"] = (("ping",), nadir_reflection, {
            "units": "1", "long_name": "normal-incidence reflection coefficient of the seabed under the ship"})
    coords = {"ping": ("ping", pings),
              "target": ("target", np.array(target_names, dtype=object), {"long_name": "target name"})}
    return xr.Dataset(data, coords=coords)
