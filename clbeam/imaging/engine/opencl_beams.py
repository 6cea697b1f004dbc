"""The beam-to-grid interpolation on an OpenCL device (kernels/beam_interp.cl).

The beam sums (a few hundred kilobytes to a few megabytes) are uploaded
once; the output grid is done in tiles of angle rows that fit the device,
like the delay-and-sum.  :func:`clbeam.imaging.engine.beams.interpolate_beams`
is the float64 NumPy form of the same computation, the oracle of the tests.
"""

from __future__ import annotations

import numpy as np

from clbeam.imaging.engine.beams import BeamPlan, consistent_supports
from clbeam.imaging.engine.clsupport import output_macros, pyopencl

#: work-items per work-group along range
LOCAL_RANGES = 64


def interpolate_beams_cl(engine, plan: BeamPlan, beam, outs: frozenset, out_windows: np.ndarray,
                         weighted: bool, min_channels: int = 1) -> tuple:
    """Output arrays by name and the flagged cells, as :func:`~clbeam.imaging.engine.beams.interpolate_beams`.

    Parameters
    ----------
    engine : OpenCLEngine
        Its context, queue, buffers, precision and program cache are used.
    plan, beam, outs, out_windows, weighted, min_channels
        As for :func:`~clbeam.imaging.engine.beams.interpolate_beams`.
    """
    real = engine.real
    n_a, n_r = out_windows.shape[0], plan.grid.shape[1]
    kernel = engine.build("beam_to_grid", [f"-DTAPS={plan.taps}", f"-DN_RANGE={n_r}", *output_macros(outs),
                                           f"-DAPODIZE={int(weighted)}", f"-DMIN_CHANNELS={int(min_channels)}"])
    s = np.stack([beam.s.real, beam.s.imag]).astype(real)
    head = [engine.upload("beam_s", s), engine.upload("beam_q", np.asarray(beam.q, dtype=real)),
            engine.upload("beam_m", np.asarray(beam.m, dtype=np.int32)),
            engine.upload("beam_w", np.asarray(beam.w if weighted else np.zeros(1), dtype=real)),
            engine.upload("beam_ok", consistent_supports(beam, plan.taps, weighted).view(np.uint8)),
            np.int32(plan.grid.shape[0])]
    out = _TileOutputs(engine, outs, weighted, n_a, n_r)
    for a0 in range(0, n_a, out.rows):
        na = min(out.rows, n_a - a0)
        rows = slice(a0, a0 + na)
        args = [engine.upload("tap0", plan.first_tap[rows].astype(np.int32)),
                engine.upload("tap_w", np.ascontiguousarray(plan.weights[rows], dtype=real)),
                engine.upload("bwin_first", np.ascontiguousarray(out_windows[rows, 0], dtype=np.int32)),
                engine.upload("bwin_end", np.ascontiguousarray(out_windows[rows, 1], dtype=np.int32))]
        local = min(LOCAL_RANGES, n_r)
        kernel(engine.queue, (-(-n_r // local) * local, na), (local, 1), *head, *args, *out.buffers(),
               np.int32(na))
        out.read(a0, na)
    engine.queue.finish()
    return out.arrays(), out.flag.astype(bool)


class _TileOutputs:
    """Host arrays of the output grid and the device buffers of one tile of angle rows."""

    NAMES = ("intensity", "cf", "s", "q", "m", "w", "flag")

    def __init__(self, engine, outs: frozenset, weighted: bool, n_a: int, n_r: int):
        self.engine, real = engine, engine.real
        self.n_r = n_r
        wanted = {"flag"} | ({"intensity"} & outs) | ({"cf"} & outs)
        if "sums" in outs:
            wanted |= {"s", "q", "m"} | ({"w"} if weighted else set())
        per_cell = sum(2 if n == "s" else 1 for n in wanted) * 8
        self.rows = engine.tile_rows(n_a, n_r, per_cell)
        self.full = {}
        for name in wanted:
            dtype = np.uint8 if name == "flag" else np.int32 if name == "m" else real
            self.full[name] = np.empty(((2,) if name == "s" else ()) + (n_a, n_r), dtype=dtype)
        itemsize = np.dtype(real).itemsize
        size = {"m": 4, "flag": 1}
        self.bufs = {name: engine.buffer("bout_" + name, (2 if name == "s" else 1) * self.rows * n_r
                                          * size.get(name, itemsize) if name in wanted else 16)
                     for name in self.NAMES}
        self.flag = self.full["flag"]

    def buffers(self) -> list:
        """The output buffers in the kernel's argument order."""
        return [self.bufs[name] for name in self.NAMES]

    def read(self, a0: int, na: int) -> None:
        """Copy a tile's results into rows ``a0 .. a0 + na``."""
        cl, queue = pyopencl(), self.engine.queue
        for name, arr in self.full.items():
            if name == "s":
                host = np.empty((2, na, self.n_r), dtype=arr.dtype)
                cl.enqueue_copy(queue, host, self.bufs[name], is_blocking=True)
                arr[:, a0:a0 + na] = host
            else:
                cl.enqueue_copy(queue, arr[a0:a0 + na], self.bufs[name], is_blocking=True)

    def arrays(self) -> dict:
        """The outputs by name, ``s`` complex."""
        out = {k: v for k, v in self.full.items() if k != "flag"}
        if "s" in out:
            out["s"] = out["s"][0] + 1j * out["s"][1]
        return out
