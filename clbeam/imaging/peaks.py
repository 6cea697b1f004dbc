"""Peak-table rows of one ping: the one builder for images in memory and in files.

:func:`peak_rows` turns a smoothed CF image into the rows of the peaks table
(docs/peaks.md): every coherence peak, or with ``mlh=True`` one detection
per main-lobe arc (:mod:`clbeam.imaging.mlh`).  What it needs of the ping
besides the image is a :class:`PingContext`, which the
:class:`~clbeam.imaging.imager.Imager` builds from a
:class:`~clbeam.model.ping.Ping` and :func:`peaks_from_images` reads back
from an image file, so ``clbeam image --peaks`` and ``clbeam peaks`` give the
same rows.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from clbeam.constants import (
    DEFAULT_MIN_CONTRAST_DB,
    DEFAULT_MIN_SNR_DB,
    PEAK_THRESHOLD,
    SBP29_ARRAY_WIDTH_M,
    SBP29_BAND_HZ,
    SOUND_SPEED_M_S,
)
from clbeam.imaging.detection import (
    contrast_at,
    contrast_windows,
    gate_peaks,
    noise_floor,
    smoothing_eigenvalues,
    snr_tests_pass,
)
from clbeam.imaging.geometry import to_earth_frame
from clbeam.imaging.mlh import (
    MLH_COLUMNS,
    arc_tolerances,
    detection_rows,
    suppress_main_lobe_highlights,
)
from clbeam.imaging.postprocess import coherence_peaks, hann_smooth, intensity_db, peak_rows_at
from clbeam.io.conventions import epoch_seconds
from clbeam.io.peaks import REFINE_COLUMNS
from clbeam.io.survey_store import SURVEY_TIME_VARIABLE
from clbeam.model.grid import PolarGrid

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PingContext:
    """What the peak rows of a ping need besides its image.

    Attributes
    ----------
    index : int
        Ping index.
    centre_yz_m : (float, float)
        Earth-frame grid centre (m): peaks' ``y``, ``z`` are measured from
        the array reference point, ranges and angles from this centre.
    source_yz_m : (float, float) or None
        Earth-frame source (m) with roll and heave applied: the centre of the
        main-lobe arcs (``None``: the grid centre).
    latitude_deg, longitude_deg, heading_deg : float or None
        Ship navigation at the ping (degree).
    band_hz : (float, float)
        Pulse band (Hz) (the SBP29's where unknown).
    array_width_m : float
        Receive array width across-track (m).
    sound_speed_m_s : float
        Sound speed the ping was imaged with (m/s).
    n_channels : int or None
        Channels that took part (the peaks' false-alarm probability); ``None``: unknown.
    time : numpy.datetime64 or None
        Time of transmission (the image file's ``ping_time``).
    draft_m : float or None
        Depth of the array reference point below the sea surface (m); ``None``: not given.
    """

    index: int
    centre_yz_m: tuple
    source_yz_m: tuple | None = None
    latitude_deg: float | None = None
    longitude_deg: float | None = None
    heading_deg: float | None = None
    band_hz: tuple = SBP29_BAND_HZ
    array_width_m: float = SBP29_ARRAY_WIDTH_M
    sound_speed_m_s: float = SOUND_SPEED_M_S
    n_channels: int | None = None
    time: np.datetime64 | None = None
    draft_m: float | None = None

    @classmethod
    def of_ping(cls, ping, grid: PolarGrid, sound_speed_m_s: float | None = None,
                n_channels: int | None = None) -> "PingContext":
        """The context of a :class:`~clbeam.model.ping.Ping` imaged on ``grid``
        (at ``sound_speed_m_s``, default the ping's, from ``n_channels`` usable channels)."""
        pulse = ping.pulse
        known = pulse is not None and (pulse.waveform is not None or
                                       (pulse.f0_hz is not None and pulse.f0_hz != pulse.f1_hz))
        band = pulse.band_hz(ping.sample_rate_hz) if known else SBP29_BAND_HZ
        n = ping.n_channels
        width = float(np.ptp(ping.element_pos_m[:, 1])) * n / max(n - 1, 1)
        source = to_earth_frame(ping.source_pos_m, roll_deg=ping.roll_deg, heave_m=ping.heave_m)
        return cls(index=int(ping.index), centre_yz_m=tuple(float(v) for v in grid.centre(tuple(ping.source_pos_m[1:]))),
                   source_yz_m=(float(source[1]), float(source[2])), latitude_deg=ping.latitude_deg,
                   longitude_deg=ping.longitude_deg, heading_deg=ping.heading_deg, band_hz=band,
                   array_width_m=width, sound_speed_m_s=float(sound_speed_m_s or ping.sound_speed_m_s),
                   n_channels=n_channels, time=getattr(ping, "time", None),
                   draft_m=getattr(ping, "draft_m", None))

    @property
    def navigation(self) -> dict:
        """``latitude``, ``longitude``, ``heading`` (degree), ``time_s`` (s since 1970-01-01 UTC) and
        ``draft_m`` (m) for the ping's columns of a row (:func:`clbeam.imaging.postprocess.peak_row`)."""
        return {"latitude": self.latitude_deg, "longitude": self.longitude_deg, "heading": self.heading_deg,
                "time_s": epoch_seconds(self.time), "draft_m": self.draft_m}



def peak_rows(context: PingContext, cf_smooth: np.ndarray, intensity: np.ndarray | None, grid: PolarGrid, *,
              threshold: float = PEAK_THRESHOLD, mlh: bool = False, position: str = "lobe", refine=None,
              min_snr_db: float | None = DEFAULT_MIN_SNR_DB,
              min_contrast_db: float | None = DEFAULT_MIN_CONTRAST_DB, **mlh_options) -> list[dict]:
    """Rows of the peaks table for one ping (docs/peaks.md).

    Parameters
    ----------
    context : PingContext
        The ping's index, grid centre, source, navigation and sonar.
    cf_smooth : numpy.ndarray
        ``(n_angle, n_range)`` Hann-smoothed CF.
    intensity : numpy.ndarray or None
        ``(n_angle, n_range)`` intensity ``|S|^2`` (NaN in the rows without it).
    grid : PolarGrid
        The image grid.
    threshold : float
        Coherence-peak threshold on the smoothed CF (0-1).
    mlh : bool
        Merge the peaks of one main-lobe arc into one detection
        (:func:`clbeam.imaging.mlh.suppress_main_lobe_highlights`, tolerances
        from the context's band, array width and sound speed); the rows then
        carry :data:`clbeam.imaging.mlh.MLH_COLUMNS`.
    position : {"lobe", "peak"}
        With ``mlh``: report the lobe fit or the sub-cell maximum.
    refine : callable, optional
        ``refine(peaks) -> RefinedPeaks`` (:func:`clbeam.imaging.subcell.subcell_peaks`
        with the ping's data): rows at the refined points, one per echo, the grid
        cell's range, angle and smoothed CF in ``cell_range_m``, ``cell_angle_deg``,
        ``cell_cf`` and the grid peaks merged in ``cell_peaks`` (not with ``mlh``).
    min_snr_db, min_contrast_db : float or None
        Keep only peaks this far above the ping's noise floor, and above the mean of the clutter around
        them where it is reverberation (dB, :mod:`clbeam.imaging.detection`); ``None``: no such test.
    **mlh_options
        With ``mlh``: overrides of :func:`~clbeam.imaging.mlh.suppress_main_lobe_highlights`.

    Returns
    -------
    list of dict
        :data:`clbeam.io.peaks.PEAK_COLUMNS`, ``snr_db``, ``contrast_db`` and ``pfa`` (with an intensity
        image) and the ship's navigation, by decreasing CF.
    """
    if mlh:
        rows = _rows(context, cf_smooth, intensity, grid, threshold, mlh, position, refine, mlh_options)
        return rows if intensity is None else _tested_rows(context, cf_smooth, intensity, grid, rows, min_snr_db,
                                                           min_contrast_db)
    if intensity is None:
        return _table(context, _peaks(context, cf_smooth, None, grid, coherence_peaks(cf_smooth, threshold), refine))
    top = float(np.max(intensity)) if intensity.size else math.nan   # NaN where a cell is NaN
    finite = math.isfinite(top)
    floor = noise_floor(intensity, cf_smooth, maximum=top if finite else None)
    peaks = _peaks(context, cf_smooth, intensity, grid, coherence_peaks(cf_smooth, threshold), refine,
                   _least_intensity(floor, min_snr_db))
    keep, tests = _tests(context, cf_smooth, intensity, grid, floor, peaks.range_m, peaks.angle_deg,
                         intensity_db(peaks.intensity), peaks.cf, min_snr_db, min_contrast_db, finite=finite or None)
    return _table(context, peaks.take(keep), tests)


def _tested_rows(context: PingContext, cf_smooth, intensity, grid: PolarGrid, rows: list, min_snr_db,
                 min_contrast_db) -> list[dict]:
    """The ``rows`` (main-lobe detections) the detection test keeps, with its columns (updated in place)."""
    keep, tests = _tests(context, cf_smooth, intensity, grid, noise_floor(intensity, cf_smooth),
                         np.array([r["range_m"] for r in rows]), np.array([r["angle_deg"] for r in rows]),
                         np.array([r["intensity_db"] for r in rows]), np.array([r["cf"] for r in rows]), min_snr_db,
                         min_contrast_db)
    kept = [rows[k] for k in keep.tolist()]
    for row, values in zip(kept, zip(*(v.tolist() for v in tests.values()))):
        row.update(zip(tests, values))
    return kept


def _tests(context: PingContext, cf_smooth, intensity, grid: PolarGrid, floor, range_m, angle_deg, level_db, cf,
           min_snr_db, min_contrast_db, finite: bool | None = None) -> tuple[np.ndarray, dict]:
    """The detection test of peaks at ``range_m``, ``angle_deg`` with intensities ``level_db`` (dB) and smoothed
    CFs ``cf`` (:func:`clbeam.imaging.detection.gate_peaks`): the kept ones' indices and their ``snr_db``,
    ``contrast_db`` and ``pfa`` columns.  The clutter is measured about the peaks the SNR test keeps only:
    the others leave the table whatever their contrast (a noise-free ping's thousands of maxima on its
    rounding are a hundred above the floor).  ``finite``: the intensity holds no NaN and no +inf (``None``:
    not known)."""
    band = context.band_hz
    lam = smoothing_eigenvalues(float(np.median(np.diff(grid.ranges_m))) if grid.shape[1] > 1 else 1.0,
                                float(band[1] - band[0]), context.sound_speed_m_s)
    window, guard = contrast_windows(band, context.array_width_m, context.sound_speed_m_s)
    floor_db = 10 * math.log10(floor) if floor > 0 and math.isfinite(floor) else math.nan
    measured = np.flatnonzero(snr_tests_pass(np.asarray(level_db, dtype=np.float64) - floor_db, min_snr_db))
    echo, clutter = np.full(len(level_db), np.nan), np.full(len(level_db), np.nan)
    if measured.size:
        echo[measured], clutter[measured] = contrast_at(intensity, grid.ranges_m, grid.angles_deg,
                                                        np.asarray(range_m)[measured], np.asarray(angle_deg)[measured],
                                                        window=window, guard=guard, finite=finite)
    keep, snr, contrast, pfa = gate_peaks(level_db, cf, floor=floor, echo_db=echo, clutter_db=clutter,
                                          n_channels=context.n_channels, eigenvalues=lam, min_snr_db=min_snr_db,
                                          min_contrast_db=min_contrast_db)
    return keep, {"snr_db": snr, "contrast_db": contrast, "pfa": pfa}


#: the relative margin below the SNR test's least intensity within which a peak still gets a row (the test
#: itself, on the row's ``intensity_db``, then decides: a margin far above its rounding)
SNR_PREFILTER_MARGIN = 1e-6


def _least_intensity(floor: float | None, min_snr_db: float | None) -> float:
    """The intensity below which a peak fails the SNR test for sure (0 where the test passes every peak)."""
    if floor is None or min_snr_db is None or not (floor > 0 and np.isfinite(floor)):
        return 0.0
    return float(floor * 10 ** (min_snr_db / 10) * (1 - SNR_PREFILTER_MARGIN))


@dataclass(frozen=True)
class _Peaks:
    """A ping's peaks as columns: position (m, degree from the grid centre), smoothed CF, intensity
    (NaN: none) and, refined, the grid cells' columns (:data:`clbeam.io.peaks.REFINE_COLUMNS`)."""

    range_m: np.ndarray
    angle_deg: np.ndarray
    cf: np.ndarray
    intensity: np.ndarray
    cells: dict

    def take(self, index: np.ndarray) -> "_Peaks":
        return _Peaks(self.range_m[index], self.angle_deg[index], self.cf[index], self.intensity[index],
                      {name: values[index] for name, values in self.cells.items()})


def _peaks(context: PingContext, cf_smooth, intensity, grid: PolarGrid, peaks: np.ndarray, refine,
           least_intensity: float = 0.0) -> _Peaks:
    """The coherence peaks ``peaks`` (``(n, 2)`` angle and range indices) of a ping (at their refined points
    with ``refine``) before the detection test; a peak less intense than ``least_intensity`` (one the SNR
    test drops for sure: a noise-free ping has thousands on its rounding) left out."""
    if refine is not None:
        refined = refine(peaks, least_intensity=least_intensity)
        refined = refined.take(np.flatnonzero(~(refined.intensity < least_intensity)))
        ia, ir = ((refined.cell[:, 0], refined.cell[:, 1]) if len(refined.range_m)
                  else (np.zeros(0, int), np.zeros(0, int)))
        cells = {"cell_range_m": grid.ranges_m[ir], "cell_angle_deg": grid.angles_deg[ia],
                 "cell_cf": cf_smooth[ia, ir].astype(np.float64), "cell_peaks": np.asarray(refined.n_cells)}
        return _Peaks(np.asarray(refined.range_m), np.asarray(refined.angle_deg), np.asarray(refined.cf_smooth),
                      np.asarray(refined.intensity), cells)
    if intensity is not None and least_intensity > 0:
        peaks = peaks[~(intensity[peaks[:, 0], peaks[:, 1]] < least_intensity)]
    ia, ir = peaks[:, 0], peaks[:, 1]
    return _Peaks(grid.ranges_m[ir], grid.angles_deg[ia], cf_smooth[ia, ir],
                  intensity[ia, ir] if intensity is not None else np.full(len(peaks), np.nan), {})


def _table(context: PingContext, peaks: _Peaks, tests: dict | None = None) -> list[dict]:
    """The rows of ``peaks`` (their cells' columns, then ``tests``'s, appended)."""
    return peak_rows_at(context.index, peaks.range_m, peaks.angle_deg, context.centre_yz_m, peaks.cf,
                        peaks.intensity, context.navigation, extra={**peaks.cells, **(tests or {})})


def _rows(context, cf_smooth, intensity, grid, threshold, mlh, position, refine, mlh_options,
          least_intensity: float = 0.0) -> list[dict]:
    """The rows of :func:`peak_rows` before the detection test; a peak less intense than ``least_intensity``
    (one the SNR test drops for sure: a noise-free ping has thousands on its rounding) gets none."""
    peaks = coherence_peaks(cf_smooth, threshold)
    if not mlh:
        return _table(context, _peaks(context, cf_smooth, intensity, grid, peaks, refine, least_intensity))
    options = {**arc_tolerances(grid, band_hz=context.band_hz, array_width_m=context.array_width_m,
                                sound_speed_m_s=context.sound_speed_m_s), "source_yz_m": context.source_yz_m,
               **mlh_options}
    dets = suppress_main_lobe_highlights(peaks, cf_smooth, grid, centre_yz_m=context.centre_yz_m, **options)
    return detection_rows(dets, context.index, intensity, context.centre_yz_m, context.navigation, position=position)


def _value(ds, name: str, i: int, default=None):
    if name not in ds.variables:
        return default
    v = float(ds[name].values[i])
    return v if np.isfinite(v) else default


def image_file_context(ds, i: int) -> PingContext:
    """The :class:`PingContext` of ping ``i`` of an image file (:class:`~clbeam.io.images.ImageWriter`);
    the SBP29's band and array and 1500 m/s where the file does not say."""
    centre = (_value(ds, "centre_y", i, 0.0), _value(ds, "centre_z", i, 0.0))
    source = (_value(ds, "source_y", i), _value(ds, "source_z", i))
    band = ds.attrs.get("pulse_band_hz")
    return PingContext(index=int(ds["ping"].values[i]), centre_yz_m=centre,
                       source_yz_m=None if None in source else source, latitude_deg=_value(ds, "latitude", i),
                       longitude_deg=_value(ds, "longitude", i), heading_deg=_value(ds, "heading", i),
                       band_hz=SBP29_BAND_HZ if band is None else tuple(float(b) for b in np.ravel(band)),
                       array_width_m=float(ds.attrs.get("array_width_m", SBP29_ARRAY_WIDTH_M)),
                       sound_speed_m_s=_value(ds, "sound_speed", i, SOUND_SPEED_M_S),
                       n_channels=_channels(_value(ds, "n_channels", i)), time=_time(ds, i),
                       draft_m=_value(ds, "draft", i))


def _time(ds, i: int):
    """Ping ``i``'s time as ``numpy.datetime64``: an image file's ``ping_time``, a survey store's
    ``time`` (``None`` where the file has neither)."""
    name = next((v for v in ("ping_time", SURVEY_TIME_VARIABLE) if v in ds.variables), None)
    if name is None:
        return None
    t = np.asarray(ds[name].values[i])
    if np.issubdtype(t.dtype, np.datetime64):
        return None if np.isnat(t) else t
    return None if not np.isfinite(t) else np.datetime64(0, "ns") + np.timedelta64(int(round(float(t) * 1e9)), "ns")


def _channels(value) -> int | None:
    return int(value) if value is not None and value > 0 else None


def peaks_from_images(ds, threshold: float = PEAK_THRESHOLD, *, mlh: bool = False,
                      min_snr_db: float | None = DEFAULT_MIN_SNR_DB,
                      min_contrast_db: float | None = DEFAULT_MIN_CONTRAST_DB, refiner=None) -> list:
    """Peak rows of every ping of an image dataset (:func:`peak_rows` on its ``cf``, Hann smoothed).

    Parameters
    ----------
    ds : xarray.Dataset
        An image file (:func:`clbeam.io.images.open_images`).
    threshold : float
        Coherence-peak threshold on the smoothed CF.
    mlh : bool
        One detection per main-lobe arc.
    min_snr_db, min_contrast_db : float or None
        As :func:`peak_rows`.
    refiner : callable, optional
        ``refiner(ping_index, cf_smooth, intensity) -> refine`` (:class:`PingFileRefiner`): the peaks moved
        to their echoes as ``clbeam image`` moves them; without it the rows are the grid cells' (coarser:
        a node can sit half a range step off its echo, and its intensity some dB below the echo's).
    """
    grid = PolarGrid(ds["range"].values, ds["angle"].values)
    if mlh and "source_y" not in ds.variables:
        log.warning("the image file predates per-ping source positions: main-lobe arcs are centred on the grid centre")
    rows = []
    for i in range(ds.sizes["ping"]):
        cf_s = hann_smooth(ds["cf"].isel(ping=i).values)
        inten = ds["intensity"].isel(ping=i).values if "intensity" in ds.variables else None
        context = image_file_context(ds, i)
        refine = None if refiner is None or mlh else refiner(context.index, cf_s, inten)
        rows.extend(peak_rows(context, cf_s, inten, grid, threshold=threshold, mlh=mlh, refine=refine,
                              min_snr_db=min_snr_db, min_contrast_db=min_contrast_db))
    return rows


#: every column a peak-table option adds (refinement's and main-lobe merging's)
OPTION_COLUMNS = REFINE_COLUMNS + MLH_COLUMNS


def option_columns(*, refine: bool, mlh: bool) -> tuple:
    """The columns the peak-table options add (:data:`clbeam.io.peaks.REFINE_COLUMNS` with refinement,
    :data:`clbeam.imaging.mlh.MLH_COLUMNS` with main-lobe merging, which refinement gives way to), sorted."""
    return tuple(sorted(MLH_COLUMNS if mlh else REFINE_COLUMNS if refine else ()))


class PingFileRefiner:
    """The refinement of an image file's peaks from the pings it was imaged from.

    Parameters
    ----------
    pings : clbeam.io.pingfile.PingFile
        The ping file the image file was made from.
    imager : clbeam.imaging.imager.Imager
        An imager on the image file's grid with the options it was imaged with
        (its interpolation, upsampling, apodization, calibration, channels).
    """

    def __init__(self, pings, imager):
        self.pings, self.imager = pings, imager

    def __call__(self, ping_index: int, cf_smooth: np.ndarray, intensity: np.ndarray | None):
        """``refine(peaks)`` of ping ``ping_index`` of the ping file (``None``: nothing to refine with)."""
        inp, setting = self.imager._prepare(self.pings.ping(int(ping_index)))
        return self.imager._refiner(inp, setting, cf_smooth, intensity)
