"""The beams beside the echo's: the imager's search across the polar grid's angles, in the detection model
(docs/detectability.md, "Beams beside the echo's").

The imager looks for coherence peaks in every beam of its grid, and its refinement moves a peak found in a
beam beside the echo's back onto the echo's intensity maximum.  An echo halfway between two range nodes
puts its own beam's nodes on the compressed pulse's first null; in a beam steered ``Δ`` (sine) off, each
channel ``n`` is read ``τ_n = x_n Δ / c`` later (``x_n`` the element's position across the array), so the
steered sum of the echo is its spectrum times the array factor

    AF(f, Δ) = (1/M) Σ_n e^(2πi f x_n Δ / c) = sin(M ψ / 2) / (M sin(ψ / 2)),   ψ = 2π f d Δ / c,

which passes less of the band's top: the envelope is wider and its null filled.

:class:`Beams` are the beams the model searches: ``per_side`` each side of the echo's, evenly in sine out to
``reach`` beam widths at the band's top, ``λ_top / D`` (within it every frequency's ``AF`` is positive and
falls away from the echo, so the intensity rises towards the echo along the arc and the refinement's arc
search climbs to it).  The noise's steered sums are jointly Gaussian over beams and lags,

    E[A(Δ₁, t₁) A(Δ₂, t₂)*] = M P Σ_k w_k e^(2πi f_k (t₁ − t₂)) AF(f_k, Δ₁ − Δ₂),

and are drawn conditionally on the echo's own beam's draws (:func:`noise_operator`), so the beams beside add
to the same draws (a ping detected in its own beam stays detected).  Each reverberation component is a
plane wave from its own direction ``δ``: its steered sum in beam ``Δ`` is its per-channel process times
``M sqrt(κ(δ − Δ))``, ``κ`` its band average of ``AF²``.  The incoherent sum ``Σ_n |p_n|²`` in a beam beside
is the own beam's with the echo's energy read at the channels' delays (:func:`echo_beside`), the echo's
cross term with the noise through the beam's mean echo, and the noise's part along the steering swapped
for the beam's; the rest of the noise's power over the channels (``M − 1`` of its ``M`` directions) is the
own beam's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.imaging.postprocess import HANN7

#: how far the search across beams reaches each side of the echo's, in beam widths at the band's top
BEAM_REACH = 1.0
#: beams searched each side of the echo's within the reach (0: the echo's own beam only)
BEAMS_PER_SIDE = 8


def sqrt_psd(cov: np.ndarray) -> np.ndarray:
    """The principal square root ``V sqrt(Λ) V^H`` of Hermitian positive semi-definite matrices
    ``(..., L, L)`` (negative rounding in ``Λ`` clipped).  Unlike the eigenvectors scaled, ``V sqrt(Λ)``,
    it is continuous in the matrix: the same normals give nearby draws for nearby covariances, so the
    draws are common random numbers across ranges and Pd is smooth in range."""
    vals, vecs = np.linalg.eigh(0.5 * (cov + np.swapaxes(cov.conj(), -1, -2)))
    return (vecs * np.sqrt(np.maximum(vals, 0.0))[..., None, :]) @ np.swapaxes(vecs.conj(), -1, -2)


@dataclass(frozen=True)
class Beams:
    """The beams beside the echo's that the detection test searches.

    Attributes
    ----------
    offsets_sin : numpy.ndarray
        ``(J,)`` their directions off the echo's, as the sine of the angle from the array's broadside.
    n_channels : int
        ``M``.
    pitch_m : float
        Element spacing ``d`` (m).
    sound_speed_m_s : float
        ``c`` (m/s).
    heave_amplitude_m : float
        The ship's heave amplitude (m): the image grid is centred on the transducers' mean position, and a
        ping heaved ``h`` puts the echo ``h tan θ Δ`` (m) deeper in range in a beam ``Δ`` off it
        (:func:`heave_draws`, :meth:`EchoBeside.at`).
    """

    offsets_sin: np.ndarray
    n_channels: int
    pitch_m: float
    sound_speed_m_s: float
    heave_amplitude_m: float = 0.0

    def factor(self, f_hz, delta_sin) -> np.ndarray:
        """:func:`array_factor` of this array."""
        return array_factor(f_hz, delta_sin, self.n_channels, self.pitch_m, self.sound_speed_m_s)


def side_beams(n_channels: int, array_width_m: float, top_frequency_hz: float, sound_speed_m_s: float, *,
               per_side: int = BEAMS_PER_SIDE, reach: float = BEAM_REACH, heave_amplitude_m: float = 0.0) -> Beams | None:
    """``per_side`` beams each side of the echo's, evenly in sine to ``reach`` times ``λ_top / D`` (``D`` the
    array's width, m; ``λ_top`` at ``top_frequency_hz``, Hz), the ship heaving ``heave_amplitude_m`` (m);
    ``None`` for none."""
    require(per_side >= 0, OptionError, f"beams beside the echo's must be >= 0, got {per_side}")
    if per_side == 0:
        return None
    width = sound_speed_m_s / top_frequency_hz / array_width_m
    step = reach * width / per_side
    k = np.arange(1, per_side + 1, dtype=np.float64)
    return Beams(np.r_[-k[::-1], k] * step, int(n_channels), array_width_m / n_channels, float(sound_speed_m_s),
                 float(heave_amplitude_m))


def array_factor(f_hz, delta_sin, n_channels: int, pitch_m: float, sound_speed_m_s: float) -> np.ndarray:
    """``AF(f, Δ) = sin(M ψ / 2) / (M sin(ψ / 2))``, ``ψ = 2π f d Δ / c``: the mean over a uniform line array's
    ``M`` elements of a plane wave ``Δ`` (sine) off the steering at ``f`` (Hz), real; broadcast."""
    psi = 2 * np.pi * pitch_m * np.asarray(f_hz, dtype=np.float64) * np.asarray(delta_sin, dtype=np.float64) / sound_speed_m_s
    s = np.sin(psi / 2)
    small = np.abs(s) < 1e-12
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(small, 1.0, np.sin(n_channels * psi / 2) / (n_channels * np.where(small, 1.0, s)))


def reverberation_gains(beams: Beams, f_hz: np.ndarray, weight: np.ndarray, reverberation, directions) -> np.ndarray:
    """``(C, J)`` each reverberation component's steered amplitude per channel in each beam,
    ``sqrt(κ(δ − Δ))`` with ``κ`` the band average of ``AF²`` over its spectrum (``density w²``) and ``δ`` its
    direction off the echo's (``directions``, sine)."""
    out = np.zeros((len(reverberation), beams.offsets_sin.size))
    for k, ((density, _), delta) in enumerate(zip(reverberation, directions)):
        spec = np.asarray(density) * weight ** 2
        af2 = beams.factor(f_hz[None, :], delta - beams.offsets_sin[:, None]) ** 2
        out[k] = np.sqrt(af2 @ spec / max(float(np.sum(spec)), 1e-300))
    return out


def _covariance(beams: Beams, f_hz: np.ndarray, weight: np.ndarray, lags_a: np.ndarray, dirs_a: np.ndarray,
                lags_b: np.ndarray, dirs_b: np.ndarray) -> np.ndarray:
    """``E[A(Δ_a, t_a) A(Δ_b, t_b)*]`` of the noise's steered sums at unit power per channel: ``M Σ_k w_k
    e^(2πi f_k (t_a − t_b)) AF(f_k, Δ_a − Δ_b)`` for points given by their lags (s) and directions (sine)."""
    diff = np.round((dirs_a[:, None] - dirs_b[None, :]) * 1e12).astype(np.int64)
    uniq, inverse = np.unique(diff, return_inverse=True)
    ta, ia = np.unique(lags_a, return_inverse=True)
    tb, ib = np.unique(lags_b, return_inverse=True)
    ea = np.exp(2j * np.pi * ta[:, None] * f_hz)
    ebh = np.exp(-2j * np.pi * tb[None, :] * f_hz[:, None])
    af = beams.factor(f_hz[None, :], (uniq * 1e-12)[:, None]) * weight             # (U, K)
    blocks = np.stack([(ea * row) @ ebh for row in af])                            # (U, La, Lb)
    return beams.n_channels * blocks[inverse.reshape(diff.shape), ia[:, None], ib[None, :]]


def noise_operator(beams: Beams, f_hz: np.ndarray, weight: np.ndarray, grid_lags: np.ndarray) -> tuple:
    """The conditional law of the noise's steered sums in the beams beside on the grid's cells ``grid_lags``
    (s), given the echo's own beam's on the same cells, at unit noise power per channel: ``(gain, root)``,
    with the sums beside ``gain @ a_own + root @ z`` (``z`` standard circular normals, ``J × L`` of them).
    The law depends on the cells' lag differences only, one for every offset of the echo from the grid
    (the refined point's taps, off the grid's cells, are left out of the conditioning)."""
    lags = np.asarray(grid_lags, dtype=np.float64) - float(grid_lags[0])
    key = (f_hz.tobytes(), weight.tobytes(), beams.offsets_sin.tobytes(), beams.n_channels, beams.pitch_m,
           beams.sound_speed_m_s, np.round(lags * 1e12).astype(np.int64).tobytes())
    if key not in _OPERATORS:
        j, own = beams.offsets_sin.size, np.zeros(lags.size)
        lag_b, dir_b = np.tile(lags, j), np.repeat(beams.offsets_sin, lags.size)
        c_oo = _covariance(beams, f_hz, weight, lags, own, lags, own)
        c_bo = _covariance(beams, f_hz, weight, lag_b, dir_b, lags, own)
        c_bb = _covariance(beams, f_hz, weight, lag_b, dir_b, lag_b, dir_b)
        vals, vecs = np.linalg.eigh(0.5 * (c_oo + c_oo.conj().T))
        keep = vals > 1e-10 * vals.max()
        gain = c_bo @ ((vecs[:, keep] / vals[keep]) @ vecs[:, keep].conj().T)
        if len(_OPERATORS) > 8:
            _OPERATORS.clear()
        _OPERATORS[key] = (gain, sqrt_psd(c_bb - gain @ c_bo.conj().T))
    return _OPERATORS[key]


#: the operators already computed (a sweep's, and its uncertain parameters', share one band and one grid)
_OPERATORS: dict = {}


class EchoBeside:
    """The echo in the beams beside the echo's, at any lag: its mean over the channels
    ``Σ_k S_k AF(f_k, Δ) e^(2πi f_k t)`` and its energy over the channels ``Σ_n |s(t + τ_n)|²`` (``s`` the
    per-channel waveform of the spectra ``S`` ``(n, K)``: the echo times the replica's weights).

    The mean is tabulated every :data:`MEAN_STEP_S` on the band's baseband (about the weights' mean
    frequency ``f_c``) and read linearly: its relative error is at most ``(2π b h)² / 8`` with ``b`` the
    band's largest distance from ``f_c`` and ``h`` the step.  The ``M`` delays ``τ_n = x_n Δ / c`` are the
    midpoints of ``M`` equal parts of ``±M d Δ / 2c``: the energy is ``M`` times the mean of ``|s|²`` over
    that span (the midpoint rule: its step is under 2 µs where ``|s|²`` varies over the pulse's 140 µs), from
    the running integral of ``|s|²`` on the same table.
    """

    def __init__(self, beams: Beams, f_hz: np.ndarray, weight: np.ndarray, spectra: np.ndarray, t_min: float,
                 t_max: float):
        m, d = beams.n_channels, beams.offsets_sin
        self.m, self.fc = m, float(np.sum(weight * f_hz))
        self.span = m * beams.pitch_m * np.abs(d) / beams.sound_speed_m_s                    # (J,)
        pad = float(self.span.max()) / 2 + 2 * MEAN_STEP_S
        self.t0 = math.floor((t_min - pad) / MEAN_STEP_S) * MEAN_STEP_S
        self.grid = self.t0 + MEAN_STEP_S * np.arange(int(math.ceil((t_max + pad - self.t0) / MEAN_STEP_S)) + 1)
        af = beams.factor(f_hz[:, None], d[None, :])                                           # (K, J)
        n, k = spectra.shape
        coeff = np.concatenate([(spectra[:, None, :] * af.T[None]).reshape(-1, k), spectra])    # (n J + n, K)
        table = _baseband(f_hz, coeff, self.fc, self.grid)
        self.mean = table[:n * d.size].reshape(n, d.size, -1)
        power = np.abs(table[n * d.size:]) ** 2                                                 # (n, T)
        self.run = np.concatenate([np.zeros((n, 1)), np.cumsum(0.5 * (power[:, 1:] + power[:, :-1]), axis=1)
                                   * MEAN_STEP_S], axis=1)

    def _read(self, table: np.ndarray, t: np.ndarray, rows: np.ndarray, beam: np.ndarray | None) -> np.ndarray:
        """``table`` ``(n, [J,] T)`` read linearly at ``t`` ``(N, J, L)`` (s) of the models ``rows`` ``(N,)``."""
        x = (t - self.t0) / MEAN_STEP_S
        i = np.clip(np.floor(x).astype(np.int64), 0, self.grid.size - 2)
        w = x - i
        r = rows[:, None, None]
        if beam is None:
            return table[r, i] * (1 - w) + table[r, i + 1] * w
        return table[r, beam, i] * (1 - w) + table[r, beam, i + 1] * w

    def at(self, t: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean and energy at lags ``t`` ``(N, J, L)`` (s) of the models ``rows`` ``(N,)``, each ``(N, J, L)``."""
        j = self.span.size
        beam = np.arange(j)[None, :, None]
        mean = self._read(self.mean, t, rows, beam) * np.exp(2j * np.pi * self.fc * t)
        half = (self.span / 2)[:, None]
        energy = self.m * (self._read(self.run, t + half, rows, None) - self._read(self.run, t - half, rows, None)) / (2 * half)
        return mean, energy


def _baseband(f_hz: np.ndarray, coeff: np.ndarray, fc: float, t: np.ndarray) -> np.ndarray:
    """``Σ_k coeff_k e^(2πi (f_k − f_c) t)`` at the uniform times ``t`` (s), ``(rows, T)``: by one inverse FFT
    where the frequencies lie on a lattice (its period longer than the times' span and the lattice's
    ``f_c`` rounded to it, the phase of the rest applied after), else directly."""
    step = float(t[1] - t[0])
    df = float(np.min(np.diff(f_hz))) if f_hz.size > 1 else 0.0
    k = np.rint((f_hz - f_hz[0]) / df).astype(np.int64) if df > 0 else np.zeros(f_hz.size, np.int64)
    size = int(round(1.0 / (df * step))) if df > 0 else 0
    if df <= 0 or not np.allclose(f_hz[0] + k * df, f_hz, rtol=0, atol=1e-6 * df) \
            or abs(size * df * step - 1.0) > 1e-9 or size < t.size:
        return coeff @ np.exp(2j * np.pi * (f_hz[:, None] - fc) * t[None, :])
    kc = int(round((fc - f_hz[0]) / df))
    spec = np.zeros((coeff.shape[0], size), dtype=np.complex128)
    spec[:, np.mod(k - kc, size)] = coeff
    full = np.fft.ifft(spec, axis=1) * size                        # at m step, m = 0 .. size - 1
    m = np.rint(t / step).astype(np.int64)
    shift = np.exp(2j * np.pi * (f_hz[0] + kc * df - fc) * t)          # the lattice's centre against f_c
    return full[:, np.mod(m, size)] * shift


#: the step (s) of :class:`EchoBeside`'s tables
MEAN_STEP_S = 2.5e-6


def heave_draws(amplitude_m: float, first: int, count: int) -> np.ndarray:
    """Heave (m) of draws ``first`` to ``first + count``: a sinusoid of ``amplitude_m`` at phases spread
    evenly over the cycle (a Weyl sequence, the golden ratio's fraction), as pings at an interval
    incommensurate with the heave's period sample it (the arcsine law)."""
    k = np.arange(first, first + count, dtype=np.float64)
    return amplitude_m * np.sin(2 * np.pi * np.mod((k + 0.5) * GOLDEN, 1.0))


#: the golden ratio's fraction
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def component_directions(model, beams: Beams, f_hz: np.ndarray, weight: np.ndarray) -> list:
    """Each reverberation component's direction off the echo's (sine): the model's ``directions`` where it
    has them, else its phase step ``β`` read as a plane wave at the band's root-mean-square frequency
    (``δ = β c / (2π f d)``)."""
    if len(getattr(model, "directions", ())) == len(model.reverberation):
        return [float(v) for v in model.directions]
    f_rms = math.sqrt(float(np.sum(weight * f_hz ** 2)))
    return [step * beams.sound_speed_m_s / (2 * math.pi * f_rms * beams.pitch_m) for _, step in model.reverberation]


def beside_passes(beams: Beams, operator: tuple, echo: tuple, own: tuple, z: list, gains: np.ndarray,
                  noise_power: np.ndarray, normals: np.ndarray, threshold: float) -> np.ndarray:
    """Whether the smoothed CF passes ``threshold`` on a grid cell within the search of any beam beside the
    echo's, for ``N`` draws (module docstring); ``(N,)``.

    Parameters
    ----------
    operator : (numpy.ndarray, numpy.ndarray)
        :func:`noise_operator`'s ``gain`` ``(J L, L)`` and ``root`` ``(J L, J L)``.
    echo : (numpy.ndarray, numpy.ndarray)
        :meth:`EchoBeside.at`'s mean and energy over the channels at the grid's ``L`` cells, ``(N, J, L)``.
    own : (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        The echo's own beam on the same cells: the per-channel echo, the noise's coherent sum and the
        incoherent sum, ``(N, L)`` each.
    z : list of numpy.ndarray
        Each reverberation component's per-channel draws on the cells ``(N, L)``.
    gains : numpy.ndarray
        ``(N, C, J)`` :func:`reverberation_gains`.
    noise_power : numpy.ndarray
        ``(N,)`` noise power per channel.
    normals : numpy.ndarray
        ``(N, J L)`` standard circular normals.
    """
    m = beams.n_channels
    s_own, a_own, b_own = own
    mean, energy = echo
    n, j, lg = mean.shape
    gain, root = operator
    an = (a_own @ gain.T + np.sqrt(noise_power)[:, None] * (normals @ root.T)).reshape(n, j, lg)
    a = m * mean + an
    for k, zk in enumerate(z):
        a = a + zk[:, None, :] * (m * gains[:, k])[:, :, None]
    a0 = a_own[:, None, :]
    b = (b_own[:, None, :] + energy - m * np.abs(s_own[:, None, :]) ** 2
         + 2 * np.real(mean.conj() * an - s_own.conj()[:, None, :] * a0) + (np.abs(an) ** 2 - np.abs(a0) ** 2) / m)
    i2 = np.abs(a) ** 2
    cf = i2 / (m * np.maximum(b, np.maximum(i2 / m, 1e-300)))
    smooth = np.lib.stride_tricks.sliding_window_view(cf, HANN7.size, axis=-1) @ HANN7
    return smooth.max(axis=(-1, -2)) > threshold
