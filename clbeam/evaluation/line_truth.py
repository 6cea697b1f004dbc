"""Survey lines scored against the simulator's truth.

A simulated ping file holds, per ping and target, where the target crosses
the ping's image plane (``truth_target_y``, ``truth_target_z``, earth
frame) and the seabed above it (``truth_target_seabed_z``); the attribute
``target_kinds`` says which targets are lines.  :func:`line_truth` gathers
them for the survey's pings (through the store's ``file_index`` and
``file_ping``); :func:`score_lines` reports, per line target:

* **detectable** pings: those with a detection (CF above the map
  threshold) within ``match_m`` of the target across the track;
* pings **on its line**: detectable pings where the ``pipeline`` line that
  follows the target best passes within ``match_m`` of it;

"Of the target" means of either place a correct imager shows it: where it
crosses the ping's plane (``truth_target_y``: a rough pipe's diffuse echo,
or any pipe near broadside) or the image of its point nearest the source
(``truth_target_image_y``: a smooth pipe's specular echo, which for a pipe
at a heading ``a`` to the ping's plane lies ``y (1 - cos^2 a)`` nearer the
track, the main-lobe arcs of Holland et al. 2024); the errors are taken to
the nearer of the two.
* **seen above chance**: whether the target's detectable pings are more
  than the clutter gives any place: the same count at copies of the target
  beyond its places across the track (:data:`CHANCE_OFFSETS_M` beyond the
  span of its crossing and its image) sets the chance rate of a ping, and
  the target is seen when its count at one of its places is improbable
  under it (binomial tail below half :data:`SEEN_P_VALUE`: each place is a
  copy's one window, where the pings near either place would take two).
  In dense clutter a pipe the imaging does not show still has detections
  within ``match_m`` in most pings, and its detectable pings are mostly the clutter's; where the
  clutter is that dense a pipe that is seen can fail the test too (its
  line found by its continuity), so the test names targets, it does not
  drop them;
* **trackable**: whether a line that followed the target exactly (at
  either place, its strongest detection in each ping within the lines'
  gates) would score above the lines' threshold
  (:func:`clbeam.survey.line_products.path_score`): a target seen above
  chance at its own place can still be one that no search over every
  place and heading reports without as many false lines from the clutter;
* **fragments**: ``pipeline`` lines that pass within ``match_m`` of it in
  at least three pings;
* the line's **position error** (RMS of its cross-track offset minus the
  target's, over every ping of its extent where the target crosses the
  plane: horizontal, in the ping's plane) and **burial error** (its burial
  minus the target's axis depth below the seabed);

and **false lines**: ``pipeline`` lines near no line target, per km of track.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import binom

#: distance across the track within which a detection or a line is on a target (m)
MATCH_M = 2.0
#: cross-track shifts of a target's copies that measure the chance of a detection near it, from the far edge of
#: the span of its crossing and its image on each side (m): clear of its echoes, within the clutter around it
CHANCE_OFFSETS_M = (-30.0, -15.0, 15.0, 30.0)
#: a target whose detectable pings have a binomial tail under the chance rate below this is seen above chance
SEEN_P_VALUE = 1e-3


@dataclass
class LineTruth:
    """The line targets of a simulated survey, per survey ping.

    Attributes
    ----------
    names : list of str
        Target names.
    y, burial : numpy.ndarray
        ``(n_pings, n_targets)`` cross-track offset (m, earth frame) and
        axis depth below the seabed (m); NaN for pings not simulated.
    image_y : numpy.ndarray
        ``(n_pings, n_targets)`` cross-track offset of the image of the
        target's nearest point (m).
    z : numpy.ndarray or None
        ``(n_pings, n_targets)`` axis depth below the transducers (m).
    """

    names: list
    y: np.ndarray
    burial: np.ndarray
    image_y: np.ndarray = None
    z: np.ndarray = None

    def nadir_deg(self, target: int) -> float:
        """The target's median angle from nadir over the pings it crosses (degree; NaN without depths)."""
        if self.z is None:
            return math.nan
        y, z = self.y[:, target], self.z[:, target]
        on = np.isfinite(y) & np.isfinite(z)
        return float(np.degrees(np.median(np.arctan2(np.abs(y[on]), z[on])))) if on.any() else math.nan

    def distance(self, pings: np.ndarray, y: np.ndarray, target: int) -> np.ndarray:
        """Distance across the track (m) from offsets ``y`` of ``pings`` to the nearer place of ``target``."""
        d = np.abs(y - self.y[pings, target])
        if self.image_y is not None:
            d = np.fmin(d, np.abs(y - self.image_y[pings, target]))
        return d


def line_truth(datasets: list, file_index: np.ndarray, file_ping: np.ndarray) -> LineTruth | None:
    """The line targets' truth for every survey ping, or ``None`` when the files have none.

    Parameters
    ----------
    datasets : list of xarray.Dataset
        The survey's input ping files, in survey order.
    file_index, file_ping : numpy.ndarray
        ``(n_pings,)`` input file and ping within it of each survey ping
        (-1: not imaged).
    """
    per_file = []
    for ds in datasets:
        if "truth_target_y" not in ds.variables:
            return None
        kinds = str(ds.attrs.get("target_kinds", "")).split(",")
        lines = [i for i, k in enumerate(kinds) if k.strip() == "line"]
        names = [str(v) for v in np.asarray(ds["target"].values)[lines]] if "target" in ds.coords else \
            [f"target {i}" for i in lines]
        image = ds["truth_target_image_y"].values if "truth_target_image_y" in ds.variables else \
            ds["truth_target_y"].values
        z = np.asarray(ds["truth_target_z"].values)
        per_file.append((names, np.asarray(ds["truth_target_y"].values)[:, lines],
                         (z - np.asarray(ds["truth_target_seabed_z"].values))[:, lines], np.asarray(image)[:, lines],
                         z[:, lines]))
    if not per_file or any(f[0] != per_file[0][0] for f in per_file):
        return None
    names = per_file[0][0]
    y = np.full((file_index.size, len(names)), np.nan)
    burial, image_y, z = np.full_like(y, np.nan), np.full_like(y, np.nan), np.full_like(y, np.nan)
    ok = (file_index >= 0) & (file_ping >= 0)
    for g in np.flatnonzero(ok):
        _, fy, fb, fi, fz = per_file[int(file_index[g])]
        k = int(file_ping[g])
        y[g], burial[g], image_y[g], z[g] = fy[k], fb[k], fi[k], fz[k]
    return LineTruth(names, y, burial, image_y, z)


def score_lines(lines, truth: LineTruth, det_ping: np.ndarray, det_y: np.ndarray, track_km: float,
                *, match_m: float = MATCH_M) -> tuple[list, dict]:
    """Per line target, how the survey's ``pipeline`` lines found it; and the false lines.

    Parameters
    ----------
    lines : SurveyLines
        :func:`clbeam.survey.line_products.survey_lines`.
    truth : LineTruth
    det_ping, det_y : numpy.ndarray
        ``(k,)`` survey ping and cross-track offset (m) of every detection.
    track_km : float
        Length of the survey line (km).
    match_m : float
        Cross-track distance within which a detection or a line is on a target (m).

    Returns
    -------
    (list of dict, dict)
        Per target: ``target``, ``detectable_pings``, ``pings_on_line``,
        ``on_line_fraction``, ``fragments``, ``line`` (-1: none),
        ``position_rms_m``, ``burial_error_m``, ``burial_se_m`` (the line's own standard error),
        ``nadir_deg`` (the target's median angle from nadir), ``chance_pings`` and ``seen`` (detectable pings at
        shifted copies of the target, and whether its own count is above that chance), ``path_score`` and
        ``trackable`` (the better score of a line on its crossing or on its image, and whether it reaches the
        lines' threshold; NaN and ``False`` where the lines offer no path score); and ``false_lines``,
        ``false_lines_per_km``, ``track_km``.
    """
    pipes = [k for k, r in enumerate(lines.rows) if r["kind"] == "pipeline"]
    near = {}  # (line, target) -> pings where the line passes within match_m
    for k in pipes:
        pings, y = lines.ping_paths[k]
        for t in range(len(truth.names)):
            near[k, t] = pings[truth.distance(pings, y, t) <= match_m]
    rows = []
    for t, name in enumerate(truth.names):
        hit = truth.distance(det_ping, det_y, t) <= match_m
        detectable = np.unique(det_ping[hit])
        chance, seen = _above_chance(truth, det_ping, det_y, t, match_m)
        cover = {k: np.intersect1d(near[k, t], detectable).size for k in pipes}
        best = max(cover, key=cover.get) if cover and max(cover.values()) > 0 else -1
        frags = sum(near[k, t].size >= 3 for k in pipes)
        row = {"target": name, "detectable_pings": int(detectable.size),
               "pings_on_line": int(cover.get(best, 0)),
               "on_line_fraction": cover.get(best, 0) / detectable.size if detectable.size else math.nan,
               "fragments": int(frags), "line": int(lines.rows[best]["line"]) if best >= 0 else -1,
               "position_rms_m": math.nan, "burial_error_m": math.nan, "burial_se_m": math.nan,
               "nadir_deg": truth.nadir_deg(t), "chance_pings": chance, "seen": seen,
               **_trackable(lines, truth, t)}
        if best >= 0:
            # over every ping of the line's extent where the target crosses the plane, near it or not
            pings, y = lines.ping_paths[best]
            on = np.isfinite(truth.y[pings, t])
            row["position_rms_m"] = float(np.sqrt(np.mean(truth.distance(pings[on], y[on], t) ** 2)))
            row["burial_error_m"] = float(lines.rows[best]["burial_m"] - np.nanmean(truth.burial[pings[on], t]))
            row["burial_se_m"] = float(lines.rows[best].get("burial_se_m", math.nan))
        rows.append(row)
    false = sum(all(near[k, t].size < 3 for t in range(len(truth.names))) for k in pipes)
    return rows, {"false_lines": int(false), "false_lines_per_km": false / track_km if track_km > 0 else math.nan,
                  "track_km": float(track_km)}


def _trackable(lines, truth: LineTruth, target: int) -> dict:
    """``path_score`` and ``trackable`` of a target (:func:`score_lines`): the lines' score of its crossing (at
    its own burial) and of its image (at its detections' burial: a specular echo lies deeper), the better."""
    score_path = getattr(lines, "score_path", None)
    if score_path is None:
        return {"path_score": math.nan, "trackable": False}
    pings = np.arange(truth.y.shape[0])
    burial = truth.burial[:, target]
    scores = [score_path(pings, truth.y[:, target], float(np.nanmedian(burial)) if np.isfinite(burial).any()
                         else None)]
    if truth.image_y is not None:
        scores.append(score_path(pings, truth.image_y[:, target]))
    best = max((v for v in scores if not math.isnan(v)), default=math.nan)
    return {"path_score": best, "trackable": bool(best >= lines.min_score)}


def _above_chance(truth: LineTruth, det_ping: np.ndarray, det_y: np.ndarray, target: int,
                  match_m: float) -> tuple[float, bool]:
    """The mean count of pings with a detection within ``match_m`` of the target's copies, and whether the
    target's own count at one of its two places (its crossing and its specular image, ``y sin^2 a`` apart for
    a pipe at ``a`` to the track) is improbable under that rate: a one-sided binomial tail over the pings the
    target crosses below half :data:`SEEN_P_VALUE` (two places tested; all of it where the two places' windows
    overlap in every ping).

    The copies lie :data:`CHANCE_OFFSETS_M` beyond the span of the two places, so that neither the target's
    echoes nor the arc between them fall in a copy's window.  Each place is tested on its own, as a copy's
    single window is: the pings with a detection near either place would offer the clutter two windows
    against the copy's one (in dense clutter, nearly twice the chance)."""
    y, image = truth.y[:, target], truth.image_y[:, target] if truth.image_y is not None else truth.y[:, target]
    lo, hi = np.fmin(y, image), np.fmax(y, image)
    crossing = int(np.count_nonzero(np.isfinite(lo)))
    if crossing == 0:
        return math.nan, False
    at = np.clip(det_ping, 0, y.size - 1)

    def pings_near(centre: np.ndarray) -> int:
        return np.unique(det_ping[np.abs(det_y - centre[at]) <= match_m]).size
    chance = float(np.mean([pings_near(hi + shift if shift > 0 else lo + shift) for shift in CHANCE_OFFSETS_M]))
    rate = min(max(chance, 0.5) / crossing, 1.0)  # half a ping at least: no copy hit is no proof of a zero rate
    own = max(pings_near(y), pings_near(image))
    places = 2 if np.nanmax(hi - lo) > 2 * match_m else 1  # windows that overlap in every ping are one place
    return chance, bool(binom.sf(min(own, crossing) - 1, crossing, rate) < SEEN_P_VALUE / places)


def score_survey(products, input_paths: list, *, match_m: float = MATCH_M) -> tuple[list, dict] | None:
    """:func:`score_lines` for a survey run on simulated files (``None`` when they hold no line truth).

    Parameters
    ----------
    products : SurveyProducts
        :func:`clbeam.survey.products.finalize_survey` (or a run's ``products``).
    input_paths : list of path-like
        The survey's input ping files, in survey order.
    """
    from clbeam.io.pingfile import open_dataset

    det = products.detections
    datasets = [open_dataset(p) for p in input_paths]
    try:
        truth = line_truth(datasets, np.asarray(det["file_index"]), np.asarray(det["file_ping"]))
    finally:
        for ds in datasets:
            ds.close()
    if truth is None:
        return None
    return score_lines(products.lines, truth, np.asarray(det["ping"]), np.asarray(det["y_m"]), products.track_km,
                       match_m=match_m)


def truth_summary(rows: list, summary: dict) -> list:
    """Lines of text: one per target, then the false lines."""
    out = []
    for r in rows:
        out.append(f"truth {r['target']}: on line {r['line']} in {r['pings_on_line']} of {r['detectable_pings']} "
                   f"detectable pings ({100 * r['on_line_fraction']:.0f} %), {r['fragments']} fragment(s), "
                   f"position RMS {r['position_rms_m']:.2f} m, burial error {r['burial_error_m']:+.2f} m")
    out.append(f"truth: {summary['false_lines']} false pipeline line(s) over {summary['track_km']:.2f} km "
               f"({summary['false_lines_per_km']:.2f} per km)")
    return out
