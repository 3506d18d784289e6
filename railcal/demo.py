"""``railcal demo``: ``railcal run`` on the built-in example, then its answers beside the truth.

The built-in example is two synthetic campaigns written by railcal's truth simulators:

* in service: journeys of the 2D car over a line with a track recording, with the seed's
  bogie and axle-box sensors and carbody floor accelerometers (above both bogies and at the
  centre);
* a stationary excitation (shaker) test of the Shinkansen-type box carbody, 27 floor
  accelerometers.

Each goes through :func:`railcal.run.run_campaign` exactly as a user's campaign would
(identify, calibrate, validate, diagnose, FMUs, exudyn cross-checks, the sign-off report),
into a results folder of its own. Then, and only here, the demo opens the truth files it
wrote beside the campaigns and checks the answers against them in ``demo.md``. Neither
campaign hides an effect, so both diagnoses should answer ``none``.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

from calibration.data.campaign import open_campaign
from calibration.truth.excitation import ExcitationSettings, synth_excitation
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec

from .run import run_campaign

DEMO_SEED = 7
#: the campaigns the demo writes (and replaces on a rerun), and the results folders of their runs
CAMPAIGNS = {"in_service": "campaign", "excitation": "excitation"}
RESULTS = {"in_service": "results_in_service", "excitation": "results_excitation"}


@dataclass(frozen=True)
class DemoSettings:
    """How big the demo's data and searches are. :data:`FULL`: the sizes of the published
    methods (10 journeys over 40 km; the seed's 1000 particles; the full-order box model);
    :data:`QUICK` (the default): smaller, and the excitation test on a coarse box model, chosen
    so that every answer the demo checks stays right (README, ``railcal demo``)."""

    in_service: InServiceSettings
    box_order_change: int = 0  # added to every panel order of the excitation test's box model (negative: coarse)
    box_calibrate: tuple = ()  # more `railcal calibrate` options of the box model's run

    def __post_init__(self):
        ExcitationSettings(order_change=self.box_order_change)  # refuses a panel order below 1

    @property
    def excitation(self) -> ExcitationSettings:
        """The excitation test synthesised: 2 x 300 s on the box model at these panel orders."""
        return ExcitationSettings(order_change=self.box_order_change)

    def run_options(self) -> dict:
        """The box run's step options: the model's panel orders and the swarm's size."""
        return {"calibrate": ("--panel-order-change", str(self.box_order_change), *self.box_calibrate)}


FULL = DemoSettings(InServiceSettings(journeys=10, line=LineSpec(length=40_000.0), carbody_sensors=True))
#: The quick demo: 8 journeys x 10 km, a seventh of FULL's running but enough cruise speeds to
#: tell the two bogies' rails apart; the excitation test on the coarse box model (every panel
#: order - 4: 969 DOF against 2709) so that its eigen-solves stay cheap, and 2 swarms of 100
#: particles.
QUICK = DemoSettings(InServiceSettings(journeys=8, line=LineSpec(length=10_000.0), carbody_sensors=True),
                     box_order_change=-4, box_calibrate=("--particles", "200", "--iterations", "200", "--swarms", "2"))
DEMO_SETTINGS = QUICK.in_service  # the in-service campaign of the default demo
#: what demo.md checks: identified rigid-body modes against the truth [%] (issue 2's acceptance)
IDENTIFY_LIMIT_PCT = {"carbody_bounce": 3.0, "carbody_pitch": 3.0, "bogie_bounce": 2.0, "bogie_pitch": 2.0}
BOX_IDENTIFY_LIMIT_PCT = 1.0  # box carbody modes against the nearest true mode


def run_demo(out: Path, *, progress=None, full: bool = False) -> Path:
    """The whole job on the built-in example into ``out``; returns demo.md's path.
    ``full``: :data:`FULL` sizes (much longer), else :data:`QUICK`."""
    demo = FULL if full else QUICK
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    say = progress or (lambda message: None)
    t0 = time.perf_counter()
    s = demo.in_service
    say(f"demo: synthesising {s.journeys} journeys over a {s.line.length / 1000:g} km line (the in-service campaign)")
    # a rerun replaces the campaigns it wrote; the writers refuse a folder railcal did not write
    synth_in_service(out / CAMPAIGNS["in_service"], seed=DEMO_SEED, settings=s, overwrite=True, progress=progress)
    say("demo: railcal run on the in-service campaign")
    runs = {"in_service": run_campaign(open_campaign(out / CAMPAIGNS["in_service"]), out / RESULTS["in_service"],
                                       model="car2d", say=say)}
    say("demo: synthesising the stationary excitation test of the box carbody (2 x 300 s, 27 floor accelerometers)")
    synth_excitation(out / CAMPAIGNS["excitation"], seed=DEMO_SEED, settings=demo.excitation, overwrite=True)
    say("demo: railcal run on the excitation test")
    runs["excitation"] = run_campaign(open_campaign(out / CAMPAIGNS["excitation"]), out / RESULTS["excitation"],
                                      model="box", say=say, options=demo.run_options())
    checks = demo_checks(out)
    text = _demo_md(out, runs, checks, demo, time.perf_counter() - t0)
    path = out / "demo.md"
    path.write_text(text)
    return path


def _result(out: Path, kind: str, name: str) -> dict | None:
    try:
        return json.loads((out / RESULTS[kind] / f"{name}.json").read_text())
    except (OSError, ValueError):
        return None


def _truth(out: Path, kind: str) -> dict:
    return json.loads((out / f"{CAMPAIGNS[kind]}.truth.json").read_text())


def demo_checks(out: Path) -> list[tuple[str, bool]]:
    """What the demo's answers must be on its effect-free synthetic data: (statement, held).
    A result that is missing fails its check."""
    out = Path(out)
    checks = []
    truth = _truth(out, "in_service")
    ident = _result(out, "in_service", "identification") or {"modes": []}
    found = {m["label"]: m["frequency_hz"] for m in ident["modes"]}
    for label, limit in IDENTIFY_LIMIT_PCT.items():
        if label not in found:
            checks.append((f"{label} identified (within {limit:g} % of the truth)", False))
            continue
        err = 100 * abs(found[label] / truth["frequencies_hz"][label] - 1)
        checks.append((f"{label} identified within {limit:g} % of the truth: {err:.2f} %", err <= limit))
    cal = _result(out, "in_service", "calibration")
    limit = max(IDENTIFY_LIMIT_PCT.values())
    checks.append((f"2D car calibrated to the identified modes within {limit:g} %: "
                   f"{cal['max_error_pct']:.2g} %" if cal else "2D car calibrated", bool(cal) and
                   cal["max_error_pct"] <= limit))
    box_truth = _truth(out, "excitation")
    box_ident = _result(out, "excitation", "identification") or {"modes": []}
    true_f = list(box_truth["frequencies_hz"].values())
    worst = max((min(100 * abs(m["frequency_hz"] / f - 1) for f in true_f) for m in box_ident["modes"]),
                default=float("inf"))
    checks.append((f"box carbody modes identified within {BOX_IDENTIFY_LIMIT_PCT:g} % of a true mode: {worst:.2f} %",
                   worst <= BOX_IDENTIFY_LIMIT_PCT))
    box_cal = _result(out, "excitation", "calibration")
    done = box_cal["pso"].get("done_pct", box_cal["pso"]["stop_pct"]) if box_cal else 0.0
    checks.append((f"box model calibrated to the identified modes within {done:g} % (full model): "
                   f"{box_cal['max_error_pct']:.3g} %" if box_cal else "box model calibrated",
                   bool(box_cal) and box_cal["max_error_pct"] <= done))
    for kind, what in (("in_service", "in-service"), ("excitation", "excitation test")):
        d = _result(out, kind, "diagnosis")
        cause = d["cause"] if d else "no diagnosis"
        checks.append((f"{what} diagnosis answers none on effect-free data: {cause}", cause == "none"))
        x = _result(out, kind, "crosscheck")
        verdict = x["verdict"] if x else "not run"
        checks.append((f"{what} model cross-checked in exudyn: {verdict}", verdict == "pass"))
        checks.append((f"{what} sign-off report written", (out / RESULTS[kind] / "report.html").is_file()))
    return checks


def _demo_md(out: Path, runs: dict, checks: list[tuple[str, bool]], demo: DemoSettings, wall_s: float) -> str:
    ok = all(held for _, held in checks)
    lines = ["# railcal demo", "",
             f"{'Full' if demo is FULL else 'Quick'} demo (`railcal demo{' --full' if demo is FULL else ''}`), "
             f"{wall_s:.0f} s in all. Two synthetic campaigns, each through `railcal run`'s steps (the box run's "
             f"calibrate with {' '.join(demo.run_options()['calibrate'])}):", ""]
    for kind, what in (("in_service", "in service (2D car)"), ("excitation", "stationary excitation test (box)")):
        folder = RESULTS[kind]
        lines.append(f"- {what}: campaign `{CAMPAIGNS[kind]}/`, results and sign-off report in `{folder}/` "
                     f"([report.html]({folder}/report.html)"
                     + (f", [report.pdf]({folder}/report.pdf)" if (out / folder / "report.pdf").is_file() else "")
                     + ")")
    lines += ["", "## Checks against the truth", "",
              f"The truth that generated the data (`campaign.truth.json`, `excitation.truth.json`) against the "
              f"answers: **{'all hold' if ok else 'NOT ALL HOLD'}**.", "",
              *[f"- {'pass' if held else 'FAIL'}: {text}" for text, held in checks], "",
              "## Steps", "", "| campaign | step | status | wall [s] |", "|---|---|---|---|"]
    for kind, record in runs.items():
        lines += [f"| {kind} | {s['name']} | {s['status']} | {s.get('seconds', '')} |" for s in record["steps"]]
    return "\n".join(lines + [""])
