"""The scene: what a simulated survey looks like, one frozen dataclass per TOML table.

A :class:`Scene` gathers the sonar (:class:`Sonar`), the recording window
(:class:`Record`), the line (:class:`Survey`), the ship's motion
(:class:`Motion`), the water column (:class:`Water`), the seabed
(:class:`Seabed`, its :class:`Scattering` and :class:`Province` tables),
the sub-bottom (:class:`SubBottom`), the targets (:class:`PointTarget`,
:class:`LineTarget`), the numerical choices and the physics (:class:`Model`)
and the discrete-scatterer statistics (:class:`Discrete`).  Each
validates its values on construction and names the scene key of a bad one
(:class:`clbeam.errors.OptionError`).  None reads files or synthesises
anything: the TOML loader (:mod:`clbeam.sim.catalog`) builds them and every
synthesiser of the simulator reads them.

Frames (docs/ping-format.md): vessel ``x`` forward, ``y`` starboard, ``z`` down; the
track frame has ``x`` along the track from the first ping's position.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from clbeam.constants import (
    KNOT_M_S,
    SBP29_ARRAY_WIDTH_M,
    SBP29_BAND_HZ,
    SBP29_N_ELEMENTS,
    SBP29_PULSE_DURATION_S,
    SBP29_SAMPLE_RATE_HZ,
    SBP29_TX_LENGTH_M,
    SOUND_SPEED_M_S,
    WATER_SPEED_RANGE_M_S,
)
from clbeam.errors import OptionError, require
from clbeam.model.pulse import lfm_replica
from clbeam.model.svp import SoundSpeedProfile


@dataclass(frozen=True)
class Sonar:
    """The sonar: receive array, transmit column, pulse, sampling.

    Attributes
    ----------
    n_elements : int
        Receive elements across-track (SBP29: 64).
    array_width_m : float
        Receive array width (m); element pitch is ``width / n``, centres at
        ``(n - (N-1)/2) · pitch`` on ``y``, ``x = z = 0``.
    tx_length_m : float
        Length of the transmit column along ``x`` (m); 16 of 32 elements of a
        7 m column in the paper: 3.5 m.
    source_offset_m : tuple of float
        Transmit acoustic centre ``(x, y, z)`` in the vessel frame (m).
    draft_m : float
        Depth of the transducers below the sea surface (m).
    sample_rate_hz : float
        Sample rate (Hz).
    pulse_f0_hz, pulse_f1_hz, pulse_duration_s : float
        LFM start and end frequency (Hz) and length (s).
    """

    n_elements: int = SBP29_N_ELEMENTS
    array_width_m: float = SBP29_ARRAY_WIDTH_M
    tx_length_m: float = SBP29_TX_LENGTH_M
    source_offset_m: tuple = (0.0, 0.0, 0.0)
    draft_m: float = 5.0
    sample_rate_hz: float = SBP29_SAMPLE_RATE_HZ
    pulse_f0_hz: float = SBP29_BAND_HZ[0]
    pulse_f1_hz: float = SBP29_BAND_HZ[1]
    pulse_duration_s: float = SBP29_PULSE_DURATION_S

    def __post_init__(self):
        require(self.n_elements >= 1, OptionError, f"sonar.n_elements must be >= 1, got {self.n_elements}")
        require(self.array_width_m > 0, OptionError, f"sonar.array_width_m must be > 0 m, got {self.array_width_m}")
        require(self.tx_length_m > 0, OptionError, f"sonar.tx_length_m must be > 0 m, got {self.tx_length_m}")
        require(len(self.source_offset_m) == 3, OptionError,
                f"sonar.source_offset_m must be [x, y, z] in m, got {list(self.source_offset_m)}")
        require(self.draft_m >= 0, OptionError, f"sonar.draft_m must be >= 0 m, got {self.draft_m}")
        require(0 < self.pulse_f0_hz < self.pulse_f1_hz, OptionError,
                f"sonar pulse band must satisfy 0 < pulse_f0_hz < pulse_f1_hz, got {self.pulse_f0_hz}-{self.pulse_f1_hz} Hz")
        require(self.sample_rate_hz >= 2.5 * self.pulse_f1_hz, OptionError,
                f"sonar.sample_rate_hz must be >= 2.5 × pulse_f1_hz = {2.5 * self.pulse_f1_hz:g} Hz "
                f"(band-limited delays), got {self.sample_rate_hz:g}")
        require(self.pulse_duration_s > 0, OptionError, f"sonar.pulse_duration_s must be > 0 s, got {self.pulse_duration_s}")

    @property
    def centre_frequency_hz(self) -> float:
        """Band centre ``(f0 + f1) / 2`` (Hz)."""
        return 0.5 * (self.pulse_f0_hz + self.pulse_f1_hz)

    def element_positions_m(self) -> np.ndarray:
        """``(n_elements, 3)`` receive element positions in the vessel frame (m)."""
        pitch = self.array_width_m / self.n_elements
        pos = np.zeros((self.n_elements, 3))
        pos[:, 1] = (np.arange(self.n_elements) - (self.n_elements - 1) / 2) * pitch
        return pos

    def replica(self) -> np.ndarray:
        """The transmit replica at the sample rate (unit amplitude)."""
        return lfm_replica(f0_hz=self.pulse_f0_hz, f1_hz=self.pulse_f1_hz, duration_s=self.pulse_duration_s,
                           sample_rate_hz=self.sample_rate_hz)


@dataclass(frozen=True)
class Record:
    """The recording window of every ping.

    Attributes
    ----------
    max_range_m : float or None
        Largest one-way slant range (m) whose whole echo is recorded: the
        record ends at ``2 R / c + pulse_duration``.  ``None``: the farthest
        target's slant range over the pings plus 50 m (at least the first
        multiple when there is a seabed).
    start_s : float
        Time of sample 0 after transmit start (s), the file's ``t0``.
    """

    max_range_m: float | None = None
    start_s: float = 0.0

    def __post_init__(self):
        require(self.max_range_m is None or self.max_range_m > 0, OptionError,
                f"record.max_range_m must be > 0 m, got {self.max_range_m}")
        require(self.start_s >= 0, OptionError, f"record.start_s must be >= 0 s, got {self.start_s}")


@dataclass(frozen=True)
class Survey:
    """The line: pings, ship speed and heading, navigation origin.

    Attributes
    ----------
    pings : int
        Pings on the line.
    ping_interval_s : float
        Time between pings (s).
    speed_knots : float
        Ship speed (kn); the ship moves ``speed · interval`` along ``x``
        between pings (4 kn, 4 s: 8.23 m).
    heading_deg : float
        Ship heading, clockwise from north (degree).
    latitude_deg, longitude_deg : float
        Position of the first ping (degree).
    start_time : str
        ISO 8601 time of the first ping (UTC).
    """

    pings: int = 1
    ping_interval_s: float = 4.0
    speed_knots: float = 4.0
    heading_deg: float = 0.0
    latitude_deg: float = 34.3
    longitude_deg: float = -119.8
    start_time: str = "2022-08-28T18:00:00"

    def __post_init__(self):
        require(self.pings >= 1, OptionError, f"survey.pings must be >= 1, got {self.pings}")
        require(self.ping_interval_s > 0, OptionError, f"survey.ping_interval_s must be > 0 s, got {self.ping_interval_s}")
        require(self.speed_knots >= 0, OptionError, f"survey.speed_knots must be >= 0, got {self.speed_knots}")
        require(abs(self.latitude_deg) < 89, OptionError, f"survey.latitude_deg must be within ±89, got {self.latitude_deg}")
        try:
            np.datetime64(self.start_time, "ns")
        except ValueError:
            raise OptionError(f"survey.start_time must be an ISO 8601 time, got {self.start_time!r}") from None

    @property
    def step_m(self) -> float:
        """Distance run between pings (m)."""
        return self.speed_knots * KNOT_M_S * self.ping_interval_s


@dataclass(frozen=True)
class Motion:
    """Ship motion: sinusoidal roll, pitch and heave sampled at the ping times.

    ``roll(t) = roll_mean + roll_amplitude · sin(2π t / roll_period)``;
    pitch and heave likewise with phases 1 and 2 rad so that the three are
    not in step.  Roll is positive starboard down, pitch positive bow up,
    heave positive up (docs/ping-format.md).  Pitch only steers the transmit beam
    along-track (the elements lie on ``x = 0``); the imager ignores it.
    """

    roll_mean_deg: float = 0.0
    roll_amplitude_deg: float = 0.0
    roll_period_s: float = 9.0
    pitch_mean_deg: float = 0.0
    pitch_amplitude_deg: float = 0.0
    pitch_period_s: float = 6.0
    heave_amplitude_m: float = 0.0
    heave_period_s: float = 7.0

    def __post_init__(self):
        for name in ("roll_period_s", "pitch_period_s", "heave_period_s"):
            require(getattr(self, name) > 0, OptionError, f"motion.{name} must be > 0 s, got {getattr(self, name)}")
        require(abs(self.roll_mean_deg) + abs(self.roll_amplitude_deg) <= 30, OptionError,
                "motion roll (mean + amplitude) must stay within ±30 degrees")

    def at(self, time_s: float) -> tuple[float, float, float]:
        """``(roll_deg, pitch_deg, heave_m)`` at ``time_s`` (s) after the first ping."""
        w = 2 * np.pi * time_s
        roll = self.roll_mean_deg + self.roll_amplitude_deg * np.sin(w / self.roll_period_s)
        pitch = self.pitch_mean_deg + self.pitch_amplitude_deg * np.sin(w / self.pitch_period_s + 1.0)
        heave = self.heave_amplitude_m * np.sin(w / self.heave_period_s + 2.0)
        return float(roll), float(pitch), float(heave)


@dataclass(frozen=True)
class Scattering:
    """Diffuse scattering of a rough interface, as random point scatterers.

    The backscattering cross-section per unit area and solid angle is
    ``σ(θ) = 10^(strength_db/10) · sin^m θ`` (``θ`` grazing, ``m`` the
    grazing exponent; Lambert's law is ``m = 2``).  A scatterer standing for
    an area ``1/n`` (``n`` the local density) gets amplitude
    ``g · sqrt(σ / n)`` with ``g`` standard normal, so the mean intensity is
    independent of the density.

    Attributes
    ----------
    strength_db : float
        ``10 log10 μ`` (dB re 1 m² per m² per steradian).
    grazing_exponent : float
        ``m``, 1 to 4.
    per_cell : float
        Expected scatterers in one range-resolution cell ``c / (2 B)`` of the
        insonified strip on each side (counted with the beam-envelope weight).
    depth_spread_m : float
        RMS vertical jitter of the scatterers about the interface (m).
    """

    strength_db: float = -30.0
    grazing_exponent: float = 2.0
    per_cell: float = 1.0
    depth_spread_m: float = 0.05

    def __post_init__(self):
        require(1 <= self.grazing_exponent <= 4, OptionError,
                f"scattering.grazing_exponent must be within 1-4, got {self.grazing_exponent}")
        require(0 < self.per_cell <= 50, OptionError, f"scattering.per_cell must be within (0, 50], got {self.per_cell}")
        require(self.depth_spread_m >= 0, OptionError, f"scattering.depth_spread_m must be >= 0 m, got {self.depth_spread_m}")


#: the deepest spread of the discrete seabed's scatterers about the interface (m): they are taken as the
#: interface's, in the water's travel times, which holds to a small fraction of the band's wavelengths
SEABED_SPREAD_MAX_M = 0.5
PHYSICS_MODELS = ("specular", "discrete")
"""Values of ``model.physics``: the smooth-pipe and importance-sampled model, or discrete point scatterers."""
TX_PATTERNS = ("band", "centre")
"""Values of ``discrete.tx_pattern``: the transmit column's pattern at every frequency, or at the band centre."""

SPECULAR_MODELS = ("impedance", "forward")
"""Values of ``seabed.specular_model``."""


@dataclass(frozen=True)
class Province:
    """A stretch of the track whose seabed scatters as a sediment of grain size ``mz``.

    The seabed scatterers whose along-track world position lies from
    ``from_along_track_m`` up to the next province's start get the
    backscattering strength of the APL-UW TR 9407 model
    (:func:`clbeam.seabed.avo.backscatter_strength_db`) at their grazing angle and
    the band centre frequency, in place of the ``sin^m`` law.  The first
    province also covers everything before its start, the last everything
    after it.

    Attributes
    ----------
    from_along_track_m : float
        Start of the province: distance along the track from the first
        ping's position (m).
    mz : float
        Mean grain size (phi), -1 to 9 (TR 9407 regressions): 1.5 medium
        sand, 4.5 coarse silt, 6 medium silt, 8 clay.
    """

    from_along_track_m: float = 0.0
    mz: float = 1.5

    def __post_init__(self):
        require(-1.0 <= self.mz <= 9.0, OptionError, f"seabed.province mz must be within -1 to 9 phi, got {self.mz}")


@dataclass(frozen=True)
class Seabed:
    """The water-sediment interface and the sediment above the sub-bottom.

    The seabed is a plane: depth below the sea surface ``depth_m`` under the
    first ping, tilted by ``slope_along_deg`` (deeper ahead) and
    ``slope_across_deg`` (deeper to starboard).

    Attributes
    ----------
    depth_m : float
        Water depth (m) under the first ping.
    slope_along_deg, slope_across_deg : float
        Seabed slopes (degree).
    sound_speed_ratio, density_ratio : float
        Sediment sound speed and density relative to water.
    attenuation_db_per_m, attenuation_ref_hz : float
        Sediment attenuation at the reference frequency, linear in frequency.
    specular : bool
        Include the nadir specular reflection (image source).
    specular_model : {"impedance", "forward"}
        Reflection coefficients of the specular echoes and multiples:
        ``"impedance"`` the flat-interface impedance contrasts (real,
        frequency independent); ``"forward"`` the layered coherent forward
        model (:func:`clbeam.seabed.forward.specular_echoes` at normal incidence):
        frequency dependent, with the sediment's attenuation and the
        interfaces' roughness loss (Eckart).
    roughness_m : float
        RMS height of the seabed's roughness (m) for the forward model's
        coherent loss; ignored by ``"impedance"``.
    multiple : bool
        Include the first surface multiple (and its doublet with the sub-bottom).
    scattering : Scattering or None
        Diffuse interface scattering.
    province : tuple of Province
        Provinces along the track (``[[seabed.province]]`` tables, starts
        increasing) whose scattering strength follows the AVO backscatter
        model for their grain size (:class:`Province`); they need a
        ``[seabed.scattering]`` table for the scatterer density and jitter.
        Empty: the ``sin^m`` law everywhere.
    province_impedance : bool
        The nadir specular echo and its multiples reflect with the
        impedance of the province under the ship (the TR 9407 density and
        sound-speed ratios of its grain size, :mod:`clbeam.seabed.avo.sediment`)
        in place of ``density_ratio`` and ``sound_speed_ratio``; needs
        provinces and ``specular_model = "impedance"``.
    """

    depth_m: float = 230.0
    slope_along_deg: float = 0.0
    slope_across_deg: float = 0.0
    sound_speed_ratio: float = 0.98
    density_ratio: float = 1.25
    attenuation_db_per_m: float = 0.15
    attenuation_ref_hz: float = 5000.0
    specular: bool = True
    specular_model: str = "impedance"
    roughness_m: float = 0.0
    multiple: bool = True
    scattering: Scattering | None = None
    province: tuple[Province, ...] = ()
    province_impedance: bool = False

    def __post_init__(self):
        require(self.depth_m > 0, OptionError, f"seabed.depth_m must be > 0 m, got {self.depth_m}")
        require(abs(self.slope_along_deg) <= 10 and abs(self.slope_across_deg) <= 10, OptionError,
                "seabed slopes must be within ±10 degrees")
        require(0.5 <= self.sound_speed_ratio <= 1.0, OptionError,
                f"seabed.sound_speed_ratio must be within 0.5-1.0 (slower sediment; no critical angle), "
                f"got {self.sound_speed_ratio}")
        require(self.density_ratio > 0, OptionError, f"seabed.density_ratio must be > 0, got {self.density_ratio}")
        require(self.attenuation_db_per_m >= 0 and self.attenuation_ref_hz > 0, OptionError,
                "seabed attenuation must be >= 0 dB/m at a reference frequency > 0 Hz")
        require(self.specular_model in SPECULAR_MODELS, OptionError,
                f"seabed.specular_model must be one of {', '.join(SPECULAR_MODELS)}, got {self.specular_model!r}")
        require(self.roughness_m >= 0, OptionError, f"seabed.roughness_m must be >= 0 m, got {self.roughness_m}")
        starts = [p.from_along_track_m for p in self.province]
        require(all(b > a for a, b in zip(starts, starts[1:])), OptionError,
                f"seabed.province from_along_track_m must increase, got {starts}")
        require(not self.province or self.scattering is not None, OptionError,
                "seabed.province needs a [seabed.scattering] table (scatterer density and jitter)")
        require(not self.province_impedance or (self.province and self.specular_model == "impedance"),
                OptionError, "seabed.province_impedance needs [[seabed.province]] tables and "
                             "specular_model = \"impedance\"")


@dataclass(frozen=True)
class SubBottom:
    """A sub-bottom reflector parallel to the seabed.

    Attributes
    ----------
    depth_below_seabed_m : float
        Thickness of the sediment layer above it (m).
    sound_speed_ratio, density_ratio : float
        The lower medium relative to water (for the nadir reflection coefficient).
    specular : bool
        Include its nadir specular reflection.
    roughness_m : float
        RMS height of its roughness (m), for ``seabed.specular_model =
        "forward"``.
    scattering : Scattering or None
        Diffuse scattering of this interface.
    """

    depth_below_seabed_m: float = 20.0
    sound_speed_ratio: float = 1.05
    density_ratio: float = 1.6
    specular: bool = True
    roughness_m: float = 0.0
    scattering: Scattering | None = None

    def __post_init__(self):
        require(self.depth_below_seabed_m > 0, OptionError,
                f"subbottom.depth_below_seabed_m must be > 0 m, got {self.depth_below_seabed_m}")
        require(self.sound_speed_ratio > 0 and self.density_ratio > 0, OptionError,
                "subbottom sound_speed_ratio and density_ratio must be > 0")
        require(self.roughness_m >= 0, OptionError, f"subbottom.roughness_m must be >= 0 m, got {self.roughness_m}")


@dataclass(frozen=True)
class PointTarget:
    """An omnidirectional point scatterer fixed in the world.

    Position in the track frame: ``x_m`` along the track from the first
    ping's position, ``y_m`` to starboard of the track, depth ``z_m`` below
    the transducers' mean depth, or ``burial_m`` below the seabed.

    Attributes
    ----------
    amplitude_m : float
        ``a`` (m): the echo is ``a / (|r - s| |r - e_n|)`` times the replica.
    """

    name: str = "point"
    x_m: float = 0.0
    y_m: float = 0.0
    z_m: float | None = None
    burial_m: float | None = None
    amplitude_m: float = 1.0

    def __post_init__(self):
        require((self.z_m is None) != (self.burial_m is None), OptionError,
                f"target '{self.name}': give exactly one of z_m or burial_m")
        require(self.burial_m is None or self.burial_m > 0, OptionError,
                f"target '{self.name}': burial_m must be > 0 m, got {self.burial_m}")


@dataclass(frozen=True)
class LineTarget:
    """A pipeline: a circular arc of omnidirectional points in the world.

    The arc passes through ``(x_m, y_m)`` (track frame) with heading
    ``angle_deg`` relative to the track (positive: turning to starboard as
    ``x`` grows) and changes heading by ``curvature_deg_per_km`` per km of
    pipe.  Its axis lies ``burial_m`` below the seabed (or at depth ``z_m``).

    Each point stands for a length ``Δs`` of pipe; the echo per unit length
    is ``reflectivity · sqrt(a / (2 λ)) · G(ka)`` with
    ``G(ka) = (ka)^1.5 / sqrt(1 + (ka)^3)``: the geometric-regime strength of
    a straight cylinder (intensity ∝ ka, Stanton 1989) falling to Rayleigh's
    ``(ka)^4`` below ``ka = 1``.  ``k`` is the wavenumber where the pipe lies.

    Attributes
    ----------
    radius_m : float
        Pipe radius ``a`` (m): 0.11 in the paper.
    reflectivity : float
        Scale of the echo (a reflection coefficient for a rigid or steel pipe).
    gap_x_m : tuple of float
        ``(x0, x1)``: no pipe between these track-frame ``x`` (m), e.g. a
        stretch washed away or lying too deep to see; empty: none.
    roughness : float
        Relative standard deviation of the echo from point to point (field
        joints, coating, marine growth): the incoherent part that scatters
        away from the specular direction and shows a pipe that crosses the
        track obliquely, whose specular point lies outside the transmit
        beam.  0: a smooth pipe.
    """

    name: str = "pipe"
    x_m: float = 0.0
    y_m: float = 0.0
    angle_deg: float = 0.0
    curvature_deg_per_km: float = 0.0
    radius_m: float = 0.11
    burial_m: float | None = None
    z_m: float | None = None
    reflectivity: float = 0.8
    gap_x_m: tuple = ()
    roughness: float = 0.0

    def __post_init__(self):
        require(self.roughness >= 0, OptionError, f"target '{self.name}': roughness must be >= 0, got {self.roughness}")
        require(len(self.gap_x_m) in (0, 2) and (not self.gap_x_m or self.gap_x_m[0] < self.gap_x_m[1]),
                OptionError, f"target '{self.name}': gap_x_m must be [x0, x1] with x0 < x1, got {list(self.gap_x_m)}")
        if self.z_m is None and self.burial_m is None:  # the paper's pipes: 1 m below the seabed
            object.__setattr__(self, "burial_m", 1.0)
        require((self.z_m is None) != (self.burial_m is None), OptionError,
                f"target '{self.name}': give exactly one of z_m or burial_m")
        require(abs(self.angle_deg) < 60, OptionError,
                f"target '{self.name}': angle_deg to the track must be within ±60 degrees, got {self.angle_deg}")
        require(self.radius_m > 0, OptionError, f"target '{self.name}': radius_m must be > 0 m, got {self.radius_m}")

    def response(self, f_hz: np.ndarray, sound_speed_m_s: float) -> np.ndarray:
        """Echo per unit length and unit ``reflectivity`` at ``f_hz``: ``sqrt(a f / (2 c)) G(ka)``."""
        f = np.asarray(f_hz, dtype=np.float64)
        ka = 2 * np.pi * f * self.radius_m / sound_speed_m_s
        return np.sqrt(self.radius_m * f / (2 * sound_speed_m_s)) * ka ** 1.5 / np.sqrt(1 + ka ** 3)


@dataclass(frozen=True)
class Model:
    """Numerical choices.

    Attributes
    ----------
    tx_beam_cut : float
        Scatterers whose along-track direction cosine ``|u|`` exceeds this
        multiple of the first null at the lowest frequency (``λ(f0) / L``;
        0.214 for 3.5 m at 2 kHz) are left out; amplitudes taper to zero
        over the last quarter (a cosine), so truncated lines leave no end echo.
    attenuation_cut_db : float
        Buried scatterers attenuated by more than this at the band centre
        (two-way, dB) are left out.
    line_spacing_m : float or None
        Point spacing along lines (m).  ``None``: a quarter of the shortest
        wavelength in the band (at 1.05 f1) divided by the largest direction
        cosine of a ray on the pipe inside the beam, so the phase step between
        points never exceeds π/2 on any ray.
    physics : {"specular", "discrete"}
        How the pipes and the rough interfaces scatter.  ``"specular"``: a
        pipe is a smooth cylinder's coherent echo (its ``ka`` response, with
        ``roughness`` as weights on it) and the interfaces are
        importance-sampled fields (``per_cell``).  ``"discrete"``: seabed,
        sub-bottom and pipes are fields of independent point scatterers with
        Rayleigh amplitudes and uniform phases whose statistics the
        ``[discrete]`` table sets (:class:`Discrete`, :mod:`clbeam.sim.discrete`).
    """

    tx_beam_cut: float = 1.0
    attenuation_cut_db: float = 40.0
    line_spacing_m: float | None = None
    physics: str = "specular"

    def __post_init__(self):
        require(self.physics in PHYSICS_MODELS, OptionError,
                f"model.physics must be one of {', '.join(PHYSICS_MODELS)}, got {self.physics!r}")
        require(0 < self.tx_beam_cut <= 3, OptionError, f"model.tx_beam_cut must be within (0, 3], got {self.tx_beam_cut}")
        require(self.attenuation_cut_db > 0, OptionError, f"model.attenuation_cut_db must be > 0, got {self.attenuation_cut_db}")
        require(self.line_spacing_m is None or self.line_spacing_m > 0, OptionError,
                f"model.line_spacing_m must be > 0 m, got {self.line_spacing_m}")


@dataclass(frozen=True)
class Discrete:
    """Statistics of the discrete-scatterer physics (``model.physics = "discrete"``, :mod:`clbeam.sim.discrete`).

    Every scatterer has a complex amplitude ``A = s · w`` with ``w`` circular complex Gaussian
    (``E|w|² = 1``: a Rayleigh magnitude and a uniform phase) and ``s²`` its mean power: for an
    interface ``σ(θ) / n`` (``σ`` the interface's backscattering cross-section per unit area and
    solid angle at the grazing angle ``θ``, from its ``scattering`` table; ``n`` the density), so the
    mean intensity does not depend on the density; for a pipe ``ρ² · 2a · μ_p · Δs`` (``ρ`` its
    ``reflectivity``, ``a`` its radius, ``μ_p`` the pipe's strength, ``Δs`` the spacing).

    Attributes
    ----------
    seabed_density_per_m2, subbottom_density_per_m2 : float
        Scatterers per m² of the seabed and of the sub-bottom horizon (a Poisson field).
    seabed_depth_m, subbottom_depth_m : float
        Half-width of the uniform depth spread about the interface (m): ``±`` this.
    pipe_spacing_m : float
        Spacing of the scatterers along a pipe's axis (m).
    pipe_strength_db : float
        ``10 log10 μ_p``: backscattering strength of the pipe per unit of its diameter and length
        (dB re 1 m² per m² per steradian), isotropic.
    tx_pattern : {"band", "centre"}
        The transmit column's along-track pattern ``sinc(L f u / c)``: at every frequency of the
        band (``"band"``, the line aperture's exact far field) or at the band centre only, as one
        real weight per scatterer (``"centre"``).
    """

    seabed_density_per_m2: float = 0.06
    seabed_depth_m: float = 0.05
    subbottom_density_per_m2: float = 0.06
    subbottom_depth_m: float = 0.1
    pipe_spacing_m: float = 0.1
    pipe_strength_db: float = 0.0
    tx_pattern: str = "band"

    def __post_init__(self):
        for key in ("seabed_density_per_m2", "subbottom_density_per_m2"):
            v = getattr(self, key)
            require(0 < v <= 10, OptionError, f"discrete.{key} must be within (0, 10] per m², got {v}")
        # the seabed's scatterers are the interface's (no refraction, transmission or attenuation): a spread
        # deeper than a few wavelengths' fraction would put buried scatterers in the water
        require(0 <= self.seabed_depth_m <= SEABED_SPREAD_MAX_M, OptionError,
                f"discrete.seabed_depth_m must be within 0-{SEABED_SPREAD_MAX_M:g} m (the seabed's scatterers are "
                f"taken as the interface's, not buried), got {self.seabed_depth_m}")
        require(0 <= self.subbottom_depth_m <= 5, OptionError,
                f"discrete.subbottom_depth_m must be within 0-5 m, got {self.subbottom_depth_m}")
        require(0.005 <= self.pipe_spacing_m <= 2, OptionError,
                f"discrete.pipe_spacing_m must be within 0.005-2 m, got {self.pipe_spacing_m}")
        require(-60 <= self.pipe_strength_db <= 20, OptionError,
                f"discrete.pipe_strength_db must be within -60 to 20 dB, got {self.pipe_strength_db}")
        require(self.tx_pattern in TX_PATTERNS, OptionError,
                f"discrete.tx_pattern must be one of {', '.join(TX_PATTERNS)}, got {self.tx_pattern!r}")


@dataclass(frozen=True)
class Water:
    """The water column's sound-speed profile (``[water]``).

    Depths are on the earth-frame ``z`` axis, like ``element_z``: metres
    below the transducers' mean depth (the array reference point), positive
    down; the sea surface is at ``z = -draft``.  The speed is linear in depth
    between points and constant beyond the first and the last
    (:class:`clbeam.model.svp.SoundSpeedProfile`).  Below the seabed the
    sediment's speed (``seabed.sound_speed_ratio`` times the profile's speed
    at the seabed) replaces it.

    Attributes
    ----------
    svp_depth_m : tuple of float
        Profile depths (m), strictly increasing.
    svp_speed_m_s : tuple of float
        Sound speed at each depth (m/s), within
        :data:`clbeam.constants.WATER_SPEED_RANGE_M_S` (1300-1700).
    """

    svp_depth_m: tuple = ()
    svp_speed_m_s: tuple = ()

    def __post_init__(self):
        d, c = (v.tolist() if isinstance(v, np.ndarray) else v for v in (self.svp_depth_m, self.svp_speed_m_s))
        for key, v in (("svp_depth_m", d), ("svp_speed_m_s", c)):
            require(isinstance(v, (list, tuple)) and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                         for x in v), OptionError,
                    f"scene key 'water.{key}' must be a list of numbers, got {v!r}")
            require(len(v) >= 1, OptionError,
                    f"scene key 'water.{key}' needs at least one value (a sound-speed profile)")
            require(all(math.isfinite(x) for x in v), OptionError,
                    f"scene key 'water.{key}' must be finite, got {list(v)}")
        require(len(d) == len(c), OptionError,
                f"water.svp_depth_m has {len(d)} depths but water.svp_speed_m_s has {len(c)} speeds")
        lo, hi = WATER_SPEED_RANGE_M_S
        for z, v in zip(d, c):
            require(lo <= v <= hi, OptionError,
                    f"water.svp_speed_m_s must be within {lo:g}-{hi:g} m/s, got {v:g} at depth {z:g} m")
        for a, b in zip(d, d[1:]):
            require(b > a, OptionError, f"water.svp_depth_m must increase strictly, got {a:g} followed by {b:g} m")
        object.__setattr__(self, "svp_depth_m", tuple(float(x) for x in d))
        object.__setattr__(self, "svp_speed_m_s", tuple(float(x) for x in c))

    def profile(self) -> SoundSpeedProfile:
        """The profile as a :class:`clbeam.model.svp.SoundSpeedProfile`."""
        return SoundSpeedProfile(np.array(self.svp_depth_m), np.array(self.svp_speed_m_s))

    @property
    def transducer_speed_m_s(self) -> float:
        """The profile's speed at the transducers (``z = 0``, m/s)."""
        return float(self.profile().speed(0.0))


@dataclass(frozen=True)
class Scene:
    """A whole scene: sonar, line, motion, environment, targets, noise.

    Attributes
    ----------
    sound_speed_m_s : float
        Isospeed water sound speed (m/s); with a ``[water]`` profile, the
        profile's speed at the transducers (``z = 0``), which a scene file
        may leave out.
    water : Water or None
        Sound-speed profile; ``None``: isospeed water at ``sound_speed_m_s``
        (straight rays).
    discrete : Discrete or None
        Statistics of the discrete-scatterer physics; filled with the defaults when
        ``model.physics = "discrete"`` and left out, an error otherwise.
    snr_db : float or None
        Noise level: ``20 log10(A_ref / σ)``, ``σ`` the standard deviation of
        the white Gaussian noise per raw sample and ``A_ref`` the raw
        amplitude of a reference echo (:meth:`clbeam.sim.simulator.Simulator.reference_amplitude`:
        the nadir seabed echo, or the first target's echo when there is no
        seabed).  ``None``: no noise.
    """

    name: str = "custom"
    description: str = ""
    sound_speed_m_s: float = SOUND_SPEED_M_S
    snr_db: float | None = None
    sonar: Sonar = field(default_factory=Sonar)
    record: Record = field(default_factory=Record)
    survey: Survey = field(default_factory=Survey)
    motion: Motion = field(default_factory=Motion)
    seabed: Seabed | None = None
    subbottom: SubBottom | None = None
    targets: tuple = ()
    model: Model = field(default_factory=Model)
    water: Water | None = None
    discrete: Discrete | None = None

    def __post_init__(self):
        lo, hi = WATER_SPEED_RANGE_M_S
        require(lo <= self.sound_speed_m_s <= hi, OptionError,
                f"sound_speed_m_s must be within {lo:g}-{hi:g} m/s, got {self.sound_speed_m_s}")
        if self.water is not None:
            c0 = self.water.transducer_speed_m_s
            require(abs(self.sound_speed_m_s - c0) <= 1e-6, OptionError,
                    f"sound_speed_m_s {self.sound_speed_m_s:g} m/s is not the [water] profile's speed at the "
                    f"transducers (z = 0), {c0:.10g} m/s: leave sound_speed_m_s out (or set it to that)")
        require(self.subbottom is None or self.seabed is not None, OptionError,
                "a [subbottom] needs a [seabed]")
        require(self.discrete is None or self.model.physics == "discrete", OptionError,
                f"a [discrete] table needs model.physics = \"discrete\" (got {self.model.physics!r})")
        if self.model.physics == "discrete":
            if self.discrete is None:
                object.__setattr__(self, "discrete", Discrete())
            require(self.seabed is None or not self.seabed.province, OptionError,
                    "seabed.province is not available with model.physics = \"discrete\" (a [seabed.scattering] "
                    "law sets its scatterers' strength)")
            if self.subbottom is not None:
                require(self.discrete.subbottom_depth_m < self.subbottom.depth_below_seabed_m, OptionError,
                        f"discrete.subbottom_depth_m ({self.discrete.subbottom_depth_m:g} m) must be less than "
                        f"subbottom.depth_below_seabed_m ({self.subbottom.depth_below_seabed_m:g} m)")
        names = [t.name for t in self.targets]
        require(len(set(names)) == len(names), OptionError, f"target names must be distinct, got {names}")
        for t in self.targets:
            require(t.burial_m is None or self.seabed is not None, OptionError,
                    f"target '{t.name}' is buried (burial_m) but the scene has no [seabed]")
        require(self.seabed is None or self.seabed.depth_m > self.sonar.draft_m + 1, OptionError,
                "seabed.depth_m must exceed the transducer draft by more than 1 m")

    def to_dict(self) -> dict:
        """The scene as plain data (the ``scene_json`` attribute of a simulated file)."""
        d = dataclasses.asdict(self)
        del d["targets"]
        for key in ("water", "discrete"):
            if d[key] is None:
                del d[key]
        d["target"] = [dict(kind=target_kind(t), **dataclasses.asdict(t)) for t in self.targets]
        return d


TARGET_KINDS = {"point": PointTarget, "line": LineTarget}
"""The ``kind`` of a ``[[target]]`` table and the dataclass it builds."""


def target_kind(target: PointTarget | LineTarget) -> str:
    """The ``kind`` (``"point"`` or ``"line"``) of a target, as a scene file names it."""
    return next(k for k, cls in TARGET_KINDS.items() if type(target) is cls)
