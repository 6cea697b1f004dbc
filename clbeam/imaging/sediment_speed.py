"""Sediment interval velocity from the coherence of a sub-bottom reflector.

The idea of Holland & Pinson (2020): image the sub-bottom with candidate
sediment speeds (rays refracted at the seabed, :mod:`clbeam.imaging.raytrace`) and
keep the speed that makes a flat sub-bottom reflector most coherent.  With
a wrong speed a flat reflector is imaged at a depth that changes with the
angle: the sediment path at water angle ``θ`` is ``h / cos θ_s`` with
``sin θ_s = (c / c_w) sin θ``, so its apparent thickness scales like
``(c'/c) cos θ_s' / cos θ_s``, 1 % too fast at nadir and several per cent
too slow beyond 50°.  The reflector's coherence detections (coherence
peaks merged per main-lobe arc, :mod:`clbeam.imaging.mlh`) then spread in depth.

The coherence of the reflector, for one candidate speed, is the largest
CF-weighted density of its detections at one depth,

    K(c) = max_z Σ_d CF_d exp(-(z_d - z)² / (2 σ²)),

with ``σ`` the compressed pulse's range resolution ``c/(2B)``: the sum of
the coherence of the detections that line up at one depth.  The estimate
is the candidate of largest ``K``, refined by a parabola through it and its
neighbours.  Detections less than ``seabed_margin_m`` below the seabed are
left out (the seabed's own depth does not depend on the sediment speed).
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.mlh import pulse_range_resolution_m
from clbeam.model.grid import PolarGrid

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SpeedScan:
    """The coherence of the sub-bottom reflector against the sediment speed.

    Attributes
    ----------
    speeds_m_s : numpy.ndarray
        Candidate sediment speeds (m/s).
    coherence : numpy.ndarray
        ``K(c)``: CF-weighted density of detections at the best depth (CF units).
    reflector_depth_m : numpy.ndarray
        Depth (m, below the grid centre) where ``K`` peaks, per candidate.
    n_detections : numpy.ndarray
        Detections below the seabed per candidate.
    estimate_m_s : float
        Sediment speed of largest coherence, parabola-refined (m/s).
    """

    speeds_m_s: np.ndarray
    coherence: np.ndarray
    reflector_depth_m: np.ndarray
    n_detections: np.ndarray
    estimate_m_s: float

    def lines(self) -> list:
        """A printable table."""
        out = ["speed (m/s)  coherence  depth (m)  detections"]
        out += [f"{c:10.1f}  {k:9.2f}  {z:9.2f}  {n:10d}" for c, k, z, n in
                zip(self.speeds_m_s, self.coherence, self.reflector_depth_m, self.n_detections)]
        out.append(f"estimate: {self.estimate_m_s:.1f} m/s")
        return out


def reflector_coherence(depth_m: np.ndarray, cf: np.ndarray, sigma_m: float) -> tuple[float, float]:
    """``max_z Σ CF_d exp(-(z_d - z)² / 2σ²)`` and its depth ``z`` (m) for
    detections at depths ``depth_m`` with coherence ``cf``; ``(0, nan)``
    without detections."""
    z = np.asarray(depth_m, dtype=np.float64)
    w = np.asarray(cf, dtype=np.float64)
    if z.size == 0:
        return 0.0, float("nan")
    grid = np.arange(z.min() - 3 * sigma_m, z.max() + 3 * sigma_m, sigma_m / 10)
    dens = np.zeros(grid.size)
    for k in range(0, z.size, 256):  # bounded memory for many detections
        dens += (w[None, k:k + 256] * np.exp(-0.5 * ((grid[:, None] - z[None, k:k + 256]) / sigma_m) ** 2)).sum(axis=1)
    i = int(np.argmax(dens))
    return float(dens[i]), float(grid[i])


def refine_maximum(x: np.ndarray, y: np.ndarray) -> float:
    """``x`` of the largest ``y``, refined by the vertex of the parabola
    through it and its two neighbours (equally spaced ``x``)."""
    i = int(np.argmax(y))
    if i == 0 or i == len(y) - 1:
        return float(x[i])
    y0, y1, y2 = y[i - 1:i + 2]
    den = y0 - 2 * y1 + y2
    off = 0.0 if den >= 0 else float(np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5))
    return float(x[i] + off * (x[i + 1] - x[i]))


def _checked_speeds(speeds_m_s) -> np.ndarray:
    """The candidate speeds (m/s): at least 3, increasing, equally spaced."""
    speeds = np.asarray(speeds_m_s, dtype=np.float64)
    require(speeds.ndim == 1 and speeds.size >= 3, OptionError, "give at least 3 candidate sediment speeds")
    steps = np.diff(speeds)
    require(bool(np.all(steps > 0)) and np.allclose(steps, steps[0]), OptionError,
            "candidate sediment speeds must be increasing and equally spaced")
    return speeds


def _scan_options(base: ImagingOptions, seabed_depth_m: float, threshold: float, first_speed_m_s: float):
    """The scan's imaging options: ``base`` with the seabed depth, MLH, threshold and a sediment speed
    set (``base`` giving any of them itself is refused), and no clutter test: the reflector is an extended
    echo that fills the clutter window, not a compact target in it."""
    require(base.sediment_speed_m_s is None and base.seabed_band_m is None and base.seabed_depth_m is None
            and not base.mlh, OptionError, "the sediment-speed scan sets the sediment speed, seabed depth, MLH and "
            "seabed band itself: leave them out of its options")
    return dataclasses.replace(base, seabed_depth_m=float(seabed_depth_m), mlh=True, threshold=threshold,
                               min_contrast_db=None,
                               outputs=tuple(set(base.outputs) | {"intensity", "cf"}), sediment_speed_m_s=first_speed_m_s)


def scan_sediment_speed(ping, grid: PolarGrid, *, seabed_depth_m: float, speeds_m_s, options: ImagingOptions | None = None,
                        engine=None, backend: str | None = None, device=None, seabed_margin_m: float = 1.0,
                        threshold: float = 0.5, progress=None) -> SpeedScan:
    """Image ``ping`` with each candidate sediment speed and measure the
    coherence of its sub-bottom reflector (module docstring).

    Parameters
    ----------
    ping : Ping
        One ping whose grid window holds a flat sub-bottom reflector.
    grid : PolarGrid
        Image grid (a window from above the reflector to below it).
    seabed_depth_m : float
        Flat seabed depth below the grid centre (m), where rays refract.
    speeds_m_s : array_like
        Equally spaced candidate sediment speeds (m/s), within 1300-2000.
    options : ImagingOptions, optional
        Mode and the rest, without a sediment speed, seabed band, seabed
        depth or MLH (the scan sets them; options giving them are refused).
    engine : object, optional
        An engine to share across the candidates.
    backend, device : optional
        Engine backend and OpenCL device when no engine is given.
    seabed_margin_m : float
        Detections within this depth below the seabed are left out (m).
    threshold : float
        Coherence-peak threshold of the detections.
    progress : callable, optional
        Called with a message per candidate.
    """
    speeds = _checked_speeds(speeds_m_s)
    opts = _scan_options(options or ImagingOptions(), seabed_depth_m, threshold, float(speeds[0]))
    band = (ping.pulse.f0_hz, ping.pulse.f1_hz) if ping.pulse is not None and ping.pulse.f0_hz is not None else None
    sigma = pulse_range_resolution_m(tuple(sorted(band)), ping.sound_speed_m_s) if band else pulse_range_resolution_m()
    k, depth, count = [], [], []
    for c in speeds:
        if progress:
            progress(f"sediment speed {c:.0f} m/s")
        opts_c = dataclasses.replace(opts, sediment_speed_m_s=float(c))
        imager = Imager(grid, opts_c, engine=engine) if engine else Imager(grid, opts_c, backend=backend, device=device)
        engine = imager.engine
        img = imager.image(ping)
        centre_z = float(img.centre_yz_m[1])
        z = np.array([p["z_m"] for p in img.peaks]) - centre_z
        cf = np.array([p["cf"] for p in img.peaks])
        keep = z > seabed_depth_m + seabed_margin_m
        value, at = reflector_coherence(z[keep], cf[keep], sigma)
        k.append(value)
        depth.append(at)
        count.append(int(keep.sum()))
    k = np.array(k)
    require(k.max() > 0, OptionError, f"no coherence detection deeper than {seabed_margin_m:g} m below the seabed at "
            "any candidate speed; check --seabed-depth, the grid window and the threshold")
    est = refine_maximum(speeds, k)
    log.info("sediment speed scan: %.1f m/s", est)
    return SpeedScan(speeds, k, np.array(depth), np.array(count), est)
