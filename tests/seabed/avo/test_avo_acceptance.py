"""Acceptance: simulated lines over sediment provinces, imaged, through ``clbeam avo --pings``.

Scene ``avo2``: 40 pings 8.23 m apart, 230 m of water, medium sand (Mz 1.5)
up to 160 m along the track and medium silt (Mz 6) after it; scene ``avo3``:
60 pings over coarse sand (Mz 1), fine sand (Mz 3) and coarse silt (Mz 5),
20 pings each.  Seabed scattering follows the TR 9407 model at the band
centre, and the nadir echo and its surface multiple reflect with each
province's impedance.  The simulated pings are imaged (0.5 m x 0.5 deg,
±75 deg, 500 m), the angular responses extracted and stacked 20 pings per
patch, and each patch's nadir echoes give its reflection coefficient and
the survey's calibration; the inversion never sees the simulator's source
level (its replica has amplitude 1 at 1 m and the image sums 64 channels:
the true calibration is -20 log10(64) = -36.12 dB).
"""

from __future__ import annotations

import csv

import numpy as np
import pytest

from clbeam.seabed.avo.attributes import angular_attributes
from clbeam.seabed.avo.model import backscatter_strength_db

pytestmark = pytest.mark.slow

FREQ_HZ = 5500.0
INC = np.arange(0.5, 85.0, 1.0)
TRUE_CALIBRATION_DB = -20 * np.log10(64)


def _model_a(mz):
    return angular_attributes(INC, backscatter_strength_db(90.0 - INC, FREQ_HZ, mz=mz)).intercept_a_db


def avo_table(scene: str, tmp_path, *extra):
    """Simulate ``scene``, image it, run ``clbeam avo --pings``; the table's rows and the truth per ping."""
    from clbeam.cli.main import build_parser, main
    from clbeam.io.pingwrite import write_ping_file
    from clbeam.sim import load_scene, simulate

    ds = simulate(load_scene(scene))
    truth = {k: np.asarray(ds[f"truth_{k}"].values) for k in ("province_mz", "nadir_reflection")}
    pings = write_ping_file(ds, tmp_path / "pings.nc")
    images = tmp_path / "img.nc"
    assert main(["image", str(pings), "-o", str(images), "--range-res", "0.5", "--angle-res", "0.5",
                 "--angles", "-75", "75", "--max-range", "500", "-q"]) == 0
    out = tmp_path / "avo.csv"
    args = build_parser().parse_args(["avo", str(images), "-o", str(out), "--pings-per-patch", "20",
                                      "--absorption", "0", "--pings", str(pings), "-q", *extra])
    assert args.func(args) == 0
    with out.open() as fh:
        return list(csv.DictReader(fh)), truth


def column(rows, name):
    return np.array([float(r[name]) for r in rows])


def test_two_provinces_separate_in_the_attributes_and_invert_to_their_grain_sizes(tmp_path):
    rows, truth = avo_table("avo2", tmp_path, "--figures", str(tmp_path / "figs"))
    assert [(r["ping_start"], r["ping_stop"]) for r in rows] == [("0", "20")] * 2 + [("20", "40")] * 2
    along = column(rows, "along_track_m")
    a = column(rows, "intercept_a_db")
    # patches at the right place: the mean position of pings 0-19 and 20-39
    step = 8.23
    assert along == pytest.approx([9.5 * step] * 2 + [29.5 * step] * 2, rel=0.01)
    assert np.all(truth["province_mz"][:20] == 1.5) and np.all(truth["province_mz"][20:] == 6.0)
    # attributes: the intercept A falls from sand to silt by the model's difference
    d_model = _model_a(1.5) - _model_a(6.0)
    d_meas = a[:2].mean() - a[2:].mean()
    print(f"A sand {a[:2]}, silt {a[2:]}; drop {d_meas:.2f} dB (model {d_model:.2f} dB)")
    # The provinces separate by three standard deviations of the patches' own noise:
    # the port/starboard spread |a0 - a1| of a province estimates sigma * sqrt(2), and
    # the drop (a mean of two patches minus a mean of two) has standard deviation sigma,
    # so drop > 3 sigma is drop > 3 spread / sqrt(2).  Its size is smaller than the
    # model's over 0-85 degrees: the 230 m water column limits the swath to about
    # 62 degrees of incidence, and the near-nadir bins, which carry most of the
    # model's difference, are dominated by the specular echo.
    spread = max(abs(a[0] - a[1]), abs(a[2] - a[3]), 0.3)
    assert d_meas > 3 * spread / np.sqrt(2)
    assert 0 < d_meas < d_model
    assert min(a[:2]) > max(a[2:])
    # self-calibrated: the constant from the nadir echoes, and the grain size of both provinces
    assert {r["calibration_source"] for r in rows} == {"nadir"}
    assert column(rows, "calibration_db") == pytest.approx([TRUE_CALIBRATION_DB] * 4, abs=1.0)
    mz = column(rows, "mz_phi")
    print(f"Mz {mz}, R {column(rows, 'nadir_reflection')} (truth {truth['nadir_reflection'][[0, 20]]})")
    assert {r["inversion"] for r in rows} == {"joint"}
    assert mz == pytest.approx([1.5, 1.5, 6.0, 6.0], abs=1.0)
    assert (tmp_path / "figs" / "avo_nadir.png").stat().st_size > 10_000


def test_three_provinces_meet_the_self_calibration_targets(tmp_path):
    """Every 20-ping patch: Mz within 1 phi of the truth, nadir R within 10 %, calibration within 1 dB."""
    rows, truth = avo_table("avo3", tmp_path)
    start = np.array([int(r["ping_start"]) for r in rows])
    true_mz, true_r = truth["province_mz"][start], truth["nadir_reflection"][start]
    assert sorted(set(true_mz)) == [1.0, 3.0, 5.0]
    mz, r = column(rows, "mz_phi"), column(rows, "nadir_reflection")
    print(f"Mz {mz} (truth {true_mz}); R {r} (truth {true_r}); calibration {rows[0]['calibration_db']}")
    assert np.all(np.abs(mz - true_mz) <= 1.0)
    assert np.all(np.abs(r / true_r - 1) <= 0.10)
    assert column(rows, "calibration_db") == pytest.approx([TRUE_CALIBRATION_DB] * len(rows), abs=1.0)
    # each patch's own calibration, before the survey combines them, within its error of the truth's 3 sigma
    own, err = column(rows, "nadir_calibration_db"), column(rows, "nadir_calibration_error_db")
    assert np.all(np.abs(own - TRUE_CALIBRATION_DB) <= 3 * err)
