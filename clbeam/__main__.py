"""``python -m clbeam``: the ``clbeam`` command."""

import sys

from clbeam.cli.main import main

sys.exit(main())
