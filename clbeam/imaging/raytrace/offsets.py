"""Per-element (offset) travel times: approximate from the tables, and exact.

:func:`offset_time_approx` is ``T + d(o) / c0`` with the cancellation-free
offset delay :func:`offset_delay_m`, what a delay-and-sum kernel can use
with :class:`~clbeam.imaging.raytrace.TravelTimeTables`;
:func:`offset_time_exact` and :func:`element_travel_times` solve an eigenray
per element and cell (``docs/raytrace.md`` compares them).
"""

from __future__ import annotations

import numpy as np

from clbeam.errors import GeometryError, OptionError, require
from clbeam.imaging.raytrace.rays import eigen_fields
from clbeam.imaging.raytrace.tables import TravelTimeTables
from clbeam.model.grid import PolarGrid
from clbeam.model.svp import SoundSpeedProfile


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
    return eigen_fields(profile, za, dy, zb, ("time_s",), workers)["time_s"]


def _yz_array(values, name: str) -> np.ndarray:
    a = np.asarray(values, dtype=np.float64)
    require(a.ndim == 2 and a.shape[1] == 2, GeometryError,
            f"{name} must be (n, 2) as (y, z) in m, got shape {a.shape}")
    require(bool(np.all(np.isfinite(a))), GeometryError, f"{name} have non-finite coordinates")
    return a
