"""``clbeam sediment-speed``: the sediment interval velocity that makes a sub-bottom reflector most coherent."""

from __future__ import annotations

import numpy as np

from clbeam.cli.options import (
    add_grid_options,
    add_imaging_options,
    grid_from_args,
    options_from_args,
    progress,
)
from clbeam.errors import OptionError, require
from clbeam.io.paths import check_output_path

NAME = "sediment-speed"
HELP = "sediment interval velocity: the speed that makes a sub-bottom reflector most coherent (scan of candidate speeds)"
DESCRIPTION = ("Image one ping with each candidate sediment speed (rays refracted at a flat seabed at --seabed-depth) "
               "and report the speed whose sub-bottom reflector detections line up best in depth (clbeam docs beyond). "
               "The scan sets --sediment-speed, --mlh and --seabed-band itself (giving them is an error); "
               "--threshold defaults to 0.5 here.")


def add_arguments(p) -> None:
    """The arguments of ``clbeam sediment-speed``."""
    p.add_argument("pings", metavar="PINGS.nc", help="ping file")
    p.add_argument("--ping", type=int, default=0, help="ping to use (default 0)")
    p.add_argument("--speeds", type=float, nargs=3, default=(1450.0, 1800.0, 10.0), metavar=("MIN", "MAX", "STEP"),
                   dest="speeds", help="candidate sediment speeds (m/s, default 1450 1800 10)")
    p.add_argument("-o", "--output", default=None, metavar="SCAN.csv", help="write the scan as CSV")
    add_grid_options(p)
    add_imaging_options(p)
    # the scan merges peaks per arc and sets the sediment speed itself; a stricter threshold keeps the reflector
    p.set_defaults(threshold=0.5)


def _write_scan(path, scan) -> None:
    with open(path, "w") as fh:
        fh.write("speed_m_s,coherence,reflector_depth_m,n_detections\n")
        for c, k, z, n in zip(scan.speeds_m_s, scan.coherence, scan.reflector_depth_m, scan.n_detections):
            fh.write(f"{float(c)!r},{float(k)!r},{float(z)!r},{int(n)}\n")


def run(args) -> int:
    """Scan the candidate speeds; print the result (and write the scan)."""
    from clbeam.imaging.sediment_speed import scan_sediment_speed
    from clbeam.io.pingfile import PingFile

    lo, hi, step = args.speeds
    require(step > 0 and hi > lo, OptionError, f"--speeds needs MIN < MAX and STEP > 0, got {lo:g} {hi:g} {step:g}")
    require(args.seabed_depth is not None, OptionError, "give the seabed depth below the transducers: --seabed-depth M")
    require(not args.mlh and args.sediment_speed is None and args.seabed_band is None, OptionError,
            "sediment-speed sets --mlh, --sediment-speed and --seabed-band itself: leave them out")
    speeds = np.arange(lo, hi + 0.5 * step, step)
    if args.output:
        check_output_path(args.output, args.pings)
    with PingFile(args.pings) as f:
        require(0 <= args.ping < len(f), OptionError, f"--ping {args.ping} is not in 0..{len(f) - 1}")
        ping = f.ping(args.ping)
        grid = grid_from_args(args, f.max_record_range_m())
    bar = progress(None, total=len(speeds), desc="sediment speed", quiet=args.quiet)
    options = options_from_args(args, seabed_depth_m=None)
    scan = scan_sediment_speed(ping, grid, seabed_depth_m=args.seabed_depth, speeds_m_s=speeds, options=options,
                               backend=args.backend, device=args.device, threshold=args.threshold,
                               progress=lambda msg: bar.update(1))
    bar.close()
    if args.output:
        _write_scan(args.output, scan)
    print("\n".join(scan.lines() if not args.quiet else scan.lines()[-1:]))
    return 0
