"""The two edges of an echo from off the ping's plane: how far off the plane a detection's echo came from.

The transmit column, ``L`` long along the track, radiates in a direction whose
cosine on its axis is ``u`` a box ``L |u| / c`` long (a line aperture's far
field).  Beyond the main lobe the box is longer than the compressed pulse, and
the image along range shows its two edges, of equal height, ``L |u| / 2``
apart, where an echo from the plane shows one peak.  A smooth pipe at a
heading returns from its nearest point, off the plane; a rough one mostly
from where it crosses the plane, its speckle several unequal peaks.
:class:`EdgeProbe` images a fine range profile about a detection from its
ping's channels and reads ``u`` from the edges' spacing
(:func:`edge_spacing_m`); the line search asks it only about the kept lines
its burials and fading leave undecided (docs/lines.md, How, step 6).
On a point scatterer 30 and 45 m off the plane at 250 m the spacing is 1.15
and 0.97 times ``L u / 2`` (the pulse's own sidelobes push close edges apart).
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.subcell import sums_at_points
from clbeam.io.pingfile import PingFile
from clbeam.model.grid import PolarGrid

log = logging.getLogger(__name__)

#: range profiled either side of a detection and its step (m): a detection sits on one edge, the other ``L u / 2``
#: away (0.6 m holds the second edge up to 1.4 times ``L u / 2`` for ``u`` to 0.24 with a 3.5 m column); 0.1 m peaks
PROFILE_HALF_M, PROFILE_STEP_M = 0.6, 0.01
#: angles profiled either side of it and their step (degree): the profile is the row through the maximum
PROFILE_HALF_DEG, PROFILE_STEP_DEG = 0.1, 0.02
#: two edges are the only maxima within this of the profile's top (dB), and within this of each other (dB)
EDGE_CLEAR_DB, EDGE_EQUAL_DB = 6.0, 3.0


def edge_spacing_m(profile: np.ndarray, step_m: float) -> float:
    """The spacing (m) of an intensity profile's two edges along range: its only two local maxima within
    :data:`EDGE_CLEAR_DB` of its top, within :data:`EDGE_EQUAL_DB` of each other, each at the vertex of the
    parabola through the logarithms of it and its neighbours; NaN otherwise (one peak, or speckle's several).
    ``profile``: intensities (any unit) every ``step_m`` m."""
    p = np.asarray(profile, dtype=np.float64)
    if p.size < 3 or not np.all(np.isfinite(p)) or p.max() <= 0:
        return math.nan
    inner = np.flatnonzero((p[1:-1] >= p[:-2]) & (p[1:-1] > p[2:])) + 1
    clear = inner[p[inner] >= p.max() * 10 ** (-EDGE_CLEAR_DB / 10)]
    if clear.size != 2 or p[clear].min() < p[clear].max() * 10 ** (-EDGE_EQUAL_DB / 10) \
            or p[clear].max() < p.max():  # the top at an end of the profile: a third peak beyond it
        return math.nan
    log_p = np.log(np.maximum(p, p.max() * 1e-12))

    def vertex(i: int) -> float:
        a, b, c = log_p[i - 1:i + 2]
        curve = a - 2 * b + c
        return i + (0.5 * (a - c) / curve if curve < 0 else 0.0)
    return abs(vertex(int(clear[1])) - vertex(int(clear[0]))) * step_m


class EdgeProbe:
    """``probe(pings, range_m, angle_deg) -> u``: the direction cosine off the ping's plane of each detection's
    echo, ``2 spacing / L`` from its edges (:func:`edge_spacing_m`), NaN where the profile shows no two edges or
    its ping cannot be read.

    Parameters
    ----------
    paths : sequence of path-like
        The survey's readable input files, in survey order (a ping's ``file_index``).
    file_index, file_ping : numpy.ndarray
        ``(n_pings,)`` each survey ping's file and its ping in the file.
    column_length_m : float
        The transmit column's length ``L`` along the track (m).
    grid : PolarGrid
        The survey's grid (its centre and, through a sound-speed profile, its travel-time tables).
    imaging : ImagingOptions, optional
        The survey's (sound speed, profile, apodization, channels): the profile is taken with them, its samples
        interpolated with the cubic and without beams.
    backend, device : str, optional
        The OpenCL backend and device (the survey's).
    """

    def __init__(self, paths, file_index: np.ndarray, file_ping: np.ndarray, column_length_m: float, *,
                 grid: PolarGrid, imaging: ImagingOptions | None = None, backend: str | None = None,
                 device: str | None = None):
        self.paths = [str(p) for p in paths]
        self.file_index, self.file_ping = np.asarray(file_index), np.asarray(file_ping)
        self.column_length_m = float(column_length_m)
        self.grid, self.backend, self.device = grid, backend, device
        self.imaging = dataclasses.replace(imaging or ImagingOptions(), interp="cubic", beams=None, upsample=None)
        self._files: dict = {}
        self._imager = None
        self._read: dict = {}  # (ping, range, angle) -> u

    def __call__(self, pings: np.ndarray, range_m: np.ndarray, angle_deg: np.ndarray) -> np.ndarray:
        u = np.full(len(pings), math.nan)
        try:
            for k, key in enumerate(zip((int(g) for g in pings), map(float, range_m), map(float, angle_deg))):
                if key not in self._read:  # a detection probed for another line (duplicates, joins): not imaged again
                    profile = self._profile(*key)
                    if profile is None:  # not profiled (a warning said why): tried again if asked again
                        continue
                    self._read[key] = 2 * edge_spacing_m(profile, PROFILE_STEP_M) / self.column_length_m
                u[k] = self._read[key]
        finally:
            self.close()
        return u

    def _profile(self, ping: int, range_m: float, angle_deg: float) -> np.ndarray | None:
        """The intensity along range through the maximum of a fine patch about ``(range_m, angle_deg)``; ``None``
        where it cannot be made (a warning says why: the products are written whatever the probe meets)."""
        index = int(self.file_index[ping])
        if not (0 <= index < len(self.paths)) or not (math.isfinite(range_m) and math.isfinite(angle_deg)):
            return None
        try:
            if index not in self._files:
                self._files[index] = PingFile(self.paths[index])
            data = self._files[index].ping(int(self.file_ping[ping]))
            if self._imager is None:  # one engine for every profile (cubic samples: -35 dB, no beams)
                self._imager = Imager(self.grid, self.imaging, backend=self.backend, device=self.device)
            ranges = range_m + np.arange(-PROFILE_HALF_M, PROFILE_HALF_M + PROFILE_STEP_M / 2, PROFILE_STEP_M)
            angles = angle_deg + np.arange(-PROFILE_HALF_DEG, PROFILE_HALF_DEG + PROFILE_STEP_DEG / 2,
                                           PROFILE_STEP_DEG)
            r, a = np.meshgrid(ranges, angles)
            sums = sums_at_points(self._imager.engine, self._imager.beamform_input(data), r, a, interp="cubic",
                                  grid=self.grid, outputs=("intensity",))
        except Exception as exc:  # an input moved or damaged since the run, no device: the probe says nothing
            log.warning("edge probe: ping %d of %s not profiled (%s)", int(self.file_ping[ping]), self.paths[index],
                        exc)
            return None
        intensity = np.asarray(sums.intensity, dtype=np.float64).reshape(r.shape)
        return intensity[int(np.argmax(np.max(intensity, axis=1)))]

    def close(self) -> None:
        """Close the input files opened."""
        for f in self._files.values():
            f.close()
        self._files = {}


#: the edges of a detection are its nearest point's when the ``u`` read from them is within these times the point's
#: (a point scatterer's read 1.15 times at u 0.12 and 0.97 times at 0.18: the pulse's sidelobes push close edges apart)
EDGE_RATIO = (0.8, 1.4)
#: the least ``u`` of a nearest point whose edges a profile resolves: ``L u / 2`` = 0.12 m for a 3.5 m column, the
#: 2-9 kHz pulse's peak about 0.1 m wide
EDGE_MIN_U = 0.07
#: detections probed a line at most, evenly along it; and the edges that must agree: at least this many, and this share
EDGE_PROBES, EDGE_MIN_AGREE, EDGE_MIN_SHARE = 12, 3, 1 / 3


def edges_from_nearest_point(probe, u_nearest: np.ndarray) -> bool:
    """Whether a line's echoes came from its nearest point off the plane: of up to :data:`EDGE_PROBES` of its
    detections whose nearest point lies at ``u_nearest`` of at least :data:`EDGE_MIN_U`, at least
    :data:`EDGE_MIN_AGREE` and :data:`EDGE_MIN_SHARE` of them show two edges whose ``u`` is within
    :data:`EDGE_RATIO` of it.  ``probe(index) -> u`` for indices into ``u_nearest`` (:class:`EdgeProbe`).

    On the tuning surveys (`--family tuning:12` and the built-in scenes, 8 detections a line) the smooth pipes'
    specular lines seen through the beam's edge showed 2-6 such edges, the rough pipes' lines at most 1.
    """
    u_nearest = np.asarray(u_nearest, dtype=np.float64)
    candidates = np.flatnonzero(u_nearest >= EDGE_MIN_U)
    if candidates.size < EDGE_MIN_AGREE:
        return False
    pick = np.unique(candidates[np.linspace(0, candidates.size - 1, min(EDGE_PROBES, candidates.size)).astype(int)])
    ratio = np.asarray(probe(pick), dtype=np.float64) / u_nearest[pick]
    agree = int(np.count_nonzero((ratio >= EDGE_RATIO[0]) & (ratio <= EDGE_RATIO[1])))
    return agree >= max(EDGE_MIN_AGREE, math.ceil(EDGE_MIN_SHARE * pick.size))
