"""Travel times through a horizontally stratified ocean by ray tracing.

The sound speed depends on depth only (:class:`SoundSpeedProfile`: piecewise
linear between points, constant beyond the ends, with optional jumps at
horizontal interfaces such as the seabed).  A ray keeps its ray parameter
``p = sin(theta) / c`` (Snell's law, ``theta`` from nadir) through every
layer and across every jump; in a layer of constant gradient ``g`` it is an
arc of a circle of radius ``1 / (p |g|)``, in a layer of constant speed a
straight line.  Per layer, from depth ``a`` (speed ``c_a``, ``cos_a``) down
to ``b`` (``h = b - a``), the closed forms are written so that they hold for
``g = 0`` too and lose no digits for small ``p``, ``g`` or ``h``::

    X = p h (c_a + c_b) / (cos_a + cos_b)                  horizontal offset
    K = (c_a + c_b) / (c_b cos_a + c_a cos_b)
    L = h K asin(p g h K) / (p g h K)                      arc length
    T = log1p(g h (1 + K) / (c_a (1 + cos_b))) / g         travel time
      = h / (c cos)                                        (g = 0)

(``sin(theta_b - theta_a) = p g h K``; the usual ``(cos_a - cos_b) / (p g)``,
``(theta_b - theta_a) / (p g)`` and ``ln(tan(theta_b/2) / tan(theta_a/2)) / g``
after removing the cancellation.)

Eigenrays (:func:`eigenrays`): for every target at once, a safeguarded
Newton iteration solves ``X(p, z) = |y|``.  The unknown is
``t = tan(chi / 2)``, ``chi`` the elevation above the horizontal of a ray
launched with ``p = cos(chi) / c_max`` (``c_max`` the fastest speed between
source and target, so ``chi`` spans ``[0, pi/2]`` for every direct
downgoing ray; rational in ``t``, exact near the horizontal).  ``X``
increases with ``p``; targets beyond ``X(1 / c_max, z)`` can only be reached
past a turning point and are *unreachable* (NaN), never given a wrong
number; so are targets above their source, and targets level with it
unless the speed just below the source is constant (a horizontal ray).
The time is returned in the stationary (Legendre) form
``T(p) + p (|y| - X(p))``, whose error is second order in the residual.

:func:`travel_time_tables` evaluates this on a :class:`~clbeam.model.grid.PolarGrid`
(the paper's 8.8 M-cell grid in a few seconds), :func:`offset_time_approx`
is the per-element approximation a delay-and-sum kernel can use with those
tables, :func:`offset_time_exact` its exact counterpart,
:func:`element_travel_times` the exact element-to-scatterer times a
simulator needs and :func:`positioning_error` where an isospeed image puts a
target.  ``docs/raytrace.md`` gives the derivations and the measured errors.

The modules, each one job: :mod:`~clbeam.imaging.raytrace.layers` (the closed
forms summed over the layers a group of rays crosses),
:mod:`~clbeam.imaging.raytrace.newton` (the eigenray iteration),
:mod:`~clbeam.imaging.raytrace.rays` (:class:`Eigenrays`, :func:`eigenrays`
and the blocks they are solved in), :mod:`~clbeam.imaging.raytrace.tables`,
:mod:`~clbeam.imaging.raytrace.offsets` and
:mod:`~clbeam.imaging.raytrace.positioning`.
"""

# copies for reading: the solver reads its tolerances from clbeam.imaging.raytrace.newton
from clbeam.imaging.raytrace.newton import LOOSE_TOL_REL, MAX_ITERATIONS, X_TOL_REL
from clbeam.imaging.raytrace.offsets import (
    element_travel_times,
    offset_delay_m,
    offset_time_approx,
    offset_time_exact,
)
from clbeam.imaging.raytrace.positioning import PositioningError, positioning_error
from clbeam.imaging.raytrace.rays import BLOCK, LEVEL_REL, Eigenrays, eigenrays
from clbeam.imaging.raytrace.tables import TravelTimeTables, travel_time_tables
from clbeam.model.svp import Layer, SoundSpeedProfile

__all__ = [
    "BLOCK",
    "LEVEL_REL",
    "LOOSE_TOL_REL",
    "MAX_ITERATIONS",
    "X_TOL_REL",
    "Eigenrays",
    "Layer",
    "PositioningError",
    "SoundSpeedProfile",
    "TravelTimeTables",
    "eigenrays",
    "element_travel_times",
    "offset_delay_m",
    "offset_time_approx",
    "offset_time_exact",
    "positioning_error",
    "travel_time_tables",
]
