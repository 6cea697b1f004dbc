"""Deprecated location of the Imager; kept for one release. Use :mod:`clbeam.imaging`."""

import warnings

from clbeam.imaging.imager import Imager, ImagingOptions, PingImage

warnings.warn("clbeam.imager is deprecated: import Imager, ImagingOptions and PingImage from clbeam.imaging",
              DeprecationWarning, stacklevel=2)

__all__ = ["Imager", "ImagingOptions", "PingImage"]
