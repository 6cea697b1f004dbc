"""Writing one paper-size ping's images (intensity and CF, 1601 x 3501 cells): uncompressed, deflated,
with the coherence factor packed in 16 bits, and both; each run's file size in ``extra_info``.

    .venv/bin/python -m pytest bench/test_bench_image_write.py --benchmark-enable
"""

import types

import numpy as np
import pytest

from clbeam.evaluation.bench import paper_grid
from clbeam.imaging.peaks import PingContext
from clbeam.io.images import ImageCompression, ImageWriter

GRID = paper_grid()


@pytest.fixture(scope="module")
def image():
    """A noisy image: exponential intensity (speckle) over a range decay, CF of 64 noise channels
    (about 1/64) with coherent patches."""
    rng = np.random.default_rng(0)
    n_a, n_r = GRID.shape
    decay = (1.0 + np.asarray(GRID.ranges_m)[None, :]) ** -2
    intensity = (rng.exponential(1.0, (n_a, n_r)) * decay).astype(np.float32)
    cf = rng.beta(1.0, 63.0, (n_a, n_r))
    cf[::97, ::53] = rng.uniform(0.3, 1.0, cf[::97, ::53].shape)
    return types.SimpleNamespace(intensity=intensity, cf=cf.astype(np.float32), cf_smooth=cf.astype(np.float32),
                                 sums=None, context=PingContext(index=0, centre_yz_m=(0.0, 0.0), draft_m=5.0),
                                 setting="")


@pytest.mark.parametrize("compression", [None, ImageCompression(1), ImageCompression(0, pack_cf=True),
                                         ImageCompression(1, pack_cf=True)],
                         ids=["uncompressed", "deflate1", "pack-cf", "deflate1+pack-cf"])
def test_write_one_paper_size_ping(benchmark, image, tmp_path, compression):
    path = tmp_path / "img.nc"

    def write():
        with ImageWriter(path, GRID, 1, ["intensity", "cf"], compression=compression) as w:
            w.write(0, image)

    benchmark.pedantic(write, rounds=3, iterations=1)
    benchmark.extra_info["file_mb"] = path.stat().st_size / 1e6
    assert path.stat().st_size > 0
