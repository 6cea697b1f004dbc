"""TR 9407 grain-size regressions against the handbook's sediment table."""

import math

import pytest

from clbeam.errors import OptionError
from clbeam.seabed.avo import sediment as sd

# Handbook sediment table (reference notes): Mz, rho, nu, delta, w2 (cm^4).
TABLE = [
    ("coarse sand", 0.5, 2.2306, 1.2503, 0.01638, 0.006957),
    ("medium sand", 1.5, 1.8446, 1.1782, 0.01624, 0.004446),
    ("fine sand", 2.5, 1.4512, 1.1073, 0.01602, 0.002715),
    ("sandy silt", 5.0, 1.1689, 0.9999, 0.01261, None),
    ("silt / sandy mud", 6.0, 1.1487, 0.9873, 0.00386, None),
    ("clay", 9.0, 1.1448, 0.9800, 0.00148, None),
]


@pytest.mark.parametrize("name, mz, rho, nu, delta, w2", TABLE)
def test_regressions_reproduce_table_to_printed_decimals(name, mz, rho, nu, delta, w2):
    # Printed to 4 (rho, nu), 5 (delta) and 6 (w2) decimals: the regression
    # must round to the printed value, i.e. differ by at most half a unit of
    # the last printed place (plus float noise).
    s = sd.sediment_from_grain_size(mz)
    assert abs(s.rho - rho) <= 0.5e-4 + 1e-12
    assert abs(s.nu - nu) <= 0.5e-4 + 1e-12
    assert abs(s.delta - delta) <= 0.5e-5 + 1e-12
    if w2 is not None:
        assert abs(s.w2_cm4 - w2) <= 0.5e-6 + 1e-12


def test_loss_parameter_hand_computation_medium_sand():
    # Mz = 1.5: k_p = 0.4556 + 0.0245*1.5 = 0.49235 dB/m/kHz,
    # nu = 1.3425 - 0.1382798*1.5 + 0.0213937*2.25 - 0.0014881*3.375 = 1.178248...
    nu = 1.3425 - 0.1382798 * 1.5 + 0.0213937 * 2.25 - 0.0014881 * 3.375
    delta = 0.49235 * nu * 1528 * math.log(10) / (40000 * math.pi)
    assert sd.attenuation_db_per_m_khz(1.5) == pytest.approx(0.49235, abs=1e-12)
    assert sd.loss_parameter(1.5) == pytest.approx(delta, rel=1e-12)


def test_w2_si_conversion_matches_notes_value():
    # Notes: medium sand w2 = 1.406e-4 m^(4 - gamma) (4 significant digits).
    s = sd.sediment_from_grain_size(1.5)
    assert s.w2_si == pytest.approx(1.406e-4, abs=0.5e-7)
    # By hand: 0.004445822 cm^4 * 1e-8 * 100^3.25 = 0.004445822 * 10^-1.5.
    assert s.w2_si == pytest.approx(0.0044458222521679 * 10 ** -1.5, rel=1e-9)


@pytest.mark.parametrize("mz_break, f", [(1.0, sd.density_ratio), (5.3, sd.density_ratio),
                                         (1.0, sd.sound_speed_ratio), (5.3, sd.sound_speed_ratio)])
def test_regression_branches_meet_at_breakpoints(mz_break, f):
    # The published pieces join to within the precision of their
    # coefficients (~1e-4): a typo in a coefficient would open a gap.
    eps = 1e-9
    assert abs(f(mz_break - eps) - f(mz_break)) < 2e-4


def test_volume_parameter_step_and_gamma():
    assert sd.volume_parameter(5.4) == 0.002
    assert sd.volume_parameter(5.5) == 0.001
    assert sd.sediment_from_grain_size(3.0).gamma == 3.25


def test_named_sediments_use_table_values_below_minus_one():
    rock = sd.sediment_named("Rock")
    assert (rock.rho, rock.nu, rock.delta) == (2.5, 2.5, 0.01374)
    assert rock.mz < -1
    assert sd.sediment_named("medium sand").rho == pytest.approx(sd.density_ratio(1.5))


@pytest.mark.parametrize("mz", [-1.5, 9.5, float("nan")])
def test_out_of_range_grain_size_raises_one_line_error(mz):
    with pytest.raises(OptionError, match="mz") as err:
        sd.sediment_from_grain_size(mz)
    assert "\n" not in str(err.value)


def test_invalid_parameters_raise():
    with pytest.raises(OptionError, match="delta"):
        sd.SedimentParams(rho=1.5, nu=1.1, delta=0.0, w2_cm4=0.001)
    with pytest.raises(OptionError, match="gamma"):
        sd.SedimentParams(rho=1.5, nu=1.1, delta=0.01, w2_cm4=0.001, gamma=4.0)
    with pytest.raises(OptionError, match="sediment name"):
        sd.sediment_named("moon dust")
