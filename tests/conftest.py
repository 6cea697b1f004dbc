"""Shared fixtures: one OpenCL engine and one reference engine per session."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))


@pytest.fixture(scope="session")
def cl_engine():
    """The OpenCL engine on the default device (PoCL in CI): never skipped."""
    from clbeam.imaging.engine import get_engine

    return get_engine("opencl")


@pytest.fixture(scope="session")
def ref_engine():
    """The float64 NumPy reference engine."""
    from clbeam.imaging.engine import get_engine

    return get_engine("reference")
