"""The ``clbeam`` command line (docs/cli.md): parse, call the library, report.

Every subcommand is one module of this package with the same four names:
``NAME`` (the subcommand), ``HELP`` (one line), ``add_arguments(parser)``
and ``run(args) -> int``; :func:`build_parser` registers each of
:data:`COMMANDS` the same way and adds ``-q/--quiet``, ``-v/--verbose`` and ``--debug``.  The optional
packages (Dask, pyproj, segyio, numba) are imported only inside ``run``, so
every command's ``--help`` works without them.  Bad input ends in one line
on stderr and exit status 2; long work shows a progress bar on a terminal.
"""

from __future__ import annotations

import argparse
import sys

from clbeam import __version__
from clbeam.cli import (
    avo,
    bench,
    demo,
    detectability,
    devices,
    docs,
    forward,
    image,
    import_segy,
    peaks,
    profile,
    sediment_speed,
    simulate,
    survey,
)
from clbeam.cli.options import add_logging_options, setup_logging
from clbeam.errors import ClbeamError

#: exit status of bad input (one line on stderr)
EXIT_BAD_INPUT = 2
#: the subcommand modules, in the order ``clbeam --help`` lists them
COMMANDS = (devices, image, peaks, simulate, demo, survey, profile, import_segy, avo, forward, sediment_speed, detectability,
            bench, docs)


def register(subparsers, command) -> argparse.ArgumentParser:
    """Add one subcommand module to an ``argparse`` subparsers object."""
    sp = subparsers.add_parser(command.NAME, help=command.HELP, description=getattr(command, "DESCRIPTION", None))
    command.add_arguments(sp)
    add_logging_options(sp)
    sp.set_defaults(func=command.run)
    return sp


def build_parser() -> argparse.ArgumentParser:
    """The ``clbeam`` argument parser with every subcommand."""
    p = argparse.ArgumentParser(prog="clbeam", description="Cross-track imaging of multibeam sub-bottom sonar element data.")
    p.add_argument("--version", action="version", version=f"clbeam {__version__}")
    add_logging_options(p, top=True)
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for command in COMMANDS:
        register(sub, command)
    return p


def main(argv=None) -> int:
    """Entry point of the ``clbeam`` command; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    setup_logging(args)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    try:
        return int(args.func(args) or 0)
    except ClbeamError as exc:
        print(f"clbeam: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("clbeam: interrupted", file=sys.stderr)
        return 130
    except (OSError, MemoryError) as exc:
        if args.debug:
            raise
        print(f"clbeam: error: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    except Exception as exc:  # a bug: one line, the traceback with --debug
        if args.debug:
            raise
        print(f"clbeam: internal error: {type(exc).__name__}: {exc} (rerun with --debug for the traceback)",
              file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
