"""Peak tables: coherence peaks as CSV (docs/peaks.md)."""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path

PEAK_COLUMNS = ("ping", "range_m", "angle_deg", "y_m", "z_m", "cf", "intensity_db")
#: the detection test's columns (clbeam.imaging.detection), in every table that has an intensity
DETECTION_COLUMNS = ("snr_db", "contrast_db", "pfa")
#: the grid centre the peak's range and angle are measured from (m, earth frame)
CENTRE_COLUMNS = ("centre_y_m", "centre_z_m")
#: depth below the sea surface (m): ``z_m`` plus the ping's draft (0 where the ping file gives none)
DEPTH_COLUMN = "depth_m"
#: the ping's time (s since 1970-01-01 UTC) and navigation (degree), and the peak's own position on the earth
#: (degree, WGS84): empty where the ping file has no time or no navigation
POSITION_COLUMNS = ("time_s", "ping_latitude_deg", "ping_longitude_deg", "heading_deg", "peak_latitude_deg",
                    "peak_longitude_deg")
#: the columns of every peaks table (``clbeam image --peaks``, ``clbeam peaks``, ``clbeam survey``), in order,
#: whatever its rows carry (a value a row lacks is an empty cell)
PEAK_CSV_COLUMNS = PEAK_COLUMNS + (DEPTH_COLUMN,) + CENTRE_COLUMNS + POSITION_COLUMNS + DETECTION_COLUMNS
#: the columns sub-cell refinement adds (docs/peaks.md), sorted as a table has them
REFINE_COLUMNS = ("cell_angle_deg", "cell_cf", "cell_peaks", "cell_range_m")


def write_peaks_csv(rows: list, path: str | os.PathLike, option_columns=None) -> Path:
    """Write peak rows to CSV.

    Parameters
    ----------
    rows : list of dict
        Peak rows (:func:`clbeam.imaging.peaks.peak_rows`).
    path : str or path-like
        The CSV to write.
    option_columns : sequence of str, optional
        The columns of the options the rows were found with (refinement:
        :data:`REFINE_COLUMNS`; main-lobe merging:
        :data:`clbeam.imaging.mlh.MLH_COLUMNS`), so that a table without a
        refined row has them too; default: those the rows carry.

    Returns
    -------
    pathlib.Path
        ``path``.  Its columns are :data:`PEAK_CSV_COLUMNS`, always (a row
        without navigation or detection test leaves those cells empty: the
        columns of a file do not depend on its data), then the columns of
        the options that add some (main-lobe merging, sub-cell refinement),
        sorted.  Floats have 10 significant digits
        (latitudes to the centimetre, eastings to the millimetre).
    """
    p = Path(path)
    extra = sorted(({k for r in rows for k in r} if option_columns is None else set(option_columns))
                   - set(PEAK_CSV_COLUMNS))
    cols = list(PEAK_CSV_COLUMNS) + extra
    with open(p, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=cols, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: _cell(v) for k, v in r.items()})
    return p


def _cell(v):
    """A CSV cell: floats round-trip, NaN empty, the rest as they are."""
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return v


def read_peaks_csv(path: str | os.PathLike) -> list:
    """Read a peaks CSV back into rows of floats (``ping`` as int; empty cells left out)."""
    with open(path, newline="") as fh:
        return [{k: (int(v) if k == "ping" else float(v)) for k, v in r.items() if v != ""} for r in csv.DictReader(fh)]
