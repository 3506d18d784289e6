"""The exudyn build of the box-type vehicle (reference_models.box), issue 6: one CMS flexible
carbody from the free carbody's own modes, rigid bogies and CartesianSpringDamper suspension,
built from the vehicle description and the stiffness factors alone. On the coarse model
(order_change = -4, 969 DOF) it must have railcal's vehicle eigenfrequencies below 20 Hz
(reduced vehicle and full model, 1e-4 relative), railcal's static floor deflection under the
exciter, and railcal's exact floor accelerations to a band-random exciter force
(NRMSE <= 1e-2 per sensor). The full-order figures: ``scripts/crosscheck_box.py``."""
import numpy as np
import pytest

from calibration.models.box.reduction import reduce_vehicle
from calibration.models.simulate import ModalSimulator
from calibration.truth.excitation import (
    EXCITER,
    SENSOR_GRID,
    ExcitationSettings,
    band_random,
    build_model,
)
from fmu_src.reference import nrmse
from reference_models.box import (
    build_box_exudyn,
    eigen_errors,
    exudyn_frequencies,
    full_frequencies,
    reduced_frequencies,
    simulate_box_exudyn,
)

CUTOFF, ZETA = 60.0, 0.02


@pytest.fixture(scope="module")
def coarse():
    model = build_model(ExcitationSettings(order_change=-4))
    p = np.ones(len(model.names))
    return model, p, reduce_vehicle(model, p, CUTOFF, SENSOR_GRID, EXCITER)


@pytest.fixture(scope="module")
def built(coarse):
    model, p, _ = coarse
    return build_box_exudyn(model, p, cutoff_hz=CUTOFF, zeta=ZETA)


def test_the_vehicle_keeps_carbody_coordinates_and_two_six_dof_bogies(coarse, built):
    _, _, reduced = coarse
    mbs, h = built
    dof = mbs.ComputeSystemDegreeOfFreedom()
    # the held frame's six coordinates are constrained; the rest is the reduced vehicle's size
    assert dof["degreeOfFreedom"] == reduced.M.shape[0] and dof["redundantConstraints"] == 0
    assert h.modes.n_modes == reduced.n_modes and len(h.bogies) == 2
    assert set(h.links) == {ln.name for ln in coarse[0].vehicle.links}


def test_eigenfrequencies_below_20_hz_agree_with_the_reduced_and_the_full_model(coarse, built):
    model, p, reduced = coarse
    ours = exudyn_frequencies(built[0], 20.0)
    for theirs in (reduced_frequencies(reduced, 20.0), full_frequencies(model, p, 20.0)):
        assert len(ours) == len(theirs) >= 18  # six carbody-on-suspension, twelve bogie modes
        assert eigen_errors(theirs, ours).max() <= 1e-4


def test_a_static_exciter_force_deflects_the_floor_as_railcal_does(coarse):
    """A constant 500 N upward: exudyn's static solution against K^-1 b F of the reduced vehicle."""
    import exudyn as exu

    model, p, reduced = coarse
    mbs, h = build_box_exudyn(model, p, cutoff_hz=CUTOFF, zeta=ZETA, force=(np.array([0.0, 1.0]),
                                                                             np.array([500.0, 500.0])))
    ss = exu.SimulationSettings()
    ss.staticSolver.verboseMode = 0
    ss.solution.file.write = False
    mbs.SolveStatic(ss)
    eta = mbs.GetNodeOutput(h.modal_node, exu.OutputVariableType.Coordinates)
    rows = np.array([h.modes.basis[3 * h.mesh[s.name] + 2] for s in SENSOR_GRID])
    expected = reduced.S @ np.linalg.solve(reduced.K, 500.0 * reduced.b_force)
    assert np.abs(expected).max() > 1e-4  # [m] the floor does move
    np.testing.assert_allclose(rows @ eta, expected, rtol=1e-6, atol=1e-9 * np.abs(expected).max())


def test_floor_accelerations_to_a_band_random_force_match_railcal_within_nrmse_1e_2(coarse):
    model, p, reduced = coarse
    fs, n = 1000.0, 501
    t = np.arange(n) / fs
    force = band_random(n, fs, (5.0, 50.0), 500.0, np.random.default_rng(7))
    w = np.zeros((n, 9))
    w[:, 8] = force
    ref = ModalSimulator(reduced.state_space(ZETA), 1.0 / fs).step_chunk(w)
    res = simulate_box_exudyn(model, p, t, force, cutoff_hz=CUTOFF, zeta=ZETA, step_size=1e-4)
    assert res.sensors == tuple(s.name for s in SENSOR_GRID)
    np.testing.assert_allclose(res.t, t, atol=1e-9)
    assert np.sqrt(np.mean(ref**2)) > 0.01  # [m/s^2] a real response
    assert max(nrmse(res.acc[:, i], ref[:, i]) for i in range(len(SENSOR_GRID))) <= 1e-2


def test_rail_input_and_bad_damping_are_refused_by_name(coarse):
    model, p, _ = coarse
    with pytest.raises(NotImplementedError, match="rail input"):
        build_box_exudyn(model, p, cutoff_hz=CUTOFF, zeta=ZETA, rail=object())
    with pytest.raises(ValueError, match="zeta"):
        build_box_exudyn(model, p, cutoff_hz=CUTOFF, zeta=-0.1)
