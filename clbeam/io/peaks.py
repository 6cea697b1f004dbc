"""Peak tables: coherence peaks as CSV (SPEC §3 step 7)."""

from __future__ import annotations

import csv
import os
from pathlib import Path

PEAK_COLUMNS = ("ping", "range_m", "angle_deg", "y_m", "z_m", "cf", "intensity_db")
#: the detection test's columns (clbeam.imaging.detection), in every table that has an intensity
DETECTION_COLUMNS = ("snr_db", "contrast_db", "pfa")


def write_peaks_csv(rows: list, path: str | os.PathLike) -> Path:
    """Write peak rows to CSV: :data:`PEAK_COLUMNS` first, then any extra columns."""
    p = Path(path)
    extra = sorted({k for r in rows for k in r} - set(PEAK_COLUMNS))
    cols = list(PEAK_COLUMNS) + extra
    with open(p, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=cols, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            # 10 significant digits: latitudes to the centimetre, eastings to the millimetre
            w.writerow({k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in r.items()})
    return p


def read_peaks_csv(path: str | os.PathLike) -> list:
    """Read a peaks CSV back into rows of floats (``ping`` as int)."""
    with open(path, newline="") as fh:
        return [{k: (int(v) if k == "ping" else float(v)) for k, v in r.items() if v != ""} for r in csv.DictReader(fh)]
