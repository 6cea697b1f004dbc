"""Ray-traced travel times through a stratified ocean (clbeam.imaging.raytrace)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from clbeam.errors import ClbeamError, GeometryError, OptionError
from clbeam.imaging import raytrace as rt
from clbeam.imaging.raytrace import newton
from clbeam.model.grid import PolarGrid
from clbeam.model.svp import SoundSpeedProfile, holland_line1_profile

#: receive aperture of the SBP29 class array (m): elements at y in [-1.764, 1.764]
HALF_APERTURE_M = 1.764
FS_HZ = 40e3


# ---------------------------------------------------------------------------
# independent references
# ---------------------------------------------------------------------------
def snell_two_layer(y: float, z: float, h1: float, c1: float, c2: float) -> float:
    """One-way time from (0, 0) to (y, z) with speed c1 above depth h1 and c2
    below: straight above h1, else brentq on the ray's elevation above the
    horizontal in the faster layer (Snell's law gives the other; the
    elevation, not the ray parameter, so that near-horizontal rays in the
    fast layer keep their precision)."""
    y = abs(y)
    if z <= h1:
        return math.hypot(y, z) / c1
    c_fast = max(c1, c2)

    def legs(elev):
        s_f, c_f = math.cos(elev), math.sin(elev)     # elevation above the horizontal
        out = []
        for h, c in ((h1, c1), (z - h1, c2)):
            if c == c_fast:
                out.append((h * s_f / c_f, h / (c * c_f)))
            else:
                s = s_f * c / c_fast
                co = math.sqrt(1.0 - s * s)
                out.append((h * s / co, h / (c * co)))
        return out

    if y == 0:
        return h1 / c1 + (z - h1) / c2
    elev = brentq(lambda a: sum(x for x, _ in legs(a)) - y, 1e-300, 0.5 * math.pi, xtol=1e-300, rtol=1e-15,
                  maxiter=2000)
    return sum(t for _, t in legs(elev))


def ivp_ray(c_of_z, dc_of_z, theta0: float, z_stops, z0: float = 0.0, breaks=()):
    """Integrate the ray equations in arc length (slowness vector form):
    dr/ds = c xi, dxi_z/ds = -c'(z) / c^2, dT/ds = 1/c, restarting at every
    depth in ``breaks`` (kinks of c(z)).  Returns (y, T, s) at each z in
    ``z_stops`` (increasing, the ray must stay downgoing)."""
    c0 = c_of_z(z0)
    state = np.array([0.0, z0, math.sin(theta0) / c0, math.cos(theta0) / c0, 0.0, 0.0])

    def rhs(_, u):
        c = c_of_z(u[1])
        return [c * u[2], c * u[3], 0.0, -dc_of_z(u[1]) / (c * c), 1.0 / c, 1.0]

    out = []
    stops = sorted(set(list(z_stops) + [b for b in breaks if z0 < b < max(z_stops)]))
    for z_target in stops:
        def hit(_, u, zt=z_target):
            return u[1] - zt
        hit.terminal = True
        hit.direction = 1
        sol = solve_ivp(rhs, (0.0, 1e5), state, method="DOP853", rtol=1e-13, atol=1e-14, events=hit, max_step=5.0)
        assert sol.status == 1, "the ray did not reach the depth"
        state = sol.y_events[0][0].copy()
        state[1] = z_target
        if z_target in z_stops:
            out.append((state[0], state[4], state[5]))
    return out


def ivp_turning_offset(c_of_z, dc_of_z, theta0: float) -> float:
    """Horizontal offset (m) where the ray launched at ``theta0`` from (0, 0)
    turns (``xi_z = 0``), by solve_ivp."""
    c0 = c_of_z(0.0)
    state = np.array([0.0, 0.0, math.sin(theta0) / c0, math.cos(theta0) / c0])

    def rhs(_, u):
        c = c_of_z(u[1])
        return [c * u[2], c * u[3], 0.0, -dc_of_z(u[1]) / (c * c)]

    def turn(_, u):
        return u[3]
    turn.terminal = True
    turn.direction = -1
    sol = solve_ivp(rhs, (0.0, 1e5), state, method="DOP853", rtol=1e-13, atol=1e-14, events=turn)
    assert sol.status == 1
    return float(sol.y_events[0][0][0])


def cell_grid(ranges, angles):
    return PolarGrid(np.asarray(ranges, dtype=float), np.asarray(angles, dtype=float))


# ---------------------------------------------------------------------------
# profile
# ---------------------------------------------------------------------------
def test_profile_speed_and_jump_sides():
    prof = SoundSpeedProfile.with_sediment(holland_line1_profile(), 225.0, 1600.0)
    assert prof.depths_m.tolist() == [-5.0, 3.0, 225.0, 225.0]
    assert prof.speed(-100.0) == 1522.0 and prof.speed(0.0) == 1522.0
    assert prof.speed(114.0) == pytest.approx(1506.0)
    assert prof.speed(225.0, side="above") == 1490.0
    assert prof.speed(225.0, side="below") == 1600.0
    assert prof.speed(1e4) == 1600.0
    assert prof.jump_depths_m.tolist() == [225.0]
    assert SoundSpeedProfile.constant(1500.0).is_constant
    same = SoundSpeedProfile.with_sediment(SoundSpeedProfile.constant(1490.0), 100.0, 1490.0)
    assert same.jump_depths_m.size == 0
    assert prof == holland_line1_profile(1600.0) and hash(prof) == hash(holland_line1_profile(1600.0))


@pytest.mark.parametrize("depths, speeds, words", [
    ([], [], "at least 1 point"),
    ([0.0, 1.0], [1500.0], "must match"),
    ([0.0, np.nan], [1500.0, 1500.0], "finite"),
    ([0.0, 10.0], [1500.0, np.inf], "finite"),
    ([0.0, 10.0], [1500.0, 1200.0], "outside 1300-2000"),
    ([0.0, 10.0], [2500.0, 1500.0], "outside 1300-2000"),
    ([0.0, 10.0, 5.0], [1500.0, 1500.0, 1500.0], "must increase"),
    ([0.0, 5.0, 5.0, 5.0], [1500.0, 1500.0, 1550.0, 1600.0], "more than twice"),
    ([0.0, 5.0, 5.0], [1500.0, 1500.0, 1500.0], "same speed"),
    ([[0.0, 1.0]], [[1500.0, 1500.0]], "1-D"),
    (["a"], [1500.0], "must be numbers"),
])
def test_bad_profiles_give_one_line_errors(depths, speeds, words):
    with pytest.raises(OptionError) as err:
        SoundSpeedProfile(depths, speeds)
    msg = str(err.value)
    assert words in msg and "\n" not in msg
    assert isinstance(err.value, ClbeamError)


def test_bad_inputs_give_one_line_errors():
    prof = SoundSpeedProfile.constant(1500.0)
    with pytest.raises(GeometryError, match="finite"):
        rt.eigenrays(prof, 0.0, [np.nan], [10.0])
    with pytest.raises(GeometryError, match=r"\(n, 2\)"):
        rt.element_travel_times(prof, np.zeros((3, 3)), np.ones((2, 2)))
    with pytest.raises(OptionError, match="SoundSpeedProfile"):
        rt.travel_time_tables("1500", cell_grid([1.0], [0.0]))
    with pytest.raises(OptionError, match="sediment speed|outside"):
        SoundSpeedProfile.with_sediment(prof, 100.0, 2500.0)


# ---------------------------------------------------------------------------
# constant profile: exact straight rays
# ---------------------------------------------------------------------------
def test_constant_profile_tables_are_straight_rays():
    c = 1500.0
    grid = cell_grid(np.r_[0.0, 0.2, np.linspace(1.0, 1100.0, 57)], np.linspace(-80.0, 80.0, 33))
    tab = rt.travel_time_tables(SoundSpeedProfile.constant(c), grid, centre_depth_m=3.0)
    r = grid.ranges_m[None, :]
    th = np.deg2rad(grid.angles_deg)[:, None]
    assert tab.reachable.all()
    assert tab.centre_speed_m_s == c
    np.testing.assert_allclose(tab.time_s, np.broadcast_to(r / c, tab.time_s.shape), rtol=1e-12, atol=0)
    np.testing.assert_allclose(tab.path_length_m, np.broadcast_to(r, tab.time_s.shape), rtol=1e-12, atol=0)
    np.testing.assert_allclose(tab.wavefront_radius_m, np.broadcast_to(r, tab.time_s.shape), rtol=1e-12, atol=0)
    np.testing.assert_allclose(tab.launch_sin, np.broadcast_to(np.sin(th), tab.time_s.shape), rtol=0, atol=1e-12)
    np.testing.assert_allclose(tab.launch_cos, np.broadcast_to(np.cos(th), tab.time_s.shape), rtol=0, atol=1e-12)


def test_constant_profile_offset_approximation_is_exact():
    prof = SoundSpeedProfile.constant(1480.0)
    grid = cell_grid(np.linspace(5.0, 1000.0, 23), np.linspace(-80.0, 80.0, 17))
    tab = rt.travel_time_tables(prof, grid)
    offs = np.array([[-1.764, 0.0], [0.9, -0.3], [1.764, 0.31]])
    exact = rt.offset_time_exact(prof, grid, offs)
    for radius in ("path", "wavefront"):
        np.testing.assert_allclose(rt.offset_time_approx(tab, offs, radius=radius), exact, rtol=0, atol=1e-13)
    y, z = grid.cell_yz()
    straight = np.hypot(y[None] - offs[:, 0, None, None], z[None] - offs[:, 1, None, None]) / 1480.0
    np.testing.assert_allclose(exact, straight, rtol=1e-12)


# ---------------------------------------------------------------------------
# layered profiles against independent computations
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("c2", [1490.0, 1600.0])
def test_two_layers_against_brentq_snell(c2):
    h1, c1 = 8.0, 1522.0
    prof = SoundSpeedProfile([0.0, h1, h1], [c1, c1, c2])
    rng = np.random.default_rng(1)
    y = np.r_[rng.uniform(-1100, 1100, 60), 0.0, 3.0, -700.0, 1000.0, 5.0]
    z = np.r_[rng.uniform(0.5, 400, 60), 300.0, 8.0, 8.0 + 1e-6, 225.0, 2.0]
    ray = rt.eigenrays(prof, 0.0, y, z)
    assert ray.reachable.all()
    ref = np.array([snell_two_layer(a, b, h1, c1, c2) for a, b in zip(y, z)])
    assert np.max(np.abs(ray.time_s - ref)) < 1e-6          # required: 1 us
    assert np.max(np.abs(ray.time_s - ref)) < 1e-11         # achieved
    # Snell's law between launch and arrival, and the sign convention
    c_end = np.where(z > h1, c2, c1)
    np.testing.assert_allclose(ray.arrival_sin / c_end, ray.launch_sin / c1, rtol=1e-12, atol=1e-16)
    assert np.all(np.sign(ray.launch_sin) == np.sign(y))
    np.testing.assert_allclose(ray.ray_parameter_s_m, ray.launch_sin / c1, rtol=1e-12, atol=1e-18)


def test_two_layers_tables_against_brentq_snell():
    h1, c1, c2 = 8.0, 1522.0, 1490.0
    prof = SoundSpeedProfile([-5.0, h1 - 5.0, h1 - 5.0], [c1, c1, c2])
    grid = cell_grid(np.linspace(0.2, 1100.0, 40), np.linspace(-80.0, 80.0, 21))
    tab = rt.travel_time_tables(prof, grid)
    y, z = grid.cell_yz()
    ref = np.vectorize(lambda a, b: snell_two_layer(a, b, h1 - 5.0, c1, c2))(y, z)
    assert np.max(np.abs(tab.time_s - ref)) < 1e-6


def _linear(c_top, c_bot, z_top, z_bot):
    g = (c_bot - c_top) / (z_bot - z_top)

    def c(z):
        return c_top + g * (min(max(z, z_top), z_bot) - z_top)

    def dc(z):
        return g if z_top <= z < z_bot else 0.0
    return c, dc


@pytest.mark.parametrize("c_top, c_bot", [(1522.0, 1490.0), (1480.0, 1540.0)])
def test_linear_gradient_against_ray_equations(c_top, c_bot):
    """Rays launched at given angles, integrated by solve_ivp through a
    constant-gradient layer 0-600 m (and the constant speed below): the
    eigenray to each point they pass gives their time, angle and length."""
    prof = SoundSpeedProfile([0.0, 600.0], [c_top, c_bot])
    c, dc = _linear(c_top, c_bot, 0.0, 600.0)
    stops = [20.0, 150.0, 400.0, 599.0, 800.0]
    thetas = [0.0, 0.3, 0.8, 1.1, 1.3] if c_bot < c_top else [0.0, 0.3, 0.6, 0.8]
    for th0 in thetas:
        pts = ivp_ray(c, dc, th0, stops, breaks=[600.0])
        for z, (y, t, s) in zip(stops, pts):
            for sign in (1.0, -1.0):
                ray = rt.eigenrays(prof, 0.0, sign * y, z)
                assert ray.reachable
                assert abs(float(ray.time_s) - t) < 1e-6      # required: 1 us
                assert abs(float(ray.time_s) - t) < 1e-9
                assert float(ray.launch_sin) == pytest.approx(sign * math.sin(th0), abs=1e-9)
                assert float(ray.path_length_m) == pytest.approx(s, rel=1e-9)


def test_paper_profile_tables_against_ray_equations():
    """Mixed layer, gradient and constant speed below (kinks at 3 and 225 m):
    table cells on rays integrated by solve_ivp."""
    prof = holland_line1_profile()
    g = -32.0 / 222.0

    def c(z):
        return 1522.0 if z < 3.0 else (1490.0 if z >= 225.0 else 1522.0 + g * (z - 3.0))

    def dc(z):
        return g if 3.0 <= z < 225.0 else 0.0

    for th0 in (0.2, 0.9, 1.35):
        pts = ivp_ray(c, dc, th0, [2.0, 100.0, 224.0, 500.0], breaks=[3.0, 225.0])
        for z, (y, t, s) in zip([2.0, 100.0, 224.0, 500.0], pts):
            ray = rt.eigenrays(prof, 0.0, y, z)
            assert abs(float(ray.time_s) - t) < 1e-9
            assert float(ray.path_length_m) == pytest.approx(s, rel=1e-9)
            # the same point as a table cell
            r, ang = math.hypot(y, z), math.degrees(math.atan2(y, z))
            tab = rt.travel_time_tables(prof, cell_grid([r], [ang]))
            assert abs(float(tab.time_s[0, 0]) - t) < 1e-9
            assert float(tab.launch_sin[0, 0]) == pytest.approx(math.sin(th0), abs=1e-9)


# ---------------------------------------------------------------------------
# unreachable targets
# ---------------------------------------------------------------------------
def test_turning_rays_make_targets_unreachable_not_wrong():
    """Speed increasing with depth: the ray launched so that it turns at depth
    z reaches X_max(z); beyond it the target needs a turning point."""
    prof = SoundSpeedProfile([0.0, 1000.0], [1480.0, 1540.0])
    c, dc = _linear(1480.0, 1540.0, 0.0, 1000.0)
    z = 200.0
    x_turn = ivp_turning_offset(c, dc, math.asin(1480.0 / c(z)))
    x_near = x_turn
    ray = rt.eigenrays(prof, 0.0, [0.5 * x_near, 0.99 * x_near, 1.01 * x_near, -1.5 * x_near, 5000.0],
                       [z, z, z, z, z])
    assert ray.reachable.tolist() == [True, True, False, False, False]
    assert np.isnan(ray.time_s[2:]).all() and np.isnan(ray.launch_sin[2:]).all()
    assert np.isnan(ray.path_length_m[2:]).all()
    # a reachable one close to the limit is right: it is on a ray solve_ivp traces
    th0 = math.asin(float(ray.launch_sin[1]))
    (y_chk, t_chk, _), = ivp_ray(c, dc, th0, [z])
    assert y_chk == pytest.approx(0.99 * x_near, abs=1e-6)
    assert abs(float(ray.time_s[1]) - t_chk) < 1e-9


def test_unreachable_cells_in_tables_and_above_source():
    prof = SoundSpeedProfile([0.0, 1000.0], [1480.0, 1700.0])
    grid = cell_grid(np.linspace(0.0, 1100.0, 56), np.linspace(-90.0, 90.0, 91))
    tab = rt.travel_time_tables(prof, grid)
    assert not tab.reachable.all() and tab.reachable[:, 0].all()
    for name in ("time_s", "launch_sin", "launch_cos", "path_length_m", "wavefront_radius_m"):
        a = getattr(tab, name)
        assert np.isnan(a[~tab.reachable]).all() and np.isfinite(a[tab.reachable]).all()
    # at 88 degrees the cell 100 m away is reached, the one at 1100 m is in
    # the shadow (the ray turning at its depth reaches 717 m); nadir always;
    # level with the source (90 degrees) only the centre in a gradient
    i88 = np.searchsorted(grid.angles_deg, 88.0)
    assert tab.reachable[i88, 5] and not tab.reachable[i88, -1]
    assert tab.reachable[np.searchsorted(grid.angles_deg, 0.0)].all()
    assert tab.reachable[[0, -1]].sum() == 2
    # the shadow boundary at 88 degrees is where the limiting ray lands
    z_shadow = grid.ranges_m * math.cos(math.radians(88.0))
    c_z = 1480.0 + 0.22 * z_shadow
    x_max = np.sqrt(1 - (1480.0 / c_z) ** 2) * c_z / 0.22
    np.testing.assert_array_equal(tab.reachable[i88], grid.ranges_m * math.sin(math.radians(88.0)) <= x_max)
    # a constant speed reaches level cells by a horizontal ray
    flat = rt.travel_time_tables(SoundSpeedProfile.constant(1500.0), grid)
    assert flat.reachable.all()
    np.testing.assert_allclose(flat.time_s[-1], grid.ranges_m / 1500.0, rtol=1e-15)
    # targets above the source or level with it (distinct) are unreachable
    ray = rt.eigenrays(prof, 50.0, [0.0, 10.0, 10.0, 0.0], [20.0, 50.0, 49.0, 50.0])
    assert ray.reachable.tolist() == [False, False, False, True]
    assert np.isnan(ray.time_s[:3]).all()
    assert float(ray.time_s[3]) == 0.0


# ---------------------------------------------------------------------------
# element times: exact eigenrays, reciprocity, simulator use
# ---------------------------------------------------------------------------
def test_element_travel_times_reciprocity_and_reference():
    prof = holland_line1_profile(1460.2)
    elems = np.stack([np.linspace(-1.764, 1.764, 8), np.linspace(-0.2, 0.2, 8)], axis=1)
    rng = np.random.default_rng(3)
    scat = np.stack([rng.uniform(-1000, 1000, 50), rng.uniform(5, 260, 50)], axis=1)
    t = rt.element_travel_times(prof, elems, scat)
    assert t.shape == (8, 50) and np.isfinite(t).all()
    back = rt.element_travel_times(prof, scat, elems)
    np.testing.assert_allclose(back.T, t, rtol=1e-13)
    for i in (0, 5):
        one = rt.eigenrays(prof, elems[i, 1], scat[:, 0] - elems[i, 0], scat[:, 1])
        np.testing.assert_allclose(t[i], one.time_s, rtol=1e-14)


def test_offset_time_exact_matches_element_times():
    prof = holland_line1_profile()
    grid = cell_grid(np.linspace(10.0, 1000.0, 7), np.linspace(-70.0, 70.0, 5))
    offs = np.array([[1.0, 0.1], [-1.764, 0.0]])
    ex = rt.offset_time_exact(prof, grid, offs, centre_depth_m=0.5)
    y, z = grid.cell_yz((0.0, 0.5))
    ref = rt.element_travel_times(prof, offs + [0.0, 0.5], np.stack([y.ravel(), z.ravel()], axis=1))
    np.testing.assert_allclose(ex, ref.reshape(ex.shape), rtol=1e-14)
    assert rt.offset_time_exact(prof, grid, offs[0], centre_depth_m=0.5).shape == grid.shape


# ---------------------------------------------------------------------------
# the per-element approximation (how a kernel uses the tables)
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def paper_offsets():
    prof = holland_line1_profile()
    grid = cell_grid(np.r_[np.arange(50.0, 200.0, 2.0), np.arange(200.0, 1100.1, 10.0)],
                     np.arange(-80.0, 80.01, 0.5))
    tab = rt.travel_time_tables(prof, grid)
    offs = np.stack([np.linspace(-HALF_APERTURE_M, HALF_APERTURE_M, 9), np.zeros(9)], axis=1)
    exact = rt.offset_time_exact(prof, grid, offs)
    assert np.isfinite(exact).all() and tab.reachable.all()
    return tab, offs, exact


def test_offset_approximation_error_over_the_aperture(paper_offsets):
    """T + d(o)/c0 against the exact eigenray from each element, paper profile,
    50-1100 m, +-80 degrees, elements across 3.53 m.  Measured: 0.052 us
    (0.0021 samples at 40 kHz, 0.17 degree at 9 kHz) with the path length as
    radius, 0.0016 us with the wavefront radius; bound: 1/200 sample."""
    tab, offs, exact = paper_offsets
    err_path = np.max(np.abs(rt.offset_time_approx(tab, offs, radius="path") - exact))
    err_wave = np.max(np.abs(rt.offset_time_approx(tab, offs, radius="wavefront") - exact))
    assert err_path * FS_HZ < 1 / 20            # the requirement
    assert err_path * FS_HZ < 1 / 200           # what it achieves (0.0021 samples)
    assert err_path * 9e3 * 360 < 0.5           # phase at 9 kHz, degrees
    assert err_wave * FS_HZ < 1 / 5000          # the better radius (6e-5 samples)
    assert err_wave < err_path / 10
    # without the curvature term the error is tens of microseconds: the
    # tables' radius matters
    plane = tab.time_s[None] - offs[:, 0, None, None] * tab.launch_sin[None] / tab.centre_speed_m_s
    assert np.max(np.abs(plane - exact)) > 1e-5


def test_offset_approximation_with_roll(paper_offsets):
    """Elements rotated by 10 degrees of roll (vertical offsets up to 0.31 m)."""
    tab, offs, _ = paper_offsets
    prof = holland_line1_profile()
    phi = math.radians(10.0)
    rolled = np.stack([offs[:, 0] * math.cos(phi), offs[:, 0] * math.sin(phi)], axis=1)
    exact = rt.offset_time_exact(prof, tab.grid, rolled)
    assert np.max(np.abs(rt.offset_time_approx(tab, rolled) - exact)) * FS_HZ < 1 / 200
    assert np.max(np.abs(rt.offset_time_approx(tab, rolled, radius="wavefront") - exact)) * FS_HZ < 1 / 2000


def test_offset_delay_is_cancellation_free():
    d = rt.offset_delay_m(1e4, 0.6, 0.8, [[1e-3, 0.0]])
    ref = math.hypot(1e4 * 0.6 - 1e-3, 1e4 * 0.8) - 1e4
    assert float(d[0]) == pytest.approx(ref, rel=1e-9)
    assert float(rt.offset_delay_m(0.0, 0.0, 1.0, [0.3, 0.4])) == pytest.approx(0.5)


# ---------------------------------------------------------------------------
# positioning error of isospeed imaging
# ---------------------------------------------------------------------------
def test_positioning_error_constant_profile():
    prof = SoundSpeedProfile.constant(1500.0)
    e = rt.positioning_error(prof, (1000.0, 225.0), 1500.0)
    assert e.error_m < 1e-9 and e.trace_error_m < 1e-9 and abs(e.range_only_horizontal_error_m) < 1e-9
    e = rt.positioning_error(prof, (1000.0, 225.0), 1515.0)
    assert e.error_m == pytest.approx(0.01 * math.hypot(1000.0, 225.0), rel=1e-9)


def test_positioning_error_paper_target_at_1km():
    """Seabed target 1 km across, 225 m down, paper profile, imaged at 1500 m/s
    (numbers in docs/raytrace.md)."""
    prof = holland_line1_profile()
    e = rt.positioning_error(prof, (1000.0, 225.0), 1500.0)
    ray = rt.eigenrays(prof, 0.0, 1000.0, 225.0)
    assert math.hypot(*e.apparent_yz_m) == pytest.approx(1500.0 * float(ray.time_s), rel=1e-12)
    assert e.apparent_yz_m[0] / math.hypot(*e.apparent_yz_m) == pytest.approx(float(ray.launch_sin), rel=1e-12)
    # the ray leaves 2.7 degrees flatter than the chord and curves down
    assert math.degrees(math.asin(float(ray.launch_sin))) - math.degrees(math.atan2(1000.0, 225.0)) == \
        pytest.approx(2.7, abs=0.1)
    assert 45.0 < e.error_m < 50.0 and e.vertical_error_m < -45.0
    assert abs(e.range_only_horizontal_error_m) < 5.0
    with pytest.raises(GeometryError, match="no direct ray"):
        rt.positioning_error(SoundSpeedProfile([0.0, 1000.0], [1480.0, 1540.0]), (5000.0, 200.0), 1500.0)


def test_eigenrays_broadcast_and_threads():
    prof = holland_line1_profile(1600.0)
    y = np.linspace(-1000, 1000, 40_000).reshape(200, 200)
    z = np.linspace(1.0, 300.0, 200)[None, :]
    one = rt.eigenrays(prof, 0.0, y, z, workers=1)
    two = rt.eigenrays(prof, 0.0, y, z, workers=2)
    assert one.time_s.shape == (200, 200)
    np.testing.assert_array_equal(one.time_s, two.time_s)
    assert one.reachable.all()


def test_unchecked_last_step_is_checked(monkeypatch):
    """With a loose threshold far too large, the final check sends the
    targets whose last step fell short back to Newton: same results."""
    prof = holland_line1_profile(1600.0)
    grid = cell_grid(np.linspace(0.0, 1100.0, 120), np.linspace(-85.0, 85.0, 35))
    ref = rt.travel_time_tables(prof, grid)
    monkeypatch.setattr(newton, "LOOSE_TOL_REL", 0.5)
    loose = rt.travel_time_tables(prof, grid)
    np.testing.assert_array_equal(loose.reachable, ref.reachable)
    assert np.nanmax(np.abs(loose.time_s - ref.time_s)) < 1e-12
    assert np.nanmax(np.abs(loose.launch_sin - ref.launch_sin)) < 1e-9


def test_targets_not_converged_are_nan_not_wrong(monkeypatch, caplog):
    prof = holland_line1_profile()
    rng = np.random.default_rng(5)
    y, z = rng.uniform(-1000, 1000, 500), rng.uniform(1.0, 300.0, 500)
    ref = rt.eigenrays(prof, 0.0, y, z)
    monkeypatch.setattr(newton, "MAX_ITERATIONS", 2)
    with caplog.at_level("WARNING", logger="clbeam.imaging.raytrace"):
        few = rt.eigenrays(prof, 0.0, y, z)
    assert 0 < np.count_nonzero(~few.reachable) < 500
    assert "did not converge" in caplog.text
    assert np.isnan(few.time_s[~few.reachable]).all()
    assert np.max(np.abs(few.time_s[few.reachable] - ref.time_s[few.reachable])) < 1e-12
