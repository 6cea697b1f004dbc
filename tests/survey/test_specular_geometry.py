"""A smooth pipe's specular extra depth and its nearest point off the ping's plane, against a brute-force nearest
point (also where that point lies outside the transmit beam, as for a pipe at 3-20 degrees to the track)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from clbeam.survey.burial import _nearest_point


@pytest.mark.parametrize("heading_deg,y_c,depth", [(8.0, 230.0, 180.5), (3.0, 600.0, 90.0), (20.0, 150.0, 300.0)])
def test_extra_depth_is_the_brute_force_nearest_points_mapped_into_the_plane(heading_deg, y_c, depth):
    a = math.radians(heading_deg)
    t = np.linspace(-400.0, 400.0, 1_600_001)  # the pipe, every 0.5 mm, through (0, y_c, depth) at heading a
    x, y = t * math.cos(a), y_c + t * math.sin(a)
    r = np.sqrt(x ** 2 + y ** 2 + depth ** 2)
    i = int(np.argmin(r))
    z_image = math.sqrt(r[i] ** 2 - y[i] ** 2)  # the imager: that range, that cone angle, in the plane
    # the echo lies at y[i], moved along its arc to the pipe's depth at y_c cos a: what specular_fit is given
    echo_y = math.sqrt(r[i] ** 2 - depth ** 2)
    yc, x_off, _, dz = _nearest_point([echo_y], [math.sin(a)], [[0.0, 0.0]], [[depth - 1.0, 0.0]], 1.0)
    assert yc[0] == pytest.approx(y_c, abs=1e-3)
    assert abs(x_off[0]) == pytest.approx(abs(x[i]), abs=1e-3)  # the grid's step along the pipe
    assert dz[0] == pytest.approx(z_image - depth, abs=1e-3)
