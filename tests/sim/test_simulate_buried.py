"""Buried targets are imaged where the truth variables say, with and without heave.

A buried echo arrives later than the straight water path says (refraction
into the slower sediment: 0.074 m of one-way range at 920 m, 1 m deep) and
from the refracted ray's direction.  A straight-ray imager therefore shows it
displaced; ``truth_target_image_y/z`` must be that apparent position, not the
geometric one.

Why heave exposes a range error of a few millimetres: the imager's polar
grid is centred on the vessel-frame (unheaved) source, so with heave ``h``
the echo's constant-range ring is off-centre by ``h`` and crosses the grid's
range rows obliquely.  Along the ring the grid range changes by
``h sin θ`` per radian, 9.3 mm per degree at 76° for ``h = 0.5 m``.  At 76°
the receive lobe is degrees wide in angle while the compressed pulse is
0.1 m wide in range, so the intensity maximum slides along the lobe to
where the ring meets a range row: an error ``ε`` in the truth's range moves
it by about ``ε / (h sin θ)``.  The 0.074 m of refraction left out moved it
by 4° (to the edge of the window).  Without heave the ring is concentric
with the rows and the angle is insensitive to range.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.io.pingfile import PingFile
from clbeam.model.grid import PolarGrid
from clbeam.sim.simulator import (
    load_scene,
    refracted_path,
    simulate,
    two_way_sediment_path_m,
    write,
)

RANGE_RES_M = 0.2
ANGLE_RES_DEG = 0.05
# heave(t) = A sin(2π t / T + 2): at the first ping (t = 0) this is A sin 2
HEAVE_M = 0.55


def buried_scene(heave_m: float):
    """A point 920 m to starboard, 1 m below a flat seabed 225 m below the
    transducers (230 m water), the ship heaved by ``heave_m`` and rolled 3°."""
    return load_scene("point", max_range_m=1000.0, snr_db=None, overrides={
        "motion.heave_amplitude_m": heave_m / math.sin(2.0), "motion.heave_period_s": 1e9,
        "motion.roll_mean_deg": 3.0,
        "seabed": {"depth_m": 230.0, "specular": False, "multiple": False},
        "target": [{"kind": "point", "name": "P", "x_m": 0.0, "y_m": 920.0, "burial_m": 1.0, "amplitude_m": 1.0}]})


def imaged(heave_m: float, tmp_path):
    """Truth and intensity maximum ``(range, angle)`` about the grid centre
    (the vessel-frame source), on a grid that has a node at the truth."""
    ds = simulate(buried_scene(heave_m))
    assert float(ds.heave[0]) == pytest.approx(heave_m, abs=1e-12)
    path = write(ds, tmp_path / f"buried{heave_m:g}.nc")
    y, z = float(ds.truth_target_image_y[0, 0]), float(ds.truth_target_image_z[0, 0])
    r0, a0 = math.hypot(y, z), math.degrees(math.atan2(y, z))
    grid = PolarGrid.regular(range_res_m=RANGE_RES_M, angle_res_deg=ANGLE_RES_DEG, min_range_m=r0 - 2.0,
                             max_range_m=r0 + 2.0, angles_deg=(a0 - 3.0, a0 + 3.0))
    assert np.min(np.abs(grid.ranges_m - r0)) < 1e-9 and np.min(np.abs(grid.angles_deg - a0)) < 1e-9
    with PingFile(path) as f:
        img = Imager(grid, ImagingOptions(interp="lanczos8")).image(f.ping(0))
    ia, ir = np.unravel_index(np.argmax(img.intensity), img.intensity.shape)
    return (r0, a0), (float(grid.ranges_m[ir]), float(grid.angles_deg[ia]))


def test_buried_point_is_imaged_at_its_truth_with_heave_and_roll_and_without_heave(tmp_path):
    (r_h, a_h), (ri_h, ai_h) = imaged(HEAVE_M, tmp_path)
    (r_0, a_0), (ri_0, ai_0) = imaged(0.0, tmp_path)
    assert 75.5 < a_h < 76.5  # 920 m across, 231 m down: ~76° from nadir
    # Tolerances.  Range: the maximum is on the node nearest the ring, and the
    # truth is a node, so one cell.  Angle: two 0.05° cells.  The receive lobe
    # changes by far less than the lanczos8 error across a cell, so the maximum
    # may sit on a neighbouring node; 0.1° corresponds (see the module
    # docstring) to a range error of 0.1 × 9.3 mm = 1 mm with heave, while the
    # refraction delay is 74 mm.
    for (r, a), (ri, ai) in (((r_h, a_h), (ri_h, ai_h)), ((r_0, a_0), (ri_0, ai_0))):
        assert abs(ri - r) <= RANGE_RES_M + 1e-9
        assert abs(ai - a) <= 2 * ANGLE_RES_DEG + 1e-9
    # the target is fixed in the world: heave moves the source, not where the
    # straight-ray imager shows the echo (the refraction delay changes by
    # 0.1 mm with 0.55 m more water above the seabed)
    assert r_h == pytest.approx(r_0, abs=1e-3) and a_h == pytest.approx(a_0, abs=1e-4)
    assert ai_h == pytest.approx(ai_0, abs=2 * ANGLE_RES_DEG + 1e-9)


def test_buried_truth_is_displaced_by_half_the_refraction_delay():
    """The apparent range exceeds the straight range by half the Snell (Fermat)
    travel-time excess times c, computed here from ``refracted_path``."""
    from clbeam.sim.simulator import Simulator

    sim = Simulator(buried_scene(HEAVE_M))
    g = sim.geometry(0)
    tr = sim.truth(g)["target"]
    apparent = math.hypot(tr["image_y"][0] - g.source[1], tr["image_z"][0] - g.source[2])
    straight = math.dist((0.0, 920.0, 226.0), g.source)
    # source at the array centre: both legs the same ray, height 225 m + heave
    leg = refracted_path(math.hypot(920.0 - g.source[1], 0.0), 225.0 - g.source[2], 1.0, 0.98)
    assert apparent - straight == pytest.approx(float(leg["time_factor_m"]) - straight, abs=1e-6)
    assert 0.06 < apparent - straight < 0.09
    # the closed forms of the refraction model hold: Snell's law at the
    # interface, and the paper's sediment path at 920 m in 230 m water
    n = 0.98
    assert math.cos(float(leg["grazing_sediment_rad"])) == pytest.approx(
        n * math.cos(float(leg["grazing_water_rad"])), rel=1e-12)
    assert two_way_sediment_path_m(920.0, 225.0, 0.77, 0.98) == pytest.approx(5.0, abs=0.05)
