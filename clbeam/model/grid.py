"""The polar image grid in the earth-referenced cross-track plane (docs/ping-format.md).

Ranges from a centre (the source's nominal position unless given) and
angles from nadir, positive to starboard; roll never moves the grid
(:mod:`clbeam.imaging.geometry` moves the array into the earth frame).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from clbeam.errors import GridError, require

#: largest grid :meth:`PolarGrid.regular` builds (the paper's grid has 8.8e6 cells)
MAX_GRID_CELLS = 2e9


@dataclass(frozen=True)
class PolarGrid:
    """A polar image grid in the cross-track plane (docs/ping-format.md).

    Cell ``(i, j)`` sits at angle ``angles_deg[i]`` from nadir (positive to
    starboard) and range ``ranges_m[j]`` from ``centre_yz_m``:
    ``y = yc + R sin θ``, ``z = zc + R cos θ``.

    Attributes
    ----------
    ranges_m : numpy.ndarray
        Ranges in metres, increasing, ``>= 0``.
    angles_deg : numpy.ndarray
        Angles in degrees from nadir, increasing, within ``[-90, 90]``.
    centre_yz_m : tuple of float or None
        Centre in the earth frame (metres); ``None`` means the source position.
    """

    ranges_m: np.ndarray
    angles_deg: np.ndarray
    centre_yz_m: tuple[float, float] | None = None
    #: angles may pass +-90 degrees (the internal beam grids of :mod:`clbeam.imaging.engine.beams`)
    beyond_vertical: bool = field(default=False, repr=False)

    def __post_init__(self):
        r = np.ascontiguousarray(self.ranges_m, dtype=np.float64)
        a = np.ascontiguousarray(self.angles_deg, dtype=np.float64)
        require(r.ndim == 1 and r.size > 0, GridError, f"grid ranges must be a non-empty 1-D array, got shape {r.shape}")
        require(a.ndim == 1 and a.size > 0, GridError, f"grid angles must be a non-empty 1-D array, got shape {a.shape}")
        require(bool(np.all(np.isfinite(r))) and bool(np.all(np.isfinite(a))), GridError, "grid ranges and angles must be finite")
        require(r[0] >= 0, GridError, f"grid ranges must be >= 0 m, got minimum {r.min():g} m")
        require(bool(np.all(np.diff(r) > 0)), GridError, "grid ranges must be strictly increasing")
        require(bool(np.all(np.diff(a) > 0)), GridError, "grid angles must be strictly increasing")
        require(self.beyond_vertical or (a[0] >= -90 and a[-1] <= 90), GridError,
                f"grid angles must lie within [-90, 90] degrees, got [{a[0]:g}, {a[-1]:g}]")
        if self.centre_yz_m is not None:
            c = tuple(float(v) for v in self.centre_yz_m)
            require(len(c) == 2 and all(np.isfinite(c)), GridError,
                    f"grid centre must be two finite numbers (y, z) in m, got {self.centre_yz_m!r}")
            object.__setattr__(self, "centre_yz_m", c)
        r.setflags(write=False)
        a.setflags(write=False)
        object.__setattr__(self, "ranges_m", r)
        object.__setattr__(self, "angles_deg", a)

    @classmethod
    def regular(cls, *, range_res_m: float = 0.2, angle_res_deg: float = 0.1,
                max_range_m: float = 1100.0, min_range_m: float = 0.0,
                angles_deg: tuple[float, float] = (-80.0, 80.0),
                centre_yz_m: tuple[float, float] | None = None) -> "PolarGrid":
        """A regular grid: ``min_range_m..max_range_m`` by ``range_res_m`` and
        ``angles_deg[0]..angles_deg[1]`` by ``angle_res_deg`` (both ends included).

        Defaults are the paper's grid (0.2 m, 0.1°) over 0–1100 m and ±80°.
        """
        require(np.isfinite(range_res_m) and range_res_m > 0, GridError, f"range resolution must be > 0 m, got {range_res_m!r}")
        require(np.isfinite(angle_res_deg) and angle_res_deg > 0, GridError,
                f"angle resolution must be > 0 degrees, got {angle_res_deg!r}")
        require(np.isfinite(max_range_m) and max_range_m > min_range_m >= 0, GridError,
                f"range window must satisfy 0 <= min < max, got min {min_range_m!r} m, max {max_range_m!r} m")
        a0, a1 = (float(v) for v in angles_deg)
        require(a1 > a0, GridError, f"angle window must satisfy min < max, got [{a0:g}, {a1:g}] degrees")
        n_r = int(np.floor((max_range_m - min_range_m) / range_res_m + 1e-9)) + 1
        n_a = int(np.floor((a1 - a0) / angle_res_deg + 1e-9)) + 1
        require(n_r * n_a <= MAX_GRID_CELLS, GridError,
                f"a grid of {n_a} angles x {n_r} ranges ({n_a * n_r:.3g} cells) exceeds {MAX_GRID_CELLS:.0e} cells; "
                "use coarser steps or a smaller window")
        ranges = min_range_m + range_res_m * np.arange(n_r)
        angles = a0 + angle_res_deg * np.arange(n_a)
        return cls(ranges, angles, centre_yz_m)

    @classmethod
    def beams(cls, ranges_m, angles_deg) -> "PolarGrid":
        """An internal beam grid: like a grid, but its angles may pass +-90 degrees
        (points above the array, where the delay-and-sum is still defined)."""
        return cls(ranges_m, angles_deg, None, beyond_vertical=True)

    @property
    def shape(self) -> tuple[int, int]:
        """``(n_angle, n_range)``: the layout of every image array."""
        return (self.angles_deg.size, self.ranges_m.size)

    @property
    def n_cells(self) -> int:
        """Number of cells."""
        return self.angles_deg.size * self.ranges_m.size

    def centre(self, source_yz_m: tuple[float, float]) -> np.ndarray:
        """Grid centre ``(y, z)`` in metres, the source's when none was given."""
        if self.centre_yz_m is None:
            return np.asarray(source_yz_m, dtype=np.float64)
        return np.asarray(self.centre_yz_m, dtype=np.float64)

    def cell_yz(self, source_yz_m: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        """Earth-frame ``y`` and ``z`` (metres) of every cell, each ``(n_angle, n_range)``."""
        c = self.centre(source_yz_m)
        th = np.deg2rad(self.angles_deg)[:, None]
        return c[0] + self.ranges_m[None, :] * np.sin(th), c[1] + self.ranges_m[None, :] * np.cos(th)




def window_cells(first: np.ndarray, lengths: np.ndarray, n_range: int, *, pad: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The cells of a window of range cells per angle row, row after row: their flat index in the
    ``(n_rows, n_range)`` grid, and their index in a packed array that gives each row's window ``pad``
    empty cells either side (0: the windows back to back).

    Parameters
    ----------
    first, lengths : numpy.ndarray
        ``(n_rows,)`` each window's first range index and its number of cells.
    n_range : int
        Range cells of a grid row.
    pad : int
        Empty cells before and after each row's window in the packed array.
    """
    first, lengths = np.asarray(first, dtype=np.int64), np.asarray(lengths, dtype=np.int64)
    before = np.r_[0, np.cumsum(lengths)[:-1]]  # cells of the rows before each
    run = np.arange(int(lengths.sum())) - np.repeat(before, lengths)  # position within its row
    grid_index = np.repeat(np.arange(lengths.size) * n_range + first, lengths) + run
    packed_index = np.repeat(before + 2 * pad * np.arange(lengths.size) + pad, lengths) + run
    return grid_index, packed_index
