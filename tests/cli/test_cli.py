"""The clbeam command (docs/cli.md): contract names, outputs, one-line errors."""

import subprocess
import sys

import numpy as np
import pytest
import xarray as xr
from scenes import dataset
from scipy.ndimage import correlate1d

from clbeam.cli.main import main
from clbeam.io.peaks import PEAK_CSV_COLUMNS, read_peaks_csv

TARGETS = [(40 + 5 * i, 10.0 * i) for i in range(3)]  # (range m, angle deg) of dataset()'s pings


@pytest.fixture(scope="module")
def ping_file(tmp_path_factory):
    ds, _ = dataset()
    path = tmp_path_factory.mktemp("cli") / "pings.nc"
    ds.to_netcdf(path)  # written by plain xarray, as another program would
    return path


def test_image_writes_the_spec_variables_and_finds_each_scatterer(ping_file, tmp_path):
    out, peaks = tmp_path / "img.nc", tmp_path / "peaks.csv"
    rc = main(["image", str(ping_file), "-o", str(out), "--peaks", str(peaks), "--max-range", "55",
               "--min-range", "30", "--angles", "-5", "25", "--interp", "cubic", "-q"])
    assert rc == 0
    ds = xr.open_dataset(out)
    for v in ("intensity", "cf"):
        assert ds[v].dims == ("ping", "angle", "range")
    assert ds["range"].attrs["units"] == "m" and ds["angle"].attrs["units"] == "degree"
    np.testing.assert_allclose(ds["range"].values[[0, -1]], [30, 55])
    for i, (r, a) in enumerate(TARGETS):
        inten = ds["intensity"].isel(ping=i)
        best = inten.where(inten == inten.max(), drop=True)
        assert float(best["range"].values[0]) == pytest.approx(r, abs=1e-6)
        assert float(best["angle"].values[0]) == pytest.approx(a, abs=0.1 + 1e-6)
        assert float(ds["cf"].isel(ping=i).sel(range=r, angle=a, method="nearest")) > 0.99
    rows = read_peaks_csv(peaks)
    assert {"ping", "range_m", "angle_deg", "y_m", "z_m", "cf", "intensity_db", "ping_latitude_deg",
            "depth_m"} <= set(rows[0])
    assert peaks.read_text().splitlines()[0].startswith(",".join(PEAK_CSV_COLUMNS) + ",")  # then the cell_* columns
    assert "cf_smooth" not in ds  # derivable from cf: written on request
    ds.close()


def test_frequency_domain_beams_from_the_command_line_hold_the_budget_against_direct_imaging(ping_file, tmp_path):
    """``--beams 2:16:frequency`` images with beams formed on the channels' spectra (the file's setting says so)
    and gives the image of every cell imaged directly with Lanczos-8 (-70 dB) within the default budget:
    intensity -40 dB, |dCF| 0.02 on cells within 40 dB."""
    from clbeam.imaging.budget import intensity_error_db

    common = ["--max-range", "55", "--min-range", "30", "--angles", "-5", "25", "-q"]
    fd, direct = tmp_path / "fd.nc", tmp_path / "direct.nc"
    assert main(["image", str(ping_file), "-o", str(fd), "--beams", "2:16:frequency", "--interp", "lanczos8"]
                + common) == 0
    assert main(["image", str(ping_file), "-o", str(direct), "--beams", "off", "--interp", "lanczos8"] + common) == 0
    with xr.open_dataset(fd) as a, xr.open_dataset(direct) as b:
        assert "in the frequency domain" in a.attrs["imaging_setting"]
        for i in range(a.sizes["ping"]):
            got, want = (ds["intensity"].isel(ping=i).values.astype(np.float64) for ds in (a, b))
            assert intensity_error_db(got, want, 40.0) <= -40.0
            keep = want >= want.max() * 1e-4
            assert np.max(np.abs(a["cf"].isel(ping=i).values[keep] - b["cf"].isel(ping=i).values[keep])) <= 0.02


def test_smoothed_cf_is_written_on_request_as_the_hann_smoothed_cf(ping_file, tmp_path):
    out = tmp_path / "img.nc"
    assert main(["image", str(ping_file), "-o", str(out), "--max-range", "55", "--min-range", "30",
                 "--angles", "-5", "25", "--outputs", "cf,cf_smooth", "-q"]) == 0
    with xr.open_dataset(out) as ds:
        assert "intensity" not in ds and {"cf", "cf_smooth"} <= set(ds)
        # scipy's correlation with the paper's 7-point Hann window, zeros beyond the grid
        want = correlate1d(ds["cf"].values.astype(np.float64), [0, 0.25, 0.75, 1, 0.75, 0.25, 0], axis=-1,
                           mode="constant") / 3
        np.testing.assert_allclose(ds["cf_smooth"].values, want, atol=1e-6)


def test_peaks_from_an_image_file_equal_those_written_while_imaging(ping_file, tmp_path):
    """Unrefined (grid-cell) peaks are the same from memory and from the file; refined ones come
    from those cells: their cell columns are file peaks, and the merged counts add up to them."""
    out, p1, p2, p3 = tmp_path / "img.zarr", tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "c.csv"
    # the gates off: the level gate judges a refined row by its refined intensity, a grid peak by its cell's,
    # and a refined row stands for grid peaks the clutter test would judge one by one
    gates = ["--min-snr-db", "off", "--min-contrast-db", "off"]
    grid_args = ["--max-range", "50", "--angles", "-20", "30", "--angle-res", "0.5", *gates, "-q"]
    assert main(["image", str(ping_file), "-o", str(out), "--peaks", str(p1), "--no-refine", *grid_args]) == 0
    assert main(["peaks", str(out), "-o", str(p2), *gates, "-q"]) == 0
    a, b = read_peaks_csv(p1), read_peaks_csv(p2)
    assert len(a) == len(b) > 0
    key = lambda r: (r["ping"], r["angle_deg"], r["range_m"])  # noqa: E731
    for ra, rb in zip(sorted(a, key=key), sorted(b, key=key)):
        assert key(ra) == key(rb)
        assert ra["cf"] == pytest.approx(rb["cf"], abs=1e-6)  # the file stores CF as float32
    assert main(["image", str(ping_file), "-o", str(tmp_path / "img2.zarr"), "--peaks", str(p3), *grid_args]) == 0
    refined = read_peaks_csv(p3)
    cells = {key(r) for r in b}
    assert all((r["ping"], r["cell_angle_deg"], r["cell_range_m"]) in cells for r in refined)
    assert sum(r["cell_peaks"] for r in refined) == len(b)


def test_reference_backend_gives_the_same_image(ping_file, tmp_path):
    args = ["--max-range", "50", "--min-range", "35", "--angles", "-5", "5", "--interp", "linear", "-q"]
    assert main(["image", str(ping_file), "-o", str(tmp_path / "a.nc"), *args]) == 0
    assert main(["image", str(ping_file), "-o", str(tmp_path / "b.nc"), "--backend", "reference", *args]) == 0
    a, b = xr.open_dataset(tmp_path / "a.nc"), xr.open_dataset(tmp_path / "b.nc")
    rel = float(np.linalg.norm(a["intensity"] - b["intensity"]) / np.linalg.norm(b["intensity"]))
    assert rel < 1e-4  # float32 kernel against float64 (see test_engine's bound)
    a.close(), b.close()


@pytest.mark.parametrize("argv, message", [
    (["image", "missing.nc", "-o", "x.nc"], "missing.nc: no such file"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--range-res", "0"], "range resolution must be > 0"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--outputs", "intensity,colour"], "output 'colour' is unknown"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--outputs", "cf,cf_smoth"], "expected some of intensity, cf, sums, cf_smooth"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--interp", "exact"], "reference backend only"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--device", "no-such-gpu"], "no OpenCL device matches"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--sound-speed", "900"], "within 1300-1700"),
    (["peaks", "{pings}", "-o", "{tmp}/p.csv"], "not a clbeam image file"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--threshold", "2"], "threshold must be within 0-1"),
    (["image", "{pings}", "-o", "{pings}"], "is the input file"),
    (["image", "{pings}", "-o", "{tmp}"], "is an existing folder"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--range-res", "1e-7"], "exceeds 2e+09 cells"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--max-error-db", "3"], "must be a negative number of dB"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--max-error-db", "-100"], "no setting reaches -100 dB"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--beams", "wide"], "--beams must be auto, off or K[:TAPS[:DOMAIN]]"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--beams", "2:16:fourier"], "beam domain must be 'time' or 'frequency'"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--beams", "0.5:8"], "beam oversampling must be within 1-16"),
    (["image", "{pings}", "-o", "{tmp}/x.nc", "--beams", "1.5:7"], "beam taps must be an even integer"),
])
def test_bad_input_exits_2_with_one_line(ping_file, tmp_path, capsys, argv, message):
    argv = [a.format(pings=ping_file, tmp=tmp_path) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("clbeam: error:") and message in err and "\n" not in err


def test_installed_command_runs_devices_and_help():
    r = subprocess.run([sys.executable, "-m", "clbeam.cli", "devices"], capture_output=True, text=True)
    assert r.returncode == 0 and "platform:" in r.stdout
    r = subprocess.run([sys.executable, "-m", "clbeam.cli", "image", "--help"], capture_output=True, text=True)
    assert r.returncode == 0
    for opt in ("--range-res", "--angle-res", "--max-range", "--angles", "--interp", "--outputs", "--backend", "--device"):
        assert opt in r.stdout
    from clbeam.imaging.engine import INTERP_MODES

    assert "{auto," + ",".join(INTERP_MODES) + "}" in r.stdout  # the modes as a choice list (docs/cli.md)


def test_peaks_mlh_from_an_image_file_equal_those_written_while_imaging(ping_file, tmp_path):
    """``clbeam peaks --mlh`` rebuilds each ping's context (source with roll, sonar) from the file:
    the merged detections equal those ``clbeam image --mlh`` made from the pings themselves."""
    out, p1, p2 = tmp_path / "img.nc", tmp_path / "a.csv", tmp_path / "b.csv"
    grid = ["--max-range", "50", "--angles", "-20", "30", "--angle-res", "0.5"]
    assert main(["image", str(ping_file), "-o", str(out), "--peaks", str(p1), *grid, "--mlh", "-q"]) == 0
    assert main(["peaks", str(out), "-o", str(p2), "--mlh", "-q"]) == 0
    a, b = read_peaks_csv(p1), read_peaks_csv(p2)
    assert len(a) == len(b) > 0 and {"n_merged", "arc_extent_deg"} <= set(b[0])
    key = lambda r: (r["ping"], round(r["angle_deg"], 6), round(r["range_m"], 6))  # noqa: E731
    for ra, rb in zip(sorted(a, key=key), sorted(b, key=key)):
        assert ra["n_merged"] == rb["n_merged"]
        assert ra["y_m"] == pytest.approx(rb["y_m"], abs=1e-4) and ra["z_m"] == pytest.approx(rb["z_m"], abs=1e-4)


def test_image_command_reaches_its_first_ping_without_xarray_or_dask(ping_file, tmp_path):
    """Start-up: the ping file and the image file are handled through h5py/h5netcdf alone (xarray,
    pandas and dask cost about a second of imports); the --debug line the bench times is there."""
    import time

    cmd = [sys.executable, "-X", "importtime", "-m", "clbeam", "--debug", "image", str(ping_file), "-o",
           str(tmp_path / "img.nc"), "--max-range", "55", "--min-range", "30", "--angles", "-5", "25", "-q"]
    t0 = time.time()
    run = subprocess.run(cmd, capture_output=True, text=True, check=True)
    before, marker, _ = run.stderr.partition("first ping's work starts at unix time ")
    assert marker
    started = float(_.split()[0])
    assert t0 < started < time.time()
    imported = {line.rsplit("|", 1)[-1].strip() for line in before.splitlines() if line.startswith("import time:")}
    assert "h5py" in imported and "pyopencl" in imported  # the parse is right
    assert not {"xarray", "pandas", "dask", "scipy.fft"} & imported
    assert xr.open_dataset(tmp_path / "img.nc")["cf"].shape[0] == 3
