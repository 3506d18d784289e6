"""Identified rigid-body modes are checked against where the campaign's priors put them."""
from __future__ import annotations

import pytest

from calibration.data.campaign import Prior, open_campaign
from calibration.data.outputs import CampaignWriter
from calibration.identification.in_service import prior_parameters
from calibration.identification.prior_range import FREQUENCY_PARAMETERS, MARGIN, outside, prior_frequency_ranges
from calibration.models.car2d import build_car, frequencies_by_label, undamped_modes
from calibration.models.vehicles import SEED_PRIOR_RANGES

from conftest import tiny_columns, tiny_meta

NOMINAL = {"m_v": 38747.0, "J_v": 611000.0, "m_b": 3087.0, "J_b": 3500.0, "k_p": 2840000.0, "k_s": 720000.0}


def _campaign(tmp_path, ranges):
    priors = {n: Prior(NOMINAL[n], lo, hi) for n, (lo, hi) in ranges.items()}
    root = tmp_path / "c"
    with CampaignWriter(root, tiny_meta(priors=priors)) as w:
        w.write_run("run_a", tiny_columns())
        w.commit()
    return open_campaign(root)


def test_the_ranges_hold_the_prior_car_and_widen_with_the_priors(tmp_path):
    narrow = _campaign(tmp_path / "a", {n: (0.95 * NOMINAL[n], 1.05 * NOMINAL[n]) for n in FREQUENCY_PARAMETERS})
    wide = _campaign(tmp_path / "b", SEED_PRIOR_RANGES)
    r_narrow = prior_frequency_ranges(narrow, prior_parameters(narrow))
    r_wide = prior_frequency_ranges(wide, prior_parameters(wide))
    f0 = frequencies_by_label(undamped_modes(build_car(prior_parameters(narrow))))
    for label, f in f0.items():
        assert r_narrow[label][0] < f < r_narrow[label][1]
        assert r_wide[label][0] <= r_narrow[label][0] and r_narrow[label][1] <= r_wide[label][1]
        # a car at the priors' corners with every stiffness 5 % up moves its frequencies by
        # at most 2.5 %: the narrow range is about +-5 % wide before its margin
        assert r_narrow[label][1] / r_narrow[label][0] < 1.2 * MARGIN**2


def test_without_a_prior_for_every_frequency_parameter_there_is_no_range(tmp_path):
    partial = _campaign(tmp_path, {n: SEED_PRIOR_RANGES[n] for n in FREQUENCY_PARAMETERS if n != "J_b"})
    assert prior_frequency_ranges(partial, prior_parameters(partial)) == {}


def test_a_mode_outside_its_range_is_named_with_the_range_and_one_inside_passes():
    ranges = {"carbody_bounce": (0.6, 1.4)}
    why = outside("carbody_bounce", 3.8, ranges)
    assert why is not None and "3.8 Hz" in why and "0.6-1.4 Hz" in why and "carbody_bounce" in why
    assert outside("carbody_bounce", 0.93, ranges) is None
    assert outside("bogie_bounce", 30.0, ranges) is None  # no range, no verdict


def test_a_carbody_mode_whose_partner_the_fit_did_not_resolve_is_undetermined_not_a_number():
    """Both carbody modes come from one two-pole fit: one pole left (its partner spent on
    another resonance) stood in for both and is neither's frequency."""
    from calibration.identification.in_service import IdentifiedMode, UndeterminedMode, unpaired_carbody

    def mode(label, f, source):
        return IdentifiedMode(label, f, 0.2, None, "input_output_fit", source, None, None)

    bogie = mode("bogie_bounce", 7.1, "own_rail")
    pitch = mode("carbody_pitch", 1.19, "trailing_rail")
    gone = UndeterminedMode("carbody_bounce", outside("carbody_bounce", 3.85, {"carbody_bounce": (0.6, 1.5)}))
    modes, undetermined = unpaired_carbody([pitch, bogie], [gone])
    assert modes == [bogie]
    why = next(u.reason for u in undetermined if u.label == "carbody_pitch")
    assert "one carbody pole (1.19 Hz)" in why and "3.85 Hz" in why
    both = [mode("carbody_bounce", 0.91, "trailing_rail"), pitch, bogie]  # a resolved pair stands
    assert unpaired_carbody(both, []) == (both, [])
    fdd = [mode("carbody_bounce", 0.9, "fdd"), bogie]  # an FDD peak is not the pair's fit
    assert unpaired_carbody(fdd, []) == (fdd, [])


def test_a_pole_damped_far_outside_what_the_priors_allow_is_another_resonance(tmp_path):
    """The intercity car's priors with Table 6-like damping: the rigid-body modes' ratios lie
    inside their ranges, and a pole at a bogie mode's frequency but damped ten times less
    (a lightly damped resonance of something else) is refused, naming the range."""
    from calibration.identification.prior_range import DAMPING_MARGIN, damping_outside, prior_damping_ranges

    damped = {**NOMINAL, "c_p": 29400.0, "c_s": 45000.0}
    ranges = {n: (0.6 * damped[n], 1.5 * damped[n]) for n in damped}
    priors = {n: Prior(damped[n], lo, hi) for n, (lo, hi) in ranges.items()}
    root = tmp_path / "c"
    with CampaignWriter(root, tiny_meta(priors=priors)) as w:
        w.write_run("run_a", tiny_columns())
        w.commit()
    campaign = open_campaign(root)
    prior = prior_parameters(campaign)
    r = prior_damping_ranges(campaign, prior)
    from calibration.models.car2d import damped_modes

    for m in damped_modes(build_car(prior)):
        assert r[m.label][0] * DAMPING_MARGIN <= m.damping_ratio <= r[m.label][1], m.label
        assert damping_outside(m.label, m.damping_ratio, r) is None
    why = damping_outside("bogie_bounce", r["bogie_bounce"][0] / 10, r)
    assert why is not None and "bogie_bounce" in why and "damping ratio" in why
    assert damping_outside("bogie_bounce", None, r) is None
    no_damping = _campaign(tmp_path / "d", {n: (0.9 * NOMINAL[n], 1.1 * NOMINAL[n]) for n in NOMINAL})
    assert prior_damping_ranges(no_damping, prior_parameters(no_damping)) == {}


def test_a_mode_that_moves_with_the_journeys_is_undetermined_and_a_steady_one_stands():
    """The jackknife standard error over the journeys is read against the accuracy a
    calibration target needs (3 % carbody, 2 % bogie by default): a carbody pitch with a
    standard error of 16 % is refused, naming it; a smaller one is not, and a mode without
    one (an FDD peak, or fewer than three refits that found it) is not judged."""
    from calibration.identification.in_service import IdentifiedMode, IdentifySettings, _unsteady

    def mode(label, f, std):
        return IdentifiedMode(label, f, 0.2, None, "input_output_fit", "trailing_rail", None, None, std)

    settings = IdentifySettings()
    why = _unsteady(mode("carbody_pitch", 1.145, 0.186), settings)
    assert why is not None and "16.24 %" in why and "exceeds 3 %" in why
    assert _unsteady(mode("carbody_pitch", 1.145, 0.025), settings) is None  # 2.2 %, within 3 %
    assert _unsteady(mode("bogie_bounce", 7.0, 0.17), settings) is not None  # 2.4 %, over 2 %
    assert _unsteady(mode("bogie_bounce", 7.0, None), settings) is None
    assert _unsteady(mode("carbody_pitch", 1.145, 0.186), IdentifySettings(max_relative_std=(0.2, 0.02))) is None
    for bad in (0.03, (0.03,), (0.0, 0.02), (0.03, 1.5), [0.03, 0.02], ("0.03", 0.02)):
        with pytest.raises(ValueError, match="max_relative_std"):
            IdentifySettings(max_relative_std=bad)
