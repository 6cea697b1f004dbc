"""Fuzzing the reader and the imager: any mutation of a valid ping file
either images to a finite CF in [0, 1] or raises a one-line ClbeamError,
never another exception."""

import numpy as np
import xarray as xr
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scenes import dataset

from clbeam.errors import ClbeamError
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.io.pingfile import PingFile
from clbeam.model.grid import PolarGrid

BASE, _ = dataset(n_pings=1)
VARIABLES = sorted(BASE.data_vars)
VALUES = st.sampled_from([0.0, -1.0, np.nan, np.inf, -np.inf, 1e30, 1e-30, 7.0, 1500.0, 40000.0])
GRID = PolarGrid.regular(range_res_m=0.5, angle_res_deg=4, min_range_m=5, max_range_m=60, angles_deg=(-60, 60))
IMAGER = Imager(GRID, ImagingOptions(interp="linear"))


def mutate(ds: xr.Dataset, how: str, name: str, value: float, where: float) -> xr.Dataset:
    ds = ds.copy(deep=True)
    if how == "drop":
        return ds.drop_vars(name)
    v = ds[name]
    if how == "fill":
        ds[name] = (v.dims, np.full(v.shape, value, dtype=np.float64 if v.dtype.kind in "fiub" else v.dtype))
    elif how == "poke":
        a = np.array(v.values, dtype=np.float64, copy=True)
        if a.size:
            a.flat[int(where * (a.size - 1))] = value
        ds[name] = (v.dims, a)
    elif how == "scalar":
        ds[name] = ((), value)
    elif how == "truncate" and "sample" in v.dims:
        ds = ds.isel(sample=slice(0, max(1, int(where * ds.sizes["sample"]))))
    return ds


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(how=st.sampled_from(["drop", "fill", "poke", "scalar", "truncate"]), name=st.sampled_from(VARIABLES),
       value=VALUES, where=st.floats(0, 1))
def test_any_mutation_images_or_fails_with_one_clear_line(tmp_path_factory, how, name, value, where):
    path = tmp_path_factory.mktemp("fuzz") / "p.nc"
    try:
        mutate(BASE, how, name, value, where).to_netcdf(path)
    except (ValueError, TypeError):
        return  # xarray itself refuses to write this mutation: nothing to read
    try:
        with PingFile(path) as f:
            img = IMAGER.image(f.ping(0))
    except ClbeamError as exc:
        assert str(exc) and "\n" not in str(exc)
        return
    assert np.isfinite(img.cf).all() and img.cf.min() >= 0 and img.cf.max() <= 1 + 1e-5
    assert np.isfinite(img.intensity).all()
