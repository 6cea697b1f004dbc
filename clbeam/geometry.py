"""Deprecated location of :class:`PolarGrid` and the frame helpers; kept for one release.

Use :mod:`clbeam.model.grid` (``PolarGrid``) and :mod:`clbeam.imaging.geometry`
(``to_earth_frame``, ``roll_matrix``, ``check_positions``).
"""

import warnings

from clbeam.imaging.geometry import check_positions, roll_matrix, to_earth_frame
from clbeam.model.grid import PolarGrid

warnings.warn("clbeam.geometry is deprecated: import PolarGrid from clbeam.imaging (or clbeam.model.grid) and "
              "the frame helpers from clbeam.imaging.geometry", DeprecationWarning, stacklevel=2)

__all__ = ["PolarGrid", "check_positions", "roll_matrix", "to_earth_frame"]
