"""OpenCL kernels against the float64 NumPy reference, every mode and output."""

import numpy as np
import pytest
from scenes import FS, bandlimited_noise, random_input

from clbeam.imaging.engine import INTERP_MODES, BeamformInput
from clbeam.imaging.engine.opencl import OpenCLEngine
from clbeam.model.grid import PolarGrid

KERNEL_MODES = [m for m, spec in INTERP_MODES.items() if spec.kernel_id >= 0]
EPS32 = np.finfo(np.float32).eps


GRID = PolarGrid.regular(range_res_m=0.37, angle_res_deg=1.3, max_range_m=60.0, angles_deg=(-75, 75))


def float32_tolerance(inp: BeamformInput) -> float:
    """Relative error bound of a float32 kernel (5x margin).

    Sample positions carry a rounding of eps * |pos| with |pos| up to
    1 + (|o_src| + max|o_n|) fs / c samples; at the top of the band the phase
    turns 2 pi 9 kHz / fs rad per sample, so each value is off by that product;
    the channel sums add about n_ch * eps.  Intensity doubles it.
    """
    reach = 1 + (np.linalg.norm(inp.source_offset_m) + np.linalg.norm(inp.element_offsets_m, axis=1).max()) * inp.samples_per_m
    per_value = 2 * np.pi * 9000.0 / inp.sample_rate_hz * reach * EPS32
    return 5 * 2 * (per_value + inp.n_channels * EPS32)


@pytest.mark.parametrize("mode", KERNEL_MODES)
def test_opencl_matches_reference_for_every_mode_and_output(cl_engine, ref_engine, mode):
    inp = random_input(seed=KERNEL_MODES.index(mode))
    outs = ("intensity", "cf", "sums")
    got = cl_engine.beamform(inp, GRID, interp=mode, outputs=outs)
    ref = ref_engine.beamform(inp, GRID, interp=mode, outputs=outs)
    tol = float32_tolerance(inp)
    assert np.array_equal(got.m, ref.m), "channel counts M differ"
    assert ref.m.max() == inp.n_channels and ref.m.min() == 0  # the grid spans in- and out-of-record cells
    if mode == "nearest":
        # a position within rounding of a half sample may pick the other neighbour: allow those cells only
        differ = ~np.isclose(got.s, ref.s, rtol=tol, atol=tol * np.abs(ref.s).max())
        assert differ.mean() < 1e-3
        keep = ~differ
    else:
        keep = np.ones(ref.m.shape, dtype=bool)
    rel = lambda a, b: np.linalg.norm((a - b)[keep]) / np.linalg.norm(b[keep])  # noqa: E731
    assert rel(got.intensity, ref.intensity) < tol
    assert rel(got.s, ref.s) < tol
    assert rel(got.q, ref.q) < tol
    assert np.max(np.abs(got.cf - ref.cf)[keep]) < 2 * tol  # |dCF| <= 2 |dS|/sqrt(MQ) (Cauchy-Schwarz)


@pytest.mark.parametrize("outputs", [("intensity",), ("cf",), ("sums",), ("intensity", "cf")])
def test_requested_outputs_only_and_identical_values(cl_engine, outputs):
    inp = random_input(seed=11)
    full = cl_engine.beamform(inp, GRID, interp="linear", outputs=("intensity", "cf", "sums"))
    part = cl_engine.beamform(inp, GRID, interp="linear", outputs=outputs)
    for name in ("intensity", "cf"):
        if name in outputs:
            np.testing.assert_array_equal(getattr(part, name), getattr(full, name))
        else:
            assert getattr(part, name) is None
    if "sums" in outputs:
        np.testing.assert_array_equal(part.m, full.m)


def test_widest_precision_kernel_matches_reference(cl_engine, ref_engine):
    """float64 where the device has cl_khr_fp64 (checked, never assumed), else float32."""
    from clbeam.imaging.engine.opencl import device_has_fp64

    precision = "float64" if device_has_fp64(cl_engine.device) else "float32"
    eng = OpenCLEngine(precision=precision)
    inp = random_input(seed=5)
    got = eng.beamform(inp, GRID, interp="cubic", outputs=("intensity", "cf"))
    ref = ref_engine.beamform(inp, GRID, interp="cubic", outputs=("intensity", "cf"))
    # float64: the kernel's cancellation-free form and the reference's plain square
    # roots agree to ~1e-12 at these ranges; float32: the bound derived above
    tol = 1e-10 if precision == "float64" else float32_tolerance(inp)
    assert np.linalg.norm(got.intensity - ref.intensity) / np.linalg.norm(ref.intensity) < tol
    assert np.max(np.abs(got.cf - ref.cf)) < 2 * tol


def test_tiling_over_angles_gives_identical_results(cl_engine):
    inp = random_input(seed=7)
    whole = cl_engine.beamform(inp, GRID, interp="linear", outputs=("intensity", "cf"))
    tiled_engine = OpenCLEngine(max_tile_cells=GRID.shape[1] * 16)  # 16 angle rows (one CPU tile) per launch
    tiled = tiled_engine.beamform(inp, GRID, interp="linear", outputs=("intensity", "cf"))
    np.testing.assert_array_equal(tiled.intensity, whole.intensity)
    np.testing.assert_array_equal(tiled.cf, whole.cf)


def test_range_window_skips_cells_without_changing_computed_values(cl_engine, ref_engine):
    inp = random_input(seed=8)
    n_a = GRID.shape[0]
    win = np.stack([np.linspace(10, 30, n_a), np.linspace(20, 50, n_a)], axis=1)
    full = cl_engine.beamform(inp, GRID, interp="cubic", outputs=("intensity", "cf"))
    part = cl_engine.beamform(inp, GRID, interp="cubic", outputs=("intensity", "cf"), range_window_m=win)
    ref = ref_engine.beamform(inp, GRID, interp="cubic", outputs=("intensity", "cf"), range_window_m=win)
    inside = (GRID.ranges_m[None, :] >= win[:, :1]) & (GRID.ranges_m[None, :] <= win[:, 1:])
    np.testing.assert_array_equal(part.intensity[inside], full.intensity[inside])
    assert np.all(part.intensity[~inside] == 0) and np.all(part.cf[~inside] == 0)
    assert np.all(ref.intensity[~inside] == 0)
    assert np.array_equal(part.intensity == 0, ref.intensity == 0)


def test_record_skipping_equals_computing_every_cell(cl_engine, ref_engine):
    # a grid reaching far beyond the record: rows skipped by the host bound
    inp = random_input(seed=9, n_s=1500)
    grid = PolarGrid.regular(range_res_m=0.5, angle_res_deg=5, max_range_m=200, angles_deg=(-60, 60))
    got = cl_engine.beamform(inp, grid, interp="lanczos4", outputs=("intensity", "sums"))
    ref = ref_engine.beamform(inp, grid, interp="lanczos4", outputs=("intensity", "sums"))
    assert np.array_equal(got.m, ref.m)
    assert (ref.m == 0).mean() > 0.5  # most of this grid lies outside the record
    assert np.linalg.norm(got.intensity - ref.intensity) / np.linalg.norm(ref.intensity) < float32_tolerance(inp)


def degenerate_input(data):
    n_ch = data.shape[0]
    eo = np.zeros((n_ch, 3))
    eo[:, 1] = np.linspace(-1.7, 1.7, n_ch)
    return BeamformInput(data, FS, 0.0, 1500.0, eo, np.zeros(3), centre_frequency_hz=5500.0)


@pytest.mark.parametrize("case", ["zeros", "nan", "inf", "dead", "one-channel"])
@pytest.mark.parametrize("mode", ["linear", "lanczos8"])
def test_cf_finite_and_within_unit_interval_on_degenerate_data(cl_engine, ref_engine, case, mode):
    data = bandlimited_noise((8, 800), seed=1)
    clean = data.copy()
    if case == "zeros":
        data[:] = 0
    elif case == "nan":
        data[:, 100:300] = np.nan
        data[3] = np.nan
    elif case == "inf":
        data[2, 50:60] = np.inf
        data[5, 400] = -np.inf + 1j
    elif case == "dead":
        data[[1, 4, 6]] = 0
    else:
        data = data[:1]
    inp = degenerate_input(data)
    grid = PolarGrid.regular(range_res_m=0.3, angle_res_deg=3, max_range_m=25, angles_deg=(-80, 80))
    got = cl_engine.beamform(inp, grid, interp=mode, outputs=("intensity", "cf", "sums"))
    ref = ref_engine.beamform(inp, grid, interp=mode, outputs=("intensity", "cf", "sums"))
    for r in (got, ref):
        assert np.isfinite(r.cf).all() and np.isfinite(r.intensity).all()
        assert r.cf.min() >= 0 and r.cf.max() <= 1 + 1e-5
    np.testing.assert_array_equal(got.m, ref.m)
    if case == "zeros":
        assert np.all(got.cf == 0) and np.all(got.intensity == 0)
    if case == "one-channel":
        # one channel: |S|^2 = Q and M = 1, so CF is exactly 1 wherever Q > 0
        assert np.allclose(ref.cf[ref.q > 0], 1.0)
        assert np.allclose(got.cf[ref.q > 0], 1.0, atol=1e-6)
    if case in ("nan", "inf"):
        # non-finite samples are skipped, not summed: fewer channels where they sit, none anywhere else
        clean_ref = ref_engine.beamform(degenerate_input(clean), grid, interp=mode, outputs=("sums",))
        assert (ref.m <= clean_ref.m).all() and (ref.m < clean_ref.m).any()
        same = ref.m == clean_ref.m
        np.testing.assert_allclose(ref.s[same], clean_ref.s[same], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("mode", ["nearest", "linear-bb", "cubic", "lanczos4"])
def test_far_cells_on_the_fresnel_branch_match_reference(cl_engine, ref_engine, mode):
    """Cells beyond the Fresnel switch range use the kernel's expansion: all
    outputs against the reference there (truncation below 1e-5 sample adds
    2 pi 9 kHz / fs * 1e-5 = 1.4e-5 to the float32 bound)."""
    from clbeam.imaging.engine.opencl import fresnel_min_range_m

    inp = random_input(seed=31, n_s=12000, t0=0.2)
    r0 = fresnel_min_range_m(inp.element_offsets_m, inp.samples_per_m)
    grid = PolarGrid.regular(range_res_m=0.37, angle_res_deg=3.1, min_range_m=max(1.5 * r0, 160),
                             max_range_m=max(1.5 * r0, 160) + 40, angles_deg=(-75, 75))
    outs = ("intensity", "cf", "sums")
    got = cl_engine.beamform(inp, grid, interp=mode, outputs=outs)
    ref = ref_engine.beamform(inp, grid, interp=mode, outputs=outs)
    tol = float32_tolerance(inp) + 5 * 2 * 2 * np.pi * 9000 / FS * 1e-5
    assert ref.m.max() == inp.n_channels
    if mode == "nearest":
        keep = np.isclose(got.s, ref.s, rtol=tol, atol=tol * np.abs(ref.s).max())
        assert keep.mean() > 0.999
    else:
        keep = np.ones(ref.m.shape, dtype=bool)
        assert np.array_equal(got.m, ref.m)
    for a, b in ((got.intensity, ref.intensity), (got.s, ref.s), (got.q, ref.q)):
        assert np.linalg.norm((a - b)[keep]) / np.linalg.norm(b[keep]) < tol


def test_record_shorter_than_the_taps_is_a_clear_error(cl_engine, ref_engine):
    from clbeam.errors import GridError

    inp = random_input(seed=1, n_ch=2, n_s=10)
    grid = PolarGrid.regular(range_res_m=0.5, angle_res_deg=10, max_range_m=5, angles_deg=(-30, 30))
    for eng in (cl_engine, ref_engine):
        with pytest.raises(GridError, match="10 samples, fewer than the 16 taps of interpolation mode 'lanczos8'"):
            eng.beamform(inp, grid, interp="lanczos8")


def test_launch_tiles_cover_every_block_row_once_in_range_row_order():
    """Against enumerating them: for each block of angles, the range rows from its windows' smallest first to
    largest end (empty windows left out), ordered by range row, then block; random windows and block sizes."""
    from clbeam.imaging.engine.opencl import launch_tiles

    rng = np.random.default_rng(4)
    for _ in range(200):
        lanes = int(rng.choice([1, 4, 16]))
        n = lanes * int(rng.integers(0, 25))
        first = rng.integers(0, 60, n)
        window = np.stack([first, np.maximum(first + rng.integers(-8, 40, n), 0)], axis=1).astype(np.int32)
        expected = []
        for b in range(n // lanes):
            w = window[b * lanes:(b + 1) * lanes]
            w = w[w[:, 1] > w[:, 0]]
            if len(w):
                expected += [(b * lanes, row) for row in range(w[:, 0].min(), w[:, 1].max())]
        expected.sort(key=lambda t: (t[1], t[0]))
        got = launch_tiles(window, lanes)
        assert got.dtype == np.int32
        assert [tuple(t) for t in got] == expected


def test_host_arrays_are_reused_only_once_nothing_else_refers_to_them():
    from clbeam.imaging.engine.opencl import HostArrays

    pool = HostArrays()
    a = pool.empty((6, 7), np.float32)
    first = id(a)
    assert id(pool.empty((6, 7), np.float32)) != first            # held by ``a``: a new array
    view = a[1:]
    del a
    assert id(pool.empty((6, 7), np.float32)) != first            # a view of it still refers to it
    del view
    again = pool.zeros((6, 7), np.float32)
    assert id(again) == first and not again.any()                 # let go: handed out again, zeroed
    assert pool.empty((7, 6), np.float32).shape == (7, 6)         # another shape: a new array
    small = HostArrays(max_bytes=1000)
    kept = [small.empty((100,), np.float64) for _ in range(3)]    # 800 bytes each: the pool keeps the newest
    assert sum(a.nbytes for a in small._arrays) <= 1000 and all(k.shape == (100,) for k in kept)


@pytest.mark.parametrize("beams", [None, "auto"])
def test_a_held_result_keeps_its_values_through_later_calls(beams):
    """The engine reuses its host arrays once let go: a result still held is never written by a later call
    of the same shapes, whose values are those of a fresh engine; the read-back counts every output's bytes."""
    from clbeam.imaging.engine.beams import BeamSampling

    inp_a, inp_b = random_input(seed=1), random_input(seed=2)
    grid = PolarGrid.regular(range_res_m=0.5, angle_res_deg=1.0, min_range_m=5.0, max_range_m=40.0,
                             angles_deg=(-60.0, 60.0))
    sampling = BeamSampling() if beams else None
    engine = OpenCLEngine()
    held = engine.beamform(inp_a, grid, outputs=("intensity", "cf"), beams=sampling)
    copy = held.intensity.copy(), held.cf.copy()
    for _ in range(3):
        engine.beamform(inp_b, grid, outputs=("intensity", "cf"), beams=sampling)
    np.testing.assert_array_equal(held.intensity, copy[0])
    np.testing.assert_array_equal(held.cf, copy[1])
    fresh = OpenCLEngine().beamform(inp_b, grid, outputs=("intensity", "cf"), beams=sampling)
    before = engine.readback.n_bytes
    again = engine.beamform(inp_b, grid, outputs=("intensity", "cf"), beams=sampling)
    np.testing.assert_array_equal(again.intensity, fresh.intensity)
    np.testing.assert_array_equal(again.cf, fresh.cf)
    assert engine.readback.n_bytes - before >= 2 * grid.n_cells * 4   # the images' two float32 planes at least
    assert not engine.readback.pending and np.isnan(engine.readback.device_s)   # no profiling: no time


def test_a_profiling_engine_times_its_copies():
    """With profiling the read-back's device time is that of its copies: positive and at most the call's."""
    import time

    grid = PolarGrid.regular(range_res_m=0.5, angle_res_deg=1.0, min_range_m=5.0, max_range_m=40.0,
                             angles_deg=(-60.0, 60.0))
    engine = OpenCLEngine(profiling=True)
    t0 = time.perf_counter()
    engine.beamform(random_input(seed=1), grid, outputs=("intensity", "cf"))
    wall = time.perf_counter() - t0
    assert engine.readback.n_bytes == 2 * grid.n_cells * 4
    assert 0 < engine.readback.device_s < wall and engine.readback.throughput_gb_s() > 0


@pytest.mark.parametrize("axis", [PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, max_range_m=1100.0).ranges_m,
                                  PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, max_range_m=1100.0).angles_deg,
                                  np.array([0.0, 0.5, 2.0, 2.1, 7.0])], ids=["ranges", "angles", "uneven"])
def test_the_lower_node_of_points_is_the_binary_searchs(axis):
    """The bilinear tables' corner: ``searchsorted(axis, x) - 1`` clipped to the intervals, and its fraction,
    at random points, on every node, halfway between nodes and beyond both ends."""
    from clbeam.imaging.engine.points import _lower_node

    rng = np.random.default_rng(5)
    span = axis[-1] - axis[0]
    x = np.concatenate([rng.uniform(axis[0] - 0.1 * span, axis[-1] + 0.1 * span, 20000), axis,
                        0.5 * (axis[1:] + axis[:-1]), np.nextafter(axis, -np.inf), np.nextafter(axis, np.inf)])
    i, t = _lower_node(axis, x)
    want = np.clip(np.searchsorted(axis, x) - 1, 0, axis.size - 2)
    np.testing.assert_array_equal(i, want)
    np.testing.assert_array_equal(t, (x - axis[want]) / (axis[want + 1] - axis[want]))


def test_kept_table_windows_follow_the_record_and_let_their_tables_go():
    """The windows of a grid's tables are kept for the next ping: a record of another start or length gets
    its own (those a fresh computation gives), and the kept ones do not hold the tables alive."""
    import gc
    import weakref

    from clbeam.imaging.engine import common, interp_mode
    from clbeam.imaging.raytrace import travel_time_tables
    from clbeam.model.svp import holland_line1_profile

    grid = PolarGrid.regular(range_res_m=0.5, angle_res_deg=2, max_range_m=70.0, angles_deg=(-80, 80))
    tables = travel_time_tables(holland_line1_profile(), grid)
    base = random_input(seed=1, n_ch=8)

    def windows(t0, n, tab):
        inp = BeamformInput(base.data[:, :n], FS, t0, 1500.0, base.element_offsets_m, base.source_offset_m,
                            tables=tab)
        return common.cell_windows(inp, grid, interp_mode("cubic"))

    cases = [(0.0, 3000), (0.03, 3000), (0.0, 1200), (0.0, 3000)]
    kept = [windows(t0, n, tables) for t0, n in cases]
    fresh = []
    for t0, n in cases:
        common._TABLE_WINDOWS = (lambda: None, {})
        fresh.append(windows(t0, n, tables))
    for a, b in zip(kept, fresh):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(kept[0], kept[1]) and not np.array_equal(kept[0], kept[2])
    ref = weakref.ref(tables)
    del tables
    gc.collect()
    assert ref() is None
