"""A numba-parallel delay-and-sum: the CPU baseline of the benchmark.

Written the way a careful user would write it with numba for speed:
``prange`` over angles, float32 arithmetic with ``fastmath``, the
per-element geometry of an angle hoisted out of the range loop (a cell's
distance to a point is ``sqrt(R^2 - 2 R u.o + |o|^2)``, ``u.o`` once per
element and angle), the range loop innermost so the samples are read in
order and the loop vectorises, linear interpolation of the analytic signal
split into real and imaginary planes, the same sums and CF as the kernels.
Non-finite samples are zeroed once before the loops (``fastmath`` assumes
finite numbers), so they count in ``M``.  It is not a clbeam backend;
``clbeam bench`` times it against the OpenCL engine, and PyLops' Kirchhoff
migration (:func:`pylops_kirchhoff`) as a peer library.
"""

from __future__ import annotations

import warnings

import numpy as np

from clbeam.imaging.engine.common import BeamformInput
from clbeam.model.grid import PolarGrid


def _compile():
    import numba

    @numba.njit(parallel=True, fastmath=True, cache=False)
    def das(re, im, e_y, e_z, e_q, s_y, s_z, s_q, sin_a, cos_a, ranges, t0_samples, samples_per_m, intensity, cf):
        n_ch, n_s = re.shape
        n_r = ranges.size
        for ia in numba.prange(sin_a.size):
            sn, cs = sin_a[ia], cos_a[ia]
            base = np.empty(n_r, np.float32)
            p_src = s_y * sn + s_z * cs
            for ir in range(n_r):
                r = ranges[ir]
                base[ir] = np.sqrt(r * r - 2 * r * p_src + s_q) * samples_per_m - t0_samples
            sr = np.zeros(n_r, np.float32)
            si = np.zeros(n_r, np.float32)
            q = np.zeros(n_r, np.float32)
            m = np.zeros(n_r, np.int32)
            for n in range(n_ch):
                p = e_y[n] * sn + e_z[n] * cs
                oq = e_q[n]
                for ir in range(n_r):
                    r = ranges[ir]
                    pos = base[ir] + np.sqrt(r * r - 2 * r * p + oq) * samples_per_m
                    k = np.int32(pos)
                    if pos >= 0 and k + 1 < n_s:
                        t = pos - k
                        vr = re[n, k] + t * (re[n, k + 1] - re[n, k])
                        vi = im[n, k] + t * (im[n, k + 1] - im[n, k])
                        sr[ir] += vr
                        si[ir] += vi
                        q[ir] += vr * vr + vi * vi
                        m[ir] += 1
            for ir in range(n_r):
                inten = sr[ir] * sr[ir] + si[ir] * si[ir]
                intensity[ia, ir] = inten
                cf[ia, ir] = inten / (m[ir] * q[ir]) if (m[ir] > 0 and q[ir] > 0) else 0.0

    return das


_DAS = None


def numba_beamform(inp: BeamformInput, grid: PolarGrid) -> tuple[np.ndarray, np.ndarray]:
    """Linear-interpolation delay-and-sum with numba (intensity in the data's units squared, CF), float32."""
    global _DAS
    if _DAS is None:
        _DAS = _compile()
    n_a, n_r = grid.shape
    intensity = np.zeros((n_a, n_r), dtype=np.float32)
    cf = np.zeros((n_a, n_r), dtype=np.float32)
    data = np.nan_to_num(np.asarray(inp.data, dtype=np.complex64), nan=0.0, posinf=0.0, neginf=0.0)
    o = np.asarray(inp.element_offsets_m, dtype=np.float64)
    s = np.asarray(inp.source_offset_m, dtype=np.float64)
    th = np.deg2rad(grid.angles_deg)
    f32 = np.float32
    _DAS(np.ascontiguousarray(data.real), np.ascontiguousarray(data.imag), o[:, 1].astype(f32), o[:, 2].astype(f32),
         (o**2).sum(axis=1).astype(f32), f32(s[1]), f32(s[2]), f32((s**2).sum()), np.sin(th).astype(f32),
         np.cos(th).astype(f32), grid.ranges_m.astype(f32), f32(inp.t0_s * inp.sample_rate_hz),
         f32(inp.sample_rate_hz / inp.sound_speed_m_s), intensity, cf)
    return intensity, cf


def pylops_kirchhoff(inp: BeamformInput, y_m: np.ndarray, z_m: np.ndarray):
    """PyLops' Kirchhoff migration (the adjoint of its demigration, analytic straight rays, numba
    engine) of the channels on a Cartesian grid: the coherent sum ``S`` (complex, ``(len(y_m),
    len(z_m))``) from the adjoint of the real and of the imaginary part, and the operator.

    The peer computes what clbeam's sum ``S`` is, with linear interpolation: one source (the
    transmitter) and the elements as receivers in the cross-track plane, times from sample 0 at
    transmit (a record starting at ``t0 > 0`` is padded).  Positions are offsets from the grid
    centre (m); returns ``(S, seconds per adjoint pair)``.
    """
    import time

    from pylops.waveeqprocessing import Kirchhoff

    pad = int(round(inp.t0_s * inp.sample_rate_hz))
    data = np.nan_to_num(np.asarray(inp.data, dtype=np.complex128))
    data = np.pad(data, ((0, 0), (max(pad, 0), 0)))
    t = np.arange(data.shape[1]) / inp.sample_rate_hz
    o = np.asarray(inp.element_offsets_m, dtype=np.float64)
    s = np.asarray(inp.source_offset_m, dtype=np.float64)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)  # PyLops announces its v3 interface
        op = Kirchhoff(z=np.asarray(z_m, dtype=np.float64), x=np.asarray(y_m, dtype=np.float64), t=t,
                       srcs=np.array([[s[1]], [s[2]]]), recs=np.stack([o[:, 1], o[:, 2]]), vel=inp.sound_speed_m_s,
                       wav=np.array([1.0]), wavcenter=0, mode="analytic", engine="numba", dtype="float64")
    start = time.perf_counter()
    image = op.H @ data.real.ravel() + 1j * (op.H @ data.imag.ravel())
    seconds = time.perf_counter() - start
    return image.reshape(len(y_m), len(z_m)), seconds
