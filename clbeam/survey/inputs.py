"""The inputs of a survey: ping files opened and validated once, in survey order.

Survey pings are numbered through the readable files in the order given; an
unreadable file takes no numbers and is reported by name (:class:`Failure`),
never dropped silently.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

from clbeam.errors import ClbeamError, SurveyError, require
from clbeam.io.pingfile import PingFile

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class InputFile:
    """A readable ping file of the survey.

    Attributes
    ----------
    path : pathlib.Path
        Absolute path.
    index : int
        Position among the readable inputs (``file_index`` of the peaks).
    n_pings : int
        Pings in the file.
    offset : int
        Survey ping number of the file's first ping: survey pings are
        numbered through the readable files in the order given.
    size_bytes : int
        File size (a Zarr folder: the sum of its files), part of the
        parameters a rerun must match.
    max_range_m : float
        Largest one-way range the file's records reach (m).
    """

    path: Path
    index: int
    n_pings: int
    offset: int
    size_bytes: int
    max_range_m: float


@dataclass(frozen=True)
class Failure:
    """An input file, or one ping of it, that could not be imaged.

    Attributes
    ----------
    file : str
        File name.
    ping : int or None
        The ping's index within the file; ``None`` when the whole file is
        unreadable.
    message : str
        What went wrong, one line.
    """

    file: str
    ping: int | None
    message: str

    def __str__(self) -> str:
        where = self.file if self.ping is None else f"{self.file} ping {self.ping}"
        return f"{where}: {self.message}"


@dataclass(frozen=True)
class ScanResult:
    """Inputs of a survey: the readable files and the unreadable ones.

    Attributes
    ----------
    files : tuple of InputFile
        Readable files, in survey order.
    failures : tuple of Failure
        Unreadable files.
    """

    files: tuple
    failures: tuple

    @property
    def n_pings(self) -> int:
        """Pings in all readable files."""
        return sum(f.n_pings for f in self.files)

    @property
    def max_range_m(self) -> float:
        """Largest record range (m) of the readable files."""
        return max(f.max_range_m for f in self.files)


def _size_bytes(path: Path) -> int:
    if path.is_dir():
        return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
    return path.stat().st_size


def scan_inputs(paths, *, stop_on_error: bool = False) -> ScanResult:
    """Open and validate every input ping file once.

    A file that cannot be opened or fails validation (docs/ping-format.md) is logged by
    name and listed in :attr:`ScanResult.failures`; with ``stop_on_error``
    its :class:`~clbeam.errors.ClbeamError` is raised instead.

    Parameters
    ----------
    paths : iterable of path-like
        Ping files (NetCDF4 or Zarr), in survey order.
    stop_on_error : bool
        Raise on the first unreadable file.

    Returns
    -------
    ScanResult

    Raises
    ------
    SurveyError
        A file given twice, or (with ``stop_on_error``) an unreadable one.
    """
    files, failures = [], []
    offset = 0
    seen = set()
    for raw in paths:
        p = Path(raw).resolve()
        require(p not in seen, SurveyError, f"input {p.name} is given twice ({p}); each ping is imaged once")
        seen.add(p)
        try:
            with PingFile(p) as pf:
                n, reach = pf.n_pings, pf.max_record_range_m()
        except Exception as exc:  # any unreadable file: named, never dropped silently
            msg = one_line(exc)
            if stop_on_error:
                raise SurveyError(f"{p.name}: {strip_file_name(msg, p)}") from None
            log.warning("skipping unreadable input %s: %s", p.name, msg)
            failures.append(Failure(p.name, None, strip_file_name(msg, p)))
            continue
        files.append(InputFile(p, len(files), n, offset, _size_bytes(p), reach))
        offset += n
    return ScanResult(tuple(files), tuple(failures))


def one_line(exc: BaseException) -> str:
    """The first line of an exception's message, with its type unless it is a :class:`ClbeamError`."""
    text = str(exc).strip().splitlines()
    msg = text[0] if text else ""
    return msg if isinstance(exc, ClbeamError) else f"{type(exc).__name__}: {msg}"


def strip_file_name(msg: str, path: Path) -> str:
    """``msg`` without a leading ``<path>: `` or ``<name>: `` (the caller names the file)."""
    for prefix in (f"{path}: ", f"{path.name}: "):
        if msg.startswith(prefix):
            return msg[len(prefix):]
    return msg


def sorted_failures(failures, scan: ScanResult) -> list:
    """Failures in survey order: by input file, the whole file first, then by ping."""
    order = {f.path.name: f.index for f in scan.files}
    return sorted(failures, key=lambda f: (order.get(f.file, -1), f.file, -1 if f.ping is None else f.ping))
