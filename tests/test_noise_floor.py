"""Channels' noise floors against the white noise of known density that made them.

A white noise of standard deviation sigma sampled at fs has the one-sided PSD 2 sigma^2 / fs
[unit^2/Hz] at every frequency: the floor each estimate must return, whatever else the
channel holds in a few lines or in the part coherent with the force."""
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.signal

from calibration.signals.noise_floor import (NON_COHERENT, SPECTRAL_FLOOR, NoiseFloor, NoiseFloorSettings, WelchSums,
                                             non_coherent_floor, spectral_floor)

FS = 500.0  # [Hz]
BAND = (25.0, 175.0)  # [Hz] above the modes, below 0.35 fs


def _density(sigma: float, fs: float = FS) -> float:
    return 2 * sigma ** 2 / fs


def _run(seconds: float, sigmas: dict, seed: int, *, tones=((60.0, 0.5), (77.64, 0.2)), gap_at=None, nan_at=None):
    """A run-like record: each channel white noise of its sigma [m/s^2] plus sinusoids
    (frequency [Hz], amplitude [m/s^2]) and a slow swell below the band; a gap (two blocks)
    and a NaN burst marked invalid where asked."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * FS)) / FS
    channels, valid = {}, {}
    for name, sigma in sigmas.items():
        x = sigma * rng.standard_normal(t.size) + 0.3 * np.sin(2 * np.pi * 1.1 * t)
        x += sum(a * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi)) for f, a in tones)
        ok = np.ones(t.size, bool)
        if nan_at is not None:
            x[nan_at:nan_at + 100] = np.nan
            ok[nan_at:nan_at + 100] = False
        channels[name], valid[name] = x, ok
    blocks = ((0, t.size),) if gap_at is None else ((0, gap_at), (gap_at, t.size))
    return SimpleNamespace(channels=channels, valid=valid, blocks=blocks, time=t)


def test_white_noise_plus_tones_gives_its_density_and_twice_the_noise_twice_the_floor():
    sums = WelchSums(("quiet", "loud"), FS, int(2 * FS))
    for k in range(3):  # runs with a gap and a NaN burst: no segment spans either
        sums.add_run(_run(200.0, {"quiet": 0.01, "loud": 0.02}, seed=k, gap_at=30_000, nan_at=70_000))
    quiet, loud = sums.floors({"quiet": "m/s^2", "loud": "m/s^2"}, BAND, 10.0)
    assert quiet.psd == pytest.approx(_density(0.01), rel=0.05)  # sigma 0.01 m/s^2: 4e-7 (m/s^2)^2/Hz
    assert quiet.asd == pytest.approx(np.sqrt(_density(0.01)), rel=0.025)
    assert loud.asd / quiet.asd == pytest.approx(2.0, rel=0.05)
    assert quiet.rms_in_band == pytest.approx(np.sqrt(_density(0.01) * (BAND[1] - BAND[0])), rel=0.025)
    assert quiet.method == SPECTRAL_FLOOR and quiet.unit == "m/s^2" and quiet.band_hz == BAND
    # 3 runs x 200 s less the NaN burst's and the gap's broken segments, in 2 s segments overlapping by half
    assert 3 * 195 < quiet.segments < 3 * 200


def test_the_floor_needs_no_long_average_few_segments_give_the_density_on_average():
    """Over 4 segments a white PSD's lines scatter as chi^2_8 / 8, whose 10th percentile is
    0.43 of the mean: the estimate corrects for it, so the mean over many short records is
    the density."""
    rng = np.random.default_rng(5)
    estimates = []
    for _ in range(40):
        x = 0.01 * rng.standard_normal(int(5 * FS))  # 5 s: 4 segments of 2 s overlapping by half
        f, p = scipy.signal.welch(x, fs=FS, nperseg=int(2 * FS))
        estimates.append(float(spectral_floor(f, p, BAND, 4, 10.0)))
    assert np.mean(estimates) == pytest.approx(_density(0.01), rel=0.06)


def _shaker(seconds: float, noise: float, seed: int, fs: float = 200.0):
    """Band-random force [N] through two modes (8 and 13 Hz, 2 % damped) to three
    accelerometers [m/s^2], each with white noise of ``noise`` x (1, 2, 1) standard deviation."""
    rng = np.random.default_rng(seed)
    n = int(seconds * fs)
    force = 100 * scipy.signal.sosfilt(scipy.signal.butter(4, (4, 40), "bandpass", fs=fs, output="sos"),
                                       rng.standard_normal(n))
    y = np.zeros((n, 3))
    for fn, shape in ((8.0, (1.0, -0.5, 0.3)), (13.0, (0.4, 1.0, -0.8))):
        b, a = scipy.signal.iirpeak(fn, Q=25, fs=fs)  # a resonance's band-pass: 1 / (2 zeta) = 25
        y += np.outer(scipy.signal.lfilter(b, a, force), shape) * 1e-3
    y += noise * np.array([1.0, 2.0, 1.0]) * rng.standard_normal(y.shape)
    return force, y, fs


@pytest.mark.parametrize("noise", [2e-4, 2e-3])
def test_the_non_coherent_output_of_a_response_is_its_sensor_noise(noise):
    force, y, fs = _shaker(600.0, noise, seed=3)
    kw = {"fs": fs, "nperseg": 1024, "axis": 0}
    f, Gff = scipy.signal.welch(force, **kw)
    _, Gfy = scipy.signal.csd(force[:, None], y, **kw)
    _, Gyy = scipy.signal.welch(y, **kw)
    segments = 1 + (force.size - 1024) // 512
    floor = non_coherent_floor(f, Gff, Gfy, Gyy, (5.0, 30.0), segments)
    assert floor[0] == pytest.approx(_density(noise, fs), rel=0.1)
    assert floor[2] == pytest.approx(_density(noise, fs), rel=0.1)
    assert np.sqrt(floor[1] / floor[0]) == pytest.approx(2.0, rel=0.08)  # twice the noise, twice the floor
    assert np.all(Gyy[(f > 7) & (f < 14)].max(axis=0) > 100 * floor)  # the response stands well above it


def test_a_floor_is_reported_in_si_with_its_band_and_method_and_bad_input_is_refused():
    floor = NoiseFloor("acc", "m/s^2", 4e-8, (6.0, 24.0), NON_COHERENT, 20)
    row = floor.to_json()
    assert row["asd_si_per_sqrt_hz"] == pytest.approx(2e-4)
    assert row["rms_in_band_si"] == pytest.approx(2e-4 * np.sqrt(18))  # over 18 Hz
    assert row["band_hz"] == [6.0, 24.0] and row["method"] == NON_COHERENT and "coheren" in row["how"]
    f = np.linspace(0, 100, 201)
    with pytest.raises(ValueError, match="band .* holds 1 spectral lines"):
        spectral_floor(f, np.ones(201), (50.0, 50.2), 10)
    with pytest.raises(ValueError, match="segments must be >= 2"):
        non_coherent_floor(f, np.ones(201), np.ones((201, 1)), np.ones((201, 1)), (10.0, 20.0), 1)
    with pytest.raises(ValueError, match="percentile must be in"):
        NoiseFloorSettings(percentile=100.0)
