"""Stacking per-ping angular responses into seafloor patches (Fonseca et al. 2005).

A patch is the stack of ``N`` consecutive pings (Fonseca: 20–30, default
30) on one side (port or starboard), binned in incidence angle.  Stacking
averages **linear intensity** ``10^(S/10)`` over the pings, then returns
to dB.  Reason: the model predicts ``10 log10 <sigma>``, the log of the
*mean* cross section; speckle makes single-ping intensities roughly
exponential, and the mean of their dB values is biased low by
``10 log10(e) * Euler-gamma = 2.51 dB`` (and by a different amount for
partly developed speckle), whereas the linear mean is unbiased.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from clbeam.constants import AVO_PINGS_PER_PATCH
from clbeam.errors import OptionError, require

SIDES = ("port", "starboard")
DEFAULT_PINGS_PER_PATCH = AVO_PINGS_PER_PATCH


@dataclass(frozen=True)
class Patch:
    """One stacked angular response.

    Attributes
    ----------
    side : str
        ``"port"`` or ``"starboard"``.
    ping_start, ping_stop : int
        Pings ``[ping_start, ping_stop)`` of the survey stacked here.
    incidence_deg : numpy.ndarray
        Bin incidence angles (deg from vertical, >= 0).
    strength_db : numpy.ndarray
        Stacked backscatter strength per bin (dB); NaN where no ping had data.
    ping_count : numpy.ndarray
        Number of pings with finite data in each bin.
    along_track_m : float
        Mean along-track position of the stacked pings (m); NaN if unknown.
    """

    side: str
    ping_start: int
    ping_stop: int
    incidence_deg: np.ndarray
    strength_db: np.ndarray
    ping_count: np.ndarray
    along_track_m: float = float("nan")


def stack_linear_db(strength_db, axis: int = 0) -> np.ndarray:
    """Mean of ``10^(S/10)`` along ``axis``, back in dB; NaNs skipped.

    ``10 log10( mean_i 10^(S_i/10) )`` over finite entries; NaN where none.

    Parameters
    ----------
    strength_db : array_like
        Backscatter strengths (dB).
    axis : int
        Axis to average.
    """
    s = np.asarray(strength_db, dtype=np.float64)
    lin = np.where(np.isfinite(s), 10.0 ** (s / 10.0), 0.0)
    n = np.isfinite(s).sum(axis=axis)
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = lin.sum(axis=axis) / n
        return np.where(n > 0, 10.0 * np.log10(mean), np.nan)


def stack_pings(incidence_deg, strength_db, *, side: str,
                pings_per_patch: int = DEFAULT_PINGS_PER_PATCH,
                along_track_m=None, first_ping: int = 0,
                keep_partial: bool = True) -> list[Patch]:
    """Stack ``pings_per_patch`` consecutive pings of one side into patches.

    Parameters
    ----------
    incidence_deg : array_like
        Incidence angle of each bin (deg), ``(n_bin,)``; sign ignored.
    strength_db : array_like
        Per-ping angular responses (dB), ``(n_ping, n_bin)``; NaN = no data.
    side : {"port", "starboard"}
        Which side these responses are from.
    pings_per_patch : int
        ``N`` (Fonseca et al.: 20–30).
    along_track_m : array_like, optional
        Along-track position of each ping (m), ``(n_ping,)``.
    first_ping : int
        Survey index of the first row (for ``ping_start``/``ping_stop``).
    keep_partial : bool
        Keep a last patch of fewer than ``N`` pings.

    Returns
    -------
    list of Patch
        In ping order.
    """
    require(side in SIDES, OptionError, f"side must be one of {SIDES}, got {side!r}")
    require(isinstance(pings_per_patch, (int, np.integer)) and pings_per_patch >= 1, OptionError,
            f"pings_per_patch must be an integer >= 1, got {pings_per_patch!r}")
    inc = np.abs(np.asarray(incidence_deg, dtype=np.float64))
    s = np.asarray(strength_db, dtype=np.float64)
    require(s.ndim == 2 and s.shape[1] == inc.size, OptionError,
            f"strength_db must be (n_ping, {inc.size}) to match incidence_deg, got {s.shape}")
    pos = None
    if along_track_m is not None:
        pos = np.asarray(along_track_m, dtype=np.float64)
        require(pos.shape == (s.shape[0],), OptionError,
                f"along_track_m must have one value per ping ({s.shape[0]}), got shape {pos.shape}")
    patches = []
    for start in range(0, s.shape[0], pings_per_patch):
        stop = min(start + pings_per_patch, s.shape[0])
        if stop - start < pings_per_patch and not keep_partial:
            break
        block = s[start:stop]
        patches.append(Patch(
            side=side, ping_start=first_ping + start, ping_stop=first_ping + stop,
            incidence_deg=inc.copy(), strength_db=stack_linear_db(block, axis=0),
            ping_count=np.isfinite(block).sum(axis=0),
            along_track_m=float(np.nanmean(pos[start:stop])) if pos is not None else float("nan")))
    return patches


def stack_sides(incidence_deg, port_db, starboard_db, *,
                pings_per_patch: int = DEFAULT_PINGS_PER_PATCH, along_track_m=None,
                first_ping: int = 0, keep_partial: bool = True) -> list[Patch]:
    """Stack both sides: patches ordered by ping block, port before starboard.

    Parameters
    ----------
    incidence_deg : array_like
        Bin incidence angles (deg), ``(n_bin,)``, shared by both sides.
    port_db, starboard_db : array_like
        Per-ping responses (dB), ``(n_ping, n_bin)`` each.
    pings_per_patch, along_track_m, first_ping, keep_partial
        As in :func:`stack_pings`.
    """
    kw = dict(pings_per_patch=pings_per_patch, along_track_m=along_track_m,
              first_ping=first_ping, keep_partial=keep_partial)
    port = stack_pings(incidence_deg, port_db, side="port", **kw)
    stbd = stack_pings(incidence_deg, starboard_db, side="starboard", **kw)
    require(len(port) == len(stbd), OptionError,
            f"port and starboard must have the same number of pings, got {len(port)} and {len(stbd)} patches")
    return [p for pair in zip(port, stbd) for p in pair]
