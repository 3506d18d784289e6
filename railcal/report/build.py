"""The sign-off report of a results folder: each step's JSON result read back, laid out by a
template into one self-contained HTML page (figures embedded), and its PDF.

The folder holds what the commands wrote, under the names ``railcal run`` gives them
(:data:`RESULTS`); a step that is absent is reported as not run. Every number in the
report's tables is taken from those files, never recomputed: each numeric cell carries the
JSON path it came from (``data-json``), so a test can hold the report to its results.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import jinja2

from calibration.data.errors import InputError
from calibration.data.outputs import check_outputs, read_result, write_atomic

from ..provenance import provenance
from .render import data_uri, html_to_pdf, pdf_available

#: step -> (file name in the results folder, its result kind)
RESULTS = {"identification": ("identification.json", "identification"),
           "calibration": ("calibration.json", "calibration"),
           "validation": ("validation.json", "validation"),
           "diagnosis": ("diagnosis.json", "diagnosis"),
           "validation_extended": ("validation_extended.json", "validation"),
           "crosscheck": ("crosscheck.json", "crosscheck"),
           "crosscheck_extended": ("crosscheck_extended.json", "crosscheck"),
           "fmu_baseline": ("fmu_baseline.json", "fmu-check"),
           "fmu_extended": ("fmu_extended.json", "fmu-check")}


def number(x, digits: int = 4) -> str:
    """A number as the report shows it: ``digits`` significant figures (an integer whole, and
    one from 10^4 up to 10^12 to the unit: a distance of 10000.5 m reads 10000, not 1e+04);
    '-' for none."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return str(x)
    if isinstance(x, int):
        return str(x)
    if 1e4 <= abs(x) < 1e12:
        return f"{x:.0f}"
    return f"{x:.{digits}g}"


def load_results(folder) -> dict:
    """{step: its JSON result} of the steps whose file is in ``folder``."""
    folder = Path(folder)
    return {step: read_result(folder / name, (kind,)) for step, (name, kind) in RESULTS.items()
            if (folder / name).is_file()}


def load_run(folder) -> dict | None:
    """The run record (``railcal run``'s run.json) in ``folder``, or None when there is none
    or it cannot be read: the report then says nothing of how its results were made."""
    try:
        record = json.loads((Path(folder) / "run.json").read_text())
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) and isinstance(record.get("steps"), list) else None


def _vehicle(campaign: str | None) -> str | None:
    """The vehicle and the campaign's name as its campaign.toml gives them, when it can be read."""
    from calibration.data.campaign import open_campaign

    if campaign is None:
        return None
    try:
        meta = open_campaign(campaign).meta
    except (InputError, OSError):  # a CampaignError is an InputError
        return None
    return "; ".join(x for x in (meta.vehicle, meta.name) if x) or None


def _figures(folder: Path, results: dict) -> dict:
    """{step: [data URI, ...]} of the figures each result names that exist."""
    out = {}
    for step, r in results.items():
        paths = [r[k] for k in ("plot", "plot_spectra") if isinstance(r.get(k), str)] + list(r.get("plots") or [])
        found = []
        for p in paths:
            p = Path(p)
            for candidate in (folder / p.name, p):  # beside the result first: a relative path was the command's
                if candidate.is_file():
                    found.append(data_uri(candidate))
                    break
        out[step] = found
    return out


def build_html(folder, results: dict, *, title: str | None = None, criteria=None) -> str:
    """The report of ``folder``'s ``results`` (:func:`load_results`) as one self-contained
    HTML page, judged against ``criteria`` (:mod:`.criteria`; None: its defaults)."""
    from .criteria import DEFAULTS, campaign_kind, evaluate, verdict

    folder = Path(folder)
    env = jinja2.Environment(loader=jinja2.PackageLoader("railcal.report", "templates"),
                             autoescape=jinja2.select_autoescape(["html", "j2"]), undefined=jinja2.StrictUndefined)
    env.filters["n"] = number
    campaign = next((r["campaign"] for r in results.values() if isinstance(r.get("campaign"), str)), None)
    run = load_run(folder)
    vehicle = _vehicle((run or {}).get("campaign")) or _vehicle(campaign)
    inputs = [folder / name for name, _ in RESULTS.values() if (folder / name).is_file()]
    step_of = {name: step for step, (name, _) in RESULTS.items()}  # result file -> its step
    needless = {step_of[o]: f"skipped: {s.get('reason')}" for s in (run or {}).get("steps", [])
                if s.get("status") == "skipped" and s.get("needless") for o in s.get("outputs", []) if o in step_of}
    acceptance = evaluate(DEFAULTS if criteria is None else criteria, results, needless)
    return env.get_template("report.html.j2").render(
        title=title or f"Vehicle model sign-off: {campaign or folder.name}", campaign=campaign, r=results,
        vehicle=vehicle, acceptance=acceptance, verdict=verdict(acceptance), default_criteria=criteria is None,
        figures=_figures(folder, results), provenance=provenance(inputs, root=folder), steps=list(RESULTS),
        kind=campaign_kind(results), run=run)


def write_report(folder, *, pdf: bool = False, criteria_path=None) -> tuple[Path, Path | None, tuple]:
    """``folder``/report.html (and report.pdf with ``pdf``) from the results there, judged
    against the criteria file ``criteria_path`` (None: the defaults): (the HTML, the PDF or
    None, the steps reported). Refuses, writing nothing, a folder with no result, a malformed
    criteria file or, with ``pdf``, a machine that cannot make one (:class:`InputError`)."""
    from .criteria import load_criteria

    folder = Path(folder)
    if not folder.is_dir():
        raise InputError("not a results folder (no such directory)", path=folder)
    html_path, pdf_path = folder / "report.html", (folder / "report.pdf" if pdf else None)
    check_outputs([html_path, pdf_path], inputs=[*(folder / name for name, _ in RESULTS.values()), criteria_path])
    criteria = None if criteria_path is None else load_criteria(criteria_path)
    if pdf and (why := pdf_available()) is not None:
        raise InputError(f"cannot make a PDF here: {why}", key="--pdf")
    results = load_results(folder)
    if not results:
        raise InputError(f"no step result ({', '.join(n for n, _ in RESULTS.values())}) to report", path=folder)
    html = build_html(folder, results, criteria=criteria)
    write_atomic(html_path, lambda f: f.write(html.encode("utf-8")))
    if pdf:
        html_to_pdf(html, pdf_path)
    return html_path, pdf_path, tuple(results)
