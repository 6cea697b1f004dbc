"""One schema for ping files: pings written from memory read back unchanged,
every written variable carries the schema's units, the in-memory reader
applies the file reader's checks, and pings of two arrays are refused."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scenes import point_ping, polar_point

from clbeam.errors import ClbeamError, PingFileError
from clbeam.io.pingfile import PingFile, pings_from_dataset
from clbeam.io.pingwrite import dataset_from_pings, write_ping_file
from clbeam.io.schema import IMAGE_VARIABLES, PING_VARIABLES, image_variables
from clbeam.model.svp import holland_line1_profile


def pings(n=3, **kw):
    out = []
    for i in range(n):
        p = point_ping(polar_point(40 + 5 * i, 10 * i), record_s=0.06, roll_deg=i, heave_m=0.1 * i, **kw)
        valid = np.ones(p.n_channels, dtype=bool)
        valid[5 + i] = False
        out.append(dataclasses.replace(p, index=i, latitude_deg=34.3 + 1e-4 * i, longitude_deg=-119.8,
                                       heading_deg=110.0, time=np.datetime64("2022-08-28T18:00:00", "ns")
                                       + np.timedelta64(4 * i, "s"), channel_valid=valid,
                                       svp=holland_line1_profile()))
    return out


@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
def test_pings_written_from_memory_read_back_unchanged(tmp_path, suffix):
    src = pings()
    with PingFile(write_ping_file(dataset_from_pings(src), tmp_path / f"p{suffix}")) as f:
        got = list(f)
    for a, b in zip(src, got):
        np.testing.assert_array_equal(b.samples, a.samples)
        np.testing.assert_array_equal(b.element_pos_m, a.element_pos_m)
        np.testing.assert_array_equal(b.channel_valid, a.channel_valid)
        for name in ("roll_deg", "heave_m", "t0_s", "sound_speed_m_s", "latitude_deg", "longitude_deg", "heading_deg",
                     "time", "kind", "sample_rate_hz", "pulse", "svp"):
            assert getattr(b, name) == getattr(a, name), name


def test_analytic_pings_round_trip_in_memory():
    src = pings(2, kind="analytic")
    got = list(pings_from_dataset(dataset_from_pings(src)))
    assert got[0].kind == "analytic"
    np.testing.assert_array_equal(got[1].samples, src[1].samples)


def test_every_written_variable_has_the_schemas_units_and_dimensions():
    ds = dataset_from_pings(pings())
    for name, var in ds.data_vars.items():
        spec = PING_VARIABLES[name]
        assert var.dims in spec.dims, name
        assert var.attrs.get("units", "") == spec.units and var.attrs["long_name"] == spec.long_name, name
    assert ds["samples"].attrs["kind"] == "raw"


def test_the_in_memory_reader_applies_the_file_readers_checks():
    ds = dataset_from_pings(pings())
    with pytest.raises(PingFileError, match="memory: variable 'roll' reaches 50 degrees"):
        pings_from_dataset(ds.assign(roll=("ping", [0.0, 50.0, 0.0])), "memory")
    with pytest.raises(PingFileError, match="variable 'element_y' has dimensions"):
        pings_from_dataset(ds.assign(element_y=(("ping", "channel"), np.zeros((3, 64)))))


def test_pings_of_two_arrays_cannot_share_a_file():
    a, b = pings(2)
    b = dataclasses.replace(b, element_pos_m=b.element_pos_m * 1.01)
    with pytest.raises(ClbeamError, match="another element layout"):
        dataset_from_pings([a, b])
    with pytest.raises(ClbeamError, match="no pings"):
        dataset_from_pings([])


def test_image_variables_follow_the_outputs():
    assert image_variables(("cf",)) == ["cf"]  # the smoothed CF on request only
    assert image_variables(("cf", "cf_smooth")) == ["cf", "cf_smooth"]
    assert image_variables(("intensity", "cf", "cf_smooth", "sums"), apodized=True) == list(IMAGE_VARIABLES)
    assert "w" not in image_variables(("sums",))
