"""Layer parameters from a compressed nadir trace (inverting Rakotonarivo eqs. 15–19).

Estimates, per echo, the two-way time and reflection coefficient and, per
layer, the attenuation slope ``k_p'`` (dB/m/kHz), by a weighted least-squares
fit of the layered model to the trace's spectrum (a model fit, not spectral
ratios; see ``docs/forward.md`` for the reasons):

1. The compressed trace ``y_c`` (circular, :func:`.trace.compress_circular`)
   gives back the received spectrum in band, ``Y = FFT(y_c) E / conj(X)``.
   White noise of standard deviation ``sigma`` on the received trace makes
   ``Y - X p_r`` independent complex Gaussian in each FFT bin with variance
   ``N sigma^2``: the residuals below are whitened by it, so the sum of
   squares is a chi-square statistic.
2. ``sigma`` comes from the compressed trace before the first echo (the
   water column), at least one pulse length before it, or from the caller.
3. Echoes are found one at a time (largest first) on a deconvolved,
   Blackman-weighted view of the residual, down to a false-alarm threshold,
   each new echo followed by a joint fit of all.
4. Model per echo (eq. 15 with smooth interfaces and attenuation linear in
   frequency, ``b = 0``): ``p0/(2 c1 tau_i) v_i 10^(-s_i f/20)
   exp(-j w tau_i)``, ``f`` in kHz, ``s_i`` the two-way loss slope above
   interface ``i`` (dB/kHz; 0 for the seafloor, the water being lossless).
5. Seafloor reflection: constant (smooth), Eckart ``v exp(-g f^2)`` (rough)
   or with a transitional bed (alone or under a rough interface) are compared
   by chi-square tests.  A seafloor that needs, or cannot exclude, a
   transitional bed of intermediate thickness is reported unresolvable: the
   paper's §5, "if rugosity is conjugated with intermediate thickness of
   transitional layer, rugosity is not assessable and reflection loss is
   sorely calculable".  No number is returned for it.  The caller may
   exclude transitional beds (``transitional_beds=False``); a smoothly
   falling reflection is then read as roughness.
6. A deeper echo whose spectrum is not linear in dB (a significant extra
   ``f^2`` term) has its reflection and the attenuation of the layers on
   both sides of it marked not separable.
7. Layer stripping: ``V_i = v_i / prod_{k<i} (1 - V_k^2)``,
   ``k_p' = (s_{i+1} - s_i) / (c_i (tau_{i+1} - tau_i))``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.fft
from scipy import stats
from scipy.optimize import least_squares

from clbeam.errors import ClbeamError, OptionError, require
from clbeam.seabed.forward.trace import Chirp
from clbeam.seabed.forward.transition import transition_coefficients

#: Upsampling of the detection view.
_UPSAMPLE = 8


class UnresolvableError(ClbeamError):
    """The trace does not determine a requested layer parameter (Rakotonarivo §5)."""


@dataclass(frozen=True)
class EchoEstimate:
    """What the trace says about one interface.

    Attributes
    ----------
    index : int
        Echo number, 0 for the seafloor.
    time_s, time_std_s : float
        Two-way time from the start of transmission and its standard error (s).
    reflection, reflection_std : float or None
        Reflection coefficient at low frequency (the smooth, sharp value;
        for a rough seafloor the ``f -> 0`` limit) and its standard error;
        ``None`` when not resolvable.
    status : str
        ``"smooth"``, ``"rough"``, ``"unresolvable"`` (seafloor) or
        ``"frequency-dependent"`` (deeper echo whose reflection and the
        attenuation above cannot be separated).
    roughness_small_m, roughness_fair_m : float or None
        For ``"rough"``: ``sigma`` read with Eckart's factor (eq. 5) or the
        fair-roughness one (eq. 7, ``3/4`` of the former); the data cannot
        tell the regimes apart.
    roughness_small_std_m, roughness_fair_std_m : float or None
        Their standard errors.
    reason : str or None
        Why a value is missing.
    note : str or None
        Caveat on a value given (an approximate stripping).
    """

    index: int
    time_s: float
    time_std_s: float
    reflection: float | None
    reflection_std: float | None
    status: str
    roughness_small_m: float | None = None
    roughness_fair_m: float | None = None
    roughness_small_std_m: float | None = None
    roughness_fair_std_m: float | None = None
    reason: str | None = None
    note: str | None = None


@dataclass(frozen=True)
class LayerEstimate:
    """The layer between two consecutive echoes.

    Attributes
    ----------
    index : int
        Layer number as in :attr:`.layers.Seabed.layers` (1 below the water).
    two_way_time_s, two_way_time_std_s : float
        Two-way travel time through it (s).
    sound_speed_m_s : float
        Speed used to turn time into thickness (given, or the water speed).
    thickness_m : float
        ``c * two_way_time / 2`` (m).
    loss_slope_db_khz, loss_slope_std_db_khz : float or None
        Two-way attenuation slope across the layer (dB/kHz).
    attenuation_db_m_khz, attenuation_std_db_m_khz : float or None
        ``k_p'`` (dB/m/kHz) with ``b = 0``.
    reason : str or None
        Why the attenuation is missing.
    """

    index: int
    two_way_time_s: float
    two_way_time_std_s: float
    sound_speed_m_s: float
    thickness_m: float
    loss_slope_db_khz: float | None
    loss_slope_std_db_khz: float | None
    attenuation_db_m_khz: float | None
    attenuation_std_db_m_khz: float | None
    reason: str | None = None


@dataclass(frozen=True)
class InversionResult:
    """Echoes and layers estimated from one trace.

    Attributes
    ----------
    echoes : tuple of EchoEstimate
    layers : tuple of LayerEstimate
    noise_std : float
        Noise standard deviation of the received trace (estimated or given).
    noise_dof : float or None
        Degrees of freedom of the noise estimate (None when given).
    reduced_chi2 : float
        Chi-square per degree of freedom of the final fit.
    seafloor_models : dict
        Chi-square adequacy (True/False) of each seafloor reflection model
        tried: ``smooth``, ``rough``, ``transitional``, ``rough+transitional``.
    """

    echoes: tuple[EchoEstimate, ...]
    layers: tuple[LayerEstimate, ...]
    noise_std: float
    noise_dof: float | None
    reduced_chi2: float
    seafloor_models: dict = field(default_factory=dict)

    @property
    def resolvable(self) -> bool:
        """True when every echo and layer has its values."""
        return not self.messages

    @property
    def messages(self) -> list[str]:
        """One line per missing value."""
        out = [e.reason for e in self.echoes if e.reason]
        out += [la.reason for la in self.layers if la.reason]
        return out

    def require_resolved(self) -> "InversionResult":
        """This result, or :class:`UnresolvableError` naming what the trace does not determine."""
        if self.messages:
            raise UnresolvableError("; ".join(self.messages))
        return self


# -- the spectral model ------------------------------------------------------
_PARAMS = {"S0": 2, "G0": 3, "T0": 4, "GT0": 5, "D": 3, "DG": 4}


class _Model:
    """Weighted least squares of the received spectrum against eq. 15's echo sum."""

    def __init__(self, freq_hz, x_spec, y_spec, scale, t0_s, p0, c1, c_ramp):
        self.f = freq_hz
        self.fk = freq_hz / 1000.0
        self.w = 2 * np.pi * freq_hz
        self.x = x_spec
        self.y = y_spec
        self.scale = scale
        self.t0 = t0_s
        self.p0, self.c1, self.c_ramp = p0, c1, c_ramp

    def ramp(self, big_l, dx_cm):
        r, _, _ = transition_coefficients(self.f, thickness_m=dx_cm / 100.0, density_top_kg_m3=1.0,
                                          density_bottom_kg_m3=math.exp(2 * big_l), sound_speed_m_s=self.c_ramp)
        return r

    def echo(self, kind, q):
        tau = q[0] * 1e-3
        phase = np.exp(-1j * self.w * (tau - self.t0)) * self.p0 / (2 * self.c1 * tau)
        if kind == "S0":
            shape = q[1] * np.ones_like(self.fk)
        elif kind == "G0":
            shape = q[1] * np.exp(-q[2] * self.fk ** 2)
        elif kind == "T0":
            shape = q[1] + (1 - q[1] ** 2) * self.ramp(q[2], q[3])
        elif kind == "GT0":   # roughness on the top's reflection; its transmission loss (P_T ~ 0) neglected
            shape = q[1] * np.exp(-q[4] * self.fk ** 2) + (1 - q[1] ** 2) * self.ramp(q[2], q[3])
        elif kind == "D":
            shape = q[1] * 10 ** (-q[2] * self.fk / 20)
        else:  # "DG"
            shape = q[1] * 10 ** (-q[2] * self.fk / 20) * np.exp(-q[3] * self.fk ** 2)
        return shape * phase

    def split(self, kinds, p):
        out, i = [], 0
        for k in kinds:
            out.append(p[i:i + _PARAMS[k]])
            i += _PARAMS[k]
        return out

    def predict(self, kinds, p):
        return sum(self.echo(k, q) for k, q in zip(kinds, self.split(kinds, p)))

    def fit(self, kinds, params_list, bounds, free=None):
        """Fit the echoes in ``free`` (default all), the others held at ``params_list``.

        Returns the flat parameter vector, the chi-square and the covariance
        (``(J^T J)^-1`` of the whitened residuals; NaN rows and columns for
        held echoes).
        """
        free = set(range(len(kinds))) if free is None else set(free)
        held = [self.echo(k, q) for j, (k, q) in enumerate(zip(kinds, params_list)) if j not in free]
        target = self.y - self.x * sum(held, np.zeros(self.f.size, complex))
        order = [j for j in range(len(kinds)) if j in free]
        sub = [kinds[j] for j in order]
        start = np.concatenate([params_list[j] for j in order])
        lower = np.concatenate([bounds[j][0] for j in order])
        upper = np.concatenate([bounds[j][1] for j in order])
        start = np.clip(start, lower + 1e-9 * (upper - lower), upper - 1e-9 * (upper - lower))

        def resid(p):
            r = (target - self.x * self.predict(sub, p)) / self.scale
            return np.concatenate([r.real, r.imag])

        res = least_squares(resid, start, bounds=(lower, upper), x_scale="jac", method="trf",
                            xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=1000)
        cov_free = np.linalg.pinv(res.jac.T @ res.jac)
        sizes = [_PARAMS[k] for k in kinds]
        offsets = np.cumsum([0] + sizes)
        flat = np.concatenate([np.asarray(q, float) for q in params_list])
        cov = np.full((flat.size, flat.size), np.nan)
        index = np.concatenate([np.arange(offsets[j], offsets[j + 1]) for j in order])
        flat[index] = res.x
        cov[np.ix_(index, index)] = cov_free
        return flat, float(2 * res.cost), cov


def _bounds(kind, q, band_s):
    """Lower/upper bounds of one echo's parameters around its start values."""
    tau_lo, tau_hi = q[0] - band_s * 1e3, q[0] + band_s * 1e3
    table = {
        "S0": ([tau_lo, -2.0], [tau_hi, 2.0]),
        "G0": ([tau_lo, -2.0, 0.0], [tau_hi, 2.0, 10.0]),
        "T0": ([tau_lo, -0.99, -2.0, 0.01], [tau_hi, 0.99, 2.0, 200.0]),
        "GT0": ([tau_lo, -0.99, -2.0, 0.01, 0.0], [tau_hi, 0.99, 2.0, 200.0, 10.0]),
        "D": ([tau_lo, -2.0, -100.0], [tau_hi, 2.0, 100.0]),
        "DG": ([tau_lo, -2.0, -100.0, -10.0], [tau_hi, 2.0, 100.0, 10.0]),
    }
    lo, hi = table[kind]
    return np.array(lo, float), np.array(hi, float)


# -- the driver ----------------------------------------------------------------
@dataclass
class _State:
    kinds: list
    params: np.ndarray
    chi2: float
    cov: np.ndarray


class _Inversion:
    """Spectra, noise, detection view and tests of one trace (steps 1–3 of the module docstring)."""

    def __init__(self, yc, chirp, fs, t0_s, p0, c1, c_layers, noise_std, false_alarm, significance):
        n = yc.size
        self.chirp, self.fs, self.t0, self.p0, self.c1 = chirp, fs, t0_s, p0, c1
        self.c_layers = c_layers
        self.c_ramp = float(c_layers[0]) if c_layers else float(c1)
        self.significance = significance
        replica = chirp.replica(fs)
        require(replica.size < n, OptionError, f"trace of {n} samples is shorter than the pulse ({replica.size})")
        energy = float(np.dot(replica, replica))
        freq = scipy.fft.rfftfreq(n, 1.0 / fs)
        x_all = scipy.fft.rfft(replica, n)
        power = np.abs(x_all) ** 2
        fit_bins = power >= 1e-3 * power.max()
        fit_bins[0] = fit_bins[-1] = False
        y_all = np.zeros_like(x_all)
        y_all[fit_bins] = scipy.fft.rfft(yc)[fit_bins] * energy / np.conj(x_all[fit_bins])
        view_bins = power >= 0.1 * power.max()
        idx = np.flatnonzero(view_bins)
        window = np.zeros(freq.size)
        window[idx] = np.blackman(idx.size + 2)[1:-1]
        self.n, self.freq, self.x_all, self.y_all = n, freq, x_all, y_all
        self.fit_bins, self.view_bins, self.window = fit_bins, view_bins, window
        self.exclusion_s = 4.0 / (freq[idx[-1]] - freq[idx[0]])
        self.view_gain = 2 * window.sum() / n          # a unit echo's peak in the view
        self.times_up = t0_s + np.arange(n * _UPSAMPLE) / (fs * _UPSAMPLE)

        first = self._first_echo_s(false_alarm)
        self.noise_dof = None
        if noise_std is None:
            stop = int((first - chirp.duration_s - self.exclusion_s - t0_s) * fs)
            dof = 2.0 * chirp.bandwidth_hz * stop / fs
            if stop < 8 or dof < 20:
                raise OptionError(f"cannot estimate the noise: only {max(stop, 0)} samples precede the first echo "
                                  f"by a pulse length; give noise_std")
            noise_std = float(np.std(yc[:stop]) * math.sqrt(energy))   # var(y_c) = sigma^2 / sum x^2
            self.noise_dof = dof
        require(math.isfinite(noise_std) and noise_std > 0, OptionError, f"noise_std must be > 0, got {noise_std!r}")
        self.noise_std = float(noise_std)
        scale = math.sqrt(n * noise_std ** 2 / 2.0)       # std of Re and Im of a white-noise FFT bin
        self.model = _Model(freq[fit_bins], x_all[fit_bins], y_all[fit_bins], scale, t0_s, p0, c1, self.c_ramp)
        self.n_res = 2 * int(fit_bins.sum())
        view_var = 2 * noise_std ** 2 / n * float(np.sum(window[view_bins] ** 2 / power[view_bins]))
        self.threshold = math.sqrt(2 * view_var * math.log(n / false_alarm))

    def view(self, spec):
        """Deconvolved, Blackman-weighted analytic view of a received-spectrum residual, upsampled."""
        full = np.zeros(self.n * _UPSAMPLE, complex)
        d = np.zeros(self.freq.size, complex)
        d[self.view_bins] = spec[self.view_bins] / self.x_all[self.view_bins] * self.window[self.view_bins]
        full[:self.freq.size] = 2 * d
        return scipy.fft.ifft(full) * _UPSAMPLE

    def _first_echo_s(self, false_alarm):
        """Time of the earliest crossing of a threshold set from the view's median (Rayleigh noise envelope)."""
        env = np.abs(self.view(self.y_all))
        sigma = float(np.median(env)) / math.sqrt(2 * math.log(2.0))
        level = max(sigma * math.sqrt(2 * math.log(env.size / false_alarm)), 1e-9 * float(env.max()))
        above = np.flatnonzero(env >= level)
        if above.size == 0:
            raise UnresolvableError("no echo stands out of the noise in the trace")
        return float(self.times_up[above[0]])

    def adequate(self, state):
        """Chi-square (F with an estimated noise) test that the model explains the data."""
        dof = self.n_res - state.params.size
        if self.noise_dof is None:
            p = stats.chi2.sf(state.chi2, dof)
        else:
            p = stats.f.sf(state.chi2 / dof, dof, self.noise_dof)
        return bool(p > self.significance)

    def needs_extra(self, small, big):
        """Likelihood-ratio test of one extra parameter (``big`` nests ``small``)."""
        delta = max(small.chi2 - big.chi2, 0.0)
        p = stats.chi2.sf(delta, 1) if self.noise_dof is None else stats.f.sf(delta, 1, self.noise_dof)
        return bool(p < self.significance)

    def fit(self, kinds, params_list, free=None):
        """Least-squares fit (echoes in ``free``, default all); returns a :class:`_State`."""
        bounds = [_bounds(k, q, self.exclusion_s / 2) for k, q in zip(kinds, params_list)]
        p, chi2, cov = self.model.fit(kinds, [np.asarray(q, float) for q in params_list], bounds, free)
        return _State(list(kinds), p, chi2, cov)

    def split(self, state):
        return [np.array(q, float) for q in self.model.split(state.kinds, state.params)]

    def detect(self, max_echoes):
        """Echoes one at a time, largest first, each followed by a joint smooth-model fit (step 3)."""
        state = None
        residual = self.y_all.copy()
        while state is None or len(state.kinds) < max_echoes:
            env = self.view(residual)
            mag = np.abs(env)
            plist = [] if state is None else self.split(state)
            for q in plist:
                mag[np.abs(self.times_up - q[0] * 1e-3) < self.exclusion_s] = 0.0
            k = int(np.argmax(mag))
            if mag[k] < self.threshold:
                break
            frac = 0.0
            if 0 < k < mag.size - 1:   # parabolic refinement of the peak
                den = mag[k - 1] - 2 * mag[k] + mag[k + 1]
                frac = 0.5 * (mag[k - 1] - mag[k + 1]) / den if den != 0 else 0.0
            tau = self.times_up[k] + frac / (self.fs * _UPSAMPLE)
            v = float(np.real(env[k])) / self.view_gain * 2 * self.c1 * tau / self.p0
            plist = sorted(plist + [np.array([tau * 1e3, v, 0.0])], key=lambda q: q[0])
            # the earliest echo is the seafloor (no loss slope above it); the others carry one
            plist = [q[:2] if i == 0 else np.array([q[0], q[1], q[2] if q.size == 3 else 0.0])
                     for i, q in enumerate(plist)]
            state = self.fit(["S0"] + ["D"] * (len(plist) - 1), plist)
            residual = self.y_all.copy()
            residual[self.fit_bins] = self.model.y - self.model.x * self.model.predict(state.kinds, state.params)
        if state is None:
            raise UnresolvableError(f"no echo above the detection threshold ({self.threshold:.3g} in the "
                                    f"deconvolved trace): noise only")
        return state

    def seafloor(self, base, transitional_beds):
        """Seafloor reflection model (step 5): state, status, reason and each model's adequacy."""
        base_q = self.split(base)

        def with_seafloor(kind, q0):   # echo 0 refitted alone, then all echoes jointly
            return self.fit([kind] + base.kinds[1:], [np.asarray(q0, float)] + base_q[1:], free={0})

        def refined(state):
            return self.fit(state.kinds, self.split(state))

        verdict = {"smooth": self.adequate(base)}
        tau0, v0 = base_q[0][0], base_q[0][1]
        rough = refined(with_seafloor("G0", [tau0, v0, 0.0]))
        verdict["rough"] = self.adequate(rough)
        if verdict["smooth"] and not self.needs_extra(base, rough):
            return base, "smooth", None, verdict
        best = {}
        if transitional_beds:
            wavelength = self.c_ramp / self.chirp.centre_hz
            for kind in ("T0", "GT0"):
                trials = []
                for dx in (0.08, 0.2, 0.4):
                    for r1 in (0.0, 0.5 * v0):
                        big_l = math.atanh(float(np.clip(v0 - r1, -0.9, 0.9)))
                        # the bed reflects from half-way down: start the top one bed crossing earlier
                        tau_top = tau0 - dx * wavelength / self.c_ramp * 1e3
                        q = [tau_top, r1, big_l, dx * wavelength * 100.0] + ([0.0] if kind == "GT0" else [])
                        trials.append(with_seafloor(kind, q))
                best[kind] = refined(min(trials, key=lambda s: s.chi2))
            verdict["transitional"] = self.adequate(best["T0"])
            verdict["rough+transitional"] = self.adequate(best["GT0"])
        if verdict["rough"] and not verdict.get("transitional", False):
            return rough, "rough", None, verdict
        if not transitional_beds:
            what = ("neither a smooth nor a rough interface explains it within the noise "
                    "(a transitional bed would, but transitional_beds is off)")
        elif verdict["rough"]:
            what = "a rough interface and a transitional bed explain it equally well"
        elif verdict["transitional"] or verdict["rough+transitional"]:
            what = "it needs a transitional bed of intermediate thickness, under which the roughness is not assessable"
        else:
            what = "no smooth, rough or transitional seafloor model explains it within the noise"
        reason = (f"echo 0 at {tau0:.3f} ms: the seafloor reflection changes with frequency and {what}: "
                  f"roughness and reflection loss are not resolvable (Rakotonarivo §5)")
        candidates = [rough] + list(best.values())
        adequate = [c for c in candidates if self.adequate(c)]
        return min(adequate or candidates, key=lambda s: s.chi2), "unresolvable", reason, verdict

    def deeper(self, seafloor):
        """Joint refit and the echoes whose spectrum is not linear in dB (step 6)."""
        n_echo = len(seafloor.kinds)
        size0 = _PARAMS[seafloor.kinds[0]]
        # a seafloor read with a transitional bed is held: its parameters are not reported
        hold = seafloor.kinds[0] in ("T0", "GT0")
        free = set(range(1, n_echo)) if hold else None
        final = self.fit(seafloor.kinds, self.split(seafloor), free)
        if hold:
            final.cov[:size0, :size0] = seafloor.cov[:size0, :size0]
        qs = self.split(final)
        flagged = set()
        for i in range(1, n_echo):
            kinds = list(final.kinds)
            kinds[i] = "DG"
            trial = [q if j != i else np.concatenate([q, [0.0]]) for j, q in enumerate(qs)]
            if self.needs_extra(final, self.fit(kinds, trial, free={i})):
                flagged.add(i)
        if flagged:   # refit with the f^2 term on them: their f -> 0 amplitudes then serve the stripping
            kinds = ["DG" if i in flagged else k for i, k in enumerate(final.kinds)]
            trial = [np.concatenate([q, [0.0]]) if i in flagged else q for i, q in enumerate(qs)]
            cov0 = final.cov[:size0, :size0].copy()
            final = self.fit(kinds, trial, free)
            if hold:
                final.cov[:size0, :size0] = cov0
        return final, flagged

    def estimates(self, final, status0, reason0, band_v0, flagged):
        """Echo and layer estimates by layer stripping (step 7)."""
        qs = self.split(final)
        offsets = np.cumsum([0] + [_PARAMS[k] for k in final.kinds])
        cov = final.cov
        std = np.sqrt(np.clip(np.diag(cov), 0, None))
        echoes, stripping, note = [], 1.0, None
        for i, q in enumerate(qs):
            o = offsets[i]
            tau, tau_std = q[0] * 1e-3, std[o] * 1e-3
            if i == 0 and status0 == "unresolvable":
                echoes.append(EchoEstimate(0, tau, tau_std, None, None, status0, reason=reason0))
                stripping *= 1 - band_v0 ** 2
                note = ("approximate: the transmission through the seafloor uses its band-average reflection "
                        "(a transitional bed transmits almost fully)")
            elif i == 0:
                refl, refl_std = float(q[1]), float(std[o + 1])
                sig = sig_std = None
                if status0 == "rough":   # exp(-P^2/2) = exp(-g f^2): sigma = sqrt(g/2) c1 / (2 pi 1000)
                    gamma, gamma_std = float(q[2]), float(std[o + 2])
                    sig = math.sqrt(gamma / 2.0) * self.c1 / (2 * math.pi * 1000.0)
                    sig_std = sig * gamma_std / (2 * gamma) if gamma > 0 else math.inf
                echoes.append(EchoEstimate(0, tau, tau_std, refl, refl_std, status0, sig,
                                           None if sig is None else 0.75 * sig, sig_std,
                                           None if sig is None else 0.75 * sig_std))
                stripping *= 1 - refl ** 2
            elif i in flagged:
                echoes.append(EchoEstimate(i, tau, tau_std, None, None, "frequency-dependent",
                                           reason=(f"echo {i} at {q[0]:.3f} ms: its spectrum is not linear in dB "
                                                   f"(rough or graded interface): its reflection and the "
                                                   f"attenuation above it are not separable")))
                stripping *= 1 - float(q[1] / stripping) ** 2
                note = (f"approximate: the transmission through interface {i} uses the low-frequency limit of its "
                        f"frequency-dependent reflection")
            else:
                refl = float(q[1] / stripping)
                echoes.append(EchoEstimate(i, tau, tau_std, refl, float(std[o + 1] / stripping), "smooth", note=note))
                stripping *= 1 - refl ** 2

        layers = []
        for i in range(len(qs) - 1):
            oa, ob = offsets[i], offsets[i + 1]
            dt = (qs[i + 1][0] - qs[i][0]) * 1e-3
            dt_std = math.sqrt(max(cov[oa, oa] + cov[ob, ob] - 2 * cov[oa, ob], 0.0)) * 1e-3
            c = float(self.c_layers[i]) if i < len(self.c_layers) else float(self.c1)
            bad = sorted({i, i + 1} & flagged)
            if bad:
                layers.append(LayerEstimate(i + 1, dt, dt_std, c, c * dt / 2, None, None, None, None,
                                            reason=f"layer {i + 1}: attenuation not separable from the "
                                                   f"frequency-dependent reflection of echo {bad[0]}"))
                continue
            # two-way loss slope across the layer: s_{i+1} - s_i, the seafloor's s being 0
            s_b, var_b = qs[i + 1][2], cov[ob + 2, ob + 2]
            s_a, var_a, cov_ab = (0.0, 0.0, 0.0) if i == 0 else (qs[i][2], cov[oa + 2, oa + 2], cov[oa + 2, ob + 2])
            slope = float(s_b - s_a)
            slope_std = math.sqrt(max(var_a + var_b - 2 * cov_ab, 0.0))
            layers.append(LayerEstimate(i + 1, dt, dt_std, c, c * dt / 2, slope, slope_std,
                                        slope / (c * dt), slope_std / (c * dt)))
        return tuple(echoes), tuple(layers)


# 70 lines for its 13 documented parameters; the body is 20 lines of checks and the steps of _Inversion
def invert_trace(compressed, chirp: Chirp, *, sample_rate_hz: float, t0_s: float = 0.0, p0: float = 1.0,
                 water_sound_speed_m_s: float = 1500.0, layer_sound_speeds_m_s=None,
                 noise_std: float | None = None, max_echoes: int = 8, false_alarm: float = 1e-4,
                 significance: float = 1e-3, transitional_beds: bool = True) -> InversionResult:
    """Two-way times, reflection coefficients and attenuation slopes from a compressed trace.

    Parameters
    ----------
    compressed : array_like
        Compressed nadir trace ``y_c`` (real, or the analytic trace whose real
        part it is), the circular compression of the received record with
        the emitted pulse normalised by its energy
        (:func:`.trace.compress_circular`, Fig. 8), ``N`` samples.
    chirp : Chirp
        The emission.
    sample_rate_hz : float
        Sample rate (Hz).
    t0_s : float
        Time of sample 0 after the start of transmission (s).
    p0 : float
        Source amplitude of eq. 15 (Pa m): the reflection coefficients are
        absolute through ``p0 / (2 c1 tau)``.
    water_sound_speed_m_s : float
        ``c1`` (m/s).
    layer_sound_speeds_m_s : sequence of float, optional
        Speeds of the layers below the seafloor, top first, to turn two-way
        times into thicknesses and attenuation per metre; default: the water
        speed (the paper's assumption, §3.1).  The first one is also the
        speed assumed in a transitional bed at the seafloor.
    noise_std : float, optional
        Noise standard deviation of the received trace (Pa); default:
        estimated from the compressed trace before the first echo.
    max_echoes : int
        Most echoes looked for.
    false_alarm : float
        Probability that noise alone crosses the detection threshold
        anywhere in the record.
    significance : float
        Level of the chi-square tests (model adequacy, extra terms).
    transitional_beds : bool
        Whether the seafloor may carry a transitional bed.  A rough
        interface and a bed of intermediate thickness both lower the
        reflection smoothly with frequency; with ``True`` (the default) a
        seafloor that both explain is unresolvable.  ``False``, when cores
        or the geology exclude a graded bed, reads such a seafloor as rough
        and gives its reflection coefficient and ``sigma``.

    Returns
    -------
    InversionResult
    """
    yc = np.real(np.asarray(compressed)).astype(float)
    require(yc.ndim == 1 and yc.size >= 16, OptionError,
            f"compressed trace must be 1-D with at least 16 samples, got shape {yc.shape}")
    require(bool(np.all(np.isfinite(yc))), OptionError, "compressed trace has non-finite samples")
    require(math.isfinite(sample_rate_hz) and sample_rate_hz > 2 * chirp.f1_hz, OptionError,
            f"sample_rate_hz must exceed twice the chirp's top frequency, got {sample_rate_hz!r}")
    require(0 < false_alarm < 1 and 0 < significance < 1, OptionError,
            f"false_alarm and significance must lie in (0, 1), got {false_alarm!r} and {significance!r}")
    require(int(max_echoes) == max_echoes and max_echoes >= 1, OptionError,
            f"max_echoes must be a positive integer, got {max_echoes!r}")
    require(math.isfinite(p0) and p0 != 0, OptionError, f"p0 must be finite and non-zero, got {p0!r}")
    job = _Inversion(yc, chirp, float(sample_rate_hz), float(t0_s), float(p0), float(water_sound_speed_m_s),
                     [float(c) for c in (layer_sound_speeds_m_s or [])], noise_std, false_alarm, significance)
    base = job.detect(int(max_echoes))
    seafloor, status0, reason0, verdict = job.seafloor(base, transitional_beds)
    final, flagged = job.deeper(seafloor)
    echoes, layers = job.estimates(final, status0, reason0, float(job.split(base)[0][1]), flagged)
    reduced = final.chi2 / (job.n_res - final.params.size)
    return InversionResult(echoes, layers, job.noise_std, job.noise_dof, float(reduced), verdict)
