"""Writing a modelled trace: CSV or NetCDF."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np


def write_trace_csv(path: Path, trace) -> None:
    """The trace as CSV: time (s), received, compressed (real part) and envelope (Pa)."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time_s", "received_pa", "compressed_pa", "envelope_pa"])
        for t, y, c in zip(trace.time_s, trace.received, trace.compressed):
            w.writerow([f"{t:.9g}", f"{y:.9g}", f"{c.real:.9g}", f"{abs(c):.9g}"])


def write_trace_netcdf(path: Path, trace, attrs: dict) -> None:
    """The trace as NetCDF: received, compressed, envelope (Pa) against time (s), and the echo times."""
    import xarray as xr

    ds = xr.Dataset(
        {"received": ("time", trace.received, {"units": "Pa", "long_name": "received pressure y(t) (eq. 19)"}),
         "compressed": ("time", trace.compressed.real, {"units": "Pa", "long_name": "compressed trace y_c"}),
         "envelope": ("time", np.abs(trace.compressed), {"units": "Pa", "long_name": "envelope of y_c"}),
         "echo_time": ("echo", trace.echoes.times_s, {"units": "s", "long_name": "two-way echo time"})},
        coords={"time": ("time", trace.time_s, {"units": "s", "long_name": "time from transmission start"}),
                "echo": ("echo", np.arange(trace.echoes.times_s.size))},
        attrs=attrs)
    ds.to_netcdf(path)
