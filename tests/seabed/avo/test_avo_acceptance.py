"""Acceptance: a simulated line over two sediment provinces, imaged, through ``clbeam avo``.

Scene ``avo2``: 40 pings 8.23 m apart, 230 m of water, medium sand (Mz 1.5)
up to 160 m along the track and medium silt (Mz 6) after it, seabed
scattering from the TR 9407 model at the band centre.  The simulated pings
are imaged (0.5 m x 0.5 deg, ±75 deg, 500 m), the angular responses are
extracted and stacked 20 pings per patch (pings 0-19 lie over the sand,
20-39 over the silt), and the patches are inverted.
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


def _model_a(mz):
    return angular_attributes(INC, backscatter_strength_db(90.0 - INC, FREQ_HZ, mz=mz)).intercept_a_db


def avo(argv):
    """``clbeam avo ARGV`` through the command line's parser."""
    from clbeam.cli.main import build_parser

    args = build_parser().parse_args(["avo", *argv])
    return args.func(args)


def test_two_provinces_separate_in_the_attributes_at_the_right_place(tmp_path):
    from clbeam.cli.main import main
    from clbeam.io.pingwrite import write_ping_file
    from clbeam.sim import load_scene, simulate

    ds = simulate(load_scene("avo2"))
    truth_mz = np.asarray(ds["truth_province_mz"].values)
    pings = write_ping_file(ds, tmp_path / "pings.nc")
    images = tmp_path / "img.nc"
    assert main(["image", str(pings), "-o", str(images), "--range-res", "0.5", "--angle-res", "0.5",
                 "--angles", "-75", "75", "--max-range", "500", "-q"]) == 0
    # first pass uncalibrated: the strengths carry the unknown source level and gains
    out = tmp_path / "avo.csv"
    assert avo([str(images), "-o", str(out), "--pings-per-patch", "20", "--absorption", "0",
                 "--figures", str(tmp_path / "figs"), "-q"]) == 0
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["ping_start"], r["ping_stop"]) for r in rows] == [("0", "20")] * 2 + [("20", "40")] * 2
    along = np.array([float(r["along_track_m"]) for r in rows])
    a = np.array([float(r["intercept_a_db"]) for r in rows])
    # patches at the right place: the mean position of pings 0-19 and 20-39
    step = 8.23
    assert along == pytest.approx([9.5 * step] * 2 + [29.5 * step] * 2, rel=0.01)
    assert np.all(truth_mz[:20] == 1.5) and np.all(truth_mz[20:] == 6.0)
    # attributes: the intercept A falls from sand to silt by the model's difference
    d_model = _model_a(1.5) - _model_a(6.0)
    d_meas = a[:2].mean() - a[2:].mean()
    print(f"A sand {a[:2]}, silt {a[2:]}; drop {d_meas:.2f} dB (model {d_model:.2f} dB)")
    # The provinces separate by three standard deviations of the patches' own noise:
    # the port/starboard spread |a0 - a1| of a province estimates sigma * sqrt(2), and
    # the drop (a mean of two patches minus a mean of two) has standard deviation sigma,
    # so drop > 3 sigma is drop > 3 spread / sqrt(2).  (Accurate imaging -- Lanczos-8
    # on 2x upsampled data, cubic on 4x, the default -- gives A sand 16.25/15.17 dB,
    # silt 12.48/13.10 dB: drop 2.92 dB, spread 1.08 dB.)  Its size is smaller than the
    # model's over 0-85 degrees: the 230 m water column limits the swath to about
    # 62 degrees of incidence, and the near-nadir bins, which carry most of the
    # model's difference, are dominated by the specular echo common to both
    # provinces.  That gap is an open item of the AVO module, not hidden here.
    spread = max(abs(a[0] - a[1]), abs(a[2] - a[3]), 0.3)
    assert d_meas > 3 * spread / np.sqrt(2)
    assert 0 < d_meas < d_model
    assert min(a[:2]) > max(a[2:])
    # Inverted grain size is not asserted: the image strengths carry an unknown
    # constant (source level, array and processing gains) and uncalibrated
    # inversions pin at the grain-size bound; calibration is an open item.
