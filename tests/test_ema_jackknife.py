"""Standard errors of a shaker test's modes (delete-one-group jackknife) against a known
three-mode system: finite, positive, proportional to the noise on the responses, and
consistent with the estimates' actual errors.

Truth: modes at 9, 12.5 and 17 Hz (1.5-2.5 % damped), six accelerometers with random real
shapes, a band-random force 5-50 Hz at 200 Hz, each mode stepped exactly (first-order
hold), white noise on every accelerometer in proportion to its rms."""
import numpy as np
import pytest
import scipy.signal

from calibration.identification.ema import Mode, frf_h1_records
from calibration.identification.ema_jackknife import group_spectra, pair_modes
from calibration.identification.excitation import ExcitationIdentifySettings, find_modes, mode_standard_errors
from test_ema import modal_filters  # the same sampling rate (200 Hz) and discretisation

FS = 200.0  # [Hz]
F_N = np.array([9.0, 12.5, 17.0])  # [Hz]
ZETA = np.array([0.02, 0.015, 0.025])
PHI = np.random.default_rng(1).standard_normal((6, 3))  # shapes at the accelerometers
PHI_F = np.array([1.0, -0.8, 1.2])  # shapes at the shaker
SETTINGS = ExcitationIdentifySettings(band=(6.0, 22.0), nperseg=4096, orders=tuple(range(8, 33, 2)),
                                      jackknife_groups=10)


def _test(noise: float, seed: int, seconds: float = 600.0):
    """Force [N] and accelerations [m/s^2] with white noise of ``noise`` x each one's rms."""
    rng = np.random.default_rng(seed)
    n = int(seconds * FS)
    force = scipy.signal.sosfilt(scipy.signal.butter(4, (5, 50), "bandpass", fs=FS, output="sos"),
                                 rng.standard_normal(n))
    y = np.column_stack([scipy.signal.lfilter(b, a, force) for b, a in modal_filters(F_N, ZETA, PHI_F)]) @ PHI.T
    return force, y + noise * y.std(axis=0) * rng.standard_normal(y.shape)


def _identified(noise: float, seed: int):
    spectra = group_spectra([_test(noise, seed)], FS, SETTINGS.nperseg, SETTINGS.jackknife_groups)
    modes = find_modes(spectra.frequency, spectra.h1(), SETTINGS)
    f = np.array([m.frequency_hz for m in modes])
    assert f.size == 3 and np.allclose(f, F_N, rtol=0.002), f
    return modes, mode_standard_errors(spectra, modes, SETTINGS)


@pytest.fixture(scope="module")
def two_noise_levels():
    return {noise: _identified(noise, seed=4) for noise in (1.6, 0.4)}


def test_standard_errors_are_finite_positive_and_from_every_replicate(two_noise_levels):
    for modes, spread in two_noise_levels.values():
        for m, s in zip(modes, spread):
            assert s.replicates == s.groups == 10
            assert 0 < s.frequency_std_hz < 0.001 * m.frequency_hz  # 600 s of a clear mode: under 0.1 %
            assert 0 < s.damping_std < 0.1 * m.damping_ratio


def test_a_quarter_of_the_noise_gives_about_a_quarter_of_the_standard_error(two_noise_levels):
    (_, loud), (_, quiet) = two_noise_levels[1.6], two_noise_levels[0.4]
    for a, b in zip(loud, quiet):  # a jackknife over 10 groups scatters by ~25 %; 4 is expected
        assert 2.0 < a.frequency_std_hz / b.frequency_std_hz < 8.0
        assert 1.5 < a.damping_std / b.damping_std < 10.0


def test_the_estimates_lie_within_a_few_standard_errors_of_the_truth(two_noise_levels):
    for modes, spread in two_noise_levels.values():
        for m, s, f_true in zip(modes, spread, F_N):
            assert abs(m.frequency_hz - f_true) < 4 * s.frequency_std_hz, (m.frequency_hz, s.frequency_std_hz)


def test_grouped_spectra_average_to_the_h1_of_all_records():
    """Groups straddle the records' ends; all of them together are the records' H1."""
    force, y = _test(0.2, seed=2, seconds=200.0)
    records = [(force[:15_000], y[:15_000]), (force[15_000:], y[15_000:]), (force[:1000], y[:1000])]  # last: too short
    spectra = group_spectra(records, FS, 2048, 7)
    whole = frf_h1_records(records, FS, 2048)
    assert spectra.segments == whole.n_averages and spectra.counts.size == 7 and spectra.counts.min() >= 4
    assert np.allclose(spectra.h1(), whole.H, rtol=1e-9, atol=1e-12 * np.abs(whole.H).max())
    left_out = spectra.average(without=3)[3]
    assert left_out == whole.n_averages - spectra.counts[3]


def test_a_mode_a_replicate_lost_is_unpaired_and_a_close_pair_is_paired_by_shape():
    a, b = np.array([1.0, 0.5, -0.2]), np.array([0.1, -0.4, 1.0])
    modes = [Mode(10.0, 0.02, a), Mode(10.02, 0.02, b), Mode(15.0, 0.02, a)]
    found = [Mode(10.021, 0.02, b * 1.3), Mode(10.001, 0.021, a)]  # swapped in order, 15 Hz lost
    paired = pair_modes(modes, found, cluster_tol=0.002, bandwidth_fraction=0.25, cluster_mac=0.8)
    assert paired[0] is found[1] and paired[1] is found[0] and paired[2] is None
    far = pair_modes(modes[:1], [Mode(10.5, 0.02, a)], cluster_tol=0.002, bandwidth_fraction=0.25, cluster_mac=0.8)
    assert far == [None]  # 5 % off: another mode, not this one


def test_fewer_than_three_groups_give_no_standard_error():
    force, y = _test(0.2, seed=2, seconds=40.0)  # 40 s: 2 segments of 4096
    spectra = group_spectra([(force, y)], FS, 4096, 10)
    modes = [Mode(9.0, 0.02, PHI[:, 0])]
    spread = mode_standard_errors(spectra, modes, SETTINGS)
    assert spectra.counts.size == 2 and spread[0].frequency_std_hz is None and spread[0].replicates == 0
    with pytest.raises(ValueError, match="groups must be >= 2"):
        group_spectra([(force, y)], FS, 4096, 1)
