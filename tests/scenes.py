"""Small scenes built independently of clbeam's simulator, for tests.

Echoes are placed with an exact fractional delay (a phase ramp on the FFT of
the replica), so they are the band-limited truth the imager should recover.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from clbeam.imaging.engine import BeamformInput
from clbeam.imaging.geometry import to_earth_frame
from clbeam.io.pingwrite import dataset_from_pings
from clbeam.model.ping import Ping
from clbeam.model.pulse import Pulse

FS = 40000.0
C = 1500.0
PULSE = Pulse(f0_hz=2000.0, f1_hz=9000.0, duration_s=0.02)


def sbp_elements(n: int = 64, width_m: float = 3.528) -> np.ndarray:
    """``(n, 3)`` receive elements equally spaced across-track, centred."""
    pos = np.zeros((n, 3))
    pos[:, 1] = (np.arange(n) - (n - 1) / 2) * width_m / n
    return pos


def delayed(waveform: np.ndarray, delay_s: np.ndarray, n_samples: int, fs: float = FS) -> np.ndarray:
    """``waveform`` delayed by ``delay_s`` (one per row), exactly band-limited."""
    nfft = 1 << int(np.ceil(np.log2(n_samples + waveform.size)))
    f = np.fft.rfftfreq(nfft, 1 / fs)
    spec = np.fft.rfft(waveform, nfft)[None, :] * np.exp(-2j * np.pi * f[None, :] * np.asarray(delay_s)[:, None])
    return np.fft.irfft(spec, nfft, axis=-1)[:, :n_samples]


def point_ping(targets_m, amplitudes=None, *, roll_deg=0.0, heave_m=0.0, n_channels=64, record_s=0.3,
               t0_s=0.0, source_m=(0.0, 0.0, 0.0), pulse=PULSE, fs=FS, c=C, kind="raw", elements_m=None) -> Ping:
    """A ping with point scatterers at earth-frame positions ``targets_m`` (``(k, 3)``, m).

    Travel times ``(|r - s| + |r - e_n|) / c`` with the array rolled and heaved
    as docs/ping-format.md says; amplitude ``a / (|r - s| |r - e_n|)``.  ``kind="analytic"``
    stores the exact compressed analytic signal instead of raw pressure; ``elements_m`` (``(n, 3)``, vessel
    frame) replaces the SBP29-like array of ``n_channels`` elements.
    """
    targets = np.atleast_2d(np.asarray(targets_m, dtype=float))
    amps = np.ones(len(targets)) if amplitudes is None else np.asarray(amplitudes, dtype=float)
    elements = sbp_elements(n_channels) if elements_m is None else np.asarray(elements_m, dtype=float)
    n_channels = len(elements)
    el = to_earth_frame(elements, roll_deg=roll_deg, heave_m=heave_m)
    src = to_earth_frame(np.asarray(source_m, dtype=float), roll_deg=roll_deg, heave_m=heave_m)
    n_samples = int(round(record_s * fs))
    replica = pulse.replica(fs)
    out = np.zeros((n_channels, n_samples), dtype=np.complex128 if kind == "analytic" else np.float64)
    if kind == "analytic":
        # compressed analytic pulse: autocorrelation of the replica, centred on its peak
        nfft = 1 << int(np.ceil(np.log2(4 * replica.size)))
        spec = np.abs(np.fft.fft(replica, nfft)) ** 2
        f = np.fft.fftfreq(nfft)
        spec[f < 0] = 0
        spec[f > 0] *= 2
        acf = np.fft.ifft(spec) / np.dot(replica, replica)
        half = replica.size
        wave = np.concatenate([acf[-half:], acf[:half]])
    for r, a in zip(targets, amps):
        d_src = np.linalg.norm(r - src)
        d_rx = np.linalg.norm(r - el, axis=1)
        tau = (d_src + d_rx) / c - t0_s
        if kind == "analytic":
            re = delayed(wave.real, tau - half / fs, n_samples, fs)
            im = delayed(wave.imag, tau - half / fs, n_samples, fs)
            out += (a / (d_src * d_rx))[:, None] * (re + 1j * im)
        else:
            out += (a / (d_src * d_rx))[:, None] * delayed(replica, tau, n_samples, fs)
    return Ping(samples=out, kind=kind, sample_rate_hz=fs, t0_s=t0_s, sound_speed_m_s=c,
                element_pos_m=elements, source_pos_m=np.asarray(source_m, dtype=float),
                channel_valid=np.ones(n_channels, dtype=bool), roll_deg=roll_deg, heave_m=heave_m, pulse=pulse)


def polar_point(range_m: float, angle_deg: float) -> np.ndarray:
    """Earth-frame position of a polar grid node centred at the origin."""
    th = np.deg2rad(angle_deg)
    return np.array([0.0, range_m * np.sin(th), range_m * np.cos(th)])


def bandlimited_noise(shape, *, f_lo=2000.0, f_hi=9000.0, fs=FS, seed=0) -> np.ndarray:
    """Complex analytic noise with its band in ``[f_lo, f_hi]`` Hz."""
    rng = np.random.default_rng(seed)
    spec = np.fft.fft(rng.standard_normal(shape), axis=-1)
    f = np.fft.fftfreq(shape[-1], 1 / fs)
    spec[..., (f < f_lo) | (f > f_hi)] = 0
    return 2 * np.fft.ifft(spec, axis=-1)


def profile_point_ping(targets_yz_m, profile, *, n_channels=64, record_s=1.5, t0_s=0.0, pulse=PULSE,
                       fs=FS, elements_m=None) -> Ping:
    """A ping of point scatterers (earth-frame ``(y, z)``, m) in a stratified
    ocean: each echo's delay is the exact eigenray time source → scatterer →
    element (:func:`clbeam.imaging.raytrace.element_travel_times`), spreading
    ``1 / (|r - s| |r - e_n|)``; the file's sound speed is the profile's at
    the transducers, and ``svp`` carries the profile."""
    from clbeam.imaging.raytrace import element_travel_times

    targets = np.atleast_2d(np.asarray(targets_yz_m, dtype=float))
    elements = sbp_elements(n_channels) if elements_m is None else np.asarray(elements_m, dtype=float)
    n_channels = len(elements)
    t_src = element_travel_times(profile, np.zeros((1, 2)), targets)[0]
    t_rx = element_travel_times(profile, elements[:, 1:], targets)
    n_samples = int(round(record_s * fs))
    replica = pulse.replica(fs)
    out = np.zeros((n_channels, n_samples))
    for j, r in enumerate(targets):
        spread = np.hypot(*r) * np.hypot(r[0] - elements[:, 1], r[1] - elements[:, 2])
        out += (1.0 / spread)[:, None] * delayed(replica, t_src[j] + t_rx[:, j] - t0_s, n_samples, fs)
    return Ping(samples=out, kind="raw", sample_rate_hz=fs, t0_s=t0_s, sound_speed_m_s=float(profile.speed(0.0)),
                element_pos_m=elements, source_pos_m=np.zeros(3), channel_valid=np.ones(n_channels, dtype=bool),
                pulse=pulse, svp=profile)


def ping_dataset(ping: Ping, **extra):
    """A one-ping dataset (float32 samples) of ``ping`` from clbeam's writer, with
    extra variables (``name=(dims, values)``)."""
    return dataset_from_pings([ping], samples_dtype=np.float32).assign(**extra)


def dataset(n_pings=3, kind="raw", seed=0):
    """Three pings of point scatterers and a minimal ping dataset of them written by hand, the
    way another program would (no element_x, few attributes): the reader must not depend on
    clbeam's own writer."""
    pings = [point_ping(polar_point(40 + 5 * i, 10 * i), kind=kind, record_s=0.08, roll_deg=i) for i in range(n_pings)]
    p0 = pings[0]
    samples = np.stack([p.samples for p in pings])
    ds = xr.Dataset(
        {
            "samples": (("ping", "channel", "sample"), samples, {"kind": kind}),
            "sample_rate": ((), p0.sample_rate_hz, {"units": "Hz"}),
            "t0": (("ping",), np.zeros(n_pings), {"units": "s"}),
            "element_y": (("channel",), p0.element_pos_m[:, 1], {"units": "m"}),
            "element_z": (("channel",), p0.element_pos_m[:, 2], {"units": "m"}),
            "source_y": ((), 0.0), "source_z": ((), 0.0),
            "sound_speed": (("ping",), np.full(n_pings, 1500.0)),
            "roll": (("ping",), np.arange(n_pings, dtype=float)),
            "pulse_f0": ((), 2000.0), "pulse_f1": ((), 9000.0), "pulse_duration": ((), 0.02),
            "latitude": (("ping",), 34.3 + 1e-4 * np.arange(n_pings)),
            "longitude": (("ping",), np.full(n_pings, -119.8)),
        },
        attrs={"clbeam_format": "ping-1"},
    )
    return ds, pings


def random_input(seed=0, n_ch=24, n_s=3000, t0=0.002):
    rng = np.random.default_rng(seed)
    data = bandlimited_noise((n_ch, n_s), seed=seed)
    eo = np.zeros((n_ch, 3))
    eo[:, 0] = rng.uniform(-0.1, 0.1, n_ch)
    eo[:, 1] = np.sort(rng.uniform(-1.8, 1.8, n_ch))
    eo[:, 2] = rng.uniform(-0.2, 0.2, n_ch)
    src = rng.uniform(-0.5, 0.5, 3)
    return BeamformInput(data, FS, t0, 1500.0, eo, src, centre_frequency_hz=5500.0)
