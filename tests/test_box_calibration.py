"""Shaker test to calibrated box model: identification finds the modes the truth put in
the data, the swarm and the refinement bring the model to them, bad requests are refused.

A coarse box model (every panel order - 4) keeps the file fast."""
import json
import re
import shutil
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.linalg
from conftest import COARSE_BOX_ORDERS
from threadpoolctl import threadpool_limits

from calibration.calibrate_box import (PairingSettings, RefineSettings, SwarmSettings, box_search, calibrate_box,
                                       targets_from_identification)
from railcal.cli import main
from calibration.data.campaign import open_campaign
from calibration.identification.excitation import ExcitationMode, identify_excitation
from calibration.box_refine import polish_box
from calibration.signals.modal import mac_matrix
from calibration.models.box.fit import (MAC_SHORTFALL_PCT, BoxFit, ModeTarget, band_pairing, carbody_mass_matrix,
                                        select_targets, sensor_operator)
from calibration.models.box.parametric_basis import full_modes
from calibration.models.box.mode_types import MODE_TYPES, template
from calibration.optimisers.pso import PSOSettings
from calibration.models.box.rig import SENSOR_GRID
from calibration.truth.excitation import ExcitationSettings, synth_excitation, truth_modes

SETTINGS = ExcitationSettings(runs=1, duration=240.0, order_change=COARSE_BOX_ORDERS)


@pytest.fixture(scope="module")
def shaker(tmp_path_factory, model):
    root = tmp_path_factory.mktemp("shaker") / "test"
    truth = synth_excitation(root, seed=2, settings=SETTINGS, model=model)
    modal = truth_modes(truth["parameters"], damping=truth["modes_kept"]["damping_ratios"], settings=SETTINGS,
                        model=model)
    with threadpool_limits(1):  # one BLAS thread: the thread-count test compares it with two
        return root, truth, modal, identify_excitation(open_campaign(root))


def _strongest_separated(modal):
    """The four strongest elastic modes in 8-20 Hz whose neighbours lie outside their
    half-power band (modal overlap < 1): what a single-exciter test must resolve."""
    f, z = modal.frequency_hz, modal.damping_ratio
    elastic = np.array([k == "elastic" for k in modal.kind])
    gap = np.array([np.min(np.abs(np.delete(f[elastic], np.flatnonzero(f[elastic] == fk)) - fk)) for fk in f])
    separated = elastic & (gap > 2 * z * f)
    strength = np.where(separated, np.linalg.norm(modal.sensor_shapes, axis=0) * np.abs(modal.exciter_shape)
                        / (2 * z), 0.0)
    return select_targets(f, modal.sensor_shapes, strength=strength, n=4)


@pytest.mark.slow
def test_identification_finds_the_strongest_separated_true_modes_with_their_shapes(shaker):
    _, _, modal, ident = shaker
    shapes = np.column_stack([m.shape for m in ident.modes])
    for t in _strongest_separated(modal):
        mac = mac_matrix(t.shape[:, None], shapes)[0]
        k = int(np.argmax(mac))
        assert ident.modes[k].frequency_hz == pytest.approx(t.frequency_hz, rel=0.005)
        assert mac[k] >= 0.95


@pytest.mark.slow
def test_identification_is_the_same_on_one_and_two_blas_threads(shaker):
    """The identified modes are the data's, not the arithmetic's: the same clusters, and
    values equal to far below the identification error (0.01-0.3 % in frequency against
    the truth), on one and on two BLAS threads (tests/test_ema.py states the tolerances)."""
    from test_ema import assert_same_modes
    root, one = shaker[0], shaker[3]  # one thread
    with threadpool_limits(2):
        two = identify_excitation(open_campaign(root))
    assert len(one.modes) >= 6
    assert_same_modes(one.modes, two.modes)
    assert [r["frequency_hz"] for r in one.rejected] == pytest.approx([r["frequency_hz"] for r in two.rejected],
                                                                      rel=1e-9)


@pytest.mark.slow
def test_identification_reports_coherence_damping_and_auto_mac(shaker):
    _, _, _, ident = shaker
    out = ident.to_json()
    assert out["frf"]["median_coherence_in_band"] > 0.9
    assert all(0 < m["damping_ratio"] < 0.1 for m in out["modes"])
    A = np.array(out["auto_mac"])
    assert np.allclose(np.diag(A), 1.0) and A.shape == (len(out["modes"]),) * 2


@pytest.mark.slow
def test_swarm_and_refinement_bring_the_model_to_the_identified_modes(shaker, model):
    """This campaign has a close pair at 13.252 / 13.265 Hz (modal overlap about 26), which
    identification reports as two modes inside one half-power band, 13.235 and 13.307 Hz,
    each a mixture of the pair (both shapes in its span, MAC 0.99): their 0.5 % split is the
    one-exciter test's error, not the truth's. As two targets no model met both (0.21 % left
    after the refinement); the targets make them one, the span of the pair, at their mean
    frequency (their shapes are alike, MAC 0.68), and every other mode a target of its own
    with its band. Expected before running: within 0.05 % of every target after the
    refinement, every MAC >= 0.9."""
    root, truth, _, ident = shaker
    campaign = open_campaign(root)
    sensors = tuple(campaign.meta.sensor(n) for n in ident.sensors)
    targets = targets_from_identification(ident, band=True)
    f = np.array([m.frequency_hz for m in ident.modes])
    half_power = np.array([m.damping_ratio * m.frequency_hz for m in ident.modes])
    in_band = [i for i in range(f.size) if np.sum(np.abs(f - f[i]) < half_power[i]) > 1]
    assert len(in_band) == 2 and len(targets) == len(ident.modes) - 1  # the pair, and only the pair, merged
    pair = next(t for t in targets if "+" in t.label)
    assert pair.frequency_hz == pytest.approx(f[in_band].mean()) and pair.band * pair.frequency_hz > np.ptp(f[in_band])
    result = calibrate_box(targets, sensors, box_search(campaign.meta.priors), model=model,
                           swarm=SwarmSettings(pso=PSOSettings(particles=60, iterations=40, target=0.5), seed=1))
    assert result.pso["best_full_pct"] <= 0.5 or result.pso["iterations"] == 40
    assert result.max_error_pct <= 0.05  # after the refinement, judged on the full model
    assert min(r["mac"] for r in result.fit) >= 0.9
    assert result.identifiability["rank"] <= len(ident.modes)


def test_identified_modes_inside_one_half_power_band_with_alike_shapes_are_one_target_of_their_span():
    """Two identified modes 0.5 % apart with 2 % damping (each inside the other's band) and
    alike shapes (MAC 0.9), and a third 10 % away: two targets, the pair's at its mean
    frequency, labelled by both, its shape in the span of theirs, its band reaching both
    members' bands. With unlike shapes (MAC 0.1) the two are two modes, each its own
    target, as they are without bands."""
    rng = np.random.default_rng(0)
    a, n, c = (rng.normal(size=8) for _ in range(3))
    n -= (n @ a) / (a @ a) * a  # orthogonal to a
    a, n = a / np.linalg.norm(a), n / np.linalg.norm(n)

    def ident(mac):
        b = np.sqrt(mac) * a + np.sqrt(1 - mac) * n  # MAC(a, b) = mac
        return SimpleNamespace(modes=(ExcitationMode("mode_1", 10.00, 0.02, a, 5, None),
                                      ExcitationMode("mode_2", 10.05, 0.02, b, 5, None),
                                      ExcitationMode("mode_3", 11.00, 0.02, c, 5, None))), b

    alike, b = ident(0.9)
    pair, alone = targets_from_identification(alike, band=True)
    assert pair.label == "mode_1+mode_2" and pair.frequency_hz == pytest.approx(10.025)
    assert (1 - pair.band) * pair.frequency_hz <= 10.0 * 0.98 and (1 + pair.band) * pair.frequency_hz >= 10.05 * 1.02
    Q = np.linalg.qr(np.column_stack([a, b]))[0]
    assert np.linalg.norm(pair.shape - Q @ (Q.T @ pair.shape)) < 1e-12 * np.linalg.norm(pair.shape)
    assert alone.label == "mode_3" and alone.band == 0.02 and np.array_equal(alone.shape, c)
    assert [t.label for t in targets_from_identification(alike)] == ["mode_1", "mode_2", "mode_3"]
    unlike, _ = ident(0.1)
    assert [(t.label, t.band) for t in targets_from_identification(unlike, band=True)] == [
        ("mode_1", 0.02), ("mode_2", 0.02), ("mode_3", 0.02)]


def test_a_mode_identified_at_a_close_pair_pairs_with_the_span_of_the_pair():
    """Two model modes 0.1 % apart inside the measured mode's half-power band: the measured
    shape, a 57/43 mixture of theirs, matches neither alone but lies in their span. A mode
    whose band holds one model mode keeps the seed's single-mode pairing."""
    rng = np.random.default_rng(0)
    phi = np.linalg.qr(rng.standard_normal((12, 4)))[0]  # four orthonormal sensor shapes
    f = np.array([9.0, 13.25, 13.265, 16.0])
    mixed = np.sqrt(0.57) * phi[:, 1] + np.sqrt(0.43) * phi[:, 2]
    shapes = np.column_stack([mixed, phi[:, 3]])
    f_target = np.array([13.24, 16.02])
    mac = mac_matrix(shapes, phi[None])
    single_idx, single_mac = band_pairing(f[None], phi[None], shapes, f_target, [0.0, 0.0], mac)
    assert single_mac[0, 0] == pytest.approx(0.57) and single_idx[0, 0] == 1
    idx, best = band_pairing(f[None], phi[None], shapes, f_target, [0.013, 0.02], mac)
    assert best[0, 0] == pytest.approx(1.0) and idx[0, 0] == 1  # the member contributing most
    assert idx[0, 1] == 3 and best[0, 1] == pytest.approx(1.0)
    narrow = band_pairing(f[None], phi[None], shapes, f_target, [0.001, 0.02], mac)  # holds 13.25 only
    assert narrow[1][0, 0] == pytest.approx(0.57)  # the band holds one mode only: no span
    excluded = band_pairing(f[None], phi[None], shapes, f_target, [0.013, 0.02], mac,
                            eligible=np.array([[True, True, False, True]]))
    assert excluded[1][0, 0] == pytest.approx(0.57)  # an ineligible mode does not join a span


def test_mode_type_templates_are_distinct_floor_patterns():
    T = np.column_stack([template(t, SENSOR_GRID, 24.5, 3.38) for t in MODE_TYPES])
    off = mac_matrix(T, T) - np.eye(T.shape[1])
    assert np.all(off < 0.5)


def test_a_target_pairs_only_with_carbody_modes(model):
    """A bogie mode moves the floor faintly through the suspension; its floor pattern can
    match a target's shape perfectly. By default (``min_carbody_share`` = 0.5) the pairing
    skips modes whose kinetic energy is mostly outside the carbody; 0 pairs blind."""
    S = sensor_operator(model, SENSOR_GRID)
    f, X = full_modes(model, np.ones(len(model.names)), 30)
    share = np.einsum("dm,dm->m", X, carbody_mass_matrix(model) @ X)
    assert np.all((share > -1e-12) & (share < 1 + 1e-9))  # M-normalised: carbody + bogies = 1
    bogie = int(np.argmin(share))
    assert share[bogie] < 0.1
    target = (ModeTarget("bogie_pattern", float(f[bogie]), S @ X[:, bogie]),)
    p = np.ones(len(model.names))
    blind, fit = BoxFit(model, S, target, min_carbody_share=0.0), BoxFit(model, S, target)
    blind.rebuild(p)
    fit.rebuild(p)
    assert blind.full_check(p)["index"][0] == bogie and blind.full_check(p)["mac"][0] == pytest.approx(1.0)
    seen = fit.full_check(p)["index"][0]
    assert share[seen] >= 0.5
    assert fit.pair(p[None, :]).index[0, 0] == seen  # the reduced pairing skips it too


def test_the_basis_is_rebuilt_off_schedule_when_the_best_gains_far_from_its_centre(model):
    """A basis is exact at its centre only. The swarm's best is checked every iteration: far
    from the centre (more than 2 %) and more than 30 % better than the centre's error, it is
    rebuilt at once, not at the next check due (every 25 iterations); near the centre, or
    far without such a gain, it waits for the check due. Rebuilt, the error at the centre is
    the full model's."""
    S = sensor_operator(model, SENSOR_GRID)
    truth = np.ones(len(model.names))
    truth[:3] = (1.3, 0.8, 1.2)
    f, X = full_modes(model, truth, 30)
    targets = select_targets(f, S @ X, n=4)
    fit = BoxFit(model, S, targets)
    centre = np.ones(len(model.names))
    fit.rebuild(centre)
    assert fit.confirmed == pytest.approx(fit.full_check(centre)["max_error_pct"], rel=1e-6)
    near, worse = centre * 1.01, 2 * truth - centre
    assert fit(worse[None])[0] > 0.7 * fit.confirmed
    assert not fit.adapt(3, near) and not fit.adapt(3, worse)
    assert fit.adapt(25, worse)  # the check due
    fit.rebuild(centre)
    assert fit(truth[None])[0] < 0.7 * fit.confirmed
    assert fit.adapt(3, truth)  # off schedule
    np.testing.assert_array_equal(fit.centre, truth)
    assert fit.confirmed == pytest.approx(fit.full_check(truth)["max_error_pct"], abs=0.05)


def test_a_typed_target_counts_only_when_its_pairing_is_sound(model):
    """With ``min_mac`` a target paired to a mode unlike its pattern (MAC below the floor)
    adds 10 % per 0.01 of shortfall, and one whose partner a better-matching target already
    has adds 100 %; sound pairings keep RTRI eq. 3, and the full check says which are sound."""
    S = sensor_operator(model, SENSOR_GRID)
    targets = tuple(ModeTarget(t, f, template(t, SENSOR_GRID, 24.5, 3.38))
                    for t, f in (("vertical_bending_1", 10.0), ("torsion_1", 12.0)))
    plain, strict = BoxFit(model, S, targets), BoxFit(model, S, targets, min_mac=0.8)
    f = np.array([[10.1, 11.4], [10.1, 11.4], [10.1, 11.4], [10.1, 11.4]])
    mac = np.array([[0.95, 0.90], [0.95, 0.50], [0.95, 0.79], [0.95, 0.90]])
    index = np.array([[7, 9], [7, 9], [7, 9], [7, 7]])  # the last row: both targets on mode 7
    assert plain.errors_pct(f, mac, index) == pytest.approx(np.tile([1.0, 5.0], (4, 1)))
    e = strict.errors_pct(f, mac, index)
    assert e[0] == pytest.approx([1.0, 5.0])  # sound: the frequency errors
    assert e[1, 1] == pytest.approx(5 + 300) and e[2, 1] == pytest.approx(5 + 10)  # MAC 0.5, 0.79 < 0.8
    assert e[3] == pytest.approx([1.0, 105.0])  # mode 7 goes to the better match
    p = np.ones(len(model.names))
    strict.rebuild(p)
    check = strict.full_check(p)
    unsound = check["mac"] < 0.8
    assert np.array_equal(check["sound"], ~unsound)  # (no shared partner between these two types)
    assert check["max_error_pct"] == pytest.approx(np.max(np.abs(check["error_pct"])
                                                          + 1000 * np.maximum(0.8 - check["mac"], 0)))


class _Recorder:
    """The fit, recording the full model's check at every point the polish evaluates."""

    def __init__(self, fit):
        self._fit, self.checks = fit, []

    def __getattr__(self, name):
        return getattr(self._fit, name)

    def gradients(self, p, macs=True):
        out = self._fit.gradients(p, macs=macs)
        self.checks.append(out[0])
        return out


POLISH_HALVING_STEPS = 4


def test_the_full_model_polish_lowers_the_error_and_keeps_the_mac_floor(model):
    """The sequential LP on the full model (exact frequency and MAC derivatives) moves
    three modes of a nominal model towards those of a perturbed one: every kept step lowers
    the full model's error and keeps every MAC over the floor, every refused step would not
    have, and the error halves within ``POLISH_HALVING_STEPS`` steps.

    The targets are modes at least 1 % from their neighbours: a double or near-double
    eigenvalue (this model has one at 10.27 Hz that no factor moves) has no shape of its own,
    the eigensolver returns a round-off-dependent vector of its eigenspace, and so would the
    target and its MAC be. The 10.27 Hz pair is the bogies': when the 9.97 Hz target's
    partner passes close to it, each has a MAC within 1e-3 of the other, and only the
    carbody-share filter (BoxFit's default) keeps round-off from choosing (without it this
    failed on two BLAS threads and passed on one). Where the step count comes from: K = K0 + sum p_i K_i with every
    K_i positive semi-definite, so d ln f / d ln p_i >= 0 and sums to at most 1/2; a step of
    +-trust in log factors moves a frequency by at most trust / 2, and with the region at 2 %
    growing by half per kept step, halving a start error of about 5 % takes at least two
    steps (1 % + 1.5 %). The minimax over three modes took three on every BLAS kernel tried;
    the fourth is a spare for a refused step."""
    S = sensor_operator(model, SENSOR_GRID)
    p_true = np.exp(np.random.default_rng(1).uniform(-0.15, 0.15, len(model.names)))
    f, X = full_modes(model, p_true, 30)
    gap = np.array([np.min(np.abs(np.delete(f, k) - f[k])) / f[k] for k in range(f.size)])
    ks = [k for k in range(f.size) if 8 < f[k] < 20 and gap[k] > 0.01][:3]
    assert len(ks) == 3
    fit = BoxFit(model, S, tuple(ModeTarget(f"m{k}", float(f[k]), S @ X[:, k]) for k in ks), min_mac=0.8)
    p0 = np.ones(len(model.names))
    fit.rebuild(p0)
    start, G, _ = fit.gradients(p0)
    ratio = start["frequency_hz"] / fit.f_target
    assert np.all(G >= -1e-12) and np.all(G.sum(axis=1) <= 0.5 * ratio * (1 + 1e-9))
    assert start["max_error_pct"] > 2.0 and np.all(start["mac"] >= fit.min_mac)

    rec = _Recorder(fit)
    r = polish_box(rec, p0, np.full(p0.size, 0.5), np.full(p0.size, 2.0), steps=POLISH_HALVING_STEPS, trust=0.02)
    trials = iter(rec.checks[1:])
    best = start["max_error_pct"]
    for status in r.statuses:
        if status == "no step keeps the MAC floor":
            continue
        trial = next(trials)
        lowers = trial["max_error_pct"] < best
        assert (status == "kept") == (lowers and trial["sound"].all()), (status, trial["max_error_pct"], best)
        if status == "kept":
            assert np.all(trial["mac"] >= fit.min_mac)
            best = trial["max_error_pct"]
    assert r.max_error_pct == best and r.start_max_error_pct == start["max_error_pct"]
    assert r.max_error_pct < 0.5 * r.start_max_error_pct
    check = fit.full_check(r.parameters)
    assert check["max_error_pct"] == pytest.approx(r.max_error_pct) and np.all(check["mac"] >= fit.min_mac)


def test_the_mac_derivatives_are_those_of_the_full_model(model):
    """The partners' MAC derivatives in log factors (Nelson's eigenvector derivative) agree
    with central differences of the full model along a random direction, as the frequency
    derivatives do. No target's partner has a rival in a double eigenvalue: the model's
    10.27 Hz pair, which no factor moves, has no vectors of its own, and with the first
    vertical bending's template its span's MAC rivals the partner's (0.95), so which of them
    a step pairs with was the CPU kernel's choice."""
    S = sensor_operator(model, SENSOR_GRID)
    targets = tuple(ModeTarget(t, f, template(t, SENSOR_GRID, 24.5, 3.38))
                    for t, f in (("lateral_vertical_1", 9.0), ("torsion_1", 12.0), ("breathing", 18.5)))
    fit = BoxFit(model, S, targets, min_mac=0.8)
    rng = np.random.default_rng(3)
    p = np.exp(rng.uniform(-0.3, 0.3, len(model.names)))
    fit.rebuild(p)
    check, G, J = fit.gradients(p)
    v, h = rng.standard_normal(p.size), 1e-4
    up, down = fit.full_check(p * np.exp(h * v)), fit.full_check(p * np.exp(-h * v))
    assert np.array_equal(up["index"], check["index"]) and np.array_equal(down["index"], check["index"])
    assert J @ v == pytest.approx((up["mac"] - down["mac"]) / (2 * h), rel=1e-4, abs=1e-7)
    assert np.abs(J @ v).max() > 1e-3  # the shapes do move
    assert G @ v == pytest.approx((up["frequency_hz"] - down["frequency_hz"]) / (2 * h) / fit.f_target, rel=1e-4)


class _OneFactorFit:
    """One target at 1.1 times its frequency, moved by one log factor q; its MAC
    0.8001 - 20 q^2 is flat at q = 0 (so the linearised floor does not bind) and falls a hair
    under 0.8 beyond |q| = 0.0022, where the frequency gains more than the score's
    shortfall penalty costs."""
    min_mac, f_target = 0.8, np.array([10.0])

    def full_check(self, p):
        q = np.log(np.asarray(p, float))
        ratio, mac = 1.1 * np.exp(q), 0.8001 - 20 * q**2
        return {"frequency_hz": self.f_target * ratio, "mac": mac, "sound": mac >= self.min_mac,
                "max_error_pct": float(100 * np.abs(ratio - 1)[0] + MAC_SHORTFALL_PCT * max(0.8 - mac[0], 0))}

    def gradients(self, p, macs=True):
        q = np.log(np.asarray(p, float))
        return self.full_check(p), 1.1 * np.exp(q)[:, None], -40 * q[:, None]


def test_the_polish_never_trades_a_sound_pairing_for_a_lower_score():
    """A step that lowers the scored error but takes a sound pairing a hair under the MAC
    floor is refused; the region halves until a step keeps the pairing sound."""
    fit = _OneFactorFit()
    assert fit.full_check([np.exp(-0.005)])["max_error_pct"] < fit.full_check([1.0])["max_error_pct"]
    r = polish_box(fit, [1.0], [0.5], [2.0], steps=3, trust=0.005)
    assert r.statuses == ("unsound", "unsound", "kept")
    assert np.log(r.parameters[0]) == pytest.approx(-0.00125)
    assert fit.full_check(r.parameters)["sound"].all()


class _UnsoundStartFit(_OneFactorFit):
    """One target met exactly at q = 0 with its MAC 0.79, a hair under the floor: the MAC
    rises with q (slope 1), the frequency too (ratio exp(q / 2))."""

    def full_check(self, p):
        q = np.log(np.asarray(p, float))
        ratio, mac = np.exp(q / 2), 0.79 + q
        return {"frequency_hz": self.f_target * ratio, "mac": mac, "sound": mac >= self.min_mac,
                "max_error_pct": float(100 * np.abs(ratio - 1)[0] + MAC_SHORTFALL_PCT * max(0.8 - mac[0], 0))}

    def gradients(self, p, macs=True):
        return self.full_check(p), 0.5 * np.exp(np.log(np.asarray(p, float)) / 2)[:, None], np.ones((1, 1))


def test_the_polish_lifts_an_unsound_pairing_over_the_floor_when_the_score_gains():
    """Met in frequency but penalised 10 % for a MAC 0.01 under the floor: the polish gives up
    half a per cent of frequency to take the MAC back to the floor."""
    fit = _UnsoundStartFit()
    r = polish_box(fit, [1.0], [0.5], [2.0], steps=1, trust=0.02)
    assert r.start_max_error_pct == pytest.approx(10.0)
    assert r.statuses == ("kept",) and r.max_error_pct == pytest.approx(0.5, abs=0.01)


@pytest.mark.slow
def test_a_staged_factor_set_swarms_on_its_first_factors_and_polishes_them_all(model):
    """The credible set: the swarm and the refinement move 14 factors, the end-wall and
    floor-floor joints join, nominal, in the polish; the file records the set, and the model
    it describes is rebuilt from it (old files without a set: the grouped factors)."""
    from calibration.models.box.shinkansen import calibrated_box_model
    from calibration.data.errors import InputError
    from calibration.models.box import factor_set
    from calibration.models.box.mode_types import typed_targets

    fs = factor_set("credible")
    targets = typed_targets({"vertical_bending_1": 9.88, "torsion_1": 15.79}, SENSOR_GRID, 24.5, 3.38)
    cal = calibrate_box(targets, SENSOR_GRID, box_search(factors=fs), factors=fs, order_change=COARSE_BOX_ORDERS,
                        swarm=SwarmSettings(pso=PSOSettings(particles=6, iterations=2, target=0.5), log_factors=True),
                        refinement=RefineSettings(rounds=1, polish_steps=1), pairing=PairingSettings(min_mac=0.8))
    out = cal.to_json()
    assert out["factor_set"] == "credible" and list(out["parameters"]) == list(fs.names)
    assert out["pso"]["factors"] == list(fs.names[:14]) and out["refinement"]["polish"]["factors"] == list(fs.names)
    assert out["search"]["end_k_r"] == [0.25, 20.0] and out["search"]["roof_shear"] == [0.1, 2.0]
    assert out["max_error_pct"] <= out["refinement"]["start_max_error_pct"]
    rebuilt, p = calibrated_box_model({"factor_set": "credible", "parameters": {"roof_shear": 0.5}})
    assert rebuilt.names == fs.names and p["roof_shear"] == 0.5 and p["end_k_t"] == 1.0
    assert calibrated_box_model({"parameters": {}})[0].names == factor_set("grouped").names
    for bad, word in (({"factor_set": "bespoke", "parameters": {}}, "bespoke"),
                      ({"factor_set": "credible", "parameters": {"roof_membrane": 1.0}}, "roof_membrane"),
                      ({"parameters": {"side_shear": float("nan")}}, "positive"),
                      ({"factor_set": "windowed", "parameters": {}}, "side_end_zone_m.*goes with"),
                      ({"factor_set": "credible", "side_end_zone_m": 5.0, "parameters": {}}, "only with them"),
                      ({"factor_set": "orthotropic", "parameters": {}}, "side_end_zone_m.*goes with"),
                      ({"factor_set": "windowed", "side_end_zone_m": 13.0, "parameters": {}}, r"in \(0, 12.25\)"),
                      ({"factor_set": "windowed", "side_end_zone_m": float("nan"), "parameters": {}}, "a length"),
                      ({"factor_set": "windowed", "side_end_zone_m": "5", "parameters": {}}, "a length")):
        with pytest.raises(InputError, match=word):
            calibrated_box_model(bad)


def test_a_box_factors_prior_must_stay_above_zero():
    from calibration.data.campaign import Prior
    from calibration.data.errors import InputError
    from calibration.models.box import factor_set

    with pytest.raises(InputError, match=r"priors\.roof_shear\.low.*above 0"):
        box_search({"roof_shear": Prior(1.0, 0.0, 2.0)}, factors=factor_set("credible"))


def test_ranges_or_factors_that_reach_an_indefinite_plate_are_refused_and_the_panel_swarm_stays_clear_of_them():
    """A cross-direction factor over its lengthwise partner must stay above nu^2 (with a
    margin): a campaign's priors that reach below it anywhere in their box, and a calibration
    file's factors at it, are refused naming both factors; the shaker diagnosis's panel
    swarm, whose lows are divided for softening, has its cross-direction lows raised
    instead, and then every corner of its box is positive definite."""
    from calibration.data.campaign import Prior
    from calibration.data.errors import InputError
    from calibration.diagnosis.excitation.softening import definite
    from calibration.models.box.shinkansen import (DEFINITE_MARGIN, MATERIAL, across_limits, calibrated_box_model,
                                                   factor_set, indefinite_plates)

    nu = 0.3
    assert all(abs(r - nu**2) < 1e-12 for _, r in across_limits().values())  # MATERIAL's coupling: nu sqrt(x11 x22)
    fs = factor_set("orthotropic", side_end_zone=5.0)
    own = box_search(factors=fs)  # the set's own ranges pass
    assert not indefinite_plates({q.name: q.low for q in own}, {q.name: q.high for q in own})
    with pytest.raises(InputError, match=r"roof_bending_across 0\.2 over roof_bending_along 4") as err:
        box_search({"roof_bending_across": Prior(1.0, 0.2, 10.0)}, factors=fs)
    assert err.value.key == "priors"
    box_search({"roof_bending_across": Prior(1.0, 0.2, 10.0), "roof_bending_along": Prior(1.0, 0.5, 1.5)}, factors=fs)
    with pytest.raises(InputError, match="floor_normal_across") as err:
        calibrated_box_model({"factor_set": "orthotropic", "side_end_zone_m": 5.0,
                              "parameters": {"floor_normal_along": 3.0, "floor_normal_across": 0.25}})
    assert err.value.key == "parameters"

    soft = tuple(replace(q, low=q.low / 30) for q in own)  # every low divided, as the panel swarm's own factors
    soft += tuple(replace(q, name=f"{q.name}@floor_rear", low=q.low / 30) for q in own if q.name.startswith("floor"))
    assert indefinite_plates({q.name: q.low for q in soft}, {q.name: q.high for q in soft})
    fixed = definite(soft)
    assert not indefinite_plates({q.name: q.low for q in fixed}, {q.name: q.high for q in fixed})
    changed = {q.name for q, r in zip(soft, fixed) if q.low != r.low}
    assert changed and all(n.partition("@")[0] in across_limits() for n in changed)  # the lengthwise lows stay down
    for q in fixed:  # the most lopsided corner of each plate, by its constitutive matrix
        base, at, suffix = q.name.partition("@")
        if base not in across_limits():
            continue
        along = next(r for r in fixed if r.name == across_limits()[base][0] + at + suffix)
        rig = MATERIAL[base.split("_")[0]][0]
        xx, yy, xy = ("D11", "D22", "D12") if "bending" in base else ("A11", "A22", "A12")
        C = np.array([[along.high * rig[xx], along.high * rig[xy]], [along.high * rig[xy], q.low * rig[yy]]])
        assert np.linalg.eigvalsh(C).min() > 0.0 and q.low / along.high > DEFINITE_MARGIN * nu**2


def test_the_windowed_set_adds_the_side_walls_end_strips_and_its_file_rebuilds_them():
    """The windowed set: the credible factors and the side walls' in-plane shear over end
    strips of the vehicle's length; its file records the length, and the model rebuilt from
    the file scales exactly those strips (their share of the side walls' shear energy)."""
    from calibration.models.box.shinkansen import (Geometry, calibrated_box_model, factor_set, side_end_zone_of,
                                                   windowed_factor_set)

    credible = factor_set("credible")
    zone = side_end_zone_of(14.0)
    assert zone == pytest.approx((Geometry().length - 14.0) / 2)
    fs = factor_set("windowed", side_end_zone=zone)
    assert fs == windowed_factor_set(zone) and fs.side_end_zone == zone and credible.side_end_zone == 0.0
    from calibration.data.errors import InputError
    with pytest.raises(InputError, match=r"in \(0, 12.25\)") as bad:  # one check, the file's key named
        windowed_factor_set(13.0)
    assert bad.value.key == "side_end_zone_m"
    assert set(fs.names) == set(credible.names) | {"side_end_shear"} and fs.polish_only == credible.polish_only
    assert fs.swarm_parameters[-1].name == "side_end_shear"  # swarmed, not left to the polish
    model, p = calibrated_box_model({"factor_set": "windowed", "side_end_zone_m": zone,
                                     "parameters": {"side_end_shear": 3.0}})
    assert p["side_end_shear"] == 3.0 and p["side_shear"] == 1.0
    side = model.vehicle.panels[[q.name for q in model.vehicle.panels].index("side_left")]
    strips, whole = side.unit_stiffness(zone)["A66"], side.unit_stiffness()["A66"]
    K = model.K_units["side_end_shear"].toarray()
    block = model.dof_slices["side_left"]
    assert np.allclose(K[block, block], side.rigidity["A66"] * strips)
    assert np.allclose(model.K_units["side_shear"].toarray()[block, block], side.rigidity["A66"] * (whole - strips))


def test_the_orthotropic_set_splits_the_rigidity_across_off_and_stays_positive_definite_over_its_ranges():
    """The orthotropic set: the windowed set with the roof's, floor's and sides' rigidity
    across (D22, A22) a factor of its own. At unit factors it is the windowed model; at the
    corner of its ranges that is most lopsided (lengthwise at the top, across at the bottom)
    every plate's constitutive matrix and the vehicle's stiffness stay positive definite."""
    from calibration.models.box import assemble
    from calibration.models.box.shinkansen import (ACROSS_RANGE, ACROSS_SPLITS, MATERIAL, calibrated_box_model,
                                                   factor_set, shinkansen_vehicle, side_end_zone_of)

    zone = side_end_zone_of(14.0)
    win, fs = factor_set("windowed", side_end_zone=zone), factor_set("orthotropic", side_end_zone=zone)
    across = {f"{name}_across" for name, _, _ in ACROSS_SPLITS}
    along = {f"{name}_along" for name, _, _ in ACROSS_SPLITS}
    assert set(fs.names) == (set(win.names) - {n for n, _, _ in ACROSS_SPLITS}) | along | across
    assert fs.polish_only == win.polish_only
    assert all(q.name not in across for q in fs.parameters[len(fs.parameters) - fs.polish_only:])  # swarmed
    for name, along, term in ACROSS_SPLITS:  # every rigidity of the windowed factor in exactly one of the two
        q, a = fs.parameters[fs.names.index(f"{name}_along")], fs.parameters[fs.names.index(f"{name}_across")]
        whole = win.parameters[win.names.index(name)]
        assert sorted(q.terms + a.terms) == sorted(whole.terms) and a.terms == (term,) and q.terms == along
        top = fs.ranges[fs.names.index(f"{name}_along")][1]
        rig = MATERIAL[q.group][0]
        xx, yy, xy = ("D11", "D22", "D12") if term == "D22" else ("A11", "A22", "A12")
        C = np.array([[top * rig[xx], top * rig[xy]], [top * rig[xy], ACROSS_RANGE[0] * rig[yy]]])
        assert np.linalg.eigvalsh(C).min() > 0, (name, C)
    vehicle = shinkansen_vehicle(parameters=fs.parameters, order_increase=COARSE_BOX_ORDERS)
    ortho = assemble(vehicle)
    windowed = assemble(shinkansen_vehicle(parameters=win.parameters, order_increase=COARSE_BOX_ORDERS))
    K1, K0 = ortho.stiffness(np.ones(len(fs.names))), windowed.stiffness(np.ones(len(win.names)))
    assert abs(K1 - K0).max() <= 1e-9 * abs(K0).max()
    corner = np.array([ACROSS_RANGE[0] if n in across else r[1] if n in along else 1.0
                       for n, r in zip(fs.names, fs.ranges)])
    scipy.linalg.cholesky(ortho.stiffness(corner).toarray())  # raises if not positive definite
    rebuilt, p = calibrated_box_model({"factor_set": "orthotropic", "side_end_zone_m": zone,
                                       "parameters": {"floor_bending_across": 3.0}})
    assert rebuilt.names == fs.names and p["floor_bending_across"] == 3.0 and p["floor_bending_along"] == 1.0


@pytest.mark.slow
def test_independent_swarms_are_each_refined_and_the_lowest_full_model_error_is_the_answer(model):
    """Split into swarms, the particles gather on as many basins; each swarm's best is refined
    and polished, the file keeps all of them, and the answer is the one that ends lowest on
    the full model."""
    from calibration.models.box import factor_set
    from calibration.models.box.mode_types import typed_targets

    fs = factor_set("credible")
    targets = typed_targets({"vertical_bending_1": 9.88, "torsion_1": 15.79}, SENSOR_GRID, 24.5, 3.38)
    cal = calibrate_box(targets, SENSOR_GRID, box_search(factors=fs), factors=fs, order_change=COARSE_BOX_ORDERS,
                        swarm=SwarmSettings(pso=PSOSettings(particles=8, iterations=2, target=0.0), log_factors=True,
                                            swarms=2),
                        refinement=RefineSettings(rounds=1, polish_steps=1), pairing=PairingSettings(min_mac=0.8))
    runs = cal.pso["swarms"]
    assert [r["particles"] for r in runs] == [4, 4] and sum(r["chosen"] for r in runs) == 1
    assert runs[0]["best"] != runs[1]["best"]  # two searches, not one twice
    chosen = next(r for r in runs if r["chosen"])
    assert chosen["end_max_error_pct"] == min(r["end_max_error_pct"] for r in runs) == cal.max_error_pct
    assert cal.pso["evaluations"] == sum(r["evaluations"] for r in runs) >= 2 * 4 * 3  # 3 generations each
    with pytest.raises(ValueError, match="2 or more"):
        SwarmSettings(pso=PSOSettings(particles=8, iterations=2), swarms=5)


@pytest.mark.slow
def test_no_further_swarm_runs_once_one_ends_refined_within_the_done_error(model):
    """The swarm's own stop (the seed's 0.5 %) is no proof of the right basin, so a campaign
    searches on until a swarm ends, refined, within ``done_pct``: met at once, one swarm
    runs; never met, every swarm runs. Without the refinement the swarm's stop decides."""
    from calibration.models.box import factor_set
    from calibration.models.box.mode_types import typed_targets

    fs = factor_set("grouped")
    targets = typed_targets({"vertical_bending_1": 9.88}, SENSOR_GRID, 24.5, 3.38)

    def swarms_run(done_pct, refine=True):
        cal = calibrate_box(targets, SENSOR_GRID, box_search(factors=fs), factors=fs, order_change=COARSE_BOX_ORDERS,
                            swarm=SwarmSettings(pso=PSOSettings(particles=6, iterations=1, target=0.0), swarms=3,
                                                done_pct=done_pct),
                            refinement=RefineSettings(enabled=refine, rounds=1))
        done = done_pct if refine else 0.0
        assert all(r["end_max_error_pct"] > done for r in cal.pso["swarms"][:-1])
        return len(cal.pso["swarms"])

    assert swarms_run(float("inf")) == 1
    assert swarms_run(0.0) == 3
    assert swarms_run(float("inf"), refine=False) == 3  # the swarm's stop, 0.0 here, decides


@pytest.mark.slow
def test_the_box_model_is_calibrated_by_swarm_only(shaker, tmp_path, capsys):
    root = shaker[0]
    assert main(["calibrate", str(root), "--model", "box", "--method", "ce", "--out", str(tmp_path / "c.json")]) == 2
    assert "--method pso" in capsys.readouterr().err
    bad = tmp_path / "t.toml"
    bad.write_text('[[targets]]\nlabel = "wobble"\nfrequency_hz = 10.0\n')
    assert main(["calibrate", "--targets", str(bad), "--model", "box", "--method", "pso",
                 "--out", str(tmp_path / "c.json")]) == 2
    assert "wobble" in capsys.readouterr().err
    good = tmp_path / "g.toml"
    good.write_text('[[targets]]\nlabel = "breathing"\nfrequency_hz = 18.5\n')
    assert main(["calibrate", "--targets", str(good), "--model", "box", "--method", "pso", "--factors", "bespoke",
                 "--out", str(tmp_path / "c.json")]) == 2
    assert "bespoke" in capsys.readouterr().err
    assert main(["calibrate", str(root), "--model", "box", "--method", "pso", "--factors", "credible",
                 "--out", str(tmp_path / "c.json")]) == 2
    err = capsys.readouterr().err
    assert "roof_membrane" in err and "credible factor set does not have" in err and "campaign.toml" in err
    assert main(["calibrate", str(root), "--model", "box", "--method", "pso", "--factors", "bespoke",
                 "--out", str(tmp_path / "c.json")]) == 2
    assert "bespoke" in capsys.readouterr().err
    assert main(["calibrate", str(root), "--model", "box", "--method", "pso", "--factors", "windowed",
                 "--out", str(tmp_path / "c.json")]) == 2
    assert "vehicle.windowed_length" in capsys.readouterr().err
    longer = tmp_path / "longer"
    shutil.copytree(root, longer)
    toml = longer / "campaign.toml"
    toml.write_text(re.sub(r"\[priors\.\w+\]\n(\w+ = [^\n]*\n)+\n?", "", toml.read_text())
                    .replace("length = 24.5\n", "length = 26.4\nwindowed_length = 25.0\n"))  # a longer car
    assert main(["calibrate", str(longer), "--model", "box", "--method", "pso", "--factors", "windowed",
                 "--out", str(tmp_path / "c.json")]) == 2
    assert "no side wall beyond the windows" in capsys.readouterr().err
    bad_fit = tmp_path / "bad_fit.json"
    bad_fit.write_text(json.dumps({"model": "box", "method": "pso", "factor_set": "grouped", "parameters": {},
                                   "max_error_pct": "small"}))
    assert main(["diagnose", str(root), "--calibration", str(bad_fit), "--out", str(tmp_path / "d.json")]) == 2
    assert "bad_fit.json" in (err := capsys.readouterr().err) and "max_error_pct" in err
    assert not (tmp_path / "d.json").exists()
    assert main(["calibrate", "--targets", str(good), "--model", "box", "--method", "pso", "--factors", "windowed",
                 "--out", str(tmp_path / "c.json")]) == 2
    assert "windowed_length" in capsys.readouterr().err
    assert not (tmp_path / "c.json").exists()


@pytest.mark.slow
def test_a_campaign_without_priors_is_calibrated_over_the_chosen_set_within_its_ranges(shaker, tmp_path):
    """A campaign's [priors] are optional: each factor of the chosen set without one is
    searched over the set's own range, the credible set's joint factors joining in the polish."""
    from calibration.calibrate_box import calibrate_box_campaign
    from calibration.models.box import factor_set

    root = tmp_path / "bare"
    shutil.copytree(shaker[0], root)
    toml = root / "campaign.toml"
    toml.write_text(re.sub(r"\[priors\.\w+\]\n(\w+ = [^\n]*\n)+\n?", "", toml.read_text()))
    campaign = open_campaign(root)
    assert campaign.meta.priors == {}
    credible = factor_set("credible")
    cal, _ = calibrate_box_campaign(campaign, factors=credible, order_change=COARSE_BOX_ORDERS, identified=shaker[3],
                                    swarm=SwarmSettings(pso=PSOSettings(particles=8, iterations=2), swarms=1,
                                                        log_factors=True),
                                    refinement=RefineSettings(enabled=True, rounds=1, polish_steps=1))
    assert cal.factor_set == "credible" and set(cal.parameters) == set(credible.names)
    for name, (lo, hi) in zip(credible.names, credible.ranges):
        assert lo <= cal.parameters[name] <= hi
    assert len(cal.fit) >= 1


def test_the_summary_names_a_pairing_a_hair_under_the_mac_floor():
    """A MAC of 0.7999991 rounds to 0.800 but is under a floor of 0.8: the summary says so."""
    from railcal.box import unsound_note
    fit = [{"label": "torsion_1", "mac": 0.884, "sound": True}, {"label": "breathing", "mac": 0.7999991, "sound": False}]
    assert unsound_note(fit) == ", breathing unsound (MAC 0.799999)"
    assert unsound_note(fit[:1]) == ""


@pytest.mark.slow
def test_identify_writes_modes_and_plots_for_a_shaker_campaign(shaker, tmp_path):
    out = tmp_path / "id.json"
    assert main(["identify", str(shaker[0]), "--out", str(out), "--quiet"]) == 0
    data = json.loads(out.read_text())
    assert data["kind"] == "stationary_excitation" and data["modes"]
    assert {"label", "frequency_hz", "damping_ratio", "shape_real", "shape_imag"} <= set(data["modes"][0])
    assert (tmp_path / "id.png").exists() and (tmp_path / "id_mac.png").exists()


def test_an_identification_file_read_back_is_its_modes_and_bad_shapes_are_refused():
    """Read back, the file's modes are the identification's (complex shapes at its sensors);
    a shape of the wrong length or not a number is exit 2 naming the mode."""
    from calibration.data.errors import InputError
    from calibration.identification.excitation import ExcitationMode, IdentifiedShapes

    mode = ExcitationMode("mode_1", 9.9, 0.012, np.array([1.0, 0.5 - 0.25j, -0.3j]), 12, 9.91)
    data = json.loads(json.dumps({"sensors": ["a", "b", "c"], "modes": [mode.to_json()]}))
    back = IdentifiedShapes.from_json(data)
    assert back.sensors == ("a", "b", "c") and back.modes[0].to_json() == mode.to_json()
    for change in ({"shape_imag": [0.0, 0.0]}, {"shape_real": ["x", 1, 2]}, {"frequency_hz": -1.0},
                   {"shape_real": [0, 0, 0], "shape_imag": [0, 0, 0]}):
        with pytest.raises(InputError, match=r"modes\[0\]"):
            IdentifiedShapes.from_json({**data, "modes": [{**data["modes"][0], **change}]})


@pytest.mark.slow
def test_the_model_at_the_truths_factors_matches_the_measured_frfs_and_nominal_does_not(shaker, tmp_path):
    """The FRF comparison of `validate` (magnitude, phase, coherence): the box model with the
    factors that made the test reproduces its FRFs' shapes; at nominal factors it does not."""
    from calibration.validation.excitation import compare_frf

    root, truth, _, ident = shaker
    campaign = open_campaign(root)
    at = {"model": "box", "order_change": COARSE_BOX_ORDERS, "fit": []}
    true = compare_frf(campaign, {**at, "parameters": truth["parameters"]}, ident)
    nominal = compare_frf(campaign, {**at, "parameters": {}}, ident)
    assert np.median(true.frac) >= 0.95 and np.median(nominal.frac) < np.median(true.frac)
    assert true.coherence.shape == true.measured.shape and np.median(true.coherence) > 0.9
    png = true.plot_phase(tmp_path / "phase.png")
    assert png.read_bytes()[:4] == b"\x89PNG"
