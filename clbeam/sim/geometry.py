"""Where everything is for one ping: positions after the ship's motion, and reflecting planes.

:func:`ping_geometry` places the receive elements, the source and the
transmit column of ping ``i`` in the earth frame (vessel axes, ``z`` down
along gravity, origin at the array reference point's mean position) after
the roll, pitch and heave of :class:`~clbeam.sim.scene.Motion`.
:func:`seabed_z` is the seabed's depth anywhere on the track;
:class:`Plane` mirrors points in the seabed, the sub-bottom and the sea
surface for the image-source echoes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from clbeam.imaging.geometry import to_earth_frame
from clbeam.sim.scene import Scene


@dataclass(frozen=True)
class PingGeometry:
    """Where everything is for one ping (earth frame: vessel axes, ``z`` down
    along gravity, origin at the array reference point's mean position).

    Attributes
    ----------
    index : int
        Ping index on the line.
    time_s : float
        Seconds since the first ping.
    along_m : float
        Distance run along the track since the first ping (m).
    roll_deg, pitch_deg, heave_m : float
        Motion (the signs of docs/ping-format.md).
    elements, source, centre : numpy.ndarray
        Receive elements ``(C, 3)``, source and array reference point (m).
    column : numpy.ndarray
        Unit vector along the transmit column (``x`` tilted by pitch).
    """

    index: int
    time_s: float
    along_m: float
    roll_deg: float
    pitch_deg: float
    heave_m: float
    elements: np.ndarray
    source: np.ndarray
    centre: np.ndarray
    column: np.ndarray


def ping_geometry(scene: Scene, index: int) -> PingGeometry:
    """Positions and motion of ping ``index`` of a scene's line.

    Parameters
    ----------
    scene : Scene
        Its sonar (element and source positions in the vessel frame, m),
        survey (ping interval, s; step along the track, m) and motion.
    index : int
        Ping index on the line.

    Returns
    -------
    PingGeometry
        Roll and heave move the elements and the source
        (:func:`clbeam.imaging.geometry.to_earth_frame`); pitch only tilts
        the transmit column.
    """
    sv = scene.survey
    time_s = index * sv.ping_interval_s
    roll, pitch, heave = scene.motion.at(time_s)
    elements = to_earth_frame(scene.sonar.element_positions_m(), roll_deg=roll, heave_m=heave)
    source_vessel = np.asarray(scene.sonar.source_offset_m, dtype=np.float64)
    source = to_earth_frame(source_vessel, roll_deg=roll, heave_m=heave)
    centre = to_earth_frame(np.zeros(3), roll_deg=roll, heave_m=heave)
    p = math.radians(pitch)
    column = np.array([math.cos(p), 0.0, -math.sin(p)])
    return PingGeometry(index=int(index), time_s=time_s, along_m=index * sv.step_m, roll_deg=roll,
                        pitch_deg=pitch, heave_m=heave, elements=elements, source=source, centre=centre,
                        column=column)


def seabed_z(scene: Scene, x_track_m, y_m) -> np.ndarray:
    """Depth of the (planar, sloped) seabed below the transducers' mean depth.

    Parameters
    ----------
    scene : Scene
        A scene with a seabed.
    x_track_m, y_m : float or array_like
        Track-frame position: along the track from the first ping's
        position, and to starboard (m).

    Returns
    -------
    numpy.ndarray
        Seabed ``z`` (m, earth frame, positive down).
    """
    sb = scene.seabed
    return (sb.depth_m - scene.sonar.draft_m + np.tan(np.deg2rad(sb.slope_along_deg)) * np.asarray(x_track_m)
            + np.tan(np.deg2rad(sb.slope_across_deg)) * np.asarray(y_m))


class Plane:
    """A plane ``(r - p0) · n = 0`` (``n`` unit, pointing down).

    Parameters
    ----------
    p0 : array_like
        A point of the plane ``(3,)``, earth frame (m).
    normal : array_like
        Its normal ``(3,)`` (normalised here, pointing down).
    """

    def __init__(self, p0, normal):
        self.p0 = np.asarray(p0, dtype=np.float64)
        n = np.asarray(normal, dtype=np.float64)
        self.n = n / np.linalg.norm(n)

    def mirror(self, p: np.ndarray) -> np.ndarray:
        """The mirror image of point ``p`` ``(3,)`` in the plane (m)."""
        return p - 2 * np.dot(p - self.p0, self.n) * self.n

    def shifted(self, distance_m: float) -> Plane:
        """The parallel plane ``distance_m`` (m) further along the normal."""
        return Plane(self.p0 + distance_m * self.n, self.n)
