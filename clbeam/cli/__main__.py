"""``python -m clbeam.cli``: the ``clbeam`` command."""

import sys

from clbeam.cli.main import main

sys.exit(main())
