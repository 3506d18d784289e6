"""The car FMU (FMI 2.0 and 3.0 co-simulation), built from C by the project's builder, run in
fmpy against the project's own model: what shared/spec/interfaces.md promises, the accuracy
of its stepping, and what it does with bad calls.

Reference: the Python car model (calibration.models.car2d) driven exactly over the same
track by fmu_src.reference. One pair of FMUs (FMI 2 and 3) is built per session
(conftest.py: ``car_fmus``, ``car_track``)."""
import shutil
import subprocess

import fmpy
import numpy as np
import pytest
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi3 import FMU3Slave
from conftest import CAR_FMU_SPEED as SPEED
from conftest import CAR_FMU_START as START
from fmpy.validation import validate_fmu

from calibration.models.parameters import CAR_PARAMETER_SPECS
from calibration.models.vehicles import INTERCITY_TRAILER as CAR
from fmu_src.reference import car_reference, nrmse, rail_inputs

RAIL = [f"z_rail_{j}" for j in range(1, 5)] + [f"dz_rail_{j}" for j in range(1, 5)]
SPEC_OUTPUTS = ["carbody_acc_z", "carbody_pitch_rate", "bogie1_acc_z", "bogie1_pitch_rate", "bogie2_acc_z",
                "bogie2_pitch_rate"] + [f"contact_force_{j}" for j in range(1, 5)]


def simulate(built, h, T=10.0, **kw):
    return fmpy.simulate_fmu(str(built.path), start_time=0.0, stop_time=T, output_interval=h, step_size=h,
                             output=SPEC_OUTPUTS, **kw)


# ------------------------------------------------------------------ what it declares

@pytest.mark.parametrize("version", [2, 3])
def test_fmpy_validates_the_fmu_and_it_declares_the_interface_variables(car_fmus, version):
    spec, built = car_fmus
    md = fmpy.read_model_description(str(built[version].path))
    v = {x.name: x for x in md.modelVariables}
    for name, ps in CAR_PARAMETER_SPECS.items():  # calibrated values are the defaults, tunable
        assert v[name].causality == "parameter" and v[name].variability == "tunable"
        assert float(v[name].start) == getattr(CAR, name)
    for name in RAIL:
        assert v[name].causality == "input" and v[name].unit == ("m" if name.startswith("z") else "m/s")
    for name in SPEC_OUTPUTS:
        assert v[name].causality == "output"
    assert v["contact_force_1"].unit == "N" and v["carbody_acc_z"].unit == "m/s2"
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canHandleVariableCommunicationStepSize
    assert {p for p in ("linux64", "win64", "x86_64-linux", "x86_64-windows")
            if f"binaries/{p}/" in " ".join(__import__("zipfile").ZipFile(built[version].path).namelist())}


# ------------------------------------------------------------------ accuracy

@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("h, tol", [(1e-3, 1e-3), (1e-2, 1e-2)])
def test_standalone_run_over_the_track_matches_the_model_at_any_step(car_fmus, car_track, version, h, tol):
    """The FMU reads the profile itself (resources/track.csv) and takes the speed as input."""
    spec, built = car_fmus
    res = simulate(built[version], h, start_values={"speed": SPEED, "track_start": START})
    ref = car_reference(spec, CAR, car_track[1], SPEED, res["time"], start=START, substeps=max(1, int(h / 5e-5)))
    errors = {n: nrmse(res[n], ref[n]) for n in SPEC_OUTPUTS}
    assert max(errors.values()) < tol, errors
    static = (CAR.m_v / 4 + CAR.m_b / 2 + CAR.m_w) * 9.80665  # the mean contact force is the axle load
    assert np.mean(res["contact_force_1"]) == pytest.approx(static, rel=1e-3)


def drive_fmi2(path, t, rail, derivatives: str):
    """A master loop over fmpy's low-level API, giving the rail inputs at each communication
    point and their derivatives: ``"none"``; ``"table"``, first derivatives as forward
    differences of the input table (what a master interpolating its table linearly has);
    ``"exact"``, first and second derivatives of the input functions."""
    z, dz, ddz, dddz = rail
    md = fmpy.read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(path)),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="master")
    fmu.instantiate()
    fmu.setBoolean([vr["standalone"]], [False])
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    ins = [vr[n] for n in RAIL]
    outs = [vr[n] for n in SPEC_OUTPUTS]
    u = np.hstack([z, dz])
    du, d2u = np.hstack([dz, ddz]), np.hstack([ddz, dddz])
    h = t[1] - t[0]

    def set_inputs(k):
        fmu.setReal(ins, list(u[k]))
        if derivatives == "table":
            fmu.setRealInputDerivatives(ins, [1] * 8, list((u[k + 1] - u[k]) / h))
        elif derivatives == "exact":
            fmu.setRealInputDerivatives(ins, [1] * 8, list(du[k]))
            fmu.setRealInputDerivatives(ins, [2] * 8, list(d2u[k]))

    set_inputs(0)
    fmu.exitInitializationMode()
    y = [fmu.getReal(outs)]
    for k in range(len(t) - 1):
        fmu.doStep(currentCommunicationPoint=t[k], communicationStepSize=h)
        if k + 2 < len(t):
            set_inputs(k + 1)  # the outputs feel the inputs at t + h directly (feedthrough)
        y.append(fmu.getReal(outs))
    fmu.terminate()
    fmu.freeInstance()
    return dict(zip(SPEC_OUTPUTS, np.array(y).T))


@pytest.mark.parametrize("derivatives, tol_bodies, tol_contact",
                         [("exact", 1e-3, 1e-3), ("table", 1e-3, 0.05), ("none", 1e-3, 0.05)])
def test_master_driven_rail_inputs_at_1ms(car_fmus, car_track, derivatives, tol_bodies, tol_contact):
    """The master sets the inputs of t + h after the step and reads the outputs, which feel
    them directly (feedthrough). With first and second input derivatives the step is exact
    for inputs quadratic over it (measured 4e-6). With first derivatives only, or none (the
    FMU then extrapolates the inputs from the last two points), the bodies still meet 1e-3;
    the contact forces carry m_w times the rail acceleration, which a difference over one
    step gives half a step off (measured 0.017 and 0.020)."""
    spec, built = car_fmus
    t = np.arange(0.0, 5.0 + 5e-4, 1e-3)
    y = drive_fmi2(built[2].path, t, rail_inputs(CAR, car_track[1], SPEED, t, START), derivatives)
    ref = car_reference(spec, CAR, car_track[1], SPEED, t, start=START)
    body = max(nrmse(y[n], ref[n]) for n in SPEC_OUTPUTS[:6])
    contact = max(nrmse(y[n], ref[n]) for n in SPEC_OUTPUTS[6:])
    assert body < tol_bodies and contact < tol_contact, (body, contact)


def test_fmi2_and_fmi3_step_identically(car_fmus):
    _, built = car_fmus
    a = simulate(built[2], 1e-3, T=2.0, start_values={"speed": SPEED, "track_start": START})
    b = simulate(built[3], 1e-3, T=2.0, start_values={"speed": SPEED, "track_start": START})
    for n in SPEC_OUTPUTS:
        assert np.array_equal(a[n], b[n]), n


def test_variable_steps_and_rollback_reproduce_the_fixed_step_run(car_fmus):
    spec, built = car_fmus
    md = fmpy.read_model_description(str(built[2].path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(built[2].path)),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="rollback")
    fmu.instantiate()
    fmu.setReal([vr["speed"], vr["track_start"]], [SPEED, START])
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    t = 0.0
    for h in (1e-3, 2e-3, 5e-3, 2e-3):  # variable communication steps
        fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        t += h
    state = fmu.getFMUstate()
    first = [fmu.doStep(currentCommunicationPoint=t, communicationStepSize=1e-3) or fmu.getReal([vr["bogie1_acc_z"]])]
    fmu.setFMUstate(state)  # roll back and redo: the same answer
    again = [fmu.doStep(currentCommunicationPoint=t, communicationStepSize=1e-3) or fmu.getReal([vr["bogie1_acc_z"]])]
    assert first == again
    blob = fmu.serializeFMUstate(state)
    fmu.setFMUstate(fmu.deSerializeFMUstate(blob))
    assert fmu.doStep(currentCommunicationPoint=t, communicationStepSize=1e-3) is None
    assert fmu.getReal([vr["bogie1_acc_z"]]) == first[0]
    fmu.freeFMUstate(state)
    fmu.terminate()
    fmu.freeInstance()
    ref = car_reference(spec, CAR, lambda s: (np.zeros_like(s),) * 4, SPEED, np.array([0.0, 1e-3]))
    assert ref["contact_force_1"][0] == pytest.approx((CAR.m_v / 4 + CAR.m_b / 2 + CAR.m_w) * 9.80665)



def _run_logged(path, **kw):
    """fmpy.simulate_fmu with the FMU's log messages collected: (result or None, messages)."""
    messages = []

    def log(*args):  # FMI 2 passes the instance name too, FMI 3 does not; the message is last
        messages.append(args[-1].decode())

    try:
        return fmpy.simulate_fmu(str(path), logger=log, **kw), messages
    except Exception:
        return None, messages


@pytest.mark.parametrize("version", [2, 3])
def test_with_its_defaults_the_car_stands_on_its_track_and_running_off_it_is_a_logged_error(car_fmus, car_track,
                                                                                             version):
    """No start values at all: the default track_start puts the last wheelset on the shipped
    profile's first point, the car stands there in static equilibrium (speed 0). Driven past
    either end of the profile, the step fails with a log naming the input and the profile."""
    from calibration.models.car2d import wheelset_positions

    _, built = car_fmus
    distance = np.loadtxt(car_track[0], delimiter=",", skiprows=1)[:, 0]
    md = fmpy.read_model_description(str(built[version].path))
    start = float(next(v.start for v in md.modelVariables if v.name == "track_start"))
    assert start + wheelset_positions(CAR).min() == pytest.approx(distance[0], abs=1e-9)
    res, log = _run_logged(built[version].path)
    assert res is not None, log
    static = (CAR.m_v / 4 + CAR.m_b / 2 + CAR.m_w) * 9.80665
    for j in range(1, 5):
        assert np.allclose(res[f"contact_force_{j}"], static, rtol=1e-9)
    assert np.allclose(res["carbody_acc_z"], 0.0, atol=1e-9)
    past_end = (distance[-1] - distance[0]) / SPEED + 1.0  # [s]
    res, log = _run_logged(built[version].path, stop_time=past_end, start_values={"speed": SPEED})
    assert res is None and "runs off the track profile" in " ".join(log) and "z_rail_1" in " ".join(log), log
    res, log = _run_logged(built[version].path, stop_time=1.0, start_values={"speed": -1.0})
    assert res is None and "z_rail_4" in " ".join(log) and "outside the profile" in " ".join(log), log


def test_export_refuses_a_track_shorter_than_the_car(tmp_path, capsys):
    import json

    from railcal.cli import main

    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({"model": "car2d", "parameters": CAR.as_dict()}))
    track = tmp_path / "short.csv"
    track.write_text("distance,level\n100,0\n110,0.001\n")
    assert main(["export-fmu", "--calibration", str(cal), "--track", str(track), "--out",
                 str(tmp_path / "car.fmu")]) == 2
    err = capsys.readouterr().err
    assert "short.csv" in err and "wheelset span of 18.360 m" in err, err
    assert not (tmp_path / "car.fmu").exists()

# ------------------------------------------------------------------ bad calls

def _slave(built, name="bad"):
    md = fmpy.read_model_description(str(built.path))
    cls = FMU2Slave if built.fmi_version == 2 else FMU3Slave
    fmu = cls(guid=md.guid, unzipDirectory=fmpy.extract(str(built.path)),
              modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    return fmu, {v.name: v.valueReference for v in md.modelVariables}


def test_bad_calls_return_errors_with_a_message_and_never_crash(car_fmus):
    _, built = car_fmus
    messages = []

    def log(env, name, status, category, message):
        messages.append(message.decode())

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(log)  # no memory callbacks: the FMU does not use them
    fmu, vr = _slave(built[2])
    fmu.instantiate(callbacks=callbacks, loggingOn=True)
    with pytest.raises(Exception):
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)  # before initialisation
    with pytest.raises(Exception):
        fmu.setReal([vr["z_rail_1"]], [float("nan")])
    with pytest.raises(Exception):
        fmu.setReal([vr["carbody_acc_z"]], [1.0])  # an output
    fmu.reset()
    fmu.setReal([vr["m_v"]], [-3.0e4])  # non-positive mass: refused when the model is built
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    with pytest.raises(Exception):
        fmu.exitInitializationMode()
    fmu.reset()  # and a reset brings back the calibrated values
    fmu.setBoolean([vr["standalone"]], [False])
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
    with pytest.raises(Exception):
        fmu.doStep(currentCommunicationPoint=5.0, communicationStepSize=1e-3)  # not where the FMU is
    fmu.terminate()
    with pytest.raises(Exception):
        fmu.setReal([vr["z_rail_1"]], [0.0])  # after terminate
    fmu.fmi2FreeInstance(fmu.component)
    fmu.fmi2FreeInstance(fmu.component)  # freeing twice is harmless
    with pytest.raises(Exception):
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)  # a freed instance: refused
    fmu.freeLibrary()
    text = " ".join(messages)
    for needle in ("not allowed in state instantiated", "z_rail_1 = nan is not finite", "carbody_acc_z is an output",
                   "m_v = -30000 must be > 0", "doStep at t = 5", "not allowed in state terminated"):
        assert needle in text, (needle, text)


def test_several_instances_at_once_do_not_share_state(car_fmus):
    _, built = car_fmus
    runs = []
    for fmi in (built[2], built[3]):
        a, vr = _slave(fmi, "a")
        b, _ = _slave(fmi, "b")
        for f, speed in ((a, SPEED), (b, 20.0)):
            f.instantiate()
            if fmi.fmi_version == 2:
                f.setReal([vr["speed"], vr["track_start"]], [speed, START])
                f.setupExperiment(startTime=0.0)
                f.enterInitializationMode()
            else:
                f.setFloat64([vr["speed"], vr["track_start"]], [speed, START])
                f.enterInitializationMode(startTime=0.0)
            f.exitInitializationMode()
        for k in range(200):
            for f in (a, b):
                f.doStep(currentCommunicationPoint=k * 1e-3, communicationStepSize=1e-3)
        get = (lambda f: f.getReal([vr["bogie1_acc_z"]])[0]) if fmi.fmi_version == 2 else \
            (lambda f: f.getFloat64([vr["bogie1_acc_z"]])[0])
        runs.append((get(a), get(b)))
        for f in (a, b):
            f.terminate()
            f.freeInstance()
    assert runs[0] == runs[1]  # FMI 2 and 3 agree instance by instance
    assert runs[0][0] != runs[0][1]  # and the two speeds gave two answers


@pytest.mark.skipif(shutil.which("x86_64-w64-mingw32-objdump") is None, reason="mingw-w64 binutils not installed")
@pytest.mark.parametrize("version", [2, 3])
def test_the_win64_dll_exports_every_fmi_function(car_fmus, version, tmp_path):
    import zipfile

    from fmu_src.build import HERE

    _, built = car_fmus
    with zipfile.ZipFile(built[version].path) as z:
        name = next(n for n in z.namelist() if n.endswith(".dll"))
        z.extract(name, tmp_path)
    dump = subprocess.run(["x86_64-w64-mingw32-objdump", "-p", str(tmp_path / name)], capture_output=True,
                          text=True, check=True).stdout
    header = (HERE / "include" / f"fmi{version}Functions.h").read_text()
    required = sorted(set(__import__("re").findall(rf"FMI{version}_Export\s+fmi{version}\w+TYPE\s+(fmi{version}\w+);",
                                                   header)))
    assert len(required) >= (44 if version == 2 else 75)
    missing = [f for f in required if f" {f}\n" not in dump]
    assert not missing, missing


@pytest.mark.parametrize("h", [1e-3, 1e-2])
def test_libcosim_runs_the_fmi2_fmu_like_fmpy_and_the_model(car_fmus, car_track, h):
    """A second, independent importer (the Open Simulation Platform's libcosim 0.0.6, which
    loads FMI 1 and 2 only): the same numbers as fmpy to 1e-9, so both match the model."""
    from fmu_src.importers import simulate_libcosim

    spec, built = car_fmus
    sv = {"speed": SPEED, "track_start": START}
    a = simulate(built[2], h, T=5.0, start_values=sv)
    b = simulate_libcosim(built[2].path, step=h, stop=5.0, outputs=SPEC_OUTPUTS, start_values=sv)
    assert np.allclose(a["time"], b["time"])
    for n in SPEC_OUTPUTS:
        assert np.max(np.abs(a[n] - b[n])) <= 1e-9 * np.std(a[n]), n
    ref = car_reference(spec, CAR, car_track[1], SPEED, b["time"], start=START, substeps=max(1, int(h / 5e-5)))
    assert max(nrmse(b[n], ref[n]) for n in SPEC_OUTPUTS) < (1e-3 if h < 5e-3 else 1e-2)


def test_export_fmu_builds_from_a_calibration_file_and_refuses_bad_ones(tmp_path, car_track, capsys):
    import json

    from railcal.cli import main

    good = tmp_path / "cal.json"
    good.write_text(json.dumps({"model": "car2d", "parameters": CAR.as_dict()}))
    out = tmp_path / "car.fmu"
    assert main(["export-fmu", "--calibration", str(good), "--fmi-version", "3", "--track", str(car_track[0]),
                 "--out", str(out)]) == 0
    assert validate_fmu(str(out)) == []
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"model": "car2d", "parameters": dict(CAR.as_dict(), k_s=-1.0)}))
    assert main(["export-fmu", "--calibration", str(bad), "--out", str(tmp_path / "x.fmu")]) == 2
    assert "k_s" in capsys.readouterr().err
    track = tmp_path / "track.csv"
    track.write_text("distance,level\n0,0\n1,nan\n")
    assert main(["export-fmu", "--calibration", str(good), "--track", str(track), "--out",
                 str(tmp_path / "y.fmu")]) == 2
    assert "level" in capsys.readouterr().err
    assert not (tmp_path / "x.fmu").exists() and not (tmp_path / "y.fmu").exists()


def test_export_with_a_campaign_adds_its_accelerometers_as_outputs_at_their_positions(tmp_path, tiny_campaign,
                                                                                      car_track):
    """The campaign's bogie accelerometer sits 0.5 m ahead of the bogie centre: the FMU
    gives its acceleration (centre acceleration minus 0.5 m x pitch acceleration)."""
    from calibration.data.campaign import open_campaign
    from fmu_src.export import car2d_fmu_spec, car_sensors, export_fmu
    from fmu_src.variables import car2d_spec

    campaign = open_campaign(tiny_campaign)
    built = export_fmu({"model": "car2d", "parameters": CAR.as_dict()}, 2, tmp_path / "car.fmu",
                       spec_for=car2d_fmu_spec, track=car_track[0], campaign=campaign, platforms=("linux64",))
    sensors = car_sensors(campaign, CAR)
    assert sensors == (("bogie1_acc_z", "bogie1", pytest.approx(8.5 - CAR.L_v)),)
    res = fmpy.simulate_fmu(str(built.path), stop_time=2.0, output_interval=1e-3, step_size=1e-3,
                            start_values={"speed": SPEED, "track_start": START},
                            output=["sensor_bogie1_acc_z", "bogie1_acc_z"])
    ref = car_reference(car2d_spec(CAR.as_dict(), sensors=sensors), CAR, car_track[1], SPEED, res["time"],
                        start=START)
    assert nrmse(res["sensor_bogie1_acc_z"], ref["sensor_bogie1_acc_z"]) < 1e-3
    assert nrmse(res["sensor_bogie1_acc_z"], res["bogie1_acc_z"]) > 0.05  # the pitch adds at 0.5 m


# ------------------------------------------------------------------ the extended model (a diagnosis's calibration)

def _extended():
    """Every addition a diagnosis can make, at once: centre of mass, bending, reservoirs,
    flexible track and a body hung under the carbody (part of m_v)."""
    from calibration.models.car2d import CarExtras, hung_body

    k = 1500.0 * (2 * np.pi * 8.0) ** 2
    body, mount = hung_body("equipment", 1500.0, -2.3, k, 2 * 0.1 * np.sqrt(k * 1500.0))
    return CarExtras(cog_offset=0.8, bending_hz=9.0, bending_node=0.5, reservoir_ratio=0.6, track_stiffness=60e6,
                     bodies=(body,), elements=(mount,), hung_in_m_v=True)


@pytest.mark.parametrize("version", [2, 3])
def test_the_extended_model_fmu_matches_the_extended_python_model_and_its_additions_are_tunable(tmp_path, car_track,
                                                                                                version):
    """The FMU of a diagnosis's extended car: each addition a tunable parameter named as in
    the calibration file; its outputs (a floor sensor 8 m ahead included, where the bending
    shows) follow the extended Python model, also after a parameter is changed."""
    from dataclasses import replace

    from fmu_src.build import build_fmu
    from fmu_src.variables import car2d_spec

    extras = _extended()
    sensors = (("floor_front", "carbody", 8.0),)
    spec = car2d_spec(CAR.as_dict(), track=car_track[0], sensors=sensors, extras=extras)
    assert spec.n_states == 2 * (6 + 1 + 2 + 4 + 1)
    built = build_fmu(spec, version, tmp_path / "ext.fmu", platforms=("linux64",))
    assert validate_fmu(str(built.path)) == []
    v = {x.name: x for x in fmpy.read_model_description(str(built.path)).modelVariables}
    for name in ("cog_offset", "bending_hz", "bending_node", "reservoir_ratio", "track_stiffness", "equipment_mass",
                 "equipment_mount_stiffness"):
        assert v[name].causality == "parameter" and v[name].variability == "tunable"
    assert float(v["bending_hz"].start) == 9.0 and float(v["equipment_x"].start) == -2.3
    outputs = SPEC_OUTPUTS + ["sensor_floor_front"]
    for tuned, start in ((extras, {}), (replace(extras, bending_hz=11.0, track_stiffness=90e6),
                                        {"bending_hz": 11.0, "track_stiffness": 90e6})):
        res = fmpy.simulate_fmu(str(built.path), stop_time=3.0, output_interval=1e-3, step_size=1e-3, output=outputs,
                                start_values={"speed": SPEED, "track_start": START, **start})
        ref = car_reference(spec, CAR, car_track[1], SPEED, res["time"], start=START, extras=tuned)
        errors = {n: nrmse(res[n], ref[n]) for n in outputs}
        assert max(errors.values()) < 1e-3, errors
    # the wheels carry the car's weight: the hung body is part of m_v, the reservoir nodes
    # add, the track's mass is below the wheels
    weight = (CAR.m_v + 2 * (CAR.m_b + extras.node_mass) + 4 * CAR.m_w) * 9.80665
    assert sum(np.mean(res[f"contact_force_{j}"]) for j in range(1, 5)) == pytest.approx(weight, rel=1e-3)
    res, log = _run_logged(built.path, stop_time=0.1, start_values={"bending_node": -0.5})
    assert res is None and "bending_node" in " ".join(log), log


def test_export_fmu_and_crosscheck_take_a_diagnosis_file_and_refuse_extras_they_cannot_build(tmp_path, car_track, capsys):
    import json

    from calibration.models.car2d import extras_to_json
    from railcal.cli import main

    cal = {"model": "car2d", "parameters": CAR.as_dict(), "extras": extras_to_json(_extended()),
           "sensor_model": {"bogie_dx": 0.3, "gyro_gain": 0.98}}
    good = tmp_path / "diag.json"
    good.write_text(json.dumps(cal))
    out = tmp_path / "ext.fmu"
    assert main(["export-fmu", "--calibration", str(good), "--track", str(car_track[0]), "--out", str(out),
                 "--quiet"]) == 0
    names = {x.name for x in fmpy.read_model_description(str(out)).modelVariables}
    assert {"cog_offset", "bending_mass_ratio", "node_mass", "track_mass", "equipment_mount_damping"} <= names
    for key, bad, word in (("extras", {**cal["extras"], "bending_hz": "fast"}, "bending_hz"),
                           ("extras", {**cal["extras"], "hung_bodies": [{**cal["extras"]["hung_bodies"][0],
                                                                          "mass": 40000.0}]}, "hung bodies"),
                           ("sensor_model", {"bogie_dx": None}, "bogie_dx")):
        path = tmp_path / "bad.json"
        path.write_text(json.dumps({**cal, key: bad}))
        assert main(["export-fmu", "--calibration", str(path), "--out", str(tmp_path / "x.fmu"), "--quiet"]) == 2
        assert word in capsys.readouterr().err
        assert not (tmp_path / "x.fmu").exists()
        assert main(["crosscheck", "--calibration", str(path), "--out", str(tmp_path / "x.json"), "--quiet"]) == 2
        assert word in capsys.readouterr().err
        assert not (tmp_path / "x.json").exists()
