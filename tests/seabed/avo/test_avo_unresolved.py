"""The AVO table flags a grain size the data do not set: relative strengths, or a fit stopped at a bound."""

import numpy as np
import pytest

from clbeam.seabed.avo.calibration import Calibration
from clbeam.seabed.avo.model import backscatter_strength_db
from clbeam.seabed.avo.sediment import MZ_MIN
from clbeam.seabed.avo.stack import stack_sides
from clbeam.seabed.avo.table import survey_records

INC = np.arange(0.0, 81.0, 1.0)
F_HZ = 5e3


def _patches(offset_db=(0.0, 0.0), mz=(2.5, 1.5)):
    """Two patches a side of noise-free sediments ``mz`` (phi, port and starboard), ``offset_db`` added to
    every strength of each side."""
    port, stbd = (np.tile(backscatter_strength_db(90 - INC, F_HZ, mz=z) + o, (40, 1)) for z, o in zip(mz, offset_db))
    return stack_sides(INC, port, stbd, pings_per_patch=20, along_track_m=np.arange(40) * 0.5)


def test_a_grain_size_from_relative_strengths_is_unresolved():
    rows = survey_records(_patches(), frequency_hz=F_HZ)  # no calibration: relative strengths
    assert rows and all(r.inversion == "response" and "mz" in r.unresolved.split(";") for r in rows)
    # the same strengths taken as absolute: the noise-free fine sand inverts to itself, resolved
    cal = Calibration(0.0, 0.5, "option")
    rows = survey_records(_patches(), frequency_hz=F_HZ, calibration=cal)
    assert [round(r.mz_phi, 3) for r in rows] == [2.5, 1.5, 2.5, 1.5]
    assert all("mz" not in r.unresolved.split(";") for r in rows)


def test_a_grain_size_stopped_at_the_inversions_bound_is_unresolved():
    """Strengths 15 dB above the coarsest sediment's: no grain size gives them, and the fit stops at the
    -1 phi bound (the issue's muddy seabed read as -1.0 phi, resolved)."""
    cal = Calibration(0.0, 0.5, "option")
    rows = survey_records(_patches((15.0, 18.0), mz=(MZ_MIN, MZ_MIN)), frequency_hz=F_HZ, calibration=cal)
    assert all(r.mz_phi == pytest.approx(MZ_MIN, abs=1e-3) for r in rows)
    assert all("mz" in r.unresolved.split(";") for r in rows)
