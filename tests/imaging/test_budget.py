"""The measured error budget: the calibration wavelet, its exact sums, and the choice of the setting."""

from __future__ import annotations

import numpy as np
import pytest
from scenes import point_ping, polar_point
from scipy.integrate import quad

from clbeam.errors import OptionError
from clbeam.imaging.budget import Budget, CalibrationScene, PulseWavelet, choose_measured_setting, with_margins
from clbeam.imaging.engine import get_engine
from clbeam.imaging.engine.errormodel import predicted_settings
from clbeam.imaging.imager import Imager, ImagingOptions
from clbeam.model.grid import PolarGrid

BAND = (2000.0, 9000.0)
GRID = PolarGrid.regular(range_res_m=0.2, angle_res_deg=0.2, max_range_m=120.0, angles_deg=(-50, 50))


FS = 40000.0
N_BINS = 1 << 14


def test_flat_wavelet_is_the_band_integral_of_the_carrier():
    """psi(t) = 1/(f1 - f0) * integral over the band of exp(i 2 pi f t) df, by quadrature; the wavelet is its
    sum over bins fs / n apart, within the Riemann sum's error of about two bins over the band."""
    psi = PulseWavelet.flat(BAND, FS, N_BINS)
    tol = 2 * (FS / N_BINS) / (BAND[1] - BAND[0])
    for t in (0.0, 1e-6, 3.3e-5, -2.1e-4, 1.7e-3):
        re = quad(lambda f, t=t: np.cos(2 * np.pi * f * t), *BAND, limit=400)[0]
        im = quad(lambda f, t=t: np.sin(2 * np.pi * f * t), *BAND, limit=400)[0]
        want = (re + 1j * im) / (BAND[1] - BAND[0])
        assert abs(psi(np.array([t]))[0] - want) < tol, t


def test_pulse_wavelet_is_the_replicas_normalised_autocorrelation():
    """Its real part at whole lags is the replica's autocorrelation over its energy (numpy.correlate)."""
    from clbeam.model.pulse import Pulse

    replica = Pulse(f0_hz=2000.0, f1_hz=9000.0, duration_s=0.01).replica(FS)
    acf = np.correlate(replica, replica, mode="full")[replica.size - 1:] / np.dot(replica, replica)
    psi = PulseWavelet.of_replica(replica, FS, N_BINS)
    lags = np.arange(60)
    np.testing.assert_allclose(psi(lags / FS).real, acf[:60], atol=1e-9)


def test_pulse_wavelet_records_and_evaluation_agree():
    """The phase-ramp records and the table's windowed sinc are the same band-limited function (-100 dB)."""
    from clbeam.model.pulse import Pulse

    psi = PulseWavelet.of_replica(Pulse(f0_hz=2000.0, f1_hz=9000.0, duration_s=0.01).replica(FS), FS, N_BINS)
    delays = np.array([0.0123456, 0.0201357])
    rec = psi.samples(0.01, 800, delays)
    t = 0.01 + np.arange(800) / FS
    np.testing.assert_allclose(rec, psi(t[None, :] - delays[:, None]), atol=1e-5)  # -100 dB of psi(0) = 1


def _input(**ping_args):
    ping = point_ping(polar_point(60.0, 10.0), record_s=0.2, kind="analytic", **ping_args)
    return Imager(GRID, ImagingOptions(interp="lanczos4", beams=None)).beamform_input(ping)


def test_exact_sums_of_a_flat_band_equal_the_reference_windowed_sinc_of_the_calibration_records():
    """The calibration's sums against the float64 reference's 64-tap interpolation of the same records
    (flat-band echoes, which that interpolator resolves): within -80 dB of the peak, far below the -40 to
    -70 dB the budget measures."""
    inp = _input(roll_deg=4.0, heave_m=0.3, source_m=(0.0, 0.3, 0.2))
    scene = CalibrationScene(inp, GRID, BAND)
    ref = get_engine("reference")
    for cin, window, exact in list(zip(scene.inputs, scene.windows, scene.exact))[::3]:
        got = ref.beamform(cin, window, interp="exact", outputs=("intensity", "cf"))
        np.testing.assert_allclose(got.intensity, exact["intensity"], rtol=0, atol=1e-4 * exact["intensity"].max())
        np.testing.assert_allclose(got.cf, exact["cf"], rtol=0, atol=1e-4)


def test_exact_sums_of_the_pulse_equal_a_direct_fourier_sum():
    """With the replica's compressed pulse (energy up to Nyquist, which a 64-tap interpolator attenuates) the
    sums at cells against the wavelet summed bin by bin at each channel's delay: within 1e-5."""
    from clbeam.model.pulse import Pulse

    inp = _input(roll_deg=4.0, heave_m=0.3, source_m=(0.0, 0.3, 0.2))
    scene = CalibrationScene(inp, GRID, BAND, Pulse(f0_hz=2000.0, f1_hz=9000.0, duration_s=0.02).replica(FS))
    psi = scene.wavelet
    k = np.arange(psi.n // 2)
    rng = np.random.default_rng(4)
    for point, window, exact in list(zip(scene.points, scene.windows, scene.exact))[::4]:
        for ia, ir in zip(rng.integers(0, window.shape[0], 6), rng.integers(0, window.shape[1], 6)):
            th = np.deg2rad(window.angles_deg[ia])
            cell = window.ranges_m[ir] * np.array([np.sin(th), np.cos(th)])
            tau = CalibrationScene.straight_delays(inp, cell) - CalibrationScene.straight_delays(inp, point)
            p = np.exp(2j * np.pi * np.outer(tau, k * FS / psi.n)) @ psi.spectrum[: psi.n // 2] / psi.n
            s, q = p.sum(), np.sum(np.abs(p) ** 2)
            assert abs(abs(s) ** 2 - exact["intensity"][ia, ir]) <= 1e-5 * exact["intensity"].max()
            assert abs(abs(s) ** 2 / (len(p) * q) - exact["cf"][ia, ir]) <= 1e-5


def test_the_chosen_setting_is_the_cheapest_measured_within_the_margins():
    inp = _input(roll_deg=-3.0, source_m=(0.0, 0.35, 0.4))
    engine = get_engine("opencl")
    across = np.linalg.norm(inp.element_offsets_m[:, 1:], axis=1)
    settings = predicted_settings(across, BAND, inp.sample_rate_hz, 1500.0, n_angles=GRID.shape[0],
                                  n_ranges=GRID.shape[1], angle_span_rad=np.deg2rad(100.0), n_samples=inp.n_samples)
    budget = Budget()
    candidates = [s for s in settings if s.error_db <= budget.max_error_db]
    scene = CalibrationScene(inp, GRID, BAND)
    chosen, measured = choose_measured_setting(candidates, scene, engine, budget)
    assert measured.meets(with_margins(budget))
    again = scene.measure(engine, chosen.interp, chosen.beams, chosen.upsample)
    assert again == measured
    for cheaper in (s for s in candidates if (s.cost, s.error_db) < (chosen.cost, chosen.error_db)):
        assert not scene.measure(engine, cheaper.interp, cheaper.beams, cheaper.upsample).meets(with_margins(budget))


def test_a_tighter_cf_budget_never_picks_a_less_accurate_setting(caplog):
    ping = point_ping(polar_point(60.0, 10.0), record_s=0.2, kind="analytic", roll_deg=2.0)
    loose = Imager(GRID, ImagingOptions(max_cf_error=0.05)).setting_of(ping)
    with caplog.at_level("WARNING", logger="clbeam.imaging.budget"):
        tight = Imager(GRID, ImagingOptions(max_cf_error=0.003)).setting_of(ping)
    assert "measured" in loose.describe() and "measured" in tight.describe()
    assert tight.cost >= loose.cost
    measured_cf = float(tight.measured.split("|dCF| ")[1].split(",")[0])
    # within the tight budget's margin, or the most accurate setting measured and a warning that none held it
    assert measured_cf <= 0.003 / 1.25 or "no setting holds the budget" in caplog.text, (tight.describe(), caplog.text)


def test_cf_budget_option_is_checked_in_one_line(tmp_path, capsys):
    from clbeam import cli

    with pytest.raises(OptionError, match="CF error budget"):
        ImagingOptions(max_cf_error=0.0)
    rc = cli.main(["image", str(tmp_path / "none.nc"), "-o", str(tmp_path / "o.nc"), "--max-cf-error", "2"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "CF error budget" in err[0], err


def test_image_file_records_both_budgets_and_the_measured_setting(tmp_path):
    import xarray as xr
    from scenes import ping_dataset

    from clbeam import cli

    ping = point_ping(polar_point(60.0, 10.0), record_s=0.2, roll_deg=2.0)
    ping_dataset(ping).to_netcdf(tmp_path / "p.nc")
    assert cli.main(["image", str(tmp_path / "p.nc"), "-o", str(tmp_path / "i.nc"), "--max-range", "100",
                     "--angles", "-40", "40", "--max-cf-error", "0.03", "-q"]) == 0
    with xr.open_dataset(tmp_path / "i.nc") as ds:
        assert ds.attrs["max_cf_error"] == 0.03 and ds.attrs["max_error_db"] == -40.0
        setting = ds.attrs["imaging_setting"]
    measured_cf = float(setting.split("|dCF| ")[1].split(",")[0])
    assert measured_cf <= 0.03 / 1.5, setting
