"""AVO figures (matplotlib, Agg): Fonseca et al. (2005) figures 1, 2 and 4.

Every function takes arrays and an output path, writes a PNG and returns
the path.  Nothing here computes an attribute: callers pass what
:mod:`clbeam.seabed.avo.attributes` and :mod:`clbeam.seabed.avo.inversion` returned.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from clbeam.seabed.avo.attributes import (  # noqa: E402
    FAR_INTERCEPT_DEG,
    FAR_RANGE_DEG,
    NEAR_INTERCEPT_DEG,
    NEAR_RANGE_DEG,
    OUTER_RANGE_DEG,
    AngularAttributes,
)

#: Colour of the background trend line (figure 2).
TREND_COLOR = "#d62728"
_RANGE_COLORS = {"near": "#1f77b4", "far": "#2ca02c", "outer": "#9467bd"}


def _save(fig, path) -> Path:
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def plot_angular_response(path, incidence_deg, strength_db, attributes: AngularAttributes, *,
                          model_db=None, title: str = "") -> Path:
    """Stacked angular response with the AVO attributes (Fonseca Fig. 1).

    Shades the near / far / outer ranges, draws each range mean as a
    horizontal segment and the near and far least-squares lines through
    their intercepts at 80° and 55° grazing (10° and 35° incidence).

    Parameters
    ----------
    path : str or pathlib.Path
        Output PNG.
    incidence_deg, strength_db : array_like
        Stacked response: incidence angles (deg) and strengths (dB).
    attributes : AngularAttributes
        Attributes of that response.
    model_db : array_like, optional
        Fitted model at the same angles, drawn as a line.
    title : str
        Figure title.
    """
    inc = np.abs(np.asarray(incidence_deg, dtype=float))
    fig, ax = plt.subplots(figsize=(8, 5))
    for name, (lo, hi) in (("near", NEAR_RANGE_DEG), ("far", FAR_RANGE_DEG), ("outer", OUTER_RANGE_DEG)):
        ax.axvspan(90 - hi, 90 - lo, color=_RANGE_COLORS[name], alpha=0.08)
        mean = getattr(attributes, f"{name}_mean_db")
        ax.hlines(mean, 90 - hi, 90 - lo, colors=_RANGE_COLORS[name], linestyles="--",
                  label=f"{name} mean {mean:.1f} dB")
    for name, (lo, hi), at in (("near", NEAR_RANGE_DEG, NEAR_INTERCEPT_DEG),
                               ("far", FAR_RANGE_DEG, FAR_INTERCEPT_DEG)):
        slope = getattr(attributes, f"{name}_slope_db_per_deg")
        value = getattr(attributes, f"{name}_intercept_db")
        g = np.array([lo, hi])
        ax.plot(90 - g, value + slope * (g - at), color=_RANGE_COLORS[name], lw=2)
        ax.plot([90 - at], [value], "o", color=_RANGE_COLORS[name],
                label=f"{name} intercept @{at:g}° grazing {value:.1f} dB, slope {slope:.2f} dB/°")
    ax.plot(inc, strength_db, ".", color="k", ms=4, label="stacked response")
    if model_db is not None:
        ax.plot(inc, model_db, "-", color="orange", label="model")
    ax.set_xlabel("incidence angle (deg)")
    ax.set_ylabel("backscatter strength (dB)")
    ax.set_xlim(0, 90)
    ax.set_title(title or f"A = {attributes.intercept_a_db:.1f} dB, B = {attributes.gradient_b_db:.1f} dB")
    ax.legend(fontsize=7, loc="lower left")
    ax.grid(alpha=0.3)
    return _save(fig, path)


def plot_gradient_intercept(path, intercept_a_db, gradient_b_db, g: float, d: float, *,
                            fluid_factor_db=None, title: str = "") -> Path:
    """Gradient–intercept crossplot with the background trend (Fonseca Fig. 2).

    Parameters
    ----------
    path : str or pathlib.Path
        Output PNG.
    intercept_a_db, gradient_b_db : array_like
        ``A`` (x axis) and ``B`` (y axis) of every patch (dB).
    g, d : float
        Background trend ``B = g A + d``, drawn in :data:`TREND_COLOR`.
    fluid_factor_db : array_like, optional
        Colours the points.
    title : str
        Figure title.
    """
    a = np.asarray(intercept_a_db, dtype=float)
    b = np.asarray(gradient_b_db, dtype=float)
    fig, ax = plt.subplots(figsize=(6, 5))
    if fluid_factor_db is None:
        ax.plot(a, b, "o", color="k", ms=4)
    else:
        sc = ax.scatter(a, b, c=fluid_factor_db, cmap="coolwarm", s=16)
        fig.colorbar(sc, ax=ax, label="fluid factor (dB)")
    x = np.array([np.nanmin(a), np.nanmax(a)])
    ax.plot(x, g * x + d, color=TREND_COLOR, lw=2, label=f"trend B = {g:.3f} A + {d:.2f}")
    ax.set_xlabel("intercept A (dB)")
    ax.set_ylabel("gradient B (dB)")
    ax.set_title(title or "gradient–intercept")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def plot_along_track(path, position, series: dict, *, sides=None, xlabel: str = "along-track position (m)") -> Path:
    """Attributes and inverted quantities along the track (Fonseca Fig. 4 as profiles).

    One panel per entry of ``series`` (label → values per patch); with
    ``sides`` the port and starboard patches are drawn as separate lines.

    Parameters
    ----------
    path : str or pathlib.Path
        Output PNG.
    position : array_like
        Along-track position (or patch index) of each patch.
    series : dict of str to array_like
        Panel label (with units) → one value per patch, e.g.
        ``{"A (dB)": ..., "fluid factor (dB)": ..., "Mz (phi)": ...}``.
    sides : array_like of str, optional
        ``"port"``/``"starboard"`` per patch.
    xlabel : str
        Label of the position axis.
    """
    x = np.asarray(position, dtype=float)
    n = max(len(series), 1)
    fig, axes = plt.subplots(n, 1, figsize=(8, 1.8 * n + 1), sharex=True, squeeze=False)
    groups = {"all": np.ones(x.size, bool)} if sides is None else {
        s: np.asarray(sides) == s for s in ("port", "starboard")}
    for ax, (label, values) in zip(axes[:, 0], series.items()):
        v = np.asarray(values, dtype=float)
        for name, m in groups.items():
            order = np.argsort(x[m])
            ax.plot(x[m][order], v[m][order], ".-", label=name if sides is not None else None)
        ax.set_ylabel(label, fontsize=8)
        ax.grid(alpha=0.3)
    if sides is not None:
        axes[0, 0].legend(fontsize=7)
    axes[-1, 0].set_xlabel(xlabel)
    return _save(fig, path)
