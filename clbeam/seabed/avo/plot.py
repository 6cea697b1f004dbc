"""AVO figures (matplotlib, Agg): Fonseca et al. (2005) figures 1, 2 and 4.

Every function takes arrays and an output path, writes a PNG and returns
the path.  Nothing here computes an attribute: callers pass what
:mod:`clbeam.seabed.avo.attributes` and :mod:`clbeam.seabed.avo.inversion` returned.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from clbeam.constants import SOUND_SPEED_M_S
from clbeam.io.figures import pyplot
from clbeam.seabed.avo.attributes import (
    FAR_INTERCEPT_DEG,
    FAR_RANGE_DEG,
    NEAR_INTERCEPT_DEG,
    NEAR_RANGE_DEG,
    OUTER_RANGE_DEG,
    AngularAttributes,
    angular_attributes,
)
from clbeam.seabed.avo.model import backscatter_strength_db
from clbeam.seabed.avo.sediment import sediment_from_grain_size

#: Colour of the background trend line (figure 2).
TREND_COLOR = "#d62728"
_RANGE_COLORS = {"near": "#1f77b4", "far": "#2ca02c", "outer": "#9467bd"}


def _save(fig, path) -> Path:
    path = Path(path)
    fig.savefig(path, dpi=100)
    pyplot().close(fig)
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
    fig, ax = pyplot().subplots(figsize=(8, 5))
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
    fig, ax = pyplot().subplots(figsize=(6, 5))
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
    fig, axes = pyplot().subplots(n, 1, figsize=(8, 1.8 * n + 1), sharex=True, squeeze=False)
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


def write_figures(folder, patches, rows, *, frequency_hz=None, sound_speed_m_s: float = SOUND_SPEED_M_S) -> list[Path]:
    """The AVO figures of a survey into ``folder`` (PNG); returns their paths.

    ``avo_response_first.png`` / ``avo_response_last.png``: the first and the
    last patch's stacked response with its attributes (and the fitted model
    when the inversion ran); ``avo_gradient_intercept.png``;
    ``avo_track.png``: A, B, fluid factor and Mz along the track;
    ``avo_nadir.png`` (when the rows have nadir coefficients): the nadir
    coefficient and calibration per patch (:func:`plot_nadir`).

    Parameters
    ----------
    folder : str or pathlib.Path
        Output folder (created).
    patches : list of Patch
        Stacked responses, in the order of ``rows``.
    rows : list of PatchRecord
        Their records (:func:`clbeam.seabed.avo.table.survey_records`).
    frequency_hz : float, optional
        Band centre (Hz) of the fitted-model curve; no curve without it.
    sound_speed_m_s : float
        Water sound speed of the model (m/s).
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for tag, k in (("first", 0), ("last", len(patches) - 1)):
        p, r = patches[k], rows[k]
        model = None
        if frequency_hz is not None and np.isfinite(r.mz_phi):
            sed = dataclasses.replace(sediment_from_grain_size(r.mz_phi), w2_cm4=r.roughness_w2_cm4,
                                      sigma2=r.volume_sigma2)
            model = backscatter_strength_db(np.clip(90.0 - p.incidence_deg, 1e-3, 90.0), frequency_hz,
                                            sediment=sed, sound_speed_water_m_s=sound_speed_m_s)
        paths.append(plot_angular_response(
            out / f"avo_response_{tag}.png", p.incidence_deg, p.strength_db,
            angular_attributes(p.incidence_deg, p.strength_db), model_db=model,
            title=f"{p.side}, pings {p.ping_start}-{p.ping_stop - 1}, along-track {p.along_track_m:.0f} m"))
    a = [r.intercept_a_db for r in rows]
    b = [r.gradient_b_db for r in rows]
    paths.append(plot_gradient_intercept(out / "avo_gradient_intercept.png", a, b, rows[0].trend_g,
                                         rows[0].trend_d_db, fluid_factor_db=[r.fluid_factor_db for r in rows]))
    series = {"A (dB)": a, "B (dB)": b, "fluid factor (dB)": [r.fluid_factor_db for r in rows]}
    if any(np.isfinite(r.mz_phi) for r in rows):
        series["Mz (phi)"] = [r.mz_phi for r in rows]
    paths.append(plot_along_track(out / "avo_track.png", [r.along_track_m for r in rows], series,
                                  sides=[r.side for r in rows]))
    if any(np.isfinite(r.nadir_reflection) for r in rows):
        paths.append(plot_nadir(out / "avo_nadir.png", rows))
    return paths


def plot_nadir(path, rows) -> Path:
    """Each patch's nadir reflection coefficient (with the fitted sediment's) and calibration along the track.

    Top: measured ``|R|`` with its standard error and, where the joint
    inversion ran, the coefficient of the fitted sediment; bottom: each
    patch's calibration with its error and the one applied to the survey.

    Parameters
    ----------
    path : str or pathlib.Path
        Output PNG.
    rows : list of PatchRecord
        The AVO table's rows (one per patch and side; the nadir values are per patch).
    """
    x = np.array([r.along_track_m for r in rows])
    fig, (top, bottom) = pyplot().subplots(2, 1, figsize=(8, 5), sharex=True)
    top.errorbar(x, [r.nadir_reflection for r in rows], yerr=[r.nadir_reflection_error for r in rows], fmt="o",
                 capsize=3, label="measured (seabed echo and multiple)")
    for side, marker in (("port", "<"), ("starboard", ">")):
        m = np.array([r.side == side and r.inversion == "joint" for r in rows])
        if m.any():
            top.plot(x[m], [r.nadir_model_reflection for r, k in zip(rows, m) if k], marker, ls="none",
                     label=f"fitted sediment ({side})")
    top.set_ylabel("nadir |R|")
    top.legend(fontsize=7)
    bottom.errorbar(x, [r.nadir_calibration_db for r in rows], yerr=[r.nadir_calibration_error_db for r in rows],
                    fmt="o", capsize=3, label="patch")
    if rows and rows[0].calibration_source != "none":
        bottom.axhline(rows[0].calibration_db, color=TREND_COLOR, label=f"applied ({rows[0].calibration_source})")
    bottom.set_ylabel("calibration (dB)")
    bottom.set_xlabel("along-track position (m)")
    bottom.legend(fontsize=7)
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    return _save(fig, path)
