"""``clbeam avo``: table columns, figures, one-line errors, two provinces on synthetic images."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from test_avo_response import northward_track, seabed_ping, write_image_file

from clbeam.cli.main import build_parser
from clbeam.errors import ClbeamError
from clbeam.seabed.avo.model import backscatter_strength_db
from clbeam.seabed.avo.table import COLUMNS

ANG = np.arange(-70.0, 70.01, 1.0)
RNG = np.arange(0.0, 310.0, 0.5)
SPACING_M = 2.0


def run(argv):
    """Parse ``clbeam avo ARGV`` with the command line's parser and run it."""
    args = build_parser().parse_args(["avo", *argv])
    return args.func(args)


@pytest.fixture(scope="module")
def two_provinces(tmp_path_factory):
    """40 pings, 2 m apart: Mz 1.5 (medium sand) for 20, then Mz 6 (silt); speckled."""
    rng = np.random.default_rng(3)
    mz = np.where(np.arange(40) < 20, 1.5, 6.0)
    data = np.array([seabed_ping(ANG, RNG, lambda i, z=z: backscatter_strength_db(90.0 - i, 5500.0, mz=z),
                                 gain=1e-3, rng=rng) for z in mz]).astype(np.float32)
    lat, lon = northward_track(40, SPACING_M)
    return write_image_file(tmp_path_factory.mktemp("avo") / "img.nc", data, ANG, RNG, latitude=lat, longitude=lon)


def test_cli_writes_the_table_and_figures_and_separates_the_provinces(two_provinces, tmp_path, capsys):
    out = tmp_path / "avo.csv"
    figs = tmp_path / "figs"
    # gain 1e-3 of the synthetic images = -30 dB: calibrated strengths
    assert run([str(two_provinces), "-o", str(out), "--pings-per-patch", "20", "--calibration-db", "30",
                "--figures", str(figs)]) == 0
    said = capsys.readouterr().out
    assert "40 ping(s) -> 4 patches" in said and "calibration +30.0 dB (--calibration-db)" in said
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert {(r["calibration_source"], r["calibration_db"], r["inversion"]) for r in rows} == {
        ("option", "30.0", "response")}
    assert tuple(rows[0].keys()) == COLUMNS
    assert [(r["side"], r["ping_start"], r["ping_stop"]) for r in rows] == [
        ("port", "0", "20"), ("starboard", "0", "20"), ("port", "20", "40"), ("starboard", "20", "40")]
    # patch centres: mean of pings 0-19 and 20-39 at 2 m spacing
    assert [float(r["along_track_m"]) for r in rows] == pytest.approx([19, 19, 59, 59], abs=1e-3)
    mz = np.array([float(r["mz_phi"]) for r in rows])
    a = np.array([float(r["intercept_a_db"]) for r in rows])
    # sand inverts coarse, silt fine; 20 speckled pings leave about 0.3-0.5 dB per bin
    assert np.all(mz[:2] < 3.0) and np.all(mz[2:] > 4.5), mz
    # the model's intercept A: sand about 6 dB above silt at 5.5 kHz (noise-free: see below)
    inc = np.arange(0.5, 85.0, 1.0)
    from clbeam.seabed.avo.attributes import angular_attributes
    a_true = [angular_attributes(inc, backscatter_strength_db(90 - inc, 5500.0, mz=z)).intercept_a_db
              for z in (1.5, 6.0)]
    assert a[:2] == pytest.approx([a_true[0]] * 2, abs=1.0)
    assert a[2:] == pytest.approx([a_true[1]] * 2, abs=1.0)
    for name in ("avo_response_first.png", "avo_response_last.png", "avo_gradient_intercept.png", "avo_track.png"):
        assert (figs / name).stat().st_size > 10_000, name


def test_partial_patch_and_no_inversion(two_provinces, tmp_path):
    out = tmp_path / "avo.csv"
    assert run([str(two_provinces), "-o", str(out), "--pings-per-patch", "30", "--no-invert", "-q"]) == 0
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    # 40 pings, 30 per patch: one full and one partial patch per side
    assert [(r["ping_start"], r["ping_stop"]) for r in rows] == [("0", "30"), ("0", "30"), ("30", "40"), ("30", "40")]
    assert all(r["mz_phi"] == "nan" for r in rows)


def test_bad_inputs_are_one_line_errors(tmp_path, two_provinces):
    import xarray as xr

    other = tmp_path / "x.nc"
    xr.Dataset({"a": ("x", np.zeros(3))}).to_netcdf(other, engine="h5netcdf")
    with pytest.raises(ClbeamError, match="not a clbeam image file") as e:
        run([str(other), "-o", str(tmp_path / "a.csv")])
    assert "\n" not in str(e.value)
    with pytest.raises(ClbeamError, match="does not exist"):
        run([str(two_provinces), "-o", str(tmp_path / "nope" / "a.csv")])
    with pytest.raises(ClbeamError, match="pings-per-patch"):
        run([str(two_provinces), "-o", str(tmp_path / "a.csv"), "--pings-per-patch", "0"])
    with pytest.raises(ClbeamError, match="frequency_hz"):
        run([str(two_provinces), "-o", str(tmp_path / "a.csv"), "--frequency", "-5"])


def flat_mud_line(tmp_path, max_range_m: float):
    """Eight pings of Line 1 without pipelines or slope, recorded to ``max_range_m``, and their images."""
    import tomllib
    from importlib.resources import files

    from clbeam.cli.main import main
    from clbeam.io.pingwrite import write_ping_file
    from clbeam.sim import simulate
    from clbeam.sim.catalog import scene_from_mapping

    d = tomllib.loads((files("clbeam.sim.scenes") / "line1.toml").read_text())
    d["target"] = []
    d["seabed"]["slope_across_deg"] = 0.0
    d["record"]["max_range_m"] = max_range_m
    d["survey"]["pings"] = 8
    pings = write_ping_file(simulate(scene_from_mapping(d, name="flat")), tmp_path / "pings.nc")
    images = tmp_path / "img.nc"
    assert main(["image", str(pings), "-o", str(images), "--range-res", "0.5", "--angle-res", "0.5",
                 "--angles", "-75", "75", "--max-range", str(max_range_m), "-q"]) == 0
    return pings, images


def test_pings_add_each_patchs_nadir_reflection_coefficient_the_closed_form(tmp_path):
    """``--pings``: the patches of a simulated line over a flat mud seabed (Line 1's, without pipelines or
    slope) carry the seabed's normal-incidence reflection coefficient from the nadir echo and its surface
    multiple, within 5 % of the closed form (m - n) / (m + n) = 0.1011, with a finite standard error; and
    the calibration its primary gives within 1 dB of the simulator's: its replica has amplitude 1 at 1 m
    (G = 1) and the image sums 64 channels, -20 log10(64) = -36.12 dB."""
    pings, images = flat_mud_line(tmp_path, 500.0)
    out = tmp_path / "avo.csv"
    assert run([str(images), "-o", str(out), "--pings-per-patch", "4", "--no-invert", "--pings", str(pings),
                "-q"]) == 0
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0].keys()) == COLUMNS and len(rows) == 4
    r_closed = (1.25 - 1 / 0.98) / (1.25 + 1 / 0.98)
    for r in rows:
        assert float(r["nadir_reflection"]) == pytest.approx(r_closed, rel=0.05)
        assert 0 < float(r["nadir_reflection_error"]) < 0.05 * r_closed
        assert float(r["nadir_calibration_db"]) == pytest.approx(-20 * np.log10(64), abs=1.0)
        assert 0 < float(r["nadir_calibration_error_db"]) < 1.0
        # the survey's calibration is the patches' combined, applied to the strengths
        assert r["calibration_source"] == "nadir" and r["inversion"] == "none"
        assert float(r["calibration_db"]) == pytest.approx(-20 * np.log10(64), abs=1.0)
    # the ping file beside the images is found by default: the same table without --pings
    found = tmp_path / "found.csv"
    assert run([str(images), "-o", str(found), "--pings-per-patch", "4", "--no-invert", "-q"]) == 0
    assert found.read_text() == out.read_text()
    # the same strengths uncalibrated: every attribute moves by the applied calibration
    plain = tmp_path / "plain.csv"
    assert run([str(images), "-o", str(plain), "--pings-per-patch", "4", "--no-invert", "--no-nadir", "-q"]) == 0
    with plain.open() as fh:
        rel = list(csv.DictReader(fh))
    assert all(x["calibration_source"] == "none" for x in rel)
    for a, b in zip(rows, rel):
        assert float(a["near_mean_db"]) - float(b["near_mean_db"]) == pytest.approx(float(a["calibration_db"]))


def test_the_nadir_calibration_is_not_applied_to_images_it_does_not_fit(tmp_path, caplog):
    """Images made with Hann weights sum the channels with a smaller gain than -20 log10(M G) assumes: the nadir
    coefficient is reported, the calibration is not applied, and a warning says why."""
    import logging

    from clbeam.cli.main import main

    pings, _ = flat_mud_line(tmp_path, 500.0)
    hann = tmp_path / "hann.nc"
    assert main(["image", str(pings), "-o", str(hann), "--range-res", "0.5", "--angle-res", "0.5",
                 "--angles", "-75", "75", "--max-range", "500", "--apodization", "hann", "-q"]) == 0
    out = tmp_path / "avo.csv"
    with caplog.at_level(logging.WARNING):
        assert run([str(hann), "-o", str(out), "--pings-per-patch", "4", "--no-invert", "-q"]) == 0
    assert "apodization hann" in caplog.text and "not applied" in caplog.text
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert all(r["calibration_source"] == "none" and float(r["calibration_db"]) == 0.0 for r in rows)
    assert all(float(r["nadir_reflection"]) == pytest.approx(0.1011, rel=0.05) for r in rows)


def test_a_record_too_short_for_the_multiple_falls_back_to_relative_strengths(tmp_path, caplog):
    """Recorded to 400 m, the multiple (455 m) is beyond every ping's end: no coefficient, a warning, the
    strengths stay relative and the inversion fits the response alone."""
    import logging

    pings, images = flat_mud_line(tmp_path, 400.0)
    out = tmp_path / "avo.csv"
    with caplog.at_level(logging.WARNING):
        assert run([str(images), "-o", str(out), "--pings-per-patch", "4", "-q"]) == 0
    assert "no patch gave a nadir calibration" in caplog.text
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert all(r["nadir_reflection"] == "nan" and r["calibration_source"] == "none" for r in rows)
    assert {r["inversion"] for r in rows} == {"response"}
    with pytest.raises(ClbeamError, match="contradict"):
        run([str(images), "-o", str(out), "--pings", str(pings), "--no-nadir"])
