"""`railcal run`: the whole job on a campaign into one folder, each step's result as its own
command writes it, resumable, and a report at the end."""
from __future__ import annotations

import json
import shutil

import pytest

from calibration.data.campaign import open_campaign
from railcal.cli import main
from railcal.report.render import pdf_available
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec

STEPS = ["identify", "calibrate", "validate", "diagnose", "export-fmu baseline", "export-fmu extended",
         "crosscheck baseline", "crosscheck extended", "report"]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    root = tmp_path_factory.mktemp("run") / "c"
    synth_in_service(root, seed=13, fmt="parquet", settings=InServiceSettings(
        journeys=3, line=LineSpec(length=6000.0), carbody_sensors=True))
    return root


def _record(out):
    return {s["name"]: s for s in json.loads((out / "run.json").read_text())["steps"]}


@pytest.mark.slow(seconds=60)
def test_run_does_every_step_then_resumes_only_what_changed(campaign, tmp_path, capsys, monkeypatch):
    out = tmp_path / "results"
    assert main(["run", str(campaign), "--out", str(out), "--quiet"]) == 0
    assert "9 steps done" in capsys.readouterr().out
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

    # a second run keeps every step; a removed result is made again, and what reads it
    (out / "validation.json").unlink()
    assert main(["run", str(campaign), "--out", str(out), "--quiet"]) == 0
    again = _record(out)
    assert [n for n, s in again.items() if s.get("reused")] == [n for n in STEPS[:-1] if n != "validate"]
    assert again["validate"]["status"] == "done" and not again["validate"].get("reused")

    # a diagnosis that gives no extended model: its FMU and cross-check are skipped, saying why, and
    # their results from before (of another model) are gone
    monkeypatch.setattr("railcal.run._no_extended_model", lambda path: "the diagnosis found none")
    capsys.readouterr()
    assert main(["run", str(campaign), "--out", str(out), "--quiet", "--no-pdf"]) == 0
    third = _record(out)
    assert {n for n, s in third.items() if s["status"] == "skipped"} == {"export-fmu extended", "crosscheck extended"}
    assert third["crosscheck extended"]["reason"] == "the diagnosis found none"
    assert not (out / "fmu" / "extended.fmu").exists() and not (out / "crosscheck_extended.json").exists()
    assert "skipped export-fmu extended,crosscheck extended: the diagnosis found none" in capsys.readouterr().out


def test_a_diagnosis_without_an_extended_model_plans_no_extended_fmu(campaign, tmp_path):
    from railcal.run import plan

    out = tmp_path / "results"
    out.mkdir()
    (out / "diagnosis.json").write_text(json.dumps({"cause": "none", "extension": None}))
    steps = {s.name: s for s in plan(open_campaign(campaign), out, "box")}
    assert "found none" in steps["export-fmu extended"].skip and steps["export-fmu baseline"].skip is None
    (out / "diagnosis.json").write_text(json.dumps({"cause": "underfloor_equipment",
                                                    "extension": {"name": "underfloor_equipment"}}))
    steps = {s.name: s for s in plan(open_campaign(campaign), out, "box")}
    assert "underfloor_equipment" in steps["crosscheck extended"].skip
    (out / "diagnosis.json").write_text(json.dumps({"cause": "none", "parameters": {}}))
    assert all(s.skip is None for s in plan(open_campaign(campaign), out, "car2d"))


@pytest.mark.slow(seconds=30)
def test_a_campaign_without_track_recording_runs_on_and_says_what_it_could_not_do(campaign, tmp_path, capsys):
    bare = tmp_path / "bare"
    shutil.copytree(campaign, bare, ignore=shutil.ignore_patterns("track"))
    out = tmp_path / "results"
    assert main(["run", str(bare), "--out", str(out), "--quiet", "--no-pdf"]) == 0
    record = _record(out)
    assert record["validate"]["status"] == "failed" and "track" in record["validate"]["reason"]
    assert record["diagnose"]["status"] == "done" and record["report"]["status"] == "done"
    assert "validate (" in capsys.readouterr().out
    assert "validation <span class=\"absent\">(not run)</span>" in (out / "report.html").read_text()


def test_run_refuses_to_write_inside_its_campaign(campaign, capsys):
    before = sorted(p.name for p in campaign.iterdir())
    assert main(["run", str(campaign), "--out", str(campaign / "results"), "--quiet"]) == 2
    assert "an input of this command" in capsys.readouterr().err
    assert sorted(p.name for p in campaign.iterdir()) == before


@pytest.mark.slow(seconds=30)
def test_a_step_that_fails_now_leaves_no_result_of_an_earlier_run(campaign, tmp_path):
    """Run, then run again after the track recording is gone: validation cannot be done, and
    its earlier result is not left for the report to show as current."""
    copy = tmp_path / "c"
    shutil.copytree(campaign, copy)
    out = tmp_path / "results"
    assert main(["run", str(copy), "--out", str(out), "--quiet", "--no-pdf"]) == 0
    assert (out / "validation.json").is_file()
    shutil.rmtree(copy / "track")
    assert main(["run", str(copy), "--out", str(out), "--quiet", "--no-pdf"]) == 0
    assert _record(out)["validate"]["status"] == "failed" and not (out / "validation.json").exists()
