"""``clbeam image``: a ping file into intensity and coherence-factor images (docs/cli.md)."""

from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path

from clbeam.cli.options import (
    add_compression_options,
    add_grid_options,
    add_imaging_options,
    compression_from_args,
    grid_from_args,
    options_from_args,
    progress,
    remove_partial,
    requested_outputs,
)
from clbeam.errors import OptionError, require
from clbeam.io.paths import check_output_path

log = logging.getLogger(__name__)

NAME = "image"
HELP = "image a ping file into intensity and coherence factor"


def add_arguments(p) -> None:
    """The arguments of ``clbeam image``."""
    p.add_argument("pings", metavar="PINGS.nc", help="ping file (NetCDF4 or Zarr; see clbeam docs ping-format)")
    p.add_argument("-o", "--output", required=True, metavar="IMAGES.nc", help="image file to write (.nc or .zarr)")
    p.add_argument("--peaks", metavar="PEAKS.csv", help="also write the coherence peaks")
    p.add_argument("--stack", type=int, default=1, metavar="K",
                   help="stack each ping with the K-1 before it: mean intensity, CF from the summed sums "
                        "(default 1: no stacking)")
    add_grid_options(p)
    add_imaging_options(p)
    add_compression_options(p)


def _check(args, opts) -> None:
    """Every option checked before a file is opened or written."""
    check_output_path(args.output, args.pings)
    if args.peaks:
        check_output_path(args.peaks, args.pings)
        require("cf" in opts.outputs, OptionError,
                f"--peaks needs the cf output (the peaks are found on the smoothed CF), got --outputs {args.outputs}")
    require(args.stack >= 1, OptionError, f"--stack must be >= 1 ping, got {args.stack}")
    require(args.stack == 1 or "cf" in opts.outputs, OptionError, "--stack needs the cf output")


def _image_pings(pings, imager, writer, stack, keep_sums: bool, quiet: bool) -> list:
    """Image every ping into ``writer``; the peak rows of all pings."""
    from clbeam.imaging.stacking import stacked_ping_image

    peaks = []
    log.debug("first ping's work starts at unix time %.3f s", time.time())  # the bench's start-up measure
    for ping in progress(pings, total=len(pings), desc="imaging", quiet=quiet):
        img = imager.image(ping)
        if stack is not None:
            img = stacked_ping_image(img, stack.add(img), keep_sums=keep_sums, peak_rows=imager.peak_row_builder(img))
        writer.write(ping.index, img)
        peaks.extend(img.peaks)
    return peaks


def run(args) -> int:
    """Image every ping of the file; write the images (and the peaks)."""
    from clbeam import __version__
    from clbeam.imaging.imager import Imager
    from clbeam.imaging.peaks import option_columns
    from clbeam.imaging.stacking import PingStack
    from clbeam.io.images import ImageWriter
    from clbeam.io.peaks import write_peaks_csv
    from clbeam.io.pingfile import PingFile
    from clbeam.io.schema import image_variables

    opts = options_from_args(args)
    _check(args, opts)
    with PingFile(args.pings) as pings:
        grid = grid_from_args(args, pings.max_record_range_m())
        variables = image_variables(requested_outputs(args), apodized=opts.apodization != "rect")
        stack = None
        if args.stack > 1:
            stack = PingStack(args.stack, opts.threshold, opts.min_channels)
            opts = dataclasses.replace(opts, outputs=tuple(set(opts.outputs) | {"intensity", "sums"}))
        imager = Imager(grid, opts, backend=args.backend, device=args.device)
        attrs = {"interp": opts.interp, "upsample": opts.upsample or "auto", "beams": args.beams,
                 "max_error_db": opts.max_error_db, "max_cf_error": opts.max_cf_error, "backend": args.backend,
                 "apodization": opts.apodization, "calibrated": int(opts.calibrate), "stacked_pings": args.stack,
                 "min_channels": opts.min_channels, "threshold": opts.threshold,
                 "min_snr_db": "off" if opts.min_snr_db is None else opts.min_snr_db,
                 "min_contrast_db": "off" if opts.min_contrast_db is None else opts.min_contrast_db,
                 "source_file": Path(args.pings).name, "clbeam_version": __version__}
        t0 = time.perf_counter()
        out = Path(args.output)
        writer = ImageWriter(out, grid, len(pings), variables, attrs, background=True,
                             compression=compression_from_args(args))
        try:
            with writer:
                peaks = _image_pings(pings, imager, writer, stack, "s_r" in variables, args.quiet)
        except BaseException:
            remove_partial(out)  # no half-written image file left behind
            raise
        if args.peaks:
            write_peaks_csv(peaks, args.peaks, option_columns(refine=opts.refine_peaks and stack is None,
                                                              mlh=opts.mlh))
    dt = time.perf_counter() - t0
    if not args.quiet:
        print(f"imaged {len(pings)} ping(s) on a {grid.shape[0]} x {grid.shape[1]} grid in {dt:.1f} s "
              f"({dt / max(len(pings), 1):.2f} s/ping) -> {args.output}"
              + (f"; {len(peaks)} peaks -> {args.peaks}" if args.peaks else ""))
    return 0
