"""Sums of delayed unit echoes on a lattice of frequencies, fast: a type-1 non-uniform FFT
(docs/detectability.md).

The echo of a pipe crossing obliquely is a sum over thousands of points along it, each at its own
delay: ``F(f_k) = Σ_p w_p e^(−2πi f_k t_p)`` at the band's ``K`` frequencies ``f_k = f_0 + k Δf``.
Evaluated directly that is ``K P`` complex exponentials.  :func:`lattice_sum` spreads the weights onto
a periodic grid of the phase ``x_p = Δf t_p`` (mod 1) with the "exponential of semicircle" kernel
(Barnett, Magland & af Klinteberg 2019, SIAM J. Sci. Comput. 41, C479), takes one FFT and divides by
the kernel's Fourier transform: ``P W`` operations and an FFT of ``2K`` points, with a relative error
about ``10^(1 − W)`` of ``Σ |w_p|`` for a kernel ``W`` grid cells wide on a grid twice as fine as the
modes need.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import sparse

#: kernel width (grid cells) and grid oversampling: error about 1e-11 of the weights' sum of moduli
KERNEL_WIDTH = 12
OVERSAMPLING = 2


@functools.lru_cache(maxsize=16)
def _kernel_transform(n_grid: int, n_modes: int, centre: int, width: int) -> np.ndarray:
    """``n_grid Ψ(m)`` at the modes ``m = −centre … n_modes − 1 − centre``: the kernel's Fourier
    transform (Gauss-Legendre over its support) times the grid size."""
    beta = 2.30 * width
    z, wq = np.polynomial.legendre.leggauss(4 * width + 32)
    phi = np.exp(beta * (np.sqrt(1.0 - z * z) - 1.0))
    alpha = 0.5 * width / n_grid                      # the kernel's half width in cycles of the phase
    m = np.arange(n_modes) - centre
    return n_grid * alpha * (np.cos(2 * np.pi * alpha * m[:, None] * z[None, :]) @ (wq * phi))


def lattice_sum(times_s, weights, f0_hz: float, df_hz: float, n_modes: int, *,
                width: int = KERNEL_WIDTH) -> np.ndarray:
    """``Σ_p w_p e^(−2πi f_k t_p)`` at ``f_k = f0_hz + k df_hz``, ``k = 0 … n_modes − 1``.

    Parameters
    ----------
    times_s : array_like
        ``(P,)`` delays ``t_p`` (s).
    weights : array_like
        ``(P,)`` or ``(P, J)`` complex weights: ``J`` sums over the same delays at once.
    f0_hz, df_hz : float
        The lattice's first frequency and its spacing (Hz).
    n_modes : int
        ``K``, the number of frequencies.
    width : int
        Kernel width (grid cells, even): the error is about ``10^(1 − width)`` of ``Σ_p |w_p|``.

    Returns
    -------
    numpy.ndarray
        ``(K,)`` or ``(K, J)`` complex.
    """
    t = np.asarray(times_s, dtype=np.float64)
    w = np.asarray(weights, dtype=np.complex128)
    flat = w.ndim == 1
    w = w.reshape(t.size, -1)
    centre = n_modes // 2
    n_grid = 2 * int(math.ceil(OVERSAMPLING * (n_modes + width) / 2))
    # shift the lattice to modes about 0 and the phase to cycles of the grid
    w = w * np.exp(-2j * np.pi * (f0_hz + centre * df_hz) * t)[:, None]
    xi = np.mod(df_hz * t, 1.0) * n_grid
    first = np.floor(xi).astype(np.int64) - width // 2 + 1
    cells = first[:, None] + np.arange(width)
    z = (cells - xi[:, None]) / (0.5 * width)
    kernel = np.exp(2.30 * width * (np.sqrt(np.maximum(1.0 - z * z, 0.0)) - 1.0))
    # the spreading as a sparse (grid x points) matrix, each column the kernel's cells about one point
    spread = sparse.csc_matrix((kernel.ravel(), np.mod(cells, n_grid).ravel(), np.arange(0, kernel.size + 1, width)),
                               shape=(n_grid, t.size))
    grid = (spread @ w).T
    spectrum = np.fft.fft(grid, axis=1)
    m = np.arange(n_modes) - centre
    out = (spectrum[:, np.mod(m, n_grid)] / _kernel_transform(n_grid, n_modes, centre, width)).T
    return out[:, 0] if flat else out
