"""The box model with a diagnosis's extension built in (calibration/models/box/extended.py):
each extension is the physics the diagnosis fitted, its reduction for the FMU and its exudyn
build agree, and a malformed extension is refused naming its key. The coarse model
(``COARSE_BOX_ORDERS``) keeps the file fast; the physics is the same at full order."""
import numpy as np
import pytest
import scipy.sparse.linalg
from conftest import COARSE_BOX_ORDERS

from calibration.data.campaign import Sensor
from calibration.data.errors import InputError
from calibration.diagnosis.excitation.basis import Operators, Stiffness
from calibration.models.box.extended import extend_vehicle, extension_of, force_gain
from calibration.models.box.mount import mount_impedance
from calibration.models.box.rig import EXCITER, SENSOR_GRID, point_record
from calibration.models.box.shinkansen import calibrated_box_model
from calibration.models.box.vehicle_reduction import frf_full, frf_reduced
from fmu_src.box import box_reduced, box_spec

BASE = {"model": "box", "parameters": {"roof_bending": 1.3, "floor_membrane": 0.8}, "order_change": COARSE_BOX_ORDERS,
        "sensors": [point_record(s) for s in SENSOR_GRID[:6]], "exciter": point_record(EXCITER)}
EQUIPMENT = {"name": "underfloor_equipment", "parameters": {
    "equipment_mass_kg": 900.0, "mounting_frequency_hz": 11.0, "mounting_damping_ratio": 0.05,
    "mount_x_m": 3.0, "mount_y_m": 0.4}}


def _with(extension):
    return {**BASE, "extension": extension}


@pytest.mark.parametrize("x", [3.0, 5.0])  # 5 m: on the joint of the middle and front floor panels
def test_equipment_is_the_diagnosis_point_impedance_on_the_vehicle(x):
    """Receptances of the vehicle without the equipment, coupled through the mount's
    impedance (Sherman-Morrison, the form the diagnosis fits), equal the extended vehicle's
    by direct solves: the equipment is the fitted mass on the fitted spring-damper."""
    model, p = calibrated_box_model(BASE)
    eq = {**EQUIPMENT["parameters"], "mount_x_m": x}
    ext, _ = calibrated_box_model(_with({**EQUIPMENT, "parameters": eq}))
    assert ext.n_dof == model.n_dof + 1  # one vertical DOF: the others are held
    mount = Sensor("mount", "displacement", "m", "floor", "z", (eq["mount_x_m"], eq["mount_y_m"], EXCITER.position[2]))
    sensors = tuple(SENSOR_GRID[:6])
    f = np.array([7.3, 10.6, 11.0, 14.2])
    w2 = (2 * np.pi * f)[:, None] ** 2
    G_se = -frf_full(model, p, f, sensors, EXCITER) / w2
    G_me = -frf_full(model, p, f, (mount,), EXCITER) / w2
    G_sm = -frf_full(model, p, f, sensors, mount) / w2
    G_mm = -frf_full(model, p, f, (mount,), mount) / w2
    kappa = mount_impedance(2 * np.pi * f, eq["equipment_mass_kg"], eq["mounting_frequency_hz"],
                            eq["mounting_damping_ratio"])[:, None]
    expected = G_se - kappa * G_me * G_sm / (1 + kappa * G_mm)
    got = -frf_full(ext, p, f, sensors, EXCITER) / w2
    np.testing.assert_allclose(got, expected, rtol=1e-7, atol=1e-9 * np.abs(expected).max())
    assert np.abs(got - G_se).max() > 0.05 * np.abs(G_se).max()  # and the equipment does change them


@pytest.mark.parametrize("panel", ["floor_middle", "roof"])
def test_softening_is_the_diagnosis_stiffness_of_the_softened_panel(panel):
    model, p = calibrated_box_model(BASE)
    ext, _ = calibrated_box_model(_with({"name": "local_panel_softening",
                                          "parameters": {"panel": panel, "rigidity_divisor": 4.0}}))
    x = np.array([p[n] for n in model.names])
    ours = Stiffness(x, panel, 4.0).matrix(Operators.build(model, SENSOR_GRID[:6], EXCITER))
    got = ext.stiffness(x)
    assert scipy.sparse.linalg.norm(got - ours) <= 1e-12 * scipy.sparse.linalg.norm(ours)
    assert scipy.sparse.linalg.norm(got - model.stiffness(x)) > 1e-3 * scipy.sparse.linalg.norm(ours)


def test_a_load_cell_gain_divides_the_fmus_frf_and_leaves_the_structure():
    gain = 1.07
    cal = _with({"name": "force_calibration", "parameters": {"force_gain": gain}})
    assert force_gain(cal) == gain and force_gain(BASE) == 1.0
    base, ext = box_reduced(BASE, 40.0), box_reduced(cal, 40.0)
    force = next(v for v in box_spec(cal, cutoff_hz=40.0, reduced=ext).variables if v.name == "exciter_force")
    assert "load cell's reading" in force.description and "1.07" in force.description
    np.testing.assert_array_equal(ext.K, base.K)
    f = np.array([6.0, 9.5, 13.0])
    np.testing.assert_allclose(frf_reduced(ext, f, 0.02), frf_reduced(base, f, 0.02) / gain, rtol=1e-12)


def test_the_equipment_in_the_fmu_reduction_and_in_exudyn_has_the_full_models_frequencies():
    """The extended vehicle reduced for the FMU (its equipment a rigid body with one free
    DOF) and built in exudyn (the other five held by constraints) against the full model:
    the eigenfrequencies below 20 Hz, within the cross-check's 1e-4."""
    from reference_models.box import (build_box_exudyn, eigen_errors, exudyn_frequencies, full_frequencies,
                                      reduced_frequencies)

    cal = _with(EQUIPMENT)
    model, p = calibrated_box_model(cal)
    reduced = box_reduced(cal, 60.0)
    assert reduced.names[-1] == "underfloor_equipment_z" and reduced.M[-1, -1] == 900.0
    mbs, _ = build_box_exudyn(model, p, cutoff_hz=60.0, zeta=0.02, sensors=SENSOR_GRID[:6], exciter=EXCITER)
    ex, red, full = exudyn_frequencies(mbs), reduced_frequencies(reduced), full_frequencies(model, p)
    assert len(ex) == len(red) == len(full)
    base_full = full_frequencies(*calibrated_box_model(BASE))
    assert len(full) == len(base_full) + 1  # the equipment's own mode
    assert eigen_errors(red, ex).max() <= 1e-4 and eigen_errors(full, ex).max() <= 1e-4


@pytest.mark.parametrize("extension, key", [
    ({"name": "bogie_hunting", "parameters": {}}, "extension.name"),
    ({"name": "underfloor_equipment", "parameters": {**EQUIPMENT["parameters"], "equipment_mass_kg": -1.0}},
     "extension.equipment_mass_kg"),
    ({"name": "underfloor_equipment", "parameters": {**EQUIPMENT["parameters"], "mount_x_m": float("nan")}},
     "extension.mount_x_m"),
    ({"name": "underfloor_equipment", "parameters": {**EQUIPMENT["parameters"], "mount_x_m": 40.0}},
     "extension.mount_x_m"),
    ({"name": "underfloor_equipment", "parameters": {**EQUIPMENT["parameters"], "mount_y_m": -2.5}},
     "extension.mount_y_m"),
    ({"name": "underfloor_equipment", "parameters": {**EQUIPMENT["parameters"], "mount_z_m": 1.0}},
     "extension.mount_z_m"),
    ({"name": "local_panel_softening", "parameters": {"panel": "bonnet", "rigidity_divisor": 2.0}},
     "extension.panel"),
    ({"name": "local_panel_softening", "parameters": {"panel": "roof"}}, "extension.rigidity_divisor"),
    ({"name": "force_calibration", "parameters": {"force_gain": True}}, "extension.force_gain"),
    ("equipment", "extension"),
])
def test_a_malformed_extension_is_refused_naming_its_key(extension, key):
    with pytest.raises(InputError) as e:
        calibrated_box_model(_with(extension))
    assert e.value.key == key


def test_without_an_extension_the_vehicle_is_itself(coarse_box_model):
    assert extension_of(BASE) is None
    assert extend_vehicle(coarse_box_model.vehicle, BASE) is coarse_box_model.vehicle


@pytest.fixture(scope="module")
def equipment_campaign(tmp_path_factory):
    """A coarse shaker test (2 x 120 s) with 3 % of the carbody's mass on mounts, and its truth."""
    from calibration.data.campaign import open_campaign
    from calibration.truth.effects import EffectChoice, effect_spec
    from calibration.truth.excitation import ExcitationSettings, synth_excitation

    root = tmp_path_factory.mktemp("equipment") / "campaign"
    truth = synth_excitation(root, seed=11, settings=ExcitationSettings(runs=2, duration=120.0,
                                                                       order_change=COARSE_BOX_ORDERS),
                             effect=EffectChoice(effect_spec("underfloor_equipment"), 0.03))
    return open_campaign(root), truth


def test_validate_carries_the_equipment_and_the_load_cells_gain(equipment_campaign):
    """The truth's own factors and equipment, validated against the campaign's FRFs: expected,
    before the first run, FRAC median 0.98 or more and least 0.95 or more with the equipment,
    median 0.9 or less without it; a load cell's gain divides every model FRF exactly."""
    from calibration.identification.excitation import identify_excitation
    from calibration.validation.excitation import compare_frf

    campaign, truth = equipment_campaign
    ident = identify_excitation(campaign)
    e = truth["effect"]
    cal = {"model": "box", "parameters": truth["parameters"], "order_change": COARSE_BOX_ORDERS,
           "sensors": [point_record(campaign.meta.sensor(n)) for n in ident.sensors],
           "exciter": point_record(campaign.meta.exciter())}
    equipment = {"name": "underfloor_equipment", "parameters": {
        "equipment_mass_kg": e["equipment_mass_kg"], "mounting_frequency_hz": e["mounting_frequency_hz"],
        "mounting_damping_ratio": e["mounting_damping_ratio"], "mount_x_m": e["position_m"][0],
        "mount_y_m": e["position_m"][1]}}
    with_it = compare_frf(campaign, {**cal, "extension": equipment}, ident)
    gain = {name: compare_frf(campaign, {**cal, "extension": {"name": "force_calibration",
                                                               "parameters": {"force_gain": g}}}, ident)
            for name, g in (("one", 1.0), ("off", 1.08))}
    assert np.median(with_it.frac) >= 0.98 and with_it.frac.min() >= 0.95
    assert np.median(gain["one"].frac) <= 0.9
    np.testing.assert_allclose(gain["off"].model, gain["one"].model / 1.08, rtol=1e-12)


def test_an_identified_modes_damping_goes_to_the_model_mode_of_its_shape():
    """Two model modes 3 % apart with orthogonal shapes; the identified modes' shapes are
    theirs in the other order of frequency: each damping goes by shape, not by frequency;
    a shape alike to none (MAC under 0.5) gives none."""
    from types import SimpleNamespace

    from calibration.models.box.modal import ModalModel
    from calibration.validation.excitation import shape_paired_damping

    shapes = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    modal = ModalModel({}, np.array([10.0, 10.3, 30.0]), np.full(3, 0.02), ("elastic",) * 3,
                       np.column_stack([shapes, [1.0, -1.0, 1.0, 1.0]]), np.ones(3), np.zeros(3))
    mode = SimpleNamespace
    ident = SimpleNamespace(modes=(mode(label="a", frequency_hz=10.25, damping_ratio=0.011, shape=shapes[:, 0]),
                                   mode(label="b", frequency_hz=10.05, damping_ratio=0.033, shape=shapes[:, 1] * 1j),
                                   mode(label="c", frequency_hz=29.0, damping_ratio=0.05,
                                        shape=np.array([1.0, 1.0, 1.0, 1.0]))))
    zeta = shape_paired_damping(modal, ident)
    np.testing.assert_array_equal(zeta[:2], [0.011, 0.033])
    assert np.isnan(zeta[2])


def test_an_extended_model_is_refused_as_a_diagnosis_baseline(tmp_path):
    from railcal.registry import MODELS

    with pytest.raises(InputError) as e:
        MODELS["box"].diagnose(None, None, _with(EQUIPMENT), tmp_path / "d.json")
    assert e.value.key == "extension"


def test_a_models_order_change_is_read_off_its_panels(coarse_box_model):
    from calibration.models.box.shinkansen import order_change_of

    assert order_change_of(coarse_box_model.vehicle) == COARSE_BOX_ORDERS
    odd = coarse_box_model.vehicle.panels[0]
    from dataclasses import replace
    vehicle = replace(coarse_box_model.vehicle, panels=(replace(odd, order=(odd.order[0] + 1, odd.order[1])),
                                                        *coarse_box_model.vehicle.panels[1:]))
    assert order_change_of(vehicle) is None


def test_the_cross_check_drives_the_exciter_and_gives_exudyn_the_force_the_load_cell_reading_stands_for(
        car_track, monkeypatch):
    """Over the track with the exciter driven by its load cell's reading: exudyn takes the
    reading over the calibration's gain, railcal's model and the FMU take the reading and
    divide it themselves. They agree within the cross-check's NRMSE 1e-2; exudyn given the
    reading as the force (the gain forgotten on its side alone) does not."""
    from railcal.crosscheck import EXCITER_READING, crosscheck_box

    path, _ = car_track
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    cal = _with({"name": "force_calibration", "parameters": {"force_gain": 1.25}})
    report = crosscheck_box(cal, table[:, 0], table[:, 1], speed=40.0, duration=0.5, cutoff_hz=40.0)
    time_ = report["time"]
    assert time_["exciter_reading"]["load_cell_gain"] == 1.25
    assert time_["exciter_reading"]["rms_n"] == EXCITER_READING["rms_n"]
    assert time_["pass"] and time_["worst_nrmse"] <= 1e-2, time_["worst_nrmse"]
    assert all(row["fmu_vs_railcal"] <= 1e-4 for row in time_["outputs"].values())
    monkeypatch.setattr("calibration.models.box.extended.force_gain", lambda calibration: 1.0)
    forgot = crosscheck_box(cal, table[:, 0], table[:, 1], speed=40.0, duration=0.5, cutoff_hz=40.0,
                            with_fmu=False)["time"]
    assert not forgot["pass"] and forgot["worst_nrmse"] > 0.05, forgot["worst_nrmse"]
