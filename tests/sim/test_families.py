"""The random survey families: draws within the documented ranges at their documented shares, pipelines
inside the swath and apart along the whole line (the simulator's own geometry), reproducible draws, a
validation split apart from the tuning seeds, and the same draws under either physics."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from clbeam.errors import OptionError
from clbeam.sim import families
from clbeam.sim.families import (
    CLUTTER_VALIDATION_SEEDS,
    VALIDATION_SEEDS,
    clutter_scene,
    is_validation_seed,
    survey_mapping,
    survey_scene,
)
from clbeam.sim.scene import LineTarget, PointTarget
from clbeam.sim.simulator import Simulator
from clbeam.sim.targets import line_crossing

DRAWS = range(200)


def _pipes(scene):
    return [t for t in scene.targets if isinstance(t, LineTarget)]


def test_a_seed_draws_one_survey_and_the_validation_seeds_are_apart():
    assert survey_mapping(7) == survey_mapping(7)
    assert survey_mapping(7) != survey_mapping(8)
    assert len(VALIDATION_SEEDS) >= 30 and len(set(VALIDATION_SEEDS) | set(CLUTTER_VALIDATION_SEEDS)) == \
        len(VALIDATION_SEEDS) + len(CLUTTER_VALIDATION_SEEDS)
    assert all(is_validation_seed(s) for s in VALIDATION_SEEDS + CLUTTER_VALIDATION_SEEDS)
    assert not any(is_validation_seed(s) for s in range(families.VALIDATION_FIRST_SEED))
    with pytest.raises(OptionError, match="seed"):
        survey_mapping(-1)


def test_draws_stay_within_the_families_ranges_at_their_shares():
    depths, counts, states, rough, gaps, headings = [], [], [], [], [], []
    for seed in DRAWS:
        scene = survey_scene(seed, pings=10)
        depth = scene.seabed.depth_m
        depths.append(depth)
        pipes = _pipes(scene)
        counts.append(len(pipes))
        for t in pipes:
            headings.append(abs(t.angle_deg))
            assert families.RADIUS_RANGE_M[0] <= t.radius_m <= families.RADIUS_RANGE_M[1]
            assert abs(t.curvature_deg_per_km) <= families.CURVATURE_MAX_DEG_PER_KM
            if t.burial_m is not None:
                assert max(t.radius_m, 0.0) <= t.burial_m <= families.BURIAL_RANGE_M[1]
                states.append("buried")
            else:   # the axis a radius above the seabed (lying on it) or 0.2-1 m higher (spanning free)
                height = (depth - families.DRAFT_M) - t.z_m - t.radius_m
                assert -1e-6 <= height <= 1.0 + 1e-6
                states.append("exposed" if height < 1e-6 else "spanning")
            rough.append(t.roughness > 0)
            gaps.append(bool(t.gap_x_m))
    assert families.DEPTH_RANGE_M[0] <= min(depths) and max(depths) <= families.DEPTH_RANGE_M[1]
    assert set(counts) <= set(range(1, 5)) and {1, 4} <= set(counts)
    assert max(headings) <= families.HEADING_RANGE_DEG[1] and min(headings) < 5 and max(headings) > 40
    n = len(states)
    # each share within four binomial standard deviations of its nominal value
    for got, share in ((states.count("exposed") / n, families.EXPOSED_SHARE),
                       (states.count("spanning") / n, families.SPANNING_SHARE),
                       (np.mean(rough), families.ROUGH_SHARE), (np.mean(gaps), families.GAP_SHARE)):
        assert abs(got - share) <= 4 * math.sqrt(share * (1 - share) / n), (got, share)


def test_pipelines_cross_every_ping_inside_the_swath_and_apart():
    """Where the simulator's own arc crosses each ping's plane: inside the swath on one side of the track,
    and the survey's pipelines at least the separation apart at every ping."""
    for seed in range(0, 60, 3):
        scene = survey_scene(seed, pings=40)
        depth = scene.seabed.depth_m - families.DRAFT_M
        inner = families.SWATH_INNER_DEPTHS * scene.seabed.depth_m
        outer = depth * math.tan(math.radians(families.SWATH_OUTER_DEG))
        along = np.arange(scene.survey.pings) * scene.survey.step_m
        ys = np.array([[line_crossing(scene, t, x)[0] for x in along] for t in _pipes(scene)])
        # the crossings' straight-segment model and the arc differ by centimetres over the line
        slack = 0.5
        assert np.all(np.abs(ys) >= inner - slack) and np.all(np.abs(ys) <= outer + slack), seed
        assert np.all(np.abs(np.sign(ys) - np.sign(ys[:, :1])) == 0), seed
        for i in range(len(ys)):
            for j in range(i):
                assert np.min(np.abs(ys[i] - ys[j])) >= families.PIPE_SEPARATION_M - slack, seed


def test_a_clutter_survey_is_its_twin_without_pipelines():
    full, clutter = survey_scene(11), clutter_scene(11)
    assert _pipes(full) and not _pipes(clutter)
    assert [t for t in full.targets if isinstance(t, PointTarget)] == list(clutter.targets)
    assert full.seabed == clutter.seabed and full.motion == clutter.motion and full.water == clutter.water


def test_a_draw_is_the_same_survey_under_either_physics():
    """The discrete draw is the specular one with only ``model.physics`` (and the name) changed, for
    pipelines and clutter; and its pipes' discrete scatterers cross each ping's plane where the scene's
    arc does (:func:`line_crossing`), at the burial the draw gave."""
    for seed in (0, 5, VALIDATION_SEEDS[0]):
        for make in (survey_scene, clutter_scene):
            spec, disc = make(seed, pings=6), make(seed, pings=6, model="discrete")
            assert disc.model.physics == "discrete" and spec.model.physics == "specular"
            assert disc.name == spec.name + "-discrete"
            same = dataclasses.replace(disc, name=spec.name, model=spec.model, discrete=None)
            assert same == spec
    with pytest.raises(OptionError, match="model"):
        survey_scene(3, model="kirchhoff")
    scene = survey_scene(2, pings=3, model="discrete")
    sim = Simulator(scene, seed=2)
    for index in range(3):
        g = sim.geometry(index)
        for k, t in enumerate(scene.targets):
            if not isinstance(t, LineTarget):
                continue
            y, z, _ = line_crossing(scene, t, g.along_m)
            pts = sim._discrete.pipes[k]
            near = np.argmin(np.abs(pts["x"] - g.along_m))
            if t.gap_x_m and t.gap_x_m[0] - 1 <= g.along_m <= t.gap_x_m[1] + 1:
                continue
            # the nearest scatterer is within half a spacing of the plane along the pipe
            assert abs(pts["y"][near] - y) <= 0.06 + 1e-3 and abs(pts["z"][near] - z) <= 1e-3, (t.name, index)
