"""Figures of a survey: the plan-view persistence map and peaks by ping (Holland et al. 2024, Figs. 9-10).

Each figure is drawn to a temporary name beside its path and renamed, so a
reader never sees half a PNG.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from clbeam.io.figures import plot_peak_map, pyplot
from clbeam.io.survey_store import temporary_path
from clbeam.model.grid import PolarGrid
from clbeam.survey.georef import SurveyNavigation

#: pings between the broadside lines drawn on the map (2 minutes at the paper's 4 s interval)
BROADSIDE_EVERY = 30


def plot_persistence(path, det_ping, det_y, det_cf, threshold: float) -> Path:
    """Detections by cross-track offset and ping (:func:`clbeam.io.figures.plot_peak_map`).

    Parameters
    ----------
    path : path-like
        PNG to write.
    det_ping, det_y, det_cf : array_like
        ``(k,)`` survey ping, cross-track offset (m) and CF of each detection.
    threshold : float
        The map threshold (CF) the detections passed.
    """
    path = Path(path)
    rows = [{"ping": int(p), "y_m": float(y), "cf": float(c)} for p, y, c in zip(det_ping, det_y, det_cf)]
    tmp = temporary_path(path, ".png")
    plot_peak_map(rows, tmp, threshold=threshold, title="coherence peaks over the survey")
    os.replace(tmp, path)
    return path


#: colour of each line kind on the map
KIND_COLOURS = {"pipeline": "k", "water": "tab:cyan", "subbottom": "tab:brown",
                "seabed-nadir": "tab:olive", "subbottom-nadir": "tab:orange", "unknown": "tab:gray"}


def plot_survey_map(path, *, nav: SurveyNavigation, det_ping, det_cf, det_pos, lines, threshold: float,
                    grid: PolarGrid | None = None) -> Path:
    """Plan-view persistence map (Holland et al. 2024, Figs. 9-10).

    Coherence peaks above ``threshold`` at their georeferenced positions,
    coloured by CF, over the ship track (blue) with the broadside directions
    of every 30th ping (2 minutes at the paper's 4 s interval) out to the
    grid's largest horizontal range, and each line's path coloured by its
    kind (pipelines black, thick and numbered).  Without navigation the
    axes are along-track distance (ping time x speed) and cross-track
    offset.

    Parameters
    ----------
    path : path-like
        PNG to write.
    nav : SurveyNavigation
        The survey's navigation (after :meth:`~SurveyNavigation.finish`).
    det_ping, det_cf : array_like
        ``(k,)`` survey ping and CF of each detection.
    det_pos : numpy.ndarray
        ``(k, 2)`` detection positions in the association frame (m).
    lines : SurveyLines
        :func:`clbeam.survey.line_products.survey_lines`.
    threshold : float
        The map threshold (CF).
    grid : PolarGrid, optional
        The image grid (length of the broadside lines).

    Returns
    -------
    pathlib.Path
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 8), dpi=110, constrained_layout=True)
    if nav.all_nav:
        shift = _draw_navigated_track(ax, nav, grid)
        ax.set_xlabel(f"easting - {shift[0]:.0f} m (EPSG:{nav.epsg})")
        ax.set_ylabel(f"northing - {shift[1]:.0f} m")
        ax.set_aspect("equal", adjustable="datalim")
    else:
        ax.set_xlabel("along-track distance (m, ping time x speed: no navigation)")
        ax.set_ylabel("cross-track offset y (m, starboard positive)")
        ax.axhline(0, color="tab:blue", lw=1.5, label="ship track")
        shift = np.zeros(2)
    x, y = det_pos[:, 0] - shift[0], det_pos[:, 1] - shift[1]
    if len(x):
        sc = ax.scatter(x, y, c=det_cf, s=8, cmap="plasma", vmin=threshold, vmax=1, zorder=3)
        fig.colorbar(sc, ax=ax, label="coherence factor", shrink=0.8)
    _draw_lines(ax, lines, shift)
    n_pipe = sum(r["kind"] == "pipeline" for r in lines.rows)
    ax.set_title(f"coherence peaks, CF > {threshold:g}: {len(x)} detections in {len(np.unique(det_ping))} pings; "
                 f"{len(lines.rows)} line(s), {n_pipe} pipeline(s)")
    ax.legend(loc="best", fontsize=8)
    return _save(plt, fig, path)


def _draw_lines(ax, lines, shift: np.ndarray) -> None:
    """The lines' paths coloured by kind, one legend entry per kind; only the pipelines numbered (the rest
    crowd around nadir)."""
    shown = set()
    for row, p in zip(lines.rows, lines.paths):
        p = p - shift
        kind = row["kind"]
        pipe = kind == "pipeline"
        ax.plot(p[:, 0], p[:, 1], color=KIND_COLOURS.get(kind, "tab:gray"), lw=2.0 if pipe else 1.0, zorder=4,
                label=None if kind in shown else f"{kind} line")
        shown.add(kind)
        if pipe:
            ax.annotate(f"{row['line']}", p[-1], fontsize=9, xytext=(3, 3), textcoords="offset points",
                        fontweight="bold")


def _save(plt, fig, path) -> Path:
    """Write the figure to ``path`` under a temporary name, rename it into place, close it."""
    path = Path(path)
    tmp = temporary_path(path, ".png")
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, path)
    return path


def _draw_navigated_track(ax, nav: SurveyNavigation, grid: PolarGrid | None) -> np.ndarray:
    """The ship track and broadside lines in UTM, relative to the track's south-west corner (returned, m)."""
    e0, n0 = float(np.nanmin(nav.e)), float(np.nanmin(nav.n))
    ax.plot(nav.e - e0, nav.n - n0, color="tab:blue", lw=1.5, label="ship track", zorder=2)
    reach = 0.0
    if grid is not None:
        reach = float(grid.ranges_m[-1] * np.max(np.abs(np.sin(np.deg2rad(grid.angles_deg)))))
    idx = np.flatnonzero(np.isfinite(nav.e))
    conv = nav.convergence_at(np.arange(nav.lat.size))
    for k in idx[::BROADSIDE_EVERY]:
        h = np.deg2rad(nav.heading[k] - conv[k])
        if reach > 0 and np.isfinite(h):
            de, dn = reach * np.cos(h), -reach * np.sin(h)
            ax.plot([nav.e[k] - e0 - de, nav.e[k] - e0 + de], [nav.n[k] - n0 - dn, nav.n[k] - n0 + dn],
                    color="0.6", ls="--", lw=0.8, zorder=1)
    return np.array([e0, n0])
