"""clbeam's water absorption and Rayleigh reflection coefficients against arlpy's (``arlpy.uwa``).

arlpy (ARL, National University of Singapore) implements the same physics
independently: Francois-Garrison absorption and the Brekhovskikh-Lysanov
reflection coefficient of a lossy fluid half-space, ``n = c / c1 (1 + i alpha)``
(TR 9407's ``kappa = (1 + i delta) / nu`` with ``alpha = delta``), angle from
the normal.  Its package metadata pins numpy < 2; ``scripts/bootstrap.sh``
installs it without its pins (``uwa`` is plain numpy and runs on numpy 2).
"""

from __future__ import annotations

import math

import arlpy.uwa as uwa
import numpy as np
import pytest

from clbeam.seabed.avo.model import reflection_coefficient
from clbeam.seabed.avo.response import francois_garrison_db_per_km
from clbeam.seabed.avo.sediment import sediment_from_grain_size
from clbeam.seabed.forward.reflection import rayleigh_reflection
from clbeam.sim.physics import reflection_coefficient as sim_reflection

RHO_W, C_W = 1000.0, 1500.0


@pytest.mark.parametrize("temperature_c", [2.0, 10.0, 25.0])
@pytest.mark.parametrize("depth_m", [0.0, 230.0, 2000.0])
def test_francois_garrison_absorption(temperature_c, depth_m):
    f = np.array([500.0, 2000.0, 5500.0, 9000.0, 50e3, 300e3])
    for salinity, ph in ((35.0, 8.0), (30.0, 7.8)):
        ours = francois_garrison_db_per_km(f, temperature_c=temperature_c, salinity_psu=salinity, depth_m=depth_m,
                                           ph=ph)
        theirs = -20 * np.log10(uwa.absorption(f, distance=1000.0, temperature=temperature_c, salinity=salinity,
                                               depth=depth_m, pH=ph))
        np.testing.assert_allclose(ours, theirs, rtol=1e-9)


@pytest.mark.parametrize("mz", [-0.5, 1.0, 3.0, 5.0, 7.0])
def test_lossy_half_space_reflection_of_the_avo_model(mz):
    """TR 9407 sediments of the AVO model (fast sands with a critical angle, slow silts), every grazing angle."""
    sed = sediment_from_grain_size(mz)
    grazing = np.array([1.0, 5.0, 15.0, 30.0, 45.0, 60.0, 89.0, 90.0])
    ours = reflection_coefficient(grazing, sed)
    theirs = np.array([complex(uwa.reflection_coeff(math.radians(90.0 - g), sed.rho * RHO_W, sed.nu * C_W,
                                                    alpha=sed.delta, rho=RHO_W, c=C_W)) for g in grazing])
    np.testing.assert_allclose(ours, theirs, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("density_ratio, speed_ratio", [(1.25, 0.98), (1.8, 0.99), (1.149, 0.987)])
def test_lossless_reflection_of_the_simulator_and_the_forward_model(density_ratio, speed_ratio):
    """The simulator's specular echoes (grazing angle) and the forward model's interfaces (incidence) against
    arlpy without loss; the nadir values are the closed form the nadir-echo tests use."""
    for incidence in (0.0, 10.0, 40.0, 75.0):
        theirs = uwa.reflection_coeff(math.radians(incidence), density_ratio * RHO_W, speed_ratio * C_W,
                                      rho=RHO_W, c=C_W)
        ours = sim_reflection(math.radians(90.0 - incidence), density_ratio, speed_ratio)
        assert float(ours) == pytest.approx(float(np.real(theirs)), rel=1e-9, abs=1e-12)
        fwd = rayleigh_reflection(RHO_W, C_W, density_ratio * RHO_W, speed_ratio * C_W, incidence)
        assert fwd == pytest.approx(complex(theirs), rel=1e-9, abs=1e-12)
