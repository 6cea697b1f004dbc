"""Deprecated location of the ping-file reader and the ping model; kept for one release.

Use :mod:`clbeam.io` (``PingFile``, ``write_ping_file``) and :mod:`clbeam.model`
(``Ping``, ``Pulse``).
"""

import warnings

from clbeam.io.pingfile import PingFile, open_dataset
from clbeam.io.pingwrite import write_ping_file
from clbeam.model.ping import Ping
from clbeam.model.pulse import Pulse

warnings.warn("clbeam.ping is deprecated: import PingFile and write_ping_file from clbeam.io, Ping and Pulse "
              "from clbeam.model", DeprecationWarning, stacklevel=2)

__all__ = ["Ping", "PingFile", "Pulse", "open_dataset", "write_ping_file"]
