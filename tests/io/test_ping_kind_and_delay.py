"""The samples' kind wherever a writer puts it, and the replica's delay
``tx_delay`` (docs/ping-format.md): read, used by pulse compression, written back."""

import numpy as np
import pytest
from scenes import dataset

from clbeam.errors import PingFileError
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.io.pingfile import PingFile
from clbeam.io.pingwrite import dataset_from_pings, write_ping_file
from clbeam.model.grid import PolarGrid


def split(ds, where):
    """``samples`` (analytic) stored as the pair, ``kind`` put ``where``: a half, the dataset or nowhere."""
    s = ds["samples"]
    out = ds.drop_vars("samples").assign(samples_r=(s.dims, s.values.real.astype(np.float32)),
                                         samples_i=(s.dims, s.values.imag.astype(np.float32)))
    if where in ("samples_r", "samples_i"):
        out[where].attrs["kind"] = "analytic"
    elif where == "dataset":
        out.attrs["kind"] = "analytic"
    return out


@pytest.mark.parametrize("where", ["samples_r", "samples_i", "dataset", "nowhere"])
def test_a_pair_is_analytic_whichever_half_says_so_or_none(tmp_path, where):
    ds, pings = dataset(kind="analytic")
    with PingFile(write_ping_file(split(ds, where), tmp_path / "p.nc")) as f:
        p = f.ping(1)
    assert p.kind == "analytic"
    np.testing.assert_allclose(p.samples, pings[1].samples, rtol=0, atol=1e-6 * np.abs(pings[1].samples).max())


def test_kind_on_the_dataset_serves_a_single_variable(tmp_path):
    ds, _ = dataset(kind="analytic")
    ds["samples"].attrs.pop("kind")
    ds.attrs["kind"] = "analytic"
    with PingFile(write_ping_file(ds, tmp_path / "p.nc")) as f:
        assert f.kind == "analytic"


@pytest.mark.parametrize("case, message", [
    ("pair says raw", "the pair 'samples_r'/'samples_i' is the analytic signal (see docs/ping-format.md) but "
                      "variable 'samples_i' has kind='raw'"),
    ("disagreement", "variable 'samples' and the dataset disagree on kind (analytic and raw)"),
])
def test_inconsistent_kinds_are_one_line_naming_the_fix(tmp_path, case, message):
    ds, _ = dataset(kind="analytic")
    if case == "pair says raw":
        ds = split(ds, "samples_r")
        ds["samples_i"].attrs["kind"] = "raw"
    else:
        ds.attrs["kind"] = "raw"
    path = write_ping_file(ds, tmp_path / "p.nc", split_complex=False)  # the file as the dataset is
    with pytest.raises(PingFileError) as err:
        PingFile(path)
    assert message in str(err.value) and "\n" not in str(err.value)


def peak_range_m(ping, grid) -> float:
    img = Imager(grid, ImagingOptions(interp="lanczos8", refine_peaks=True)).image(ping)
    best = max(img.peaks, key=lambda r: r["intensity_db"])
    return best["range_m"]


def test_a_replica_that_starts_before_transmit_is_placed_by_tx_delay(tmp_path):
    # the same pings, their replica given as a wavelet padded by 4 ms before it: the replica's
    # first sample 4 ms before transmit start (tx_delay = -4 ms)
    ds, pings = dataset(kind="raw")
    fs = float(ds["sample_rate"])
    replica = pings[0].pulse.replica(fs)
    pad = int(0.004 * fs)
    shifted = ds.drop_vars(["pulse_f0", "pulse_f1", "pulse_duration"]).assign(
        tx_waveform=(("tx_sample",), np.r_[np.zeros(pad), replica]))
    grid = PolarGrid.regular(range_res_m=0.05, angle_res_deg=0.5, min_range_m=36, max_range_m=43, angles_deg=(-20, 20))
    truth = peak_range_m(pings[0], grid)
    assert truth == pytest.approx(40.0, abs=0.02)
    with PingFile(write_ping_file(shifted, tmp_path / "late.nc")) as f:
        late = peak_range_m(f.ping(0), grid)
    # without tx_delay, compression aligns the echo with the padding's start: every echo 3 m (c t / 2) early
    assert truth - late == pytest.approx(1500.0 * pad / fs / 2, abs=0.02)
    delayed = shifted.assign(tx_delay=((), -pad / fs))
    with PingFile(write_ping_file(delayed, tmp_path / "delayed.nc")) as f:
        p = f.ping(0)
        assert p.pulse.delay_s == pytest.approx(-pad / fs)
        assert peak_range_m(p, grid) == pytest.approx(truth, abs=0.01)
    # written back by clbeam's writer with the delay
    with PingFile(write_ping_file(dataset_from_pings([p]), tmp_path / "again.nc")) as f:
        assert f.ping(0).pulse.delay_s == pytest.approx(-pad / fs)
