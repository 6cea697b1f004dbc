"""Peaks per ping on the simulated Line 1 with the CF threshold alone, with the noise test (the channel
minimum and the level above the noise floor) and with the default test (also the clutter contrast), and
the pipeline detections kept (docs/peaks.md).

    python bench/detection_line1.py [--pings 3]

A peak is near a target when it is the demo's detection of it (within the
demo's horizontal distance and 5 m of depth); the others are the rest.
"""

from __future__ import annotations

import argparse


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pings", type=int, default=3, help="pings to simulate (default 3)")
    parser.add_argument("--scene", default="line1", help="built-in scene (default line1; line4: the pipelines at 595-920 m)")
    args = parser.parse_args()

    from clbeam.evaluation.demo import score_targets, truth_yz
    from clbeam.imaging.imager import Imager, ImagingOptions
    from clbeam.io.pingfile import pings_from_dataset
    from clbeam.model.grid import PolarGrid
    from clbeam.sim import load_scene, simulate

    n = args.pings
    ds = simulate(load_scene(args.scene, pings=n, max_range_m=1100.0))
    pings = pings_from_dataset(ds, args.scene)
    grid = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, max_range_m=1100.0, angles_deg=(-80.0, 80.0))
    tests = {"CF threshold only": ImagingOptions(min_channels=1, min_snr_db=None, min_contrast_db=None),
             "noise test": ImagingOptions(min_contrast_db=None),
             "default test (noise and clutter contrast)": ImagingOptions()}
    imagers = {k: Imager(grid, o) for k, o in tests.items()}
    counts = {k: [0, 0, 0, 0] for k in tests}
    for i in range(n):
        truth = truth_yz(ds, i)
        for label, imager in imagers.items():
            rows = imager.image(pings.ping(i)).peaks
            scores, rest = score_targets(rows, truth[:, 0], truth[:, 1], ds["target"].values, i)
            c = counts[label]
            c[0], c[1] = c[0] + len(rows), c[1] + len(rest)
            c[2], c[3] = c[2] + sum(s.detected for s in scores), c[3] + len(scores)
        print(f"ping {i} done", flush=True)
    print("| peaks | per ping | near no target, per ping | targets detected |\n|---|---:|---:|---:|")
    for label, (total, others, hits, targets) in counts.items():
        print(f"| {label} | {total / n:.0f} | {others / n:.1f} | {hits}/{targets} |", flush=True)


if __name__ == "__main__":
    main()
