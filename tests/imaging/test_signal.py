"""Pulse compression, analytic signal, replica and upsampling against scipy."""

import numpy as np
import pytest
import scipy.fft
import scipy.signal

from clbeam.errors import OptionError
from clbeam.imaging.signal import compress_analytic, upsample_analytic
from clbeam.model.pulse import lfm_replica

FS = 40000.0


def test_lfm_replica_sweeps_from_f0_to_f1():
    r = lfm_replica(f0_hz=2000, f1_hz=9000, duration_s=0.08, sample_rate_hz=FS)
    assert r.size == 3200
    # instantaneous frequency from the unwrapped phase of the analytic signal
    phase = np.unwrap(np.angle(scipy.signal.hilbert(r)))
    f_inst = np.diff(phase) * FS / (2 * np.pi)
    mid = slice(200, -200)  # Hilbert edge effects
    t = (np.arange(r.size - 1) + 0.5) / FS
    expected = 2000 + (9000 - 2000) * t / 0.08
    assert np.max(np.abs(f_inst[mid] - expected[mid])) < 50  # Hz; ripple of the edge-free part


def test_compression_equals_scipy_correlate_then_hilbert():
    rng = np.random.default_rng(3)
    rep = lfm_replica(f0_hz=2000, f1_hz=9000, duration_s=0.01, sample_rate_hz=FS)
    n, m = 2000, rep.size
    x = rng.standard_normal((3, n))
    y = compress_analytic(x, rep)
    nfft = scipy.fft.next_fast_len(n + m - 1)
    for ch in range(3):
        lags = scipy.signal.correlate(x[ch], rep, mode="full") / np.dot(rep, rep)  # lags -(m-1) .. n-1
        # the same correlation laid out circularly on nfft points, then scipy's Hilbert
        circ = np.zeros(nfft)
        circ[:n] = lags[m - 1:]
        circ[nfft - (m - 1):] = lags[:m - 1]
        expected = scipy.signal.hilbert(circ)[:n]
        np.testing.assert_allclose(y[ch], expected, rtol=0, atol=1e-10 * np.abs(expected).max())


@pytest.mark.parametrize("n", [2000, 1626])        # transforms of 2400 and 2025 points
@pytest.mark.parametrize("factor", [2, 3, 4])
def test_compression_with_upsampling_is_the_fourier_resampled_correlation(n, factor):
    """One inverse transform for compression and upsampling: scipy's Fourier resampling of the analytic
    circular correlation (the Nyquist bin split between both ends), even and odd transform lengths."""
    rng = np.random.default_rng(4)
    rep = lfm_replica(f0_hz=2000, f1_hz=9000, duration_s=0.01, sample_rate_hz=FS)
    m = rep.size
    x = rng.standard_normal((2, n))
    y = compress_analytic(x, rep, upsample=factor)
    assert y.shape == (2, factor * n)
    nfft = scipy.fft.next_fast_len(n + m - 1)
    assert nfft % 2 == (n == 1626)
    for ch in range(2):
        lags = scipy.signal.correlate(x[ch], rep, mode="full") / np.dot(rep, rep)
        circ = np.zeros(nfft)
        circ[:n] = lags[m - 1:]
        circ[nfft - (m - 1):] = lags[:m - 1]
        expected = scipy.signal.resample(scipy.signal.hilbert(circ), factor * nfft)[:factor * n]
        np.testing.assert_allclose(y[ch], expected, rtol=0, atol=1e-10 * np.abs(expected).max())


def test_upsampled_compression_marks_the_samples_beside_corrupted_outputs():
    rep = np.ones(5)
    x = np.arange(40.0)
    x[20] = np.nan
    y = compress_analytic(x, rep, upsample=2)
    # y[k] (input rate) touched the NaN for k = 16..20: the upsampled samples 31..41 lie beside them
    assert np.flatnonzero(np.isnan(y)).tolist() == list(range(31, 42))


def test_compressed_echo_peaks_at_arrival_with_its_amplitude():
    rep = lfm_replica(f0_hz=2000, f1_hz=9000, duration_s=0.02, sample_rate_hz=FS)
    x = np.zeros(4000)
    k0, a = 1234, 0.7
    x[k0:k0 + rep.size] = a * rep
    y = compress_analytic(x, rep)
    assert int(np.argmax(np.abs(y))) == k0
    assert y[k0].real == pytest.approx(a, rel=1e-9)


def test_non_finite_input_marks_exactly_the_corrupted_outputs():
    rep = np.ones(5)
    x = np.arange(40.0)
    x[20] = np.nan
    y = compress_analytic(x, rep)
    # y[k] uses x[k..k+4]: k = 16..20 touched the NaN
    assert np.flatnonzero(np.isnan(y)).tolist() == [16, 17, 18, 19, 20]
    assert np.isfinite(y[:16]).all() and np.isfinite(y[21:]).all()


def test_upsampling_is_exact_for_a_bandlimited_periodic_signal():
    n, factor = 256, 4
    k = np.arange(n)
    f = 17 / n  # an exact DFT bin: the periodic interpolant is the signal itself
    x = np.exp(2j * np.pi * f * k)
    up = upsample_analytic(x, factor)
    t = np.arange(n * factor) / factor
    np.testing.assert_allclose(up, np.exp(2j * np.pi * f * t), atol=1e-12)


def test_complex64_upsampling_is_complex128_to_float32_rounding():
    """A float32 engine's channels upsample in complex64: within 1e-6 of complex128 (relative to the
    record's largest sample) over a band-limited record, complex64 out, and a NaN sample's neighbours NaN."""
    rng = np.random.default_rng(5)
    spec = np.zeros((3, 4096), dtype=np.complex128)
    spec[:, 200:900] = rng.standard_normal((3, 700)) + 1j * rng.standard_normal((3, 700))
    x = np.fft.ifft(spec, axis=-1)
    exact = upsample_analytic(x, 2)
    x32 = x.astype(np.complex64)
    x32[1, 100] = np.nan
    got = upsample_analytic(x32, 2)
    assert got.dtype == np.complex64
    assert np.isnan(got[1, 199:202]).all() and np.isfinite(got[0]).all()
    np.testing.assert_array_less(np.abs(got[0] - exact[0]).max(), 1e-6 * np.abs(exact[0]).max())


def test_replica_rejects_a_band_above_nyquist():
    with pytest.raises(OptionError, match="Nyquist"):
        lfm_replica(f0_hz=2000, f1_hz=25000, duration_s=0.01, sample_rate_hz=FS)


def test_float32_compression_is_float64_to_float32_rounding():
    """The float32 FFTs of a float32 engine's compression: within 1e-6 of float64 (relative,
    over the record), complex64 out; magnitudes float32 sums cannot hold stay in float64."""
    from clbeam.imaging.imager import compression_precision

    rng = np.random.default_rng(2)
    x = rng.standard_normal((4, 5000))
    replica = np.sin(2 * np.pi * np.linspace(0, 40, 400)) * np.hanning(400)
    y64, y32 = compress_analytic(x, replica), compress_analytic(x, replica, precision="float32")
    assert y32.dtype == np.complex64 and y64.dtype == np.complex128
    assert np.linalg.norm(y32 - y64) / np.linalg.norm(y64) < 1e-6
    assert compression_precision(x, "float32") == "float32"
    assert compression_precision(x * 1e30, "float32") == compression_precision(x * 1e-30, "float32") == "float64"
    assert compression_precision(x, "float64") == "float64"
