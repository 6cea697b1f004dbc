"""How far a buried pipe can be seen: a detection-performance model (docs/detectability.md).

For a pipe of given radius, burial, reflectivity and roughness at a horizontal range and heading from
the track, in a scene's water, seabed, sub-bottom, sonar and noise, the model predicts the echo, the
reverberation and the noise each channel holds at the pipe's delay, and from them the probability that
the default detection test (or the thresholds a user sets) reports the pipe.  It follows the
simulator's physics (:mod:`clbeam.sim.physics`, docs/simulator.md) term by term, analytically:

- **echo**: spherical spreading on the straight distances, the transmit column's boxcar beam
  ``sinc(L f u / c)`` at the pipe's specular point, water absorption (Francois-Garrison, optional: the
  simulator has none), the two-way transmission ``1 − V²`` into the sediment, its attenuation over the
  Snell path, and the pipe's stationary-phase line echo ``ρ H(f) sqrt(λ R / 2) / R²`` with
  ``H(f) = sqrt(a f / 2c) G(ka)``: at every frequency of the band.  Where the specular point lies
  outside the beam (a pipe crossing obliquely) the echo is the integral along the pipe, numerically;
  a rough pipe adds its incoherent scattering over the stretch in the resolution cell;
- **reverberation**: the seabed's ``μ sin^m θ`` over the ring at the echo's delay inside the beam,
  ``σ c / (2 R² y(u))`` per unit delay and beam cosine, and the sub-bottom's through the sediment at
  that delay, each with its arrival direction relative to the pipe's;
- **noise**: the scene's ``snr_db`` re the nadir seabed echo, compressed by the replica.

:mod:`clbeam.evaluation.detectability_stats` turns them into the probability of detection.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.evaluation.detectability_beams import BEAMS_PER_SIDE, side_beams
from clbeam.evaluation.detectability_stats import (
    DEFAULT_DRAWS,
    GRID_OFFSETS,
    ChannelModel,
    Tests,
    monte_carlo_batch,
    phase_step_for_coherence,
)
from clbeam.imaging.detection import CONTRAST_GUARD, CONTRAST_WINDOW
from clbeam.sim.physics import attenuation_np_per_m_hz, reflection_coefficient, refracted_path
from clbeam.sim.scene import LineTarget, Scene

#: coarse frequency bins of the band (Hz): the echo and the covariances need lags of a few metres only
BIN_HZ = 50.0


@dataclass(frozen=True)
class Pipe:
    """A pipe as the model sees it.

    Attributes
    ----------
    name : str
        Label.
    radius_m : float
        Radius ``a`` (m).
    burial_m : float
        Depth of its axis below the seabed (m).
    reflectivity : float
        Echo scale (the simulator's ``reflectivity``).
    roughness : float
        Relative standard deviation of the echo from point to point (the simulator's ``roughness``).
    heading_deg : float
        Angle between the pipe and the track (degree; 0: parallel, broadside to every ping).
    """

    name: str = "pipe"
    radius_m: float = 0.11
    burial_m: float = 1.0
    reflectivity: float = 0.8
    roughness: float = 0.0
    heading_deg: float = 0.0

    def __post_init__(self):
        require(math.isfinite(self.radius_m) and self.radius_m > 0, OptionError,
                f"pipe '{self.name}': radius must be > 0 m, got {self.radius_m}")
        require(math.isfinite(self.burial_m) and self.burial_m >= 0, OptionError,
                f"pipe '{self.name}': burial must be >= 0 m, got {self.burial_m}")
        require(self.reflectivity > 0, OptionError, f"pipe '{self.name}': reflectivity must be > 0, got {self.reflectivity}")
        require(self.roughness >= 0, OptionError, f"pipe '{self.name}': roughness must be >= 0, got {self.roughness}")
        require(abs(self.heading_deg) < 60, OptionError,
                f"pipe '{self.name}': heading to the track must be within ±60 degrees, got {self.heading_deg}")


@dataclass(frozen=True)
class Environment:
    """The water, seabed, sonar and noise of a scene, as the model uses them.

    Attributes
    ----------
    scene : Scene
        The scene (sonar, seabed, sub-bottom, ``snr_db``).
    absorption_db_per_km : float or None
        Water absorption at the band centre's scale (dB/km, one way); ``None``: Francois-Garrison at
        every frequency (``temperature_c``, ``salinity_psu``, at half the water depth); 0: none (the
        simulator).
    temperature_c, salinity_psu : float
        For Francois-Garrison.
    noise_offset_db : float
        Noise level added to the scene's (dB; positive: noisier).
    tests : Tests
        The detection test.
    """

    scene: Scene
    absorption_db_per_km: float | None = 0.0
    temperature_c: float = 10.0
    salinity_psu: float = 34.0
    noise_offset_db: float = 0.0
    tests: Tests = field(default_factory=Tests)

    def __post_init__(self):
        sc = self.scene
        require(sc.seabed is not None, OptionError, f"scene '{sc.name}' has no seabed: the model needs one")
        require(sc.snr_db is not None, OptionError, f"scene '{sc.name}' has no noise (snr_db): the model needs a noise level")
        require(sc.seabed.slope_along_deg == 0 and sc.seabed.slope_across_deg == 0, OptionError,
                f"scene '{sc.name}': the model needs a flat seabed")

    @property
    def height_m(self) -> float:
        """Height of the transducers above the seabed (m)."""
        return self.scene.seabed.depth_m - self.scene.sonar.draft_m

    @property
    def c(self) -> float:
        """Sound speed at the transducers (m/s)."""
        return float(self.scene.sound_speed_m_s)


def pipes_of_scene(scene: Scene) -> list[tuple[Pipe, float]]:
    """The scene's pipelines as :class:`Pipe` with their mean horizontal range over the pings (m).

    Raises
    ------
    OptionError
        The scene has no pipeline, or one that is not buried.
    """
    from clbeam.sim.targets import line_crossing

    lines = [t for t in scene.targets if isinstance(t, LineTarget)]
    require(bool(lines), OptionError, f"scene '{scene.name}' has no pipelines ([[target]] kind = \"line\")")
    out = []
    along = np.arange(scene.survey.pings) * scene.survey.step_m
    for t in lines:
        require(t.burial_m is not None, OptionError, f"target '{t.name}': the model needs a buried pipe (burial_m)")
        cross = np.array([line_crossing(scene, t, a) for a in along])
        ok = np.isfinite(cross[:, 0])
        require(bool(ok.any()), OptionError, f"target '{t.name}' never crosses the pings' plane")
        out.append((Pipe(t.name, t.radius_m, t.burial_m, t.reflectivity, t.roughness,
                         float(np.mean(cross[ok, 2]))), float(np.mean(np.abs(cross[ok, 0])))))
    return out


# -- the band -------------------------------------------------------------------------
def band(env: Environment) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (Hz) of the band in :data:`BIN_HZ` bins and the replica's power spectrum over them
    (summing to 1)."""
    so = env.scene.sonar
    x = so.replica()
    nfft = 1 << int(math.ceil(math.log2(4 * x.size)))
    f = np.fft.rfftfreq(nfft, 1.0 / so.sample_rate_hz)
    p = np.abs(np.fft.rfft(x, nfft)) ** 2
    edges = np.arange(0.0, so.sample_rate_hz / 2, BIN_HZ)
    idx = np.digitize(f, edges) - 1
    power = np.bincount(idx, weights=p, minlength=edges.size)[:edges.size]
    centre = edges + BIN_HZ / 2
    keep = power > 1e-4 * power.max()
    return centre[keep], power[keep] / power[keep].sum()


def noise_power(env: Environment) -> float:
    """Compressed noise power per channel, ``2 σ² / E`` (``σ`` from ``snr_db`` re the nadir seabed echo
    ``V / 2h``, ``E`` the replica's energy)."""
    sb, so = env.scene.seabed, env.scene.sonar
    v = abs(float(reflection_coefficient(math.pi / 2, sb.density_ratio, sb.sound_speed_ratio)))
    sigma = v / (2 * env.height_m) * 10 ** (-(env.scene.snr_db - env.noise_offset_db) / 20)
    energy = float(np.sum(so.replica().astype(np.float64) ** 2))
    return 2 * sigma * sigma / energy


def absorption_db_per_m(env: Environment, f_hz: np.ndarray) -> np.ndarray:
    """One-way water absorption at ``f_hz`` (dB/m)."""
    if env.absorption_db_per_km is not None:
        return np.full(np.shape(f_hz), env.absorption_db_per_km / 1000.0)
    from clbeam.seabed.avo import francois_garrison_db_per_km

    return francois_garrison_db_per_km(f_hz, temperature_c=env.temperature_c, salinity_psu=env.salinity_psu,
                                       depth_m=0.5 * env.scene.seabed.depth_m) / 1000.0


def beam(env: Environment, u, f_hz) -> np.ndarray:
    """The transmit column's pattern ``sinc(L f u / c)`` times the simulator's taper (1 to ``0.75 u_cut``,
    cosine to 0 at ``u_cut = λ(f0) / L``) at direction cosines ``u`` and frequencies ``f_hz``."""
    so = env.scene.sonar
    return np.sinc(so.tx_length_m * np.asarray(f_hz) * np.asarray(u) / env.c) * 0.5 * (1 + np.cos(np.pi * _taper_x(env, u)))


def _taper_x(env: Environment, u) -> np.ndarray:
    """Where ``|u|`` lies on the taper's half cosine: 0 to ``0.75 u_cut``, then linearly to 1 at ``u_cut``."""
    so = env.scene.sonar
    u_cut = min(env.scene.model.tx_beam_cut * env.c / so.pulse_f0_hz / so.tx_length_m, 0.5)
    return np.clip((np.abs(np.asarray(u, dtype=np.float64)) - 0.75 * u_cut) / (0.25 * u_cut), 0.0, 1.0)


# -- the echo ---------------------------------------------------------------------------
def pipe_geometry(env: Environment, pipe: Pipe, range_m: float) -> dict:
    """Where the pipe's specular point is and the paths to it.

    Returns
    -------
    dict
        ``horizontal_m`` (to the specular point), ``along_m`` (its along-track offset), ``slant_m``
        (straight), ``u`` (its direction cosine on the transmit column), ``delay_range_m`` (the echo's
        delay times ``c / 2``), ``sediment_m`` (two-way in-sediment path), ``transmission`` (two-way
        ``1 − V²``), ``grazing_deg`` (in the water), ``sin_arrival`` (sine of the ray's angle from the
        vertical at the array: its direction across the array).
    """
    sb = env.scene.seabed
    d = math.radians(pipe.heading_deg)
    rho = abs(range_m) * math.cos(d)
    x_sp = abs(range_m) * math.sin(d) * math.cos(d)
    h = env.height_m
    path = refracted_path(math.hypot(rho, x_sp), h, pipe.burial_m, sb.sound_speed_ratio)
    slant = math.sqrt(rho ** 2 + x_sp ** 2 + (h + pipe.burial_m) ** 2)
    graz = float(path["grazing_water_rad"])
    v = float(reflection_coefficient(graz, sb.density_ratio, sb.sound_speed_ratio))
    return {"horizontal_m": rho, "along_m": x_sp, "slant_m": slant, "u": x_sp / slant,
            "delay_range_m": float(path["time_factor_m"]), "sediment_m": 2 * float(path["sediment_m"]),
            "transmission": 1 - v * v, "grazing_deg": math.degrees(graz), "sin_arrival": math.cos(graz)}


def line_response(pipe: Pipe, f_hz, sound_speed_m_s: float) -> np.ndarray:
    """``H(f) = sqrt(a f / 2c) G(ka)``, ``G(x) = x^1.5 / sqrt(1 + x³)``: the echo per unit length and unit
    reflectivity of the simulator's pipe (:meth:`clbeam.sim.scene.LineTarget.response`)."""
    return LineTarget(radius_m=pipe.radius_m, burial_m=max(pipe.burial_m, 1e-9)).response(f_hz, sound_speed_m_s)


def echo_spectrum(env: Environment, pipe: Pipe, range_m: float, f_hz: np.ndarray, *,
                  method: str = "auto") -> np.ndarray:
    """The pipe's echo per channel (re the replica at 1 m) at ``f_hz``, its delay removed.

    ``"stationary"``: ``ρ T H(f) sqrt(λ R / 2) / R² · b(u, f) · e^(−α f ℓ) · 10^(−a_w 2R / 20) e^(−iπ/4)``
    at the specular point; ``"integral"``: the sum along the pipe (every 1/8 of the shortest
    wavelength's Fresnel phase step) of the same point echoes, each at its own beam cosine and
    delay; ``"auto"``: the integral where the specular point lies past the beam's first null at the
    band's top, where the stationary point no longer dominates.

    Parameters
    ----------
    env : Environment
    pipe : Pipe
    range_m : float
        Horizontal range of the pipe from the track where it crosses the ping's plane (m).
    f_hz : numpy.ndarray
        Frequencies (Hz).
    method : {"auto", "stationary", "integral"}

    Returns
    -------
    numpy.ndarray
        Complex amplitude spectrum (dimensionless re the replica at 1 m, i.e. m⁻¹ of range squared).
    """
    require(method in ("auto", "stationary", "integral"), OptionError, f"unknown echo method {method!r}")
    geo = pipe_geometry(env, pipe, range_m)
    f = np.asarray(f_hz, dtype=np.float64)
    c_sed = env.c * env.scene.seabed.sound_speed_ratio
    common = (pipe.reflectivity * geo["transmission"] * line_response(pipe, f, c_sed)
              * np.exp(-attenuation_np_per_m_hz(env.scene.seabed) * f * geo["sediment_m"]))
    so = env.scene.sonar
    if method == "auto":
        method = "integral" if abs(geo["u"]) > env.c / (so.pulse_f1_hz * so.tx_length_m) else "stationary"
    r = geo["slant_m"]
    if method == "stationary":
        spread = np.sqrt(env.c / f * r / 2) / r ** 2
        loss = 10 ** (-absorption_db_per_m(env, f) * 2 * r / 20)
        return common * spread * loss * beam(env, geo["u"], f) * np.exp(-0.25j * np.pi)
    sc, so = env.scene, env.scene.sonar
    key = (env.c, env.height_m, pipe.burial_m, pipe.heading_deg, float(range_m), sc.seabed.sound_speed_ratio,
           so.tx_length_m, so.pulse_f0_hz, so.pulse_f1_hz, sc.model.tx_beam_cut, env.absorption_db_per_km,
           env.temperature_c, env.salinity_psu, sc.seabed.depth_m, f.tobytes())
    if key not in _ALONG_CACHE:
        if len(_ALONG_CACHE) > 4096:
            _ALONG_CACHE.clear()
        _ALONG_CACHE[key] = _along_pipe_fast(env, pipe, range_m, f, geo)
    return common * _ALONG_CACHE[key]


#: the integrals along pipes already computed (the uncertain attenuation, noise and scattering leave them
#: as they are)
_ALONG_CACHE: dict = {}


def _pipe_points(env: Environment, pipe: Pipe, range_m: float, geo: dict) -> tuple:
    """The simulator's points along a straight pipe inside the beam's cut: every quarter of the shortest
    wavelength over the largest direction cosine of a ray on the pipe.

    Returns
    -------
    tuple
        ``u`` (direction cosines on the transmit column), ``slant`` (m), ``tau`` (delays re the specular
        point's, s) and the spacing ``step`` (m).
    """
    so = env.scene.sonar
    d = math.radians(pipe.heading_deg)
    h, b = env.height_m, pipe.burial_m
    u_cut = min(env.scene.model.tx_beam_cut * env.c / so.pulse_f0_hz / so.tx_length_m, 0.5)
    reach = (math.hypot(abs(range_m), h + b) + abs(range_m) * abs(math.sin(d))) * u_cut / math.sqrt(1 - u_cut ** 2)
    step = env.c / (1.05 * so.pulse_f1_hz) / 4 / min(1.0, u_cut + abs(math.sin(d)))
    s = np.arange(-reach / math.cos(d), reach / math.cos(d) + step, step)
    x, y = s * math.cos(d), abs(range_m) + s * math.sin(d)
    rho = np.hypot(x, y)
    path = refracted_path(rho, h, b, env.scene.seabed.sound_speed_ratio)
    slant = np.sqrt(rho ** 2 + (h + b) ** 2)
    u = x / slant
    inside = np.abs(u) < u_cut
    u, slant, tf = u[inside], slant[inside], path["time_factor_m"][inside]
    return u, slant, 2 * (tf - geo["delay_range_m"]) / env.c, step


def _along_pipe(env: Environment, pipe: Pipe, range_m: float, f: np.ndarray, geo: dict) -> np.ndarray:
    """``Σ Δs b(u_s, f) e^(−2πi f (τ_s − τ_0)) 10^(−a_w 2R_s/20) / R_s²`` along a straight pipe inside the
    beam's cut (delay of the specular point removed) at the points of :func:`_pipe_points`, term by term:
    the reference of :func:`_along_pipe_fast`."""
    u, slant, tau, step = _pipe_points(env, pipe, range_m, geo)
    loss = 10 ** (-absorption_db_per_m(env, f)[:, None] * 2 * slant[None, :] / 20)
    phase = np.exp(-2j * np.pi * f[:, None] * tau[None, :])
    return np.einsum("fs,fs->f", beam(env, u[None, :], f[:, None]) * loss / slant ** 2, phase) * step


#: relative size of the first absorption term left out of :func:`_along_pipe_fast`'s expansion
ABSORPTION_TERM_TOL = 1e-15


def _along_pipe_fast(env: Environment, pipe: Pipe, range_m: float, f: np.ndarray, geo: dict) -> np.ndarray:
    """:func:`_along_pipe` by a non-uniform FFT (:func:`~clbeam.evaluation.detectability_nufft.lattice_sum`).

    The boxcar beam is a pair of delays, ``sinc(2 f x) e^(−2πifτ) = (e^(−2πif(τ−x)) − e^(−2πif(τ+x))) /
    (4πi f x)`` with ``x = L u / 2c``, and the absorption ``e^(−γ(f) R_s)`` a Taylor series in
    ``(γ(f) − γ̄) (R_s − R̄)`` summed until its next term is below :data:`ABSORPTION_TERM_TOL`; points so
    near ``u = 0`` that the pair would cancel to rounding are summed directly.  Frequencies off a lattice
    of :data:`BIN_HZ` fall back to the direct sum.
    """
    k = np.rint((f - f[0]) / BIN_HZ).astype(np.int64)
    if f.size < 2 or not np.allclose(f[0] + k * BIN_HZ, f, rtol=0, atol=1e-6 * BIN_HZ):
        return _along_pipe(env, pipe, range_m, f, geo)
    from clbeam.evaluation.detectability_nufft import lattice_sum

    u, slant, tau, step = _pipe_points(env, pipe, range_m, geo)
    gamma = absorption_db_per_m(env, f) * math.log(10) / 10           # per m of slant, both ways
    g_mid, g_half = 0.5 * (gamma.max() + gamma.min()), 0.5 * (gamma.max() - gamma.min())
    dr = slant - 0.5 * (slant.max() + slant.min())
    amp = step * 0.5 * (1 + np.cos(np.pi * _taper_x(env, u))) / slant ** 2 * np.exp(-g_mid * dr)
    x = env.scene.sonar.tx_length_m * u / (2 * env.c)
    near = np.abs(2 * np.pi * f.min() * x) < 1e-6
    n_terms, term, arg = 1, 1.0, g_half * float(np.max(np.abs(dr), initial=0.0))
    while term * arg / n_terms > ABSORPTION_TERM_TOL:
        term *= arg / n_terms
        n_terms += 1
    far = ~near
    powers = (dr[far, None] ** np.arange(n_terms)) / np.array([math.factorial(n) for n in range(n_terms)])
    pair = (amp[far] / x[far])[:, None] * powers
    sums = lattice_sum(np.r_[tau[far] - x[far], tau[far] + x[far]], np.r_[pair, -pair], f[0], BIN_HZ, int(k[-1]) + 1)[k]
    series = np.sum(sums * (-(gamma - g_mid))[:, None] ** np.arange(n_terms), axis=1)
    out = np.exp(-gamma * (slant.max() + slant.min()) / 2) * series / (4j * np.pi * f)
    if near.any():
        loss = np.exp(-gamma[:, None] * slant[None, near])
        out = out + (beam(env, u[None, near], f[:, None]) * loss / slant[near] ** 2
                     * np.exp(-2j * np.pi * f[:, None] * tau[None, near])).sum(axis=1) * step
    return out


# -- reverberation ------------------------------------------------------------------------
def _ring(env: Environment, f: np.ndarray, slant_m: float, horizontal_m: float) -> np.ndarray:
    """``∫ b(u, f)² R² / y(u) du`` over the ring of constant delay: ``R`` the straight slant range,
    ``y(u) = sqrt(ρ² − R² u²)`` the across-track distance at along-track ``x = R u`` (``ρ`` the ring's
    horizontal distance at ``x = 0``); the beam is even in ``u``: twice the half ring."""
    so = env.scene.sonar
    u_cut = min(env.scene.model.tx_beam_cut * env.c / so.pulse_f0_hz / so.tx_length_m, 0.5)
    u_max = min(u_cut, 0.999 * horizontal_m / slant_m)
    u, b2 = _beam_squared(env, f, u_max)
    y = np.sqrt(np.maximum(horizontal_m ** 2 - (slant_m * u) ** 2, 1e-6))
    return 2 * np.trapezoid(b2 * slant_m ** 2 / y[None, :], u, axis=1)


def _beam_squared(env: Environment, f: np.ndarray, u_max: float) -> tuple[np.ndarray, np.ndarray]:
    """241 direction cosines from 0 to ``u_max`` and ``b(u, f)²`` on them, kept for the next range (the
    ring's ``u_max`` is the beam's cut at all but the nearest ranges)."""
    so = env.scene.sonar
    key = (u_max, env.c, so.tx_length_m, so.pulse_f0_hz, env.scene.model.tx_beam_cut, f.tobytes())
    if _BEAM_CACHE.get("key") != key:
        u = np.linspace(0.0, u_max, 241)
        _BEAM_CACHE.update(key=key, value=(u, beam(env, u[None, :], f[:, None]) ** 2))
    return _BEAM_CACHE["value"]


#: the last ring's beam squared (:func:`_beam_squared`)
_BEAM_CACHE: dict = {}


def reverberation(env: Environment, pipe: Pipe, range_m: float, f: np.ndarray) -> list[dict]:
    """The seabed's and the sub-bottom's reverberation at the pipe's delay.

    Returns
    -------
    list of dict
        Per interface: ``density`` (power spectral density per unit delay over ``f``, in the units of
        :class:`~clbeam.evaluation.detectability_stats.ChannelModel`), ``sin_arrival`` (its arrival
        direction across the array) and ``name``.
    """
    sc = env.scene
    sb, h = sc.seabed, env.height_m
    geo = pipe_geometry(env, pipe, range_m)
    r_delay = geo["delay_range_m"]
    out = []
    absorb = 10 ** (-absorption_db_per_m(env, f) * 2 * r_delay / 10)
    if sb.scattering is not None and r_delay > h:
        rho = math.sqrt(r_delay ** 2 - h ** 2)
        sigma = _strength(env, math.asin(h / r_delay), sb.scattering)
        # power per unit delay of the ring at slant R: σ (c/2) ∫ b² R² du / (y R⁴) (dA = R du · R dR / y)
        dens = sigma * (env.c / 2) * _ring(env, f, r_delay, rho) / r_delay ** 4 * absorb
        out.append({"name": "seabed", "density": dens, "sin_arrival": rho / r_delay})
    sub = sc.subbottom
    if sub is not None and sub.scattering is not None:
        d = sub.depth_below_seabed_m
        rho = _horizontal_at(env, r_delay, d)
        if rho is not None:
            path = refracted_path(rho, h, d, sb.sound_speed_ratio)
            gw, gs = float(path["grazing_water_rad"]), float(path["grazing_sediment_rad"])
            v = float(reflection_coefficient(gw, sb.density_ratio, sb.sound_speed_ratio))
            slant = math.hypot(rho, h + d)
            sigma = _strength(env, gs, sub.scattering)
            att = np.exp(-2 * attenuation_np_per_m_hz(sb) * f * 2 * float(path["sediment_m"]))
            # the ring at the delay: R du along, (ρ/y) dρ across, dρ/dτ = c / (2 cos θ_w): σ T² c ρ R ∫b²/y du / (2 cos θ_w R⁴)
            dens = (sigma * (1 - v * v) ** 2 * att * env.c / (2 * math.cos(gw)) * rho / slant
                    * _ring(env, f, slant, rho) / slant ** 4 * absorb)
            out.append({"name": "subbottom", "density": dens, "sin_arrival": math.cos(gw)})
    return out


def _strength(env: Environment, grazing_rad: float, scattering) -> float:
    """``σ = μ sin^m θ`` (the seabed's provinces: the first province's TR 9407 strength)."""
    sb = env.scene.seabed
    if scattering is sb.scattering and sb.province:
        from clbeam.seabed.avo import backscatter_strength_db

        s = backscatter_strength_db(np.array([math.degrees(grazing_rad)]), env.scene.sonar.centre_frequency_hz,
                                    mz=sb.province[0].mz, sound_speed_water_m_s=env.c)
        return float(10 ** (float(np.ravel(s)[0]) / 10))
    return 10 ** (scattering.strength_db / 10) * math.sin(grazing_rad) ** scattering.grazing_exponent


def _horizontal_at(env: Environment, delay_range_m: float, depth_below_m: float) -> float | None:
    """Horizontal distance at which a point ``depth_below_m`` under the seabed has the echo's delay."""
    from scipy.optimize import brentq

    h, n = env.height_m, env.scene.seabed.sound_speed_ratio

    def tf(rho):
        return float(refracted_path(rho, h, depth_below_m, n)["time_factor_m"]) - delay_range_m

    if tf(0.0) >= 0:
        return None
    return float(brentq(tf, 0.0, delay_range_m, xtol=1e-6))


def rough_density(env: Environment, pipe: Pipe, range_m: float, f: np.ndarray) -> float:
    """Spectral density scale of a rough pipe's incoherent echo: ``(ρ r)² Δs`` times the points' echo
    power per unit delay at the echo's delay; ``Δs`` the simulator's point spacing."""
    if pipe.roughness <= 0:
        return 0.0
    so = env.scene.sonar
    u_cut = min(env.scene.model.tx_beam_cut * env.c / so.pulse_f0_hz / so.tx_length_m, 0.5)
    spacing = env.c / (1.05 * so.pulse_f1_hz) / (4 * min(1.0, u_cut + abs(math.sin(math.radians(pipe.heading_deg)))))
    return (pipe.reflectivity * pipe.roughness) ** 2 * spacing


# -- the channel model and Pd -----------------------------------------------------------------
def channel_model(env: Environment, pipe: Pipe, range_m: float) -> tuple[ChannelModel, dict]:
    """The :class:`ChannelModel` of the pipe at ``range_m`` and the levels it comes from.

    Returns
    -------
    (ChannelModel, dict)
        The model and ``levels``: ``echo_db`` (the compressed echo's peak power per channel), ``noise_db``,
        ``seabed_db``, ``subbottom_db``, ``rough_db`` (powers per channel at the echo's delay, dB re 1),
        ``clutter_over_floor_db`` and the geometry of :func:`pipe_geometry`.
    """
    f, w = band(env)
    geo = pipe_geometry(env, pipe, range_m)
    echo = echo_spectrum(env, pipe, range_m, f)
    p_n = noise_power(env)
    comps, levels, directions = [], {}, []
    m = env.scene.sonar.n_elements
    beamwidth = env.c / env.scene.sonar.centre_frequency_hz / env.scene.sonar.array_width_m
    window = _window_coherence(env, f, geo, beamwidth)
    clutter = 0.0
    for r in reverberation(env, pipe, range_m, f):
        delta = r["sin_arrival"] - geo["sin_arrival"]
        spec = r["density"] * w ** 2
        kappa = float(np.sum(spec * _af2(env, f, delta)) / np.sum(spec))
        comps.append((r["density"], phase_step_for_coherence(kappa, m)))
        directions.append(delta)
        power = float(np.sum(spec)) / BIN_HZ
        levels[f"{r['name']}_db"] = 10 * math.log10(max(power, 1e-300))
        clutter += m * power * float(np.sum(spec * window(delta)) / np.sum(spec))
    rough = rough_density(env, pipe, range_m, f)
    if rough > 0:
        dens = rough * _rough_spectrum(env, pipe, range_m, f)
        comps.append((dens, 0.0))
        directions.append(0.0)
        levels["rough_db"] = 10 * math.log10(max(float(np.sum(dens * w ** 2)) / BIN_HZ, 1e-300))
    sin_a = min(geo["sin_arrival"], 1.0 - 1e-9)
    model = ChannelModel(f, w, echo, p_n, tuple(comps), m, BIN_HZ, tuple(directions),
                         sin_a / math.sqrt(1.0 - sin_a * sin_a))
    peak = abs(model.echo_waveform(0.0))
    levels.update(echo_db=20 * math.log10(max(peak, 1e-300)), noise_db=10 * math.log10(p_n),
                  clutter_over_floor_db=10 * math.log10(1 + clutter / p_n), **geo)
    levels["clutter"] = 1 + clutter / p_n
    return model, levels


def _af2(env: Environment, f: np.ndarray, delta_sin: float) -> np.ndarray:
    """``|AF(f)|²`` of one plane wave ``delta_sin`` off the steering, per frequency."""
    so = env.scene.sonar
    m, pitch = so.n_elements, so.array_width_m / so.n_elements
    psi = 2 * np.pi * pitch * f * delta_sin / env.c
    s = np.sin(psi / 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        af = np.where(np.abs(s) < 1e-12, 1.0, np.sin(m * psi / 2) / (m * np.where(np.abs(s) < 1e-12, 1.0, s)))
    return af ** 2


def _window_coherence(env: Environment, f: np.ndarray, geo: dict, beamwidth_rad: float):
    """``delta -> |AF(f)|²`` averaged over the clutter window's cells off the guard's angle band
    (:data:`~clbeam.imaging.detection.CONTRAST_WINDOW`, ``CONTRAST_GUARD``), per frequency, for a
    reverberation arriving ``delta`` (sine) off the pipe's direction."""
    theta = math.asin(min(geo["sin_arrival"], 1.0))
    lo, hi = CONTRAST_GUARD[1] * beamwidth_rad, CONTRAST_WINDOW[1] * beamwidth_rad
    offs = np.linspace(lo, hi, 24)
    cells = np.r_[-offs, offs]
    shifts = np.sin(theta + cells) - math.sin(theta)

    def mean_af2(delta: float) -> np.ndarray:
        return np.mean(_af2(env, f[None, :], delta - shifts[:, None]), axis=0)

    return mean_af2


def _rough_spectrum(env: Environment, pipe: Pipe, range_m: float, f: np.ndarray) -> np.ndarray:
    """Power per unit delay, per ``(ρ r)² Δs``, of a rough pipe's points near the echo's delay: the
    points of the stretch in the resolution cell, ``|T H b e^(−αfℓ)|² / R⁴`` times ``ds/dτ``
    (``R c / (2 |s|)`` each side of the specular point, averaged over the resolution's first ±c/2B)."""
    geo = pipe_geometry(env, pipe, range_m)
    so = env.scene.sonar
    r = geo["slant_m"]
    c_sed = env.c * env.scene.seabed.sound_speed_ratio
    unit = (geo["transmission"] * line_response(pipe, f, c_sed)
            * np.exp(-attenuation_np_per_m_hz(env.scene.seabed) * f * geo["sediment_m"])
            * beam(env, geo["u"], f)) ** 2 / r ** 4
    # points within one resolution cell of delay: |s| < sqrt(2 R δr); their delay density averaged over it
    res = env.c / (2 * (so.pulse_f1_hz - so.pulse_f0_hz))
    half = math.sqrt(2 * r * res)
    per_delay = 2 * half / (2 * res / env.c)
    return unit * per_delay


def detection(env: Environment, pipe: Pipe, range_m: float, *, draws: int = DEFAULT_DRAWS, seed: int = 0,
              offsets: int = GRID_OFFSETS, beside: int = BEAMS_PER_SIDE) -> dict:
    """Probability of detection of ``pipe`` at horizontal range ``range_m`` (m) and its levels, the echo's
    offset from the grid's nodes spread over ``offsets`` values across a range cell, the CF test searching
    ``beside`` beams each side of the echo's (:func:`search_beams`; 0: its own beam only).

    Returns
    -------
    dict
        :func:`~clbeam.evaluation.detectability_stats.monte_carlo_tests`' probabilities (``pd``, ...)
        and :func:`channel_model`'s levels.
    """
    return detections(env, pipe, [range_m], draws=draws, seed=seed, offsets=offsets, beside=beside)[0]


def search_beams(env: Environment, beside: int = BEAMS_PER_SIDE):
    """The beams beside the echo's that the CF test searches: ``beside`` each side, evenly in sine out to
    :data:`~clbeam.evaluation.detectability_beams.BEAM_REACH` beam widths at the band's top
    (:func:`~clbeam.evaluation.detectability_beams.side_beams`); ``None`` for 0."""
    so, motion = env.scene.sonar, env.scene.motion
    heave = 0.0 if motion is None else float(motion.heave_amplitude_m)
    return side_beams(so.n_elements, so.array_width_m, so.pulse_f1_hz, env.c, per_side=beside, heave_amplitude_m=heave)


def detections(env: Environment, pipe: Pipe, ranges_m, *, draws: int = DEFAULT_DRAWS, seed: int = 0,
               offsets: int = GRID_OFFSETS, beside: int = BEAMS_PER_SIDE) -> list[dict]:
    """:func:`detection` at every horizontal range of ``ranges_m`` (m), the Monte Carlo of all ranges at
    once (:func:`~clbeam.evaluation.detectability_stats.monte_carlo_batch`: each range gets the draws it
    would get alone, common random numbers across ranges)."""
    ranges = [float(r) for r in np.atleast_1d(np.asarray(ranges_m, dtype=np.float64))]
    for r in ranges:
        require(math.isfinite(r) and r > 0, OptionError, f"range must be > 0 m, got {r}")
    built = [channel_model(env, pipe, r) for r in ranges]
    res = monte_carlo_batch([mo for mo, _ in built], env.tests, clutters=[lv["clutter"] for _, lv in built],
                            sound_speed_m_s=env.c, draws=draws, seed=seed, offsets=offsets,
                            beams=search_beams(env, beside))
    return [{**lv, **r} for (_, lv), r in zip(built, res)]


def with_uncertain(env: Environment, pipe: Pipe, name: str, sign: int) -> tuple[Environment, Pipe]:
    """The environment and pipe with one uncertain parameter moved by one standard deviation
    (:data:`UNCERTAIN`) in direction ``sign`` (±1)."""
    sc = env.scene
    step = UNCERTAIN[name] * sign
    if name == "attenuation":
        sb = replace(sc.seabed, attenuation_db_per_m=sc.seabed.attenuation_db_per_m * (1 + step))
        return replace(env, scene=replace(sc, seabed=sb)), pipe
    if name == "noise":
        return replace(env, noise_offset_db=env.noise_offset_db + step), pipe
    if name == "scattering":
        sb = sc.seabed
        if sb.scattering is not None:
            sb = replace(sb, scattering=replace(sb.scattering, strength_db=sb.scattering.strength_db + step))
        sub = sc.subbottom
        if sub is not None and sub.scattering is not None:
            sub = replace(sub, scattering=replace(sub.scattering, strength_db=sub.scattering.strength_db + step))
        return replace(env, scene=replace(sc, seabed=sb, subbottom=sub)), pipe
    if name == "burial":
        return env, replace(pipe, burial_m=max(pipe.burial_m * (1 + step), 0.0))
    raise OptionError(f"unknown uncertain parameter {name!r}")  # pragma: no cover - a programming error


#: one standard deviation of the environment's uncertain parameters: sediment attenuation (relative),
#: noise level (dB), scattering strengths (dB), burial (relative)
UNCERTAIN = {"attenuation": 0.3, "noise": 3.0, "scattering": 3.0, "burial": 0.2}
