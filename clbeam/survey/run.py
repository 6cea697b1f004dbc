"""A survey run: every pending ping imaged and committed, here or on a Dask cluster.

Each ping, once imaged, is committed by one ledger file
``<OUT>/survey_state/pings/<ping>.json`` (its peaks, navigation, grid
centre, source and sonar; :func:`ping_record`) written under a temporary
name, flushed and renamed: the rename is atomic, so the file either is whole
or is not there.  Its image chunks (if any) are written before it.  The set
of these files is the ledger of done pings; a rerun images only the others,
and rewrites a ping whose image chunks a kill cut short (its ledger file was
never renamed into place).  The products are rebuilt from the ledger at the
end of every run (:func:`clbeam.survey.products.finalize_survey`).  The
processing parameters are stored in the output; a rerun with different ones
stops with a one-line error unless ``restart=True``.

Work is cut into tasks (:class:`BlockTask`), pings of one file each, small and
picklable; :func:`process_block` runs one in this process or on a Dask
worker, with an :class:`~clbeam.imaging.imager.Imager` built once per
worker thread.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import threading
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.imaging.imager import Imager, ImagingOptions, check_grid_fits_memory
from clbeam.imaging.peaks import OPTION_COLUMNS
from clbeam.io.images import image_arrays
from clbeam.io.peaks import DETECTION_COLUMNS, PEAK_COLUMNS
from clbeam.io.pingfile import PingFile
from clbeam.io.survey_store import (
    SurveyError,
    SurveyLock,
    clean_temporaries,
    create_store,
    done_pings,
    is_survey_store,
    ledger_path,
    read_root_attrs,
    remove_products,
    remove_store,
    write_ledger_record,
)
from clbeam.model.grid import PolarGrid
from clbeam.survey.inputs import Failure, ScanResult, one_line, scan_inputs, sorted_failures, strip_file_name
from clbeam.survey.options import SurveyOptions, engine_key, first_difference, survey_parameters
from clbeam.survey.products import SurveyProducts, finalize_survey

log = logging.getLogger(__name__)

STAGES = ("read_s", "compress_s", "image_s", "peaks_s", "write_s")
"""Stages of the time split: read the ping, pulse compression (and the
analytic signal, roll correction), the imaging kernel, CF smoothing and
peak picking, writing images and the ledger."""


# ---------------------------------------------------------------------------
# One block of pings (runs in this process or on a Dask worker)
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class BlockTask:
    """Pings of one file for one task; small and picklable (no engine).

    Attributes
    ----------
    output : str
        The survey store.
    file_path : str
        The ping file.
    file_index, offset : int
        Its index among the readable inputs and the survey ping of its first ping.
    pings : tuple of int
        Pings of the file to image.
    grid, imaging, backend, device
        As :class:`~clbeam.survey.options.SurveyOptions`.
    variables : tuple of str
        Image variables to write (empty: none).
    engine_key : str
        Identifies the imaging engine (:func:`~clbeam.survey.options.engine_key`).
    stop_on_error : bool
        Stop the block at the first ping that fails.
    """

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
    """What a block did: pings committed, skipped (already done), failed, and seconds per stage (:data:`STAGES`)."""

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
    """The ledger record of one imaged ping.

    Parameters
    ----------
    img : PingImage
        The ping's images and peaks (:meth:`clbeam.imaging.imager.Imager.image`).
    ping : Ping
        The ping as read (index in its file, navigation, time).
    survey_ping, file_index : int
        Its survey ping number and input file.

    Returns
    -------
    dict
        JSON-serialisable: navigation (degree), time (ISO 8601, UTC), grid
        centre and source (m, earth frame), sound speed (m/s), pulse band
        (Hz), array width (m), draft (m; ``None``: the ping file gives none),
        and the peaks (:data:`clbeam.io.peaks.PEAK_COLUMNS` besides ``ping``,
        :data:`clbeam.io.peaks.DETECTION_COLUMNS`, and the columns of
        refinement or main-lobe merging, :data:`clbeam.imaging.peaks.OPTION_COLUMNS`, where a row has them).
    """
    keys = [k for k in PEAK_COLUMNS if k != "ping"] + list(DETECTION_COLUMNS)
    ctx = img.context
    source = ctx.source_yz_m or (None, None)
    return {
        "ping": survey_ping, "file_index": file_index, "file_ping": ping.index,
        "latitude_deg": ping.latitude_deg, "longitude_deg": ping.longitude_deg, "heading_deg": ping.heading_deg,
        "time": _iso(ping.time), "centre_y_m": float(ctx.centre_yz_m[0]), "centre_z_m": float(ctx.centre_yz_m[1]),
        "source_y_m": source[0], "source_z_m": source[1], "sound_speed_m_s": float(ctx.sound_speed_m_s),
        "band_hz": [float(b) for b in ctx.band_hz], "array_width_m": float(ctx.array_width_m),
        "n_channels_used": int(img.n_channels_used), "draft_m": ping.draft_m,
        "peaks": [{**{k: float(r.get(k, math.nan)) for k in keys},
                   **{k: float(r[k]) for k in OPTION_COLUMNS if k in r}} for r in img.peaks],
    }


class _PingReader:
    """The task's ping file, opened on first use and reopened after a failed ping
    (a failed read may leave the file in a bad state)."""

    def __init__(self, path: str):
        self.path, self.file = path, None

    def ping(self, i: int):
        if self.file is None:
            self.file = PingFile(self.path)
        return self.file.ping(i)

    def close(self) -> None:
        if self.file is not None:
            self.file.close()
            self.file = None


def _commit_ping(task: BlockTask, reader: _PingReader, imager: Imager, group, i: int, timings: dict) -> None:
    """Read, image and commit ping ``i`` of the task's file: image chunks first, then the ledger file."""
    g = task.offset + i
    t0 = time.perf_counter()
    ping = reader.ping(i)
    t1 = time.perf_counter()
    img = imager.image(ping)
    t2 = time.perf_counter()
    if group is not None:
        arrays = image_arrays(img)
        for v in task.variables:
            group[v][g] = arrays[v]
    write_ledger_record(task.output, g, ping_record(img, ping, g, task.file_index))
    t3 = time.perf_counter()
    ts = img.timings_s
    timings["read_s"] += t1 - t0
    timings["compress_s"] += ts.get("compress_s", 0.0)
    timings["image_s"] += ts.get("image_s", 0.0)
    timings["peaks_s"] += ts.get("postprocess_s", 0.0)
    timings["write_s"] += t3 - t2


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

    Returns
    -------
    BlockResult
    """
    res = BlockResult()
    imager = _thread_imager(task)
    group = None
    if task.variables:
        import zarr

        group = zarr.open_group(task.output, mode="r+")
    name = Path(task.file_path).name
    reader = _PingReader(task.file_path)
    try:
        for i in task.pings:
            failed = False
            if ledger_path(task.output, task.offset + i).exists():  # committed by an earlier run or try
                res.skipped += 1
            else:
                try:
                    _commit_ping(task, reader, imager, group, i, res.timings_s)
                    res.done.append(task.offset + i)
                except Exception as exc:  # an unreadable or unimageable ping: reported, never dropped silently
                    reader.close()
                    msg = strip_file_name(one_line(exc), Path(task.file_path))
                    log.warning("%s ping %d: not imaged: %s", name, i, msg)
                    res.failures.append(Failure(name, i, msg))
                    failed = True
            if on_ping:
                on_ping(1)
            if failed and task.stop_on_error:
                break
    finally:
        reader.close()
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
    products: SurveyProducts | None = None
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
        Ping files in survey order (or the result of :func:`~clbeam.survey.inputs.scan_inputs`).
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
        (e.g. :func:`clbeam.cli.options.progress`).

    Returns
    -------
    SurveyResult
    """
    scan = inputs if isinstance(inputs, ScanResult) else scan_inputs(inputs, stop_on_error=stop_on_error)
    _check_run(scan, options, workers, scheduler)
    output = Path(output).absolute()
    params = survey_parameters(scan, options)
    lock = _open_or_create(output, scan, options, params, restart=restart)
    try:
        clean_temporaries(output)
        done = done_pings(output, validate=True)
        pending = set(range(scan.n_pings)) - done
        key = engine_key(params, options)
        tasks = [BlockTask(str(output), str(f.path), f.index, f.offset, pings, options.grid, options.imaging,
                           options.backend, options.device, tuple(options.image_variables), key, stop_on_error)
                 for f, pings in _blocks(scan, pending, options.block_pings)]
        results, n_workers, wall = _run_tasks(tasks, len(pending), progress, stop_on_error, workers, scheduler)
        failures = sorted_failures(list(scan.failures) + [fl for r in results for fl in r.failures], scan)
        if stop_on_error and failures:
            raise SurveyError(f"stopped at {failures[0]} (without --stop-on-error it is reported and skipped)")
        # counted from the ledger: a task Dask retried after losing its worker finds the pings the
        # first try committed already done, and the first try's result never arrives
        n_imaged = len(done_pings(output) - done)
        timings = {k: sum((r.timings_s[k] for r in results), 0.0) for k in STAGES}
        result = SurveyResult(output, scan.n_pings, len(done), n_imaged, failures, wall, timings, workers=n_workers,
                              n_timed=sum(len(r.done) for r in results))
        result.products = finalize_survey(output, options, failures=failures, inputs=[f.path for f in scan.files])
        return result
    finally:
        lock.release()


def _check_run(scan: ScanResult, options: SurveyOptions, workers, scheduler) -> None:
    """Refuse a run without readable inputs, with bad worker options, or with a grid too large."""
    require(bool(scan.files), SurveyError,
            "no readable input file" + (f" ({'; '.join(map(str, scan.failures))})" if scan.failures else ""))
    require(workers is None or (int(workers) == workers and workers >= 1), OptionError,
            f"workers must be an integer >= 1, got {workers!r}")
    require(workers is None or scheduler is None, OptionError, "give --workers or --scheduler, not both")
    check_grid_fits_memory(options.grid, options.imaging)


def _open_or_create(output: Path, scan: ScanResult, options: SurveyOptions, params: dict, *,
                    restart: bool) -> SurveyLock:
    """Check the store against ``params`` (discard it with ``restart``) or create it; returns the held lock."""
    require(output.suffix == ".zarr", SurveyError, f"output {output.name} must end in .zarr (a Zarr store)")
    if output.exists():
        require(is_survey_store(output), SurveyError,
                f"{output.name} exists and is not a clbeam survey store; choose another output "
                "(it is never overwritten, not even with --restart)")
        lock = SurveyLock(output)
        stored = json.loads(read_root_attrs(output).get("survey_parameters", "{}"))
        diff = first_difference(stored, params)
        if not restart:
            if diff is None:
                return lock
            lock.release()
            raise SurveyError(f"{output.name} was made with other parameters ({diff}); "
                              "rerun with --restart to discard it and start again")
        log.warning("restart: discarding %s%s", output.name, f" ({diff})" if diff else "")
        remove_store(output)
        lock.release()
    elif restart:
        remove_products(output)
    create_store(output, grid=options.grid, n_pings=scan.n_pings, variables=options.image_variables, params=params,
                 input_names=[f.path.name for f in scan.files])
    return SurveyLock(output)


def _run_tasks(tasks: list, n_pending: int, progress, stop_on_error: bool, workers, scheduler) -> tuple:
    """Run the tasks here or on Dask, with a progress bar; ``(results, workers, wall seconds)``."""
    bar = progress(n_pending) if progress else None
    try:
        if workers is None and scheduler is None:
            t0 = time.perf_counter()
            return _run_here(tasks, bar, stop_on_error), 0, time.perf_counter() - t0
        return _run_dask(tasks, bar, stop_on_error, workers=workers, scheduler=scheduler)
    finally:
        if bar is not None:
            bar.close()


def _run_here(tasks: list, bar, stop_on_error: bool) -> list:
    results = []
    update = bar.update if bar is not None else None
    for t in tasks:
        r = process_block(t, on_ping=update)
        results.append(r)
        if stop_on_error and r.failures:
            break
    return results


def _distributed():
    """The ``distributed`` module, or a one-line error naming the extra."""
    try:
        import distributed
    except ImportError:  # pragma: no cover - the survey extra is a declared dependency
        raise SurveyError("--workers/--scheduler need dask[distributed] (pip install 'clbeam[survey]')") from None
    return distributed


def _dask_client(stack: contextlib.ExitStack, dist, workers, scheduler):
    """A client of a new ``LocalCluster`` of ``workers`` processes, or of the scheduler at ``scheduler``."""
    if scheduler is not None:
        try:
            return stack.enter_context(dist.Client(scheduler, timeout="30s"))
        except OSError as exc:
            raise SurveyError(f"cannot reach the Dask scheduler at {scheduler}: {one_line(exc)}") from None
    import dask

    # Dask sets MALLOC_TRIM_THRESHOLD_ in its workers, which turns off glibc's adaptive mmap
    # threshold: every ping's arrays are then fresh pages, faulted in again (twice the time per
    # ping on the benchmark).  The workers keep the allocator's defaults instead.
    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}):
        cluster = stack.enter_context(dist.LocalCluster(n_workers=int(workers), threads_per_worker=1,
                                                        processes=True, dashboard_address=None,
                                                        silence_logs=logging.ERROR))
    return stack.enter_context(dist.Client(cluster))


def _run_dask(tasks: list, bar, stop_on_error: bool, *, workers, scheduler) -> tuple:
    """Run the blocks on a Dask cluster; ``(results, workers, wall seconds from the first task)``."""
    dist = _distributed()
    t_start = time.perf_counter()
    with contextlib.ExitStack() as stack:
        client = _dask_client(stack, dist, workers, scheduler)
        n_workers = len(client.scheduler_info().get("workers", {}))
        log.info("Dask: %d worker(s), %d task(s), connected in %.1f s", n_workers, len(tasks),
                 time.perf_counter() - t_start)
        t_start = time.perf_counter()
        futures = [client.submit(process_block, t, key=f"clbeam-survey-{t.offset + t.pings[0]}-{uuid.uuid4().hex[:8]}",
                                 pure=False) for t in tasks]
        results = []
        try:
            for fut in dist.as_completed(futures):
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
