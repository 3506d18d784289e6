"""Cross-Entropy track inference (the seed's section 7 baseline): the car model's own
response over a known profile, inverted."""
import math

import numpy as np
import pytest
import scipy.signal

from calibration.models.car2d import wheelset_positions
from calibration.track_inference.cross_entropy import CESettings, infer_pass_ce
from calibration.track_inference.passes import Channel, Pass

from track_passes import STEP
from track_passes import own_pass as _own_pass


def _d1(x: np.ndarray) -> np.ndarray:
    """The D1 band (3-25 m), zero phase, on the 0.25 m grid."""
    sos = scipy.signal.butter(4, [1 / 25, 1 / 3], btype="bandpass", fs=1 / STEP, output="sos")
    return scipy.signal.sosfiltfilt(sos, x)


@pytest.mark.slow(seconds=10)
def test_ce_recovers_the_d1_profile_from_the_models_own_response():
    p, ps, (sx, zx) = _own_pass(300.0)
    pr = infer_pass_ce(ps, p, CESettings())
    assert pr.distance == pytest.approx(ps.s + wheelset_positions(p)[0])
    assert np.all(np.isfinite(pr.level)) and np.all(np.isfinite(pr.std)) and math.isnan(pr.log_likelihood)
    assert set(pr.innovation_ratio) == {"acc", "gyro"}
    assert all(0 < r < 0.1 for r in pr.innovation_ratio.values())  # most of each channel explained
    keep = slice(int(30 / STEP), -int(30 / STEP))
    est, true = _d1(pr.level)[keep], _d1(np.interp(pr.distance, sx, zx))[keep]
    assert np.corrcoef(est, true)[0, 1] > 0.8  # threshold set before the first run


def test_ce_ignores_axle_boxes_and_refuses_a_pass_it_cannot_use():
    p, ps, _ = _own_pass(40.0)
    with pytest.raises(ValueError, match="lookahead"):
        infer_pass_ce(ps, p, CESettings(lookahead=2.0))
    axle_only = Pass(ps.run_id, ps.s, ps.t, ps.v, ps.a, (Channel("axle1", "axle", ps.channels[0].values, wheelset=1),))
    with pytest.raises(ValueError, match="no bogie"):
        infer_pass_ce(axle_only, p, CESettings())
    quick = CESettings(population=40, max_generations=5)
    with_axle = Pass(ps.run_id, ps.s, ps.t, ps.v, ps.a, ps.channels + axle_only.channels)
    a, b = infer_pass_ce(ps, p, quick), infer_pass_ce(with_axle, p, quick)
    assert np.array_equal(a.level, b.level) and set(b.innovation_ratio) == {"acc", "gyro"}


@pytest.mark.parametrize("bad", [
    {"population": 5}, {"population": 500.0}, {"elite_fraction": 0.0}, {"elite_fraction": 1.0},
    {"population": 10, "elite_fraction": 0.1}, {"window": 0.0}, {"window": 5.2}, {"lookahead": 4.9},
    {"node_spacing": -0.5}, {"initial_std": 0.0}, {"height_limit": math.inf}, {"smoothing": 1.5},
    {"smoothing": 0.0}, {"tolerance": -1e-3}, {"restarts": -1}, {"max_generations": 0}, {"trend_length": 0.0},
    {"seed": -1},
])
def test_settings_are_checked(bad):
    with pytest.raises(ValueError, match="CESettings"):
        CESettings(**bad)
