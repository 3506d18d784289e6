"""Run the project's FMUs in other co-simulation masters ("importers") than fmpy.

``simulate_libcosim`` runs an FMU in the Open Simulation Platform's libcosim through the
PyPI package ``libcosimpy`` (0.0.6) with libcosim's fixed-step algorithm, optional
per-step real inputs and start values, and returns every requested output at every
communication point as a numpy structured array (SI units, as declared by the FMU).

libcosimpy 0.0.6 facts this module relies on (read from its source and checked on the
project's FMUs):

* Only FMI 1.0 and 2.0 co-simulation FMUs load; an FMI 3.0 FMU is refused with
  "Unsupported feature: Unsupported FMI version for FMU '...'".
* Time is an integer number of nanoseconds, so ``step`` must be a whole number of ns.
* An execution step runs: (initialisation, on the first step only) -> manipulators ->
  set inputs -> ``doStep(t, step)`` -> observers.  An input override placed before
  ``step(1)`` therefore holds over the step that starts at t, as in fmpy.
* ``CosimObserver.time_series_*_samples`` drops one sample whenever the samples asked for
  include step 0 (it trims by counting zero step numbers); ``_read_samples`` works around it.
* An FMU error during a step comes back as a failed step (RuntimeError here), but one during
  initialisation (inside the first step) makes libcosim call ``std::terminate``: the Python
  process aborts ("terminate called after throwing an instance of 'cosim::error'").
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from libcosimpy._internal import get_last_error_message
from libcosimpy.CosimEnums import CosimVariableCausality, CosimVariableType
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimManipulator import CosimManipulator
from libcosimpy.CosimObserver import CosimObserver
from libcosimpy.CosimSlave import CosimLocalSlave, CosimSlaveVariableDescription

NS_PER_S = 1_000_000_000  # libcosim's time unit is the nanosecond
CHUNK_STEPS = 10_000  # samples are fetched (and libcosim's buffer bounded) every this many steps

_SETTABLE = (CosimVariableCausality.PARAMETER, CosimVariableCausality.INPUT)
_OBSERVABLE = {CosimVariableType.REAL: np.float64, CosimVariableType.INTEGER: np.int32}


def simulate_libcosim(fmu: Path | str, *, step: float, stop: float, outputs: Sequence[str],
                      start_values: Mapping[str, float | bool | str] | None = None,
                      inputs: np.ndarray | None = None, log_level: str = "warning") -> np.ndarray:
    """Simulate a co-simulation FMU in libcosim from t = 0 to ``stop`` [s] in steps of ``step`` [s].

    ``start_values`` sets parameters/inputs (Real, Integer, Boolean or String by the FMU's
    declaration) before initialisation.  ``inputs`` is a structured array with a ``time``
    field on the communication points 0, step, ..., stop - step (a row at ``stop`` or later
    is allowed and unused) and one field per Real input of the FMU; the row at time t is set
    before the step starting at t (and the row at t = 0 also during initialisation, as fmpy
    does).  ``log_level`` is libcosim's process-wide log level ("trace" ... "fatal").

    Returns a structured array with ``time`` [s] and one field per name in ``outputs`` (Real
    or Integer variables), one row per communication point t = 0, step, ..., stop.

    Raises ValueError for a missing or unloadable FMU (including FMI 3.0, which libcosim
    cannot load), an unknown or unsuitable variable name, a badly typed value or an input
    array off the time grid; RuntimeError if libcosim reports a failure while stepping.
    """
    fmu = Path(fmu)
    n_steps, step_ns = _time_grid(step, stop)
    if len(set(outputs)) != len(outputs) or "time" in outputs:
        raise ValueError(f"outputs must be distinct variable names other than 'time': {list(outputs)}")
    if not fmu.is_file():
        raise ValueError(f"FMU file not found: {fmu}")

    if log_level.upper() not in CosimLogLevel.__members__:
        raise ValueError(f"log_level must be one of {[m.lower() for m in CosimLogLevel.__members__]}")
    log_output_level(CosimLogLevel[log_level.upper()])
    execution = CosimExecution.from_step_size(step_ns)
    slave = CosimLocalSlave(fmu_path=str(fmu), instance_name=fmu.stem)
    if not slave.ptr():
        raise ValueError(f"libcosim cannot load the FMU {fmu}: {get_last_error_message()}")
    index = execution.add_local_slave(slave)
    if index < 0:
        raise ValueError(f"libcosim cannot add the FMU {fmu} to an execution: {get_last_error_message()}")
    variables = {v.name.decode(): v for v in execution.slave_variables(index)}

    def lookup(name: str, role: str) -> CosimSlaveVariableDescription:
        if name not in variables:
            raise ValueError(f"{fmu.name} has no variable named {name!r} (given as {role})")
        return variables[name]

    for name, value in (start_values or {}).items():
        _set_initial_value(execution, index, lookup(name, "a start value"), name, value)

    input_refs: list[int] = []
    input_values = np.empty((n_steps, 0))
    if inputs is not None:
        input_names, input_values = _input_table(inputs, n_steps, step)
        for name in input_names:
            var = lookup(name, "an input field")
            if (CosimVariableType(var.type) is not CosimVariableType.REAL
                    or CosimVariableCausality(var.causality) is not CosimVariableCausality.INPUT):
                raise ValueError(f"{fmu.name}: {name!r} is not a Real input, so it cannot be an input field")
            input_refs.append(var.reference)
            _set_initial_value(execution, index, var, name, float(input_values[0, len(input_refs) - 1]))

    observer = CosimObserver.create_time_series(buffer_size=CHUNK_STEPS + 1)
    execution.add_observer(observer)
    observed = []
    for name in outputs:
        var = lookup(name, "an output")
        vtype = CosimVariableType(var.type)
        if vtype not in _OBSERVABLE:
            raise ValueError(f"{fmu.name}: output {name!r} is {vtype.name}; only Real and Integer can be recorded")
        if not observer.start_time_series(index, var.reference, vtype):
            raise ValueError(f"libcosim cannot observe {name!r} of {fmu.name}: {get_last_error_message()}")
        observed.append((name, var.reference, vtype))

    manipulator = None
    if input_refs:
        manipulator = CosimManipulator.create_override()
        execution.add_manipulator(manipulator)

    result = np.zeros(n_steps + 1, dtype=[("time", np.float64)]
                      + [(name, _OBSERVABLE[vtype]) for name, _, vtype in observed])
    time_ns = np.zeros(n_steps + 1, dtype=np.int64)
    done = 0
    while done < n_steps:
        todo = min(CHUNK_STEPS, n_steps - done)
        if manipulator is None:
            ok = execution.step(todo)
        else:  # one step at a time, the override for step k placed just before it
            ok = True
            for k in range(done, done + todo):
                ok = (manipulator.slave_real_values(index, input_refs, input_values[k].tolist())
                      and execution.step(1))
                if not ok:
                    break
        if not ok:
            reached = execution.status().current_time / NS_PER_S
            raise RuntimeError(f"libcosim failed to simulate {fmu.name} beyond t = {reached:g} s: "
                               f"{get_last_error_message()}")
        for name, ref, vtype in observed:
            if done == 0:
                time_ns[:1], result[name][:1] = _read_samples(observer, index, ref, vtype, 0, 1)
            times, values = _read_samples(observer, index, ref, vtype, done + 1, todo)
            time_ns[done + 1:done + todo + 1], result[name][done + 1:done + todo + 1] = times, values
        done += todo
    if np.any(time_ns != step_ns * np.arange(n_steps + 1)):
        raise RuntimeError(f"libcosim's sample times for {fmu.name} are off the {step:g} s grid")
    result["time"] = time_ns / NS_PER_S
    return result


def _time_grid(step: float, stop: float) -> tuple[int, int]:
    """Number of communication steps and the step in ns, checking both are whole numbers."""
    if not (step > 0 and stop > 0):
        raise ValueError(f"step and stop must be positive, got step={step}, stop={stop}")
    step_ns = round(step * NS_PER_S)
    if step_ns < 1 or abs(step * NS_PER_S - step_ns) > 1e-3:
        raise ValueError(f"step = {step} s is not a whole number of nanoseconds (libcosim's time unit)")
    n_steps = round(stop / step)
    if abs(n_steps * step - stop) > 1e-9 * stop:
        raise ValueError(f"stop = {stop} s is not a whole number of steps of {step} s")
    return n_steps, step_ns


def _set_initial_value(execution: CosimExecution, index: int, var: CosimSlaveVariableDescription,
                       name: str, value) -> None:
    """Set ``value`` as the initial value of the parameter or input ``var`` named ``name``."""
    causality = CosimVariableCausality(var.causality)
    if causality not in _SETTABLE:
        raise ValueError(f"{name!r} is {causality.name.lower()}, not a parameter or input: it has no start value to set")
    vtype = CosimVariableType(var.type)
    is_bool = isinstance(value, (bool, np.bool_))
    is_number = isinstance(value, (int, float, np.integer, np.floating)) and not is_bool
    if vtype is CosimVariableType.STRING and isinstance(value, str):
        ok = execution.string_initial_value(index, var.reference, value)
    elif vtype is CosimVariableType.BOOLEAN and is_bool:
        ok = execution.boolean_initial_value(index, var.reference, bool(value))
    elif vtype is CosimVariableType.INTEGER and is_number and float(value).is_integer():
        ok = execution.integer_initial_value(index, var.reference, int(value))
    elif vtype is CosimVariableType.REAL and is_number:
        ok = execution.real_initial_value(index, var.reference, float(value))
    else:
        raise ValueError(f"{name!r} is a {vtype.name} variable; {value!r} is not a value for it")
    if not ok:
        raise ValueError(f"libcosim cannot set {name!r} to {value!r}: {get_last_error_message()}")


def _input_table(inputs: np.ndarray, n_steps: int, step: float) -> tuple[list[str], np.ndarray]:
    """The input names and their values (n_steps, n_inputs) for the steps starting at k step."""
    names = list(inputs.dtype.names or ())
    if "time" not in names or len(names) < 2:
        raise ValueError("inputs must be a structured array with a 'time' field and at least one input field")
    names.remove("time")
    if len(inputs) < n_steps:
        raise ValueError(f"inputs has {len(inputs)} rows, needs one per step start ({n_steps})")
    grid = step * np.arange(min(len(inputs), n_steps + 1))
    off = np.abs(np.asarray(inputs["time"][:grid.size], float) - grid)
    if np.any(off > 1e-6 * step):
        k = int(np.flatnonzero(off > 1e-6 * step)[0])
        raise ValueError(f"inputs['time'][{k}] = {inputs['time'][k]} s is off the communication point {grid[k]} s")
    values = np.column_stack([np.asarray(inputs[name][:n_steps], np.float64) for name in names])
    if not np.all(np.isfinite(values)):
        raise ValueError("inputs contain non-finite values")
    return names, values


def _read_samples(observer: CosimObserver, index: int, ref: int, vtype: CosimVariableType,
                  first: int, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Times [ns] and values of ``count`` recorded samples of a variable from step ``first`` on.

    libcosimpy 0.0.6 trims the samples it returns by counting step numbers equal to 0, so a
    read starting at step 0 loses one sample; step 0 is therefore read as the first of two.
    """
    read = (observer.time_series_real_samples if vtype is CosimVariableType.REAL
            else observer.time_series_integer_samples)
    asked = count + 1 if first == 0 else count
    times, steps, values = (np.asarray(a) for a in read(index, ref, from_step=first, sample_count=asked))
    times, steps, values = times[:count], steps[:count], values[:count]
    if not np.array_equal(steps, np.arange(first, first + count)):
        raise RuntimeError(f"libcosim returned steps {steps[:3]}... for steps {first}..{first + count - 1}")
    return times, values
