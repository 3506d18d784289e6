"""The amplitude-dependent suspension extension (issue 31): dry friction statistically
linearised at each cell's amplitude. Its physics (the linearisation's constant, the
suspension's relative velocity) is checked against closed forms and a second route; its
fit on band sums made by the linearised car itself is a unit test of the code, not
evidence that the diagnosis finds friction in data it did not make (that is the bench's,
``scripts/bench_diagnose.py --truth exudyn --only suspension_friction``)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from calibration.diagnosis.in_service import DiagnosisSettings
from calibration.diagnosis.in_service.amplitude import (FRICTION, GAUSSIAN, amplitude_classes, relinearised,
                                                        suspension_rms, viscous)
from calibration.diagnosis.in_service.extensions import EXTENSIONS
from calibration.diagnosis.in_service.hypotheses import Hypothesis
from calibration.diagnosis.in_service.records import Layout, Statistics
from calibration.diagnosis.in_service.response import (FIT_NAMES, ResponseProblem, SensorModel, fit_response,
                                                       transfer)
from calibration.diagnosis.in_service.selection import kept
from calibration.models.assembly import elongation_rows
from calibration.models.car2d import CarExtras, Output, build_car, frequency_response
from calibration.models.vehicles import INTERCITY_TRAILER

from gradient_checks import assert_gradient_is_exact

F = np.geomspace(0.5, 25.0, 90)


def test_dry_friction_linearised_on_a_gaussian_velocity_is_sqrt_2_over_pi_f_over_sigma():
    rng = np.random.default_rng(3)
    for sigma in (0.005, 0.02):
        v = rng.normal(0.0, sigma, 400_000)
        c_eq = np.mean(700.0 * np.sign(v) * v) / np.mean(v * v)  # the mean-square best viscous damper
        assert c_eq == pytest.approx(GAUSSIAN * 700.0 / sigma, rel=0.01)


def test_a_uniform_rail_rise_stretches_no_suspension_element():
    """The car lifted bodily by a unit rise of every rail: springs and dampers do not move."""
    asm = build_car(INTERCITY_TRAILER)
    q = np.linalg.solve(asm.K, asm.B_k @ np.ones(4))
    for name in ("secondary1", "secondary2", "primary1", "primary4"):
        g, h = elongation_rows(asm, name)
        assert g @ q + h.sum() == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(KeyError, match="no spring-damper 'tertiary'"):
        elongation_rows(asm, "tertiary")


def _input_cells(levels, rng, *, one_spectrum: bool = False) -> Statistics:
    """Cells of rail input only, each ``levels[i]`` x a random spectrum (the same one with
    ``one_spectrum``)."""
    stats = Statistics(("u1", "u2", "u3", "u4"), np.r_[F, 26.0], F, 10.0)
    X = rng.normal(size=(F.size, 4, 6)) + 1j * rng.normal(size=(F.size, 4, 6))
    for i, a in enumerate(levels):
        if not one_spectrum and i:
            X = rng.normal(size=(F.size, 4, 6)) + 1j * rng.normal(size=(F.size, 4, 6))
        stats.S[("r", 20.0 + i)] = a * a * X @ X.conj().transpose(0, 2, 1)
        stats.seconds[("r", 20.0 + i)] = 50.0
    return stats


def test_suspension_rms_is_the_relative_velocity_of_the_cars_own_frequency_response():
    """Second route: velocities of the carbody and bogie at the pivot (and of the bogie over
    a wheelset, less the rail's) from the car's frequency response to rail levels."""
    p = INTERCITY_TRAILER
    stats = _input_cells([1.0, 2.0], np.random.default_rng(4), one_spectrum=True)
    got = suspension_rms(p, CarExtras(), stats, set(stats.S))
    outs = [Output("c1", "velocity", "carbody", p.L_v), Output("b1", "velocity", "bogie1", p.L_v),
            Output("c2", "velocity", "carbody", -p.L_v), Output("b2", "velocity", "bogie2", -p.L_v)]
    outs += [Output(f"w{j}", "velocity", f"bogie{1 + j // 2}", x)
             for j, x in enumerate((p.L_v + p.L_b, p.L_v - p.L_b, -p.L_v + p.L_b, -p.L_v - p.L_b))]
    H = frequency_response(build_car(p), outs, F)  # per unit rail level
    w = 2 * np.pi * F
    rail = np.broadcast_to(np.eye(4) * (1j * w)[:, None, None], (F.size, 4, 4))  # the rails' own velocity
    rel = np.concatenate([H[:, 0:1] - H[:, 1:2], H[:, 2:3] - H[:, 3:4], H[:, 4:] - rail], axis=1)
    rel = rel / -(w * w)[:, None, None]  # per unit rail acceleration
    for k, (sig_s, sig_p) in got.items():
        ms = np.einsum("kij,kjl,kil->i", rel, stats.S[k], rel.conj()).real / stats.seconds[k]
        assert sig_s == pytest.approx(np.sqrt(ms[:2].mean()), rel=1e-9)
        assert sig_p == pytest.approx(np.sqrt(ms[2:].mean()), rel=1e-9)
    assert got[("r", 21.0)][0] == pytest.approx(2 * got[("r", 20.0)][0], rel=1e-12)  # linear in the input


def _layout(p) -> Layout:
    return Layout(axle={}, responses=(Output("b1", "acceleration", "bogie1", p.L_v + 0.5),
                                      Output("g1", "pitch_rate", "bogie1"),
                                      Output("c0", "acceleration", "carbody", 0.0),
                                      Output("c1", "acceleration", "carbody", 9.0)),
                  response_sensors=(), L_v=p.L_v, L_b=p.L_b, length=23.0)


@pytest.mark.slow(seconds=8)
def test_response_fit_recovers_secondary_friction_from_cells_of_different_amplitude():
    """Band sums made by the class-linearised car itself (eight cells whose rail inputs
    differ by up to 4x, secondary friction 300 N, each class's sigma consistent with it):
    the fit from a car 10-20 % off finds the friction and a residual near zero; the cost's
    gradient matches central differences. Accelerations per rail acceleration do not change
    when every mass, stiffness and damping (and so the friction) is scaled alike, so the
    friction is checked against the carbody's mass."""
    p_true = INTERCITY_TRAILER
    lay = _layout(p_true)
    start = p_true.replace(m_v=p_true.m_v * 1.1, k_s=p_true.k_s * 0.85, c_s=p_true.c_s * 1.2, k_p=p_true.k_p * 0.9)
    stats = _input_cells(np.geomspace(1.0, 4.0, 8) * 1e-2, np.random.default_rng(5))
    truth = {"friction_secondary": 300.0, "friction_primary": 10.0}
    first = amplitude_classes(start, stats, set(stats.S))
    classes = relinearised(first, p_true, truth, stats, set(stats.S))
    # self-consistent: the quiet classes move less once their friction damps them
    assert classes.sigma[0, 0] < first.sigma[0, 0] and np.all(np.diff(classes.sigma[:, 0]) > 0)
    again = relinearised(classes, p_true, truth, stats, set(stats.S), iterations=1)
    assert again.sigma == pytest.approx(classes.sigma, rel=1e-3)
    stats = Statistics(("u1", "u2", "u3", "u4", "b1", "g1", "c0", "c1"), stats.edges, F, 10.0,
                       {k: _full(S, p_true, classes.added(truth, classes.sigma[classes.of(k)]), lay)
                        for k, S in stats.S.items()}, dict(stats.seconds))
    ext = EXTENSIONS["amplitude_dependent_suspension"]
    bounds = {n: (getattr(p_true, n) / 2, getattr(p_true, n) * 2) for n in FIT_NAMES}
    plain = fit_response(stats, lay, set(stats.S), start, bounds, ext_params=ext.params, make=ext.make)
    fit = fit_response(stats, lay, set(stats.S), start, bounds, ext_params=ext.params, make=ext.make,
                       relinearise=True)
    scale = fit.parameters.m_v / p_true.m_v
    assert fit.values["friction_secondary"] / scale == pytest.approx(300.0, rel=0.01)
    assert fit.values["friction_primary"] / scale < 50.0
    assert np.all(fit.nrp_train < 1e-5)
    # the fitted car carries the damping at the reference amplitude, each cell its class's difference
    ref = classes.added(truth, classes.reference)[0]
    assert fit.parameters.c_s / scale == pytest.approx(p_true.c_s + ref, rel=0.01)
    assert viscous(fit.parameters, fit.values).c_s / scale == pytest.approx(p_true.c_s, rel=0.01)
    # on the start car's amplitudes alone the spread is too narrow and the friction too large
    assert plain.values["friction_secondary"] / (plain.parameters.m_v / p_true.m_v) > 1.5 * 300.0
    quiet, rough = min(stats.S, key=lambda k: k[1]), max(stats.S, key=lambda k: k[1])
    assert fit.damping[quiet][0] > 0 > fit.damping[rough][0]

    problem = ResponseProblem(stats, lay, set(stats.S), start, bounds, ext.params, ext.make, amplitude=classes)
    assert len(problem.groups) == 4
    assert_gradient_is_exact(problem)


def _full(Suu, p, added, lay):
    """A cell's band sums (inputs and responses) of car ``p`` with damping ``added``."""
    p = p.replace(c_s=p.c_s + added[0], c_p=p.c_p + added[1])
    G = transfer(p, CarExtras(), SensorModel(), lay, F)
    S = np.zeros((F.size, 8, 8), complex)
    S[:, :4, :4], S[:, 4:, :4] = Suu, G @ Suu
    S[:, :4, 4:], S[:, 4:, 4:] = (G @ Suu).conj().transpose(0, 2, 1), G @ Suu @ G.conj().transpose(0, 2, 1)
    return S


def test_friction_is_a_property_and_may_be_absent_from_the_primary_but_not_pinned_at_its_top():
    """Every suspension has some friction: a property at any size. A primary without
    friction is fitted at the range's low end, which is the effect absent there, not a
    parameter standing in for something else; at the top of its range it stands in."""
    s, ext = DiagnosisSettings(), EXTENSIONS["amplitude_dependent_suspension"]
    assert ext.always_normal and ext.absent_at_low == FRICTION
    h = Hypothesis(extension=ext, evidence_score=0.0, parameters={"friction_secondary": 1200.0,
                                                                  "friction_primary": 10.0},
                   parameters_at_bounds=(), model={}, heldout_error={}, residual=None, systematic_left=0.1,
                   systematic_after=0.05, best_channel="bogie1_acc_z", gain=0.4, worst_change=0.0, losses=(),
                   penalised_gain=0.38, fit=None)
    assert kept(ext, h, s)
    assert kept(ext, replace(h, parameters_at_bounds=("friction_primary",)), s)
    top = replace(h, parameters={"friction_secondary": 5000.0, "friction_primary": 10.0},
                  parameters_at_bounds=("friction_secondary", "friction_primary"))
    assert not kept(ext, top, s)


def test_a_model_with_friction_says_at_which_amplitude_its_damping_holds():
    """The extended model handed on is linear: its c_s and c_p carry the friction's damping
    at the training runs' amplitude, and the file says so with the friction."""
    from calibration.diagnosis.in_service.response import ResponseFit
    from calibration.diagnosis.in_service.result import InServiceDiagnosis

    values = {"friction_secondary": 800.0, "friction_primary": 10.0,
              "amplitude_reference_m_per_s": {"secondary": 0.012, "primary": 0.02}}
    p = INTERCITY_TRAILER.replace(c_s=INTERCITY_TRAILER.c_s + GAUSSIAN * 800.0 / 0.012)
    fit = ResponseFit(p, CarExtras(), SensorModel(), values, np.zeros(2), (), 1)
    plain = ResponseFit(INTERCITY_TRAILER, CarExtras(), SensorModel(), {}, np.zeros(2), (), 1)
    blank = dict.fromkeys(("campaign", "cause", "summary", "evidence", "hypotheses", "best", "start", "bounds",
                           "training_runs", "heldout_runs", "settings", "layout", "statistics", "detectability"))
    out = InServiceDiagnosis(**blank, baseline=plain, extended=fit).model_json()
    assert out["parameters"]["c_s"] == pytest.approx(p.c_s)
    assert viscous(p, values).c_s == pytest.approx(INTERCITY_TRAILER.c_s)
    lin = out["linearised"]["amplitude_dependent_suspension"]
    assert lin["friction_secondary"] == 800.0 and lin["reference_rms_velocity_m_per_s"]["secondary"] == 0.012
    assert "linearised" not in InServiceDiagnosis(**blank, baseline=plain).model_json()


def test_a_held_out_journeys_load_is_fitted_with_the_damping_its_amplitude_adds():
    """Journey loads and friction together, on band sums made by the linearised car: two
    training runs (loads 0 and +10 %) and a held-out run at load 0, each in four speed
    cells of different amplitude. The held-out run's load, fitted on half its cells and
    judged on the other half, must come out as its own (against the training mean), not
    absorb the damping its amplitude adds."""
    from calibration.diagnosis.in_service.extensions import combined
    from calibration.diagnosis.in_service.response import loaded

    p_true = INTERCITY_TRAILER
    lay = _layout(p_true)
    rng = np.random.default_rng(8)
    runs = {"r1": 0.0, "r2": 0.10, "r3": 0.0}
    u = Statistics(("u1", "u2", "u3", "u4"), np.r_[F, 26.0], F, 10.0)
    for run in runs:
        for i, a in enumerate((1.0, 1.6, 2.4, 3.5)):
            X = rng.normal(size=(F.size, 4, 6)) + 1j * rng.normal(size=(F.size, 4, 6))
            u.S[(run, 20.0 + i)], u.seconds[(run, 20.0 + i)] = (a * 1e-2) ** 2 * X @ X.conj().transpose(0, 2, 1), 50.0
    train = {k for k in u.S if k[0] != "r3"}
    held = set(u.S) - train
    truth = {"friction_secondary": 300.0, "friction_primary": 10.0}
    classes = amplitude_classes(p_true, u, train, held)
    S = {}
    for k, Suu in u.S.items():
        p, _ = loaded(p_true, CarExtras(), runs[k[0]])
        S[k] = _full(Suu, p, classes.added(truth, classes.sigma[classes.of(k)]), lay)
    stats = Statistics(("u1", "u2", "u3", "u4", "b1", "g1", "c0", "c1"), u.edges, F, 10.0, S, dict(u.seconds))
    ext = combined(EXTENSIONS["journey_load"], EXTENSIONS["amplitude_dependent_suspension"])
    bounds = {n: (getattr(p_true, n) / 2, getattr(p_true, n) * 2) for n in FIT_NAMES}
    fit = fit_response(stats, lay, train, p_true, bounds, ext_params=ext.params, make=ext.make, per_run=True,
                       heldout_keys=held)
    assert fit.values["journey_loads"]["r3"] == pytest.approx(1 / 1.05 - 1, abs=0.005)
    assert fit.values["journey_loads"]["r2"] == pytest.approx(1.10 / 1.05 - 1, abs=0.005)
    # the exact gradient holds with a load per run and a damping per amplitude class (8 groups)
    problem = ResponseProblem(stats, lay, train, p_true, bounds, ext.params, ext.make, per_run=True,
                              amplitude=classes)
    assert len(problem.groups) > 4
    assert_gradient_is_exact(problem)
