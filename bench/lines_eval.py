"""Lines found in simulated surveys, scored against the simulator's truth: the evaluation table of the README.

Simulates each scene (cached in the work folder), runs ``clbeam survey``'s
processing on it (paper grid, 0.2 m x 0.1 degree, default imaging with the
seabed band 5 m above to 40 m below the seabed), builds the lines and
scores them (:mod:`clbeam.evaluation.line_truth`).  Prints a Markdown table
per scene and the false-line rate of the clutter-only scene against the
score threshold, and times the line building of a 1,000-ping survey
(synthetic detections at the simulated lines' density).

    python bench/lines_eval.py [--work DIR] [--scenes line1,line4,cross,boulders,clutter,clutter:1,clutter:2]

A scene ``NAME:SEED`` is simulated with that random seed (seabed, clutter,
noise); a scene given with several seeds gets a table of its pipelines'
burial errors over them, against the standard errors their lines report.

``family:SEED`` and ``clutter-family:SEED`` are the random survey families
(:mod:`clbeam.sim.families`: the survey drawn from SEED, with and without its
pipelines; SEED also seeds the noise).  ``--family tuning:N`` adds the first N
tuning draws of both, ``--family validation`` every validation draw (32
surveys with pipelines, 8 clutter-only), ``--family validation:N`` the first N
of those with pipelines and every fourth clutter-only one up to N: the figures are reported per split,
tuning (every built-in scene, on which the detector was developed, and the
family's tuning seeds) apart from validation (nothing was ever chosen on it).

    python bench/lines_eval.py --work DIR --scenes "" --family validation

``--model discrete`` renders the family draws under the discrete-scatterer physics
(:mod:`clbeam.sim.discrete`; the same surveys, their files and stores tagged ``-discrete``).
"""

from __future__ import annotations

import argparse
import math
import time
import tracemalloc
from pathlib import Path

import numpy as np

from clbeam.evaluation.line_truth import CHANCE_OFFSETS_M, score_survey
from clbeam.imaging.imager import ImagingOptions
from clbeam.io.pingwrite import write_ping_file
from clbeam.model.grid import PolarGrid
from clbeam.sim import load_scene, simulate
from clbeam.survey import SurveyOptions, run_survey, scan_inputs
from clbeam.survey.line_options import LineOptions
from clbeam.survey.products import finalize_survey

SCENES = ("line1", "line4", "cross", "boulders", "clutter", "clutter:1", "clutter:2")
#: the pings of a family survey (8.23 m apart: 0.32 km)
FAMILY_PINGS = 40
#: the targets of the validation summary: on its line over this share of its detectable pings, position RMS and
#: burial error within these (m), pipelines up to this angle from nadir (degree)
ON_LINE_TARGET, POSITION_TARGET_M, BURIAL_TARGET_M, NADIR_LIMIT_DEG = 0.9, 0.5, 0.5, 60.0


def load_spec(spec: str, model: str = "specular"):
    """The scene of a spec (``NAME``, ``NAME:SEED``, ``family:SEED``, ``clutter-family:SEED``) and its noise seed;
    ``model``: the physics of the family draws (a built-in scene keeps its own)."""
    from clbeam.sim.families import clutter_scene
    from clbeam.sim.families import survey_scene as family_scene

    name, _, seed = spec.partition(":")
    if name in ("family", "clutter-family"):
        draw = int(seed)
        return (family_scene if name == "family" else clutter_scene)(draw, pings=FAMILY_PINGS, model=model), draw
    return load_scene(name), int(seed or 0)


def split_of(spec: str) -> str:
    """``validation`` for a family's validation draw, else ``tuning``."""
    from clbeam.sim.families import is_validation_seed

    name, _, seed = spec.partition(":")
    return "validation" if name in ("family", "clutter-family") and is_validation_seed(int(seed)) else "tuning"


def family_specs(choice: str) -> list:
    """The specs of ``--family``: ``tuning:N`` (the first N tuning draws, with and without pipelines, a clutter
    survey for every fourth), ``validation`` (every validation draw) or ``validation:N`` (the first N with
    pipelines, and a clutter-only one for every fourth)."""
    from clbeam.sim.families import CLUTTER_VALIDATION_SEEDS, VALIDATION_SEEDS

    if choice == "validation":
        return [f"family:{s}" for s in VALIDATION_SEEDS] + [f"clutter-family:{s}" for s in CLUTTER_VALIDATION_SEEDS]
    kind, _, n = choice.partition(":")
    if kind not in ("tuning", "validation") or not n.isdigit():
        raise SystemExit(f"lines_eval: --family is tuning:N, validation or validation:N, got {choice!r}")
    if kind == "validation":
        n_clutter = -(-int(n) // 4)
        return ([f"family:{s}" for s in VALIDATION_SEEDS[:int(n)]]
                + [f"clutter-family:{s}" for s in CLUTTER_VALIDATION_SEEDS[:n_clutter]])
    return [f"family:{s}" for s in range(int(n))] + [f"clutter-family:{s}" for s in range(0, int(n), 4)]


def split_summary(split: str, scored: list, clutter_km: float, clutter_false: int) -> list:
    """Lines of text: a split's pipelines up to :data:`NADIR_LIMIT_DEG` against the targets, those whose
    detectable pings are no more than chance gives (``seen``, :mod:`clbeam.evaluation.line_truth`) named and
    the targets over the others, and
    its false pipeline lines per km over its clutter-only surveys; ``scored``: every target row of the split."""
    rows = [r for r in scored if not r["nadir_deg"] > NADIR_LIMIT_DEG and r["detectable_pings"] > 0]
    unseen = [f"{r.get('scene', '')} {r['target']} ({r['detectable_pings']} pings, {r['chance_pings']:.0f} at the copies)"
              for r in rows if not r["seen"]]
    if not rows:
        return [f"{split}: no pipeline within {NADIR_LIMIT_DEG:g} degrees of nadir was detectable"]
    on = np.array([r["on_line_fraction"] >= ON_LINE_TARGET for r in rows])
    pos = np.array([r["position_rms_m"] for r in rows])
    worst = np.nanmax(pos) if np.isfinite(pos).any() else float("nan")
    bur = np.array([r["burial_error_m"] for r in rows])
    se = np.array([r["burial_se_m"] for r in rows])
    covered = np.abs(bur) <= 2 * se
    out = [f"{split}: {len(rows)} pipelines within {NADIR_LIMIT_DEG:g} degrees of nadir: one line over >= "
           f"{100 * ON_LINE_TARGET:.0f} % of the detectable pings {on.sum()} ({100 * on.mean():.0f} %); position RMS "
           f"<= {POSITION_TARGET_M} m {np.sum(pos <= POSITION_TARGET_M)}, worst {worst:.2f} m; "
           f"burial within {BURIAL_TARGET_M} m {np.sum(np.abs(bur) <= BURIAL_TARGET_M)} "
           f"({100 * np.mean(np.abs(bur) <= BURIAL_TARGET_M):.0f} %), within two reported standard errors "
           f"{covered.sum()} ({100 * covered.mean():.0f} %, nominal 95 %; of the {np.isfinite(bur).sum()} with a line "
           f"{100 * covered.sum() / max(np.isfinite(bur).sum(), 1):.0f} %)"]
    if unseen:
        out.append(f"{split}: of these, {len(unseen)} with no more pings with a detection near them than their "
                   f"copies {' and '.join(f'{d:g}' for d in sorted({abs(v) for v in CHANCE_OFFSETS_M}))} m beyond its "
                   "crossing and its image (their detectable pings are mostly the clutter's): " + ", ".join(unseen))
        seen = np.array([bool(r["seen"]) for r in rows])
        out.append(f"{split}: of the {seen.sum()} seen above chance: one line {on[seen].sum()}, position RMS <= "
                   f"{POSITION_TARGET_M} m {np.sum(pos[seen] <= POSITION_TARGET_M)}, burial within {BURIAL_TARGET_M} m "
                   f"{np.sum(np.abs(bur[seen]) <= BURIAL_TARGET_M)}, within two reported standard errors "
                   f"{covered[seen].sum()}")
    out.append(_trackable_summary(split, rows, on, np.abs(bur) <= BURIAL_TARGET_M))
    doubled = [f"{r.get('scene', '')} {r['target']} ({r['fragments']})" for r in rows if r["fragments"] > 1]
    out.append(f"{split}: {len(doubled)} pipeline(s) with more than one pipeline line along them (duplicates, "
               f"images, fragments): {', '.join(doubled) or 'none'}")
    if clutter_km > 0:
        out.append(f"{split}: {clutter_false} false pipeline line(s) over {clutter_km:.2f} km of clutter-only survey "
                   f"({clutter_false / clutter_km:.2f} per km)")
    return out


def _trackable_summary(split: str, rows: list, one_line: np.ndarray, burial_ok: np.ndarray) -> str:
    """One line of text: how many of ``rows`` a line that followed them exactly would report (``trackable``,
    :mod:`clbeam.evaluation.line_truth`), how many of those are one line and how many within the burial target,
    and the others' path scores."""
    track = np.array([bool(r.get("trackable")) for r in rows])
    below = ", ".join(f"{r.get('scene', '')} {r['target']} ({r.get('path_score', math.nan):.1f})" for r in rows
                      if not r.get("trackable"))
    return (f"{split}: {track.sum()} trackable (a line on the true path would score above the threshold): one line "
            f"{one_line[track].sum()}, burial within {BURIAL_TARGET_M} m {burial_ok[track].sum()}; the others' "
            f"path scores: {below or 'none'}")


def survey_scene(spec: str, work: Path, lines: LineOptions, model: str = "specular"):
    """Simulate (once) and survey one scene (``NAME`` or ``NAME:SEED``; a family draw under the physics
    ``model``); its products."""
    name, _, seed = spec.partition(":")
    tag = f"{name}_s{seed}" if seed else name
    if model != "specular" and name in ("family", "clutter-family"):
        tag += f"-{model}"
    nc = work / f"{tag}.nc"
    if not nc.exists():
        scene, noise_seed = load_spec(spec, model)
        write_ping_file(simulate(scene, seed=noise_seed), nc)
    scan = scan_inputs([nc])
    if not scan.files:
        raise SystemExit(f"lines_eval: {nc} is not a readable ping file; delete it to simulate the scene again")
    grid = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, max_range_m=scan.max_range_m, min_range_m=0.0,
                             angles_deg=(-80.0, 80.0))
    # clbeam survey's defaults: the seabed band given, no per-ping clutter test (the lines do that job)
    opts = SurveyOptions(grid=grid, imaging=ImagingOptions(seabed_band_m=(5.0, 40.0), min_contrast_db=None),
                         lines=lines)
    out = work / f"{tag}.zarr"
    res = run_survey(scan, out, opts)
    return res, nc, out, opts


def scene_rows(name: str, products, nc: Path, scored=None) -> tuple[list, list]:
    """Table rows of one scene, and per pipeline ``(target, burial error, the line's own standard error)`` (m)
    (``scored``: its :func:`score_survey`, made here when not given)."""
    scored = score_survey(products, [nc]) if scored is None else scored
    if scored is None:
        return [], []
    rows, summary = scored
    out, burials = [], []
    for r in rows:
        untrackable = not r.get("trackable") and not math.isnan(r.get("path_score", math.nan))
        target = r["target"] + ("" if r["seen"] else " (at chance)") + (" (untrackable)" if untrackable else "")
        out.append(f"| {name} | {target} | {r['detectable_pings']} | {r['pings_on_line']} "
                   f"({100 * r['on_line_fraction']:.0f} %) | {r['fragments']} | {r['position_rms_m']:.2f} | "
                   f"{r['burial_error_m']:+.2f} | {summary['false_lines']} |")
        burials.append((r["target"], r["burial_error_m"], r["burial_se_m"]))
    if not rows:
        out.append(f"| {name} | (none) | | | | | | {summary['false_lines']} |")
    return out, burials


def burial_over_seeds(burials: dict) -> list:
    """Per scene surveyed with more than one seed and per pipeline: the RMS of its burial error over the seeds,
    how many came within 0.5 m, and the mean standard error its lines reported; ``burials``: scene name ->
    list of :func:`scene_rows`' triples, one list per seed."""
    out = ["| scene | pipeline | surveys (seeds) | burial error, RMS (m) | largest (m) | within 0.5 m "
           "| reported standard error, mean (m) |", "|---|---|---|---|---|---|---|"]
    for name, runs in burials.items():
        if len(runs) < 2:
            continue
        for target in dict.fromkeys(t for run in runs for t, _, _ in run):
            err = np.array([e for run in runs for t, e, _ in run if t == target], dtype=np.float64)
            se = np.array([r for run in runs for t, _, r in run if t == target], dtype=np.float64)
            found = np.isfinite(err)
            if not found.any():
                out.append(f"| {name} | {target} | 0 of {len(runs)} | | | 0 | |")
                continue
            se = se[np.isfinite(se)]
            out.append(f"| {name} | {target} | {found.sum()} of {len(runs)} | {np.sqrt(np.mean(err[found] ** 2)):.2f} "
                       f"| {np.max(np.abs(err[found])):.2f} | {np.sum(np.abs(err[found]) <= 0.5)} "
                       f"| {np.mean(se) if se.size else float('nan'):.2f} |")
    return out if len(out) > 2 else []


def false_rate(runs: list, thresholds=(-6, -4, -2, 0, 2, 4, 6)) -> list:
    """Pipeline lines (and lines of any kind) per km against the score threshold over clutter-only surveys
    (the lines built once with no threshold, counted by score, without the edges test: it would image every
    chance track's detections again); ``runs``: ``(store, options, input file)``."""
    rows, km = [], 0.0
    kept = []
    for out, opts, nc in runs:
        pr = finalize_survey(out, SurveyOptions(grid=opts.grid, imaging=opts.imaging,
                                                lines=LineOptions(min_score=-1e9)))
        km += pr.track_km
        kept += pr.lines.rows
        finalize_survey(out, opts, inputs=[nc])  # the products with the default threshold again
    for s in thresholds:
        over = [r for r in kept if r["score"] >= s]
        n_pipe = sum(r["kind"] == "pipeline" for r in over)
        rows.append(f"| {s:g} | {n_pipe} | {n_pipe / km:.2f} | {len(over)} |")
    chance = [r["score"] for r in kept if r["kind"] == "pipeline"]
    best = f"the best chance pipeline line scores {max(chance):.1f}" if chance else "no chance pipeline line at all"
    return [f"{len(runs)} clutter-only survey(s), {km:.2f} km; {best} ({len(chance)} pipeline-kind track(s) of any "
            "score)", "", "| min score | pipeline lines | per km | lines of any kind |", "|---|---|---|---|"] + rows


def time_thousand_pings(density_per_m: float = 0.05, n_pings: int = 1000) -> str:
    """Line building of a synthetic 1,000-ping survey: seconds (three runs, no allocation tracing) and the peak
    memory of the search (a fourth run, traced)."""
    from clbeam.survey.line_products import line_ranker
    from clbeam.survey.lines import TrackFrame, find_tracks

    rng = np.random.default_rng(0)
    ping, y, b = [], [], []
    for k in range(n_pings):
        n = rng.poisson(density_per_m * 1400)
        ping += [k] * (n + 2)
        y += list(rng.uniform(-700, 700, n)) + [-300 + 0.05 * k * 8 + rng.normal(0, 0.3), 450 + rng.normal(0, 0.3)]
        b += list(rng.uniform(-2, 25, n)) + [1.0, 1.2]
    ping, y, b = map(np.asarray, (ping, y, b))
    s = np.arange(n_pings) * 8.0
    frame = TrackFrame(ping=ping, s=s[ping], y=y, b=b, cf=np.full(ping.size, 0.6), b_sigma=np.full(ping.size, 0.2),
                       b_post=b, pings=np.arange(n_pings), ping_s=s)
    times = []
    for _ in range(3):  # untraced: tracing every allocation slows the search by about half
        t0 = time.perf_counter()
        tracks = find_tracks(frame, LineOptions(), rank=line_ranker(frame, LineOptions()))
        times.append(time.perf_counter() - t0)
    tracemalloc.start()
    find_tracks(frame, LineOptions(), rank=line_ranker(frame, LineOptions()))
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return (f"{n_pings} pings, {ping.size} detections ({density_per_m:g} per m across per ping): {len(tracks)} "
            f"tracks in {np.median(times):.2f} s (median of three, {min(times):.2f}-{max(times):.2f} s), peak "
            f"memory of the search {peak / 1e6:.1f} MB (a fourth run, traced)")


def main(argv=None) -> None:
    """Simulate, survey and score the scenes and family draws of the command line (``argv``, default
    ``sys.argv``) and print the tables per split, the false-line rates and the 1,000-ping timing."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", default="lines_eval", type=Path)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--family", action="append", default=[], metavar="tuning:N|validation",
                    help="add survey-family draws (repeatable)")
    ap.add_argument("--model", default="specular", choices=("specular", "discrete"),
                    help="the physics the family draws are rendered under")
    args = ap.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)
    header = ["| scene | pipeline | detectable pings | on its line | fragments | position RMS (m) | burial error (m) "
              "| false pipeline lines |", "|---|---|---|---|---|---|---|---|"]
    tables = {"tuning": list(header), "validation": list(header)}
    clutter, burials = [], {}
    scored_by_split = {"tuning": [], "validation": []}
    clutter_by_split = {"tuning": [0.0, 0], "validation": [0.0, 0]}
    specs = [s for s in args.scenes.split(",") if s] + [s for f in args.family for s in family_specs(f)]
    for spec in specs:
        t0 = time.perf_counter()
        split = split_of(spec)
        res, nc, out, opts = survey_scene(spec, args.work, LineOptions(), args.model)
        scored = score_survey(res.products, [nc])
        for r in scored[0] if scored is not None else ():
            r["scene"] = spec
        rows, scene_burials = scene_rows(spec, res.products, nc, scored)
        tables[split] += rows
        if scored is not None:
            if spec.partition(":")[0] in ("clutter", "clutter-family"):
                clutter_by_split[split][0] += scored[1]["track_km"]
                clutter_by_split[split][1] += scored[1]["false_lines"]
            else:
                scored_by_split[split] += scored[0]
        # a family's draws are different surveys, a built-in scene's seeds the same one's noise
        burials.setdefault(spec if spec.partition(":")[0] in ("family", "clutter-family") else spec.partition(":")[0],
                           []).append(scene_burials)
        scores = [r["score"] for r in res.products.lines.rows if r["kind"] == "pipeline"]
        print(f"{spec}: surveyed in {time.perf_counter() - t0:.0f} s, {res.products.n_pipelines} pipeline line(s)"
              + (f" scoring {min(scores):.1f}-{max(scores):.1f}" if scores else ""))
        if spec.startswith("clutter"):
            clutter.append((out, opts, nc))
    if clutter:
        print("\n" + "\n".join(false_rate(clutter)))
    for split in ("tuning", "validation"):
        if len(tables[split]) > 2:
            print(f"\n{split.capitalize()} scenes\n\n" + "\n".join(tables[split]))
            print("\n" + "\n".join(split_summary(split, scored_by_split[split], *clutter_by_split[split])))
    seeds = burial_over_seeds({k: v for k, v in burials.items() if k != "clutter"})
    if seeds:
        print("\nBurials over noise seeds\n\n" + "\n".join(seeds))
    print("\n" + time_thousand_pings())


if __name__ == "__main__":
    main()
