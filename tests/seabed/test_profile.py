"""clbeam profile: the vertical beam per ping, its SEG-Y file and figure.

Expected values come from the scenes' geometry (a point scatterer placed
directly below, the simulator's seabed depth), from the ping file's own
variables (navigation, time, pulse) and from the definition of the trace,
``|S| / M`` of the Imager's sums on a one-angle grid.
"""

import datetime

import numpy as np
import pytest
import segyio
import xarray as xr
from scenes import FS, PULSE, C, point_ping

from clbeam.cli.main import build_parser, main
from clbeam.errors import ClbeamError, OptionError
from clbeam.imaging.geometry import to_earth_frame
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.imaging.vertical_beam import TraceAxis
from clbeam.io.pingfile import PingFile
from clbeam.io.pingwrite import write_ping_file
from clbeam.model.grid import PolarGrid

TARGET_R = 75.0  # m, directly below the source (earth frame)
AMPLITUDE = 2.5
ROLL = (0.0, 4.0, -6.0)  # degree
HEAVE = (0.0, 0.5, -0.3)  # m
T0 = (0.0127, 0.0150, 0.0127)  # s; the traces start at the earliest, rounded down to whole ms
DELAY_MS = 12
TIMES = ("2024-02-29T23:59:58.700", "2024-03-01T00:00:02.700", "2024-03-01T00:00:06.700")
LAT = (34.3, 34.30007, 34.30014)
LON = (-119.8, -119.80002, -119.80004)
RECORD_S = 0.15  # holds the echo of the 20 ms pulse at 100 ms two-way time, with heave
VALID = np.ones((3, 64), dtype=bool)
VALID[2, :16] = False  # ping 2: 16 dead channels, so M = 48 and |S| / M still equals the echo amplitude


def run_profile(argv):
    """Parse ``clbeam profile ARGV`` with the command line's parser and run it."""
    args = build_parser().parse_args(["profile", *map(str, argv)])
    return args.func(args)


@pytest.fixture(scope="module")
def point_file(tmp_path_factory):
    """Three raw pings of a point scatterer at 75 m straight down, each rolled and heaved differently."""
    pings = [point_ping([0.0, 0.0, TARGET_R], [AMPLITUDE], roll_deg=r, heave_m=h, t0_s=t0, record_s=RECORD_S)
             for r, h, t0 in zip(ROLL, HEAVE, T0)]
    p0 = pings[0]
    ds = xr.Dataset({
        "samples": (("ping", "channel", "sample"), np.stack([p.samples for p in pings]), {"kind": "raw"}),
        "sample_rate": ((), FS), "t0": (("ping",), np.array(T0)),
        "element_y": (("channel",), p0.element_pos_m[:, 1]), "element_z": (("channel",), p0.element_pos_m[:, 2]),
        "source_y": ((), 0.0), "source_z": ((), 0.0),
        "sound_speed": (("ping",), np.full(3, C)),
        "roll": (("ping",), np.array(ROLL)), "heave": (("ping",), np.array(HEAVE)),
        "latitude": (("ping",), np.array(LAT)), "longitude": (("ping",), np.array(LON)),
        "ping_time": (("ping",), np.array(TIMES, dtype="datetime64[ns]")),
        "channel_valid": (("ping", "channel"), VALID),
        "pulse_f0": ((), PULSE.f0_hz), "pulse_f1": ((), PULSE.f1_hz), "pulse_duration": ((), PULSE.duration_s),
    })
    path = tmp_path_factory.mktemp("profile") / "points.nc"
    write_ping_file(ds, path)
    return path


@pytest.fixture(scope="module")
def profiles(point_file, tmp_path_factory):
    """The envelope and the analytic profile of ``point_file`` (OpenCL engine, Lanczos-8)."""
    out = tmp_path_factory.mktemp("profile-out")
    env, ana = out / "env.sgy", out / "ana.sgy"
    assert run_profile([point_file, "-o", env, "--interp", "lanczos8", "-q"]) == 0
    assert run_profile([point_file, "-o", ana, "--interp", "lanczos8", "--analytic", "--png", out / "ana-fig.png",
                        "-q"]) == 0
    return env, ana


def expected_peak_amplitude(i):
    """Mean over the live channels of the echo amplitude ``a / (|r - s| |r - e_n|)`` of ping ``i`` (scenes.point_ping)."""
    p = point_ping([0.0, 0.0, TARGET_R], roll_deg=ROLL[i], heave_m=HEAVE[i], record_s=0.01)
    el = to_earth_frame(p.element_pos_m, roll_deg=ROLL[i], heave_m=HEAVE[i])
    src = to_earth_frame(p.source_pos_m, roll_deg=ROLL[i], heave_m=HEAVE[i])
    r = np.array([0.0, 0.0, TARGET_R])
    amp = AMPLITUDE / (np.linalg.norm(r - src) * np.linalg.norm(r - el, axis=1))
    return float(np.mean(amp[VALID[i]]))


def sums_on_trace_axis(path, times_s, interp, engine):
    """``S / M`` per ping from the Imager on the grid ``R = c t / 2`` at 0 degree, computed here."""
    out = []
    with PingFile(path) as f:
        for p in f:
            grid = PolarGrid(0.5 * p.sound_speed_m_s * times_s, np.array([0.0]))
            img = Imager(grid, ImagingOptions(interp=interp, outputs=("sums",)), engine=engine).image(p)
            s, m = img.sums.s[0], img.sums.m[0]
            out.append(np.where(m > 0, s / np.maximum(m, 1), 0))
    return np.array(out)


# -- SEG-Y round trip ----------------------------------------------------------------
def test_segy_headers_hold_the_pings_time_axis_navigation_time_and_pulse(point_file, profiles):
    env, _ = profiles
    n_expected = int(np.floor((max(T0) + (RECORD_S * FS - 1) / FS - DELAY_MS / 1e3) * FS + 1e-9)) + 1
    with segyio.open(env, ignore_geometry=True) as f:
        assert f.tracecount == 3
        assert len(f.samples) == n_expected
        assert f.bin[segyio.BinField.Interval] == 1e6 / FS == 25
        assert f.bin[segyio.BinField.Format] == 5  # IEEE float
        assert f.bin[segyio.BinField.Traces] == 1
        assert (f.bin[segyio.BinField.SweepFrequencyStart], f.bin[segyio.BinField.SweepFrequencyEnd],
                f.bin[segyio.BinField.SweepLength], f.bin[segyio.BinField.Sweep]) == (2000, 9000, 20, 1)
        assert f.samples[0] == DELAY_MS and f.samples[1] - f.samples[0] == pytest.approx(0.025)
        text = bytes(f.text[0]).decode("ascii")
        assert "CLBEAM" in text and "points.nc" in text and "0 DEG FROM NADIR" in text and "|S|/M" in text
        for i in range(3):
            h = f.header[i]
            T = segyio.TraceField
            assert (h[T.TRACE_SEQUENCE_LINE], h[T.TRACE_SEQUENCE_FILE], h[T.FieldRecord], h[T.TraceNumber]) \
                == (i + 1, i + 1, i + 1, 1)
            assert h[T.DelayRecordingTime] == DELAY_MS
            assert (h[T.TRACE_SAMPLE_COUNT], h[T.TRACE_SAMPLE_INTERVAL]) == (n_expected, 25)
            assert (h[T.SweepFrequencyStart], h[T.SweepFrequencyEnd], h[T.SweepLength], h[T.SweepType]) \
                == (2000, 9000, 20, 1)
            assert h[T.NStackedTraces] == VALID[i].sum()  # channels used
            # coordinates: arc-seconds (units 2) with a negative scalar = divisor (SEG-Y rev 1)
            assert h[T.CoordinateUnits] == 2 and h[T.SourceGroupScalar] < 0
            scale = 1.0 / -h[T.SourceGroupScalar]
            assert h[T.SourceX] * scale / 3600 == pytest.approx(LON[i], abs=0.51 * scale / 3600)
            assert h[T.SourceY] * scale / 3600 == pytest.approx(LAT[i], abs=0.51 * scale / 3600)
            when = datetime.datetime.fromisoformat(TIMES[i])
            assert (h[T.YearDataRecorded], h[T.DayOfYear], h[T.HourOfDay], h[T.MinuteOfHour], h[T.SecondOfMinute]) \
                == (when.year, when.timetuple().tm_yday, when.hour, when.minute, when.second)
        assert [f.header[i][segyio.TraceField.DayOfYear] for i in range(3)] == [60, 61, 61]  # 2024 is a leap year


def test_segy_traces_are_the_envelope_of_the_coherent_sum_over_the_channels(point_file, profiles, cl_engine):
    env, _ = profiles
    with segyio.open(env, ignore_geometry=True) as f:
        data = segyio.tools.collect(f.trace[:])
        times = f.samples * 1e-3
    expected = np.abs(sums_on_trace_axis(point_file, times, "lanczos8", cl_engine))
    # the file holds float32: relative rounding 2^-24 of each value
    np.testing.assert_allclose(data, expected, rtol=1e-6, atol=1e-6 * expected.max())
    assert data.dtype == np.float32


# -- the beam points straight down ---------------------------------------------------
def test_envelope_peaks_at_a_point_below_at_its_range_whatever_the_roll_and_heave(profiles):
    env, _ = profiles
    with segyio.open(env, ignore_geometry=True) as f:
        times_ms = f.samples
        for i in range(3):
            trace = f.trace[i]
            k = int(np.argmax(trace))
            # two-way time 2 R / c from the (heave-compensated) source: 100 ms, sample 3520.
            # Without heave compensation ping 1's echo would sit 2 h / c = 0.67 ms (27 samples) later.
            assert times_ms[k] == pytest.approx(2e3 * TARGET_R / C, abs=0.025 + 1e-9)
            # a coherent sum straight down keeps the echo's full amplitude: roll compensated (with the roll
            # ignored, the 4 and -6 degree pings keep only 26 % and 14 % of it).
            # Tolerance 0.5 %: Lanczos-8 interpolation at 9 kHz / 40 kHz (about 2e-4) and the
            # compressed LFM's peak, which equals the amplitude to about 1e-4.
            assert trace[k] == pytest.approx(expected_peak_amplitude(i), rel=5e-3)


def test_envelope_peaks_at_the_simulated_seabed_two_way_time(tmp_path, cl_engine):
    from clbeam.sim import load_scene, simulate

    ds = simulate(load_scene("line1", pings=2, max_range_m=260))
    pings = tmp_path / "line1.nc"
    write_ping_file(ds, pings)
    out = tmp_path / "line1.sgy"
    assert run_profile([pings, "-o", out, "-q"]) == 0
    z = ds["truth_seabed_z"].values - float(ds["source_z"])  # seabed below the source (m)
    c = ds["sound_speed"].values
    with segyio.open(out, ignore_geometry=True) as f:
        dt_ms = f.samples[1] - f.samples[0]
        for i in range(2):
            t_peak = f.samples[int(np.argmax(f.trace[i]))]
            # within two samples: the rough seabed's scatterers spread the echo over a few centimetres
            assert t_peak == pytest.approx(2e3 * z[i] / c[i], abs=2 * dt_ms + 1e-9)
    import matplotlib.image

    png = matplotlib.image.imread(out.with_suffix(".png"))  # the figure, next to the SEG-Y file
    assert png.ndim == 3 and png.shape[0] > 200 and png.shape[1] > 400


# -- analytic layout -----------------------------------------------------------------
def test_analytic_writes_real_and_imaginary_traces_of_s_over_m(point_file, profiles, cl_engine):
    env, ana = profiles
    with segyio.open(ana, ignore_geometry=True) as f, segyio.open(env, ignore_geometry=True) as g:
        assert f.tracecount == 6 and f.bin[segyio.BinField.Traces] == 2
        T = segyio.TraceField
        assert [(f.header[j][T.FieldRecord], f.header[j][T.TraceNumber]) for j in range(6)] \
            == [(1, 1), (1, 2), (2, 1), (2, 2), (3, 1), (3, 2)]
        data = segyio.tools.collect(f.trace[:])
        envelope = segyio.tools.collect(g.trace[:])
        times = f.samples * 1e-3
    z = data[0::2] + 1j * data[1::2]
    expected = sums_on_trace_axis(point_file, times, "lanczos8", cl_engine)
    np.testing.assert_allclose(z, expected, rtol=1e-6, atol=1e-6 * np.abs(expected).max())
    np.testing.assert_allclose(np.abs(z), envelope, rtol=1e-6, atol=1e-6 * envelope.max())
    k = np.argmax(envelope, axis=1)
    for i in range(3):
        # the compressed echo of a point is real and positive at its delay (zero phase)
        assert z[i, k[i]].real == pytest.approx(expected_peak_amplitude(i), rel=5e-3)
        assert abs(z[i, k[i]].imag) < 1e-2 * z[i, k[i]].real
    assert (ana.parent / "ana-fig.png").stat().st_size > 0  # --png


# -- the time axis -------------------------------------------------------------------------
def test_trace_axis_rounds_to_whole_microseconds_and_milliseconds_and_honours_max_range():
    ax = TraceAxis.for_record(sample_rate_hz=48000.0, t0_s=[0.0049, 0.0061], n_record_samples=4800,
                              sound_speed_m_s=[1490.0, 1500.0])
    assert (ax.delay_ms, ax.interval_us) == (4, 21)  # 20.83 us -> 21; 4.9 ms -> 4
    assert ax.times_s[-1] <= 0.0061 + 4799 / 48000 < ax.times_s[-1] + 21e-6
    ax = TraceAxis.for_record(sample_rate_hz=40000.0, t0_s=0.0, n_record_samples=40000, sound_speed_m_s=[1490.0, 1500.0],
                              max_range_m=150.0)
    # ends at 2 M / c of the slowest ping, so every ping reaches 150 m
    assert ax.ranges_m(1490.0)[-1] == pytest.approx(150.0, abs=0.5 * 1490.0 * 25e-6)
    with pytest.raises(OptionError, match="65535"):
        TraceAxis.for_record(sample_rate_hz=40000.0, t0_s=0.0, n_record_samples=70000, sound_speed_m_s=1500.0)


# -- bad input ---------------------------------------------------------------------------------
@pytest.mark.parametrize("case", ["missing file", "not a ping file", "no such folder", "output is a folder",
                                  "negative max range", "max range before the record", "figure is the output"])
def test_bad_input_is_one_line_and_exit_2(case, point_file, tmp_path, capsys):
    bad = tmp_path / "bad.nc"
    bad.write_text("not netcdf")
    out = tmp_path / "p.sgy"
    argv = {
        "missing file": [tmp_path / "none.nc", "-o", out],
        "not a ping file": [bad, "-o", out],
        "no such folder": [point_file, "-o", tmp_path / "nowhere" / "p.sgy"],
        "output is a folder": [point_file, "-o", tmp_path],
        "negative max range": [point_file, "-o", out, "--max-range", "-5"],
        "max range before the record": [point_file, "-o", out, "--max-range", "5"],  # record starts at 9 m
        "figure is the output": [point_file, "-o", out, "--png", out],
    }[case]
    rc = main(["profile", *map(str, argv), "-q"])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert err.startswith("clbeam: error:") and "\n" not in err
    assert not out.exists()


def test_missing_segyio_is_one_line_naming_the_extra(point_file, tmp_path, capsys, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "segyio", None)  # import segyio now raises ImportError
    out = tmp_path / "p.sgy"
    rc = main(["profile", str(point_file), "-o", str(out), "-q"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "segyio" in err and "clbeam[segy]" in err and "\n" not in err
    assert not out.exists()


def test_failure_midway_leaves_no_partial_segy(point_file, tmp_path, monkeypatch):
    from clbeam.imaging import vertical_beam

    calls = []
    real = vertical_beam.VerticalBeam.__call__

    def failing(self, ping):
        calls.append(ping.index)
        if ping.index == 1:
            raise ClbeamError("ping 1 failed")
        return real(self, ping)

    monkeypatch.setattr(vertical_beam.VerticalBeam, "__call__", failing)
    out = tmp_path / "p.sgy"
    with pytest.raises(ClbeamError, match="ping 1 failed"):
        run_profile([point_file, "-o", out, "-q"])
    assert calls == [0, 1] and not out.exists() and not out.with_suffix(".png").exists()


def test_segy_header_names_the_setting_auto_chose(point_file, tmp_path):
    from clbeam.imaging.vertical_beam import TraceAxis, VerticalBeam
    from clbeam.io.pingfile import PingFile
    from clbeam.seabed.profile import write_profile

    out = write_profile(point_file, tmp_path / "auto.sgy", plot=False).segy_path
    with segyio.open(out, ignore_geometry=True) as f:
        lines = [bytes(f.text[0]).decode("ascii")[80 * k:80 * (k + 1)].strip() for k in range(40)]
    line = next(x for x in lines if "INTERPOLATION" in x)
    assert "AUTO" not in line and "PREDICTED" in line  # a mode, its beams and the predicted error, not 'auto'
    with PingFile(point_file) as pf:
        ping, axis = pf.ping(0), TraceAxis.for_file(pf)
    assert VerticalBeam(axis, interp="auto").setting(ping).upper()[:40] in line
