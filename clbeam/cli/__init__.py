"""The ``clbeam`` command line (docs/cli.md)."""

from clbeam.cli.main import build_parser, main

__all__ = ["build_parser", "main"]
