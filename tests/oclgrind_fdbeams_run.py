"""Frequency-domain beams on a tiny grid whose ranges start in the array's near field and run past the
record's end, with skipped samples in one channel; executed under Oclgrind by test_fdbeams.py.

Prints the device used and one line per variant (precision, layout) with its largest relative difference
to the float64 reference engine imaging the same beams (NumPy steering, the same zones).
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from scenes import bandlimited_noise  # noqa: E402

from clbeam.imaging.engine import BeamformInput, get_engine  # noqa: E402
from clbeam.imaging.engine.beams import BeamSampling  # noqa: E402
from clbeam.imaging.engine.fdbeams import zone_plan  # noqa: E402
from clbeam.imaging.engine.opencl import OpenCLEngine, device_has_fp64  # noqa: E402
from clbeam.model.grid import PolarGrid  # noqa: E402

data = bandlimited_noise((6, 2400), seed=5)
data[2, 1500:1504] = np.nan
eo = np.zeros((6, 3))
eo[:, 1] = np.linspace(-0.3, 0.3, 6)
inp = BeamformInput(data, 40000.0, 0.0005, 1500.0, eo, np.array([0.0, 0.2, 0.1]), centre_frequency_hz=5500.0,
                    band_hz=(2000.0, 9000.0))
# 0-50 m: the near rows and those past the record (45 m) in time, the zones between in frequency
grid = PolarGrid.regular(range_res_m=0.1, angle_res_deg=2.0, max_range_m=50.0, angles_deg=(-80, 80))
sampling = BeamSampling(1.25, 8, domain="frequency")
ref = get_engine("reference")
want = ref.beamform(inp, grid, interp="cubic", outputs=("intensity", "cf", "sums"), beams=sampling)
first = get_engine("opencl")
print("device:", first.label)
precisions = ["float32"] + (["float64"] if device_has_fp64(first.device) else [])
runs = [(p, (16, 1)) for p in precisions] + [("float32", (1, 8)), ("float32", (4, 2))]
for precision, layout in runs:
    eng = OpenCLEngine(precision=precision, layout=layout)
    got = eng.beamform(inp, grid, interp="cubic", outputs=("intensity", "cf", "sums"), beams=sampling)
    rel = max(np.linalg.norm(got.intensity - want.intensity) / np.linalg.norm(want.intensity),
              np.max(np.abs(got.cf - want.cf)), np.linalg.norm(got.s - want.s) / np.linalg.norm(want.s))
    print(f"variant fd-beams {precision} {layout} rel={rel:.2e} m_equal={np.array_equal(got.m, want.m)} "
          f"m_range={want.m.min()}-{want.m.max()}")
plan_rows = zone_plan(inp, grid)   # the beams' ranges are the grid's
print(f"zones {plan_rows.n_zones} rows {plan_rows.bounds[0]}-{plan_rows.bounds[-1]} of {grid.shape[1]}")
