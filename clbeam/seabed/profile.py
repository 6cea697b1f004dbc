"""Along-track profile: the vertical beam of every ping, as SEG-Y and as a figure.

:func:`write_profile` forms the vertical beam of each ping of a ping file
(:class:`~clbeam.imaging.vertical_beam.VerticalBeam`: the mean analytic
signal ``S / M`` on an earth-referenced nadir beam), writes the traces as
SEG-Y (:class:`~clbeam.io.segy.SegyProfileWriter`, IEEE float) with the
ping's navigation, time and pulse in the trace headers, and draws the
profile like Holland et al. (2024) Fig. 1 (:func:`plot_profile`).
``clbeam profile`` (:mod:`clbeam.cli.profile`) is the command;
``docs/profile.md`` lists every header field written.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from clbeam import __version__
from clbeam.errors import OptionError, require
from clbeam.imaging.vertical_beam import TraceAxis, VerticalBeam, pool_max
from clbeam.io.paths import check_output_path
from clbeam.io.pingfile import PingFile
from clbeam.io.segy import COORDINATE_SCALAR, SegyProfileWriter, segyio_module
from clbeam.model.geodesy import along_track_m

#: the profile figure keeps at most this many rows (max-pooled) of each trace
PLOT_MAX_ROWS = 2000


# -- the figure --------------------------------------------------------------------
def _interp_linear(x, xp, fp):
    """Piecewise-linear ``fp(xp)`` at ``x``, extended linearly beyond both ends."""
    x = np.asarray(x, dtype=np.float64)
    y = np.interp(x, xp, fp)
    lo, hi = x < xp[0], x > xp[-1]
    y = np.where(lo, fp[0] + (x - xp[0]) * (fp[1] - fp[0]) / (xp[1] - xp[0]), y)
    return np.where(hi, fp[-1] + (x - xp[-1]) * (fp[-1] - fp[-2]) / (xp[-1] - xp[-2]), y)


def profile_figure(envelope: np.ndarray, *, t_top_s: float, t_bottom_s: float, sound_speed_m_s: float,
                   along_track_distance_m: np.ndarray | None = None, title: str = "",
                   dynamic_range_db: float = 50.0):
    """The figure of an along-track profile like Holland et al. (2024) Fig. 1.

    Parameters
    ----------
    envelope : numpy.ndarray
        ``(n_ping, n_rows)`` envelope, rows evenly spaced in two-way time;
        row ``i`` is ping ``i``, drawn centred on ``i`` of the ping axis
        (pings numbered from 0, as in every other output).
    t_top_s, t_bottom_s : float
        Two-way time (s) of the top edge of the first row and the bottom edge
        of the last.
    sound_speed_m_s : float
        Sound speed (m/s) of the depth axis, ``depth = c t / 2`` below the source.
    along_track_distance_m : numpy.ndarray, optional
        Distance of each ping along the track (m), drawn as the top axis when
        it increases strictly.
    title : str
        Figure title.
    dynamic_range_db : float
        Colour range (dB) below the profile's maximum.

    Returns
    -------
    matplotlib.figure.Figure
        The figure (not drawn on a screen).
    """
    from matplotlib.figure import Figure

    env = np.asarray(envelope, dtype=np.float64)
    top = float(env.max()) if env.size and env.max() > 0 else 1.0
    with np.errstate(divide="ignore"):
        db = 20 * np.log10(env / top)
    n_ping = env.shape[0]
    fig = Figure(figsize=(10, 5.5), layout="constrained")
    ax = fig.add_subplot()
    im = ax.imshow(db.T, extent=(-0.5, n_ping - 0.5, 1e3 * t_bottom_s, 1e3 * t_top_s), aspect="auto",
                   cmap="gray_r", vmin=-dynamic_range_db, vmax=0, interpolation="nearest")
    _label_axes(ax, n_ping, sound_speed_m_s, along_track_distance_m)
    fig.colorbar(im, ax=ax, label="envelope (dB re maximum)", pad=0.02)
    if title:
        fig.suptitle(title)
    return fig


def plot_profile(envelope: np.ndarray, path, **kwargs) -> Path:
    """Draw an along-track profile (:func:`profile_figure`) into a PNG file.

    Parameters
    ----------
    envelope : numpy.ndarray
        ``(n_ping, n_rows)`` envelope, rows evenly spaced in two-way time.
    path : str or path-like
        PNG file to write.
    **kwargs
        The keyword arguments of :func:`profile_figure` (time axis (s), sound
        speed (m/s), along-track distance (m), title, dynamic range (dB)).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    fig = profile_figure(envelope, **kwargs)
    p = Path(path)
    try:
        fig.savefig(p, dpi=120)
    except OSError as exc:
        raise OptionError(f"cannot write figure {p}: {exc}") from None
    return p


def _label_axes(ax, n_ping: int, sound_speed_m_s: float, along_track_distance_m) -> None:
    """Ping (from 0) and two-way time (ms) axes, with depth (m, ``c t / 2``) on the right and, when it
    increases strictly, along-track distance (m) on top."""
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("ping")
    ax.set_ylabel("two-way time (ms)")
    half_c_ms = 0.5 * sound_speed_m_s * 1e-3
    ax.secondary_yaxis("right", functions=(lambda t: t * half_c_ms, lambda d: d / half_c_ms)).set_ylabel(
        f"depth below the source (m, c = {sound_speed_m_s:g} m/s)")
    d = along_track_distance_m
    if d is not None and len(d) == n_ping and n_ping > 1 and np.all(np.diff(d) > 0):
        pings = np.arange(n_ping, dtype=np.float64)
        sec = ax.secondary_xaxis("top", functions=(lambda p: _interp_linear(p, pings, d),
                                                   lambda x: _interp_linear(x, d, pings)))
        sec.set_xlabel("along-track distance (m)")


# -- the whole profile -------------------------------------------------------------
@dataclass(frozen=True)
class ProfileResult:
    """What :func:`write_profile` wrote.

    Attributes
    ----------
    segy_path : pathlib.Path
        SEG-Y file.
    png_path : pathlib.Path or None
        Figure, if drawn.
    axis : TraceAxis
        Trace time axis.
    n_pings : int
        Pings (one ensemble each).
    traces_per_ping : int
        1 (envelope) or 2 (real, imaginary part of ``S / M``).
    seconds : float
        Wall time (s).
    """

    segy_path: Path
    png_path: Path | None
    axis: TraceAxis
    n_pings: int
    traces_per_ping: int
    seconds: float


def _header_lines(source: Path, pings: PingFile, axis: TraceAxis, *, interp: str, analytic: bool) -> list[str]:
    """The lines of the SEG-Y textual header: what the traces are and where each field is."""
    n = pings.n_pings
    c = np.asarray(pings.ds["sound_speed"].values, dtype=np.float64)
    pulse = pings.pulse
    if pulse is None:
        pulse_line = "PULSE: NONE (INPUT ALREADY PULSE-COMPRESSED ANALYTIC)"
    elif pulse.waveform is not None:
        pulse_line = f"PULSE: EXPLICIT WAVEFORM, {len(pulse.waveform)} SAMPLES; SWEEP TYPE 4 (OTHER)"
    else:
        pulse_line = (f"PULSE: LFM {pulse.f0_hz:g}-{pulse.f1_hz:g} HZ, {1e3 * pulse.duration_s:g} MS; "
                      "SWEEP FIELDS SET, TYPE 1 (LINEAR)")
    layout = ("TRACES PER PING 2: REAL(S/M) (TRACE NUMBER 1), IMAG(S/M) (TRACE NUMBER 2)" if analytic
              else "TRACES PER PING 1: ENVELOPE |S|/M (TRACE NUMBER 1)")
    return [
        f"CLBEAM {__version__} ALONG-TRACK PROFILE: ONE VERTICAL BEAM PER PING",
        f"SOURCE FILE: {source.name}",
        f"PINGS: {n}  TRACES: {n * (2 if analytic else 1)}  SAMPLES/TRACE: {axis.n_samples}",
        f"SAMPLE INTERVAL: {axis.interval_us} US  DELAY (T0): {axis.delay_ms} MS  FORMAT 5 IEEE FLOAT",
        "BEAM: 0 DEG FROM NADIR, EARTH-REFERENCED (ROLL, HEAVE COMPENSATED; PITCH IGNORED)",
        "DELAY-AND-SUM OF PULSE-COMPRESSED ANALYTIC CHANNELS",
        f"INTERPOLATION {interp.upper()}",
        "S = COHERENT SUM OVER THE M CONTRIBUTING CHANNELS; TRACE = S/M, 0 WHERE M = 0",
        layout,
        "SAMPLE K: TWO-WAY TIME DELAY + K*INTERVAL; RANGE FROM SOURCE = C*T/2",
        f"SOUND SPEED {c.min():g}-{c.max():g} M/S" if c.min() != c.max() else f"SOUND SPEED {c.min():g} M/S",
        pulse_line,
        "COORDINATES: SOURCE/GROUP/CDP X = LONGITUDE, Y = LATITUDE IN ARC-SECONDS,",
        f"  SCALAR {COORDINATE_SCALAR} (BYTES 71-72), COORDINATE UNITS 2 (BYTES 89-90)",
        "TIME: PING TIME (UTC, TIME BASIS 4), WHOLE SECONDS",
        "FIELD RECORD = CDP = ENERGY SOURCE POINT = PING INDEX IN THE FILE + 1",
        "NSTACKEDTRACES (BYTES 33-34) = CHANNELS USED IN THE PING",
    ]


def _output_paths(segy_path, png_path, plot: bool) -> tuple[Path, Path | None]:
    """The SEG-Y path and the figure's (``None`` without ``plot``), both checked writable."""
    segy = Path(segy_path)
    png = (Path(png_path) if png_path is not None else segy.with_suffix(".png")) if plot else None
    require(png is None or png.resolve() != segy.resolve(), OptionError,
            f"the figure and the SEG-Y file are both {segy}; give another --png")
    check_output_path(segy, what="SEG-Y file", zarr_ok=False)
    if png is not None:
        check_output_path(png, what="figure", zarr_ok=False)
    return segy, png


@dataclass(frozen=True)
class _Traced:
    """What writing the traces leaves for the figure and the result.

    ``rows``: ``(n_ping, n_rows)`` envelopes max-pooled by ``factor`` samples
    (``None`` without a figure); ``latitude_deg``, ``longitude_deg``: each
    ping's position (degrees, NaN without navigation); ``sound_speed_m_s``:
    the mean sound speed (m/s) of the pings, for the depth axis.
    """

    rows: np.ndarray | None
    factor: int
    latitude_deg: np.ndarray
    longitude_deg: np.ndarray
    sound_speed_m_s: float

    @property
    def n_pings(self) -> int:
        """Pings written."""
        return self.latitude_deg.size


def _open_writer(segy_path: Path, pings_path: Path, pings: PingFile, axis: TraceAxis, *, interp: str,
                 analytic: bool) -> SegyProfileWriter:
    """The SEG-Y writer of the profile of ``pings``, its textual header filled in."""
    return SegyProfileWriter(segy_path, axis, pings.n_pings, analytic=analytic,
                             text_lines=_header_lines(pings_path, pings, axis, interp=interp, analytic=analytic),
                             pulse=pings.pulse, sample_rate_hz=pings.sample_rate_hz,
                             n_record_samples=pings.n_samples)


def _write_traces(pings: PingFile, beam: VerticalBeam, writer: SegyProfileWriter, *, keep_rows: bool,
                  progress=None) -> _Traced:
    """Form and write the vertical beam of every ping, keeping what the figure needs."""
    n, n_samples = pings.n_pings, beam.axis.n_samples
    factor = max(1, -(-n_samples // PLOT_MAX_ROWS))
    rows = np.zeros((n, -(-n_samples // factor)), dtype=np.float32) if keep_rows else None
    lat, lon = np.full(n, np.nan), np.full(n, np.nan)
    for ping in progress(pings, n) if progress is not None else pings:
        tr = beam(ping)
        writer.write(ping, tr.analytic, tr.n_channels_used)
        if rows is not None:
            rows[ping.index] = pool_max(tr.envelope, factor)
        if ping.has_navigation:
            lat[ping.index], lon[ping.index] = ping.latitude_deg, ping.longitude_deg
    return _Traced(rows, factor, lat, lon, float(np.mean(pings.ds["sound_speed"].values)))


def _draw(traced: _Traced, png: Path, axis: TraceAxis, title: str) -> None:
    """The profile figure of the pooled rows, with along-track distance when every ping has navigation."""
    dt = 1e-6 * axis.interval_us
    t_top = 1e-3 * axis.delay_ms - 0.5 * dt
    lat, lon = traced.latitude_deg, traced.longitude_deg
    dist = along_track_m(lat, lon) if np.all(np.isfinite(lat)) and lat.size > 1 else None
    plot_profile(traced.rows, png, t_top_s=t_top, t_bottom_s=t_top + traced.rows.shape[1] * traced.factor * dt,
                 sound_speed_m_s=traced.sound_speed_m_s, along_track_distance_m=dist, title=title)


def write_profile(pings_path, segy_path, *, png_path=None, plot: bool = True, max_range_m: float | None = None,
                  interp: str = "auto", analytic: bool = False, backend: str = "opencl", device=None,
                  engine=None, progress=None) -> ProfileResult:
    """Form the vertical beam of every ping of a ping file; write SEG-Y and a figure.

    Parameters
    ----------
    pings_path : str or path-like
        Ping file (docs/ping-format.md).
    segy_path : str or path-like
        SEG-Y file to write (see ``docs/profile.md``).
    png_path : str or path-like, optional
        Figure to write; default: ``segy_path`` with suffix ``.png``.
    plot : bool
        Draw the figure.
    max_range_m : float, optional
        Largest range (m) of the traces (default: the end of the record).
    interp : str
        Interpolation mode of the delay-and-sum.
    analytic : bool
        Write the real and imaginary parts of ``S / M`` (2 traces per ping)
        instead of the envelope ``|S| / M``.
    backend : {"opencl", "reference"}
        Imaging engine.
    device : str or int, optional
        OpenCL device.
    engine : object, optional
        An existing engine to use.
    progress : callable, optional
        ``progress(iterable, total)`` wraps the ping loop (a progress bar).

    Returns
    -------
    ProfileResult

    Raises
    ------
    ClbeamError
        On a bad ping file, option or output path; a partly written SEG-Y
        file is removed.
    """
    t_start = time.perf_counter()
    segy_path, png = _output_paths(segy_path, png_path, plot)
    segyio_module()  # before any imaging
    pings_path = Path(pings_path)
    with PingFile(pings_path) as pings:
        axis = TraceAxis.for_file(pings, max_range_m=max_range_m)
        beam = VerticalBeam(axis, interp=interp, backend=backend, device=device, engine=engine)
        setting = beam.setting(pings.ping(0)) if interp == "auto" else interp  # the header names what is used
        writer = _open_writer(segy_path, pings_path, pings, axis, interp=setting, analytic=analytic)
        try:
            with writer:
                traced = _write_traces(pings, beam, writer, keep_rows=png is not None, progress=progress)
        except BaseException:
            segy_path.unlink(missing_ok=True)  # no half-written profile left behind
            raise
    if png is not None:
        _draw(traced, png, axis, f"{pings_path.name}: vertical beam, envelope |S|/M")
    return ProfileResult(segy_path=segy_path, png_path=png, axis=axis, n_pings=traced.n_pings,
                         traces_per_ping=2 if analytic else 1, seconds=time.perf_counter() - t_start)

__all__ = ["PLOT_MAX_ROWS", "ProfileResult", "plot_profile", "profile_figure", "write_profile"]
