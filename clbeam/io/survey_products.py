"""The survey's peak and object tables: Zarr groups, CSV and GeoJSON.

:class:`PeakTableWriter` streams the georeferenced peaks of a survey to the
store's group ``peaks``, to ``X.peaks.csv`` and to ``X.peaks.geojson``;
:func:`write_feature_tables` writes the associated objects to the group
``objects``, ``X.objects.csv`` and ``X.objects.geojson``, and the lines to
``lines``, ``X.lines.csv`` and ``X.lines.geojson``.  Text products are
written under temporary names and renamed, so a reader sees the old file or
the new one, never a part.  The CSV's floats have full round-trip
precision, the GeoJSON's the precision the values have (positions to 1e-7
degree, about 1 cm; metres to the millimetre: :func:`geojson_number`); a
peak's GeoJSON point carries its depth below the sea surface as a negative
third coordinate (RFC 7946 §3.1.1: an elevation, here above the sea surface,
not the ellipsoid).  An unknown value is an empty CSV cell and a GeoJSON
``null``.
"""

from __future__ import annotations

import contextlib
import csv
import json
import logging
import math
import os
import warnings
from pathlib import Path

import numpy as np

from clbeam.io.schema import TIME_CALENDAR, TIME_UNITS
from clbeam.io.survey_store import temporary_path, write_atomic

log = logging.getLogger(__name__)

PEAK_BLOCK_ROWS = 65536
"""Peak rows buffered before they are appended to the Zarr group ``peaks``."""

PEAK_TABLE = {
    # name: (dtype, long name, units)
    "ping": (np.int64, "survey ping number (through the readable inputs in order)", "1"),
    "range_m": (np.float64, "range from the grid centre", "m"),
    "angle_deg": (np.float64, "angle from nadir, positive to starboard", "degree"),
    "y_m": (np.float64, "cross-track offset, positive to starboard", "m"),
    "z_m": (np.float64, "depth below the array reference point", "m"),
    "depth_m": (np.float64, "depth below the sea surface: z_m plus the draft (0 where none is given)", "m"),
    "cf": (np.float64, "smoothed coherence factor at the peak", "1"),
    "intensity_db": (np.float64, "intensity |S|^2 at the peak (dB re the squared sample units)", "1"),
    "snr_db": (np.float64, "intensity over the ping's noise floor (dB)", "1"),
    "contrast_db": (np.float64, "echo over the mean clutter around it (dB)", "1"),
    "pfa": (np.float64, "probability that incoherent noise gives this smoothed CF or more, per cell", "1"),
    "file_index": (np.int32, "index of the input file (attribute input_files)", "1"),
    "file_ping": (np.int32, "ping index within the input file", "1"),
    "time_s": (np.float64, "ping time (UTC)", TIME_UNITS),
    "ping_latitude_deg": (np.float64, "latitude of the ping", "degree_north"),
    "ping_longitude_deg": (np.float64, "longitude of the ping", "degree_east"),
    "heading_deg": (np.float64, "heading of the ping (course over ground where the file has none)", "degree"),
    "peak_latitude_deg": (np.float64, "latitude of the peak", "degree_north"),
    "peak_longitude_deg": (np.float64, "longitude of the peak", "degree_east"),
    "easting_m": (np.float64, "UTM easting of the peak (zone: attribute utm_epsg)", "m"),
    "northing_m": (np.float64, "UTM northing of the peak (zone: attribute utm_epsg)", "m"),
    "along_track_m": (np.float64, "along-track distance from ping time x ship speed (no navigation)", "m"),
    "object": (np.int64, "associated object (-1: none, or CF at or below the map threshold)", "1"),
    "line": (np.int64, "line the detection lies on (-1: none, or CF at or below the map threshold)", "1"),
}
"""Columns of the group ``peaks``: dtype, long name, units (UDUNITS; levels in dB have units "1")."""
#: CF attributes of the group ``peaks`` besides long name and units
PEAK_CF_ATTRIBUTES = {
    "time_s": {"standard_name": "time", "calendar": TIME_CALENDAR},
    "ping_latitude_deg": {"standard_name": "latitude"}, "ping_longitude_deg": {"standard_name": "longitude"},
    "peak_latitude_deg": {"standard_name": "latitude"}, "peak_longitude_deg": {"standard_name": "longitude"},
    "depth_m": {"standard_name": "depth", "positive": "down"},
}
NAV_COLUMNS = ("ping_latitude_deg", "ping_longitude_deg", "heading_deg", "peak_latitude_deg",
               "peak_longitude_deg", "easting_m", "northing_m")
"""Peak columns that need navigation."""
OBJECT_COLUMNS = ("object", "n_pings", "n_detections", "first_ping", "last_ping", "length_m", "mean_cf", "max_cf",
                  "mean_y_m", "mean_z_m")
"""Columns of every object row (the first five are integers)."""
LINE_COLUMNS = ("line", "kind", "n_pings", "first_ping", "last_ping", "length_m", "heading_deg", "mean_cf", "score",
                "burial_m", "burial_std_m", "mean_y_m", "mean_z_m", "detected_fraction", "burial_se_m",
                "burial_resolved", "specular")
"""Columns of every line row (``kind`` a string; ``line``, ``n_pings``, the pings and ``burial_resolved`` integers)."""
LINE_INTEGERS = ("line", "n_pings", "first_ping", "last_ping", "burial_resolved", "specular")
LINE_KINDS = ("pipeline", "water", "subbottom", "seabed-nadir", "subbottom-nadir", "unknown")
"""Kinds of a line (:func:`clbeam.survey.line_products.line_kind`), in the order of their stored codes."""


def csv_cell(v) -> str:
    """A number as a CSV cell: integers as such, floats round-trip, NaN empty."""
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    v = float(v)
    return "" if math.isnan(v) else repr(v)


def json_number(v):
    """A number for JSON: ``int``, ``float``, or ``None`` for NaN and infinities."""
    if isinstance(v, (int, np.integer)):
        return int(v)
    v = float(v)
    return v if math.isfinite(v) else None


#: decimals of a GeoJSON number by the end of its column's name: latitudes and longitudes to 1e-7 degree
#: (1.1 cm), metres to the millimetre, other angles to 1e-4 degree (1.7 mm at 1 km), seconds to the millisecond
GEOJSON_DECIMALS = (("_latitude_deg", 7), ("_longitude_deg", 7), ("_m", 3), ("_deg", 4), ("_s", 3))
#: significant digits of the GeoJSON's other floats (coherence, levels in dB, probabilities)
GEOJSON_DIGITS = 6
#: JSON separators of the GeoJSON: no blank after commas and colons
_COMPACT = (",", ":")


def geojson_number(column: str, v):
    """A value of column ``column`` for GeoJSON, at the precision it has.

    Parameters
    ----------
    column : str
        The column's name: its ending picks the decimals (:data:`GEOJSON_DECIMALS`);
        other floats keep :data:`GEOJSON_DIGITS` significant digits.
    v : number
        The value.

    Returns
    -------
    int, float or None
        Integers as such, NaN and infinities as ``None``.
    """
    v = json_number(v)
    if not isinstance(v, float):
        return v
    for ending, decimals in GEOJSON_DECIMALS:
        if column.endswith(ending):
            return round(v, decimals)
    return float(f"{v:.{GEOJSON_DIGITS}g}")


def geojson_position(longitude_deg: float, latitude_deg: float, depth_m: float | None = None) -> list:
    """A GeoJSON position: longitude and latitude to 1e-7 degree and, where the depth below the sea
    surface is known, its negative (m, to the centimetre) as the third coordinate (RFC 7946 §3.1.1)."""
    pos = [round(float(longitude_deg), 7), round(float(latitude_deg), 7)]
    if depth_m is not None and math.isfinite(depth_m):
        pos.append(round(-float(depth_m), 2) + 0.0)  # + 0.0: no "-0.0"
    return pos


class PeakTableWriter:
    """Streams peak rows to the group ``peaks`` of a store, a CSV and a GeoJSON.

    Parameters
    ----------
    output : pathlib.Path
        The store.
    files : dict
        ``peaks_csv`` and ``peaks_geojson`` paths (:func:`clbeam.io.survey_store.product_paths`).
    csv_columns : list of str
        Columns of the CSV and properties of the GeoJSON points, in order.
    geojson : bool
        Write the GeoJSON (peaks with a position become WGS84 points).
    attrs : dict
        Attributes of the group ``peaks``.
    draft_m : numpy.ndarray, optional
        ``(n_survey_pings,)`` depth of the array reference point below the sea
        surface (m; NaN where unknown): ``depth_m`` is ``z_m`` plus the
        ping's draft.  Without it (or where it is NaN) the draft is 0, with one warning.

    Notes
    -----
    Call :meth:`add` for each block of rows, then :meth:`close` (renames the
    files into place) or, on an error, :meth:`abort`.
    """

    def __init__(self, output: Path, files: dict, csv_columns: list, geojson: bool, attrs: dict, *,
                 draft_m: np.ndarray | None = None):
        self.output, self.attrs = output, attrs
        self.draft_m = None if draft_m is None else np.asarray(draft_m, dtype=np.float64)
        self._warned_draft = False
        self.csv_columns = csv_columns
        self.tmp = {k: temporary_path(p) for k, p in files.items()}
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
        """Append rows: ``cols`` holds an equal-length array for every :data:`PEAK_TABLE` column
        (``depth_m`` may be left out: it is ``z_m`` plus the draft)."""
        n = len(cols["ping"])
        if n == 0:
            return
        if "depth_m" not in cols:
            cols = {**cols, "depth_m": np.asarray(cols["z_m"], dtype=np.float64) + self._drafts(cols["ping"])}
        for row in zip(*(cols[c] for c in self.csv_columns)):
            self.csv.writerow([csv_cell(v) for v in row])
        if self.geo_fh is not None:
            self._add_features(cols, n)
        for k in PEAK_TABLE:
            self.buffer[k].append(np.asarray(cols[k]))
        self.n_buffered += n
        if self.n_buffered >= PEAK_BLOCK_ROWS:
            self._flush()

    def _drafts(self, pings) -> np.ndarray:
        """The draft (m) of each row's survey ping; 0 where unknown, with one warning."""
        pings = np.asarray(pings, dtype=np.int64)
        draft = np.full(pings.shape, np.nan) if self.draft_m is None else self.draft_m[pings]
        unknown = ~np.isfinite(draft)
        if unknown.any() and not self._warned_draft:
            log.warning("%s: no draft for %s: the peaks' depths below the sea surface (depth_m, the GeoJSON's "
                        "third coordinate) take the array reference point at the surface (draft 0 m)",
                        self.output.name, "some pings" if self.draft_m is not None else "the pings")
            self._warned_draft = True
        return np.where(unknown, 0.0, draft)

    def _add_features(self, cols: dict, n: int) -> None:
        for k in range(n):
            lat, lon = cols["peak_latitude_deg"][k], cols["peak_longitude_deg"][k]
            if not (math.isfinite(lat) and math.isfinite(lon)):
                continue
            feat = {"type": "Feature",
                    "geometry": {"type": "Point", "coordinates": geojson_position(lon, lat, cols["depth_m"][k])},
                    "properties": {c: geojson_number(c, cols[c][k]) for c in self.csv_columns}}
            self.geo_fh.write(("" if self.first_feature else ",\n") + json.dumps(feat, separators=_COMPACT))
            self.first_feature = False

    def _flush(self, force: bool = False) -> None:
        import xarray as xr

        if self.n_buffered == 0 and not (force and not self.zarr_started):
            return
        data = {}
        for k, (dtype, long_name, units) in PEAK_TABLE.items():
            arr = np.concatenate(self.buffer[k]).astype(dtype) if self.buffer[k] else np.zeros(0, dtype=dtype)
            data[k] = (("peak",), arr, {"long_name": long_name, "units": units, **PEAK_CF_ATTRIBUTES.get(k, {})})
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
        """Write what is buffered and rename the files into place."""
        self._flush(force=True)
        self.csv_fh.close()
        os.replace(self.tmp["peaks_csv"], self.files["peaks_csv"])
        if self.geo_fh is not None:
            self.geo_fh.write("\n]}\n")
            self.geo_fh.close()
            os.replace(self.tmp["peaks_geojson"], self.files["peaks_geojson"])

    def abort(self) -> None:
        """Close and remove the temporary files (the products in place stay as they were)."""
        for fh in (self.csv_fh, self.geo_fh):
            if fh is not None and not fh.closed:
                fh.close()
        for p in self.tmp.values():
            with contextlib.suppress(OSError):
                p.unlink()


def write_feature_tables(output: Path, paths: tuple, group: str, rows: list, columns: list, integers,
                         coords: list | None, title: str, categories: dict | None = None) -> None:
    """Write a table of features (objects, lines): a Zarr group, a CSV and a GeoJSON.

    Parameters
    ----------
    output : pathlib.Path
        The store.
    paths : (pathlib.Path, pathlib.Path)
        The CSV and the GeoJSON.
    group : str
        The store's group (``objects``, ``lines``), one entry per row along
        the dimension ``object``, ``line``; a string column is stored as
        integers with CF ``flag_values`` and ``flag_meanings``.
    rows : list of dict
        One row per feature, with every name of ``columns``.
    columns : list of str
        Columns: ``integers`` as integers, strings as such, the rest floats.
    coords : list or None
        Per feature, the ``[longitude, latitude]`` (degree; a third value: the
        depth below the sea surface, m) of its path: a GeoJSON LineString (a
        Point for one position), to 1e-7 degree (:func:`geojson_position`).  ``None``: no
        navigation, and an existing GeoJSON is removed.
    title : str
        Name of the GeoJSON feature collection.
    categories : dict, optional
        Per string column, its possible values (their order gives the
        stored codes); other string columns are coded in sorted order.
    """
    import xarray as xr

    csv_path, geojson_path = paths
    tmp = temporary_path(csv_path)
    with open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for r in rows:
            w.writerow([r[c] if isinstance(r[c], str) else csv_cell(r[c]) for c in columns])
    os.replace(tmp, csv_path)
    if coords is not None:
        feats = []
        for xy, r in zip(coords, rows):
            xy = [geojson_position(*p) for p in xy]
            geom = {"type": "LineString", "coordinates": xy} if len(xy) > 1 else {"type": "Point", "coordinates": xy[0]}
            feats.append({"type": "Feature", "geometry": geom, "properties": {
                c: r[c] if isinstance(r[c], str) else geojson_number(c, r[c]) for c in columns}})
        write_atomic(geojson_path, json.dumps({"type": "FeatureCollection", "name": title, "features": feats},
                                              separators=_COMPACT).encode())
    else:
        with contextlib.suppress(FileNotFoundError):
            geojson_path.unlink()
    data = _feature_variables(group[:-1], rows, columns, set(integers), categories or {})  # objects -> object
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        xr.Dataset(data).to_zarr(output, group=group, mode="w", consolidated=False)


#: long names of the columns of the object and line tables (the positions' are built from their names)
FEATURE_LONG_NAMES = {
    "object": "object number", "line": "line number", "kind": "kind of line",
    "n_pings": "pings the feature is detected in", "n_detections": "detections of the feature",
    "first_ping": "first survey ping of the feature", "last_ping": "last survey ping of the feature",
    "length_m": "length along its path", "heading_deg": "heading of the line, clockwise from north",
    "mean_cf": "mean smoothed coherence factor of its detections", "max_cf": "largest smoothed coherence factor",
    "mean_y_m": "mean cross-track offset, positive to starboard", "mean_z_m": "mean depth below the array reference point",
    "score": "line score, -log10 of its expected number by chance", "burial_m": "burial below the seabed",
    "burial_std_m": "spread of the burials along the line", "burial_se_m": "standard error of the burial",
    "burial_resolved": "burial resolved from the seabed (1) or not (0)", "specular": "specular line (1) or diffuse (0)",
    "detected_fraction": "fraction of the line's pings with a detection",
}


def feature_attributes(column: str) -> dict:
    """CF attributes of a column of the object or line tables: long name, units by the name's ending
    (``_latitude_deg``, ``_longitude_deg``, ``_deg``, ``_m``; ``1`` otherwise), standard name of positions."""
    if column.endswith("_latitude_deg"):
        extra = {"units": "degree_north", "standard_name": "latitude"}
    elif column.endswith("_longitude_deg"):
        extra = {"units": "degree_east", "standard_name": "longitude"}
    else:
        extra = {"units": "degree" if column.endswith("_deg") else "m" if column.endswith("_m") else "1"}
    tag, _, rest = column.partition("_")
    what = (rest.rsplit("_", 1)[0] if rest.endswith(("_deg", "_m")) else rest).replace("_", " ")
    name = FEATURE_LONG_NAMES.get(column) or (f"{what} at the {tag} of the path" if tag in ("start", "end")
                                              else column.replace("_", " "))
    return {"long_name": name, **extra}


def _feature_variables(dim: str, rows: list, columns: list, integer: set, categories: dict) -> dict:
    """The Zarr variables of a feature table: integers, floats, and categories as small integers with CF flags
    (Zarr v3 has no stable string type)."""
    import xarray as xr

    data = {}
    for c in columns:
        vals = [r[c] for r in rows]
        if c in categories or (vals and isinstance(vals[0], str)):
            names = list(categories.get(c) or sorted(set(vals)))
            data[c] = xr.Variable((dim,), np.array([names.index(v) for v in vals], dtype=np.int8),
                                  {"long_name": FEATURE_LONG_NAMES.get(c, c), "flag_values": list(range(len(names))),
                                   "flag_meanings": " ".join(names)})
        else:
            data[c] = ((dim,), np.array(vals, dtype=np.int64 if c in integer else np.float64), feature_attributes(c))
    return data
