"""``clbeam devices``: the OpenCL platforms and devices found."""

from __future__ import annotations

NAME = "devices"
HELP = "list the OpenCL platforms and devices found"


def add_arguments(p) -> None:
    """``clbeam devices`` takes no arguments beyond ``-q``."""


def run(args) -> int:
    """Print one line per OpenCL device; 1 when there is none."""
    from clbeam.imaging.engine.opencl import NO_OPENCL, device_has_fp64, list_devices

    devices = list_devices()
    if not devices:
        print(NO_OPENCL)
        return 1
    for i, d in enumerate(devices):
        print(f"[{i}] {d.name.strip()}  platform: {d.platform.name.strip()}  "
              f"compute units: {d.max_compute_units}  memory: {d.global_mem_size / 2**30:.1f} GiB  "
              f"max alloc: {d.max_mem_alloc_size / 2**30:.1f} GiB  fp64: {'yes' if device_has_fp64(d) else 'no'}")
    return 0
