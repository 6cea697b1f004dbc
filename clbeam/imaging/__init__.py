"""The imaging chain of one ping: pulse compression and analytic signal,
earth frame, travel times (straight or ray-traced), the OpenCL and float64
engines, apodization, Hann smoothing, coherence peaks, MLH and stacking,
and the :class:`Imager` that runs them in order.  Imports :mod:`clbeam.io`
and :mod:`clbeam.model` below it, nothing above."""

from clbeam.imaging.engine import INTERP_MODES, BeamformInput, Sums, get_engine
from clbeam.imaging.imager import Imager, ImagingOptions, PingImage
from clbeam.imaging.peaks import PingContext, peak_rows, peaks_from_images
from clbeam.model.grid import PolarGrid

__all__ = ["INTERP_MODES", "BeamformInput", "Imager", "ImagingOptions", "PingContext", "PingImage", "PolarGrid",
           "Sums", "get_engine", "peak_rows", "peaks_from_images"]
