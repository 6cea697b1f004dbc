"""The seabed's normal-incidence reflection coefficient from its nadir echo and the first surface multiple.

The vertical beam (:class:`clbeam.imaging.vertical_beam.VerticalBeam`, earth
referenced: heave and roll compensated) of a ping over a flat seabed holds
the seabed echo at two-way time ``t1`` and its first surface multiple
(seabed, sea surface, seabed) at ``t2 = 2 t1 + 2 d / c`` for transducers
``d`` below the surface.  Both travel the same water, so with image-source
spreading (amplitude ``1 / L``, ``L = c t`` the unfolded path)

    A1 = K R / L1,        A2 = K R Rs R / L2,

``K`` the unknown source level and gains, ``Rs`` the sea surface's
reflection coefficient (``-1``, less its roughness loss), and so

    |R| = (A2 / A1) (t2 / t1) exp(alpha c (t2 - t1)) / |Rs|

without knowing ``K`` (``alpha`` the water's absorption, in nepers per
metre).  Each amplitude is measured as the square root of the trace's
energy in a window about its peak, less the noise energy of a window of
the water column (:func:`echo_energy`), not from one sample: a rough
seabed spreads its echo in time.

Limits: a seabed sloping by ``s`` sends the seabed echo back from ``s``
off the vertical and the multiple from about ``2 s``; on the vertical beam
alone the array's beam pattern weighs them unequally (15 % low at 0.8
degree for the SBP29), so :class:`NadirMeter` measures each on the beam that
points at it (slopes up to about 3 degrees).  The seabed must be smooth
over the multiple's first Fresnel zone (``sqrt(lambda L2) / 2``, about 8 m
at 5.5 kHz and 230 m of water); a rough seabed scatters part of each echo
out of the specular direction, more of the multiple's (two bounces): R
then reads low by the roughness loss, as the forward model's Eckart factor
says.  The multiple must lie inside the record (else the reason says so
and the coefficient is NaN).  See docs/avo.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from clbeam.errors import OptionError, require

#: the first strong return: the first sample within this of the trace's maximum (dB)
PRIMARY_BELOW_MAX_DB = 20.0


@dataclass(frozen=True)
class NadirEchoes:
    """The nadir echo and its multiple in one trace.

    Attributes
    ----------
    primary_s, multiple_s : float
        Two-way times of their peaks (s; NaN: not found).
    primary_amplitude, multiple_amplitude : float
        ``sqrt(energy)`` of each echo over its window, noise removed (trace units, times sqrt(s)).
    reflection : float
        ``|R|`` of the seabed at normal incidence (NaN without a multiple).
    reason : str
        Why ``reflection`` is NaN ("" when it is not).
    primary_beam_deg, multiple_beam_deg : float
        Beams (degree from nadir, earth frame) the echoes were measured on.
    """

    primary_s: float
    multiple_s: float
    primary_amplitude: float
    multiple_amplitude: float
    reflection: float
    reason: str = ""
    primary_beam_deg: float = 0.0
    multiple_beam_deg: float = 0.0


def echo_energy(envelope: np.ndarray, times_s: np.ndarray, t_s: float, half_window_s: float,
                noise_power: float) -> float:
    """Energy of the trace about ``t_s`` (``sum |s|^2 dt`` over ``t_s +- half_window_s``) less the noise's."""
    dt = float(times_s[1] - times_s[0])
    m = np.abs(times_s - t_s) <= half_window_s
    return max(float(np.sum(envelope[m] ** 2) * dt - noise_power * m.sum() * dt), 0.0)


def _peak_after(envelope: np.ndarray, times_s: np.ndarray, start_s: float, stop_s: float, level: float,
                span_s: float) -> float:
    """Time (s) of an echo's peak: the largest sample within ``span_s`` after the first one above ``level`` in
    ``start_s..stop_s`` (a compressed pulse's leading sidelobes cross the level first), refined by a parabola."""
    m = np.flatnonzero((times_s >= start_s) & (times_s <= stop_s))
    if m.size < 3:
        return math.nan
    above = np.flatnonzero(envelope[m] >= level)
    if not above.size:
        return math.nan
    t_first = times_s[m[above[0]]]
    win = np.flatnonzero((times_s >= t_first) & (times_s <= t_first + span_s))
    k = int(win[np.argmax(envelope[win])])
    frac = 0.0
    if 0 < k < envelope.size - 1:
        a, b, c = envelope[k - 1], envelope[k], envelope[k + 1]
        den = a - 2 * b + c
        frac = 0.5 * (a - c) / den if den != 0 else 0.0
    return float(times_s[k] + frac * (times_s[1] - times_s[0]))


def _check_trace(env: np.ndarray, t: np.ndarray, sound_speed_m_s: float, bandwidth_hz: float) -> None:
    require(env.ndim == 1 and env.size == t.size and env.size >= 8, OptionError,
            f"nadir echoes need a trace and its times of one length >= 8, got {env.shape} and {t.shape}")
    require(bool(np.isfinite(env).all()) and bool(np.all(np.diff(t) > 0)), OptionError,
            "nadir echoes need a finite trace and increasing times (NaN or Inf samples, or a bad time axis)")
    require(sound_speed_m_s > 0 and bandwidth_hz > 0, OptionError,
            "nadir echoes need a positive sound speed and bandwidth")


def nadir_echoes(trace: np.ndarray, times_s: np.ndarray, *, sound_speed_m_s: float, bandwidth_hz: float,
                 half_window_s: float | None = None, transducer_depth_m: float | None = None,
                 max_transducer_depth_m: float = 30.0, absorption_db_per_km: float = 0.0,
                 surface_loss_db: float = 0.0) -> NadirEchoes:
    """The seabed echo, its first surface multiple and the reflection coefficient they give (module docstring).

    Parameters
    ----------
    trace : numpy.ndarray
        ``(n,)`` vertical-beam trace: the pulse-compressed analytic signal
        (:attr:`BeamTrace.analytic`) or its envelope.
    times_s : numpy.ndarray
        ``(n,)`` two-way times of its samples (s), evenly spaced.
    sound_speed_m_s : float
        Water sound speed (m/s).
    bandwidth_hz : float
        Pulse bandwidth (Hz): the default window is ``+- 4 / bandwidth``.
    half_window_s : float, optional
        Half-width of the energy windows (s).
    transducer_depth_m : float, optional
        Depth of the transducers below the sea surface (m): the multiple
        is sought at ``2 t1 + 2 d / c``; without it, the first echo after
        ``2 t1`` within ``max_transducer_depth_m``.
    absorption_db_per_km : float
        Water absorption at the band's centre (dB/km).
    surface_loss_db : float
        Loss of the sea-surface reflection (dB; 0: a flat surface, ``|Rs| = 1``).

    Returns
    -------
    NadirEchoes
    """
    env = np.abs(np.asarray(trace))
    t = np.asarray(times_s, dtype=np.float64)
    _check_trace(env, t, sound_speed_m_s, bandwidth_hz)
    w = half_window_s if half_window_s is not None else 4.0 / bandwidth_hz
    top = float(np.max(env))
    if not top > 0:
        return NadirEchoes(math.nan, math.nan, math.nan, math.nan, math.nan, "empty trace")
    t1 = _peak_after(env, t, t[0], t[-1], top * 10 ** (-PRIMARY_BELOW_MAX_DB / 20), 2 * w)
    noise = _noise_power(env, t, t1, w)
    e1 = echo_energy(env, t, t1, w, noise)
    lo, hi = _multiple_window(t1, w, sound_speed_m_s, transducer_depth_m, max_transducer_depth_m)
    if hi + 3 * w > t[-1]:
        return NadirEchoes(t1, math.nan, math.sqrt(e1), math.nan, math.nan,
                           f"the multiple (expected near {2 * t1 * 1e3:.1f} ms) lies beyond the record's end "
                           f"({t[-1] * 1e3:.1f} ms)")
    window = (t >= lo) & (t <= hi)
    floor = math.sqrt(noise) if noise > 0 else 0.0
    level = max(0.5 * float(np.max(env[window])), 4 * floor)
    t2 = _peak_after(env, t, lo, hi, level, 2 * w)
    e2 = echo_energy(env, t, t2, w, noise) if math.isfinite(t2) else math.nan
    if not (math.isfinite(t2) and e2 > 0 and e1 > 0):
        return NadirEchoes(t1, t2, math.sqrt(e1), math.nan, math.nan, "no multiple above the noise")
    alpha_np_m = absorption_db_per_km / 1000 / (20 / math.log(10))
    r = math.sqrt(e2 / e1) * (t2 / t1) * math.exp(alpha_np_m * sound_speed_m_s * (t2 - t1)) \
        / 10 ** (-surface_loss_db / 20)
    return NadirEchoes(t1, t2, math.sqrt(e1), math.sqrt(e2), r)


def _noise_power(env: np.ndarray, t: np.ndarray, t1: float, w: float) -> float:
    """Mean noise power of the water column before the primary, clear of its window (0 when too short):
    ``|noise|^2`` is exponential, its mean the median over ln 2 (the median ignores a stray echo)."""
    quiet = (t < t1 - 3 * w) & (t > t[0])
    return float(np.median(env[quiet] ** 2)) / math.log(2) if quiet.sum() > 8 else 0.0


def _multiple_window(t1: float, w: float, c: float, depth_m: float | None, max_depth_m: float) -> tuple:
    """Times (s) between which the multiple is sought: about ``2 t1 + 2 d / c``, ``d`` the transducers' depth
    (given, or up to ``max_depth_m``), widened by two half-windows."""
    if depth_m is not None:
        t = 2 * t1 + 2 * depth_m / c
        return t - 2 * w, t + 2 * w
    return 2 * t1 - 2 * w, 2 * t1 + 2 * max_depth_m / c + 2 * w


class NadirMeter:
    """Measures the nadir reflection coefficient of pings, each echo on the beam that points at it.

    The vertical beam (0 degree) finds the seabed echo and its multiple;
    each is then measured on a fan of beams about nadir (``+- fan_deg``)
    and taken on the beam of most energy: over a seabed sloping by ``s``
    the seabed echo arrives from ``s`` off the vertical and the multiple
    from about ``2 s``, and the array's beam (``+-2`` degrees at the band's
    centre for the SBP29) would weigh them unequally on the vertical beam
    alone (15 % low at 0.8 degree).  Slopes up to about ``fan_deg / 2``.

    Parameters
    ----------
    imager_factory : callable
        ``grid -> Imager`` (sharing one engine), for the fans.
    vertical : VerticalBeam
        The vertical beam of the file.
    fan_deg, fan_step_deg : float
        Half-width and step of the fan (degree).
    """

    def __init__(self, imager_factory, vertical, *, fan_deg: float = 6.0, fan_step_deg: float = 0.2):
        require(0 < fan_step_deg <= fan_deg <= 30, OptionError,
                f"the fan needs 0 < step <= half-width <= 30 degrees, got {fan_step_deg!r} and {fan_deg!r}")
        self.imager_factory = imager_factory
        self.vertical = vertical
        self.angles = np.arange(-fan_deg, fan_deg + fan_step_deg / 2, fan_step_deg)

    def __call__(self, ping, *, bandwidth_hz: float, **kwargs) -> NadirEchoes:
        """:func:`nadir_echoes` of ``ping`` with each echo's amplitude from its own beam.

        The multiple, two specular bounces and little scattered energy about
        it, fixes the direction: its fan's energy peak (refined by a parabola
        through the largest beam and its neighbours) gives ``2 s``, and the
        seabed echo is measured at ``s``.  The seabed echo's own fan would
        not do: over a rough seabed the scattered energy about nadir moves its
        peak by a beam or two (a 1 degree pick on a flat silt seabed read R
        18 % high)."""
        c = float(ping.sound_speed_m_s)
        t = self.vertical.axis.times_s
        first = nadir_echoes(self.vertical(ping).analytic, t, sound_speed_m_s=c, bandwidth_hz=bandwidth_hz, **kwargs)
        if not math.isfinite(first.reflection):
            return first
        w = kwargs.get("half_window_s") or 4.0 / bandwidth_hz
        fan = self._energies(ping, c * first.multiple_s / 2, self.angles, w, c)
        th2 = _refined_peak(self.angles, fan)
        e1, e2 = (float(self._energies(ping, c * ts / 2, np.array([th]), w, c)[0])
                  for ts, th in ((first.primary_s, th2 / 2), (first.multiple_s, th2)))
        scale = first.reflection / (first.multiple_amplitude / first.primary_amplitude)
        return NadirEchoes(first.primary_s, first.multiple_s, math.sqrt(e1), math.sqrt(e2),
                           math.sqrt(e2 / e1) * scale if e1 > 0 else math.nan, "", th2 / 2, th2)

    def _energies(self, ping, range_m: float, angles: np.ndarray, w: float, c: float) -> np.ndarray:
        """Energy of the echo at ``range_m`` on beams ``angles`` (the same ``+-w`` in two-way time as
        :func:`nadir_echoes`)."""
        from clbeam.model.grid import PolarGrid

        step = c * float(self.vertical.axis.times_s[1] - self.vertical.axis.times_s[0]) / 2
        ranges = np.arange(range_m - c * w / 2, range_m + c * w / 2 + step / 2, step)
        img = self.imager_factory(PolarGrid(ranges, angles)).image(ping)
        s, m = np.asarray(img.sums.s), np.asarray(img.sums.m)
        power = np.where(m > 0, np.abs(s) ** 2 / np.maximum(m, 1) ** 2, 0.0)
        return power.sum(axis=1) * 2 * step / c


def _refined_peak(angles: np.ndarray, energy: np.ndarray) -> float:
    """Angle (degree) of the energy's peak: the vertex of the parabola through the largest beam and its neighbours
    (the largest beam itself at the fan's edge)."""
    k = int(np.argmax(energy))
    if not 0 < k < energy.size - 1:
        return float(angles[k])
    a, b, c = energy[k - 1], energy[k], energy[k + 1]
    den = a - 2 * b + c
    frac = 0.5 * (a - c) / den if den < 0 else 0.0
    return float(angles[k] + np.clip(frac, -0.5, 0.5) * (angles[1] - angles[0]))


def patch_reflection(values) -> tuple[float, float, int]:
    """A patch's nadir reflection coefficient from its pings': ``(median, standard error, pings)``.

    The median keeps a ping whose multiple met a passing target or a
    noise burst from moving the patch; the standard error is the pings'
    spread (``1.2533 x std / sqrt(n)``, the median's for Gaussian spread).
    NaN values (no multiple) are left out; all NaN gives ``(nan, nan, 0)``.
    """
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if not v.size:
        return math.nan, math.nan, 0
    se = 1.2533 * float(np.std(v, ddof=1)) / math.sqrt(v.size) if v.size > 1 else math.nan
    return float(np.median(v)), se, int(v.size)


def _window(trace: np.ndarray, times_s: np.ndarray, t_s: float, half_s: float) -> np.ndarray:
    """The analytic trace about ``t_s`` (+-``half_s``), shifted by a fraction of a sample (FFT phase ramp) so
    that ``t_s`` falls on the window's middle sample."""
    dt = float(times_s[1] - times_s[0])
    n = max(1, int(round(half_s / dt)))
    pos = (t_s - times_s[0]) / dt
    k = int(math.floor(pos))
    lo, hi = max(k - 4 * n, 0), min(k + 4 * n, trace.size)
    x = np.asarray(trace[lo:hi], dtype=np.complex128)
    f = np.fft.fftfreq(x.size)
    xs = np.fft.ifft(np.fft.fft(x) * np.exp(2j * np.pi * f * (pos - k)))
    mid = k - lo
    return xs[mid - n:mid + n + 1]


def coherent_reflection(traces, times_s: np.ndarray, primary_s, multiple_s, *, bandwidth_hz: float,
                        half_window_s: float | None = None, absorption_db_per_km: float = 0.0,
                        surface_loss_db: float = 0.0, sound_speed_m_s: float = 1500.0,
                        multiple_traces=None) -> tuple[float, float]:
    """A patch's nadir reflection coefficient from the coherent means of its pings' echoes: ``(R, standard error)``.

    Over a rough seabed the scattered part of each echo fills the windows
    ping by ping (on the simulated sand of scene ``avo2`` one ping reads
    ``R`` at 0.03-0.08 against 0.101), while the specular part keeps its
    phase from ping to ping.  The multiple, little scattered, is picked
    to microseconds in every ping (a pick more than 3 MADs off the patch's
    linear trend is replaced by the trend); the primary's time in each ping
    is half the multiple's plus the patch's median offset (the primary's
    own picks wander with the scattering).  Each ping's windows are moved
    onto those times (a fractional-sample shift), averaged, and the energy of the mean,
    less what the scattered part leaves in a mean of ``N`` pings (the
    pings' spread about the mean over ``N``), gives each echo.  The
    standard error is the jackknife's (leave one ping out).

    Parameters
    ----------
    traces : sequence of numpy.ndarray
        ``N`` vertical-beam traces (analytic) of the patch.
    times_s : numpy.ndarray
        Their common two-way times (s).
    primary_s, multiple_s : array_like
        ``(N,)`` each ping's echo times (:func:`nadir_echoes`; NaN pings are left out).
    bandwidth_hz, half_window_s, absorption_db_per_km, surface_loss_db, sound_speed_m_s
        As :func:`nadir_echoes`.
    multiple_traces : sequence of numpy.ndarray, optional
        The traces to take the multiples from (a beam steered onto them over
        a sloping seabed); default ``traces``.
    """
    windows = _patch_windows(traces, times_s, primary_s, multiple_s, bandwidth_hz, half_window_s,
                             multiple_traces)
    if windows is None:
        return math.nan, math.nan
    p, m, trend1, trend2 = windows
    gain = _path_gain(trend1, trend2, absorption_db_per_km, surface_loss_db, sound_speed_m_s)
    return _jackknife(lambda rows: _reflection(p[rows], m[rows], gain), p.shape[0])


def coherent_calibration_db(traces, times_s: np.ndarray, primary_s, multiple_s, n_channels: int, *,
                            bandwidth_hz: float, sound_speed_m_s: float = 1500.0, half_window_s: float | None = None,
                            absorption_db_per_km: float = 0.0, surface_loss_db: float = 0.0,
                            multiple_traces=None) -> tuple[float, float]:
    """The constant that makes a patch's image strengths absolute: ``(-20 log10(M G), standard error)`` (dB).

    The vertical beam is the mean of the ``M`` channels' compressed
    signals; the specular seabed echo on it is ``G R / L1`` (``L1 = c t1``
    the two-way path, ``R`` the nadir reflection coefficient), so ``G`` is
    the system's amplitude at 1 m in the trace's units (source level,
    sensitivity and compression gains).  The image intensity is ``|S|^2``
    summed over the channels, ``M^2 G^2`` times the scattered intensity at
    1 m, so ``S = 10 log10 I + 40 log10 R + 2 alpha R - 10 log10 A
    - 20 log10(M G)`` (:mod:`clbeam.seabed.avo.response`).  ``G`` comes from
    the coherent mean of the patch's primaries (its energy less what the
    scattering leaves, times the peak-to-energy ratio of the clean
    multiple's mean: the same pulse), over ``R`` of the same pings
    (:func:`coherent_reflection`) and the water's absorption over ``L1``.  An error in the primary's amplitude
    enters twice (once through ``R``); the standard error is the
    jackknife's of the two together.

    Parameters
    ----------
    traces, times_s, primary_s, multiple_s, bandwidth_hz, half_window_s, multiple_traces
        As :func:`coherent_reflection`; so are ``absorption_db_per_km`` and ``surface_loss_db``.
    n_channels : int
        Channels summed in the image (``M``).
    sound_speed_m_s : float
        Water sound speed (m/s), for ``L1``.

    Returns
    -------
    tuple of float
        ``calibration_db`` and its standard error (NaN when the echoes cannot give them).
    """
    windows = _patch_windows(traces, times_s, primary_s, multiple_s, bandwidth_hz, half_window_s,
                             multiple_traces)
    if windows is None or n_channels < 1:
        return math.nan, math.nan
    p, m, trend1, trend2 = windows
    gain = _path_gain(trend1, trend2, absorption_db_per_km, surface_loss_db, sound_speed_m_s)
    l1 = sound_speed_m_s * float(np.median(trend1))

    def estimate(rows):
        r = _reflection(p[rows], m[rows], gain)
        e1, e2 = _coherent_energy(p[rows]), _coherent_energy(m[rows])
        if not (r > 0 and e1 > 0 and e2 > 0):
            return math.nan
        peak = math.sqrt(e1 * float(np.max(np.abs(m[rows].mean(axis=0)))) ** 2 / e2)
        return -20 * math.log10(n_channels * peak * l1 / r) - absorption_db_per_km * l1 / 1000
    return _jackknife(estimate, p.shape[0])


def _patch_windows(traces, times_s, primary_s, multiple_s, bandwidth_hz, half_window_s, multiple_traces):
    """:func:`_aligned_windows` of the usable pings, or None when fewer than 3 are."""
    t1, t2 = np.asarray(primary_s, dtype=np.float64), np.asarray(multiple_s, dtype=np.float64)
    times_s = np.asarray(times_s, dtype=np.float64)
    w = half_window_s if half_window_s is not None else 4.0 / max(bandwidth_hz, 1e-30)
    ok = _usable_pings(len(traces), times_s, t1, t2, bandwidth_hz, w)
    if ok.size < 3:
        return None
    return _aligned_windows(traces, times_s, t1, t2, ok, w, multiple_traces)


def _path_gain(trend1, trend2, absorption_db_per_km: float, surface_loss_db: float, c: float) -> float:
    """``(t2 / t1) exp(alpha c (t2 - t1)) / |Rs|``: what turns the echoes' amplitude ratio into ``R``."""
    alpha_np_m = absorption_db_per_km / 1000 / (20 / math.log(10))
    return (float(np.median(trend2 / trend1)) * math.exp(alpha_np_m * c * float(np.median(trend2 - trend1)))
            / 10 ** (-surface_loss_db / 20))


def _reflection(p: np.ndarray, m: np.ndarray, gain: float) -> float:
    """``R`` of aligned primary and multiple windows: the ratio of their coherent amplitudes times the path gain."""
    e1, e2 = max(_coherent_energy(p), 0.0), max(_coherent_energy(m), 0.0)
    return math.sqrt(e2 / e1) * gain if e1 > 0 else math.nan


def _jackknife(estimate, n: int) -> tuple[float, float]:
    """``estimate`` of all ``n`` rows and its jackknife standard error (leave one row out; NaN below 2)."""
    full = estimate(np.arange(n))
    jack = np.array([estimate(np.delete(np.arange(n), j)) for j in range(n)])
    jack = jack[np.isfinite(jack)]
    k = jack.size
    if k < 2:
        return full, math.nan
    return full, math.sqrt((k - 1) / k * float(np.sum((jack - jack.mean()) ** 2)))


def _aligned_windows(traces, times_s: np.ndarray, t1: np.ndarray, t2: np.ndarray, ok: np.ndarray,
                     w: float, multiple_traces=None) -> tuple:
    """The usable pings' primary and multiple windows moved onto their echo times, and those times.

    The multiple is the clean echo (two specular bounces, little scattered
    energy about it): its times carry each ping's change, half of it the
    primary's; the primary's picks only set the common offset.
    """
    trend2 = _robust_trend(ok, t2[ok])
    resid = t2[ok] - trend2
    mad = 1.4826 * float(np.median(np.abs(resid)))
    trend2 = np.where(np.abs(resid) <= 3 * max(mad, 1e-6), t2[ok], trend2)  # the picks, unless one went astray
    trend1 = trend2 / 2 + float(np.median(t1[ok] - t2[ok] / 2))
    p = np.array([_window(traces[i], times_s, a, w) for i, a in zip(ok, trend1)])
    mt = traces if multiple_traces is None else multiple_traces
    m = np.array([_window(mt[i], times_s, b, w) for i, b in zip(ok, trend2)])
    return p, m, trend1, trend2


def _usable_pings(n_traces: int, times_s: np.ndarray, t1: np.ndarray, t2: np.ndarray, bandwidth_hz: float,
                  w: float) -> np.ndarray:
    """Indices of the pings whose echo times are known and whose windows (with the fractional shift's margin)
    lie inside the record; one-line errors for inconsistent inputs."""
    require(bandwidth_hz > 0 and t1.size == t2.size == n_traces, OptionError,
            f"coherent reflection needs a positive bandwidth and one primary and multiple time per trace, got "
            f"{n_traces} traces, {t1.size} and {t2.size} times")
    inside = (t1 - 5 * w >= times_s[0]) & (t2 + 5 * w <= times_s[-1])
    return np.flatnonzero(np.isfinite(t1) & np.isfinite(t2) & inside)


def _coherent_energy(x: np.ndarray) -> float:
    """Energy of the mean of the rows of ``x``, less the rows' spread about it over their number."""
    mean = x.mean(axis=0)
    n = x.shape[0]
    spread = float(np.sum(np.abs(x - mean) ** 2)) / (n * (n - 1)) if n > 1 else 0.0
    return float(np.sum(np.abs(mean) ** 2)) - spread


def _robust_trend(index: np.ndarray, values: np.ndarray) -> np.ndarray:
    """A straight line through ``values`` against ``index``, values beyond 3 MADs of the first fit left out."""
    fit = np.polyfit(index, values, 1) if np.ptp(index) > 0 else np.array([0.0, float(np.median(values))])
    resid = values - np.polyval(fit, index)
    mad = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
    keep = np.abs(resid) <= 3 * max(mad, 1e-9)
    if keep.sum() >= 2 and np.ptp(index[keep]) > 0:
        fit = np.polyfit(index[keep], values[keep], 1)
    return np.polyval(fit, index)


class PatchNadir(NamedTuple):
    """A patch's nadir reflection coefficient and the calibration it gives, with their standard errors."""

    reflection: float
    reflection_error: float
    calibration_db: float
    calibration_error_db: float


def patch_reflections(pings_path, ranges, *, bandwidth_hz: float, absorption_db_per_km: float = 0.0,
                      backend: str = "opencl", device=None, progress=None) -> list[PatchNadir]:
    """The nadir reflection coefficient of patches of a ping file and the calibration it gives, one
    :class:`PatchNadir` per ``(start, stop)`` (:func:`coherent_reflection`, :func:`coherent_calibration_db`).

    The patch's first ping fixes the beams that point at its seabed echo
    and its multiple (:class:`NadirMeter`: over a seabed sloping by ``s``,
    ``s`` and ``2 s`` off the vertical); each ping's traces on them
    (:class:`~clbeam.imaging.vertical_beam.VerticalBeam` steered) give its
    echo times (:func:`nadir_echoes`), and the patch's coherent means its
    coefficient (:func:`coherent_reflection`).

    Parameters
    ----------
    pings_path : path-like
        The ping file (docs/ping-format.md) the patches' images were made from.
    ranges : sequence of (int, int)
        Patches as ping ranges ``start..stop - 1``.
    bandwidth_hz : float
        Pulse bandwidth (Hz).
    absorption_db_per_km : float
        Water absorption at the band's centre (dB/km), as the strengths' corrections use.
    backend, device
        Imaging engine of the vertical beam.
    progress : callable, optional
        Called with no argument after each ping.
    """
    from clbeam.io.pingfile import PingFile

    with PingFile(pings_path) as pings:
        stop = max((b for _, b in ranges), default=0)
        require(stop <= pings.n_pings, OptionError,
                f"{Path(pings_path).name}: the patches reach ping {stop - 1}, the file has {pings.n_pings} ping(s)")
        return [_patch(pings, a, b, bandwidth_hz, absorption_db_per_km, backend, device, progress)
                for a, b in ranges]


def _patch(pings, a: int, b: int, bandwidth_hz: float, absorption_db_per_km: float, backend, device,
           progress) -> PatchNadir:
    """The :class:`PatchNadir` of pings ``a..b-1``, each echo on the beam that points at it."""
    from clbeam.imaging.imager import Imager, ImagingOptions
    from clbeam.imaging.vertical_beam import TraceAxis, VerticalBeam

    axis = TraceAxis.for_file(pings)
    vertical = VerticalBeam(axis, backend=backend, device=device)
    opts = ImagingOptions(interp="cubic", outputs=("sums",), use_svp=False)
    fan = NadirMeter(lambda g: Imager(g, opts, engine=vertical.engine), vertical)(pings.ping(a), bandwidth_hz=bandwidth_hz)
    beams = [VerticalBeam(axis, engine=vertical.engine, angle_deg=th)
             for th in (fan.primary_beam_deg, fan.multiple_beam_deg)]
    t = axis.times_s
    rows = []
    for i in range(a, b):
        p = pings.ping(i)
        tp, tm = beams[0](p), beams[1](p)
        c = float(p.sound_speed_m_s)
        e1 = nadir_echoes(tp.analytic, t, sound_speed_m_s=c, bandwidth_hz=bandwidth_hz)
        e2 = nadir_echoes(tm.analytic, t, sound_speed_m_s=c, bandwidth_hz=bandwidth_hz)
        rows.append((tp.analytic, tm.analytic, e1.primary_s, e2.multiple_s, tp.n_channels_used, c))
        if progress is not None:
            progress()
    tr1, tr2, p1, p2, m, c = (list(v) for v in zip(*rows))
    c0 = float(np.median(c))
    r, se = coherent_reflection(tr1, t, p1, p2, bandwidth_hz=bandwidth_hz, multiple_traces=tr2,
                                absorption_db_per_km=absorption_db_per_km, sound_speed_m_s=c0)
    cal, cal_se = coherent_calibration_db(tr1, t, p1, p2, int(np.median(m)), bandwidth_hz=bandwidth_hz,
                                          sound_speed_m_s=c0, multiple_traces=tr2,
                                          absorption_db_per_km=absorption_db_per_km)
    return PatchNadir(r, se, cal, cal_se)
