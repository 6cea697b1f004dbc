"""The beam-to-grid interpolation on an OpenCL device (kernels/beam_interp.cl).

The beam sums (a few hundred kilobytes to a few megabytes) are uploaded
once; the output grid is done in tiles of angle rows that fit the device,
like the delay-and-sum.  :func:`clbeam.imaging.engine.beams.interpolate_beams`
is the float64 NumPy form of the same computation, the oracle of the tests.
"""

from __future__ import annotations

import numpy as np

from clbeam.imaging.engine.beams import BeamPlan, consistent_supports
from clbeam.imaging.engine.clsupport import output_macros
from clbeam.model.grid import window_cells

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
    first = np.clip(np.asarray(out_windows[:, 0], dtype=np.int64), 0, n_r)
    lengths = np.clip(np.asarray(out_windows[:, 1], dtype=np.int64), first, n_r) - first
    out = _TileOutputs(engine, outs, weighted, n_a, n_r)
    for a0 in range(0, n_a, out.rows):
        na = min(out.rows, n_a - a0)
        rows = slice(a0, a0 + na)
        n_cells = int(lengths[rows].sum())
        if n_cells == 0:  # nothing of these angles in the window: their cells stay 0
            continue
        packed_first = np.r_[0, np.cumsum(lengths[rows])[:-1]]
        args = [engine.upload("tap0", plan.first_tap[rows].astype(np.int32)),
                engine.upload("tap_w", np.ascontiguousarray(plan.weights[rows], dtype=real)),
                engine.upload("bwin_first", first[rows].astype(np.int32)),
                engine.upload("bwin_end", (first[rows] + lengths[rows]).astype(np.int32)),
                engine.upload("bout_first", packed_first.astype(np.int32))]
        local = min(LOCAL_RANGES, n_r)
        width = int(lengths[rows].max())
        kernel(engine.queue, (-(-width // local) * local, na), (local, 1), *head, *args, *out.buffers(),
               np.int32(na), np.int32(n_cells))
        out.read(a0, first[rows], lengths[rows])
    engine.queue.finish()
    engine.readback.settle()
    out.settle()
    return out.arrays(), out.flagged()


class _TileOutputs:
    """Host arrays of the output grid (0 outside the windows), the flagged cells' indices, and the device
    buffers of one tile of angle rows, whose cells come back packed window after window."""

    NAMES = ("intensity", "cf", "s", "q", "m", "w", "flag")

    def __init__(self, engine, outs: frozenset, weighted: bool, n_a: int, n_r: int):
        self.engine, real = engine, engine.real
        self.n_r = n_r
        wanted = {"flag"} | ({"intensity"} & outs) | ({"cf"} & outs)
        if "sums" in outs:
            wanted |= {"s", "q", "m"} | ({"w"} if weighted else set())
        per_cell = sum(2 if n == "s" else 1 for n in wanted) * 8
        # the kernel's packed cell indices are 32-bit
        self.rows = max(1, min(engine.tile_rows(n_a, n_r, per_cell), (2**31 - 1) // max(n_r, 1)))
        self.full = {}
        for name in wanted - {"flag"}:  # the flags come back as the flagged cells' indices, not as a grid
            dtype = np.int32 if name == "m" else real
            self.full[name] = engine.host.zeros(((2,) if name == "s" else ()) + (n_a, n_r), dtype)
        itemsize = np.dtype(real).itemsize
        size = {"m": 4, "flag": 1}
        self.bufs = {name: engine.buffer("bout_" + name, (2 if name == "s" else 1) * self.rows * n_r
                                          * size.get(name, itemsize) if name in wanted else 16)
                     for name in self.NAMES}
        self._flagged: list = []
        self._tiles: list = []   # the tiles read but not settled

    def buffers(self) -> list:
        """The output buffers in the kernel's argument order."""
        return [self.bufs[name] for name in self.NAMES]

    def read(self, a0: int, first: np.ndarray, lengths: np.ndarray) -> None:
        """Queue the copies of a tile's packed cells (the windows ``[first, first + lengths)`` of rows ``a0 ..``):
        straight into the grid's rows where the windows are whole rows, else into packed host arrays that
        :meth:`settle` spreads into place; none waited for (the queue runs in order)."""
        na, n_cells = lengths.size, int(lengths.sum())
        whole = n_cells == na * self.n_r  # every cell: the packed layout is the grid's
        flags = self.engine.host.empty((n_cells,), np.uint8)
        self.engine.read_into(flags, self.bufs["flag"])
        packed = []
        for name, arr in self.full.items():
            planes = [arr[0, a0:a0 + na], arr[1, a0:a0 + na]] if name == "s" else [arr[a0:a0 + na]]
            for k, plane in enumerate(planes):  # contiguous rows
                dest = plane if whole else self.engine.host.empty((n_cells,), arr.dtype)
                self.engine.read_into(dest, self.bufs[name], k * n_cells * arr.itemsize)
                if not whole:
                    packed.append((plane, dest))
        # where the packed cells go in the tile's flattened rows
        spread = None if whole else window_cells(first, lengths, self.n_r)[0]
        self._tiles.append((a0, flags, spread, packed))

    def settle(self) -> None:
        """After the queue's ``finish``: the packed cells spread into the grid, the flagged cells listed."""
        for a0, flags, spread, packed in self._tiles:
            at = np.flatnonzero(flags)
            rows, cols = np.divmod(at if spread is None else spread[at], self.n_r)
            self._flagged.append(np.stack([rows + a0, cols]))
            for plane, dest in packed:
                plane.reshape(-1)[spread] = dest
        self._tiles = []

    def flagged(self) -> tuple[np.ndarray, np.ndarray]:
        """Angle and range indices of the flagged cells."""
        both = np.concatenate(self._flagged or [np.zeros((2, 0), dtype=np.int64)], axis=1)
        return both[0], both[1]

    def arrays(self) -> dict:
        """The outputs by name, ``s`` complex."""
        out = dict(self.full)
        if "s" in out:
            out["s"] = out["s"][0] + 1j * out["s"][1]
        return out
