"""Predicted Pd against the detection fraction measured on simulated surveys (docs/detectability.md).

For each seabed (Line 4's mud, and sand) a scene with broadside pipes at eight horizontal ranges,
1 m deep to starboard and 2 m to port, is simulated and imaged around each pipe with the imager's
default detection test, on grids whose nodes lie a random fraction of a range step from each pipe's echo
(redrawn every block of pings).  A ping detects a pipe when a peak lies on the pipe's equal-delay arc
within the arc window of its echo (``arc``); ``placed`` also asks for the peak within the scoring window
of the pipe's image.  The same pings with the pipes silent (reflectivity 0) give each window's false
detections.  The model (:mod:`clbeam.evaluation.detectability`, no water absorption: the simulator has
none) is evaluated at the same ranges.  The tuning draws (``--tune-seed``) are the ones any choice of the
model or the scoring was looked at on; the validation draws (``--seeds``) report.

    python bench/detectability_eval.py [--pings 24] [--seeds 2 3] [--tune-seed 1] [--tune-pings 12]
        [--silent-pings 8] [--offsets 64] [--beside 8] [--one-side] [--cache DIR]
        [--out docs/detectability_validation.png] [--csv detectability_validation.csv]

``--cache DIR`` keeps each survey's peaks (a pickle per seabed, seed, pings and silence) so that a rerun
scores them again without simulating; about 20 s a ping on two shared cores, 10 s silent.
``--one-side`` surveys each side's pipes alone, twice the pings: the two pipes of a range lie at one
horizontal range, and their echoes cross on a few channels (docs/detectability.md, "Near ranges").
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import pickle
import time

import numpy as np

RANGES = (250.0, 450.0, 650.0, 850.0, 1000.0, 1150.0, 1300.0, 1450.0)
BURIALS = (1.0, 2.0)


def predicted(seabed: str, offsets: int | None = None, beside: int | None = None) -> dict:
    """``{(burial, range): Pd}`` of the model on the seabed's validation scene (``offsets``: the model's
    grid offsets, ``beside``: its beams each side of the echo's; default its own)."""
    from clbeam.evaluation.detectability import Environment, Pipe, detections
    from clbeam.evaluation.detectability_validation import validation_scene

    env = Environment(validation_scene(seabed, RANGES, BURIALS), absorption_db_per_km=0.0)
    kw = {k: v for k, v in (("offsets", offsets), ("beside", beside)) if v is not None}
    return {(b, r): res["pd"] for b in BURIALS
            for r, res in zip(RANGES, detections(env, Pipe(burial_m=b), RANGES, draws=4096, **kw))}


def survey_peaks(seabed: str, seed: int, pings: int, *, silent: bool = False, cache: str | None = None,
                 sides: str = "SP") -> dict:
    """:func:`~clbeam.evaluation.detectability_validation.ping_peaks` of one survey (the pipes of ``sides``),
    from ``cache`` where it holds them."""
    from clbeam.evaluation.detectability_validation import ping_peaks, validation_scene

    tag = "" if sides == "SP" else f"_{sides}"
    path = None if cache is None else os.path.join(cache, f"peaks_{seabed}_{seed}_{pings}{'_silent' * silent}{tag}.pkl")
    if path is not None and os.path.exists(path):
        with open(path, "rb") as fh:
            return pickle.load(fh)
    t0 = time.perf_counter()
    peaks = ping_peaks(validation_scene(seabed, RANGES, BURIALS, pings=pings, silent=silent, sides=sides), seed=seed)
    print(f"  {seabed} seed {seed}{' silent' * silent} {sides}: {pings} pings in {time.perf_counter() - t0:.0f} s", flush=True)
    if path is not None:
        os.makedirs(cache, exist_ok=True)
        with open(path, "wb") as fh:
            pickle.dump(peaks, fh)
    return peaks


def measured(seabed: str, seeds, pings: int, *, silent: bool = False, cache: str | None = None,
             one_side: bool = False) -> dict:
    """``{(burial, range): {"arc": (hits, pings), "placed": (hits, pings)}}`` over the seeds; ``one_side``:
    each side's pipes surveyed alone (no echo of the other side's pipe crossing theirs)."""
    from clbeam.evaluation.detectability_validation import arc_window, score, validation_scene

    window = arc_window(validation_scene(seabed, RANGES, BURIALS))
    out: dict = {}
    surveys = [(seed, sides) for seed in seeds for sides in (("S", "P") if one_side else ("SP",))]
    for seed, sides in surveys:
        peaks = survey_peaks(seabed, seed, pings, silent=silent, cache=cache, sides=sides)
        for name, counts in score(peaks, window).items():
            key = (BURIALS[0] if name[0] == "S" else BURIALS[1], float(name[1:]))
            prev = out.setdefault(key, {"arc": (0, 0), "placed": (0, 0)})
            out[key] = {k: (prev[k][0] + counts[k][0], prev[k][1] + counts[k][1]) for k in counts}
    return out


def _frac(counts) -> float:
    return counts[0] / counts[1] if counts[1] else math.nan


def report(label: str, pred: dict, meas: dict, silent: dict) -> list[dict]:
    """Rows of the table and the markdown lines printed; the worst difference, the false detections and
    the R50 check."""
    rows = []
    print(f"\n{label}\n\n| seabed | burial (m) | range (m) | predicted Pd | on the arc | fraction | difference | placed |"
          " false on silent pings |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for (seabed, b, r), pd in sorted(pred.items()):
        m, s = meas[(seabed, b, r)], silent.get((seabed, b, r), {"arc": (0, 0)})
        frac = _frac(m["arc"])
        rows.append({"set": label, "seabed": seabed, "burial_m": b, "range_m": r, "pd": pd, "hits": m["arc"][0],
                     "pings": m["arc"][1], "fraction": frac, "difference": frac - pd,
                     "placed": _frac(m["placed"]), "false_hits": s["arc"][0], "silent_pings": s["arc"][1]})
        print(f"| {seabed} | {b:g} | {r:.0f} | {pd:.2f} | {m['arc'][0]}/{m['arc'][1]} | {frac:.2f} | {frac - pd:+.2f} |"
              f" {_frac(m['placed']):.2f} | {s['arc'][0]}/{s['arc'][1]} |")
    worst = max(rows, key=lambda row: abs(row["difference"]))
    print(f"\nworst |measured - predicted|: {abs(worst['difference']):.2f} ({worst['seabed']}, {worst['burial_m']:g} m, "
          f"{worst['range_m']:.0f} m); within 0.15: {sum(abs(r['difference']) <= 0.15 for r in rows)} of {len(rows)}")
    false_hits, silent_n = sum(r["false_hits"] for r in rows), sum(r["silent_pings"] for r in rows)
    if silent_n:
        print(f"false detections in the arc window on silent pings: {false_hits} of {silent_n} ({false_hits / silent_n:.4f})")
    _r50(pred, meas)
    return rows


def _r50(pred: dict, meas: dict) -> None:
    """The ranges of 50 % detection, predicted against measured on the arc."""
    from clbeam.evaluation.detectability_sweep import crossing_range

    print("\n| seabed | burial (m) | predicted R50 (m) | measured R50 (m) | difference |\n|---|---:|---:|---:|---:|")
    for seabed in sorted({k[0] for k in pred}):
        for b in BURIALS:
            p50 = crossing_range(RANGES, [pred[(seabed, b, r)] for r in RANGES], 0.5)
            m50 = crossing_range(RANGES, [_frac(meas[(seabed, b, r)]["arc"]) for r in RANGES], 0.5)
            print(f"| {seabed} | {b:g} | {p50:.0f} | {m50:.0f} | {100 * (m50 - p50) / p50:+.1f} % |")


def figure(path: str, pred: dict, meas: dict) -> None:
    """Predicted Pd curves and measured fractions on the arc with their binomial standard errors."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, seabed in zip(axes, ("mud", "sand")):
        for b, colour in zip(BURIALS, ("C0", "C1")):
            ax.plot(RANGES, [pred[(seabed, b, r)] for r in RANGES], "-", color=colour, label=f"{b:g} m predicted")
            frac = np.array([_frac(meas[(seabed, b, r)]["arc"]) for r in RANGES])
            n = np.array([meas[(seabed, b, r)]["arc"][1] for r in RANGES])
            err = np.sqrt(np.maximum(frac * (1 - frac), 0.25 / n) / n)
            ax.errorbar(RANGES, frac, yerr=err, fmt="o", color=colour, capsize=3, label=f"{b:g} m measured")
        ax.set_title(f"{seabed}")
        ax.set_xlabel("horizontal range (m)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("probability of detection")
    axes[0].legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"figure: {path}")


def _arguments(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pings", type=int, default=24, help="pings per validation seed (default 24)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[2, 3], help="validation seeds (default 2 3)")
    ap.add_argument("--tune-seed", type=int, default=1, help="tuning seed (default 1)")
    ap.add_argument("--tune-pings", type=int, default=12, help="pings of the tuning seed (default 12; 0: none)")
    ap.add_argument("--silent-pings", type=int, default=8, help="silent pings per seed (default 8; 0: none)")
    ap.add_argument("--offsets", type=int, nargs="+", default=None,
                    help="the model's grid offsets, one table each (default the model's own)")
    ap.add_argument("--beside", type=int, default=None,
                    help="the model's beams searched each side of the echo's (default its own; 0: the echo's beam only)")
    ap.add_argument("--cache", default=None, help="folder keeping each survey's peaks")
    ap.add_argument("--one-side", action="store_true",
                    help="survey each side's pipes alone (the two sides' echoes cross at one horizontal range)")
    ap.add_argument("--out", default="docs/detectability_validation.png", help="figure")
    ap.add_argument("--csv", default=None, help="table of every row (CSV)")
    args = ap.parse_args(argv)
    if args.pings < 1:
        ap.error(f"--pings must be at least 1, got {args.pings}")
    return args


def main(argv=None) -> None:
    """Measure the surveys, predict, print the tables, draw the figure (module docstring)."""
    args = _arguments(argv)
    sets = ([(f"tuning (seed {args.tune_seed}, {args.tune_pings} pings)", [args.tune_seed], args.tune_pings)]
            if args.tune_pings else [])
    sets.append((f"validation (seeds {' '.join(map(str, args.seeds))}, {args.pings} pings each)", args.seeds, args.pings))
    rows = []
    for offsets in args.offsets or [None]:
        pred = {(s, *k): v for s in ("mud", "sand") for k, v in predicted(s, offsets, args.beside).items()}
        for label, seeds, pings in sets:
            meas = {(s, *k): v for s in ("mud", "sand") for k, v in measured(s, seeds, pings, cache=args.cache,
                                                                        one_side=args.one_side).items()}
            silent = {} if not args.silent_pings else {
                (s, *k): v for s in ("mud", "sand")
                for k, v in measured(s, seeds, args.silent_pings, silent=True, cache=args.cache,
                                    one_side=args.one_side).items()}
            rows += report(f"{label}, model offsets {offsets or 'default'}", pred, meas, silent)
    figure(args.out, pred, meas)
    if args.csv:
        with open(args.csv, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)


if __name__ == "__main__":
    main()
