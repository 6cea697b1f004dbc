"""The data model: what a ping, a pulse, a sound-speed profile and an image
grid are, and positions on the WGS84 ellipsoid.  Pure data and arithmetic:
nothing here reads files or runs a device, and it imports only
:mod:`clbeam.constants` and :mod:`clbeam.errors`."""

from clbeam.model.grid import PolarGrid
from clbeam.model.ping import Ping
from clbeam.model.pulse import Pulse, lfm_replica
from clbeam.model.svp import SoundSpeedProfile

__all__ = ["Ping", "PolarGrid", "Pulse", "SoundSpeedProfile", "lfm_replica"]
