"""Batched model evaluation and the Cross-Entropy optimiser (seed section 6.2)."""
import numpy as np
import pytest

from calibration.models.batch import LinearFamily
from calibration.models.car2d import build_car, frequencies_by_label, undamped_modes
from calibration.models.vehicles import INTERCITY_TRAILER
from calibration.optimisers.cross_entropy import SEED_TABLE7, CEParameter, CESettings, cross_entropy


def test_batched_frequencies_equal_the_single_model_for_every_row():
    fam = LinearFamily.of_car(INTERCITY_TRAILER)
    rng = np.random.default_rng(0)
    base = np.array([getattr(INTERCITY_TRAILER, n) for n in fam.names])
    P = base * (1 + rng.uniform(-0.3, 0.3, (40, len(base))))
    F = fam.frequencies(P)
    for i in range(len(P)):
        ref = frequencies_by_label(undamped_modes(build_car(INTERCITY_TRAILER.replace(**dict(zip(fam.names, P[i]))))))
        for label, f in ref.items():
            assert F[label][i] == pytest.approx(f, rel=1e-12)


def test_batched_family_refuses_parameters_that_are_not_linear():
    with pytest.raises(ValueError, match="L_v"):
        LinearFamily.of_car(INTERCITY_TRAILER, names=("m_v", "L_v"))


def test_cross_entropy_finds_the_minimum_of_a_bowl_inside_truncated_ranges():
    params = (CEParameter("a", 5.0, 3.0, 0.0, 10.0, 0.01), CEParameter("b", 5.0, 3.0, 0.0, 10.0, 0.01))
    target = np.array([2.0, 7.5])
    seen = []

    def objective(X):
        seen.append(X.copy())
        return ((X - target) ** 2).sum(axis=1)

    res = cross_entropy(objective, params, np.random.default_rng(1), settings=CESettings(population=200))
    assert res.converged
    np.testing.assert_allclose(res.mean, target, atol=0.01)
    X = np.vstack(seen)
    assert X.min() >= 0.0 and X.max() <= 10.0  # samples respect the truncation
    assert all(len(s) in (200, 1) for s in seen)  # one batched call per generation


def test_cross_entropy_runs_are_reproducible_from_the_generator_seed():
    fam = LinearFamily.of_car(INTERCITY_TRAILER, names=tuple(p.name for p in SEED_TABLE7))
    target = {"carbody_bounce": 1.08, "carbody_pitch": 2.19, "bogie_bounce": 6.53, "bogie_pitch": 4.31}

    def objective(X):
        F = fam.frequencies(X)
        return sum((F[k] - v) ** 2 for k, v in target.items())  # seed eq. 1

    settings = CESettings(max_generations=60)
    a = cross_entropy(objective, SEED_TABLE7, np.random.default_rng(7), settings=settings)
    b = cross_entropy(objective, SEED_TABLE7, np.random.default_rng(7), settings=settings)
    np.testing.assert_array_equal(a.mean, b.mean)
    assert a.best_value <= a.history[0]["elite_best"]


def test_ce_parameters_refuse_inverted_bounds():
    with pytest.raises(ValueError, match="infeasible"):
        CEParameter("m_v", 38000.0, 1e3, 40000.0, 36000.0, 50.0)


def test_smoothed_ce_over_a_fixed_budget_reaches_the_seed_table_8_neighbourhood():
    # The seed's Table 8: 1.07-1.08 Hz carbody bounce with m_v at its lower bound (Table 9).
    # The literal elite update stalls lower, and so does a smoothed one under the seed's
    # stopping rule (module docstring); smoothed over a fixed 400 generations it gets there.
    fam = LinearFamily.of_car(INTERCITY_TRAILER, names=tuple(p.name for p in SEED_TABLE7))
    target = {"carbody_bounce": 1.08, "carbody_pitch": 2.19, "bogie_bounce": 6.53, "bogie_pitch": 4.31}

    def objective(X):
        F = fam.frequencies(X)
        return sum((F[k] - v) ** 2 for k, v in target.items())

    res = cross_entropy(objective, SEED_TABLE7, np.random.default_rng(0),
                        settings=CESettings(smoothing=0.7, max_generations=400, convergence_fraction=1e-12))
    assert not res.converged and res.generations == 400
    F = fam.frequencies(res.mean[None])
    assert F["carbody_bounce"][0] == pytest.approx(1.08, abs=0.01)
    for label in ("carbody_pitch", "bogie_bounce", "bogie_pitch"):
        assert F[label][0] == pytest.approx(target[label], abs=0.005)
    assert res.mean[0] == pytest.approx(36850.0, abs=5.0)  # m_v on its lower bound, as in the seed
