"""Probability of detection against range: sweeps, the ranges where it falls to 0.9 and 0.5 with their
uncertainty, and the survey line spacing that keeps it (docs/detectability.md).

:func:`predict` is the Python API of ``clbeam detectability``: a scene (a built-in name, a TOML file or a
:class:`~clbeam.sim.scene.Scene`), its pipelines and a range sweep in, a :class:`Prediction` out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.evaluation.detectability import UNCERTAIN, Environment, Pipe, detections, pipes_of_scene, with_uncertain
from clbeam.evaluation.detectability_stats import DEFAULT_DRAWS

#: draws per evaluation of the perturbed environments, and ranges of their coarse sweep
UNCERTAINTY_DRAWS = 256
UNCERTAINTY_RANGES = 8
#: the levels whose ranges a prediction reports
LEVELS = (0.9, 0.5)


def crossing_range(ranges_m, pd, level: float) -> float:
    """The range (m) where Pd first falls below ``level``, interpolated linearly between the sweep's ranges.

    Returns
    -------
    float
        NaN where Pd is below ``level`` at the sweep's first range; ``inf`` where it never falls below
        within the sweep.
    """
    r, p = np.asarray(ranges_m, dtype=np.float64), np.asarray(pd, dtype=np.float64)
    below = np.flatnonzero(p < level)
    if below.size == 0:
        return math.inf
    k = int(below[0])
    if k == 0:
        return math.nan
    return float(r[k - 1] + (p[k - 1] - level) / (p[k - 1] - p[k]) * (r[k] - r[k - 1]))


def line_spacing(ranges_m, pd, level: float = 0.9) -> float:
    """The largest spacing ``s`` (m) of parallel survey lines such that a pipe anywhere between two
    adjacent lines, ``d`` from one and ``s − d`` from the other, is detected from at least one with
    probability ``1 − (1 − Pd(d)) (1 − Pd(s − d)) ≥ level`` (the lines' detections independent).

    Pd closer than the sweep's first range is taken as there (the near ranges the sweep leaves out are
    not worse); beyond its last, as 0.  NaN where even ``s`` equal to the first range fails.
    """
    r, p = np.asarray(ranges_m, dtype=np.float64), np.asarray(pd, dtype=np.float64)

    def pd_at(d):
        return np.interp(d, r, p, left=p[0], right=0.0)

    best = math.nan
    for s in np.linspace(r[0], 2 * r[-1], 801):
        d = np.linspace(0.0, s, 201)
        if np.all(1 - (1 - pd_at(d)) * (1 - pd_at(s - d)) >= level):
            best = float(s)
    return best


@dataclass(frozen=True)
class PipePrediction:
    """Pd against range of one pipeline.

    Attributes
    ----------
    pipe : Pipe
        The pipe.
    mean_range_m : float
        Its mean horizontal range over the scene's pings (m).
    rows : list of dict
        One per range: ``target``, ``range_m``, ``pd`` and the levels and test probabilities of
        :func:`~clbeam.evaluation.detectability.detection`.
    ranges_at : dict
        ``{level: range_m}`` (:func:`crossing_range`).
    uncertainty_m : dict
        ``{level: one standard deviation (m)}`` from the uncertain parameters
        (:data:`~clbeam.evaluation.detectability.UNCERTAIN`), their shifts added in quadrature.
    spacing_m : float
        :func:`line_spacing` at 0.9.
    """

    pipe: Pipe
    mean_range_m: float
    rows: list
    ranges_at: dict
    uncertainty_m: dict
    spacing_m: float


@dataclass(frozen=True)
class Prediction:
    """:func:`predict`'s result: one :class:`PipePrediction` per pipeline."""

    scene_name: str
    pipes: list

    def rows(self) -> list[dict]:
        """Every pipeline's rows."""
        return [row for p in self.pipes for row in p.rows]

    def summary_lines(self) -> list[str]:
        """One line per pipeline: its ranges of Pd 0.9 and 0.5 with their uncertainty and the spacing."""
        out = []
        for p in self.pipes:
            parts = [f"{p.pipe.name}: Pd {p.rows[0]['pd']:.2f} at {p.rows[0]['range_m']:.0f} m"
                     if len(p.rows) == 1 else f"{p.pipe.name}:"]
            if len(p.rows) > 1:
                for level in LEVELS:
                    parts.append(f"Pd {level:g} at {_fmt_range(p.ranges_at[level], p.rows)}"
                                 f" ± {p.uncertainty_m[level]:.0f} m" if math.isfinite(p.uncertainty_m[level])
                                 else f"Pd {level:g} at {_fmt_range(p.ranges_at[level], p.rows)}")
                parts.append(f"line spacing for Pd >= 0.9: {p.spacing_m:.0f} m" if math.isfinite(p.spacing_m)
                             else "line spacing for Pd >= 0.9: none within the sweep")
            out.append(" ".join(parts[:1]) + (" " + "; ".join(parts[1:]) if len(parts) > 1 else ""))
        return out


def _fmt_range(value: float, rows: list) -> str:
    if math.isinf(value):
        return f"beyond {rows[-1]['range_m']:.0f} m"
    if math.isnan(value):
        return f"below {rows[0]['range_m']:.0f} m"
    return f"{value:.0f} m"


def sweep(env: Environment, pipe: Pipe, ranges_m, *, draws: int = DEFAULT_DRAWS, seed: int = 0) -> list[dict]:
    """:func:`~clbeam.evaluation.detectability.detections` at every range (m), common random numbers."""
    rows = []
    for r, res in zip(ranges_m, detections(env, pipe, ranges_m, draws=draws, seed=seed)):
        res.pop("cf_refined")
        rows.append({"target": pipe.name, "range_m": float(r), **res})
    return rows


def uncertainty(env: Environment, pipe: Pipe, ranges_m, nominal: dict, *, seed: int = 0) -> dict:
    """One standard deviation (m) of the ranges of :data:`LEVELS` from the uncertain parameters: each moved
    by ±1 σ, Pd evaluated on :data:`UNCERTAINTY_RANGES` ranges about the nominal ranges (within the
    sweep), half the difference of the two ranges per parameter, added in quadrature.  NaN where a
    level's range is not within the sweep, nominal or moved."""
    r = np.asarray(ranges_m, dtype=np.float64)
    found = [v for v in nominal.values() if math.isfinite(v)]
    if not found:
        return {level: math.nan for level in LEVELS}
    lo, hi = max(r[0], 0.6 * min(found)), min(r[-1], 1.6 * max(found))
    coarse = np.linspace(lo, hi, UNCERTAINTY_RANGES)
    shifts = {level: [] for level in LEVELS}
    for name in UNCERTAIN:
        at = {}
        for sign in (-1, 1):
            e, p = with_uncertain(env, pipe, name, sign)
            pd = [res["pd"] for res in detections(e, p, coarse, draws=UNCERTAINTY_DRAWS, seed=seed)]
            at[sign] = {level: crossing_range(coarse, pd, level) for level in LEVELS}
        for level in LEVELS:
            shifts[level].append(0.5 * (at[1][level] - at[-1][level]))
    out = {}
    for level in LEVELS:
        s = np.asarray(shifts[level])
        out[level] = float(np.sqrt(np.sum(s ** 2))) if math.isfinite(nominal[level]) and np.all(np.isfinite(s)) else math.nan
    return out


def parse_ranges(text: str) -> np.ndarray:
    """``START:STOP:STEP`` (m, STOP included when on the step) as an array; one-line errors."""
    parts = text.split(":")
    require(len(parts) == 3, OptionError, f"--ranges must be START:STOP:STEP in m, got {text!r}")
    try:
        start, stop, step = (float(v) for v in parts)
    except ValueError:
        raise OptionError(f"--ranges must be three numbers START:STOP:STEP in m, got {text!r}") from None
    require(all(math.isfinite(v) for v in (start, stop, step)), OptionError, f"--ranges must be finite, got {text!r}")
    require(start > 0 and step > 0 and stop >= start, OptionError,
            f"--ranges needs 0 < START <= STOP and STEP > 0 (m), got {text!r}")
    n = int(math.floor((stop - start) / step + 1e-9)) + 1
    require(n <= 2000, OptionError, f"--ranges gives {n} ranges; at most 2000")
    return start + step * np.arange(n)


def predict(scene, *, ranges_m=None, heading_deg: float | None = None, absorption_db_per_km: float | None = None,
            tests=None, draws: int = DEFAULT_DRAWS, seed: int = 0, with_uncertainty: bool = True,
            overrides: dict | None = None) -> Prediction:
    """Pd against horizontal range for every pipeline of a scene.

    Parameters
    ----------
    scene : str, path or Scene
        A built-in scene name, a TOML file or a scene.
    ranges_m : array_like, optional
        Horizontal ranges from the track (m); ``None``: each pipeline at its own mean range in the scene.
    heading_deg : float, optional
        Heading of every pipe to the track (degree); ``None``: each pipeline's mean over the pings.
    absorption_db_per_km : float, optional
        Water absorption (dB/km); ``None``: Francois-Garrison; 0: none (as the simulator).
    tests : Tests, optional
        The detection test (default: the imager's).
    draws, seed : int
        Monte Carlo draws per range and seed.
    with_uncertainty : bool
        Compute the uncertainty of the ranges of Pd 0.9 and 0.5 (sweeps only).
    overrides : dict, optional
        Dotted scene keys replacing the scene's values (:func:`clbeam.sim.load_scene`).

    Raises
    ------
    OptionError
        A scene without pipelines, a range beyond the record, a bad pipe.
    """
    from clbeam.evaluation.detectability_stats import Tests
    from clbeam.sim.catalog import load_scene

    sc = load_scene(scene, overrides=overrides or {})
    pipes = pipes_of_scene(sc)
    env = Environment(sc, absorption_db_per_km=absorption_db_per_km, tests=tests or Tests())
    record = _record_range(sc, pipes)
    out = []
    cache = {}
    for pipe, mean_range in pipes:
        if heading_deg is not None:
            pipe = replace(pipe, heading_deg=float(heading_deg))
        ranges = np.array([mean_range]) if ranges_m is None else np.asarray(ranges_m, dtype=np.float64)
        h = env.height_m + pipe.burial_m
        far = float(np.max(np.hypot(ranges, h)))
        require(far <= record + 1e-6, OptionError,
                f"range {float(ranges.max()):.0f} m is beyond the record of scene '{sc.name}' "
                f"({far:.0f} m slant > record.max_range_m {record:.0f} m)")
        key = replace(pipe, name="")
        if key not in cache:
            rows = sweep(env, pipe, ranges, draws=draws, seed=seed)
            pd = [row["pd"] for row in rows]
            at = {level: crossing_range(ranges, pd, level) for level in LEVELS}
            unc = (uncertainty(env, pipe, ranges, at, seed=seed) if with_uncertainty and ranges.size > 2
                   else {level: math.nan for level in LEVELS})
            cache[key] = (rows, at, unc, line_spacing(ranges, pd) if ranges.size > 1 else math.nan)
        rows, at, unc, spacing = cache[key]
        rows = [{**row, "target": pipe.name} for row in rows]
        out.append(PipePrediction(pipe, mean_range, rows, at, unc, spacing))
    return Prediction(sc.name, out)


def plot(prediction: Prediction, path, *, title: str | None = None) -> None:
    """Figure of Pd against horizontal range for every pipeline, with the ranges of Pd 0.9 and 0.5
    (shaded: their uncertainty), written to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    seen = {}
    for k, p in enumerate(prediction.pipes):
        r = [row["range_m"] for row in p.rows]
        pd = [row["pd"] for row in p.rows]
        key = replace(p.pipe, name="")
        if key in seen:                       # the same pipe: one curve, named after all
            seen[key].set_label(seen[key].get_label() + f", {p.pipe.name}")
            continue
        (line,) = ax.plot(r, pd, "-", color=f"C{k}", label=f"{p.pipe.name}")
        seen[key] = line
        for level in LEVELS:
            x, dx = p.ranges_at[level], p.uncertainty_m[level]
            if math.isfinite(x):
                ax.axvline(x, color=f"C{k}", ls=":", lw=1)
                if math.isfinite(dx):
                    ax.axvspan(x - dx, x + dx, color=f"C{k}", alpha=0.12)
                ax.annotate(f"{level:g}: {x:.0f} m", (x, level), xytext=(4, 4), textcoords="offset points",
                            fontsize=8, color=f"C{k}")
    ax.set_xlabel("horizontal range from the track (m)")
    ax.set_ylabel("probability of detection")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)
    ax.set_title(title or f"{prediction.scene_name}: predicted Pd")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _record_range(scene, pipes: list) -> float:
    """The record's largest slant range (m): ``record.max_range_m``, or the simulator's default (the
    farthest pipeline plus 50 m)."""
    if scene.record.max_range_m is not None:
        return float(scene.record.max_range_m)
    h = scene.seabed.depth_m - scene.sonar.draft_m
    return max(math.hypot(r, h + p.burial_m) for p, r in pipes) + 50.0
