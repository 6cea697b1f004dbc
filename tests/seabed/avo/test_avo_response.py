"""Angular responses from image files: corrections, seabed slope, binning, navigation.

The synthetic images here are built forward from a known backscatter
strength (:func:`seabed_ping`), so the extraction must give it back:
``I(a, R) = K 10^(S(i)/10) A(R0, i) R0^-4 10^(-2 alpha R0 / 10) g(R - R0)``
with ``R0`` the seabed line's range along beam ``a``, ``i = |a + atan s|``,
``A`` the insonified area, ``g`` a Gaussian of peak 1 and half width at half
maximum ``max(E/2, 2 dr)`` (``E`` the echo's range extent in the beam, ``dr``
the range step), optionally times unit-mean exponential speckle.
"""

from __future__ import annotations

import math
import types

import numpy as np
import pyproj
import pytest

from clbeam.constants import WGS84_A_M, WGS84_F
from clbeam.errors import ClbeamError, OptionError
from clbeam.imaging.peaks import PingContext
from clbeam.seabed.avo.model import backscatter_strength_db, lambert_strength_db
from clbeam.seabed.avo.response import (
    ResponseOptions,
    along_track_positions_m,
    angular_responses,
    francois_garrison_db_per_km,
    incidence_angle_deg,
    insonified_area_m2,
    pick_seabed,
    ping_response,
    strength_from_intensity_db,
)

ANGLES = np.arange(-75.0, 75.01, 0.5)
RANGES = np.arange(0.0, 420.0, 0.5)
INC = np.arange(0.5, 85.0, 1.0)


# ---------------------------------------------------------------------------
# synthetic data (also used by the CLI tests)
# ---------------------------------------------------------------------------
def seabed_ping(angles_deg, ranges_m, strength_fn, *, z0=100.0, slope_deg=0.0, gain=1e-3,
                options=None, rng=None):
    """Intensity ``(n_angle, n_range)`` of one ping; ``strength_fn(incidence_deg) -> dB``."""
    o = options or ResponseOptions()
    ang = np.asarray(angles_deg, float)
    a = np.deg2rad(ang)
    r = np.asarray(ranges_m, float)
    dr = r[1] - r[0]
    s = math.tan(math.radians(slope_deg))
    r0 = z0 / (np.cos(a) - s * np.sin(a))
    inc = np.abs(ang + slope_deg)
    area = insonified_area_m2(r0, inc, o, steering_deg=ang)
    peak = (gain * 10 ** (strength_fn(inc) / 10) * area / r0 ** 4
            * 10 ** (-2 * o.absorption_db_per_m * r0 / 10))
    extent = r0 * np.tan(np.deg2rad(inc)) * o.wavelength_m / (o.rx_width_m * np.cos(a))
    hw = np.maximum(extent / 2, 2 * dr)
    inten = peak[:, None] * np.exp(-math.log(2) * ((r[None, :] - r0[:, None]) / hw[:, None]) ** 2)
    if rng is not None:
        inten = inten * rng.exponential(1.0, inten.shape)
    return inten + 1e-6 * np.min(peak)


def write_image_file(path, intensity, angles_deg, ranges_m, *, latitude=None, longitude=None, cf=True):
    """Write ``intensity (n_ping, n_angle, n_range)`` as a clbeam image file."""
    from clbeam.io.images import ImageWriter

    grid = types.SimpleNamespace(angles_deg=np.asarray(angles_deg, float), ranges_m=np.asarray(ranges_m, float),
                                 shape=(len(angles_deg), len(ranges_m)))
    variables = ["intensity", "cf"] if cf else ["cf"]
    with ImageWriter(path, grid, intensity.shape[0], variables, {"source_file": "synthetic"}) as w:
        for p in range(intensity.shape[0]):
            ctx = PingContext(index=p, centre_yz_m=(0.0, 0.0), latitude_deg=None if latitude is None else latitude[p],
                              longitude_deg=None if longitude is None else longitude[p], heading_deg=0.0)
            img = types.SimpleNamespace(intensity=intensity[p], cf=np.zeros_like(intensity[p]),
                                        cf_smooth=np.zeros_like(intensity[p]), sums=None, context=ctx)
            w.write(p, img)
    return path


def northward_track(n, spacing_m, lat0=50.0, lon0=-4.0):
    """Latitude/longitude (deg) of ``n`` pings ``spacing_m`` apart due north (WGS84, pyproj)."""
    lon, lat, _ = pyproj.Geod(ellps="WGS84").fwd(np.full(n, lon0), np.full(n, lat0), np.zeros(n),
                                                 np.arange(n) * spacing_m)
    return np.asarray(lat), np.full(n, lon0)


def lambert(inc):
    return lambert_strength_db(90.0 - np.asarray(inc))


# ---------------------------------------------------------------------------
# corrections by hand
# ---------------------------------------------------------------------------
def test_insonified_area_and_strength_by_hand():
    o = ResponseOptions(frequency_hz=5500.0, bandwidth_hz=7000.0, sound_speed_m_s=1500.0, tx_length_m=3.5,
                        rx_width_m=3.528, absorption_db_per_km=0.5, calibration_db=3.0)
    # R = 200 m, i = 30 deg: c/(2B) = 0.1071429 m, / sin 30 = 0.2142857 m across;
    # lambda = 0.2727273 m, beta_along = 0.0779221 rad, R beta = 15.584416 m -> 3.339518 m^2.
    # Beam-limited across: 200 * 0.2727273 / (3.528 cos 30) / cos 30 = 20.6137 m: larger, not used.
    assert insonified_area_m2(200.0, 30.0, o) == pytest.approx(3.339518, rel=1e-6)
    # Near nadir (i = 0.1 deg, R = 100 m) the beam limit wins:
    # 100 * 0.07730365 / cos^2(0.1 deg) * 100 * 0.07792208 = 60.23679 m^2 (pulse limit 61.4 m across).
    assert insonified_area_m2(100.0, 0.1, o) == pytest.approx(60.23679, rel=1e-6)
    # S = 10 log10(1e-9) + 40 log10(200) + 2 * 0.0005 * 200 - 10 log10(3.339518) + 3
    #   = -90 + 92.041200 + 0.2 - 5.236838 + 3 = 0.004362 dB
    assert strength_from_intensity_db(1e-9, 200.0, 30.0, o) == pytest.approx(0.004362, abs=1e-5)
    assert np.isnan(strength_from_intensity_db(0.0, 200.0, 30.0, o))


def test_francois_garrison_against_ainslie_mccolm():
    # Ainslie & McColm (1998), an independent simplified fit (dB/km, f kHz, z km).
    def ainslie(f, t=10.0, s=35.0, z=0.0, ph=8.0):
        f1 = 0.78 * math.sqrt(s / 35) * math.exp(t / 26)
        f2 = 42 * math.exp(t / 17)
        return (0.106 * f1 * f * f / (f1 * f1 + f * f) * math.exp((ph - 8) / 0.56)
                + 0.52 * (1 + t / 43) * (s / 35) * f2 * f * f / (f2 * f2 + f * f) * math.exp(-z / 6)
                + 0.00049 * f * f * math.exp(-(t / 27 + z / 17)))
    for f_khz in (2.0, 5.5, 9.0, 30.0):
        fg = francois_garrison_db_per_km(f_khz * 1e3)
        # the two fits agree to about 10 % over 1-100 kHz in ordinary sea water
        assert fg == pytest.approx(ainslie(f_khz), rel=0.15), f_khz
    assert ResponseOptions().absorption_db_per_m == pytest.approx(francois_garrison_db_per_km(5500.0) / 1e3)
    assert 0.2 < francois_garrison_db_per_km(5500.0) < 0.6


def test_incidence_on_a_slope_against_the_geometry():
    # Seabed deeper to starboard by 5 deg: the beam normal to it points 5 deg to port.
    assert incidence_angle_deg(-5.0, 5.0) == pytest.approx(0.0)
    # Starboard beam at 40 deg: ray (sin 40, cos 40), seabed normal (sin 5, -cos 5) -> 45 deg.
    ray = np.array([math.sin(math.radians(40)), math.cos(math.radians(40))])
    normal = np.array([math.sin(math.radians(5)), -math.cos(math.radians(5))])
    assert incidence_angle_deg(40.0, 5.0) == pytest.approx(math.degrees(math.acos(-ray @ normal)))
    assert incidence_angle_deg(-40.0, 5.0) == pytest.approx(35.0)


# ---------------------------------------------------------------------------
# one ping
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("slope_deg", [0.0, 5.0, -3.0])
def test_noise_free_ping_gives_back_the_strength_and_the_slope(slope_deg):
    o = ResponseOptions()
    inten = seabed_ping(ANGLES, RANGES, lambda i: backscatter_strength_db(90.0 - i, 5500.0, mz=3.0),
                        slope_deg=slope_deg, gain=1e-3, options=o)
    cal = ResponseOptions(calibration_db=30.0)  # -10 log10(gain)
    port, stbd, sb = ping_response(inten, ANGLES, RANGES, INC, cal)
    assert sb.slope_deg == pytest.approx(slope_deg, abs=0.05)
    assert sb.z0_m == pytest.approx(100.0, abs=0.3)
    truth = backscatter_strength_db(90.0 - INC, 5500.0, mz=3.0)
    for side in (port, stbd):
        ok = np.isfinite(side) & (INC > 2)
        err = side[ok] - truth[ok]
        # Window within E/8 of a Gaussian of HWHM >= E/2 costs <= 0.06 dB; the
        # nearest cell, <= dr/2 off a Gaussian of HWHM >= 2 dr, <= 0.19 dB.
        # Bins mix beams of strengths up to the model's change over 1 deg.
        slope_per_bin = np.abs(np.gradient(truth))[ok]
        assert np.all(err <= 0.01 + slope_per_bin), (slope_deg, err.max())
        assert np.all(err >= -0.2 - slope_per_bin), (slope_deg, err.min())
    # a slope moves the incidence range each side reaches: starboard beams (0, 75]
    # deg meet it at |a + phi|, port beams [-75, 0) at |a + phi| as well
    # (the 420 m range grid ends the swath before 75 deg beyond 65 deg)
    stbd_lo, port_lo = max(slope_deg, 0.0), max(-slope_deg, 0.0)
    assert np.isfinite(stbd[(INC > stbd_lo + 1) & (INC < 65 + slope_deg)]).all()
    assert np.isnan(stbd[INC < stbd_lo - 1]).all()
    assert np.isfinite(port[(INC > port_lo + 1) & (INC < 65 - slope_deg)]).all()
    assert np.isnan(port[INC < port_lo - 1]).all()


def test_ignoring_the_slope_would_be_seen():
    # Lambert seabed sloping 5 deg: at 60 deg beam angle the incidence is 65 (stbd) and
    # 55 (port); a flat-seabed assumption would be off by 10 log10(cos^2 65 / cos^2 60) = -1.46 dB.
    inten = seabed_ping(ANGLES, RANGES, lambert, slope_deg=5.0, gain=1.0)
    port, stbd, sb = ping_response(inten, ANGLES, RANGES, INC, ResponseOptions())
    k = np.searchsorted(INC, 65.0)
    assert stbd[k] == pytest.approx(lambert(INC[k]), abs=0.15)
    assert abs(stbd[k] - lambert(60.5)) > 1.0


def test_speckled_pings_stack_to_the_strength():
    from clbeam.seabed.avo.stack import stack_linear_db

    rng = np.random.default_rng(7)
    fn = lambda i: backscatter_strength_db(90.0 - i, 5500.0, mz=6.0)  # noqa: E731
    rows = [ping_response(seabed_ping(ANGLES, RANGES, fn, gain=1e-3, rng=rng), ANGLES, RANGES, INC,
                          ResponseOptions(calibration_db=30.0))[1] for _ in range(30)]
    stacked = stack_linear_db(np.array(rows), axis=0)
    truth = fn(INC)
    sel = (INC > 15) & (INC < 70)
    err = stacked[sel] - truth[sel]
    # >= 30 pings x 2 beams x >= 1 cell of unit-mean exponential speckle per bin:
    # relative std <= 1/sqrt(60), 0.56 dB; the mean over 55 bins, <= 0.08 dB (4 sigma: 0.3).
    assert abs(err.mean()) < 0.3
    assert np.all(np.abs(err) < 4 * 0.56 + 0.2)


def test_pick_fails_cleanly_without_signal():
    with pytest.raises(ClbeamError, match="seabed"):
        pick_seabed(np.zeros((ANGLES.size, RANGES.size)), ANGLES, RANGES)


def test_options_are_checked():
    with pytest.raises(OptionError, match="frequency_hz"):
        ResponseOptions(frequency_hz=0.0)
    with pytest.raises(OptionError, match="absorption"):
        ResponseOptions(absorption_db_per_km=-1.0)


# ---------------------------------------------------------------------------
# navigation and files
# ---------------------------------------------------------------------------
def test_along_track_from_navigation_and_without():
    lat, lon = northward_track(5, 2.5)
    assert along_track_positions_m(lat, lon) == pytest.approx([0, 2.5, 5.0, 7.5, 10.0], abs=1e-6)
    # due east at 60 N: 1e-4 deg of longitude is the parallel's radius N cos 60 times 1e-4 pi/180 = 5.58 m,
    # N = a / sqrt(1 - e^2 sin^2 60) on WGS84 (the chord differs from the arc by 1e-12)
    e = along_track_positions_m([60.0, 60.0], [0.0, 1e-4])
    e2 = WGS84_F * (2 - WGS84_F)
    n_radius = WGS84_A_M / math.sqrt(1 - e2 * math.sin(math.radians(60.0)) ** 2)
    assert e[1] == pytest.approx(n_radius * 0.5 * math.radians(1e-4), rel=1e-9)
    assert along_track_positions_m([np.nan] * 3, [np.nan] * 3, ping_spacing_m=2.0) == pytest.approx([0, 2, 4])


def test_angular_responses_from_a_file(tmp_path):
    ang, rng_m = np.arange(-70.0, 70.01, 1.0), np.arange(0.0, 320.0, 0.5)
    lat, lon = northward_track(4, 3.0)
    fn = lambda i: backscatter_strength_db(90.0 - i, 5500.0, mz=2.0)  # noqa: E731
    data = np.array([seabed_ping(ang, rng_m, fn, gain=1e-3) for _ in range(4)])
    path = write_image_file(tmp_path / "img.nc", data, ang, rng_m, latitude=lat, longitude=lon)
    bins = np.arange(1.0, 85.0, 1.0)  # centred on the beams (every 1 deg at whole degrees)
    res = angular_responses(path, bins, ResponseOptions(calibration_db=30.0))
    assert res.port_db.shape == (4, bins.size) and res.starboard_db.shape == (4, bins.size)
    assert res.along_track_m == pytest.approx([0, 3, 6, 9], abs=1e-6)
    assert res.seabed_depth_m == pytest.approx(100.0, abs=0.3)
    sel = (bins > 5) & (bins < 65)
    # the tolerance of the noise-free ping test: <= 0.19 dB, nearest cell off the peak
    for side in (res.port_db, res.starboard_db):
        err = side[:, sel] - fn(bins[sel])
        assert err.max() < 0.01 and err.min() > -0.2


def test_file_errors_are_one_line(tmp_path):
    ang, rng_m = np.arange(-60.0, 60.01, 1.0), np.arange(0.0, 250.0, 0.5)
    no_int = write_image_file(tmp_path / "cf.nc", np.ones((1, ang.size, rng_m.size)), ang, rng_m, cf=False)
    with pytest.raises(ClbeamError, match="intensity") as e:
        angular_responses(no_int)
    assert "\n" not in str(e.value)
    other = tmp_path / "x.nc"
    import xarray as xr
    xr.Dataset({"a": ("x", np.zeros(3))}).to_netcdf(other, engine="h5netcdf")
    with pytest.raises(ClbeamError, match="not a clbeam image file"):
        angular_responses(other)
    empty = write_image_file(tmp_path / "z.nc", np.zeros((1, ang.size, rng_m.size)), ang, rng_m)
    with pytest.raises(ClbeamError, match="ping 0: cannot pick the seabed"):
        angular_responses(empty)
