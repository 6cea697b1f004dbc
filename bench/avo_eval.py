"""Grain size from self-calibrated backscatter on simulated provinces, against the simulator's truth.

Simulates each scene (cached in the work folder), images it as the AVO
acceptance test does (0.5 m x 0.5 degree, +-75 degree, 500 m), runs
``clbeam avo --pings`` (20-ping patches, no absorption: the simulator has
none) and prints a Markdown table per patch: the province's grain size and
the inverted one with its 68 % interval, the nadir reflection coefficient
against the truth, each patch's calibration and the survey's against the
simulator's own (replica amplitude 1 at 1 m, 64 channels: -20 log10 64).

    python bench/avo_eval.py [--work DIR] [--scenes avo3,avo2,avo3:1]

A scene ``NAME:SEED`` is simulated with that random seed (scatterers, noise).
"""

from __future__ import annotations

import argparse
import csv
import math
import tempfile
import time
from pathlib import Path

import numpy as np
import xarray as xr

from clbeam.cli.main import main
from clbeam.io.pingwrite import write_ping_file
from clbeam.sim import load_scene, simulate

TRUE_CALIBRATION_DB = -20 * math.log10(64)


def run_scene(spec: str, work: Path):
    """Simulate (once), image and run ``clbeam avo --pings`` on one scene: the table's rows, the truth per ping
    and the seconds ``clbeam avo`` took."""
    name, _, seed = spec.partition(":")
    tag = f"{name}_s{seed}" if seed else name
    pings = work / f"{tag}.nc"
    if not pings.exists():
        write_ping_file(simulate(load_scene(name), seed=int(seed or 0)), pings)
    with xr.open_dataset(pings, engine="h5netcdf") as ds:
        truth = {k: np.asarray(ds[f"truth_{k}"].values) for k in ("province_mz", "nadir_reflection")}
    images = work / f"{tag}_img.nc"
    if not images.exists():
        assert main(["image", str(pings), "-o", str(images), "--range-res", "0.5", "--angle-res", "0.5",
                     "--angles", "-75", "75", "--max-range", "500", "-q"]) == 0
    out = work / f"{tag}_avo.csv"
    t0 = time.perf_counter()
    assert main(["avo", str(images), "-o", str(out), "--pings-per-patch", "20", "--absorption", "0",
                 "--pings", str(pings), "--figures", str(work / f"{tag}_figs"), "-q"]) == 0
    seconds = time.perf_counter() - t0
    with out.open() as fh:
        return list(csv.DictReader(fh)), truth, seconds


def table(spec: str, rows: list, truth: dict) -> list[str]:
    """Markdown rows of one scene."""
    out = []
    for r in rows:
        k = int(r["ping_start"])
        mz, r0 = truth["province_mz"][k], truth["nadir_reflection"][k]
        got = float(r["nadir_reflection"])
        flag = f" ({r['unresolved']})" if r["unresolved"] else ""
        out.append(
            f"| {spec} | {r['ping_start']}-{int(r['ping_stop']) - 1} {r['side']} | {mz:g} | "
            f"{float(r['mz_phi']):.2f} [{float(r['mz_low_phi']):.2f}, {float(r['mz_high_phi']):.2f}]{flag} | "
            f"{r0:.3f} | {got:.3f} ± {float(r['nadir_reflection_error']):.3f} ({100 * (got / r0 - 1):+.0f} %) | "
            f"{float(r['nadir_calibration_db']) - TRUE_CALIBRATION_DB:+.2f} ± "
            f"{float(r['nadir_calibration_error_db']):.2f} | {float(r['calibration_db']) - TRUE_CALIBRATION_DB:+.2f} |")
    return out


def main_eval(argv=None) -> int:
    """Run the evaluation and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", default=None, help="folder for the simulated and imaged files (default: a temporary one)")
    ap.add_argument("--scenes", default="avo3,avo2", help="comma-separated scenes, NAME or NAME:SEED")
    args = ap.parse_args(argv)
    work = Path(args.work or tempfile.mkdtemp(prefix="avo_eval_"))
    work.mkdir(parents=True, exist_ok=True)
    lines = ["| scene | pings, side | Mz truth | Mz [68 %] | R truth | R measured | patch calibration − truth (dB) "
             "| survey calibration − truth (dB) |", "|---|---|---|---|---|---|---|---|"]
    for spec in args.scenes.split(","):
        rows, truth, seconds = run_scene(spec, work)
        lines += table(spec, rows, truth)
        print(f"{spec}: clbeam avo --pings took {seconds:.1f} s for {len(truth['province_mz'])} pings")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main_eval())
