"""Subcommands that live beside their modules, registered with the parser.

Each registrar is ``register(subparsers, add_common_options)``.
"""

from __future__ import annotations

REGISTRARS: list = []
