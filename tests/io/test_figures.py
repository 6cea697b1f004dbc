"""Figures: the polar-to-raster resampling puts values where the geometry says."""

import numpy as np
from scenes import point_ping, polar_point

from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.io.figures import plot_cross_track, polar_to_raster
from clbeam.model.grid import PolarGrid


def test_raster_pixel_takes_the_value_of_the_polar_cell_under_it():
    grid = PolarGrid.regular(range_res_m=1, angle_res_deg=1, max_range_m=50, angles_deg=(-45, 45))
    values = np.add.outer(grid.angles_deg, 1000 * grid.ranges_m)  # encodes (angle, range)
    y, z = np.array([0.0, 20 * np.sin(np.deg2rad(30)), -10.0]), np.array([20 * np.cos(np.deg2rad(30)), 30.0])
    out = polar_to_raster(values, grid, (0.0, 0.0), y, z)
    # pixel (y = 10, z = 17.32) is at R = 20, angle 30
    assert out[0, 1] == 30 + 1000 * 20
    # pixel (0, 30): R = 30, angle 0; pixel (-10, 30): R = 31.6 -> 32, angle -18.4 -> -18
    assert out[1, 0] == 0 + 1000 * 30
    assert out[1, 2] == -18 + 1000 * 32
    # outside the angular span: NaN
    assert np.isnan(polar_to_raster(values, grid, (0.0, 0.0), np.array([40.0]), np.array([5.0])))[0, 0]


def test_cross_track_figure_is_written_with_its_brightest_pixel_at_the_target(tmp_path):
    grid = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.5, min_range_m=60, max_range_m=100, angles_deg=(-40, 40))
    img = Imager(grid, ImagingOptions(interp="cubic")).image(point_ping(polar_point(80, 20), record_s=0.15))
    path = plot_cross_track(img, tmp_path / "fig.png", seabed_z_m=75.0, targets_yz_m=[[27.4, 75.2]])
    assert path.stat().st_size > 20_000
    # pixels finer than a range cell (0.2 m), so the peak cell is hit by some pixel
    y = np.arange(20, 35, 0.1)
    z = np.arange(65, 85, 0.1)
    r = polar_to_raster(img.intensity, grid, img.centre_yz_m, y, z)
    iz, iy = np.unravel_index(np.nanargmax(r), r.shape)
    # within half an angular cell at 80 m (0.35 m) plus half a raster pixel (0.05 m)
    tol = 0.5 * 80 * np.deg2rad(0.5) + 0.05 + 1e-9
    assert abs(y[iy] - 80 * np.sin(np.deg2rad(20))) <= tol and abs(z[iz] - 80 * np.cos(np.deg2rad(20))) <= tol
