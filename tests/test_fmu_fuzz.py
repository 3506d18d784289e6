"""Fuzzing every vehicle FMU of the model registry (railcal.registry.MODELS; FMI 2.0 and 3.0
co-simulation, built from each model's example calibration) through fmpy's low-level API.

A seeded generator drives random sequences of FMI calls with hostile arguments: NaN, inf and
huge values, zero, negative and huge step sizes, wrong communication points, unknown value
references, calls out of order (doStep before initialisation, set after terminate, exit
initialisation twice), FMU states got, set, freed (twice), serialised and deserialised with
bad sizes and damaged bytes, reset at any point, nonsense track files and non-positive
parameters, input derivatives of odd orders, calls on freed instances. The fuzzer knows no
model: it reads the inputs, outputs and tunable parameters from the modelDescription, and
knows only the names of the stand-alone interface every vehicle FMU shares (speed,
track_start, standalone: fmu_src.variables.standalone_variables). Any call may be refused (an
error status: fmpy raises FMICallException); none may take the process down or hang it,
every refusal of a live instance says why in the log, and afterwards a fresh instance of
the same loaded library runs bit for bit like an untouched FMU, and as its model does
(:data:`PHYSICS`: the project's exact responses).

A crash would kill pytest, so every sequence runs in a child process: tests/fmu_fuzzer.py
run as a script, ``python fmu_fuzzer.py FMU_DIR VERSION SCENARIO OUT_DIR``. Each call is written
to OUT_DIR/calls.log before it is made, so a dead child's last call is the log's last line;
the test prints the seed, the signal and the last calls.
"""
from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmu_fuzzer import CLEAN_H, CLEAN_STEPS, SPEED, START, clean_run, output_names

from fmu_src.export import export_fmu
from fmu_src.reference import nrmse
from railcal.registry import MODELS

CHILD = Path(__file__).with_name("fmu_fuzzer.py")
CALLS = 1000  # per seed and FMI version
TIMEOUT = 90.0  # [s] for a child; a sequence takes 1-20 s on a busy machine, a hang never ends
TAIL = 30  # calls shown when a child dies

#: seeds per model (CALLS calls each, in FMI 2 and 3). One for the box: its sequences take
#: 7-18 s against the car's 1-3 s (the first step of every (re)initialised instance computes
#: the exact discretisation of 236 states, 0.15-0.4 s, and the sequences re-initialise often)
#: and its FMUs build in 10 s against 4; the FMI layer they exercise is the car's
#: (fmu_src/common), which the car's four seeds cover.
SEEDS = {"car2d": (1, 2, 3, 4), "box": (1,)}
DEFAULT_SEEDS = (1, 2, 3, 4)  # a model added to the registry
NRMSE_TOL = 1e-4  # a clean run (1 ms steps) against the exact response; measured 1.5e-6 (car), 8.9e-6 (box)


# ------------------------------------------------------------------ the physics, per model
# Each takes the model's calibration, the track profile and the clean run's times, computes
# the model's own answer once, and returns the check of a clean run ({output: values}).


def car_physics(calibration: dict, profile, t: np.ndarray):
    """Every output as the car model's exact response over the track (fmu_src.reference,
    started in static equilibrium), and the mean wheel-rail force the static axle load."""
    from calibration.models.car2d import GRAVITY
    from calibration.models.parameters import CarParameters
    from fmu_src.reference import car_reference

    p = CarParameters.from_mapping(calibration["parameters"])
    ref = car_reference(MODELS["car2d"].fmu_spec(calibration), p, profile, SPEED, t, start=START)
    axle_load = (p.m_v / 4 + p.m_b / 2 + p.m_w) * GRAVITY  # [N]

    def check(run: dict[str, np.ndarray]):
        errors = {n: nrmse(run[n], ref[n]) for n in ref}
        assert set(errors) == set(run) and max(errors.values()) < NRMSE_TOL, errors
        assert np.mean(run["contact_force_1"]) == pytest.approx(axle_load, rel=1e-3)

    return check


def box_physics(calibration: dict, profile, t: np.ndarray):
    """Every floor acceleration as the reduced vehicle's exact response over the track
    (fmu_src.reference.box_reference: the reduction, cut-off and damping export uses; no
    exciter force, started in static equilibrium)."""
    from fmu_src.box import box_reduced, calibrated_damping
    from fmu_src.reference import box_reference

    reduced = box_reduced(calibration)
    y = box_reference(reduced, calibrated_damping(calibration), profile, SPEED, t, np.zeros_like(t), start=START)
    ref = dict(zip(reduced.sensors, y.T))

    def check(run: dict[str, np.ndarray]):
        errors = {n: nrmse(run[n], ref[n]) for n in ref}
        assert set(errors) == set(run) and max(errors.values()) < NRMSE_TOL, errors

    return check


PHYSICS = {"car2d": car_physics, "box": box_physics}


class ExampleFMU:
    """A model's FMUs (FMI 2 and 3, unzipped) built from its example calibration, the clean
    run of each, untouched, in this process, and the check of the model's physics."""

    def __init__(self, name: str, calibration: dict, track, folder: Path):
        assert name in PHYSICS, f"{name}: give its physics check in PHYSICS"
        self.dirs = {}
        for v in (2, 3):
            built = export_fmu(calibration, v, folder / f"{name}{v}.fmu", spec_for=MODELS[name].fmu_spec,
                               track=track[0], platforms=("linux64",))
            self.dirs[v] = fmpy.extract(str(built.path), unzipdir=folder / f"{name}_fmi{v}")
        self.outputs = output_names(self.dirs[2])
        self.untouched = {v: clean_run(self.dirs[v], v) for v in (2, 3)}
        self.check_physics = PHYSICS[name](calibration, track[1], CLEAN_H * np.arange(CLEAN_STEPS + 1))


@pytest.fixture(scope="module")
def example_fmus(example_calibration, car_track, tmp_path_factory):
    """name -> :class:`ExampleFMU` of the model's example calibration (the box's at coarse panel
    orders, conftest), built on first use (a worker builds the models its tests need)."""
    cache: dict[str, ExampleFMU] = {}

    def get(name: str) -> ExampleFMU:
        if name not in cache:
            cache[name] = ExampleFMU(name, example_calibration(name), car_track,
                                     tmp_path_factory.mktemp(f"fuzz_{name}"))
        return cache[name]

    return get


def run_child(fmu_dir, version, scenario, out: Path, timeout=TIMEOUT) -> dict:
    """Run a scenario in a child process; fail with the last calls if it dies or hangs."""
    out.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, str(CHILD), str(fmu_dir), str(version), scenario, str(out)]
    what = f"{Path(fmu_dir).name}, {scenario}"

    def tail():
        log = out / "calls.log"
        lines = log.read_text(encoding="utf-8", errors="replace").splitlines() if log.exists() else []
        return "\n".join(lines[-TAIL:])

    try:
        proc = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:  # the child is killed
        proc = None
    if proc is None:
        pytest.fail(f"{what}: no answer after {timeout} s (a hang); the last calls (the last one unanswered):\n"
                    f"{tail()}", pytrace=False)
    if proc.returncode != 0:
        how = (f"killed by {signal.Signals(-proc.returncode).name}" if proc.returncode < 0
               else f"exit code {proc.returncode}")
        pytest.fail(f"{what}: the process died ({how}); the last calls (a crash in the last one leaves it "
                    f"unanswered):\n{tail()}\n--- stderr:\n{proc.stderr[-3000:]}", pytrace=False)
    return json.loads((out / "summary.json").read_text())


SEQUENCES = [pytest.param(name, version, seed, id=f"{name}-fmi{version}-seed{seed}")
             for name in MODELS for version in (2, 3) for seed in SEEDS.get(name, DEFAULT_SEEDS)]
INSTANCES = [pytest.param(name, version, id=f"{name}-fmi{version}") for name in MODELS for version in (2, 3)]


@pytest.mark.slow(seconds=4)
@pytest.mark.parametrize("name, version, seed", SEQUENCES)
def test_random_call_sequences_are_refused_or_served_and_leave_the_fmu_working(example_fmus, tmp_path, name,
                                                                            version, seed):
    fmu = example_fmus(name)
    summary = run_child(fmu.dirs[version], version, f"seed:{seed}:{CALLS}", tmp_path)
    assert summary["calls"] >= CALLS
    served = {op for op, (ok, _) in summary["outcomes"].items() if ok}
    refused = {op for op, (_, no) in summary["outcomes"].items() if no}
    # the sequences go deep: they step, restore and deserialise states, and are refused as often
    assert {"doStep", "exitInitializationMode", "setFMUState", "deserializeFMUState"} <= served, summary
    assert {"doStep", "setReal", "exitInitializationMode", "deserializeFMUState", "setFMUState"} <= refused, summary
    assert summary["silent"] == []  # every refusal of a live instance logged why

    after = np.load(tmp_path / "clean.npy")  # a fresh instance of the fuzzed, still loaded library
    assert np.isfinite(after).all()
    assert np.array_equal(after, fmu.untouched[version])  # bit for bit like an untouched FMU
    fmu.check_physics(dict(zip(fmu.outputs, after.T)))


@pytest.mark.slow(seconds=2)
@pytest.mark.parametrize("name, version", INSTANCES)
def test_a_forged_fmu_state_is_refused_not_stepped(example_fmus, tmp_path, name, version):
    """Found by this fuzzer (in the car FMU; the FMI layer is every model's).
    inst_set_state takes the snapshot's mode unchecked; a mode with the step bit and others
    (0xffffffff, 5, 12) passes inst_allowed's bit test for doStep but not set_state's
    ``== ST_STEP`` test that loads the track, so a stand-alone doStep finds no track, and its
    error message reads inst->track.x[0] of the unloaded track (NULL)."""
    summary = run_child(example_fmus(name).dirs[version], version, "forged_state", tmp_path, timeout=10.0)
    assert summary["outcomes"]["doStep"] == [0, 1]


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
@pytest.mark.slow(seconds=2)
@pytest.mark.parametrize("name, version", INSTANCES)
def test_a_track_file_without_end_is_refused(example_fmus, tmp_path, name, version):
    summary = run_child(example_fmus(name).dirs[version], version, "endless_track", tmp_path, timeout=3.0)
    assert summary["outcomes"]["exitInitializationMode"] == [0, 1]
