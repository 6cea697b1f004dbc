"""The WGS84 geodesic of clbeam.model.geodesy: the built-in solution against
pyproj (Karney's algorithm) and closed forms on the ellipsoid."""

import math

import numpy as np
import pyproj
import pytest

from clbeam.constants import WGS84_A_M, WGS84_F
from clbeam.model.geodesy import along_track_m, geodesic_direct, geodesic_inverse

GEOD = pyproj.Geod(ellps="WGS84")
RNG = np.random.default_rng(7)
LAT, LON = RNG.uniform(-80, 80, 500), RNG.uniform(-180, 180, 500)
AZ, DIST = RNG.uniform(0, 360, 500), RNG.uniform(0, 200e3, 500)


def test_builtin_direct_matches_pyproj_to_a_micrometre():
    lat, lon = geodesic_direct(LAT, LON, AZ, DIST, use_pyproj=False)
    lon_p, lat_p, _ = GEOD.fwd(LON, LAT, AZ, DIST)
    _, _, miss = GEOD.inv(lon, lat, lon_p, lat_p)
    assert np.max(miss) < 1e-5


def test_builtin_inverse_matches_pyproj():
    lon2, lat2, _ = GEOD.fwd(LON, LAT, AZ, DIST)
    d, az = geodesic_inverse(LAT, LON, lat2, lon2, use_pyproj=False)
    az_p, _, d_p = GEOD.inv(LON, LAT, lon2, lat2)
    assert np.max(np.abs(d - d_p)) < 1e-5
    assert np.max(np.abs((az - az_p + 180.0) % 360.0 - 180.0)[DIST > 1.0]) < 1e-7


def test_quarter_meridian_closed_form():
    """Equator to pole along a meridian: the quarter meridian of WGS84, 10 001 965.729 m."""
    d, az = geodesic_inverse(0.0, 0.0, 90.0, 0.0, use_pyproj=False)
    assert float(d) == pytest.approx(10_001_965.729, abs=1e-3)
    assert float(az) == pytest.approx(0.0, abs=1e-9)


def test_along_track_of_a_parallel_step_and_nan_propagation():
    """1e-4 degree east at 60 N is the parallel's radius N cos(60) times the angle."""
    e2 = WGS84_F * (2 - WGS84_F)
    n_radius = WGS84_A_M / math.sqrt(1 - e2 * math.sin(math.radians(60.0)) ** 2)
    for use in (True, False):
        s = along_track_m([60.0, 60.0, 60.0], [0.0, 1e-4, 2e-4], use_pyproj=use)
        assert s == pytest.approx(np.arange(3) * n_radius * 0.5 * math.radians(1e-4), rel=1e-9)
    lat, lon = geodesic_direct([np.nan, 10.0], [0.0, 0.0], [0.0, 90.0], [1.0, np.nan])
    assert np.all(np.isnan(lat)) and np.all(np.isnan(lon))


def test_one_arc_minute_of_latitude_is_the_meridian_radius_times_the_angle():
    """Along a meridian the arc is the meridian radius M = a (1 - e^2) / (1 - e^2 sin^2)^(3/2)
    (at the arc's middle latitude: 5e-11 relative for one arc minute) times the angle."""
    e2 = WGS84_F * (2 - WGS84_F)

    def meridian_radius(lat):
        return WGS84_A_M * (1 - e2) / (1 - e2 * math.sin(math.radians(lat)) ** 2) ** 1.5

    arc = math.radians(1 / 60)
    first, second = meridian_radius(34 + 0.5 / 60) * arc, meridian_radius(34 + 1.5 / 60) * arc
    expected = [0.0, first, first + second]
    for use in (True, False):
        d = along_track_m([34.0, 34.0 + 1 / 60, 34.0 + 2 / 60], [-119.8, -119.8, -119.8], use_pyproj=use)
        np.testing.assert_allclose(d, expected, rtol=1e-9)
