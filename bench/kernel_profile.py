"""What bounds the kernel on this machine: the same cells x channels and the
same arithmetic with the channel data spread over a large or a small
footprint, with one or all CPU threads.

    python bench/kernel_profile.py [--modes nearest linear cubic lanczos4]

The paper grid (0.2 m x 0.1 degree, 0-1100 m, ±80 degrees, 64 channels) is
imaged from band-limited noise.  "record" keeps the paper's 40 kHz record
(62 000 samples, 32 MB of float32 pairs: every cell's taps are a gather
from memory); "compact" multiplies the sound speed by 30, so the same
delays' arithmetic runs over 2 070 samples (1 MB, cache-resident).  If the
compact case is much faster, the sample gathers dominate; if it is not,
the per-cell, per-channel arithmetic does.  Each line is the best of 3.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

CHILD = "--child"


def run_child(modes, compact: bool) -> None:
    sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
    from scenes import bandlimited_noise, sbp_elements

    from clbeam.evaluation.bench import paper_grid
    from clbeam.imaging.engine import BeamformInput, get_engine

    c = 1500.0 * (30 if compact else 1)
    n = 2070 if compact else 62000
    data = bandlimited_noise((64, n), seed=0)
    inp = BeamformInput(data, 40000.0, 0.0, c, sbp_elements(64), np.zeros(3), centre_frequency_hz=5500.0)
    grid = paper_grid()
    eng = get_engine("opencl")
    for mode in modes:
        eng.beamform(inp, grid, interp=mode)
        best = min(_timed(lambda mode=mode: eng.beamform(inp, grid, interp=mode)) for _ in range(3))
        print(f"{mode} {best:.3f} {grid.n_cells * 64 / best:.3e}", flush=True)


def _timed(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--modes", nargs="+", default=["nearest", "linear", "cubic", "lanczos4"])
    ap.add_argument(CHILD, nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        run_child(args.modes, args.child[0] == "compact")
        return 0
    rows = {}
    for threads in (1, os.cpu_count() or 1):
        for layout in ("record", "compact"):
            env = dict(os.environ, POCL_MAX_PTHREAD_COUNT=str(threads), POCL_CPU_MAX_CU_COUNT=str(threads))
            out = subprocess.run([sys.executable, __file__, "--modes", *args.modes, CHILD, layout, str(threads)],
                                 env=env, capture_output=True, text=True, check=True).stdout
            for line in out.splitlines():
                mode, t, rate = line.split()
                rows[(mode, threads, layout)] = (float(t), float(rate))
    print("| mode | threads | record (s, cells·ch/s) | compact (s, cells·ch/s) | record / compact |")
    print("|---|---:|---:|---:|---:|")
    for mode in args.modes:
        for threads in (1, os.cpu_count() or 1):
            (tr, rr), (tc, rc) = rows[(mode, threads, "record")], rows[(mode, threads, "compact")]
            print(f"| {mode} | {threads} | {tr:.2f}, {rr:.2e} | {tc:.2f}, {rc:.2e} | {tr / tc:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
