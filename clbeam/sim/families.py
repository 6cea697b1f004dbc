"""Random survey families: whole survey lines drawn from a seed, for judging the lines on scenes nobody tuned on.

:func:`survey_scene` draws one survey line from a seed: the water depth, the ship's motion, a sound-speed
profile, the seabed's clutter, 1-4 pipelines (any heading to the track up to 45 degrees, buried 0-3 m,
lying exposed on the seabed or spanning free above it, 0.1-0.5 m in radius, smooth or rough, curved up to
20 degrees per km, with gaps) and boulders, loose and in rows; :func:`clutter_scene` draws the same
surveys without pipelines (the false-line rate).  The draws are split once and for all:

- **tuning** draws: seeds below :data:`VALIDATION_FIRST_SEED`, on which detector parameters may be chosen;
- **validation** draws: :data:`VALIDATION_SEEDS` (pipelines) and :data:`CLUTTER_VALIDATION_SEEDS`
  (clutter only), on which nothing is ever chosen: the figures the documentation quotes.

Every draw is a plain :class:`~clbeam.sim.scene.Scene` (its mapping, :func:`survey_mapping`, is what a
scene's TOML file would hold), so ``clbeam simulate`` and the truth scoring treat it like any other.  A
draw can be rendered under either physics (``model="specular"``, the default, or ``"discrete"``:
:mod:`clbeam.sim.discrete`): the same seed is the same survey under both.
"""

from __future__ import annotations

import math

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.sim.catalog import scene_from_mapping
from clbeam.sim.scene import PHYSICS_MODELS, Scene

#: seeds from here on are validation draws; tuning uses the seeds below
VALIDATION_FIRST_SEED = 1000
#: the validation surveys with pipelines, and the clutter-only ones
VALIDATION_SEEDS = tuple(range(VALIDATION_FIRST_SEED, VALIDATION_FIRST_SEED + 32))
CLUTTER_VALIDATION_SEEDS = tuple(range(VALIDATION_FIRST_SEED + 500, VALIDATION_FIRST_SEED + 508))
#: the families' ranges: water depth (m), pipelines per survey, heading to the track (degree), burial below the
#: seabed (m), radius (m), curvature (degree per km)
DEPTH_RANGE_M = (50.0, 400.0)
PIPELINES_RANGE = (1, 4)
HEADING_RANGE_DEG = (0.0, 45.0)
BURIAL_RANGE_M = (0.0, 3.0)
RADIUS_RANGE_M = (0.1, 0.5)
CURVATURE_MAX_DEG_PER_KM = 20.0
#: shares of the pipelines lying exposed on the seabed, spanning free above it (0.2-1 m), rough (a relative
#: spread of 0.5-3 from point to point: coated, jointed, overgrown), with a gap
EXPOSED_SHARE, SPANNING_SHARE, ROUGH_SHARE, GAP_SHARE = 0.15, 0.1, 0.5, 0.2
#: the swath the pipelines are kept in: from this many water depths across to this angle from nadir (degree)
SWATH_INNER_DEPTHS, SWATH_OUTER_DEG = 0.2, 65.0
#: pipelines stay this far apart across the track over the whole line (m)
PIPE_SEPARATION_M = 30.0
#: the transducers' depth below the sea surface (m): the seabed's depth is the sea surface's, a target's z the
#: transducers'
DRAFT_M = 5.0
#: the record's slant range: to this angle from nadir at the seabed, at most this many metres
RECORD_ANGLE_DEG, RECORD_MAX_M = 72.0, 1100.0


def is_validation_seed(seed: int) -> bool:
    """Whether ``seed`` draws a validation survey (nothing may be chosen on it)."""
    return int(seed) >= VALIDATION_FIRST_SEED


def survey_scene(seed: int, *, pings: int = 40, pipelines: bool = True, model: str = "specular") -> Scene:
    """The survey line drawn from ``seed`` (:func:`survey_mapping`) as a scene.

    Parameters
    ----------
    seed : int
        The draw (>= 0); :data:`VALIDATION_SEEDS` are the validation draws.
    pings : int
        Pings on the line (8.23 m apart).
    pipelines : bool
        ``False``: the same survey without its pipelines (clutter only).
    model : {"specular", "discrete"}
        The physics it is rendered under (``model.physics``): the same draw, seabed, targets and
        navigation, with the pipes and interfaces as the specular model's or as discrete scatterers
        (:mod:`clbeam.sim.discrete`, the ``[discrete]`` defaults).  A discrete draw's name ends in
        ``-discrete``.
    """
    suffix = "" if model == "specular" else f"-{model}"
    return scene_from_mapping(survey_mapping(seed, pings=pings, pipelines=pipelines, model=model),
                              name=f"{'family' if pipelines else 'clutter-family'}-{int(seed)}{suffix}")


def clutter_scene(seed: int, *, pings: int = 40, model: str = "specular") -> Scene:
    """The clutter-only survey drawn from ``seed``: :func:`survey_scene` without pipelines (``model`` as there)."""
    return survey_scene(seed, pings=pings, pipelines=False, model=model)


def survey_mapping(seed: int, *, pings: int = 40, pipelines: bool = True, model: str = "specular") -> dict:
    """The scene mapping (the tables of a scene's TOML file) of the survey drawn from ``seed``, under the
    physics ``model`` (``"specular"`` or ``"discrete"``; the draw itself does not depend on it)."""
    require(int(seed) == seed and seed >= 0, OptionError, f"a survey family's seed must be an integer >= 0, got {seed!r}")
    require(pings >= 2, OptionError, f"a survey family's line needs at least 2 pings, got {pings}")
    require(model in PHYSICS_MODELS, OptionError,
            f"a survey family's model must be one of {', '.join(PHYSICS_MODELS)}, got {model!r}")
    rng = np.random.default_rng([int(seed), 20261204])
    depth = _u(rng, *DEPTH_RANGE_M, 2)
    record = min((depth - DRAFT_M) / math.cos(math.radians(RECORD_ANGLE_DEG)), RECORD_MAX_M)
    step = 4.0 * 4.0 * 1852.0 / 3600.0
    mapping = {
        "name": f"family-{seed}", "description": f"random survey family, draw {seed}", "snr_db": float(rng.uniform(15, 30)),
        "sonar": {"n_elements": 64, "array_width_m": 3.528, "tx_length_m": 3.5, "draft_m": DRAFT_M,
                  "sample_rate_hz": 40000.0, "pulse_f0_hz": 2000.0, "pulse_f1_hz": 9000.0, "pulse_duration_s": 0.08},
        "record": {"max_range_m": round(record, 1)},
        "survey": {"pings": int(pings), "ping_interval_s": 4.0, "speed_knots": 4.0,
                   "heading_deg": _u(rng, 0, 360, 1), "latitude_deg": 34.29,
                   "longitude_deg": -119.77, "start_time": "2022-08-29T02:00:00"},
        "motion": {"roll_mean_deg": _u(rng, -1, 1, 2), "roll_amplitude_deg": _u(rng, 0, 5, 2),
                   "roll_period_s": _u(rng, 7, 12, 2), "pitch_amplitude_deg": 0.4, "pitch_period_s": 6.3,
                   "heave_amplitude_m": _u(rng, 0, 1, 2), "heave_period_s": _u(rng, 6, 10, 2)},
        "seabed": _seabed(rng, depth),
        "subbottom": _subbottom(rng),
    }
    water = _profile(rng, depth)
    if water is not None:
        mapping["water"] = water
    else:
        mapping["sound_speed_m_s"] = 1500.0
    # the pipelines are drawn whether or not they are kept, so that a clutter-only survey is its twin's clutter
    pipes = _pipelines(rng, depth, (pings - 1) * step)
    targets = (pipes if pipelines else []) + _boulders(rng, depth, (pings - 1) * step)
    if targets:
        mapping["target"] = targets
    if model != "specular":
        mapping["model"] = {"physics": model}
    return mapping


def _u(rng, low: float, high: float, digits: int) -> float:
    """A uniform draw in ``[low, high)`` rounded to ``digits`` decimals (as a scene file would hold it)."""
    return round(float(rng.uniform(low, high)), digits)


def _seabed(rng, depth: float) -> dict:
    """The seabed: a muddy to sandy sediment and its clutter's strength."""
    return {"depth_m": round(depth, 2), "sound_speed_ratio": _u(rng, 0.97, 1.0, 3),
            "density_ratio": _u(rng, 1.2, 1.9, 3), "attenuation_db_per_m": _u(rng, 0.05, 0.3, 3),
            "attenuation_ref_hz": 5000.0, "specular": True, "multiple": True,
            "scattering": {"strength_db": _u(rng, -34, -22, 1), "grazing_exponent": 2.0,
                           "per_cell": _u(rng, 0.5, 3.0, 2), "depth_spread_m": 0.05}}


def _subbottom(rng) -> dict:
    """A horizon 5-30 m below the seabed, weak to strong."""
    return {"depth_below_seabed_m": _u(rng, 5, 30, 1), "sound_speed_ratio": 1.05,
            "density_ratio": _u(rng, 1.3, 2.0, 3), "specular": True,
            "scattering": {"strength_db": _u(rng, -32, -24, 1), "grazing_exponent": 2.0,
                           "per_cell": 0.5, "depth_spread_m": 0.1}}


def _profile(rng, depth: float) -> dict | None:
    """No profile (isospeed water), a gradient, or a mixed layer over a thermocline, a third each."""
    kind = int(rng.integers(3))
    if kind == 0:
        return None
    top = float(rng.uniform(1490, 1530))
    if kind == 1:
        bottom = top + float(rng.uniform(-30, 20))
        return {"svp_depth_m": [-5.0, depth + 2000.0], "svp_speed_m_s": [round(top, 2), round(bottom, 2)]}
    layer = float(rng.uniform(0.1, 0.5)) * depth
    cline = layer + float(rng.uniform(0.1, 0.3)) * depth
    below = top - float(rng.uniform(10, 35))
    return {"svp_depth_m": [-5.0, round(layer, 2), round(cline, 2), depth + 2000.0],
            "svp_speed_m_s": [round(top, 2), round(top, 2), round(below, 2), round(below, 2)]}


def _pipelines(rng, depth: float, line_m: float) -> list:
    """1-4 pipelines kept inside the swath and apart over the whole line, as scene targets."""
    inner, outer = SWATH_INNER_DEPTHS * depth, (depth - DRAFT_M) * math.tan(math.radians(SWATH_OUTER_DEG))
    pipes, paths = [], []
    for k in range(int(rng.integers(PIPELINES_RANGE[0], PIPELINES_RANGE[1] + 1))):
        for _ in range(50):  # a heading and a crossing that keep the pipe in the swath, apart from the others
            angle = float(rng.uniform(*HEADING_RANGE_DEG)) * float(rng.choice([-1.0, 1.0]))
            curvature = float(rng.uniform(-CURVATURE_MAX_DEG_PER_KM, CURVATURE_MAX_DEG_PER_KM))
            side = float(rng.choice([-1.0, 1.0]))
            y_mid = side * float(rng.uniform(inner, outer))
            path = _crossings(y_mid, angle, curvature, line_m)
            if np.all((np.abs(path) >= inner) & (np.abs(path) <= outer) & (np.sign(path) == side)) and \
                    all(np.min(np.abs(path - other)) >= PIPE_SEPARATION_M for other in paths):
                break
        else:
            continue
        paths.append(path)
        pipes.append(_pipe(rng, chr(ord("A") + k), y_mid, angle, curvature, line_m, depth))
    return pipes


def _crossings(y_mid: float, angle_deg: float, curvature_deg_per_km: float, line_m: float) -> np.ndarray:
    """Where a pipe through ``(line_m / 2, y_mid)`` crosses the ping planes along the line (m across)."""
    x = np.linspace(0.0, line_m, 33) - 0.5 * line_m
    heading = np.radians(angle_deg + curvature_deg_per_km * x / 1000.0 / 2.0)
    return y_mid + x * np.tan(heading)


def _pipe(rng, name: str, y_mid: float, angle: float, curvature: float, line_m: float, depth: float) -> dict:
    """One pipeline target: buried, exposed on the seabed or spanning free above it."""
    radius = _u(rng, *RADIUS_RANGE_M, 3)
    target = {"kind": "line", "name": name, "x_m": round(0.5 * line_m, 2), "y_m": round(y_mid, 2),
              "angle_deg": round(angle, 2), "curvature_deg_per_km": round(curvature, 2), "radius_m": round(radius, 3),
              "reflectivity": _u(rng, 0.5, 0.9, 2)}
    state = float(rng.uniform())
    if state < EXPOSED_SHARE:
        target["z_m"] = round(depth - DRAFT_M - radius, 3)                 # lying on the seabed
    elif state < EXPOSED_SHARE + SPANNING_SHARE:
        target["z_m"] = round(depth - DRAFT_M - radius - float(rng.uniform(0.2, 1.0)), 3)   # spanning free above it
    else:
        target["burial_m"] = round(max(float(rng.uniform(*BURIAL_RANGE_M)), radius), 3)
    if rng.uniform() < ROUGH_SHARE:
        target["roughness"] = _u(rng, 0.5, 3.0, 2)
    if rng.uniform() < GAP_SHARE:
        x0 = float(rng.uniform(0.2, 0.7)) * line_m
        target["gap_x_m"] = [round(x0, 1), round(x0 + float(rng.uniform(30, 80)), 1)]
    return target


def _boulders(rng, depth: float, line_m: float) -> list:
    """Loose boulders over the swath, and in half the surveys a row of them along a line."""
    outer = depth * math.tan(math.radians(SWATH_OUTER_DEG))
    out = [{"kind": "point", "name": f"boulder{k}", "x_m": _u(rng, 0, line_m, 1),
            "y_m": _u(rng, -outer, outer, 1), "burial_m": _u(rng, 0.05, 0.5, 2),
            "amplitude_m": _u(rng, 0.08, 0.25, 3)} for k in range(int(rng.integers(0, 11)))]
    if rng.uniform() < 0.5:
        n = int(rng.integers(4, 9))
        x0, y0 = float(rng.uniform(0, 0.3 * line_m)), float(rng.uniform(-outer, outer))
        angle = math.radians(float(rng.uniform(-20, 20)))
        gaps = np.cumsum(rng.uniform(15, 85, n))
        out += [{"kind": "point", "name": f"row{k}", "x_m": round(x0 + g * math.cos(angle), 1),
                 "y_m": round(y0 + g * math.sin(angle), 1), "burial_m": 0.1,
                 "amplitude_m": _u(rng, 0.12, 0.25, 3)} for k, g in enumerate(gaps)]
    return out
