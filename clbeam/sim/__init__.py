"""Synthetic multibeam sub-bottom profiler pings: scenes, the simulator and its truth.

A scene (:class:`Scene`, loaded from the built-in TOML scenes or a file by
:func:`load_scene`) describes the sonar, the line, the ship's motion, the
water column, the seabed and the targets; :func:`simulate` renders its
pings as a ping-file dataset with truth variables, and :func:`write`
stores it.  :class:`Simulator` makes one ping at a time.  The modules are
split by what they synthesise; :mod:`clbeam.sim.simulator` lists them.
"""

from clbeam.lazy import lazy_exports

_EXPORTS = {
    "clbeam.sim.simulator": ("Scene", "Simulator", "list_scenes", "load_scene", "simulate", "write"),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(name for names in _EXPORTS.values() for name in names)
