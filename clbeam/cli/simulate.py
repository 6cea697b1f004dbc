"""``clbeam simulate``: a scene's pings into a ping file (docs/ping-format.md)."""

from __future__ import annotations

import sys
import time

NAME = "simulate"
HELP = "simulate a scene's pings into a ping file (see clbeam docs ping-format)"


def add_arguments(p) -> None:
    """The arguments of ``clbeam simulate``."""
    p.add_argument("-o", "--output", required=True, metavar="PINGS.nc", help="ping file to write (.nc or .zarr)")
    p.add_argument("--scene", default="line1", metavar="NAME|FILE",
                   help="built-in scene (line1, line4, point, avo2, avo3, svp1km, cross, boulders, clutter) "
                        "or a TOML file (default line1)")
    p.add_argument("--pings", type=int, default=None, help="number of pings (default: the scene's)")
    p.add_argument("--max-range", type=float, default=None, metavar="M", help="largest recorded slant range (m)")
    p.add_argument("--seed", type=int, default=0, help="random seed of seabed and noise (default 0)")


def run(args) -> int:
    """Simulate and write the ping file; prints one summary line."""
    from clbeam.io.paths import check_output_path
    from clbeam.io.pingwrite import write_ping_file
    from clbeam.sim import load_scene, simulate

    check_output_path(args.output)
    scene = load_scene(args.scene, pings=args.pings, max_range_m=args.max_range)
    t0 = time.perf_counter()
    ds = simulate(scene, seed=args.seed, progress=not args.quiet and sys.stderr.isatty())
    write_ping_file(ds, args.output)
    if not args.quiet:
        print(f"simulated {ds.sizes['ping']} ping(s) of '{scene.name}' ({ds.sizes['channel']} channels x "
              f"{ds.sizes['sample']} samples) in {time.perf_counter() - t0:.1f} s -> {args.output}")
    return 0
