"""``-v``, ``--debug`` and ``--debug --debug``: clbeam's messages by level, the libraries' held at WARNING.

Each case runs in a fresh interpreter (logging's state is global): it parses
the arguments with the command line's parser, configures logging as
``clbeam`` does, then logs one message at each level on a clbeam logger and
on the loggers of libraries clbeam uses, and the test reads stderr.
"""

import subprocess
import sys

import pytest

SNIPPET = """
import logging, sys
from clbeam.cli.main import build_parser
from clbeam.cli.options import setup_logging
args = build_parser().parse_args(sys.argv[1:])
setup_logging(args)
print(args.verbose, args.debug)
for name in ("clbeam.imaging.imager", "numba.core.ssa", "matplotlib.font_manager", "distributed.worker",
             "asyncio", "PIL.PngImagePlugin", "fsspec.local", "h5py._conv", "some.other.library"):
    log = logging.getLogger(name)
    for level in ("debug", "info", "warning"):
        getattr(log, level)("%s %s", name, level)
"""

LIBRARIES = ("numba.core.ssa", "matplotlib.font_manager", "distributed.worker", "asyncio", "PIL.PngImagePlugin",
             "fsspec.local", "h5py._conv", "some.other.library")


def logged(*argv):
    """``(verbose, debug)`` counts and the set of ``(logger, level)`` messages that reached stderr."""
    r = subprocess.run([sys.executable, "-c", SNIPPET, *argv], capture_output=True, text=True, check=True)
    verbose, debug = map(int, r.stdout.split())
    seen = {tuple(line.rsplit(": ", 1)[-1].split()) for line in r.stderr.splitlines() if line.startswith("clbeam: ")}
    return (verbose, debug), seen


def levels(seen, name):
    return {level for logger, level in seen if logger == name}


@pytest.mark.parametrize("argv, counts, clbeam_levels", [
    (["docs"], (0, 0), {"warning"}),
    (["docs", "-q"], (0, 0), {"warning"}),
    (["docs", "-v"], (1, 0), {"info", "warning"}),
    (["-v", "docs"], (1, 0), {"info", "warning"}),
    (["docs", "--debug"], (0, 1), {"debug", "info", "warning"}),
    (["--debug", "docs"], (0, 1), {"debug", "info", "warning"}),
])
def test_clbeam_logs_by_level_and_the_libraries_stay_at_warning(argv, counts, clbeam_levels):
    got, seen = logged(*argv)
    assert got == counts
    assert levels(seen, "clbeam.imaging.imager") == clbeam_levels
    for name in LIBRARIES:
        assert levels(seen, name) == {"warning"}, name


@pytest.mark.parametrize("argv", [["docs", "--debug", "--debug"], ["--debug", "docs", "--debug"]])
def test_debug_twice_lets_every_library_log_its_debug_messages(argv):
    got, seen = logged(*argv)
    assert got == (0, 2)  # the main parser's and the subcommand's count add up
    for name in ("clbeam.imaging.imager", *LIBRARIES):
        assert levels(seen, name) == {"debug", "info", "warning"}, name


def test_the_format_names_clbeam_and_the_level():
    r = subprocess.run([sys.executable, "-c", SNIPPET, "docs", "-v"], capture_output=True, text=True, check=True)
    assert "clbeam: INFO: clbeam.imaging.imager info" in r.stderr.splitlines()
