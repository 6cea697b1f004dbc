"""``clbeam peaks``: the coherence peaks of an image file as CSV."""

from __future__ import annotations

from clbeam.cli.options import add_min_snr_option
from clbeam.constants import PEAK_THRESHOLD

NAME = "peaks"
HELP = "coherence peaks of an image file"


def add_arguments(p) -> None:
    """The arguments of ``clbeam peaks``."""
    p.add_argument("images", metavar="IMAGES.nc", help="image file written by 'clbeam image'")
    p.add_argument("-o", "--output", required=True, metavar="PEAKS.csv", help="CSV file to write")
    p.add_argument("--threshold", type=float, default=PEAK_THRESHOLD,
                   help=f"threshold on smoothed CF (default {PEAK_THRESHOLD:g})")
    p.add_argument("--mlh", action="store_true",
                   help="merge the coherence peaks on one main-lobe arc into one detection (lobe-fitted position)")
    add_min_snr_option(p)


def run(args) -> int:
    """Find the peaks of every ping of the image file; write them as CSV."""
    from clbeam.imaging.peaks import peaks_from_images
    from clbeam.io.images import open_images
    from clbeam.io.paths import check_output_path
    from clbeam.io.peaks import write_peaks_csv

    check_output_path(args.output, args.images)
    ds = open_images(args.images)
    try:
        rows = peaks_from_images(ds, args.threshold, mlh=args.mlh, min_snr_db=args.min_snr_db,
                                 min_contrast_db=args.min_contrast_db)
    finally:
        ds.close()
    write_peaks_csv(rows, args.output)
    if not args.quiet:
        print(f"{len(rows)} coherence peak(s) above {args.threshold:g} -> {args.output}")
    return 0
