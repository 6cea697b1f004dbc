"""The error budget of what users read, measured on the ping's own geometry.

The error model (:mod:`clbeam.imaging.engine.errormodel`) predicts the intensity error of each setting
from the array's band limit; it says nothing of the coherence factor, which peaks are picked on, and it
cannot see everything a real geometry does (a jittered array, a source offset, roll, an element's
tilt).  The budget here is measured instead: point echoes of a flat-band analytic wavelet are placed
through the ping's own channels (element and source offsets from the grid centre, sample rate, record,
weights, band), imaged by a candidate setting on small windows of the output grid around each point, and
compared with their exact delay-and-sum, evaluated in closed form at every cell's travel times:

- the intensity error: error energy over signal energy (dB) on cells within ``dynamic_range_db`` of
  the window's maximum;
- the CF error: the largest ``|dCF|`` on those cells;
- the CF at a point that sits on a node (ideally 1).

:func:`choose_measured_setting` walks the candidates the error model lets through, cheapest first, and
keeps the first that meets all three; a candidate it cannot measure is skipped (the safer, dearer one
is taken).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.imaging.engine.common import BeamformInput
from clbeam.model.grid import PolarGrid

log = logging.getLogger(__name__)

#: half-width (degree) of each point's window, and range cells either side of it
WINDOW_HALF_DEG = 8.0
WINDOW_RANGE_CELLS = 12
#: the points' angles as fractions of the grid's largest |angle| (0: nadir, or the grid's middle) and their
#: ranges as fractions of the grid's (and at most of the record's) largest range; every other point sits off
#: the grid's nodes by these fractions of a range and an angle step
POINT_ANGLE_FRACTIONS = (0.0, 0.3, 0.55, -0.75, -0.92)
POINT_RANGE_FRACTIONS = (0.5, 0.9)
OFF_NODE_CELLS = (0.37, 0.41)
#: samples of record either side of a calibration echo (51 ms at 40 kHz: the longest interpolator reaches
#: 32 samples, and the FFT upsampling's wrap-around of the wavelet's tails stays below -80 dB there)
RECORD_PAD = 2048


@dataclass(frozen=True)
class Budget:
    """What the default setting must hold.

    Attributes
    ----------
    max_error_db : float
        Intensity error (dB, error energy over signal energy on cells within ``dynamic_range_db``).
    max_cf_error : float
        Largest ``|dCF|`` on those cells.
    min_node_cf : float
        CF at a point echo on a grid node.
    dynamic_range_db : float
        Cells within this of the window's maximum intensity count (dB).
    """

    max_error_db: float = -40.0
    max_cf_error: float = 0.02
    min_node_cf: float = 0.99
    dynamic_range_db: float = 40.0

    def __post_init__(self):
        require(math.isfinite(self.max_error_db) and self.max_error_db < 0, OptionError,
                f"the intensity error budget must be a negative number of dB, got {self.max_error_db!r}")
        require(0 < self.max_cf_error <= 1, OptionError,
                f"the CF error budget must be within (0, 1], got {self.max_cf_error!r}")


@dataclass(frozen=True)
class Measured:
    """One setting's errors on the calibration points (see the module's description)."""

    error_db: float
    cf_error: float
    node_cf: float

    def meets(self, budget: Budget) -> bool:
        """True when every figure is within ``budget``."""
        return (self.error_db <= budget.max_error_db and self.cf_error <= budget.max_cf_error
                and self.node_cf >= budget.min_node_cf)

    def describe(self) -> str:
        """One line of the three figures."""
        return f"{self.error_db:.1f} dB, |dCF| {self.cf_error:.3f}, CF {self.node_cf:.4f} on a node"


def intensity_error_db(got: np.ndarray, exact: np.ndarray, dynamic_range_db: float = 40.0) -> float:
    """Error energy over signal energy (dB) of an intensity image on cells within ``dynamic_range_db`` of
    the exact image's maximum."""
    keep = exact >= exact.max() * 10 ** (-dynamic_range_db / 10)
    return float(10 * np.log10(max(np.sum((got[keep] - exact[keep]) ** 2), 1e-300) / np.sum(exact[keep] ** 2)))


def flat_band_wavelet(t_s: np.ndarray, band_hz: tuple) -> np.ndarray:
    """The analytic wavelet whose spectrum is flat over ``band_hz`` (Hz) and 0 outside, at times ``t_s``
    (s), 1 at ``t = 0``: ``(exp(i 2 pi f1 t) - exp(i 2 pi f0 t)) / (i 2 pi t (f1 - f0))``."""
    f0, f1 = float(band_hz[0]), float(band_hz[1])
    t = np.asarray(t_s, dtype=np.float64)
    small = np.abs(t) * (f1 - f0) < 1e-9
    ts = np.where(small, 1.0, t)
    out = (np.exp(2j * np.pi * f1 * ts) - np.exp(2j * np.pi * f0 * ts)) / (2j * np.pi * ts * (f1 - f0))
    # near t = 0: the wavelet is the band's mean carrier to second order
    return np.where(small, np.exp(1j * np.pi * (f0 + f1) * t), out)


class CalibrationScene:
    """Point echoes through the channels of ``inp`` and their exact sums on windows of ``grid``.

    Parameters
    ----------
    inp : BeamformInput
        The ping's channels as the engine images them (offsets from the grid centre, m; straight rays).
    grid : PolarGrid
        The output grid (its steps and span place the points and the windows).
    band_hz : (float, float)
        The signal band (Hz).
    """

    def __init__(self, inp: BeamformInput, grid: PolarGrid, band_hz: tuple):
        self.band_hz = (float(band_hz[0]), float(band_hz[1]))
        self.points, self.on_node, self.windows = _points_and_windows(inp, grid)
        # one point a record (the wavelet's tails, 1 / t, would otherwise reach the other points' cells), each
        # the part of the ping's record around its echoes
        self.inputs = [self._record(inp, self._delays(inp, p)) for p in self.points]
        self.exact = [self._exact(inp, w, p) for w, p in zip(self.windows, self.points)]

    def _record(self, inp: BeamformInput, delays_s: np.ndarray) -> BeamformInput:
        """``inp`` with the point's echoes (``delays_s`` per channel) on the stretch of its record within
        ``RECORD_PAD`` samples of them."""
        fs = inp.sample_rate_hz
        first = max(0, int(math.floor((delays_s.min() - inp.t0_s) * fs)) - RECORD_PAD)
        end = min(inp.n_samples, int(math.ceil((delays_s.max() - inp.t0_s) * fs)) + RECORD_PAD)
        t0 = inp.t0_s + first / fs
        times = t0 + np.arange(end - first) / fs
        data = flat_band_wavelet(times[None, :] - delays_s[:, None], self.band_hz)
        return dataclasses.replace(inp, data=data, t0_s=t0, tables=None, table_source=None, data_token=object(),
                                   band_hz=self.band_hz)

    @staticmethod
    def _delays(inp: BeamformInput, point_yz: np.ndarray, extra_axes: int = 0) -> np.ndarray:
        """Two-way times source -> point -> element (s), ``(n_channel, *points)``."""
        p = np.asarray(point_yz, dtype=np.float64)
        py, pz = p[..., 0], p[..., 1]
        src, el = np.asarray(inp.source_offset_m, dtype=np.float64), np.asarray(inp.element_offsets_m, dtype=np.float64)
        d_src = np.sqrt(src[0] ** 2 + (py - src[1]) ** 2 + (pz - src[2]) ** 2)
        shape = (-1,) + (1,) * py.ndim
        d_el = np.sqrt(el[:, 0].reshape(shape) ** 2 + (py[None] - el[:, 1].reshape(shape)) ** 2
                       + (pz[None] - el[:, 2].reshape(shape)) ** 2)
        return (d_src[None] + d_el) / inp.sound_speed_m_s

    def _exact(self, inp: BeamformInput, window: PolarGrid, point_yz: np.ndarray) -> dict:
        """Intensity and CF of the point's echo at every cell of ``window``, in closed form."""
        th = np.deg2rad(window.angles_deg)[:, None]
        cells = np.stack(np.broadcast_arrays(window.ranges_m[None, :] * np.sin(th),
                                             window.ranges_m[None, :] * np.cos(th)), axis=-1)
        tau = self._delays(inp, cells)                                     # (n_channel, n_angle, n_range)
        p = flat_band_wavelet(tau - self._delays(inp, point_yz)[:, None, None], self.band_hz)
        w = np.ones(inp.n_channels) if inp.weights is None else np.asarray(inp.weights, dtype=np.float64)
        s = np.tensordot(w, p, axes=1)
        q = np.tensordot(w, np.abs(p) ** 2, axes=1)
        intensity = np.abs(s) ** 2
        cf = np.where(q > 0, intensity / (np.sum(w) * np.where(q > 0, q, 1.0)), 0.0)
        return {"intensity": intensity, "cf": cf}

    def measure(self, engine, interp: str, beams, upsample: int = 1, budget: Budget = Budget()) -> Measured:
        """The errors of one setting (mode, beam sampling, upsampling) on these points."""
        from clbeam.imaging.signal import upsample_analytic

        errors, cf_errors, node = [], [], [1.0]
        for inp, window, exact, on_node in zip(self.inputs, self.windows, self.exact, self.on_node):
            if upsample > 1:
                inp = dataclasses.replace(inp, data=upsample_analytic(inp.data, upsample),
                                          sample_rate_hz=inp.sample_rate_hz * upsample, data_token=object())
            got = engine.beamform(inp, window, interp=interp, outputs=("intensity", "cf"), beams=beams)
            keep = exact["intensity"] >= exact["intensity"].max() * 10 ** (-budget.dynamic_range_db / 10)
            errors.append(intensity_error_db(got.intensity.astype(np.float64), exact["intensity"],
                                             budget.dynamic_range_db))
            cf_errors.append(float(np.max(np.abs(got.cf[keep] - exact["cf"][keep]))))
            if on_node:
                ia, ir = np.unravel_index(np.argmax(exact["intensity"]), window.shape)
                node.append(float(got.cf[ia, ir]))
        return Measured(max(errors), max(cf_errors), min(node))


def _points_and_windows(inp: BeamformInput, grid: PolarGrid) -> tuple[list, list, list]:
    """Calibration points (earth-frame ``(y, z)`` from the grid centre, m), whether each sits on a node of
    ``grid``, and a window of ``grid``'s steps around each: at every angle of :data:`POINT_ANGLE_FRACTIONS`
    and range of :data:`POINT_RANGE_FRACTIONS`, on a node, and off one by :data:`OFF_NODE_CELLS`."""
    a, r = grid.angles_deg, grid.ranges_m
    da = float(np.median(np.diff(a))) if a.size > 1 else 0.1
    dr = float(np.median(np.diff(r))) if r.size > 1 else 0.2
    record_m = 0.5 * inp.sound_speed_m_s * (inp.t0_s + inp.n_samples / inp.sample_rate_hz)
    edge = float(max(abs(a[0]), abs(a[-1])))
    middle = 0.0 if a[0] <= 0.0 <= a[-1] else 0.5 * float(a[0] + a[-1])
    reach = edge if middle == 0.0 else 0.5 * float(a[-1] - a[0])
    n_a = int(round(WINDOW_HALF_DEG / da))
    points, on_node, windows = [], [], []
    for k, (rf, af) in enumerate((rf, af) for rf in POINT_RANGE_FRACTIONS for af in POINT_ANGLE_FRACTIONS):
        r_point = min(rf * float(r[-1]), 0.9 * record_m - WINDOW_RANGE_CELLS * dr)
        ir = int(np.clip(np.searchsorted(r, r_point), WINDOW_RANGE_CELLS, max(r.size - WINDOW_RANGE_CELLS - 1, 0)))
        ia = int(np.argmin(np.abs(a - (middle + af * reach))))
        shift = OFF_NODE_CELLS if k % 2 else (0.0, 0.0)
        th, rr = math.radians(float(a[ia]) + shift[1] * da), float(r[ir]) + shift[0] * dr
        points.append(np.array([rr * math.sin(th), rr * math.cos(th)]))
        on_node.append(not k % 2)
        windows.append(PolarGrid.beams(float(r[ir]) + dr * np.arange(-WINDOW_RANGE_CELLS, WINDOW_RANGE_CELLS + 1),
                                       float(a[ia]) + da * np.arange(-n_a, n_a + 1)))
    return points, on_node, windows


#: the measured figures must hold the budget with some room: ten points stand for every cell of the grid.
#: On the tuning scenes (two jittered, rolled arrays with source offsets, on-node points at other ranges)
#: the calibration's |dCF| was 1.3-4 times the scenes' own, its intensity error 1-4 dB above theirs
CF_ERROR_MARGIN = 1.25
NODE_DEFICIT_MARGIN = 1.5
ERROR_DB_MARGIN = 1.0


def with_margins(budget: Budget) -> Budget:
    """The budget the calibration's measurements must meet (:data:`CF_ERROR_MARGIN` and the others)."""
    return Budget(max_error_db=budget.max_error_db - ERROR_DB_MARGIN,
                  max_cf_error=budget.max_cf_error / CF_ERROR_MARGIN,
                  min_node_cf=1.0 - (1.0 - budget.min_node_cf) / NODE_DEFICIT_MARGIN,
                  dynamic_range_db=budget.dynamic_range_db)


def choose_measured_setting(candidates: list, scene: CalibrationScene, engine, budget: Budget):
    """The cheapest of ``candidates`` (:class:`~clbeam.imaging.engine.errormodel.Setting`, each predicted
    within the intensity budget) whose measured errors on ``scene`` meet ``budget`` with margins
    (:func:`with_margins`), as ``(setting, measured)``; the most accurate one measured, with a warning,
    when none does.  A candidate the engine cannot run is skipped."""
    require(bool(candidates), OptionError, "no setting to measure: the error model let none through")
    strict = with_margins(budget)
    tried = []
    for setting in sorted(candidates, key=lambda s: (s.cost, s.error_db)):
        try:
            measured = scene.measure(engine, setting.interp, setting.beams, setting.upsample, budget)
        except OptionError as exc:   # e.g. a basebanded mode without a carrier
            log.debug("setting %s not measured: %s", setting.describe(), exc)
            continue
        log.debug("setting %s measured %s", setting.describe(), measured.describe())
        if measured.meets(strict):
            return setting, measured
        tried.append((setting, measured))
    require(bool(tried), OptionError, "no candidate setting could be measured on this ping's geometry")
    setting, measured = min(tried, key=lambda sm: (sm[1].cf_error, sm[1].error_db))
    log.warning("no setting holds the budget (%.0f dB, |dCF| %.3f) with room on this geometry; imaging with %s "
                "(measured %s)", budget.max_error_db, budget.max_cf_error, setting.describe(), measured.describe())
    return setting, measured
