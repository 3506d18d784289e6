"""The FMU fuzzer's child process (tests/test_fmu_fuzz.py tells what it does and why): a
seeded generator of hostile FMI call sequences through fmpy's low-level API, and the clean
run of a fresh instance afterwards.

    python fmu_fuzzer.py FMU_DIR VERSION SCENARIO OUT_DIR

It needs neither pytest nor the project: a crash here must not take the test session down.
"""
from __future__ import annotations

import json
import sys
from ctypes import POINTER, byref, c_double, c_uint, cast, create_string_buffer
from pathlib import Path

import fmpy
import numpy as np
from fmpy.fmi1 import FMICallException

SPEED, START = 40.0, 100.0  # [m/s], [m]: the clean run, as in test_fmu_car.py and test_fmu_box.py
CLEAN_STEPS, CLEAN_H = 1000, 1e-3  # 1 s at 1 ms

NAN, INF = float("nan"), float("inf")
HOSTILE = (NAN, INF, -INF, 0.0, -0.0, -1.0, 1e308, -1e308, 5e-324, 1e-300, 1e300)
STEP_SIZES = (1e-3, 1e-3, 1e-3, 2e-3, 5e-3, 1e-2, 0.1, 1.0, 0.0, -0.0, -1e-3, NAN, INF, -INF, 1e-300, 5e-324, 1e3,
              1e10, 1e300)
START_TIMES = (0.0, 0.0, 0.0, 1.0, -5.0, 1e300, -1e300, NAN, INF, -INF)
UNKNOWN_VRS = (1000, 2**31 - 1, 2**32 - 1)  # plus the first value reference past the last variable
ORDERS = (1, 1, 2, 2, 0, -1, 3, 7, -2**31, 2**31 - 1)
STATUS = ("ok", "warning", "discard", "error", "fatal", "pending")


# ================================================================== the child: one sequence


def bad_tracks(folder: Path) -> list[str]:
    """Track files the FMU must refuse or survive, written to ``folder``; and paths that are no
    track files at all. (/dev/zero, a file without end, has its own test.)"""
    files = {
        "header_only.csv": b"distance,level\n",
        "one_point.csv": b"distance,level\n0,0\n",
        "backwards.csv": b"distance,level\n0,0\n2,0\n1,0\n",
        "nan_level.csv": b"distance,level\n0,0\n1,nan\n",
        "no_header.csv": b"0,0\n1,0\n",
        "wrong_columns.csv": b"x,z\n0,0\n1,0\n",
        "dense.csv": b"distance,level\n0,0\n1e-12,0\n",  # any step crosses too many points
        "short.csv": b"distance,level\n0,0\n10,0.001\n",  # the car leaves it after a few steps
        "huge_levels.csv": b"distance,level\n0,1e300\n500,-1e300\n1000,1e300\n",
        "long_line.csv": b"distance,level\n" + b"1," * 5000 + b"1\n",
        "binary.csv": bytes(range(256)) * 8,
        "empty.csv": b"",
    }
    for name, text in files.items():
        (folder / name).write_bytes(text)
    return [str(folder / name) for name in files] + [
        "track.csv", "", "/", ".", "..", str(folder), "/nonexistent/track.csv", "no_such_track.csv",
        "../" * 40 + "etc/passwd", "x" * 20000, "%s%s%n%x%%", "ünï/路径.csv", "file:///etc/passwd",
        "C:\\tracks\\track.csv"]


class Fuzzer:
    """Drives instances of one FMU (one FMI version) through ``call``, which logs every call
    before making it and records its outcome."""

    def __init__(self, fmu_dir: str, version: int, out: Path, log, rng: np.random.Generator):
        from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
        from fmpy.fmi3 import FMU3Slave

        self.dir, self.v, self.rng = fmu_dir, version, rng
        self.md = fmpy.read_model_description(fmu_dir, validate=False)
        variables = self.md.modelVariables
        self.vr = {x.name: x.valueReference for x in variables}
        self.nominal = {x.valueReference: float(x.start) if x.type in ("Real", "Float64") and x.start else 0.0
                        for x in variables}
        self.nominal[self.vr["speed"]] = SPEED
        self.nominal[self.vr["track_start"]] = START
        n = len(variables)
        self.reals = [x.valueReference for x in variables if x.type in ("Real", "Float64")]
        self.inputs = [x.valueReference for x in variables
                       if x.causality == "input" and x.valueReference in self.reals]
        self.outputs = [x.valueReference for x in variables if x.causality == "output"]
        self.tunable = [x.valueReference for x in variables
                        if x.causality == "parameter" and x.variability == "tunable"]
        self.booleans = [x.valueReference for x in variables if x.type == "Boolean"]
        self.strings = [x.valueReference for x in variables if x.type == "String"]
        self.any_vr = list(range(n)) + [n, *UNKNOWN_VRS]
        self.tracks = bad_tracks(out)
        self.slave_cls = FMU2Slave if version == 2 else FMU3Slave
        self._callbacks2 = (fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
        self.log = log  # a text file: every call is written (and flushed) before it is made
        self.k = 0
        self.messages: list[str] = []
        self.outcomes: dict[str, list[int]] = {}  # op -> [ok, refused]
        self.silent: list[str] = []  # refusals of a live instance without a logged message
        self.live: list = []  # slaves with a live instance
        self.freed: list = []  # (slave, pointer) of freed instances
        self.loaded: list = []  # every slave: each holds one load of the library
        self.states: list = []  # FMU states (ctypes pointers; freed ones are NULL)
        self.blobs: list[bytes] = []  # serialised states

    # ------------------------------------------------------------ plumbing

    def _logger(self, *args):
        self.messages.append(args[-1].decode(errors="replace"))

    def slave(self):
        s = self.slave_cls(guid=self.md.guid, unzipDirectory=self.dir,
                           modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=f"fuzz{len(self.loaded)}")
        self.loaded.append(s)
        return s

    def call(self, op: str, text: str, fn, *args, freed: bool = False, **kw):
        """Make one FMI call; an error status is an outcome, not a failure."""
        self.k += 1
        self.log.write(f"{self.k:5d} {text}")
        self.log.flush()
        self.messages.clear()
        counts = self.outcomes.setdefault(op, [0, 0])
        try:
            result = fn(*args, **kw)
        except FMICallException as e:
            counts[1] += 1
            label = STATUS[e.status] if 0 <= e.status < len(STATUS) else str(e.status)
            first = self.messages[0][:160] if self.messages else "(no message)"
            self.log.write(f" -> {label}: {first}\n")
            if not self.messages and not freed:
                self.silent.append(text)
            return False, None
        counts[0] += 1
        self.log.write(" -> ok\n")
        return True, result

    def raw(self, s, name: str):
        """A slave's FMI function itself: ``raw(s, "DoStep")`` is s.fmi2DoStep or s.fmi3DoStep."""
        return getattr(s, f"fmi{self.v}{name}")

    def value(self, vr: int) -> float:
        r = self.rng.random()
        if r < 0.45:
            return self.nominal.get(vr, 0.0) * (1 + 0.1 * self.rng.standard_normal())
        if r < 0.75:
            return float(self.rng.choice(HOSTILE))
        return float(self.rng.standard_normal() * 10.0 ** self.rng.integers(-6, 12))

    def pick(self, seq):
        return seq[int(self.rng.integers(len(seq)))]

    def target(self):
        return self.pick(self.live) if self.live else None

    # ------------------------------------------------------------ operations

    def instantiate(self):
        s = self.slave()
        if self.v == 2:
            cb_type, logger_type = self._callbacks2
            cb = cb_type()
            cb.logger = logger_type(self._logger)
            self.call("instantiate", f"{s.instanceName}: instantiate", s.instantiate, callbacks=cb, loggingOn=True)
        else:
            self.call("instantiate", f"{s.instanceName}: instantiate", s.instantiate, loggingOn=True,
                      logMessage=self._logger)
        self.live.append(s)

    def instantiate_badly(self):
        """Wrong GUID, wrong interface type, nonsense resource location: refused or harmless."""
        from fmpy.fmi3 import fmi3InstanceEnvironment, fmi3IntermediateUpdateCallback, fmi3LogMessageCallback

        s = self.slave()
        how = int(self.rng.integers(4))
        guid = (b"{00000000-0000-0000-0000-000000000000}" if how == 0 else None if how == 3
                else self.md.guid.encode())
        resources = self.pick([b"", b"file:///nonexistent", b"not a uri", b"%zz%41", None,
                               Path(self.dir, "resources").as_uri().encode()])
        text = f"{s.instanceName}: instantiate(guid={guid!r}, resources={resources!r}, odd interface={how == 1})"
        if self.v == 2:
            cb_type, logger_type = self._callbacks2
            s.callbacks = cb_type()
            s.callbacks.logger = logger_type(self._logger)
            _, c = self.call("instantiate", text, s.fmi2Instantiate, s.instanceName.encode(), 0 if how == 1 else 1,
                              guid, resources, byref(s.callbacks), False, True)
        else:
            s.logMessage = fmi3LogMessageCallback(self._logger)
            s.intermediateUpdate = fmi3IntermediateUpdateCallback()
            _, c = self.call("instantiate", text, s.fmi3InstantiateCoSimulation, s.instanceName.encode(), guid,
                              resources, False, True, how == 1, False, None, 0, fmi3InstanceEnvironment(),
                              s.logMessage, s.intermediateUpdate)
        self.log.write(f"      -> instance {c!r}\n")
        if c:
            s.component = c
            self.live.append(s)

    def free_instance(self):
        s = self.target()
        if s is None:
            return
        self.live.remove(s)
        for _ in range(2):  # freeing twice is harmless
            self.call("freeInstance", f"{s.instanceName}: freeInstance", self.raw(s, "FreeInstance"), s.component)
        self.freed.append((s, s.component))

    def call_freed(self):
        """A freed (or null) instance is refused, never touched. (Not an address malloc has given
        to a live instance since: that is the live instance.)"""
        live = {x.component for x in self.live}
        stale = [(s, c) for s, c in self.freed if c not in live]
        s, c = self.pick(stale) if stale and self.rng.random() < 0.8 else (self.slave(), None)
        kind = int(self.rng.integers(4))
        name = f"{s.instanceName}(freed {c!r})"
        if kind == 0:
            self.call("freeInstance", f"{name}: freeInstance", self.raw(s, "FreeInstance"), c, freed=True)
        elif kind == 1:
            vrs, arr = (c_uint * 1)(self.inputs[0]), (c_double * 1)(0.0)
            if self.v == 2:
                self.call("setReal", f"{name}: setReal", s.fmi2SetReal, c, vrs, 1, arr, freed=True)
            else:
                self.call("setReal", f"{name}: setFloat64", s.fmi3SetFloat64, c, vrs, 1, arr, 1, freed=True)
        elif kind == 2:
            if self.v == 2:
                self.call("doStep", f"{name}: doStep", s.fmi2DoStep, c, 0.0, 1e-3, 1, freed=True)
            else:
                from fmpy.fmi3 import fmi3Boolean, fmi3Float64
                flags = [fmi3Boolean() for _ in range(3)]
                last = fmi3Float64()
                self.call("doStep", f"{name}: doStep", s.fmi3DoStep, c, 0.0, 1e-3, True, *map(byref, flags),
                          byref(last), freed=True)
        else:
            self.call("terminate", f"{name}: terminate", self.raw(s, "Terminate"), c, freed=True)

    def enter_initialization(self, s=None, t0=None):
        s = s or self.target()
        if s is None:
            return
        t0 = float(self.pick(START_TIMES)) if t0 is None else t0
        if self.v == 2:
            if self.rng.random() < 0.9:
                self.call("setupExperiment", f"{s.instanceName}: setupExperiment(startTime={t0!r})",
                          s.setupExperiment, startTime=t0)
            self.call("enterInitializationMode", f"{s.instanceName}: enterInitializationMode",
                      s.enterInitializationMode)
        else:
            self.call("enterInitializationMode", f"{s.instanceName}: enterInitializationMode(startTime={t0!r})",
                      s.enterInitializationMode, startTime=t0)

    def exit_initialization(self, s=None):
        s = s or self.target()
        if s is not None:
            self.call("exitInitializationMode", f"{s.instanceName}: exitInitializationMode", s.exitInitializationMode)

    def now(self, s) -> float:
        ok, t = self.call("getReal", f"{s.instanceName}: get time", self.get_reals(s), [self.vr["time"]])
        return t[0] if ok else 0.0

    def get_reals(self, s):
        return s.getReal if self.v == 2 else s.getFloat64

    def set_reals(self, s):
        return s.setReal if self.v == 2 else s.setFloat64

    def do_step(self, s=None, h=None):
        s = s or self.target()
        if s is None:
            return
        t = self.now(s)
        r = self.rng.random()
        if r > 0.85:
            t = t + float(self.rng.choice([-1.0, 1.0])) * 10.0 ** float(self.rng.uniform(-12, 3))
        elif r > 0.8:
            t = float(self.pick(HOSTILE))
        h = float(self.pick(STEP_SIZES)) if h is None else h
        self.call("doStep", f"{s.instanceName}: doStep({t!r}, {h!r})", s.doStep, currentCommunicationPoint=t,
                  communicationStepSize=h)

    def set_real(self):
        """Any value reference, the inputs, the tunable parameters (non-positive masses, damping
        ratios, lengths: refused when the model is built) or any Real."""
        s = self.target()
        if s is None:
            return
        pool = self.pick([self.any_vr, self.inputs, self.tunable or self.reals, self.reals])
        vrs = [int(self.pick(pool)) for _ in range(int(self.rng.integers(1, 5)))]
        values = [self.value(vr) for vr in vrs]
        self.call("setReal", f"{s.instanceName}: setReal({vrs}, {values})", self.set_reals(s), vrs, values)

    def get_real(self):
        s = self.target()
        if s is None:
            return
        pool = self.pick([self.any_vr, self.outputs, self.reals, self.reals])
        vrs = [int(self.pick(pool)) for _ in range(int(self.rng.integers(1, 40)))]
        self.call("getReal", f"{s.instanceName}: getReal({vrs})", self.get_reals(s), vrs)

    def set_boolean(self):
        s = self.target()
        if s is None:
            return
        vr = int(self.pick(self.booleans if self.booleans and self.rng.random() < 0.7 else self.any_vr))
        value = self.pick([True, False, 2, -1]) if self.v == 2 else bool(self.rng.random() < 0.5)
        self.call("setBoolean", f"{s.instanceName}: setBoolean([{vr}], [{value}])", s.setBoolean, [vr], [value])

    def set_string(self):
        s = self.target()
        if s is None:
            return
        vr = int(self.pick(self.strings if self.strings and self.rng.random() < 0.8 else self.any_vr))
        path = self.pick(self.tracks)
        self.call("setString", f"{s.instanceName}: setString([{vr}], [{path[:80]!r}])", s.setString, [vr], [path])

    def get_other(self):
        """getBoolean / getString on any value reference."""
        s = self.target()
        if s is None:
            return
        vr = int(self.pick(self.any_vr))
        fn = s.getBoolean if self.rng.random() < 0.5 else s.getString
        self.call(fn.__name__, f"{s.instanceName}: {fn.__name__}([{vr}])", fn, [vr])

    def derivatives(self):
        """FMI 2: input derivatives of any order (more than 64 at once too); FMI 3 has none: output
        derivatives, which this FMU does not give."""
        s = self.target()
        if s is None:
            return
        n = int(self.pick([1, 2, 8, 70]))
        pool = self.inputs if self.rng.random() < 0.7 else self.any_vr
        vrs = [int(self.pick(pool)) for _ in range(n)]
        orders = [int(self.pick(ORDERS)) for _ in range(n)]
        if self.v == 2:
            values = [self.value(vr) if self.rng.random() < 0.5 else float(self.rng.standard_normal()) for vr in vrs]
            self.call("setRealInputDerivatives", f"{s.instanceName}: setRealInputDerivatives({vrs}, {orders}, "
                      f"{values})", s.setRealInputDerivatives, vrs, orders, values)
        else:
            self.call("getOutputDerivatives", f"{s.instanceName}: getOutputDerivatives({vrs}, {orders})",
                      s.getOutputDerivatives, vrs, orders)

    def terminate(self):
        s = self.target()
        if s is not None:
            self.call("terminate", f"{s.instanceName}: terminate", s.terminate)

    def reset(self):
        s = self.target()
        if s is not None:
            self.call("reset", f"{s.instanceName}: reset", s.reset)

    def restart(self):
        """A well-behaved start, so that sequences reach step mode often."""
        s = self.target()
        if s is None:
            return
        self.call("reset", f"{s.instanceName}: reset", s.reset)
        standalone = bool(self.rng.random() < 0.6)
        self.call("setBoolean", f"{s.instanceName}: setBoolean(standalone={standalone})", s.setBoolean,
                  [self.vr["standalone"]], [standalone])
        self.call("setReal", f"{s.instanceName}: setReal(speed, track_start = {SPEED}, {START})", self.set_reals(s),
                  [self.vr["speed"], self.vr["track_start"]], [SPEED, START])
        self.enter_initialization(s, 0.0)
        self.exit_initialization(s)
        for _ in range(int(self.rng.integers(0, 4))):
            self.do_step(s, 1e-3)

    def get_state(self):
        s = self.target()
        if s is None:
            return
        if self.states and self.rng.random() < 0.3:  # into an existing state (NULL if freed: a new one)
            state = self.pick(self.states)
            self.call("getFMUState", f"{s.instanceName}: getFMUState(into {state.value!r})",
                      self.raw(s, "GetFMUstate" if self.v == 2 else "GetFMUState"), s.component, byref(state))
        else:
            ok, state = self.call("getFMUState", f"{s.instanceName}: getFMUState", s.getFMUState)
            if ok:
                self.states.append(state)

    def set_state(self):
        s = self.target()
        if s is None or not self.states:
            return
        state = self.pick(self.states)
        self.call("setFMUState", f"{s.instanceName}: setFMUState({state.value!r})", s.setFMUState, state)

    def free_state(self):
        s = self.target()
        if s is None or not self.states:
            return
        state = self.pick(self.states)  # fmpy passes its address: the FMU sets it to NULL, so twice is harmless
        self.call("freeFMUState", f"{s.instanceName}: freeFMUState({state.value!r})", s.freeFMUState, state)

    def serialize(self):
        s = self.target()
        if s is None or not self.states:
            return
        state = self.pick(self.states)
        if self.rng.random() < 0.7:
            ok, blob = self.call("serializeFMUState", f"{s.instanceName}: serializeFMUState({state.value!r})",
                                 s.serializeFMUState, state)
            if ok:
                self.blobs.append(blob)
            return
        # a buffer shorter than the state, with its true size
        size = int(self.pick([0, 1, 8, 100]))
        buf = create_string_buffer(max(size, 1))
        from fmpy.fmi3 import fmi3Byte
        arg = buf if self.v == 2 else cast(buf, POINTER(fmi3Byte))
        self.call("serializeFMUState", f"{s.instanceName}: serializeFMUState({state.value!r}, size={size})",
                  self.raw(s, "SerializeFMUstate" if self.v == 2 else "SerializeFMUState"), s.component,
                  state, arg, size)

    def deserialize(self):
        """Good bytes, bytes of the wrong length, a wrong magic number, random bytes, and good bytes
        with damaged values past the header (magic, mode: see test_a_forged_fmu_state...)."""
        s = self.target()
        if s is None or not self.blobs:
            return
        blob = bytearray(self.pick(self.blobs))
        how = self.pick(["good", "good", "short", "long", "empty", "magic", "random", "damaged"])
        if how == "short":
            blob = blob[:int(self.rng.integers(len(blob)))]
        elif how == "long":
            blob += bytes(int(self.rng.integers(1, 1000)))
        elif how == "empty":
            blob = bytearray()
        elif how == "magic":
            blob[0] ^= 0xFF
        elif how == "random":
            blob = bytearray(self.rng.bytes(len(blob)))
        elif how == "damaged":
            for _ in range(int(self.rng.integers(1, 8))):
                blob[int(self.rng.integers(8, len(blob)))] = int(self.rng.integers(256))
        into = self.pick(self.states) if self.states and self.rng.random() < 0.3 else None
        where = f", into {into.value!r}" if into is not None else ""
        ok, state = self.call("deserializeFMUState", f"{s.instanceName}: deserializeFMUState({how}, {len(blob)} "
                              f"bytes{where})",
                              s.deserializeFMUState, bytes(blob), into)
        if ok and into is None:
            self.states.append(state)

    def unsupported(self):
        """Functions of interfaces this FMU does not declare: refused with a message."""
        s = self.target()
        if s is None:
            return
        if self.v == 2:
            fn, args = self.pick([(s.cancelStep, ()), (s.getRealStatus, (2,)), (s.getBooleanStatus, (0,)),
                                  (s.getIntegerStatus, (0,)), (s.getDirectionalDerivative, ([20], [12], [1.0]))])
        else:
            fn, args = self.pick([(s.enterEventMode, ()), (s.enterStepMode, ()), (s.getInt32, ([1],)),
                                  (s.getFloat32, ([1],)), (s.setInt32, ([1], [5]))])
        self.call(fn.__name__, f"{s.instanceName}: {fn.__name__}{args}", fn, *args)

    def debug_logging(self):
        s = self.target()
        if s is not None:
            on = bool(self.rng.random() < 0.8)
            self.call("setDebugLogging", f"{s.instanceName}: setDebugLogging({on})", s.setDebugLogging, on,
                      ["logEvents", "nonsense"])

    # ------------------------------------------------------------ the sequence

    def run(self, calls: int):
        ops = {self.instantiate: 2, self.instantiate_badly: 1, self.free_instance: 1, self.call_freed: 1,
               self.enter_initialization: 5, self.exit_initialization: 6, self.do_step: 25, self.terminate: 2,
               self.reset: 3, self.restart: 8, self.set_real: 12, self.get_real: 5, self.set_boolean: 3,
               self.set_string: 3, self.get_other: 2, self.derivatives: 4, self.get_state: 4, self.set_state: 4,
               self.free_state: 3, self.serialize: 3, self.deserialize: 4, self.unsupported: 2,
               self.debug_logging: 1}
        fns, weights = list(ops), np.array(list(ops.values()), float)
        while self.k < calls:
            op = fns[self.rng.choice(len(fns), p=weights / weights.sum())]
            if op is self.instantiate and len(self.live) >= 3:
                op = self.free_instance
            op()
        while self.live:
            self.free_instance()

    def close(self):
        for s in self.loaded:
            s.freeLibrary()


def output_names(fmu_dir) -> list[str]:
    """The FMU's outputs, in the order of its modelDescription (the columns of a clean run)."""
    return [x.name for x in fmpy.read_model_description(fmu_dir, validate=False).modelVariables
            if x.causality == "output"]


def clean_run(fmu_dir: str, version: int) -> np.ndarray:
    """1 s over the shipped track at 40 m/s from 100 m in 1 ms steps, every other input at its
    start value (0): the outputs at every communication point, (CLEAN_STEPS + 1, outputs),
    columns in :func:`output_names`' order."""
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave

    md = fmpy.read_model_description(fmu_dir, validate=False)
    vr = {x.name: x.valueReference for x in md.modelVariables}
    fmu = (FMU2Slave if version == 2 else FMU3Slave)(guid=md.guid, unzipDirectory=fmu_dir,
                                                     modelIdentifier=md.coSimulation.modelIdentifier,
                                                     instanceName="clean")
    fmu.instantiate()
    outs = [vr[n] for n in output_names(fmu_dir)]
    if version == 2:
        fmu.setReal([vr["speed"], vr["track_start"]], [SPEED, START])
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        get = fmu.getReal
    else:
        fmu.setFloat64([vr["speed"], vr["track_start"]], [SPEED, START])
        fmu.enterInitializationMode(startTime=0.0)
        get = fmu.getFloat64
    fmu.exitInitializationMode()
    y = [get(outs)]
    for k in range(CLEAN_STEPS):
        fmu.doStep(currentCommunicationPoint=k * CLEAN_H, communicationStepSize=CLEAN_H)
        y.append(get(outs))
    fmu.terminate()
    fmu.freeInstance()
    return np.array(y)


def forged_state(fz: Fuzzer):
    """A serialised state whose magic number is right but whose mode is none of the FMU's
    (a damaged file, or one written by another build): refused, never stepped."""
    fz.instantiate()
    s = fz.live[0]
    _, state = fz.call("getFMUState", f"{s.instanceName}: getFMUState", s.getFMUState)
    _, blob = fz.call("serializeFMUState", f"{s.instanceName}: serializeFMUState", s.serializeFMUState, state)
    blob = bytearray(blob)
    blob[4:8] = b"\xff\xff\xff\xff"  # Snapshot.state, after the magic number
    _, forged = fz.call("deserializeFMUState", f"{s.instanceName}: deserializeFMUState(mode bytes 4-7 = ff ff ff ff)",
                        s.deserializeFMUState, bytes(blob))
    fz.call("setFMUState", f"{s.instanceName}: setFMUState(forged)", s.setFMUState, forged)
    fz.call("doStep", f"{s.instanceName}: doStep(0.0, 0.001)", s.doStep, currentCommunicationPoint=0.0,
            communicationStepSize=1e-3)
    fz.free_instance()


def endless_track(fz: Fuzzer):
    """A track file that never ends (/dev/zero): refused in bounded time."""
    fz.instantiate()
    s = fz.live[0]
    fz.call("setString", f"{s.instanceName}: setString(track_file = '/dev/zero')", s.setString,
            [fz.vr["track_file"]], ["/dev/zero"])
    fz.enter_initialization(s, 0.0)
    fz.exit_initialization(s)
    fz.free_instance()


SCENARIOS = {"forged_state": forged_state, "endless_track": endless_track}


def child(fmu_dir: str, version: int, scenario: str, out: Path):
    """Run one scenario (``seed:<n>:<calls>`` for a random sequence); then, for a random
    sequence, a clean run of a fresh instance while the fuzzed library is still loaded. Writes
    summary.json (and clean.npy)."""
    import faulthandler

    faulthandler.enable()  # a crash prints the Python stack to stderr
    with open(out / "calls.log", "w", encoding="utf-8") as log:
        if scenario.startswith("seed:"):
            _, seed, calls = scenario.split(":")
            fz = Fuzzer(fmu_dir, version, out, log, np.random.default_rng(int(seed)))
            fz.run(int(calls))
            log.write("----- a fresh instance: the clean run\n")
            log.flush()
            np.save(out / "clean.npy", clean_run(fmu_dir, version))
        else:
            fz = Fuzzer(fmu_dir, version, out, log, np.random.default_rng(0))
            SCENARIOS[scenario](fz)
        fz.close()
    (out / "summary.json").write_text(json.dumps({"calls": fz.k, "outcomes": fz.outcomes, "silent": fz.silent}))


if __name__ == "__main__":
    child(sys.argv[1], int(sys.argv[2]), sys.argv[3], Path(sys.argv[4]))
    sys.exit(0)
