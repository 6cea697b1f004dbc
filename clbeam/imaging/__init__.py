"""The imaging chain of one ping: pulse compression and analytic signal,
earth frame, travel times (straight or ray-traced), the OpenCL and float64
engines, apodization, Hann smoothing, coherence peaks, MLH and stacking,
and the :class:`Imager` that runs them in order.  Imports :mod:`clbeam.io`
and :mod:`clbeam.model` below it, nothing above."""

from clbeam.lazy import lazy_exports

_EXPORTS = {
    "clbeam.imaging.engine": ("INTERP_MODES", "BeamformInput", "Sums", "get_engine"),
    "clbeam.imaging.imager": ("Imager", "ImagingOptions", "PingImage"),
    "clbeam.imaging.peaks": ("PingContext", "peak_rows", "peaks_from_images"),
    "clbeam.model.grid": ("PolarGrid",),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
