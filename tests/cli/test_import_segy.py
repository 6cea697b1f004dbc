"""``clbeam import-segy``: a multichannel SEG-Y file written with segyio into a ping file; options,
a mapping file, and bad input in one line (exit 2)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import xarray as xr
from segy_files import ENSEMBLES, N_CH, N_PINGS, N_S, TEXT, T, element_y_m, write_vendor_segy

from clbeam.cli.main import main


@pytest.fixture(scope="module")
def bare_segy(tmp_path_factory):
    """A vendor file whose textual header says nothing of the pulse or the source."""
    path = tmp_path_factory.mktemp("cli-segy") / "bare.sgy"
    samples = write_vendor_segy(path, extra=lambda i, j: {T.CDP: 500 + i})
    return path, samples


def test_import_writes_a_ping_file_with_the_options_given(bare_segy, tmp_path, capsys):
    path, samples = bare_segy
    out = tmp_path / "pings.nc"
    rc = main(["import-segy", str(path), "-o", str(out), "--pulse", "2000", "9000", "0.02", "--source", "0", "0.1",
               "0.2", "--tx-delay", "0.0005"])
    assert rc == 0
    line = capsys.readouterr().out
    assert f"imported {N_PINGS} ping(s) of {N_CH} channels x {N_S} samples" in line and "pulse: option" in line
    with xr.open_dataset(out) as ds:
        assert ds.attrs["clbeam_format"] == "ping-1"
        np.testing.assert_array_equal(ds["samples"].values, samples)
        np.testing.assert_array_equal(ds["ping"].values, ENSEMBLES)
        np.testing.assert_allclose(ds["element_y"].values, element_y_m(), atol=1e-15)
        assert (float(ds["pulse_f0"]), float(ds["pulse_f1"]), float(ds["pulse_duration"])) == (2000, 9000, 0.02)
        assert (float(ds["source_y"]), float(ds["source_z"]), float(ds["tx_delay"])) == (0.1, 0.2, 0.0005)


def test_a_mapping_file_chooses_the_ensemble_field(bare_segy, tmp_path):
    path, _ = bare_segy
    mapping, out = tmp_path / "map.toml", tmp_path / "pings.nc"
    mapping.write_text('ensemble = "CDP"  # this exporter numbers pings in bytes 21-24\nheading = false\n')
    assert main(["import-segy", str(path), "-o", str(out), "--mapping", str(mapping), "--pulse", "2000", "9000",
                 "0.02", "-q"]) == 0
    with xr.open_dataset(out) as ds:
        np.testing.assert_array_equal(ds["ping"].values, [500, 501, 502])
        assert "heading" not in ds and "roll" in ds


def _error_line(capsys):
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("clbeam: error:"), err
    return err


def test_bad_input_is_one_line_and_exit_2(bare_segy, tmp_path, capsys):
    path, _ = bare_segy
    out = tmp_path / "p.nc"
    junk = tmp_path / "junk.sgy"
    junk.write_bytes(b"\x00" * 5000)
    assert main(["import-segy", str(junk), "-o", str(out), "-q"]) == 2
    assert "not a SEG-Y file" in _error_line(capsys)
    bad_map = tmp_path / "bad.toml"
    bad_map.write_text('roll = "RollAngle"\n')
    assert main(["import-segy", str(path), "-o", str(out), "--mapping", str(bad_map), "-q"]) == 2
    assert "unknown trace-header field 'RollAngle'" in _error_line(capsys)
    assert main(["import-segy", str(path), "-o", str(out), "-q"]) == 2  # the bare file has no pulse
    assert "--pulse F0 F1 DURATION" in _error_line(capsys)
    assert main(["import-segy", str(path), "-o", str(tmp_path / "no" / "p.nc"), "-q"]) == 2
    assert "does not exist" in _error_line(capsys)
    uneven = tmp_path / "uneven.sgy"
    write_vendor_segy(uneven, text=TEXT, counts=[N_CH, N_CH, N_CH - 2])
    assert main(["import-segy", str(uneven), "-o", str(out), "-q"]) == 2
    assert f"has {N_CH - 2} traces" in _error_line(capsys)


def test_without_segyio_the_command_names_the_extra(tmp_path):
    runner = ("import sys\nsys.modules['segyio'] = None\nfrom clbeam.cli.main import main\n"
              "sys.exit(main(sys.argv[1:]))")
    r = subprocess.run([sys.executable, "-c", runner, "import-segy", "x.sgy", "-o", "p.nc"], capture_output=True,
                       text=True, cwd=tmp_path, timeout=300)
    err = r.stderr.strip()
    assert r.returncode == 2 and "\n" not in err and "pip install 'clbeam[segy]'" in err, err
