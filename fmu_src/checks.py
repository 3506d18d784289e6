"""What a reviewer checks of a built FMU before handing it on, each by a tool other than the
one that built it:

* fmpy's validation of the model description against the FMI schema and rules;
* fmutool's conformity and semantic checks (the FMU Manipulation Toolbox, an independent
  implementation of the standard's rules);
* the same run in two co-simulation masters, fmpy and libcosim (the Open Simulation
  Platform's), with every Real input driven by a sine of its own, every output compared;
* its variables, with causality, variability and unit, as an importer sees them.
"""
from __future__ import annotations

import contextlib
import io
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_LEVEL = re.compile(r"^(DEBUG|INFO|WARNING|ERROR|CRITICAL)\s*\| (.*)$")


def fmutool_log(path) -> tuple[int, list[tuple[str, str]]]:
    """Run ``fmutool -input PATH -check``: its exit code and its log as (level, message)."""
    proc = subprocess.run([sys.executable, "-m", "fmu_manipulation_toolbox.cli.fmutool", "-input", str(path),
                           "-check"], check=False, capture_output=True, text=True, timeout=300)
    records = []
    for line in _ANSI.sub("", proc.stdout + proc.stderr).splitlines():
        m = _LEVEL.match(line)
        if m:
            records.append((m[1], m[2].strip()))
        elif line.strip():  # a message over several lines, or a traceback: keep it, at its record's level
            records.append((records[-1][0] if records else "UNPARSED", line.strip()))
    return proc.returncode, records


def fmutool_check(path) -> dict:
    """fmutool's verdict on the FMU at ``path``: its exit code and its warnings and errors."""
    code, log = fmutool_log(path)
    problems = [f"{level}: {msg}" for level, msg in log if level not in ("DEBUG", "INFO")]
    return {"exit_code": code, "problems": problems, "pass": code == 0 and not problems}


def _drive(inputs, t: np.ndarray) -> np.ndarray:
    """Every driven input a sine of its own frequency (1.1, 2.3, 3.5, ... Hz), its amplitude
    by its unit: rails move 1 mm (and 1 cm/s), a force is 100 N."""
    table = np.zeros(t.size, dtype=[("time", float)] + [(v.name, float) for v in inputs])
    table["time"] = t
    for k, v in enumerate(inputs):
        scale = {"m": 1e-3, "m/s": 1e-2, "N": 100.0}.get(v.unit or (v.declaredType and v.declaredType.unit), 1e-3)
        table[v.name] = scale * np.sin(2 * np.pi * (1.1 + 1.2 * k) * t)
    return table


def masters_agree(path, *, step: float = 1e-3, stop: float = 2.0) -> dict:
    """The FMU run from rest in fmpy and in libcosim with the same inputs: the largest
    difference of each Real output over its standard deviation (fmpy's run), and the worst."""
    import fmpy

    from .importers import simulate_libcosim

    md = fmpy.read_model_description(str(path))
    real = [v for v in md.modelVariables if v.type == "Real"]
    # as a co-simulation sees it: the rails from its inputs (not from a track it carries), its speed left alone
    start = {v.name: False for v in md.modelVariables if v.name == "standalone"}
    inputs = [v for v in real if v.causality == "input" and v.name != "speed"]
    outputs = [v.name for v in real if v.causality == "output"]
    t = np.arange(0.0, stop + step / 2, step)
    table = _drive(inputs, t)
    with contextlib.redirect_stdout(io.StringIO()):  # fmpy prints a line for the speed input it is not given
        a = fmpy.simulate_fmu(str(path), stop_time=stop, output_interval=step, step_size=step, input=table,
                              output=outputs, start_values=start)
    # libcosim's FMI Library logs two errors for every FMI 2 FMU's independent variable `time`
    # (fmi-library issue 21, a misreading of the standard): only its failures are shown
    b = simulate_libcosim(path, step=step, stop=stop, outputs=outputs, inputs=table, start_values=start,
                          log_level="fatal")
    n = min(len(a), len(b))
    std = {name: float(np.std(a[name][:n])) for name in outputs}
    rel = {name: float(np.max(np.abs(a[name][:n] - b[name][:n]))) / std[name] if std[name] > 0 else None
           for name in outputs}
    moved = [r for r in rel.values() if r is not None]
    return {"step_s": step, "stop_s": stop, "inputs": [v.name for v in inputs], "std": std,
            "max_difference_over_std": rel, "worst": max(moved) if moved else None}


def check_fmu(path, *, tolerance: float = 1e-9) -> dict:
    """Every check of the module docstring on the FMU at ``path``, as a JSON-ready record."""
    import fmpy
    from fmpy.model_description import ValidationError
    from fmpy.validation import validate_fmu

    path = Path(path)
    try:
        fmpy_problems = [str(p) for p in validate_fmu(str(path))]
    except ValidationError as e:  # a model description fmpy cannot even read as valid
        fmpy_problems = [str(e)]
    md = fmpy.read_model_description(str(path), validate=False)
    variables = [{"name": v.name, "causality": v.causality, "variability": v.variability, "type": v.type,
                  "unit": v.unit or (v.declaredType.unit if v.declaredType else None)} for v in md.modelVariables]
    out = {"fmu": path.name, "fmi_version": md.fmiVersion,
           "model_identifier": md.coSimulation.modelIdentifier if md.coSimulation else None, "guid": md.guid,
           "fmpy_validate": {"problems": fmpy_problems, "pass": not fmpy_problems},
           "fmutool": fmutool_check(path), "variables": variables}
    if not md.fmiVersion.startswith("2"):
        out["fmpy_vs_libcosim_not_run"] = f"libcosim loads FMI 1 and 2 only; this FMU is FMI {md.fmiVersion}"
    elif fmpy_problems:
        out["fmpy_vs_libcosim_not_run"] = "the model description did not pass fmpy's validation"
    else:
        agree = masters_agree(path)
        # a run in which no output moves compares nothing: it fails
        out["fmpy_vs_libcosim"] = {**agree, "tolerance": tolerance,
                                   "pass": agree["worst"] is not None and agree["worst"] <= tolerance}
    # an FMI 3 FMU is judged on the two checkers alone, and the record says why
    checks = [out["fmpy_validate"]["pass"], out["fmutool"]["pass"], out.get("fmpy_vs_libcosim", {}).get("pass", True)]
    out["verdict"] = "pass" if all(checks) else "fail"
    return out
