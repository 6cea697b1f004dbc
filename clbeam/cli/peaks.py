"""``clbeam peaks``: the coherence peaks of an image file as CSV."""

from __future__ import annotations

import logging
from pathlib import Path

from clbeam.cli.options import add_min_snr_option
from clbeam.constants import PEAK_THRESHOLD
from clbeam.errors import OptionError, require

log = logging.getLogger(__name__)

NAME = "peaks"
HELP = "coherence peaks of an image file"
DESCRIPTION = ("The coherence peaks of every ping of an image file, in the table 'clbeam image --peaks' and "
               "'clbeam survey' write (clbeam docs products). With --pings (the ping file the images were made "
               "from) each peak is moved to its echo as 'clbeam image' moves it, and the rows are image's; "
               "without it the rows are the grid cells' peaks, coarser (a node can sit half a range step off "
               "its echo and its intensity many dB below the echo's; several cells of one echo are several "
               "rows), with a warning.")


def add_arguments(p) -> None:
    """The arguments of ``clbeam peaks``."""
    p.add_argument("images", metavar="IMAGES.nc", help="image file written by 'clbeam image'")
    p.add_argument("-o", "--output", required=True, metavar="PEAKS.csv", help="CSV file to write")
    p.add_argument("--pings", metavar="PINGS.nc",
                   help="the ping file the images were made from: refine each peak to its echo, as 'clbeam image' "
                        "does (default: the grid cells' peaks, with a warning)")
    p.add_argument("--threshold", type=float, default=PEAK_THRESHOLD,
                   help=f"threshold on smoothed CF (default {PEAK_THRESHOLD:g})")
    p.add_argument("--mlh", action="store_true",
                   help="merge the coherence peaks on one main-lobe arc into one detection (lobe-fitted position; "
                        "not refined)")
    add_min_snr_option(p)


def _imager(ds, backend: str | None = None):
    """An imager on the image file's grid with the options its attributes record."""
    import numpy as np

    from clbeam.cli.options import parse_beams
    from clbeam.imaging.imager import Imager, ImagingOptions
    from clbeam.model.grid import PolarGrid

    a = ds.attrs
    upsample = a.get("upsample", "auto")
    opts = ImagingOptions(
        interp=str(a.get("interp", "auto")), upsample=None if upsample == "auto" else int(upsample),
        outputs=("intensity", "cf"), beams=parse_beams(str(a.get("beams", "auto"))),
        apodization=str(a.get("apodization", "rect")), calibrate=bool(int(a.get("calibrated", 1))),
        min_channels=float(a["min_channels"]) if "min_channels" in a else ImagingOptions.min_channels,
        sound_speed_m_s=float(np.nanmedian(ds["sound_speed"].values)) if "sound_speed" in ds.variables else None,
        **{k: float(a[k]) for k in ("max_error_db", "max_cf_error") if k in a})
    return Imager(PolarGrid(ds["range"].values, ds["angle"].values), opts, backend=backend or a.get("backend"))


def _refiner(args, ds, stack):
    """The :class:`~clbeam.imaging.peaks.PingFileRefiner` of ``--pings`` (``None`` without it, or with ``--mlh``)."""
    from clbeam.imaging.peaks import PingFileRefiner
    from clbeam.io.pingfile import PingFile

    if args.pings is None:
        if not args.mlh:
            log.warning("%s: no --pings: the rows are the grid cells' peaks, not refined to their echoes as "
                        "'clbeam image --peaks' gives them (positions to half a cell, intensities some dB low, "
                        "one row per cell of an echo)", Path(args.images).name)
        return None
    require(int(ds.attrs.get("stacked_pings", 1)) == 1, OptionError,
            f"--pings: {Path(args.images).name} holds stacked images (--stack "
            f"{ds.attrs.get('stacked_pings')}), whose peaks no single ping refines; leave --pings out")
    source = ds.attrs.get("source_file")
    if source is not None and source != Path(args.pings).name:
        log.warning("%s was imaged from %s, not %s", Path(args.images).name, source, Path(args.pings).name)
    if args.mlh:
        return None
    return PingFileRefiner(stack.enter_context(PingFile(args.pings)), _imager(ds))


def run(args) -> int:
    """Find the peaks of every ping of the image file; write them as CSV."""
    import contextlib

    from clbeam.imaging.peaks import option_columns, peaks_from_images
    from clbeam.io.images import open_images
    from clbeam.io.paths import check_output_path
    from clbeam.io.peaks import write_peaks_csv

    check_output_path(args.output, args.images)
    ds = open_images(args.images)
    try:
        require("cf" in ds.variables, OptionError,
                f"{Path(args.images).name} has no cf image, which the peaks are found on: image it with "
                "--outputs intensity,cf")
        with contextlib.ExitStack() as stack:
            refiner = _refiner(args, ds, stack)
            rows = peaks_from_images(ds, args.threshold, mlh=args.mlh, min_snr_db=args.min_snr_db,
                                     min_contrast_db=args.min_contrast_db, refiner=refiner)
    finally:
        ds.close()
    write_peaks_csv(rows, args.output, option_columns(refine=refiner is not None, mlh=args.mlh))
    if not args.quiet:
        print(f"{len(rows)} coherence peak(s) above {args.threshold:g}"
              f"{', refined to their echoes' if refiner is not None else ' (grid cells)'} -> {args.output}")
    return 0
