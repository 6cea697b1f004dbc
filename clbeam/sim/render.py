"""Rendering echo sets into samples: fractional-delay deposits, filters, one pulse convolution.

A synthesiser (targets, seabed fields, specular paths) hands over an
:class:`Echoes` set: positions, amplitudes, delays or ray-traced times, the
transmit beam's direction cosine and any frequency-dependent factor.
:class:`Renderer` turns the sets of one ping into samples: each echo is
deposited as band-limited fractional-delay taps (a least-squares filter
exact to 0.5 % in the pulse band, :func:`_fd_tables`) per scatterer and
channel, the along-track transmit boxcar ``L |u| / c`` as a pair of steps
that a running sum turns into the box (:class:`_Accumulator`); sets with
sediment attenuation ``exp(-α(f) ℓ)`` or a spectral response are filtered
on short time blocks (:meth:`Renderer._block_filter`); then every channel
is convolved with the pulse once, by FFT.  The cost scales with scatterers
× channels, not with samples.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import typing
from dataclasses import dataclass

import numpy as np
import scipy.fft

from clbeam.errors import ClbeamError
from clbeam.sim.geometry import PingGeometry
from clbeam.sim.scene import Sonar

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


@dataclass
class Echoes:
    """A set of echoes of one ping, all arrays ``(S,)`` or ``(S, 3)``.

    ``pos``: scatterer (or image-source) position, earth frame (m);
    ``amp``: amplitude (m for scatterers, 1 for image sources), real or
    complex: a complex ``A`` gives the echo ``Re{A x_a(t - τ)}`` (``x_a`` the
    analytic pulse), the pulse's phase rotated by ``arg A``;
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
        """Number of echoes ``S``."""
        return len(self.amp)

    def subset(self, mask: np.ndarray) -> Echoes:
        """The echoes selected by the boolean ``mask`` ``(S,)``."""
        return dataclasses.replace(
            self, pos=self.pos[mask], amp=self.amp[mask], src_leg=self.src_leg[mask], spread=self.spread[mask],
            extra_s=self.extra_s[mask], u=self.u[mask], b_s=None if self.b_s is None else self.b_s[mask],
            rx_tilt=None if self.rx_tilt is None else self.rx_tilt[mask],
            times_s=None if self.times_s is None else self.times_s[mask])


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
        """Add impulses of weight ``w`` at record sample ``t`` (both ``(S, C)``;
        ``w`` complex for phase-rotated echoes: the accumulator turns complex)."""
        self.imp = self._deposit(self.imp, t, w, self.imp_cols, clip=False)

    def steps(self, t: np.ndarray, w: np.ndarray) -> None:
        """Add steps of height ``w`` at record sample ``t`` (both ``(S, C)``)."""
        if self.stp is None:
            self.stp = np.zeros_like(self.imp)
        # a one-sample box starting at t, summed, is a step at t: the running
        # sum 1/(1 - e^{-jΩ}) = e^{jΩ/2}/(jΩ sinc(Ω/2π)) undoes the box's half
        # sample delay and its sinc, leaving e^{-jΩt}/(jΩ)
        self.stp = self._deposit(self.stp, t, w, self.box_cols, clip=True)

    def add(self, lo: int, y: np.ndarray) -> None:
        """Add ``y`` ``(C, n)`` from column ``lo`` on (clipped to the window)."""
        a, b = max(lo, 0), min(lo + y.shape[1], self.length)
        if b > a:
            if np.iscomplexobj(y) and not np.iscomplexobj(self.imp):
                self.imp = self.imp.astype(np.complex128)
            self.imp[:, a:b] += y[:, a - lo:b - lo]

    def _deposit(self, out, t, w, cols, *, clip: bool) -> np.ndarray:
        """Deposit into ``out`` and return it (a complex copy when ``w`` is complex and ``out`` real)."""
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
            return out
        if np.iscomplexobj(w) and not np.iscomplexobj(out):
            out = out.astype(np.complex128)
        n_ch = out.shape[0]
        lo = int(k0.min())
        hi = int(k0.max()) + self.taps
        span = hi - lo
        base = (k0 - lo) + (np.arange(n_ch) * span)[None, :]
        base = base.ravel()
        ph = ph.ravel()
        w = w.ravel()
        if not np.iscomplexobj(w):
            acc = np.zeros(n_ch * span)
            for j, col in enumerate(cols):
                acc += np.bincount(base + j, col[ph] * w, minlength=n_ch * span)
            out[:, lo:hi] += acc.reshape(n_ch, span)
            return out
        # the real and imaginary parts share the indices and the taps
        wr, wi = np.ascontiguousarray(w.real), np.ascontiguousarray(w.imag)
        acc_r, acc_i = np.zeros(n_ch * span), np.zeros(n_ch * span)
        for j, col in enumerate(cols):
            idx, tap = base + j, col[ph]
            acc_r += np.bincount(idx, tap * wr, minlength=n_ch * span)
            acc_i += np.bincount(idx, tap * wi, minlength=n_ch * span)
        out[:, lo:hi] += (acc_r + 1j * acc_i).reshape(n_ch, span)
        return out

    def total(self) -> np.ndarray:
        """Impulses plus the running sum of the steps (``(C, length)``)."""
        if self.stp is None:
            return self.imp
        return self.imp + np.cumsum(self.stp, axis=1)


class Renderer:
    """Renders the echo sets of a ping into raw samples.

    Parameters
    ----------
    sonar : Sonar
        Sample rate, pulse band and replica, transmit column length.
    sound_speed_m_s : float
        Sound speed at the transducers (m/s): straight-ray delays and the
        transmit boxcar width ``L |u| / c``.
    t0_s : float
        Time of sample 0 after transmit start (s).
    n_samples : int
        Samples per channel.

    Attributes
    ----------
    replica : numpy.ndarray
        The transmit replica (unit amplitude) every channel is convolved with.
    tables : tuple
        The fractional-delay tables (:func:`_fd_tables`) for the band.
    """

    def __init__(self, sonar: Sonar, *, sound_speed_m_s: float, t0_s: float, n_samples: int):
        self.c = sound_speed_m_s
        self.fs = sonar.sample_rate_hz
        self.fc = sonar.centre_frequency_hz
        self.band_hz = (sonar.pulse_f0_hz, sonar.pulse_f1_hz)
        self.tx_length_m = sonar.tx_length_m
        self.t0 = t0_s
        self.n_samples = n_samples
        self.replica = sonar.replica()
        self.n_pulse = self.replica.size
        self.tables = _fd_tables(2 * np.pi * min(1.1 * sonar.pulse_f1_hz, 0.45 * self.fs) / self.fs)

    def render(self, g: PingGeometry, sets: list[Echoes]) -> np.ndarray:
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
            acc.add(local.start - FILTER_PAD - acc.start, y)
        total = acc.total()
        nfft = scipy.fft.next_fast_len(total.shape[1] + self.n_pulse, real=True)
        if np.iscomplexobj(total):
            # deposits D_r + j D_i of echoes Re{A x_a(t - τ)}: D_r ⊛ x - D_i ⊛ H{x}, whose
            # spectrum on f > 0 is (D_r + j D_i) X (the Hilbert transform is -j sgn f)
            quad = scipy.fft.rfft(total.imag, nfft, axis=1)
            quad[:, 0] = 0.0
            if nfft % 2 == 0:
                quad[:, -1] = 0.0
            spec = scipy.fft.rfft(total.real, nfft, axis=1) + 1j * quad
        else:
            spec = scipy.fft.rfft(total, nfft, axis=1)
        spec *= scipy.fft.rfft(self.replica, nfft)[None, :]
        y = scipy.fft.irfft(spec, nfft, axis=1)
        return y[:, -start:-start + self.n_samples]

    def _pair_chunks(self, g: PingGeometry, e: Echoes):
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
        ws_all = self.tx_length_m * np.abs(e.u) / self.c * self.fs
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

    def _deposit(self, g: PingGeometry, e: Echoes, acc: _Accumulator, amp_scale: np.ndarray | None = None) -> None:
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

    def _deposit_local(self, g: PingGeometry, e: Echoes):
        """Deposit a filtered set into its own accumulator over its time support;
        return it and the attenuation ``b`` (s) of each filter block."""
        ws = self.tx_length_m * np.abs(e.u) / self.c * self.fs
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
        lo, hi, w = self.band_hz[0] - 1000.0, self.band_hz[1] + 1000.0, 1000.0
        x = np.clip(np.maximum(lo - f, f - hi) / w, 0.0, 1.0)
        return 0.5 * (1 + np.cos(np.pi * x))

    def _block_filter(self, x: np.ndarray, b_blocks: np.ndarray, response) -> np.ndarray:
        """Zero-phase filter ``W(f) H(f) exp(-b_j f)`` applied to each block ``j``
        of ``x`` (``(C, n_blocks · FILTER_BLOCK)``); the blocks' outputs overlap-add
        into ``(C, n_blocks · FILTER_BLOCK + 2 FILTER_PAD)``."""
        if np.iscomplexobj(x):  # a real, zero-phase filter: each part on its own
            return self._block_filter(x.real, b_blocks, response) + 1j * self._block_filter(x.imag, b_blocks, response)
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
