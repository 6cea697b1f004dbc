"""NumPy float64 reference backend: the oracle of every test.

Written for clarity: straight-line travel times ``(|r - s| + |r - e_n|) / c``
from plain square roots, each interpolation mode from its textbook formula,
the sums of Holland et al. (2024) eqs. 1–2 with the 1/M normalisation of CF
(``1/W`` with receive apodization, :mod:`clbeam.imaging.apodization`).
"""

from __future__ import annotations

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.imaging.engine.common import (
    EXACT_HALF_WIDTH,
    BeamformInput,
    Engine,
    InterpMode,
    Sums,
    baseband,
    carrier_phase,
    channel_signature,
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


class ReferenceEngine(Engine):
    """float64 NumPy delay-and-sum (same interface as the OpenCL engine).

    Parameters
    ----------
    precision : {"float64"} or None
        Only float64 (the reference's arithmetic); ``None`` means float64.
    device : None
        The reference runs on the CPU; a device is refused.
    """

    name = "reference"
    precision = "float64"

    def __init__(self, precision: str | None = None, device=None):
        require(precision in (None, "float64"), OptionError,
                f"the reference backend computes in float64 only, got precision '{precision}'")
        require(device is None, OptionError,
                f"the reference backend runs on the CPU; device {device!r} applies to the OpenCL backend only")

    def _beamform(self, inp: BeamformInput, grid: PolarGrid, mode: InterpMode, outs: frozenset,
                  range_window_m: np.ndarray | None, scale: float) -> Sums:
        """The sums over channels, cell block by cell block (see :meth:`Engine.beamform`)."""
        data = np.asarray(inp.data, dtype=np.complex128)
        if scale != 1.0:  # only finite data are scaled (amplitude_exponent is 0 when a sample is infinite)
            data = data * scale
        if mode.baseband:
            data = baseband(data, inp.centre_frequency_hz, inp.sample_rate_hz)
        computed = _computed(grid, range_window_m)
        acc = _accumulate(inp, data, _CellPaths.of_grid(inp, grid), mode, computed)
        return _results(acc, outs, grid.shape, inp.weights is not None, inp.min_channels)


def _computed(grid: PolarGrid, range_window_m) -> np.ndarray:
    """Cells to compute: the caller's window only (cells outside the record fall out by themselves)."""
    n_a, n_r = grid.shape
    if range_window_m is None:
        return np.ones(n_a * n_r, dtype=bool)
    win = user_windows(grid, range_window_m)
    j = np.arange(n_r)[None, :]
    return ((j >= win[:, :1]) & (j < win[:, 1:])).ravel()


def _accumulate(inp: BeamformInput, data: np.ndarray, paths: "_CellPaths", mode: InterpMode,
                computed: np.ndarray) -> dict:
    """``S, Q, M, W, G`` of the cells of ``paths`` (flat), block by block; cells not ``computed`` stay 0."""
    n_cells = computed.size
    acc = {"s": np.zeros(n_cells, dtype=np.complex128), "q": np.zeros(n_cells), "m": np.zeros(n_cells, dtype=np.int32),
           "w": np.zeros(n_cells), "g": np.zeros(n_cells)}
    signature = channel_signature(inp.n_channels)
    weights = np.ones(inp.n_channels) if inp.weights is None else np.asarray(inp.weights, dtype=np.float64)
    for b0 in range(0, n_cells, BLOCK_CELLS):
        sl = slice(b0, min(b0 + BLOCK_CELLS, n_cells))
        for n, pos in enumerate(paths.sample_positions(sl)):
            v = interpolate(data[n], pos, mode)
            if mode.baseband:
                v = v * _carrier(inp, pos)
            ok = np.isfinite(v) & computed[sl]
            v = np.where(ok, v, 0)
            acc["s"][sl] += weights[n] * v
            acc["q"][sl] += weights[n] * np.abs(v) ** 2
            acc["m"][sl] += ok
            acc["w"][sl] += weights[n] * ok
            acc["g"][sl] += signature[n] * ok
    return acc


class _CellPaths:
    """Fractional sample positions of every channel's echo from a block of cells (or points)."""

    def __init__(self, inp: BeamformInput, cell_y: np.ndarray, cell_z: np.ndarray, tables: dict | None = None):
        self.inp = inp
        self.cell_y, self.cell_z = cell_y, cell_z
        self.c = inp.sound_speed_m_s
        if tables is not None:
            # two-way time from the centre, and each point's ray direction and wavefront radius
            self.t_centre = 2.0 * np.ravel(tables["time_s"])
            self.ray_y, self.ray_z = np.ravel(tables["launch_sin"]), np.ravel(tables["launch_cos"])
            self.rho = np.ravel(tables["wavefront_radius_m"])
            self.c = float(tables["centre_speed_m_s"])
        self.tabled = tables is not None

    @classmethod
    def of_grid(cls, inp: BeamformInput, grid: PolarGrid) -> "_CellPaths":
        """The paths of every cell of ``grid`` (through ``inp.tables`` when given)."""
        th = np.deg2rad(grid.angles_deg)
        cell_y = (grid.ranges_m[None, :] * np.sin(th)[:, None]).ravel()
        cell_z = (grid.ranges_m[None, :] * np.cos(th)[:, None]).ravel()
        tables = None
        if inp.tables is not None:
            inp.check_tables(grid)
            tab = inp.tables
            tables = {"time_s": tab.time_s, "launch_sin": tab.launch_sin, "launch_cos": tab.launch_cos,
                      "wavefront_radius_m": tab.wavefront_radius_m, "centre_speed_m_s": tab.centre_speed_m_s}
        return cls(inp, cell_y, cell_z, tables)

    def sample_positions(self, sl: slice):
        """Yield, channel by channel, the sample positions ``(t - t0) fs`` for the cells ``sl``."""
        inp, c = self.inp, self.c
        if not self.tabled:  # straight rays: the path length from each point to the cell
            y, z = self.cell_y[sl], self.cell_z[sl]
            t_base = 0.0
        else:  # rays from the centre; a point's path differs by |rho u - o| - rho
            y, z = self.rho[sl] * self.ray_y[sl], self.rho[sl] * self.ray_z[sl]
            t_base = self.t_centre[sl] - 2 * self.rho[sl] / c
        so = np.asarray(inp.source_offset_m, dtype=np.float64)
        d_src = np.sqrt(so[0] ** 2 + (y - so[1]) ** 2 + (z - so[2]) ** 2)
        for o in inp.element_offsets_m:
            d_rx = np.sqrt(o[0] ** 2 + (y - o[1]) ** 2 + (z - o[2]) ** 2)
            yield (t_base + (d_src + d_rx) / c - inp.t0_s) * inp.sample_rate_hz


def _carrier(inp: BeamformInput, pos: np.ndarray) -> np.ndarray:
    """The carrier phase factor a basebanded value gets back at sample position ``pos``."""
    fs = inp.sample_rate_hz
    k = np.floor(pos)
    w = 2 * np.pi * inp.centre_frequency_hz / fs
    return np.exp(1j * (carrier_phase(inp.centre_frequency_hz, fs, np.where(np.isfinite(k), k, 0)) + w * (pos - k)))


def _results(acc: dict, outs: frozenset, shape: tuple, weighted: bool, min_channels: int = 1) -> Sums:
    """Intensity ``|S|^2``, CF ``|S|^2 / (W Q)`` (0 where ``W Q = 0`` or ``M < min_channels``) and the raw
    sums, as requested."""
    s, q, wsum = acc["s"], acc["q"], acc["w"]
    inten = np.abs(s) ** 2
    result = Sums()
    if "intensity" in outs:
        result.intensity = inten.reshape(shape)
    if "cf" in outs:
        with np.errstate(invalid="ignore", divide="ignore"):
            cf = np.where((wsum > 0) & (q > 0) & (acc["m"] >= min_channels), inten / (wsum * q), 0.0)
        result.cf = cf.reshape(shape)
    if "sums" in outs:
        result.s, result.q, result.m = s.reshape(shape), q.reshape(shape), acc["m"].reshape(shape)
        if weighted:
            result.w = wsum.reshape(shape)
    if "signature" in outs:
        result.signature = acc["g"].reshape(shape)
    return result
