"""Filters, spectra, FRF estimation and modal fits against closed forms."""
import numpy as np
import pytest
import scipy.signal

from calibration.identification.fdd import FDDSettings, segment_csd
from calibration.identification.frf import fit_poles, h1
from calibration.signals.filters import bandpass, butter_sos, highpass

FS = 500.0


def test_bandpass_keeps_an_in_band_sine_unshifted_and_kills_sleeper_frequencies():
    # 200 s: the 0.25 Hz section rings for ~2.4 s per e-fold after the abrupt start
    t = np.arange(0, 200, 1 / FS)
    inside = np.sin(2 * np.pi * 5.0 * t + 0.3)
    y = bandpass(inside + np.sin(2 * np.pi * 57.0 * t), FS)
    mid = slice(len(t) // 4, 3 * len(t) // 4)
    np.testing.assert_allclose(y[mid], inside[mid], atol=2e-3)  # zero phase, unit gain in band
    # forwards and backwards: the gain at the sleeper frequency is |H|^2 of the designed filter
    out = bandpass(np.sin(2 * np.pi * 57.0 * t), FS)
    _, h = scipy.signal.sosfreqz(butter_sos(6, (0.25, 25.0), "bandpass", FS), worN=[57.0], fs=FS)
    assert np.abs(out[mid]).max() == pytest.approx(np.abs(h[0]) ** 2, rel=0.01)
    assert np.abs(h[0]) ** 2 < 2e-3  # below -54 dB


def test_highpass_removes_offset_and_drift_of_the_gyro():
    t = np.arange(0, 200, 1 / FS)
    signal = 0.01 * np.sin(2 * np.pi * 4.0 * t)
    y = highpass(0.4 + 0.002 * t + signal, FS)
    mid = slice(len(t) // 4, 3 * len(t) // 4)
    assert np.abs(y[mid] - signal[mid]).max() < 1e-4


def test_filter_design_refuses_cutoffs_outside_nyquist():
    with pytest.raises(ValueError, match="inside"):
        butter_sos(6, 300.0, "lowpass", FS)


def test_psd_of_a_sine_integrates_to_half_its_squared_amplitude():
    fs, A = 100.0, 0.7
    t = np.arange(0, 200, 1 / fs)
    f, G = segment_csd(A * np.sin(2 * np.pi * 3.3 * t)[None, :], fs, FDDSettings())
    power = np.real(G[:, 0, 0]).sum() * (f[1] - f[0])
    assert power == pytest.approx(A**2 / 2, rel=1e-3)


def test_two_input_h1_recovers_known_filters():
    rng = np.random.default_rng(0)
    fs, n = 100.0, 200_000
    u = rng.normal(size=(2, n))
    b1, a1 = scipy.signal.butter(2, 10.0, fs=fs)
    b2 = [0.5, -0.25]
    y = scipy.signal.lfilter(b1, a1, u[0]) + scipy.signal.lfilter(b2, [1.0], u[1])
    f, G = segment_csd(np.vstack([u, y]), fs, FDDSettings(welch_s=10.24, nfft_factor=1))
    H, coh = h1(G, [2], [0, 1])
    _, H1 = scipy.signal.freqz(b1, a1, worN=f, fs=fs)
    _, H2 = scipy.signal.freqz(b2, [1.0], worN=f, fs=fs)
    sel = (f > 0.5) & (f < 30)
    assert np.abs(H[sel, 0, 0] - H1[sel]).max() < 0.02
    assert np.abs(H[sel, 0, 1] - H2[sel]).max() < 0.02
    assert coh[sel, 0].min() > 0.99


@pytest.mark.parametrize("fn, zeta", [(0.9, 0.07), (7.2, 0.17)])
def test_rational_fit_returns_the_poles_of_a_base_excited_oscillator(fn, zeta):
    # acceleration transmissibility of a mass on a spring-damper over a moving base
    f = np.linspace(0.05, 25, 4000)
    wn, s = 2 * np.pi * fn, 1j * 2 * np.pi * f
    H = (2 * zeta * wn * s + wn**2) / (s**2 + 2 * zeta * wn * s + wn**2)
    (pole,) = fit_poles(f, H, (fn / 3, fn * 3), 1)
    assert pole.frequency_hz == pytest.approx(fn, rel=1e-9)
    assert pole.damping_ratio == pytest.approx(zeta, rel=1e-9)
    assert pole.damped_frequency_hz == pytest.approx(fn * np.sqrt(1 - zeta**2), rel=1e-9)


def test_band_slices_are_not_halved_like_dc_and_nyquist():
    from calibration.identification.fdd import csd_from_frames, welch_frames

    x = np.random.default_rng(2).normal(size=(2, 20_000))
    X, f, scale = welch_frames(x, 100.0, FDDSettings())
    full = csd_from_frames(X, scale)
    inner = csd_from_frames(X[:, :, 5:-5], scale, full_spectrum=False)
    np.testing.assert_allclose(inner, full[5:-5])


def test_jittered_samples_are_put_on_a_uniform_grid_within_the_spline_error_bound():
    """A 25 Hz sine (the top of the analysis band) sampled at 500 Hz with +-0.45 sample
    jitter, re-sampled uniformly by the cubic spline: within 0.1 % of its amplitude."""
    from calibration.signals.resample import is_regular, to_uniform_grid

    fs, f = 500.0, 25.0
    rng = np.random.default_rng(5)
    t = np.arange(5000) / fs + rng.uniform(-0.45, 0.45, 5000) / fs
    assert not is_regular(t, fs)
    tu, xu = to_uniform_grid(t, np.sin(2 * np.pi * f * t), fs)
    assert is_regular(tu, fs) and tu[0] == t[0] and tu[-1] <= t[-1]
    assert np.max(np.abs(xu - np.sin(2 * np.pi * f * tu))[5:-5]) < 1e-3


def test_regular_run_keeps_gaps_and_invalid_samples():
    """Re-sampling never bridges a gap and never turns a missing sample into a valid one."""
    from calibration.data.campaign import Gap, Run
    from calibration.signals.resample import regular_run

    fs = 100.0
    rng = np.random.default_rng(2)
    t = np.concatenate([np.arange(1000), 1100 + np.arange(1000)]) / fs + rng.uniform(-0.3, 0.3, 2000) / fs
    x = np.sin(2 * np.pi * 2.0 * t)
    x[500] = np.nan
    run = Run("r", None, t, {"a": x}, {"a": np.isfinite(x)}, ((0, 1000), (1000, 2000)), (Gap(t[999], t[1000]),),
              distance=30.0 * t, speed=np.full(t.size, 30.0))
    reg = regular_run(run, fs)
    assert len(reg.blocks) == 2 and reg.gaps == run.gaps
    first, second = (reg.time[a:b] for a, b in reg.blocks)
    assert first[-1] <= t[999] and second[0] == t[1000]  # nothing invented inside the gap
    bad = ~reg.valid["a"]
    assert bad.any() and np.all(np.abs(reg.time[bad] - t[500]) < 4 / fs)
    ok = reg.valid["a"]
    np.testing.assert_allclose(reg.channels["a"][ok], np.sin(2 * np.pi * 2.0 * reg.time[ok]), atol=1e-4)
    assert np.all(np.diff(reg.distance) > 0)
