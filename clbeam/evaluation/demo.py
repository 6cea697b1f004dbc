"""``clbeam demo``: the paper's Line 1 simulated, imaged and searched.

Simulates a few pings of the ``line1`` scene (three pipelines buried 1 m, to
port at about 275, 460 and 600 m in 230 m of water), writes them as a ping
file, images them on the paper's grid (0.2 m x 0.1 degree), smooths CF,
picks coherence peaks, writes figures like the paper's Fig. 4 and the peaks
table, and scores the detections against the simulated truth.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from clbeam.constants import MAP_THRESHOLD, PEAK_THRESHOLD
from clbeam.evaluation.scoring import HIT_HORIZONTAL_M
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.peaks import option_columns
from clbeam.io.figures import plot_cross_track
from clbeam.io.images import ImageWriter
from clbeam.io.peaks import write_peaks_csv
from clbeam.io.pingfile import PingFile
from clbeam.io.pingwrite import write_ping_file
from clbeam.io.schema import image_variables
from clbeam.model.grid import PolarGrid
from clbeam.sim import load_scene, simulate

log = logging.getLogger(__name__)

#: a detection is a coherence peak within this horizontal distance of a pipeline (m)
HIT_DISTANCE_M = HIT_HORIZONTAL_M


@dataclass
class TargetScore:
    """The best coherence peak near one target in one ping."""

    ping: int
    name: str
    y_m: float
    z_m: float
    peak_y_m: float = np.nan
    peak_z_m: float = np.nan
    cf: float = np.nan

    @property
    def offset_m(self) -> float:
        """Horizontal distance (m) of the peak from the target."""
        return abs(self.peak_y_m - self.y_m)

    @property
    def detected(self) -> bool:
        """True when the peak is within :data:`HIT_DISTANCE_M`."""
        return bool(np.isfinite(self.peak_y_m)) and self.offset_m <= HIT_DISTANCE_M


@dataclass
class DemoResult:
    """What the demo produced and measured."""

    scores: list
    other_peaks: list
    files: list
    timings_s: dict = field(default_factory=dict)


def score_targets(peaks: list, truth_y: np.ndarray, truth_z: np.ndarray, names, ping: int,
                  *, depth_window_m: float = 5.0) -> tuple[list, list]:
    """Match a ping's peaks to its targets.

    For each target the peak of highest CF within :data:`HIT_DISTANCE_M`
    horizontally and ``depth_window_m`` vertically is its detection (else the
    horizontally nearest peak in that depth window is reported as a miss);
    the peaks near no target are returned as the others.
    """
    scores, used = [], set()
    for name, ty, tz in zip(names, truth_y, truth_z):
        s = TargetScore(ping, str(name), float(ty), float(tz))
        near = [(k, p) for k, p in enumerate(peaks) if abs(p["z_m"] - tz) <= depth_window_m]
        hits = [(k, p) for k, p in near if abs(p["y_m"] - ty) <= HIT_DISTANCE_M]
        pick = max(hits, key=lambda kp: kp[1]["cf"]) if hits else (
            min(near, key=lambda kp: abs(kp[1]["y_m"] - ty)) if near else None)
        if pick is not None:
            s.peak_y_m, s.peak_z_m, s.cf = pick[1]["y_m"], pick[1]["z_m"], pick[1]["cf"]
        used.update(k for k, _ in hits)
        scores.append(s)
    others = [p for k, p in enumerate(peaks) if k not in used]
    return scores, others


def run_demo(out_dir="clbeam-demo", *, pings: int = 3, scene: str = "line1", interp: str = "auto",
             device=None, backend: str = "opencl", max_range_m: float = 700.0, progress=None) -> DemoResult:
    """Simulate, image, detect and draw; see the module docstring.

    Parameters
    ----------
    out_dir : path-like
        Folder for ``pings.nc``, ``images.nc``, ``peaks.csv`` and the PNGs.
    pings : int
        Pings to simulate (consecutive, 4 s apart).
    scene : str
        Built-in scene name or TOML file.
    interp : str
        Interpolation mode.
    max_range_m : float
        Largest slant range imaged (m).
    progress : callable, optional
        Called with a message per stage.
    """
    say = progress or (lambda msg: log.info(msg))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t = {}

    say(f"simulating {pings} ping(s) of '{scene}'")
    t0 = time.perf_counter()
    sc = load_scene(scene, pings=pings, max_range_m=max_range_m)
    ds = simulate(sc)
    ping_path = write_ping_file(ds, out / "pings.nc")
    t["simulate_s"] = time.perf_counter() - t0

    grid = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, max_range_m=max_range_m, angles_deg=(-80.0, 80.0))
    imager = Imager(grid, ImagingOptions(interp=interp), backend=backend, device=device)
    names = ds["target"].values if "target" in ds.coords else np.arange(ds.sizes.get("target", 0))
    scores, others, rows, files = [], [], [], [ping_path]
    for key in ("compress_s", "image_s", "postprocess_s", "figures_s"):
        t[key] = 0.0
    with PingFile(ping_path) as f, ImageWriter(out / "images.nc", grid, len(f), image_variables(imager.options.outputs),
                                                 {"scene": scene, "interp": interp,
                                                  "source_file": ping_path.name}) as writer:
        for ping in f:
            say(f"imaging ping {ping.index + 1}/{len(f)}")
            img = imager.image(ping)
            for k, v in img.timings_s.items():
                t[k] = t.get(k, 0.0) + v
            writer.write(ping.index, img)
            rows.extend(img.peaks)
            truth = truth_yz(ds, ping.index)
            s, o = score_targets(img.peaks, truth[:, 0], truth[:, 1], names, ping.index)
            scores += s
            others += o
            if ping.index == 0 or ping.index == len(f) - 1:
                t1 = time.perf_counter()
                files.append(_figure(out, img, ds, truth, sc, scene))
                t["figures_s"] += time.perf_counter() - t1
    columns = option_columns(refine=imager.options.refine_peaks, mlh=imager.options.mlh)
    files += [out / "images.nc", write_peaks_csv(rows, out / "peaks.csv", columns)]
    return DemoResult(scores, others, files, t)


def truth_yz(ds, ping: int) -> np.ndarray:
    """``(k, 2)`` where a straight-ray image shows each target of ``ping`` (nearest point, refraction),
    else its crossing of the image plane."""
    key = "truth_target_image" if "truth_target_image_y" in ds.variables else "truth_target"
    return np.stack([ds[f"{key}_y"].values[ping], ds[f"{key}_z"].values[ping]], axis=1)


def seabed_profile(scene, ds, ping: int):
    """The scene's seabed across ``ping``: ``z(y)`` (m, earth frame, of the cross-track offset ``y``, m), the
    simulation's nadir seabed depth ``truth_seabed_z`` sloping across the track as the scene's seabed does
    (``slope_across_deg``); ``None`` where the simulation has no seabed."""
    if scene.seabed is None or "truth_seabed_z" not in ds.variables:
        return None
    z0 = float(ds["truth_seabed_z"].values[ping])
    slope = math.tan(math.radians(scene.seabed.slope_across_deg))
    return lambda y: z0 + slope * np.asarray(y, dtype=np.float64)


def _figure(out: Path, img, ds, truth_yz: np.ndarray, sc, scene: str) -> Path:
    """The paper's Fig. 4-style figure of one ping, with the seabed as the scene has it and the targets."""
    png = out / f"ping{img.ping:03d}.png"
    plot_cross_track(img, png, seabed_z_m=seabed_profile(sc, ds, img.ping), targets_yz_m=truth_yz,
                     title=f"{scene}, ping {img.ping}")
    return png


def summary_lines(result: DemoResult, threshold: float = PEAK_THRESHOLD) -> list[str]:
    """Human-readable summary: detections per pipeline, other peaks, timings."""
    lines = ["detections (coherence peak within 2 m horizontally of the pipeline):"]
    for name in dict.fromkeys(s.name for s in result.scores):
        ss = [s for s in result.scores if s.name == name]
        hits = [s for s in ss if s.detected]
        best = max(hits, key=lambda s: s.cf) if hits else None
        where = f"y = {ss[0].y_m:7.1f} m, z = {ss[0].z_m:5.1f} m"
        lines.append(f"  pipeline {name:>2} ({where}): detected in {len(hits)}/{len(ss)} ping(s)"
                     + (f", best CF {best.cf:.2f} at {best.offset_m:.1f} m" if best else ""))
    n_pings = len({s.ping for s in result.scores}) or 1
    strong = sum(p["cf"] > MAP_THRESHOLD for p in result.other_peaks)
    lines.append(f"other coherence peaks (seabed and sub-bottom scatterers, sidelobes): "
                 f"{len(result.other_peaks) / n_pings:.0f} per ping above {threshold:g}, "
                 f"{strong / n_pings:.0f} above {MAP_THRESHOLD:g}")
    lines.append("time: " + ", ".join(f"{k[:-2]} {v:.1f} s" for k, v in result.timings_s.items()))
    lines.append("files: " + ", ".join(str(p) for p in result.files))
    return lines
