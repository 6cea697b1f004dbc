"""Ping stacking: consecutive pings' sums combined into one image.

The ship moves about 8 m between pings, so a ping's coherent sum ``S`` is
not added coherently to the next one's; what is combined is, cell by cell,
over the last ``K`` pings ``p``:

    intensity = (1/K) Σ_p |S_p|^2                (incoherent average)
    CF        = Σ_p |S_p|^2 / Σ_p W_p Q_p        (CF from the stacked sums)

with ``W_p = M_p`` without apodization.  Every term obeys
``|S_p|^2 <= W_p Q_p``, so the stacked CF lies in [0, 1], and it lies
between the smallest and the largest of the pings' CFs (a mediant); a ping
whose cell got no channel adds nothing to either sum.  A target that stays
in its cell from ping to ping (a pipeline near the track direction) keeps
its coherence, while seabed scatterers, whose speckle changes from ping to
ping, average out: fewer false coherence peaks.
"""

from __future__ import annotations

import functools
from collections import deque
from dataclasses import dataclass

import numpy as np

from clbeam.constants import PEAK_THRESHOLD
from clbeam.errors import OptionError, require
from clbeam.imaging.engine.common import min_channels_of
from clbeam.imaging.postprocess import coherence_peaks, hann_smooth


@dataclass
class StackedImage:
    """The stack ending at one ping.

    Attributes
    ----------
    ping : int
        Index of the newest ping in the stack.
    pings : tuple of int
        The pings stacked (oldest first).
    intensity : numpy.ndarray
        Mean ``|S|^2`` over the stacked pings (squared input units), ``(n_angle, n_range)``.
    cf, cf_smooth : numpy.ndarray
        Stacked coherence factor and its 7-point Hann smoothing along range.
    threshold : float
        Coherence-peak threshold of :attr:`peaks`.
    """

    ping: int
    pings: tuple
    intensity: np.ndarray
    cf: np.ndarray
    cf_smooth: np.ndarray
    threshold: float = PEAK_THRESHOLD

    @functools.cached_property
    def peaks(self) -> np.ndarray:
        """``(n_peaks, 2)`` (angle, range) indices of the coherence peaks of
        ``cf_smooth`` (found on first use: the CLI makes its peak rows itself)."""
        return coherence_peaks(self.cf_smooth, self.threshold)


class PingStack:
    """Trailing stack of the last ``k`` pings' sums (``k = 1``: no stacking).

    Parameters
    ----------
    k : int
        Pings per stack; the first ``k - 1`` stacks hold the pings there are.
    threshold : float
        Coherence-peak threshold on the stacked, smoothed CF.
    min_channels : float
        A ping's cell adds to the stacked CF only when summed from at least
        this many channels (a count, or below 1 a fraction of its usable
        channels: :class:`~clbeam.imaging.imager.ImagingOptions`).

    Feed it the :class:`~clbeam.imaging.imager.PingImage` of consecutive pings
    imaged with the ``"sums"`` output on one grid; :meth:`add` returns the
    stack ending at that ping.
    """

    def __init__(self, k: int, threshold: float = PEAK_THRESHOLD, min_channels: float = 1):
        require(int(k) == k and k >= 1, OptionError, f"pings per stack must be an integer >= 1, got {k!r}")
        self.k = int(k)
        self.threshold = threshold
        self.min_channels = min_channels
        self._window: deque = deque(maxlen=self.k)
        self._shape = None

    def add(self, img) -> StackedImage:
        """Add one ping's image (with raw sums) and return the stack ending at it."""
        sums = img.sums
        require(sums is not None and sums.s is not None, OptionError,
                "ping stacking needs the raw sums: image with the 'sums' output")
        inten = np.abs(np.asarray(sums.s, dtype=np.complex128)) ** 2
        if self._shape is None:
            self._shape = inten.shape
        require(inten.shape == self._shape, OptionError,
                f"ping {img.ping}: image shape {inten.shape} differs from the stack's {self._shape}; one grid per stack")
        enough = sums.m >= min_channels_of(self.min_channels, img.n_channels_used)
        den = sums.coherence_denominator()
        if not enough.all():  # otherwise the CF numerator is the intensity itself: no second array held
            den *= enough
        self._window.append((img.ping, inten, inten if enough.all() else inten * enough, den))
        num = np.sum([w[2] for w in self._window], axis=0)
        den = np.sum([w[3] for w in self._window], axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            cf = np.where(den > 0, num / den, 0.0)
        cf_smooth = hann_smooth(cf)
        mean_intensity = np.sum([w[1] for w in self._window], axis=0) / len(self._window)
        return StackedImage(ping=img.ping, pings=tuple(w[0] for w in self._window), intensity=mean_intensity,
                            cf=cf, cf_smooth=cf_smooth, threshold=self.threshold)


def stacked_ping_image(img, stacked: StackedImage, peak_rows, *, keep_sums: bool = False):
    """``img`` (a :class:`~clbeam.imaging.imager.PingImage`) with its intensity, CF,
    smoothed CF and peaks replaced by the stack's; ``peak_rows(cf_smooth,
    intensity)`` makes the peak table rows; the ping's own raw sums are kept
    only with ``keep_sums``."""
    import dataclasses

    return dataclasses.replace(img, intensity=stacked.intensity, cf=stacked.cf, cf_smooth=stacked.cf_smooth,
                               sums=img.sums if keep_sums else None,
                               peaks=peak_rows(stacked.cf_smooth, stacked.intensity))
