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
import dataclasses
import logging
import re
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from clbeam.constants import PEAK_THRESHOLD
from clbeam.imaging.engine import get_engine
from clbeam.imaging.engine.beams import BeamSampling
from clbeam.imaging.engine.errormodel import predicted_settings
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.postprocess import coherence_peaks, hann_smooth
from clbeam.imaging.signal import upsample_analytic
from clbeam.io.figures import pyplot
from clbeam.model.grid import PolarGrid

log = logging.getLogger(__name__)

@dataclass(frozen=True)
class Case:
    """One setting to benchmark: a mode, its upsampling, precision and beam sampling, or ``mode="auto"``
    with an error budget (the setting the Imager picks for the scene)."""

    mode: str
    upsample: int = 1
    precision: str = "float32"
    beams: BeamSampling | None = None
    budget_db: float | None = None


#: the cases benchmarked by default: every mode directly, the upsampled ones, float64, beam-sampled ones and the
#: settings ``--interp auto`` picks at -40 and -60 dB
DEFAULT_CASES = (
    Case("nearest"), Case("linear"), Case("linear-bb"), Case("cubic"), Case("lanczos4"), Case("lanczos8"),
    Case("nearest", 4), Case("linear", 2), Case("linear", 4), Case("cubic", 2), Case("linear-bb", 2),
    Case("cubic", precision="float64"), Case("lanczos8", precision="float64"),
    Case("cubic", beams=BeamSampling(1.5, 8)), Case("lanczos4", beams=BeamSampling(1.25, 12)),
    Case("lanczos4", beams=BeamSampling(1.5, 8)), Case("cubic", 2, beams=BeamSampling(1.5, 12)),
    Case("lanczos8", beams=BeamSampling(1.5, 12)), Case("lanczos8", beams=BeamSampling(2.0, 16)),
    Case("auto", budget_db=-40.0), Case("auto", budget_db=-60.0),
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
    beams: str = ""
    predicted_error_db: float = np.nan
    budget_db: float = np.nan

    @property
    def label(self) -> str:
        """``mode`` with its upsampling, beams and precision when not the default (``auto -40 dB: …``)."""
        s = self.mode + (f" x{self.upsample}" if self.upsample > 1 else "") + (f" beams {self.beams}" if self.beams else "")
        s += " f64" if self.precision == "float64" else ""
        return f"auto {self.budget_db:g} dB: {s}" if np.isfinite(self.budget_db) else s


@dataclass
class BenchResult:
    """All rows plus the baselines and the set-up they were measured on."""

    rows: list
    numpy_cells_ch_per_s: float
    numba_cells_ch_per_s: float
    whole_ping_ms: dict
    skipping: list
    setup: dict = field(default_factory=dict)
    command: dict = field(default_factory=dict)
    pylops_cells_ch_per_s: float = np.nan
    #: :func:`clbeam.evaluation.zoo.zoo_command_times`: the whole command on each zoo scene
    zoo_commands: dict = field(default_factory=dict)


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
    cases : iterable of Case
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
    settings = inputs.predicted()
    for case in cases:
        eng = engines.get(case.precision)
        if eng is None:
            eng = engines[case.precision] = get_engine("opencl", precision=case.precision)
        case = inputs.resolve(case, eng)
        say(f"{case.mode} x{case.upsample} {case.precision}" + (f" beams {_beams_label(case.beams)}" if case.beams else ""))
        rate, row = _mode_row(eng, inputs, grid, accuracy_grid, exact, case, repeats, threshold)
        rows.append(BenchRow(*row, rate / numpy_rate, rate / numba_rate, beams=_beams_label(case.beams),
                             predicted_error_db=_predicted(settings, case), budget_db=case.budget_db or np.nan))
    say("whole ping and skipping")
    eng = engines.get("float32") or get_engine("opencl")
    whole, skipping = _whole_ping(eng, ping, grid, repeats)
    setup = {"grid": f"{grid.shape[1]} ranges x {grid.shape[0]} angles", "channels": inp1.n_channels,
             "samples": inp1.n_samples, "sample_rate_hz": inp1.sample_rate_hz, "device": getattr(eng, "label", "?"),
             "accuracy_window": f"{accuracy_grid.shape[1]} ranges x {accuracy_grid.shape[0]} angles"}
    say("PyLops' Kirchhoff adjoint")
    return BenchResult(rows, numpy_rate, numba_rate, whole, skipping, setup,
                       pylops_cells_ch_per_s=pylops_rate(inp1, grid, n_cells=min(3e5, grid.n_cells)))


class _Inputs:
    """The ping's beamforming input per upsampling factor, prepared once."""

    def __init__(self, ping, grid: PolarGrid):
        self.ping, self.grid = ping, grid
        self.reference = get_engine("reference")
        self._inputs = {}

    def predicted(self) -> list:
        """The error model's settings for this scene and grid (:func:`~clbeam.imaging.engine.errormodel.predicted_settings`)."""
        inp = self.get(1)
        across = np.linalg.norm(self.ping.element_pos_m[:, 1:] - self.ping.source_pos_m[1:], axis=1)
        return predicted_settings(across, inp.band_hz, inp.sample_rate_hz, inp.sound_speed_m_s,
                                  n_angles=self.grid.shape[0], n_ranges=self.grid.shape[1],
                                  angle_span_rad=float(np.deg2rad(np.ptp(self.grid.angles_deg))),
                                  n_samples=inp.n_samples)

    def resolve(self, case: Case, engine) -> Case:
        """An ``auto`` case as the setting an Imager with its budget picks for this ping."""
        if case.mode != "auto":
            return case
        imager = Imager(self.grid, ImagingOptions(max_error_db=case.budget_db, use_svp=False), engine=engine)
        _, s = imager._prepare(self.ping)
        return Case(s.interp, s.upsample, case.precision, s.beams, case.budget_db)

    def get(self, upsample: int):
        if upsample not in self._inputs:
            # straight rays: one input serves the timing grid, its subsample and the accuracy window
            opts = ImagingOptions(upsample=upsample, use_svp=False)
            inp = Imager(self.grid, opts, engine=self.reference).beamform_input(self.ping)
            # no data token: every timed call scales and uploads the channels, as one ping's imaging does
            self._inputs[upsample] = dataclasses.replace(inp, data_token=None)
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


def pylops_rate(inp, grid: PolarGrid, n_cells: float = 3e5) -> float:
    """Cells x channels per second of PyLops' Kirchhoff adjoint (the coherent sum only, real and imaginary
    parts; the operator built once, as for many pings) on a Cartesian grid of about ``n_cells`` over
    ``grid``'s extent (its travel-time tables hold 65 numbers a cell); NaN without PyLops."""
    try:
        import pylops  # noqa: F401
    except ImportError:
        return np.nan
    from clbeam.evaluation.baselines import pylops_kirchhoff

    r_max = float(grid.ranges_m[-1])
    y_half = r_max * np.sin(np.deg2rad(np.max(np.abs(grid.angles_deg))))
    n_y = int(np.sqrt(n_cells * 2 * y_half / r_max))
    y, z = np.linspace(-y_half, y_half, n_y), np.linspace(0.05 * r_max, r_max, int(n_cells / n_y))
    pylops_kirchhoff(inp, y[:4], z[:4])  # compile
    _, seconds = pylops_kirchhoff(inp, y, z)
    return y.size * z.size * inp.n_channels / seconds


def _mode_row(eng, inputs: _Inputs, grid: PolarGrid, accuracy_grid: PolarGrid, exact, case: Case, repeats: int,
              threshold: float) -> tuple:
    """Rate (cells x channels / s) and the measured fields of one case's :class:`BenchRow`.

    A beam-sampled case is measured on the full grid and cropped to the
    accuracy window (its beams are those of the full grid), a direct one on
    the window itself (every cell is computed alike)."""
    inp = inputs.get(case.upsample)
    outputs = ("intensity", "cf")

    def run(g):
        return eng.beamform(inp, g, interp=case.mode, outputs=outputs, beams=case.beams)

    run(grid)  # build
    t = best_time(lambda: run(grid), repeats)
    if case.upsample > 1:  # the FFT upsampling is part of the mode's cost
        t += best_time(lambda: upsample_analytic(inputs.get(1).data, case.upsample), 1)
    acc = _crop(run(grid), grid, accuracy_grid) if case.beams is not None and _is_subgrid(accuracy_grid, grid) \
        else run(accuracy_grid)
    prec, rec = peak_agreement(acc.cf, exact.cf, threshold)
    rate = grid.n_cells * inp.n_channels / t
    return rate, (case.mode, case.upsample, case.precision, 1e3 * t, rate,
                  intensity_error_db(acc.intensity.astype(np.float64), exact.intensity),
                  float(np.max(np.abs(acc.cf - exact.cf))), prec, rec)


def _is_subgrid(window: PolarGrid, grid: PolarGrid) -> bool:
    """True when the window's cells are a block of the grid's."""
    ia = np.searchsorted(grid.angles_deg, window.angles_deg[0] - 1e-9)
    ir = np.searchsorted(grid.ranges_m, window.ranges_m[0] - 1e-9)
    a, r = grid.angles_deg[ia:ia + window.shape[0]], grid.ranges_m[ir:ir + window.shape[1]]
    return (a.size == window.shape[0] and r.size == window.shape[1] and np.allclose(a, window.angles_deg, atol=1e-9)
            and np.allclose(r, window.ranges_m, atol=1e-9))


def _crop(sums, grid: PolarGrid, window: PolarGrid):
    """The window's cells of an image of ``grid`` (the window's nodes are nodes of the grid)."""
    ia = np.searchsorted(grid.angles_deg, window.angles_deg[0] - 1e-9)
    ir = np.searchsorted(grid.ranges_m, window.ranges_m[0] - 1e-9)
    rows, cols = slice(ia, ia + window.shape[0]), slice(ir, ir + window.shape[1])
    return type(sums)(intensity=sums.intensity[rows, cols], cf=sums.cf[rows, cols])


def _beams_label(beams) -> str:
    return f"x{beams.oversampling:g}/{beams.taps}" if beams is not None else ""


def _predicted(settings: list, case: Case) -> float:
    """The error model's prediction for a case (dB), NaN for a mode it does not cover."""
    for s in settings:
        if s.interp == case.mode and s.upsample == case.upsample and s.beams == case.beams:
            return s.error_db
    return np.nan


def _whole_ping(eng, ping, grid: PolarGrid, repeats: int) -> tuple:
    """Time per ping of the whole chain (raw to peaks) by stage with the default setting (``--interp
    auto`` within the default budget), and with each skipping option."""
    whole, skipping = {}, []
    for label, opts in (
        ("full grid, intensity + CF", ImagingOptions()),
        ("intensity only", ImagingOptions(outputs=("intensity",))),
        ("seabed band -5/+40 m", ImagingOptions(seabed_band_m=(5.0, 40.0))),
    ):
        imager = Imager(grid, opts, engine=eng)
        imager.image(ping)
        runs = []
        for _ in range(max(1, repeats - 1)):
            t0 = time.perf_counter()
            img = imager.image(ping)
            runs.append((time.perf_counter() - t0, img.timings_s, img.stages_s))
        t, stages, inner = min(runs, key=lambda run: run[0])  # the stages of the fastest run, the one reported
        skipping.append({"what": label, "ms_per_ping": 1e3 * t,
                         "stages_ms": {k: 1e3 * v for k, v in {"compress_s": stages.get("compress_s", 0.0),
                                                                **inner}.items()}})
        if label.startswith("full"):
            whole = {k: 1e3 * v for k, v in stages.items()}
            whole["total_ms"] = 1e3 * t
    return whole, skipping


def time_image_command(dataset, work_dir, pings=(1, 3)) -> dict:
    """``clbeam image --peaks`` timed as a whole (a new process, start-up and file writing included) on
    ping files of the first ``pings[0]`` and ``pings[1]`` pings of ``dataset``: the time per ping is
    the difference over the extra pings; the start-up is from the process's launch to the first
    ping's work (the command's ``--debug`` line), the one-time cost what is left of the shorter run
    beyond its pings (start-up, the first ping's warm-up and closing the file) (s).  The shorter run is
    made once untimed first, so that no kernel compiling lands in one of the timed runs."""
    from clbeam.io.pingwrite import write_ping_file

    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    totals, starts = [], []
    # the shorter run once untimed first: the OpenCL driver's program cache then holds every kernel variant the
    # command builds (a changed kernel source costs seconds of compiling in the first run only)
    for k, n in enumerate((pings[0], *pings)):
        src = write_ping_file(dataset.isel(ping=slice(0, n)), work / f"pings{n}.nc")
        cmd = [sys.executable, "-m", "clbeam", "--debug", "image", str(src), "-o", str(work / f"images{n}.nc"),
               "--peaks", str(work / f"peaks{n}.csv"), "-q"]
        launched, t0 = time.time(), time.perf_counter()
        run = subprocess.run(cmd, capture_output=True, text=True)
        if run.returncode != 0:
            raise RuntimeError(f"clbeam image failed ({run.returncode}): {run.stderr.strip().splitlines()[-1:]}")
        if k == 0:
            continue
        totals.append(time.perf_counter() - t0)
        found = re.search(r"first ping's work starts at unix time ([0-9.]+)", run.stderr)
        starts.append(float(found.group(1)) - launched if found else float("nan"))
    per_ping = (totals[1] - totals[0]) / (pings[1] - pings[0])
    start_up = min((v for v in starts if v == v), default=float("nan"))  # NaN: no --debug line found
    return {"pings": pings[1], "total_s": totals[1], "s_per_ping": per_ping, "start_up_s": start_up,
            "one_time_s": totals[0] - per_ping * pings[0]}


def markdown_table(result: BenchResult) -> str:
    """The result as Markdown tables."""
    lines = ["| setting | ms/ping | cells·ch/s | intensity error (dB) | predicted (dB) | max abs ΔCF "
             "| peak precision / recall | × NumPy | × numba |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in result.rows:
        lines.append(f"| {r.label} | {r.ms_per_ping:.0f} | {r.cells_ch_per_s:.2e} | {r.intensity_error_db:.1f} "
                     f"| {r.predicted_error_db:.1f} | {r.max_abs_dcf:.3f} | {r.peak_precision:.2f} / {r.peak_recall:.2f} "
                     f"| {r.x_numpy:.0f} | {r.x_numba:.1f} |")
    lines += ["", f"NumPy float64 reference: {result.numpy_cells_ch_per_s:.2e} cells·ch/s; "
                  f"numba parallel linear (float32, fastmath, hoisted geometry): "
                  f"{result.numba_cells_ch_per_s:.2e} cells·ch/s; PyLops Kirchhoff adjoint (linear, S only): "
                  f"{result.pylops_cells_ch_per_s:.2e} cells·ch/s.", "",
              "| skipping | ms/ping |", "|---|---:|"]
    lines += [f"| {s['what']} | {s['ms_per_ping']:.0f} |" for s in result.skipping]
    lines += ["", "Whole ping (raw → intensity, CF, peaks), ms: "
              + ", ".join(f"{k.replace('_s', '')} {v:.0f}" for k, v in result.whole_ping_ms.items()), "",
              "Where a ping's time goes (what bounds the whole-ping targets), ms: compress (pulse compression), "
              "beams (the sums on the beams), to grid (their interpolation to the grid, read back), flagged "
              "(cells imaged directly), smooth (the CF's smoothing), peaks (peaks, refinement, detection tests):", ""]
    lines += [f"- {s['what']}: " + ", ".join(f"{k.replace('_s', '').replace('_', ' ')} {v:.0f}"
                                              for k, v in s.get("stages_ms", {}).items()) for s in result.skipping]
    lines += ["",
              "Set-up: " + ", ".join(f"{k} {v}" for k, v in result.setup.items())]
    if result.command:
        c = result.command
        lines += ["", f"`clbeam image --peaks` on a {c['pings']}-ping file (a new process, image file written): "
                      f"{c['total_s']:.2f} s, {c['s_per_ping']:.2f} s per ping, start-up (launch to the first ping's "
                      f"work) {c['start_up_s']:.2f} s, one-time costs {c.get('one_time_s', float('nan')):.2f} s"]
    if result.zoo_commands:
        lines += ["", "`clbeam image --peaks` on the scene zoo (a 1- and a 5-ping file of each, after an untimed "
                      "1-ping run; the one-time costs hold the setting's measurement on the scene's geometry):", "",
                  "| scene | s per ping | one-time costs (s) | start-up (s) |", "|---|---:|---:|---:|"]
        lines += [f"| {name} | {c['s_per_ping']:.2f} | {c['one_time_s']:.2f} | {c['start_up_s']:.2f} |"
                  for name, c in result.zoo_commands.items()]
    targets = target_rows(result)
    if targets:
        lines += ["", "| target (paper grid) | measured | target | |", "|---|---:|---:|---|"]
        lines += [_target_line(*t) for t in targets]
    return "\n".join(lines) + "\n"


def target_rows(result: BenchResult) -> list[tuple[str, float, float, str]]:
    """The beam-sampling work's targets (paper grid) against this run: ``(what, measured, target, unit)``,
    a target met when the measurement is at most the target (at least, for the ``x`` ratios)."""
    auto = {r.budget_db: r for r in result.rows if np.isfinite(r.budget_db)}
    out = []
    if -40.0 in auto:
        r = auto[-40.0]
        out += [("default setting: beamforming", r.ms_per_ping, 250.0, "ms"),
                ("default setting: intensity error", r.intensity_error_db, -40.0, "dB"),
                ("default setting: max abs ΔCF", r.max_abs_dcf, 0.02, ""),
                ("default setting: x NumPy reference", r.x_numpy, 250.0, "x"),
                ("default setting: x numba baseline", r.x_numba, 10.0, "x")]
    if -60.0 in auto:
        out.append(("-60 dB setting: beamforming", auto[-60.0].ms_per_ping, 1000.0, "ms"))
    if result.whole_ping_ms:
        out.append(("whole ping, raw to refined peaks", result.whole_ping_ms.get("total_ms", np.nan), 500.0, "ms"))
    band = [s["ms_per_ping"] for s in result.skipping if s["what"].startswith("seabed band")]
    if band:
        out.append(("whole ping with the seabed band", band[0], 150.0, "ms"))
    if result.command:
        out += [("clbeam image, per ping", result.command["s_per_ping"], 0.7, "s"),
                ("clbeam image, launch to the first ping's work", result.command["start_up_s"], 0.5, "s")]
    if result.zoo_commands:
        worst = max(result.zoo_commands, key=lambda name: result.zoo_commands[name]["s_per_ping"])
        out.append((f"clbeam image, per ping, worst zoo scene ({worst})",
                    result.zoo_commands[worst]["s_per_ping"], 0.7, "s"))
    return out


def _target_line(what: str, got: float, target: float, unit: str) -> str:
    met = got >= target if unit == "x" else got <= target
    verdict = "met" if met else (f"not met: {got / target:.1f}x the target" if unit in ("ms", "s")
                                 else f"not met by {abs(got - target):.3g} {unit}".rstrip())
    return f"| {what} | {got:.3g} {unit} | {target:g} {unit} | {verdict} |".replace("  |", " |")


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
        if label.startswith("auto"):  # the same point as a beam row: a star and the budget below it
            ax.scatter(t, e, s=90, marker="*", color="tab:red", zorder=4)
            ax.annotate(label.split(":")[0], (t, e), textcoords="offset points", xytext=(4, -11), fontsize=7,
                        color="tab:red")
            continue
        ax.scatter(t, e, s=30, color="tab:green" if "beams" in label else "tab:blue", zorder=3)
        ax.annotate(label, (t, e), textcoords="offset points", xytext=(4, 3), fontsize=7)
    ax.plot(*zip(*front), color="tab:orange", lw=1.5, label="Pareto front", zorder=2)
    ax.set_xscale("log")
    ax.set_xlabel("time per ping on the paper grid (ms, log); green: beam-sampled")
    ax.set_ylabel("intensity error vs exact (dB)")
    ax.set_title("clbeam imaging settings: run time against error")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
