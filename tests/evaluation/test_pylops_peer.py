"""PyLops' Kirchhoff migration, the benchmark's peer, computes clbeam's coherent sum.

On a point scatterer, PyLops' adjoint (straight rays, linear interpolation)
and clbeam's float64 reference engine with linear interpolation, evaluated
at the same Cartesian points, give the same complex sum ``S``.
"""

import numpy as np
from scenes import point_ping, polar_point

from clbeam.evaluation.baselines import pylops_kirchhoff
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.subcell import sums_at_points
from clbeam.model.grid import PolarGrid


def test_pylops_kirchhoff_adjoint_is_the_reference_coherent_sum(ref_engine):
    r, a = 70.3, 25.0
    ping = point_ping([polar_point(r, a)], record_s=0.12)
    grid = PolarGrid.regular(range_res_m=0.5, angle_res_deg=1.0, min_range_m=20, max_range_m=85, angles_deg=(-60, 60))
    inp = Imager(grid, ImagingOptions(interp="linear"), engine=ref_engine).beamform_input(ping)
    y, z = np.arange(28.0, 31.5, 0.05), np.arange(62.5, 65.0, 0.05)
    s_peer, _ = pylops_kirchhoff(inp, y, z)
    yy, zz = np.meshgrid(y, z, indexing="ij")
    ours = sums_at_points(ref_engine, inp, np.hypot(yy, zz), np.rad2deg(np.arctan2(yy, zz)), interp="linear",
                          outputs=("sums",)).s
    assert np.linalg.norm(s_peer - ours) / np.linalg.norm(ours) < 1e-6
    i, j = np.unravel_index(np.argmax(np.abs(ours)), ours.shape)
    assert abs(np.hypot(y[i], z[j]) - r) < 0.05  # the image is the scatterer's, not an empty corner
