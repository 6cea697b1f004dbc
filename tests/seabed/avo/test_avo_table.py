"""Per-patch AVO table: survey chain and CSV round trip."""

import csv
import math

import numpy as np
import pytest

from clbeam.errors import OptionError
from clbeam.seabed.avo import attributes as at
from clbeam.seabed.avo.model import backscatter_strength_db
from clbeam.seabed.avo.stack import stack_sides
from clbeam.seabed.avo.table import COLUMNS, survey_records, write_csv

INC = np.arange(0.0, 81.0, 1.0)


def _survey(n_ping=90):
    # Port over fine sand then silt, starboard over medium sand, 3 patches each.
    mz_port = np.where(np.arange(n_ping) < 45, 2.5, 6.0)
    port = np.array([backscatter_strength_db(90 - INC, 5e3, mz=z) for z in mz_port])
    stbd = np.tile(backscatter_strength_db(90 - INC, 5e3, mz=1.5), (n_ping, 1))
    return stack_sides(INC, port, stbd, pings_per_patch=30, along_track_m=np.arange(n_ping) * 0.5)


def test_records_follow_the_attribute_functions_and_write_a_round_trip_csv(tmp_path):
    patches = _survey()
    rows = survey_records(patches, frequency_hz=5e3)
    assert [(r.side, r.ping_start, r.ping_stop) for r in rows] == [
        ("port", 0, 30), ("starboard", 0, 30), ("port", 30, 60), ("starboard", 30, 60),
        ("port", 60, 90), ("starboard", 60, 90)]
    a = np.array([r.intercept_a_db for r in rows])
    b = np.array([r.gradient_b_db for r in rows])
    g, d = at.background_trend(a, b)
    for r in rows:
        # Eq. 4 by hand from the row's own A, B and the survey trend.
        assert r.fluid_factor_db == pytest.approx((-g * r.intercept_a_db + r.gradient_b_db - d) / math.hypot(g, 1))
        assert r.product_db2 == pytest.approx(r.intercept_a_db * r.gradient_b_db)
    # Noise-free patches of one sediment invert to it (mixed patch 30-60
    # on port is 15 pings fine sand + 15 silt and is not checked).
    assert rows[0].mz_phi == pytest.approx(2.5, abs=1e-3)
    assert rows[1].mz_phi == pytest.approx(1.5, abs=1e-3)
    assert rows[4].mz_phi == pytest.approx(6.0, abs=1e-3)
    # Mean along-track position of pings 30..59 at 0.5 m spacing = 22.25 m.
    assert rows[2].along_track_m == pytest.approx(22.25)

    path = write_csv(tmp_path / "avo.csv", rows)
    with path.open() as fh:
        table = list(csv.reader(fh))
    assert tuple(table[0]) == COLUMNS
    assert len(table) == 1 + len(rows)
    for line, r in zip(table[1:], rows):
        for name, text in zip(COLUMNS, line):
            v = getattr(r, name)
            if isinstance(v, str):
                assert text == v
            elif isinstance(v, float) and math.isnan(v):
                assert text == "nan"
            else:
                assert float(text) == v  # repr round trip is exact


def test_records_without_inversion_leave_inversion_columns_nan():
    rows = survey_records(_survey(60), invert=False)
    assert all(math.isnan(r.mz_phi) and math.isnan(r.misfit_db) for r in rows)


def test_table_errors():
    patches = _survey(60)
    with pytest.raises(OptionError, match="at least 2 patches"):
        survey_records(patches[:1], frequency_hz=5e3)
    with pytest.raises(OptionError, match="frequency_hz"):
        survey_records(patches)
    with pytest.raises(OptionError, match="does not exist"):
        write_csv("/nonexistent-dir-for-avo/x.csv", [])
