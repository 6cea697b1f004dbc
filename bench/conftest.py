"""Benchmark fixtures (pytest-benchmark): a paper-size ping built once."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))


@pytest.fixture(scope="session")
def paper_input():
    """Analytic band-limited data, 64 channels x 1.5 s at 40 kHz, SBP29 array."""
    from scenes import bandlimited_noise, sbp_elements

    from clbeam.imaging.engine import BeamformInput

    data = bandlimited_noise((64, 60000), seed=0)
    return BeamformInput(data, 40000.0, 0.0, 1500.0, sbp_elements(64), np.zeros(3), centre_frequency_hz=5500.0)


@pytest.fixture(scope="session")
def engine():
    from clbeam.imaging.engine import get_engine

    return get_engine("opencl")
