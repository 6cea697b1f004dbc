"""Figures: cross-track images like Holland et al. (2024) Fig. 4.

Polar images are resampled onto a regular (y, z) raster (nearest cell) so a
paper-size grid draws in a fraction of a second; port is negative y, depth
(z) increases downward, all in metres below the transducers.
"""

from __future__ import annotations

import numpy as np

from clbeam.constants import MAP_THRESHOLD, PEAK_THRESHOLD
from clbeam.model.grid import PolarGrid


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (PNG files, no display needed).

    Every figure of clbeam is drawn through this, so importing clbeam never
    changes the caller's matplotlib backend: it is chosen on first use only.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def polar_to_raster(values: np.ndarray, grid: PolarGrid, centre_yz_m, y_m: np.ndarray, z_m: np.ndarray,
                    fill=np.nan) -> np.ndarray:
    """Nearest-cell resampling of a polar image onto the raster ``y_m x z_m``.

    Returns ``(len(z_m), len(y_m))``; raster points outside the grid get ``fill``.
    """
    yy, zz = np.meshgrid(np.asarray(y_m) - centre_yz_m[0], np.asarray(z_m) - centre_yz_m[1])
    r = np.hypot(yy, zz)
    a = np.rad2deg(np.arctan2(yy, zz))
    ranges, angles = grid.ranges_m, grid.angles_deg
    ir = np.clip(np.round((r - ranges[0]) / (ranges[-1] - ranges[0]) * (ranges.size - 1)).astype(int), 0, ranges.size - 1) \
        if ranges.size > 1 else np.zeros(r.shape, dtype=int)
    ia = np.clip(np.round((a - angles[0]) / (angles[-1] - angles[0]) * (angles.size - 1)).astype(int), 0, angles.size - 1) \
        if angles.size > 1 else np.zeros(a.shape, dtype=int)
    out = values[ia, ir].astype(np.float64)
    dr = (ranges[-1] - ranges[0]) / max(ranges.size - 1, 1)
    da = (angles[-1] - angles[0]) / max(angles.size - 1, 1)
    outside = (r < ranges[0] - dr) | (r > ranges[-1] + dr) | (a < angles[0] - da) | (a > angles[-1] + da)
    out[outside] = fill
    return out


def image_extent(grid: PolarGrid, centre_yz_m) -> tuple[float, float, float, float]:
    """``(y_min, y_max, z_min, z_max)`` (m) covered by the grid."""
    th = np.deg2rad(grid.angles_deg)
    r = grid.ranges_m
    y = centre_yz_m[0] + np.outer(np.sin(th), [r[0], r[-1]])
    z = centre_yz_m[1] + np.outer(np.cos(th), [r[0], r[-1]])
    return float(y.min()), float(y.max()), float(min(z.min(), centre_yz_m[1])), float(z.max())


def plot_cross_track(img, path, *, seabed_z_m=None, targets_yz_m=None, title: str = "",
                     zoom: tuple | None = None, dynamic_range_db: float = 45.0, pixel_m: float | None = None):
    """Three panels like Holland et al. Fig. 4: intensity (dB), coherence
    factor and coherence peaks, with the seabed line and known targets.

    Parameters
    ----------
    img : PingImage
        From :meth:`clbeam.imaging.imager.Imager.image` (intensity and CF).
    path : path-like
        PNG to write.
    seabed_z_m : float or callable, optional
        Seabed depth below the transducers (m), drawn dotted: one depth (a
        flat seabed), or ``z(y)`` of the cross-track offset ``y`` (m, NumPy
        arrays in and out): a sloping seabed, drawn as the scene has it.
    targets_yz_m : array-like, optional
        ``(k, 2)`` known target positions (m), drawn as open circles.
    zoom : (y0, y1, z0, z1), optional
        Window (m) of the CF and peaks panels (the box on the intensity panel);
        default: the seabed band ±40 m across the grid.
    """
    plt = pyplot()
    grid, c = img.grid, img.centre_yz_m
    y0, y1, z0, z1 = image_extent(grid, c)
    seabed = seabed_line(seabed_z_m, y0, y1)
    if zoom is None:
        zoom = (y0, y1, seabed[1].min() - 40, seabed[1].max() + 40) if seabed is not None else (y0, y1, z0, z1)
    fig, axes = plt.subplots(3, 1, figsize=(11, 11), dpi=110, constrained_layout=True)
    _intensity_panel(fig, axes[0], img, (y0, y1, z0, z1), zoom, dynamic_range_db, pixel_m, title)
    _cf_panel(fig, axes[1], img, zoom)
    _peaks_panel(fig, axes[2], img.peaks, zoom)
    for k, ax in enumerate(axes):
        if seabed is not None:
            ax.plot(*seabed, color="#8b5a2b", ls=":", lw=1.2, label="seabed" if k == 2 else None)
        if targets_yz_m is not None and len(targets_yz_m):
            t = np.asarray(targets_yz_m)
            ax.scatter(t[:, 0], t[:, 1], s=90, facecolors="none", edgecolors="cyan", lw=1.3, zorder=4,
                       label="buried pipe (truth)" if k == 2 else None)
        ax.set_xlabel("cross-track y (m, port negative)")
        ax.set_ylabel("depth z (m below transducers)")
    if seabed_z_m is not None or targets_yz_m is not None:
        axes[2].legend(loc="lower right", fontsize=8)
    axes[0].set_xlim(y0, y1)
    axes[0].set_ylim(z1, z0)
    fig.savefig(path)
    plt.close(fig)
    return path


def seabed_line(seabed_z_m, y0_m: float, y1_m: float, n: int = 201):
    """The seabed drawn from ``y0_m`` to ``y1_m`` (m): ``(y, z)`` arrays (m) of ``n`` points of a depth or of
    ``z(y)`` (:func:`plot_cross_track`'s ``seabed_z_m``); ``None`` without one."""
    if seabed_z_m is None:
        return None
    y = np.linspace(y0_m, y1_m, n)
    z = seabed_z_m(y) if callable(seabed_z_m) else np.full(n, float(seabed_z_m))
    return y, np.broadcast_to(np.asarray(z, dtype=np.float64), y.shape)


def _intensity_panel(fig, ax, img, extent, zoom, dynamic_range_db: float, pixel_m, title: str) -> None:
    """(a) intensity in dB with the box of the zoomed panels."""
    y0, y1, z0, z1 = extent
    step = pixel_m or max((y1 - y0) / 1400, (z1 - z0) / 600, 0.2)
    ys, zs = np.arange(y0, y1, step), np.arange(z0, z1, step)
    inten = img.intensity if img.intensity is not None else np.abs(img.sums.s) ** 2
    db = 10 * np.log10(np.maximum(inten, inten.max() * 1e-30) / inten.max())
    # the nadir specular echo dominates the maximum: scale to the image's bright tail instead
    computed = db[inten > 0]
    top = float(np.percentile(computed, 99.95)) if computed.size else 0.0
    im = ax.imshow(polar_to_raster(db, img.grid, img.centre_yz_m, ys, zs), extent=(ys[0], ys[-1], zs[-1], zs[0]),
                   aspect="auto", cmap="viridis", vmin=top - dynamic_range_db, vmax=top, interpolation="nearest")
    fig.colorbar(im, ax=ax, label="intensity (dB re max)")
    ax.add_patch(pyplot().Rectangle((zoom[0], zoom[2]), zoom[1] - zoom[0], zoom[3] - zoom[2], fill=False, ec="white",
                                    lw=1))
    ax.set_title((title + ": " if title else "") + "(a) intensity |Σ p|²")


def _cf_panel(fig, ax, img, zoom) -> None:
    """(b) the smoothed coherence factor in the zoom window."""
    zy = np.arange(zoom[0], zoom[1], max((zoom[1] - zoom[0]) / 1400, 0.2))
    zz = np.arange(zoom[2], zoom[3], max((zoom[3] - zoom[2]) / 400, 0.1))
    cf = img.cf_smooth if img.cf_smooth is not None else img.cf
    im = ax.imshow(polar_to_raster(cf, img.grid, img.centre_yz_m, zy, zz), extent=(zy[0], zy[-1], zz[-1], zz[0]),
                   aspect="auto", cmap="magma", vmin=0, vmax=1, interpolation="nearest")
    fig.colorbar(im, ax=ax, label="coherence factor")
    ax.set_title("(b) coherence factor (7-point Hann smoothed)")


def _peaks_panel(fig, ax, peaks: list, zoom) -> None:
    """(c) the coherence peaks, coloured by CF, in the zoom window."""
    ax.set_facecolor("#f4f4f4")
    if peaks:
        py = np.array([p["y_m"] for p in peaks])
        pz = np.array([p["z_m"] for p in peaks])
        pc = np.array([p["cf"] for p in peaks])
        sc = ax.scatter(py, pz, c=pc, s=10 + 40 * pc, cmap="plasma", vmin=PEAK_THRESHOLD, vmax=1, edgecolors="none",
                        zorder=3)
        fig.colorbar(sc, ax=ax, label="coherence peak CF")
    ax.set_xlim(zoom[0], zoom[1])
    ax.set_ylim(zoom[3], zoom[2])
    ax.set_title(f"(c) coherence peaks ({len(peaks)} above threshold)")


def plot_peak_map(rows, path, *, targets=None, title: str = "coherence peaks over the line",
                  threshold: float = MAP_THRESHOLD):
    """Persistence map like Holland et al. Figs. 9-10: peaks of all pings by
    cross-track position (y) and ping, coloured by CF."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 5), dpi=110, constrained_layout=True)
    sel = [r for r in rows if r["cf"] > threshold]
    if sel:
        sc = ax.scatter([r["y_m"] for r in sel], [r["ping"] for r in sel], c=[r["cf"] for r in sel], s=12,
                        cmap="plasma", vmin=threshold, vmax=1)
        fig.colorbar(sc, ax=ax, label="CF")
    if targets is not None:
        for k, (pings, ys) in enumerate(targets):
            ax.plot(ys, pings, color="cyan", lw=1, label="pipe (truth)" if k == 0 else None)
        ax.legend(loc="upper right")
    ax.set_xlabel("cross-track y (m, port negative)")
    ax.set_ylabel("ping")
    ax.set_title(f"{title} (CF > {threshold:g})")
    fig.savefig(path)
    plt.close(fig)
    return path
