"""`railcal run`: the whole job on a campaign into one folder, each step's result as its own
command writes it, resumable, and a report at the end."""
from __future__ import annotations

import json
import shutil

import pytest

from calibration.data.campaign import open_campaign
from railcal.cli import main
from railcal.report.build import load_results, number
from railcal.report.criteria import DEFAULTS, evaluate, verdict
from test_report import _at, _Cells
from railcal.report.render import pdf_available
from calibration.truth.effects import EFFECTS, EffectChoice
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec

STEPS = ["identify", "calibrate", "validate", "diagnose", "validate extended", "export-fmu baseline",
         "export-fmu extended", "crosscheck baseline", "crosscheck extended", "report"]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """A small campaign whose car hides a strong centre-of-mass offset (1.5 m): the diagnosis
    names it, so the extended model's steps have a model to run on."""
    root = tmp_path_factory.mktemp("run") / "c"
    synth_in_service(root, seed=13, fmt="parquet", effect=EffectChoice(EFFECTS["cog_offset"], 1.5),
                     settings=InServiceSettings(journeys=3, line=LineSpec(length=6000.0), carbody_sensors=True))
    return root


def _record(out):
    return {s["name"]: s for s in json.loads((out / "run.json").read_text())["steps"]}


@pytest.mark.slow(seconds=100)
def test_a_campaign_written_by_hand_runs_every_step_resumes_and_leaves_no_stale_result(
        campaign, tmp_path, capsys, monkeypatch):
    """The whole job on a campaign written from the format's page; run again it keeps what is
    unchanged; the steps that cannot or need not run are skipped and their results of before
    removed."""
    hand = tmp_path / "hand"
    _write_by_hand(campaign, hand)
    out = tmp_path / "results"
    assert main(["run", str(hand), "--out", str(out), "--quiet"]) == 0, capsys.readouterr().err
    assert "10 steps done" in capsys.readouterr().out
    record = _record(out)
    assert list(record) == STEPS and all(s["status"] == "done" for s in record.values()), record
    assert json.loads((out / "run.json").read_text())["stopped_at"] is None
    for name in ("identification", "calibration", "validation", "diagnosis", "crosscheck", "crosscheck_extended"):
        assert json.loads((out / f"{name}.json").read_text())["format"].startswith("railcal-")
    assert (out / "fmu" / "baseline.fmu").is_file() and (out / "fmu" / "extended.fmu").is_file()
    assert (out / "report.html").is_file() and (out / "report.pdf").is_file() == (pdf_available() is None)
    assert "calibrate" in (out / "run.log").read_text()
    # calibrate reads the identification made before it, never identifies again
    assert "--identification" in record["calibrate"]["command"]
    # every number in the report's tables is its result's, the cross-checks' and the data's included
    html = (out / "report.html").read_text()
    parser = _Cells()
    parser.feed(html)
    assert {path.split("/")[0] for path, _ in parser.cells} == {
        "identification", "calibration", "validation", "diagnosis", "validation_extended", "crosscheck",
        "crosscheck_extended", "fmu_baseline", "fmu_extended"}
    assert json.loads((out / "fmu_baseline.json").read_text())["verdict"] == "pass"
    for path, text in parser.cells:  # to the figures the template shows: 4, or 2 for the tiny agreements
        assert any(text == number(_at(out, path), digits) for digits in (2, 4)), (path, text)
    assert verdict(evaluate(DEFAULTS, load_results(out))) in html
    assert "test car; hand-written test campaign" in html  # the sign-off block names them as campaign.toml does
    ident = json.loads((out / "identification.json").read_text())

    # a second run keeps every step; a removed result is made again, and what reads it (no
    # PDF: the first and third runs write one)
    (out / "validation.json").unlink()
    assert main(["run", str(hand), "--out", str(out), "--quiet", "--no-pdf"]) == 0
    again = _record(out)
    assert [n for n, s in again.items() if s.get("reused")] == [n for n in STEPS[:-1] if n != "validate"]
    assert again["validate"]["status"] == "done" and not again["validate"].get("reused")

    # a diagnosis that gives no extended model: its FMU and cross-check are skipped, saying why, and
    # their results from before (of another model) are gone
    monkeypatch.setattr("railcal.run._no_extended_model", lambda path: ("the diagnosis found none", True))
    capsys.readouterr()
    assert main(["run", str(hand), "--out", str(out), "--quiet"]) == 0
    third = _record(out)
    assert {n for n, s in third.items() if s["status"] == "skipped"} == {"validate extended", "export-fmu extended",
                                                                          "crosscheck extended"}
    assert third["crosscheck extended"]["reason"] == "the diagnosis found none"
    assert not (out / "fmu" / "extended.fmu").exists() and not (out / "crosscheck_extended.json").exists()
    assert "skipped validate extended,export-fmu extended,crosscheck extended: the diagnosis found none" in \
        capsys.readouterr().out
    html = (out / "report.html").read_text()  # the report says how its results were made, and what was left out
    assert "How the results were made" in html and "Step crosscheck extended skipped: the diagnosis found none." in html
    assert ("not applicable (NRMSE of every validated channel, extended model; PSD error of every validated channel, "
            "extended model; FMU checks of the extended model; exudyn cross-check of the extended model)") in html
    assert (out / "report.pdf").is_file() == (pdf_available() is None)

    # the track recording gone: validation cannot be done now, the run goes on and says so, and
    # the earlier validation is not left for the report to show as current. The campaign is
    # now the generator's own (other units, another layout), which the run identifies anew
    # anyway, so that the same measurements are seen to give the same modes.
    shutil.rmtree(hand)
    shutil.copytree(campaign, hand, ignore=shutil.ignore_patterns("track"))
    capsys.readouterr()
    assert main(["run", str(hand), "--out", str(out), "--quiet", "--no-pdf"]) == 0
    generated = {m["label"]: m["frequency_hz"] for m in json.loads((out / "identification.json").read_text())["modes"]}
    assert {m["label"] for m in ident["modes"]} == set(generated)
    for m in ident["modes"]:
        assert m["frequency_hz"] == pytest.approx(generated[m["label"]], rel=1e-5), m["label"]
    record = _record(out)
    assert record["validate"]["status"] == "failed" and "track" in record["validate"]["reason"]
    assert record["diagnose"]["status"] == "done" and record["report"]["status"] == "done"
    assert not (out / "validation.json").exists() and not (out / "report.pdf").exists()  # the PDF, of before
    assert "validate (" in capsys.readouterr().out
    assert "validation <span class=\"absent\">(not run)</span>" in (out / "report.html").read_text()


def test_the_extended_models_steps_are_skipped_when_there_is_none_or_its_file_holds_none(campaign, tmp_path):
    from railcal.run import plan

    out = tmp_path / "results"
    out.mkdir()

    def extended_steps(diagnosis: dict, model: str) -> list:
        (out / "diagnosis.json").write_text(json.dumps(diagnosis))
        steps = plan(open_campaign(campaign), out, model)
        assert all(s.skip is None for s in steps if "extended" not in s.name)
        return [s for s in steps if "extended" in s.name]

    # nothing found (an excitation test; in service, no finding at all): needless
    for diagnosis, model in (({"cause": "none", "extension": None}, "box"),
                             ({"cause": "none", "extension": None, "findings": [], "parameters": {}}, "car2d")):
        steps = extended_steps(diagnosis, model)
        assert len(steps) == 3 and all("found none" in s.skip and s.needless for s in steps)
    # a cause whose file holds no extended model (no parameters): not needless, a gap
    steps = extended_steps({"cause": "underfloor_equipment", "extension": {"name": "underfloor_equipment"}}, "box")
    assert all("underfloor_equipment" in s.skip and "no extended model" in s.skip and not s.needless for s in steps)
    # an excitation-test cause with its extended model: run
    steps = extended_steps({"cause": "underfloor_equipment", "extension": {"name": "underfloor_equipment"},
                            "model": "box", "parameters": {}}, "box")
    assert all(s.skip is None for s in steps)
    # in service, a property found with no cause: an extended model, run
    steps = extended_steps({"cause": "none", "extension": None, "findings": [{"name": "m", "role": "property"}],
                            "parameters": {}}, "car2d")
    assert all(s.skip is None for s in steps)


def test_run_refuses_to_write_inside_its_campaign(campaign, capsys):
    before = sorted(p.name for p in campaign.iterdir())
    assert main(["run", str(campaign), "--out", str(campaign / "results"), "--quiet"]) == 2
    assert "an input of this command" in capsys.readouterr().err
    assert sorted(p.name for p in campaign.iterdir()) == before


def _write_by_hand(source, root):
    """``source``'s measurements as a person would write a campaign from the format's page
    (docs/campaign-format.md), with no railcal writer: campaign.toml as text, SI units where
    the generator wrote g and deg/s, the sensors and columns in another order, comment lines,
    and no truth file anywhere."""
    c = open_campaign(source)
    meta = c.meta
    unit = {"acceleration": "m/s^2", "angular_velocity": "rad/s"}
    sensors = sorted(meta.sensors, key=lambda s: s.name, reverse=True)
    toml = ['format = "railcal-campaign/1"', 'kind = "in_service"', 'name = "hand-written test campaign"', "",
            "[vehicle]", 'name = "test car"']
    toml += [f"{k} = {v!r}" for k, v in meta.geometry.items()]
    for name, p in meta.priors.items():
        toml += ["", f"[priors.{name}]", f"nominal = {p.nominal!r}", f"low = {p.low!r}", f"high = {p.high!r}"]
    for s in sensors:
        toml += ["", "[[sensors]]", f'name = "{s.name}"', f'quantity = "{s.quantity}"', f'unit = "{unit[s.quantity]}"',
                 f'body = "{s.body}"', f'direction = "{s.direction}"', f"position = {list(s.position)!r}"]
    toml += ["", "[sampling]", f"rate = {meta.sampling_rate!r}", ""]
    (root / "runs").mkdir(parents=True)
    (root / "campaign.toml").write_text("\n".join(toml))
    for run in c.iter_runs():
        columns = ["time", "speed", "distance", *(s.name for s in sensors)]
        values = [run.time, run.speed, run.distance, *(run.channels[s.name] for s in sensors)]
        with open(root / "runs" / f"{run.run_id}.csv", "w") as f:
            f.write(f"# {run.run_id}, written by hand\n{','.join(columns)}\n")
            for row in zip(*values):
                f.write(",".join(f"{x:.10g}" for x in row) + "\n")
    (root / "track").mkdir()
    for track in c.tracks():
        rows = "".join(f"{d:.6f},{z:.6e}\n" for d, z in zip(track.distance, track.level))
        (root / "track" / f"{track.name}.csv").write_text(f'# band = "{track.band}"\ndistance,level\n{rows}')
