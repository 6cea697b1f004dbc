"""Synthetic multibeam sub-bottom profiler pings: scenes, the simulator and its truth.

A scene (:class:`Scene`, loaded from the built-in TOML scenes or a file by
:func:`load_scene`) describes the sonar, the line, the ship's motion, the
water column, the seabed and the targets; :func:`simulate` renders its
pings as a ping-file dataset with truth variables, and :func:`write`
stores it.  :class:`Simulator` makes one ping at a time.  The modules are
split by what they synthesise; :mod:`clbeam.sim.simulator` lists them.
"""

from clbeam.sim.simulator import Scene, Simulator, list_scenes, load_scene, simulate, write

__all__ = ["Scene", "Simulator", "list_scenes", "load_scene", "simulate", "write"]
