"""Every vehicle model of the registry (railcal.registry.MODELS) as an FMU, FMI 2 and 3, built
from its example calibration through the command line (``railcal export-fmu``): the build
succeeds and validates, every physical variable carries its SI unit, the FMU at rest on a
level track outputs zero motion and the static load, and bad calibrations are refused
(exit 2) with a message naming the key.

What one model's FMU does in depth (accuracy against the model, bad FMI calls, importers)
is in test_fmu_car.py and test_fmu_box.py; random call sequences on every model's FMU in
test_fmu_fuzz.py. The box's example is built at coarse panel orders (conftest)."""
import json
import re

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from railcal.cli import main
from railcal.registry import MODELS

VERSIONS = [pytest.param(name, version, id=f"{name}-fmi{version}") for name in MODELS for version in (2, 3)]
G = 9.80665  # [m/s^2] standard gravity

#: Real variables without a unit because they are dimensionless
DIMENSIONLESS = {"zeta_carbody": "damping ratio of the carbody's elastic modes"}

#: SI base-unit exponents of the symbols FMI unit names are made of here
SYMBOLS = {"kg": {"kg": 1}, "m": {"m": 1}, "s": {"s": 1}, "rad": {"rad": 1}, "N": {"kg": 1, "m": 1, "s": -2}}


def car_static_forces(calibration: dict) -> dict[str, float]:
    """Each wheel-rail force at rest: the axle load, a quarter of the carbody, half a bogie
    and a wheelset [N]."""
    p = calibration["parameters"]
    return {f"contact_force_{j}": (p["m_v"] / 4 + p["m_b"] / 2 + p["m_w"]) * G for j in range(1, 5)}


#: the force outputs [N] of each model at rest, from its calibration (the box has none: its
#: outputs are floor accelerations); a model whose FMU outputs a force missing here fails
STATIC_FORCES = {"car2d": car_static_forces, "box": lambda calibration: {}}

#: a parameter each model refuses to take negative
NEGATIVE = {"car2d": "k_s", "box": "floor_bending"}


def _drop(key):
    def change(c):
        del c[key]
    return change


def _drop_parameter(key):
    def change(c):
        del c["parameters"][key]
    return change


def _set(key, value):
    def change(c):
        c[key] = value
    return change


#: calibrations only one model refuses: (id, change of its example, what the message names)
MODEL_REFUSALS = {
    "car2d": [("missing_m_v", _drop_parameter("m_v"), "m_v")],
    "box": [("no_sensors", _drop("sensors"), "sensors"), ("no_exciter", _drop("exciter"), "'exciter'"),
            ("empty_sensors", _set("sensors", []), "sensors"),
            ("sensor_without_position", _set("sensors", [{"name": "floor_1"}]), "sensors"),
            ("fractional_order_change", _set("order_change", 1.5), "order_change")],
}


def export(tmp_path, calibration: dict, *args: str, stem: str = "cal") -> tuple[int, object]:
    """``railcal export-fmu`` of ``calibration`` (written to a JSON file): (exit code, the .fmu path)."""
    path = tmp_path / f"{stem}.json"
    path.write_text(json.dumps(calibration))
    out = tmp_path / f"{stem}.fmu"
    return main(["export-fmu", "--calibration", str(path), *args, "--out", str(out)]), out


@pytest.fixture(scope="module")
def level_track(tmp_path_factory):
    """A level track recording: 200 m at level 0."""
    path = tmp_path_factory.mktemp("level") / "level.csv"
    path.write_text("distance,level\n" + "".join(f"{x},0\n" for x in range(0, 201, 5)))
    return path


@pytest.fixture(scope="module")
def cli_fmus(example_calibration, level_track, tmp_path_factory):
    """(name, version) -> (calibration, exit code, .fmu) of ``railcal export-fmu`` with the
    level track shipped, built on first use."""
    cache = {}

    def get(name: str, version: int):
        if (name, version) not in cache:
            calibration = example_calibration(name)
            code, out = export(tmp_path_factory.mktemp(f"cli_{name}{version}"), calibration, "--fmi-version",
                               str(version), "--track", str(level_track), stem=name)
            cache[name, version] = calibration, code, out
        return cache[name, version]

    return get


@pytest.mark.slow(seconds=5)
@pytest.mark.parametrize("name, version", VERSIONS)
def test_export_fmu_builds_every_model_and_fmpy_validates_it(cli_fmus, capsys, name, version):
    _, code, out = cli_fmus(name, version)
    assert code == 0, capsys.readouterr().err
    assert validate_fmu(str(out)) == []
    md = fmpy.read_model_description(str(out))
    assert md.fmiVersion.startswith(str(version)) and md.coSimulation is not None
    v = {x.name: x for x in md.modelVariables}
    for j in range(1, 5):  # every vehicle FMU takes the rails under its four wheelsets
        assert (v[f"z_rail_{j}"].causality, v[f"z_rail_{j}"].unit) == ("input", "m")
        assert (v[f"dz_rail_{j}"].causality, v[f"dz_rail_{j}"].unit) == ("input", "m/s")
    assert any(x.causality == "output" for x in md.modelVariables)


def si_exponents(unit: str) -> dict[str, int]:
    """The SI base-unit exponents of an FMI unit name made of :data:`SYMBOLS` ('.' multiplies,
    '/' divides, a trailing integer is a power): 'N.s/m' -> {kg: 1, s: -1}."""
    total: dict[str, int] = {}
    for k, part in enumerate(unit.split("/")):
        for factor in part.split("."):
            m = re.fullmatch(r"([A-Za-z]+)(-?\d*)", factor)
            assert m and m[1] in SYMBOLS, f"unit {unit!r}: cannot read {factor!r}"
            power = int(m[2] or 1) * (1 if k == 0 else -1)
            for base, e in SYMBOLS[m[1]].items():
                total[base] = total.get(base, 0) + e * power
    return {b: e for b, e in total.items() if e}


@pytest.mark.slow(seconds=1)
@pytest.mark.parametrize("name, version", VERSIONS)
def test_every_physical_variable_has_its_si_unit(cli_fmus, name, version):
    """Every Real variable but the dimensionless ones has a unit, declared with the base units
    its name says (N is kg m s^-2, no factor or offset): an importer converting units gets
    SI values."""
    _, code, out = cli_fmus(name, version)
    assert code == 0
    md = fmpy.read_model_description(str(out))
    reals = [x for x in md.modelVariables if x.type in ("Real", "Float64")]
    assert [x.name for x in reals if x.unit is None] == [x.name for x in reals if x.name in DIMENSIONLESS]
    assert all(x.unit is None for x in md.modelVariables if x.type not in ("Real", "Float64"))
    assert next(x.unit for x in md.modelVariables if x.causality == "independent") == "s"
    declared = {u.name: u.baseUnit for u in md.unitDefinitions}
    for unit in {x.unit for x in reals if x.unit}:
        base = declared[unit]
        exponents = {b: getattr(base, b) for b in ("kg", "m", "s", "A", "K", "mol", "cd", "rad") if getattr(base, b)}
        assert exponents == si_exponents(unit), unit
        assert (base.factor, base.offset) == (1.0, 0.0), unit


@pytest.mark.slow(seconds=1)
@pytest.mark.parametrize("name, version", VERSIONS)
@pytest.mark.parametrize("how", ["standalone", "rail_inputs"])
def test_at_rest_on_a_level_track_the_outputs_are_zero_or_the_static_load(cli_fmus, name, version, how):
    """0.5 s in 1 ms steps from the FMU's start (static equilibrium): running at 40 m/s over
    the shipped level track, or taking rail inputs that stay 0. Nothing moves: accelerations
    and rates are 0 to 1e-9 (m/s^2, rad/s), forces the static load to a relative 1e-9 (room
    for round-off of another compiler; measured: exactly 0 and the static load)."""
    calibration, code, out = cli_fmus(name, version)
    assert code == 0
    md = fmpy.read_model_description(str(out))
    outputs = {x.name: x.unit for x in md.modelVariables if x.causality == "output"}
    start = {"speed": 40.0} if how == "standalone" else {"standalone": False}
    res = fmpy.simulate_fmu(str(out), stop_time=0.5, step_size=1e-3, output_interval=1e-3, start_values=start,
                            output=list(outputs))
    assert res["time"][-1] == pytest.approx(0.5)
    assert name in STATIC_FORCES, f"{name}: give its static forces in STATIC_FORCES"
    static = STATIC_FORCES[name](calibration)
    assert set(static) == {n for n, u in outputs.items() if u == "N"}, "give the model's static forces"
    for n, unit in outputs.items():
        assert np.isfinite(res[n]).all(), n
        if unit == "N":
            np.testing.assert_allclose(res[n], static[n], rtol=1e-9, atol=0, err_msg=n)
        else:
            assert unit in ("m/s2", "rad/s"), f"{n}: no expectation for an output in {unit}"
            assert np.max(np.abs(res[n])) <= 1e-9, n


def _negative(name):
    def change(c):
        c["parameters"][NEGATIVE[name]] = -1.0
    return change


def _unknown_parameter(c):
    c["parameters"]["not_a_parameter"] = 1.0


REFUSALS = [pytest.param(name, change, needle, id=f"{name}-{what}")
            for name in MODELS
            for what, change, needle in [("no_parameters", _drop("parameters"), "key 'parameters'"),
                                         ("negative_parameter", _negative(name), NEGATIVE.get(name, "?")),
                                         ("unknown_parameter", _unknown_parameter, "not_a_parameter"),
                                         *MODEL_REFUSALS.get(name, [])]]


@pytest.mark.parametrize("name, change, needle", REFUSALS)
def test_bad_calibrations_are_refused_with_exit_2_naming_the_key(example_calibration, tmp_path, capsys, name, change,
                                                                 needle):
    assert name in NEGATIVE, f"{name}: give a parameter it refuses negative in NEGATIVE"
    calibration = example_calibration(name)
    change(calibration)
    code, out = export(tmp_path, calibration)
    err = capsys.readouterr().err
    assert code == 2 and needle in err, err
    assert re.search(r"key '\w+'", err), err  # and the key it read
    assert not out.exists()


def test_an_unknown_model_is_refused_naming_it_and_the_models_known(example_calibration, tmp_path, capsys):
    calibration = dict(example_calibration(next(iter(MODELS))), model="tram")
    code, out = export(tmp_path, calibration, stem="tram_calibration")
    err = capsys.readouterr().err
    assert code == 2 and "tram_calibration.json" in err and "key 'model'" in err and "'tram'" in err, err
    assert all(name in err for name in MODELS), err
    assert not out.exists()
