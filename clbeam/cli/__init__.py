"""The ``clbeam`` command line (SPEC §8)."""

from clbeam.cli.main import build_parser, main

__all__ = ["build_parser", "main"]
