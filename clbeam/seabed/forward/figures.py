"""Figures of the forward model: compressed traces and echo spectra (Rakotonarivo Figs. 8–9).

Drawn with matplotlib's object interface on the Agg canvas, so importing
this module changes no global backend and needs no display.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from clbeam.seabed.forward.config import table2_layout
from clbeam.seabed.forward.trace import CHIRPS, ForwardTrace, simulate_trace

#: Colours of the paper's Figs. 8–9: black layout 1, red layout 2.
LAYOUT_COLOURS = {1: "black", 2: "red"}


def _figure(width_in: float, height_in: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def _band(trace: ForwardTrace) -> np.ndarray:
    return (trace.freq_hz >= trace.chirp.f0_hz) & (trace.freq_hz <= trace.chirp.f1_hz)


def echo_spectra_db(trace: ForwardTrace) -> np.ndarray:
    """Spectrum level of each echo in the received trace, ``20 log10 |A_i(w) x(w)|`` (dB re 1 Pa/Hz·Hz).

    Parameters
    ----------
    trace : ForwardTrace

    Returns
    -------
    numpy.ndarray
        ``(n_echo, n_freq)``; ``-inf`` where an echo is absent.
    """
    with np.errstate(divide="ignore"):
        return 20 * np.log10(np.abs(trace.echoes.spectra() * trace.emitted_spectrum[None, :]))


def plot_trace(trace: ForwardTrace, path, *, title: str = "") -> Path:
    """Compressed trace ``y_c`` and its envelope against time, echo times marked (Fig. 8).

    Parameters
    ----------
    trace : ForwardTrace
    path : str or pathlib.Path
        PNG to write.
    title : str
        Figure title.

    Returns
    -------
    pathlib.Path
    """
    fig = _figure(8.0, 3.5)
    ax = fig.add_subplot(1, 1, 1)
    t_ms = trace.time_s * 1e3
    ax.plot(t_ms, trace.compressed.real, color="0.3", lw=0.7, label="y_c")
    ax.plot(t_ms, np.abs(trace.compressed), color="C0", lw=1.0, label="envelope")
    for tau in trace.echoes.times_s[np.isfinite(trace.echoes.times_s)]:
        ax.axvline(tau * 1e3, color="C3", lw=0.6, ls=":")
    times = trace.echoes.times_s[np.isfinite(trace.echoes.times_s)]
    if times.size:
        pad = 2 * trace.chirp.duration_s * 1e3 / 10 + 1.0
        ax.set_xlim(times.min() * 1e3 - pad, times.max() * 1e3 + pad)
    ax.set_xlabel("two-way time (ms)")
    ax.set_ylabel("compressed pressure (Pa)")
    ax.set_title(title or f"compressed trace, chirp {trace.chirp.f0_hz:g}-{trace.chirp.f1_hz:g} Hz")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    return path


def plot_spectra(trace: ForwardTrace, path, *, title: str = "") -> Path:
    """Spectrum of each echo over the chirp band (Fig. 9).

    Parameters
    ----------
    trace : ForwardTrace
    path : str or pathlib.Path
        PNG to write.
    title : str
        Figure title.

    Returns
    -------
    pathlib.Path
    """
    fig = _figure(6.5, 4.0)
    ax = fig.add_subplot(1, 1, 1)
    band = _band(trace)
    levels = echo_spectra_db(trace)
    for i, row in enumerate(levels):
        if np.isfinite(trace.echoes.times_s[i]):
            ax.plot(trace.freq_hz[band] / 1e3, row[band], lw=1.0, label=f"echo {i + 1}")
    ax.set_xlabel("frequency (kHz)")
    ax.set_ylabel("level (dB re 1 Pa s)")
    ax.set_title(title or "echo spectra")
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    return path


@dataclass(frozen=True)
class Table2Traces:
    """The traces behind the Figs. 8–9 reproductions.

    Attributes
    ----------
    traces : dict
        ``(layout, chirp_name) -> ForwardTrace`` for layouts 1, 2 and chirps
        ``"low"``, ``"high"``.
    smooth_seafloor : dict
        ``chirp_name -> ForwardTrace`` of layout 2 with ``sigma1 = 0`` (the
        third echo-3 curve of Fig. 9).
    """

    traces: dict
    smooth_seafloor: dict


def table2_traces(*, sample_rate_hz: float = 48000.0) -> Table2Traces:
    """Noise-free traces of Table 2's layouts for the paper's two chirps (§4).

    Parameters
    ----------
    sample_rate_hz : float
        Sample rate (Hz).
    """
    layouts = {n: table2_layout(n) for n in (1, 2)}
    smooth = layouts[2].with_interface(1, roughness_m=0.0)
    record = None
    traces, smooth_traces = {}, {}
    for name, chirp in CHIRPS.items():
        for n, seabed in layouts.items():
            tr = simulate_trace(seabed, chirp, sample_rate_hz=sample_rate_hz, record_s=record)
            record = tr.time_s.size / sample_rate_hz   # one record length for all, so the traces overlay
            traces[(n, name)] = tr
        smooth_traces[name] = simulate_trace(smooth, chirp, sample_rate_hz=sample_rate_hz, record_s=record)
    return Table2Traces(traces, smooth_traces)


def table2_figures(out_dir, *, sample_rate_hz: float = 48000.0, data: Table2Traces | None = None) -> dict:
    """Write the reproductions of Figs. 8 (compressed traces) and 9 (echo spectra).

    Fig. 8: ``y_c`` of layouts 1 (black) and 2 (red) for the 1.7–5.2 kHz and
    5–15 kHz chirps.  Fig. 9: spectra of echoes 1 and 3 for both layouts,
    with echo 3 of layout 2 also drawn for a smooth seafloor (``sigma1 =
    0``, dashed), for each chirp.

    Parameters
    ----------
    out_dir : str or pathlib.Path
        Folder (created if needed).
    sample_rate_hz : float
        Sample rate (Hz).
    data : Table2Traces, optional
        Traces already computed by :func:`table2_traces`.

    Returns
    -------
    dict
        ``{"fig8": Path, "fig9": Path}``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    data = data or table2_traces(sample_rate_hz=sample_rate_hz)
    return {"fig8": _fig8(data, out / "fig8_compressed_table2.png"), "fig9": _fig9(data, out / "fig9_spectra_table2.png")}


def _fig8(data: Table2Traces, path: Path) -> Path:
    """Fig. 8: the compressed traces of both layouts, one panel per chirp."""
    fig = _figure(9.0, 6.0)
    for row, name in enumerate(CHIRPS):
        ax = fig.add_subplot(2, 1, row + 1)
        for n in (1, 2):
            tr = data.traces[(n, name)]
            ax.plot(tr.time_s * 1e3, tr.compressed.real, color=LAYOUT_COLOURS[n], lw=0.7, label=f"layout {n}")
        times = data.traces[(1, name)].echoes.times_s
        ax.set_xlim(times.min() * 1e3 - 2.0, times.max() * 1e3 + 2.0)
        chirp = CHIRPS[name]
        ax.set_title(f"chirp {chirp.f0_hz / 1e3:g}-{chirp.f1_hz / 1e3:g} kHz, {chirp.duration_s * 1e3:g} ms",
                     fontsize=9)
        ax.set_ylabel("y_c (Pa)")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_xlabel("two-way time (ms)")
    fig.suptitle("Compressed backscattered field (Rakotonarivo Fig. 8, Table 2 layouts)")
    fig.tight_layout()
    fig.savefig(path)
    return path


def _fig9(data: Table2Traces, path: Path) -> Path:
    """Fig. 9: spectra of echoes 1 and 3 of both layouts (and a smooth seafloor), per chirp."""
    fig = _figure(9.0, 6.5)
    for row, name in enumerate(CHIRPS):
        for col, echo in enumerate((0, 2)):
            ax = fig.add_subplot(2, 2, 2 * row + col + 1)
            for n in (1, 2):
                tr = data.traces[(n, name)]
                band = _band(tr)
                ax.plot(tr.freq_hz[band] / 1e3, echo_spectra_db(tr)[echo][band], color=LAYOUT_COLOURS[n],
                        lw=1.0, label=f"layout {n}")
            if echo == 2:
                tr = data.smooth_seafloor[name]
                band = _band(tr)
                ax.plot(tr.freq_hz[band] / 1e3, echo_spectra_db(tr)[echo][band], color="red", lw=1.0, ls="--",
                        label="layout 2, sigma1 = 0")
            ax.set_title(f"echo {echo + 1}, chirp {name}", fontsize=9)
            ax.set_xlabel("frequency (kHz)")
            ax.set_ylabel("level (dB)")
            ax.legend(fontsize=7)
    fig.suptitle("Echo spectra (Rakotonarivo Fig. 9)")
    fig.tight_layout()
    fig.savefig(path)
    return path
