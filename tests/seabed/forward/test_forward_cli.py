"""The ``forward`` subcommand and the Figs. 8–9 reproductions."""

import csv

import numpy as np
import pytest
import xarray as xr
from matplotlib.image import imread

from clbeam.cli.forward import run
from clbeam.cli.main import build_parser
from clbeam.errors import ClbeamError, OptionError
from clbeam.seabed.forward import LayoutFileError, echo_times, table2_layout
from clbeam.seabed.forward.figures import echo_spectra_db, table2_figures, table2_traces


def parse(argv):
    return build_parser().parse_args(argv)


def test_forward_writes_the_trace_figures_and_a_one_line_summary(tmp_path, capsys):
    args = parse(["forward", "--layers", "table2-layout1", "--chirp", "high", "-o", str(tmp_path)])
    assert args.func is run and run(args) == 0
    out = capsys.readouterr().out.strip().splitlines()
    # one line, with the echo times 2 h / c summed (26.667, 29.167, 33.804 ms)
    assert len(out) == 1 and "3 echo(es) at 26.667, 29.167, 33.804 ms" in out[0]
    with open(tmp_path / "table2-layout1_trace.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    t = np.array([float(r["time_s"]) for r in rows])
    env = np.array([float(r["envelope_pa"]) for r in rows])
    # the strongest echo is the second: V2 (1 - V1^2) / (2 c1 tau2) = 0.1874 / 87.5 = 2.14e-3 Pa against the
    # seafloor's 0.1620 / 80 = 2.03e-3 Pa; the envelope peaks within half a sample (10.4 us) of its 2 h / c sum
    peak = t[np.argmax(env)]
    assert abs(peak - echo_times(table2_layout(1))[1]) <= 0.5 / 48000.0 + 1e-12
    # figure sizes: 8 x 3.5 in and 6.5 x 4 in at 100 dpi
    assert imread(tmp_path / "table2-layout1_compressed.png").shape[:2] == (350, 800)
    assert imread(tmp_path / "table2-layout1_spectra.png").shape[:2] == (400, 650)


def test_forward_writes_netcdf_with_units(tmp_path, capsys):
    layout = tmp_path / "site.toml"
    layout.write_text('[water]\ndepth_m = 15.0\n[[layers]]\nsound_speed_m_s = 1600.0\ndensity_kg_m3 = 1300.0\n')
    args = parse(["forward", "--layers", str(layout), "--chirp", "2000,8000,0.005", "--format", "netcdf",
                  "-o", str(tmp_path / "out"), "-q"])
    assert run(args) == 0 and capsys.readouterr().out == ""
    ds = xr.open_dataset(tmp_path / "out" / "site_trace.nc")
    assert ds["compressed"].attrs["units"] == "Pa" and ds["time"].attrs["units"] == "s"
    # one smooth interface 15 m down: echo at 20 ms, compressed peak R/(2 c1 tau) (eq. 15, normalised)
    assert float(ds["echo_time"][0]) == pytest.approx(0.02, rel=1e-15)
    r = (1300 * 1600 - 1.5e6) / (1300 * 1600 + 1.5e6)
    assert float(ds["compressed"].sel(time=0.02, method="nearest")) == pytest.approx(r / (2 * 1500 * 0.02), rel=1e-9)
    ds.close()


@pytest.mark.parametrize("argv,error,message", [
    (["--chirp", "fast"], OptionError, "F0,F1,DUR"),
    (["--incidence", "95"], OptionError, "--incidence"),
])
def test_forward_bad_options_raise_one_line_errors(tmp_path, argv, error, message):
    args = parse(["forward", "--layers", "table2-layout1", "-o", str(tmp_path)] + argv)
    with pytest.raises(error, match=message) as info:
        run(args)
    assert "\n" not in str(info.value)


def test_forward_missing_layout_file_is_a_clbeam_error(tmp_path):
    args = parse(["forward", "--layers", str(tmp_path / "nope.toml"), "-o", str(tmp_path)])
    with pytest.raises(LayoutFileError, match="not found"):
        run(args)
    assert issubclass(LayoutFileError, ClbeamError)


def test_forward_is_registered_with_the_shared_quiet_option():
    args = build_parser().parse_args(["forward", "--layers", "x.toml", "-q"])
    assert args.quiet and args.chirp == "low" and args.func is run


def test_table2_figures_are_written_and_their_curves_follow_the_model(tmp_path):
    data = table2_traces()
    paths = table2_figures(tmp_path, data=data)
    assert imread(paths["fig8"]).shape[:2] == (600, 900) and imread(paths["fig9"]).shape[:2] == (650, 900)
    # Fig. 9 curves are 20 log10 |A_i(w) x(w)|: layout 1's echo 1 is the emitted spectrum scaled by the
    # smooth seafloor echo R/(2 c1 tau), a constant
    tr = data.traces[(1, "high")]
    band = (tr.freq_hz > 6000) & (tr.freq_hz < 14000)
    r = (1300 * 1600 - 1.5e6) / (1300 * 1600 + 1.5e6)
    expected = 20 * np.log10(np.abs(tr.emitted_spectrum[band]) * r / (2 * 1500 * 40 / 1500))
    np.testing.assert_allclose(echo_spectra_db(tr)[0][band], expected, atol=1e-9)
