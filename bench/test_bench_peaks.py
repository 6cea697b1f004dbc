"""The peak stage of a paper-size ping at 10, 10^3 and 10^4 candidate maxima, and the images' read-back
(pytest-benchmark).

    .venv/bin/python -m pytest bench/test_bench_peaks.py --benchmark-enable

What is timed:

- ``test_peak_rows``: :func:`clbeam.imaging.peaks.peak_rows` on a smoothed CF and an intensity of the paper
  grid (0.2 m x 0.1 degree, 0-1100 m, ±80 degrees: 1601 x 5501 cells) holding ``n`` isolated maxima above
  the threshold, each 20 dB above an exponential noise floor (so every one passes the SNR test and has its
  clutter measured: the stage's worst case at that count): regional maxima, noise floor, clutter test,
  rows; ``refined`` adds the sub-cell refinement of every maximum (:func:`clbeam.imaging.subcell.subcell_peaks`
  on 64 channels of band-limited noise, linear interpolation, float32 OpenCL on the default device).
  Ten maxima have their clutter summed box by box; a thousand and more from the summed-area table of the
  band they cover, their echoes from sliding maxima along range (docs/bench.md, "The peak stage").
- ``test_readback``: one ``engine.beamform`` of the paper grid (intensity and CF, every cell directly, and
  beam-sampled) on a profiling engine; ``extra_info`` holds the bytes read back, their copies' device time
  and the throughput (GB/s).
"""

import dataclasses
import functools

import numpy as np
import pytest

from clbeam.evaluation.bench import paper_grid
from clbeam.imaging.engine import interp_mode
from clbeam.imaging.engine.beams import BeamSampling
from clbeam.imaging.engine.opencl import OpenCLEngine
from clbeam.imaging.peaks import PingContext, peak_rows
from clbeam.imaging.subcell import subcell_peaks

GRID = paper_grid()
CONTEXT = PingContext(index=0, centre_yz_m=(0.0, 0.0), n_channels=64)


def scene(n_maxima: int, seed: int = 0):
    """A smoothed CF of 0.1 with ``n_maxima`` cells of 0.6 at least 4 cells apart (each its own regional
    maximum) and an intensity of exponential noise (mean 1) with those cells at 100."""
    rng = np.random.default_rng(seed)
    lattice = np.stack(np.meshgrid(np.arange(2, GRID.shape[0] - 2, 4), np.arange(2, GRID.shape[1] - 2, 4),
                                   indexing="ij"), axis=-1).reshape(-1, 2)
    cells = lattice[rng.choice(len(lattice), n_maxima, replace=False)]
    cf = np.full(GRID.shape, 0.1, dtype=np.float32)
    cf[cells[:, 0], cells[:, 1]] = 0.6
    intensity = rng.exponential(1.0, GRID.shape).astype(np.float32)
    intensity[cells[:, 0], cells[:, 1]] = 100.0
    return cf, intensity


@pytest.mark.parametrize("refined", [False, True], ids=["grid", "refined"])
@pytest.mark.parametrize("n_maxima", [10, 1000, 10_000])
def test_peak_rows(benchmark, engine, paper_input, n_maxima, refined):
    cf, intensity = scene(n_maxima)
    # one data token, as the imager gives a ping: the engine uploads the channels once
    inp = dataclasses.replace(paper_input, data_token=object())
    refine = functools.partial(subcell_peaks, engine, inp, GRID, mode=interp_mode("linear"), cf_smooth=cf,
                               intensity=intensity, threshold=0.25) if refined else None
    rows = peak_rows(CONTEXT, cf, intensity, GRID, refine=refine)  # build the kernels once
    rows = benchmark.pedantic(peak_rows, args=(CONTEXT, cf, intensity, GRID), kwargs={"refine": refine},
                              rounds=3, iterations=1)
    benchmark.extra_info["rows"] = len(rows)
    if not refined:  # each maximum stands alone 20 dB above the noise: a row each
        assert len(rows) == n_maxima


@pytest.mark.parametrize("beams", [None, BeamSampling()], ids=["direct", "beam-sampled"])
def test_readback(benchmark, paper_input, beams):
    engine = OpenCLEngine(profiling=True)
    engine.beamform(paper_input, GRID, interp="linear", beams=beams)
    start = (engine.readback.n_bytes, engine.readback.device_s)
    benchmark.pedantic(engine.beamform, args=(paper_input, GRID), kwargs={"interp": "linear", "beams": beams},
                       rounds=3, iterations=1)
    n_bytes = (engine.readback.n_bytes - start[0]) / 3
    seconds = (engine.readback.device_s - start[1]) / 3
    benchmark.extra_info.update(read_mb=n_bytes / 1e6, read_ms=seconds * 1e3, read_gb_s=n_bytes / seconds / 1e9)
    assert n_bytes >= 2 * GRID.n_cells * 4  # the intensity and the CF in float32 at least
