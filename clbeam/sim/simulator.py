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
and heave, :func:`clbeam.model.grid.to_earth_frame`), ``x`` the LFM replica
(:func:`clbeam.imaging.signal.lfm_replica`) and ``b`` the along-track transmit beam:
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

With a sound-speed profile (``[water]``: ``svp_depth_m``, ``svp_speed_m_s``
on the earth-frame ``z`` axis) the delays are ray traced instead
(:mod:`clbeam.imaging.raytrace`): ``τ_n`` is the eigenray time from the source to
the scatterer plus the one from the scatterer to element ``n``, through the
water profile, or for buried scatterers through it and the sediment below
the seabed; the image-source echoes are unfolded through the layers they
cross.  The spreading stays ``1 / (|r - s| |r - e_n|)`` on the straight
distances.

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
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.fft
import scipy.optimize
import tomllib
import xarray as xr

from clbeam import __version__
from clbeam.constants import KNOT_M_S, WATER_SPEED_RANGE_M_S
from clbeam.errors import ClbeamError, OptionError, require
from clbeam.imaging.geometry import to_earth_frame
from clbeam.imaging.raytrace import eigenrays
from clbeam.io.schema import FORMAT_ATTRIBUTE, PING_FORMAT, ping_variable
from clbeam.model.geodesy import geodesic_direct
from clbeam.model.pulse import lfm_replica
from clbeam.model.svp import SoundSpeedProfile

log = logging.getLogger(__name__)

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
    burial_m: float | None = None
    z_m: float | None = None
    reflectivity: float = 0.8

    def __post_init__(self):
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
    """

    tx_beam_cut: float = 1.0
    attenuation_cut_db: float = 40.0
    line_spacing_m: float | None = None

    def __post_init__(self):
        require(0 < self.tx_beam_cut <= 3, OptionError, f"model.tx_beam_cut must be within (0, 3], got {self.tx_beam_cut}")
        require(self.attenuation_cut_db > 0, OptionError, f"model.attenuation_cut_db must be > 0, got {self.attenuation_cut_db}")
        require(self.line_spacing_m is None or self.line_spacing_m > 0, OptionError,
                f"model.line_spacing_m must be > 0 m, got {self.line_spacing_m}")


"""Sound speeds (m/s) a water column (``sound_speed_m_s``, ``[water]``) may have."""


@dataclass(frozen=True)
class Water:
    """The water column's sound-speed profile (``[water]``).

    Depths are on the earth-frame ``z`` axis, like ``element_z``: metres
    below the transducers' mean depth (the array reference point), positive
    down; the sea surface is at ``z = -draft``.  The speed is linear in depth
    between points and constant beyond the first and the last
    (:class:`clbeam.imaging.raytrace.SoundSpeedProfile`).  Below the seabed the
    sediment's speed (``seabed.sound_speed_ratio`` times the profile's speed
    at the seabed) replaces it.

    Attributes
    ----------
    svp_depth_m : tuple of float
        Profile depths (m), strictly increasing.
    svp_speed_m_s : tuple of float
        Sound speed at each depth (m/s), 1300-1700.
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
        """The profile as a :class:`clbeam.imaging.raytrace.SoundSpeedProfile`."""
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
    water: Water | None = None

    def __post_init__(self):
        require(1300 <= self.sound_speed_m_s <= 1700, OptionError,
                f"sound_speed_m_s must be within 1300-1700 m/s, got {self.sound_speed_m_s}")
        if self.water is not None:
            c0 = self.water.transducer_speed_m_s
            require(abs(self.sound_speed_m_s - c0) <= 1e-6, OptionError,
                    f"sound_speed_m_s {self.sound_speed_m_s:g} m/s is not the [water] profile's speed at the "
                    f"transducers (z = 0), {c0:.10g} m/s: leave sound_speed_m_s out (or set it to that)")
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
        if d["water"] is None:
            del d["water"]
        d["target"] = [dict(kind=_TARGET_KINDS_INV[type(t)], **dataclasses.asdict(t)) for t in self.targets]
        return d


TRUTH_VARIABLES = {
    "x": ("m", "target along-track offset from the image plane (0 for lines)"),
    "y": ("m", "target horizontal range, earth frame, starboard positive"),
    "z": ("m", "target depth below the transducers' mean depth"),
    "angle": ("degree", "line heading relative to the track at the image plane"),
    "seabed_z": ("m", "seabed depth above the target"),
    "image_y": ("m", "expected image y of the echo (nearest point, same range and cone angle)"),
    "image_z": ("m", "expected image z of the echo (nearest point, same range and cone angle)"),
    "u": ("1", "along-track direction cosine of the target's nearest point"),
}
"""Per-target truth of :meth:`Simulator.truth`, stored as ``truth_target_<key>``: units and long name."""
TRUTH_KEYS = tuple(TRUTH_VARIABLES)

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
    if data.get("water") is not None and "sound_speed_m_s" not in data:
        # the transducers' speed follows from the profile
        water = _convert(Water, data["water"], "water")
        data["sound_speed_m_s"] = water.transducer_speed_m_s
    scene = _from_mapping(Scene, data, "")
    scene = dataclasses.replace(scene, targets=tuple(targets))
    if name is not None:
        scene = dataclasses.replace(scene, name=name)
    return scene


def list_scenes() -> list[str]:
    """Names of the built-in scenes (``clbeam/scenes/*.toml``)."""
    root = importlib.resources.files("clbeam.sim.scenes")
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def _read_toml(source: str | os.PathLike) -> tuple[dict, str]:
    text_source = str(source)
    if text_source in list_scenes():
        text = importlib.resources.files("clbeam.sim.scenes").joinpath(f"{text_source}.toml").read_text()
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
        ``"line1"``, ``"line4"``, ``"point"``, ``"avo2"``, ``"svp1km"`` (see :func:`list_scenes`), a
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
# Rays through a sound-speed profile (scenes with [water])
# ---------------------------------------------------------------------------
RAY_PAIRS = 1 << 18
"""End-scatterer pairs per call of the eigenray solver (memory bound)."""
SEABED_RAY_TOL_REL = 1e-9
"""Seabed crossing of a ray to a point below a sloped seabed: converged when
the horizontal miss is below this times the distance (1 µm at 1 km)."""


def _ray_legs(profile: SoundSpeedProfile, ends: np.ndarray, pos: np.ndarray, *, directions: bool = True) -> dict:
    """Direct eigenrays between ``ends`` ``(P, 3)`` and positions ``(S, 3)``
    (earth frame, m; ``z`` on the profile's axis) in a horizontally
    stratified medium: each pair's ray lies in their vertical plane, solved
    from the shallower end (:func:`clbeam.imaging.raytrace.eigenrays`).

    Returns
    -------
    dict
        ``time_s`` ``(P, S)`` one-way times (s), NaN where no direct ray joins
        the pair; with ``directions`` also ``p`` ``(P, S)`` the magnitude of the
        ray parameter (s/m), ``end_dir`` and ``pos_dir`` ``(P, S, 3)`` the
        unit propagation directions at the end (leaving it) and at the
        position (arriving there from the end).
    """
    ends = np.asarray(ends, dtype=np.float64)
    pos = np.asarray(pos, dtype=np.float64)
    n_e, n_s = len(ends), len(pos)
    out = {"time_s": np.full((n_e, n_s), np.nan)}
    if directions:
        out.update(p=np.full((n_e, n_s), np.nan), end_dir=np.full((n_e, n_s, 3), np.nan),
                   pos_dir=np.full((n_e, n_s, 3), np.nan))
    step = max(1, RAY_PAIRS // max(n_e, 1))
    for a in range(0, n_s, step):
        sl = slice(a, min(a + step, n_s))
        d = pos[None, sl, :] - ends[:, None, :]
        rho = np.hypot(d[..., 0], d[..., 1])
        z_end = np.broadcast_to(ends[:, None, 2], rho.shape)
        z_pos = np.broadcast_to(pos[None, sl, 2], rho.shape)
        down = z_pos >= z_end
        r = eigenrays(profile, np.where(down, z_end, z_pos), rho, np.where(down, z_pos, z_end))
        out["time_s"][:, sl] = r.time_s
        if not directions:
            continue
        out["p"][:, sl] = np.abs(r.ray_parameter_s_m)
        h = d[..., :2] / np.maximum(rho, 1e-300)[..., None]
        # a ray solved from the position down to the end runs backwards
        for key, s_, c_ in (("end_dir", np.where(down, r.launch_sin, r.arrival_sin),
                             np.where(down, r.launch_cos, -r.arrival_cos)),
                            ("pos_dir", np.where(down, r.arrival_sin, r.launch_sin),
                             np.where(down, r.arrival_cos, -r.launch_cos))):
            out[key][:, sl, :2] = h * np.abs(s_)[..., None]
            out[key][:, sl, 2] = c_
    return out


def _seabed_ray_legs(water: SoundSpeedProfile, ends: np.ndarray, pos: np.ndarray, seabed_z: np.ndarray,
                     sediment_speed_m_s: np.ndarray, *, directions: bool = True) -> dict:
    """Like :func:`_ray_legs` for positions below a locally flat seabed.

    Position ``j`` lies below a horizontal interface at ``seabed_z[j]`` with
    the constant sediment speed ``sediment_speed_m_s[j]`` below it and the
    ``water`` profile above; the ends lie above it.  The ray is the water
    eigenray from the end to the seabed crossing at horizontal distance
    ``y_w`` plus a straight sediment segment at Snell's angle
    (``sin θ_s = p c_s``); Newton's method on ``y_w`` makes the two meet
    (``y_w + b tan θ_s = ρ``, ``b`` the depth below the seabed).  The time is
    the Fermat time through the crossing point, stationary in ``y_w``.  For
    one seabed depth this is the eigenray of
    :meth:`~clbeam.imaging.raytrace.SoundSpeedProfile.with_sediment`; per position it
    handles a sloped seabed taken as locally flat.
    """
    ends = np.asarray(ends, dtype=np.float64)
    pos = np.asarray(pos, dtype=np.float64)
    d = pos[None, :, :] - ends[:, None, :]
    rho = np.hypot(d[..., 0], d[..., 1])
    z0 = np.broadcast_to(ends[:, None, 2], rho.shape)
    zs = np.broadcast_to(np.asarray(seabed_z, dtype=np.float64)[None, :], rho.shape)
    b = np.maximum(np.broadcast_to(pos[None, :, 2], rho.shape) - zs, 0.0)
    cs = np.broadcast_to(np.asarray(sediment_speed_m_s, dtype=np.float64)[None, :], rho.shape)
    c_end = water.speed(z0)
    tol = SEABED_RAY_TOL_REL * np.hypot(rho, zs + b - z0)
    yw = rho * (zs - z0) / np.maximum(zs + b - z0, 1e-300)       # the straight line's crossing
    for _ in range(40):
        r = eigenrays(water, z0, yw, zs)
        p = np.abs(r.ray_parameter_s_m)
        sin_s = p * cs
        cos_s = np.sqrt(np.maximum(1.0 - sin_s * sin_s, 1e-300))
        miss = yw + b * sin_s / cos_s - rho
        if not np.any(np.abs(miss) > tol):          # NaN (no water ray) counts as done
            break
        # d(miss)/d(yw) = 1 + b c_s / cos^3 · dp/dX, dX/dp = rho_wf c_end / cos_end^2
        dxdp = r.wavefront_radius_m * c_end / np.maximum(r.launch_cos ** 2, 1e-300)
        slope = 1.0 + b * cs / cos_s ** 3 / np.maximum(dxdp, 1e-300)
        yw = np.where(np.isfinite(miss), np.clip(yw - miss / slope, 0.0, rho), yw)
    else:
        bad = np.abs(miss) > tol
        log.warning("%d rays to points below the seabed did not converge; they are dropped", int(bad.sum()))
        r = dataclasses.replace(r, time_s=np.where(bad, np.nan, r.time_s))
    time = r.time_s + np.hypot(b, rho - yw) / cs
    out = {"time_s": time}
    if directions:
        h = d[..., :2] / np.maximum(rho, 1e-300)[..., None]
        end_dir = np.empty(rho.shape + (3,))
        pos_dir = np.empty(rho.shape + (3,))
        end_dir[..., :2] = h * np.abs(r.launch_sin)[..., None]
        end_dir[..., 2] = r.launch_cos
        pos_dir[..., :2] = h * sin_s[..., None]
        pos_dir[..., 2] = np.where(np.isfinite(time), cos_s, np.nan)
        out.update(p=p, end_dir=end_dir, pos_dir=pos_dir)
    return out


def _ray_offset_time(profile: SoundSpeedProfile, p: float, z0: float, z1: float) -> tuple[float, float]:
    """Horizontal offset (m) and time (s) of a downgoing ray of ray parameter
    ``p >= 0`` from depth ``z0`` to ``z1 >= z0``; NaN where it turns before.

    Per piece of constant gradient ``g`` from ``a`` to ``b`` (``h = b - a``):
    ``X = p h (c_a + c_b) / (cos_a + cos_b)`` and
    ``T = ln(c_b (1 + cos_a) / (c_a (1 + cos_b))) / g`` (``h / (c cos)`` when
    ``g h`` is negligible).
    """
    cuts = [z0] + [float(z) for z in np.unique(profile.depths_m) if z0 < z < z1] + [z1]
    x = t = 0.0
    for a, b in zip(cuts, cuts[1:]):
        h = b - a
        if h <= 0:
            continue
        ca, cb = float(profile.speed(a, side="below")), float(profile.speed(b, side="above"))
        sa, sb = p * ca, p * cb
        if sa >= 1.0 or sb >= 1.0:
            return math.nan, math.nan
        cos_a, cos_b = math.sqrt(1.0 - sa * sa), math.sqrt(1.0 - sb * sb)
        x += p * h * (ca + cb) / (cos_a + cos_b)
        g = (cb - ca) / h
        if abs(g * h) <= 1e-9 * ca:
            t += 2.0 * h / (ca * cos_a + cb * cos_b)
        else:
            t += math.log(cb * (1.0 + cos_a) / (ca * (1.0 + cos_b))) / g
    return x, t


def _turning_depth(profile: SoundSpeedProfile, p: float, z0: float) -> float:
    """Depth (m) below ``z0`` where a ray of ray parameter ``p`` turns
    (``p c = 1``), ``inf`` if it never does."""
    if p <= 0:
        return math.inf
    cuts = [z0] + [float(z) for z in np.unique(profile.depths_m) if z > z0]
    for a, b in zip(cuts, cuts[1:] + [math.inf]):
        ca = float(profile.speed(a, side="below"))
        if p * ca >= 1.0:
            return a
        if math.isfinite(b):
            cb = float(profile.speed(b, side="above"))
            if p * cb >= 1.0:
                return a + (1.0 / p - ca) * (b - a) / (cb - ca)
    return math.inf


def _ray_point(profile: SoundSpeedProfile, z0: float, sin0: float, time_s: float) -> tuple[float, float]:
    """Where the ray leaving depth ``z0`` at ``sin0`` from nadir (signed,
    downgoing) is after ``time_s``: ``(y offset, z)`` (m), NaN if it turns
    first."""
    p = abs(sin0) / float(profile.speed(z0))
    z_hi = z0 + float(np.max(profile.speeds_m_s)) * time_s * 1.000001
    z_turn = _turning_depth(profile, p, z0)
    if z_turn < z_hi:
        z_hi = z0 + (z_turn - z0) * (1.0 - 1e-12)

    def late(z):
        return _ray_offset_time(profile, p, z0, z)[1] - time_s

    if not late(z_hi) >= 0:
        return math.nan, math.nan
    z = scipy.optimize.brentq(late, z0, z_hi, xtol=1e-10, rtol=1e-14, maxiter=200)
    return math.copysign(_ray_offset_time(profile, p, z0, z)[0], sin0), z


def _unfold(medium: SoundSpeedProfile, turns: list[float]) -> tuple[SoundSpeedProfile, float, float]:
    """A ray reflected at horizontal planes, unfolded into a downgoing one.

    The ray leaves downward, reflects at depth ``turns[0]`` (a bottom, from
    above), then ``turns[1]`` (a top, from below), and so on alternately.
    Returns the profile along the unfolded depth ``s`` (``s = z`` before the
    first turn), the unfolded depth ``S`` of the last turn and its depth
    ``R``: after an odd number of turns a point at depth ``z`` on the last
    (upgoing) leg is at ``s = S + (R - z)``.
    """
    d, c = medium.depths_m, medium.speeds_m_s
    pts: list[tuple[float, float]] = [(float(z), float(v)) for z, v in zip(d, c) if z < turns[0]]
    pts.append((turns[0], float(medium.speed(turns[0], side="above"))))
    s_turn, z_turn = turns[0], turns[0]
    legs = list(turns[1:]) + [None]
    for i, nxt in enumerate(legs):
        up = i % 2 == 0                         # after a bottom the ray goes up
        if up:
            inside = [(z, v) for z, v in zip(d[::-1], c[::-1]) if z < z_turn and (nxt is None or z > nxt)]
            pts.extend((s_turn + (z_turn - z), float(v)) for z, v in inside)
        else:
            inside = [(z, v) for z, v in zip(d, c) if z > z_turn and (nxt is None or z < nxt)]
            pts.extend((s_turn + (z - z_turn), float(v)) for z, v in inside)
        if nxt is None:
            break
        s_next = s_turn + abs(z_turn - nxt)
        pts.append((s_next, float(medium.speed(nxt, side="below" if up else "above"))))
        s_turn, z_turn = s_next, nxt
    uniq = [pts[0]]
    for q in pts[1:]:
        if q != uniq[-1]:
            uniq.append(q)
    s_arr, c_arr = (np.array(v) for v in zip(*uniq))
    return SoundSpeedProfile(s_arr, c_arr), float(s_turn), float(z_turn)


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
    delay across the array); ``times_s``: with a sound-speed profile, the
    ray-traced two-way time of every scatterer-channel pair ``(S, C)`` (s),
    in place of the straight-ray delay from ``src_leg``, ``extra_s`` and
    ``rx_tilt`` (the spreading is still ``spread`` times the straight receive
    leg).
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
    times_s: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.amp)

    def subset(self, mask: np.ndarray) -> "_Echoes":
        return dataclasses.replace(
            self, pos=self.pos[mask], amp=self.amp[mask], src_leg=self.src_leg[mask], spread=self.spread[mask],
            extra_s=self.extra_s[mask], u=self.u[mask], b_s=None if self.b_s is None else self.b_s[mask],
            rx_tilt=None if self.rx_tilt is None else self.rx_tilt[mask],
            times_s=None if self.times_s is None else self.times_s[mask])


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
        self._setup_profile()
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
        t_end = 2 * self.max_range_m / self.c_min + so.pulse_duration_s
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
    def _setup_profile(self) -> None:
        """The scene's sound-speed profile (``[water]``), if any.

        ``svp``: the water profile (``None``: isospeed); ``svp_sediment``: it
        cut at a flat seabed with the sediment's speed below (``None`` without
        a seabed or with a sloped one); ``c``: the speed at the transducers;
        ``c_min``: the slowest speed of the profile (record length, pipeline
        point spacing); ``c_seabed``: the water speed at the seabed under the
        first ping (the sediment's speed is ``sound_speed_ratio`` times it).
        Isospeed: all ``sound_speed_m_s``.
        """
        sc = self.scene
        self.svp = self.svp_sediment = None
        self.c_min = self.c_seabed = self.c
        if sc.water is None:
            return
        self.svp = sc.water.profile()
        self.c = float(self.svp.speed(0.0))
        self.c_min = float(np.min(self.svp.speeds_m_s))
        sb = sc.seabed
        if sb is not None:
            z_sb = sb.depth_m - sc.sonar.draft_m
            self.c_seabed = float(self.svp.speed(z_sb, side="above"))
            if sb.slope_along_deg == 0 and sb.slope_across_deg == 0:
                self.svp_sediment = SoundSpeedProfile.with_sediment(self.svp, z_sb,
                                                                    sb.sound_speed_ratio * self.c_seabed)

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
        from clbeam.seabed.avo import backscatter_strength_db

        table = np.stack([backscatter_strength_db(self.PROVINCE_GRAZING_DEG, self.fc, mz=p.mz,
                                                  sound_speed_water_m_s=self.c_seabed) for p in sb.province])
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
            wl_min = self.c_min / (1.05 * self.scene.sonar.pulse_f1_hz)
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

    # -- rays through the profile ---------------------------------------------------
    def _legs(self, ends: np.ndarray, pos: np.ndarray, *, buried: bool = False, seabed_z=None,
              directions: bool = True) -> dict:
        """Ray-traced legs between ``ends`` ``(P, 3)`` and scatterers ``pos``
        ``(S, 3)`` (:func:`_ray_legs`): through the water profile, or for
        ``buried`` scatterers (below the seabed at depths ``seabed_z`` ``(S,)``)
        through the profile with the sediment below a flat seabed, or past a
        locally flat seabed at ``seabed_z`` when it is sloped
        (:func:`_seabed_ray_legs`)."""
        if not buried:
            return _ray_legs(self.svp, ends, pos, directions=directions)
        if self.svp_sediment is not None:
            return _ray_legs(self.svp_sediment, ends, pos, directions=directions)
        zs = np.asarray(seabed_z, dtype=np.float64)
        c_s = self.scene.seabed.sound_speed_ratio * self.svp.speed(zs, side="above")
        return _seabed_ray_legs(self.svp, ends, pos, zs, c_s, directions=directions)

    def _source_rays(self, g: PingGeometry, pos: np.ndarray, **kw) -> dict:
        """Ray-traced source legs of scatterers ``pos`` ``(S, 3)``: ``time_s``,
        ``p``, ``launch`` (direction leaving the source), ``arrival`` (at the
        scatterer) and ``u``, the launch direction's cosine on the transmit
        column (the transmit beam sees the ray's launch direction)."""
        r = {k: v[0] for k, v in self._legs(g.source[None, :], pos, **kw).items()}
        r["launch"], r["arrival"] = r.pop("end_dir"), r.pop("pos_dir")
        r["u"] = r["launch"] @ g.column
        return r

    def _buried_rays(self, g: PingGeometry, pos: np.ndarray, seabed_z: np.ndarray, src: dict) -> dict:
        """In-sediment path, attenuation and transmission of buried scatterers
        from their ray-traced legs (the source's and the array centre's), as
        :meth:`_buried` does with Snell rays from straight water paths."""
        sb = self.scene.seabed
        b = np.maximum(pos[:, 2] - seabed_z, 0.0)
        cos_c = self._legs(g.centre[None, :], pos, buried=True, seabed_z=seabed_z)["pos_dir"][0, :, 2]
        cos_s = src["arrival"][:, 2]
        path = b / cos_s + b / cos_c
        sin_w = np.clip(src["p"] * self.svp.speed(seabed_z, side="above"), 0.0, 1.0)
        v = reflection_coefficient(np.arccos(sin_w), sb.density_ratio, sb.sound_speed_ratio)
        return {"b_s": self.alpha_np * path, "transmission": 1 - v * v, "path_m": path,
                "grazing_sediment_rad": np.arcsin(np.clip(cos_s, 0.0, 1.0))}

    def _traced_echoes(self, label: str, g: PingGeometry, pos: np.ndarray, amp: np.ndarray, src: dict, *,
                       buried: bool = False, seabed_z=None, b_s=None, response=None) -> _Echoes:
        """An echo set whose two-way times are ray traced: the source leg
        ``src`` (:meth:`_source_rays`) plus each element's leg.  Scatterers
        that a direct ray does not reach (from the source or any element) are
        dropped.  Spreading stays ``1 / (|r - s| |r - e_n|)`` on the straight
        distances."""
        rx = self._legs(g.elements, pos, buried=buried, seabed_z=seabed_z, directions=False)["time_s"]
        times = src["time_s"][:, None] + rx.T
        ok = np.all(np.isfinite(times), axis=1) & np.isfinite(amp) & np.isfinite(src["u"])
        if b_s is not None:
            ok &= np.isfinite(b_s)
        if not ok.all():
            log.info("%s: %d of %d scatterers have no direct ray to the source or an element; dropped",
                     label, int((~ok).sum()), ok.size)
        dist = np.linalg.norm(pos - g.source, axis=1)
        u = src["u"]
        return _Echoes(label=label, pos=pos[ok], amp=(amp * self.taper(u))[ok], src_leg=dist[ok], spread=dist[ok],
                       extra_s=np.zeros(int(ok.sum())), u=u[ok], b_s=None if b_s is None else b_s[ok],
                       response=response, times_s=times[ok])

    def _specular_times(self, g: PingGeometry, names: list[str], img: np.ndarray) -> np.ndarray:
        """``(1, C)`` two-way times of an image-source path through the profile.

        ``names`` are the reflectors in turn (``"seabed"``, ``"surface"``,
        ``"deep"``: the sub-bottom).  Flat seabed: the exact eigenray of the
        unfolded path (:func:`_unfold`) from the source to each element.  A
        sloped seabed: the straight image-source time at the transducers'
        speed plus the profile's correction of the same path with flat
        reflectors at the nadir depths (vertical, source to array centre).
        """
        sc, sb = self.scene, self.scene.seabed
        z_sb = float(self.seabed_z(g.along_m, 0.0))
        d = sc.subbottom.depth_below_seabed_m if sc.subbottom is not None else 0.0
        depth = {"seabed": z_sb, "surface": -sc.sonar.draft_m, "deep": z_sb + d}

        def unfolded_times(medium, turns, ends):
            unf, s_last, z_last = _unfold(medium, turns)
            e = np.array(ends, dtype=np.float64)
            e[:, 2] = s_last + (z_last - e[:, 2])
            return _ray_legs(unf, g.source[None, :], e, directions=False)["time_s"][0]

        turns = [depth[n] for n in names]
        if self.svp_sediment is not None:
            return unfolded_times(self.svp_sediment, turns, g.elements)[None, :]
        medium = SoundSpeedProfile.with_sediment(self.svp, z_sb, sb.sound_speed_ratio
                                                 * float(self.svp.speed(z_sb, side="above")))
        t_prof = unfolded_times(medium, turns, g.centre[None, :])[0]
        equiv = {**depth, "deep": z_sb + d / sb.sound_speed_ratio}    # the isospeed model's equivalent plane
        t_iso = unfolded_times(SoundSpeedProfile.constant(self.c), [equiv[n] for n in names], g.centre[None, :])[0]
        straight = np.linalg.norm(g.elements - img, axis=1) / self.c
        return (straight + (t_prof - t_iso))[None, :]

    # -- echo sets ---------------------------------------------------------------
    def echoes(self, g: PingGeometry) -> list[_Echoes]:
        """Every echo set of ping ``g``: targets, specular paths, random fields."""
        sets = []
        for t, pts in zip(self.scene.targets, self._lines):
            e = self._point_echo(g, t) if pts is None else self._line_echo(g, t, pts)
            if e is not None and len(e):
                sets.append(e)
        if self.scene.seabed is not None:
            sets.extend(e for e in self._specular_echoes(g) if len(e))
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
        if self.svp is not None:
            buried = t.burial_m is not None
            zsb = np.array([z - t.burial_m]) if buried else None
            src = self._source_rays(g, pos, buried=buried, seabed_z=zsb)
            b_s = None
            if buried:
                bur = self._buried_rays(g, pos, zsb, src)
                amp, b_s = amp * bur["transmission"], bur["b_s"]
            e = self._traced_echoes(t.name, g, pos, amp, src, buried=buried, seabed_z=zsb, b_s=b_s)
            if not len(e):
                log.warning("target '%s': no direct ray reaches it in ping %d; left out", t.name, g.index)
            return e
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
        if self.svp is not None:
            return self._line_echo_traced(g, t, pts, pos)
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

    def _line_echo_traced(self, g: PingGeometry, t: LineTarget, pts: dict, pos: np.ndarray) -> _Echoes:
        """:meth:`_line_echo` through the sound-speed profile."""
        buried = t.burial_m is not None
        zsb = pos[:, 2] - t.burial_m if buried else None
        src = self._source_rays(g, pos, buried=buried, seabed_z=zsb)
        keep = np.abs(src["u"]) < self.u_cut             # NaN: no ray, out
        pos, src = pos[keep], {k: v[keep] for k, v in src.items()}
        zsb = zsb[keep] if buried else None
        amp = np.full(len(pos), t.reflectivity * pts["spacing"])
        b_s = None
        if buried:
            medium_c = self.c_seabed * self.scene.seabed.sound_speed_ratio
            bur = self._buried_rays(g, pos, zsb, src)
            amp, b_s = amp * bur["transmission"], bur["b_s"]
        else:
            medium_c = float(self.svp.speed(np.median(pos[:, 2]))) if len(pos) else self.c
        return self._traced_echoes(t.name, g, pos, amp, src, buried=buried, seabed_z=zsb, b_s=b_s,
                                   response=functools.partial(t.response, sound_speed_m_s=medium_c))

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
        names = {id(seabed): "seabed", id(surface): "surface"}
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
            names[id(deep)] = "deep"
            if sub.specular:
                paths.append(("subbottom", [deep], v2, 2 * d))
            if sb.multiple and sub.specular:
                paths.append(("multiple-doublet", [seabed, surface, deep], -2 * v1 * v2, 2 * d))
                paths.append(("multiple-subbottom", [deep, surface, deep], -v2 * v2, 4 * d))
        sets = []
        for label, planes, amp, path in paths:
            b = np.array([self.alpha_np * path]) if path > 0 else None
            sets.append(self._image_source(g, label, planes, amp, b_s=b, names=[names[id(p)] for p in planes]))
        return sets

    def _image_source(self, g: PingGeometry, label: str, planes: list, amp: float, *, b_s=None,
                      response=None, names=None) -> _Echoes:
        """The echo of the source mirrored in ``planes`` in turn (amplitude
        ``amp`` times ``response(f)``, spreading along the unfolded path).
        With a sound-speed profile the times follow it
        (:meth:`_specular_times`; ``names`` name the planes)."""
        img = g.source.copy()
        for p in planes:
            img = p.mirror(img)
        rx = g.centre.copy()
        for p in reversed(planes):
            rx = p.mirror(rx)
        ray = rx - g.source
        u = float(ray @ g.column / np.linalg.norm(ray))
        e = _Echoes(label=label, pos=img[None, :], amp=np.array([amp]), src_leg=np.zeros(1), spread=np.ones(1),
                    extra_s=np.zeros(1), u=np.array([u]), b_s=b_s, response=response)
        if self.svp is None or names is None:
            return e
        e.times_s = self._specular_times(g, names, img)
        if not np.all(np.isfinite(e.times_s)):
            log.warning("%s echo: no direct unfolded ray to some element in ping %d; left out", label, g.index)
            return e.subset(np.zeros(1, dtype=bool))
        return e

    def forward_seabed(self, water_m: float = 1.0):
        """The scene's seabed as a :class:`clbeam.seabed.forward.Seabed`: water
        (``water_m`` thick, lossless), the sediment (its speed, density,
        linear attenuation and the seabed roughness) down to the sub-bottom,
        and the half-space below (or the sediment as the half-space)."""
        from clbeam.seabed.forward import (
            Interface,
            Layer,
            PowerLawAttenuation,
            water_column,
        )
        from clbeam.seabed.forward import Seabed as LayeredSeabed

        sb, sub = self.scene.seabed, self.scene.subbottom
        rho_w = 1000.0
        k_p = sb.attenuation_db_per_m / (sb.attenuation_ref_hz / 1000.0)  # dB/m/kHz, linear law
        c_w = self.c_seabed  # the water's speed at the seabed (isospeed: sound_speed_m_s)
        sediment = dict(sound_speed_m_s=sb.sound_speed_ratio * c_w, density_kg_m3=sb.density_ratio * rho_w,
                        attenuation=PowerLawAttenuation(k_p, 1.0), top=Interface(roughness_m=sb.roughness_m),
                        name="sediment")
        layers = [water_column(water_m, sound_speed_m_s=c_w, density_kg_m3=rho_w)]
        if sub is None:
            layers.append(Layer(math.inf, **sediment))
        else:
            layers.append(Layer(sub.depth_below_seabed_m, **sediment))
            layers.append(Layer(math.inf, sub.sound_speed_ratio * c_w, sub.density_ratio * rho_w,
                                top=Interface(roughness_m=sub.roughness_m), name="subbottom"))
        return LayeredSeabed(tuple(layers), name=self.scene.name)

    def forward_specular_response(self, f_hz) -> np.ndarray:
        """``(n_echo, n_freq)`` complex nadir echo factors of the forward model
        without spreading or delay: ``V_i prod(T T') prod(H^2)`` of the seabed
        (row 0) and the sub-bottom (row 1), at ``f_hz``."""
        from clbeam.seabed.forward import specular_echoes

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

        names = {id(seabed): "seabed", id(surface): "surface"}
        paths = []  # (label, planes, rows of the response multiplied, sign)
        if sb.specular:
            paths.append(("seabed", [seabed], (0,), 1.0))
        if sb.multiple:
            paths.append(("multiple", [seabed, surface, seabed], (0, 0), -1.0))
        if sub is not None:
            deep = seabed.shifted(sub.depth_below_seabed_m * seabed.n[2] / sb.sound_speed_ratio)
            names[id(deep)] = "deep"
            if sub.specular:
                paths.append(("subbottom", [deep], (1,), 1.0))
            if sb.multiple and sub.specular:
                paths.append(("multiple-doublet", [seabed, surface, deep], (0, 1), -2.0))
                paths.append(("multiple-subbottom", [deep, surface, deep], (1, 1), -1.0))
        return [self._image_source(g, label, planes, 1.0, response=factor(rows, sign),
                                   names=[names[id(p)] for p in planes])
                for label, planes, rows, sign in paths]

    def _field_echo(self, g: PingGeometry, f: dict) -> _Echoes:
        """The random scatterers of one interface that ping ``g`` keeps."""
        x_ext = self.max_range_m * self.u_cut / math.sqrt(1 - self.u_cut ** 2)
        lo, hi = np.searchsorted(f["x"], [g.along_m - x_ext, g.along_m + x_ext])
        x_t, y = f["x"][lo:hi], f["y"][lo:hi]
        z_sb = self.seabed_z(x_t, y)
        pos = np.stack([x_t - g.along_m, y, z_sb + f["depth"] + f["zeta"][lo:hi]], axis=1)
        if self.svp is not None:
            return self._field_echo_traced(g, f, lo, hi, x_t, pos, z_sb)
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

    def _field_echo_traced(self, g: PingGeometry, f: dict, lo: int, hi: int, x_t: np.ndarray, pos: np.ndarray,
                           z_sb: np.ndarray) -> _Echoes:
        """:meth:`_field_echo` through the sound-speed profile: the beam and
        the importance weight see the ray's launch direction, the grazing
        angle is the ray's at the scatterer (in the sediment below the
        seabed), the times are ray traced."""
        buried = f["depth"] > 0
        src = self._source_rays(g, pos, buried=buried, seabed_z=z_sb if buried else None)
        dist = np.linalg.norm(pos - g.source, axis=1)
        u = src["u"]
        weight = self.envelope(u)
        keep = (f["q"][lo:hi] < weight) & (np.abs(u) < self.u_cut) & (dist < self.max_range_m + 10)
        pos, weight, z_sb = pos[keep], weight[keep], z_sb[keep]
        src = {k: v[keep] for k, v in src.items()}
        g_amp = f["g"][lo:hi][keep]
        density = f["n"][lo:hi][keep] * weight
        sc: Scattering = f["scattering"]
        b_s = None
        trans = 1.0
        if buried:
            bur = self._buried_rays(g, pos, z_sb, src)
            sin_graz = np.sin(bur["grazing_sediment_rad"])
            trans, b_s = bur["transmission"], bur["b_s"]
        else:
            sin_graz = np.abs(src["arrival"] @ self._seabed_plane(g).n)
        if f["layer"] == 1 and self._provinces is not None:
            sigma = 10 ** (self.province_strength_db(x_t[keep], np.arcsin(np.clip(sin_graz, 0.0, 1.0))) / 10)
        else:
            sigma = 10 ** (sc.strength_db / 10) * sin_graz ** sc.grazing_exponent
        amp = g_amp * np.sqrt(sigma / density) * trans
        if b_s is not None:
            # before the element legs are traced: they are the cost
            cut = ~(b_s * self.fc * DB_PER_NEPER > self.scene.model.attenuation_cut_db)
            pos, amp, b_s, z_sb = pos[cut], amp[cut], b_s[cut], z_sb[cut]
            src = {k: v[cut] for k, v in src.items()}
        return self._traced_echoes(f"layer{f['layer']}", g, pos, amp, src, buried=buried,
                                   seabed_z=z_sb if buried else None, b_s=b_s)

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
        if e.times_s is None:
            t_centre = e.src_leg + np.sqrt(np.einsum("ij,ij->i", rel0, rel0)) + e.extra_s * self.c
            order = np.argsort(t_centre, kind="stable")
            t_sorted = t_centre[order] * (self.fs / self.c)
        else:
            t_traced = (e.times_s - self.t0) * self.fs           # record samples (S, C)
            t_mean = t_traced.mean(axis=1)
            order = np.argsort(t_mean, kind="stable")
            t_sorted = t_mean[order]
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
            if e.times_s is not None:
                t = t_traced[rows]
            else:
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
        ws = self.scene.sonar.tx_length_m * np.abs(e.u) / self.c * self.fs
        if e.times_s is None:
            rel = e.pos - g.centre
            t_c = ((e.src_leg + np.sqrt(np.einsum("ij,ij->i", rel, rel))) / self.c + e.extra_s - self.t0) * self.fs
            t_first = t_last = t_c
            spread = float(np.max(np.linalg.norm(g.elements - g.centre, axis=1))) / self.c * self.fs + 2
        else:
            t_ch = (e.times_s - self.t0) * self.fs
            t_c, t_first, t_last, spread = t_ch.mean(axis=1), t_ch.min(axis=1), t_ch.max(axis=1), 2.0
        lo = int(math.floor(np.min(t_first - ws / 2) - spread)) - self.tables[0] - 2
        hi = int(math.ceil(np.max(t_last + ws / 2) + spread)) + self.tables[0] + 2
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
        point of the target nearest the source (:meth:`image_position`; with
        a sound-speed profile, where an imager using that profile shows it,
        :meth:`_traced_truth`);
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
            if self.svp is not None:
                out["image_y"][k], out["image_z"][k], out["u"][k] = self._traced_truth(g, t, nearest)
            else:
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

    def _traced_truth(self, g: PingGeometry, t, nearest: np.ndarray) -> tuple[float, float, float]:
        """``(image_y, image_z, u)`` of a target's nearest point with a profile.

        Where a 2-D imager that traces rays through the same profile (and
        the same sediment below the seabed) shows the echo: the point of the
        plane ``x = 0`` at the echo's travel time from the source along the
        ray whose launch direction has the echo's direction cosine on the
        (rolled) receive-array axis (:meth:`image_position`'s range and cone
        angle, ray traced).  A scatterer in the plane is shown where it is.
        ``u`` is the launch direction's cosine on the transmit column.
        """
        buried = t.burial_m is not None
        zsb = np.array([nearest[2] - t.burial_m]) if buried else None
        src = self._source_rays(g, nearest[None, :], buried=buried, seabed_z=zsb)
        u = float(src["u"][0])
        if not math.isfinite(u):
            return math.nan, math.nan, math.nan
        phi = math.radians(g.roll_deg)
        axis = np.array([0.0, math.cos(phi), math.sin(phi)])
        down = np.array([0.0, -math.sin(phi), math.cos(phi)])
        kappa = float(np.clip(src["launch"][0] @ axis, -1.0, 1.0))
        d = kappa * axis + math.sqrt(1.0 - kappa * kappa) * down     # launch direction in the plane
        if not buried:
            medium = self.svp
        elif self.svp_sediment is not None:
            medium = self.svp_sediment
        else:
            medium = SoundSpeedProfile.with_sediment(
                self.svp, float(zsb[0]), self.scene.seabed.sound_speed_ratio
                * float(self.svp.speed(float(zsb[0]), side="above")))
        dy, z = _ray_point(medium, float(g.source[2]), float(d[1]), float(src["time_s"][0]))
        return float(g.source[1]) + dy, z, u

    # -- the dataset ---------------------------------------------------------------
    def navigation(self, g: PingGeometry) -> tuple[float, float]:
        """Latitude and longitude (degree) of ping ``g``: ``along_m`` from the
        line's start along its heading on the WGS84 ellipsoid."""
        sv = self.scene.survey
        lat, lon = geodesic_direct(sv.latitude_deg, sv.longitude_deg, sv.heading_deg, g.along_m)
        return float(lat), float(lon)

    def dataset(self, *, progress: bool = False) -> xr.Dataset:
        """Every prepared ping as a SPEC §7 dataset (with truth variables)."""
        from tqdm import tqdm

        n_p, n_c = len(self.indices), self.scene.sonar.n_elements
        samples = np.empty((n_p, n_c, self.n_samples), dtype=np.float32)
        motion, nav = np.zeros((n_p, 3)), np.zeros((n_p, 2))
        truth = []
        for j, i in enumerate(tqdm(self.indices, desc="simulate", unit="ping", disable=not progress, leave=False)):
            g = self.geometry(int(i))
            samples[j] = self.ping(int(i))
            motion[j] = (g.roll_deg, g.pitch_deg, g.heave_m)
            nav[j] = self.navigation(g)
            truth.append(self.truth(g))
        ds = xr.Dataset({name: ping_variable(name, v) for name, v in self._spec_values(motion, nav).items()},
                        coords={"ping": ("ping", self.indices, {"long_name": "ping index on the line"})},
                        attrs=self._attributes())
        ds["samples"] = ping_variable("samples", samples)
        ds["samples"].attrs.update(kind="raw", long_name="element pressure re source pressure at 1 m")
        if self.svp is not None:
            ds["sound_speed"].attrs["long_name"] = "sound speed at the transducers (z = 0 of svp_depth)"
        return ds.merge(self._truth_dataset(truth))

    def _spec_values(self, motion: np.ndarray, nav: np.ndarray) -> dict:
        """The SPEC §7 variables of the prepared pings (names of :data:`clbeam.io.schema.PING_VARIABLES`)."""
        sc, so, n_p = self.scene, self.scene.sonar, len(self.indices)
        start = np.datetime64(sc.survey.start_time, "ns")
        ev, sv = self.element_vessel, self.source_vessel
        values = {
            "sample_rate": self.fs, "t0": np.full(n_p, self.t0), "sound_speed": np.full(n_p, self.c),
            "element_x": ev[:, 0], "element_y": ev[:, 1], "element_z": ev[:, 2],
            "source_x": float(sv[0]), "source_y": float(sv[1]), "source_z": float(sv[2]),
            "roll": motion[:, 0], "pitch": motion[:, 1], "heave": motion[:, 2],
            "heading": np.full(n_p, sc.survey.heading_deg), "latitude": nav[:, 0], "longitude": nav[:, 1],
            "ping_time": start + (self.indices * sc.survey.ping_interval_s * 1e9).astype("timedelta64[ns]"),
            "pulse_f0": so.pulse_f0_hz, "pulse_f1": so.pulse_f1_hz, "pulse_duration": so.pulse_duration_s,
            "channel_valid": np.ones(so.n_elements, dtype=bool),
        }
        if self.svp is not None:
            values["svp_depth"], values["svp_speed"] = np.array(self.svp.depths_m), np.array(self.svp.speeds_m_s)
        return values

    def _attributes(self) -> dict:
        sc = self.scene
        return {
            FORMAT_ATTRIBUTE: PING_FORMAT,
            "title": f"clbeam simulation of scene '{sc.name}'",
            "source": f"clbeam {__version__} clbeam.sim",
            "scene": sc.name,
            "scene_json": json.dumps(sc.to_dict()),
            "seed": self.seed,
            "snr_db": "none" if sc.snr_db is None else float(sc.snr_db),
            "reference_amplitude": self.reference_amplitude(),
            "target_kinds": ",".join(_TARGET_KINDS_INV[type(t)] for t in sc.targets),
        }

    def _truth_dataset(self, truth: list) -> xr.Dataset:
        """The simulator's truth per ping (targets, seabed, province) in the earth frame."""
        sc = self.scene
        tt = {k: np.array([tr["target"][k] for tr in truth], dtype=np.float64).reshape(len(truth), len(sc.targets))
              for k in TRUTH_KEYS}
        data = {f"truth_target_{k}": (("ping", "target"), tt[k], {"units": units, "long_name": long_name})
                for k, (units, long_name) in TRUTH_VARIABLES.items()}
        data["truth_seabed_z"] = (("ping",), np.array([tr["seabed_z"] for tr in truth], dtype=np.float64),
                                  {"units": "m", "long_name": "seabed depth at nadir below the transducers' mean depth"})
        data["noise_std"] = ((), self.noise_std, {"units": "1", "long_name": "standard deviation of the added noise per sample"})
        if self._provinces is not None:
            mz = np.array([self.province_mz(float(i) * sc.survey.step_m) for i in self.indices])
            data["truth_province_mz"] = (("ping",), mz, {"units": "phi", "long_name":
                                                         "grain size of the seabed province under the ship"})
        coords = {"ping": ("ping", self.indices),
                  "target": ("target", np.array([t.name for t in sc.targets], dtype=object), {"long_name": "target name"})}
        return xr.Dataset(data, coords=coords)

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
    ``.zarr`` path (:func:`clbeam.io.pingwrite.write_ping_file`)."""
    from clbeam.io.pingwrite import write_ping_file

    return write_ping_file(ds, path)
