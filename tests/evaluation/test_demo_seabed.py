"""The demo's figure draws the seabed as the scene has it (Line 1 slopes 0.8 degree across the track)."""

import math

import numpy as np
import pytest

from clbeam.evaluation.demo import seabed_profile
from clbeam.io.figures import seabed_line
from clbeam.sim import load_scene, simulate


def test_the_drawn_seabed_lies_at_the_scenes_seabed_under_each_pipe():
    sc = load_scene("line1", pings=2, max_range_m=380)
    ds = simulate(sc)
    assert sc.seabed.slope_across_deg != 0  # a flat line at the nadir depth would miss the pipes' seabed
    x, y = ds["truth_target_x"].values, ds["truth_target_y"].values
    truth = ds["truth_target_seabed_z"].values
    # the simulator's seabed under each pipe, at the pipe's own along-track offset x: the profile is the ping's
    # plane (x = 0), so it may differ by the along-track slope over x
    along = np.abs(np.tan(math.radians(sc.seabed.slope_along_deg)) * x)
    for ping in range(ds.sizes["ping"]):
        z = seabed_profile(sc, ds, ping)
        assert np.all(np.abs(z(y[ping]) - truth[ping]) <= along[ping] + 1e-9)
        # a flat line at the nadir depth misses by the slope across the pipes' offsets: metres at 200-300 m
        assert np.max(np.abs(truth[ping] - ds["truth_seabed_z"].values[ping])) > 2.0
        ys, zs = seabed_line(z, -800.0, 800.0)
        assert ys[0] < y[ping].min() and y[ping].max() < ys[-1]
        np.testing.assert_allclose(np.interp(y[ping], ys, zs), truth[ping], atol=along[ping].max() + 1e-9)


def test_a_flat_seabed_is_drawn_flat():
    ys, zs = seabed_line(120.0, -10.0, 10.0, n=5)
    np.testing.assert_array_equal(ys, np.linspace(-10, 10, 5))
    assert zs.tolist() == [120.0] * 5
    assert seabed_line(None, 0.0, 1.0) is None
    assert pytest.approx(seabed_line(lambda y: 2 * y, 0.0, 1.0, n=3)[1].tolist()) == [0.0, 1.0, 2.0]
