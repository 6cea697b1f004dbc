"""NumPy float64 reference backend: the oracle of every test.

Written for clarity: straight-line travel times ``(|r - s| + |r - e_n|) / c``
from plain square roots, each interpolation mode from its textbook formula,
the sums of Holland et al. (2024) eqs. 1–2 with the 1/M normalisation of CF
(``1/W`` with receive apodization, :mod:`clbeam.imaging.apodization`).
"""

from __future__ import annotations

import numpy as np

from clbeam.imaging.engine.common import (
    EXACT_HALF_WIDTH,
    BeamformInput,
    InterpMode,
    Sums,
    baseband,
    carrier_phase,
    check_outputs,
    check_record_length,
    interp_mode,
    user_windows,
)
from clbeam.model.grid import PolarGrid

#: cells per block: bounds the reference's memory to a few hundred MB
BLOCK_CELLS = 1 << 18
KAISER_BETA = 12.0


def tap_weights(mode: InterpMode, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tap offsets ``m`` and weights ``w[m, cell]`` for fractions ``t`` in [0, 1).

    The interpolated value is ``Σ_m w[m] x[k + m]``.
    """
    name = mode.name
    if name == "nearest":
        return np.array([0]), np.ones((1,) + t.shape)
    if name in ("linear", "linear-bb"):
        return np.array([0, 1]), np.stack([1 - t, t])
    if name == "cubic":  # Keys (1981), a = -0.5
        a = -0.5
        m = np.array([-1, 0, 1, 2])
        x = np.abs(t[None, :] - m[:, None])
        w = np.where(x <= 1, (a + 2) * x**3 - (a + 3) * x**2 + 1,
                     np.where(x < 2, a * x**3 - 5 * a * x**2 + 8 * a * x - 4 * a, 0.0))
        return m, w
    if name.startswith("lanczos"):
        a = mode.lanczos_a
        m = np.arange(-(a - 1), a + 1)
        x = t[None, :] - m[:, None]
        return m, np.sinc(x) * np.sinc(x / a)
    if name == "exact":  # Kaiser-windowed sinc, 2 * EXACT_HALF_WIDTH taps
        h = EXACT_HALF_WIDTH
        m = np.arange(-(h - 1), h + 1)
        x = t[None, :] - m[:, None]
        win = np.i0(KAISER_BETA * np.sqrt(np.clip(1 - (x / h) ** 2, 0, None))) / np.i0(KAISER_BETA)
        return m, np.sinc(x) * win
    raise AssertionError(name)


def interpolate(channel: np.ndarray, pos: np.ndarray, mode: InterpMode) -> np.ndarray:
    """Interpolate one complex channel at fractional sample positions ``pos``.

    Returns complex values, NaN where the mode's support leaves the record.
    """
    if mode.name == "nearest":
        k = np.floor(pos + 0.5)
        t = np.zeros_like(pos)
    else:
        k = np.floor(pos)
        t = pos - k
    n = channel.shape[-1]
    inside = (k - mode.taps_before >= 0) & (k + mode.taps_after <= n - 1)
    k = np.where(inside, k, mode.taps_before).astype(np.int64)
    offsets, w = tap_weights(mode, t)
    val = np.zeros(pos.shape, dtype=np.complex128)
    with np.errstate(invalid="ignore", over="ignore"):  # non-finite samples give NaN, skipped below
        for j, m in enumerate(offsets):
            val += w[j] * channel[k + m]
    val[~inside] = np.nan
    return val


class ReferenceEngine:
    """float64 NumPy delay-and-sum (same interface as the OpenCL engine)."""

    name = "reference"
    precision = "float64"

    def beamform(self, inp: BeamformInput, grid: PolarGrid, *, interp: str = "linear",
                 outputs=("intensity", "cf"), range_window_m: np.ndarray | None = None) -> Sums:
        """Image one ping: sums ``S, Q, M`` and from them intensity and CF.

        Parameters
        ----------
        inp : BeamformInput
            Analytic channels and geometry (earth frame, offsets from the grid centre).
        grid : PolarGrid
            Image grid.
        interp : str
            Interpolation mode (:data:`clbeam.imaging.engine.INTERP_MODES`).
        outputs : iterable of str
            Any of ``"intensity"``, ``"cf"``, ``"sums"``.
        range_window_m : numpy.ndarray, optional
            ``(n_angle, 2)`` range interval (m) to compute per angle; others are 0.
        """
        mode = interp_mode(interp)
        check_record_length(inp, mode)
        outs = check_outputs(outputs)
        data = np.asarray(inp.data, dtype=np.complex128)
        if mode.baseband:
            data = baseband(data, inp.centre_frequency_hz, inp.sample_rate_hz)
        n_a, n_r = grid.shape
        th = np.deg2rad(grid.angles_deg)
        cell_y = (grid.ranges_m[None, :] * np.sin(th)[:, None]).ravel()
        cell_z = (grid.ranges_m[None, :] * np.cos(th)[:, None]).ravel()
        computed = np.ones(n_a * n_r, dtype=bool)
        if range_window_m is not None:
            # the caller's window only: cells outside the record fall out by themselves
            win = user_windows(grid, range_window_m)
            j = np.arange(n_r)[None, :]
            computed = ((j >= win[:, :1]) & (j < win[:, 1:])).ravel()
        s = np.zeros(n_a * n_r, dtype=np.complex128)
        q = np.zeros(n_a * n_r)
        m = np.zeros(n_a * n_r, dtype=np.int32)
        wsum = np.zeros(n_a * n_r)
        weights = np.ones(inp.n_channels) if inp.weights is None else np.asarray(inp.weights, dtype=np.float64)
        so = np.asarray(inp.source_offset_m, dtype=np.float64)
        fs, c = inp.sample_rate_hz, inp.sound_speed_m_s
        if inp.tables is not None:
            inp.check_tables(grid)
            tab = inp.tables
            # two-way time from the centre, and each point's ray direction and wavefront radius
            t_centre = 2.0 * tab.time_s.ravel()
            ray_y, ray_z = tab.launch_sin.ravel(), tab.launch_cos.ravel()
            rho = tab.wavefront_radius_m.ravel()
            c = tab.centre_speed_m_s
        w = 2 * np.pi * inp.centre_frequency_hz / fs
        for b0 in range(0, n_a * n_r, BLOCK_CELLS):
            sl = slice(b0, min(b0 + BLOCK_CELLS, n_a * n_r))
            if inp.tables is None:  # straight rays: the path length from each point to the cell
                y, z = cell_y[sl], cell_z[sl]
                t_base = 0.0
            else:  # rays from the centre; a point's path differs by |rho u - o| - rho
                y, z = rho[sl] * ray_y[sl], rho[sl] * ray_z[sl]
                t_base = t_centre[sl] - 2 * rho[sl] / c
            d_src = np.sqrt(so[0] ** 2 + (y - so[1]) ** 2 + (z - so[2]) ** 2)
            for n, o in enumerate(inp.element_offsets_m):
                d_rx = np.sqrt(o[0] ** 2 + (y - o[1]) ** 2 + (z - o[2]) ** 2)
                pos = (t_base + (d_src + d_rx) / c - inp.t0_s) * fs
                v = interpolate(data[n], pos, mode)
                if mode.baseband:
                    k = np.floor(pos)
                    v = v * np.exp(1j * (carrier_phase(inp.centre_frequency_hz, fs, np.where(np.isfinite(k), k, 0)) + w * (pos - k)))
                ok = np.isfinite(v) & computed[sl]
                s[sl] += weights[n] * np.where(ok, v, 0)
                q[sl] += weights[n] * np.where(ok, np.abs(np.where(ok, v, 0)) ** 2, 0)
                m[sl] += ok
                wsum[sl] += weights[n] * ok
        inten = np.abs(s) ** 2
        result = Sums()
        if "intensity" in outs:
            result.intensity = inten.reshape(n_a, n_r)
        if "cf" in outs:
            with np.errstate(invalid="ignore", divide="ignore"):
                cf = np.where((wsum > 0) & (q > 0), inten / (wsum * q), 0.0)
            result.cf = cf.reshape(n_a, n_r)
        if "sums" in outs:
            result.s, result.q, result.m = s.reshape(n_a, n_r), q.reshape(n_a, n_r), m.reshape(n_a, n_r)
            if inp.weights is not None:
                result.w = wsum.reshape(n_a, n_r)
        return result
