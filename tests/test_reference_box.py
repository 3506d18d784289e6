"""The exudyn build of the box-type vehicle (reference_models.box), issue 6: a modal flexible
carbody from the free carbody's own modes (its modal equations an ObjectGenericODE2, its
attachment points a CMS body on the same coordinates), rigid bogies and CartesianSpringDamper
suspension, built from the vehicle description and the stiffness factors alone. On the coarse model
(order_change = -4, 969 DOF) it must have railcal's vehicle eigenfrequencies below 20 Hz
(reduced vehicle and full model, 1e-4 relative), railcal's static floor deflection under the
exciter, and railcal's exact floor accelerations to a band-random exciter force
(NRMSE <= 1e-2 per sensor); over the track (conftest's car_track at 40 m/s, axle boxes on
the rail levels) its floor accelerations must match railcal's exact reduced-vehicle
response and the stand-alone box FMU (FMI 2, fmpy, 1 ms) within NRMSE 1e-2 per sensor.
The full-order figures: ``scripts/crosscheck_box.py``."""
import fmpy
import numpy as np
import pytest
from conftest import CAR_FMU_SPEED as SPEED
from conftest import CAR_FMU_START as START

from calibration.models.box.vehicle_reduction import reduce_vehicle
from calibration.models.simulate import ModalSimulator
from calibration.models.box.rig import EXCITER, SENSOR_GRID
from calibration.models.box.shinkansen import shinkansen_model
from calibration.signals.filters import band_random
from fmu_src.box import box_spec
from fmu_src.build import build_fmu
from fmu_src.reference import box_reference, nrmse
from reference_models.box import (
    build_box_exudyn,
    eigen_errors,
    exudyn_frequencies,
    full_frequencies,
    reduced_frequencies,
    simulate_box_exudyn,
)
from reference_models.rail import RailInput

CUTOFF, ZETA = 60.0, 0.02


@pytest.fixture(scope="module")
def coarse():
    model = shinkansen_model(-4)
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


def test_one_computation_of_the_carbody_modes_serves_several_builds(coarse, built):
    """The modal data of one build make another with the same frequencies; modal data for a
    different cut-off are refused by name."""
    model, p, _ = coarse
    mbs, h = built
    again, h2 = build_box_exudyn(model, p, cutoff_hz=CUTOFF, zeta=ZETA, modes=h.modes)
    assert h2.modes is h.modes
    np.testing.assert_allclose(exudyn_frequencies(again, 20.0), exudyn_frequencies(mbs, 20.0), rtol=1e-12)
    with pytest.raises(ValueError, match="modes: computed for a cut-off of 60.0 Hz, here 40.0 Hz"):
        build_box_exudyn(model, p, cutoff_hz=40.0, zeta=ZETA, modes=h.modes)


def test_the_carbody_mass_and_stiffness_are_its_modal_equations_alone(coarse, built):
    """exudyn's linearised system on the carbody's modal coordinates: mass I and, with the
    bogies and suspension taken out of the stiffness, diag(omega^2); the CMS body (FFRF terms
    off, frame held) adds nothing."""
    import exudyn as exu

    mbs, h = built
    ss = exu.SimulationSettings()
    ss.staticSolver.newton.numericalDifferentiation.jacobianConnectorDerivative = False  # as exudyn_frequencies
    M, K, _ = mbs.ComputeLinearizedSystem(ss)
    ltg = mbs.GetNodeODE2Index(h.modal_node)
    n = h.modes.omega.size
    sl = slice(ltg, ltg + n)
    np.testing.assert_allclose(np.asarray(M)[sl, sl], np.eye(n), atol=1e-12)
    # the suspension's part of K on eta: D^T k D over the seats, from the attachment rows
    Kc = np.asarray(K)[sl, sl] - np.diag(h.modes.omega**2)
    assert np.abs(Kc).max() > 0  # the suspension does act on the carbody ...
    seats = [ln for ln in coarse[0].vehicle.links if ln.name in h.mesh]
    Ks = sum(h.modes.basis[3 * h.mesh[ln.name]:3 * h.mesh[ln.name] + 3].T @ np.diag(ln.k)
             @ h.modes.basis[3 * h.mesh[ln.name]:3 * h.mesh[ln.name] + 3] for ln in seats)
    np.testing.assert_allclose(Kc, Ks, rtol=1e-9, atol=1e-9 * np.abs(Ks).max())  # ... and nothing else


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
    res = simulate_box_exudyn(model, p, duration=t[-1], force=(t, force), cutoff_hz=CUTOFF, zeta=ZETA, step_size=1e-4)
    assert res.sensors == tuple(s.name for s in SENSOR_GRID)
    np.testing.assert_allclose(res.t, t, atol=1e-9)
    assert np.sqrt(np.mean(ref**2)) > 0.01  # [m/s^2] a real response
    assert max(nrmse(res.acc[:, i], ref[:, i]) for i in range(len(SENSOR_GRID))) <= 1e-2


@pytest.fixture(scope="module")
def over_the_track(coarse, car_track, tmp_path_factory):
    """0.5 s over the track at 40 m/s, no exciter force: (t, exudyn response, railcal, FMU)."""
    model, p, reduced = coarse
    path, profile = car_track
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    rail = RailInput(table[:, 0], table[:, 1], SPEED, START)
    res = simulate_box_exudyn(model, p, duration=0.5, rail=rail, cutoff_hz=CUTOFF, zeta=ZETA, step_size=2e-4)
    t = res.t
    ref = box_reference(reduced, ZETA, profile, SPEED, t, np.zeros(t.size), start=START)
    fmu = build_fmu(box_spec({"model": "box", "parameters": {}},
                             points=(SENSOR_GRID, EXCITER), reduced=reduced, track=path), 2,
                    tmp_path_factory.mktemp("box_ref") / "box2.fmu")
    out = fmpy.simulate_fmu(str(fmu.path), stop_time=t[-1], step_size=1e-3, output_interval=1e-3,
                            start_values={"speed": SPEED, "track_start": START, "zeta_carbody": ZETA},
                            output=[s.name for s in SENSOR_GRID])
    return t, res, ref, np.column_stack([out[s.name] for s in SENSOR_GRID])


def test_floor_accelerations_over_the_track_match_railcal_and_the_fmu_within_nrmse_1e_2(over_the_track):
    t, res, ref, fmu = over_the_track
    assert res.sensors == tuple(s.name for s in SENSOR_GRID) and fmu.shape == ref.shape == res.acc.shape
    np.testing.assert_allclose(t, np.arange(501) * 1e-3, atol=1e-9)  # [s] 1 ms samples over 0.5 s
    assert np.sqrt(np.mean(ref**2)) > 0.05  # [m/s^2] the track shakes the floor (measured 0.12)
    # started in static equilibrium on the rail: the floor is at rest at t = 0
    assert np.abs(res.acc[0]).max() <= 1e-6 * np.abs(ref).max()
    railcal = [nrmse(res.acc[:, i], ref[:, i]) for i in range(len(SENSOR_GRID))]
    fmi = [nrmse(res.acc[:, i], fmu[:, i]) for i in range(len(SENSOR_GRID))]
    assert max(railcal) <= 1e-2, max(railcal)  # measured 7.3e-4 (step 2e-4 s)
    assert max(fmi) <= 1e-2, max(fmi)  # measured 7.3e-4; the FMU itself is within 8e-6 of railcal


def test_bad_rail_and_bad_damping_are_refused_by_name(coarse):
    model, p, _ = coarse
    with pytest.raises(TypeError, match="RailInput"):
        build_box_exudyn(model, p, cutoff_hz=CUTOFF, zeta=ZETA, rail=object())
    short = RailInput(np.array([0.0, 50.0, 100.0]), np.zeros(3), SPEED, 50.0)
    with pytest.raises(ValueError, match="covers only 0.00-100.00 m"):
        simulate_box_exudyn(model, p, duration=2.0, rail=short, cutoff_hz=CUTOFF, zeta=ZETA)
    with pytest.raises(ValueError, match="zeta"):
        build_box_exudyn(model, p, cutoff_hz=CUTOFF, zeta=-0.1)
