"""Device choice: by index, by name, by environment; clear errors when none fits."""

import pytest

from clbeam.errors import DeviceError
from clbeam.imaging.engine import opencl


def test_choose_by_index_name_and_environment(monkeypatch):
    devices = opencl.list_devices()
    assert devices, "the test machine has an OpenCL device (PoCL)"
    first = devices[0]
    assert opencl.choose_device(0) == first
    assert opencl.choose_device("0") == first
    assert opencl.choose_device(first.name.strip()[:6].lower()) == first  # case-insensitive substring
    monkeypatch.setenv("CLBEAM_DEVICE", "0")
    assert opencl.choose_device() == first
    with pytest.raises(DeviceError, match=r"index 99 out of range 0\.\.\d+"):
        opencl.choose_device(99)
    with pytest.raises(DeviceError, match="no OpenCL device matches 'nonexistent'; found: "):
        opencl.choose_device("nonexistent")


def test_no_device_says_how_to_install_one(monkeypatch):
    monkeypatch.setattr(opencl, "list_devices", lambda: [])
    with pytest.raises(DeviceError, match="apt-get install pocl-opencl-icd.*--backend reference"):
        opencl.choose_device()


def test_float64_refused_without_fp64(monkeypatch):
    monkeypatch.setattr(opencl, "device_has_fp64", lambda dev: False)
    with pytest.raises(DeviceError, match=r"has no double precision \(cl_khr_fp64\); use precision float32"):
        opencl.OpenCLEngine(precision="float64")


def test_reference_backend_needs_no_opencl(monkeypatch):
    from clbeam.imaging.engine import get_engine

    monkeypatch.setattr(opencl, "list_devices", lambda: [])
    assert get_engine("reference").precision == "float64"
