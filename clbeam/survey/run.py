"""Whole surveys: many pings imaged into coherence peaks (and images).

A survey is the flow of one ping (:class:`clbeam.imaging.imager.Imager`) mapped over
every ping of many ping files (SPEC §7), streamed one ping at a time so that
memory does not grow with the survey, resumable after any interruption, in
one process or on a Dask cluster, followed by the survey products:

* the coherence peaks of every ping, georeferenced (Holland et al. 2024,
  Section III; SPEC §3 step 7): in the output Zarr store (group ``peaks``)
  and as ``<stem>.peaks.csv`` / ``<stem>.peaks.geojson`` beside it;
* the persistence map of the peaks over the line (paper Figs. 9-10,
  threshold 0.4): ``<stem>.map.png`` (plan view) and
  ``<stem>.persistence.png`` (cross-track offset against ping);
* detections associated across pings into objects (a buried pipeline is a
  line of detections, a false alarm stays alone): group ``objects`` and
  ``<stem>.objects.csv`` / ``<stem>.objects.geojson``;
* with ``images=True``, the images ``intensity``, ``cf``, ``cf_smooth``
  ``(ping, angle, range)``: chunked (one chunk per ping), compressed Zarr in
  the layout of :class:`clbeam.io.images.ImageWriter`.

Resume and no loss
------------------
Each ping, once imaged, is committed by one file
``<OUT>/survey_state/pings/<ping>.json`` (its peaks, navigation and grid
centre) written under a temporary name, flushed and renamed: the rename is
atomic, so the file either is whole or is not there.  Its image chunks (if
any) are written before it.  The set of these files is the ledger of done
pings; a rerun images only the others, and rewrites a ping whose image
chunks a kill cut short (its ledger file was never renamed into place).
The products are rebuilt from the ledger at the end of every run, so they
never hold a ping twice or miss a committed one.  The processing
parameters are stored in the output; a rerun with different ones stops
with a one-line error unless ``restart=True`` (``--restart``).

See ``docs/survey.md`` for the command line, the file layout, running on a
cluster and the association rule.
"""

from __future__ import annotations

import array
import contextlib
import csv
import dataclasses
import errno
import fcntl
import hashlib
import json
import logging
import math
import os
import re
import shutil
import threading
import time
import uuid
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from clbeam import __version__
from clbeam.errors import ClbeamError, OptionError, require
from clbeam.imaging.imager import Imager, ImagingOptions, check_grid_fits_memory
from clbeam.io.images import ImageWriter, image_arrays
from clbeam.io.peaks import PEAK_COLUMNS
from clbeam.io.pingfile import PingFile
from clbeam.io.schema import image_variables
from clbeam.model.grid import PolarGrid

log = logging.getLogger(__name__)

SURVEY_FORMAT = "survey-1"
"""Value of the root attribute ``clbeam_survey`` of a survey store."""
STATE_DIR = "survey_state"
"""Folder, inside the output store, of the resume state."""
LEDGER_DIR = f"{STATE_DIR}/pings"
"""Folder of the per-ping ledger files ``<ping:09d>.json``."""
DEFAULT_MAP_THRESHOLD = 0.4
"""CF threshold of the persistence map and of the association (paper Figs. 9-10)."""
PEAK_BLOCK_ROWS = 65536
"""Peak rows buffered before they are appended to the products."""

_LEDGER_NAME = re.compile(r"^(\d{9})\.json$")
_EPOCH = np.datetime64(0, "ns")


class SurveyError(ClbeamError):
    """A survey cannot start or continue (output in use, parameters differ, no input)."""


# ---------------------------------------------------------------------------
# Inputs
# ---------------------------------------------------------------------------
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

    ``ping`` is the ping's index within the file, ``None`` when the whole
    file is unreadable.
    """

    file: str
    ping: int | None
    message: str

    def __str__(self) -> str:
        where = self.file if self.ping is None else f"{self.file} ping {self.ping}"
        return f"{where}: {self.message}"


@dataclass(frozen=True)
class ScanResult:
    """Inputs of a survey: the readable files and the unreadable ones."""

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

    A file that cannot be opened or fails validation (SPEC §7) is logged by
    name and listed in :attr:`ScanResult.failures`; with ``stop_on_error``
    its :class:`~clbeam.errors.ClbeamError` is raised instead.

    Parameters
    ----------
    paths : iterable of path-like
        Ping files (NetCDF4 or Zarr), in survey order.
    stop_on_error : bool
        Raise on the first unreadable file.

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
            msg = _one_line(exc)
            if stop_on_error:
                raise SurveyError(f"{p.name}: {_strip_name(msg, p)}") from None
            log.warning("skipping unreadable input %s: %s", p.name, msg)
            failures.append(Failure(p.name, None, _strip_name(msg, p)))
            continue
        files.append(InputFile(p, len(files), n, offset, _size_bytes(p), reach))
        offset += n
    return ScanResult(tuple(files), tuple(failures))


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    msg = text[0] if text else ""
    return msg if isinstance(exc, ClbeamError) else f"{type(exc).__name__}: {msg}"


def _strip_name(msg: str, path: Path) -> str:
    for prefix in (f"{path}: ", f"{path.name}: "):
        if msg.startswith(prefix):
            return msg[len(prefix):]
    return msg


# ---------------------------------------------------------------------------
# Options and parameters
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class AssociationOptions:
    """How detections are associated across pings into objects.

    Two detections (coherence peaks with CF above ``threshold``) of pings
    ``i < j`` are linked when ``j - i <= max_gap_pings + 1``, their
    horizontal separation measured across the track of ping ``j`` (easting
    and northing projected on ping ``j``'s starboard direction; without
    navigation, the difference of their cross-track offsets ``y``) is at
    most ``link_distance_m`` and their depths ``z`` differ by at most
    ``depth_tolerance_m``.  Linked detections form groups (connected
    components); a group spanning at least ``min_pings`` distinct pings is
    an object, the rest stay isolated (object ``-1``).

    Attributes
    ----------
    threshold : float
        CF threshold (paper Figs. 9-10: 0.4).
    link_distance_m : float
        Largest cross-track separation of linked detections (m).  An object
        crossing the track at an angle ``a`` moves ``spacing tan(a)``
        across per ping: the default 3 m follows lines up to about 20
        degrees off the track at 8 m ping spacing.
    depth_tolerance_m : float
        Largest depth difference of linked detections (m).
    max_gap_pings : int
        Pings without a detection a line may skip.
    min_pings : int
        Distinct pings an object needs.
    """

    threshold: float = DEFAULT_MAP_THRESHOLD
    link_distance_m: float = 3.0
    depth_tolerance_m: float = 3.0
    max_gap_pings: int = 2
    min_pings: int = 5

    def __post_init__(self):
        require(0 <= self.threshold <= 1, OptionError, f"map threshold must be within 0-1, got {self.threshold!r}")
        require(self.link_distance_m > 0, OptionError, f"link distance must be > 0 m, got {self.link_distance_m!r}")
        require(self.depth_tolerance_m > 0, OptionError, f"link depth must be > 0 m, got {self.depth_tolerance_m!r}")
        require(int(self.max_gap_pings) == self.max_gap_pings and self.max_gap_pings >= 0, OptionError,
                f"max gap must be an integer >= 0 pings, got {self.max_gap_pings!r}")
        require(int(self.min_pings) == self.min_pings and self.min_pings >= 1, OptionError,
                f"min pings must be an integer >= 1, got {self.min_pings!r}")


@dataclass(frozen=True)
class SurveyOptions:
    """Everything a survey run needs besides its inputs and output.

    Attributes
    ----------
    grid : PolarGrid
        Image grid of every ping.
    imaging : ImagingOptions
        Mode, outputs (must include ``"cf"``), peak threshold, seabed band …
    backend : {"opencl", "reference"}
        Imaging engine.
    device : str or int or None
        OpenCL device (index or name substring); not part of the stored
        parameters (every device runs the same kernels).
    images : bool
        Also write the images (``intensity``, ``cf``, ``cf_smooth``; the raw
        sums with ``"sums"`` in the outputs).
    block_pings : int
        Pings per task (Dask) and per progress step.
    association : AssociationOptions
        Map threshold and association rule (products only: a rerun may
        change them without ``restart``).
    speed_m_s : float or None
        Ship speed (m/s) for the along-track distance of pings without
        navigation: ``speed x (ping time - first ping time)``.
    """

    grid: PolarGrid
    imaging: ImagingOptions = field(default_factory=ImagingOptions)
    backend: str = "opencl"
    device: object = None
    images: bool = False
    block_pings: int = 8
    association: AssociationOptions = field(default_factory=AssociationOptions)
    speed_m_s: float | None = None

    def __post_init__(self):
        require("cf" in self.imaging.outputs, OptionError,
                f"outputs {','.join(self.imaging.outputs)} lack 'cf': a survey always writes the coherence peaks")
        require(self.backend in ("opencl", "reference"), OptionError,
                f"backend '{self.backend}' is unknown, expected 'opencl' or 'reference'")
        require(int(self.block_pings) == self.block_pings and self.block_pings >= 1, OptionError,
                f"block pings must be an integer >= 1, got {self.block_pings!r}")
        require(self.speed_m_s is None or (math.isfinite(self.speed_m_s) and self.speed_m_s > 0), OptionError,
                f"speed must be > 0 m/s, got {self.speed_m_s!r}")

    @property
    def image_variables(self) -> list:
        """Image variables written with ``images=True`` (:func:`clbeam.io.schema.image_variables`)."""
        if not self.images:
            return []
        return image_variables(self.imaging.outputs, apodized=self.imaging.apodization != "rect")


def _axis_summary(a: np.ndarray) -> dict:
    return {"first": float(a[0]), "last": float(a[-1]), "n": int(a.size),
            "sha1": hashlib.sha1(np.ascontiguousarray(a, dtype=np.float64).tobytes()).hexdigest()[:16]}


def survey_parameters(scan: ScanResult, options: SurveyOptions) -> dict:
    """The processing parameters a survey store is bound to.

    A rerun must give the same values (``restart`` otherwise): the grid,
    the imaging options, the backend, whether images are written, and the
    readable inputs (name, pings, size in bytes).  Device, workers, block
    size and the product options are free to change.
    """
    g = options.grid
    imaging = {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(options.imaging).items()}
    return {
        "format": SURVEY_FORMAT,
        "grid": {"ranges_m": _axis_summary(g.ranges_m), "angles_deg": _axis_summary(g.angles_deg),
                 "centre_yz_m": None if g.centre_yz_m is None else list(g.centre_yz_m)},
        "imaging": imaging,
        "backend": options.backend,
        "images": options.image_variables,
        "inputs": [{"name": f.path.name, "n_pings": f.n_pings, "size_bytes": f.size_bytes} for f in scan.files],
    }


def _first_difference(stored, now, where="") -> str | None:
    if isinstance(stored, dict) and isinstance(now, dict):
        for k in list(stored) + [k for k in now if k not in stored]:
            d = _first_difference(stored.get(k), now.get(k), f"{where}.{k}" if where else k)
            if d:
                return d
        return None
    if isinstance(stored, list) and isinstance(now, list) and len(stored) == len(now):
        for i, (a, b) in enumerate(zip(stored, now)):
            d = _first_difference(a, b, f"{where}[{i}]")
            if d:
                return d
        return None
    if stored != now:
        def show(v):
            s = json.dumps(v)
            return s if len(s) <= 60 else s[:57] + "..."
        return f"{where}: {show(stored)} in the output, {show(now)} now"
    return None


# ---------------------------------------------------------------------------
# The output store and its ledger
# ---------------------------------------------------------------------------
def product_paths(output) -> dict:
    """Paths of the products written beside the store ``output`` (``X.zarr``
    gives ``X.peaks.csv``, ``X.peaks.geojson``, ``X.objects.csv``,
    ``X.objects.geojson``, ``X.map.png``, ``X.persistence.png``)."""
    out = Path(output)
    stem = out.with_suffix("")
    names = ("peaks.csv", "peaks.geojson", "objects.csv", "objects.geojson", "map.png", "persistence.png")
    return {n.replace(".", "_"): Path(f"{stem}.{n}") for n in names}


def is_survey_store(path) -> bool:
    """True when ``path`` is a survey store written by :func:`run_survey`."""
    p = Path(path)
    try:
        meta = json.loads((p / "zarr.json").read_text())
    except (OSError, ValueError):
        return False
    return meta.get("attributes", {}).get("clbeam_survey") == SURVEY_FORMAT


def _read_root_attrs(path: Path) -> dict:
    return json.loads((path / "zarr.json").read_text()).get("attributes", {})


def _consolidate(path: Path) -> None:
    import zarr

    with warnings.catch_warnings():
        # the resume state is a plain folder inside the store: zarr notes it and moves on
        warnings.simplefilter("ignore")
        zarr.consolidate_metadata(str(path))


def _write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically: temporary name, flush, fsync, rename."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}")
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def ledger_path(output, ping: int) -> Path:
    """Ledger file of survey ping ``ping`` in the store ``output``."""
    return Path(output) / LEDGER_DIR / f"{ping:09d}.json"


def done_pings(output, *, validate: bool = False) -> set:
    """Survey pings committed to the ledger of ``output``.

    With ``validate``, every ledger file is parsed; one that does not parse
    (only possible after a machine crash, not a process kill) is removed so
    that its ping is imaged again.
    """
    d = Path(output) / LEDGER_DIR
    done = set()
    if not d.is_dir():
        return done
    for entry in os.scandir(d):
        m = _LEDGER_NAME.match(entry.name)
        if not m:
            continue
        if validate:
            try:
                with open(entry.path, "rb") as fh:
                    rec = json.load(fh)
                require(rec.get("ping") == int(m.group(1)), SurveyError, "ping number mismatch")
            except (OSError, ValueError, ClbeamError) as exc:
                log.warning("ledger file %s is unreadable (%s): ping %d will be imaged again", entry.name, exc,
                            int(m.group(1)))
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)
                continue
        done.add(int(m.group(1)))
    return done


def _clean_temporaries(output: Path) -> None:
    d = output / LEDGER_DIR
    if d.is_dir():
        for entry in os.scandir(d):
            if entry.name.startswith(".") and ".tmp-" in entry.name:
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)
    for leftover in output.parent.glob(f".{output.name}.creating-*"):
        m = re.search(r"creating-(\d+)-", leftover.name)
        if m and not _pid_alive(int(m.group(1))):
            shutil.rmtree(leftover, ignore_errors=True)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except OSError as exc:
        return exc.errno == errno.EPERM
    return True


class _Lock:
    """An exclusive ``flock`` on the store's lock file for the whole run (freed
    by the kernel when the process dies, even by ``kill -9``)."""

    def __init__(self, output: Path):
        self.path = output / STATE_DIR / "lock"
        self.fh = open(self.path, "a+")
        try:
            fcntl.flock(self.fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self.fh.close()
            raise SurveyError(f"{output.name} is in use by another clbeam survey; wait for it to end") from None
        self.fh.seek(0)
        self.fh.truncate()
        self.fh.write(f"{os.getpid()}\n")
        self.fh.flush()

    def release(self) -> None:
        if self.fh is not None:
            fcntl.flock(self.fh.fileno(), fcntl.LOCK_UN)
            self.fh.close()
            self.fh = None


_PER_PING_EXTRA = {
    "imaged": ("ping imaged and committed to the ledger", None, bool),
    "time": ("time of transmission (UTC)", None, np.float64),
    "file_index": ("index of the ping's input file (attribute input_files)", "1", np.int32),
    "file_ping": ("index of the ping within its input file", "1", np.int32),
    "n_peaks": ("coherence peaks of the ping", "1", np.int32),
}


def _create_store(output: Path, scan: ScanResult, options: SurveyOptions, params: dict) -> None:
    """Create the store in a temporary folder beside ``output`` and rename it
    into place, so that a store either exists whole or not at all."""
    import xarray as xr

    tmp = output.parent / f".{output.name}.creating-{os.getpid()}-{uuid.uuid4().hex[:8]}.zarr"
    attrs = {"clbeam_survey": SURVEY_FORMAT, "survey_parameters": json.dumps(params),
             "clbeam_version": __version__, "input_files": json.dumps([f.path.name for f in scan.files]),
             "survey_complete": False, "source": "clbeam survey"}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ImageWriter(tmp, options.grid, scan.n_pings, options.image_variables, attrs).close()
            n = scan.n_pings
            extra = {}
            for name, (long_name, units, dtype) in _PER_PING_EXTRA.items():
                if dtype is bool:
                    data = np.zeros(n, dtype=bool)
                elif dtype is np.float64:
                    data = np.full(n, np.nan)
                else:
                    data = np.full(n, -1, dtype=dtype)
                a = {"long_name": long_name}
                if units:
                    a["units"] = units
                if name == "time":
                    a.update(units="seconds since 1970-01-01T00:00:00", calendar="proleptic_gregorian")
                extra[name] = (("ping",), data, a)
            # xarray's append mode replaces the root attributes with the dataset's: give them again
            xr.Dataset(extra, attrs=attrs).to_zarr(tmp, mode="a", consolidated=False)
        _consolidate(tmp)
        require(is_survey_store(tmp), SurveyError, f"{output.name}: the new store lacks its attributes")
        (tmp / LEDGER_DIR).mkdir(parents=True)
        (tmp / STATE_DIR / "parameters.json").write_text(json.dumps(params, indent=1) + "\n")
        os.rename(tmp, output)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _remove_outputs(output: Path) -> None:
    shutil.rmtree(output)
    for p in product_paths(output).values():
        with contextlib.suppress(FileNotFoundError):
            p.unlink()


def _open_or_create(output: Path, scan: ScanResult, options: SurveyOptions, *, restart: bool) -> _Lock:
    """Check or create the store; returns the held lock."""
    params = survey_parameters(scan, options)
    require(output.suffix == ".zarr", SurveyError, f"output {output.name} must end in .zarr (a Zarr store)")
    if output.exists():
        require(is_survey_store(output), SurveyError,
                f"{output.name} exists and is not a clbeam survey store; choose another output "
                "(it is never overwritten, not even with --restart)")
        lock = _Lock(output)
        stored = json.loads(_read_root_attrs(output).get("survey_parameters", "{}"))
        diff = _first_difference(stored, params)
        if not restart:
            if diff is None:
                return lock
            lock.release()
            raise SurveyError(f"{output.name} was made with other parameters ({diff}); "
                              "rerun with --restart to discard it and start again")
        log.warning("restart: discarding %s%s", output.name, f" ({diff})" if diff else "")
        _remove_outputs(output)
        lock.release()
    elif restart:
        for p in product_paths(output).values():
            with contextlib.suppress(FileNotFoundError):
                p.unlink()
    _create_store(output, scan, options, params)
    return _Lock(output)


# ---------------------------------------------------------------------------
# One block of pings (runs in this process or on a Dask worker)
# ---------------------------------------------------------------------------
STAGES = ("read_s", "compress_s", "image_s", "peaks_s", "write_s")
"""Stages of the time split: read the ping, pulse compression (and the
analytic signal, roll correction), the imaging kernel, CF smoothing and
peak picking, writing images and the ledger."""


@dataclass(frozen=True)
class BlockTask:
    """Pings of one file for one task; small and picklable (no engine)."""

    output: str
    file_path: str
    file_index: int
    offset: int
    pings: tuple
    grid: PolarGrid
    imaging: ImagingOptions
    backend: str
    device: object
    variables: tuple
    engine_key: str
    stop_on_error: bool = False


@dataclass
class BlockResult:
    """What a block did: pings committed, failures, seconds per stage."""

    done: list = field(default_factory=list)
    skipped: int = 0
    failures: list = field(default_factory=list)
    timings_s: dict = field(default_factory=lambda: dict.fromkeys(STAGES, 0.0))


_local = threading.local()


def _thread_imager(task: BlockTask) -> Imager:
    """The Imager of this thread, built once per thread and parameters.

    A Dask worker runs tasks on its own threads, so each worker (thread)
    creates its OpenCL context and compiles its program once, on its first
    task; the engine never travels between processes.
    """
    cache = getattr(_local, "imagers", None)
    if cache is None:
        cache = _local.imagers = {}
    imager = cache.get(task.engine_key)
    if imager is None:
        cache.clear()
        imager = cache[task.engine_key] = Imager(task.grid, task.imaging, backend=task.backend, device=task.device)
    return imager


def _iso(t) -> str | None:
    return None if t is None or np.isnat(t) else str(np.datetime64(t, "ns"))


def ping_record(img, ping, survey_ping: int, file_index: int) -> dict:
    """The ledger record of one imaged ping: navigation, grid centre and its
    peaks (the :data:`clbeam.io.peaks.PEAK_COLUMNS` besides ``ping``)."""
    keys = [k for k in PEAK_COLUMNS if k != "ping"]
    return {
        "ping": survey_ping, "file_index": file_index, "file_ping": ping.index,
        "latitude_deg": ping.latitude_deg, "longitude_deg": ping.longitude_deg, "heading_deg": ping.heading_deg,
        "time": _iso(ping.time), "centre_y_m": float(img.centre_yz_m[0]), "centre_z_m": float(img.centre_yz_m[1]),
        "n_channels_used": int(img.n_channels_used),
        "peaks": [{k: float(r[k]) for k in keys} for r in img.peaks],
    }


def process_block(task: BlockTask, on_ping=None) -> BlockResult:
    """Image the pings of ``task`` and commit each to the ledger.

    For each ping not yet in the ledger: read, image, write its image chunks
    (one chunk per variable, a region no other ping shares), then write its
    ledger file atomically.  A ping that cannot be read or imaged is logged
    and listed in the result (with ``stop_on_error`` the block stops there).

    Parameters
    ----------
    task : BlockTask
        Which pings, and how.
    on_ping : callable, optional
        Called with 1 after each ping (progress in a single process).
    """
    res = BlockResult()
    out = Path(task.output)
    imager = _thread_imager(task)
    group = None
    if task.variables:
        import zarr

        group = zarr.open_group(str(out), mode="r+")
    name = Path(task.file_path).name
    pings = None
    try:
        for i in task.pings:
            g = task.offset + i
            rec_path = ledger_path(out, g)
            if rec_path.exists():  # committed by an earlier run, or by a first try of this task
                res.skipped += 1
                if on_ping:
                    on_ping(1)
                continue
            t0 = time.perf_counter()
            try:
                if pings is None:
                    pings = PingFile(task.file_path)
                ping = pings.ping(i)
                t1 = time.perf_counter()
                img = imager.image(ping)
                t2 = time.perf_counter()
                if group is not None:
                    arrays = image_arrays(img)
                    for v in task.variables:
                        group[v][g] = arrays[v]
                _write_atomic(rec_path, json.dumps(ping_record(img, ping, g, task.file_index)).encode())
                t3 = time.perf_counter()
            except Exception as exc:  # an unreadable or unimageable ping: reported, never dropped silently
                if pings is not None:  # reopen for the next ping: a failed read may leave the file in a bad state
                    pings.close()
                    pings = None
                msg = _strip_name(_one_line(exc), Path(task.file_path))
                log.warning("%s ping %d: not imaged: %s", name, i, msg)
                res.failures.append(Failure(name, i, msg))
                if on_ping:
                    on_ping(1)
                if task.stop_on_error:
                    break
                continue
            ts = img.timings_s
            res.timings_s["read_s"] += t1 - t0
            res.timings_s["compress_s"] += ts.get("compress_s", 0.0)
            res.timings_s["image_s"] += ts.get("image_s", 0.0)
            res.timings_s["peaks_s"] += ts.get("postprocess_s", 0.0)
            res.timings_s["write_s"] += t3 - t2
            res.done.append(g)
            if on_ping:
                on_ping(1)
    finally:
        if pings is not None:
            pings.close()
    return res


def _blocks(scan: ScanResult, pending: set, block: int) -> list:
    """``(file, pings)`` runs of at most ``block`` pending pings of one file."""
    out = []
    for f in scan.files:
        todo = [i for i in range(f.n_pings) if f.offset + i in pending]
        for k in range(0, len(todo), block):
            out.append((f, tuple(todo[k:k + block])))
    return out


# ---------------------------------------------------------------------------
# The run
# ---------------------------------------------------------------------------
@dataclass
class SurveyResult:
    """Outcome of :func:`run_survey`.

    Attributes
    ----------
    output : pathlib.Path
        The store.
    n_pings : int
        Pings in the readable inputs.
    n_done_before : int
        Pings already in the ledger when the run started.
    n_imaged : int
        Pings imaged by this run.
    failures : list of Failure
        Unreadable files and pings not imaged (retried by a rerun).
    wall_s : float
        Seconds imaging, from the first task to the last result (without
        starting a Dask cluster and without the products).
    timings_s : dict
        Seconds per stage (:data:`STAGES`) summed over the pings of this
        run (over all workers with Dask; a task lost with its worker is
        not counted).
    products : SurveyProducts or None
        What :func:`finalize_survey` wrote.
    workers : int
        Dask workers used (0: this process).
    n_timed : int
        Pings whose stage times are in ``timings_s``.
    """

    output: Path
    n_pings: int
    n_done_before: int
    n_imaged: int
    failures: list
    wall_s: float
    timings_s: dict
    products: "SurveyProducts | None" = None
    workers: int = 0
    n_timed: int = 0

    @property
    def time_per_ping_s(self) -> dict:
        """Mean seconds per ping of each stage (:data:`STAGES`)."""
        return {k: (v / self.n_timed if self.n_timed else float("nan")) for k, v in self.timings_s.items()}

    @property
    def pings_per_s(self) -> float:
        """Pings imaged per second of wall time by this run."""
        return self.n_imaged / self.wall_s if self.wall_s > 0 else float("nan")

    @property
    def complete(self) -> bool:
        """Every ping of the readable inputs is in the ledger and no input failed."""
        return self.products is not None and self.products.n_imaged == self.n_pings and not self.failures


def run_survey(inputs, output, options: SurveyOptions, *, workers: int | None = None, scheduler: str | None = None,
               restart: bool = False, stop_on_error: bool = False, progress=None) -> SurveyResult:
    """Image a survey into ``output`` (a ``.zarr`` store) and write its products.

    Parameters
    ----------
    inputs : sequence of path-like, or ScanResult
        Ping files in survey order (or the result of :func:`scan_inputs`).
    output : path-like
        Survey store (``.zarr``), created or continued.
    options : SurveyOptions
        Grid, imaging, images, products.
    workers : int, optional
        Start a Dask ``LocalCluster`` with this many worker processes (one
        thread each).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); the
        workers must see the inputs and the output at the same paths.
    restart : bool
        Discard an existing survey store (with its products) and start
        again; without it, a store made with other parameters is refused.
        A folder that is not a survey store is never removed.
    stop_on_error : bool
        Stop at the first unreadable file or ping (:class:`SurveyError`)
        instead of reporting and skipping it.
    progress : callable, optional
        ``progress(total)`` returns a bar with ``update(n)`` and ``close()``
        (e.g. :func:`clbeam.cli.main.progress`).

    Returns
    -------
    SurveyResult
    """
    scan = inputs if isinstance(inputs, ScanResult) else scan_inputs(inputs, stop_on_error=stop_on_error)
    require(bool(scan.files), SurveyError,
            "no readable input file" + (f" ({'; '.join(map(str, scan.failures))})" if scan.failures else ""))
    require(workers is None or (int(workers) == workers and workers >= 1), OptionError,
            f"workers must be an integer >= 1, got {workers!r}")
    require(workers is None or scheduler is None, OptionError, "give --workers or --scheduler, not both")
    check_grid_fits_memory(options.grid, options.imaging)
    output = Path(output).absolute()
    lock = _open_or_create(output, scan, options, restart=restart)
    try:
        _clean_temporaries(output)
        done = done_pings(output, validate=True)
        pending = set(range(scan.n_pings)) - done
        params = survey_parameters(scan, options)
        key = hashlib.sha1(json.dumps([params["grid"], params["imaging"], options.backend, repr(options.device)],
                                      sort_keys=True).encode()).hexdigest()
        tasks = [BlockTask(str(output), str(f.path), f.index, f.offset, pings, options.grid, options.imaging,
                           options.backend, options.device, tuple(options.image_variables), key, stop_on_error)
                 for f, pings in _blocks(scan, pending, options.block_pings)]
        bar = progress(len(pending)) if progress else None
        try:
            if workers is None and scheduler is None:
                t0 = time.perf_counter()
                results = _run_here(tasks, bar, stop_on_error)
                n_workers, wall = 0, time.perf_counter() - t0
            else:
                results, n_workers, wall = _run_dask(tasks, bar, stop_on_error, workers=workers, scheduler=scheduler)
        finally:
            if bar is not None:
                bar.close()
        timings = dict.fromkeys(STAGES, 0.0)
        failures = list(scan.failures)
        for r in results:
            failures.extend(r.failures)
            for k in STAGES:
                timings[k] += r.timings_s[k]
        failures = _sorted_failures(failures, scan)
        if stop_on_error and failures:
            raise SurveyError(f"stopped at {failures[0]} (without --stop-on-error it is reported and skipped)")
        # counted from the ledger: a task Dask retried after losing its worker finds the pings the
        # first try committed already done, and the first try's result never arrives
        n_imaged = len(done_pings(output) - done)
        result = SurveyResult(output, scan.n_pings, len(done), n_imaged, failures, wall, timings, workers=n_workers,
                              n_timed=sum(len(r.done) for r in results))
        result.products = finalize_survey(output, options, failures=failures)
        return result
    finally:
        lock.release()


def _sorted_failures(failures: list, scan: ScanResult) -> list:
    order = {f.path.name: f.index for f in scan.files}
    return sorted(failures, key=lambda f: (order.get(f.file, -1), f.file, -1 if f.ping is None else f.ping))


def _run_here(tasks: list, bar, stop_on_error: bool) -> list:
    results = []
    update = bar.update if bar is not None else None
    for t in tasks:
        r = process_block(t, on_ping=update)
        results.append(r)
        if stop_on_error and r.failures:
            break
    return results


def _run_dask(tasks: list, bar, stop_on_error: bool, *, workers, scheduler) -> tuple:
    """Run the blocks on a Dask cluster: a new ``LocalCluster`` of ``workers``
    processes, or the scheduler at ``scheduler``."""
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:  # pragma: no cover - the survey extra is a declared dependency
        raise SurveyError("--workers/--scheduler need dask[distributed] (pip install 'clbeam[survey]')") from None
    t_start = time.perf_counter()
    with contextlib.ExitStack() as stack:
        if scheduler is None:
            import dask

            # Dask sets MALLOC_TRIM_THRESHOLD_ in its workers, which turns off glibc's adaptive mmap
            # threshold: every ping's arrays are then fresh pages, faulted in again (twice the time per
            # ping on the benchmark).  The workers keep the allocator's defaults instead.
            with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
                cluster = stack.enter_context(LocalCluster(n_workers=int(workers), threads_per_worker=1,
                                                           processes=True, dashboard_address=None,
                                                           silence_logs=logging.ERROR))
            client = stack.enter_context(Client(cluster))
        else:
            try:
                client = stack.enter_context(Client(scheduler, timeout="30s"))
            except OSError as exc:
                raise SurveyError(f"cannot reach the Dask scheduler at {scheduler}: {_one_line(exc)}") from None
        n_workers = len(client.scheduler_info().get("workers", {}))
        log.info("Dask: %d worker(s), %d task(s), connected in %.1f s", n_workers, len(tasks),
                 time.perf_counter() - t_start)
        t_start = time.perf_counter()
        futures = [client.submit(process_block, t, key=f"clbeam-survey-{t.offset + t.pings[0]}-{uuid.uuid4().hex[:8]}",
                                 pure=False) for t in tasks]
        results = []
        try:
            for fut in as_completed(futures):
                r = fut.result()
                results.append(r)
                if bar is not None:
                    bar.update(len(r.done) + r.skipped + len(r.failures))
                if stop_on_error and r.failures:
                    break
        finally:
            for fut in futures:
                if not fut.done():
                    fut.cancel()
        return results, n_workers, time.perf_counter() - t_start


# ---------------------------------------------------------------------------
# Georeferencing
# ---------------------------------------------------------------------------
def utm_epsg(latitude_deg: float, longitude_deg: float) -> int:
    """EPSG code of the standard UTM zone (WGS84) holding a position: 326zz
    north of the equator, 327zz south, zone ``floor((lon + 180) / 6) + 1``
    (the Norway and Svalbard exceptions are not applied)."""
    zone = int(math.floor((((longitude_deg + 180.0) % 360.0)) / 6.0)) + 1
    return (32600 if latitude_deg >= 0 else 32700) + min(zone, 60)


def peak_positions(latitude_deg, longitude_deg, heading_deg, y_m):
    """Latitude and longitude of points ``y_m`` to starboard of ping positions.

    The cross-track plane of a ping is vertical and perpendicular to its
    heading, so a point ``y`` metres to starboard (SPEC §2) lies at
    horizontal distance ``|y|`` along the azimuth ``heading + 90`` degrees
    (``heading - 90`` for port, ``y < 0``), measured clockwise from true
    north.  The point is found on the WGS84 ellipsoid along that geodesic
    (:meth:`pyproj.Geod.fwd`), which avoids the grid convergence of a
    projected offset (about 1.7 degrees three degrees off a UTM central
    meridian at 34 degrees north: 17 m at 600 m).

    Parameters
    ----------
    latitude_deg, longitude_deg : array_like
        Ping positions (degree).
    heading_deg : array_like
        Ping headings, clockwise from true north (degree).
    y_m : array_like
        Cross-track offsets, positive to starboard (m).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Latitude and longitude (degree) of the points.
    """
    import pyproj

    lat, lon, hdg, y = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64)
                                             for a in (latitude_deg, longitude_deg, heading_deg, y_m)))
    out_lat, out_lon = np.full(lat.shape, np.nan), np.full(lat.shape, np.nan)
    ok = np.isfinite(lat) & np.isfinite(lon) & np.isfinite(hdg) & np.isfinite(y)
    if ok.any():
        az = np.where(y[ok] >= 0, hdg[ok] + 90.0, hdg[ok] - 90.0)
        lon2, lat2, _ = pyproj.Geod(ellps="WGS84").fwd(lon[ok], lat[ok], az, np.abs(y[ok]))
        out_lat[ok], out_lon[ok] = lat2, lon2
    return out_lat, out_lon


def to_utm(latitude_deg, longitude_deg, epsg: int):
    """Easting and northing (m) in the UTM zone ``epsg`` (pyproj)."""
    import pyproj

    tr = pyproj.Transformer.from_crs("EPSG:4326", f"EPSG:{epsg}", always_xy=True)
    lon, lat = np.asarray(longitude_deg, dtype=np.float64), np.asarray(latitude_deg, dtype=np.float64)
    e, n = tr.transform(lon, lat)
    e, n = np.asarray(e, dtype=np.float64), np.asarray(n, dtype=np.float64)
    bad = ~(np.isfinite(lat) & np.isfinite(lon))
    e[bad] = np.nan
    n[bad] = np.nan
    return e, n


def course_over_ground_deg(easting_m, northing_m) -> np.ndarray:
    """Course over ground (degree clockwise from grid north) of a track, from
    central differences of consecutive positions (one-sided at the ends);
    NaN where a ping has no neighbour with a position."""
    e, n = np.asarray(easting_m, dtype=np.float64), np.asarray(northing_m, dtype=np.float64)
    out = np.full(e.shape, np.nan)
    idx = np.flatnonzero(np.isfinite(e) & np.isfinite(n))
    if idx.size < 2:
        return out
    ee, nn = e[idx], n[idx]
    de, dn = np.gradient(ee), np.gradient(nn)
    out[idx] = np.rad2deg(np.arctan2(de, dn)) % 360.0
    return out


# ---------------------------------------------------------------------------
# Association of detections across pings
# ---------------------------------------------------------------------------
def associate(ping, position_m, starboard, z_m, options: AssociationOptions | None = None) -> np.ndarray:
    """Associate detections across pings into objects (see :class:`AssociationOptions`).

    Parameters
    ----------
    ping : array_like of int
        ``(n,)`` survey ping of each detection.
    position_m : array_like
        ``(n, 2)`` horizontal positions (m): easting and northing, or
        along- and across-track distance.
    starboard : array_like
        ``(n, 2)`` unit vectors to starboard of each detection's ping in the
        same frame (``(cos h, -sin h)`` in easting/northing for heading
        ``h``; ``(0, 1)`` in along/across).
    z_m : array_like
        ``(n,)`` depths (m).
    options : AssociationOptions, optional

    Returns
    -------
    numpy.ndarray
        ``(n,)`` int: object number (0, 1, … ordered by first ping, then
        mean position) or -1 for a detection left alone.
    """
    import scipy.sparse
    from scipy.sparse.csgraph import connected_components

    o = options or AssociationOptions()
    p = np.asarray(ping, dtype=np.int64)
    pos = np.asarray(position_m, dtype=np.float64).reshape(-1, 2)
    sb = np.asarray(starboard, dtype=np.float64).reshape(-1, 2)
    z = np.asarray(z_m, dtype=np.float64)
    n = p.size
    labels = np.full(n, -1, dtype=np.int64)
    if n == 0:
        return labels
    order = np.argsort(p, kind="stable")
    ps = p[order]
    pings, starts = np.unique(ps, return_index=True)
    ends = np.r_[starts[1:], n]
    rows, cols = [], []
    reach = int(o.max_gap_pings) + 1
    for k, pk in enumerate(pings):
        b = order[starts[k]:ends[k]]
        lo = np.searchsorted(pings, pk - reach)
        if lo == k:
            continue
        a = order[starts[lo]:starts[k]]
        d = pos[b][:, None, :] - pos[a][None, :, :]
        s = sb[b][:, None, :]
        # a frame axis the starboard vector does not use (e.g. an unknown along-track distance) adds nothing
        across = np.abs(np.where(s == 0, 0.0, d * s).sum(axis=-1))
        dz = np.abs(z[b][:, None] - z[a][None, :])
        ok = np.isfinite(across) & (across <= o.link_distance_m) & (dz <= o.depth_tolerance_m)
        ib, ia = np.nonzero(ok)
        rows.append(b[ib])
        cols.append(a[ia])
    if rows:
        r, c = np.concatenate(rows), np.concatenate(cols)
    else:
        r = c = np.zeros(0, dtype=np.int64)
    graph = scipy.sparse.coo_matrix((np.ones(r.size), (r, c)), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    keep = []
    for lab in np.unique(comp):
        m = comp == lab
        if np.unique(p[m]).size >= o.min_pings:
            keep.append((int(p[m].min()), float(np.nanmean(pos[m, 0])), float(np.nanmean(pos[m, 1])), lab))
    keep.sort(key=lambda t: (t[0], np.nan_to_num(t[1]), np.nan_to_num(t[2])))
    for num, (*_, lab) in enumerate(keep):
        labels[comp == lab] = num
    return labels


def describe_objects(labels, ping, position_m, cf, y_m, z_m) -> list:
    """One row per object: ``object``, ``n_pings``, ``n_detections``,
    ``first_ping``, ``last_ping``, ``length_m`` (the polyline through the
    per-ping mean positions, in ping order), ``mean_cf``, ``max_cf``,
    ``mean_y_m``, ``mean_z_m`` and the polyline ``path`` (``(k, 2)``)."""
    labels = np.asarray(labels)
    p, pos = np.asarray(ping), np.asarray(position_m, dtype=np.float64).reshape(-1, 2)
    cf, y, z = (np.asarray(a, dtype=np.float64) for a in (cf, y_m, z_m))
    out = []
    for num in range(int(labels.max()) + 1 if labels.size else 0):
        m = np.flatnonzero(labels == num)
        pings = np.unique(p[m])
        path = np.array([pos[m[p[m] == q]].mean(axis=0) for q in pings])
        seg = np.hypot(*np.diff(path, axis=0).T) if len(path) > 1 else np.zeros(0)
        out.append({"object": num, "n_pings": int(pings.size), "n_detections": int(m.size),
                    "first_ping": int(pings[0]), "last_ping": int(pings[-1]),
                    "length_m": float(seg.sum()), "mean_cf": float(cf[m].mean()), "max_cf": float(cf[m].max()),
                    "mean_y_m": float(y[m].mean()), "mean_z_m": float(z[m].mean()), "path": path})
    return out


# ---------------------------------------------------------------------------
# Products
# ---------------------------------------------------------------------------
PEAK_TABLE = {
    # name: (dtype, long name, units)
    "ping": (np.int64, "survey ping number (through the readable inputs in order)", "1"),
    "range_m": (np.float64, "range from the grid centre", "m"),
    "angle_deg": (np.float64, "angle from nadir, positive to starboard", "degree"),
    "y_m": (np.float64, "cross-track offset, positive to starboard", "m"),
    "z_m": (np.float64, "depth below the array reference point", "m"),
    "cf": (np.float64, "smoothed coherence factor at the peak", "1"),
    "intensity_db": (np.float64, "intensity |S|^2 at the peak", "dB re input units squared"),
    "file_index": (np.int32, "index of the input file (attribute input_files)", "1"),
    "file_ping": (np.int32, "ping index within the input file", "1"),
    "time_s": (np.float64, "ping time, seconds since 1970-01-01 UTC", "s"),
    "ping_latitude_deg": (np.float64, "latitude of the ping", "degree_north"),
    "ping_longitude_deg": (np.float64, "longitude of the ping", "degree_east"),
    "heading_deg": (np.float64, "heading of the ping (course over ground where the file has none)", "degree"),
    "peak_latitude_deg": (np.float64, "latitude of the peak", "degree_north"),
    "peak_longitude_deg": (np.float64, "longitude of the peak", "degree_east"),
    "easting_m": (np.float64, "UTM easting of the peak (zone: attribute utm_epsg)", "m"),
    "northing_m": (np.float64, "UTM northing of the peak (zone: attribute utm_epsg)", "m"),
    "along_track_m": (np.float64, "along-track distance from ping time x ship speed (no navigation)", "m"),
    "object": (np.int64, "associated object (-1: none, or CF at or below the map threshold)", "1"),
}
NAV_COLUMNS = ("ping_latitude_deg", "ping_longitude_deg", "heading_deg", "peak_latitude_deg",
               "peak_longitude_deg", "easting_m", "northing_m")


@dataclass
class SurveyProducts:
    """What :func:`finalize_survey` wrote and found."""

    n_imaged: int
    n_peaks: int
    n_detections: int
    objects: list
    navigation: bool
    utm_epsg: int | None
    files: dict


def _ledger_names(output: Path) -> list:
    return sorted(e.name for e in os.scandir(output / LEDGER_DIR) if _LEDGER_NAME.match(e.name))


def _iter_records(output: Path, names: list):
    d = output / LEDGER_DIR
    for name in names:
        with open(d / name, "rb") as fh:
            yield json.load(fh)


def _nan(v) -> float:
    return np.nan if v is None else float(v)


class _Navigation:
    """Per-ping navigation of the survey, and georeferencing of peaks."""

    def __init__(self, n: int, speed_m_s: float | None):
        self.lat = np.full(n, np.nan)
        self.lon = np.full(n, np.nan)
        self.heading = np.full(n, np.nan)
        self.heading_file = np.full(n, np.nan)
        self.time_s = np.full(n, np.nan)
        self.speed = speed_m_s
        self.epsg = None
        self._conv = None

    def finish(self, imaged: np.ndarray) -> None:
        """Fill the headings and the UTM positions once every record is read."""
        nav = np.isfinite(self.lat) & np.isfinite(self.lon)
        self.has_nav = nav
        self.all_nav = bool(imaged.any()) and bool(nav[imaged].all())
        self.heading = self.heading_file.copy()
        if nav.any():
            k = int(np.flatnonzero(nav)[0])
            self.epsg = utm_epsg(self.lat[k], self.lon[k])
            self.e, self.n = to_utm(self.lat, self.lon, self.epsg)
            missing = nav & ~np.isfinite(self.heading)
            if missing.any():
                # course over ground in grid coordinates, turned to true north: add the meridian convergence
                cog = course_over_ground_deg(self.e, self.n)
                self.heading[missing] = (cog[missing] + self._convergence(missing)) % 360.0
                log.warning("%d navigated ping(s) have no heading: course over ground used", int(missing.sum()))
        t = self.time_s[np.isfinite(self.time_s)]
        self.t_ref = float(t.min()) if t.size else np.nan
        blind = imaged & ~nav
        if blind.any() and (self.speed is None or not t.size):
            log.warning("%d ping(s) have no navigation%s: along-track distance unknown (give the ping times "
                        "and --speed)", int(blind.sum()), "" if t.size else " and no ping times")

    def _convergence(self, mask) -> np.ndarray:
        import pyproj

        f = pyproj.Proj(f"EPSG:{self.epsg}").get_factors(self.lon[mask], self.lat[mask])
        return np.asarray(f.meridian_convergence, dtype=np.float64)

    def along_m(self, pings) -> np.ndarray:
        if self.speed is None:
            return np.full(np.shape(pings), np.nan)
        return self.speed * (self.time_s[pings] - self.t_ref)

    def peak_columns(self, pings: np.ndarray, y_m: np.ndarray) -> dict:
        """Georeferenced columns for peaks of ``pings`` at offsets ``y_m``."""
        plat, plon = peak_positions(self.lat[pings], self.lon[pings], self.heading[pings], y_m)
        cols = {"ping_latitude_deg": self.lat[pings], "ping_longitude_deg": self.lon[pings],
                "heading_deg": self.heading[pings], "peak_latitude_deg": plat, "peak_longitude_deg": plon}
        if self.epsg is not None:
            cols["easting_m"], cols["northing_m"] = to_utm(plat, plon, self.epsg)
        else:
            cols["easting_m"] = cols["northing_m"] = np.full(np.shape(y_m), np.nan)
        along = np.where(self.has_nav[pings], np.nan, self.along_m(pings))
        cols["along_track_m"] = along
        return cols

    def frame(self, pings: np.ndarray, y_m: np.ndarray, cols: dict) -> tuple:
        """Association frame: positions and starboard unit vectors."""
        if self.all_nav:
            h = np.deg2rad(self.heading[pings])
            # the starboard direction in grid coordinates: true azimuth heading + 90 less the convergence
            conv = np.deg2rad(self._convergence_at(pings))
            sb = np.stack([np.cos(h - conv), -np.sin(h - conv)], axis=1)
            return np.stack([cols["easting_m"], cols["northing_m"]], axis=1), sb
        return np.stack([self.along_m(pings), y_m], axis=1), np.tile([0.0, 1.0], (len(pings), 1))

    def _convergence_at(self, pings) -> np.ndarray:
        """Meridian convergence (degree, grid north to true north) at the pings."""
        if self._conv is None:
            self._conv = np.zeros(self.lat.size)
            nav = self.has_nav
            if nav.any():
                self._conv[nav] = self._convergence(nav)
        return self._conv[pings]


def _fmt(v) -> str:
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    v = float(v)
    return "" if math.isnan(v) else repr(v)


def _json_num(v):
    if isinstance(v, (int, np.integer)):
        return int(v)
    v = float(v)
    return v if math.isfinite(v) else None


class _PeakWriter:
    """Streams peak rows to the Zarr group ``peaks``, the CSV and the GeoJSON."""

    def __init__(self, output: Path, files: dict, csv_columns: list, geojson: bool, attrs: dict):
        self.output, self.attrs = output, attrs
        self.csv_columns = csv_columns
        self.tmp = {k: p.with_name(f".{p.name}.tmp-{os.getpid()}") for k, p in files.items()}
        self.files = files
        self.csv_fh = open(self.tmp["peaks_csv"], "w", newline="")
        self.csv = csv.writer(self.csv_fh)
        self.csv.writerow(csv_columns)
        self.geo_fh = None
        if geojson:
            self.geo_fh = open(self.tmp["peaks_geojson"], "w")
            self.geo_fh.write('{"type": "FeatureCollection", "name": "clbeam coherence peaks", "features": [\n')
            self.first_feature = True
        self.buffer = {k: [] for k in PEAK_TABLE}
        self.n_buffered = 0
        self.n_written = 0
        self.zarr_started = False

    def add(self, cols: dict) -> None:
        n = len(cols["ping"])
        if n == 0:
            return
        for row in zip(*(cols[c] for c in self.csv_columns)):
            self.csv.writerow([_fmt(v) for v in row])
        if self.geo_fh is not None:
            props = self.csv_columns
            for k in range(n):
                lat, lon = cols["peak_latitude_deg"][k], cols["peak_longitude_deg"][k]
                if not (math.isfinite(lat) and math.isfinite(lon)):
                    continue
                feat = {"type": "Feature", "geometry": {"type": "Point", "coordinates": [float(lon), float(lat)]},
                        "properties": {c: _json_num(cols[c][k]) for c in props}}
                self.geo_fh.write(("" if self.first_feature else ",\n") + json.dumps(feat))
                self.first_feature = False
        for k in PEAK_TABLE:
            self.buffer[k].append(np.asarray(cols[k]))
        self.n_buffered += n
        if self.n_buffered >= PEAK_BLOCK_ROWS:
            self._flush()

    def _flush(self, force: bool = False) -> None:
        import xarray as xr

        if self.n_buffered == 0 and not (force and not self.zarr_started):
            return
        data = {}
        for k, (dtype, long_name, units) in PEAK_TABLE.items():
            arr = np.concatenate(self.buffer[k]).astype(dtype) if self.buffer[k] else np.zeros(0, dtype=dtype)
            data[k] = (("peak",), arr, {"long_name": long_name, "units": units})
        # every write gives the attributes: xarray's append mode replaces them with the dataset's
        ds = xr.Dataset(data, attrs=self.attrs)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if not self.zarr_started:
                ds.to_zarr(self.output, group="peaks", mode="w", consolidated=False)
                self.zarr_started = True
            else:
                ds.to_zarr(self.output, group="peaks", append_dim="peak", consolidated=False)
        self.n_written += self.n_buffered
        self.buffer = {k: [] for k in PEAK_TABLE}
        self.n_buffered = 0

    def close(self) -> None:
        self._flush(force=True)
        self.csv_fh.close()
        os.replace(self.tmp["peaks_csv"], self.files["peaks_csv"])
        if self.geo_fh is not None:
            self.geo_fh.write("\n]}\n")
            self.geo_fh.close()
            os.replace(self.tmp["peaks_geojson"], self.files["peaks_geojson"])

    def abort(self) -> None:
        for fh in (self.csv_fh, self.geo_fh):
            if fh is not None and not fh.closed:
                fh.close()
        for p in self.tmp.values():
            with contextlib.suppress(OSError):
                p.unlink()


def finalize_survey(output, options: SurveyOptions, *, failures=()) -> SurveyProducts:
    """Build the survey products from the ledger of ``output``.

    Reads the ledger twice, one ping at a time: first the navigation and the
    detections above the map threshold (the only survey-wide arrays kept:
    about 200 bytes per detection and 4 per peak), which are associated
    into objects; then
    every peak, georeferenced and written to the Zarr group ``peaks``, the
    CSV and the GeoJSON.  Each text product is written under a temporary
    name and renamed; the store's per-ping variables (navigation, time,
    grid centre, ``imaged``, ``n_peaks``) and attributes are updated.

    Returns
    -------
    SurveyProducts
    """
    import zarr

    output = Path(output)
    root = zarr.open_group(str(output), mode="r+")
    n = int(root["ping"].shape[0])
    assoc = options.association
    nav = _Navigation(n, options.speed_m_s)
    per_ping = {"imaged": np.zeros(n, dtype=bool), "n_peaks": np.full(n, -1, dtype=np.int32),
                "file_index": np.full(n, -1, dtype=np.int32), "file_ping": np.full(n, -1, dtype=np.int32),
                "centre_y": np.full(n, np.nan), "centre_z": np.full(n, np.nan)}
    det_ping, det_row = array.array("q"), array.array("q")
    det_y, det_z, det_cf = array.array("d"), array.array("d"), array.array("d")
    names = _ledger_names(output)  # both passes read these, whatever a late task may still commit
    row = 0
    for rec in _iter_records(output, names):
        g = rec["ping"]
        per_ping["imaged"][g] = True
        per_ping["n_peaks"][g] = len(rec["peaks"])
        per_ping["file_index"][g], per_ping["file_ping"][g] = rec["file_index"], rec["file_ping"]
        per_ping["centre_y"][g], per_ping["centre_z"][g] = rec["centre_y_m"], rec["centre_z_m"]
        nav.lat[g], nav.lon[g] = _nan(rec["latitude_deg"]), _nan(rec["longitude_deg"])
        nav.heading_file[g] = _nan(rec["heading_deg"])
        if rec["time"] is not None:
            nav.time_s[g] = (np.datetime64(rec["time"], "ns") - _EPOCH) / np.timedelta64(1, "s")
        for k, pk in enumerate(rec["peaks"]):
            if pk["cf"] > assoc.threshold:
                det_ping.append(g)
                det_y.append(pk["y_m"])
                det_z.append(pk["z_m"])
                det_cf.append(pk["cf"])
                det_row.append(row + k)
        row += len(rec["peaks"])
    n_rows = row
    nav.finish(per_ping["imaged"])
    det_ping = np.asarray(det_ping, dtype=np.int64)
    det_y, det_z, det_cf = (np.asarray(a, dtype=np.float64) for a in (det_y, det_z, det_cf))
    det_cols = nav.peak_columns(det_ping, det_y)
    pos, sb = nav.frame(det_ping, det_y, det_cols)
    labels = associate(det_ping, pos, sb, det_z, assoc)
    objects = describe_objects(labels, det_ping, pos, det_cf, det_y, det_z)
    row_object = np.full(n_rows, -1, dtype=np.int32)
    row_object[np.asarray(det_row, dtype=np.int64)] = labels
    navigated = bool(nav.has_nav.any())
    files = product_paths(output)

    # -- peaks: Zarr, CSV, GeoJSON ----------------------------------------
    csv_columns = list(PEAK_COLUMNS) + ["file_index", "file_ping", "time_s"]
    if navigated:
        csv_columns += list(NAV_COLUMNS)
    if (~nav.has_nav).any():
        csv_columns.append("along_track_m")
    csv_columns.append("object")
    attrs = {"utm_epsg": nav.epsg if nav.epsg is not None else -1, "peak_threshold": options.imaging.threshold,
             "map_threshold": assoc.threshold}
    writer = _PeakWriter(output, {k: files[k] for k in ("peaks_csv", "peaks_geojson")}, csv_columns,
                         navigated, attrs)
    try:
        row = 0
        for rec in _iter_records(output, names):
            pk = rec["peaks"]
            k = len(pk)
            if k == 0:
                continue
            g = rec["ping"]
            cols = {c: np.array([r[c] for r in pk], dtype=np.float64) for c in PEAK_COLUMNS if c != "ping"}
            pings = np.full(k, g, dtype=np.int64)
            cols["ping"] = pings
            cols["file_index"] = np.full(k, rec["file_index"], dtype=np.int32)
            cols["file_ping"] = np.full(k, rec["file_ping"], dtype=np.int32)
            cols["time_s"] = np.full(k, nav.time_s[g])
            cols.update(nav.peak_columns(pings, cols["y_m"]))
            cols["object"] = row_object[row:row + k].astype(np.int64)
            writer.add(cols)
            row += k
        writer.close()
    except BaseException:
        writer.abort()
        raise

    # -- objects -------------------------------------------------------------
    _write_objects(output, files, objects, nav, det_ping, labels, det_cols)

    # -- per-ping variables and attributes --------------------------------
    root["latitude"][:] = nav.lat
    root["longitude"][:] = nav.lon
    root["heading"][:] = nav.heading
    root["time"][:] = nav.time_s
    for k, v in per_ping.items():
        root[k][:] = v
    n_imaged = int(per_ping["imaged"].sum())
    root.attrs.update({
        "survey_complete": bool(n_imaged == n and not failures),
        "pings_imaged": n_imaged, "pings_total": n,
        "utm_epsg": nav.epsg if nav.epsg is not None else -1,
        "association": json.dumps(dataclasses.asdict(assoc)),
        "speed_m_s": options.speed_m_s if options.speed_m_s is not None else -1.0,
        "failures": json.dumps([str(f) for f in failures]),
    })
    _consolidate(output)

    # -- figures -------------------------------------------------------------
    try:
        plot_survey_map(files["map_png"], nav=nav, det_ping=det_ping, det_cf=det_cf, det_pos=pos,
                        objects=objects, threshold=assoc.threshold, grid=options.grid)
        _plot_persistence(files["persistence_png"], det_ping, det_y, det_cf, assoc.threshold)
    except Exception as exc:  # a figure must not lose the tables written above
        log.warning("survey figures not written: %s", _one_line(exc))
    return SurveyProducts(n_imaged=n_imaged, n_peaks=n_rows, n_detections=int(det_ping.size), objects=objects,
                          navigation=navigated, utm_epsg=nav.epsg, files=files)


OBJECT_COLUMNS = ("object", "n_pings", "n_detections", "first_ping", "last_ping", "length_m", "mean_cf", "max_cf",
                  "mean_y_m", "mean_z_m")


def _write_objects(output: Path, files: dict, objects: list, nav: _Navigation, det_ping, labels, det_cols) -> None:
    import xarray as xr

    geo = nav.all_nav
    extra = ("start_latitude_deg", "start_longitude_deg", "end_latitude_deg", "end_longitude_deg",
             "start_easting_m", "start_northing_m", "end_easting_m", "end_northing_m") if geo else \
        ("start_along_track_m", "end_along_track_m")
    rows = []
    for ob in objects:
        r = {k: ob[k] for k in OBJECT_COLUMNS}
        m = labels == ob["object"]
        if geo:
            first, last = ob["first_ping"], ob["last_ping"]
            for tag, q in (("start", first), ("end", last)):
                sel = m & (det_ping == q)
                r[f"{tag}_latitude_deg"] = float(np.mean(det_cols["peak_latitude_deg"][sel]))
                r[f"{tag}_longitude_deg"] = float(np.mean(det_cols["peak_longitude_deg"][sel]))
                r[f"{tag}_easting_m"] = float(np.mean(det_cols["easting_m"][sel]))
                r[f"{tag}_northing_m"] = float(np.mean(det_cols["northing_m"][sel]))
        else:
            r["start_along_track_m"] = float(ob["path"][0, 0]) if nav.speed is not None else np.nan
            r["end_along_track_m"] = float(ob["path"][-1, 0]) if nav.speed is not None else np.nan
        rows.append(r)
    cols = list(OBJECT_COLUMNS) + list(extra)
    tmp = files["objects_csv"].with_name(f".{files['objects_csv'].name}.tmp-{os.getpid()}")
    with open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for r in rows:
            w.writerow([_fmt(r[c]) for c in cols])
    os.replace(tmp, files["objects_csv"])
    if geo:
        feats = []
        for ob, r in zip(objects, rows):
            m = labels == ob["object"]
            pings = np.unique(det_ping[m])
            coords = [[float(np.mean(det_cols["peak_longitude_deg"][m & (det_ping == q)])),
                       float(np.mean(det_cols["peak_latitude_deg"][m & (det_ping == q)]))] for q in pings]
            geom = {"type": "LineString", "coordinates": coords} if len(coords) > 1 else \
                {"type": "Point", "coordinates": coords[0]}
            feats.append({"type": "Feature", "geometry": geom, "properties": {c: _json_num(r[c]) for c in cols}})
        _write_atomic(files["objects_geojson"], json.dumps(
            {"type": "FeatureCollection", "name": "clbeam associated objects", "features": feats}).encode())
    else:
        with contextlib.suppress(FileNotFoundError):
            files["objects_geojson"].unlink()
    data = {c: (("object",), np.array([r[c] for r in rows], dtype=np.int64 if c in OBJECT_COLUMNS[:5] else np.float64))
            for c in cols}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        xr.Dataset(data).to_zarr(output, group="objects", mode="w", consolidated=False)


def _plot_persistence(path: Path, det_ping, det_y, det_cf, threshold: float) -> None:
    from clbeam.io.figures import plot_peak_map

    rows = [{"ping": int(p), "y_m": float(y), "cf": float(c)} for p, y, c in zip(det_ping, det_y, det_cf)]
    tmp = path.with_name(f".{path.stem}.tmp-{os.getpid()}.png")
    plot_peak_map(rows, tmp, threshold=threshold, title="coherence peaks over the survey")
    os.replace(tmp, path)


def plot_survey_map(path, *, nav: _Navigation, det_ping, det_cf, det_pos, objects, threshold: float,
                    grid: PolarGrid | None = None):
    """Plan-view persistence map (Holland et al. 2024, Figs. 9-10).

    Coherence peaks above ``threshold`` at their georeferenced positions,
    coloured by CF, over the ship track (blue) with the broadside directions
    of every 30th ping (2 minutes at the paper's 4 s interval) out to the
    grid's largest horizontal range, and each associated object's path
    (black) with its number.  Without navigation the axes are along-track
    distance (ping time x speed) and cross-track offset.
    """
    from clbeam.io.figures import pyplot

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 8), dpi=110, constrained_layout=True)
    if nav.all_nav:
        e0, n0 = float(np.nanmin(nav.e)), float(np.nanmin(nav.n))
        ax.plot(nav.e - e0, nav.n - n0, color="tab:blue", lw=1.5, label="ship track", zorder=2)
        reach = 0.0
        if grid is not None:
            reach = float(grid.ranges_m[-1] * np.max(np.abs(np.sin(np.deg2rad(grid.angles_deg)))))
        idx = np.flatnonzero(np.isfinite(nav.e))
        conv = nav._convergence_at(np.arange(nav.lat.size))
        for k in idx[::30]:
            h = np.deg2rad(nav.heading[k] - conv[k])
            if reach > 0 and np.isfinite(h):
                de, dn = reach * np.cos(h), -reach * np.sin(h)
                ax.plot([nav.e[k] - e0 - de, nav.e[k] - e0 + de], [nav.n[k] - n0 - dn, nav.n[k] - n0 + dn],
                        color="0.6", ls="--", lw=0.8, zorder=1)
        x, y = det_pos[:, 0] - e0, det_pos[:, 1] - n0
        ax.set_xlabel(f"easting - {e0:.0f} m (EPSG:{nav.epsg})")
        ax.set_ylabel(f"northing - {n0:.0f} m")
        ax.set_aspect("equal", adjustable="datalim")
        shift = np.array([e0, n0])
    else:
        x, y = det_pos[:, 0], det_pos[:, 1]
        ax.set_xlabel("along-track distance (m, ping time x speed: no navigation)")
        ax.set_ylabel("cross-track offset y (m, starboard positive)")
        ax.axhline(0, color="tab:blue", lw=1.5, label="ship track")
        shift = np.zeros(2)
    if len(x):
        sc = ax.scatter(x, y, c=det_cf, s=8, cmap="plasma", vmin=threshold, vmax=1, zorder=3)
        fig.colorbar(sc, ax=ax, label="coherence factor", shrink=0.8)
    for ob in objects:
        p = ob["path"] - shift
        ax.plot(p[:, 0], p[:, 1], color="k", lw=1.0, zorder=4)
        ax.annotate(str(ob["object"]), p[-1], fontsize=8, xytext=(3, 3), textcoords="offset points")
    ax.set_title(f"coherence peaks, CF > {threshold:g}: {len(x)} detections in {len(np.unique(det_ping))} pings, "
                 f"{len(objects)} object(s)")
    ax.legend(loc="best", fontsize=8)
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.tmp-{os.getpid()}.png")
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, path)
    return path


# ---------------------------------------------------------------------------
# Reading a survey back
# ---------------------------------------------------------------------------
def open_survey(output, group: str | None = None):
    """Open a survey store with xarray: the per-ping variables and images
    (default), or the group ``"peaks"`` or ``"objects"``."""
    import xarray as xr

    p = Path(output)
    require(is_survey_store(p), SurveyError, f"{p.name}: not a clbeam survey store")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return xr.open_zarr(p, group=group)


__all__ = ["AssociationOptions", "BlockTask", "Failure", "InputFile", "ScanResult", "SurveyError", "SurveyOptions",
           "SurveyProducts", "SurveyResult", "associate", "course_over_ground_deg", "describe_objects",
           "done_pings", "finalize_survey", "ledger_path", "open_survey", "peak_positions", "plot_survey_map",
           "process_block", "product_paths", "run_survey", "scan_inputs",
           "survey_parameters", "to_utm", "utm_epsg"]
