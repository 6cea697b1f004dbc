"""The Lanczos kernel and the polynomial form of its tap weights that the float32 kernels evaluate.

With the fraction ``t`` of a sample position in ``[0, 1)``, tap ``m`` of
``2 A`` has offset ``x = t + A - 1 - m`` and weight ``L(x) = A sin(pi x)
sin(pi x / A) / (pi x)^2``.  Written in ``s = t - 1/2``, taps ``m`` and
``2 A - 1 - m`` are mirror images, ``w_m(s)`` and ``w_m(-s)``, so each pair
shares an even part ``E(s^2)`` and an odd part ``s O(s^2)``.  Fitting ``E``
and ``O`` with five coefficients each (degree 9 in ``s``) holds every weight
within about 1e-8 of ``L`` (1.6e-7 once evaluated in float32, which is
float32's own rounding), with no division and no sine: kernels/interp.h
holds these coefficients for ``A`` = 4 and 8.
"""

from __future__ import annotations

import numpy as np

#: coefficients per even and odd part (lowest power of ``s^2`` first)
N_COEFFICIENTS = 5


def lanczos(x: np.ndarray, lobes: int) -> np.ndarray:
    """The Lanczos kernel ``L(x)`` with ``lobes`` lobes (0 for ``|x| >= lobes``, 1 at 0); ``x`` in samples."""
    x = np.asarray(x, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        value = lobes * np.sin(np.pi * x) * np.sin(np.pi * x / lobes) / (np.pi * x) ** 2
    return np.where(x == 0, 1.0, np.where(np.abs(x) < lobes, value, 0.0))


def lanczos_polynomials(lobes: int, n_nodes: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares coefficients ``(even, odd)``, each ``(lobes, N_COEFFICIENTS)``, of the tap weights.

    ``w_m(s) = E_m(s^2) + s O_m(s^2)`` and ``w_{2A-1-m}(s) = E_m(s^2) - s O_m(s^2)`` for ``m < A``, with
    ``s = t - 1/2``; fitted on ``n_nodes`` Chebyshev nodes of ``s`` in ``[-1/2, 1/2]``.
    """
    k = np.arange(n_nodes)
    s = 0.5 * np.cos(np.pi * (k + 0.5) / n_nodes)
    powers = s[:, None] ** (2 * np.arange(N_COEFFICIENTS))[None, :]
    even = np.zeros((lobes, N_COEFFICIENTS))
    odd = np.zeros((lobes, N_COEFFICIENTS))
    for m in range(lobes):
        w, mirror = lanczos(s + lobes - 0.5 - m, lobes), lanczos(-s + lobes - 0.5 - m, lobes)
        even[m] = np.linalg.lstsq(powers, 0.5 * (w + mirror), rcond=None)[0]
        odd[m] = np.linalg.lstsq(powers * s[:, None], 0.5 * (w - mirror), rcond=None)[0]
    return even, odd


def polynomial_weights(t: np.ndarray, even: np.ndarray, odd: np.ndarray, dtype=np.float32) -> np.ndarray:
    """The ``(t.size, 2 A)`` tap weights at fractions ``t`` from the coefficients, evaluated in ``dtype`` with
    Horner's rule as the kernel does."""
    real = np.dtype(dtype).type
    s = (np.asarray(t, dtype=dtype).ravel() - real(0.5)).astype(dtype)
    u = (s * s).astype(dtype)
    lobes = even.shape[0]
    out = np.zeros((s.size, 2 * lobes), dtype=dtype)
    for m in range(lobes):
        e = np.zeros_like(s)
        o = np.zeros_like(s)
        for j in range(N_COEFFICIENTS - 1, -1, -1):
            e = (e * u + real(even[m, j])).astype(dtype)
            o = (o * u + real(odd[m, j])).astype(dtype)
        o = (s * o).astype(dtype)
        out[:, m], out[:, 2 * lobes - 1 - m] = e + o, e - o
    return out
