"""The beam stage in the frequency domain against the time-domain beam stage, on the bench's paper ping.

    python bench/fd_beams.py [--repeats N]

The bench's Line 4 ping on the paper grid (0.2 m x 0.1 degree, 0-1100 m, +-80 degrees): the default
setting (``--interp auto``, measured on the ping's calibration echoes) gives the beams and the
time-domain stage (its mode on its upsampled channels; Lanczos-8 too, the most accurate time-domain
mode); the frequency-domain stage
(:mod:`clbeam.imaging.engine.fdbeams`, steering on the OpenCL device, transforms on the host) forms the
same sums on the same beams from the channels as recorded.  Both are timed in one run, best of
``--repeats``, after an untimed call that builds the kernels; the frequency-domain stage's time is split
into its steps.  Then both stages' errors on the ping's calibration echoes (the budget's measure) for three
beam samplings.  Prints the tables (markdown).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def _best(fn, repeats: int):
    fn()
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        runs.append(time.perf_counter() - t0)
    return min(runs), out


class _TimedSteering:
    """A steering function that adds its calls' time up."""

    def __init__(self, steer):
        self.steer, self.seconds = steer, 0.0

    def __call__(self, *args):
        t0 = time.perf_counter()
        out = self.steer(*args)
        self.seconds += time.perf_counter() - t0
        return out


def main(argv=None) -> None:
    """Time the beam stage in the time and the frequency domain on the bench ping (ms, best of ``--repeats``)
    and print their errors against the exact sums; ``argv``: the command line (default ``sys.argv``)."""
    from clbeam.evaluation.bench import paper_grid
    from clbeam.imaging.engine import get_engine
    from clbeam.imaging.engine.common import interp_mode
    from clbeam.imaging.engine.fdbeams import frequency_beam_sums, zone_plan
    from clbeam.imaging.engine.opencl_fdbeams import ClSteering
    from clbeam.imaging.imager import Imager, ImagingOptions
    from clbeam.io.pingfile import pings_from_dataset
    from clbeam.sim import load_scene, simulate

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    ping = pings_from_dataset(simulate(load_scene("line4", pings=1)), "line4").ping(0)   # the zoo's "bench"
    grid = paper_grid()
    engine = get_engine("opencl")
    imager = Imager(grid, ImagingOptions(), engine=engine)
    setting = imager.setting_of(ping)
    inp_td = imager.beamform_input(ping)
    inp_fd = Imager(grid, ImagingOptions(interp=setting.interp, upsample=1, beams=setting.beams),
                    engine=engine).beamform_input(ping)
    plan = engine._beam_plan(inp_td, grid, setting.beams, None)
    mode = interp_mode(setting.interp)
    outs = frozenset({"sums", "signature"})
    t_td, td = _best(lambda: engine._beamform(inp_td, plan.grid, mode, outs, plan.beam_window_m, 1.0), args.repeats)
    t_l8, _ = _best(lambda: engine._beamform(inp_fd, plan.grid, interp_mode("lanczos8"), outs, plan.beam_window_m,
                                             1.0), args.repeats)
    steer = _TimedSteering(ClSteering(engine))
    zones = zone_plan(inp_fd, plan.grid)

    def time_domain(rows_grid):
        return engine._beamform(inp_fd, rows_grid, interp_mode("lanczos4"), outs, None, 1.0)

    def fd_stage():
        steer.seconds = 0.0
        return frequency_beam_sums(inp_fd, plan.grid, time_domain=time_domain, steer=steer, zones=zones,
                                   window_m=plan.beam_window_m)

    t_fd, fd = _best(fd_stage, args.repeats)
    rows = slice(int(zones.bounds[0]), int(zones.bounds[-1]))
    diff = np.sum(np.abs(fd.s[:, rows] - td.s[:, rows]) ** 2) / np.sum(np.abs(td.s[:, rows]) ** 2)
    print(f"setting: {setting.describe()}")
    print(f"beams: {plan.grid.shape[0]} x {plan.grid.shape[1]} ranges; channels: {inp_fd.n_channels} at "
          f"{inp_fd.sample_rate_hz:g} Hz (time domain: {inp_td.sample_rate_hz:g} Hz)")
    print(f"zones: {zones.n_zones} over rows {zones.bounds[0]}-{zones.bounds[-1]} "
          f"({grid.ranges_m[zones.bounds[0]]:.1f}-{grid.ranges_m[zones.bounds[-1] - 1]:.1f} m), path error bound "
          f"{1e3 * zones.path_error_bound_m:.2f} mm")
    print("\n| beam stage | ms |\n|---|---:|")
    print(f"| time domain ({setting.interp} x{setting.upsample}) | {1e3 * t_td:.0f} |")
    print(f"| time domain (lanczos8 x1) | {1e3 * t_l8:.0f} |")
    print(f"| frequency domain, all | {1e3 * t_fd:.0f} |")
    print(f"| of which steering (OpenCL, with transfers) | {1e3 * steer.seconds:.0f} |")
    print(f"\nS on the zones' rows, frequency against time domain: {10 * np.log10(diff):.1f} dB")
    _accuracy(ping, inp_fd, grid, engine)


def _accuracy(ping, inp, grid, engine) -> None:
    """The errors of both stages on the ping's calibration echoes against their exact sums (the budget's
    measure, :class:`clbeam.imaging.budget.CalibrationScene`)."""
    from clbeam.imaging.budget import CalibrationScene
    from clbeam.imaging.engine.beams import BeamSampling

    scene = CalibrationScene(inp, grid, inp.band_hz, ping.pulse.replica(ping.sample_rate_hz))
    print("\n| beams | time domain (lanczos4) | frequency domain |\n|---|---|---|")
    for k, taps in ((1.5, 12), (2.0, 12), (2.0, 16)):
        row = [scene.measure_domain(engine, "lanczos4", BeamSampling(k, taps, domain=d)).describe()
               for d in ("time", "frequency")]
        print(f"| x{k:g}/{taps} | {row[0]} | {row[1]} |")


if __name__ == "__main__":
    main()
