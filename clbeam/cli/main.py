"""The ``clbeam`` command line (SPEC §8): parse, call the library, report.

Every subcommand has ``--help``; bad input ends in one line on stderr and a
non-zero exit (2); long work shows a progress bar on a terminal (``--quiet``
turns it off).
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
import time
from pathlib import Path

from clbeam import __version__
from clbeam.errors import ClbeamError, OptionError, require

log = logging.getLogger("clbeam")

EXIT_BAD_INPUT = 2


def progress(iterable, *, total=None, desc="", quiet=False, unit="ping"):
    """A tqdm progress bar on a terminal, nothing otherwise or with ``quiet``."""
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, unit=unit, disable=quiet or not sys.stderr.isatty(),
                dynamic_ncols=True, leave=False)


# -- shared option groups ----------------------------------------------------
def add_grid_options(p: argparse.ArgumentParser) -> None:
    """Grid options of SPEC §8."""
    g = p.add_argument_group("grid")
    g.add_argument("--range-res", type=float, default=0.2, metavar="M", help="range step (m, default 0.2)")
    g.add_argument("--angle-res", type=float, default=0.1, metavar="DEG", help="angle step (degree, default 0.1)")
    g.add_argument("--max-range", type=float, default=None, metavar="M",
                   help="largest range (m, default: the end of the record)")
    g.add_argument("--min-range", type=float, default=0.0, metavar="M", help="smallest range (m, default 0)")
    g.add_argument("--angles", type=float, nargs=2, default=(-80.0, 80.0), metavar=("MIN", "MAX"),
                   help="angle window from nadir (degree, starboard positive, default -80 80)")


def add_engine_options(p: argparse.ArgumentParser) -> None:
    """Mode, outputs, backend and device options."""
    from clbeam.imaging.engine import INTERP_MODES

    g = p.add_argument_group("imaging")
    g.add_argument("--interp", default="cubic", choices=[m for m in INTERP_MODES],
                   help="interpolation mode (default cubic: see the README's run-time/error table); "
                        "'exact' runs on the reference backend only")
    g.add_argument("--upsample", type=int, default=1, metavar="N", help="FFT upsampling of the analytic signal (default 1)")
    g.add_argument("--outputs", default="intensity,cf", metavar="LIST",
                   help="comma-separated outputs: intensity, cf, sums (default intensity,cf)")
    g.add_argument("--backend", default="opencl", choices=["opencl", "reference"], help="imaging engine (default opencl)")
    g.add_argument("--device", default=None, help="OpenCL device: index or name substring (default: CLBEAM_DEVICE or the first)")
    g.add_argument("--precision", default="float32", choices=["float32", "float64"], help="kernel arithmetic (default float32)")
    g.add_argument("--sound-speed", type=float, default=None, metavar="M/S", help="override the file's sound speed (m/s)")
    g.add_argument("--threshold", type=float, default=0.25, help="coherence-peak threshold on smoothed CF (default 0.25)")
    g.add_argument("--seabed-band", type=float, nargs=2, default=None, metavar=("ABOVE", "BELOW"),
                   help="compute only cells from ABOVE m above to BELOW m below the seabed (e.g. 5 40)")
    g.add_argument("--seabed-depth", type=float, default=None, metavar="M",
                   help="seabed depth below the transducers for --seabed-band (default: picked per ping)")
    g.add_argument("--apodization", default="rect", metavar="WINDOW",
                   help="receive window across the array: rect, hann, tukey[:alpha], chebyshev[:dB] "
                        "(default rect; CF becomes the weighted CF)")
    g.add_argument("--isospeed", action="store_true",
                   help="straight rays at the file's sound speed even when it has a sound-speed profile (svp_*)")
    g.add_argument("--sediment-speed", type=float, default=None, metavar="M/S",
                   help="sediment interval velocity below the seabed (m/s): rays refract at the seabed "
                        "(--seabed-depth, else picked per ping)")
    g.add_argument("--mlh", action="store_true",
                   help="merge the coherence peaks on one main-lobe arc into one detection (lobe-fitted position)")
    g.add_argument("--no-calibration", action="store_true",
                   help="ignore the file's element_gain_db / element_phase_deg (default: remove them)")


def options_from_args(args):
    """:class:`~clbeam.imaging.imager.ImagingOptions` from parsed arguments."""
    from clbeam.imaging.imager import ImagingOptions

    outputs = tuple(s.strip() for s in args.outputs.split(",") if s.strip())
    return ImagingOptions(interp=args.interp, upsample=args.upsample, outputs=outputs, threshold=args.threshold,
                          sound_speed_m_s=args.sound_speed, precision=args.precision,
                          seabed_band_m=tuple(args.seabed_band) if args.seabed_band else None,
                          seabed_depth_m=args.seabed_depth, apodization=args.apodization,
                          calibrate=not args.no_calibration, mlh=args.mlh, use_svp=not args.isospeed,
                          sediment_speed_m_s=args.sediment_speed)


def grid_from_args(args, max_range_default: float):
    """:class:`~clbeam.model.grid.PolarGrid` from parsed arguments."""
    from clbeam.model.grid import PolarGrid

    return PolarGrid.regular(range_res_m=args.range_res, angle_res_deg=args.angle_res,
                             max_range_m=args.max_range if args.max_range is not None else max_range_default,
                             min_range_m=args.min_range, angles_deg=tuple(args.angles))


def check_output_path(output, *inputs) -> None:
    """Refuse an output that is one of the inputs or an existing folder
    (other than a Zarr store), before anything is written or removed."""
    out = Path(output)
    for inp in inputs:
        require(not (out.exists() and Path(inp).exists() and out.resolve() == Path(inp).resolve()), OptionError,
                f"output {out} is the input file; choose another name")
    require(not (out.is_dir() and out.suffix != ".zarr"), OptionError,
            f"output {out} is an existing folder; give a file name")
    require(out.parent.exists() or str(out.parent) == "", OptionError, f"output folder {out.parent} does not exist")


def remove_partial(path: Path) -> None:
    """Delete an output file or Zarr folder left incomplete by an error."""
    import shutil

    if path.is_dir():
        shutil.rmtree(path, ignore_errors=True)
    elif path.exists():
        path.unlink()


# -- subcommands -------------------------------------------------------------
def cmd_devices(args) -> int:
    from clbeam.imaging.engine.opencl import device_has_fp64, list_devices

    devices = list_devices()
    if not devices:
        print("no OpenCL device found; install an OpenCL driver (Debian: apt-get install pocl-opencl-icd) "
              "or use --backend reference")
        return 1
    for i, d in enumerate(devices):
        print(f"[{i}] {d.name.strip()}  platform: {d.platform.name.strip()}  "
              f"compute units: {d.max_compute_units}  memory: {d.global_mem_size / 2**30:.1f} GiB  "
              f"max alloc: {d.max_mem_alloc_size / 2**30:.1f} GiB  fp64: {'yes' if device_has_fp64(d) else 'no'}")
    return 0


def cmd_image(args) -> int:
    from clbeam.imaging.imager import Imager
    from clbeam.io.images import ImageWriter
    from clbeam.io.peaks import write_peaks_csv
    from clbeam.io.pingfile import PingFile
    from clbeam.io.schema import image_variables

    opts = options_from_args(args)
    check_output_path(args.output, args.pings)
    if args.peaks:
        check_output_path(args.peaks, args.pings)
    if args.backend == "opencl":
        from clbeam.imaging.engine import interp_mode

        require(interp_mode(opts.interp).kernel_id >= 0, OptionError,
                f"interpolation mode '{opts.interp}' exists in the reference backend only; add --backend reference")
    require(args.stack >= 1, OptionError, f"--stack must be >= 1 ping, got {args.stack}")
    require(args.stack == 1 or "cf" in opts.outputs, OptionError, "--stack needs the cf output")
    with PingFile(args.pings) as pings:
        grid = grid_from_args(args, pings.max_record_range_m())
        variables = image_variables(opts.outputs, apodized=opts.apodization != "rect")
        stack = None
        if args.stack > 1:
            from clbeam.imaging.stacking import PingStack, stacked_ping_image

            stack = PingStack(args.stack, opts.threshold)
            opts = dataclasses.replace(opts, outputs=tuple(set(opts.outputs) | {"intensity", "sums"}))
        imager = Imager(grid, opts, backend=args.backend, device=args.device)
        attrs = {"interp": opts.interp, "upsample": opts.upsample, "backend": args.backend,
                 "apodization": opts.apodization, "calibrated": int(opts.calibrate), "stacked_pings": args.stack,
                 "source_file": Path(args.pings).name, "clbeam_version": __version__}
        peaks = []
        t0 = time.perf_counter()
        created = False
        try:
            with ImageWriter(args.output, grid, len(pings), variables, attrs) as writer:
                created = True
                for ping in progress(pings, total=len(pings), desc="imaging", quiet=args.quiet):
                    img = imager.image(ping)
                    if stack is not None:
                        img = stacked_ping_image(
                            img, stack.add(img), keep_sums="s_r" in variables,
                            peak_rows=lambda cf, inten, ping=ping, img=img: imager.peak_rows(ping, cf, inten,
                                                                                              img.source_yz_m))
                    writer.write(ping.index, img, latitude=ping.latitude_deg, longitude=ping.longitude_deg,
                                 heading=ping.heading_deg)
                    peaks.extend(img.peaks)
        except BaseException:
            if created:
                remove_partial(Path(args.output))  # no half-written image file left behind
            raise
        if args.peaks:
            write_peaks_csv(peaks, args.peaks)
    dt = time.perf_counter() - t0
    if not args.quiet:
        print(f"imaged {len(pings)} ping(s) on a {grid.shape[0]} x {grid.shape[1]} grid in {dt:.1f} s "
              f"({dt / max(len(pings), 1):.2f} s/ping) -> {args.output}" + (f"; {len(peaks)} peaks -> {args.peaks}" if args.peaks else ""))
    return 0


def cmd_peaks(args) -> int:
    from clbeam.imaging.postprocess import peaks_from_images
    from clbeam.io.images import open_images
    from clbeam.io.peaks import write_peaks_csv

    ds = open_images(args.images)
    try:
        rows = peaks_from_images(ds, args.threshold)
    finally:
        ds.close()
    write_peaks_csv(rows, args.output)
    if not args.quiet:
        print(f"{len(rows)} coherence peak(s) above {args.threshold:g} -> {args.output}")
    return 0


# -- parser ------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    """The ``clbeam`` argument parser with every subcommand."""
    p = argparse.ArgumentParser(prog="clbeam", description="Cross-track imaging of multibeam sub-bottom sonar element data.")
    p.add_argument("--version", action="version", version=f"clbeam {__version__}")
    p.add_argument("--debug", action="store_true", help="show full tracebacks and debug logging")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    def common(sp):
        sp.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")

    sp = sub.add_parser("devices", help="list the OpenCL platforms and devices found")
    sp.set_defaults(func=cmd_devices)

    sp = sub.add_parser("image", help="image a ping file into intensity and coherence factor")
    sp.add_argument("pings", metavar="PINGS.nc", help="ping file (NetCDF4 or Zarr, SPEC §7)")
    sp.add_argument("-o", "--output", required=True, metavar="IMAGES.nc", help="image file to write (.nc or .zarr)")
    sp.add_argument("--peaks", metavar="PEAKS.csv", help="also write the coherence peaks")
    sp.add_argument("--stack", type=int, default=1, metavar="K",
                    help="stack each ping with the K-1 before it: mean intensity, CF from the summed sums "
                         "(default 1: no stacking)")
    add_grid_options(sp)
    add_engine_options(sp)
    common(sp)
    sp.set_defaults(func=cmd_image)

    sp = sub.add_parser("peaks", help="coherence peaks of an image file")
    sp.add_argument("images", metavar="IMAGES.nc", help="image file written by 'clbeam image'")
    sp.add_argument("-o", "--output", required=True, metavar="PEAKS.csv", help="CSV file to write")
    sp.add_argument("--threshold", type=float, default=0.25, help="threshold on smoothed CF (default 0.25)")
    common(sp)
    sp.set_defaults(func=cmd_peaks)

    for register in _plugins():
        register(sub, common)
    return p


def _plugins():
    """Subcommands defined beside their modules (simulate, demo, forward …)."""
    from clbeam.cli import commands

    return commands.REGISTRARS


def main(argv=None) -> int:
    """Entry point of the ``clbeam`` command; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.debug else logging.WARNING,
                        format="clbeam: %(levelname)s: %(message)s")
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    try:
        return int(args.func(args) or 0)
    except ClbeamError as exc:
        print(f"clbeam: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("clbeam: interrupted", file=sys.stderr)
        return 130
    except (OSError, MemoryError) as exc:
        if args.debug:
            raise
        print(f"clbeam: error: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    except Exception as exc:  # a bug: one line, the traceback with --debug
        if args.debug:
            raise
        print(f"clbeam: internal error: {type(exc).__name__}: {exc} (rerun with --debug for the traceback)",
              file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
