"""The Imager: one ping through the whole chain.

compress (analytic signal) → earth frame (roll, heave) → engine (S, Q, M →
intensity, CF) → Hann smoothing → coherence peaks.  Build it once (grid,
mode, device); it compiles the kernels on first use and keeps them and its
device buffers for every later ping, which is what a processing server or a
survey worker holds.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import math
import os
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from clbeam.constants import (
    DEFAULT_MAX_CF_ERROR,
    DEFAULT_MAX_ERROR_DB,
    DEFAULT_MIN_CHANNELS,
    DEFAULT_MIN_CONTRAST_DB,
    DEFAULT_MIN_SNR_DB,
    PEAK_THRESHOLD,
    SEDIMENT_SPEED_RANGE_M_S,
    WATER_SPEED_RANGE_M_S,
)
from clbeam.errors import GridError, OptionError, require
from clbeam.imaging.apodization import (
    calibration_factors,
    parse_window,
    receive_weights,
)
from clbeam.imaging.budget import (
    Budget,
    CalibrationScene,
    choose_measured_setting,
    measurement_key,
    remembered_choice,
)
from clbeam.imaging.engine import BeamformInput, Sums, get_engine, interp_mode
from clbeam.imaging.engine.beams import BeamSampling
from clbeam.imaging.engine.common import cell_windows, check_mode_runs_on, check_outputs, min_channels_of, user_windows
from clbeam.imaging.engine.errormodel import BEAM_CHOICES, Setting, choose_setting, predicted_settings
from clbeam.imaging.geometry import check_positions, to_earth_frame
from clbeam.imaging.peaks import PingContext, peak_rows
from clbeam.imaging.postprocess import hann_smooth, hann_smooth_in_windows
from clbeam.imaging.raytrace import travel_time_tables
from clbeam.imaging.seabed_band import pick_seabed_depth_m, seabed_window_m
from clbeam.imaging.signal import compress_analytic, pulse_band_hz, upsample_analytic
from clbeam.imaging.subcell import subcell_peaks
from clbeam.model.grid import PolarGrid
from clbeam.model.ping import Ping
from clbeam.model.svp import SoundSpeedProfile

log = logging.getLogger(__name__)


#: beam-sampled imaging through a sound-speed profile interpolates from at least this many beams: its band
#: limit is measured on the travel-time tables (:func:`clbeam.imaging.engine.beams.refracted_band_limit`),
#: and with 8 taps a 80 m/s jump left a CF error of 0.034 at -36 dB beside a point (0.011 with 12)
REFRACTED_MIN_TAPS = 12


@dataclass(frozen=True)
class ImagingOptions:
    """How a ping is imaged.

    Attributes
    ----------
    interp : str
        Interpolation mode (see :data:`clbeam.imaging.engine.INTERP_MODES`),
        or ``"auto"``: the cheapest mode, upsampling and beam sampling whose
        predicted error is within ``max_error_db``
        (:mod:`clbeam.imaging.engine.errormodel`).
    upsample : int or None
        FFT upsampling factor of the analytic signal before interpolation;
        ``None``: chosen with the mode (1 for a forced mode).
    max_error_db : float
        Error budget of the intensity against the exact image (dB) that
        ``"auto"`` settings meet.
    max_cf_error : float
        Error budget of the coherence factor: the largest ``|dCF|`` on cells
        within 40 dB of an echo's peak, measured with the CF at an echo on a
        node (at least 0.99) on the ping's own geometry
        (:mod:`clbeam.imaging.budget`) for ``"auto"`` settings.
    outputs : tuple of str
        Requested outputs: ``"intensity"``, ``"cf"``, ``"sums"``; CF also
        gives the smoothed CF and the coherence peaks.
    threshold : float
        Coherence-peak threshold on the smoothed CF (paper: 0.25).
    sound_speed_m_s : float or None
        Override of the file's sound speed (m/s).
    precision : str or None
        ``"float32"`` or ``"float64"`` arithmetic; ``None``: the engine's own
        (float32 on OpenCL, float64 on the reference).  An engine of another
        precision is refused.
    seabed_band_m : (float, float) or None
        Compute only cells from this far above to this far below the seabed
        (m), e.g. ``(5, 40)``; ``None`` computes the whole grid.
    seabed_depth_m : float or None
        Seabed depth below the grid centre (m) for the band; ``None`` picks it
        per ping from the first strong return at nadir.
    apodization : str
        Receive window across the array: ``"rect"`` (none), ``"hann"``,
        ``"tukey[:alpha]"``, ``"chebyshev[:sidelobe_db]"``
        (:mod:`clbeam.imaging.apodization`; CF becomes the weighted CF).
    calibrate : bool
        Remove the ping file's ``element_gain_db`` / ``element_phase_deg``
        from the channels (when the file has them).
    use_svp : bool
        Ray-trace the travel times through the ping file's sound-speed profile
        (``svp_depth``, ``svp_speed``) when it has one (:mod:`clbeam.imaging.raytrace`);
        ``False`` (or ``sound_speed_m_s``) images with straight rays.
    sediment_speed_m_s : float or None
        Sediment interval velocity (m/s) below a flat seabed at
        ``seabed_depth_m`` (picked per ping when not given): rays refract at
        the seabed (Snell) on their way to sub-bottom cells.
    mlh : bool
        Merge the coherence peaks on one main-lobe arc into one detection
        with a lobe-fitted position (:mod:`clbeam.imaging.mlh`); the peak rows then
        carry ``n_merged``, ``arc_extent_deg`` and ``arc_range_spread_m``.
    beams : "auto", BeamSampling or None
        Beam-sampled imaging (:mod:`clbeam.imaging.engine.beams`): the sums
        on the beams the aperture resolves, interpolated to the grid's
        angles; ``"auto"``: chosen by the budget (off with a forced mode,
        which then images every cell as before); ``None`` computes every cell directly.
    refine_peaks : bool
        Move every coherence peak to its echo's intensity maximum from the exact
        sums, one row per echo (:mod:`clbeam.imaging.subcell`; not with ``mlh``).
    min_channels : float
        CF, and so the peaks, only in cells summed from at least this many
        channels: a count (an integer >= 1) or, below 1, a fraction of the
        ping's usable channels (default 0.5: half).  With one channel CF is 1
        by definition; near the record's ends, where few channels reach a
        cell, CF is large for noise.
    min_snr_db : float or None
        Peaks only this far (dB) above the ping's noise floor
        (:mod:`clbeam.imaging.detection`; default 6 dB); ``None``: every peak above the threshold.
    min_contrast_db : float or None
        Peaks only this far (dB) above the mean of the clutter around them
        (:mod:`clbeam.imaging.detection`, where the clutter is reverberation; default 12 dB); ``None``: no
        clutter test.
    """

    interp: str = "auto"
    upsample: int | None = None
    outputs: tuple = ("intensity", "cf")
    threshold: float = PEAK_THRESHOLD
    sound_speed_m_s: float | None = None
    precision: str | None = None
    seabed_band_m: tuple | None = None
    seabed_depth_m: float | None = None
    apodization: str = "rect"
    calibrate: bool = True
    use_svp: bool = True
    sediment_speed_m_s: float | None = None
    mlh: bool = False
    beams: BeamSampling | str | None = "auto"
    max_error_db: float = DEFAULT_MAX_ERROR_DB
    max_cf_error: float = DEFAULT_MAX_CF_ERROR
    refine_peaks: bool = True
    min_channels: float = DEFAULT_MIN_CHANNELS
    min_snr_db: float | None = DEFAULT_MIN_SNR_DB
    min_contrast_db: float | None = DEFAULT_MIN_CONTRAST_DB

    def __post_init__(self):
        if self.interp != "auto":
            interp_mode(self.interp)
        require(self.beams is None or self.beams == "auto" or isinstance(self.beams, BeamSampling), OptionError,
                f"beams must be 'auto', None or a BeamSampling, got {self.beams!r}")
        require(math.isfinite(self.max_error_db) and self.max_error_db < 0, OptionError,
                f"the error budget must be a negative number of dB, got {self.max_error_db!r}")
        require(isinstance(self.max_cf_error, (int, float)) and 0 < self.max_cf_error <= 1, OptionError,
                f"the CF error budget must be within (0, 1], got {self.max_cf_error!r}")
        object.__setattr__(self, "apodization", parse_window(self.apodization).label)
        object.__setattr__(self, "outputs", tuple(sorted(check_outputs(self.outputs))))
        require(self.upsample is None or (int(self.upsample) == self.upsample and 1 <= self.upsample <= 16),
                OptionError, f"upsample must be an integer 1-16, got {self.upsample!r}")
        require(0 <= self.threshold <= 1, OptionError, f"threshold must be within 0-1, got {self.threshold!r}")
        require(isinstance(self.min_channels, (int, float)) and math.isfinite(self.min_channels)
                and (0 < self.min_channels < 1 or (self.min_channels >= 1 and int(self.min_channels) == self.min_channels)),
                OptionError, f"the minimum of channels must be a fraction in (0, 1) or a count >= 1, "
                f"got {self.min_channels!r}")
        require(self.min_snr_db is None or math.isfinite(self.min_snr_db), OptionError,
                f"the minimum SNR must be a finite number of dB or None, got {self.min_snr_db!r}")
        require(self.min_contrast_db is None or math.isfinite(self.min_contrast_db), OptionError,
                f"the minimum clutter contrast must be a finite number of dB or None, got {self.min_contrast_db!r}")
        if self.seabed_band_m is not None:
            band = tuple(float(v) for v in self.seabed_band_m)
            require(len(band) == 2 and all(np.isfinite(band)) and band[0] + band[1] > 0, OptionError,
                    f"seabed band must be (above, below) metres with a positive width, got {self.seabed_band_m!r}")
            object.__setattr__(self, "seabed_band_m", band)
        require(not self.mlh or "cf" in self.outputs, OptionError,
                "mlh merges coherence peaks, which need the cf output")
        require(self.seabed_depth_m is None or self.seabed_band_m is not None or self.sediment_speed_m_s is not None,
                OptionError, "a seabed depth serves the seabed band or the sediment speed: give one of them too, "
                "or leave the depth out")
        require(self.precision in (None, "float32", "float64"), OptionError,
                f"precision '{self.precision}' is unknown, expected 'float32' or 'float64'")
        for name, value, (lo, hi) in (("sediment speed", self.sediment_speed_m_s, SEDIMENT_SPEED_RANGE_M_S),
                                      ("sound speed", self.sound_speed_m_s, WATER_SPEED_RANGE_M_S)):
            require(value is None or lo <= value <= hi, OptionError,
                    f"{name} must be within {lo:g}-{hi:g} m/s, got {value!r}")


@dataclass
class PingImage:
    """The images and coherence peaks of one ping.

    Attributes
    ----------
    ping : int
        Ping index in its file.
    grid : PolarGrid
        Image grid; every array is ``(n_angle, n_range)``.
    intensity, cf, cf_smooth : numpy.ndarray or None
        ``|S|^2``, coherence factor and its 7-point Hann smoothing along range.
    sums : Sums or None
        Raw sums ``S``, ``Q``, ``M`` (when requested) for stacking pings.
    peaks : list of dict
        One row per coherence peak (:data:`clbeam.io.peaks.PEAK_COLUMNS`, plus navigation).
    context : PingContext
        The ping's grid centre, source, navigation and sonar (what its peak
        rows and its image file need).
    timings_s : dict
        Seconds spent per stage: ``compress_s``, ``image_s``, ``postprocess_s``.
    stages_s : dict
        Seconds inside them: the engine's (:attr:`Sums.timings_s`), ``smooth_s`` (the CF's smoothing)
        and ``peaks_s`` (the peaks, their refinement and detection tests).
    n_channels_used : int
        Channels that took part.
    setting : str
        The mode, upsampling and beam sampling used, with the predicted error.
    """

    ping: int
    grid: PolarGrid
    intensity: np.ndarray | None
    cf: np.ndarray | None
    cf_smooth: np.ndarray | None
    sums: Sums | None
    peaks: list
    context: PingContext
    timings_s: dict = field(default_factory=dict)
    stages_s: dict = field(default_factory=dict)
    n_channels_used: int = 0
    setting: str = ""

    @property
    def centre_yz_m(self) -> tuple:
        """Earth-frame grid centre ``(y, z)`` (m) of this ping."""
        return self.context.centre_yz_m

    @property
    def source_yz_m(self) -> tuple:
        """Deprecated name of :attr:`centre_yz_m` (the grid centre, not the rolled source: that is
        ``context.source_yz_m``); kept for one release."""
        warnings.warn("PingImage.source_yz_m is deprecated: it is the grid centre, now PingImage.centre_yz_m",
                      DeprecationWarning, stacklevel=2)
        return self.centre_yz_m


class Imager:
    """Images pings on a fixed grid with fixed options.

    Parameters
    ----------
    grid : PolarGrid
        Image grid (earth frame, centre at the source unless given).
    options : ImagingOptions, optional
        Mode, outputs, threshold …
    backend : {"opencl", "reference"}, optional
        Engine backend (default opencl); with ``engine``, it must name the engine's.
    device : str or int, optional
        OpenCL device (index or name substring); not with ``engine``.
    engine : object, optional
        An existing engine to share (e.g. one per device in a server); its
        precision must be ``options.precision`` when that is given.

    Examples
    --------
    >>> imager = Imager(PolarGrid.regular(max_range_m=700))      # doctest: +SKIP
    >>> with PingFile("line1.nc") as f:                           # doctest: +SKIP
    ...     images = [imager.image(p) for p in f]
    """

    def __init__(self, grid: PolarGrid, options: ImagingOptions | None = None, *, backend: str | None = None,
                 device=None, engine=None):
        self.grid = grid
        self.options = opts = options or ImagingOptions()
        check_grid_fits_memory(grid, opts)
        if opts.interp != "auto":
            check_mode_runs_on(interp_mode(opts.interp), engine.name if engine is not None else backend or "opencl")
        if engine is None:
            engine = get_engine(backend or "opencl", device=device, precision=opts.precision)
        else:
            require(device is None, OptionError, "give a device or an engine, not both (the engine has its device)")
            require(backend in (None, engine.name), OptionError,
                    f"backend '{backend}' differs from the engine's '{engine.name}'")
            require(opts.precision in (None, engine.precision), OptionError,
                    f"precision '{opts.precision}' differs from the engine's '{engine.precision}'")
        self.engine = engine
        self._tables: dict = {}
        self._settings: dict = {}
        self._warned_beyond = False

    # -- preparation ------------------------------------------------------
    def usable_channels(self, ping: Ping) -> np.ndarray:
        """Bool mask of the channels imaged: those not flagged invalid, entirely zero or entirely
        non-finite (the others logged), their non-finite samples counted in the log."""
        require(ping.kind != "raw" or ping.pulse is not None, OptionError,
                "raw samples need a pulse description to compress")
        x = ping.samples
        used = np.asarray(ping.channel_valid, dtype=bool).copy()
        finite = np.isfinite(x)
        dead = ~finite.any(axis=1) | ~np.any(np.where(finite, x, 0) != 0, axis=1)
        if (dead & used).any():
            log.warning("ping %d: %d channel(s) all zero or non-finite, left out: %s", ping.index,
                        int((dead & used).sum()), np.flatnonzero(dead & used).tolist())
        used &= ~dead
        n_bad = int((~finite[used]).sum())
        if n_bad:
            log.warning("ping %d: %d non-finite sample(s) skipped", ping.index, n_bad)
        return used

    def analytic_channels(self, ping: Ping, used: np.ndarray, upsample: int = 1) -> np.ndarray:
        """Pulse-compressed analytic signal of the channels ``used`` (bool mask), complex
        ``(n_used, upsample n_sample)`` at ``upsample`` times the record's rate (raw pings: one inverse
        transform for compression and upsampling, :func:`compress_analytic`), non-finite samples NaN."""
        x = ping.samples[used]
        if ping.kind == "raw":
            data = compress_analytic(x, ping.pulse.replica(ping.sample_rate_hz),
                                     precision=compression_precision(x, self.engine.precision), upsample=upsample)
        else:
            complex_type = np.complex64 if self.engine.precision == "float32" else np.complex128
            data = upsample_analytic(np.where(np.isfinite(x), x, np.nan).astype(complex_type), upsample)
        factors = calibration_factors(ping.element_gain_db, ping.element_phase_deg, ping.n_channels)
        if self.options.calibrate and factors is not None:
            data *= factors[used, None]
        return data

    def beamform_input(self, ping: Ping) -> BeamformInput:
        """Everything the engine needs for ``ping``: analytic channels and
        roll/heave-corrected offsets from the grid centre (upsampled as the setting says)."""
        return self._prepare(ping)[0]

    def _prepare(self, ping: Ping) -> tuple[BeamformInput, Setting]:
        """The engine's input for ``ping`` and the setting it is imaged with."""
        check_positions("element positions", ping.element_pos_m)
        check_positions("source position", ping.source_pos_m)
        used = self.usable_channels(ping)
        elements = to_earth_frame(ping.element_pos_m[used], roll_deg=ping.roll_deg, heave_m=ping.heave_m)
        source = to_earth_frame(ping.source_pos_m, roll_deg=ping.roll_deg, heave_m=ping.heave_m)
        centre = np.r_[0.0, self.grid.centre(tuple(ping.source_pos_m[1:]))]
        band = pulse_band_hz(ping.pulse, ping.sample_rate_hz)
        fc = ping.pulse.centre_frequency_hz if ping.pulse is not None else None
        if fc is None and band is not None:  # an explicit waveform: the carrier of the basebanded modes is its band's centre
            fc = 0.5 * (band[0] + band[1])
        window = parse_window(self.options.apodization)
        weights = None if window.uniform else receive_weights(window, ping.element_pos_m[:, 1])[used]
        # the record's shape without its samples (the setting needs the geometry, not the data): the channels
        # are compressed once the setting's upsampling is known, in the same inverse transform
        record = np.broadcast_to(np.zeros((), np.complex64), (int(used.sum()), ping.samples.shape[1]))
        inp = BeamformInput(
            data=record, sample_rate_hz=ping.sample_rate_hz, t0_s=ping.t0_s - compression_delay_s(ping),
            sound_speed_m_s=self.options.sound_speed_m_s or ping.sound_speed_m_s,
            element_offsets_m=elements - centre, source_offset_m=source - centre,
            centre_frequency_hz=fc or 0.0, weights=weights, band_hz=band,
            min_channels=min_channels_of(self.options.min_channels, record.shape[0]),
            data_token=object())  # one token a ping: the engine uploads its channels once for every stage
        check_grid_reaches_record(inp, self.grid)   # before the setting, which is measured on the record's cells
        picked = None                               # a seabed picked from the channels needs them at once
        if self.options.sediment_speed_m_s is not None and self.options.seabed_depth_m is None and used.any():
            picked = self.analytic_channels(ping, used)
            inp = dataclasses.replace(inp, data=picked, data_token=object())
        profile = self._travel_profile(ping, inp, float(centre[2]))
        # the setting is measured on the array as mounted (no roll, no heave): one setting a line, whichever
        # ping comes first; each ping's beams still follow its own roll and heave (their band limit)
        mounted = dataclasses.replace(inp, element_offsets_m=ping.element_pos_m[used] - centre,
                                      source_offset_m=ping.source_pos_m - centre)
        setting = self.setting(ping.element_pos_m[used] - centre, band, ping, record.shape[1], geometry=mounted,
                               profile=(profile, float(centre[2])))
        # compressed again at a higher rate rather than upsampled: the same channels as with the depth given
        data = picked if picked is not None and setting.upsample == 1 else \
            self.analytic_channels(ping, used, setting.upsample)
        inp = dataclasses.replace(inp, data=data, sample_rate_hz=ping.sample_rate_hz * setting.upsample,
                                  data_token=object())
        return self._with_tables(inp, profile, float(centre[2])), setting

    def setting_of(self, ping: Ping) -> Setting:
        """The setting ``ping`` is imaged with (:meth:`setting` of its prepared channels)."""
        return self._prepare(ping)[1]

    def setting(self, offsets_m: np.ndarray, band_hz, ping: Ping, n_samples: int,
                geometry: BeamformInput | None = None, profile: tuple = (None, 0.0)) -> Setting:
        """Mode, upsampling and beam sampling for a ping of this array, band and sampling
        (:func:`clbeam.imaging.engine.errormodel.choose_setting`; with ``--interp auto`` and
        ``geometry``, the ping's input before upsampling, the cheapest candidate whose errors measured on
        point echoes through that geometry, along rays through ``profile`` (the profile and the grid centre's
        depth, m) where one applies, hold the budget, :mod:`clbeam.imaging.budget`; cached, logged once).

        Parameters
        ----------
        offsets_m : numpy.ndarray
            ``(n_channel, 3)`` positions (m) of the used elements from the grid centre, vessel frame.
        band_hz : (float, float) or None
            Pulse band (Hz); ``None``: up to half the sample rate.
        ping : Ping
            The ping (sample rate, sound speed).
        n_samples : int
            Samples per channel.
        """
        opts = self.options
        forced = None if opts.interp == "auto" else opts.interp
        # a forced mode images every cell directly unless beams are asked for too: it keeps its own results
        beams = opts.beams if not (forced and opts.beams == "auto") else None
        if opts.sediment_speed_m_s is not None and beams == "auto":
            # rays refract at the seabed: the sums jump there in angle and are not band-limited (docs/beams.md)
            beams = None
        if len(offsets_m) == 0:  # no usable channel: the image is empty whatever the setting
            return Setting(forced or "cubic", opts.upsample or 1, None, math.nan, math.nan)
        band = band_hz or (0.0, 0.5 * ping.sample_rate_hz)
        c = opts.sound_speed_m_s or ping.sound_speed_m_s
        across = np.linalg.norm(offsets_m[:, 1:], axis=1)
        # vessel-frame offsets (roll does not change their lengths) to the mm, speed to 1 m/s: one setting a line
        refracted = self.water_profile(ping) is not None and not ping.svp.is_constant
        key = (tuple(band), ping.sample_rate_hz, round(c), across.round(3).tobytes(), n_samples, refracted)
        setting = self._settings.get(key)
        if setting is None:
            predicted = self._predicted(across, band, ping.sample_rate_hz, c, n_samples, beams, refracted)
            setting = choose_setting(predicted, opts.max_error_db, interp=forced,
                                     upsample=opts.upsample or (1 if forced else None), beams=beams)
            # forced beams (straight rays for the frequency domain's) still measure the time interpolation
            measured = beams == "auto" or (isinstance(beams, BeamSampling)
                                           and (beams.domain == "time" or profile[0] is None))
            if geometry is not None and forced is None and measured and opts.upsample is None:
                setting = self._measured_setting(predicted, geometry, band, ping, profile, beams)
            log.info("imaging setting: %s", setting.describe())
            self._settings[key] = setting
        return setting

    def _predicted(self, across_m: np.ndarray, band, sample_rate_hz: float, c: float, n_samples: int, beams,
                   refracted: bool) -> list[Setting]:
        """The error model's settings for elements ``across_m`` (m) from the centre, band (Hz), rate (Hz), sound
        speed (m/s) and record: the candidate beam samplings and a forced one's time-domain twin."""
        span = float(np.deg2rad(np.ptp(self.grid.angles_deg)))
        twin = dataclasses.replace(beams, domain="time") if isinstance(beams, BeamSampling) else None
        samplings = BEAM_CHOICES + ((twin,) if twin is not None and twin not in BEAM_CHOICES else ())
        predicted = predicted_settings(across_m, band, sample_rate_hz, c, n_angles=self.grid.shape[0],
                                       n_ranges=self.grid.shape[1], angle_span_rad=span, n_samples=n_samples,
                                       samplings=samplings)
        if refracted and beams == "auto":
            # the band limit of refracted sums is measured on the tables, not bounded: taps to spare
            predicted = [s for s in predicted if s.beams is None or s.beams.taps >= REFRACTED_MIN_TAPS]
        return predicted

    def _measured_setting(self, predicted: list, geometry: BeamformInput, band, ping: Ping, profile: tuple,
                          beams="auto") -> Setting:
        """The cheapest of the settings predicted within the intensity budget whose errors measured on
        echoes of the ping's pulse through ``geometry`` hold the whole budget
        (:func:`clbeam.imaging.budget.choose_measured_setting`); with forced ``beams`` (a BeamSampling), the
        cheapest time interpolation and upsampling with those beams."""
        opts = self.options
        budget = Budget(max_error_db=opts.max_error_db, max_cf_error=opts.max_cf_error)
        candidates = [s for s in predicted if s.error_db <= opts.max_error_db]
        if isinstance(beams, BeamSampling):
            twin = dataclasses.replace(beams, domain="time")     # the model's bound for either domain
            candidates = [dataclasses.replace(s, beams=beams) for s in predicted
                          if s.beams == twin and s.error_db <= opts.max_error_db]
        replica = ping.pulse.replica(ping.sample_rate_hz) if ping.pulse is not None else None
        key = measurement_key(geometry, self.grid, band, replica, profile, budget, candidates, self.engine)
        setting, measured = remembered_choice(key, lambda: choose_measured_setting(
            candidates, CalibrationScene(geometry, self.grid, band, replica, profile=profile[0],
                                         centre_depth_m=profile[1]), self.engine, budget))
        return dataclasses.replace(setting, measured=measured.describe())

    # -- sound-speed profile ----------------------------------------------
    def water_profile(self, ping: Ping):
        """The ping's sound-speed profile when the travel times follow it, else ``None``."""
        if self.options.use_svp and self.options.sound_speed_m_s is None:
            return ping.svp
        return None

    def _travel_profile(self, ping: Ping, inp: BeamformInput, centre_z_m: float) -> SoundSpeedProfile | None:
        """The profile the travel times follow (the ping's, with the sediment below a given or picked
        seabed), or ``None`` for straight rays."""
        profile = self.water_profile(ping)
        c_sed = self.options.sediment_speed_m_s
        if (profile is None and c_sed is None) or inp.n_channels == 0:  # no channel: the image is empty anyway
            return None
        if profile is None:
            profile = SoundSpeedProfile.constant(inp.sound_speed_m_s)
        elif c_sed is None and not profile.is_constant:   # a constant speed holds at any depth
            check_profile_reaches_grid(profile, self.grid, centre_z_m)
        if c_sed is not None:
            depth = self.options.seabed_depth_m
            if depth is None:
                depth = pick_seabed_depth_m(inp, profile=profile, centre_depth_m=centre_z_m)
            # 1 cm steps: a picked seabed that moves with heave reuses its tables
            profile = SoundSpeedProfile.with_sediment(profile, round(depth + centre_z_m, 2), c_sed)
        return profile

    def _with_tables(self, inp: BeamformInput, profile: SoundSpeedProfile | None, centre_z_m: float) -> BeamformInput:
        """``inp`` with the ray-traced travel-time tables of the grid through ``profile`` (cached per profile
        and grid centre depth), or as it is for straight rays."""
        if profile is None:
            return inp
        return dataclasses.replace(inp, table_source=functools.partial(self._grid_tables, profile, centre_z_m))

    def _grid_tables(self, profile: SoundSpeedProfile, centre_z_m: float, grid: PolarGrid):
        """The travel-time tables of ``grid`` through ``profile`` from a centre at ``centre_z_m``,
        cached per profile, centre depth and grid (the output grid and the internal beam grid)."""
        key = (profile, round(centre_z_m, 6), grid.shape, hash(grid.ranges_m.tobytes()), hash(grid.angles_deg.tobytes()))
        tables = self._tables.get(key)
        if tables is None:
            t0 = time.perf_counter()
            tables = travel_time_tables(profile, grid, centre_z_m)
            log.info("travel-time tables of a %d x %d grid in %.2f s", *grid.shape, time.perf_counter() - t0)
            if len(self._tables) >= 4:  # about 41 bytes per cell each: two output grids, a beam grid and its probe
                self._tables.pop(next(iter(self._tables)))
            self._tables[key] = tables
        return tables

    # -- imaging ----------------------------------------------------------
    def image(self, ping: Ping, *, range_window_m: np.ndarray | None = None) -> PingImage:
        """Image one ping.

        Parameters
        ----------
        ping : Ping
            The ping (see :class:`clbeam.io.pingfile.PingFile`).
        range_window_m : numpy.ndarray, optional
            ``(n_angle, 2)`` ranges (m) to compute per angle (e.g. a seabed
            band); cells outside are 0.
        """
        t = {}
        t_start = time.perf_counter()
        inp, setting = self._prepare(ping)
        t["compress_s"] = time.perf_counter() - t_start
        if inp.n_channels == 0:
            log.warning("ping %d: no usable channel; the image is empty", ping.index)
        if range_window_m is None and self.options.seabed_band_m is not None:
            range_window_m = self._seabed_window(ping, inp)
        check_grid_reaches_record(inp, self.grid)
        self._warn_beyond_record(inp)
        t0 = time.perf_counter()
        outs = set(self.options.outputs)
        sums = self.engine.beamform(inp, self.grid, interp=setting.interp,
                                    outputs=outs | {"intensity"} if "cf" in outs else outs,
                                    range_window_m=range_window_m, beams=setting.beams)
        t["image_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        context = PingContext.of_ping(ping, self.grid, self.options.sound_speed_m_s, n_channels=inp.n_channels)
        cf_smooth = peaks = None
        stages = dict(sums.timings_s)
        if sums.cf is not None:
            cf_smooth = hann_smooth(sums.cf) if range_window_m is None else \
                hann_smooth_in_windows(sums.cf, user_windows(self.grid, range_window_m))
            stages["smooth_s"] = time.perf_counter() - t0
            refine = self._refiner(inp, setting, cf_smooth, sums.intensity)
            peaks = self.peak_rows(context, cf_smooth, sums.intensity, refine=refine)
        t["postprocess_s"] = time.perf_counter() - t0
        if "smooth_s" in stages:
            stages["peaks_s"] = t["postprocess_s"] - stages["smooth_s"]
        return PingImage(ping=ping.index, grid=self.grid,
                         intensity=sums.intensity if "intensity" in outs else None, cf=sums.cf, cf_smooth=cf_smooth,
                         sums=sums if "sums" in outs else None, peaks=peaks or [], context=context, timings_s=t,
                         stages_s=stages,
                         n_channels_used=inp.n_channels, setting=_described(setting, sums))

    def _warn_beyond_record(self, inp: BeamformInput) -> None:
        """A warning, the first time only, when the grid runs past the record's end by more than a range step."""
        excess, end_m = grid_beyond_record_m(inp, self.grid)
        step = float(np.max(np.diff(self.grid.ranges_m))) if self.grid.shape[1] > 1 else 0.0
        if excess > step and not self._warned_beyond:
            self._warned_beyond = True
            log.warning("the grid reaches %.2f m beyond the end of the record (to %.2f m; the record ends at "
                        "%.2f m): fewer channels reach the cells there, and their CF needs at least %d of %d "
                        "channels (--min-channels)", excess, float(self.grid.ranges_m[-1]), end_m,
                        inp.min_channels, inp.n_channels)

    def _seabed_window(self, ping: Ping, inp: BeamformInput) -> np.ndarray:
        """Per-angle ranges of the seabed band around the given or picked seabed."""
        depth = self.options.seabed_depth_m
        if depth is None and inp.n_channels:
            depth = pick_seabed_depth_m(inp, profile=self.water_profile(ping),
                                        centre_depth_m=float(self.grid.centre(tuple(ping.source_pos_m[1:]))[1]))
        if depth is None:  # no usable channel: nothing to pick, the image is empty anyway
            depth = float(self.grid.ranges_m[0])
        return seabed_window_m(self.grid, depth, self.options.seabed_band_m)

    def peak_rows(self, context: PingContext, cf_smooth: np.ndarray, intensity: np.ndarray | None, *,
                  refine=None) -> list:
        """Rows of the peaks table for one ping (docs/peaks.md) with this imager's threshold and MLH
        option (refined with ``refine``, see :func:`clbeam.imaging.peaks.peak_rows`)."""
        return peak_rows(context, cf_smooth, intensity, self.grid, threshold=self.options.threshold,
                         min_snr_db=self.options.min_snr_db, min_contrast_db=self.options.min_contrast_db,
                         mlh=self.options.mlh, refine=refine)

    def _refiner(self, inp: BeamformInput, setting: Setting, cf_smooth: np.ndarray, intensity: np.ndarray | None):
        """``refine(peaks)`` for this ping's peaks, or ``None`` when refinement is off (or MLH is on)."""
        if not self.options.refine_peaks or self.options.mlh or inp.n_channels == 0:
            return None
        mode = interp_mode(setting.interp)
        return functools.partial(subcell_peaks, self.engine, inp, self.grid, mode=mode, cf_smooth=cf_smooth, intensity=intensity,
                                 threshold=self.options.threshold)

    def peak_row_builder(self, img: PingImage):
        """``f(cf_smooth, intensity) -> rows`` for another image of ``img``'s ping (e.g. a stack)."""
        return lambda cf_smooth, intensity: self.peak_rows(img.context, cf_smooth, intensity)


def check_profile_reaches_grid(profile: SoundSpeedProfile, grid: PolarGrid, centre_z_m: float) -> None:
    """Raise :class:`GridError` unless ``profile`` (depths on the earth-frame ``z`` axis, m) reaches the
    deepest cell of ``grid`` (centred ``centre_z_m`` m below the array reference point): below its last
    point the speed would be held at the last value, which for a cast that stops short of the seabed
    images the deeper cells through water nobody measured."""
    theta = np.deg2rad(grid.angles_deg)
    cos_max = 1.0 if theta.min() <= 0.0 <= theta.max() else float(np.max(np.cos(theta)))
    deepest = centre_z_m + float(grid.ranges_m.max()) * max(cos_max, 0.0)
    last = float(profile.depths_m[-1])
    require(last >= deepest, GridError,
            f"the sound-speed profile (svp_depth) ends at {last:g} m but the grid reaches {deepest:.1f} m below the "
            f"array: extend the profile to {math.ceil(deepest):d} m (a last point with the speed to hold), image "
            "a shallower grid, or ignore the profile (--isospeed)")


def _described(setting: Setting, sums) -> str:
    """The setting as the ping was imaged: a beam-sampled setting whose beams would not have saved work
    (a sound-speed profile's travel times, :meth:`Engine.beamform`) was imaged directly."""
    if setting.beams is not None and "direct_s" in sums.timings_s:
        return dataclasses.replace(setting, beams=None).describe() + " (beams off: the profile's travel times)"
    return setting.describe()


def compression_delay_s(ping: Ping) -> float:
    """How late (s) pulse compression puts every echo: the replica's ``tx_delay`` for raw pressure, 0 for
    analytic data (compressed already)."""
    if ping.kind == "raw" and ping.pulse is not None:
        return float(ping.pulse.delay_s)
    return 0.0


def compression_precision(samples: np.ndarray, engine_precision: str) -> str:
    """Pulse compression in float32 for a float32 engine, unless the samples' magnitudes (beyond
    1e-25 to 1e25) would under- or overflow float32 FFT sums: then float64 (the engine scales after)."""
    if engine_precision != "float32" or samples.size == 0:
        return "float64"
    with np.errstate(invalid="ignore"):
        peak = float(np.nanmax(np.abs(samples))) if np.isfinite(samples).any() else 0.0
    return "float32" if 1e-25 < peak < 1e25 else "float64"


def check_grid_fits_memory(grid: PolarGrid, options: ImagingOptions, *, fraction: float = 0.5) -> None:
    """Raise :class:`GridError` when one ping's output arrays would need more
    than ``fraction`` of this machine's memory (host memory per ping is about
    ``n_cells x`` 8 bytes per output plus 16 for CF smoothing and peaks, plus
    106 for ray-traced travel times when a ping may carry a profile)."""
    per_cell = 8 * (len(options.outputs) + 3 * ("sums" in options.outputs)) + 16
    if options.use_svp or options.sediment_speed_m_s is not None:
        per_cell += 2 * 41 + 24  # two cached travel-time table sets and the kernel's per-cell copy
    need = grid.n_cells * per_cell
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return
    require(need <= fraction * total, GridError,
            f"a grid of {grid.shape[0]} angles x {grid.shape[1]} ranges ({grid.n_cells:.3g} cells) needs "
            f"{need / 2**30:.1f} GiB per ping, more than {fraction:.0%} of this machine's {total / 2**30:.1f} GiB; "
            "use a coarser grid or a smaller window")


def grid_beyond_record_m(inp: BeamformInput, grid: PolarGrid) -> tuple[float, float]:
    """How far (m) the grid's last range lies beyond the range the record reaches, ``c (t0 + n / fs) / 2``
    (as :meth:`clbeam.io.pingfile.PingFile.max_record_range_m`), and that range (m)."""
    end_m = 0.5 * inp.sound_speed_m_s * (inp.t0_s + inp.n_samples / inp.sample_rate_hz)
    return max(0.0, float(grid.ranges_m[-1]) - end_m), end_m


def check_grid_reaches_record(inp: BeamformInput, grid: PolarGrid) -> None:
    """Raise :class:`GridError` when no cell of ``grid`` can be imaged from
    the record (every travel time before its first or after its last sample)."""
    win = cell_windows(inp, grid, interp_mode("nearest"))
    if inp.n_channels and not np.any(win[:, 1] > win[:, 0]):
        t_end = inp.t0_s + (inp.n_samples - 1) / inp.sample_rate_hz
        c = inp.sound_speed_m_s
        raise GridError(f"grid ranges {grid.ranges_m[0]:g}-{grid.ranges_m[-1]:g} m lie outside the record, which "
                        f"reaches ranges {0.5 * c * inp.t0_s:g}-{0.5 * c * t_end:g} m")


__all__ = ["Imager", "ImagingOptions", "PingImage", "check_grid_fits_memory", "check_grid_reaches_record",
           "grid_beyond_record_m", "min_channels_of"]
