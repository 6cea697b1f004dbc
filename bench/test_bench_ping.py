"""Whole ping (raw samples → intensity, CF, smoothed CF, peaks) per mode.

    .venv/bin/python -m pytest bench/test_bench_ping.py --benchmark-enable
"""

import numpy as np
import pytest
from scenes import point_ping, polar_point

from clbeam.evaluation.bench import paper_grid
from clbeam.imaging.imager import Imager, ImagingOptions

GRID = paper_grid()


@pytest.fixture(scope="module")
def raw_ping():
    rng = np.random.default_rng(1)
    targets = [polar_point(r, a) for r, a in zip(rng.uniform(240, 1000, 40), rng.uniform(-75, 75, 40))]
    ping = point_ping(targets, rng.uniform(0.5, 2, 40), record_s=1.5)
    ping.samples[:] += 1e-5 * rng.standard_normal(ping.samples.shape)
    return ping


@pytest.mark.parametrize("mode", ["linear", "cubic"])
@pytest.mark.parametrize("band", [None, (5.0, 40.0)])
def test_whole_ping(benchmark, engine, raw_ping, mode, band):
    imager = Imager(GRID, ImagingOptions(interp=mode, seabed_band_m=band, seabed_depth_m=225.0 if band else None),
                    engine=engine)
    imager.image(raw_ping)
    img = benchmark.pedantic(imager.image, args=(raw_ping,), rounds=3, iterations=1)
    assert img.cf.shape == GRID.shape
