"""``clbeam detectability``: the probability of detecting a scene's pipelines against horizontal range
(docs/detectability.md)."""

from __future__ import annotations

import argparse
import math

NAME = "detectability"
HELP = "predict the probability of detecting a scene's pipelines against horizontal range (see clbeam docs detectability)"

#: the CSV's columns after target, range_m and pd
COLUMNS = ("p_cf", "p_snr", "p_contrast", "cf_median", "echo_db", "noise_db", "seabed_db", "subbottom_db",
           "clutter_over_floor_db", "slant_m", "grazing_deg", "sediment_m", "heading_deg")


def _override(text: str) -> tuple[str, object]:
    """``KEY=VALUE`` of ``--set``: the value as TOML reads it (a number, true/false, a quoted string)."""
    import tomllib

    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE (a dotted scene key), got {text!r}")
    try:
        return key.strip(), tomllib.loads(f"v = {value.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        return key.strip(), value.strip()


def _db_or_off(text: str):
    from clbeam.cli.options import min_snr_db

    return min_snr_db(text)


def add_arguments(p) -> None:
    """The arguments of ``clbeam detectability``."""
    from clbeam.constants import DEFAULT_MIN_CONTRAST_DB, DEFAULT_MIN_SNR_DB, PEAK_THRESHOLD

    p.add_argument("scene", metavar="SCENE", help="built-in scene (e.g. line4, the paper's Line 4) or a scene TOML file")
    p.add_argument("-o", "--output", required=True, metavar="OUT.csv",
                   help="table to write: one row per pipeline and range (target, range_m, pd, ...)")
    p.add_argument("--ranges", default=None, metavar="START:STOP:STEP",
                   help="horizontal ranges from the track (m, STOP included); default: each pipeline at its "
                        "own mean horizontal range in the scene")
    p.add_argument("--heading", type=float, default=None, metavar="DEG",
                   help="heading of every pipeline to the track (degree; 0: broadside); default each pipeline's "
                        "mean over the scene's pings")
    p.add_argument("--absorption", default="francois-garrison", metavar="DB_PER_KM|francois-garrison",
                   help="water absorption: a number of dB/km (0: none, as the simulator) or francois-garrison "
                        "(default, at every frequency of the band)")
    p.add_argument("--set", dest="overrides", type=_override, action="append", default=[], metavar="KEY=VALUE",
                   help="replace a scene value (dotted key, e.g. snr_db=20 or record.max_range_m=2500); repeatable")
    p.add_argument("--figure", default=None, metavar="PNG",
                   help="figure of Pd against range (default with --ranges: OUT with .png)")
    p.add_argument("--threshold", type=float, default=PEAK_THRESHOLD, help=f"smoothed-CF threshold (default {PEAK_THRESHOLD})")
    p.add_argument("--min-snr-db", type=_db_or_off, default=DEFAULT_MIN_SNR_DB, metavar="DB|off",
                   help=f"level over the noise floor a peak needs (default {DEFAULT_MIN_SNR_DB:g} dB)")
    p.add_argument("--min-contrast-db", type=_db_or_off, default=DEFAULT_MIN_CONTRAST_DB, metavar="DB|off",
                   help=f"level over the clutter a peak needs where it is reverberation (default "
                        f"{DEFAULT_MIN_CONTRAST_DB:g} dB, the imager's)")
    p.add_argument("--range-step", type=float, default=0.2, metavar="M",
                   help="the image grid's range step, the smoothed CF's cells (m, default 0.2)")
    p.add_argument("--draws", type=int, default=512, help="Monte Carlo draws per range (default 512: Pd within ±0.022)")
    p.add_argument("--seed", type=int, default=0, help="Monte Carlo seed (default 0)")
    p.add_argument("--no-uncertainty", action="store_true",
                   help="skip the uncertainty of the ranges of Pd 0.9 and 0.5 (faster)")


def _absorption(text: str) -> float | None:
    from clbeam.errors import OptionError

    if text.strip().lower() in ("francois-garrison", "fg"):
        return None
    try:
        value = float(text)
    except ValueError:
        raise OptionError(f"--absorption must be a number of dB/km or francois-garrison, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0):
        raise OptionError(f"--absorption must be >= 0 dB/km, got {text!r}")
    return value


def run(args) -> int:
    """Predict, write the table (and the figure), print one summary line per pipeline."""
    from clbeam.errors import OptionError, require
    from clbeam.evaluation.detectability_stats import Tests
    from clbeam.evaluation.detectability_sweep import parse_ranges, predict
    from clbeam.io.paths import check_output_path

    check_output_path(args.output)
    require(args.draws >= 16, OptionError, f"--draws must be at least 16, got {args.draws}")
    ranges = parse_ranges(args.ranges) if args.ranges is not None else None
    tests = Tests(threshold=args.threshold, min_snr_db=args.min_snr_db, min_contrast_db=args.min_contrast_db,
                  range_step_m=args.range_step)
    pred = predict(args.scene, ranges_m=ranges, heading_deg=args.heading, absorption_db_per_km=_absorption(args.absorption),
                   tests=tests, draws=args.draws, seed=args.seed, with_uncertainty=not args.no_uncertainty,
                   overrides=dict(args.overrides))
    _write_csv(args.output, pred)
    figure = args.figure or (str(args.output).rsplit(".", 1)[0] + ".png" if ranges is not None else None)
    if figure:
        from clbeam.evaluation.detectability_sweep import plot

        plot(pred, figure)
    if not args.quiet:
        for line in pred.summary_lines():
            print(line)
        print(f"-> {args.output}" + (f", {figure}" if figure else ""))
    return 0


def _write_csv(path, pred) -> None:
    import csv

    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(("target", "range_m", "pd") + COLUMNS)
        for p in pred.pipes:
            for row in p.rows:
                values = {**row, "heading_deg": p.pipe.heading_deg}
                w.writerow([row["target"], f"{row['range_m']:.2f}", f"{row['pd']:.4f}"]
                           + [_fmt(values.get(k, math.nan)) for k in COLUMNS])


def _fmt(v) -> str:
    if isinstance(v, bool):
        return str(int(v))
    return f"{float(v):.4g}" if math.isfinite(float(v)) else ""
