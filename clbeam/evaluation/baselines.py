"""A numba-parallel delay-and-sum: the CPU baseline of the benchmark.

Written the way a competent user would write it with numba: ``prange`` over
angles, straight-line distances with ``sqrt``, linear interpolation of the
complex64 analytic signal, the same sums and CF as the kernels.  It is not a
clbeam backend; ``clbeam bench`` times it against the OpenCL engine.
"""

from __future__ import annotations

import numpy as np

from clbeam.imaging.engine.common import BeamformInput
from clbeam.model.grid import PolarGrid


def _compile():
    import numba

    @numba.njit(parallel=True, fastmath=False, cache=False)
    def das(data, ey, ez, ex, sy, sz, sx, sin_a, cos_a, ranges, t0, fs, c, intensity, cf):
        n_ch, n_s = data.shape
        for ia in numba.prange(sin_a.size):
            s_a, c_a = sin_a[ia], cos_a[ia]
            for ir in range(ranges.size):
                y = ranges[ir] * s_a
                z = ranges[ir] * c_a
                d_src = np.sqrt(sx * sx + (y - sy) ** 2 + (z - sz) ** 2)
                acc = 0j
                q = 0.0
                m = 0
                for n in range(n_ch):
                    d = d_src + np.sqrt(ex[n] ** 2 + (y - ey[n]) ** 2 + (z - ez[n]) ** 2)
                    pos = (d / c - t0) * fs
                    k = int(np.floor(pos))
                    if k < 0 or k + 1 >= n_s:
                        continue
                    t = pos - k
                    v = data[n, k] + t * (data[n, k + 1] - data[n, k])
                    if not (np.isfinite(v.real) and np.isfinite(v.imag)):
                        continue
                    acc += v
                    q += v.real * v.real + v.imag * v.imag
                    m += 1
                inten = acc.real * acc.real + acc.imag * acc.imag
                intensity[ia, ir] = inten
                cf[ia, ir] = inten / (m * q) if (m > 0 and q > 0) else 0.0

    return das


_DAS = None


def numba_beamform(inp: BeamformInput, grid: PolarGrid) -> tuple[np.ndarray, np.ndarray]:
    """Linear-interpolation delay-and-sum with numba (intensity, CF), float32 outputs."""
    global _DAS
    if _DAS is None:
        _DAS = _compile()
    n_a, n_r = grid.shape
    intensity = np.zeros((n_a, n_r), dtype=np.float32)
    cf = np.zeros((n_a, n_r), dtype=np.float32)
    o = np.asarray(inp.element_offsets_m, dtype=np.float64)
    s = np.asarray(inp.source_offset_m, dtype=np.float64)
    th = np.deg2rad(grid.angles_deg)
    _DAS(np.ascontiguousarray(inp.data, dtype=np.complex64), o[:, 1].copy(), o[:, 2].copy(), o[:, 0].copy(),
         s[1], s[2], s[0], np.sin(th), np.cos(th), grid.ranges_m, inp.t0_s, inp.sample_rate_hz,
         inp.sound_speed_m_s, intensity, cf)
    return intensity, cf
