"""Ping files (docs/ping-format.md): round trips in every storage form, and one clear
error for every kind of bad file."""

import numpy as np
import pytest
from scenes import dataset

from clbeam.errors import PingFileError
from clbeam.io.pingfile import PingFile
from clbeam.io.pingwrite import write_ping_file


@pytest.mark.parametrize("form", ["nc", "zarr", "nc-split", "nc-netcdf4"])
@pytest.mark.parametrize("kind", ["raw", "analytic"])
def test_round_trip_reads_every_ping_as_written(tmp_path, form, kind):
    ds, pings = dataset(kind=kind)
    if form == "nc-split" and kind == "analytic":
        s = ds["samples"]
        ds = ds.drop_vars("samples").assign(samples_r=s.real.astype(np.float32), samples_i=s.imag.astype(np.float32))
        ds["samples_r"].attrs["kind"] = "analytic"
    path = tmp_path / ("p.zarr" if form == "zarr" else "p.nc")
    if form == "nc-netcdf4":  # written by another program: plain netCDF4 library
        ds.to_netcdf(path, engine="netcdf4", auto_complex=True)
    else:
        write_ping_file(ds, path)
    with PingFile(path) as f:
        assert (f.n_pings, f.n_channels) == (3, 64)
        for i, p in enumerate(f):
            tol = 1e-6 if form == "nc-split" else 0
            np.testing.assert_allclose(p.samples, pings[i].samples, rtol=tol, atol=tol * np.abs(pings[i].samples).max())
            assert p.kind == kind and p.roll_deg == i and p.index == i
            assert p.latitude_deg == pytest.approx(34.3 + 1e-4 * i)
        np.testing.assert_allclose(f.ping(0).element_pos_m, pings[0].element_pos_m)


def write(tmp_path, ds, name="bad.nc"):
    path = tmp_path / name
    ds.to_netcdf(path, engine="h5netcdf", invalid_netcdf=any(v.dtype.kind == "c" for v in ds.data_vars.values()) or None)
    return path


def drop(name):
    return lambda ds: ds.drop_vars(name)


def setv(name, value, dims=None):
    def f(ds):
        ds = ds.copy()
        ds[name] = (dims if dims is not None else ds[name].dims, value)
        return ds
    return f


BAD = {
    "missing samples": (drop("samples"), "missing variable 'samples'"),
    "missing sample_rate": (drop("sample_rate"), "missing variable 'sample_rate'"),
    "missing element_y": (drop("element_y"), "missing variable 'element_y'"),
    "missing sound_speed": (drop("sound_speed"), "missing variable 'sound_speed'"),
    "missing pulse": (lambda ds: ds.drop_vars(["pulse_f0", "pulse_f1", "pulse_duration"]), "missing pulse description"),
    "half a pulse": (drop("pulse_f1"), "missing variable 'pulse_f1'"),
    "zero sample rate": (setv("sample_rate", 0.0), "'sample_rate' is 0 Hz"),
    "negative sample rate": (setv("sample_rate", -40000.0), "expected > 0"),
    "sound speed too low": (setv("sound_speed", np.full(3, 1000.0)), "within 1300-1700"),
    "zero sound speed": (setv("sound_speed", np.zeros(3)), "within 1300-1700"),
    "roll too large": (setv("roll", np.array([0.0, 50.0, 0.0])), "within ±45"),
    "nan roll": (setv("roll", np.array([0.0, np.nan, 0.0])), "'roll' has 1 non-finite"),
    "nan element": (setv("element_y", np.r_[np.nan, np.zeros(63)]), "'element_y' has 1 non-finite"),
    "inf source": (setv("source_z", np.inf), "'source_z' has 1 non-finite"),
    "duplicated elements": (setv("element_y", np.zeros(64)), "duplicated"),
    "wrong sample dims": (lambda ds: ds.assign(samples=ds["samples"].transpose("channel", "ping", "sample")),
                          "dimensions ('channel', 'ping', 'sample')"),
    "string samples": (lambda ds: ds.assign(samples=(("ping", "channel", "sample"),
                                                     np.full(ds["samples"].shape, "a", dtype="U1"))), "expected numbers"),
    "complex raw": (lambda ds: ds.assign(samples=ds["samples"].astype(np.complex64)), "complex but kind='raw'"),
    "unknown kind": (lambda ds: ds.assign(samples=ds["samples"].assign_attrs(kind="cooked")), "kind='cooked'"),
    "wrong format": (lambda ds: ds.assign_attrs(clbeam_format="ping-0"), "is 'ping-0', expected 'ping-1'"),
    "no format": (lambda ds: ds.drop_attrs(deep=False), "'clbeam_format' is missing"),
    "no pings": (lambda ds: ds.isel(ping=slice(0, 0)), "contains no pings"),
    "negative t0": (setv("t0", np.array([0.0, -1.0, 0.0])), "'t0' has negative"),
    "pulse above nyquist": (setv("pulse_f1", 30000.0), "must lie within 0-20000 Hz"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_file_gives_one_line_error_naming_the_problem(tmp_path, case):
    ds, _ = dataset()
    mutate, message = BAD[case]
    path = write(tmp_path, mutate(ds))
    with pytest.raises(PingFileError) as exc:
        PingFile(path)
    text = str(exc.value)
    assert message in text and "\n" not in text and text.startswith("bad.nc: ")


def test_empty_truncated_and_missing_files(tmp_path):
    empty = tmp_path / "empty.nc"
    empty.write_bytes(b"")
    with pytest.raises(PingFileError, match="file is empty"):
        PingFile(empty)
    ds, _ = dataset()
    good = write(tmp_path, ds, "good.nc")
    cut = tmp_path / "cut.nc"
    cut.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(PingFileError, match="not a readable NetCDF4/HDF5 file"):
        PingFile(cut)
    with pytest.raises(PingFileError, match="no such file"):
        PingFile(tmp_path / "nowhere.nc")
    garbage = tmp_path / "text.nc"
    garbage.write_text("this is not a netcdf file\n")
    with pytest.raises(PingFileError, match="not a readable"):
        PingFile(garbage)


def test_per_ping_dead_channel_mask_is_read(tmp_path):
    ds, _ = dataset()
    mask = np.ones((3, 64), dtype=bool)
    mask[1, [5, 9]] = False
    ds["channel_valid"] = (("ping", "channel"), mask)
    with PingFile(write(tmp_path, ds)) as f:
        assert f.ping(0).channel_valid.all()
        assert np.flatnonzero(~f.ping(1).channel_valid).tolist() == [5, 9]


def test_optional_variables_take_their_defaults(tmp_path):
    ds, _ = dataset()
    ds = ds.drop_vars(["roll", "latitude", "longitude"])
    with PingFile(write(tmp_path, ds)) as f:
        p = f.ping(2)
        assert p.roll_deg == 0.0 and p.heave_m == 0.0 and not p.has_navigation
        assert np.all(p.element_pos_m[:, 0] == 0.0)
