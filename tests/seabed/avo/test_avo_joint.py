"""Joint inversion of the nadir reflection coefficient and the calibrated response (clbeam.seabed.avo.joint),
and the survey's calibration from its patches (clbeam.seabed.avo.calibration).

Data are the TR 9407 model's own response and the closed-form normal-incidence coefficient
``(rho nu - 1) / (rho nu + 1)`` of the regressions' density and sound-speed ratios: the inversion must give
back the grain size that made them, the calibration offset it was given, and say when the data cannot
tell grain sizes apart (finer than about 5.5 phi the regressions' impedance and strengths barely change).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from clbeam.errors import OptionError
from clbeam.seabed.avo.calibration import SYSTEMATIC_ERROR_DB, survey_calibration
from clbeam.seabed.avo.joint import invert_joint, nadir_model_reflection
from clbeam.seabed.avo.model import backscatter_strength_db
from clbeam.seabed.avo.sediment import density_ratio, sound_speed_ratio

FREQ_HZ = 5500.0
INC = np.arange(0.5, 62.0, 1.0)  # a 230 m water column and a 500 m record: incidence to about 62 degrees


def closed_form_r(mz: float) -> float:
    z = density_ratio(mz) * sound_speed_ratio(mz)
    return (z - 1) / (z + 1)


@pytest.mark.parametrize("mz", [1.0, 3.0, 5.0])
def test_nadir_model_is_the_closed_form_within_the_sediments_loss(mz):
    assert nadir_model_reflection(mz) == pytest.approx(closed_form_r(mz), rel=0.01)


@pytest.mark.parametrize("mz", [0.5, 2.5, 4.5])
def test_model_data_give_back_their_grain_size(mz):
    s = backscatter_strength_db(90.0 - INC, FREQ_HZ, mz=mz)
    j = invert_joint(INC, s, FREQ_HZ, nadir_reflection=closed_form_r(mz), nadir_reflection_error=0.01)
    assert j.mz == pytest.approx(mz, abs=0.15)
    assert j.mz_low <= mz <= j.mz_high and "mz" not in j.unresolved
    assert abs(j.calibration_offset_db) < 0.3 and j.misfit_db < 0.3
    assert j.nadir_model_reflection == pytest.approx(closed_form_r(mz), rel=0.03)


def test_a_wrong_calibration_is_taken_up_by_the_offset_when_roughness_and_volume_follow_the_regressions():
    """Strengths 3 dB too high, said to be good to 3 dB: the nadir coefficient holds the grain size, and the
    fitted offset takes the 3 dB back."""
    mz = 2.0
    s = backscatter_strength_db(90.0 - INC, FREQ_HZ, mz=mz) + 3.0
    j = invert_joint(INC, s, FREQ_HZ, nadir_reflection=closed_form_r(mz), nadir_reflection_error=0.005,
                     calibration_error_db=3.0, fit_roughness=False, fit_volume=False)
    assert j.mz == pytest.approx(mz, abs=0.15)
    assert j.calibration_offset_db == pytest.approx(-3.0, abs=0.3)


def test_fine_sediments_are_flagged_unresolved_with_an_interval_that_holds_the_truth():
    mz = 7.0
    s = backscatter_strength_db(90.0 - INC, FREQ_HZ, mz=mz)
    j = invert_joint(INC, s, FREQ_HZ, nadir_reflection=closed_form_r(mz), nadir_reflection_error=0.004)
    assert "mz" in j.unresolved
    assert j.mz_low <= mz <= j.mz_high and j.mz_high - j.mz_low > 2.0
    assert j.mz_low > 5.0  # finer than coarse silt, that much it can say


@pytest.mark.parametrize("r", [0.0, 1.0, float("nan"), -0.2])
def test_bad_nadir_coefficients_are_refused_in_one_line(r):
    with pytest.raises(OptionError, match="nadir reflection coefficient"):
        invert_joint(INC, backscatter_strength_db(90.0 - INC, FREQ_HZ, mz=2.0), FREQ_HZ, nadir_reflection=r)


def test_too_few_bins_are_refused():
    with pytest.raises(OptionError, match="more data than"):
        invert_joint(INC[:14], np.full(14, -20.0), FREQ_HZ, nadir_reflection=0.2)  # all nearer than 15 degrees


def test_survey_calibration_is_the_inverse_variance_mean_with_the_floor():
    # two patches agreeing within their errors: weights 4 and 1, mean -35.8 dB, error sqrt(1/5) with the floor
    cal = survey_calibration([-36.0, -35.0, float("nan")], [0.5, 1.0, 0.2])
    assert cal.db == pytest.approx(-35.8) and cal.n_patches == 2 and cal.source == "nadir"
    assert cal.error_db == pytest.approx(math.hypot(math.sqrt(0.2), SYSTEMATIC_ERROR_DB))
    # two patches 2 dB apart with 0.3 dB errors: the scatter is 4.7 times what the errors allow (Birge ratio
    # sqrt((1/0.09) (1 + 1) / 1) = 4.71), so the mean's error 0.212 dB grows to 1.0 dB
    cal = survey_calibration([-36.0, -34.0], [0.3, 0.3])
    assert cal.db == pytest.approx(-35.0)
    assert cal.error_db == pytest.approx(math.hypot(1.0, SYSTEMATIC_ERROR_DB), rel=1e-9)
    assert survey_calibration([float("nan")], [1.0]) is None
    with pytest.raises(OptionError, match="one length"):
        survey_calibration([1.0, 2.0], [1.0])


def test_the_grain_size_interval_is_never_narrower_than_the_data_allow():
    """Off the 0.25-phi profile grid, noise-free data still get an interval about the truth with a width."""
    mz = 1.125
    s = backscatter_strength_db(90.0 - INC, FREQ_HZ, mz=mz)
    j = invert_joint(INC, s, FREQ_HZ, nadir_reflection=closed_form_r(mz), nadir_reflection_error=0.01)
    assert j.mz_low < mz < j.mz_high and 0.02 < j.mz_high - j.mz_low < 1.0
