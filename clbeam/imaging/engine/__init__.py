"""The imaging engine: one interface, two backends.

``backend="opencl"`` runs the kernels in ``kernels/`` on any OpenCL device;
``backend="reference"`` is the same maths in float64 NumPy, written for
clarity, the oracle of every test.  Both take a :class:`BeamformInput` (the
analytic channels and their earth-frame geometry) and a
:class:`~clbeam.model.grid.PolarGrid`, and return :class:`Sums`.
"""

from __future__ import annotations

from clbeam.imaging.engine.common import (
    INTERP_MODES,
    OUTPUTS,
    BeamformInput,
    InterpMode,
    Sums,
    interp_mode,
)


def get_engine(backend: str = "opencl", *, device=None, precision: str | None = None):
    """Create an imaging engine.

    Parameters
    ----------
    backend : {"opencl", "reference"}
        OpenCL kernels or the float64 NumPy reference.
    device : str or int, optional
        OpenCL device: an index into :func:`clbeam.imaging.engine.opencl.list_devices`
        or a substring of its name (default: ``CLBEAM_DEVICE`` or the first).
    precision : {"float32", "float64"} or None
        Arithmetic: the OpenCL kernels run float32 (default) or float64
        (needs ``cl_khr_fp64``, checked); the reference is float64 only and
        refuses float32, and refuses a device.
    """
    from clbeam.errors import OptionError

    if backend == "reference":
        from clbeam.imaging.engine.reference import ReferenceEngine

        return ReferenceEngine(precision=precision, device=device)
    if backend == "opencl":
        from clbeam.imaging.engine.opencl import OpenCLEngine

        return OpenCLEngine(device=device, precision=precision)
    raise OptionError(f"backend '{backend}' is unknown, expected 'opencl' or 'reference'")


__all__ = ["INTERP_MODES", "OUTPUTS", "BeamformInput", "InterpMode", "Sums", "get_engine", "interp_mode"]
