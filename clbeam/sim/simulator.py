"""Element-level synthesis of multibeam sub-bottom profiler pings (docs/simulator.md, docs/ping-format.md).

The simulator builds what an SBP29-class sonar records on its 64 receive
elements for a scene: buried pipelines (line scatterers), point scatterers,
a rough seabed and a rough sub-bottom interface (random scatterers whose
strength falls with grazing angle as ``sin^m``, or follows the AVO
backscatter model of a grain size per province), the nadir specular echoes of
both interfaces, the first surface multiple and its doublet, and noise, with
the ship moving along a track and rolling, pitching and heaving.

Model (vessel frame ``x`` forward, ``y`` starboard, ``z`` down; docs/ping-format.md)
-----------------------------------------------------------------------
A point scatterer of amplitude ``a`` (m) at ``r`` produces on element ``n``

    p_n(t) = a / (|r - s| |r - e_n|) · b(t) ⊛ x(t - τ_n),
    τ_n = (|r - s| + |r - e_n|) / c,

with ``s`` the source and ``e_n`` the element in the earth frame (after roll
and heave, :func:`clbeam.imaging.geometry.to_earth_frame`), ``x`` the LFM replica
(:func:`clbeam.model.pulse.lfm_replica`) and ``b`` the along-track transmit beam:
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
(:mod:`clbeam.sim.rays` on :func:`clbeam.imaging.raytrace.eigenrays`):
``τ_n`` is the eigenray time from the source to the scatterer plus the one
from the scatterer to element ``n``, through the water profile, or for buried scatterers through it and the sediment below
the seabed; the image-source echoes are unfolded through the layers they
cross.  The spreading stays ``1 / (|r - s| |r - e_n|)`` on the straight
distances.

Layout
------
This module holds the :class:`Simulator` core (construction, ping geometry,
the echo sets of a ping, rendering, noise, navigation, the dataset) and
:func:`simulate` / :func:`write`; it re-exports the public names of the
modules the simulator is split into, by what each synthesises:

- :mod:`clbeam.sim.scene`: the frozen scene dataclasses;
- :mod:`clbeam.sim.catalog`: TOML scenes (:func:`load_scene`, :func:`list_scenes`);
- :mod:`clbeam.sim.physics`: closed forms (far field, beamwidth, Snell, reflection);
- :mod:`clbeam.sim.geometry`: per-ping positions, the seabed, reflecting planes;
- :mod:`clbeam.sim.rays`: eigenray legs and unfolded paths through a profile;
- :mod:`clbeam.sim.propagation`: the beam's reach and the paths of one scene;
- :mod:`clbeam.sim.targets`: point and line (pipeline) echoes;
- :mod:`clbeam.sim.seabed`: random interface scatterers and seabed provinces;
- :mod:`clbeam.sim.specular`: image-source echoes and multiples;
- :mod:`clbeam.sim.discrete`: the discrete-scatterer physics (``model.physics = "discrete"``);
- :mod:`clbeam.sim.truth`: target positions and where an imager shows them;
- :mod:`clbeam.sim.render`: echo sets into samples.

The parts are composed, not mixed into one class: the simulator owns a
:class:`~clbeam.sim.propagation.Propagation` (what every synthesiser needs
to know about the scene's medium and beam, computed once) and a
:class:`~clbeam.sim.render.Renderer`, and the synthesisers are plain
functions of the propagation and the ping, so each reads what it uses from
one place and can be tested on its own.

See ``docs/simulator.md`` for every parameter, the choices behind the
built-in scenes and what is left out.
"""

from __future__ import annotations

import json
import logging
import math
import os
from pathlib import Path

import numpy as np
import xarray as xr

from clbeam import __version__
from clbeam.errors import OptionError, require
from clbeam.io.pingwrite import write_ping_file
from clbeam.io.schema import FORMAT_ATTRIBUTE, PING_FORMAT, ping_variable
from clbeam.model.geodesy import geodesic_direct
from clbeam.sim.catalog import list_scenes, load_scene, scene_from_mapping
from clbeam.sim.discrete import DiscreteModel, pipe_power_per_m
from clbeam.sim.geometry import PingGeometry, ping_geometry, seabed_z
from clbeam.sim.physics import (
    DB_PER_NEPER,
    attenuation_np_per_m_hz,
    ka_sin_phi,
    nadir_angle_deg,
    reflection_coefficient,
    refracted_path,
    transmit_beamwidth_deg,
    transmit_far_field_m,
    two_way_sediment_path_m,
)
from clbeam.sim.propagation import Propagation
from clbeam.sim.render import Echoes, Renderer
from clbeam.sim.scene import (
    SPECULAR_MODELS,
    Discrete,
    LineTarget,
    Model,
    Motion,
    PointTarget,
    Province,
    Record,
    Scattering,
    Scene,
    Seabed,
    Sonar,
    SubBottom,
    Survey,
    Water,
    target_kind,
)
from clbeam.sim.seabed import Provinces, field_echo, scatterer_fields
from clbeam.sim.specular import forward_seabed, forward_specular_response, nadir_reflection, specular_echoes
from clbeam.sim.targets import line_crossing, line_echo, line_points, point_echo, target_world
from clbeam.sim.truth import TRUTH_KEYS, TRUTH_VARIABLES, image_position, ping_truth, truth_dataset

__all__ = [
    "DB_PER_NEPER", "SPECULAR_MODELS", "TRUTH_KEYS", "TRUTH_VARIABLES",
    "Discrete", "LineTarget", "Model", "Motion", "PingGeometry", "PointTarget", "Province", "Record", "Scattering", "Scene",
    "Seabed", "Simulator", "Sonar", "SubBottom", "Survey", "Water",
    "attenuation_np_per_m_hz", "ka_sin_phi", "list_scenes", "load_scene", "nadir_angle_deg",
    "reflection_coefficient", "refracted_path", "scene_from_mapping", "simulate", "transmit_beamwidth_deg",
    "transmit_far_field_m", "two_way_sediment_path_m", "write",
]

log = logging.getLogger(__name__)


def unused_under_discrete(scene: Scene) -> list[str]:
    """The keys of ``scene`` set away from their defaults that the discrete-scatterer physics does not use
    (docs/simulator.md): a pipe's ``roughness`` (every discrete pipe scatters along its length), an
    interface's ``scattering.per_cell`` and ``depth_spread_m`` (its scatterers' density and spread are the
    ``[discrete]`` table's) and ``model.line_spacing_m``."""
    out = [f"target '{t.name}' roughness" for t in scene.targets if isinstance(t, LineTarget) and t.roughness > 0]
    default = Scattering()
    for name, layer in (("seabed", scene.seabed), ("subbottom", scene.subbottom)):
        sc = None if layer is None else layer.scattering
        for key in ("per_cell", "depth_spread_m"):
            if sc is not None and getattr(sc, key) != getattr(default, key):
                out.append(f"{name}.scattering.{key}")
    if scene.model.line_spacing_m is not None:
        out.append("model.line_spacing_m")
    return out


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

    Attributes
    ----------
    scene : Scene
        The scene.
    indices : numpy.ndarray
        The prepared ping indices.
    max_range_m : float
        Largest fully recorded one-way slant range (m).
    n_samples : int
        Samples per channel; sample ``k`` is at ``t0 + k / fs`` (s).
    replica : numpy.ndarray
        The transmit replica (unit amplitude).
    noise_std : float
        Standard deviation of the added noise per raw sample.
    propagation : Propagation
        The scene's beam reach and sound paths.
    renderer : Renderer
        Turns echo sets into samples.
    """

    def __init__(self, scene, *, seed: int = 0, pings=None):
        self.scene = scene if isinstance(scene, Scene) else load_scene(scene)
        require(int(seed) == seed and seed >= 0, OptionError, f"seed must be a non-negative integer, got {seed!r}")
        self.seed = int(seed)
        self.indices = self._indices(pings)
        sc, so = self.scene, self.scene.sonar
        self.fs = so.sample_rate_hz
        self.fc = so.centre_frequency_hz
        self.element_vessel = so.element_positions_m()
        self.source_vessel = np.asarray(so.source_offset_m, dtype=np.float64)
        self.max_range_m = sc.record.max_range_m or self._auto_max_range()
        self.propagation = Propagation(sc, max_range_m=self.max_range_m)
        self.t0 = sc.record.start_s
        t_end = 2 * self.max_range_m / self.propagation.c_min + so.pulse_duration_s
        require(t_end > self.t0, OptionError,
                f"record.start_s {self.t0:g} s is after the record end {t_end:g} s (max_range_m {self.max_range_m:g} m)")
        self.n_samples = int(math.ceil((t_end - self.t0) * self.fs))
        self.renderer = Renderer(so, sound_speed_m_s=self.c, t0_s=self.t0, n_samples=self.n_samples)
        self.replica = self.renderer.replica
        along = self.indices * sc.survey.step_m
        x_ext = self.propagation.x_ext_m
        self._x_window = (float(along.min()) - x_ext, float(along.max()) + x_ext)
        self.provinces = None
        if sc.seabed is not None and sc.seabed.province:
            self.provinces = Provinces(sc.seabed.province, frequency_hz=self.fc,
                                       sound_speed_water_m_s=self.propagation.c_seabed)
        self._discrete = None
        if sc.model.physics == "discrete":
            self._discrete = DiscreteModel(self.propagation, seed=self.seed, x_window=self._x_window)
            unused = unused_under_discrete(sc)
            if unused:
                log.warning("scene '%s': model.physics = \"discrete\" does not use %s (docs/simulator.md)",
                            sc.name, ", ".join(unused))
        self._fields = [] if self._discrete else scatterer_fields(self.propagation, seed=self.seed,
                                                                  x_window=self._x_window)
        track_m = (max(sc.survey.pings, int(self.indices.max()) + 1) - 1) * sc.survey.step_m
        self._lines = [line_points(self.propagation, t, x_window=self._x_window, track_m=track_m)
                       if isinstance(t, LineTarget) else None for t in sc.targets]
        self.noise_std = self._noise_std()

    # -- the medium, from the propagation --------------------------------------
    @property
    def c(self) -> float:
        """Sound speed at the transducers (m/s)."""
        return self.propagation.c

    @property
    def svp(self):
        """The ``[water]`` sound-speed profile, ``None`` for isospeed water."""
        return self.propagation.svp

    @property
    def svp_sediment(self):
        """The profile with the sediment below a flat seabed (``None`` without
        a profile, a seabed, or with a sloped seabed)."""
        return self.propagation.svp_sediment

    @property
    def alpha_np(self) -> float:
        """Sediment attenuation slope ``α / f`` (Np m⁻¹ Hz⁻¹)."""
        return self.propagation.alpha_np

    # -- set-up ----------------------------------------------------------------
    def _indices(self, pings) -> np.ndarray:
        """The ping indices to prepare: all, the first ``n``, or those given."""
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

    def _auto_max_range(self) -> float:
        """The farthest target's slant range over the pings plus 50 m, at
        least the first multiple when there is a seabed (m)."""
        sc = self.scene
        ranges = [0.0]
        along = self.indices * sc.survey.step_m
        for t in sc.targets:
            if isinstance(t, PointTarget):
                x, y, z = target_world(sc, t)
                ranges.append(float(np.max(np.sqrt((x - along) ** 2 + y ** 2 + z ** 2))))
            else:
                for a in along:
                    y, z, _ = line_crossing(sc, t, a)
                    if np.isfinite(y):
                        ranges.append(math.hypot(y, z))
        r = max(ranges) + 50.0
        if sc.seabed is not None:
            r = max(r, 2 * (sc.seabed.depth_m - sc.sonar.draft_m) + 2 * sc.sonar.draft_m + 50.0)
        return r

    def _noise_std(self) -> float:
        """Noise standard deviation per sample from ``snr_db`` (0: no noise)."""
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
        a line (discrete physics: the RMS echo ``sqrt(σ_L sqrt(λ_c R / 2)) / R²``
        of the scatterers on that length, ``σ_L`` the pipe's mean cross-section
        per metre).  1 when there is neither.
        """
        sc = self.scene
        if sc.seabed is not None:
            v = abs(float(reflection_coefficient(np.pi / 2, sc.seabed.density_ratio, sc.seabed.sound_speed_ratio)))
            return v / (2 * (sc.seabed.depth_m - sc.sonar.draft_m))
        if sc.targets:
            t = sc.targets[0]
            if isinstance(t, PointTarget):
                x, y, z = target_world(sc, t)
                return t.amplitude_m / (x * x + y * y + z * z)
            y, z, _ = line_crossing(sc, t, 0.0)
            r = math.hypot(y, z)
            if self._discrete is not None:  # the RMS echo of the incoherent pipe's Fresnel length
                return math.sqrt(pipe_power_per_m(sc.discrete, t) * math.sqrt(self.c / self.fc * r / 2)) / r ** 2
            return t.reflectivity * float(t.response(self.fc, self.c)) * math.sqrt(self.c / self.fc * r / 2) / r ** 2
        return 1.0

    # -- the scene's geometry ------------------------------------------------------
    def seabed_z(self, x_track_m, y_m) -> np.ndarray:
        """Seabed depth below the transducers' mean depth at track-frame ``(x, y)`` (m)."""
        return seabed_z(self.scene, x_track_m, y_m)

    def envelope(self, u: np.ndarray) -> np.ndarray:
        """Importance weight of a random scatterer at direction cosine ``u``."""
        return self.propagation.envelope(u)

    def taper(self, u: np.ndarray) -> np.ndarray:
        """Cull window on ``|u|``: 1 up to ``0.75 u_cut``, cosine to 0 at ``u_cut``."""
        return self.propagation.taper(u)

    def province_mz(self, along_m: float) -> float:
        """Grain size (phi) of the seabed province at ``along_m`` along the
        track (m); NaN when the scene has no provinces."""
        return math.nan if self.provinces is None else self.provinces.mz_at(along_m)

    def province_strength_db(self, x_track_m, grazing_rad) -> np.ndarray:
        """AVO backscattering strength (dB) of the seabed at along-track
        positions ``x_track_m`` (m) and grazing angles ``grazing_rad``, from
        the province there, at the band centre frequency."""
        return self.provinces.strength_db(x_track_m, grazing_rad)

    def forward_seabed(self, water_m: float = 1.0):
        """The scene's seabed as a :class:`clbeam.seabed.forward.Seabed`
        (:func:`clbeam.sim.specular.forward_seabed`; ``water_m`` of water on top, m)."""
        return forward_seabed(self.scene, self.propagation.c_seabed, water_m)

    def forward_specular_response(self, f_hz) -> np.ndarray:
        """``(n_echo, n_freq)`` complex nadir echo factors of the forward model
        at ``f_hz`` (Hz): the seabed (row 0) and the sub-bottom (row 1)
        (:func:`clbeam.sim.specular.forward_specular_response`)."""
        return forward_specular_response(self.scene, self.propagation.c_seabed, f_hz)

    # -- one ping ------------------------------------------------------------------
    def geometry(self, index: int) -> PingGeometry:
        """Positions and motion of ping ``index`` (:func:`clbeam.sim.geometry.ping_geometry`)."""
        return ping_geometry(self.scene, index)

    def echoes(self, g: PingGeometry) -> list[Echoes]:
        """Every echo set of ping ``g``: targets, specular paths, random fields."""
        prop = self.propagation
        sets = []
        if self._discrete is not None:   # targets and interfaces as discrete scatterers
            sets.extend(self._discrete.echoes(g))
        for t, pts in zip(self.scene.targets if self._discrete is None else (), self._lines):
            e = point_echo(prop, g, t) if pts is None else line_echo(prop, g, t, pts)
            if e is not None and len(e):
                sets.append(e)
        if self.scene.seabed is not None:
            sets.extend(e for e in specular_echoes(prop, g) if len(e))
        for f in self._fields:
            e = field_echo(prop, g, f, self.provinces)
            if len(e):
                sets.append(e)
        return sets

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

    def render(self, g: PingGeometry, sets: list[Echoes]) -> np.ndarray:
        """Noise-free samples ``(channel, sample)`` float64 of the echo sets
        (:meth:`clbeam.sim.render.Renderer.render`)."""
        return self.renderer.render(g, sets)

    def truth(self, g: PingGeometry) -> dict:
        """Target positions in the earth frame of ping ``g``, where an imager
        shows them, and the seabed depth (:func:`clbeam.sim.truth.ping_truth`)."""
        return ping_truth(self.propagation, g, self._lines)

    image_position = staticmethod(image_position)

    def navigation(self, g: PingGeometry) -> tuple[float, float]:
        """Latitude and longitude (degree) of ping ``g``: ``along_m`` from the
        line's start along its heading on the WGS84 ellipsoid."""
        sv = self.scene.survey
        lat, lon = geodesic_direct(sv.latitude_deg, sv.longitude_deg, sv.heading_deg, g.along_m)
        return float(lat), float(lon)

    # -- the dataset -----------------------------------------------------------------
    def dataset(self, *, progress: bool = False) -> xr.Dataset:
        """Every prepared ping as a ping dataset (docs/ping-format.md) (with truth variables).

        Parameters
        ----------
        progress : bool
            Show a progress bar.

        Returns
        -------
        xarray.Dataset
            The variables of :data:`clbeam.io.schema.PING_VARIABLES` with their
            units (:func:`clbeam.io.schema.ping_variable`), the raw samples and
            the truth (:func:`clbeam.sim.truth.truth_dataset`).
        """
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
        """The ping-file variables of the prepared pings (names of :data:`clbeam.io.schema.PING_VARIABLES`)."""
        sc, so, n_p = self.scene, self.scene.sonar, len(self.indices)
        start = np.datetime64(sc.survey.start_time, "ns")
        ev, sv = self.element_vessel, self.source_vessel
        values = {
            "sample_rate": self.fs, "t0": np.full(n_p, self.t0), "sound_speed": np.full(n_p, self.c),
            "element_x": ev[:, 0], "element_y": ev[:, 1], "element_z": ev[:, 2],
            "source_x": float(sv[0]), "source_y": float(sv[1]), "source_z": float(sv[2]),
            "roll": motion[:, 0], "pitch": motion[:, 1], "heave": motion[:, 2],
            "heading": np.full(n_p, sc.survey.heading_deg), "latitude": nav[:, 0], "longitude": nav[:, 1],
            "draft": np.full(n_p, float(so.draft_m)),
            "ping_time": start + (self.indices * sc.survey.ping_interval_s * 1e9).astype("timedelta64[ns]"),
            "pulse_f0": so.pulse_f0_hz, "pulse_f1": so.pulse_f1_hz, "pulse_duration": so.pulse_duration_s,
            "channel_valid": np.ones(so.n_elements, dtype=bool),
        }
        if self.svp is not None:
            values["svp_depth"], values["svp_speed"] = np.array(self.svp.depths_m), np.array(self.svp.speeds_m_s)
        return values

    def _attributes(self) -> dict:
        """Global attributes: the format, the scene (as JSON), seed and noise level."""
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
            "target_kinds": ",".join(target_kind(t) for t in sc.targets),
        }

    def _truth_dataset(self, truth: list) -> xr.Dataset:
        """The simulator's truth per ping (targets, seabed, province) in the earth frame."""
        sc = self.scene
        mz = r = None
        if self.provinces is not None:
            along = [float(i) * sc.survey.step_m for i in self.indices]
            mz = np.array([self.province_mz(a) for a in along])
            r = np.array([nadir_reflection(sc, a) for a in along])
        return truth_dataset(truth, target_names=[t.name for t in sc.targets], pings=self.indices,
                             noise_std=self.noise_std, province_mz=mz, nadir_reflection=r)


def simulate(scene, *, pings=None, seed: int = 0, progress: bool = False) -> xr.Dataset:
    """Simulate the pings of a scene as a ping dataset (docs/ping-format.md).

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
    return write_ping_file(ds, path)
