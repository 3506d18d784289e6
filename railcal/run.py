"""``railcal run``: the whole job on a user's campaign, into one folder.

Each step is the railcal command of the same name, writing its JSON and figures as that
command does; a later step reads the earlier ones' files (``calibrate`` takes the
identification made before, ``diagnose`` the calibration, ...) instead of computing them
again. A step is skipped when its command line and the content of its inputs are those of
its last completed run (``run.json`` keeps each step's key, a SHA-256 of both) and its
outputs are still there, so a run stopped half-way, or repeated, does only what is new.

Identification and calibration are needed by everything after them: their failure stops
the run. Any other step that cannot be done with this campaign (no track recording to
validate over, no C compiler for an FMU) is recorded with its reason, and the run goes on;
the report says which steps ran. Every step's summary line goes to ``run.log``.
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import json
import statistics
import time
from dataclasses import dataclass, replace
from pathlib import Path

import jinja2

from calibration.data.errors import InputError
from calibration.data.outputs import check_outputs, write_atomic, write_json_atomic

from .provenance import file_sha256, provenance

RUN_FORMAT = "railcal-run/1"


@dataclass(frozen=True)
class Step:
    """One command of the run: its railcal arguments (without ``--quiet``), the files (or
    the campaign folder) whose content decides its result, and the files it writes."""

    name: str
    argv: tuple
    inputs: tuple
    outputs: tuple
    needed: bool = False  # its failure stops the run
    skip: str | None = None  # why it is not run on this campaign (its inputs say it cannot or need not be)
    needless: bool = False  # skipped because its answer is known (no extended model), not because it cannot be done


def _content_key(step: Step, known: dict) -> str:
    """SHA-256 of the step's command line and its inputs' content (``known``: hashes already
    made, by path: the campaign folder's fingerprint)."""
    h = hashlib.sha256(json.dumps(list(step.argv)).encode())
    for path in map(Path, step.inputs):
        h.update((known.get(path) or (file_sha256(path) if path.is_file() else "absent")).encode())
    return h.hexdigest()


def _speed(identification: Path, default: float = 40.0) -> float:
    """[m/s] the median of the runs' mean speeds in an identification, for the cross-check."""
    try:
        runs = json.loads(identification.read_text())["data"]["runs"]
        return float(statistics.median(0.5 * (r["speed_m_s"][0] + r["speed_m_s"][1]) for r in runs))
    except (OSError, ValueError, KeyError, TypeError, IndexError, statistics.StatisticsError):
        return default


def _no_extended_model(diagnosis: Path) -> tuple[str, bool] | None:
    """Why the diagnosis at ``diagnosis`` gives no extended model to validate, export and
    cross-check, and whether that is because there is none (True: the steps are needless) or
    because its file holds none (False); None when it gives one (or is not made yet)."""
    try:
        d = json.loads(diagnosis.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(d, dict):
        return None
    if not d.get("extension") and not d.get("findings"):  # in service, findings are the causes and properties
        return f"the diagnosis found {d.get('cause')}: there is no extended model, the calibrated one stands", True
    if "parameters" not in d:  # a cause without a model to carry it (a file made by hand, say)
        return (f"the diagnosis file names {d.get('cause')} but holds no extended model (no 'parameters'): "
                f"diagnose again to make one", False)
    return None


def plan(campaign, out: Path, model: str, options: dict | None = None) -> list[Step]:
    """The steps of a run of ``campaign`` (an opened campaign) into ``out`` with ``model``;
    ``options``: more command-line arguments of a step, by its name (``{"calibrate":
    ["--particles", "200"]}``), which are part of its key."""
    options = options or {}
    root = str(campaign.root)
    f = {name: out / f"{name}.json" for name in ("identification", "calibration", "validation", "diagnosis",
                                                 "validation_extended", "crosscheck", "crosscheck_extended",
                                                 "fmu_baseline", "fmu_extended")}
    track = [str(sorted(campaign.track_paths)[0])] if campaign.track_paths else []
    calibrate = ["calibrate", root, "--identification", str(f["identification"]), "--model", model, "--refine"]
    if model == "box":
        calibrate += ["--method", "pso"]
    fmu = {"baseline": out / "fmu" / "baseline.fmu", "extended": out / "fmu" / "extended.fmu"}
    no_extended = _no_extended_model(f["diagnosis"])
    skip = {"baseline": {}, "extended": {} if no_extended is None else
            {"skip": no_extended[0], "needless": no_extended[1]}}
    steps = [Step("identify", ("identify", root, "--out", str(f["identification"])), (campaign.root,),
                  (f["identification"],), needed=True),
             Step("calibrate", tuple(calibrate + ["--out", str(f["calibration"])]),
                  (campaign.root, f["identification"]), (f["calibration"],), needed=True),
             Step("validate", ("validate", root, "--calibration", str(f["calibration"]), "--out", str(f["validation"])),
                  (campaign.root, f["calibration"]), (f["validation"],)),
             Step("diagnose", ("diagnose", root, "--calibration", str(f["calibration"]), "--out", str(f["diagnosis"])),
                  (campaign.root, f["calibration"]), (f["diagnosis"],)),
             # the extended model over the same track and runs: its responses and its ride comfort
             Step("validate extended", ("validate", root, "--calibration", str(f["diagnosis"]), "--out",
                                        str(f["validation_extended"])),
                  (campaign.root, f["diagnosis"]), (f["validation_extended"],), **skip["extended"])]
    for which, source in (("baseline", f["calibration"]), ("extended", f["diagnosis"])):
        extra = ["--track", *track] if track and model == "car2d" else []
        steps.append(Step(f"export-fmu {which}", ("export-fmu", "--calibration", str(source), *extra,
                                                  "--out", str(fmu[which]), "--check", str(f[f"fmu_{which}"])),
                          (source, *map(Path, track)), (fmu[which], f[f"fmu_{which}"]), **skip[which]))
    speed = f"{_speed(f['identification']):.6g}"
    for which, source, result in (("baseline", f["calibration"], f["crosscheck"]),
                                  ("extended", f["diagnosis"], f["crosscheck_extended"])):
        extra = ["--track", *track, "--speed", speed] if track and model == "car2d" else []
        steps.append(Step(f"crosscheck {which}", ("crosscheck", "--calibration", str(source), *extra,
                                                  "--out", str(result)),
                          (source, *map(Path, track)), (result,), **skip[which]))
    return [replace(s, argv=s.argv + tuple(options.get(s.name, ()))) for s in steps]


def _invoke(argv) -> tuple[int, str, str]:
    """Run one railcal command in this process: (exit code, its stdout, its stderr)."""
    from .cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([*argv, "--quiet"])
    return code, out.getvalue().strip(), err.getvalue().strip()


def run_campaign(campaign, out, *, model: str, pdf: bool = True, say=print, criteria_path=None,
                 options: dict | None = None) -> dict:
    """Run every step of :func:`plan` (with ``options``) into ``out`` (created), skipping
    those unchanged, then the report; return the run record (also written to
    ``out``/run.json)."""
    from .report.build import write_report
    from .report.render import pdf_available

    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a folder; --out takes the folder to write the run into", path=out,
                         key="--out")
    check_outputs([out / "run.json"], inputs=[campaign.root, criteria_path])  # never inside the campaign it reads
    if criteria_path is not None:  # a malformed file is refused before any work
        from .report.criteria import load_criteria

        load_criteria(criteria_path)
    out.mkdir(parents=True, exist_ok=True)
    record_path, log_path = out / "run.json", out / "run.log"
    previous = {}
    if record_path.is_file():
        try:
            previous = {s["name"]: s for s in json.loads(record_path.read_text()).get("steps", [])}
        except (ValueError, AttributeError):
            previous = {}
    campaign_sha = campaign.fingerprint()  # every step reads the campaign: hashed once
    known = {Path(campaign.root): campaign_sha}
    steps, log, stopped = [], [], None
    planned = plan(campaign, out, model, options)
    for i in range(1, len(planned) + 1):
        step = plan(campaign, out, model, options)[i - 1]  # planned again: a step's options may read an earlier result
        key = _content_key(step, known)
        last = previous.get(step.name, {})
        if step.skip is not None:
            for o in step.outputs:  # an earlier run's result of it would describe another model
                Path(o).unlink(missing_ok=True)
            steps.append({"name": step.name, "command": ["railcal", *step.argv], "key": key, "status": "skipped",
                          "reason": step.skip, "needless": step.needless,
                          "outputs": [Path(o).name for o in step.outputs]})
            log.append(f"{step.name}: skipped, {step.skip}")
            say(f"[{i}/{len(planned) + 1}] {step.name}: skipped, {step.skip}")
            continue
        if last.get("key") == key and last.get("status") == "done" and all(Path(o).exists() for o in step.outputs):
            steps.append({**last, "status": "done", "reused": True})
            say(f"[{i}/{len(planned) + 1}] {step.name}: unchanged since its last run, kept")
            continue
        say(f"[{i}/{len(planned) + 1}] {step.name} ...")
        (out / "fmu").mkdir(exist_ok=True)
        t0 = time.perf_counter()
        code, text, err = _invoke(step.argv)
        seconds = time.perf_counter() - t0
        entry = {"name": step.name, "command": ["railcal", *step.argv], "key": key, "seconds": round(seconds, 1),
                 "status": "done" if code == 0 else "failed", "summary": text or None,
                 "reason": None if code == 0 else (err.splitlines()[-1] if err else f"exit {code}")}
        steps.append(entry)
        log.append(f"{step.name} ({seconds:.1f} s): {text or entry['reason']}")
        say(f"    {text or entry['reason']}")
        if code != 0:
            # an earlier run's results are stale now: this step's, and when the run stops here, every later step's
            for stale in (planned[i - 1:] if step.needed else [step]):
                for o in stale.outputs:
                    Path(o).unlink(missing_ok=True)
            if step.needed:
                stopped = step.name
                break
    if stopped is not None:
        steps += [{"name": s.name, "status": "not run", "reason": f"the run stopped at {stopped}"}
                  for s in planned[len(steps):]]
    record = {"format": RUN_FORMAT, "campaign": str(Path(campaign.root).resolve()), "campaign_sha256": campaign_sha,
              "model": model, "stopped_at": stopped, "steps": steps, "provenance": provenance([], argv=None)}
    write_json_atomic(record_path, record)  # the report shows how its results were made: the steps so far
    why_no_pdf = pdf_available() if pdf else "not asked for"
    for old in ("report.html", "report.pdf"):  # an earlier report shows earlier results: never left beside these
        (out / old).unlink(missing_ok=True)
    try:
        html, made_pdf, reported = write_report(out, pdf=why_no_pdf is None, criteria_path=criteria_path)
        steps.append({"name": "report", "status": "done", "summary": f"{html}" + (f", {made_pdf}" if made_pdf else ""),
                      "reason": None if made_pdf else f"no PDF: {why_no_pdf}"})
        say(f"[{len(planned) + 1}/{len(planned) + 1}] report: {html}" + (f" and {made_pdf}" if made_pdf else
                                                                            f" (no PDF: {why_no_pdf})"))
    except (InputError, jinja2.TemplateError) as e:  # a result the template cannot lay out: the steps stay
        steps.append({"name": "report", "status": "failed", "reason": f"{type(e).__name__}: {e}"})
    write_json_atomic(record_path, record)
    previous_log = log_path.read_text() if log_path.is_file() else ""
    write_atomic(log_path, lambda fh: fh.write((previous_log + "".join(f"{line}\n" for line in log)).encode()))
    return record
