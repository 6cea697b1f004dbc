"""The statistics behind the detection-performance model: the coherence factor of an echo in noise and
reverberation, in closed form for one cell and by Monte Carlo of the channel model for the tests a peak
must pass (docs/detectability.md).

**One cell, closed form.** On ``M`` channels steered at an echo, channel ``n`` holds ``c + w_n``: a
coherent part ``c`` (the echo, and reverberation from the same direction) and noise ``w_n``, independent
circular complex Gaussian of power ``P``.  Split the noise into its mean over the channels and the rest:
``CF = A / (A + B)`` with ``A = M |c + w̄|² / P`` and ``B = Σ |w_n − w̄|² / P``, independent, ``2A``
non-central χ² with 2 degrees of freedom and non-centrality ``2 M x`` (``x = |c|² / P``, the per-channel
signal-to-noise ratio) and ``B`` Gamma(``M − 1``).  So ``P(CF > t) = E_B[Q₁(sqrt(2 M x), sqrt(2 t B /
(1 − t)))]``, one integral over ``B`` (:func:`cf_exceedance`): ``(1 − t)^(M−1)`` for pure noise
(Beta(1, M − 1), as :mod:`clbeam.imaging.detection`), 1 below ``t = 1`` for a pure echo.

**The tests, Monte Carlo.** A pipe is detected when a coherence peak near its echo clears the smoothed
CF threshold on the image grid, and the refined peak then stands ``min_snr_db`` over the noise floor and,
where the clutter is reverberation, ``min_contrast_db`` over the clutter.  The smoothed CF is a
Hann-weighted mean over seven range cells, most of which see the echo's compressed tails, the
reverberation and the noise rather than its peak: no closed form.  :func:`monte_carlo_tests` draws the
channel model itself on the lags the test looks at: the echo's compressed (deterministic) waveform,
each reverberation component as a complex Gaussian process along delay (its covariance from its
power spectrum, coherent across the array up to its arrival direction's phase ramp) and each channel's
noise, independent across channels and correlated along delay as the compressed replica.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from clbeam.errors import OptionError, require
from clbeam.evaluation import detectability_beams as db
from clbeam.evaluation.detectability_beams import beside_passes, heave_draws, sqrt_psd
from clbeam.imaging.postprocess import HANN7

#: grid cells either side of the echo whose smoothed CF can make the pipe's peak
SEARCH_CELLS = 2
#: draws of the channel model per evaluation, and the offsets of the echo from the grid nodes they use
DEFAULT_DRAWS = 1024
GRID_OFFSETS = 64
#: offsets drawn together (memory: models x offsets x draws x lags)
OFFSET_CHUNK = 16
#: draws per offset at least: fewer draws spread over fewer offsets (each offset costs a principal root of
#: every covariance, whatever its draws)
MIN_DRAWS_PER_OFFSET = 16


def cf_exceedance(threshold, n_channels: int, snr) -> np.ndarray:
    """``P(CF > t)`` of one cell whose ``M`` channels hold a fixed coherent part at per-channel
    signal-to-noise ratio ``snr`` in independent circular Gaussian noise (module docstring).

    Parameters
    ----------
    threshold : float or array_like
        ``t`` (0-1).
    n_channels : int
        ``M`` (at least 2).
    snr : float or array_like
        ``x = |c|² / P`` (power ratio, not dB); 0: pure noise.

    Returns
    -------
    numpy.ndarray
        The probability, broadcast over ``threshold`` and ``snr``.
    """
    from scipy import stats

    require(n_channels >= 2, OptionError, f"the CF needs at least 2 channels, got {n_channels}")
    t, x = np.broadcast_arrays(np.asarray(threshold, dtype=np.float64), np.asarray(snr, dtype=np.float64))
    m = int(n_channels)
    # Gauss-Laguerre quadrature over B ~ Gamma(M - 1): nodes of the generalised Laguerre weight b^(M-2) e^-b
    nodes, weights = _laguerre(m - 2)
    out = np.empty(t.shape)
    for idx in np.ndindex(t.shape):
        ti, xi = float(t[idx]), float(x[idx])
        if ti <= 0:
            out[idx] = 1.0
            continue
        if ti >= 1:
            out[idx] = 0.0
            continue
        a = ti * nodes / (1 - ti)
        # P(A > a) with 2A ~ ncx2(2, 2 M x)
        tail = stats.ncx2.sf(2 * a, 2, 2 * m * xi) if xi > 0 else np.exp(-a)
        out[idx] = float(np.sum(weights * tail))
    return out[()]


def _laguerre(alpha: int, n: int = 96) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and weights (normalised to sum 1) of ``n``-point generalised Gauss-Laguerre quadrature."""
    from scipy.special import roots_genlaguerre

    x, w = roots_genlaguerre(n, alpha)
    return x, w / w.sum()


@dataclass(frozen=True)
class ChannelModel:
    """What one range cell's channels hold about a pipe's echo, as the Monte Carlo draws it.

    Attributes
    ----------
    frequency_hz : numpy.ndarray
        ``(K,)`` frequencies of the band (Hz).
    weight : numpy.ndarray
        ``(K,)`` the replica's power spectrum over them, summing to 1: the compressed output of an echo
        of spectrum ``G`` at lag ``τ`` is ``Σ G_k weight_k e^(2πi f_k τ)``.
    echo : numpy.ndarray
        ``(K,)`` the echo's complex spectrum per channel (re the replica), its delay removed.
    noise_power : float
        Compressed noise power per channel (``2 σ² / E``).
    reverberation : tuple of (numpy.ndarray, float)
        Each component's power spectral density over ``frequency_hz`` (power per unit delay per
        ``weight²``) and its arrival direction's phase step across the array (rad per element; 0: the
        echo's direction).
    n_channels : int
        ``M``.
    bin_hz : float
        Spacing of ``frequency_hz`` (Hz).
    directions : tuple of float
        Each reverberation component's arrival direction off the echo's (sine of the angle from the array's
        broadside), for the beams beside the echo's (:mod:`~clbeam.evaluation.detectability_beams`); empty:
        read from its phase step.
    arrival_tan : float
        Tangent of the echo's angle from the vertical at the array (the heave's slide of the echo across
        the beams beside, :class:`~clbeam.evaluation.detectability_beams.Beams`).
    """

    frequency_hz: np.ndarray
    weight: np.ndarray
    echo: np.ndarray
    noise_power: float
    reverberation: tuple
    n_channels: int
    bin_hz: float
    directions: tuple = ()
    arrival_tan: float = 0.0

    def echo_waveform(self, lag_s) -> np.ndarray:
        """The echo's compressed analytic signal per channel at lags ``lag_s`` (s)."""
        lag = np.asarray(lag_s, dtype=np.float64)
        return np.einsum("...k,k->...", np.exp(2j * np.pi * lag[..., None] * self.frequency_hz), self.echo * self.weight)

    def noise_covariance(self, lag_s) -> np.ndarray:
        """Noise covariance between two lags ``lag_s`` apart (s), per channel."""
        lag = np.asarray(lag_s, dtype=np.float64)
        return self.noise_power * (np.exp(2j * np.pi * lag[..., None] * self.frequency_hz) @ self.weight)

    def reverberation_covariance(self, k: int, lag_s) -> np.ndarray:
        """Component ``k``'s covariance between two lags ``lag_s`` apart (s), per channel."""
        lag = np.asarray(lag_s, dtype=np.float64)
        density = self.reverberation[k][0]
        return (np.exp(2j * np.pi * lag[..., None] * self.frequency_hz) @ (density * self.weight ** 2)) / self.bin_hz

    def reverberation_power(self) -> np.ndarray:
        """Each component's power per channel (zero lag)."""
        return np.array([float(np.real(self.reverberation_covariance(k, 0.0))) for k in range(len(self.reverberation))])


@dataclass(frozen=True)
class Tests:
    """The detection test a peak must pass (:class:`clbeam.imaging.imager.ImagingOptions`' defaults).

    Attributes
    ----------
    threshold : float
        Smoothed-CF threshold.
    min_snr_db : float or None
        Level over the noise floor (dB); ``None``: no test.
    min_contrast_db : float or None
        Level over the clutter where the clutter stands :data:`REVERBERATION_MARGIN_DB` over the floor
        (dB); ``None``: no test.
    range_step_m : float
        The image grid's range step (m): the smoothed CF's cells.
    """

    __test__ = False   # a detection test's settings, not a test class for pytest to collect

    threshold: float = 0.25
    min_snr_db: float | None = 6.0
    min_contrast_db: float | None = 12.0
    range_step_m: float = 0.2

    def __post_init__(self):
        require(0.0 <= self.threshold <= 1.0, OptionError, f"threshold must be within 0-1, got {self.threshold!r}")
        require(self.range_step_m > 0, OptionError, f"range step must be > 0 m, got {self.range_step_m!r}")


def _complex_normals(rng: np.random.Generator, shape: tuple) -> np.ndarray:
    """Circular complex Gaussians of unit power (the real parts drawn first, then the imaginary)."""
    re = rng.standard_normal(shape)
    return (re + 1j * rng.standard_normal(shape)) / math.sqrt(2)


def _apply(root: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``root_ng z_g`` for every model ``n`` and offset ``g``: ``(n, G, L, L)`` roots on ``(G, ..., L)``
    normals, ``(n, G, ..., L)``."""
    return np.einsum("g...l,ngkl->ng...k", z, root)     # einsum: no threaded BLAS for tiny products


def _channel_sums(models: list, s: np.ndarray, z: list, cov: np.ndarray, rng: np.random.Generator,
                  per: int, exact: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, N) = (Σ p_n, Σ |p_n|², Σ w_n)`` over the channels at each lag (``N`` the noise's part of ``A``),
    ``(n, G, per, L)`` each, for ``n`` models
    with as many reverberation components at ``G`` offsets of the echo from the grid, drawn from the same
    normals for every model: the echo's compressed waveform ``s`` ``(n, G, L)``, the reverberation draws
    ``z`` (each ``(n, G, per, L)``, on its phase ramp) and the noise (covariance ``cov`` ``(G, L, L)`` per
    channel at unit power, scaled by each model's ``noise_power``: the root of a scaled matrix is the
    root scaled, so one root serves every model).

    Not ``exact``: the channels' space is split into the span ``Q`` of the steering vector and the
    ramps (``q`` directions, drawn exactly) and its complement, whose noise power ``|w_⊥|²`` at a lag
    is a sum of ``M − q`` exponentials, correlated between lags as ``|C|²``: drawn as a Gaussian of
    that mean and covariance (``M − q`` is 61 or more on the SBP29: its skewness, 0.26, is left out).
    """
    m, (g, n_lags) = models[0].n_channels, s.shape[1:]
    n_idx = np.arange(m) - 0.5 * (m - 1)
    steps = np.array([[step for _, step in mo.reverberation] for mo in models]).reshape(len(models), -1)
    ramps = np.exp(1j * steps[:, :, None] * n_idx)                                  # (n, C, M)
    power = np.array([mo.noise_power for mo in models], dtype=np.float64)
    root = np.sqrt(power)[:, None, None, None] * sqrt_psd(cov)[None]
    if exact:
        noise = _apply(root, _complex_normals(rng, (g, per, m, n_lags)))
        p = s[:, :, None, None, :] + noise
        for k, zk in enumerate(z):
            p = p + zk[:, :, :, None, :] * ramps[:, k, None, None, :, None]
        return p.sum(axis=3), np.sum(np.abs(p) ** 2, axis=3), noise.sum(axis=3)
    basis = np.concatenate([np.ones((len(models), m, 1)), np.swapaxes(ramps[:, steps[0] != 0, :], 1, 2)], axis=2)
    qh = np.swapaxes(np.linalg.qr(basis)[0].conj(), 1, 2)                            # (n, q, M)
    q = qh.shape[1]
    ce = qh.sum(axis=2)
    noise = _apply(root, _complex_normals(rng, (g, per, q, n_lags)))
    pq = s[:, :, None, None, :] * ce[:, None, None, :, None] + noise
    for k, zk in enumerate(z):
        pq = pq + zk[:, :, :, None, :] * np.einsum("njm,nm->nj", qh, ramps[:, k])[:, None, None, :, None]
    a = np.einsum("nj,ngpjl->ngpl", ce.conj(), pq)
    mean = (m - q) * power[:, None] * np.real(cov[None, :, 0, 0])
    rest_root = power[:, None, None, None] * sqrt_psd((m - q) * np.abs(cov) ** 2)[None]
    rest = mean[:, :, None, None] + _apply(rest_root, rng.standard_normal((g, per, n_lags)))
    return a, np.sum(np.abs(pq) ** 2, axis=3) + np.maximum(rest.real, 0.0), np.einsum("nj,ngpjl->ngpl", ce.conj(), noise)


def _lag_covariances(models: list, lag_sets: list) -> tuple:
    """The noise's ``(U,)`` covariance at unit power and the reverberation's ``(n, C, U)`` covariances of
    ``n`` models on one band at every distinct lag difference of ``lag_sets`` (s), at once, and for each set
    the index array ``(L, L)`` into them."""
    mo = models[0]
    diffs = np.concatenate([(lg[:, None] - lg[None, :]).ravel() for lg in lag_sets])
    key = np.round(diffs * 1e9).astype(np.int64)          # ns
    uniq, inverse = np.unique(key, return_inverse=True)
    phase = np.exp(2j * np.pi * (uniq * 1e-9)[:, None] * mo.frequency_hz)
    cov_noise = np.einsum("uk,k->u", phase, mo.weight)
    dens = np.array([[d for d, _ in m.reverberation] for m in models]).reshape(len(models), -1, mo.frequency_hz.size)
    cov_rev = np.einsum("uk,nck->ncu", phase, dens * mo.weight ** 2) / mo.bin_hz
    wheres, start = [], 0
    for lags in lag_sets:
        size = lags.size * lags.size
        wheres.append(inverse[start:start + size].reshape(lags.size, lags.size))
        start += size
    return cov_noise, cov_rev, wheres


def _offset_tests(a: np.ndarray, b: np.ndarray, models: list, tests: Tests, n_grid: int, clutter: np.ndarray,
                  contrast_applies: np.ndarray) -> dict:
    """The tests' outcomes ``(n, per)`` of one offset's draws from their coherent sums ``a`` and incoherent
    sums ``b`` ``(n, per, L)`` (``n_grid`` grid cells, then the refined point's seven smoothing taps); the
    noise floor ``M P`` is 1 in the intensity's units."""
    m = models[0].n_channels
    intensity = np.abs(a) ** 2 / (m * np.array([mo.noise_power for mo in models]))[:, None, None]
    cf = np.abs(a) ** 2 / (m * b)
    grid_cf = np.stack([np.einsum("npl,l->np", cf[..., i - 3:i + 4], HANN7) for i in range(3, n_grid - 3)], axis=-1)
    level = intensity[..., n_grid + 3]
    echo = np.max(intensity, axis=-1)
    snr = np.ones(level.shape, bool) if tests.min_snr_db is None else level >= 10 ** (tests.min_snr_db / 10)
    contrast = np.ones(level.shape, bool)
    if tests.min_contrast_db is not None:
        contrast = ~contrast_applies[:, None] | (echo >= clutter[:, None] * 10 ** (tests.min_contrast_db / 10))
    return {"cf": np.max(grid_cf, axis=-1) > tests.threshold, "snr": snr, "contrast": contrast,
            "cf_ref": np.einsum("npl,l->np", cf[..., n_grid:], HANN7)}


def monte_carlo_tests(model: ChannelModel, tests: Tests, *, clutter: float, sound_speed_m_s: float,
                      draws: int = DEFAULT_DRAWS, seed: int = 0, exact: bool = False, offsets: int = GRID_OFFSETS,
                      beams=None) -> dict:
    """Probability that the pipe's echo gives a peak that passes the detection test, by Monte Carlo.

    Parameters
    ----------
    model : ChannelModel
        The echo, reverberation and noise of the cell.
    tests : Tests
        The test.
    clutter : float
        Mean intensity of the clutter window around the echo in units of the per-channel noise power
        times ``M`` (the noise floor is 1 in these units).
    sound_speed_m_s : float
        Sound speed of the image grid (m/s): lags are ``2 Δr / c``.
    draws : int
        Draws (split evenly over the offsets of the echo from the grid's nodes).
    seed : int
        Seed (common random numbers across calls give smooth curves).
    exact : bool
        Draw every channel's noise (slow); by default the noise is drawn in the few directions the echo
        and the reverberation span and the rest of its power over the channels, a sum of ``M − q``
        correlated exponentials, as a Gaussian of the same mean and covariance (:func:`_channel_sums`).
    offsets : int
        Offsets of the echo from the grid's nodes, at the middles of equal parts of a cell (the echo's
        offset is uniform over a cell); at most one per :data:`MIN_DRAWS_PER_OFFSET` draws.
    beams : detectability_beams.Beams, optional
        Beams beside the echo's whose grid cells the CF test also searches
        (:mod:`~clbeam.evaluation.detectability_beams`); ``None``: the echo's own beam only.

    Returns
    -------
    dict
        ``pd`` (all tests), ``p_cf`` (the grid's smoothed CF), ``p_snr`` and ``p_contrast`` (each with
        the CF test), ``pd_own_beam`` (all tests, the CF test on the echo's own beam only), the draws'
        smoothed CF at the refined point ``cf_refined`` and its median ``cf_median``, and whether the
        clutter test applied (``reverberation_limited``).
    """
    return monte_carlo_batch([model], tests, clutters=[clutter], sound_speed_m_s=sound_speed_m_s, draws=draws,
                             seed=seed, exact=exact, offsets=offsets, beams=beams)[0]


def monte_carlo_batch(models: list, tests: Tests, *, clutters, sound_speed_m_s: float, draws: int = DEFAULT_DRAWS,
                      seed: int = 0, exact: bool = False, offsets: int = GRID_OFFSETS, beams=None) -> list[dict]:
    """:func:`monte_carlo_tests` of many models on one band (a sweep's ranges) at once.

    Each model gets the very draws it would get alone (the same seed, the same normals through the
    principal root of its own covariances): the models with as many reverberation components and
    directions are drawn together.

    Returns
    -------
    list of dict
        :func:`monte_carlo_tests`' result per model, in order.
    """
    groups: dict = {}
    for i, mo in enumerate(models):
        require(mo.frequency_hz.shape == models[0].frequency_hz.shape and np.array_equal(mo.frequency_hz, models[0].frequency_hz)
                and np.array_equal(mo.weight, models[0].weight), OptionError, "a batch of channel models needs one band")
        groups.setdefault(tuple(step != 0 for _, step in mo.reverberation), []).append(i)
    out = [None] * len(models)
    for idx in groups.values():
        res = _group_tests([models[i] for i in idx], tests, np.array([clutters[i] for i in idx], dtype=np.float64),
                           sound_speed_m_s, draws, seed, exact, offsets, beams)
        for i, r in zip(idx, res):
            out[i] = r
    return out


def _group_tests(models: list, tests: Tests, clutter: np.ndarray, sound_speed_m_s: float, draws: int, seed: int,
                 exact: bool, offsets: int, beams) -> list[dict]:
    """:func:`monte_carlo_batch` of models whose reverberation arrives from as many directions, the
    offsets drawn :data:`OFFSET_CHUNK` at a time; the beams beside the echo's from their own generator, so
    that the echo's own beam gets the draws it gets alone."""
    rng = np.random.default_rng(seed)
    dr = tests.range_step_m
    half = SEARCH_CELLS + 3
    offsets = min(offsets, max(draws // MIN_DRAWS_PER_OFFSET, 1))
    per = max(draws // offsets, 1)
    contrast_applies = (tests.min_contrast_db is not None) & (10 * np.log10(np.maximum(clutter, 1e-300)) >= 3.0)
    results = {k: [] for k in ("cf", "snr", "contrast", "cf_ref", "beside")}
    # grid cells about the echo at each offset, then the refined point (the echo) with its smoothing neighbours
    cell_sets = [np.r_[((j + 0.5) / offsets - 0.5) * dr + dr * np.arange(-half, half + 1), dr * np.arange(-3, 4)]
                 for j in range(offsets)]
    lag_sets = [2.0 * cells / sound_speed_m_s for cells in cell_sets]
    cov_noise, cov_rev, wheres = _lag_covariances(models, lag_sets)
    spectra = np.stack([mo.echo * mo.weight for mo in models])                       # (n, K)
    beside = None if beams is None else _Beside(beams, models, lag_sets, 2 * half + 1, spectra, seed)
    for j0 in range(0, offsets, OFFSET_CHUNK):
        lags = np.stack(lag_sets[j0:j0 + OFFSET_CHUNK])                                # (G, L)
        where = np.stack(wheres[j0:j0 + OFFSET_CHUNK])                                 # (G, L, L)
        g = lags.shape[0]
        s = np.einsum("glk,nk->ngl", np.exp(2j * np.pi * lags[..., None] * models[0].frequency_hz), spectra)
        z = [_apply(sqrt_psd(cov_rev[:, k][:, where]), _complex_normals(rng, (g, per, lags.shape[1])))
             for k in range(cov_rev.shape[1])]
        a, b, a_noise = _channel_sums(models, s, z, cov_noise[where], rng, per, exact)
        shape = (len(models), g * per, lags.shape[1])
        for k, v in _offset_tests(a.reshape(shape), b.reshape(shape), models, tests, 2 * half + 1, clutter,
                                  contrast_applies).items():
            results[k].append(v)
        if beside is not None:
            todo = ~results["cf"][-1] & results["snr"][-1] & results["contrast"][-1]
            results["beside"].append(beside.passes(j0, g, per, (s, a_noise, b.reshape(a_noise.shape)), z,
                                                   tests.threshold, todo))
    cf_own, snr_ok, con_ok, cf_ref = (np.concatenate(results[k], axis=1) for k in ("cf", "snr", "contrast", "cf_ref"))
    cf_ok = cf_own | np.concatenate(results["beside"], axis=1) if beside is not None else cf_own
    return [{"pd": float(np.mean(cf_ok[i] & snr_ok[i] & con_ok[i])), "p_cf": float(np.mean(cf_ok[i])),
             "p_snr": float(np.mean(cf_ok[i] & snr_ok[i])), "p_contrast": float(np.mean(cf_ok[i] & con_ok[i])),
             "pd_own_beam": float(np.mean(cf_own[i] & snr_ok[i] & con_ok[i])),
             "cf_median": float(np.median(cf_ref[i])), "cf_refined": cf_ref[i],
             "reverberation_limited": bool(contrast_applies[i])} for i in range(len(models))]


class _Beside:
    """The beams beside the echo's for one group of models (:mod:`~clbeam.evaluation.detectability_beams`):
    the noise's conditional law, the echo in the beams and the reverberation's gains, computed once."""

    def __init__(self, beams, models: list, lag_sets: list, n_grid: int, spectra: np.ndarray, seed: int):
        f, w = models[0].frequency_hz, models[0].weight
        self.beams, self.n_grid = beams, n_grid
        self.grid_lags = np.stack([lg[:n_grid] for lg in lag_sets])                     # (offsets, Lg)
        self.operator = db.noise_operator(beams, f, w, self.grid_lags[0])
        self.tan = np.array([m.arrival_tan for m in models], dtype=np.float64)
        reach = 2 * beams.heave_amplitude_m * float(np.max(np.abs(self.tan))) * float(np.max(np.abs(beams.offsets_sin)))
        self.echo = db.EchoBeside(beams, f, w, spectra, float(self.grid_lags.min()) - reach / beams.sound_speed_m_s,
                                  float(self.grid_lags.max()) + reach / beams.sound_speed_m_s)
        self.gains = np.stack([db.reverberation_gains(beams, f, w, m.reverberation, db.component_directions(m, beams, f, w))
                               for m in models]).reshape(len(models), -1, beams.offsets_sin.size)
        self.power = np.array([m.noise_power for m in models], dtype=np.float64)
        self.rng = np.random.default_rng([int(seed), 32])

    def passes(self, j0: int, g: int, per: int, own: tuple, z: list, threshold: float, todo: np.ndarray) -> np.ndarray:
        """``(n, g per)`` whether a beam beside passes the CF test, offsets ``j0`` to ``j0 + g``, for the draws
        ``todo`` (``(n, g per)``: those the echo's own beam does not already decide): the echo in beam ``Δ``
        slid by the draw's heave ``h`` (up), ``h tan θ Δ`` farther in range."""
        b, lg = self.beams, self.n_grid
        normals = _complex_normals(self.rng, (g * per, b.offsets_sin.size * lg))     # drawn for every draw
        ni, k = np.nonzero(todo)
        out = np.zeros(todo.shape, dtype=bool)
        if ni.size == 0:
            return out
        gi, pi = np.divmod(k, per)
        heave = heave_draws(b.heave_amplitude_m, j0 * per, g * per)[k]
        shift = 2 * (heave * self.tan[ni])[:, None] * b.offsets_sin / b.sound_speed_m_s   # (N, J)
        t = self.grid_lags[j0 + gi][:, None, :] - shift[:, :, None]                        # (N, J, Lg)
        s, a_noise, b_own = own
        pick = (s[ni, gi, :lg], a_noise[ni, gi, pi, :lg], b_own[ni, gi, pi, :lg])
        out[ni, k] = beside_passes(b, self.operator, self.echo.at(t, ni), pick, [zk[ni, gi, pi, :lg] for zk in z],
                                   self.gains[ni], self.power[ni], normals[k], threshold)
        return out


def phase_step_for_coherence(kappa: float, n_channels: int) -> float:
    """The phase step across the array (rad per element) of a plane wave whose steered coherent fraction
    ``|AF|² = |sin(M ψ / 2) / (M sin(ψ / 2))|²`` is ``kappa`` (0-1), on the main lobe."""
    from scipy.optimize import brentq

    kappa = float(np.clip(kappa, 0.0, 1.0))
    if kappa >= 1.0 - 1e-12:
        return 0.0
    m = int(n_channels)

    def af2(psi):
        return (math.sin(m * psi / 2) / (m * math.sin(psi / 2))) ** 2

    return float(brentq(lambda psi: af2(psi) - kappa, 1e-12, 2 * math.pi / m * (1 - 1e-9)))
