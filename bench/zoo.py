"""Run time against error on a zoo of scenes: each setting's worst error over the zoo beside its time.

    python bench/zoo.py -o OUT [--skip-command]

Five scenes on the paper's grid (0.2 m x 0.1 degree, 0-1100 m, +-80 degrees), described in
:mod:`clbeam.evaluation.zoo` (the bench's Line 4 ping, a jittered rolled array with a source offset, a jump in
the sound speed, noise-free points, the clutter scene); their point echoes are built there independently
of the imaging code.  Every setting images the whole grid (so its beams are those of a real
image) and is compared, on windows of +-8 degrees and +-2.4 m around each point, with the float64
reference's 64-tap windowed-sinc interpolation of the same channels and travel times: intensity error
(error energy over signal energy on cells within 40 dB of each window's maximum), the largest |dCF| on
those cells, and the CF at the points on nodes.  Times are one ``engine.beamform`` of the bench ping
(intensity and CF, read back), best of two, in one run.  Unless ``--skip-command``, ``clbeam image``
(image file written, refined peaks) is timed as a whole on a five-ping file of every scene: (t5 - t1) / 4
from a one-ping and a five-ping run, after an untimed one-ping run (:func:`clbeam.evaluation.zoo.zoo_command_times`,
as ``clbeam bench`` times it).

Writes ``OUT/zoo.md`` (the tables) and ``OUT/zoo.png`` (worst error against time).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from clbeam.evaluation.zoo import zoo, zoo_command_times

DYNAMIC_RANGE_DB = 40.0
#: the settings every scene is measured with besides its own auto choice: (mode, upsampling, beams)
SETTINGS = (("lanczos4", 1, (1.5, 8)), ("lanczos4", 1, (2.0, 12)), ("lanczos8", 1, (2.0, 16)),
            ("cubic", 2, (2.0, 12)), ("cubic", 2, None), ("lanczos4", 1, None), ("lanczos8", 1, None))


def _windows(grid, spec):
    """``(angle slice, range slice, on node)`` of the grid around each point, or of a window grid."""
    from clbeam.model.grid import PolarGrid

    if isinstance(spec, PolarGrid):
        ia = np.searchsorted(grid.angles_deg, spec.angles_deg[[0, -1]] - 1e-9)
        ir = np.searchsorted(grid.ranges_m, spec.ranges_m[[0, -1]] - 1e-9)
        return [(slice(ia[0], ia[1] + 1), slice(ir[0], ir[1] + 1), False)]
    out = []
    for r, a, node in spec:
        ia = int(np.argmin(np.abs(grid.angles_deg - a)))
        ir = int(np.argmin(np.abs(grid.ranges_m - r)))
        out.append((slice(max(ia - 80, 0), ia + 81), slice(max(ir - 12, 0), ir + 13), node))
    return out


def measure_scene(name, ping, spec, grid, engine, settings) -> dict:
    """Each setting's (intensity error dB, max |dCF|, CF on a node) on the scene, and its auto setting."""
    from clbeam.imaging.budget import intensity_error_db
    from clbeam.imaging.engine import get_engine
    from clbeam.imaging.engine.beams import BeamSampling
    from clbeam.imaging.imager import Imager, ImagingOptions
    from clbeam.model.grid import PolarGrid

    auto = Imager(grid, ImagingOptions(), engine=engine).setting_of(ping)
    reference = get_engine("reference")
    # the exact image once per window, from the channels as recorded (an upsampled copy is the same signal)
    recorded = Imager(grid, ImagingOptions(interp="lanczos4", upsample=1, beams=None), engine=engine).beamform_input(ping)
    windows = _windows(grid, spec)
    exacts = [reference.beamform(recorded.for_grid(w), w, interp="exact", outputs=("intensity", "cf"))
              for w in (PolarGrid.beams(grid.ranges_m[sr], grid.angles_deg[sa]) for sa, sr, _ in windows)]
    rows = {}
    auto_spec = (auto.interp, auto.upsample, None if auto.beams is None else (auto.beams.oversampling, auto.beams.taps))
    for label, (interp, up, beams) in [("auto: " + auto.describe().split(":")[0], auto_spec)] + \
            [(_label(s), s) for s in settings]:
        sampling = None if beams is None else BeamSampling(*beams)
        imager = Imager(grid, ImagingOptions(interp=interp, upsample=up, beams=sampling, refine_peaks=False),
                        engine=engine)
        inp = imager.beamform_input(ping)
        got = engine.beamform(inp, grid, interp=interp, outputs=("intensity", "cf"), beams=sampling)
        errs, dcfs, node_cf = [], [], [1.0]
        for (sa, sr, node), exact in zip(windows, exacts):
            keep = exact.intensity >= exact.intensity.max() * 10 ** (-DYNAMIC_RANGE_DB / 10)
            errs.append(intensity_error_db(got.intensity[sa, sr].astype(np.float64), exact.intensity, DYNAMIC_RANGE_DB))
            dcfs.append(float(np.max(np.abs(got.cf[sa, sr][keep] - exact.cf[keep]))))
            if node:
                ja, jr = np.unravel_index(np.argmax(exact.intensity), exact.intensity.shape)
                node_cf.append(float(got.cf[sa, sr][ja, jr]))
        rows[label] = (max(errs), max(dcfs), min(node_cf))
        print(f"  {name:9s} {label:32s} {max(errs):7.1f} dB  |dCF| {max(dcfs):.3f}  node CF {min(node_cf):.4f}",
              flush=True)
    return {"auto": auto.describe(), "rows": rows}


def _label(setting) -> str:
    interp, up, beams = setting
    up_s = f" x{up}" if up > 1 else ""
    return f"{interp}{up_s} " + (f"beams x{beams[0]:g}/{beams[1]}" if beams else "direct")


def time_settings(ping, grid, engine, settings) -> dict:
    """ms of one engine.beamform of ``ping`` per setting (best of two)."""
    from clbeam.imaging.engine.beams import BeamSampling
    from clbeam.imaging.imager import Imager, ImagingOptions

    out = {}
    for s in settings:
        interp, up, beams = s
        sampling = None if beams is None else BeamSampling(*beams)
        inp = Imager(grid, ImagingOptions(interp=interp, upsample=up, beams=sampling, use_svp=False),
                     engine=engine).beamform_input(ping)
        best = np.inf
        for _ in range(2):
            t = time.perf_counter()
            engine.beamform(inp, grid, interp=interp, outputs=("intensity", "cf"), beams=sampling)
            best = min(best, time.perf_counter() - t)
        out[_label(s)] = 1000 * best
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("-o", "--output", required=True, help="output folder")
    parser.add_argument("--skip-command", action="store_true", help="do not time clbeam image as a whole")
    parser.add_argument("--auto-only", action="store_true", help="measure each scene's auto setting only")
    args = parser.parse_args(argv)
    from clbeam.evaluation.bench import paper_grid
    from clbeam.imaging.engine import get_engine

    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    grid = paper_grid()
    engine = get_engine("opencl")
    scenes = zoo(grid)
    settings = () if args.auto_only else SETTINGS
    results = {name: measure_scene(name, ping, spec, grid, engine, settings) for name, (ping, spec) in scenes.items()}
    times = time_settings(scenes["bench"][0], grid, engine, settings)
    commands = {}
    if not args.skip_command:
        with tempfile.TemporaryDirectory() as tmp:
            commands = {name: c["s_per_ping"] for name, c in zoo_command_times(tmp).items()}
    (out / "zoo.md").write_text(_markdown(results, times, commands))
    _plot(results, times, out / "zoo.png")
    print((out / "zoo.md").read_text())
    return 0


def _markdown(results, times, commands) -> str:
    names = list(results)
    lines = ["| setting | ms/ping (bench ping) | worst intensity error (dB) | worst max abs dCF | lowest CF on a node |",
             "|---|---:|---:|---:|---:|"]
    for label, ms in times.items():
        worst = [results[n]["rows"][label] for n in names]
        lines.append(f"| {label} | {ms:.0f} | {max(w[0] for w in worst):.1f} | {max(w[1] for w in worst):.3f} "
                     f"| {min(w[2] for w in worst):.4f} |")
    lines += ["", "| scene | auto setting | intensity error (dB) | max abs dCF | CF on a node | clbeam image s/ping |",
              "|---|---|---:|---:|---:|---:|"]
    for n in names:
        label = next(k for k in results[n]["rows"] if k.startswith("auto"))
        e, d, c = results[n]["rows"][label]
        cmd = f"{commands[n]:.2f}" if n in commands else "-"
        lines.append(f"| {n} | {results[n]['auto']} | {e:.1f} | {d:.3f} | {c:.4f} | {cmd} |")
    return "\n".join(lines) + "\n"


def _plot(results, times, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for label, ms in times.items():
        worst = [results[n]["rows"][label] for n in results]
        ax[0].scatter(ms, max(w[0] for w in worst))
        ax[1].scatter(ms, max(w[1] for w in worst))
        for a, v in ((ax[0], max(w[0] for w in worst)), (ax[1], max(w[1] for w in worst))):
            a.annotate(label, (ms, v), fontsize=7)
    ax[0].axhline(-40, color="r", lw=0.8)
    ax[1].axhline(0.02, color="r", lw=0.8)
    ax[0].set(xlabel="ms per ping (bench ping)", ylabel="worst intensity error over the zoo (dB)")
    ax[1].set(xlabel="ms per ping (bench ping)", ylabel="worst max |dCF| over the zoo", yscale="log")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    raise SystemExit(main())
