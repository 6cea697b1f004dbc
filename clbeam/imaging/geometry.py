"""Frames and motion correction (docs/ping-format.md).

Vessel frame: ``x`` forward, ``y`` to starboard, ``z`` down, origin at the
array reference point.  The earth frame used for imaging has the same origin
and axes with ``z`` along gravity: roll rotates the array and the source about
``x`` (positive roll = starboard side down) and heave shifts them along ``z``
(positive heave = vessel up, so positions move to smaller ``z``).  Pitch is
ignored: the image is the 2-D cross-track plane ``x = 0``.
"""

from __future__ import annotations

import numpy as np

from clbeam.errors import GeometryError, require


def roll_matrix(roll_deg: float) -> np.ndarray:
    """Rotation about ``x`` taking vessel-frame vectors to the earth frame.

    Parameters
    ----------
    roll_deg : float
        Roll angle in degrees, positive when the starboard side is down.

    Returns
    -------
    numpy.ndarray
        3×3 matrix ``R`` with ``earth = R @ vessel``; a starboard point
        ``(0, 1, 0)`` goes to ``(0, cos φ, sin φ)``, i.e. down for ``φ > 0``.
    """
    phi = np.deg2rad(roll_deg)
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def to_earth_frame(positions_m: np.ndarray, *, roll_deg: float = 0.0,
                   heave_m: float = 0.0) -> np.ndarray:
    """Vessel-frame positions (``(..., 3)`` as ``x, y, z`` in metres) to the earth frame.

    Roll is applied about the frame origin (the array reference point), then
    heave (metres, positive up) is subtracted from ``z``.
    """
    pos = np.asarray(positions_m, dtype=np.float64)
    out = pos @ roll_matrix(roll_deg).T
    out[..., 2] -= heave_m
    return out


def check_positions(name: str, positions_m: np.ndarray) -> None:
    """Raise :class:`GeometryError` unless ``positions_m`` is a finite ``(..., 3)`` array."""
    p = np.asarray(positions_m)
    require(p.shape[-1:] == (3,), GeometryError, f"{name} must have 3 coordinates (x, y, z) per point, got shape {p.shape}")
    require(bool(np.all(np.isfinite(p))), GeometryError, f"{name} has non-finite coordinates")
