"""Predicted Pd against the detection fraction measured on simulated surveys (docs/detectability.md).

For each seabed (Line 4's mud, and sand) a scene with broadside pipes at eight horizontal ranges,
1 m deep to starboard and 2 m to port, is simulated and imaged around each pipe with the imager's
default detection test; a ping detects a pipe when a peak lies within the scoring window of its image.
The model (:mod:`clbeam.evaluation.detectability`, no water absorption: the simulator has none) is
evaluated at the same ranges.  The tuning draws (``--tune-seed``) are the ones any choice of the
model was looked at on; the validation draws (``--seeds``) report.

    python bench/detectability_eval.py [--pings 24] [--seeds 2 3] [--tune-seed 1] [--tune-pings 12]
        [--out docs/detectability_validation.png] [--csv detectability_validation.csv]
"""

from __future__ import annotations

import argparse
import csv
import math
import time

import numpy as np

RANGES = (250.0, 450.0, 650.0, 850.0, 1000.0, 1150.0, 1300.0, 1450.0)
BURIALS = (1.0, 2.0)


def predicted(seabed: str) -> dict:
    """``{(burial, range): Pd}`` of the model on the seabed's validation scene."""
    from clbeam.evaluation.detectability import Environment, Pipe, detections
    from clbeam.evaluation.detectability_validation import validation_scene

    env = Environment(validation_scene(seabed, RANGES, BURIALS), absorption_db_per_km=0.0)
    return {(b, r): res["pd"] for b in BURIALS
            for r, res in zip(RANGES, detections(env, Pipe(burial_m=b), RANGES, draws=4096))}


def measured(seabed: str, seeds, pings: int) -> dict:
    """``{(burial, range): (hits, pings)}`` over the seeds."""
    from clbeam.evaluation.detectability_validation import measure, validation_scene

    out = {}
    for seed in seeds:
        t0 = time.perf_counter()
        counts = measure(validation_scene(seabed, RANGES, BURIALS, pings=pings), seed=seed)
        print(f"  {seabed} seed {seed}: {pings} pings in {time.perf_counter() - t0:.0f} s", flush=True)
        for name, (hits, n) in counts.items():
            key = (BURIALS[0] if name[0] == "S" else BURIALS[1], float(name[1:]))
            h0, n0 = out.get(key, (0, 0))
            out[key] = (h0 + hits, n0 + n)
    return out


def report(label: str, pred: dict, meas: dict) -> list[dict]:
    """Rows of the table and the markdown lines printed; the worst difference and the R50 check."""
    from clbeam.evaluation.detectability_sweep import crossing_range

    rows = []
    print(f"\n{label}\n\n| seabed | burial (m) | range (m) | predicted Pd | measured | fraction | difference |\n"
          "|---|---:|---:|---:|---:|---:|---:|")
    for (seabed, b, r), pd in sorted(pred.items()):
        hits, n = meas[(seabed, b, r)]
        frac = hits / n
        rows.append({"set": label, "seabed": seabed, "burial_m": b, "range_m": r, "pd": pd, "hits": hits,
                     "pings": n, "fraction": frac, "difference": frac - pd})
        print(f"| {seabed} | {b:g} | {r:.0f} | {pd:.2f} | {hits}/{n} | {frac:.2f} | {frac - pd:+.2f} |")
    worst = max(rows, key=lambda row: abs(row["difference"]))
    print(f"\nworst |measured - predicted|: {abs(worst['difference']):.2f} ({worst['seabed']}, {worst['burial_m']:g} m, "
          f"{worst['range_m']:.0f} m)")
    print("\n| seabed | burial (m) | predicted R50 (m) | measured R50 (m) | difference |\n|---|---:|---:|---:|---:|")
    for seabed in sorted({k[0] for k in pred}):
        for b in BURIALS:
            p50 = crossing_range(RANGES, [pred[(seabed, b, r)] for r in RANGES], 0.5)
            m50 = crossing_range(RANGES, [meas[(seabed, b, r)][0] / meas[(seabed, b, r)][1] for r in RANGES], 0.5)
            print(f"| {seabed} | {b:g} | {p50:.0f} | {m50:.0f} | {100 * (m50 - p50) / p50:+.1f} % |")
    return rows


def figure(path: str, pred: dict, meas: dict) -> None:
    """Predicted Pd curves and measured fractions with their binomial standard errors."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, seabed in zip(axes, ("mud", "sand")):
        for b, colour in zip(BURIALS, ("C0", "C1")):
            ax.plot(RANGES, [pred[(seabed, b, r)] for r in RANGES], "-", color=colour, label=f"{b:g} m predicted")
            frac = np.array([meas[(seabed, b, r)][0] / meas[(seabed, b, r)][1] for r in RANGES])
            n = np.array([meas[(seabed, b, r)][1] for r in RANGES])
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


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pings", type=int, default=24, help="pings per validation seed (default 24)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[2, 3], help="validation seeds (default 2 3)")
    ap.add_argument("--tune-seed", type=int, default=1, help="tuning seed (default 1)")
    ap.add_argument("--tune-pings", type=int, default=12, help="pings of the tuning seed (default 12; 0: none)")
    ap.add_argument("--out", default="docs/detectability_validation.png", help="figure")
    ap.add_argument("--csv", default=None, help="table of every row (CSV)")
    args = ap.parse_args(argv)
    if args.pings < 1:
        ap.error(f"--pings must be at least 1, got {args.pings}")
    pred, tune, valid = {}, {}, {}
    for seabed in ("mud", "sand"):
        pred.update({(seabed, *k): v for k, v in predicted(seabed).items()})
        if args.tune_pings:
            tune.update({(seabed, *k): v for k, v in measured(seabed, [args.tune_seed], args.tune_pings).items()})
        valid.update({(seabed, *k): v for k, v in measured(seabed, args.seeds, args.pings).items()})
    rows = report(f"tuning (seed {args.tune_seed}, {args.tune_pings} pings)", pred, tune) if tune else []
    rows += report(f"validation (seeds {' '.join(map(str, args.seeds))}, {args.pings} pings each)", pred, valid)
    figure(args.out, pred, valid)
    if args.csv:
        with open(args.csv, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    if any(math.isnan(row["fraction"]) for row in rows):  # pragma: no cover - a ping count of zero
        raise SystemExit("no pings measured")


if __name__ == "__main__":
    main()
