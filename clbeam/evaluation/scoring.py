"""Detections scored against the simulator's truth.

:func:`score_detections` counts one-to-one matches of detections to truth
positions, so a second peak on one object is a false positive;
:func:`compare_on_simulation` measures precision and recall of coherence
peaks with and without main-lobe highlight suppression
(:mod:`clbeam.imaging.mlh`) on a simulated scene.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from clbeam.constants import PEAK_THRESHOLD
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.peaks import peak_rows
from clbeam.io.pingfile import pings_from_dataset
from clbeam.model.grid import PolarGrid
from clbeam.sim import load_scene, simulate

log = logging.getLogger(__name__)

#: a detection matches a truth position within this horizontal distance (m), as in the demo
HIT_HORIZONTAL_M = 2.0


#: ... and within this vertical distance (m): the arc runs steeply at far ranges
HIT_VERTICAL_M = 5.0


# ---------------------------------------------------------------------------
# Scoring against truth
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class DetectionScore:
    """Counts of one-to-one matches between detections and truth positions.

    Attributes
    ----------
    true_positives : int
        Detections matched to a truth position.
    false_positives : int
        Detections matched to none (clutter, and second peaks on one object).
    false_negatives : int
        Truth positions no detection matched.
    """

    true_positives: int = 0
    false_positives: int = 0
    false_negatives: int = 0

    @property
    def precision(self) -> float:
        """``TP / (TP + FP)``; NaN without detections."""
        n = self.true_positives + self.false_positives
        return self.true_positives / n if n else float("nan")

    @property
    def recall(self) -> float:
        """``TP / (TP + FN)``; NaN without truth."""
        n = self.true_positives + self.false_negatives
        return self.true_positives / n if n else float("nan")

    def __add__(self, other: "DetectionScore") -> "DetectionScore":
        return DetectionScore(self.true_positives + other.true_positives,
                              self.false_positives + other.false_positives,
                              self.false_negatives + other.false_negatives)


def score_detections(detections_yz_m, truth_yz_m, *, max_horizontal_m: float = HIT_HORIZONTAL_M,
                     max_vertical_m: float = HIT_VERTICAL_M) -> DetectionScore:
    """Match detections to truth one-to-one and count hits, false alarms and misses.

    A pair can match when the detection is within ``max_horizontal_m`` in
    ``y`` and ``max_vertical_m`` in ``z`` of the truth; pairs are taken
    nearest first (Euclidean distance in the cross-track plane), each
    detection and each truth at most once.  A second detection of an object
    is thus a false positive.

    Parameters
    ----------
    detections_yz_m : array_like
        ``(n, 2)`` detections ``(y, z)`` (m).
    truth_yz_m : array_like
        ``(k, 2)`` truth ``(y, z)`` (m); rows with NaN are ignored.
    max_horizontal_m, max_vertical_m : float
        Match window (m).
    """
    det = np.asarray(detections_yz_m, dtype=np.float64).reshape(-1, 2)
    tru = np.asarray(truth_yz_m, dtype=np.float64).reshape(-1, 2)
    tru = tru[np.all(np.isfinite(tru), axis=1)]
    dy = np.abs(det[:, None, 0] - tru[None, :, 0])
    dz = np.abs(det[:, None, 1] - tru[None, :, 1])
    ok = (dy <= max_horizontal_m) & (dz <= max_vertical_m)
    dist = np.hypot(dy, dz)
    pairs = sorted(zip(*np.nonzero(ok)), key=lambda p: (dist[p], p))
    used_d, used_t = set(), set()
    for i, j in pairs:
        if i not in used_d and j not in used_t:
            used_d.add(i)
            used_t.add(j)
    tp = len(used_d)
    return DetectionScore(tp, det.shape[0] - tp, tru.shape[0] - tp)


def rows_yz(rows: list[dict]) -> np.ndarray:
    """``(n, 2)`` ``(y_m, z_m)`` of peak rows."""
    return np.array([[r["y_m"], r["z_m"]] for r in rows], dtype=np.float64).reshape(-1, 2)


# ---------------------------------------------------------------------------
# Measurement on a simulated scene
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class MLHComparison:
    """Precision and recall of coherence peaks with and without MLH suppression.

    Attributes
    ----------
    without : DetectionScore
        Every coherence peak a detection (the paper's processing).
    peak, lobe : DetectionScore
        One detection per arc, placed at its sub-cell maximum or at its lobe fit.
    n_pings : int
        Pings scored.
    n_peaks, n_detections : int
        Coherence peaks, and detections after suppression, over the pings.
    """

    without: DetectionScore
    peak: DetectionScore
    lobe: DetectionScore
    n_pings: int
    n_peaks: int
    n_detections: int

    def lines(self) -> list[str]:
        """Human-readable summary, one line per case."""
        out = [f"{self.n_pings} ping(s): {self.n_peaks} coherence peaks, {self.n_detections} after MLH suppression"]
        for name, s in (("without MLH", self.without), ("MLH, peak", self.peak), ("MLH, lobe fit", self.lobe)):
            out.append(f"{name:>14}: precision {s.precision:.3f}, recall {s.recall:.3f} "
                       f"(TP {s.true_positives}, FP {s.false_positives}, FN {s.false_negatives})")
        return out


def compare_on_simulation(scene: str = "line1", *, pings: int = 3, grid: PolarGrid | None = None,
                          threshold: float = PEAK_THRESHOLD, interp: str = "cubic", backend: str = "opencl",
                          engine=None, seed: int = 0, max_horizontal_m: float = HIT_HORIZONTAL_M,
                          max_vertical_m: float = HIT_VERTICAL_M, **options) -> MLHComparison:
    """Simulate a scene, image it and score its detections with and without MLH suppression.

    The truth is where a straight-ray imager shows each target
    (``truth_target_image_y/z``); every coherence peak in the grid counts,
    so seabed and sub-bottom clutter are false positives in every case.

    Parameters
    ----------
    scene : str
        Built-in scene name or TOML file (default the paper's Line 1).
    pings : int
        Pings simulated and scored (the first ``pings`` of the line).
    grid : PolarGrid, optional
        Image grid; default a window around Line 1's pipelines, 320-660 m
        and -80 to -35 degrees on the paper's 0.2 m x 0.1 degree cells.
    threshold : float
        Coherence-peak threshold.
    interp, backend, engine
        Imaging mode, engine backend, or an engine to share.
    seed : int
        Simulation seed.
    max_horizontal_m, max_vertical_m : float
        Match window of :func:`score_detections` (m).
    **options
        Passed to :func:`suppress_main_lobe_highlights`.
    """
    grid = grid or PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, min_range_m=320.0, max_range_m=660.0,
                                     angles_deg=(-80.0, -35.0))
    ds = simulate(load_scene(scene, pings=pings, max_range_m=float(grid.ranges_m[-1]) + 20.0), seed=seed)
    # MLH merges the grid's peaks: both sides of the comparison start from them (no clutter test: the
    # comparison is of what MLH does to every coherence peak)
    imager = Imager(grid, ImagingOptions(interp=interp, threshold=threshold, refine_peaks=False, min_contrast_db=None),
                    backend=backend, engine=engine)
    win = {"max_horizontal_m": max_horizontal_m, "max_vertical_m": max_vertical_m}
    scores = {k: DetectionScore() for k in ("without", "peak", "lobe")}
    n_peaks = n_dets = 0
    for ping in pings_from_dataset(ds, f"scene {scene}"):
        img = imager.image(ping)
        truth = np.stack([ds["truth_target_image_y"].values[ping.index],
                          ds["truth_target_image_z"].values[ping.index]], axis=1)
        scores["without"] += score_detections(rows_yz(img.peaks), truth, **win)
        for which in ("peak", "lobe"):
            rows = peak_rows(img.context, img.cf_smooth, img.intensity, grid, threshold=threshold, mlh=True,
                             position=which, **options)
            scores[which] += score_detections(rows_yz(rows), truth, **win)
        n_peaks += len(img.peaks)
        n_dets += len(rows)
        log.info("ping %d: %d coherence peaks, %d after MLH suppression", ping.index, len(img.peaks), len(rows))
    return MLHComparison(scores["without"], scores["peak"], scores["lobe"], len(ds["ping"]), n_peaks, n_dets)
