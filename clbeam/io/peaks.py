"""Peak tables: coherence peaks as CSV (docs/peaks.md)."""

from __future__ import annotations

import csv
import os
from pathlib import Path

PEAK_COLUMNS = ("ping", "range_m", "angle_deg", "y_m", "z_m", "cf", "intensity_db")
#: the detection test's columns (clbeam.imaging.detection), in every table that has an intensity
DETECTION_COLUMNS = ("snr_db", "contrast_db", "pfa")
#: the grid centre the peak's range and angle are measured from (m, earth frame)
CENTRE_COLUMNS = ("centre_y_m", "centre_z_m")
#: the ship's navigation at the ping (degree), empty where the ping file has none
SHIP_COLUMNS = ("ship_latitude_deg", "ship_longitude_deg", "ship_heading_deg")
#: the columns of every peaks CSV, in order, whatever its rows carry (a value a row lacks is an empty cell)
PEAK_CSV_COLUMNS = PEAK_COLUMNS + CENTRE_COLUMNS + SHIP_COLUMNS + DETECTION_COLUMNS


def write_peaks_csv(rows: list, path: str | os.PathLike) -> Path:
    """Write peak rows to CSV.

    Parameters
    ----------
    rows : list of dict
        Peak rows (:func:`clbeam.imaging.peaks.peak_rows`).
    path : str or path-like
        The CSV to write.

    Returns
    -------
    pathlib.Path
        ``path``.  Its columns are :data:`PEAK_CSV_COLUMNS`, always (a row
        without navigation or detection test leaves those cells empty: the
        columns of a file do not depend on its data), then the columns of
        the options that add some (main-lobe merging, sub-cell refinement)
        that the rows carry, sorted.  Floats have 10 significant digits
        (latitudes to the centimetre, eastings to the millimetre).
    """
    p = Path(path)
    extra = sorted({k for r in rows for k in r} - set(PEAK_CSV_COLUMNS))
    cols = list(PEAK_CSV_COLUMNS) + extra
    with open(p, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=cols, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in r.items()})
    return p


def read_peaks_csv(path: str | os.PathLike) -> list:
    """Read a peaks CSV back into rows of floats (``ping`` as int; empty cells left out)."""
    with open(path, newline="") as fh:
        return [{k: (int(v) if k == "ping" else float(v)) for k, v in r.items() if v != ""} for r in csv.DictReader(fh)]
