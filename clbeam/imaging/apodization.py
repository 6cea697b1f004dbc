"""Receive apodization and element calibration.

Apodization weights ``w_n >= 0`` enter the coherent sum and the weighted
coherence factor

    S_w = Σ w_n p_n,   Q_w = Σ w_n |p_n|^2,   W = Σ w_n,
    CF_w = |S_w|^2 / (W Q_w),

the sums running over the channels that contribute to the cell (sample
inside the record, channel valid, value finite).  By the Cauchy-Schwarz
inequality on ``√w_n · √w_n p_n``, ``|S_w|^2 <= W Q_w``, so CF_w lies in
[0, 1]; it is 1 exactly when every contributing ``p_n`` is the same value
(a perfectly coherent, equal-amplitude arrival), whatever the window, and
with ``w_n = 1`` it is the coherence factor of Holland et al. (2024) eq. 2
with the 1/M of docs/imaging.md.

Element calibration: the ping file's optional ``element_gain_db(channel)``
and ``element_phase_deg(channel)`` describe each channel's response, i.e.
the recorded analytic signal is ``10^(g/20) e^(j φ)`` times the true one.
Calibration divides it out of the pulse-compressed analytic signal.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError, require

#: window names and their default parameter (None: no parameter)
WINDOWS = {"rect": None, "hann": None, "tukey": 0.5, "chebyshev": 40.0}


@dataclass(frozen=True)
class Window:
    """A receive window: ``name`` in :data:`WINDOWS` and its parameter
    (Tukey taper fraction alpha in [0, 1]; Dolph-Chebyshev sidelobe level in dB > 0)."""

    name: str = "rect"
    param: float | None = None

    @property
    def label(self) -> str:
        """``name`` or ``name:param``."""
        return self.name if self.param is None else f"{self.name}:{self.param:g}"

    @property
    def uniform(self) -> bool:
        """True for the rectangular window (all weights 1)."""
        return self.name == "rect"


def parse_window(spec: str | Window | None) -> Window:
    """A :class:`Window` from ``"rect"``, ``"hann"``, ``"tukey[:alpha]"`` or
    ``"chebyshev[:sidelobe_db]"`` (one-line error otherwise)."""
    if isinstance(spec, Window):
        return spec
    text = (spec or "rect").strip().lower()
    name, _, arg = text.partition(":")
    require(name in WINDOWS, OptionError,
            f"apodization window '{spec}' is unknown, expected one of rect, hann, tukey[:alpha], chebyshev[:dB]")
    if WINDOWS[name] is None:
        require(not arg, OptionError, f"apodization window '{name}' takes no parameter, got '{spec}'")
        return Window(name)
    try:
        param = float(arg) if arg else WINDOWS[name]
    except ValueError:
        raise OptionError(f"apodization window '{spec}': parameter '{arg}' is not a number") from None
    if name == "tukey":
        require(0.0 <= param <= 1.0, OptionError, f"Tukey alpha must be within 0-1, got {param:g}")
    else:
        require(10.0 <= param <= 200.0, OptionError, f"Chebyshev sidelobe level must be 10-200 dB, got {param:g}")
    return Window(name, param)


def receive_weights(window: str | Window, element_y_m: np.ndarray) -> np.ndarray:
    """Weights (``float64``, ``(channel,)``, peak 1) of ``window`` across the array.

    The window is sampled once per element in the order of the elements'
    across-track position ``element_y_m`` (m), for the whole array: a dead
    channel keeps its place and is simply left out of the sums, so the
    window's shape does not depend on which channels are alive.  Hann and
    Tukey are the symmetric windows of :mod:`scipy.signal.windows` on
    ``n + 2`` points without their zero ends (``0.5 (1 - cos(2π (k+1)/(n+1)))``
    for Hann), Dolph-Chebyshev is ``chebwin(n)``.
    """
    from scipy.signal import windows

    w = parse_window(window)
    y = np.asarray(element_y_m, dtype=np.float64)
    n = y.size
    if w.uniform or n == 1:
        return np.ones(n)
    # Hann and Tukey on n + 2 points without their two zero ends: every
    # element keeps a weight (a 2- or 3-element array is not silenced)
    if w.name == "hann":
        shape = windows.hann(n + 2, sym=True)[1:-1]
    elif w.name == "tukey":
        shape = windows.tukey(n + 2, alpha=w.param, sym=True)[1:-1]
    else:
        with warnings.catch_warnings():  # scipy's note on spectral analysis below 45 dB, not about arrays
            warnings.simplefilter("ignore", UserWarning)
            shape = windows.chebwin(n, at=w.param, sym=True)
    out = np.empty(n)
    out[np.argsort(y, kind="stable")] = shape / shape.max()
    return out


def calibration_factors(gain_db: np.ndarray | None, phase_deg: np.ndarray | None, n_channels: int) -> np.ndarray | None:
    """Complex factors ``10^(-g/20) e^(-j φ)`` (``(channel,)``) that remove
    each channel's gain ``g`` (dB) and phase ``φ`` (degree) from its analytic
    signal; ``None`` when the file gives neither."""
    if gain_db is None and phase_deg is None:
        return None
    g = np.zeros(n_channels) if gain_db is None else np.asarray(gain_db, dtype=np.float64)
    ph = np.zeros(n_channels) if phase_deg is None else np.asarray(phase_deg, dtype=np.float64)
    return 10.0 ** (-g / 20.0) * np.exp(-1j * np.deg2rad(ph))


def sidelobe_level_db(profile: np.ndarray, peak_index: int) -> float:
    """Peak sidelobe level (dB re the main lobe) of an angular intensity
    profile: the largest value beyond the main lobe's first minima on either
    side of ``peak_index``."""
    p = np.asarray(profile, dtype=np.float64)
    i = int(peak_index)
    left = i
    while left > 0 and p[left - 1] <= p[left]:
        left -= 1
    right = i
    while right < p.size - 1 and p[right + 1] <= p[right]:
        right += 1
    side = np.concatenate([p[:left], p[right + 1:]])
    require(side.size > 0, OptionError, "the profile holds no sidelobe beyond the main lobe")
    return float(10 * np.log10(side.max() / p[i]))
