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

import logging
import time
from pathlib import Path

from clbeam.cli.options import progress
from clbeam.constants import (
    AVO_PINGS_PER_PATCH,
    SBP29_ARRAY_WIDTH_M,
    SBP29_BAND_HZ,
    SBP29_CENTRE_FREQUENCY_HZ,
    SBP29_TX_LENGTH_M,
    SOUND_SPEED_M_S,
)
from clbeam.errors import OptionError, require
from clbeam.io.paths import check_output_path

log = logging.getLogger(__name__)

NAME = "avo"
HELP = "AVO analysis: angular responses from an image file, patches, attributes, inversion for grain size (see clbeam docs avo)"


def options_from_args(args):
    """The :class:`~clbeam.seabed.avo.response.ResponseOptions` of the parsed command line."""
    from clbeam.seabed.avo.response import ResponseOptions

    return ResponseOptions(frequency_hz=args.frequency, bandwidth_hz=args.bandwidth,
                           sound_speed_m_s=args.sound_speed, tx_length_m=args.tx_length,
                           rx_width_m=args.rx_width, absorption_db_per_km=args.absorption,
                           calibration_db=args.calibration_db or 0.0)


def run(args) -> int:
    """Run ``clbeam avo``; returns the exit status."""
    import dataclasses

    from clbeam.seabed.avo.plot import write_figures
    from clbeam.seabed.avo.response import DEFAULT_INCIDENCE_DEG, angular_responses
    from clbeam.seabed.avo.stack import stack_sides
    from clbeam.seabed.avo.table import survey_records, write_csv

    t0 = time.perf_counter()
    require(args.pings_per_patch >= 1, OptionError,
            f"--pings-per-patch must be >= 1, got {args.pings_per_patch}")
    require(args.ping_spacing > 0, OptionError, f"--ping-spacing must be > 0 m, got {args.ping_spacing}")
    require(not (args.pings and args.no_nadir), OptionError, "--pings and --no-nadir contradict each other")
    out = check_output_path(args.output, args.images, what="AVO table")
    opts = options_from_args(args)
    resp = angular_responses(args.images, DEFAULT_INCIDENCE_DEG, opts, ping_spacing_m=args.ping_spacing)
    n = resp.port_db.shape[0]
    patches = stack_sides(resp.incidence_deg, resp.port_db, resp.starboard_db,
                          pings_per_patch=args.pings_per_patch, along_track_m=resp.along_track_m)
    attrs = _image_attributes(args.images)
    pings = args.pings or (None if args.no_nadir else _pings_beside(args.images, attrs))
    nadir = _nadir_reflections(patches, pings, args, opts.absorption_db_per_m * 1000) if pings else {}
    cal = _calibration(nadir, args, attrs)
    if cal.source == "nadir":  # the option's calibration is in the strengths already
        patches = [dataclasses.replace(p, strength_db=p.strength_db + cal.db) for p in patches]
    rows = survey_records(patches, frequency_hz=opts.frequency_hz, invert=not args.no_invert, nadir=nadir,
                          calibration=cal, sound_speed_water_m_s=opts.sound_speed_m_s)
    write_csv(out, rows)
    figs = write_figures(args.figures, patches, rows, frequency_hz=opts.frequency_hz,
                         sound_speed_m_s=opts.sound_speed_m_s) if args.figures else []
    if not args.quiet:
        partial = "" if n % args.pings_per_patch == 0 else \
            f" (last patch of {n % args.pings_per_patch} ping(s))"
        print(f"{n} ping(s) -> {len(patches)} patches{partial}; {_calibration_text(cal)} -> {out}"
              + (f"; {len(figs)} figures -> {args.figures}" if figs else "")
              + f" in {time.perf_counter() - t0:.1f} s")
    return 0


def _image_attributes(images) -> dict:
    """The image file's global attributes."""
    from clbeam.io.images import open_images

    with open_images(images) as ds:
        return dict(ds.attrs)


def _pings_beside(images, attrs: dict) -> Path | None:
    """The ping file the images were made from (their ``source_file`` attribute), when it lies beside them."""
    name = attrs.get("source_file")
    path = Path(images).parent / str(name) if name else None
    if path is None or not path.exists():
        return None
    log.warning("nadir calibration from %s, the ping file beside the images (--no-nadir to skip)", path.name)
    return path


def _calibration_blocked(attrs: dict) -> str:
    """Why the nadir calibration does not fit these images ("" when it does): it is for single-ping images of
    channel-calibrated data summed without weights (``-20 log10(M G)``)."""
    found = [f"{k} {attrs[k]}" for k, ok in (("apodization", "rect"), ("calibrated", "1"), ("stacked_pings", "1"))
             if k in attrs and str(attrs[k]) != ok]
    return ", ".join(found)


def _nadir_reflections(patches: list, pings, args, absorption_db_per_km: float) -> dict:
    """``(ping_start, ping_stop) -> PatchNadir`` of every patch, from the ping file ``pings``."""
    from clbeam.seabed.nadir import patch_reflections

    ranges = sorted({(p.ping_start, p.ping_stop) for p in patches})
    bar = progress(None, total=sum(b - a for a, b in ranges), desc="nadir", quiet=args.quiet)
    try:
        return dict(zip(ranges, patch_reflections(pings, ranges, bandwidth_hz=args.bandwidth,
                                                  absorption_db_per_km=absorption_db_per_km, progress=bar.update)))
    finally:
        bar.close()


def _calibration(nadir: dict, args, attrs: dict):
    """The calibration to apply: ``--calibration-db``, else the patches' nadir estimates combined, else none."""
    from clbeam.seabed.avo.calibration import SYSTEMATIC_ERROR_DB, Calibration, survey_calibration

    if args.calibration_db is not None:  # taken good to the nadir estimate's floor in the joint inversion
        return Calibration(args.calibration_db, SYSTEMATIC_ERROR_DB, "option")
    blocked = _calibration_blocked(attrs)
    if nadir and blocked:
        log.warning("the images were made with %s: the nadir calibration (for single-ping, channel-calibrated, "
                    "unweighted images) is reported, not applied; strengths stay relative (give --calibration-db)",
                    blocked)
        return Calibration(0.0, float("nan"), "none")
    found = list(nadir.values())
    cal = survey_calibration([f.calibration_db for f in found], [f.calibration_error_db for f in found])
    if cal is None and found:
        log.warning("no patch gave a nadir calibration (no multiple above the noise, or beyond the record): "
                    "strengths stay relative")
    return cal or Calibration(0.0, float("nan"), "none")


def _calibration_text(cal) -> str:
    """One phrase for the summary line."""
    if cal.source == "nadir":
        return f"calibration {cal.db:+.1f} +- {cal.error_db:.1f} dB from {cal.n_patches} patches' nadir echoes"
    if cal.source == "option":
        return f"calibration {cal.db:+.1f} dB (--calibration-db)"
    return "strengths relative (no calibration)"


def add_arguments(p) -> None:
    """The arguments of ``clbeam avo``."""
    p.add_argument("images", metavar="IMAGES.nc", help="image file written by 'clbeam image' (with intensity)")
    p.add_argument("-o", "--output", required=True, metavar="AVO.csv", help="per-patch table to write")
    p.add_argument("--pings-per-patch", type=int, default=AVO_PINGS_PER_PATCH, metavar="N",
                   help=f"consecutive pings stacked per patch and side (default {AVO_PINGS_PER_PATCH}; "
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
    p.add_argument("--calibration-db", type=float, default=None, metavar="DB",
                   help="added to every strength (dB); default: from the nadir echoes with --pings, "
                        "else 0 (strengths relative to an unknown constant)")
    p.add_argument("--ping-spacing", type=float, default=1.0, metavar="M",
                   help="along-track ping spacing used when the file has no navigation (m, default 1)")
    p.add_argument("--no-invert", action="store_true", help="attributes only, no model inversion")
    p.add_argument("--no-nadir", action="store_true",
                   help="no nadir reflection coefficient or calibration, even with the images' ping file beside them")
    p.add_argument("--pings", default=None, metavar="PINGS.nc",
                   help="the ping file the images were made from (default: their source file, when it lies beside "
                        "them): each patch's nadir reflection coefficient "
                        "from the seabed echo and its surface multiple, the calibration the patches give together "
                        "(applied unless --calibration-db), and a joint inversion of both with the response "
                        "(clbeam docs avo)")
    p.add_argument("--figures", default=None, metavar="DIR", help="also draw the AVO figures (PNG) into DIR")
