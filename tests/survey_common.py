"""What the survey tests share: the grids, the command line in this process, and the simulated line."""

from __future__ import annotations

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


