"""The engine owns what makes it correct, and refuses what it cannot honour:
amplitude normalisation inside ``engine.beamform`` (a server calling the engine
directly gets it), and one-line errors for a precision, device or backend an
engine or an Imager cannot take."""

from __future__ import annotations

import numpy as np
import pytest
from scenes import random_input

from clbeam.errors import OptionError
from clbeam.imaging.engine import BeamformInput, get_engine
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.model.grid import PolarGrid

GRID = PolarGrid.regular(range_res_m=0.37, angle_res_deg=1.3, max_range_m=60.0, angles_deg=(-75, 75))


@pytest.mark.parametrize("scale", [2.0**-110, 3e-33, 1e31])
def test_engine_called_directly_images_extreme_amplitudes(cl_engine, ref_engine, scale):
    """1e-33 and 1e31 amplitudes would under- and overflow float32 sums of |S|^2 (1e-66, 1e62):
    the engine images them as the float64 reference does, in the data's units."""
    inp = random_input(seed=3)
    loud = BeamformInput(inp.data * scale, inp.sample_rate_hz, inp.t0_s, inp.sound_speed_m_s,
                         inp.element_offsets_m, inp.source_offset_m, centre_frequency_hz=inp.centre_frequency_hz)
    got = cl_engine.beamform(loud, GRID, interp="cubic", outputs=("intensity", "cf", "sums"))
    ref = ref_engine.beamform(inp, GRID, interp="cubic", outputs=("intensity", "cf", "sums"))
    top = ref.intensity.max()
    # float32 arithmetic of the unscaled data: within 1e-4 of the peak (test_engine's float32 bound is tighter per mode)
    np.testing.assert_allclose(got.intensity / scale**2, ref.intensity, atol=1e-4 * top)
    np.testing.assert_allclose(got.q / scale**2, ref.q, atol=1e-4 * ref.q.max())
    np.testing.assert_allclose(got.s / scale, ref.s, atol=1e-2 * np.sqrt(top))
    np.testing.assert_allclose(got.cf, ref.cf, atol=1e-4)
    assert got.s.dtype == np.complex128 and got.q.dtype == np.float64


def test_reference_engine_refuses_float32_and_a_device():
    with pytest.raises(OptionError, match="float64 only"):
        get_engine("reference", precision="float32")
    with pytest.raises(OptionError, match="runs on the CPU"):
        get_engine("reference", device=0)
    assert get_engine("reference", precision="float64").precision == "float64"


def test_imager_refuses_options_its_engine_cannot_honour(cl_engine, ref_engine):
    with pytest.raises(OptionError, match="precision 'float32' differs from the engine's 'float64'"):
        Imager(GRID, ImagingOptions(precision="float32"), engine=ref_engine)
    with pytest.raises(OptionError, match="backend 'reference' differs"):
        Imager(GRID, engine=cl_engine, backend="reference")
    with pytest.raises(OptionError, match="not both"):
        Imager(GRID, engine=cl_engine, device=0)
    with pytest.raises(OptionError, match="reference backend only"):
        Imager(GRID, ImagingOptions(interp="exact"), engine=cl_engine)
    assert Imager(GRID, engine=ref_engine).engine is ref_engine  # precision None: the engine's own


def test_a_data_token_reuses_the_upload_only_for_its_own_data(cl_engine, ref_engine):
    """Calls with one token share the device copy (same results as the reference); a call with
    other data (another token, or none) uploads its own, and the token's data come back after it."""
    import dataclasses

    a, b = random_input(seed=4), random_input(seed=5)
    token = object()
    a_tok = dataclasses.replace(a, data_token=token)
    want_a = ref_engine.beamform(a, GRID, interp="cubic", outputs=("intensity",)).intensity
    want_b = ref_engine.beamform(b, GRID, interp="cubic", outputs=("intensity",)).intensity
    top = want_a.max()
    for inp, want in ((a_tok, want_a), (a_tok, want_a), (b, want_b), (a_tok, want_a),
                      (dataclasses.replace(b, data_token=object()), want_b)):
        got = cl_engine.beamform(inp, GRID, interp="cubic", outputs=("intensity",)).intensity
        np.testing.assert_allclose(got, want, atol=1e-4 * top)
