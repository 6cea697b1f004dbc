"""``clbeam bench``: run time against error of every interpolation mode; table and Pareto plot."""

from __future__ import annotations

from clbeam.cli.options import require_extra, stage_printer

NAME = "bench"
HELP = "run time against error of every interpolation mode; table and Pareto plot"
#: pings of the file ``clbeam image`` is timed on (against a one-ping file)
COMMAND_PINGS = 4


def add_arguments(p) -> None:
    """The arguments of ``clbeam bench``."""
    p.add_argument("-o", "--output", default="clbeam-bench", metavar="DIR", help="output folder (default clbeam-bench)")
    p.add_argument("--scene", default="line4", help="scene to image (default line4: a pipe at 920 m)")
    p.add_argument("--max-range", type=float, default=1100.0, metavar="M", help="record range (m, default 1100)")
    p.add_argument("--repeats", type=int, default=3, help="timed runs per mode, best kept (default 3)")
    p.add_argument("--accuracy-window", type=float, nargs=4, default=(880.0, 1000.0, 68.0, 80.0),
                   metavar=("R0", "R1", "A0", "A1"),
                   help="ranges (m) and angles (degree) where errors are measured against the exact "
                        "reference (default 880 1000 68 80: line4's pipe at 920 m)")
    p.add_argument("--no-zoo", action="store_true",
                   help="skip timing clbeam image on the scene zoo (five scenes, 1 and 5 pings each: minutes)")


def run(args) -> int:
    """Simulate one ping, time and score every mode, write the table and the plot."""
    require_extra("numba", "bench", "bench")
    import tempfile
    from pathlib import Path

    from clbeam.evaluation.bench import (
        accuracy_window,
        markdown_table,
        run_benchmark,
        time_image_command,
        write_report,
    )
    from clbeam.io.pingfile import pings_from_dataset
    from clbeam.sim import load_scene, simulate

    say = stage_printer(args)
    say(f"simulating {COMMAND_PINGS} pings of '{args.scene}'")
    dataset = simulate(load_scene(args.scene, pings=COMMAND_PINGS, max_range_m=args.max_range))
    ping = pings_from_dataset(dataset, args.scene).ping(0)
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    window = accuracy_window(tuple(args.accuracy_window[:2]), tuple(args.accuracy_window[2:]))
    res = run_benchmark(ping, accuracy_grid=window, repeats=args.repeats, progress=say)
    say(f"clbeam image on 1 and {COMMAND_PINGS} pings, timed as commands")
    with tempfile.TemporaryDirectory(dir=out) as work:
        res.command = time_image_command(dataset, work, pings=(1, COMMAND_PINGS))
        if not args.no_zoo:
            from clbeam.evaluation.zoo import zoo_command_times

            res.zoo_commands = zoo_command_times(work, progress=say)
    paths = write_report(res, out)
    if not args.quiet:
        print(markdown_table(res))
        print(f"table -> {paths['markdown']}, {paths['csv']}; plot -> {paths['plot']}")
    return 0
