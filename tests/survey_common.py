"""What the survey tests share: the grids, the command line in this process, the simulated line, and a
built-in scene surveyed as a user runs it and scored against its truth."""

from __future__ import annotations

from pathlib import Path

from clbeam import cli

N_PINGS = 12
PER_FILE = 4
#: 12 pings are a short line: pipeline A scores about 0.4 on them (30 over the 56 pings of Line 1)
LINES = ["--line-min-score", "0"]
GRID = ["--range-res", "0.5", "--angle-res", "0.25", "--min-range", "200", "--max-range", "380",
        "--angles", "-60", "60"]
#: a small window around pipeline A for the runs whose cost does not matter
TINY = ["--range-res", "0.5", "--angle-res", "0.5", "--min-range", "300", "--max-range", "380",
        "--angles", "-60", "-40"]

def survey_main(argv) -> int:
    """``clbeam`` in this process."""
    return cli.main(list(argv))


RUN_CLI = "import sys\nfrom clbeam import cli\nsys.exit(cli.main(sys.argv[1:]))\n"


def scored_surveys(scene: str, seeds, work: Path, survey_args: list) -> list:
    """A built-in ``scene`` simulated with each noise seed and surveyed as ``clbeam survey IN -o OUT
    *survey_args``: per seed, the truth's rows by target name and the false-line summary
    (:func:`clbeam.evaluation.line_truth.score_survey`)."""
    from clbeam.cli.main import build_parser
    from clbeam.cli.survey import options_from_survey_args
    from clbeam.evaluation.line_truth import score_survey
    from clbeam.io.pingwrite import write_ping_file
    from clbeam.sim import load_scene, simulate
    from clbeam.survey import run_survey, scan_inputs

    out = []
    for seed in seeds:
        nc = work / f"{scene}_{seed}.nc"
        write_ping_file(simulate(load_scene(scene), seed=seed), nc)
        args = build_parser().parse_args(["survey", str(nc), "-o", str(work / f"{scene}_{seed}.zarr"),
                                          *survey_args, "--quiet"])
        scan = scan_inputs(args.inputs)
        res = run_survey(scan, args.output, options_from_survey_args(args, scan))
        rows, summary = score_survey(res.products, [nc])
        out.append(({r["target"]: r for r in rows}, summary))
    return out
