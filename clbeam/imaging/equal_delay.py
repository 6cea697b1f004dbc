"""Equal-delay curves through ray-traced travel-time tables: where a point's echo lies at other angles.

The sub-cell refinement (:mod:`clbeam.imaging.subcell`) searches an echo's maximum along the curve of
cells with the echo's delay.  In isospeed water that curve is the grid's arc of constant range, moved
by the source's and the array's offsets from the grid centre (:class:`EqualDelay`).
Through a sound-speed profile the centre's one-way time ``T(R, theta)`` changes along the arc too:
``dT/dtheta = R sin(phi_c - theta) / c(z)`` at fixed ``R``, ``phi_c`` the ray's direction at the cell,
which under a 60 m/s jump 80 m down is 2 ms per radian at 250 m and 34 degrees.  A search along the
arc then crosses the echo's lobe, which is long along the curve and short across it, and stops beside
its maximum (0.16-0.26 degree at 200-250 m on that profile).  :class:`TableEqualDelay` follows the
tables instead.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from clbeam.imaging.engine.points import bilinear_tables
from clbeam.model.grid import PolarGrid

if TYPE_CHECKING:
    from clbeam.imaging.engine.common import BeamformInput

#: Newton steps of the curve's range (``T`` is linear in ``R`` to parts in 1e4 over a step)
NEWTON_STEPS = 2
#: range step (m) of the difference ``dT/dR``
RANGE_DIFFERENCE_M = 0.25


class EqualDelay:
    """The range at which a point's echo delay is the same at another angle, to first order in the source's and
    the array's offsets from the grid centre (straight rays).

    The two-way path to a cell at range ``R`` and direction ``u = (sin theta, cos theta)`` is about
    ``2 R - (o_s + o_a) . u`` (``o_s``, ``o_a`` the source and the array centre, across and down, from the
    grid centre), so the echo of ``(r, theta)`` lies at ``r + (o_s + o_a) . (u' - u) / 2`` along ``theta'``.
    Heave and roll move the array off the centre: under 0.45 m of heave the curve leaves the grid's arc by
    8 mm a degree at 70 degrees, as much as the flat far beam changes over a degree.
    """

    def __init__(self, inp: BeamformInput):
        src = np.asarray(inp.source_offset_m, dtype=np.float64)[1:]
        arr = np.mean(np.asarray(inp.element_offsets_m, dtype=np.float64)[:, 1:], axis=0) if inp.n_channels else src
        self.half_offset = 0.5 * (src + arr)

    def __call__(self, range_m, from_deg, to_deg) -> np.ndarray:
        """Ranges (m) at angles ``to_deg`` with the delay of ``range_m`` at ``from_deg`` (broadcast)."""
        t0, t1 = np.deg2rad(from_deg), np.deg2rad(to_deg)
        oy, oz = self.half_offset
        return range_m + oy * (np.sin(t1) - np.sin(t0)) + oz * (np.cos(t1) - np.cos(t0))


class TableEqualDelay:
    """The range at which a point's echo delay is the same at another angle, through travel-time tables.

    The two-way delay of a cell is ``2 T(R, theta) - (o_s + o_a) . u / c0`` to first order in the
    source's and the array centre's offsets ``o_s``, ``o_a`` from the grid centre (``u`` the ray's
    launch direction, ``c0`` the speed at the centre), so the echo of ``(r, theta)`` lies at the
    ``r'`` along ``theta'`` where ``T(r', theta') = T(r, theta) + (o_s + o_a) . (u' - u) / (2 c0)``,
    found by Newton steps on the tables interpolated bilinearly (as the refinement's points are).

    Parameters
    ----------
    inp : BeamformInput
        The ping's input (source and element offsets from the grid centre, m).
    tables : clbeam.imaging.raytrace.TravelTimeTables
        The tables of ``grid``.
    grid : PolarGrid
        The grid the tables belong to.
    """

    def __init__(self, inp, tables, grid: PolarGrid):
        src = np.asarray(inp.source_offset_m, dtype=np.float64)[1:]
        arr = np.mean(np.asarray(inp.element_offsets_m, dtype=np.float64)[:, 1:], axis=0) if inp.n_channels else src
        self.half_offset = 0.5 * (src + arr)
        self.tables, self.grid = tables, grid

    def _values(self, range_m, angle_deg, names=("time_s", "launch_sin", "launch_cos")) -> dict:
        r, a = np.broadcast_arrays(np.asarray(range_m, dtype=np.float64), np.asarray(angle_deg, dtype=np.float64))
        return bilinear_tables(self.tables, self.grid, r, a, names=names)

    def _offset_term_s(self, values: dict) -> np.ndarray:
        """``(o_s + o_a) . u / (2 c0)`` (s) with the launch directions ``u`` of ``values``."""
        oy, oz = self.half_offset
        return (oy * values["launch_sin"] + oz * values["launch_cos"]) / self.tables.centre_speed_m_s

    def __call__(self, range_m, from_deg, to_deg) -> np.ndarray:
        """Ranges (m) at angles ``to_deg`` (degree) with the delay of ``range_m`` at ``from_deg`` (broadcast);
        the range itself where a ray reaches neither point.  The launch direction and ``dT/dR`` are taken at
        ``(range_m, to_deg)`` (over the millimetres of a Newton step they change by parts in 1e5), the time at
        each step."""
        r0, a0, a1 = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (range_m, from_deg, to_deg)))
        start = self._values(r0, a0)
        there = self._values(r0, a1)
        target = start["time_s"] - self._offset_term_s(start) + self._offset_term_s(there)
        h = RANGE_DIFFERENCE_M
        slope = (self._values(r0 + h, a1, ("time_s",))["time_s"] - there["time_s"]) / h
        r, t = r0.copy(), there["time_s"]
        for _ in range(NEWTON_STEPS):
            step = (t - target) / slope
            r = np.where(np.isfinite(step) & (slope > 0), r - step, r)
            t = self._values(r, a1, ("time_s",))["time_s"]
        return r


def equal_delay_curve(inp, tables, grid: PolarGrid):
    """The equal-delay curve of ``inp``'s echoes: through ``grid``'s travel-time ``tables`` when the ping has
    them (:class:`TableEqualDelay`), else along straight rays (:class:`EqualDelay`)."""
    return EqualDelay(inp) if tables is None else TableEqualDelay(inp, tables, grid)
