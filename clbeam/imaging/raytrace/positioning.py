"""Where an isospeed image puts a target seen through a stratified medium."""

from __future__ import annotations

import math
from dataclasses import dataclass

from clbeam.errors import GeometryError, OptionError, require
from clbeam.imaging.raytrace.rays import eigenrays
from clbeam.model.svp import SoundSpeedProfile


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
