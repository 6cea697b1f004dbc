"""The frequency-domain beams' steering sums on an OpenCL device (kernels/fdbeam.cl).

:func:`clbeam.imaging.engine.fdbeams.steer_numpy` is the float64 NumPy form of the same sums, the oracle of
the tests; the transforms stay on the host (NumPy/SciPy FFTs).
"""

from __future__ import annotations

import numpy as np

from clbeam.errors import GridError, require
from clbeam.imaging.engine.clsupport import pyopencl

#: bins per lane (each turned from the previous by one complex product)
BINS = 8


class ClSteering:
    """``steer(spectra, delays_cycles, first_bin)`` on an engine's device, as
    :func:`~clbeam.imaging.engine.fdbeams.steer_numpy` (in the engine's precision).

    Parameters
    ----------
    engine : OpenCLEngine
        Its context, queue, buffers, precision, program cache and layout (vector lanes, work-items per
        group: bin columns here, angles in the delay-and-sum) are used.
    """

    def __init__(self, engine):
        self.engine = engine
        cl = pyopencl()
        self.vec, local = engine.vec, engine.local
        self.kernel = engine.build("fd_steer", [f"-DBINS={BINS}", f"-DVEC={self.vec}"])
        limit = self.kernel.get_work_group_info(cl.kernel_work_group_info.WORK_GROUP_SIZE, engine.device)
        self.local = max(1, min(local, int(limit)))

    def __call__(self, spectra: np.ndarray, delays_cycles: np.ndarray, first_bin: int) -> np.ndarray:
        """``(n_beam, n_bin)`` complex128 steering sums of ``spectra`` ``(n_channel, n_bin)`` (complex) with
        ``delays_cycles`` ``(n_beam, n_channel)`` (cycles per bin), bins from ``first_bin``."""
        eng, real = self.engine, self.engine.real
        n_chan, n_bin = spectra.shape
        n_beam = delays_cycles.shape[0]
        require(delays_cycles.shape == (n_beam, n_chan), GridError,
                f"delays must be (n_beam, {n_chan}), got {delays_cycles.shape}")
        group = self.vec * self.local                 # columns per work-group
        stride = -(-n_bin // (BINS * group)) * group  # the launch's columns: whole work-groups
        require(2 * BINS * stride * max(n_chan, n_beam) < 2**31, GridError,
                f"{n_bin} bins x {max(n_chan, n_beam)} channels or beams exceed the kernel's indexing")
        n_pad = BINS * stride
        spec = np.empty((n_chan, 2, n_pad), dtype=real)
        spec[:, :, n_bin:] = 0
        spec[:, 0, :n_bin], spec[:, 1, :n_bin] = spectra.real, spectra.imag
        d = np.asarray(delays_cycles, dtype=np.float64)
        turn = 2 * np.pi * np.mod(stride * d, 1.0)
        step = np.stack([np.cos(turn), np.sin(turn)], axis=-1).astype(real)
        out_buf = eng.buffer("fd_out", n_beam * 2 * n_pad * np.dtype(real).itemsize)
        self.kernel(eng.queue, (stride // self.vec, n_beam), (self.local, 1), eng.upload("fd_spec", spec),
                    eng.upload("fd_delay", d.astype(real)), eng.upload("fd_step", step),
                    eng.upload("fd_lanes", np.arange(self.vec, dtype=real)), np.int32(n_chan), np.int32(stride),
                    np.int32(first_bin), out_buf)
        out = np.empty((n_beam, 2, n_pad), dtype=real)
        pyopencl().enqueue_copy(eng.queue, out, out_buf)
        result = np.empty((n_beam, n_bin), dtype=np.complex128)
        result.real, result.imag = out[:, 0, :n_bin], out[:, 1, :n_bin]
        return result
