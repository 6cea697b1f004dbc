"""Run time against error: every interpolation mode on one scene, one process.

What is timed: ``engine.beamform`` (upload, kernel, read-back of intensity
and CF) on the full grid, best of ``repeats`` after a warm-up that builds the
kernel, plus the FFT upsampling for the upsampled modes; the whole ping (raw samples → intensity, CF, smoothed CF, peaks)
through :class:`~clbeam.imaging.imager.Imager`.  Baselines in the same run: the
float64 NumPy reference (timed on every ``reference_stride``-th angle row and
scaled by cells) and a numba-parallel linear delay-and-sum on the full grid.

Errors are measured on an accuracy window of the same scene (full
resolution, a block of angles and ranges) against the exact band-limited
float64 reference: intensity error energy over signal energy (dB) over cells
within 40 dB of the window's maximum, the largest |ΔCF|, and coherence-peak
precision and recall (a peak matches when an exact one lies within one cell).
"""

from __future__ import annotations

import csv
import logging
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from clbeam.constants import PEAK_THRESHOLD
from clbeam.imaging.engine import get_engine
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.postprocess import coherence_peaks, hann_smooth
from clbeam.imaging.signal import upsample_analytic
from clbeam.io.figures import pyplot
from clbeam.model.grid import PolarGrid

log = logging.getLogger(__name__)

#: (mode, upsample, precision) triples benchmarked by default
DEFAULT_CASES = (
    ("nearest", 1, "float32"), ("linear", 1, "float32"), ("linear-bb", 1, "float32"),
    ("cubic", 1, "float32"), ("lanczos4", 1, "float32"), ("lanczos8", 1, "float32"),
    ("nearest", 4, "float32"), ("linear", 2, "float32"), ("linear", 4, "float32"), ("cubic", 2, "float32"),
    ("linear-bb", 2, "float32"), ("cubic", 1, "float64"), ("lanczos8", 1, "float64"),
)


@dataclass
class BenchRow:
    """One benchmarked case."""

    mode: str
    upsample: int
    precision: str
    ms_per_ping: float
    cells_ch_per_s: float
    intensity_error_db: float
    max_abs_dcf: float
    peak_precision: float
    peak_recall: float
    x_numpy: float = np.nan
    x_numba: float = np.nan

    @property
    def label(self) -> str:
        """``mode`` with its upsampling and precision when not the default."""
        s = self.mode + (f" x{self.upsample}" if self.upsample > 1 else "")
        return s + (" f64" if self.precision == "float64" else "")


@dataclass
class BenchResult:
    """All rows plus the baselines and the set-up they were measured on."""

    rows: list
    numpy_cells_ch_per_s: float
    numba_cells_ch_per_s: float
    whole_ping_ms: dict
    skipping: list
    setup: dict = field(default_factory=dict)


def paper_grid() -> PolarGrid:
    """The paper's grid: 0.2 m x 0.1 degree, 0-1100 m, ±80 degrees."""
    return PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, max_range_m=1100.0, angles_deg=(-80.0, 80.0))


def accuracy_window(ranges_m=(880.0, 1000.0), angles_deg=(68.0, 80.0)) -> PolarGrid:
    """The error-measure window at the paper's resolution; the default holds
    ``line4``'s pipeline C (920 m across, 76 degrees) and the seabed around it."""
    return PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.1, min_range_m=ranges_m[0], max_range_m=ranges_m[1],
                             angles_deg=angles_deg)


def best_time(fn, repeats: int) -> float:
    """Smallest wall time (s) of ``repeats`` calls of ``fn``."""
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def intensity_error_db(got: np.ndarray, exact: np.ndarray, dynamic_range_db: float = 40.0) -> float:
    """Error energy over signal energy (dB) on cells within ``dynamic_range_db`` of the maximum."""
    keep = exact >= exact.max() * 10 ** (-dynamic_range_db / 10)
    return float(10 * np.log10(np.sum((got[keep] - exact[keep]) ** 2) / np.sum(exact[keep] ** 2)))


def peak_agreement(got_cf: np.ndarray, exact_cf: np.ndarray, threshold: float) -> tuple[float, float]:
    """Precision and recall of coherence peaks against the exact image's (one-cell tolerance)."""
    a = coherence_peaks(hann_smooth(got_cf), threshold)
    b = coherence_peaks(hann_smooth(exact_cf), threshold)
    if len(a) == 0 or len(b) == 0:
        return (float(len(a) == len(b)),) * 2
    d = np.max(np.abs(a[:, None, :] - b[None, :, :]), axis=2)
    return float(np.mean(d.min(axis=1) <= 1)), float(np.mean(d.min(axis=0) <= 1))


def run_benchmark(ping, *, grid: PolarGrid | None = None, accuracy_grid: PolarGrid | None = None,
                  cases=DEFAULT_CASES, repeats: int = 3, reference_stride: int = 40, threshold: float = PEAK_THRESHOLD,
                  default_mode: str = "cubic", progress=None) -> BenchResult:
    """Benchmark every case on ``ping`` (see the module docstring for what is measured).

    Parameters
    ----------
    ping : Ping
        The scene (raw or analytic).
    grid : PolarGrid
        Timing grid (default: the paper's).
    accuracy_grid : PolarGrid
        Window for the error measures (default :func:`accuracy_window`).
    cases : iterable of (mode, upsample, precision)
        What to measure.
    repeats : int
        Timed runs per case (best kept).
    reference_stride : int
        The NumPy reference is timed on every n-th angle row.
    """
    grid = grid or paper_grid()
    accuracy_grid = accuracy_grid or accuracy_window()
    say = progress or (lambda msg: log.info(msg))
    inputs = _Inputs(ping, grid)
    inp1 = inputs.get(1)
    say("exact float64 reference on the accuracy window")
    exact = inputs.reference.beamform(inp1, accuracy_grid, interp="exact", outputs=("intensity", "cf"))
    say("NumPy reference and numba baselines")
    numpy_rate, numba_rate = _baseline_rates(inputs, grid, reference_stride, default_mode, repeats)
    rows, engines = [], {}
    for mode, up, precision in cases:
        eng = engines.get(precision)
        if eng is None:
            eng = engines[precision] = get_engine("opencl", precision=precision)
        say(f"{mode} x{up} {precision}")
        rate, row = _mode_row(eng, inputs, grid, accuracy_grid, exact, (mode, up, precision), repeats, threshold)
        rows.append(BenchRow(*row, rate / numpy_rate, rate / numba_rate))
    say("whole ping and skipping")
    eng = engines.get("float32") or get_engine("opencl")
    whole, skipping = _whole_ping(eng, ping, grid, default_mode, repeats)
    setup = {"grid": f"{grid.shape[1]} ranges x {grid.shape[0]} angles", "channels": inp1.n_channels,
             "samples": inp1.n_samples, "sample_rate_hz": inp1.sample_rate_hz, "device": getattr(eng, "label", "?"),
             "accuracy_window": f"{accuracy_grid.shape[1]} ranges x {accuracy_grid.shape[0]} angles"}
    return BenchResult(rows, numpy_rate, numba_rate, whole, skipping, setup)


class _Inputs:
    """The ping's beamforming input per upsampling factor, prepared once."""

    def __init__(self, ping, grid: PolarGrid):
        self.ping, self.grid = ping, grid
        self.reference = get_engine("reference")
        self._inputs = {}

    def get(self, upsample: int):
        if upsample not in self._inputs:
            # straight rays: one input serves the timing grid, its subsample and the accuracy window
            opts = ImagingOptions(upsample=upsample, use_svp=False)
            self._inputs[upsample] = Imager(self.grid, opts, engine=self.reference).beamform_input(self.ping)
        return self._inputs[upsample]


def _baseline_rates(inputs: _Inputs, grid: PolarGrid, stride: int, mode: str, repeats: int) -> tuple:
    """Cells x channels per second of the NumPy reference (every ``stride``-th angle row) and of the
    numba baseline (NaN without numba)."""
    inp1, ref = inputs.get(1), inputs.reference
    sub = PolarGrid(grid.ranges_m, grid.angles_deg[::stride])
    t_ref = best_time(lambda: ref.beamform(inp1, sub, interp=mode, outputs=("intensity", "cf")), 1)
    numpy_rate = sub.n_cells * inp1.n_channels / t_ref
    try:
        from clbeam.evaluation.baselines import numba_beamform
    except ImportError:
        return numpy_rate, np.nan
    numba_beamform(inp1, PolarGrid(grid.ranges_m[:8], grid.angles_deg[:2]))  # compile
    t_nb = best_time(lambda: numba_beamform(inp1, grid), max(1, repeats - 1))
    return numpy_rate, grid.n_cells * inp1.n_channels / t_nb


def _mode_row(eng, inputs: _Inputs, grid: PolarGrid, accuracy_grid: PolarGrid, exact, case: tuple, repeats: int,
              threshold: float) -> tuple:
    """Rate (cells x channels / s) and the measured fields of one case's :class:`BenchRow`."""
    mode, up, precision = case
    inp = inputs.get(up)
    outputs = ("intensity", "cf")
    eng.beamform(inp, grid, interp=mode, outputs=outputs)  # build
    t = best_time(lambda: eng.beamform(inp, grid, interp=mode, outputs=outputs), repeats)
    if up > 1:  # the FFT upsampling is part of the mode's cost
        t += best_time(lambda: upsample_analytic(inputs.get(1).data, up), 1)
    acc = eng.beamform(inp, accuracy_grid, interp=mode, outputs=outputs)
    prec, rec = peak_agreement(acc.cf, exact.cf, threshold)
    rate = grid.n_cells * inp.n_channels / t
    return rate, (mode, up, precision, 1e3 * t, rate, intensity_error_db(acc.intensity.astype(np.float64), exact.intensity),
                  float(np.max(np.abs(acc.cf - exact.cf))), prec, rec)


def _whole_ping(eng, ping, grid: PolarGrid, mode: str, repeats: int) -> tuple:
    """Time per ping of the whole chain (raw to peaks) by stage, and with each skipping option."""
    whole, skipping = {}, []
    for label, opts in (
        ("full grid, intensity + CF", ImagingOptions(interp=mode)),
        ("intensity only", ImagingOptions(interp=mode, outputs=("intensity",))),
        ("seabed band -5/+40 m", ImagingOptions(interp=mode, seabed_band_m=(5.0, 40.0))),
    ):
        imager = Imager(grid, opts, engine=eng)
        imager.image(ping)
        t = best_time(lambda imager=imager: imager.image(ping), max(1, repeats - 1))
        skipping.append({"what": label, "ms_per_ping": 1e3 * t})
        if label.startswith("full"):
            img = imager.image(ping)
            whole = {k: 1e3 * v for k, v in img.timings_s.items()}
            whole["total_ms"] = 1e3 * t
    return whole, skipping


def markdown_table(result: BenchResult) -> str:
    """The result as Markdown tables."""
    lines = ["| mode | ms/ping | cells·ch/s | intensity error (dB) | max abs ΔCF | peak precision / recall "
             "| × NumPy | × numba |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in result.rows:
        lines.append(f"| {r.label} | {r.ms_per_ping:.0f} | {r.cells_ch_per_s:.2e} | {r.intensity_error_db:.1f} "
                     f"| {r.max_abs_dcf:.3f} | {r.peak_precision:.2f} / {r.peak_recall:.2f} "
                     f"| {r.x_numpy:.0f} | {r.x_numba:.1f} |")
    lines += ["", f"NumPy float64 reference: {result.numpy_cells_ch_per_s:.2e} cells·ch/s; "
                  f"numba parallel linear: {result.numba_cells_ch_per_s:.2e} cells·ch/s.", "",
              "| skipping | ms/ping |", "|---|---:|"]
    lines += [f"| {s['what']} | {s['ms_per_ping']:.0f} |" for s in result.skipping]
    lines += ["", "Whole ping (raw → intensity, CF, peaks), ms: "
              + ", ".join(f"{k.replace('_s', '')} {v:.0f}" for k, v in result.whole_ping_ms.items()), "",
              "Set-up: " + ", ".join(f"{k} {v}" for k, v in result.setup.items())]
    return "\n".join(lines) + "\n"


def write_report(result: BenchResult, out_dir) -> dict:
    """Write ``bench.md``, ``bench.csv`` and the Pareto plot ``pareto.png``; return their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    md = out / "bench.md"
    md.write_text(markdown_table(result))
    csv_path = out / "bench.csv"
    with open(csv_path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(asdict(result.rows[0])))
        w.writeheader()
        for r in result.rows:
            w.writerow(asdict(r))
    png = out / "pareto.png"
    plot_pareto(result, png)
    return {"markdown": md, "csv": csv_path, "plot": png}


def plot_pareto(result: BenchResult, path) -> None:
    """Run time against intensity error, the Pareto front drawn."""
    plt = pyplot()

    fig, ax = plt.subplots(figsize=(7, 4.5), dpi=120)
    pts = sorted(((r.ms_per_ping, r.intensity_error_db, r.label) for r in result.rows))
    front, best = [], np.inf
    for t, e, _ in pts:
        if e < best - 0.1:  # strictly better by more than rounding of the table
            front.append((t, e))
            best = e
    for t, e, label in pts:
        ax.scatter(t, e, s=30, color="tab:blue", zorder=3)
        ax.annotate(label, (t, e), textcoords="offset points", xytext=(4, 3), fontsize=7)
    ax.plot(*zip(*front), color="tab:orange", lw=1.5, label="Pareto front", zorder=2)
    ax.set_xscale("log")
    ax.set_xlabel("time per ping on the paper grid (ms, log)")
    ax.set_ylabel("intensity error vs exact (dB)")
    ax.set_title("clbeam interpolation modes: run time against error")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
