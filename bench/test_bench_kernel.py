"""Kernel run time per interpolation mode on the paper grid (pytest-benchmark).

    .venv/bin/python -m pytest bench/test_bench_kernel.py --benchmark-enable

What is timed: one ``engine.beamform`` call (upload, kernel, read-back of
intensity and CF) for 64 channels on 0.2 m x 0.1 degree, 0-1100 m, ±80°.
"""

import pytest

from clbeam.evaluation.bench import paper_grid
from clbeam.imaging.engine import INTERP_MODES

GRID = paper_grid()


@pytest.mark.parametrize("mode", [m for m, s in INTERP_MODES.items() if s.kernel_id >= 0])
def test_kernel_paper_grid(benchmark, engine, paper_input, mode):
    engine.beamform(paper_input, GRID, interp=mode, outputs=("intensity", "cf"))  # build once
    res = benchmark.pedantic(engine.beamform, args=(paper_input, GRID),
                             kwargs={"interp": mode, "outputs": ("intensity", "cf")}, rounds=3, iterations=1)
    benchmark.extra_info["cells_ch_per_s"] = GRID.n_cells * paper_input.n_channels / benchmark.stats["min"]
    assert res.cf.shape == GRID.shape


def test_numba_baseline_paper_grid(benchmark, paper_input):
    from clbeam.evaluation.baselines import numba_beamform

    numba_beamform(paper_input, GRID)
    benchmark.pedantic(numba_beamform, args=(paper_input, GRID), rounds=2, iterations=1)
    benchmark.extra_info["cells_ch_per_s"] = GRID.n_cells * paper_input.n_channels / benchmark.stats["min"]
