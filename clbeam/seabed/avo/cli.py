"""``clbeam avo IMAGES.nc -o AVO.csv``: angular responses, patches, attributes, inversion.

The command chains :func:`clbeam.seabed.avo.response.angular_responses`,
:func:`clbeam.seabed.avo.stack.stack_sides`, :func:`clbeam.seabed.avo.table.survey_records`
and :func:`clbeam.seabed.avo.table.write_csv`; with ``--figures DIR`` it also draws
the stacked responses of the first and last patch with their attributes,
the gradient–intercept crossplot with the background trend, and the
attributes and inverted grain size along the track.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.seabed.avo.response import (
    DEFAULT_INCIDENCE_DEG,
    ResponseOptions,
    angular_responses,
)
from clbeam.seabed.avo.stack import DEFAULT_PINGS_PER_PATCH, stack_sides
from clbeam.seabed.avo.table import survey_records, write_csv


def options_from_args(args) -> ResponseOptions:
    """The :class:`ResponseOptions` of the parsed command line."""
    return ResponseOptions(frequency_hz=args.frequency, bandwidth_hz=args.bandwidth,
                           sound_speed_m_s=args.sound_speed, tx_length_m=args.tx_length,
                           rx_width_m=args.rx_width, absorption_db_per_km=args.absorption,
                           calibration_db=args.calibration_db)


def write_figures(folder, patches, rows, *, frequency_hz=None, sound_speed_m_s: float = 1500.0) -> list[Path]:
    """The AVO figures of a survey into ``folder`` (PNG); returns their paths.

    ``avo_response_first.png`` / ``avo_response_last.png``: the first and the
    last patch's stacked response with its attributes (and the fitted model
    when the inversion ran); ``avo_gradient_intercept.png``;
    ``avo_track.png``: A, B, fluid factor and Mz along the track.

    Parameters
    ----------
    folder : str or pathlib.Path
        Output folder (created).
    patches : list of Patch
        Stacked responses, in the order of ``rows``.
    rows : list of PatchRecord
        Their records (:func:`clbeam.seabed.avo.table.survey_records`).
    frequency_hz : float, optional
        Band centre (Hz) of the fitted-model curve; no curve without it.
    sound_speed_m_s : float
        Water sound speed of the model (m/s).
    """
    from clbeam.seabed.avo.attributes import angular_attributes
    from clbeam.seabed.avo.model import backscatter_strength_db
    from clbeam.seabed.avo.plot import (
        plot_along_track,
        plot_angular_response,
        plot_gradient_intercept,
    )
    from clbeam.seabed.avo.sediment import sediment_from_grain_size

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for tag, k in (("first", 0), ("last", len(patches) - 1)):
        p, r = patches[k], rows[k]
        model = None
        if frequency_hz is not None and np.isfinite(r.mz_phi):
            sed = dataclasses.replace(sediment_from_grain_size(r.mz_phi), w2_cm4=r.roughness_w2_cm4,
                                      sigma2=r.volume_sigma2)
            model = backscatter_strength_db(np.clip(90.0 - p.incidence_deg, 1e-3, 90.0), frequency_hz,
                                            sediment=sed, sound_speed_water_m_s=sound_speed_m_s)
        paths.append(plot_angular_response(
            out / f"avo_response_{tag}.png", p.incidence_deg, p.strength_db,
            angular_attributes(p.incidence_deg, p.strength_db), model_db=model,
            title=f"{p.side}, pings {p.ping_start}-{p.ping_stop - 1}, along-track {p.along_track_m:.0f} m"))
    a = [r.intercept_a_db for r in rows]
    b = [r.gradient_b_db for r in rows]
    paths.append(plot_gradient_intercept(out / "avo_gradient_intercept.png", a, b, rows[0].trend_g,
                                         rows[0].trend_d_db, fluid_factor_db=[r.fluid_factor_db for r in rows]))
    series = {"A (dB)": a, "B (dB)": b, "fluid factor (dB)": [r.fluid_factor_db for r in rows]}
    if any(np.isfinite(r.mz_phi) for r in rows):
        series["Mz (phi)"] = [r.mz_phi for r in rows]
    paths.append(plot_along_track(out / "avo_track.png", [r.along_track_m for r in rows], series,
                                  sides=[r.side for r in rows]))
    return paths


def cmd_avo(args) -> int:
    """Run ``clbeam avo``; returns the exit status."""
    t0 = time.perf_counter()
    require(args.pings_per_patch >= 1, OptionError,
            f"--pings-per-patch must be >= 1, got {args.pings_per_patch}")
    require(args.ping_spacing > 0, OptionError, f"--ping-spacing must be > 0 m, got {args.ping_spacing}")
    out = Path(args.output)
    require(out.parent.exists(), OptionError, f"output folder {str(out.parent)!r} does not exist")
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
    write_csv(out, rows)
    figs = write_figures(args.figures, patches, rows, frequency_hz=opts.frequency_hz,
                         sound_speed_m_s=opts.sound_speed_m_s) if args.figures else []
    if not args.quiet:
        partial = "" if n % args.pings_per_patch == 0 else \
            f" (last patch of {n % args.pings_per_patch} ping(s))"
        print(f"{n} ping(s) -> {len(patches)} patches{partial} -> {out}"
              + (f"; {len(figs)} figures -> {args.figures}" if figs else "")
              + f" in {time.perf_counter() - t0:.1f} s", file=sys.stdout)
    return 0


def register_avo(sub, common) -> None:
    """Add the ``avo`` subcommand to the clbeam parser."""
    sp = sub.add_parser("avo", help="AVO analysis: angular responses from an image file, patches, "
                                    "attributes, inversion for grain size (SPEC §5)")
    sp.add_argument("images", metavar="IMAGES.nc", help="image file written by 'clbeam image' (with intensity)")
    sp.add_argument("-o", "--output", required=True, metavar="AVO.csv", help="per-patch table to write")
    sp.add_argument("--pings-per-patch", type=int, default=DEFAULT_PINGS_PER_PATCH, metavar="N",
                    help=f"consecutive pings stacked per patch and side (default {DEFAULT_PINGS_PER_PATCH}; "
                         "a last, shorter patch is kept)")
    sp.add_argument("--frequency", type=float, default=5500.0, metavar="HZ",
                    help="band centre (Hz, default 5500: the SBP29's 2-9 kHz sweep)")
    sp.add_argument("--bandwidth", type=float, default=7000.0, metavar="HZ",
                    help="pulse bandwidth (Hz, default 7000); compressed pulse 1/bandwidth")
    sp.add_argument("--sound-speed", type=float, default=1500.0, metavar="M/S", help="water sound speed (default 1500)")
    sp.add_argument("--tx-length", type=float, default=3.5, metavar="M",
                    help="along-track length of the transmit column (m, default 3.5)")
    sp.add_argument("--rx-width", type=float, default=3.528, metavar="M",
                    help="across-track width of the receive array (m, default 3.528)")
    sp.add_argument("--absorption", type=float, default=None, metavar="DB/KM",
                    help="water absorption (dB/km; default Francois-Garrison at the band centre, 10 °C, 35 PSU)")
    sp.add_argument("--calibration-db", type=float, default=0.0, metavar="DB",
                    help="added to every strength (dB; default 0: strengths relative to an unknown constant)")
    sp.add_argument("--ping-spacing", type=float, default=1.0, metavar="M",
                    help="along-track ping spacing used when the file has no navigation (m, default 1)")
    sp.add_argument("--no-invert", action="store_true", help="attributes only, no model inversion")
    sp.add_argument("--figures", default=None, metavar="DIR", help="also draw the AVO figures (PNG) into DIR")
    common(sp)
    sp.set_defaults(func=cmd_avo)
