"""Run every kernel variant on a tiny grid whose delays run off both ends of
the record; executed under Oclgrind by test_oclgrind.py.

Prints the device used and one line per variant with its largest relative
difference to the float64 reference.
"""

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from scenes import bandlimited_noise  # noqa: E402

from clbeam.imaging.engine import INTERP_MODES, BeamformInput, get_engine  # noqa: E402
from clbeam.imaging.engine.beams import BeamSampling  # noqa: E402
from clbeam.imaging.engine.opencl import device_has_fp64  # noqa: E402
from clbeam.imaging.raytrace import travel_time_tables  # noqa: E402
from clbeam.imaging.subcell import sums_at_points  # noqa: E402
from clbeam.model.grid import PolarGrid  # noqa: E402
from clbeam.model.svp import SoundSpeedProfile  # noqa: E402

data = bandlimited_noise((6, 160), seed=2)
data[2, 40:45] = np.nan
eo = np.zeros((6, 3))
eo[:, 1] = np.linspace(-1.5, 1.5, 6)
inp = BeamformInput(data, 40000.0, 0.0005, 1500.0, eo, np.array([0.0, 0.2, 0.1]), centre_frequency_hz=5500.0)
# rays through a strong gradient: some cells of the tiny grid unreachable
tabled = BeamformInput(data, 40000.0, 0.0005, 1500.0, eo, np.array([0.0, 0.2, 0.1]), centre_frequency_hz=5500.0,
                       tables=travel_time_tables(SoundSpeedProfile([0.0, 0.5], [1480.0, 1700.0]),
                                                 PolarGrid.regular(range_res_m=0.4, angle_res_deg=20, max_range_m=4.0,
                                                                   angles_deg=(-80, 80))))
weighted = BeamformInput(data, 40000.0, 0.0005, 1500.0, eo, np.array([0.0, 0.2, 0.1]), centre_frequency_hz=5500.0,
                         weights=np.array([0.1, 0.5, 1.0, 1.0, 0.5, 0.0]))
banded = replace(inp, band_hz=(2000.0, 9000.0))
# ranges from the source (delays before sample 0) to beyond the record's end
grid = PolarGrid.regular(range_res_m=0.4, angle_res_deg=20, max_range_m=4.0, angles_deg=(-80, 80))
ref = get_engine("reference")
precisions = ["float32"]
first = get_engine("opencl")
print("device:", first.label)
if device_has_fp64(first.device):
    precisions.append("float64")
from clbeam.imaging.engine.opencl import OpenCLEngine  # noqa: E402

# every precision with the CPU layout (16 lanes), and the GPU layout (1 lane, groups of 8) in float32
runs = [(p, (16, 1)) for p in precisions] + [("float32", (1, 8)), ("float32", (4, 2))]
for precision, layout in runs:
    eng = OpenCLEngine(precision=precision, layout=layout)
    for mode, spec in INTERP_MODES.items():
        if spec.kernel_id < 0:
            continue
        got = eng.beamform(inp, grid, interp=mode, outputs=("intensity", "cf", "sums"))
        want = ref.beamform(inp, grid, interp=mode, outputs=("intensity", "cf", "sums"))
        rel = np.linalg.norm(got.intensity - want.intensity) / np.linalg.norm(want.intensity)
        m_equal = np.array_equal(got.m, want.m)
        print(f"variant {precision} {layout} {mode} rel={rel:.2e} m_equal={m_equal} m_range={want.m.min()}-{want.m.max()}")
    # receive apodization (weights buffer, W output) and ray-traced tables in every mode of this layout
    for label, case in (("apodized", weighted), ("tables", tabled)):
        for mode, spec in INTERP_MODES.items():
            if spec.kernel_id < 0:
                continue
            got = eng.beamform(case, grid, interp=mode, outputs=("intensity", "cf", "sums"))
            want = ref.beamform(case, grid, interp=mode, outputs=("intensity", "cf", "sums"))
            rel = max(np.linalg.norm(got.intensity - want.intensity) / np.linalg.norm(want.intensity),
                      np.max(np.abs(got.cf - want.cf)))
            if case.weights is not None:
                rel = max(rel, np.max(np.abs(got.w - want.w)) / case.weights.sum())
            m_equal = np.array_equal(got.m, want.m)
            print(f"variant {label} {precision} {layout} {mode} rel={rel:.2e} m_equal={m_equal} "
                  f"m_range={want.m.min()}-{want.m.max()}")
    # beam-sampled imaging: the beam grid (beyond +-90 degrees), the beam-to-grid kernel, and the
    # cells it flags (NaN samples, the record's ends) imaged directly; against the reference's own
    beam_grid = PolarGrid.regular(range_res_m=0.4, angle_res_deg=1.0, max_range_m=4.0, angles_deg=(-80, 80))
    sampling = BeamSampling(1.25, 8)
    for label, case in (("beams", banded), ("beams-apodized", replace(weighted, band_hz=(2000.0, 9000.0)))):
        got = eng.beamform(case, beam_grid, interp="cubic", outputs=("intensity", "cf", "sums"), beams=sampling)
        want = ref.beamform(case, beam_grid, interp="cubic", outputs=("intensity", "cf", "sums"), beams=sampling)
        rel = max(np.linalg.norm(got.intensity - want.intensity) / np.linalg.norm(want.intensity),
                  np.max(np.abs(got.cf - want.cf)))
        m_equal = np.array_equal(got.m, want.m)
        print(f"variant {label} {precision} {layout} cubic rel={rel:.2e} m_equal={m_equal} "
              f"m_range={want.m.min()}-{want.m.max()}")
    # a band of ranges per angle (packed output cells), some angles without any
    n_win = beam_grid.shape[0]
    window = np.stack([np.linspace(0.2, 3.6, n_win), np.linspace(0.2, 3.6, n_win) + 1.3], axis=1)
    window[::7] = [1.0, -1.0]
    got = eng.beamform(banded, beam_grid, interp="cubic", outputs=("intensity", "cf", "sums"), beams=sampling,
                       range_window_m=window)
    want = ref.beamform(banded, beam_grid, interp="cubic", outputs=("intensity", "cf", "sums"), beams=sampling,
                        range_window_m=window)
    rel = max(np.linalg.norm(got.intensity - want.intensity) / np.linalg.norm(want.intensity),
              np.max(np.abs(got.cf - want.cf)), np.linalg.norm(got.s - want.s) / np.linalg.norm(want.s),
              np.linalg.norm(got.q - want.q) / np.linalg.norm(want.q))
    print(f"variant beams-window {precision} {layout} cubic rel={rel:.2e} m_equal={np.array_equal(got.m, want.m)} "
          f"m_range={want.m.min()}-{want.m.max()}")
    # the sums at arbitrary points (sub-cell peak refinement): one table entry per point, straight
    # rays or the grid's ray-traced tables interpolated; the last point lies beyond the record
    pts_r, pts_a = np.array([0.3, 1.7, 2.9, 4.0]), np.array([-75.0, -12.5, 33.3, 0.0])
    for label, case in (("points", inp), ("points-tables", tabled)):
        for mode in ("cubic", "lanczos8"):
            got = sums_at_points(eng, case, pts_r, pts_a, interp=mode, grid=grid, outputs=("intensity", "cf", "sums"))
            want = sums_at_points(ref, case, pts_r, pts_a, interp=mode, grid=grid,
                                  outputs=("intensity", "cf", "sums"))
            rel = max(np.linalg.norm(got.intensity - want.intensity) / np.linalg.norm(want.intensity),
                      np.max(np.abs(got.cf - want.cf)))
            m_equal = np.array_equal(got.m, want.m)
            print(f"variant {label} {precision} {layout} {mode} rel={rel:.2e} m_equal={m_equal} "
                  f"m_range={want.m.min()}-{want.m.max()}")
