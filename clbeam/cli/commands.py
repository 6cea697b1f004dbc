"""Subcommands beyond image/peaks/devices: simulate, demo, bench, forward, profile, avo, survey, sediment-speed.

Each registrar is ``register(subparsers, add_common_options)``; the CLI calls
them all when it builds its parser.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from clbeam.errors import OptionError, require


def _say(args):
    return (lambda msg: None) if args.quiet else (lambda msg: print(f"  {msg} …", file=sys.stderr, flush=True))


def cmd_simulate(args) -> int:
    from clbeam.io.pingwrite import write_ping_file
    from clbeam.sim.simulator import load_scene, simulate

    scene = load_scene(args.scene, pings=args.pings, max_range_m=args.max_range)
    t0 = time.perf_counter()
    ds = simulate(scene, seed=args.seed, progress=not args.quiet and sys.stderr.isatty())
    write_ping_file(ds, args.output)
    if not args.quiet:
        print(f"simulated {ds.sizes['ping']} ping(s) of '{scene.name}' ({ds.sizes['channel']} channels x "
              f"{ds.sizes['sample']} samples) in {time.perf_counter() - t0:.1f} s -> {args.output}")
    return 0


def register_simulate(sub, common) -> None:
    sp = sub.add_parser("simulate", help="simulate a scene's pings into a ping file (SPEC §7)")
    sp.add_argument("-o", "--output", required=True, metavar="PINGS.nc", help="ping file to write (.nc or .zarr)")
    sp.add_argument("--scene", default="line1", metavar="NAME|FILE",
                    help="built-in scene (line1, line4, point) or a TOML file (default line1)")
    sp.add_argument("--pings", type=int, default=None, help="number of pings (default: the scene's)")
    sp.add_argument("--max-range", type=float, default=None, metavar="M", help="largest recorded slant range (m)")
    sp.add_argument("--seed", type=int, default=0, help="random seed of seabed and noise (default 0)")
    common(sp)
    sp.set_defaults(func=cmd_simulate)


def cmd_demo(args) -> int:
    from clbeam.evaluation.demo import run_demo, summary_lines

    t0 = time.perf_counter()
    if not args.quiet:
        print(f"clbeam demo: Holland et al. (2024) Line 1 -> {args.output}/", flush=True)
    res = run_demo(args.output, pings=args.pings, scene=args.scene, interp=args.interp, device=args.device,
                   backend=args.backend, progress=_say(args))
    if not args.quiet:
        print("\n".join(summary_lines(res)))
        print(f"done in {time.perf_counter() - t0:.1f} s; open {args.output}/ping000.png")
    return 0


def register_demo(sub, common) -> None:
    from clbeam.imaging.engine import INTERP_MODES

    sp = sub.add_parser("demo", help="simulate the paper's Line 1, image it, detect the pipelines, draw figures")
    sp.add_argument("-o", "--output", default="clbeam-demo", metavar="DIR", help="output folder (default clbeam-demo)")
    sp.add_argument("--pings", type=int, default=3, help="pings to simulate (default 3)")
    sp.add_argument("--scene", default="line1", help="scene (default line1)")
    sp.add_argument("--interp", default="cubic", choices=list(INTERP_MODES), help="interpolation mode (default cubic)")
    sp.add_argument("--backend", default="opencl", choices=["opencl", "reference"])
    sp.add_argument("--device", default=None, help="OpenCL device: index or name substring")
    common(sp)
    sp.set_defaults(func=cmd_demo)


def cmd_bench(args) -> int:
    from clbeam.evaluation.bench import markdown_table, run_benchmark, write_report
    from clbeam.io.pingfile import PingFile
    from clbeam.io.pingwrite import write_ping_file
    from clbeam.sim.simulator import load_scene, simulate

    say = _say(args)
    say(f"simulating one ping of '{args.scene}'")
    ds = simulate(load_scene(args.scene, pings=1, max_range_m=args.max_range))
    from pathlib import Path

    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    with PingFile(write_ping_file(ds, out / "bench-ping.nc")) as f:
        ping = f.ping(0)
    from clbeam.evaluation.bench import accuracy_window

    window = accuracy_window(tuple(args.accuracy_window[:2]), tuple(args.accuracy_window[2:]))
    res = run_benchmark(ping, accuracy_grid=window, repeats=args.repeats, progress=say)
    paths = write_report(res, out)
    if not args.quiet:
        print(markdown_table(res))
        print(f"table -> {paths['markdown']}, {paths['csv']}; plot -> {paths['plot']}")
    return 0


def register_bench(sub, common) -> None:
    sp = sub.add_parser("bench", help="run time against error of every interpolation mode; table and Pareto plot")
    sp.add_argument("-o", "--output", default="clbeam-bench", metavar="DIR", help="output folder (default clbeam-bench)")
    sp.add_argument("--scene", default="line4", help="scene to image (default line4: a pipe at 920 m)")
    sp.add_argument("--max-range", type=float, default=1100.0, metavar="M", help="record range (m, default 1100)")
    sp.add_argument("--repeats", type=int, default=3, help="timed runs per mode, best kept (default 3)")
    sp.add_argument("--accuracy-window", type=float, nargs=4, default=(880.0, 1000.0, 68.0, 80.0),
                    metavar=("R0", "R1", "A0", "A1"),
                    help="ranges (m) and angles (degree) where errors are measured against the exact "
                         "reference (default 880 1000 68 80: line4's pipe at 920 m)")
    common(sp)
    sp.set_defaults(func=cmd_bench)


def register_forward(sub, common) -> None:
    from clbeam.seabed.forward.cli import add_parser

    add_parser(sub, common)


def register_profile(sub, common) -> None:
    from clbeam.seabed.profile import register_profile as register

    register(sub, common)


def register_avo(sub, common) -> None:
    from clbeam.seabed.avo.cli import register_avo as register

    register(sub, common)


def register_survey(sub, common) -> None:
    from clbeam.survey.run import register_survey as register

    register(sub, common)


def cmd_sediment_speed(args) -> int:
    from clbeam.cli.main import (
        check_output_path,
        grid_from_args,
        options_from_args,
        progress,
    )
    from clbeam.imaging.sediment_speed import scan_sediment_speed
    from clbeam.io.pingfile import PingFile

    lo, hi, step = args.speeds
    require(step > 0 and hi > lo, OptionError, f"--speeds needs MIN < MAX and STEP > 0, got {lo:g} {hi:g} {step:g}")
    require(args.seabed_depth is not None, OptionError, "give the seabed depth below the transducers: --seabed-depth M")
    speeds = np.arange(lo, hi + 0.5 * step, step)
    if args.output:
        check_output_path(args.output, args.pings)
    with PingFile(args.pings) as f:
        require(0 <= args.ping < len(f), OptionError, f"--ping {args.ping} is not in 0..{len(f) - 1}")
        ping = f.ping(args.ping)
        grid = grid_from_args(args, f.max_record_range_m())
    bar = progress(None, total=len(speeds), desc="sediment speed", quiet=args.quiet)
    scan = scan_sediment_speed(ping, grid, seabed_depth_m=args.seabed_depth, speeds_m_s=speeds,
                               options=options_from_args(args), backend=args.backend, threshold=args.threshold,
                               progress=lambda msg: bar.update(1))
    bar.close()
    if args.output:
        with open(args.output, "w") as fh:
            fh.write("speed_m_s,coherence,reflector_depth_m,n_detections\n")
            for c, k, z, n in zip(scan.speeds_m_s, scan.coherence, scan.reflector_depth_m, scan.n_detections):
                fh.write(f"{float(c)!r},{float(k)!r},{float(z)!r},{int(n)}\n")
    print("\n".join(scan.lines() if not args.quiet else scan.lines()[-1:]))
    return 0


def register_sediment_speed(sub, common) -> None:
    from clbeam.cli.main import add_engine_options, add_grid_options

    sp = sub.add_parser("sediment-speed", help="sediment interval velocity: the speed that makes a sub-bottom "
                                                "reflector most coherent (scan of candidate speeds)",
                        description="Image one ping with each candidate sediment speed (rays refracted at a flat "
                                    "seabed at --seabed-depth) and report the speed whose sub-bottom reflector "
                                    "detections line up best in depth (docs/beyond.md). --sediment-speed, --mlh and "
                                    "--seabed-band are set by the scan; --threshold defaults to 0.5 here.")
    sp.add_argument("pings", metavar="PINGS.nc", help="ping file")
    sp.add_argument("--ping", type=int, default=0, help="ping to use (default 0)")
    sp.add_argument("--speeds", type=float, nargs=3, default=(1450.0, 1800.0, 10.0), metavar=("MIN", "MAX", "STEP"),
                    dest="speeds", help="candidate sediment speeds (m/s, default 1450 1800 10)")
    sp.add_argument("-o", "--output", default=None, metavar="SCAN.csv", help="write the scan as CSV")
    add_grid_options(sp)
    add_engine_options(sp)
    # the scan merges peaks per arc and sets the sediment speed itself; a stricter threshold keeps the reflector
    sp.set_defaults(threshold=0.5)
    common(sp)
    sp.set_defaults(func=cmd_sediment_speed)


REGISTRARS: list = [register_simulate, register_demo, register_bench, register_forward, register_profile, register_avo,
                    register_survey, register_sediment_speed]
