"""The seabed band: the seabed picked from a ping, and the ranges around it worth imaging.

A sub-bottom image needs only the cells from a few metres above the seabed
to some tens of metres below it (``--seabed-band``); the seabed depth is
given or picked per ping from the first strong return at nadir.
"""

from __future__ import annotations

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.imaging.engine import BeamformInput
from clbeam.imaging.raytrace import eigenrays
from clbeam.model.grid import PolarGrid


def pick_seabed_depth_m(inp: BeamformInput, *, below_peak_db: float = 20.0, profile=None,
                        centre_depth_m: float = 0.0) -> float:
    """Seabed depth below the grid centre (m) from the first strong return.

    The channels' envelopes are summed; the first sample within
    ``below_peak_db`` of the strongest is the nadir seabed echo, at two-way
    time ``t`` and so depth ``c t / 2`` (the array spans metres, the water
    hundreds: the offsets' effect is below a range cell).  With a
    sound-speed ``profile`` (depth axis: the grid centre at
    ``centre_depth_m``) the depth is where the vertical ray's one-way time
    from the source is ``t / 2``.
    """
    env = np.nansum(np.abs(inp.data), axis=0)
    require(env.size > 0 and np.max(env) > 0, OptionError,
            "cannot pick the seabed: the ping has no signal; give the seabed depth")
    k = int(np.argmax(env >= np.max(env) * 10 ** (-below_peak_db / 20)))
    one_way_s = 0.5 * (inp.t0_s + k / inp.sample_rate_hz)
    source_z = float(inp.source_offset_m[2])
    if profile is None:  # measured from the (heaved) source, returned below the grid centre
        return inp.sound_speed_m_s * one_way_s + source_z
    z_src = centre_depth_m + source_z
    z = z_src + np.arange(1, 40001) * (float(np.max(profile.speeds_m_s)) * one_way_s / 40000)
    t = eigenrays(profile, z_src, np.zeros_like(z), z).time_s
    return float(np.interp(one_way_s, t, z)) - centre_depth_m


def seabed_window_m(grid: PolarGrid, depth_m: float, band_m: tuple) -> np.ndarray:
    """Per-angle range interval ``(n_angle, 2)`` (m) covering a flat seabed at
    ``depth_m`` below the grid centre, from ``band_m[0]`` above to
    ``band_m[1]`` below it: ``R = z / cos(theta)``."""
    above, below = band_m
    cos_t = np.cos(np.deg2rad(grid.angles_deg))
    lo = np.maximum(depth_m - above, 0.0) / cos_t
    hi = (depth_m + below) / cos_t
    return np.stack([lo, hi], axis=1)
