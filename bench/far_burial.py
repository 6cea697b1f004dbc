"""What bounds a far pipe's burial: Line 4's pipeline C (920 m, 76 degrees from nadir) with and without noise.

Simulates the first pings of Line 4 four ways (the scene as it is; without
noise; without the seabed's scattering; without either), images a window
around C on the paper grid (0.2 m x 0.1 degree, default imaging) and, over
the pings where C's echo lies where it crosses the ping's plane (the pipe
near broadside, its image within 0.5 m of the crossing), prints the depth
error of the most intense refined peak within 3 m of C across the track:
its mean and standard deviation over the pings.

    python bench/far_burial.py [--pings 12] [--seed 0]
"""

from __future__ import annotations

import argparse

import numpy as np

from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.io.pingfile import pings_from_dataset
from clbeam.model.grid import PolarGrid
from clbeam.sim import load_scene, simulate

NO_SCATTER = {"seabed.scattering.strength_db": -120.0}
VARIANTS = {"as simulated": {}, "no noise": {"snr_db": None}, "no seabed scattering": {"overrides": NO_SCATTER},
            "neither": {"snr_db": None, "overrides": NO_SCATTER}}


def depth_errors(pings: int, seed: int, **scene_options) -> np.ndarray:
    """C's peak depth minus its true depth (m) in each broadside ping of one simulation."""
    ds = simulate(load_scene("line4", pings=pings, **scene_options), seed=seed)
    t = [str(v) for v in ds["target"].values].index("C")
    y, z = ds["truth_target_y"].values[:, t], ds["truth_target_z"].values[:, t]
    image_y = ds["truth_target_image_y"].values[:, t]
    imager = Imager(PolarGrid(np.arange(935.0, 960.0, 0.2), np.arange(73.0, 79.0, 0.1)), ImagingOptions())
    errors = []
    for k, ping in enumerate(pings_from_dataset(ds)):
        if abs(image_y[k] - y[k]) > 0.5:
            continue
        near = [r for r in imager.image(ping).peaks if abs(r["y_m"] - y[k]) < 3.0]
        if near:
            errors.append(max(near, key=lambda r: r["intensity_db"])["z_m"] - z[k])
    return np.asarray(errors)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pings", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    if args.pings < 1:
        ap.error(f"--pings must be at least 1, got {args.pings}")
    print("| simulation | broadside pings | depth error mean (m) | std (m) | per ping (m) |\n|---|---|---|---|---|")
    for name, options in VARIANTS.items():
        e = depth_errors(args.pings, args.seed, **options)
        if e.size == 0:
            print(f"| {name} | 0 | | | (C not broadside, or not detected, in these pings) |", flush=True)
            continue
        print(f"| {name} | {e.size} | {e.mean():+.2f} | {e.std():.2f} | {' '.join(f'{v:+.1f}' for v in e)} |",
              flush=True)


if __name__ == "__main__":
    main()
