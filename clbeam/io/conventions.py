"""The CF and ACDD attributes of the files clbeam writes.

Every NetCDF or Zarr file clbeam writes (ping files, image files, the
survey store) declares :data:`CONVENTIONS` and carries the discovery
attributes of the Attribute Convention for Data Discovery 1.3 (title,
summary, keywords, history, date_created, source, the time and position it
covers), so that CF tools (the IOOS compliance checker, Panoply, THREDDS)
read and catalogue it.  The variables' own CF attributes (units,
standard names) are in :mod:`clbeam.io.schema`.
"""

from __future__ import annotations

import math
from datetime import datetime, timezone

import numpy as np

from clbeam import __version__

#: the global attribute ``Conventions`` of every file clbeam writes
CONVENTIONS = "CF-1.10, ACDD-1.3"
#: the standard-name table whose names :mod:`clbeam.io.schema` uses
STANDARD_NAME_VOCABULARY = "CF Standard Name Table v93"
#: ACDD keywords of clbeam's files
KEYWORDS = ("multibeam sonar, sub-bottom profiler, cross-track imaging, coherence factor, "
            "beamforming, buried pipelines, sediment")


def utc_now() -> str:
    """The current UTC time as ISO 8601 to the second (``2025-01-31T12:00:00Z``)."""
    return datetime.now(timezone.utc).replace(microsecond=0).strftime("%Y-%m-%dT%H:%M:%SZ")


def discovery_attributes(existing: dict | None, *, title: str, summary: str, history: str) -> dict:
    """The CF and ACDD global attributes of a file being written.

    Parameters
    ----------
    existing : dict or None
        The attributes the file's content already carries (a dataset's
        ``attrs``): its ``title``, ``summary`` and ``source`` are kept, its
        ``history`` gets the new line appended.
    title, summary : str
        What the file holds, where ``existing`` does not say.
    history : str
        What this write did (one line; the UTC time and clbeam's version are
        put in front).

    Returns
    -------
    dict
        ``Conventions``, ``title``, ``summary``, ``keywords``, ``history``,
        ``date_created``, ``source``, ``product_version``,
        ``standard_name_vocabulary``.
    """
    existing = existing or {}
    now = utc_now()
    line = f"{now} clbeam {__version__}: {history}"
    before = str(existing.get("history", "")).rstrip()
    return {
        "Conventions": CONVENTIONS,
        "title": str(existing.get("title") or title),
        "summary": str(existing.get("summary") or summary),
        "keywords": str(existing.get("keywords") or KEYWORDS),
        "history": f"{before}\n{line}" if before else line,
        "date_created": now,
        "source": str(existing.get("source") or f"clbeam {__version__}"),
        "product_version": __version__,
        "standard_name_vocabulary": STANDARD_NAME_VOCABULARY,
    }


def _iso(t: np.datetime64) -> str:
    return str(np.datetime_as_string(np.datetime64(t, "s"), unit="s")) + "Z"


def coverage_attributes(times=None, latitudes_deg=None, longitudes_deg=None) -> dict:
    """ACDD coverage attributes of the pings a file holds.

    Parameters
    ----------
    times : array_like of datetime64, optional
        Ping times (NaT where unknown).
    latitudes_deg, longitudes_deg : array_like of float, optional
        Ping positions (degree; NaN where unknown).

    Returns
    -------
    dict
        ``time_coverage_start`` and ``time_coverage_end`` (ISO 8601, UTC)
        where some time is known; ``geospatial_lat_min``, ``_max``,
        ``geospatial_lon_min``, ``_max`` (degree) and their units where some
        position is known.  Empty when nothing is known.
    """
    out = {}
    if times is not None:
        t = np.asarray(times, dtype="datetime64[ns]")
        t = t[~np.isnat(t)]
        if t.size:
            out["time_coverage_start"], out["time_coverage_end"] = _iso(t.min()), _iso(t.max())
    for axis, values, units in (("lat", latitudes_deg, "degree_north"), ("lon", longitudes_deg, "degree_east")):
        if values is None:
            continue
        v = np.asarray(values, dtype=np.float64)
        v = v[np.isfinite(v)]
        if v.size:
            out[f"geospatial_{axis}_min"], out[f"geospatial_{axis}_max"] = float(v.min()), float(v.max())
            out[f"geospatial_{axis}_units"] = units
    return out


def epoch_seconds(t) -> float:
    """A time (datetime64 or ``None``) as seconds since 1970-01-01 UTC (:data:`clbeam.io.schema.TIME_UNITS`;
    NaN where unknown)."""
    if t is None:
        return math.nan
    t = np.datetime64(t, "ns")
    if np.isnat(t):
        return math.nan
    return float((t - np.datetime64(0, "ns")) / np.timedelta64(1, "ns")) * 1e-9
