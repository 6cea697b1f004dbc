"""The error budget of what users read, measured on the ping's own geometry.

The error model (:mod:`clbeam.imaging.engine.errormodel`) predicts the intensity error of each setting
from the array's band limit; it says nothing of the coherence factor, which peaks are picked on, and it
cannot see everything a real geometry does (a jittered array, a source offset, roll, an element's
tilt, a short pulse whose spectrum reaches past its nominal band).  The budget here is measured
instead: point echoes of the ping's own compressed pulse are placed through its own channels (element
and source offsets from the grid centre, sample rate, record, weights), imaged by a candidate setting on
small windows of the output grid around each point, and compared with their exact delay-and-sum,
evaluated at every cell's travel times (:class:`PulseWavelet`):

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
import hashlib
import logging
import math
import threading
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
#: ranges as fractions of the grid's (and at most of the record's) largest range; points off the grid's nodes
#: sit these fractions of a range and an angle step from one
POINT_ANGLE_FRACTIONS = (0.0, 0.3, 0.55, -0.75, -0.92)
POINT_RANGE_FRACTIONS = (0.5, 0.9, 0.7)
OFF_NODE_CELLS = (0.37, 0.41)
#: at each range, the points on nodes (None) or off them with their echo at this fraction of a sample: the
#: time interpolators' errors, coherent over a short array's channels, change tenfold within a sample
SAMPLE_FRACTIONS = (None, 0.5, 0.25)
#: and a sweep of echoes below the array, off nodes, at these fractions of a sample: there every channel's
#: delay has about the same fraction, and the time interpolation's error adds up coherently
SWEEP_RANGE_FRACTION = 0.6
SWEEP_SAMPLE_FRACTIONS = (0.125, 0.375, 0.625, 0.75, 0.875)
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
    the exact image's maximum (cells without an exact value, which no ray reaches, left out)."""
    keep = exact >= np.nanmax(exact) * 10 ** (-dynamic_range_db / 10)
    return float(10 * np.log10(max(np.sum((got[keep] - exact[keep]) ** 2), 1e-300) / np.sum(exact[keep] ** 2)))


class PulseWavelet:
    """A point echo's compressed analytic pulse ``psi(t)``: the band-limited function with the analytic
    spectrum ``S_k`` on ``n`` bins ``k fs / n`` (periodic over ``n / fs`` s), ``psi(0) = 1``.

    :meth:`samples` gives a record of delayed copies exactly (phase ramps on the bins); :meth:`__call__`
    evaluates it at any time from a table 32 times finer than ``fs`` by four-point Lagrange interpolation
    (the table holds the band within 1/64 of its own Nyquist: the interpolation's error, about
    ``(pi nu)^4 / 6``, is below -100 dB).

    Parameters
    ----------
    spectrum : numpy.ndarray
        ``(n,)`` complex analytic spectrum (zero at negative frequencies).
    sample_rate_hz : float
        ``fs`` (Hz).
    """

    OVERSAMPLING = 32

    def __init__(self, spectrum: np.ndarray, sample_rate_hz: float):
        s = np.asarray(spectrum, dtype=np.complex128)
        self.n, self.fs = s.size, float(sample_rate_hz)
        self.spectrum = s * (self.n / np.sum(s))            # psi(0) = sum(S) / n = 1
        fine = np.zeros(self.n * self.OVERSAMPLING, dtype=np.complex128)
        fine[: self.n // 2] = self.spectrum[: self.n // 2]
        self.table = np.fft.ifft(fine) * self.OVERSAMPLING          # psi at t = j / (8 fs), one period
        self.freqs = np.fft.fftfreq(self.n, 1.0 / self.fs)

    @classmethod
    def of_replica(cls, replica: np.ndarray, sample_rate_hz: float, n: int) -> "PulseWavelet":
        """The compressed pulse of a transmit ``replica`` (its analytic autocorrelation) on ``n`` bins."""
        r = np.fft.fft(np.asarray(replica, dtype=np.float64), n)
        power = np.abs(r) ** 2
        power[n // 2:] = 0.0
        power[1: n // 2] *= 2.0
        return cls(power.astype(np.complex128), sample_rate_hz)

    @classmethod
    def flat(cls, band_hz: tuple, sample_rate_hz: float, n: int) -> "PulseWavelet":
        """The wavelet whose spectrum is flat over ``band_hz`` (Hz) and 0 elsewhere, on ``n`` bins."""
        f = np.fft.fftfreq(n, 1.0 / sample_rate_hz)
        return cls(((f >= band_hz[0]) & (f <= band_hz[1])).astype(np.complex128), sample_rate_hz)

    def samples(self, t0_s: float, n_samples: int, delays_s: np.ndarray) -> np.ndarray:
        """``psi(t0 + j / fs - delay)`` for ``j < n_samples`` (at most the period) and each delay (s):
        ``(n_delays, n_samples)``."""
        require(n_samples <= self.n, OptionError, f"a record of {n_samples} samples exceeds the wavelet's period")
        ramps = np.exp(-2j * np.pi * self.freqs[None, :] * (np.asarray(delays_s)[:, None] - t0_s))
        return np.fft.ifft(self.spectrum[None, :] * ramps, axis=-1)[:, :n_samples]

    def __call__(self, t_s: np.ndarray) -> np.ndarray:
        """``psi`` at times ``t_s`` (s), any shape: four-point Lagrange interpolation of the table."""
        x = np.asarray(t_s, dtype=np.float64) * self.fs * self.OVERSAMPLING
        base = np.floor(x).astype(np.int64)
        u = x - base
        m = self.table.size
        # Lagrange weights of the nodes -1, 0, 1, 2 at u in [0, 1)
        weights = (-u * (u - 1) * (u - 2) / 6, (u + 1) * (u - 1) * (u - 2) / 2, -(u + 1) * u * (u - 2) / 2,
                   (u + 1) * u * (u - 1) / 6)
        return sum(self.table[(base + k) % m] * w for k, w in zip((-1, 0, 1, 2), weights))


class CalibrationScene:
    """Point echoes through the channels of ``inp`` and their exact sums on windows of ``grid``.

    Parameters
    ----------
    inp : BeamformInput
        The ping's channels as the engine images them (offsets from the grid centre, m; straight rays).
    grid : PolarGrid
        The output grid (its steps and span place the points and the windows).
    band_hz : (float, float)
        The signal band (Hz): the wavelet's where no replica is given, and the beams' band limit.
    replica : numpy.ndarray, optional
        The transmit replica at ``inp``'s sample rate: the echoes are its compressed pulse, whose spectrum
        reaches past the band's nominal edges (a short LFM's Fresnel ripples), as the ping's do.
    profile : SoundSpeedProfile, optional
        The profile the ping's travel times follow: the echoes' delays and the cells' are then the
        engine's model through its eigenray tables (the centre's time and a channel's offset along the
        ray's launch direction and wavefront radius), and the engine images them with tables; refraction
        makes the time interpolators' errors add up over the channels (Lanczos-4's |dCF| 0.001-0.006 on
        points in isospeed water, 0.009-0.023 on the same points beyond a 60 m/s jump).
    centre_depth_m : float
        Depth of the grid centre on the profile's axis (m).
    """

    def __init__(self, inp: BeamformInput, grid: PolarGrid, band_hz: tuple, replica: np.ndarray | None = None, *,
                 profile=None, centre_depth_m: float = 0.0):
        self.band_hz = (float(band_hz[0]), float(band_hz[1]))
        self.profile, self.centre_depth_m, self._tables = profile, float(centre_depth_m), {}
        # a period of four replicas: the compressed pulse (twice the replica long) and its copies a period
        # away stay clear of each other and of the record around it
        n = 1 << int(math.ceil(math.log2(max(4 * (0 if replica is None else len(replica)), 2 * RECORD_PAD + 8192))))
        self.wavelet = PulseWavelet.flat(self.band_hz, inp.sample_rate_hz, n) if replica is None else \
            PulseWavelet.of_replica(replica, inp.sample_rate_hz, n)
        self.points, self.on_node, spans = _points_and_windows(inp, grid)
        # each point imaged on every angle of the grid (the beams the ping's image has) at its window's ranges
        self.strips = [PolarGrid.beams(ranges, grid.angles_deg) for ranges, _ in spans]
        self.angle_slices = [angles for _, angles in spans]
        self.windows = [PolarGrid.beams(ranges, grid.angles_deg[angles]) for ranges, angles in spans]
        # one point a record (the wavelet's tails would otherwise reach the other points' cells), each the
        # part of the ping's record around its echoes
        delays = [self._delays(inp, p) for p in self.points]
        # a point no ray reaches (a profile's shadow) is left out
        reached = [k for k, d in enumerate(delays) if np.all(np.isfinite(d))]
        self.points, self.on_node = [self.points[k] for k in reached], [self.on_node[k] for k in reached]
        self.strips, self.angle_slices = [self.strips[k] for k in reached], [self.angle_slices[k] for k in reached]
        self.windows = [self.windows[k] for k in reached]
        require(bool(reached), OptionError, "no calibration point of the grid is reached by a ray")
        self.inputs = [self._record(inp, delays[k]) for k in reached]
        self.exact = [self._exact(inp, w, p) for w, p in zip(self.windows, self.points)]
        # off-node points first, the far range first: where the errors are largest, so that a failing setting
        # is told in a point or two
        self.order = sorted(range(len(self.points)), key=lambda k: (self.on_node[k], -float(np.hypot(*self.points[k]))))

    def _record(self, inp: BeamformInput, delays_s: np.ndarray) -> BeamformInput:
        """``inp`` with the point's echoes (``delays_s`` per channel) on the stretch of its record within
        ``RECORD_PAD`` samples of them."""
        fs = inp.sample_rate_hz
        first = max(0, int(math.floor((delays_s.min() - inp.t0_s) * fs)) - RECORD_PAD)
        end = min(inp.n_samples, int(math.ceil((delays_s.max() - inp.t0_s) * fs)) + RECORD_PAD)
        t0 = inp.t0_s + first / fs
        data = self.wavelet.samples(t0, end - first, delays_s)
        return dataclasses.replace(inp, data=data, t0_s=t0, tables=None, data_token=object(), band_hz=self.band_hz,
                                   table_source=None if self.profile is None else self._tables_of)

    def _tables_of(self, grid: PolarGrid):
        """The eigenray tables of ``grid`` through the profile, kept for the walk's every candidate."""
        from clbeam.imaging.raytrace import travel_time_tables

        key = (grid.shape, grid.ranges_m.tobytes(), grid.angles_deg.tobytes())
        if key not in self._tables:
            self._tables[key] = travel_time_tables(self.profile, grid, self.centre_depth_m)
        return self._tables[key]

    def _delays(self, inp: BeamformInput, point_yz: np.ndarray) -> np.ndarray:
        """Two-way times source -> point -> element (s), ``(n_channel,)``."""
        if self.profile is None:
            return self.straight_delays(inp, point_yz)
        r, th = float(np.hypot(*point_yz)), float(np.degrees(np.arctan2(*point_yz)))
        return self._table_delays(inp, self._tables_of(PolarGrid.beams([r], [th])))[:, 0, 0]

    def _cell_delays(self, inp: BeamformInput, window: PolarGrid) -> np.ndarray:
        """Two-way times source -> cell -> element (s) at every cell of ``window``, ``(n_channel, *shape)``."""
        if self.profile is not None:
            return self._table_delays(inp, self._tables_of(window))
        th = np.deg2rad(window.angles_deg)[:, None]
        cells = np.stack(np.broadcast_arrays(window.ranges_m[None, :] * np.sin(th),
                                             window.ranges_m[None, :] * np.cos(th)), axis=-1)
        return self.straight_delays(inp, cells)

    @staticmethod
    def _table_delays(inp: BeamformInput, tables) -> np.ndarray:
        """The engine's two-way times through eigenray ``tables``: ``2 T + (d(o_s) + d(o_n)) / c0``, ``d`` the
        offset's delay along the ray's launch direction and wavefront radius (s), ``(n_channel, *shape)``."""
        from clbeam.imaging.raytrace.offsets import offset_delay_m

        args = (tables.wavefront_radius_m, tables.launch_sin, tables.launch_cos)
        d_src = offset_delay_m(*args, np.asarray(inp.source_offset_m, dtype=np.float64)[1:])
        d_el = offset_delay_m(*args, np.asarray(inp.element_offsets_m, dtype=np.float64)[:, 1:])
        return 2.0 * tables.time_s[None] + (d_src[None] + d_el) / tables.centre_speed_m_s

    @staticmethod
    def straight_delays(inp: BeamformInput, point_yz: np.ndarray) -> np.ndarray:
        """Two-way times source -> point -> element along straight rays (s), ``(n_channel, *points)``."""
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
        p = self.wavelet(self._cell_delays(inp, window) - self._delays(inp, point_yz)[:, None, None])
        w = np.ones(inp.n_channels) if inp.weights is None else np.asarray(inp.weights, dtype=np.float64)
        s = np.tensordot(w, p, axes=1)
        q = np.tensordot(w, np.abs(p) ** 2, axes=1)
        intensity = np.abs(s) ** 2
        cf = np.where(q > 0, intensity / (np.sum(w) * np.where(q > 0, q, 1.0)), 0.0)
        return {"intensity": intensity, "cf": cf}

    def measure(self, engine, interp: str, beams, upsample: int = 1, budget: Budget = Budget(),
                stop_beyond: Budget | None = None) -> Measured:
        """The errors of one setting (mode, beam sampling, upsampling) on these points; with
        ``stop_beyond``, as soon as one point's figures miss that budget (the worst points first: off
        nodes, far out).  Beams in the frequency domain form the rows nearer than their zones in time with
        the setting's mode, which the points may not reach: their figures are the worse of theirs and their
        time-domain twin's."""
        own = self.measure_domain(engine, interp, beams, upsample, budget, stop_beyond)
        if beams is None or beams.domain != "frequency" or (stop_beyond is not None and not own.meets(stop_beyond)):
            return own
        twin = self.measure_domain(engine, interp, dataclasses.replace(beams, domain="time"), upsample, budget,
                                    stop_beyond)
        return Measured(max(own.error_db, twin.error_db), max(own.cf_error, twin.cf_error),
                        min(own.node_cf, twin.node_cf))

    def measure_domain(self, engine, interp: str, beams, upsample: int = 1, budget: Budget = Budget(),
                       stop_beyond: Budget | None = None) -> Measured:
        """:meth:`measure` of the beams' own domain alone (frequency-domain beams without their time-domain
        twin): intensity error (dB), largest |dCF| and least CF on a node over the points."""
        from clbeam.imaging.signal import upsample_analytic

        errors, cf_errors, node = [], [], [1.0]
        for k in self.order:
            inp = self.inputs[k]
            if upsample > 1:
                inp = dataclasses.replace(inp, data=upsample_analytic(inp.data, upsample),
                                          sample_rate_hz=inp.sample_rate_hz * upsample, data_token=object())
            got = engine.beamform(inp, self.strips[k], interp=interp, outputs=("intensity", "cf"), beams=beams)
            intensity, cf = got.intensity[self.angle_slices[k]], got.cf[self.angle_slices[k]]
            exact = self.exact[k]
            keep = exact["intensity"] >= np.nanmax(exact["intensity"]) * 10 ** (-budget.dynamic_range_db / 10)
            errors.append(intensity_error_db(intensity.astype(np.float64), exact["intensity"], budget.dynamic_range_db))
            cf_errors.append(float(np.max(np.abs(cf[keep] - exact["cf"][keep]))))
            if self.on_node[k]:
                ia, ir = np.unravel_index(np.nanargmax(exact["intensity"]), exact["intensity"].shape)
                node.append(float(cf[ia, ir]))
            measured = Measured(max(errors), max(cf_errors), min(node))
            if stop_beyond is not None and not measured.meets(stop_beyond):
                break
        return measured


def _points_and_windows(inp: BeamformInput, grid: PolarGrid) -> tuple[list, list, list]:
    """Calibration points (earth-frame ``(y, z)`` from the grid centre, m), whether each sits on a node of
    ``grid``, and a window around each (``grid``'s ranges about it, and the slice of ``grid``'s angles within
    :data:`WINDOW_HALF_DEG`): at every angle of :data:`POINT_ANGLE_FRACTIONS` and range of
    :data:`POINT_RANGE_FRACTIONS`, on a node or off one by :data:`OFF_NODE_CELLS` with its echo at a
    fraction of a sample (:data:`SAMPLE_FRACTIONS`), and the sweep below the array
    (:data:`SWEEP_SAMPLE_FRACTIONS`)."""
    a, r = grid.angles_deg, grid.ranges_m
    da = float(np.median(np.diff(a))) if a.size > 1 else 0.1
    dr = float(np.median(np.diff(r))) if r.size > 1 else 0.2
    record_m = 0.5 * inp.sound_speed_m_s * (inp.t0_s + inp.n_samples / inp.sample_rate_hz)
    edge = float(max(abs(a[0]), abs(a[-1])))
    middle = 0.0 if a[0] <= 0.0 <= a[-1] else 0.5 * float(a[0] + a[-1])
    reach = edge if middle == 0.0 else 0.5 * float(a[-1] - a[0])
    n_a = int(round(WINDOW_HALF_DEG / da))
    points, on_node, windows = [], [], []
    sweep = [(SWEEP_RANGE_FRACTION, f, 0.0) for f in SWEEP_SAMPLE_FRACTIONS]
    grid_points = [(rf, fraction, af) for rf, fraction in zip(POINT_RANGE_FRACTIONS, SAMPLE_FRACTIONS)
                   for af in POINT_ANGLE_FRACTIONS]
    for rf, fraction, af in grid_points + sweep:
        r_point = min(rf * float(r[-1]), 0.9 * record_m - WINDOW_RANGE_CELLS * dr)
        ir = int(np.clip(np.searchsorted(r, r_point), WINDOW_RANGE_CELLS, max(r.size - WINDOW_RANGE_CELLS - 1, 0)))
        ia = int(np.argmin(np.abs(a - (middle + af * reach))))
        node = fraction is None
        th = math.radians(float(a[ia]) + (0.0 if node else OFF_NODE_CELLS[1] * da))
        rr = float(r[ir]) + (0.0 if node else OFF_NODE_CELLS[0] * dr)
        if not node:   # its echo at a set fraction of a sample (half-way: where time interpolators err most)
            x = (2.0 * rr / inp.sound_speed_m_s - inp.t0_s) * inp.sample_rate_hz
            rr += (math.floor(x) + fraction - x) * inp.sound_speed_m_s / (2.0 * inp.sample_rate_hz)
        points.append(np.array([rr * math.sin(th), rr * math.cos(th)]))
        on_node.append(node)
        windows.append((r[max(ir - WINDOW_RANGE_CELLS, 0): ir + WINDOW_RANGE_CELLS + 1],
                        slice(max(ia - n_a, 0), ia + n_a + 1)))
    return points, on_node, windows


#: the measured figures must hold the budget with some room: twenty points stand for every cell of the grid,
#: and a point's |dCF| changes threefold with a few millimetres of range.  Chosen on the scene zoo
#: (bench/zoo.py, the tuning set): a setting's worst |dCF| on the zoo's points ran up to 2.4 times its
#: calibration's (Lanczos-4, 0.017 against 0.007, within the budget), cubic on the upsampled signal's below it
CF_ERROR_MARGIN = 1.75
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
            measured = scene.measure(engine, setting.interp, setting.beams, setting.upsample, budget, stop_beyond=strict)
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


#: measured choices kept by the process (least recently used out first): every Imager of one geometry, band,
#: grid and budget (a server's, a survey's workers', a test suite's) measures it once
MEASURED_CHOICES = 64
_choices: dict = {}
_choices_lock = threading.Lock()


def measurement_key(inp: BeamformInput, grid: PolarGrid, band_hz, replica, profile: tuple, budget: Budget,
                    candidates: list, engine) -> tuple:
    """What a measured choice depends on: the channels' geometry (to 0.1 mm), record, weights, band, pulse,
    profile, grid, budget, candidates and the engine's kind and precision."""
    def digest(a) -> str:
        return hashlib.sha1(np.ascontiguousarray(a).tobytes()).hexdigest() if a is not None else ""

    return (np.round(inp.element_offsets_m, 4).tobytes(), np.round(inp.source_offset_m, 4).tobytes(),
            inp.sample_rate_hz, round(inp.t0_s, 9), inp.n_samples, inp.sound_speed_m_s, digest(inp.weights),
            tuple(band_hz), digest(replica), None if profile[0] is None else hash(profile[0]), round(profile[1], 6),
            digest(grid.ranges_m), digest(grid.angles_deg), budget, tuple(candidates),
            type(engine).__name__, getattr(engine, "precision", ""), getattr(engine, "device_name", ""))


def remembered_choice(key: tuple, choose):
    """``choose()`` (a measured ``(setting, measured)``), once per ``key`` in this process."""
    with _choices_lock:
        if key in _choices:
            _choices[key] = _choices.pop(key)        # most recently used last
            return _choices[key]
    value = choose()
    with _choices_lock:
        _choices[key] = value
        while len(_choices) > MEASURED_CHOICES:
            _choices.pop(next(iter(_choices)))
    return value
