"""The one exception family of clbeam.

Every error a user can cause (a bad file, an impossible option, a missing
device) is a :class:`ClbeamError`; its message is one line that names the
variable, the value found and what was expected.  The command line prints
that line and exits non-zero; library callers catch :class:`ClbeamError`.
"""


class ClbeamError(Exception):
    """Base class of every error clbeam raises on bad input or set-up."""


class PingFileError(ClbeamError):
    """A ping file (docs/ping-format.md) is missing, unreadable or invalid."""


class GeometryError(ClbeamError):
    """Array, source or grid geometry is non-finite or impossible."""


class GridError(ClbeamError):
    """The requested image grid is empty, too large or outside the record."""


class DeviceError(ClbeamError):
    """No usable OpenCL platform or device, or a device cannot run a kernel."""


class OptionError(ClbeamError):
    """An option has a value outside what it accepts."""


class SurveyError(ClbeamError):
    """A survey cannot start or continue (output in use, parameters differ, no input)."""


def require(condition: bool, error: type[ClbeamError], message: str) -> None:
    """Raise ``error(message)`` unless ``condition`` holds."""
    if not condition:
        raise error(message)
