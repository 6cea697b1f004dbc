"""What the OpenCL backend's modules share: the pyopencl import, kernel sources and build macros."""

from __future__ import annotations

from importlib import resources

from clbeam.errors import DeviceError


def pyopencl():
    """The pyopencl module, or a one-line :class:`DeviceError` when it cannot be imported."""
    try:
        import pyopencl as cl
    except ImportError as exc:  # pragma: no cover - pyopencl is a dependency
        raise DeviceError(f"pyopencl is not importable ({exc}); install clbeam's dependencies") from None
    return cl


#: the source file of each kernel entry point
KERNEL_FILES = {"beamform": "beamform.cl", "beam_to_grid": "beam_interp.cl", "fd_steer": "fdbeam.cl"}


def output_macros(outs: frozenset) -> list:
    """The ``WANT_*`` build macros of the requested outputs."""
    return [f"-DWANT_INTENSITY={int('intensity' in outs)}", f"-DWANT_CF={int('cf' in outs)}",
            f"-DWANT_SUMS={int('sums' in outs)}", f"-DWANT_SIGNATURE={int('signature' in outs)}"]


def kernel_source(name: str = "beamform.cl") -> str:
    """A kernel file's source with its headers inlined (avoids include paths)."""
    root = resources.files("clbeam.kernels")
    src = (root / name).read_text()
    for header in ("common.h", "vector.h", "interp.h"):
        src = src.replace(f'#include "{header}"', (root / header).read_text())
    return src
