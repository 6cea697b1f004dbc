"""Simulated surveys that check the detection-performance model: the same pipe at many horizontal ranges,
its measured detection fraction against the predicted Pd (docs/detectability.md, ``bench/detectability_eval.py``).

:func:`validation_scene` builds Line 4's environment (or a sand seabed) with pipes parallel to the track
(broadside to every ping) at the given ranges, one burial to starboard and another to port;
:func:`measure` simulates its pings, images a window around each pipe with the imager's default
detection test and counts the pings with a peak within the scoring window of the pipe's image
(:data:`~clbeam.evaluation.scoring.HIT_HORIZONTAL_M`, :data:`~clbeam.evaluation.scoring.HIT_VERTICAL_M`).
"""

from __future__ import annotations

import importlib.resources
import math
import tomllib

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.evaluation.scoring import HIT_HORIZONTAL_M, HIT_VERTICAL_M

#: the seabeds of the validation: Line 4's mud as the paper describes it, and a sand (the simulator's
#: sediment is never faster than the water: its speed ratio stays 1)
SEABEDS = {
    "mud": {"seabed": {}, "scattering_db": -30.0, "snr_db": 15.0},
    "sand": {"seabed": {"sound_speed_ratio": 1.0, "density_ratio": 1.9, "attenuation_db_per_m": 0.25},
             "scattering_db": -22.0, "snr_db": 25.0},
}
#: half-sizes of the image window about each pipe (m of range, degree of angle): the clutter window's
CLUTTER_HALF = (11.0, 7.0)
#: pings simulated at a time (a ping depends only on the scene, the seed and its index)
BLOCK_PINGS = 8


def validation_scene(seabed: str, ranges_m, burials_m=(1.0, 2.0), *, pings: int = 10, snr_db: float | None = None):
    """Line 4's scene with broadside pipes at ``ranges_m`` (m): burial ``burials_m[0]`` to starboard,
    ``burials_m[1]`` to port, named ``S<range>`` and ``P<range>``.

    Parameters
    ----------
    seabed : {"mud", "sand"}
        :data:`SEABEDS`.
    ranges_m : sequence of float
        Horizontal ranges (m).
    burials_m : (float, float)
        Burials of the starboard and port pipes (m).
    pings : int
        Pings of the line.
    snr_db : float, optional
        Noise re the nadir seabed echo (dB); default the seabed's in :data:`SEABEDS`.
    """
    from clbeam.sim.catalog import scene_from_mapping

    require(seabed in SEABEDS, OptionError, f"seabed must be one of {', '.join(SEABEDS)}, got {seabed!r}")
    spec = SEABEDS[seabed]
    d = tomllib.loads((importlib.resources.files("clbeam.sim.scenes") / "line4.toml").read_text())
    d["seabed"].update(spec["seabed"])
    d["seabed"]["scattering"]["strength_db"] = spec["scattering_db"]
    d["snr_db"] = spec["snr_db"] if snr_db is None else snr_db
    d["survey"]["pings"] = pings
    h = d["seabed"]["depth_m"] - d["sonar"]["draft_m"]
    d["record"]["max_range_m"] = float(math.hypot(max(ranges_m), h + max(burials_m)) + 2 * CLUTTER_HALF[0])
    d["target"] = [{"kind": "line", "name": f"{side}{int(round(r))}", "y_m": sign * float(r), "angle_deg": 0.0,
                    "curvature_deg_per_km": 0.0, "radius_m": 0.11, "burial_m": float(b), "reflectivity": 0.8}
                   for side, sign, b in (("S", 1.0, burials_m[0]), ("P", -1.0, burials_m[1])) for r in ranges_m]
    return scene_from_mapping(d, name=f"{seabed}-validation")


def measure(scene, *, seed: int = 0, progress=None) -> dict:
    """Detection fraction of every pipe of a :func:`validation_scene` over its pings.

    Returns
    -------
    dict
        ``{target: (hits, pings)}``.
    """
    from clbeam.imaging.imager import Imager, ImagingOptions
    from clbeam.io.pingfile import pings_from_dataset
    from clbeam.model.grid import PolarGrid
    from clbeam.sim import simulate

    counts, imagers = {}, {}
    for first in range(0, scene.survey.pings, BLOCK_PINGS):
        ds = simulate(scene, pings=list(range(first, min(first + BLOCK_PINGS, scene.survey.pings))), seed=seed)
        names = [str(v) for v in ds["target"].values]
        iy, iz = ds["truth_target_image_y"].values, ds["truth_target_image_z"].values
        for j, name in enumerate(names):
            if name not in imagers:
                r, a = math.hypot(iy[0, j], iz[0, j]), math.degrees(math.atan2(iy[0, j], iz[0, j]))
                grid = PolarGrid(np.arange(r - CLUTTER_HALF[0], r + CLUTTER_HALF[0], 0.2),
                                 np.arange(a - CLUTTER_HALF[1], a + CLUTTER_HALF[1], 0.1))
                imagers[name], counts[name] = Imager(grid, ImagingOptions()), [0, 0]
        for k, ping in enumerate(pings_from_dataset(ds)):
            for j, name in enumerate(names):
                rows = imagers[name].image(ping).peaks
                hit = any(abs(row["y_m"] - iy[k, j]) <= HIT_HORIZONTAL_M and abs(row["z_m"] - iz[k, j]) <= HIT_VERTICAL_M
                          for row in rows)
                counts[name][0] += int(hit)
                counts[name][1] += 1
            if progress is not None:
                progress(first + k)
    return {name: tuple(v) for name, v in counts.items()}
