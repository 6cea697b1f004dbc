"""The survey store on disk: a Zarr (v3) image store with a resume ledger.

A survey store (``clbeam survey``, :func:`clbeam.survey.run_survey`) is an
image store in the layout of :class:`clbeam.io.images.ImageWriter` (so
:func:`clbeam.io.images.open_images` and ``clbeam peaks`` read it) with
per-ping bookkeeping variables, the groups ``peaks``, ``objects`` and ``lines``, and the
folder ``survey_state/``:

* ``survey_state/pings/<ping:09d>.json``: one ledger file per committed
  ping, written under a temporary name, flushed (``fsync``) and renamed, so
  it is either whole or absent;
* ``survey_state/parameters.json``: the processing parameters, also in the
  root attribute ``survey_parameters``;
* ``survey_state/lock``: the file a run holds an exclusive ``flock`` on.

This module knows the layout only; what the records hold and when they are
written is :mod:`clbeam.survey`'s.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import logging
import os
import re
import shutil
import uuid
import warnings
from pathlib import Path

import numpy as np

from clbeam import __version__
from clbeam.errors import ClbeamError, SurveyError, require
from clbeam.io.conventions import coverage_attributes, utc_now
from clbeam.io.images import ImageWriter
from clbeam.io.schema import FORMAT_ATTRIBUTE, IMAGE_FORMAT
from clbeam.model.grid import PolarGrid

log = logging.getLogger(__name__)

SURVEY_FORMAT = "survey-1"
"""Value of the root attribute ``clbeam_survey`` of a survey store."""
STATE_DIR = "survey_state"
"""Folder, inside the output store, of the resume state."""
LEDGER_DIR = f"{STATE_DIR}/pings"
"""Folder of the per-ping ledger files ``<ping:09d>.json``."""
PRODUCT_SUFFIXES = ("peaks.csv", "peaks.geojson", "objects.csv", "objects.geojson", "lines.csv", "lines.geojson",
                    "map.png", "persistence.png")
"""Files written beside the store ``X.zarr``: ``X.<suffix>``."""

_LEDGER_NAME = re.compile(r"^(\d{9})\.json$")

#: the per-ping time of a survey store (an image file's ``ping_time``; seconds since 1970 UTC, CF)
SURVEY_TIME_VARIABLE = "time"
#: per-ping variables of a survey store besides those of an image file: (long name, units, dtype); -1 in the
#: integer ones: the ping is not imaged (their ``valid_min`` is 0)
SURVEY_PING_VARIABLES = {
    "imaged": ("ping imaged and committed to the ledger", None, bool),
    "file_index": ("index of the ping's input file (attribute input_files)", "1", np.int32),
    "file_ping": ("index of the ping within its input file", "1", np.int32),
    "n_peaks": ("coherence peaks of the ping", "1", np.int32),
}


def product_paths(output) -> dict:
    """Paths of the products written beside a survey store.

    Parameters
    ----------
    output : path-like
        The store, ``X.zarr``.

    Returns
    -------
    dict of str to pathlib.Path
        ``peaks_csv``, ``peaks_geojson``, ``objects_csv``,
        ``objects_geojson``, ``lines_csv``, ``lines_geojson``, ``map_png``,
        ``persistence_png``: ``X.peaks.csv``
        and so on.
    """
    stem = Path(output).with_suffix("")
    return {n.replace(".", "_"): Path(f"{stem}.{n}") for n in PRODUCT_SUFFIXES}


def is_survey_store(path) -> bool:
    """True when ``path`` is a survey store (root attribute ``clbeam_survey``)."""
    try:
        meta = json.loads((Path(path) / "zarr.json").read_text())
    except (OSError, ValueError):
        return False
    return meta.get("attributes", {}).get("clbeam_survey") == SURVEY_FORMAT


def read_root_attrs(path) -> dict:
    """The root attributes of the Zarr store ``path``, read from its ``zarr.json``."""
    return json.loads((Path(path) / "zarr.json").read_text()).get("attributes", {})


def consolidate(path) -> None:
    """Consolidate the metadata of the Zarr store ``path``."""
    import zarr

    with warnings.catch_warnings():
        # the resume state is a plain folder inside the store: zarr notes it and moves on
        warnings.simplefilter("ignore")
        zarr.consolidate_metadata(str(path))


def write_atomic(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically: temporary name, flush, ``fsync``, rename."""
    path = Path(path)
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


def temporary_path(path, suffix: str = "") -> Path:
    """A hidden temporary name beside ``path`` for this process (``.<name>.tmp-<pid><suffix>``)."""
    path = Path(path)
    return path.with_name(f".{path.name}.tmp-{os.getpid()}{suffix}")


# ---------------------------------------------------------------------------
# The ledger
# ---------------------------------------------------------------------------
def ledger_path(output, ping: int) -> Path:
    """Ledger file of survey ping ``ping`` in the store ``output``."""
    return Path(output) / LEDGER_DIR / f"{ping:09d}.json"


def write_ledger_record(output, ping: int, record: dict) -> None:
    """Commit survey ping ``ping``: its record, written atomically (:func:`write_atomic`)."""
    write_atomic(ledger_path(output, ping), json.dumps(record).encode())


def done_pings(output, *, validate: bool = False) -> set:
    """Survey pings committed to the ledger of ``output``.

    Parameters
    ----------
    output : path-like
        The store.
    validate : bool
        Parse every ledger file; one that does not parse (only possible
        after a machine crash, not a process kill) is removed so that its
        ping is imaged again.

    Returns
    -------
    set of int
        Survey ping numbers.
    """
    d = Path(output) / LEDGER_DIR
    done = set()
    if not d.is_dir():
        return done
    for entry in os.scandir(d):
        m = _LEDGER_NAME.match(entry.name)
        if not m:
            continue
        if validate and not _record_parses(entry, int(m.group(1))):
            continue
        done.add(int(m.group(1)))
    return done


def _record_parses(entry, ping: int) -> bool:
    """Whether a ledger file parses and names its ping; one that does not is removed."""
    try:
        with open(entry.path, "rb") as fh:
            rec = json.load(fh)
        require(rec.get("ping") == ping, SurveyError, "ping number mismatch")
    except (OSError, ValueError, ClbeamError) as exc:
        log.warning("ledger file %s is unreadable (%s): ping %d will be imaged again", entry.name, exc, ping)
        with contextlib.suppress(OSError):
            os.unlink(entry.path)
        return False
    return True


def ledger_names(output) -> list:
    """File names of the committed ledger records of ``output``, in ping order."""
    return sorted(e.name for e in os.scandir(Path(output) / LEDGER_DIR) if _LEDGER_NAME.match(e.name))


def iter_ledger_records(output, names: list):
    """The ledger records ``names`` (from :func:`ledger_names`) of ``output``, one at a time (dict)."""
    d = Path(output) / LEDGER_DIR
    for name in names:
        with open(d / name, "rb") as fh:
            yield json.load(fh)


def clean_temporaries(output) -> None:
    """Remove what a killed run left: temporary ledger files, and stores
    being created by a process that no longer runs."""
    output = Path(output)
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


class SurveyLock:
    """An exclusive ``flock`` on the store's lock file for a whole run.

    The kernel frees it when the process dies, even by ``kill -9``.

    Parameters
    ----------
    output : pathlib.Path
        The store.

    Raises
    ------
    SurveyError
        Another process holds the lock.
    """

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
        """Free the lock (once; later calls do nothing)."""
        if self.fh is not None:
            fcntl.flock(self.fh.fileno(), fcntl.LOCK_UN)
            self.fh.close()
            self.fh = None


# ---------------------------------------------------------------------------
# The store
# ---------------------------------------------------------------------------
def _bookkeeping(n_pings: int) -> dict:
    """The :data:`SURVEY_PING_VARIABLES` before any ping is committed."""
    out = {}
    for name, (long_name, units, dtype) in SURVEY_PING_VARIABLES.items():
        if dtype is bool:
            data = np.zeros(n_pings, dtype=bool)
        elif dtype is np.float64:
            data = np.full(n_pings, np.nan)
        else:
            data = np.full(n_pings, -1, dtype=dtype)
        a = {"long_name": long_name, "coverage_content_type": "auxiliaryInformation"}
        if units:
            a["units"] = units
        if np.issubdtype(dtype, np.integer):
            a["valid_min"] = np.asarray(0, dtype=dtype)
        out[name] = (("ping",), data, a)
    return out


def create_store(output: Path, *, grid: PolarGrid, n_pings: int, variables, params: dict, input_names) -> None:
    """Create an empty survey store, whole or not at all.

    The store is built in a temporary folder beside ``output`` and renamed
    into place.

    Parameters
    ----------
    output : pathlib.Path
        The store to create (must not exist).
    grid : PolarGrid
        Image grid of every ping.
    n_pings : int
        Survey pings.
    variables : sequence of str
        Image variables (:data:`clbeam.io.schema.IMAGE_VARIABLES`; may be empty).
    params : dict
        Processing parameters (root attribute ``survey_parameters`` and
        ``survey_state/parameters.json``).
    input_names : sequence of str
        Names of the readable inputs (root attribute ``input_files``).
    """
    import xarray as xr

    tmp = output.parent / f".{output.name}.creating-{os.getpid()}-{uuid.uuid4().hex[:8]}.zarr"
    # the image format too: image readers check it
    attrs = {FORMAT_ATTRIBUTE: IMAGE_FORMAT, "clbeam_survey": SURVEY_FORMAT, "survey_parameters": json.dumps(params),
             "clbeam_version": __version__, "input_files": json.dumps(list(input_names)),
             "survey_complete": False, "source": f"clbeam {__version__} survey", "title": "clbeam survey store",
             "summary": "A survey's multibeam sub-bottom sonar pings: per-ping navigation and bookkeeping, the "
                        "cross-track images where asked, and the coherence peaks, objects and lines found in them "
                        "(groups peaks, objects, lines)."}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ImageWriter(tmp, grid, n_pings, variables, attrs, time_variable=SURVEY_TIME_VARIABLE).close()
            # xarray's append mode replaces the root attributes with the dataset's: give the writer's
            # (with its CF and ACDD ones) again
            xr.Dataset(_bookkeeping(n_pings), attrs=read_root_attrs(tmp)).to_zarr(tmp, mode="a", consolidated=False)
        consolidate(tmp)
        require(is_survey_store(tmp), SurveyError, f"{output.name}: the new store lacks its attributes")
        (tmp / LEDGER_DIR).mkdir(parents=True)
        (tmp / STATE_DIR / "parameters.json").write_text(json.dumps(params, indent=1) + "\n")
        os.rename(tmp, output)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def remove_products(output) -> None:
    """Remove the products beside ``output`` (:func:`product_paths`) that exist."""
    for p in product_paths(output).values():
        with contextlib.suppress(FileNotFoundError):
            p.unlink()


def remove_store(output: Path) -> None:
    """Remove the survey store ``output`` and its products."""
    shutil.rmtree(output)
    remove_products(output)


def store_ping_count(output) -> int:
    """Survey pings of the store ``output``."""
    import zarr

    return int(zarr.open_group(str(output), mode="r")["ping"].shape[0])


def update_store(output, variables: dict, attrs: dict) -> None:
    """Overwrite whole per-ping variables and update root attributes, then consolidate.

    Parameters
    ----------
    output : path-like
        The store.
    variables : dict of str to numpy.ndarray
        ``(ping,)`` values of per-ping variables; one the store lacks (a
        store made by an older clbeam) is left out, with a log message.
        ``time`` (seconds since 1970 UTC), ``latitude`` and ``longitude``
        (degree) also give the ACDD coverage attributes.
    attrs : dict
        Root attributes to set; one whose value is ``None`` (not known) is
        removed.  ``date_modified`` is set to now.
    """
    import zarr

    root = zarr.open_group(str(output), mode="r+")
    for name, values in variables.items():
        if name not in root:
            log.info("%s has no variable %s (made by an older clbeam): not written", Path(output).name, name)
            continue
        root[name][:] = values
    seconds = variables.get(SURVEY_TIME_VARIABLE)
    times = None
    if seconds is not None:
        s = np.asarray(seconds, dtype=np.float64)
        ns = np.round(np.where(np.isfinite(s), s, 0.0) * 1e9).astype(np.int64)
        times = np.where(np.isfinite(s), ns.astype("datetime64[ns]"), np.datetime64("NaT", "ns"))
    new = {**attrs, "date_modified": utc_now(),
           **coverage_attributes(times, variables.get("latitude"), variables.get("longitude"))}
    for key, value in new.items():
        if value is None:
            root.attrs.pop(key, None)
    root.attrs.update({k: v for k, v in new.items() if v is not None})
    consolidate(output)


def open_survey(output, group: str | None = None):
    """Open a survey store with xarray.

    Parameters
    ----------
    output : path-like
        The store.
    group : {None, "peaks", "objects", "lines"}
        The per-ping variables and images (default), or a product group.

    Returns
    -------
    xarray.Dataset
    """
    import xarray as xr

    p = Path(output)
    require(is_survey_store(p), SurveyError, f"{p.name}: not a clbeam survey store")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return xr.open_zarr(p, group=group)
