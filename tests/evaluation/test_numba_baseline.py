"""The benchmark's numba baseline computes what the reference computes."""

import numpy as np
from scenes import random_input

from clbeam.evaluation.baselines import numba_beamform
from clbeam.model.grid import PolarGrid


def test_numba_baseline_matches_reference_linear(ref_engine):
    inp = random_input(seed=21)
    grid = PolarGrid.regular(range_res_m=0.4, angle_res_deg=3, max_range_m=50, angles_deg=(-70, 70))
    inten, cf = numba_beamform(inp, grid)
    ref = ref_engine.beamform(inp, grid, interp="linear", outputs=("intensity", "cf"))
    # complex64 data and float32 outputs: relative error of a few float32 epsilons per channel
    assert np.linalg.norm(inten - ref.intensity) / np.linalg.norm(ref.intensity) < 1e-4
    assert np.abs(cf - ref.cf).max() < 1e-4
