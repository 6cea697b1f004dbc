"""The survey products, rebuilt from the ledger at the end of every run.

:func:`finalize_survey` reads the ledger twice, one ping at a time.  The
first pass gathers the per-ping values (navigation, grid centre, source,
sound speed, the seabed fitted to the ping's peaks) and the detections
above the map threshold, the only survey-wide arrays kept (about 200 bytes
per detection and 4 per peak); the detections are associated into objects
(:func:`clbeam.survey.association.associate`) and tracked into lines
(:func:`clbeam.survey.line_products.survey_lines`), found again where lines
lying on or above the seabed held its upper edge
(:func:`clbeam.survey.seabed_refit.seabed_off_lines`), the first search's
lines carried into the second where it finds none along them.  The second pass
georeferences every peak and streams it to the group ``peaks``, the CSV and
the GeoJSON (:class:`clbeam.io.survey_products.PeakTableWriter`).  Then the
objects, the lines, the store's per-ping variables and attributes, and the
figures.
Every product holds each committed ping exactly once.
"""

from __future__ import annotations

import array
import contextlib
import dataclasses
import json
import logging
import math
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from clbeam.imaging.peaks import OPTION_COLUMNS, option_columns
from clbeam.io.conventions import epoch_seconds
from clbeam.io.peaks import CENTRE_COLUMNS, DETECTION_COLUMNS, PEAK_COLUMNS, PEAK_CSV_COLUMNS
from clbeam.io.survey_products import (
    LINE_INTEGERS,
    LINE_KINDS,
    OBJECT_COLUMNS,
    PeakTableWriter,
    write_feature_tables,
)
from clbeam.io.survey_store import (
    iter_ledger_records,
    ledger_names,
    product_paths,
    read_root_attrs,
    store_ping_count,
    update_store,
)
from clbeam.survey.association import associate, describe_objects
from clbeam.survey.burial import (
    offplane_deepening_m,
    peak_slide_rad,
    pooled_seabed_lines,
    receive_beam_width_rad,
    smear_deepening_m,
)
from clbeam.survey.edges import EdgeProbe
from clbeam.survey.georef import SurveyNavigation
from clbeam.survey.inputs import one_line
from clbeam.survey.line_products import LineDetections, SurveyLines, line_rows, survey_lines, track_distance_m
from clbeam.survey.options import SurveyOptions
from clbeam.survey.plots import plot_persistence, plot_survey_map
from clbeam.survey.seabed_refit import seabed_off_lines

log = logging.getLogger(__name__)

#: per-ping variables of the store filled from the ledger records: (record key, fill value, dtype)
_RECORD_VARIABLES = {
    "centre_y": ("centre_y_m", np.nan, np.float64), "centre_z": ("centre_z_m", np.nan, np.float64),
    "source_y": ("source_y_m", np.nan, np.float64), "source_z": ("source_z_m", np.nan, np.float64),
    "sound_speed": ("sound_speed_m_s", np.nan, np.float64), "n_channels": ("n_channels_used", np.nan, np.float64),
    "file_index": ("file_index", -1, np.int32), "file_ping": ("file_ping", -1, np.int32),
    "draft": ("draft_m", np.nan, np.float64),
}


@dataclass
class SurveyProducts:
    """What :func:`finalize_survey` wrote and found.

    Attributes
    ----------
    n_imaged : int
        Pings in the ledger.
    n_peaks : int
        Coherence peaks of those pings.
    n_detections : int
        Peaks above the map threshold.
    objects : list of dict
        :func:`clbeam.survey.association.describe_objects`.
    lines : SurveyLines
        The lines (:func:`clbeam.survey.line_products.survey_lines`).
    navigation : bool
        Some ping has a position (peaks carry latitude and longitude; GeoJSON written).
    utm_epsg : int or None
        UTM zone of the eastings and northings.
    files : dict
        :func:`clbeam.io.survey_store.product_paths`.
    detections : dict
        ``ping``, ``y_m``, ``z_m`` of the detections (m, earth frame), and per survey ping its
        ``file_index`` and ``file_ping`` (for scoring against a simulation's truth).
    track_km : float
        Length of the survey line (km; NaN without navigation or speed).
    """

    n_imaged: int
    n_peaks: int
    n_detections: int
    objects: list
    lines: SurveyLines
    navigation: bool
    utm_epsg: int | None
    files: dict
    detections: dict = None
    track_km: float = float("nan")

    @property
    def n_pipelines(self) -> int:
        """Lines of the kind ``pipeline``."""
        return sum(r["kind"] == "pipeline" for r in self.lines.rows)


@dataclass
class _Detections:
    """Peaks above the map threshold, in ledger order, with their association."""

    ping: np.ndarray
    y: np.ndarray
    z: np.ndarray
    cf: np.ndarray
    row: np.ndarray
    intensity_db: np.ndarray = None
    snr_db: np.ndarray = None
    cols: dict = None
    pos: np.ndarray = None
    labels: np.ndarray = None
    objects: list = None


@dataclass
class _FirstPass:
    """What the first reading of the ledger keeps."""

    nav: SurveyNavigation
    per_ping: dict
    detections: _Detections
    n_rows: int
    sonar: dict
    seabed: np.ndarray = None
    seabed_peaks: list = None


def finalize_survey(output, options: SurveyOptions, *, failures=(), inputs=None) -> SurveyProducts:
    """Build the survey products from the ledger of ``output``.

    Reads the ledger twice, one ping at a time: first the navigation and the detections above the map
    threshold (the only survey-wide arrays kept: about 200 bytes per detection and 12 per peak, the peaks'
    positions kept for the seabed pooled over pings), which are associated into objects; then every peak,
    georeferenced and written to the Zarr group ``peaks``, the CSV and the GeoJSON.  Each text product is
    written under a temporary name and renamed; the store's per-ping variables (navigation, time, grid centre,
    source, sound speed, ``imaged``, ``n_peaks``) and attributes (with the sonar's ``pulse_band_hz`` and
    ``array_width_m``, as in an image file) are updated.

    Parameters
    ----------
    output : path-like
        The survey store.
    options : SurveyOptions
        The run's options (map threshold and association rule, speed, grid).
    failures : sequence of Failure
        Inputs and pings not imaged (store attribute ``failures``).
    inputs : sequence of path-like, optional
        The readable input files in survey order (the store's ``input_files``): with them the lines their
        other tests leave undecided are asked where their echoes came from (:mod:`clbeam.survey.edges`).

    Returns
    -------
    SurveyProducts
    """
    output = Path(output)
    assoc = options.association
    names = ledger_names(output)  # both passes read these, whatever a late task may still commit
    first = _read_ledger(output, names, store_ping_count(output), options)
    nav, det = first.nav, first.detections
    nav.finish(first.per_ping["imaged"])
    _associate(det, nav, assoc)
    slide = peak_slide_rad(det.snr_db, _receive_beam_rad(first), _angle_step_rad(options.grid))
    centre = np.stack([first.per_ping["centre_y"], first.per_ping["centre_z"]], axis=1)
    smear = _smear_depth(det, centre, math.radians(options.lines.beam_width_deg))
    probe = _edge_probe(output, inputs, first, det, centre, options)
    lines = _find_lines(first, det, LineDetections(det.ping, det.y, det.z, det.cf, det.intensity_db, slide, smear,
                                                   probe), centre, options)
    row_labels = {c: np.full(first.n_rows, -1, dtype=np.int64) for c in ("object", "line")}
    row_labels["object"][det.row] = det.labels
    row_labels["line"][det.row] = lines.labels
    files = product_paths(output)
    _write_peaks(output, names, files, options, nav, row_labels, first.per_ping["draft"])
    _write_features(output, files, det, lines, nav)
    n_imaged = int(first.per_ping["imaged"].sum())
    update_store(output, {"latitude": nav.lat, "longitude": nav.lon, "heading": nav.heading, "time": nav.time_s,
                          **first.per_ping}, _store_attrs(first, options, failures))
    try:
        plot_survey_map(files["map_png"], nav=nav, det_ping=det.ping, det_cf=det.cf, det_pos=det.pos,
                        lines=lines, threshold=assoc.threshold, grid=options.grid)
        plot_persistence(files["persistence_png"], det.ping, det.y, det.cf, assoc.threshold)
    except Exception as exc:  # a figure must not lose the tables written above
        log.warning("survey figures not written: %s", one_line(exc))
    return SurveyProducts(n_imaged=n_imaged, n_peaks=first.n_rows, n_detections=int(det.ping.size),
                          objects=det.objects, lines=lines, navigation=bool(nav.has_nav.any()), utm_epsg=nav.epsg,
                          files=files, track_km=track_length_km(nav, first.per_ping["imaged"]),
                          detections={"ping": det.ping, "y_m": det.y, "z_m": det.z, "file_index": first.per_ping["file_index"],
                                      "file_ping": first.per_ping["file_ping"]})


def _find_lines(first: _FirstPass, det: _Detections, line_det: LineDetections, centre_yz: np.ndarray,
                options: SurveyOptions) -> SurveyLines:
    """The survey's lines: found once over the first seabed without the edge probe (its lines only tell where
    the seabed's upper edge may lie on them), then with it over the seabed fitted again without the lines
    lying on or above it (:func:`clbeam.survey.seabed_refit.seabed_off_lines`), or over the first where none
    does (the first lines are kept where there is no probe either, or no line).  The second search takes the
    first one's kept tracks as candidates (``survey_lines(..., carried=)``): one stays where no line of its own
    lies along it."""
    imaged, nav = first.per_ping["imaged"], first.nav
    with _said_once(logging.getLogger(survey_lines.__module__)):
        quick = survey_lines(dataclasses.replace(line_det, edge_probe=None), first.seabed, centre_yz, imaged, nav,
                             options.lines)
        refit = seabed_off_lines(first.seabed_peaks, first.seabed, quick, (det.ping, det.y, det.z), centre_yz, nav,
                                 options.lines)
        if refit is None and (line_det.edge_probe is None or not quick.rows):  # the probe only describes kept lines
            return quick
        return survey_lines(line_det, first.seabed if refit is None else refit, centre_yz, imaged, nav,
                            options.lines, carried=quick.tracks)


class _OncePerThread(logging.Filter):
    """Drops a message its thread has said already while that thread is within :func:`_said_once`; other
    threads' messages pass (surveys finalized side by side in one process keep their own warnings)."""

    def __init__(self):
        super().__init__()
        self.local = threading.local()

    def filter(self, record: logging.LogRecord) -> bool:
        said = getattr(self.local, "said", None)
        if said is None:
            return True
        message = record.getMessage()
        new = message not in said
        said.add(message)
        return new


_ONCE = _OncePerThread()


@contextlib.contextmanager
def _said_once(logger: logging.Logger):
    """Within it, ``logger`` says each message once to this thread (the lines are searched twice).  The filter
    stays on the logger, passing everything outside such a block: adding and removing it per survey would change
    a logger other threads are using."""
    logger.addFilter(_ONCE)  # once: a filter already there is not added again
    _ONCE.local.said = set()
    try:
        yield
    finally:
        _ONCE.local.said = None


def _edge_probe(output: Path, inputs, first: _FirstPass, det: _Detections, centre_yz: np.ndarray,
                options: SurveyOptions):
    """``probe(detections) -> u`` (:class:`clbeam.survey.edges.EdgeProbe` at the detections' ranges and angles from
    their grid centres), or ``None``: no inputs given, inputs other than the store's, no pulse band or no beam
    width (the column's length ``L`` is the band centre's wavelength over the lines' ``beam_width_deg``, 4.5
    degrees for the SBP29's 3.5 m)."""
    band = first.sonar.get("pulse_band_hz")
    if inputs is None or not band or not options.lines.beam_width_deg > 0:
        return None
    names = json.loads(read_root_attrs(output).get("input_files", "[]"))
    if names != [Path(p).name for p in inputs]:
        log.warning("lines: the inputs are not the store's %s; undecided lines are not probed", names)
        return None
    column_m = _sound_speed(first) / (0.5 * (band[0] + band[1])) / math.radians(options.lines.beam_width_deg)
    probe = EdgeProbe(inputs, first.per_ping["file_index"], first.per_ping["file_ping"], column_m, grid=options.grid,
                      imaging=options.imaging, backend=options.backend, device=options.device)
    range_m, angle_rad = _range_angle(det, centre_yz)
    angle_deg = np.degrees(angle_rad)
    return lambda index: probe(det.ping[index], range_m[index], angle_deg[index])


def track_length_km(nav: SurveyNavigation, imaged: np.ndarray) -> float:
    """Length of the survey line over its imaged pings (km): the distance between navigated positions, or the
    along-track distance from ping time and speed; NaN without either."""
    pings = np.flatnonzero(imaged)
    if pings.size < 2:
        return 0.0 if pings.size else math.nan
    s, known = track_distance_m(nav, pings)
    return float(s[-1] - s[0]) / 1000 if known else math.nan


def _write_features(output: Path, files: dict, det: _Detections, lines: SurveyLines, nav: SurveyNavigation) -> None:
    """The object and line tables."""
    rows, columns, paths = object_rows(det.objects, nav, det.ping, det.labels, det.cols)
    write_feature_tables(output, (files["objects_csv"], files["objects_geojson"]), "objects", rows, columns,
                         OBJECT_COLUMNS[:5], paths, "clbeam associated objects")
    rows, columns, paths = line_rows(lines, nav)
    write_feature_tables(output, (files["lines_csv"], files["lines_geojson"]), "lines", rows, columns,
                         LINE_INTEGERS, paths, "clbeam lines", categories={"kind": LINE_KINDS})


def _seabed_peaks(rec: dict, beam_width_rad: float) -> tuple:
    """One ping's peaks ``(y, z)`` (m) for its seabed (:func:`clbeam.survey.burial.pooled_seabed_lines`), each
    raised by the depth its echoes from off the ping's plane add (:func:`clbeam.survey.burial.
    offplane_deepening_m`; none where a peak has no range or angle), in float32: a survey's every peak is kept
    until its pings are read."""
    peaks = rec["peaks"]
    y, z, r, a = (np.array([_nan(pk.get(k)) for pk in peaks]) for k in ("y_m", "z_m", "range_m", "angle_deg"))
    deeper = offplane_deepening_m(r, np.radians(a), beam_width_rad, rec.get("band_hz"))
    return y.astype(np.float32), (z - np.nan_to_num(deeper, nan=0.0)).astype(np.float32)


def _smear_depth(det: _Detections, centre_yz: np.ndarray, beam_width_rad: float) -> np.ndarray:
    """Each detection's depth below a line's crossing were it an echo of the line's stretch inside the transmit
    beam (m, :func:`clbeam.survey.burial.smear_deepening_m` at its range and angle from its grid centre
    ``centre_yz``, ``(n_pings, 2)`` m)."""
    return smear_deepening_m(*_range_angle(det, centre_yz), beam_width_rad)


def _range_angle(det: _Detections, centre_yz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each detection's slant range (m) and angle from nadir (rad) about its ping's grid centre ``centre_yz``
    (``(n_pings, 2)`` m)."""
    dy, dz = det.y - centre_yz[det.ping, 0], det.z - centre_yz[det.ping, 1]
    return np.hypot(dy, dz), np.arctan2(dy, dz)


def _sound_speed(first: _FirstPass) -> float:
    """The survey's median sound speed (m/s; 1500 where no ping gives one)."""
    c = first.per_ping["sound_speed"]
    return float(np.nanmedian(c)) if np.isfinite(c).any() else 1500.0


def _receive_beam_rad(first: _FirstPass) -> float:
    """The receive beam's width of the survey's sonar (rad, NaN: unknown) at its median sound speed."""
    return receive_beam_width_rad(first.sonar.get("pulse_band_hz"), first.sonar.get("array_width_m"),
                                  _sound_speed(first))


def _angle_step_rad(grid) -> float:
    """The grid's median angle step (rad; 0 with one angle)."""
    a = np.asarray(grid.angles_deg, dtype=np.float64)
    return math.radians(float(np.median(np.diff(a)))) if a.size > 1 else 0.0


def _nan(v) -> float:
    return np.nan if v is None else float(v)


def _associate(det: _Detections, nav: SurveyNavigation, assoc) -> None:
    """Georeference the detections and associate them into objects (fills ``det``)."""
    det.cols = nav.peak_columns(det.ping, det.y)
    det.pos, sb = nav.frame(det.ping, det.y, det.cols)
    det.labels = associate(det.ping, det.pos, sb, det.z, assoc)
    det.objects = describe_objects(det.labels, det.ping, det.pos, det.cf, det.y, det.z)


def _store_attrs(first: _FirstPass, options: SurveyOptions, failures) -> dict:
    """Root attributes of the store after the products: completeness, UTM zone, options, failures, sonar."""
    n = first.nav.lat.size
    n_imaged = int(first.per_ping["imaged"].sum())
    return {
        "survey_complete": bool(n_imaged == n and not failures),
        "pings_imaged": n_imaged, "pings_total": n,
        "utm_epsg": first.nav.epsg if first.nav.epsg is not None else -1,
        "association": json.dumps(dataclasses.asdict(options.association)),
        "speed_m_s": options.speed_m_s,  # None (not given): no attribute
        "failures": json.dumps([str(f) for f in failures]),
        **first.sonar,
    }


def _read_ledger(output: Path, names: list, n: int, options: SurveyOptions) -> _FirstPass:
    """First pass: per-ping values, navigation, the sonar of the first ping, and the detections."""
    threshold = options.association.threshold
    nav = SurveyNavigation(n, options.speed_m_s)
    per_ping = {"imaged": np.zeros(n, dtype=bool), "n_peaks": np.full(n, -1, dtype=np.int32)}
    per_ping.update({k: np.full(n, fill, dtype=dtype) for k, (_, fill, dtype) in _RECORD_VARIABLES.items()})
    det_ping, det_row = array.array("q"), array.array("q")
    det_y, det_z, det_cf, det_level, det_snr = (array.array("d") for _ in range(5))
    sonar = {}
    seabed_peaks = [None] * n
    row = 0
    for rec in iter_ledger_records(output, names):
        g = rec["ping"]
        per_ping["imaged"][g] = True
        per_ping["n_peaks"][g] = len(rec["peaks"])
        for k, (key, fill, _) in _RECORD_VARIABLES.items():
            v = rec.get(key)  # None: unknown, or a record written before the key existed
            per_ping[k][g] = fill if v is None else v
        nav.lat[g], nav.lon[g] = _nan(rec["latitude_deg"]), _nan(rec["longitude_deg"])
        nav.heading_file[g] = _nan(rec["heading_deg"])
        if rec["time"] is not None:
            nav.time_s[g] = epoch_seconds(np.datetime64(rec["time"], "ns"))
        if not sonar and rec.get("band_hz") is not None:
            # as an image file: the sonar of the first ping written (the lowest survey ping)
            sonar = {"pulse_band_hz": [float(b) for b in rec["band_hz"]],
                     "array_width_m": float(rec["array_width_m"])}
        seabed_peaks[g] = _seabed_peaks(rec, math.radians(options.lines.beam_width_deg))
        for k, pk in enumerate(rec["peaks"]):
            if pk["cf"] > threshold:
                det_ping.append(g)
                det_y.append(pk["y_m"])
                det_z.append(pk["z_m"])
                det_cf.append(pk["cf"])
                det_level.append(pk.get("intensity_db", np.nan))
                det_snr.append(_nan(pk.get("snr_db")))
                det_row.append(row + k)
        row += len(rec["peaks"])
    dets = _Detections(np.asarray(det_ping, dtype=np.int64), *(np.asarray(a, dtype=np.float64)
                                                               for a in (det_y, det_z, det_cf)),
                       row=np.asarray(det_row, dtype=np.int64), intensity_db=np.asarray(det_level, dtype=np.float64),
                       snr_db=np.asarray(det_snr, dtype=np.float64))
    return _FirstPass(nav, per_ping, dets, row, sonar, pooled_seabed_lines(seabed_peaks), seabed_peaks)


def peak_csv_columns(nav: SurveyNavigation, imaging=None) -> list:
    """Columns of the peaks CSV: the table every peaks command writes (:data:`clbeam.io.peaks.PEAK_CSV_COLUMNS`,
    then the columns of refinement or main-lobe merging where the imaging options (``imaging``, an
    :class:`~clbeam.imaging.imager.ImagingOptions`) have them), then the survey's own: the input file and
    ping, the UTM position (some pings navigated) and the along-track distance (some not), ``object`` and
    ``line``."""
    columns = list(PEAK_CSV_COLUMNS)
    if imaging is not None:
        columns += option_columns(refine=imaging.refine_peaks and not imaging.mlh, mlh=imaging.mlh)
    columns += list(SURVEY_PEAK_COLUMNS)
    if nav.has_nav.any():
        columns += ["easting_m", "northing_m"]
    if (~nav.has_nav).any():
        columns.append("along_track_m")
    columns += ["object", "line"]
    return columns


#: the option columns that count (grid peaks merged into a refined row, peaks merged into a detection)
INTEGER_OPTION_COLUMNS = ("cell_peaks", "n_merged")
#: the survey's columns of the peaks table after the common ones
SURVEY_PEAK_COLUMNS = ("file_index", "file_ping")


def _write_peaks(output: Path, names: list, files: dict, options: SurveyOptions, nav: SurveyNavigation,
                 row_labels: dict, draft_m: np.ndarray) -> None:
    """Second pass: every peak, georeferenced, to the group ``peaks``, the CSV and the GeoJSON (``draft_m``:
    each survey ping's draft, m, NaN where unknown)."""
    attrs = {"utm_epsg": nav.epsg if nav.epsg is not None else -1, "peak_threshold": options.imaging.threshold,
             "map_threshold": options.association.threshold}
    writer = PeakTableWriter(output, {k: files[k] for k in ("peaks_csv", "peaks_geojson")},
                             peak_csv_columns(nav, options.imaging), bool(nav.has_nav.any()), attrs, draft_m=draft_m)
    try:
        row = 0
        for rec in iter_ledger_records(output, names):
            k = len(rec["peaks"])
            if k:
                writer.add(_peak_columns(rec, nav, {c: v[row:row + k] for c, v in row_labels.items()}))
            row += k
        writer.close()
    except BaseException:
        writer.abort()
        raise


def _peak_columns(rec: dict, nav: SurveyNavigation, labels: dict) -> dict:
    """The peak-table columns of one ledger record."""
    pk = rec["peaks"]
    k = len(pk)
    g = rec["ping"]
    cols = {c: np.array([r[c] for r in pk], dtype=np.float64) for c in PEAK_COLUMNS if c != "ping"}
    # ledgers written before the detection test have no such keys: NaN
    # (and before the ledger kept the refinement's and merging's columns: NaN)
    cols.update({c: np.array([r.get(c, np.nan) for r in pk], dtype=np.float64)
                 for c in DETECTION_COLUMNS + OPTION_COLUMNS})
    for c in INTEGER_OPTION_COLUMNS:  # counts, as the other tables write them (NaN: a ledger from before)
        if np.isfinite(cols[c]).all():
            cols[c] = cols[c].astype(np.int64)
    for c in CENTRE_COLUMNS:
        cols[c] = np.full(k, _nan(rec.get(c)))
    pings = np.full(k, g, dtype=np.int64)
    cols["ping"] = pings
    cols["file_index"] = np.full(k, rec["file_index"], dtype=np.int32)
    cols["file_ping"] = np.full(k, rec["file_ping"], dtype=np.int32)
    cols["time_s"] = np.full(k, nav.time_s[g])
    cols.update(nav.peak_columns(pings, cols["y_m"]))
    cols.update(labels)
    return cols


def object_rows(objects: list, nav: SurveyNavigation, det_ping, labels, det_cols) -> tuple:
    """The rows of the object tables, their columns, and the objects' paths.

    Parameters
    ----------
    objects : list of dict
        :func:`clbeam.survey.association.describe_objects`.
    nav : SurveyNavigation
    det_ping, labels : numpy.ndarray
        ``(k,)`` survey ping and object of each detection.
    det_cols : dict
        The detections' :meth:`SurveyNavigation.peak_columns`.

    Returns
    -------
    (list of dict, list of str, list or None)
        Rows; columns (:data:`clbeam.io.survey_products.OBJECT_COLUMNS`,
        then start and end positions: WGS84 and UTM (m) with navigation,
        along-track distances (m) without); with navigation, per object the
        ``[longitude, latitude]`` (degree) of its per-ping mean positions,
        else ``None``.
    """
    geo = nav.all_nav
    extra = ("start_latitude_deg", "start_longitude_deg", "end_latitude_deg", "end_longitude_deg",
             "start_easting_m", "start_northing_m", "end_easting_m", "end_northing_m") if geo else \
        ("start_along_track_m", "end_along_track_m")
    rows, lines = [], []
    for ob in objects:
        r = {k: ob[k] for k in OBJECT_COLUMNS}
        m = labels == ob["object"]
        if geo:
            for tag, q in (("start", ob["first_ping"]), ("end", ob["last_ping"])):
                sel = m & (det_ping == q)
                r[f"{tag}_latitude_deg"] = float(np.mean(det_cols["peak_latitude_deg"][sel]))
                r[f"{tag}_longitude_deg"] = float(np.mean(det_cols["peak_longitude_deg"][sel]))
                r[f"{tag}_easting_m"] = float(np.mean(det_cols["easting_m"][sel]))
                r[f"{tag}_northing_m"] = float(np.mean(det_cols["northing_m"][sel]))
            lines.append([[float(np.mean(det_cols["peak_longitude_deg"][m & (det_ping == q)])),
                           float(np.mean(det_cols["peak_latitude_deg"][m & (det_ping == q)]))]
                          for q in np.unique(det_ping[m])])
        else:
            r["start_along_track_m"] = float(ob["path"][0, 0]) if nav.speed is not None else np.nan
            r["end_along_track_m"] = float(ob["path"][-1, 0]) if nav.speed is not None else np.nan
        rows.append(r)
    return rows, list(OBJECT_COLUMNS) + list(extra), lines if geo else None
