"""OpenCL backend: device choice, program build and cache, buffers, tiling.

One :class:`OpenCLEngine` holds a context, a command queue, the programs it
has built (one per combination of mode, precision, outputs and sizes, built
once) and its device buffers (reused while they are large enough).  Calls
are serialised by a lock, so one engine may be shared by threads; a server
wanting parallel devices holds one engine per device.
"""

from __future__ import annotations

import logging
import os
import sys
import threading
from dataclasses import dataclass, field

import numpy as np

from clbeam.errors import DeviceError, GridError, OptionError, require
from clbeam.imaging.engine.clsupport import KERNEL_FILES, kernel_source, output_macros, pyopencl
from clbeam.imaging.engine.common import (
    BeamformInput,
    Engine,
    InterpMode,
    Sums,
    baseband,
    carrier_phase,
    cell_windows,
    channel_signature,
    check_mode_runs_on,
    range_bases,
)
from clbeam.imaging.engine.opencl_beams import interpolate_beams_cl
from clbeam.model.grid import PolarGrid

log = logging.getLogger(__name__)

#: cells per work-item (vector lanes) and work-items per group, by device type:
#: CPU drivers vectorise explicit lanes well and want tiny groups; GPUs want
#: one cell per work-item and full groups (clamped to the device limit)
CPU_LAYOUT = (16, 1)
GPU_LAYOUT = (1, 64)
#: fraction of the device's global memory one tile of outputs may use
TILE_MEMORY_FRACTION = 0.25
#: fraction of the device's global memory the kept per-cell tables' tiles may hold between calls
KEPT_TABLE_MEMORY_FRACTION = 0.25


#: bytes of host arrays an engine keeps for reuse at most (its last calls' results, once let go)
HOST_POOL_BYTES = 512 << 20


class HostArrays:
    """Host arrays for an engine's results and scratch, each reused once nothing but this pool refers to it.

    A fresh array's pages are mapped on its first write, which can cost more than the device's copy into it
    (on a virtual machine 70 MB of fresh pages took 27-250 ms to copy into, touched ones 13-22 ms); a ping's
    images are let go before the next ping's are made, so their pages serve the next ping's.  An array that
    anything else refers to (a caller, a view of it, a pending copy's event) is never handed out again.
    """

    #: references to an array of the pool that nothing else holds: the pool's list, the loop's name and
    #: ``sys.getrefcount``'s argument
    FREE_REFERENCES = 3

    def __init__(self, max_bytes: int = HOST_POOL_BYTES):
        self.max_bytes = max_bytes
        self._arrays: list = []

    def empty(self, shape: tuple, dtype) -> np.ndarray:
        """An array of ``shape`` and ``dtype`` (its values arbitrary): a free one of the pool, else a new one."""
        dtype, shape = np.dtype(dtype), tuple(int(n) for n in shape)
        for k in range(len(self._arrays)):
            arr = self._arrays[k]
            if arr.shape == shape and arr.dtype == dtype and sys.getrefcount(arr) <= self.FREE_REFERENCES:
                self._arrays.append(self._arrays.pop(k))  # the most recently handed out last
                return arr
        arr = np.empty(shape, dtype=dtype)
        self._arrays.append(arr)
        while len(self._arrays) > 1 and sum(a.nbytes for a in self._arrays) > self.max_bytes:
            self._arrays.pop(0)   # the oldest leaves the pool (whoever holds it keeps it)
        return arr

    def zeros(self, shape: tuple, dtype) -> np.ndarray:
        """As :meth:`empty`, filled with zeros."""
        arr = self.empty(shape, dtype)
        arr.fill(0)
        return arr


def list_devices() -> list:
    """All OpenCL devices of all platforms, in platform order (empty when none)."""
    cl = pyopencl()
    try:
        platforms = cl.get_platforms()
    except cl.Error:
        return []
    devices = []
    for p in platforms:
        try:
            devices.extend(p.get_devices())
        except cl.Error:
            continue
    return devices


def device_label(dev) -> str:
    """``"device name (platform name)"``."""
    return f"{dev.name.strip()} ({dev.platform.name.strip()})"


NO_OPENCL = ("no OpenCL device found; install an OpenCL driver (on Debian: apt-get install pocl-opencl-icd) "
             "or use --backend reference")


def choose_device(device=None):
    """Pick an OpenCL device by index, by name substring, by ``CLBEAM_DEVICE``,
    or the first one found."""
    devices = list_devices()
    require(len(devices) > 0, DeviceError, NO_OPENCL)
    if device is None:
        device = os.environ.get("CLBEAM_DEVICE")
    if device is None or device == "":
        return devices[0]
    if isinstance(device, int) or (isinstance(device, str) and device.isdigit()):
        i = int(device)
        require(0 <= i < len(devices), DeviceError, f"OpenCL device index {i} out of range 0..{len(devices) - 1}")
        return devices[i]
    for d in devices:
        if str(device).lower() in device_label(d).lower():
            return d
    raise DeviceError(f"no OpenCL device matches '{device}'; found: " + "; ".join(device_label(d) for d in devices))


def device_has_fp64(dev) -> bool:
    """True when the device supports double precision (``cl_khr_fp64``)."""
    if "cl_khr_fp64" in dev.extensions:
        return True
    try:  # OpenCL 1.2+ devices report double support here even without the extension string
        return dev.double_fp_config != 0
    except Exception:  # some drivers raise for a query on a device without doubles
        return False


class OpenCLEngine(Engine):
    """Delay-and-sum on an OpenCL device (same interface as the reference).

    Parameters
    ----------
    device : str or int, optional
        Device index or name substring; default ``CLBEAM_DEVICE`` or the first.
    precision : {"float32", "float64"} or None
        Kernel arithmetic (default float32); float64 only on devices with ``cl_khr_fp64``.
    max_tile_cells : int, optional
        Cap on cells per launch (tiles over angle); default from device memory.
    layout : (int, int), optional
        Cells per work-item (1, 2, 4, 8 or 16 vector lanes) and work-items per
        work-group; default by device type (:data:`CPU_LAYOUT`, :data:`GPU_LAYOUT`).
    profiling : bool
        Time the device's commands (:attr:`readback` then gives the copies' device time).

    Attributes
    ----------
    readback : Readback
        The device-to-host copies so far (bytes; their device time with ``profiling``).
    """

    name = "opencl"

    def __init__(self, device=None, precision: str | None = None, max_tile_cells: int | None = None,
                 layout: tuple[int, int] | None = None, profiling: bool = False):
        cl = pyopencl()
        precision = precision or "float32"
        require(precision in ("float32", "float64"), OptionError,
                f"precision '{precision}' is unknown, expected 'float32' or 'float64'")
        self.device = choose_device(device)
        if precision == "float64":
            require(device_has_fp64(self.device), DeviceError,
                    f"{device_label(self.device)} has no double precision (cl_khr_fp64); use precision float32")
        self.precision = precision
        self.real = np.float64 if precision == "float64" else np.float32
        self.ctx = cl.Context([self.device])
        self.queue = cl.CommandQueue(
            self.ctx, properties=cl.command_queue_properties.PROFILING_ENABLE if profiling else 0)
        self.readback = Readback()
        self.host = HostArrays()
        self._kernels: dict = {}
        self._buffers: dict = {}
        self._data_key = None  # (data token, scale, baseband) of the data buffer's contents
        self._cell_tables = (None, None)  # (key, tables) of the last large grid's per-cell tables
        self._table_tiles: dict = {}  # (first angle, angles, padded angles) -> device buffers of those tables' tiles
        self._lock = threading.Lock()
        self._fresnel_key = None
        self._fresnel_value = float("inf")
        self._fd_steering = None
        self.max_tile_cells = max_tile_cells
        # the expansion serves float32 speed; float64 is the accuracy mode: exact distances
        self.fresnel = precision == "float32"
        is_cpu = bool(self.device.type & cl.device_type.CPU)
        self.vec, self.local = layout or (CPU_LAYOUT if is_cpu else GPU_LAYOUT)
        require(self.vec in (1, 2, 4, 8, 16) and self.local >= 1, OptionError,
                f"layout must be (lanes in 1, 2, 4, 8, 16; work-items >= 1), got {layout!r}")
        log.info("OpenCL device: %s, %s", device_label(self.device), precision)

    @property
    def label(self) -> str:
        """Device name and platform."""
        return device_label(self.device)

    def release(self) -> None:
        """Free the device buffers and the host arrays kept for reuse (the compiled programs are kept)."""
        with self._lock:
            for buf in self._buffers.values():
                buf.release()
            self._buffers.clear()
            self.host = HostArrays()
            self._data_key = None
            self._forget_cell_tables()

    def _fresnel_range(self, offsets_m: np.ndarray, samples_per_m: float) -> float:
        key = (np.round(offsets_m, 6).tobytes(), round(samples_per_m, 9), self.fresnel)
        if self._fresnel_key != key:
            self._fresnel_key = key
            self._fresnel_value = fresnel_min_range_m(offsets_m, samples_per_m, self.fresnel)
        return self._fresnel_value

    # -- program cache ----------------------------------------------------
    def _kernel(self, mode: InterpMode, outs: frozenset, n_samples: int, n_range: int, apodize: bool = False,
                table: bool = False, min_channels: int = 1):
        """The delay-and-sum kernel of this mode, outputs and sizes (built once)."""
        return self.build("beamform", [
            f"-DINTERP={mode.kernel_id}",
            f"-DLANCZOS_A={max(mode.lanczos_a, 1)}",
            f"-DBASEBAND={int(mode.baseband)}",
            f"-DN_SAMPLES={n_samples}",
            f"-DN_RANGE={n_range}",
            *output_macros(outs),
            f"-DVEC={self.vec}",
            f"-DAPODIZE={int(apodize)}",
            f"-DTRAVEL_TABLE={int(table)}",
            f"-DMIN_CHANNELS={int(min_channels)}",
        ])

    def build(self, entry: str, macros: list):
        """Kernel ``entry`` of ``kernels/<entry's file>`` built with ``macros`` and this engine's
        precision; kept, so each combination is built once."""
        key = (entry, tuple(macros))
        k = self._kernels.get(key)
        if k is None:
            cl = pyopencl()
            opts = [f"-DREAL_T={'double' if self.precision == 'float64' else 'float'}",
                    f"-DREAL_IS_DOUBLE={int(self.precision == 'float64')}", *macros]
            try:
                prg = cl.Program(self.ctx, kernel_source(KERNEL_FILES[entry])).build(options=opts)
            except cl.Error as exc:
                errors = [ln for ln in str(exc).splitlines() if "error" in ln.lower()]
                log.debug("kernel build log: %s", exc)
                raise DeviceError(f"kernel build failed on {self.label}: {(errors or [str(exc)])[-1].strip()}") from None
            k = getattr(prg, entry)
            self._kernels[key] = k
        return k

    def buffer(self, name: str, nbytes: int):
        cl = pyopencl()
        nbytes = max(int(nbytes), 16)
        buf = self._buffers.get(name)
        if buf is None or buf.size < nbytes:
            if buf is not None:
                buf.release()
            try:
                buf = cl.Buffer(self.ctx, cl.mem_flags.READ_WRITE, nbytes)
            except cl.Error as exc:
                raise DeviceError(f"cannot allocate {nbytes / 2**20:.1f} MiB on {self.label}: {exc}") from None
            self._buffers[name] = buf
        return buf

    def read_into(self, host: np.ndarray, buffer, offset_bytes: int = 0) -> None:
        """Queue the copy of ``host.nbytes`` from ``buffer`` at ``offset_bytes`` into the contiguous ``host``
        (waited for by the call's ``finish``), counted in :attr:`readback`."""
        event = pyopencl().enqueue_copy(self.queue, host, buffer, src_offset=offset_bytes, is_blocking=False)
        self.readback.add(event, host.nbytes)

    def upload(self, name: str, array: np.ndarray):
        cl = pyopencl()
        a = np.ascontiguousarray(array)
        buf = self.buffer(name, a.nbytes)
        cl.enqueue_copy(self.queue, buf, a)
        return buf

    def tile_rows(self, n_a: int, n_r: int, bytes_per_cell: int) -> int:
        """Angle rows of ``n_r`` ranges per launch that fit the device at ``bytes_per_cell``."""
        if self.max_tile_cells is not None:
            cells = self.max_tile_cells
        else:
            limit = min(self.device.max_mem_alloc_size, TILE_MEMORY_FRACTION * self.device.global_mem_size)
            cells = int(limit // max(bytes_per_cell, 1))
        rows = max(1, min(n_a, cells // n_r))
        require(cells >= n_r, GridError,
                f"one angle row of {n_r} ranges does not fit the device memory of {self.label}; use fewer ranges")
        return rows

    # -- imaging ----------------------------------------------------------
    def _check_mode(self, mode: InterpMode) -> None:
        check_mode_runs_on(mode, self.name)

    def _interpolate_beams(self, plan, beam, outs, out_windows, weighted, min_channels: int = 1):
        """Beam sums to the output grid on the device (kernels/beam_interp.cl)."""
        with self._lock:
            return interpolate_beams_cl(self, plan, beam, outs, out_windows, weighted, min_channels)

    def _steering(self):
        """The frequency-domain beams' steering sums on the device (kernels/fdbeam.cl), built once."""
        if self._fd_steering is None:
            from clbeam.imaging.engine.opencl_fdbeams import ClSteering

            self._fd_steering = _Locked(ClSteering(self), self._lock)
        return self._fd_steering

    def _beamform(self, inp, grid, mode, outs, range_window_m, scale: float) -> Sums:
        """Image one ping on the device (see :meth:`Engine.beamform`): one
        command queue per engine, so calls from several threads take turns."""
        require(2 * inp.n_channels * (inp.n_samples + 1) < 2**31, GridError,
                f"{inp.n_channels} channels x {inp.n_samples} samples exceed the kernel's 32-bit indexing; "
                "image fewer samples")
        with self._lock:
            launch = self._prepare(inp, grid, mode, outs, range_window_m, scale)
            out = _Outputs(self, grid, outs, inp.weights is not None, launch.rows)
            for a0 in range(0, grid.shape[0], launch.rows):
                self._run_tile(launch, out, a0)
            self.queue.finish()
            self.readback.settle()
        return out.sums()

    def _prepare(self, inp, grid, mode, outs, range_window_m, scale: float) -> "_Launch":
        """Kernel, uploaded channel data (times ``scale``) and per-range tables, cell windows and tile size of one call."""
        real = self.real
        data_buffer = self._upload_data(inp, mode, scale)
        o = np.asarray(inp.element_offsets_m, dtype=np.float64)
        chan = np.stack([o[:, 1], o[:, 2], np.sum(o * o, axis=1), o[:, 0] ** 2], axis=1).astype(real)
        so = np.asarray(inp.source_offset_m, dtype=np.float64)
        base_int, base_frac, base_phase = split_samples(range_bases(inp, grid), inp, real)
        apodize, table = inp.weights is not None, inp.tables is not None
        if table:
            inp.check_tables(grid)
        kernel = self._kernel(mode, outs, inp.n_samples, grid.shape[1], apodize, table, inp.min_channels)
        itemsize = np.dtype(real).itemsize
        per_cell = (itemsize * (("intensity" in outs) + ("cf" in outs) + (3 + apodize) * ("sums" in outs) + 5 * table
                                + ("signature" in outs)) + 4 * ("sums" in outs) + 4 * table)
        wg_max = kernel.get_work_group_info(pyopencl().kernel_work_group_info.WORK_GROUP_SIZE, self.device)
        local = max(1, min(self.local, wg_max))
        lanes = self.vec * local  # angles per tile
        th = np.deg2rad(grid.angles_deg)
        args = [data_buffer, self.upload("chan", chan), np.int32(inp.n_channels),
                self.upload("weights", np.asarray(inp.weights if apodize else np.ones(1), dtype=real))]
        signature = self.upload("signature", channel_signature(inp.n_channels).astype(real))
        ranges = [self.upload("range", grid.ranges_m.astype(real)), self.upload("base_int", base_int),
                  self.upload("base_frac", base_frac), self.upload("base_phase", base_phase),
                  real(so[1]), real(so[2]), real(so[0] ** 2), real(np.dot(so, so)),
                  real(inp.samples_per_m), real(self._fresnel_range(o, inp.samples_per_m)),
                  real(2 * np.pi * inp.centre_frequency_hz / inp.sample_rate_hz)]
        return _Launch(kernel=kernel, local=local, lanes=lanes,
                       rows=max(lanes, self.tile_rows(grid.shape[0], grid.shape[1], per_cell) // lanes * lanes),
                       window=cell_windows(inp, grid, mode, range_window_m),
                       angle_tab=np.stack([np.sin(th), np.cos(th)], axis=1).astype(real),
                       cell_tabs=self._cell_tables_of(inp, grid) if table else None, head_args=args, range_args=ranges,
                       signature=signature)

    def _cell_tables_of(self, inp, grid) -> dict:
        """:func:`cell_tables` of ``inp`` on ``grid``; a grid of :data:`CACHED_TABLE_CELLS` cells or more (not a
        list of points, one range: a refinement's, made anew each call) keeps them for the next call with the
        same tables, record start, sample rate and carrier (the pings of a line through one profile: a
        paper-size grid's take about 1 s to make)."""
        key = (inp.tables, grid, inp.t0_s, inp.sample_rate_hz, inp.centre_frequency_hz)
        last, tabs = self._cell_tables
        if last is not None and all(a is b if k < 2 else a == b for k, (a, b) in enumerate(zip(last, key))):
            return tabs
        tabs = cell_tables(inp, grid, self.real)
        if grid.n_cells >= CACHED_TABLE_CELLS and grid.shape[1] > 1:
            self._forget_cell_tables()
            self._cell_tables = (key, tabs)
        return tabs

    def _forget_cell_tables(self) -> None:
        """Let the kept per-cell tables and their device tiles go."""
        for bufs in self._table_tiles.values():
            for buf in bufs:
                buf.release()
        self._table_tiles = {}
        self._cell_tables = (None, None)

    def _table_tile(self, cell_tabs: dict, a0: int, na: int, na_pad: int) -> list:
        """Device buffers of the per-cell tables' angle rows ``a0 .. a0 + na`` padded to ``na_pad``: the kept
        tables' tiles stay on the device for the next call (a paper-size grid's six tables, 0.2 GB, padded and
        uploaded anew took 0.1-0.2 s a ping) while they fit :data:`KEPT_TABLE_MEMORY_FRACTION` of its memory."""
        kept, key = cell_tabs is self._cell_tables[1], (a0, na, na_pad)
        if kept and key in self._table_tiles:
            return self._table_tiles[key]
        padded = [_padded_table(cell_tabs[k], a0, na, na_pad, k) for k in TABLE_NAMES]
        held = sum(b.size for bufs in self._table_tiles.values() for b in bufs)
        if kept and held + sum(t.nbytes for t in padded) <= KEPT_TABLE_MEMORY_FRACTION * self.device.global_mem_size:
            cl = pyopencl()
            try:
                bufs = [cl.Buffer(self.ctx, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR, hostbuf=t)
                        for t in padded]
            except cl.Error:  # the device is full: uploaded each call instead
                pass
            else:
                self._table_tiles[key] = bufs
                return bufs
        return [self.upload("tab_" + k, t) for k, t in zip(TABLE_NAMES, padded)]

    def _upload_data(self, inp, mode, scale: float):
        """The device copy of the channels times ``scale`` (basebanded for the basebanded modes),
        uploaded again unless the last upload was of the same data token, scale and baseband."""
        key = (inp.data_token, scale, mode.baseband)
        last = self._data_key
        if inp.data_token is not None and last is not None and last[0] is key[0] and last[1:] == key[1:]:
            return self._buffers["data"]
        data = np.asarray(inp.data)
        if mode.baseband:
            data = baseband(data, inp.centre_frequency_hz, inp.sample_rate_hz)
        inter = self.host.empty((inp.n_channels, inp.n_samples, 2), self.real)
        np.multiply(data.real, scale, out=inter[..., 0])
        np.multiply(data.imag, scale, out=inter[..., 1])
        self._data_key = None  # a failed upload leaves no key behind
        buffer = self.upload("data", inter)
        self._data_key = key
        return buffer

    def _run_tile(self, launch: "_Launch", out: "_Outputs", a0: int) -> None:
        """Launch the kernel on the angle rows ``a0 ..`` of one tile and read its results back."""
        real = self.real
        na = min(launch.rows, out.n_angles - a0)
        na_pad = -(-na // launch.lanes) * launch.lanes
        tab = np.zeros((2, na_pad), dtype=real)
        tab[:, :na] = launch.angle_tab[a0:a0 + na].T
        win = np.zeros((na_pad, 2), dtype=np.int32)
        win[:na] = launch.window[a0:a0 + na]
        tiles = launch_tiles(win, launch.lanes)
        tab_bufs = [self.buffer("tab_" + k, 16) for k in TABLE_NAMES]
        if launch.cell_tabs is not None:
            tab_bufs = self._table_tile(launch.cell_tabs, a0, na, na_pad)
        out.clear(na_pad)
        if len(tiles):
            launch.kernel(self.queue, (len(tiles) * launch.local,), (launch.local,),
                          *launch.head_args, self.upload("tiles", tiles),
                          self.upload("angle_sin", tab[0]), self.upload("angle_cos", tab[1]),
                          self.upload("win_first", np.ascontiguousarray(win[:, 0])),
                          self.upload("win_end", np.ascontiguousarray(win[:, 1])),
                          *launch.range_args, *out.buffer_args(launch.signature), np.int32(na_pad), *tab_bufs)
        out.read(a0, na, na_pad)


class _Locked:
    """A callable that holds ``lock`` while it runs (the engine's queue and buffers are shared)."""

    def __init__(self, fn, lock):
        self.fn, self.lock = fn, lock

    def __call__(self, *args):
        with self.lock:
            return self.fn(*args)


@dataclass
class Readback:
    """The engine's device-to-host copies so far: their bytes and, on a profiling queue, their device time
    (NaN otherwise).  A copy's event holds its host array until :meth:`settle` (an event let go before its
    copy ends would wait for it), which each call does after its queue's ``finish``."""

    n_bytes: int = 0
    device_s: float = 0.0
    pending: list = field(default_factory=list)

    def add(self, event, n_bytes: int) -> None:
        """Count a queued copy of ``n_bytes``."""
        self.n_bytes += int(n_bytes)
        self.pending.append(event)

    def settle(self) -> None:
        """Add the finished copies' device time and let their events go."""
        for event in self.pending:
            try:
                self.device_s += (event.profile.end - event.profile.start) * 1e-9
            except pyopencl().Error:  # the queue does not profile
                self.device_s = float("nan")
        self.pending = []

    def throughput_gb_s(self) -> float:
        """Bytes over device time (GB/s; NaN without profiling)."""
        return self.n_bytes / self.device_s / 1e9 if self.device_s > 0 else float("nan")


@dataclass
class _Launch:
    """What every tile of one call shares: the kernel, its launch shape, the
    per-angle tables and windows, and the leading kernel arguments."""

    kernel: object
    local: int
    lanes: int
    rows: int
    window: np.ndarray
    angle_tab: np.ndarray
    cell_tabs: dict | None
    head_args: list
    range_args: list
    signature: object


class _Outputs:
    """The host arrays of one call's outputs and their device buffers (one tile of rows)."""

    PLANES = {"intensity": 1, "cf": 1, "s": 2, "q": 1, "m": 1, "w": 1, "g": 1}

    def __init__(self, engine: "OpenCLEngine", grid: PolarGrid, outs: frozenset, apodize: bool, rows: int):
        self.engine, real = engine, engine.real
        self.n_angles, self.n_ranges = n_a, n_r = grid.shape
        self.full = {}
        host = engine.host
        if "intensity" in outs:
            self.full["intensity"] = host.empty((n_a, n_r), real)
        if "cf" in outs:
            self.full["cf"] = host.empty((n_a, n_r), real)
        if "sums" in outs:
            self.full.update(s=host.empty((2, n_a, n_r), real), q=host.empty((n_a, n_r), real),
                             m=host.empty((n_a, n_r), np.int32))
            if apodize:
                self.full["w"] = host.empty((n_a, n_r), real)
        if "signature" in outs:
            self.full["g"] = host.empty((n_a, n_r), real)
        self.bufs = {name: engine.buffer("out_" + name, planes * rows * n_r * (4 if name == "m" else real().itemsize)
                                          if name in self.full else 16) for name, planes in self.PLANES.items()}

    def buffer_args(self, signature) -> list:
        """The output buffers in the kernel's argument order, the channel signature before ``out_g``."""
        b = self.bufs
        return [b["intensity"], b["cf"], b["s"], b["q"], b["m"], b["w"], signature, b["g"]]

    def clear(self, na_pad: int) -> None:
        """Zero the outputs of a tile of ``na_pad`` angle rows (cells the kernel skips stay 0)."""
        cl = pyopencl()
        for name, arr in self.full.items():
            cl.enqueue_fill_buffer(self.engine.queue, self.bufs[name], np.zeros(1, dtype=arr.dtype), 0,
                                   self.PLANES[name] * na_pad * self.n_ranges * arr.itemsize)

    def read(self, a0: int, na: int, na_pad: int) -> None:
        """Queue the copies of a tile's results into rows ``a0 .. a0 + na`` of the host arrays: one per output
        plane, straight into place, not waited for (the queue runs in order: the next tile's commands start
        after them; the call's ``finish`` waits for the last)."""
        for name, arr in self.full.items():
            planes = [arr[0, a0:a0 + na], arr[1, a0:a0 + na]] if name == "s" else [arr[a0:a0 + na]]
            for k, plane in enumerate(planes):
                self.engine.read_into(plane, self.bufs[name], k * na_pad * self.n_ranges * arr.itemsize)

    def sums(self) -> Sums:
        """The results as :class:`Sums`."""
        f = self.full
        res = Sums(intensity=f.get("intensity"), cf=f.get("cf"), q=f.get("q"), m=f.get("m"), w=f.get("w"),
                   signature=f.get("g"))
        if "s" in f:
            res.s = f["s"][0] + 1j * f["s"][1]
        return res


def _padded_table(a: np.ndarray, a0: int, na: int, na_pad: int, name: str) -> np.ndarray:
    """Rows ``a0 .. a0 + na`` of a per-cell table, transposed to ``(n_range, na_pad)``; padding
    angles get a tap no ray reaches."""
    t = np.zeros((a.shape[1], na_pad), dtype=a.dtype)
    t[:, :na] = a[a0:a0 + na].T
    if name == "int":
        t[:, na:] = UNREACHABLE_TAP
    return t


#: cells of a grid at least whose per-cell tables the engine keeps for its next call
CACHED_TABLE_CELLS = 1 << 18
#: names of the per-cell travel-time tables, in the kernel's argument order
TABLE_NAMES = ("int", "frac", "phase", "sin", "cos", "rho")
#: integer tap of a cell no ray reaches: far before any record, so never inside
UNREACHABLE_TAP = -(1 << 30)
#: wavefront radii (m) are clipped here for the float32 kernel
MAX_WAVEFRONT_RADIUS_M = 1e8


def split_samples(base: np.ndarray, inp: BeamformInput, real) -> tuple:
    """Sample positions (float64) split into the integer sample (int32), the
    fraction and the carrier phase at the integer sample (``real``): float32
    keeps sub-sample precision at any range this way."""
    k = np.floor(base)
    require(bool(np.all(np.abs(k) < 2**31 - 2**20)), GridError,
            "grid ranges reach beyond 2^31 samples of the record; reduce the maximum range")
    phase = carrier_phase(inp.centre_frequency_hz, inp.sample_rate_hz, k.astype(np.int64)).astype(real)
    return k.astype(np.int32), (base - k).astype(real), phase


def cell_tables(inp: BeamformInput, grid: PolarGrid, real=np.float32) -> dict:
    """The kernel's per-cell tables ``(n_angle, n_range)`` from ``inp.tables``:
    the centre's two-way sample position split into an integer and a
    fraction (float64 on the host), its carrier phase, the launch direction
    and the wavefront radius; unreachable cells get :data:`UNREACHABLE_TAP`
    and finite dummies."""
    tab = inp.tables
    base = inp.cell_base_samples(grid)
    ok = np.isfinite(base) & np.isfinite(tab.wavefront_radius_m) & np.isfinite(tab.launch_sin) & np.isfinite(tab.launch_cos)
    k, frac, phase = split_samples(np.where(ok, base, 0.0), inp, real)
    th = np.deg2rad(grid.angles_deg)[:, None]
    return {
        "int": np.where(ok, k, UNREACHABLE_TAP).astype(np.int32),
        "frac": np.where(ok, frac, 0.0).astype(real),
        "phase": phase,
        "sin": np.where(ok, tab.launch_sin, np.sin(th)).astype(real),
        "cos": np.where(ok, tab.launch_cos, np.cos(th)).astype(real),
        # near grazing rays the radius can reach 1e11 m, whose square overflows
        # float32; beyond 1e8 m the curvature term is below 1e-8 m anyway
        "rho": np.where(ok, np.minimum(tab.wavefront_radius_m, MAX_WAVEFRONT_RADIUS_M), grid.ranges_m[None, :]).astype(real),
    }


def launch_tiles(window: np.ndarray, local_angles: int) -> np.ndarray:
    """Work-group tiles ``(n_tiles, 2)`` = (first angle, range row) covering
    every cell inside ``window`` (``(n_angle_padded, 2)`` first/end range).

    A tile is ``local_angles`` consecutive angles at one range row; for each
    block of angles the rows from the smallest first to the largest end are
    launched, the kernel zeroes the cells of a tile outside their own window.
    Tiles are ordered by range row, then angle: the cells of one range row
    read each channel's record within a few dozen samples of one another,
    so consecutive work-groups find their samples in cache (2.2-2.5x faster
    for the low-order modes on a CPU than angle-block order, which streams
    the whole record once per block of angles; bench/kernel_profile.py).
    """
    n = window.shape[0] // local_angles
    blocks = window.reshape(n, local_angles, 2)
    nonempty = blocks[:, :, 1] > blocks[:, :, 0]
    lo = np.where(nonempty, blocks[:, :, 0], np.iinfo(np.int32).max).min(axis=1)
    hi = np.where(nonempty, blocks[:, :, 1], 0).max(axis=1)
    counts = np.maximum(hi - lo, 0).astype(np.int64)
    first = np.repeat(np.arange(n) * local_angles, counts)
    # each block's rows lo .. hi - 1, all blocks at once (a point list has one block per 16 points)
    rows = np.arange(int(counts.sum())) + np.repeat(lo.astype(np.int64) - (np.cumsum(counts) - counts), counts)
    tiles = np.stack([first, rows], axis=1).astype(np.int32)
    return tiles[np.lexsort((tiles[:, 0], tiles[:, 1]))]


#: truncation error allowed for the Fresnel expansion of the element delays (samples)
FRESNEL_TOLERANCE_SAMPLES = 1e-5


def fresnel_min_range_m(offsets_m: np.ndarray, samples_per_m: float, enabled: bool = True) -> float:
    """Smallest range (m) from which the third-order expansion of every
    element's ``|R u - o| - R`` is within :data:`FRESNEL_TOLERANCE_SAMPLES`.

    The error is measured, not bounded: for ranges on a geometric ladder the
    exact and expanded delays of all elements are compared over all angles
    (it falls like ``|o|^4 / R^3``); ``inf`` disables the expansion.
    """
    if not enabled or len(offsets_m) == 0:
        return float("inf")
    o = np.asarray(offsets_m, dtype=np.float64)
    th = np.deg2rad(np.linspace(-90, 90, 181))
    u = np.stack([np.sin(th), np.cos(th)], axis=1)
    p = u @ o[:, 1:3].T                        # (angle, element)
    q = np.sum(o * o, axis=1)[None, :]
    tol_m = FRESNEL_TOLERANCE_SAMPLES / samples_per_m
    reach = max(float(np.sqrt(q.max())), 1e-3)
    for r in reach * 2.0 ** np.arange(1, 40, 0.25):
        exact = np.sqrt((r * u[:, :1] - o[None, :, 1]) ** 2 + (r * u[:, 1:] - o[None, :, 2]) ** 2
                        + o[None, :, 0] ** 2) - r
        approx = -p + (q - p * p) / (2 * r) * (1 + p / r)
        if np.max(np.abs(exact - approx)) < tol_m:
            return float(r)
    return float("inf")
