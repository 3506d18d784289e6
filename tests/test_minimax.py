"""The linearised minimax step of the sequential-LP frequency fit: it meets the targets
where the linearisation allows, shares the error equally when the region binds, and keeps
a quantity above its floor (a pairing's MAC) at the cost of the frequencies."""
import numpy as np
import pytest

from calibration.optimisers.minimax import linearised_minimax

RATIO = np.array([1.02, 0.97])  # two model frequencies over their targets
G = np.eye(2)  # each moved by its own log factor only
Q, LO, HI = np.zeros(2), np.full(2, -1.0), np.full(2, 1.0)


def test_a_step_inside_the_region_meets_every_target():
    d, t = linearised_minimax(RATIO, G, Q, LO, HI, trust=0.05)
    assert d == pytest.approx([-0.02, 0.03], abs=1e-9)
    assert t == pytest.approx(0.0, abs=1e-9)


def test_a_small_region_leaves_the_largest_error_at_what_the_region_cannot_reach():
    d, t = linearised_minimax(RATIO, G, Q, LO, HI, trust=0.01)
    assert t == pytest.approx(0.02)  # the second target: 3 % off, moved 1 %
    assert np.max(np.abs(RATIO + G @ d - 1)) == pytest.approx(t)


def test_the_bounds_limit_the_step_as_the_region_does():
    _, t = linearised_minimax(RATIO, G, Q, LO, np.array([1.0, 0.01]), trust=0.05)
    assert t == pytest.approx(0.02)


def test_a_floor_on_another_quantity_is_kept_at_the_cost_of_the_fit():
    # a MAC of 0.81 that moves with the first log factor (slope 1), floor 0.8: the first
    # factor may fall by at most 0.01, so the first target stays 1 % high
    keep, keep_grad = np.array([0.81]), np.array([[1.0, 0.0]])
    d, t = linearised_minimax(RATIO, G, Q, LO, HI, 0.05, keep, keep_grad, 0.8)
    assert d[0] == pytest.approx(-0.01)
    assert t == pytest.approx(0.01)
    assert 0.81 + keep_grad @ d >= 0.8 - 1e-12


def test_a_floor_the_region_cannot_reach_has_no_step():
    assert linearised_minimax(RATIO, G, Q, LO, HI, 0.05, np.array([0.7]), np.array([[1.0, 0.0]]), 0.8) is None


def test_a_mac_under_its_floor_is_lifted_back_only_where_the_scored_penalty_outweighs_the_frequency():
    # one target met exactly; its MAC 0.79 rises with the factor (slope 1), its frequency too
    # (slope 0.5); the score adds weight x the shortfall under 0.8
    ratio, g, mac, J = np.array([1.0]), np.array([[0.5]]), np.array([0.79]), np.array([[1.0]])
    q, lo, hi = np.zeros(1), np.full(1, -1.0), np.full(1, 1.0)
    d, t = linearised_minimax(ratio, g, q, lo, hi, 0.05, penalty=(mac, J, 0.8, 10.0))
    assert d[0] == pytest.approx(0.01) and t == pytest.approx(0.005)  # lifted to the floor: 0.5 % off
    d, t = linearised_minimax(ratio, g, q, lo, hi, 0.05, penalty=(mac, J, 0.8, 0.4))
    assert d[0] == pytest.approx(0.0, abs=1e-12) and t == pytest.approx(0.004)  # cheaper to stay under
    d, t = linearised_minimax(ratio, g, q, lo, hi, 0.05)
    assert d[0] == pytest.approx(0.0, abs=1e-12) and t == pytest.approx(0.0, abs=1e-12)  # no penalty: frequencies only


def test_a_step_cost_leaves_the_factors_the_errors_do_not_see_where_they_are():
    # a third factor moves nothing: without a cost the LP may put it anywhere in the region
    # (a vertex: its edge); with a small cost it stays, and the largest error falls as before
    g = np.hstack([G, np.zeros((2, 1))])
    q, lo, hi = np.zeros(3), np.full(3, -1.0), np.full(3, 1.0)
    d, t = linearised_minimax(RATIO, g, q, lo, hi, trust=0.01, step_cost=1e-4)
    assert d[2] == pytest.approx(0.0, abs=1e-12)
    assert t == pytest.approx(0.02)  # the same reach as without the cost
    assert d[:2] == pytest.approx([0.0, 0.01], abs=1e-12)  # and of the first only what the max needs: none
    # a step gaining less than it costs is not taken: 0.01 % off, the factor moves it one for one
    d, t = linearised_minimax(np.array([1.0001]), np.eye(1), np.zeros(1), np.full(1, -1.0), np.full(1, 1.0),
                              trust=0.01, step_cost=2.0)
    assert d[0] == pytest.approx(0.0, abs=1e-12) and t == pytest.approx(1e-4)
