"""Multichannel SEG-Y import and export (clbeam.io.segy_import, segy_export, segy_mapping).

Files are written here with segyio directly, the way a sonar's exporter
would, and every imported variable is checked against the integers written
and the SEG-Y rev 1 meaning of their fields.  A ping file exported and
imported again keeps every variable within half the resolution of its field;
and a SEG-Y copy of a simulated scene images as the scene itself.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest
import segyio
import xarray as xr
from scenes import point_ping, polar_point
from segy_files import (
    DEAD,
    DELAY,
    DRAFT_MM,
    ENSEMBLES,
    HEADING_UDEG,
    HEAVE_MM,
    LAT_MAS,
    LON_MAS,
    N_CH,
    N_PINGS,
    N_S,
    ROLL_UDEG,
    SPEED,
    TEXT,
    TIME,
    B,
    T,
    element_y_m,
    element_z_mm,
    write_vendor_segy,
)

from clbeam.errors import OptionError, PingFileError
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.io.pingfile import PingFile, pings_from_dataset
from clbeam.io.pingwrite import dataset_from_pings, write_ping_file
from clbeam.io.segy_export import export_segy
from clbeam.io.segy_import import SegyImportOptions, import_segy, read_segy_pings
from clbeam.io.segy_mapping import FIELD_BYTES, TRACE_FIELDS, load_mapping, mapping_from_dict
from clbeam.model.grid import PolarGrid


@pytest.fixture(scope="module")
def vendor_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("segy") / "vendor.sgy"
    samples = write_vendor_segy(path, text=TEXT)
    return path, samples


# -- the mapping --------------------------------------------------------------------------
def test_the_trace_header_table_is_segyio_s_rev1_layout():
    fields = {k: int(getattr(T, k)) for k in dir(T) if not k.startswith("_") and isinstance(getattr(T, k), int)}
    assert TRACE_FIELDS == fields
    assert FIELD_BYTES["DelayRecordingTime"] == 2 and FIELD_BYTES["offset"] == 4 and FIELD_BYTES["UnassignedInt2"] == 4
    assert sum(FIELD_BYTES.values()) == 240


def test_a_mapping_file_replaces_entries_by_field_name_or_byte(tmp_path):
    p = tmp_path / "map.toml"
    p.write_text('ensemble = "CDP"\nroll = {byte = 181, scale = 1e-3}\nheading = false\n'
                 't0 = {field = "lagtimea", scale = 1e-3}\nping_time = false\n')
    m = load_mapping(p)
    assert m.get("ensemble").field == "CDP" and m.get("heading") is None and not m.ping_time
    assert (m.get("roll").field, m.get("roll").scale, m.get("t0").field, m.get("t0").scalar) == ("CDP_X", 1e-3,
                                                                                                "LagTimeA", None)
    assert m.get("element_y").field == "offset"  # untouched entries keep their defaults


@pytest.mark.parametrize("table, words", [
    ({"roll": "Rol"}, ["'roll'", "unknown trace-header field 'Rol'"]),
    ({"roll": {"byte": 38}}, ["byte 38 does not start"]),
    ({"rol": "CDP"}, ["unknown entry 'rol'"]),
    ({"t0": False}, ["'t0' cannot be switched off"]),
    ({"roll": "offset"}, ["'roll' and 'element_y' both name field offset"]),
    ({"roll": "ElevationScalar"}, ["the scalar of"]),
    ({"roll": {"field": "CDP_X", "scale": 0}}, ["scale must be a finite non-zero"]),
    ({"latitude": False}, ["'longitude' is set but 'latitude' is not"]),
])
def test_a_bad_mapping_is_one_line_naming_the_entry(table, words):
    with pytest.raises(OptionError) as e:
        mapping_from_dict(table)
    assert "\n" not in str(e.value) and all(w in str(e.value) for w in words)


# -- a file written with segyio ---------------------------------------------------------------
def test_every_variable_of_a_segyio_written_file_is_imported_as_written(vendor_file):
    path, samples = vendor_file
    ds, origins = read_segy_pings(path)
    assert origins == {"pulse": "textual header", "source": "textual header", "tx_delay": "textual header"}
    np.testing.assert_array_equal(ds["ping"].values, ENSEMBLES)
    np.testing.assert_array_equal(ds["samples"].values, samples)  # float32 both, channels sorted
    assert ds["samples"].attrs["kind"] == "raw"
    assert float(ds["sample_rate"]) == 1e6 / 25
    np.testing.assert_allclose(ds["t0"].values, np.array(DELAY) / 10 * 1e-3, rtol=1e-15)
    np.testing.assert_allclose(ds["element_y"].values, element_y_m(), atol=1e-15)
    np.testing.assert_allclose(ds["element_z"].values, -element_z_mm() * 1e-3, atol=1e-15)  # elevation up, z down
    np.testing.assert_array_equal(ds["element_x"].values, 0.0)
    np.testing.assert_allclose(ds["heave"].values, np.array(HEAVE_MM) * 1e-3, atol=1e-15)
    np.testing.assert_allclose(ds["draft"].values, np.array(DRAFT_MM) * 1e-3, atol=1e-15)
    np.testing.assert_array_equal(ds["sound_speed"].values, SPEED)
    np.testing.assert_allclose(ds["roll"].values, np.array(ROLL_UDEG) / 1e6, atol=1e-12)
    np.testing.assert_allclose(ds["heading"].values, np.array(HEADING_UDEG) / 1e6, atol=1e-12)
    np.testing.assert_allclose(ds["latitude"].values, np.array(LAT_MAS) / 1000 / 3600, atol=1e-12)
    np.testing.assert_allclose(ds["longitude"].values, np.array(LON_MAS) / 1000 / 3600, atol=1e-12)
    want = [np.datetime64(f"{y}-01-01") + np.timedelta64(d - 1, "D") + np.timedelta64(3600 * h + 60 * m + s, "s")
            for y, d, h, m, s in TIME]
    np.testing.assert_array_equal(ds["ping_time"].values, np.array(want, dtype="datetime64[ns]"))
    assert str(ds["ping_time"].values[2])[:19] == "2024-03-01T00:00:03"  # day 61 of a leap year
    valid = np.ones((N_PINGS, N_CH), dtype=bool)
    valid[DEAD] = False
    np.testing.assert_array_equal(ds["channel_valid"].values, valid)
    assert (float(ds["pulse_f0"]), float(ds["pulse_f1"]), float(ds["pulse_duration"])) == (2000.0, 9000.0, 0.02)
    assert (float(ds["source_x"]), float(ds["source_y"]), float(ds["source_z"]), float(ds["tx_delay"])) == (
        0.0, 0.25, -0.125, 0.001)
    assert "pitch" not in ds  # not in the default mapping


def test_the_imported_file_reads_back_through_the_ping_reader(vendor_file, tmp_path):
    path, samples = vendor_file
    res = import_segy(path, tmp_path / "p.nc")
    assert (res.n_pings, res.n_channels, res.n_samples, res.sample_rate_hz) == (N_PINGS, N_CH, N_S, 40000.0)
    with PingFile(res.path) as f:
        p = f.ping(1)
        np.testing.assert_array_equal(p.samples, samples[1])
        assert p.pulse.f0_hz == 2000.0 and p.roll_deg == pytest.approx(-2.5, abs=1e-12)
        assert not p.channel_valid[5] and p.channel_valid.sum() == N_CH - 1


def test_options_replace_what_the_headers_and_text_say(vendor_file):
    path, _ = vendor_file
    ds, origins = read_segy_pings(path, options=SegyImportOptions(
        pulse=(3000.0, 8000.0, 0.005), source_m=(0.1, 0.2, 0.3), tx_delay_s=0.0, sound_speed_m_s=1490.5,
        element_pitch_m=0.05))
    assert (float(ds["pulse_f0"]), float(ds["pulse_f1"]), float(ds["pulse_duration"])) == (3000.0, 8000.0, 0.005)
    assert (float(ds["source_x"]), float(ds["source_y"]), float(ds["source_z"])) == (0.1, 0.2, 0.3)
    np.testing.assert_array_equal(ds["sound_speed"].values, 1490.5)
    np.testing.assert_allclose(ds["element_y"].values, (np.arange(N_CH) - 3.5) * 0.05, atol=1e-15)
    assert origins["pulse"] == origins["source"] == origins["tx_delay"] == "option"


def test_the_pulse_falls_back_to_the_binary_sweep_and_the_interval_to_the_binary_header(tmp_path):
    path = tmp_path / "f.sgy"
    write_vendor_segy(path, sweep=(2500, 8500, 40), trace_interval=0, binary_interval=50, shuffle=False)
    ds, origins = read_segy_pings(path)
    assert origins["pulse"] == "binary header sweep" and origins["source"].startswith("default")
    assert (float(ds["pulse_f0"]), float(ds["pulse_f1"]), float(ds["pulse_duration"])) == (2500.0, 8500.0, 0.04)
    assert float(ds["sample_rate"]) == 1e6 / 50
    assert "tx_delay" not in ds


@pytest.mark.parametrize("units, scalar, lat_raw, want_deg", [
    (3, -10000, 343000, 34.3),  # decimal degrees
    (4, -100, 34180000, 34.3),  # DDDMMSS.ss: 34 18' 00.00"
    (2, 1, 123480, 34.3),  # arc-seconds, no scalar
])
def test_coordinate_units_decide_the_degrees_of_a_coordinate(tmp_path, units, scalar, lat_raw, want_deg):
    path = tmp_path / "c.sgy"
    write_vendor_segy(path, text=TEXT, extra=lambda i, j: {T.CoordinateUnits: units, T.SourceGroupScalar: scalar,
                                                            T.SourceY: lat_raw, T.SourceX: -lat_raw})
    ds, _ = read_segy_pings(path)
    np.testing.assert_allclose(ds["latitude"].values, want_deg, atol=1e-12)
    np.testing.assert_allclose(ds["longitude"].values, -want_deg, atol=1e-12)


def test_a_mapping_moves_variables_to_other_fields(tmp_path):
    path = tmp_path / "m.sgy"
    write_vendor_segy(path, text=TEXT, extra=lambda i, j: {T.CDP: 7 + i, T.CDP_X: 4000 + i, T.UnassignedInt1: 0})
    m = mapping_from_dict({"ensemble": "CDP", "pitch": {"field": "CDP_X", "scale": 1e-3}, "roll": False})
    ds, _ = read_segy_pings(path, mapping=m)
    np.testing.assert_array_equal(ds["ping"].values, [7, 8, 9])
    np.testing.assert_allclose(ds["pitch"].values, [4.0, 4.001, 4.002], atol=1e-12)
    assert "roll" not in ds


# -- bad input -------------------------------------------------------------------------------
def _one_line(exc_info, *words):
    msg = str(exc_info.value)
    assert "\n" not in msg and all(w in msg for w in words), msg


def test_bad_files_are_one_line_errors(tmp_path):
    empty, junk, netcdf = tmp_path / "e.sgy", tmp_path / "j.sgy", tmp_path / "n.nc"
    empty.write_bytes(b"")
    junk.write_bytes(bytes(range(256)) * 20)
    xr.Dataset({"a": ("x", np.arange(3.0))}).to_netcdf(netcdf)
    for path, words in ((empty, ("e.sgy", "empty")), (junk, ("j.sgy", "not a SEG-Y")),
                        (netcdf, ("n.nc", "not a SEG-Y")), (tmp_path / "none.sgy", ("no such file",))):
        with pytest.raises(PingFileError) as e:
            read_segy_pings(path)
        _one_line(e, *words)


def test_ensembles_of_unequal_trace_counts_are_refused(tmp_path):
    path = tmp_path / "u.sgy"
    write_vendor_segy(path, text=TEXT, counts=[N_CH, N_CH - 1, N_CH])
    with pytest.raises(PingFileError) as e:
        read_segy_pings(path)
    _one_line(e, "ensemble 102", f"has {N_CH - 1} traces", f"ensemble 101 has {N_CH}")


def test_a_repeated_channel_and_a_zero_interval_are_refused(tmp_path):
    rep, zero = tmp_path / "r.sgy", tmp_path / "z.sgy"
    write_vendor_segy(rep, text=TEXT, extra=lambda i, j: {T.TraceNumber: 1 if j < 2 else j + 1})
    with pytest.raises(PingFileError) as e:
        read_segy_pings(rep)
    _one_line(e, "channel 1", "twice")
    write_vendor_segy(zero, text=TEXT, trace_interval=0, binary_interval=0)
    with pytest.raises(PingFileError) as e:
        read_segy_pings(zero)
    _one_line(e, "sample interval is 0")


def test_a_file_without_pulse_or_differing_t0_within_a_ping_is_refused(tmp_path):
    bare, odd = tmp_path / "b.sgy", tmp_path / "o.sgy"
    write_vendor_segy(bare)
    with pytest.raises(PingFileError) as e:
        read_segy_pings(bare)
    _one_line(e, "no pulse description", "--pulse")
    write_vendor_segy(odd, text=TEXT, extra=lambda i, j: {T.DelayRecordingTime: 200} if (i, j) == (2, 3) else {})
    with pytest.raises(PingFileError) as e:
        read_segy_pings(odd)
    _one_line(e, "t0", "DelayRecordingTime", "ensemble 103")


def test_a_file_without_sound_speed_needs_the_option(tmp_path):
    path = tmp_path / "c.sgy"
    write_vendor_segy(path, text=TEXT, extra=lambda i, j: {T.WeatheringVelocity: 0})
    with pytest.raises(PingFileError) as e:
        read_segy_pings(path)
    _one_line(e, "no sound speed", "WeatheringVelocity", "--sound-speed")
    ds, _ = read_segy_pings(path, options=SegyImportOptions(sound_speed_m_s=1480.0))
    np.testing.assert_array_equal(ds["sound_speed"].values, 1480.0)


# -- ping file -> SEG-Y -> ping file --------------------------------------------------------------------
@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """Two pings of the reference scene (roll, heave, navigation), a dead channel, and their SEG-Y copy."""
    from clbeam.sim import load_scene, simulate

    out = tmp_path_factory.mktemp("roundtrip")
    ds = simulate(load_scene("line1", pings=2, max_range_m=120), seed=3)
    valid = np.ones((2, ds.sizes["channel"]), dtype=bool)
    valid[1, 10] = False
    ds["channel_valid"] = (("ping", "channel"), valid)
    ds = ds.assign_coords(ping=[40, 41])
    ds["draft"] = (("ping",), np.array([5.0, 5.123456]))
    src, sgy, back = out / "src.nc", out / "copy.sgy", out / "back.nc"
    write_ping_file(ds, src)
    export_segy(src, sgy)
    import_segy(sgy, back)
    return src, sgy, back


#: half the resolution of each variable's default field (with the scalar the exporter picks)
HALF_STEP = {"element_y": 0.5e-7, "element_z": 0.5e-4, "roll": 0.5e-6, "heading": 0.5e-6, "heave": 0.5e-4,
             "draft": 0.5e-4,
             "latitude": 0.5e-3 / 3600, "longitude": 0.5e-3 / 3600}


def test_a_ping_file_survives_segy_and_back(simulated):
    src, _, back = simulated
    a, b = xr.open_dataset(src), xr.open_dataset(back)
    np.testing.assert_array_equal(b["ping"].values, [40, 41])
    np.testing.assert_array_equal(b["samples"].values, a["samples"].values)  # float32 both
    for name in ("sample_rate", "t0", "sound_speed", "pulse_f0", "pulse_f1", "pulse_duration", "source_x",
                 "source_y", "source_z", "element_x", "channel_valid"):
        np.testing.assert_array_equal(b[name].values, a[name].values, err_msg=name)
    for name, half in HALF_STEP.items():
        np.testing.assert_allclose(b[name].values, a[name].values, rtol=0, atol=half * (1 + 1e-9), err_msg=name)
    assert np.any(a["roll"].values != 0) and np.any(a["heave"].values != 0)  # the test moves them
    # whole seconds: the scene's pings are 4 s apart from a whole second
    np.testing.assert_array_equal(b["ping_time"].values, a["ping_time"].values)
    assert "pitch" not in b  # no default field: left out with a warning
    a.close()
    b.close()


def test_the_exported_file_is_standard_segy(simulated):
    src, sgy, _ = simulated
    with xr.open_dataset(src) as a, segyio.open(sgy, ignore_geometry=True) as f:
        n_ch, n_s = a.sizes["channel"], a.sizes["sample"]
        assert f.tracecount == 2 * n_ch and len(f.samples) == n_s
        assert (f.bin[B.Format], f.bin[B.Interval], f.bin[B.Traces], f.bin[B.SEGYRevision]) == (5, 25, n_ch, 1)
        assert (f.bin[B.SweepFrequencyStart], f.bin[B.SweepFrequencyEnd], f.bin[B.SweepLength]) == (2000, 9000, 80)
        h = f.header[n_ch + 10]
        assert (h[T.FieldRecord], h[T.TraceNumber], h[T.TraceIdentificationCode]) == (41, 11, 2)
        assert h[T.CoordinateUnits] == 2 and h[T.SourceGroupScalar] == -1000 and h[T.TimeBaseCode] == 4
        np.testing.assert_array_equal(f.trace[n_ch + 3], a["samples"].values[1, 3])
        text = bytes(f.text[0]).decode("ascii")
        assert "pulse_duration=0.08" in text and "map element_y = offset" in text


def test_export_refuses_analytic_samples_and_an_interval_off_the_microsecond(tmp_path):
    analytic = dataset_from_pings([point_ping(polar_point(30, 0), kind="analytic", record_s=0.05)])
    with pytest.raises(OptionError) as e:
        export_segy(pings_from_dataset(analytic), tmp_path / "a.sgy")
    _one_line(e, "kind='analytic'")
    odd = dataset_from_pings([point_ping(polar_point(30, 0), record_s=0.05, fs=48000.0)])
    with pytest.raises(OptionError) as e:
        export_segy(pings_from_dataset(odd), tmp_path / "b.sgy")
    _one_line(e, "sample interval", "TRACE_SAMPLE_INTERVAL")


def test_export_logs_a_rounded_sound_speed_and_a_finer_mapping_keeps_it(tmp_path, caplog):
    ds = dataset_from_pings([point_ping(polar_point(30, 0), record_s=0.05, c=1522.4)])
    with caplog.at_level(logging.WARNING, logger="clbeam"):
        export_segy(pings_from_dataset(ds), tmp_path / "c.sgy")
    assert any("sound_speed rounded" in r.getMessage() and "WeatheringVelocity" in r.getMessage()
               for r in caplog.records)
    back, _ = read_segy_pings(tmp_path / "c.sgy")
    assert float(back["sound_speed"][0]) == 1522.0  # whole m/s, the error the warning names
    fine = mapping_from_dict({"sound_speed": {"field": "ShotPoint", "scale": 1e-6}})
    export_segy(pings_from_dataset(ds), tmp_path / "d.sgy", mapping=fine)
    back, _ = read_segy_pings(tmp_path / "d.sgy", mapping=fine)
    assert float(back["sound_speed"][0]) == pytest.approx(1522.4, abs=5e-7)


# -- a SEG-Y copy images as the original -----------------------------------------------------------
def _image(ping_path, grid, ref_engine, outputs=("intensity", "cf")):
    imager = Imager(grid, ImagingOptions(interp="exact", outputs=outputs), engine=ref_engine)
    with PingFile(ping_path) as f:
        return [imager.image(p) for p in f]


def test_a_segy_copy_of_a_simulated_scene_images_as_the_scene(tmp_path, ref_engine):
    """The point scene's samples are float32 already and its geometry fits the fields exactly: the copy's
    images equal the original's to the float64 rounding of the element positions' decimal (1e-16 m)."""
    from clbeam.sim import load_scene, simulate

    src, sgy, back = tmp_path / "p.nc", tmp_path / "p.sgy", tmp_path / "q.nc"
    write_ping_file(simulate(load_scene("point", max_range_m=260)), src)
    export_segy(src, sgy)
    import_segy(sgy, back)
    target_deg = np.degrees(np.arctan2(150.0, 200.0))
    grid = PolarGrid(np.arange(245.0, 255.0, 0.1), np.arange(target_deg - 3, target_deg + 3, 0.1))
    (a,), (b,) = _image(src, grid, ref_engine), _image(back, grid, ref_engine)
    peak = a.intensity.max()
    assert peak > 0 and np.unravel_index(a.intensity.argmax(), a.intensity.shape)[0] in range(28, 33)
    np.testing.assert_allclose(b.intensity, a.intensity, rtol=0, atol=1e-12 * peak)
    np.testing.assert_allclose(b.cf, a.cf, rtol=0, atol=1e-10)


def test_a_segy_copy_of_float64_samples_images_within_float32_rounding(tmp_path, ref_engine):
    """SEG-Y keeps IEEE float32: each sample x becomes x (1 + d), |d| <= u = 2^-24.  The imaging is linear
    in the samples, so the copy's sum S differs from the original's by the image of the rounding residual;
    for one echo through a matched filter (Cauchy-Schwarz: |<h, x d>| <= u ||h|| ||x||, with
    ||h|| = sqrt(2) ||s|| for the analytic replica and ||x|| = a ||s||) every cell's error is at most
    sqrt(2) u times the focused sum S_target, so |I' - I| <= (2 sqrt(2) u + 2 u^2) I_target."""
    u = 2.0 ** -24
    target = polar_point(60.0, 20.0)
    ping = point_ping(target, [3.0], record_s=0.12, roll_deg=1.5, heave_m=0.25)  # float64 samples
    src, sgy, back, res = tmp_path / "p.nc", tmp_path / "p.sgy", tmp_path / "q.nc", tmp_path / "r.nc"
    write_ping_file(dataset_from_pings([ping]), src)
    mapping = mapping_from_dict({"heave": {"field": "SourceSurfaceElevation", "scalar": "ElevationScalar",
                                           "scale": 1e-3}})  # heave in mm x scalar: 0.1 um, exact here
    export_segy(src, sgy, mapping=mapping)
    import_segy(sgy, back, mapping=mapping)
    residual = dataset_from_pings([ping]).copy()
    residual["samples"].values[:] = ping.samples.astype(np.float32).astype(np.float64) - ping.samples
    write_ping_file(residual, res)
    grid = PolarGrid(60.0 + 0.05 * np.arange(-100, 100), 20.0 + 0.2 * np.arange(-25, 25))  # a node on the target
    (a,), (b,), (r,) = (_image(p, grid, ref_engine, ("sums", "intensity")) for p in (src, back, res))
    s_a, s_b, s_r = (x.sums.s for x in (a, b, r))
    # linearity: the copy's S is the original's plus the image of the float32 residual
    np.testing.assert_allclose(s_b, s_a + s_r, rtol=0, atol=1e-12 * np.abs(s_a).max())
    assert np.abs(s_r).max() > 0  # the samples were rounded
    i_target = a.intensity[25, 100]
    assert i_target == pytest.approx(a.intensity.max(), rel=1e-3)
    np.testing.assert_allclose(b.intensity, a.intensity, rtol=0, atol=(2 * np.sqrt(2) * u + 2 * u * u) * i_target)


# -- the documentation ------------------------------------------------------------------------
DOC = __import__("pathlib").Path(__file__).resolve().parents[2] / "docs" / "import.md"


def test_the_mapping_table_of_the_docs_is_the_default_mapping():
    from clbeam.io.segy_mapping import DEFAULT_ENTRIES

    rows = {}
    for line in DOC.read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.split("|")[1:-1]] if line.startswith("| `") else []
        if len(cells) == 6:
            rows[cells[0].strip("`")] = cells
    assert set(DEFAULT_ENTRIES) <= set(rows)
    for name, entry in DEFAULT_ENTRIES.items():
        field, scalar, scale = rows[name][2], rows[name][3], rows[name][4]
        if entry is None:
            assert field.startswith("not mapped"), name
            continue
        assert field.startswith(f"`{entry.field}` ({entry.byte}-{entry.byte + entry.n_bytes - 1})"), name
        assert scalar == ("" if entry.scalar is None else f"`{entry.scalar}` ({TRACE_FIELDS[entry.scalar]}-"
                          f"{TRACE_FIELDS[entry.scalar] + 1})"), name
        if entry.scale is None:
            assert scale == "`CoordinateUnits`", name
        elif name not in ("ensemble", "channel"):
            assert float(scale.split()[0]) == entry.scale, name


def test_the_docs_mapping_example_loads(tmp_path):
    import re

    example = re.search(r"```toml\n(.*?)```", DOC.read_text(encoding="utf-8"), flags=re.S).group(1)
    (tmp_path / "vendor.toml").write_text(example)
    m = load_mapping(tmp_path / "vendor.toml")
    assert (m.get("ensemble").field, m.get("element_y").field, m.get("roll").field) == ("CDP", "GroupX", "UnassignedInt1")
    assert m.get("t0").scalar is None and m.get("heading") is None and m.get("element_z") is None
