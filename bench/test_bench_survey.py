"""Survey throughput (pytest-benchmark): pings per second of a simulated line.

What is timed: :func:`clbeam.survey.run_survey` on 24 pings of the
simulator's ``line1`` (64 channels, 40 534 samples: ranges to 760 m) in
three NetCDF files of 8 pings, imaged on the paper's grid (0.2 m x 0.1
degree, 0-700 m, ±80 degrees: 1601 x 3501 cells) with the seabed band
(5 m above to 40 m below the seabed, picked per ping), cubic interpolation,
float32 OpenCL on the default device; peaks always, images with
``--images``.  Each round starts from an empty output and ends with the
products (peak tables, objects, maps).

- ``in-process``: no Dask, one process;
- ``dask-1``, ``dask-2``: a Dask ``LocalCluster`` of 1 or 2 worker
  processes (one thread each, each with its own OpenCL context).

``extra_info`` holds the imaging rate (pings per second from the first task
to the last result: without starting the cluster and without the products)
and the time split per ping (read, compress, image, peaks, write; summed
over workers).  Every run's peaks must equal the in-process run's.

Run with ``pytest bench/test_bench_survey.py --benchmark-enable -s``; the
project's default ``--benchmark-disable`` runs each once as a smoke test.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from clbeam.imaging.imager import ImagingOptions
from clbeam.io.pingwrite import write_ping_file
from clbeam.model.grid import PolarGrid
from clbeam.sim import load_scene, simulate
from clbeam.survey import SurveyOptions, open_survey, run_survey

PINGS, PER_FILE = 24, 8
GRID = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, max_range_m=700.0, angles_deg=(-80.0, 80.0))
OPTIONS = ImagingOptions(interp="cubic", seabed_band_m=(5.0, 40.0))


@pytest.fixture(scope="module")
def line_files(tmp_path_factory):
    ds = simulate(load_scene("line1", pings=PINGS))
    d = tmp_path_factory.mktemp("bench-survey")
    return [write_ping_file(ds.isel(ping=slice(k, k + PER_FILE)), d / f"line1_{k // PER_FILE}.nc")
            for k in range(0, PINGS, PER_FILE)]


@pytest.fixture(scope="module")
def reference_peaks(line_files, tmp_path_factory):
    out = tmp_path_factory.mktemp("bench-ref") / "ref.zarr"
    run_survey(line_files, out, SurveyOptions(grid=GRID, imaging=OPTIONS))
    return open_survey(out, "peaks").load()


@pytest.mark.parametrize("workers, images", [(None, False), (1, False), (2, False), (None, True)],
                         ids=["in-process", "dask-1", "dask-2", "in-process-images"])
def test_bench_survey_line(benchmark, line_files, reference_peaks, tmp_path, workers, images):
    out = tmp_path / "survey.zarr"
    options = SurveyOptions(grid=GRID, imaging=OPTIONS, images=images)
    results = []

    def setup():
        shutil.rmtree(out, ignore_errors=True)

    def run():
        results.append(run_survey(line_files, out, options, workers=workers))

    benchmark.pedantic(run, setup=setup, rounds=1, iterations=1)
    res = results[-1]
    assert res.complete and res.n_imaged == PINGS, (res.n_imaged, res.n_done_before, [str(f) for f in res.failures])
    peaks = open_survey(out, "peaks").load()
    for col in ("ping", "range_m", "angle_deg", "cf", "intensity_db"):
        np.testing.assert_array_equal(peaks[col].values, reference_peaks[col].values)
    split_ms = {k[:-2]: 1e3 * v for k, v in res.time_per_ping_s.items()}
    benchmark.extra_info.update({"pings": PINGS, "grid": f"{GRID.shape[0]} x {GRID.shape[1]}",
                                 "workers": workers or 0, "images": images,
                                 "imaging_pings_per_s": round(res.pings_per_s, 3),
                                 "split_ms_per_ping": {k: round(v, 1) for k, v in split_ms.items()}})
    print(f"\n{benchmark.name}: {res.pings_per_s:.2f} pings/s imaging, "
          + ", ".join(f"{k} {v:.0f} ms" for k, v in split_ms.items()))
