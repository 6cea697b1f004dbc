"""Simulated surveys that check the detection-performance model: the same pipe at many horizontal ranges,
its measured detection fraction against the predicted Pd (docs/detectability.md, ``bench/detectability_eval.py``).

:func:`validation_scene` builds Line 4's environment (or a sand seabed) with pipes parallel to the track
(broadside to every ping) at the given ranges, one burial to starboard and another to port;
:func:`ping_peaks` simulates its pings and images a window around each pipe with the imager's default
detection test, on grids whose nodes lie a random fraction of a range step from the pipe's echo, drawn
anew for every ping (:func:`grid_fraction`).  :func:`score` counts the pings that detect each pipe two ways: a peak on the
pipe's equal-delay arc within :func:`arc_window` of its echo (what the model predicts: that the pipe
gives a peak), and a peak also placed within the scoring window of the pipe's image
(:data:`~clbeam.evaluation.scoring.HIT_HORIZONTAL_M`, :data:`~clbeam.evaluation.scoring.HIT_VERTICAL_M`).
"""

from __future__ import annotations

import importlib.resources
import math
import tomllib
from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.evaluation.detectability_stats import SEARCH_CELLS, Tests
from clbeam.evaluation.scoring import HIT_HORIZONTAL_M, HIT_VERTICAL_M
from clbeam.imaging.postprocess import HANN7

#: the seabeds of the validation: Line 4's mud as the paper describes it, and a sand (the simulator's
#: sediment is never faster than the water: its speed ratio stays 1)
SEABEDS = {
    "mud": {"seabed": {}, "scattering_db": -30.0, "snr_db": 15.0},
    "sand": {"seabed": {"sound_speed_ratio": 1.0, "density_ratio": 1.9, "attenuation_db_per_m": 0.25},
             "scattering_db": -22.0, "snr_db": 25.0},
}
#: half-sizes of the image window about each pipe (m of range, degree of angle): the clutter window's
CLUTTER_HALF = (11.0, 7.0)
#: pings simulated at a time (a ping depends only on the scene, the seed and its index)
BLOCK_PINGS = 8
#: the arc window's half-width in standard deviations of the threshold-level echo's direction
ARC_SIGMAS = 3.0
#: the image grid's steps (m of range, degree of angle)
RANGE_STEP_M, ANGLE_STEP_DEG = 0.2, 0.1


def validation_scene(seabed: str, ranges_m, burials_m=(1.0, 2.0), *, pings: int = 10, snr_db: float | None = None,
                     silent: bool = False, sides: str = "SP"):
    """Line 4's scene with broadside pipes at ``ranges_m`` (m): burial ``burials_m[0]`` to starboard,
    ``burials_m[1]`` to port, named ``S<range>`` and ``P<range>``.

    The two pipes of a range lie at the same horizontal range, so their slant ranges differ by less than the
    spread of either echo's arrival across the array (0.67 m against 1.29 m at 250 m): arriving from opposite
    sides, the two echoes meet on a few channels, and there the other pipe's echo adds to the incoherent sum
    of the coherence factor (docs/detectability.md, "Near ranges").  ``sides="S"`` or ``"P"`` keeps one side.

    Parameters
    ----------
    seabed : {"mud", "sand"}
        :data:`SEABEDS`.
    ranges_m : sequence of float
        Horizontal ranges (m).
    burials_m : (float, float)
        Burials of the starboard and port pipes (m).
    pings : int
        Pings of the line.
    snr_db : float, optional
        Noise re the nadir seabed echo (dB); default the seabed's in :data:`SEABEDS`.
    silent : bool
        Pipes of reflectivity 0: the same pings (seabed, noise, motion, the pipes' truth) without their
        echoes, on which a scoring window's false detections are counted.
    sides : str
        The sides that get pipes: ``"SP"`` (both), ``"S"`` (starboard) or ``"P"`` (port).
    """
    from clbeam.sim.catalog import scene_from_mapping

    require(seabed in SEABEDS, OptionError, f"seabed must be one of {', '.join(SEABEDS)}, got {seabed!r}")
    require(sides in ("SP", "S", "P"), OptionError, f"sides must be 'SP', 'S' or 'P', got {sides!r}")
    spec = SEABEDS[seabed]
    d = tomllib.loads((importlib.resources.files("clbeam.sim.scenes") / "line4.toml").read_text())
    d["seabed"].update(spec["seabed"])
    d["seabed"]["scattering"]["strength_db"] = spec["scattering_db"]
    d["snr_db"] = spec["snr_db"] if snr_db is None else snr_db
    d["survey"]["pings"] = pings
    h = d["seabed"]["depth_m"] - d["sonar"]["draft_m"]
    d["record"]["max_range_m"] = float(math.hypot(max(ranges_m), h + max(burials_m)) + 2 * CLUTTER_HALF[0])
    d["target"] = [{"kind": "line", "name": f"{side}{int(round(r))}", "y_m": sign * float(r), "angle_deg": 0.0,
                    "curvature_deg_per_km": 0.0, "radius_m": 0.11, "burial_m": float(b),
                    "reflectivity": 0.0 if silent else 0.8}
                   for side, sign, b in (("S", 1.0, burials_m[0]), ("P", -1.0, burials_m[1])) if side in sides
                   for r in ranges_m]
    return scene_from_mapping(d, name=f"{seabed}-validation")


def grid_fraction(seed: int, ping: int, index: int) -> float:
    """The offset (fraction of a range step, 0-1) of target ``index``'s image grid from its echo in ping
    ``ping`` drawn with ``seed``: uniform, as a surveyed pipe's range is, and the same whatever else is
    measured."""
    return float(np.random.default_rng([int(seed), 32, int(ping), int(index)]).random())


@dataclass(frozen=True)
class ArcWindow:
    """Where a peak counts as the pipe's: on its equal-delay arc, near its echo.

    Attributes
    ----------
    range_m : float
        Slant-range tolerance about the echo's range (m).
    sin_half : float
        Half-width along the arc in the sine of the angle from the array's broadside (roll included).
    """

    range_m: float
    sin_half: float

    def admits(self, echo: dict, peak: dict) -> bool:
        """Whether ``peak`` (``range_m``, ``angle_deg``: m, degree in the image frame) lies in the window
        about ``echo`` (the same, and the ping's ``roll_deg``)."""
        roll = math.radians(echo["roll_deg"])
        du = math.sin(math.radians(peak["angle_deg"]) + roll) - math.sin(math.radians(echo["angle_deg"]) + roll)
        return abs(peak["range_m"] - echo["range_m"]) <= self.range_m and abs(du) <= self.sin_half


def threshold_snr(tests: Tests, n_channels: int) -> float:
    """The per-channel signal-to-noise ratio (power ratio) of an echo whose own cell's CF, seen through the
    Hann smoothing's centre tap alone, reaches the smoothed-CF threshold: ``CF₀ = t / w₀`` with the mean
    ``CF₀ ≈ (M x + 1) / (M x + M)``, so ``x = (M CF₀ − 1) / (M (1 − CF₀))`` (2.9 for ``t`` 0.25, ``M`` 64)."""
    m = int(n_channels)
    cf0 = min(tests.threshold / float(np.max(HANN7)), 1.0 - 1e-9)
    return max((m * cf0 - 1.0) / (m * (1.0 - cf0)), 0.0)


def direction_sigma(scene, snr: float) -> float:
    """Cramér-Rao bound on the direction, as the sine of the angle from broadside, of a plane wave on the
    scene's receive array at per-channel signal-to-noise ratio ``snr``.

    The phase step per element of a complex exponential on ``M`` channels has variance at least
    ``6 / (x M (M² − 1))`` (Rife & Boorstyn 1974); the sine is the step times ``c / (2π f d)`` with ``d``
    the element pitch (m) and ``f`` the band's root-mean-square frequency (Hz).
    """
    so = scene.sonar
    m = int(so.n_elements)
    f0, f1 = so.pulse_f0_hz, so.pulse_f1_hz
    f_rms = math.sqrt((f1 ** 3 - f0 ** 3) / (3.0 * (f1 - f0)))
    sigma_step = math.sqrt(6.0 / (snr * m * (m * m - 1.0)))
    return scene.sound_speed_m_s * sigma_step / (2 * math.pi * f_rms * so.array_width_m / m)


def arc_window(scene, tests: Tests | None = None) -> ArcWindow:
    """The arc window of a scene's pipes (docs/detectability.md).

    Along range: the model's search, :data:`~clbeam.evaluation.detectability_stats.SEARCH_CELLS` grid
    cells either side of a node within half a cell of the echo, plus the half cell a refined peak moves
    from its node: ``(SEARCH_CELLS + 1) × step`` (0.6 m; the compressed pulse resolves ``c / 2B``, 0.11 m).
    Along the arc: :data:`ARC_SIGMAS` times :func:`direction_sigma` of an echo at :func:`threshold_snr`.
    """
    tests = Tests() if tests is None else tests
    snr = threshold_snr(tests, scene.sonar.n_elements)
    return ArcWindow((SEARCH_CELLS + 1) * tests.range_step_m, ARC_SIGMAS * direction_sigma(scene, snr))


def placed(echo: dict, peak: dict) -> bool:
    """Whether ``peak`` lies within the scoring window of the pipe's image (``y_m``, ``z_m``: m)."""
    return abs(peak["y_m"] - echo["y_m"]) <= HIT_HORIZONTAL_M and abs(peak["z_m"] - echo["z_m"]) <= HIT_VERTICAL_M


def _grid(echo: dict, fraction: float):
    """The image window about ``echo`` (``range_m``, ``angle_deg``): ``±CLUTTER_HALF``, its range nodes
    ``fraction`` of a step beyond the echo's (the echo lies that far short of a node)."""
    from clbeam.model.grid import PolarGrid

    start = echo["range_m"] - CLUTTER_HALF[0] + fraction * RANGE_STEP_M
    return PolarGrid(start + RANGE_STEP_M * np.arange(round(2 * CLUTTER_HALF[0] / RANGE_STEP_M)),
                     np.arange(echo["angle_deg"] - CLUTTER_HALF[1], echo["angle_deg"] + CLUTTER_HALF[1], ANGLE_STEP_DEG))


def _echoes(ds) -> list:
    """Each ping's echoes ``{target: echo}`` (:func:`ping_peaks`) from a simulated dataset's truth."""
    iy, iz = ds["truth_target_image_y"].values, ds["truth_target_image_z"].values
    roll = ds["roll"].values if "roll" in ds.variables else np.zeros(iy.shape[0])
    names = [str(v) for v in ds["target"].values]
    return [{name: {"range_m": math.hypot(iy[k, j], iz[k, j]), "angle_deg": math.degrees(math.atan2(iy[k, j], iz[k, j])),
                    "y_m": float(iy[k, j]), "z_m": float(iz[k, j]), "roll_deg": float(roll[k])}
             for j, name in enumerate(names)} for k in range(iy.shape[0])]


def ping_peaks(scene, *, seed: int = 0, progress=None) -> dict:
    """Every pipe's echo and the peaks imaged about it, ping by ping, each on a grid of its own sub-cell
    offset (:func:`grid_fraction`).

    The imager keeps its default detection test and images every cell directly with 8-tap Lanczos
    interpolation: the most accurate of the settings its default chooses among by measuring each new
    grid, which would cost seconds for every grid.

    Returns
    -------
    dict
        ``{target: [(echo, peaks), ...]}`` in ping order: ``echo`` the pipe's image (``range_m``,
        ``angle_deg``, ``y_m``, ``z_m``: m and degree in the heave- and roll-corrected frame) and the
        ping's ``roll_deg``; ``peaks`` the imager's peak rows (the same keys among others).
    """
    from clbeam.imaging.imager import Imager, ImagingOptions
    from clbeam.io.pingfile import pings_from_dataset
    from clbeam.sim import simulate

    options = ImagingOptions(interp="lanczos8", upsample=1)
    out: dict = {}
    for first in range(0, scene.survey.pings, BLOCK_PINGS):
        ds = simulate(scene, pings=list(range(first, min(first + BLOCK_PINGS, scene.survey.pings))), seed=seed)
        for k, (ping, echoes) in enumerate(zip(pings_from_dataset(ds), _echoes(ds))):
            for j, (name, echo) in enumerate(echoes.items()):
                imager = Imager(_grid(echo, grid_fraction(seed, first + k, j)), options)
                out.setdefault(name, []).append((echo, imager.image(ping).peaks))
            if progress is not None:
                progress(first + k)
    return out


def score(peaks: dict, window: ArcWindow) -> dict:
    """The pings that detect each pipe of :func:`ping_peaks`' result.

    Returns
    -------
    dict
        ``{target: {"arc": (hits, pings), "placed": (hits, pings)}}``: a peak in ``window`` on the pipe's
        arc; a peak in ``window`` that is also :func:`placed` within the image's scoring window.
    """
    out = {}
    for name, pings in peaks.items():
        arc = [[p for p in rows if window.admits(echo, p)] for echo, rows in pings]
        hits_arc = sum(bool(a) for a in arc)
        hits_placed = sum(any(placed(echo, p) for p in a) for (echo, _), a in zip(pings, arc))
        out[name] = {"arc": (hits_arc, len(pings)), "placed": (hits_placed, len(pings))}
    return out


def measure(scene, *, seed: int = 0, window: ArcWindow | None = None, progress=None) -> dict:
    """Detection fraction of every pipe of a :func:`validation_scene` over its pings, scored along the arc.

    Returns
    -------
    dict
        ``{target: (hits, pings)}`` (``window`` default :func:`arc_window`).
    """
    window = arc_window(scene) if window is None else window
    return {name: v["arc"] for name, v in score(ping_peaks(scene, seed=seed, progress=progress), window).items()}
