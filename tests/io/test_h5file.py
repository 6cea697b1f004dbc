"""The light NetCDF4 reader (h5py alone) against xarray's decoding of the same files: every ping
field the same, and every file it cannot read as xarray would handed to xarray."""

import dataclasses

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from scenes import dataset

from clbeam.errors import PingFileError
from clbeam.io.h5file import PlainDataset, open_plain
from clbeam.io.pingfile import PingDataset, PingFile, open_dataset


def _with_everything(kind: str) -> xr.Dataset:
    """The test dataset with every optional variable a ping can take from a file."""
    ds, _ = dataset(kind=kind)
    n = ds.sizes["ping"]
    valid = np.ones((n, 64), dtype=bool)
    valid[1, 5] = False
    return ds.assign(
        ping_time=(("ping",), pd.date_range("2022-08-29T02:00:00.25", periods=n, freq="4s").values),
        channel_valid=(("ping", "channel"), valid),
        heave=(("ping",), np.array([0.1, -0.2, 0.3])), pitch=(("ping",), np.array([0.5, 0.0, -0.5])),
        heading=(("ping",), np.full(n, 290.0)), element_x=(("channel",), np.zeros(64)),
        element_gain_db=(("channel",), np.linspace(-1, 1, 64)), element_phase_deg=(("channel",), np.linspace(-5, 5, 64)),
        svp_depth=(("svp",), np.array([0.0, 100.0, 300.0])), svp_speed=(("svp",), np.array([1500.0, 1490.0, 1485.0])),
        tx_delay=((), 1e-3),
    )


def _split(ds: xr.Dataset) -> xr.Dataset:
    s = ds["samples"]
    out = ds.drop_vars("samples").assign(samples_r=s.real.astype(np.float32), samples_i=s.imag.astype(np.float32))
    out["samples_r"].attrs["kind"] = "analytic"
    return out


def _assert_same_pings(a: PingDataset, b: PingDataset) -> None:
    assert (a.n_pings, a.n_channels, a.n_samples, a.kind) == (b.n_pings, b.n_channels, b.n_samples, b.kind)
    for i in range(a.n_pings):
        pa, pb = a.ping(i), b.ping(i)
        for field in dataclasses.fields(pa):
            va, vb = getattr(pa, field.name), getattr(pb, field.name)
            if isinstance(va, np.ndarray) or isinstance(vb, np.ndarray):
                assert np.asarray(va).dtype == np.asarray(vb).dtype, field.name
                np.testing.assert_array_equal(va, vb, err_msg=field.name)
            elif field.name == "svp":
                np.testing.assert_array_equal(va.speeds_m_s, vb.speeds_m_s)
            elif field.name == "pulse":
                assert (va.f0_hz, va.f1_hz, va.duration_s, va.delay_s) == (vb.f0_hz, vb.f1_hz, vb.duration_s, vb.delay_s)
            else:
                assert va == vb, (field.name, va, vb)


@pytest.mark.parametrize("form", ["raw", "analytic", "split", "netcdf4-library"])
def test_plain_reader_gives_the_pings_xarray_gives(tmp_path, form):
    ds = _with_everything("analytic" if form in ("analytic", "split") else "raw")
    if form == "split":
        ds = _split(ds)
    path = tmp_path / "p.nc"
    if form == "netcdf4-library":
        ds.to_netcdf(path, engine="netcdf4")
    else:
        ds.to_netcdf(path, engine="h5netcdf", invalid_netcdf=form == "analytic" or None)
    with PingFile(path) as fast:
        assert isinstance(fast.ds, PlainDataset)
        slow = PingDataset(open_dataset(path), "p.nc")
        _assert_same_pings(fast, slow)
        assert fast.ping(1).channel_valid.sum() == 63
        assert fast.ping(2).time == np.datetime64("2022-08-29T02:00:08.250", "ns")
        slow.close()


@pytest.mark.parametrize("units, values", [("seconds since 2022-08-29 02:00:00", [0.5, 4.5, 8.5]),
                                           ("days since 2022-08-29", [0, 1, 2]),
                                           ("milliseconds since 2022-08-29T02:00:00", [0, 250, 1000])])
def test_times_decoded_as_xarray_decodes_them(tmp_path, units, values):
    ds, _ = dataset()
    ds = ds.assign(ping_time=(("ping",), np.asarray(values), {"units": units, "calendar": "standard"}))
    path = tmp_path / "p.nc"
    ds.to_netcdf(path, engine="h5netcdf")
    plain = open_plain(path)
    expected = xr.open_dataset(path)["ping_time"].values
    np.testing.assert_array_equal(plain["ping_time"].values, expected)
    plain.close()


def _packed(ds):
    return ds, {"samples": {"dtype": "int16", "scale_factor": 1e-4, "_FillValue": -32768}}


def _int_fill(ds):
    return ds.assign(roll=ds["roll"].astype(np.int32)), {"roll": {"_FillValue": -999}}


@pytest.mark.parametrize("change", [_packed, _int_fill], ids=["packed", "integer fill"])
def test_files_that_need_decoding_go_to_xarray(tmp_path, change):
    ds, encoding = change(dataset()[0])
    path = tmp_path / "p.nc"
    ds.to_netcdf(path, engine="h5netcdf", encoding=encoding)
    assert open_plain(path) is None
    with PingFile(path) as pings:
        assert not isinstance(pings.ds, PlainDataset)
        reference = PingDataset(xr.open_dataset(path), "p.nc")
        np.testing.assert_array_equal(pings.ping(2).samples, reference.ping(2).samples)
        reference.close()


def test_other_calendars_go_to_xarray_and_its_error(tmp_path):
    ds, _ = dataset()
    ds = ds.assign(ping_time=(("ping",), np.array([0.0, 1.0, 2.0]), {"units": "days since 2022-08-29", "calendar": "noleap"}))
    path = tmp_path / "p.nc"
    ds.to_netcdf(path, engine="h5netcdf")
    assert open_plain(path) is None
    with pytest.raises(PingFileError, match="'ping_time' has dtype object, expected datetime64"):
        PingFile(path)


def test_netcdf3_and_garbage_are_not_plain(tmp_path):
    ds, pings = dataset()
    path = tmp_path / "p3.nc"
    ds.to_netcdf(path, engine="scipy")
    assert open_plain(path) is None
    with PingFile(path) as f:
        np.testing.assert_allclose(f.ping(1).samples, pings[1].samples, rtol=1e-6)
    junk = tmp_path / "junk.nc"
    junk.write_bytes(b"not a file of any kind")
    assert open_plain(junk) is None


def test_unlimited_ping_dimension_and_netcdf_c_names_go_to_xarray(tmp_path):
    """netCDF-C leaves an unlimited dimension without a variable at length 0 (xarray reads its true
    length) and stores a variable named like a dimension as '_nc4_non_coord_<name>'."""
    ds, pings = dataset()
    path = tmp_path / "unlimited.nc"
    ds.to_netcdf(path, engine="netcdf4", unlimited_dims=["ping"])
    assert open_plain(path) is None
    with PingFile(path) as f:
        assert f.n_pings == 3
        np.testing.assert_allclose(f.ping(2).samples, pings[2].samples, rtol=1e-6)
    odd = tmp_path / "noncoord.nc"
    ds.assign(channel=(("ping",), np.arange(3.0))).to_netcdf(odd, engine="netcdf4")
    assert open_plain(odd) is None


def test_attributes_times_and_byte_orders_read_as_xarray_reads_them(tmp_path):
    """A one-element byte-string attribute, NaN and far-off times, and big-endian samples."""
    import h5py

    ds, _ = dataset(kind="analytic")
    ds = _split(ds).assign(ping_time=(("ping",), np.array([0.0, np.nan, 8.0]),
                                       {"units": "seconds since 2022-08-29 02:00:00"}))
    path = tmp_path / "p.nc"
    ds.to_netcdf(path, engine="h5netcdf", encoding={"samples_r": {"dtype": ">f4"}})
    with h5py.File(path, "a") as f:
        f["samples_i"].attrs["kind"] = np.array([b"analytic"], dtype="S8")
    plain = open_plain(path)
    assert plain["samples_i"].attrs["kind"] == "analytic"
    assert plain["samples_r"].dtype == plain["samples_i"].dtype == np.float32
    expected = xr.open_dataset(path)["ping_time"].values
    np.testing.assert_array_equal(plain["ping_time"].values, expected)  # NaN -> NaT
    assert np.isnat(plain["ping_time"].values[1])
    plain.close()
    far = tmp_path / "far.nc"
    dataset()[0].assign(ping_time=(("ping",), np.array([0.0, 1.0, 2.0]),
                                   {"units": "days since 1600-01-01"})).to_netcdf(far, engine="h5netcdf")
    assert open_plain(far) is None  # before 1678: no datetime64[ns]; xarray makes cftime objects
