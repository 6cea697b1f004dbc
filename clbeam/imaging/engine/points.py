"""The delay-and-sum at a list of points instead of a grid.

A point is a cell with its own travel-time table entry: the one-way time
from the grid centre, its ray's launch direction, length and wavefront radius.  The
engine images ``n`` points as a grid of ``n`` angles and one range whose
tables hold them, so every backend, mode and precision runs them unchanged.
The beam-sampled imaging images its flagged cells this way (a few thousand
cells scattered over the whole grid), the peak refinement its local grids.
"""

from __future__ import annotations

import numpy as np

from clbeam.imaging.raytrace.tables import TravelTimeTables
from clbeam.model.grid import PolarGrid


def point_grid(n_points: int) -> PolarGrid:
    """The grid of ``n_points`` points: one range, an angle per point (its values are not used: the tables hold
    the points)."""
    return PolarGrid(np.array([1.0]), np.linspace(-90.0, 90.0, n_points + 1)[:-1])


def straight_ray_values(ranges_m: np.ndarray, angles_deg: np.ndarray, sound_speed_m_s: float) -> dict:
    """Table values of points along straight rays at ``sound_speed_m_s`` (m/s): one-way time (s), launch
    direction and wavefront radius (m), each shaped like ``ranges_m``."""
    th = np.deg2rad(angles_deg)
    return {"time_s": ranges_m / sound_speed_m_s, "launch_sin": np.sin(th), "launch_cos": np.cos(th),
            "wavefront_radius_m": ranges_m}


def point_tables(values: dict, centre_speed_m_s: float, centre_depth_m: float, points: PolarGrid) -> TravelTimeTables:
    """The travel-time tables of ``points`` (:func:`point_grid`) from per-point values (as
    :func:`straight_ray_values`, ``path_length_m`` optional: the wavefront radius when not given, which it is
    along a straight ray; NaN time where no ray reaches)."""
    col = {k: np.asarray(v, dtype=np.float64).reshape(-1, 1) for k, v in values.items()}
    return TravelTimeTables(time_s=col["time_s"], launch_sin=col["launch_sin"], launch_cos=col["launch_cos"],
                            path_length_m=col.get("path_length_m", col["wavefront_radius_m"]),
                            wavefront_radius_m=col["wavefront_radius_m"],
                            reachable=np.isfinite(col["time_s"]), centre_speed_m_s=centre_speed_m_s,
                            centre_depth_m=centre_depth_m, grid=points)


def node_tables(inp, grid: PolarGrid, rows: np.ndarray, cols: np.ndarray) -> TravelTimeTables:
    """The tables of the cells ``(rows[k], cols[k])`` of ``grid`` as points: the grid's own tables at those
    cells (``inp.tables`` or ``inp.table_source``), else straight rays at ``inp.sound_speed_m_s``."""
    points = point_grid(rows.size)
    tables = inp.for_grid(grid).tables
    if tables is None:
        values = straight_ray_values(grid.ranges_m[cols], grid.angles_deg[rows], inp.sound_speed_m_s)
        return point_tables(values, inp.sound_speed_m_s, 0.0, points)
    values = {name: getattr(tables, name)[rows, cols]
              for name in ("time_s", "launch_sin", "launch_cos", "path_length_m", "wavefront_radius_m")}
    return point_tables(values, tables.centre_speed_m_s, tables.centre_depth_m, points)


def bilinear_tables(tables, grid: PolarGrid, ranges_m: np.ndarray, angles_deg: np.ndarray,
                    names=("time_s", "launch_sin", "launch_cos", "wavefront_radius_m")) -> dict:
    """The travel-time tables of ``grid`` interpolated to points (NaN where a corner is unreachable): the
    fields ``names`` (the launch direction, when both its parts are asked for, normalised)."""
    ia, ta = _lower_node(grid.angles_deg, angles_deg)
    ir, tr = _lower_node(grid.ranges_m, ranges_m)
    n_r = grid.shape[1]
    ia1 = np.minimum(ia + 1, grid.shape[0] - 1)
    ir1 = np.minimum(ir + 1, n_r - 1)
    # the four corners' flat indices and weights, once for every field
    corner = [(ia * n_r + ir, (1 - ta) * (1 - tr)), (ia * n_r + ir1, (1 - ta) * tr),
              (ia1 * n_r + ir, ta * (1 - tr)), (ia1 * n_r + ir1, ta * tr)]
    out = {}
    for name in names:
        v = np.asarray(getattr(tables, name)).reshape(-1)
        value = np.asarray(sum(v[index] * weight for index, weight in corner), dtype=np.float64)
        bad = ~np.isfinite(value)
        if bad.any():  # a corner without weight (an unreachable one on a node) does not poison the point
            value[bad] = sum(np.where(weight[bad] == 0, 0.0, v[index[bad]] * weight[bad]) for index, weight in corner)
        out[name] = value
    if "launch_sin" in out and "launch_cos" in out:
        # the launch direction is a unit vector (the kernels' path formula relies on it): interpolate, then normalise
        norm = np.hypot(out["launch_sin"], out["launch_cos"])
        out["launch_sin"], out["launch_cos"] = out["launch_sin"] / norm, out["launch_cos"] / norm
    return out


def _lower_node(axis: np.ndarray, x: np.ndarray) -> tuple:
    """Index of the last node of the increasing ``axis`` below each ``x`` (``searchsorted(axis, x) - 1``, clipped
    to the first and the last interval) and the fraction of its interval ``x`` lies at.  On an evenly spaced axis
    the index is guessed from the spacing and corrected by one node where rounding put it off: a refinement's
    hundreds of thousands of points took a binary search each."""
    x = np.asarray(x, dtype=np.float64)
    n = axis.size
    if n < 2:
        return np.zeros(x.shape, dtype=np.int64), np.zeros(x.shape)
    step = (axis[-1] - axis[0]) / (n - 1)
    if step > 0 and np.allclose(np.diff(axis), step, rtol=1e-6, atol=0.0):
        with np.errstate(invalid="ignore"):
            guess = np.floor((x - axis[0]) / step)
        i = np.clip(np.nan_to_num(guess, nan=0.0), 0, n - 1).astype(np.int64)
        i -= axis[i] >= x                                   # searchsorted(left) - 1: the last node strictly below
        i += (i + 1 < n) & (axis[np.minimum(i + 1, n - 1)] < x)
    else:
        i = np.searchsorted(axis, x) - 1
    i = np.clip(i, 0, n - 2)
    return i, (x - axis[i]) / (axis[i + 1] - axis[i])
