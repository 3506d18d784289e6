"""The exudyn build of the 2D car (reference_models.car2d), issue 6: built from the parameter
object alone, it must have railcal's eigenvalues (undamped to 1e-6, damped to 1e-4, relative)
and railcal's response over a track (NRMSE <= 1e-3 per output), and the remaining
difference must be exudyn's time-integration error.

The 10 s figure and its wall time are printed by ``scripts/crosscheck_car.py``; here the
runs are 1-2 s.

The extended car (``CarExtras``: centre of mass offset, carbody bending, air-spring
reservoirs, flexible track, hung equipment) is held to the same tolerances, each addition
alone and all together (``EXTENDED``)."""
from dataclasses import replace

import exudyn as exu
import numpy as np
import pytest
from conftest import CAR_FMU_SPEED as SPEED
from conftest import CAR_FMU_START as START

from calibration.models.car2d import CarExtras, build_car, hung_body, wheelset_positions
from calibration.models.vehicles import INTERCITY_TRAILER as CAR
from calibration.models.vehicles import VEHICLES
from fmu_src.reference import car_reference, nrmse, smooth_profile
from fmu_src.variables import car2d_spec
from reference_models.car2d import (BODIES, OUTPUTS, IntegratorSettings, build_car_exudyn, carbody_rest, eigen_errors,
                                    exudyn_eigenvalues, railcal_eigenvalues, simulate_car_exudyn)
from reference_models.rail import RailInput

VEHICLE_NAMES = sorted(VEHICLES)


def _equipment(mass=1500.0, x=-2.3, hz=8.0, zeta=0.1):
    """A tank of ``mass`` [kg] hung under the carbody at ``x`` [m] on a ``hz`` mount."""
    w = 2 * np.pi * hz
    return hung_body("tank", mass, x, mass * w * w, 2 * zeta * mass * w)


_TANK, _MOUNT = _equipment()
#: Each addition of railcal's extended car alone, and all together ("all").
EXTENDED = {
    "cog": CarExtras(cog_offset=0.8),
    "bending": CarExtras(bending_hz=9.0, bending_node=0.5),
    "reservoir": CarExtras(reservoir_ratio=0.6, reservoir_corner_hz=2.5),
    "track": CarExtras(track_stiffness=60e6),
    "hung": CarExtras(bodies=(_TANK,), elements=(_MOUNT,)),
    "hung_in_m_v": CarExtras(bodies=(_TANK,), elements=(_MOUNT,), hung_in_m_v=True),
    "all": CarExtras(cog_offset=0.8, bending_hz=9.0, bending_node=0.5, reservoir_ratio=0.6, reservoir_corner_hz=2.5,
                     track_stiffness=60e6, bodies=(_TANK,), elements=(_MOUNT,), hung_in_m_v=True),
}
#: The same, each addition changed by 10 %: what the tolerances must be able to see.
PERTURBED = {
    "cog": replace(EXTENDED["cog"], cog_offset=0.88),
    "bending": replace(EXTENDED["bending"], bending_hz=9.9),
    "reservoir": replace(EXTENDED["reservoir"], reservoir_ratio=0.66),
    "track": replace(EXTENDED["track"], track_stiffness=66e6),
    "hung": replace(EXTENDED["hung"], bodies=(_equipment(mass=1650.0)[0],)),
    "hung_in_m_v": replace(EXTENDED["hung_in_m_v"], bodies=(_equipment(mass=1650.0)[0],)),
    "all": replace(EXTENDED["all"], bending_node=0.55),
}


@pytest.fixture(scope="module")
def track_rail():
    """The FMU tests' track (900 m, seed 3) as the exudyn car's rail input, and its spline."""
    s, z, profile = smooth_profile(900.0, seed=3)
    return RailInput(s, z, SPEED, START), profile


# ------------------------------------------------------------------ what is built

def test_the_car_keeps_bounce_and_pitch_of_three_bodies_and_nothing_else():
    mbs, h = build_car_exudyn(CAR)
    dof = mbs.ComputeSystemDegreeOfFreedom()
    assert dof["degreeOfFreedom"] == 6 and dof["redundantConstraints"] == 0
    assert set(h.coordinates) == {f"{b}_{q}" for b in BODIES for q in ("z", "pitch")}
    assert len(h.rail_constraints) == 4 and len(h.longitudinal_constraints) == 3 and len(h.springs) == 6


def test_on_a_rail_rising_forward_the_car_starts_relaxed_and_nose_up():
    """Rail level = a s: resting on it with every spring relaxed, each body sits at the rail
    level under its centre and pitches by -a (railcal's pitch lowers the front)."""
    a, start = 2e-3, 50.0
    s = np.linspace(0.0, 200.0, 81)
    mbs, h = build_car_exudyn(CAR, rail=RailInput(s, a * s, speed=10.0, start=start))
    q = mbs.systemData.GetODE2Coordinates(configuration=exu.ConfigurationType.Initial)
    x = {"carbody": 0.0, "bogie1": CAR.L_v, "bogie2": -CAR.L_v}
    for b in BODIES:
        (iz, sz), (ip, sp) = h.coordinates[f"{b}_z"], h.coordinates[f"{b}_pitch"]
        assert sz * q[iz] == pytest.approx(a * (start + x[b]), rel=1e-12)
        assert sp * q[ip] == pytest.approx(-a, rel=1e-12)


# ------------------------------------------------------------------ eigenvalues

@pytest.mark.parametrize("name", VEHICLE_NAMES)
def test_undamped_frequencies_agree_with_railcal_to_1e_6(name):
    p = VEHICLES[name]
    ours, theirs = railcal_eigenvalues(p, damped=False), exudyn_eigenvalues(p, damped=False)
    assert len(theirs) == 6
    assert eigen_errors(ours, theirs).max() <= 1e-6, (ours, theirs)


@pytest.mark.parametrize("name", VEHICLE_NAMES)
def test_damped_eigenvalues_agree_with_railcal_to_1e_4(name):
    p = VEHICLES[name]
    ours, theirs = railcal_eigenvalues(p, damped=True), exudyn_eigenvalues(p, damped=True)
    assert len(theirs) == 6 and np.all(theirs.real < 0)
    assert eigen_errors(ours, theirs).max() <= 1e-4, (ours, theirs)


@pytest.mark.parametrize("name", VEHICLE_NAMES)
def test_bogie_pitch_is_the_closed_form_pair(name):
    """The secondary acts at the bogie centre, so bogie pitch is decoupled:
    J_b th'' + 2 c_p L_b^2 th' + 2 k_p L_b^2 th = 0, once per bogie."""
    p = VEHICLES[name]
    k, c = 2 * p.k_p * p.L_b**2 / p.J_b, 2 * p.c_p * p.L_b**2 / p.J_b
    f = exudyn_eigenvalues(p, damped=False)
    assert np.sum(np.isclose(f, np.sqrt(k) / (2 * np.pi), rtol=1e-12)) == 2
    lam = exudyn_eigenvalues(p, damped=True)
    assert np.sum(np.isclose(lam, complex(-c / 2, np.sqrt(k - c**2 / 4)), rtol=1e-12)) == 2


# ------------------------------------------------------------------ the extended car

@pytest.mark.parametrize("extension", sorted(EXTENDED))
def test_the_extended_car_has_the_degrees_of_freedom_and_elements_of_railcal(extension):
    ex = EXTENDED[extension]
    asm = build_car(CAR, extras=ex)
    mbs, h = build_car_exudyn(CAR, extras=ex)
    dof = mbs.ComputeSystemDegreeOfFreedom()
    assert dof["degreeOfFreedom"] == len(asm.dofs) and dof["redundantConstraints"] == 0
    # on a flexible track railcal's wheelset coordinate is the centre of mass of the wheelset
    # and its track mass, exudyn's the two levels with the rail's between them: no one coordinate
    centres = {f"wheelset{j}_z" for j in range(1, 5)} if ex.track_stiffness is not None else set()
    assert set(h.coordinates) == set(asm.dofs) - centres
    assert set(h.springs) == {e.name for e in asm.elements}


@pytest.mark.parametrize("name", VEHICLE_NAMES)
@pytest.mark.parametrize("extension", sorted(EXTENDED))
def test_extended_undamped_frequencies_agree_with_railcal_to_1e_6(extension, name):
    p, ex = VEHICLES[name], EXTENDED[extension]
    ours, theirs = railcal_eigenvalues(p, damped=False, extras=ex), exudyn_eigenvalues(p, damped=False, extras=ex)
    assert eigen_errors(ours, theirs).max() <= 1e-6, (ours, theirs)


@pytest.mark.parametrize("name", VEHICLE_NAMES)
@pytest.mark.parametrize("extension", sorted(EXTENDED))
def test_extended_damped_eigenvalues_agree_with_railcal_to_1e_4(extension, name):
    p, ex = VEHICLES[name], EXTENDED[extension]
    ours, theirs = railcal_eigenvalues(p, damped=True, extras=ex), exudyn_eigenvalues(p, damped=True, extras=ex)
    assert np.all(theirs.real < 0)
    assert eigen_errors(ours, theirs).max() <= 1e-4, (ours, theirs)


@pytest.mark.parametrize("extension", sorted(EXTENDED))
def test_a_tenth_more_of_any_addition_fails_the_eigenvalue_tolerances(extension):
    """The tolerances can see each addition: exudyn's car with one addition 10 % off is
    far outside them against railcal's."""
    ex, off = EXTENDED[extension], PERTURBED[extension]
    undamped = eigen_errors(railcal_eigenvalues(CAR, damped=False, extras=ex),
                            exudyn_eigenvalues(CAR, damped=False, extras=off))
    damped = eigen_errors(railcal_eigenvalues(CAR, damped=True, extras=ex),
                          exudyn_eigenvalues(CAR, damped=True, extras=off))
    assert undamped.max() > 100 * 1e-6 and damped.max() > 10 * 1e-4, (undamped, damped)


def test_equipment_carved_out_of_m_v_leaves_the_whole_carbody_as_weighed():
    """The rigid rest plus the tank keep m_v, the centre at cog_offset and J_v about it;
    railcal's carbody is the same rest body."""
    ex = EXTENDED["all"]
    m, x, J = carbody_rest(CAR, ex)
    assert m + _TANK.mass == pytest.approx(CAR.m_v, rel=1e-14)
    assert (m * x + _TANK.mass * _TANK.x) / CAR.m_v == pytest.approx(ex.cog_offset, rel=1e-12)
    assert J + m * (x - ex.cog_offset) ** 2 + _TANK.mass * (_TANK.x - ex.cog_offset) ** 2 == \
        pytest.approx(CAR.J_v, rel=1e-12)
    railcal = next(b for b in build_car(CAR, extras=ex).bodies if b.name == "carbody")
    assert (m, x, J) == pytest.approx((railcal.mass, railcal.x, railcal.inertia), rel=1e-12)


def test_on_a_rail_rising_forward_the_extended_car_starts_relaxed_and_nose_up():
    """Rail level = a s: every body of the extended car rests at the rail level under its
    centre, pitches by -a, the carbody unbent; the wheelsets ride on the relaxed track, the
    track masses at zero, moving as railcal's static start has it (the centre of mass of
    wheelset and track mass at rest: the track down at m_w / (m_w + m_t) of the rail's rate,
    the wheelset up at the rest of it)."""
    a, start, speed = 2e-3, 50.0, 10.0
    s = np.linspace(0.0, 200.0, 81)
    ex = EXTENDED["all"]
    mbs, h = build_car_exudyn(CAR, rail=RailInput(s, a * s, speed=speed, start=start), extras=ex)
    q = mbs.systemData.GetODE2Coordinates(configuration=exu.ConfigurationType.Initial)
    v = mbs.systemData.GetODE2Coordinates_t(configuration=exu.ConfigurationType.Initial)
    share = CAR.m_w / (CAR.m_w + ex.track_mass)
    for j, xw in enumerate(wheelset_positions(CAR), start=1):
        track, wheel = (mbs.GetNodeODE2Index(h.nodes[f"{n}{j}"]) for n in ("track", "wheelset"))
        assert (q[track], v[track]) == pytest.approx((0.0, -share * a * speed), abs=1e-15)
        assert (q[wheel], v[wheel]) == pytest.approx((a * (start + xw), (1 - share) * a * speed), rel=1e-12)
    x = {b.name: b.x for b in build_car(CAR, extras=ex).bodies}
    expected = {"carbody_bending": 0.0}
    for body, xb in x.items():
        expected[f"{body}_z"] = a * (start + xb)
        expected[f"{body}_pitch"] = -a
    assert set(h.coordinates) <= set(expected)
    for dof, (i, sign) in h.coordinates.items():
        assert sign * q[i] == pytest.approx(expected[dof], rel=1e-12, abs=1e-15), dof
    for x_point, (node, _) in h.carbody_points.items():  # the bending carbody's attachment points
        assert q[mbs.GetNodeODE2Index(node)] == pytest.approx(a * (start + x_point), rel=1e-12)


@pytest.mark.parametrize("extras, match", [
    (CarExtras(bodies=(replace(_TANK, inertia=100.0),), elements=(_MOUNT,)), "'tank': .* point masses only"),
    (CarExtras(bodies=(_TANK,), elements=(replace(_MOUNT, bottom=replace(_MOUNT.top, body=None, x=0.0,
                                                                           input="z_rail_1")),)),
     "'tank_mount' ends on the input 'z_rail_1'"),
    (CarExtras(bodies=(_equipment(mass=40000.0)[0],), elements=(_MOUNT,), hung_in_m_v=True),
     r"leave the rigid carbody -1253 kg"),
])
def test_additions_the_exudyn_car_cannot_build_are_refused_saying_which(extras, match):
    with pytest.raises(ValueError, match=match):
        build_car_exudyn(CAR, extras=extras)


def test_extended_response_over_the_track_matches_railcal_within_nrmse_1e_3(track_rail):
    rail, profile = track_rail
    ex = EXTENDED["all"]
    res = simulate_car_exudyn(CAR, rail, duration=0.5, output_interval=1e-3, extras=ex)
    ref = car_reference(car2d_spec(CAR.as_dict(), extras=ex), CAR, profile, SPEED, res.t, start=START, extras=ex)
    errors = {n: nrmse(res.outputs[n], ref[n]) for n in OUTPUTS}
    assert max(errors.values()) <= 1e-3, errors
    assert res.outputs["carbody_acc_z"][0] == pytest.approx(ref["carbody_acc_z"][0], rel=1e-6)  # same start


# ------------------------------------------------------------------ response over a track

def test_response_over_the_track_matches_railcal_within_nrmse_1e_3(track_rail):
    rail, profile = track_rail
    res = simulate_car_exudyn(CAR, rail, duration=2.0, output_interval=1e-3)
    ref = car_reference(car2d_spec(CAR.as_dict()), CAR, profile, SPEED, res.t, start=START)
    assert res.t[0] == 0.0 and res.t[-1] == pytest.approx(2.0) and len(res.t) == 2001
    errors = {n: nrmse(res.outputs[n], ref[n]) for n in OUTPUTS}
    assert max(errors.values()) <= 1e-3, errors
    assert res.outputs["bogie1_acc_z"][0] == pytest.approx(ref["bogie1_acc_z"][0], rel=1e-6)  # same start


def test_what_differs_from_railcal_is_second_order_integration_error(track_rail):
    """Halving exudyn's step divides the NRMSE by ~4: the models agree, the integrator errs."""
    rail, profile = track_rail
    err = []
    for h in (8e-4, 4e-4):
        res = simulate_car_exudyn(CAR, rail, duration=1.0, output_interval=8e-4, settings=IntegratorSettings(h))
        ref = car_reference(car2d_spec(CAR.as_dict()), CAR, profile, SPEED, res.t, start=START, substeps=16)
        err.append(max(nrmse(res.outputs[n], ref[n]) for n in OUTPUTS))
    assert 3.0 < err[0] / err[1] < 6.0, err


def test_response_matches_the_car_fmu_within_nrmse_1e_3(car_fmus, track_rail):
    """The FMU runs stand-alone over the same track file (resources/track.csv)."""
    import fmpy

    _, built = car_fmus
    rail, _ = track_rail
    res = simulate_car_exudyn(CAR, rail, duration=2.0, output_interval=1e-3)
    fmu = fmpy.simulate_fmu(str(built[2].path), start_time=0.0, stop_time=2.0, output_interval=1e-3, step_size=1e-3,
                            output=list(OUTPUTS), start_values={"speed": SPEED, "track_start": START})
    np.testing.assert_allclose(fmu["time"], res.t, atol=1e-9)
    errors = {n: nrmse(res.outputs[n], fmu[n]) for n in OUTPUTS}
    assert max(errors.values()) <= 1e-3, errors


# ------------------------------------------------------------------ bad input

@pytest.mark.parametrize("kwargs, match", [
    (dict(distance=[0.0, 1.0, 1.0, 2.0], level=[0.0] * 4, speed=40.0), r"increase strictly; row 2 \(1.0 m\)"),
    (dict(distance=[0.0, 1.0], level=[0.0, 0.0], speed=40.0), "at least 3 points"),
    (dict(distance=[0.0, 1.0, 2.0], level=[0.0, 0.0], speed=40.0), "equal length"),
    (dict(distance=[0.0, 1.0, 2.0], level=[0.0, np.nan, 0.0], speed=40.0), "finite"),
    (dict(distance=[0.0, 1.0, 2.0], level=[0.0] * 3, speed=0.0), "speed = 0.0 m/s; must be > 0"),
])
def test_a_bad_rail_table_is_refused_saying_what_is_wrong(kwargs, match):
    with pytest.raises(ValueError, match=match):
        RailInput(**kwargs)


def test_a_run_beyond_the_end_of_the_track_is_refused_naming_the_distances(track_rail):
    rail, _ = track_rail
    with pytest.raises(ValueError, match=r"track distances 90.\d\d-909.\d\d m in 20.0 s.*0.00-900.00 m"):
        simulate_car_exudyn(CAR, rail, duration=20.0)


@pytest.mark.parametrize("kwargs, match", [
    (dict(duration=1.0, output_interval=1e-3, settings=IntegratorSettings(3e-4)), "multiple of the step size"),
    (dict(duration=1.0005, output_interval=1e-3), "multiple of output_interval"),
])
def test_sampling_that_does_not_fit_the_steps_is_refused(track_rail, kwargs, match):
    with pytest.raises(ValueError, match=match):
        simulate_car_exudyn(CAR, track_rail[0], **kwargs)


def test_integrator_settings_refuse_nonphysical_values():
    with pytest.raises(ValueError, match="step_size = -0.001 s; must be > 0"):
        IntegratorSettings(step_size=-1e-3)
    with pytest.raises(ValueError, match=r"spectral_radius = 1.5; must be in \[0, 1\]"):
        IntegratorSettings(spectral_radius=1.5)


def test_railcal_crosscheck_writes_eigen_and_time_comparisons_with_a_verdict(tmp_path, capsys):
    import json

    from railcal.cli import main
    from calibration.models.vehicles import INTERCITY_TRAILER

    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({"model": "car2d", "parameters": INTERCITY_TRAILER.as_dict()}))
    out = tmp_path / "xc.json"
    assert main(["crosscheck", "--calibration", str(cal), "--duration", "2", "--out", str(out)]) == 0
    rep = json.loads(out.read_text())
    assert rep["verdict"] == "pass"
    assert rep["eigen"]["undamped"]["max_relative_error"] < 1e-6 and rep["eigen"]["damped"]["max_relative_error"] < 1e-4
    assert rep["time"]["worst_nrmse"] < 1e-3 and set(rep["time"]["outputs"]["bogie1_acc_z"]) == {
        "rms", "exudyn_vs_railcal", "exudyn_vs_fmu", "fmu_vs_railcal"}
    assert (tmp_path / "xc.png").read_bytes()[:4] == b"\x89PNG"
    cal.write_text(json.dumps({"model": "car2d", "parameters": dict(INTERCITY_TRAILER.as_dict(), m_b=0.0)}))
    assert main(["crosscheck", "--calibration", str(cal), "--out", str(tmp_path / "bad.json")]) == 2
    assert "m_b" in capsys.readouterr().err and not (tmp_path / "bad.json").exists()
    cal.write_text(json.dumps({"model": "box", "parameters": {"roof_membrane": -1.0}}))
    assert main(["crosscheck", "--calibration", str(cal), "--out", str(tmp_path / "bad.json")]) == 2
    assert "roof_membrane" in capsys.readouterr().err and not (tmp_path / "bad.json").exists()


def test_the_crosscheck_verdict_judges_the_physics_and_only_reports_the_wall_time(monkeypatch):
    """A machine so loaded that every clock reading jumps 1000 s: the two computations still
    agree, so the verdict is pass, and the wall time is reported beside it."""
    import itertools
    import types

    import railcal.crosscheck as crosscheck

    ticks = itertools.count(0.0, 1000.0)
    monkeypatch.setattr(crosscheck, "time", types.SimpleNamespace(perf_counter=lambda: next(ticks)))
    s, z, _ = smooth_profile(200.0, seed=3)
    rep = crosscheck.crosscheck_car(CAR, s, z, speed=SPEED, duration=0.5, with_fmu=False)
    assert rep["time"]["worst_nrmse"] < 1e-3 and rep["time"]["pass"]
    assert rep["verdict"] == "pass" and rep["wall_time_s"] >= 1000.0
    assert not any("wall" in k for k in crosscheck.TOLERANCES)
