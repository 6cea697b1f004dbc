"""``clbeam demo``: simulate the paper's Line 1, image it, detect the pipelines, draw figures."""

from __future__ import annotations

import time

from clbeam.cli.options import add_engine_choice, stage_printer

NAME = "demo"
HELP = "simulate the paper's Line 1, image it, detect the pipelines, draw figures"


def add_arguments(p) -> None:
    """The arguments of ``clbeam demo``."""
    p.add_argument("-o", "--output", default="clbeam-demo", metavar="DIR", help="output folder (default clbeam-demo)")
    p.add_argument("--pings", type=int, default=3, help="pings to simulate (default 3)")
    p.add_argument("--scene", default="line1", help="scene (default line1)")
    add_engine_choice(p)


def run(args) -> int:
    """Run the demo and print the detections against the simulator's truth."""
    from clbeam.evaluation.demo import run_demo, summary_lines

    t0 = time.perf_counter()
    if not args.quiet:
        print(f"clbeam demo: Holland et al. (2024) Line 1 -> {args.output}/", flush=True)
    res = run_demo(args.output, pings=args.pings, scene=args.scene, interp=args.interp, device=args.device,
                   backend=args.backend, progress=stage_printer(args))
    if not args.quiet:
        print("\n".join(summary_lines(res)))
        print(f"done in {time.perf_counter() - t0:.1f} s; open {args.output}/ping000.png")
    return 0
