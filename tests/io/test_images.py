"""Image files written ping by ping, in the caller's thread or overlapped with the next ping's work."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import xarray as xr
from scenes import point_ping, polar_point

from clbeam.errors import ClbeamError
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.io.images import ImageWriter
from clbeam.model.grid import PolarGrid

GRID = PolarGrid.regular(range_res_m=0.5, angle_res_deg=1.0, min_range_m=30, max_range_m=60, angles_deg=(-40, 40))


@pytest.fixture(scope="module")
def images():
    imager = Imager(GRID, ImagingOptions())
    return [imager.image(dataclasses.replace(point_ping([polar_point(40 + 5 * i, 10 * i - 15)], record_s=0.09),
                                             index=i)) for i in range(4)]


@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
def test_background_writing_gives_the_images_written_in_the_callers_thread(images, tmp_path, suffix):
    paths = []
    for background in (False, True):
        path = tmp_path / f"img_{background}{suffix}"
        with ImageWriter(path, GRID, len(images), ["intensity", "cf", "cf_smooth"], background=background) as w:
            for img in images:
                w.write(img.ping, img)
        paths.append(path)
    a, b = (xr.open_dataset(p, engine="zarr" if suffix == ".zarr" else None) for p in paths)
    for name in ("intensity", "cf", "cf_smooth", "centre_z"):
        np.testing.assert_array_equal(a[name].values, b[name].values)
    np.testing.assert_array_equal(b["intensity"].values[2], images[2].intensity.astype(np.float32))
    assert a.attrs["imaging_setting"] == b.attrs["imaging_setting"] == images[0].setting
    a.close(), b.close()


def test_an_error_in_a_background_write_is_raised_by_close(images, tmp_path):
    bad = dataclasses.replace(images[1], cf=None, cf_smooth=None)
    w = ImageWriter(tmp_path / "img.nc", GRID, 2, ["intensity", "cf"], background=True)
    w.write(0, images[0])
    w.write(1, bad)
    with pytest.raises(ClbeamError, match="ping 1: the image lacks 'cf'"):
        w.close()
    assert w._file is None  # closed all the same
