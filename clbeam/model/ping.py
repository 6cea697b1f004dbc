"""One ping in memory: element time series, geometry, motion, pulse (docs/ping-format.md).

The reader (:mod:`clbeam.io.pingfile`) and the simulator build :class:`Ping`
objects; the imager consumes them.  Nothing here touches disk.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from clbeam.model.pulse import Pulse
from clbeam.model.svp import SoundSpeedProfile


@dataclass(frozen=True)
class Ping:
    """One ping: element time series, geometry, motion and pulse.

    Attributes
    ----------
    samples : numpy.ndarray
        ``(channel, sample)``: real pressure (``kind="raw"``) or complex
        pulse-compressed analytic signal (``kind="analytic"``).
    kind : str
        ``"raw"`` or ``"analytic"``.
    sample_rate_hz : float
        Sample rate (Hz); sample ``k`` is at ``t0_s + k / sample_rate_hz``.
    t0_s : float
        Time of sample 0 after transmit start (s).
    sound_speed_m_s : float
        Isospeed sound speed (m/s).
    element_pos_m : numpy.ndarray
        ``(channel, 3)`` receive elements ``x, y, z`` in the vessel frame (m).
    source_pos_m : numpy.ndarray
        ``(3,)`` transmit acoustic centre in the vessel frame (m).
    channel_valid : numpy.ndarray
        ``(channel,)`` bool, False for dead channels.
    roll_deg, heave_m : float
        Motion: roll (degrees, starboard down positive), heave (m, up positive).
    draft_m : float or None
        Depth of the array reference point below the sea surface (m): the
        earth frame's ``z`` plus the draft is the depth below the surface;
        ``None``: not given.
    svp : clbeam.imaging.raytrace.SoundSpeedProfile or None
        Sound-speed profile from ``svp_depth(svp)`` (m, earth-frame ``z``
        below the array reference point) and ``svp_speed(svp)`` (m/s).
    element_gain_db, element_phase_deg : numpy.ndarray or None
        ``(channel,)`` channel responses (dB, degree): the recorded analytic
        signal is ``10^(g/20) e^(j φ)`` times the true one (removed by
        calibration, :mod:`clbeam.imaging.apodization`).
    """

    samples: np.ndarray
    kind: str
    sample_rate_hz: float
    t0_s: float
    sound_speed_m_s: float
    element_pos_m: np.ndarray
    source_pos_m: np.ndarray
    channel_valid: np.ndarray
    roll_deg: float = 0.0
    heave_m: float = 0.0
    pitch_deg: float | None = None
    heading_deg: float | None = None
    latitude_deg: float | None = None
    longitude_deg: float | None = None
    time: np.datetime64 | None = None
    pulse: Pulse | None = None
    index: int = 0
    element_gain_db: np.ndarray | None = None
    element_phase_deg: np.ndarray | None = None
    svp: SoundSpeedProfile | None = None
    extras: dict = field(default_factory=dict)
    draft_m: float | None = None

    @property
    def n_channels(self) -> int:
        """Number of receive channels."""
        return self.samples.shape[0]

    @property
    def n_samples(self) -> int:
        """Samples per channel."""
        return self.samples.shape[1]

    @property
    def has_navigation(self) -> bool:
        """True when latitude and longitude are known."""
        return self.latitude_deg is not None and self.longitude_deg is not None
