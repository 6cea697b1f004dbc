"""``clbeam avo IMAGES.nc -o AVO.csv``: angular responses, patches, attributes, inversion.

The command chains :func:`clbeam.seabed.avo.response.angular_responses`,
:func:`clbeam.seabed.avo.stack.stack_sides`, :func:`clbeam.seabed.avo.table.survey_records`
and :func:`clbeam.seabed.avo.table.write_csv`; with ``--figures DIR`` it also draws
the stacked responses of the first and last patch with their attributes,
the gradient–intercept crossplot with the background trend, and the
attributes and inverted grain size along the track
(:func:`clbeam.seabed.avo.plot.write_figures`).
"""

from __future__ import annotations

import time

from clbeam.cli.options import progress
from clbeam.constants import (
    SBP29_ARRAY_WIDTH_M,
    SBP29_BAND_HZ,
    SBP29_CENTRE_FREQUENCY_HZ,
    SBP29_TX_LENGTH_M,
    SOUND_SPEED_M_S,
)
from clbeam.errors import OptionError, require
from clbeam.io.paths import check_output_path
from clbeam.seabed.avo.stack import DEFAULT_PINGS_PER_PATCH

NAME = "avo"
HELP = "AVO analysis: angular responses from an image file, patches, attributes, inversion for grain size (SPEC §5)"


def options_from_args(args):
    """The :class:`~clbeam.seabed.avo.response.ResponseOptions` of the parsed command line."""
    from clbeam.seabed.avo.response import ResponseOptions

    return ResponseOptions(frequency_hz=args.frequency, bandwidth_hz=args.bandwidth,
                           sound_speed_m_s=args.sound_speed, tx_length_m=args.tx_length,
                           rx_width_m=args.rx_width, absorption_db_per_km=args.absorption,
                           calibration_db=args.calibration_db)


def run(args) -> int:
    """Run ``clbeam avo``; returns the exit status."""
    from clbeam.seabed.avo.plot import write_figures
    from clbeam.seabed.avo.response import DEFAULT_INCIDENCE_DEG, angular_responses
    from clbeam.seabed.avo.stack import stack_sides
    from clbeam.seabed.avo.table import survey_records, write_csv

    t0 = time.perf_counter()
    require(args.pings_per_patch >= 1, OptionError,
            f"--pings-per-patch must be >= 1, got {args.pings_per_patch}")
    require(args.ping_spacing > 0, OptionError, f"--ping-spacing must be > 0 m, got {args.ping_spacing}")
    out = check_output_path(args.output, args.images, what="AVO table")
    opts = options_from_args(args)
    resp = angular_responses(args.images, DEFAULT_INCIDENCE_DEG, opts, ping_spacing_m=args.ping_spacing)
    n = resp.port_db.shape[0]
    patches = stack_sides(resp.incidence_deg, resp.port_db, resp.starboard_db,
                          pings_per_patch=args.pings_per_patch, along_track_m=resp.along_track_m)
    if args.no_invert:
        rows = survey_records(patches, invert=False)
    else:
        rows = survey_records(patches, frequency_hz=opts.frequency_hz,
                              sound_speed_water_m_s=opts.sound_speed_m_s)
    if args.pings:
        rows = _with_nadir_reflection(rows, args)
    write_csv(out, rows)
    figs = write_figures(args.figures, patches, rows, frequency_hz=opts.frequency_hz,
                         sound_speed_m_s=opts.sound_speed_m_s) if args.figures else []
    if not args.quiet:
        partial = "" if n % args.pings_per_patch == 0 else \
            f" (last patch of {n % args.pings_per_patch} ping(s))"
        print(f"{n} ping(s) -> {len(patches)} patches{partial} -> {out}"
              + (f"; {len(figs)} figures -> {args.figures}" if figs else "")
              + f" in {time.perf_counter() - t0:.1f} s")
    return 0


def _with_nadir_reflection(rows: list, args) -> list:
    """The rows with each patch's nadir reflection coefficient from the ping file ``--pings``."""
    import dataclasses

    from clbeam.seabed.nadir import patch_reflections

    ranges = sorted({(r.ping_start, r.ping_stop) for r in rows})
    bar = progress(None, total=sum(b - a for a, b in ranges), desc="nadir", quiet=args.quiet)
    try:
        found = dict(zip(ranges, patch_reflections(args.pings, ranges, bandwidth_hz=args.bandwidth,
                                                    progress=bar.update)))
    finally:
        bar.close()
    return [dataclasses.replace(r, nadir_reflection=found[r.ping_start, r.ping_stop][0],
                                nadir_reflection_error=found[r.ping_start, r.ping_stop][1],
                                nadir_calibration_db=found[r.ping_start, r.ping_stop][2]) for r in rows]


def add_arguments(p) -> None:
    """The arguments of ``clbeam avo``."""
    p.add_argument("images", metavar="IMAGES.nc", help="image file written by 'clbeam image' (with intensity)")
    p.add_argument("-o", "--output", required=True, metavar="AVO.csv", help="per-patch table to write")
    p.add_argument("--pings-per-patch", type=int, default=DEFAULT_PINGS_PER_PATCH, metavar="N",
                   help=f"consecutive pings stacked per patch and side (default {DEFAULT_PINGS_PER_PATCH}; "
                        "a last, shorter patch is kept)")
    p.add_argument("--frequency", type=float, default=SBP29_CENTRE_FREQUENCY_HZ, metavar="HZ",
                   help=f"band centre (Hz, default {SBP29_CENTRE_FREQUENCY_HZ:g}: the SBP29's 2-9 kHz sweep)")
    p.add_argument("--bandwidth", type=float, default=SBP29_BAND_HZ[1] - SBP29_BAND_HZ[0], metavar="HZ",
                   help="pulse bandwidth (Hz, default 7000); compressed pulse 1/bandwidth")
    p.add_argument("--sound-speed", type=float, default=SOUND_SPEED_M_S, metavar="M/S",
                   help=f"water sound speed (default {SOUND_SPEED_M_S:g})")
    p.add_argument("--tx-length", type=float, default=SBP29_TX_LENGTH_M, metavar="M",
                   help="along-track length of the transmit column (m, default 3.5)")
    p.add_argument("--rx-width", type=float, default=SBP29_ARRAY_WIDTH_M, metavar="M",
                   help=f"across-track width of the receive array (m, default {SBP29_ARRAY_WIDTH_M:g})")
    p.add_argument("--absorption", type=float, default=None, metavar="DB/KM",
                   help="water absorption (dB/km; default Francois-Garrison at the band centre, 10 °C, 35 PSU)")
    p.add_argument("--calibration-db", type=float, default=0.0, metavar="DB",
                   help="added to every strength (dB; default 0: strengths relative to an unknown constant)")
    p.add_argument("--ping-spacing", type=float, default=1.0, metavar="M",
                   help="along-track ping spacing used when the file has no navigation (m, default 1)")
    p.add_argument("--no-invert", action="store_true", help="attributes only, no model inversion")
    p.add_argument("--pings", default=None, metavar="PINGS.nc",
                   help="the ping file the images were made from: adds each patch's nadir reflection coefficient "
                        "from the seabed echo and its surface multiple, and the calibration it gives (reported, "
                        "not applied; docs/avo.md)")
    p.add_argument("--figures", default=None, metavar="DIR", help="also draw the AVO figures (PNG) into DIR")
