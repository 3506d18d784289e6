"""Ride comfort: the weightings against the standard's tabulated values, the indices on
signals whose answer is known by hand, and the comfort of a car run over its track recording."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from calibration.data.campaign import open_campaign
from calibration.models.parameters import CarParameters
from calibration.signals.comfort import (WB_EN, WB_ISO, WC, WD, WK, block_rms, n_mv, sperling_b, sperling_wz,
                                         weighted)
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec
from calibration.validation.comfort import floor_comfort
from calibration.validation.in_service import validate

#: ISO 8041-1:2017 Annex B design-goal factors at f = 10^(n/10) Hz, n = -10..26 (0.1-400 Hz):
#: Tables B.1 (Wb), B.2 (Wc), B.3 (Wd) and B.8 (Wk), as transcribed, with a check against the
#: printed dB column, in the phonometry project's test data (tests/reference_data/vibration.py)
ANNEX_B = {
    "Wb": (WB_ISO, [0.02494, 0.03941, 0.06198, 0.09645, 0.1464, 0.2113, 0.28, 0.3347, 0.3666, 0.3808, 0.3853,
                    0.3864, 0.3916, 0.4168, 0.496, 0.6653, 0.885, 1.026, 1.054, 1.026, 0.9745, 0.9042, 0.8144,
                    0.7088, 0.5973, 0.4906, 0.395, 0.3118, 0.2389, 0.1734, 0.1154, 0.06929, 0.03818, 0.01999,
                    0.0102, 0.005154, 0.002591]),
    "Wc": (WC, [0.06238, 0.09858, 0.1551, 0.2415, 0.3669, 0.5302, 0.7042, 0.8442, 0.9292, 0.9716, 0.991, 1.0,
                1.006, 1.012, 1.017, 1.023, 1.024, 1.013, 0.9739, 0.8941, 0.7762, 0.6425, 0.5166, 0.4098, 0.3236,
                0.2549, 0.2002, 0.1557, 0.1182, 0.08538, 0.05665, 0.03394, 0.01868, 0.009772, 0.004987, 0.002518,
                0.001266]),
    "Wd": (WD, [0.06242, 0.09867, 0.1553, 0.242, 0.3682, 0.533, 0.7097, 0.854, 0.9443, 0.9914, 1.011, 1.007,
                0.9707, 0.8913, 0.7733, 0.6398, 0.5143, 0.4081, 0.3226, 0.255, 0.2017, 0.1597, 0.1266, 0.1004,
                0.07958, 0.06299, 0.04965, 0.03872, 0.02946, 0.0213, 0.01414, 0.008478, 0.004668, 0.002442,
                0.001246, 0.0006293, 0.0003164]),
    "Wk": (WK, [0.03121, 0.04931, 0.07756, 0.1207, 0.1832, 0.2644, 0.3504, 0.4188, 0.4588, 0.4767, 0.4825,
                0.4846, 0.4935, 0.5308, 0.6335, 0.8071, 0.9648, 1.039, 1.054, 1.037, 0.9884, 0.8989, 0.7743,
                0.6373, 0.5103, 0.4031, 0.316, 0.2451, 0.1857, 0.1339, 0.08873, 0.05311, 0.02922, 0.01528,
                0.007795, 0.003935, 0.001978]),
}
ANNEX_B_HZ = 10.0 ** (np.arange(-10, 27) / 10)


@pytest.mark.parametrize("name", sorted(ANNEX_B))
def test_weightings_are_within_a_tenth_of_a_decibel_of_iso_8041_annex_b(name):
    w, table = ANNEX_B[name]
    error_db = 20 * np.log10(w.magnitude(ANNEX_B_HZ) / np.array(table))
    assert np.max(np.abs(error_db)) < 0.1


@pytest.mark.parametrize("w, factor", [(WB_ISO, 0.8126), (WC, 0.5145), (WD, 0.1261), (WK, 0.7718)])
def test_weightings_at_the_reference_frequency_are_iso_8041_table_1s(w, factor):
    """ISO 8041-1 Table 1: the factor at 100 rad/s (15.915 Hz), printed to four figures."""
    assert w.magnitude(100 / (2 * np.pi)) == pytest.approx(factor, abs=5e-5)


def _zpk_magnitude(w, f):
    """|H| of ``w`` built again as zeros, poles and gain from its stages' polynomials."""
    def pair(fc, q):
        wc = 2 * np.pi * fc
        return np.roots([1.0, wc / q, wc * wc])
    zeros = [0.0, 0.0, -2 * np.pi * w.f3]
    poles = list(pair(w.f1, 1 / np.sqrt(2))) + list(pair(w.f2, 1 / np.sqrt(2))) + list(pair(w.f4, w.q4))
    gain = w.k * (2 * np.pi * w.f2) ** 2 * (2 * np.pi * w.f4) ** 2 / (2 * np.pi * w.f3)
    if w.f5 is not None:
        zeros += list(pair(w.f5, w.q5))
        poles += list(pair(w.f6, w.q6))
    _, h = scipy.signal.freqs_zpk(zeros, poles, gain, 2 * np.pi * np.asarray(f))
    return np.abs(h)


@pytest.mark.parametrize("w", [WB_EN, WB_ISO, WC, WD, WK], ids=lambda w: w.name)
def test_a_second_implementation_from_poles_and_zeros_agrees(w):
    """The EN 12299 Wb has no table at hand: it is checked against the same definition built
    another way (poles and zeros of each stage, scipy's evaluation), as are the others."""
    f = np.geomspace(0.05, 500.0, 400)
    assert np.max(np.abs(20 * np.log10(w.magnitude(f) / _zpk_magnitude(w, f)))) < 1e-9


def test_the_en_and_iso_wb_are_told_apart_and_share_their_asymptotes():
    assert abs(20 * np.log10(WB_EN.magnitude(16.0) / WB_ISO.magnitude(16.0))) > 0.5
    # between the band limits, below the step: K (f5 / f6)^2 = 0.4 (EN 12299's low-frequency gain)
    for w in (WB_EN, WB_ISO):
        bare = type(w)(w.name, None, 1e9, w.f3, w.f4, w.q4, w.f5, w.q5, w.f6, w.q6, w.k)
        assert bare.magnitude(1e-3) == pytest.approx(0.4, rel=1e-3)
        assert bare.magnitude(1e-3) / bare.magnitude(2e-3) == pytest.approx(1.0, rel=1e-3)
    # outside the band limits: 40 dB a decade below 0.4 Hz, 60 above 100 Hz (low-pass and transition)
    assert WB_EN.magnitude(0.01) / WB_EN.magnitude(0.1) == pytest.approx(0.01, rel=0.02)
    assert WB_EN.magnitude(10000.0) / WB_EN.magnitude(1000.0) == pytest.approx(1e-3, rel=0.05)


def test_a_weighted_sine_has_the_weightings_amplitude():
    fs, f0 = 200.0, 5.0
    t = np.arange(int(60 * fs)) / fs
    out = weighted(np.sin(2 * np.pi * f0 * t), fs, WB_EN)
    steady = out[int(10 * fs):int(50 * fs)]
    assert np.sqrt(2 * np.mean(steady ** 2)) == pytest.approx(WB_EN.magnitude(f0), rel=1e-3)


def test_block_rms_takes_whole_blocks_only():
    fs = 10.0
    a = np.concatenate([np.full(50, 1.0), np.full(50, -3.0), np.full(20, 9.0)])
    assert block_rms(a, fs, 5.0) == pytest.approx([1.0, 3.0])
    with pytest.raises(ValueError, match="no 5.0 s block"):
        block_rms(a[:40], fs, 5.0)


def test_n_mv_of_steady_sines_is_six_times_their_weighted_rms():
    fs = 200.0
    t = np.arange(int(300 * fs)) / fs
    az, ax = 0.3 * np.sin(2 * np.pi * 4.0 * t), 0.2 * np.sin(2 * np.pi * 1.0 * t)
    z_only = n_mv(fs, z=az)
    expected_z = 0.3 / np.sqrt(2) * WB_EN.magnitude(4.0)
    assert z_only["directions"] == ("z",)
    assert z_only["n_mv"] == pytest.approx(6 * expected_z, rel=2e-3)
    both = n_mv(fs, x=ax, z=az)
    expected_x = 0.2 / np.sqrt(2) * WD.magnitude(1.0)
    assert both["n_mv"] == pytest.approx(6 * np.hypot(expected_x, expected_z), rel=2e-3)
    with pytest.raises(ValueError, match="at least one"):
        n_mv(fs)


def test_n_mv_takes_the_95th_percentile_of_the_five_second_rms():
    """Forty 5 s blocks of a 4 Hz sine whose amplitude steps 1, 2, ... 40 x 0.01 m/s^2: the
    95th percentile of the blocks' weighted rms (linear interpolation) is at 38.05 x 0.01."""
    fs, f0 = 200.0, 4.0
    m = int(5 * fs)
    t = np.arange(40 * m) / fs
    amplitude = 0.01 * np.repeat(np.arange(1, 41), m)
    res = n_mv(fs, z=amplitude * np.sin(2 * np.pi * f0 * t))
    expected = np.percentile(0.01 * np.arange(1, 41), 95) / np.sqrt(2) * WB_EN.magnitude(f0)
    assert res["p95_m_per_s2"]["z"] == pytest.approx(expected, rel=5e-3)


def test_sperlings_b_follows_his_frequency_factor_and_wz_of_a_sine():
    """B(f)^3 is Sperling's 0.896^10 F(f) / f (F = 0.325 f^2 below 5.9 Hz, 400 / f^2 above)
    within 4 % from 1 to 10 Hz, away from the corner of his piecewise F (7 % at 5.9 Hz, which a
    rational filter rounds); a sine of amplitude A gives Wz = (B(f) A [cm/s^2])^0.3."""
    f = np.linspace(1.0, 10.0, 37)
    f = f[np.abs(f - 5.9) > 0.6]
    F = np.where(f < 5.9, 0.325 * f ** 2, 400 / f ** 2)
    assert np.max(np.abs(sperling_b(f) / (0.896 ** 10 * F / f) ** (1 / 3) - 1)) < 0.04
    fs, f0, A = 200.0, 3.0, 0.5
    t = np.arange(int(100 * fs)) / fs
    assert sperling_wz(A * np.sin(2 * np.pi * f0 * t), fs) == pytest.approx((sperling_b(f0) * 100 * A) ** 0.3,
                                                                           rel=1e-6)
    assert sperling_b(f0, "lateral") == pytest.approx(1.25 * sperling_b(f0))


# ------------------------------------------------------------------ over the track recording

def test_ride_comfort_of_the_cars_own_campaign_matches_its_floor_accelerometers(tmp_path):
    """A campaign made by railcal's own truth with floor accelerometers, the truth's car as
    the calibration: at each floor position the model's vertical N_MV part and Wz over the
    recording agree with the measured ones within the sensors' noise (0.02 m/s^2 rms adds
    power: measured a few per cent higher)."""
    root = tmp_path / "c"
    truth = synth_in_service(root, seed=11, fmt="parquet", settings=InServiceSettings(
        journeys=3, line=LineSpec(length=6000.0), carbody_sensors=True))
    result = validate(open_campaign(root), CarParameters(**truth["parameters"]))
    summary = result.to_json()["ride_comfort"]
    assert set(summary) == {"carbody_front_acc_z", "carbody_centre_acc_z", "carbody_rear_acc_z"}
    for pos, c in summary.items():
        assert c["runs"] == 3
        assert c["measured"]["n_mv_z"] == pytest.approx(c["model"]["n_mv_z"], rel=0.1), pos
        assert c["measured"]["wz"] == pytest.approx(c["model"]["wz"], rel=0.05), pos
    # above a bogie the pitch adds to the bounce: the ends ride worse than the centre
    assert summary["carbody_front_acc_z"]["model"]["n_mv_z"] > summary["carbody_centre_acc_z"]["model"]["n_mv_z"]


def test_ride_comfort_without_floor_sensors_is_the_models_at_en_12299s_positions(synthetic_campaign):
    root, truth = synthetic_campaign
    p = CarParameters(**truth["parameters"])
    summary = validate(open_campaign(root), p).to_json()["ride_comfort"]
    assert {pos: c["x_m"] for pos, c in summary.items()} == {"floor_front": p.L_v, "floor_centre": 0.0,
                                                             "floor_rear": -p.L_v}
    assert all(c["measured"] is None and c["model"]["n_mv_z"] > 0 for c in summary.values())


def test_a_stretch_shorter_than_four_five_second_blocks_gives_no_comfort_figure():
    fs = 100.0
    assert floor_comfort("x", 0.0, fs, np.ones(int(19.9 * fs)), None) is None
    assert floor_comfort("x", 0.0, fs, np.sin(np.arange(int(20 * fs))), None) is not None
