"""Sound speed against depth: a horizontally stratified ocean (and sediment).

Piecewise linear between points, constant beyond the ends, with optional
jumps at horizontal interfaces such as the seabed.  The ray tracer
(:mod:`clbeam.imaging.raytrace`) follows rays through it; ping files carry
it as ``svp_depth(svp)``, ``svp_speed(svp)`` (docs/ping-format.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from clbeam.constants import PROFILE_SPEED_RANGE_M_S
from clbeam.errors import OptionError, require

#: slowest and fastest sound speed a profile may hold (m/s): water 1300-1700, sediment up to 2000
SPEED_MIN_M_S, SPEED_MAX_M_S = PROFILE_SPEED_RANGE_M_S


class Layer(NamedTuple):
    """Depth interval ``[top, bot]`` with ``c(z) = c_ref + g (z - z_ref)``."""

    top: float
    bot: float
    z_ref: float
    c_ref: float
    g: float


@dataclass(frozen=True)
class SoundSpeedProfile:
    """Sound speed against depth, piecewise linear, constant beyond the ends.

    Attributes
    ----------
    depths_m : numpy.ndarray
        Depths (m, positive down) on the earth-frame ``z`` axis, i.e. below
        the transducer reference (``z = 0``): non-decreasing; a depth may be
        repeated once, with two different speeds, to make a jump (an
        interface such as the seabed).  Negative depths (above the
        transducers) are allowed.
    speeds_m_s : numpy.ndarray
        Sound speed (m/s) at each depth, within
        ``[SPEED_MIN_M_S, SPEED_MAX_M_S]`` (1300-2000 m/s).

    Notes
    -----
    Between two points of different depth the speed is linear in depth (a
    constant-gradient layer); above the first point it is ``speeds_m_s[0]``,
    below the last ``speeds_m_s[-1]``.  At a jump depth the upper value holds
    just above the interface and the lower value just below it; a point
    exactly on an interface is reached from above.
    """

    depths_m: np.ndarray
    speeds_m_s: np.ndarray
    layers: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        d = _as_float_array(self.depths_m, "profile depths")
        c = _as_float_array(self.speeds_m_s, "profile speeds")
        _check_points(d, c)
        d.setflags(write=False)
        c.setflags(write=False)
        object.__setattr__(self, "depths_m", d)
        object.__setattr__(self, "speeds_m_s", c)
        object.__setattr__(self, "layers", _build_layers(d, c))

    def __eq__(self, other):
        if not isinstance(other, SoundSpeedProfile):
            return NotImplemented
        return bool(np.array_equal(self.depths_m, other.depths_m) and np.array_equal(self.speeds_m_s, other.speeds_m_s))

    def __hash__(self):
        return hash((self.depths_m.tobytes(), self.speeds_m_s.tobytes()))

    # -- constructors --------------------------------------------------------
    @classmethod
    def constant(cls, speed_m_s: float, depth_m: float = 0.0) -> "SoundSpeedProfile":
        """An isospeed ocean.

        Parameters
        ----------
        speed_m_s : float
            Sound speed (m/s).
        depth_m : float
            Depth of the single profile point (m); irrelevant to the result.

        Returns
        -------
        SoundSpeedProfile
        """
        return cls(np.array([depth_m], dtype=np.float64), np.array([speed_m_s], dtype=np.float64))

    @classmethod
    def with_sediment(cls, water: "SoundSpeedProfile", seabed_depth_m: float,
                      sediment_speed_m_s: float) -> "SoundSpeedProfile":
        """A water profile cut at a flat seabed, with a constant sediment speed below.

        Parameters
        ----------
        water : SoundSpeedProfile
            Water-column profile; its points below the seabed are dropped and
            its speed at the seabed (from above) becomes the last water point.
        seabed_depth_m : float
            Depth of the seabed (m, on the profile's depth axis).
        sediment_speed_m_s : float
            Sediment interval velocity (m/s) below the seabed, e.g. 0.98 x
            1490 m/s for the paper's mud.

        Returns
        -------
        SoundSpeedProfile
            With a jump (two points at ``seabed_depth_m``) when the sediment
            speed differs from the water speed at the seabed.

        Raises
        ------
        OptionError
            When the seabed depth is not finite or the sediment speed is out of range.
        """
        require(isinstance(water, SoundSpeedProfile), OptionError,
                f"with_sediment needs a SoundSpeedProfile for the water, got {type(water).__name__}")
        zs = float(seabed_depth_m)
        require(math.isfinite(zs), OptionError, f"seabed depth must be finite, got {seabed_depth_m!r}")
        keep = water.depths_m < zs
        c_sb = float(water.speed(zs, side="above"))
        depths = np.concatenate([water.depths_m[keep], [zs]])
        speeds = np.concatenate([water.speeds_m_s[keep], [c_sb]])
        if float(sediment_speed_m_s) != c_sb:
            depths = np.append(depths, zs)
            speeds = np.append(speeds, float(sediment_speed_m_s))
        return cls(depths, speeds)

    # -- queries -------------------------------------------------------------
    def speed(self, depth_m, side: str = "below") -> np.ndarray:
        """Sound speed at depths (m/s).

        Parameters
        ----------
        depth_m : array_like
            Depths (m).
        side : {"below", "above"}
            Which value holds exactly at a jump: the one just below the
            interface (a ray leaving downward) or just above it (a ray
            arriving from above).

        Returns
        -------
        numpy.ndarray
            Speeds (m/s), the shape of ``depth_m``.
        """
        require(side in ("below", "above"), OptionError, f"side must be 'below' or 'above', got {side!r}")
        z = np.asarray(depth_m, dtype=np.float64)
        out = np.empty(z.shape)
        for lay in self.layers:
            inside = (z >= lay.top) & (z < lay.bot) if side == "below" else (z > lay.top) & (z <= lay.bot)
            out = np.where(inside, lay.c_ref + lay.g * (np.clip(z, lay.top, lay.bot) - lay.z_ref), out)
        return out

    @property
    def jump_depths_m(self) -> np.ndarray:
        """Depths of the speed jumps (m), possibly empty."""
        d = self.depths_m
        return d[1:][np.diff(d) == 0]

    @property
    def is_constant(self) -> bool:
        """True when the speed is the same everywhere."""
        return bool(np.all(self.speeds_m_s == self.speeds_m_s[0]))


#: depth (m) to which :func:`holland_line1_profile` holds its seabed speed, so that it reaches any grid
#: of the paper's record (1.5 s: 1125 m)
HOLLAND_PROFILE_END_M = 2000.0


def holland_line1_profile(sediment_speed_m_s: float | None = None) -> SoundSpeedProfile:
    """The measured profile of Holland et al. (2024), Line 1, on the array's depth axis.

    Transducers 5 m below the surface (``z = 0``); 1522 m/s in the 8 m
    surface mixed layer (``z = -5`` to ``3`` m), then linear to 1490 m/s at
    the seabed, 225 m below the transducers; 1490 m/s below (a last point at
    2000 m, so the profile reaches every grid of the paper's record) unless a
    sediment speed is given.

    Parameters
    ----------
    sediment_speed_m_s : float, optional
        Sediment speed (m/s) below the seabed (the paper's mud: 0.98 x 1490).

    Returns
    -------
    SoundSpeedProfile
    """
    water = SoundSpeedProfile(np.array([-5.0, 3.0, 225.0, HOLLAND_PROFILE_END_M]),
                              np.array([1522.0, 1522.0, 1490.0, 1490.0]))
    if sediment_speed_m_s is None:
        return water
    return SoundSpeedProfile.with_sediment(water, 225.0, sediment_speed_m_s)


def _check_points(d: np.ndarray, c: np.ndarray) -> None:
    """One-line :class:`OptionError` unless ``(d, c)`` make a valid profile."""
    if d.ndim != 1 or d.size < 1:
        raise OptionError(f"a sound-speed profile needs at least 1 point (1-D depths), got shape {d.shape}")
    if c.shape != d.shape:
        raise OptionError(f"profile speeds must match the depths: {d.size} depths, speeds of shape {c.shape}")
    if not np.all(np.isfinite(d)):
        raise OptionError(f"profile depths must be finite, got {d[~np.isfinite(d)][0]:g}")
    if not np.all(np.isfinite(c)):
        raise OptionError(f"profile speeds must be finite, got {c[~np.isfinite(c)][0]:g}")
    out = np.flatnonzero((c < SPEED_MIN_M_S) | (c > SPEED_MAX_M_S))
    if out.size:
        raise OptionError(f"profile speed {c[out[0]]:g} m/s at depth {d[out[0]]:g} m is outside "
                          f"{SPEED_MIN_M_S:g}-{SPEED_MAX_M_S:g} m/s (water 1300-1700, sediment up to 2000)")
    step = np.diff(d)
    dec = np.flatnonzero(step < 0)
    if dec.size:
        raise OptionError(f"profile depths must increase, got {d[dec[0]]:g} m followed by {d[dec[0] + 1]:g} m")
    rep = np.flatnonzero(step == 0)
    triple = rep[1:][np.diff(rep) == 1]
    if triple.size:
        raise OptionError(f"profile depth {d[triple[0]]:g} m appears more than twice; a jump is one repeated depth")
    same = rep[c[rep] == c[rep + 1]]
    if same.size:
        raise OptionError(f"profile depth {d[same[0]]:g} m is repeated with the same speed; "
                          "a repeated depth must be a jump in speed")


def _as_float_array(values, name: str) -> np.ndarray:
    try:
        return np.array(values, dtype=np.float64, ndmin=1)
    except (TypeError, ValueError):
        raise OptionError(f"{name} must be numbers, got {values!r}") from None


def _build_layers(d: np.ndarray, c: np.ndarray) -> tuple[Layer, ...]:
    layers = [Layer(-math.inf, float(d[0]), float(d[0]), float(c[0]), 0.0)]
    for i in range(d.size - 1):
        if d[i + 1] > d[i]:
            g = float((c[i + 1] - c[i]) / (d[i + 1] - d[i]))
            layers.append(Layer(float(d[i]), float(d[i + 1]), float(d[i]), float(c[i]), g))
    layers.append(Layer(float(d[-1]), math.inf, float(d[-1]), float(c[-1]), 0.0))
    return tuple(layers)
