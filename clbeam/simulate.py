"""Element-level synthesis of multibeam sub-bottom profiler pings (SPEC §4, §7).

The simulator builds what an SBP29-class sonar records on its 64 receive
elements for a scene: buried pipelines (line scatterers), point scatterers,
a rough seabed and a rough sub-bottom interface (random scatterers whose
strength falls with grazing angle as ``sin^m``, or follows the AVO
backscatter model of a grain size per province), the nadir specular echoes of
both interfaces, the first surface multiple and its doublet, and noise, with
the ship moving along a track and rolling, pitching and heaving.

Model (vessel frame ``x`` forward, ``y`` starboard, ``z`` down; SPEC §2)
-----------------------------------------------------------------------
A point scatterer of amplitude ``a`` (m) at ``r`` produces on element ``n``

    p_n(t) = a / (|r - s| |r - e_n|) · b(t) ⊛ x(t - τ_n),
    τ_n = (|r - s| + |r - e_n|) / c,

with ``s`` the source and ``e_n`` the element in the earth frame (after roll
and heave, :func:`clbeam.geometry.to_earth_frame`), ``x`` the LFM replica
(:func:`clbeam.signal.lfm_replica`) and ``b`` the along-track transmit beam:
a continuous line aperture of length ``L`` along the column axis radiates,
in its far field (``L²/λ`` = 74 m at 9 kHz for 3.5 m), a boxcar of duration
``L |u| / c`` (unit area), ``u`` the direction cosine of the ray on the column
axis.  Its spectrum is ``sinc(L f u / c)``: the beam pattern, applied at every
frequency, not only at the band centre.

Each echo is deposited as band-limited fractional-delay taps (a least-squares
filter exact to 0.5 % in the pulse band) per scatterer and channel; the
boxcar is deposited as a pair of steps that a running sum turns into the box.
Then every channel is convolved with the pulse once, by FFT: the cost scales
with scatterers × channels, not with samples.  Frequency-dependent factors
that differ between echoes (sediment attenuation ``exp(-α(f) ℓ)``, the
pipeline's ``ka`` response) are applied to short time blocks of each echo
set before the pulse convolution, with a per-scatterer band-centre
correction inside a block.

See ``docs/simulator.md`` for every parameter, the choices behind the
built-in scenes and what is left out.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.resources
import json
import logging
import math
import os
import tomllib
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.fft
import xarray as xr

from . import __version__
from .errors import ClbeamError, OptionError, require
from .geometry import to_earth_frame
from .signal import lfm_replica

log = logging.getLogger(__name__)

KNOT_M_S = 1852.0 / 3600.0
"""One knot in m/s."""
EARTH_RADIUS_M = 6_371_008.8
"""Mean Earth radius (m) for the local tangent-plane navigation."""
DB_PER_NEPER = 20.0 / math.log(10.0)
"""Decibels in one neper (amplitude)."""

FD_PHASES = 1024
"""Fractional-delay table resolution: 1/1024 sample (25 ns at 40 kHz)."""
FD_TOLERANCE = 5e-3
"""Largest complex error of the fractional-delay filter in the pulse band."""
BOXCAR_MIN_SAMPLES = 0.25
"""Transmit boxcars shorter than this (samples) are deposited as impulses
scaled by ``sinc(f_c w)``; the neglected spectral tilt is below 0.3 %."""
FILTER_BLOCK = 512
"""Samples per block of the time-varying attenuation/response filter."""
FILTER_PAD = 256
"""Guard samples on each side of a filter block (the filter's impulse
response is confined to about 40 samples by the band window)."""
CHUNK_PAIRS = 1 << 18
"""Scatterer-channel pairs processed per vectorised chunk (memory bound)."""
CHUNK_SPAN = 2048
"""Largest spread of arrival times (samples) within one chunk."""


# ---------------------------------------------------------------------------
# Scene description
# ---------------------------------------------------------------------------
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

    n_elements: int = 64
    array_width_m: float = 3.528
    tx_length_m: float = 3.5
    source_offset_m: tuple = (0.0, 0.0, 0.0)
    draft_m: float = 5.0
    sample_rate_hz: float = 40000.0
    pulse_f0_hz: float = 2000.0
    pulse_f1_hz: float = 9000.0
    pulse_duration_s: float = 0.08

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
    heave positive up (SPEC §2).  Pitch only steers the transmit beam
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


SPECULAR_MODELS = ("impedance", "forward")
"""Values of ``seabed.specular_model``."""


@dataclass(frozen=True)
class Province:
    """A stretch of the track whose seabed scatters as a sediment of grain size ``mz``.

    The seabed scatterers whose along-track world position lies from
    ``from_along_track_m`` up to the next province's start get the
    backscattering strength of the APL-UW TR 9407 model
    (:func:`clbeam.avo.backscatter_strength_db`) at their grazing angle and
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
        model (:func:`clbeam.forward.specular_echoes` at normal incidence):
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
    """

    name: str = "pipe"
    x_m: float = 0.0
    y_m: float = 0.0
    angle_deg: float = 0.0
    curvature_deg_per_km: float = 0.0
    radius_m: float = 0.11
    burial_m: float | None = 1.0
    z_m: float | None = None
    reflectivity: float = 0.8

    def __post_init__(self):
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
    """

    tx_beam_cut: float = 1.0
    attenuation_cut_db: float = 40.0
    line_spacing_m: float | None = None

    def __post_init__(self):
        require(0 < self.tx_beam_cut <= 3, OptionError, f"model.tx_beam_cut must be within (0, 3], got {self.tx_beam_cut}")
        require(self.attenuation_cut_db > 0, OptionError, f"model.attenuation_cut_db must be > 0, got {self.attenuation_cut_db}")
        require(self.line_spacing_m is None or self.line_spacing_m > 0, OptionError,
                f"model.line_spacing_m must be > 0 m, got {self.line_spacing_m}")


@dataclass(frozen=True)
class Scene:
    """A whole scene: sonar, line, motion, environment, targets, noise.

    Attributes
    ----------
    sound_speed_m_s : float
        Isospeed water sound speed (m/s).
    snr_db : float or None
        Noise level: ``20 log10(A_ref / σ)``, ``σ`` the standard deviation of
        the white Gaussian noise per raw sample and ``A_ref`` the raw
        amplitude of a reference echo (:meth:`Simulator.reference_amplitude`:
        the nadir seabed echo, or the first target's echo when there is no
        seabed).  ``None``: no noise.
    """

    name: str = "custom"
    description: str = ""
    sound_speed_m_s: float = 1500.0
    snr_db: float | None = None
    sonar: Sonar = field(default_factory=Sonar)
    record: Record = field(default_factory=Record)
    survey: Survey = field(default_factory=Survey)
    motion: Motion = field(default_factory=Motion)
    seabed: Seabed | None = None
    subbottom: SubBottom | None = None
    targets: tuple = ()
    model: Model = field(default_factory=Model)

    def __post_init__(self):
        require(1300 <= self.sound_speed_m_s <= 1700, OptionError,
                f"sound_speed_m_s must be within 1300-1700 m/s, got {self.sound_speed_m_s}")
        require(self.subbottom is None or self.seabed is not None, OptionError,
                "a [subbottom] needs a [seabed]")
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
        d["target"] = [dict(kind=_TARGET_KINDS_INV[type(t)], **dataclasses.asdict(t)) for t in self.targets]
        return d


TRUTH_KEYS = ("x", "y", "z", "angle", "seabed_z", "image_y", "image_z", "u")
"""Per-target truth of :meth:`Simulator.truth`, stored as ``truth_target_<key>``."""

_TARGET_KINDS = {"point": PointTarget, "line": LineTarget}
_TARGET_KINDS_INV = {v: k for k, v in _TARGET_KINDS.items()}


# ---------------------------------------------------------------------------
# Scene files
# ---------------------------------------------------------------------------
def _convert(hint, value, where: str):
    """Convert a TOML value to the annotated type ``hint`` (one-line errors)."""
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if value is None:
            return None
        return _convert(args[0], value, where)
    if dataclasses.is_dataclass(hint):
        require(isinstance(value, dict), OptionError, f"scene key '{where}' must be a table, got {value!r}")
        return _from_mapping(hint, value, where)
    if hint is bool:
        require(isinstance(value, bool), OptionError, f"scene key '{where}' must be true or false, got {value!r}")
        return value
    if hint is int:
        require(isinstance(value, int) and not isinstance(value, bool) or (isinstance(value, float) and value.is_integer()),
                OptionError, f"scene key '{where}' must be an integer, got {value!r}")
        return int(value)
    if hint is float:
        require(isinstance(value, (int, float)) and not isinstance(value, bool), OptionError,
                f"scene key '{where}' must be a number, got {value!r}")
        require(math.isfinite(value), OptionError, f"scene key '{where}' must be finite, got {value!r}")
        return float(value)
    if hint is str:
        require(isinstance(value, str), OptionError, f"scene key '{where}' must be a string, got {value!r}")
        return value
    if origin is tuple and typing.get_args(hint) and dataclasses.is_dataclass(typing.get_args(hint)[0]):
        cls = typing.get_args(hint)[0]
        require(isinstance(value, (list, tuple)) and all(isinstance(v, dict) for v in value), OptionError,
                f"scene key '{where}' must be a list of tables, got {value!r}")
        return tuple(_from_mapping(cls, v, f"{where}[{i}]") for i, v in enumerate(value))
    if hint is tuple:
        require(isinstance(value, (list, tuple)) and all(isinstance(v, (int, float)) for v in value), OptionError,
                f"scene key '{where}' must be a list of numbers, got {value!r}")
        return tuple(float(v) for v in value)
    raise OptionError(f"scene key '{where}': unsupported type {hint}")  # pragma: no cover - a programming error


def _from_mapping(cls, mapping: dict, where: str):
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    kwargs = {}
    for key, value in mapping.items():
        here = f"{where}.{key}" if where else key
        require(key in names, OptionError, f"unknown scene key '{here}' (expected one of: {', '.join(names)})")
        kwargs[key] = _convert(hints[key], value, here)
    return cls(**kwargs)


def scene_from_mapping(data: dict, *, name: str | None = None) -> Scene:
    """Build a :class:`Scene` from parsed TOML (nested dicts; ``target`` is a
    list of tables, each with ``kind = "point"`` or ``"line"``).

    Raises
    ------
    clbeam.errors.OptionError
        On an unknown key, a value of the wrong type or out of range.
    """
    data = dict(data)
    targets = []
    for i, t in enumerate(data.pop("target", [])):
        require(isinstance(t, dict), OptionError, f"scene key 'target[{i}]' must be a table")
        t = dict(t)
        kind = t.pop("kind", None)
        require(kind in _TARGET_KINDS, OptionError,
                f"scene key 'target[{i}].kind' must be one of {sorted(_TARGET_KINDS)}, got {kind!r}")
        targets.append(_from_mapping(_TARGET_KINDS[kind], t, f"target[{i}]"))
    scene = _from_mapping(Scene, data, "")
    scene = dataclasses.replace(scene, targets=tuple(targets))
    if name is not None:
        scene = dataclasses.replace(scene, name=name)
    return scene


def list_scenes() -> list[str]:
    """Names of the built-in scenes (``clbeam/scenes/*.toml``)."""
    root = importlib.resources.files("clbeam.scenes")
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def _read_toml(source: str | os.PathLike) -> tuple[dict, str]:
    text_source = str(source)
    if text_source in list_scenes():
        text = importlib.resources.files("clbeam.scenes").joinpath(f"{text_source}.toml").read_text()
        origin = text_source
    else:
        path = Path(source)
        require(path.suffix == ".toml" or path.exists(), OptionError,
                f"unknown scene '{text_source}': not a built-in scene ({', '.join(list_scenes())}) nor a .toml file")
        require(path.is_file(), OptionError, f"scene file {path}: no such file")
        text = path.read_text()
        origin = path.stem
    try:
        return tomllib.loads(text), origin
    except tomllib.TOMLDecodeError as exc:
        raise OptionError(f"scene {origin}: invalid TOML ({exc})") from None


_UNSET = object()


def load_scene(source: str | os.PathLike | Scene, *, pings: int | None = None, max_range_m: float | None = None,
               snr_db=_UNSET, overrides: dict | None = None) -> Scene:
    """Load a scene by built-in name or TOML path, with options overridden.

    Parameters
    ----------
    source : str, path-like or Scene
        ``"line1"``, ``"line4"``, ``"point"``, ``"avo2"`` (see :func:`list_scenes`), a
        ``.toml`` file, or a :class:`Scene` (overrides applied to it).
    pings : int, optional
        Number of pings on the line.
    max_range_m : float, optional
        Largest fully recorded slant range (m).
    snr_db : float or None, optional
        Noise level (see :class:`Scene`); ``None`` switches the noise off.
    overrides : dict, optional
        Dotted TOML keys and values, e.g. ``{"motion.roll_mean_deg": 5.0,
        "seabed.scattering.per_cell": 2}``; ``"target"`` replaces the target
        list (a list of tables).  ``None`` values remove a key.

    Returns
    -------
    Scene
    """
    if isinstance(source, Scene):
        data, origin = source.to_dict(), source.name
        data = _drop_none(data)
    else:
        data, origin = _read_toml(source)
    items = dict(overrides or {})
    if pings is not None:
        items["survey.pings"] = pings
    if max_range_m is not None:
        items["record.max_range_m"] = max_range_m
    if snr_db is not _UNSET:
        items["snr_db"] = snr_db
    for key, value in items.items():
        _set_dotted(data, key, value)
    data.setdefault("name", origin)
    return scene_from_mapping(data)


def _drop_none(d):
    if isinstance(d, dict):
        return {k: _drop_none(v) for k, v in d.items() if v is not None}
    if isinstance(d, list):
        return [_drop_none(v) for v in d]
    return d


def _set_dotted(data: dict, key: str, value) -> None:
    parts = key.split(".")
    node = data
    for p in parts[:-1]:
        nxt = node.get(p)
        if nxt is None:
            nxt = node[p] = {}
        require(isinstance(nxt, dict), OptionError, f"scene override '{key}': '{p}' is not a table")
        node = nxt
    if value is None:
        node.pop(parts[-1], None)
    else:
        node[parts[-1]] = value


# ---------------------------------------------------------------------------
# Physics helpers (also the paper checks)
# ---------------------------------------------------------------------------
def transmit_far_field_m(length_m: float = 3.5, frequency_hz: float = 9000.0,
                         sound_speed_m_s: float = 1500.0) -> float:
    """Far-field distance ``L² / λ`` (m) of a line aperture of length ``L``.

    Holland et al. (2024) §III: 74 m for the 3.5 m column at 9 kHz.
    """
    return length_m ** 2 * frequency_hz / sound_speed_m_s


def transmit_beamwidth_deg(length_m: float = 3.5, frequency_hz: float = 4000.0,
                           sound_speed_m_s: float = 1500.0) -> float:
    """Full −3 dB width (degree) of a uniform line aperture, ``2 asin(0.443 λ / L)``.

    About 5.4° for 3.5 m at 4 kHz (the paper: "∼6°").
    """
    return 2 * math.degrees(math.asin(0.4429 * sound_speed_m_s / (frequency_hz * length_m)))


def ka_sin_phi(radius_m: float, frequency_hz, phi_deg=90.0, sound_speed_m_s: float = 1500.0):
    """``k a sin φ`` of a cylinder of radius ``a`` (Holland et al. 2024 §IV-A).

    ``φ`` is the horizontal angle between the incoming wave and the cylinder
    axis (90° at broadside).
    """
    k = 2 * np.pi * np.asarray(frequency_hz, dtype=np.float64) / sound_speed_m_s
    return k * radius_m * np.sin(np.deg2rad(phi_deg))


def nadir_angle_deg(horizontal_m: float, depth_m: float) -> float:
    """Angle from nadir (degree) of a point ``horizontal_m`` across and
    ``depth_m`` below the transducers, straight rays: 76° at 920 m in 230 m."""
    return math.degrees(math.atan2(horizontal_m, depth_m))


def reflection_coefficient(grazing_rad, density_ratio: float, sound_speed_ratio: float):
    """Plane-wave pressure reflection coefficient of a fluid-fluid interface.

    ``V = (m sin θ − sqrt(n² − cos² θ)) / (m sin θ + sqrt(n² − cos² θ))``,
    ``m`` the density ratio, ``n = c1 / c2`` (lower medium slower: no
    critical angle), ``θ`` grazing in the upper medium.
    """
    n = 1.0 / sound_speed_ratio
    s = np.sin(grazing_rad)
    root = np.sqrt(np.maximum(n * n - np.cos(grazing_rad) ** 2, 0.0))
    return (density_ratio * s - root) / (density_ratio * s + root)


def refracted_path(horizontal_m, height_m, depth_m, sound_speed_ratio: float) -> dict:
    """Ray from a point ``height_m`` above a flat interface to a point
    ``depth_m`` below it, ``horizontal_m`` away (Snell's law, vectorised).

    Parameters
    ----------
    horizontal_m, height_m, depth_m : array_like
        Horizontal distance, height of the upper end above the interface and
        depth of the lower end below it (m).
    sound_speed_ratio : float
        ``c2 / c1`` of the lower medium (< 1: slower, rays bend to the normal).

    Returns
    -------
    dict
        ``water_m`` and ``sediment_m`` (path lengths, m), ``time_factor_m``
        (``water + sediment / ratio``: the travel time times ``c1``),
        ``grazing_water_rad`` and ``grazing_sediment_rad``.
    """
    rho = np.asarray(horizontal_m, dtype=np.float64)
    h = np.asarray(height_m, dtype=np.float64)
    d = np.maximum(np.asarray(depth_m, dtype=np.float64), 0.0)
    n = float(sound_speed_ratio)
    # unknown: s = sin(angle from vertical) in the upper medium; n s below.
    s = rho / np.maximum(np.hypot(rho, h + d), 1e-300)
    s_max = min(1.0, 1.0 / n) * (1 - 1e-15)
    for _ in range(60):
        cw = np.sqrt(1 - s * s)
        cs = np.sqrt(1 - (n * s) ** 2)
        f = h * s / cw + d * n * s / cs - rho
        fp = h / cw ** 3 + d * n / cs ** 3
        step = f / np.maximum(fp, 1e-300)
        s = np.clip(s - step, 0.0, s_max)
        if np.all(np.abs(f) <= 1e-9 * np.maximum(rho, 1.0)):
            break
    cw = np.sqrt(1 - s * s)
    cs = np.sqrt(1 - (n * s) ** 2)
    water = h / cw
    sediment = d / cs
    return {"water_m": water, "sediment_m": sediment, "time_factor_m": water + sediment / n,
            "grazing_water_rad": np.arcsin(cw), "grazing_sediment_rad": np.arcsin(cs)}


def attenuation_np_per_m_hz(seabed: Seabed) -> float:
    """Sediment attenuation slope ``α / f`` in nepers per metre per hertz."""
    return seabed.attenuation_db_per_m / DB_PER_NEPER / seabed.attenuation_ref_hz


def two_way_sediment_path_m(horizontal_m: float, height_m: float, burial_m: float,
                            sound_speed_ratio: float) -> float:
    """Two-way in-sediment path (m) to a buried point, monostatic (Snell).

    The paper quotes 5 m (0.75 dB at 5 kHz) at 920 m in 230 m water with a
    speed ratio of 0.98; the 1 m burial to the pipe axis gives 6.5 m here
    (see ``docs/simulator.md``).
    """
    return 2 * float(refracted_path(horizontal_m, height_m, burial_m, sound_speed_ratio)["sediment_m"])


# ---------------------------------------------------------------------------
# Fractional-delay tables
# ---------------------------------------------------------------------------
@functools.lru_cache(maxsize=8)
def _fd_tables(omega_hi: float) -> tuple[int, np.ndarray, np.ndarray]:
    """Least-squares fractional-delay filters over ``[0, omega_hi]`` rad/sample.

    Returns ``(taps, impulse, box)``: ``(taps, FD_PHASES + 1)`` tables whose
    column ``p`` holds the taps at offsets ``-(taps//2 - 1) .. taps//2`` of an
    impulse at fraction ``p / FD_PHASES``, and of a one-sample box starting
    there (for steps).  The smallest even tap count meeting
    :data:`FD_TOLERANCE` is used; every column sums to one (exact DC gain).
    """
    om = np.linspace(0.0, omega_hi, 512)
    alpha = np.arange(FD_PHASES + 1) / FD_PHASES
    for taps in range(4, 18, 2):
        n = np.arange(taps) - (taps // 2 - 1)
        basis = np.exp(-1j * np.outer(om, n))
        a = np.vstack([basis.real, basis.imag])
        target = np.exp(-1j * np.outer(om, alpha))
        box = target * (np.exp(-0.5j * om) * np.sinc(om / (2 * np.pi)))[:, None]
        tables = []
        err = 0.0
        for tgt in (target, box):
            h, *_ = np.linalg.lstsq(a, np.vstack([tgt.real, tgt.imag]), rcond=None)
            err = max(err, float(np.abs(basis @ h - tgt).max()))
            tables.append(h / h.sum(axis=0, keepdims=True))
        if err <= FD_TOLERANCE:
            return taps, tables[0], tables[1]
    raise ClbeamError("fractional-delay design failed")  # pragma: no cover - the band is validated


class _Accumulator:
    """Band-limited impulses and steps on the sample grid of ``n_channels``.

    Column ``j`` is sample ``start + j`` of the record.  ``impulses`` adds
    ``w δ(k - t)``; ``steps`` adds ``w H(k - t)`` (a step, turned into the
    box by :meth:`total`'s running sum).
    """

    def __init__(self, n_channels: int, start: int, length: int, tables):
        self.start, self.length = start, length
        self.taps, imp, box = tables
        self.imp_cols = [np.ascontiguousarray(imp[j]) for j in range(self.taps)]
        self.box_cols = [np.ascontiguousarray(box[j]) for j in range(self.taps)]
        self.imp = np.zeros((n_channels, length))
        self.stp = None

    def impulses(self, t: np.ndarray, w: np.ndarray) -> None:
        """Add impulses of weight ``w`` at record sample ``t`` (both ``(S, C)``)."""
        self._deposit(self.imp, t, w, self.imp_cols, clip=False)

    def steps(self, t: np.ndarray, w: np.ndarray) -> None:
        """Add steps of height ``w`` at record sample ``t`` (both ``(S, C)``)."""
        if self.stp is None:
            self.stp = np.zeros_like(self.imp)
        # a one-sample box starting at t, summed, is a step at t: the running
        # sum 1/(1 - e^{-jΩ}) = e^{jΩ/2}/(jΩ sinc(Ω/2π)) undoes the box's half
        # sample delay and its sinc, leaving e^{-jΩt}/(jΩ)
        self._deposit(self.stp, t, w, self.box_cols, clip=True)

    def _deposit(self, out, t, w, cols, *, clip: bool) -> None:
        k = np.floor(t)
        ph = np.rint((t - k) * FD_PHASES).astype(np.intp)
        k0 = k.astype(np.intp) - (self.taps // 2 - 1) - self.start
        if not clip:
            # an impulse outside the window cannot reach the record: drop it
            outside = (k0 < 0) | (k0 > self.length - self.taps)
            if outside.any():
                w = np.where(outside, 0.0, w)
        # a step before the window is moved to its first sample (a box that
        # started even earlier is the same inside it); one after never matters
        np.clip(k0, 0, self.length - self.taps, out=k0)
        if k0.size == 0:
            return
        n_ch = out.shape[0]
        lo = int(k0.min())
        hi = int(k0.max()) + self.taps
        span = hi - lo
        base = (k0 - lo) + (np.arange(n_ch) * span)[None, :]
        base = base.ravel()
        ph = ph.ravel()
        w = w.ravel()
        acc = np.zeros(n_ch * span)
        for j, col in enumerate(cols):
            acc += np.bincount(base + j, col[ph] * w, minlength=n_ch * span)
        out[:, lo:hi] += acc.reshape(n_ch, span)

    def total(self) -> np.ndarray:
        """Impulses plus the running sum of the steps (``(C, length)``)."""
        if self.stp is None:
            return self.imp
        return self.imp + np.cumsum(self.stp, axis=1)


# ---------------------------------------------------------------------------
# Echo sets
# ---------------------------------------------------------------------------
@dataclass
class _Echoes:
    """A set of echoes of one ping, all arrays ``(S,)`` or ``(S, 3)``.

    ``pos``: scatterer (or image-source) position, earth frame (m);
    ``amp``: amplitude (m for scatterers, 1 for image sources);
    ``src_leg``: source-to-scatterer distance added to the receive leg (m,
    0 for image sources); ``spread``: divisor of the amplitude besides the
    receive leg (m, 1 for image sources); ``extra_s``: extra delay
    (refraction, s); ``u``: direction cosine of the transmitted ray on the
    column axis; ``b_s``: attenuation ``exp(-b f)`` (s) or ``None``;
    ``response``: a spectral response ``f -> H(f)`` or ``None``;
    ``rx_tilt``: for refracted echoes, the refracted minus the straight ray
    direction at the array (``(S, 3)``): element ``n`` gets the extra delay
    ``-rx_tilt · (e_n - o) / c`` (the first-order change of the refraction
    delay across the array).
    """

    label: str
    pos: np.ndarray
    amp: np.ndarray
    src_leg: np.ndarray
    spread: np.ndarray
    extra_s: np.ndarray
    u: np.ndarray
    b_s: np.ndarray | None = None
    response: typing.Callable | None = None
    rx_tilt: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.amp)

    def subset(self, mask: np.ndarray) -> "_Echoes":
        return dataclasses.replace(
            self, pos=self.pos[mask], amp=self.amp[mask], src_leg=self.src_leg[mask], spread=self.spread[mask],
            extra_s=self.extra_s[mask], u=self.u[mask], b_s=None if self.b_s is None else self.b_s[mask],
            rx_tilt=None if self.rx_tilt is None else self.rx_tilt[mask])


@dataclass(frozen=True)
class PingGeometry:
    """Where everything is for one ping (earth frame: vessel axes, ``z`` down
    along gravity, origin at the array reference point's mean position).

    Attributes
    ----------
    index : int
        Ping index on the line.
    time_s : float
        Seconds since the first ping.
    along_m : float
        Distance run along the track since the first ping (m).
    roll_deg, pitch_deg, heave_m : float
        Motion (SPEC §2 signs).
    elements, source, centre : numpy.ndarray
        Receive elements ``(C, 3)``, source and array reference point (m).
    column : numpy.ndarray
        Unit vector along the transmit column (``x`` tilted by pitch).
    """

    index: int
    time_s: float
    along_m: float
    roll_deg: float
    pitch_deg: float
    heave_m: float
    elements: np.ndarray
    source: np.ndarray
    centre: np.ndarray
    column: np.ndarray


class _Plane:
    """A plane ``(r - p0) · n = 0`` (``n`` unit, pointing down)."""

    def __init__(self, p0, normal):
        self.p0 = np.asarray(p0, dtype=np.float64)
        n = np.asarray(normal, dtype=np.float64)
        self.n = n / np.linalg.norm(n)

    def mirror(self, p: np.ndarray) -> np.ndarray:
        return p - 2 * np.dot(p - self.p0, self.n) * self.n

    def shifted(self, distance_m: float) -> "_Plane":
        return _Plane(self.p0 + distance_m * self.n, self.n)


# ---------------------------------------------------------------------------
# The simulator
# ---------------------------------------------------------------------------
class Simulator:
    """Synthesises the pings of a scene one at a time.

    Building it prepares what every ping shares (replica, delay tables, the
    world-fixed random seabed fields and pipeline points for the pings
    asked for); :meth:`ping` then renders one ping.  A ping depends only on
    the scene, the seed and its index, not on which other pings are made.

    Parameters
    ----------
    scene : Scene, str or path-like
        A scene or a name/path for :func:`load_scene`.
    seed : int
        Seed of the random seabed fields and of the noise.
    pings : int or sequence of int, optional
        The ping indices to prepare for: all of the scene's (default), the
        first ``n``, or the given indices.
    """

    def __init__(self, scene, *, seed: int = 0, pings=None):
        self.scene = scene if isinstance(scene, Scene) else load_scene(scene)
        require(int(seed) == seed and seed >= 0, OptionError, f"seed must be a non-negative integer, got {seed!r}")
        self.seed = int(seed)
        self.indices = self._indices(pings)
        sc, so = self.scene, self.scene.sonar
        self.c = sc.sound_speed_m_s
        self.fs = so.sample_rate_hz
        self.fc = so.centre_frequency_hz
        self.replica = so.replica()
        self.n_pulse = self.replica.size
        self.element_vessel = so.element_positions_m()
        self.source_vessel = np.asarray(so.source_offset_m, dtype=np.float64)
        wl_f0 = self.c / so.pulse_f0_hz
        self.u_cut = min(sc.model.tx_beam_cut * wl_f0 / so.tx_length_m, 0.5)
        self.u_flat = 0.75 * self.u_cut
        self.tables = _fd_tables(2 * np.pi * min(1.1 * so.pulse_f1_hz, 0.45 * self.fs) / self.fs)
        self._envelope_u, self._envelope = self._beam_envelope()
        self.max_range_m = sc.record.max_range_m or self._auto_max_range()
        self.t0 = sc.record.start_s
        t_end = 2 * self.max_range_m / self.c + so.pulse_duration_s
        require(t_end > self.t0, OptionError,
                f"record.start_s {self.t0:g} s is after the record end {t_end:g} s (max_range_m {self.max_range_m:g} m)")
        self.n_samples = int(math.ceil((t_end - self.t0) * self.fs))
        along = np.array([i * sc.survey.step_m for i in self.indices])
        x_ext = self.max_range_m * self.u_cut / math.sqrt(1 - self.u_cut ** 2)
        self._x_window = (float(along.min()) - x_ext, float(along.max()) + x_ext)
        self.alpha_np = attenuation_np_per_m_hz(sc.seabed) if sc.seabed is not None else 0.0
        self._provinces = self._province_tables()
        self._fields = self._make_fields()
        self._lines = [self._line_points(t) if isinstance(t, LineTarget) else None for t in sc.targets]
        self.noise_std = self._noise_std()

    # -- set-up ----------------------------------------------------------
    def _indices(self, pings) -> np.ndarray:
        if pings is None:
            idx = np.arange(self.scene.survey.pings)
        elif np.isscalar(pings):
            require(int(pings) == pings and pings >= 1, OptionError, f"pings must be a positive integer, got {pings!r}")
            idx = np.arange(int(pings))
        else:
            idx = np.asarray(list(pings))
            require(idx.size > 0 and np.issubdtype(idx.dtype, np.integer) and bool(np.all(idx >= 0)), OptionError,
                    f"pings must be non-negative integer indices, got {list(pings)!r}")
        return idx.astype(np.int64)

    def _beam_envelope(self) -> tuple[np.ndarray, np.ndarray]:
        """Band-averaged transmit beam energy against ``u`` (1 on axis), floored
        at 0.1: the importance weight of the random seabed scatterers."""
        so = self.scene.sonar
        u = np.linspace(0, self.u_cut, 257)
        f = np.linspace(so.pulse_f0_hz, so.pulse_f1_hz, 64)
        energy = np.mean(np.sinc(so.tx_length_m * np.outer(u, f) / self.c) ** 2, axis=1)
        return u, np.maximum(energy / energy[0], 0.1)

    def envelope(self, u: np.ndarray) -> np.ndarray:
        """Importance weight of a random scatterer at direction cosine ``u``."""
        return np.interp(np.abs(u), self._envelope_u, self._envelope, right=0.0)

    def taper(self, u: np.ndarray) -> np.ndarray:
        """Cull window on ``|u|``: 1 up to ``0.75 u_cut``, cosine to 0 at ``u_cut``."""
        a = np.abs(u)
        x = np.clip((a - self.u_flat) / (self.u_cut - self.u_flat), 0.0, 1.0)
        return 0.5 * (1 + np.cos(np.pi * x))

    def seabed_z(self, x_track_m, y_m) -> np.ndarray:
        """Seabed depth below the transducers' mean depth at track-frame ``(x, y)`` (m)."""
        sb = self.scene.seabed
        return (sb.depth_m - self.scene.sonar.draft_m + np.tan(np.deg2rad(sb.slope_along_deg)) * np.asarray(x_track_m)
                + np.tan(np.deg2rad(sb.slope_across_deg)) * np.asarray(y_m))

    def _target_world(self, t) -> tuple[float, float, float]:
        """World (track-frame) position of a point target (m)."""
        z = t.z_m if t.z_m is not None else float(self.seabed_z(t.x_m, t.y_m)) + t.burial_m
        return t.x_m, t.y_m, z

    def _auto_max_range(self) -> float:
        sc = self.scene
        ranges = [0.0]
        along = self.indices * sc.survey.step_m
        for t in sc.targets:
            if isinstance(t, PointTarget):
                x, y, z = self._target_world(t)
                ranges.append(float(np.max(np.sqrt((x - along) ** 2 + y ** 2 + z ** 2))))
            else:
                for a in along:
                    y, z, _ = self._line_crossing_coarse(t, a)
                    if np.isfinite(y):
                        ranges.append(math.hypot(y, z))
        r = max(ranges) + 50.0
        if sc.seabed is not None:
            r = max(r, 2 * (sc.seabed.depth_m - sc.sonar.draft_m) + 2 * sc.sonar.draft_m + 50.0)
        return r

    def _noise_std(self) -> float:
        if self.scene.snr_db is None:
            return 0.0
        return self.reference_amplitude() * 10 ** (-self.scene.snr_db / 20)

    def reference_amplitude(self) -> float:
        """Raw amplitude of the echo the SNR refers to (replica amplitude 1 at 1 m).

        With a seabed: its nadir specular echo ``V / (2 h)`` (``h`` the
        transducers' height above it under the first ping, ``V`` its normal
        reflection coefficient).  Otherwise the first target's echo at the
        array centre for the first ping: ``a / R²`` for a point, the
        broadside stationary-phase echo ``ρ_p H(f_c) sqrt(λ_c R / 2) / R²`` for
        a line.  1 when there is neither.
        """
        sc = self.scene
        if sc.seabed is not None:
            v = abs(float(reflection_coefficient(np.pi / 2, sc.seabed.density_ratio, sc.seabed.sound_speed_ratio)))
            return v / (2 * (sc.seabed.depth_m - sc.sonar.draft_m))
        if sc.targets:
            t = sc.targets[0]
            if isinstance(t, PointTarget):
                x, y, z = self._target_world(t)
                return t.amplitude_m / (x * x + y * y + z * z)
            y, z, _ = self._line_crossing_coarse(t, 0.0)
            r = math.hypot(y, z)
            return t.reflectivity * float(t.response(self.fc, self.c)) * math.sqrt(self.c / self.fc * r / 2) / r ** 2
        return 1.0

    # -- seabed provinces ---------------------------------------------------
    PROVINCE_GRAZING_DEG = np.linspace(0.05, 90.0, 1800)
    """Grazing angles (degree) at which each province's strength is tabulated
    (0.05° apart; the model is smooth, linear interpolation in dB)."""

    def _province_tables(self) -> dict | None:
        """Starts (m) and strength tables (dB at :attr:`PROVINCE_GRAZING_DEG`,
        band centre) of the seabed provinces; ``None`` without provinces."""
        sb = self.scene.seabed
        if sb is None or not sb.province:
            return None
        from .avo import backscatter_strength_db

        table = np.stack([backscatter_strength_db(self.PROVINCE_GRAZING_DEG, self.fc, mz=p.mz,
                                                  sound_speed_water_m_s=self.c) for p in sb.province])
        return {"start": np.array([p.from_along_track_m for p in sb.province]),
                "mz": np.array([p.mz for p in sb.province]), "strength_db": table}

    def _province_index(self, x_track_m) -> np.ndarray:
        """Index of the province at track-frame along-track positions (m)."""
        start = self._provinces["start"]
        return np.clip(np.searchsorted(start, np.asarray(x_track_m), side="right") - 1, 0, start.size - 1)

    def province_mz(self, along_m: float) -> float:
        """Grain size (phi) of the seabed province at ``along_m`` along the
        track (m); NaN when the scene has no provinces."""
        if self._provinces is None:
            return math.nan
        return float(self._provinces["mz"][self._province_index(along_m)])

    def province_strength_db(self, x_track_m, grazing_rad) -> np.ndarray:
        """AVO backscattering strength (dB) of the seabed at along-track
        positions ``x_track_m`` (m) and grazing angles ``grazing_rad``, from
        the province there, at the band centre frequency."""
        k = self._province_index(x_track_m)
        deg = np.clip(np.degrees(np.asarray(grazing_rad, dtype=np.float64)), self.PROVINCE_GRAZING_DEG[0], 90.0)
        out = np.empty(deg.shape)
        for j in np.unique(k):
            sel = k == j
            out[sel] = np.interp(deg[sel], self.PROVINCE_GRAZING_DEG, self._provinces["strength_db"][j])
        return out

    # -- world-fixed random fields ------------------------------------------
    def _make_fields(self) -> list:
        sc = self.scene
        fields = []
        if sc.seabed is not None and sc.seabed.scattering is not None:
            fields.append(self._field(1, sc.seabed.scattering, 0.0))
        if sc.subbottom is not None and sc.subbottom.scattering is not None:
            fields.append(self._field(2, sc.subbottom.scattering, sc.subbottom.depth_below_seabed_m))
        return fields

    def _density(self, y_m: np.ndarray, scattering: Scattering, depth_below_seabed_m: float) -> np.ndarray:
        """Scatterers per m² at cross-track ``y`` so that one range cell of the
        strip on one side holds ``per_cell`` (with the envelope weight)."""
        so = self.scene.sonar
        dr = self.c / (2 * (so.pulse_f1_hz - so.pulse_f0_hz))
        h = np.maximum(self.seabed_z(0.0, y_m) + depth_below_seabed_m, 1.0)
        ay = np.abs(y_m)
        r = np.hypot(ay, h)
        dy = np.sqrt(ay * ay + 2 * r * dr + dr * dr) - ay
        width = r * 2 * np.trapezoid(self._envelope, self._envelope_u)
        return scattering.per_cell / (dy * width)

    def _field(self, layer: int, scattering: Scattering, depth_below_seabed_m: float) -> dict:
        """Random scatterers of one interface over the tiles the pings need.

        Every 64 m tile of the world draws its scatterers from its own seeded
        generator, so a scatterer is where it is whatever pings are asked for.
        Each keeps a uniform score ``q``; a ping keeps it when ``q`` is below
        the envelope weight at its ``u`` (importance sampling).
        """
        tile = 64.0
        h_mean = self.scene.seabed.depth_m - self.scene.sonar.draft_m + depth_below_seabed_m
        y_max = math.sqrt(max((self.max_range_m + 20) ** 2 - (0.5 * h_mean) ** 2, 1.0))
        x_lo, x_hi = self._x_window
        ix = np.arange(math.floor(x_lo / tile), math.floor(x_hi / tile) + 1)
        iy = np.arange(math.floor(-y_max / tile), math.floor(y_max / tile) + 1)
        out = {k: [] for k in ("x", "y", "zeta", "g", "q", "n")}
        for jy in iy:
            ys = (jy + np.linspace(0, 1, 17)) * tile
            n_max = 1.02 * float(np.max(self._density(ys, scattering, depth_below_seabed_m)))
            for jx in ix:
                rng = np.random.default_rng([self.seed, 2, layer, int(jx) + (1 << 30), int(jy) + (1 << 30)])
                n = rng.poisson(n_max * tile * tile)
                x = (jx + rng.random(n)) * tile
                y = (jy + rng.random(n)) * tile
                zeta = rng.normal(0.0, scattering.depth_spread_m, n) if scattering.depth_spread_m > 0 else np.zeros(n)
                g = rng.standard_normal(n)
                q = rng.random(n)
                dens = self._density(y, scattering, depth_below_seabed_m)
                frac = np.minimum(dens / n_max, 1.0)
                keep = q < frac
                for k, v in (("x", x), ("y", y), ("zeta", zeta), ("g", g), ("q", q / frac), ("n", dens)):
                    out[k].append(v[keep])
        arrays = {k: np.concatenate(v) if v else np.zeros(0) for k, v in out.items()}
        order = np.argsort(arrays["x"], kind="stable")
        arrays = {k: v[order] for k, v in arrays.items()}
        arrays.update(layer=layer, scattering=scattering, depth=depth_below_seabed_m)
        log.debug("layer %d: %d scatterers stored", layer, arrays["x"].size)
        return arrays

    # -- pipelines -------------------------------------------------------------
    @staticmethod
    def _arc(t: LineTarget, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Track-frame ``(x, y, heading)`` of a line at arc lengths ``s`` (m, rad)."""
        d0 = math.radians(t.angle_deg)
        kappa = math.radians(t.curvature_deg_per_km) / 1000.0
        d = d0 + kappa * s
        if abs(kappa) < 1e-12:
            return t.x_m + s * math.cos(d0), t.y_m + s * math.sin(d0), d
        return t.x_m + (np.sin(d) - math.sin(d0)) / kappa, t.y_m - (np.cos(d) - math.cos(d0)) / kappa, d

    def _arc_extent(self, t: LineTarget, x_lo: float, x_hi: float) -> tuple[float, float]:
        """Arc-length interval whose points lie within ``x_lo..x_hi`` with heading within ±80°."""
        span = 2 * (abs(x_hi - t.x_m) + abs(x_lo - t.x_m)) + 100.0
        s = np.arange(-span, span, 0.5)
        x, _, d = self._arc(t, s)
        # heading linear in s: |d| < 80° is one interval, on which x grows
        # monotonically, so the points kept form one stretch
        ok = (x >= x_lo) & (x <= x_hi) & (np.abs(d) < np.radians(80))
        require(bool(ok.any()), OptionError, f"target '{t.name}' never comes near the track")
        idx = np.flatnonzero(ok)
        return float(s[idx[0]]), float(s[idx[-1]])

    def _line_crossing_coarse(self, t: LineTarget, along_m: float) -> tuple[float, float, float]:
        """``(y, z, heading_deg)`` of a line where it crosses ``x = along_m`` (NaN if never)."""
        s0, s1 = self._arc_extent(t, along_m - 5000.0, along_m + 5000.0)
        s = np.linspace(s0, s1, 4001)
        x, y, d = self._arc(t, s)
        if not (x.min() <= along_m <= x.max()):
            return math.nan, math.nan, math.nan
        yc = float(np.interp(along_m, x, y))
        dc = float(np.interp(along_m, x, d))
        if t.z_m is not None:
            zc = t.z_m
        else:
            zc = float(self.seabed_z(along_m, yc)) + t.burial_m
        return yc, zc, math.degrees(dc)

    def _line_points(self, t: LineTarget) -> dict:
        """Points along a line every ``Δs`` over the stretch the pings can see."""
        spacing = self.scene.model.line_spacing_m
        if spacing is None:
            # from the stretch the whole line can see, not the pings asked for,
            # so that a ping is the same whichever pings are made
            n_line = max(self.scene.survey.pings, int(self.indices.max()) + 1)
            track = (n_line - 1) * self.scene.survey.step_m
            x_ext = self.max_range_m * self.u_cut / math.sqrt(1 - self.u_cut ** 2)
            a0, a1 = self._arc_extent(t, -x_ext - 10.0, track + x_ext + 10.0)
            _, _, d = self._arc(t, np.linspace(a0, a1, 1025))
            wl_min = self.c / (1.05 * self.scene.sonar.pulse_f1_hz)
            max_cos = min(1.0, self.u_cut + float(np.max(np.abs(np.sin(d)))))
            spacing = wl_min / (4 * max_cos)
        x_lo, x_hi = self._x_window
        s0, s1 = self._arc_extent(t, x_lo - 10.0, x_hi + 10.0)
        # points at whole multiples of the spacing from the reference point
        s = np.arange(math.floor(s0 / spacing), math.ceil(s1 / spacing) + 1) * spacing
        x, y, d = self._arc(t, s)
        order = np.argsort(x, kind="stable")
        z = np.full(s.size, t.z_m) if t.z_m is not None else self.seabed_z(x, y) + t.burial_m
        log.debug("line %s: %d points, spacing %.3f m", t.name, s.size, spacing)
        return {"x": x[order], "y": y[order], "z": z[order], "spacing": spacing}

    # -- per-ping geometry -----------------------------------------------------
    def geometry(self, index: int) -> PingGeometry:
        """Positions and motion of ping ``index``."""
        sv = self.scene.survey
        time_s = index * sv.ping_interval_s
        roll, pitch, heave = self.scene.motion.at(time_s)
        elements = to_earth_frame(self.element_vessel, roll_deg=roll, heave_m=heave)
        source = to_earth_frame(self.source_vessel, roll_deg=roll, heave_m=heave)
        centre = to_earth_frame(np.zeros(3), roll_deg=roll, heave_m=heave)
        p = math.radians(pitch)
        column = np.array([math.cos(p), 0.0, -math.sin(p)])
        return PingGeometry(index=int(index), time_s=time_s, along_m=index * sv.step_m, roll_deg=roll,
                            pitch_deg=pitch, heave_m=heave, elements=elements, source=source, centre=centre,
                            column=column)

    def _seabed_plane(self, g: PingGeometry) -> _Plane:
        sb = self.scene.seabed
        gx = math.tan(math.radians(sb.slope_along_deg))
        gy = math.tan(math.radians(sb.slope_across_deg))
        return _Plane([0.0, 0.0, float(self.seabed_z(g.along_m, 0.0))], [-gx, -gy, 1.0])

    def _direction_cosine(self, g: PingGeometry, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(|r - s|, u)`` for positions ``(S, 3)``."""
        rel = pos - g.source
        dist = np.sqrt(np.einsum("ij,ij->i", rel, rel))
        return dist, (rel @ g.column) / np.maximum(dist, 1e-12)

    def _buried(self, g: PingGeometry, pos: np.ndarray, depth_below_m: np.ndarray, seabed_z: np.ndarray) -> dict:
        """Refraction delay, in-sediment path and transmission loss of buried points."""
        sb = self.scene.seabed
        legs = []
        for end in (g.source, g.centre):
            rho = np.hypot(pos[:, 0] - end[0], pos[:, 1] - end[1])
            legs.append((refracted_path(rho, seabed_z - end[2], depth_below_m, sb.sound_speed_ratio),
                         np.sqrt(np.sum((pos - end) ** 2, axis=1))))
        extra = sum(leg["time_factor_m"] - straight for leg, straight in legs) / self.c
        path = sum(leg["sediment_m"] for leg, _ in legs)
        v = reflection_coefficient(legs[0][0]["grazing_water_rad"], sb.density_ratio, sb.sound_speed_ratio)
        # ray directions at the array centre: refracted (it arrives from the
        # crossing point of the interface) and straight
        rel = pos - g.centre
        horiz = np.hypot(rel[:, 0], rel[:, 1])
        graz = legs[1][0]["grazing_water_rad"]
        scale = np.cos(graz) / np.maximum(horiz, 1e-12)
        ray = np.stack([rel[:, 0] * scale, rel[:, 1] * scale, np.sin(graz)], axis=1)
        tilt = ray - rel / legs[1][1][:, None]
        return {"extra_s": extra, "b_s": self.alpha_np * path, "transmission": 1 - v * v,
                "grazing_sediment_rad": legs[0][0]["grazing_sediment_rad"], "path_m": path, "rx_tilt": tilt}

    # -- echo sets ---------------------------------------------------------------
    def echoes(self, g: PingGeometry) -> list[_Echoes]:
        """Every echo set of ping ``g``: targets, specular paths, random fields."""
        sets = []
        for t, pts in zip(self.scene.targets, self._lines):
            e = self._point_echo(g, t) if pts is None else self._line_echo(g, t, pts)
            if e is not None and len(e):
                sets.append(e)
        if self.scene.seabed is not None:
            sets.extend(self._specular_echoes(g))
        for f in self._fields:
            e = self._field_echo(g, f)
            if len(e):
                sets.append(e)
        return sets

    def _scatterers(self, label, g, pos, amp, **kw) -> _Echoes:
        dist, u = self._direction_cosine(g, pos)
        return _Echoes(label=label, pos=pos, amp=amp * self.taper(u), src_leg=dist, spread=dist,
                       extra_s=kw.pop("extra_s", np.zeros(len(amp))), u=u, **kw)

    def _point_echo(self, g: PingGeometry, t: PointTarget) -> _Echoes:
        x, y, z = self._target_world(t)
        pos = np.array([[x - g.along_m, y, z]])
        amp = np.array([t.amplitude_m])
        if t.burial_m is None:
            return self._scatterers(t.name, g, pos, amp)
        bur = self._buried(g, pos, np.array([t.burial_m]), np.array([z - t.burial_m]))
        return self._scatterers(t.name, g, pos, amp * bur["transmission"], extra_s=bur["extra_s"], b_s=bur["b_s"],
                                rx_tilt=bur["rx_tilt"])

    def _line_echo(self, g: PingGeometry, t: LineTarget, pts: dict) -> _Echoes | None:
        x_ext = self.max_range_m * self.u_cut / math.sqrt(1 - self.u_cut ** 2)
        lo, hi = np.searchsorted(pts["x"], [g.along_m - x_ext, g.along_m + x_ext])
        if hi <= lo:
            return None
        pos = np.stack([pts["x"][lo:hi] - g.along_m, pts["y"][lo:hi], pts["z"][lo:hi]], axis=1)
        _, u = self._direction_cosine(g, pos)
        keep = np.abs(u) < self.u_cut
        pos = pos[keep]
        amp = np.full(len(pos), t.reflectivity * pts["spacing"])
        medium_c = self.c
        kw = {}
        if t.burial_m is not None:
            medium_c = self.c * self.scene.seabed.sound_speed_ratio
            bur = self._buried(g, pos, np.full(len(pos), t.burial_m), pos[:, 2] - t.burial_m)
            amp = amp * bur["transmission"]
            kw = {"extra_s": bur["extra_s"], "b_s": bur["b_s"], "rx_tilt": bur["rx_tilt"]}
        return self._scatterers(t.name, g, pos, amp, response=functools.partial(t.response, sound_speed_m_s=medium_c),
                                **kw)

    def _specular_echoes(self, g: PingGeometry) -> list[_Echoes]:
        """Image sources: seabed, sub-bottom, first multiple and its doublet.

        The sub-bottom is imaged through an equivalent plane whose normal
        offset ``d c / c_s`` gives the right vertical two-way time (the
        slower sediment is replaced by water of the same travel time).
        """
        sc = self.scene
        sb, sub = sc.seabed, sc.subbottom
        seabed = self._seabed_plane(g)
        surface = _Plane([0.0, 0.0, -sc.sonar.draft_m], [0.0, 0.0, 1.0])
        if sb.specular_model == "forward":
            return self._forward_specular_echoes(g, seabed, surface)
        v1 = float(reflection_coefficient(np.pi / 2, sb.density_ratio, sb.sound_speed_ratio))
        paths = []  # (label, planes, amplitude, two-way sediment path in m)
        if sb.specular:
            paths.append(("seabed", [seabed], v1, 0.0))
        if sb.multiple:
            paths.append(("multiple", [seabed, surface, seabed], -v1 * v1, 0.0))
        if sub is not None:
            c_s = sb.sound_speed_ratio
            z1 = sb.density_ratio * sb.sound_speed_ratio
            z2 = sub.density_ratio * sub.sound_speed_ratio
            v2 = (z2 - z1) / (z2 + z1) * (1 - v1 * v1)
            d = sub.depth_below_seabed_m
            deep = seabed.shifted(d * seabed.n[2] / c_s)  # vertical thickness d, normal thickness d cos(slope)
            if sub.specular:
                paths.append(("subbottom", [deep], v2, 2 * d))
            if sb.multiple and sub.specular:
                paths.append(("multiple-doublet", [seabed, surface, deep], -2 * v1 * v2, 2 * d))
                paths.append(("multiple-subbottom", [deep, surface, deep], -v2 * v2, 4 * d))
        sets = []
        for label, planes, amp, path in paths:
            b = np.array([self.alpha_np * path]) if path > 0 else None
            sets.append(self._image_source(g, label, planes, amp, b_s=b))
        return sets

    def _image_source(self, g: PingGeometry, label: str, planes: list, amp: float, *, b_s=None,
                      response=None) -> _Echoes:
        """The echo of the source mirrored in ``planes`` in turn (amplitude
        ``amp`` times ``response(f)``, spreading along the unfolded path)."""
        img = g.source.copy()
        for p in planes:
            img = p.mirror(img)
        rx = g.centre.copy()
        for p in reversed(planes):
            rx = p.mirror(rx)
        ray = rx - g.source
        u = float(ray @ g.column / np.linalg.norm(ray))
        return _Echoes(label=label, pos=img[None, :], amp=np.array([amp]), src_leg=np.zeros(1), spread=np.ones(1),
                       extra_s=np.zeros(1), u=np.array([u]), b_s=b_s, response=response)

    def forward_seabed(self, water_m: float = 1.0):
        """The scene's seabed as a :class:`clbeam.forward.Seabed`: water
        (``water_m`` thick, lossless), the sediment (its speed, density,
        linear attenuation and the seabed roughness) down to the sub-bottom,
        and the half-space below (or the sediment as the half-space)."""
        from .forward import Interface, Layer, PowerLawAttenuation, Seabed as LayeredSeabed, water_column

        sb, sub = self.scene.seabed, self.scene.subbottom
        rho_w = 1000.0
        k_p = sb.attenuation_db_per_m / (sb.attenuation_ref_hz / 1000.0)  # dB/m/kHz, linear law
        sediment = dict(sound_speed_m_s=sb.sound_speed_ratio * self.c, density_kg_m3=sb.density_ratio * rho_w,
                        attenuation=PowerLawAttenuation(k_p, 1.0), top=Interface(roughness_m=sb.roughness_m),
                        name="sediment")
        layers = [water_column(water_m, sound_speed_m_s=self.c, density_kg_m3=rho_w)]
        if sub is None:
            layers.append(Layer(math.inf, **sediment))
        else:
            layers.append(Layer(sub.depth_below_seabed_m, **sediment))
            layers.append(Layer(math.inf, sub.sound_speed_ratio * self.c, sub.density_ratio * rho_w,
                                top=Interface(roughness_m=sub.roughness_m), name="subbottom"))
        return LayeredSeabed(tuple(layers), name=self.scene.name)

    def forward_specular_response(self, f_hz) -> np.ndarray:
        """``(n_echo, n_freq)`` complex nadir echo factors of the forward model
        without spreading or delay: ``V_i prod(T T') prod(H^2)`` of the seabed
        (row 0) and the sub-bottom (row 1), at ``f_hz``."""
        from .forward import specular_echoes

        e = specular_echoes(self.forward_seabed(), np.asarray(f_hz, dtype=np.float64), incidence_deg=0.0)
        return e.reflection * e.transmission * e.attenuation

    def _forward_specular_echoes(self, g: PingGeometry, seabed: _Plane, surface: _Plane) -> list[_Echoes]:
        """The specular echoes and multiples with the forward model's factors
        (:meth:`forward_specular_response`) as their spectral responses; the
        surface reflects with -1."""
        sb, sub = self.scene.seabed, self.scene.subbottom

        def factor(rows, sign):
            def response(f):
                # the model is evaluated within the band (the band window
                # removes everything more than 2 kHz outside it)
                so = self.scene.sonar
                r = self.forward_specular_response(np.clip(f, 0.5 * so.pulse_f0_hz, 2.0 * so.pulse_f1_hz))
                out = sign * np.ones(len(f), dtype=complex)
                for i in rows:
                    out = out * r[i]
                return out
            return response

        paths = []  # (label, planes, rows of the response multiplied, sign)
        if sb.specular:
            paths.append(("seabed", [seabed], (0,), 1.0))
        if sb.multiple:
            paths.append(("multiple", [seabed, surface, seabed], (0, 0), -1.0))
        if sub is not None:
            deep = seabed.shifted(sub.depth_below_seabed_m * seabed.n[2] / sb.sound_speed_ratio)
            if sub.specular:
                paths.append(("subbottom", [deep], (1,), 1.0))
            if sb.multiple and sub.specular:
                paths.append(("multiple-doublet", [seabed, surface, deep], (0, 1), -2.0))
                paths.append(("multiple-subbottom", [deep, surface, deep], (1, 1), -1.0))
        return [self._image_source(g, label, planes, 1.0, response=factor(rows, sign))
                for label, planes, rows, sign in paths]

    def _field_echo(self, g: PingGeometry, f: dict) -> _Echoes:
        """The random scatterers of one interface that ping ``g`` keeps."""
        x_ext = self.max_range_m * self.u_cut / math.sqrt(1 - self.u_cut ** 2)
        lo, hi = np.searchsorted(f["x"], [g.along_m - x_ext, g.along_m + x_ext])
        x_t, y = f["x"][lo:hi], f["y"][lo:hi]
        z_sb = self.seabed_z(x_t, y)
        pos = np.stack([x_t - g.along_m, y, z_sb + f["depth"] + f["zeta"][lo:hi]], axis=1)
        dist, u = self._direction_cosine(g, pos)
        weight = self.envelope(u)
        keep = (f["q"][lo:hi] < weight) & (np.abs(u) < self.u_cut) & (dist < self.max_range_m + 10)
        pos, dist, u, weight = pos[keep], dist[keep], u[keep], weight[keep]
        z_sb = z_sb[keep]
        g_amp = f["g"][lo:hi][keep]
        density = f["n"][lo:hi][keep] * weight
        sc: Scattering = f["scattering"]
        kw = {}
        trans = 1.0
        if f["depth"] > 0:
            bur = self._buried(g, pos, pos[:, 2] - z_sb, z_sb)
            sin_graz = np.sin(bur["grazing_sediment_rad"])
            trans = bur["transmission"]
            kw = {"extra_s": bur["extra_s"], "b_s": bur["b_s"], "rx_tilt": bur["rx_tilt"]}
        else:
            normal = self._seabed_plane(g).n
            sin_graz = np.abs((pos - g.source) @ normal) / dist
        if f["layer"] == 1 and self._provinces is not None:
            sigma = 10 ** (self.province_strength_db(x_t[keep], np.arcsin(np.clip(sin_graz, 0.0, 1.0))) / 10)
        else:
            sigma = 10 ** (sc.strength_db / 10) * sin_graz ** sc.grazing_exponent
        amp = g_amp * np.sqrt(sigma / density) * trans
        e = _Echoes(label=f"layer{f['layer']}", pos=pos, amp=amp * self.taper(u), src_leg=dist, spread=dist,
                    extra_s=kw.get("extra_s", np.zeros(len(amp))), u=u, b_s=kw.get("b_s"), rx_tilt=kw.get("rx_tilt"))
        if e.b_s is not None:
            cut = e.b_s * self.fc * DB_PER_NEPER <= self.scene.model.attenuation_cut_db
            e = e.subset(cut)
        return e

    # -- rendering ---------------------------------------------------------------
    def ping(self, index: int) -> np.ndarray:
        """Raw samples ``(channel, sample)`` float32 of ping ``index``."""
        g = self.geometry(int(index))
        out = self.render(g, self.echoes(g)).astype(np.float32)
        if self.noise_std > 0:
            rng = np.random.default_rng([self.seed, 1, int(index)])
            noise = rng.standard_normal(out.shape, dtype=np.float32)
            noise *= np.float32(self.noise_std)
            out += noise
        return out

    def render(self, g: PingGeometry, sets: list[_Echoes]) -> np.ndarray:
        """Noise-free samples ``(channel, sample)`` float64 of the echo sets."""
        start = -self.n_pulse - FILTER_PAD - 8
        acc = _Accumulator(len(g.elements), start, self.n_samples - start, self.tables)
        for e in sets:
            filtered = e.response is not None or (e.b_s is not None and bool(np.any(e.b_s > 0)))
            if not filtered:
                self._deposit(g, e, acc)
                continue
            local, b_blocks = self._deposit_local(g, e)
            if local is None:
                continue
            y = self._block_filter(local.total(), b_blocks, e.response)
            lo = local.start - FILTER_PAD - acc.start
            a, b = max(lo, 0), min(lo + y.shape[1], acc.length)
            if b > a:
                acc.imp[:, a:b] += y[:, a - lo:b - lo]
        total = acc.total()
        nfft = scipy.fft.next_fast_len(total.shape[1] + self.n_pulse, real=True)
        spec = scipy.fft.rfft(total, nfft, axis=1)
        spec *= scipy.fft.rfft(self.replica, nfft)[None, :]
        y = scipy.fft.irfft(spec, nfft, axis=1)
        return y[:, -start:-start + self.n_samples]

    def _pair_chunks(self, g: PingGeometry, e: _Echoes):
        """Yield ``(rows, t, w, ws)``: record-sample times and weights ``(S, C)``
        of every scatterer-channel pair, and boxcar widths (samples), by chunks
        of scatterers sorted by arrival."""
        o = g.centre
        eo = g.elements - o
        ee = np.einsum("ij,ij->i", eo, eo)
        rel0 = e.pos - o
        t_centre = e.src_leg + np.sqrt(np.einsum("ij,ij->i", rel0, rel0)) + e.extra_s * self.c
        order = np.argsort(t_centre, kind="stable")
        t_sorted = t_centre[order] * (self.fs / self.c)
        ws_all = self.scene.sonar.tx_length_m * np.abs(e.u) / self.c * self.fs
        n_ch = len(eo)
        step = max(1, CHUNK_PAIRS // n_ch)
        fs_c = self.fs / self.c
        i = 0
        while i < len(order):
            # at most `step` scatterers arriving within CHUNK_SPAN samples, so
            # that each chunk's scratch window stays small
            stop = min(i + step, int(np.searchsorted(t_sorted, t_sorted[i] + CHUNK_SPAN)))
            stop = max(stop, i + 1)
            rows = order[i:stop]
            i = stop
            rel = rel0[rows]
            d2 = rel @ (-2.0 * eo.T)
            d2 += np.einsum("ij,ij->i", rel, rel)[:, None]
            d2 += ee[None, :]
            d = np.sqrt(d2, out=d2)
            t = (d + e.src_leg[rows, None]) * fs_c
            t += ((e.extra_s[rows] - self.t0) * self.fs)[:, None]
            if e.rx_tilt is not None:
                t -= e.rx_tilt[rows] @ (eo.T * (self.fs / self.c))
            w = e.amp[rows, None] / (e.spread[rows, None] * d)
            yield rows, t, w, ws_all[rows]

    def _deposit(self, g: PingGeometry, e: _Echoes, acc: _Accumulator, amp_scale: np.ndarray | None = None) -> None:
        """Deposit an echo set's impulses and transmit boxcars into ``acc``."""
        for rows, t, w, ws in self._pair_chunks(g, e):
            if amp_scale is not None:
                w *= amp_scale[rows, None]
            short = ws < BOXCAR_MIN_SAMPLES
            if short.any():
                # boxcar of width w_s treated as an impulse scaled by its band-centre gain
                gain = np.sinc(self.fc * ws[short] / self.fs)
                acc.impulses(t[short], w[short] * gain[:, None])
            if not short.all():
                long_ = ~short
                half = 0.5 * ws[long_, None]
                h = w[long_] / ws[long_, None]
                acc.steps(t[long_] - half, h)
                acc.steps(t[long_] + half, -h)

    def _deposit_local(self, g: PingGeometry, e: _Echoes):
        """Deposit a filtered set into its own accumulator over its time support;
        return it and the attenuation ``b`` (s) of each filter block."""
        rel = e.pos - g.centre
        t_c = ((e.src_leg + np.sqrt(np.einsum("ij,ij->i", rel, rel))) / self.c + e.extra_s - self.t0) * self.fs
        ws = self.scene.sonar.tx_length_m * np.abs(e.u) / self.c * self.fs
        spread = float(np.max(np.linalg.norm(g.elements - g.centre, axis=1))) / self.c * self.fs + 2
        lo = int(math.floor(np.min(t_c - ws / 2) - spread)) - self.tables[0] - 2
        hi = int(math.ceil(np.max(t_c + ws / 2) + spread)) + self.tables[0] + 2
        lo = max(lo, -self.n_pulse - 8)
        hi = min(hi, self.n_samples + 8)
        if hi <= lo:
            return None, None
        n_blocks = -(-(hi - lo) // FILTER_BLOCK)
        local = _Accumulator(len(g.elements), lo, n_blocks * FILTER_BLOCK, self.tables)
        b = e.b_s if e.b_s is not None else np.zeros(len(e))
        block = np.clip(((t_c - lo) // FILTER_BLOCK).astype(np.intp), 0, n_blocks - 1)
        b_blocks = np.full(n_blocks, np.nan)
        for j in np.unique(block):
            b_blocks[j] = np.median(b[block == j])
        have = np.flatnonzero(np.isfinite(b_blocks))
        b_blocks = np.interp(np.arange(n_blocks), have, b_blocks[have])
        # within a block: exact at the band centre for every scatterer
        scale = np.exp(-(b - b_blocks[block]) * self.fc)
        self._deposit(g, e, local, amp_scale=scale)
        return local, b_blocks

    def _band_window(self, f: np.ndarray) -> np.ndarray:
        """1 over the pulse band widened by 1 kHz, cosine to 0 over another 1 kHz."""
        so = self.scene.sonar
        lo, hi, w = so.pulse_f0_hz - 1000.0, so.pulse_f1_hz + 1000.0, 1000.0
        x = np.clip(np.maximum(lo - f, f - hi) / w, 0.0, 1.0)
        return 0.5 * (1 + np.cos(np.pi * x))

    def _block_filter(self, x: np.ndarray, b_blocks: np.ndarray, response) -> np.ndarray:
        """Zero-phase filter ``W(f) H(f) exp(-b_j f)`` applied to each block ``j``
        of ``x`` (``(C, n_blocks · FILTER_BLOCK)``); the blocks' outputs overlap-add
        into ``(C, n_blocks · FILTER_BLOCK + 2 FILTER_PAD)``."""
        n_ch, n = x.shape
        nb = n // FILTER_BLOCK
        nfft = FILTER_BLOCK + 2 * FILTER_PAD
        buf = np.zeros((nb, n_ch, nfft))
        buf[:, :, FILTER_PAD:FILTER_PAD + FILTER_BLOCK] = x.reshape(n_ch, nb, FILTER_BLOCK).transpose(1, 0, 2)
        f = np.fft.rfftfreq(nfft, 1 / self.fs)
        h = self._band_window(f)
        if response is not None:
            h = h * response(f)
        filt = h[None, :] * np.exp(-np.outer(b_blocks, f))
        y = scipy.fft.irfft(scipy.fft.rfft(buf, axis=2) * filt[:, None, :], nfft, axis=2)
        out = np.zeros((n_ch, n + 2 * FILTER_PAD))
        for j in range(nb):
            out[:, j * FILTER_BLOCK:j * FILTER_BLOCK + nfft] += y[j]
        return out

    # -- truth -------------------------------------------------------------------
    def image_position(self, g: PingGeometry, r: np.ndarray, *, extra_m: float = 0.0,
                       rx_tilt: np.ndarray | None = None) -> tuple[float, float]:
        """Where a 2-D straight-ray imager puts an echo from ``r`` (earth frame, m).

        The point of the plane ``x = 0`` at the echo's apparent range from the
        source and apparent direction cosine on the (rolled) receive-array
        axis.  For an echo in the water these are ``|r - s|`` and the straight
        ray's direction.  A buried echo arrives later and from a slightly
        different direction (refraction at the seabed, :meth:`_buried`).

        Parameters
        ----------
        g : PingGeometry
            The ping.
        r : array_like
            Scatterer position ``(3,)``, earth frame (m).
        extra_m : float
            One-way range added by refraction (m): half the refraction delay
            times the water sound speed.
        rx_tilt : array_like, optional
            Refracted minus straight unit ray direction at the array ``(3,)``.

        Returns
        -------
        (float, float)
            ``(y, z)`` of the image point, earth frame (m).
        """
        q = np.asarray(r, dtype=np.float64) - g.source
        dist = float(np.linalg.norm(q))
        rng = dist + extra_m
        ray = q / max(dist, 1e-12)
        if rx_tilt is not None:
            ray = ray + np.asarray(rx_tilt, dtype=np.float64)
            ray /= np.linalg.norm(ray)
        phi = math.radians(g.roll_deg)
        axis = np.array([0.0, math.cos(phi), math.sin(phi)])
        down = np.array([0.0, -math.sin(phi), math.cos(phi)])
        along = rng * float(ray @ axis)
        p = g.source + along * axis + math.sqrt(max(rng * rng - along * along, 0.0)) * down
        return float(p[1]), float(p[2])

    def truth(self, g: PingGeometry) -> dict:
        """Target positions in the earth frame of ping ``g`` and the seabed depth.

        ``x, y, z``: lines where they cross the image plane ``x = 0``, points
        where they are; ``z`` is below the transducers' mean depth (heave is
        in the source and element positions, not in the frame).
        ``image_y, image_z``: where the imager should show the echo, from the
        point of the target nearest the source (:meth:`image_position`);
        ``u``: that point's direction cosine on the transmit column (the
        beam's −3 dB half-width is about 0.02 at 9 kHz, 0.09 at 2 kHz).
        """
        n = len(self.scene.targets)
        out = {k: np.full(n, np.nan) for k in TRUTH_KEYS}
        for k, (t, pts) in enumerate(zip(self.scene.targets, self._lines)):
            if isinstance(t, PointTarget):
                x, y, z = self._target_world(t)
                out["x"][k], out["y"][k], out["z"][k] = x - g.along_m, y, z
                nearest = np.array([x - g.along_m, y, z])
            else:
                y, z, ang = self._line_crossing_coarse(t, g.along_m)
                out["x"][k], out["y"][k], out["z"][k], out["angle"][k] = 0.0, y, z, ang
                rel = np.stack([pts["x"] - g.along_m, pts["y"], pts["z"]], axis=1) - g.source
                nearest = rel[np.argmin(np.einsum("ij,ij->i", rel, rel))] + g.source
            refraction = {}
            if t.burial_m is not None:
                # the apparent position: the refracted echo arrives later
                # and from the refracted ray's direction at the array
                bur = self._buried(g, nearest[None, :], np.array([t.burial_m]),
                                   np.array([nearest[2] - t.burial_m]))
                refraction = {"extra_m": 0.5 * self.c * float(bur["extra_s"][0]), "rx_tilt": bur["rx_tilt"][0]}
            out["image_y"][k], out["image_z"][k] = self.image_position(g, nearest, **refraction)
            out["u"][k] = float(self._direction_cosine(g, nearest[None, :])[1][0])
            if self.scene.seabed is not None and np.isfinite(out["y"][k]):
                out["seabed_z"][k] = float(self.seabed_z(g.along_m + out["x"][k], out["y"][k]))
        seabed = float(self.seabed_z(g.along_m, 0.0)) if self.scene.seabed is not None else np.nan
        return {"target": out, "seabed_z": seabed}

    # -- the dataset ---------------------------------------------------------------
    def navigation(self, g: PingGeometry) -> tuple[float, float]:
        """Latitude and longitude (degree) of ping ``g`` on a local tangent plane."""
        sv = self.scene.survey
        hd = math.radians(sv.heading_deg)
        east, north = g.along_m * math.sin(hd), g.along_m * math.cos(hd)
        lat = sv.latitude_deg + math.degrees(north / EARTH_RADIUS_M)
        lon = sv.longitude_deg + math.degrees(east / (EARTH_RADIUS_M * math.cos(math.radians(sv.latitude_deg))))
        return lat, lon

    def dataset(self, *, progress: bool = False) -> xr.Dataset:
        """Every prepared ping as a SPEC §7 dataset (with truth variables)."""
        from tqdm import tqdm

        sc = self.scene
        n_p, n_c, n_t = len(self.indices), sc.sonar.n_elements, len(sc.targets)
        samples = np.empty((n_p, n_c, self.n_samples), dtype=np.float32)
        motion = np.zeros((n_p, 3))
        nav = np.zeros((n_p, 2))
        tt = {k: np.full((n_p, n_t), np.nan) for k in TRUTH_KEYS}
        seabed = np.full(n_p, np.nan)
        for j, i in enumerate(tqdm(self.indices, desc="simulate", unit="ping", disable=not progress, leave=False)):
            g = self.geometry(int(i))
            samples[j] = self.ping(int(i))
            motion[j] = (g.roll_deg, g.pitch_deg, g.heave_m)
            nav[j] = self.navigation(g)
            tr = self.truth(g)
            for k in tt:
                tt[k][j] = tr["target"][k]
            seabed[j] = tr["seabed_z"]
        start = np.datetime64(sc.survey.start_time, "ns")
        times = start + (self.indices * sc.survey.ping_interval_s * 1e9).astype("timedelta64[ns]")
        so = sc.sonar
        ev = self.element_vessel
        ds = xr.Dataset(
            {
                "samples": (("ping", "channel", "sample"), samples,
                            {"kind": "raw", "units": "1", "long_name": "element pressure re source pressure at 1 m"}),
                "sample_rate": ((), self.fs, {"units": "Hz", "long_name": "sample rate"}),
                "t0": (("ping",), np.full(n_p, self.t0), {"units": "s", "long_name": "time of sample 0 after transmit start"}),
                "element_x": (("channel",), ev[:, 0], {"units": "m", "long_name": "receive element x (forward), vessel frame"}),
                "element_y": (("channel",), ev[:, 1], {"units": "m", "long_name": "receive element y (starboard), vessel frame"}),
                "element_z": (("channel",), ev[:, 2], {"units": "m", "long_name": "receive element z (down), vessel frame"}),
                "source_x": ((), float(self.source_vessel[0]), {"units": "m", "long_name": "transmit acoustic centre x, vessel frame"}),
                "source_y": ((), float(self.source_vessel[1]), {"units": "m", "long_name": "transmit acoustic centre y, vessel frame"}),
                "source_z": ((), float(self.source_vessel[2]), {"units": "m", "long_name": "transmit acoustic centre z, vessel frame"}),
                "sound_speed": (("ping",), np.full(n_p, self.c), {"units": "m/s", "long_name": "isospeed sound speed"}),
                "roll": (("ping",), motion[:, 0], {"units": "degree", "long_name": "roll, positive starboard down"}),
                "pitch": (("ping",), motion[:, 1], {"units": "degree", "long_name": "pitch, positive bow up"}),
                "heave": (("ping",), motion[:, 2], {"units": "m", "long_name": "heave, positive up"}),
                "heading": (("ping",), np.full(n_p, sc.survey.heading_deg),
                            {"units": "degree", "long_name": "heading, clockwise from north"}),
                "latitude": (("ping",), nav[:, 0], {"units": "degree_north", "long_name": "latitude"}),
                "longitude": (("ping",), nav[:, 1], {"units": "degree_east", "long_name": "longitude"}),
                "ping_time": (("ping",), times, {"long_name": "time of transmission (UTC)"}),
                "pulse_f0": ((), so.pulse_f0_hz, {"units": "Hz", "long_name": "LFM start frequency"}),
                "pulse_f1": ((), so.pulse_f1_hz, {"units": "Hz", "long_name": "LFM end frequency"}),
                "pulse_duration": ((), so.pulse_duration_s, {"units": "s", "long_name": "LFM length"}),
                "channel_valid": (("channel",), np.ones(n_c, dtype=bool), {"units": "1", "long_name": "channel is usable"}),
                "noise_std": ((), self.noise_std, {"units": "1", "long_name": "standard deviation of the added noise per sample"}),
                "truth_target_x": (("ping", "target"), tt["x"],
                                   {"units": "m", "long_name": "target along-track offset from the image plane (0 for lines)"}),
                "truth_target_y": (("ping", "target"), tt["y"],
                                   {"units": "m", "long_name": "target horizontal range, earth frame, starboard positive"}),
                "truth_target_z": (("ping", "target"), tt["z"],
                                   {"units": "m", "long_name": "target depth below the transducers' mean depth"}),
                "truth_target_angle": (("ping", "target"), tt["angle"],
                                       {"units": "degree", "long_name": "line heading relative to the track at the image plane"}),
                "truth_target_seabed_z": (("ping", "target"), tt["seabed_z"],
                                          {"units": "m", "long_name": "seabed depth above the target"}),
                "truth_target_image_y": (("ping", "target"), tt["image_y"],
                                         {"units": "m", "long_name": "expected image y of the echo (nearest point, same range and cone angle)"}),
                "truth_target_image_z": (("ping", "target"), tt["image_z"],
                                         {"units": "m", "long_name": "expected image z of the echo (nearest point, same range and cone angle)"}),
                "truth_target_u": (("ping", "target"), tt["u"],
                                   {"units": "1", "long_name": "along-track direction cosine of the target's nearest point"}),
                "truth_seabed_z": (("ping",), seabed, {"units": "m", "long_name": "seabed depth at nadir below the transducers' mean depth"}),
            },
            coords={
                "ping": ("ping", self.indices, {"long_name": "ping index on the line"}),
                "target": ("target", np.array([t.name for t in sc.targets], dtype=object), {"long_name": "target name"}),
            },
            attrs={
                "clbeam_format": "ping-1",
                "title": f"clbeam simulation of scene '{sc.name}'",
                "source": f"clbeam {__version__} clbeam.simulate",
                "scene": sc.name,
                "scene_json": json.dumps(sc.to_dict()),
                "seed": self.seed,
                "snr_db": "none" if sc.snr_db is None else float(sc.snr_db),
                "reference_amplitude": self.reference_amplitude(),
                "target_kinds": ",".join(_TARGET_KINDS_INV[type(t)] for t in sc.targets),
            },
        )
        if self._provinces is not None:
            mz = np.array([self.province_mz(float(i) * sc.survey.step_m) for i in self.indices])
            ds["truth_province_mz"] = (("ping",), mz, {"units": "phi", "long_name":
                                                      "grain size of the seabed province under the ship"})
        return ds


def simulate(scene, *, pings=None, seed: int = 0, progress: bool = False) -> xr.Dataset:
    """Simulate the pings of a scene as a SPEC §7 ping dataset.

    Parameters
    ----------
    scene : Scene, str or path-like
        A :class:`Scene`, a built-in scene name (``"line1"``, ``"line4"``,
        ``"point"``) or a TOML file.
    pings : int or sequence of int, optional
        All of the scene's pings (default), the first ``n``, or these indices.
    seed : int
        Seed of the random seabed and of the noise; the same seed gives the
        same samples.
    progress : bool
        Show a progress bar.

    Returns
    -------
    xarray.Dataset
        ``samples(ping, channel, sample)`` float32 (``kind="raw"``), geometry,
        motion, navigation and pulse variables with units, global
        ``clbeam_format="ping-1"``, and the truth: ``truth_target_x/y/z``,
        ``truth_target_angle``, ``truth_target_seabed_z (ping, target)`` and
        ``truth_seabed_z (ping)`` in the earth frame (m, degree).
    """
    return Simulator(scene, seed=seed, pings=pings).dataset(progress=progress)


def write(ds: xr.Dataset, path: str | os.PathLike) -> Path:
    """Write a simulated dataset as a ping file: NetCDF4, or Zarr for a
    ``.zarr`` path (:func:`clbeam.ping.write_ping_file`)."""
    from .ping import write_ping_file

    return write_ping_file(ds, path)
