"""AVO figures: files are PNGs of the expected size with the expected marks."""

import matplotlib.colors as mcolors
import matplotlib.image as mimage
import numpy as np

from clbeam.seabed.avo import plot
from clbeam.seabed.avo.attributes import (
    angular_attributes,
    background_trend,
    fluid_factor,
)
from clbeam.seabed.avo.model import backscatter_strength_db

INC = np.arange(0.0, 81.0, 1.0)


def _read(path):
    # Independent reader: matplotlib's PNG decoder, RGBA floats in [0, 1].
    assert path.stat().st_size > 1000
    with open(path, "rb") as fh:
        assert fh.read(8) == b"\x89PNG\r\n\x1a\n"
    return mimage.imread(path)


def _pixels_of(img, color, tol=0.02):
    rgb = np.array(mcolors.to_rgb(color))
    return int(np.sum(np.all(np.abs(img[..., :3] - rgb) < tol, axis=-1)))


def test_angular_response_figure(tmp_path):
    y = backscatter_strength_db(90 - INC, 5e3, mz=3.0)
    img = _read(plot.plot_angular_response(tmp_path / "resp.png", INC, y, angular_attributes(INC, y), model_db=y))
    assert img.shape[:2] == (500, 800)  # 8 x 5 in at 100 dpi
    assert _pixels_of(img, "orange") > 100  # the model line is drawn
    assert img[..., :3].std() > 0.05  # not a blank canvas


def test_gradient_intercept_figure_draws_the_trend(tmp_path):
    rng = np.random.default_rng(0)
    a = rng.uniform(-30, -10, 30)
    b = 0.5 * a + 3 + rng.normal(0, 1, 30)
    g, d = background_trend(a, b)
    path = plot.plot_gradient_intercept(tmp_path / "gi.png", a, b, g, d, fluid_factor_db=fluid_factor(a, b, g, d))
    img = _read(path)
    assert img.shape[:2] == (500, 600)
    assert _pixels_of(img, plot.TREND_COLOR) > 200  # a 2-px line across the axes


def test_along_track_figure(tmp_path):
    x = np.arange(10) * 15.0
    sides = np.array(["port", "starboard"] * 5)
    path = plot.plot_along_track(tmp_path / "track.png", x, {"A (dB)": -20 + x / 50, "Mz (phi)": 2 + x / 100},
                                 sides=sides)
    img = _read(path)
    assert img.shape[:2] == (round(100 * (1.8 * 2 + 1)), 800)  # 8 x 4.6 in at 100 dpi
    assert _pixels_of(img, "#1f77b4") > 50 and _pixels_of(img, "#ff7f0e") > 50  # both sides drawn
