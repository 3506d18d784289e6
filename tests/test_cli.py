"""The command line's conventions (shared/spec/interfaces.md) and its promise to lose nothing:
no command removes what railcal did not write or writes over its own inputs, and a bad
output path is exit 2 before any work."""
from __future__ import annotations

import argparse
import json
import os
from importlib.metadata import version

import pytest

from railcal.cli import build_parser, main
from calibration.data.outputs import SYNTH_MARKER
from test_outputs import special_files, still_special

TARGETS = "".join(f'[[targets]]\nlabel = "{k}"\nfrequency_hz = {v}\n' for k, v in
                  {"carbody_bounce": 1.08, "carbody_pitch": 2.19, "bogie_bounce": 6.53, "bogie_pitch": 4.31}.items())


def run(args, capsys):
    code = main([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def snapshot(folder):
    return {str(p.relative_to(folder)): p.read_bytes() if p.is_file() else None for p in sorted(folder.rglob("*"))}


# ---------------------------------------------------------------- synth --force
SMALL = {"in-service": ["--journeys", "1", "--length-km", "5"], "excitation": ["--runs", "1", "--duration", "20"]}


@pytest.mark.parametrize("kind", ["in-service", "excitation"])
@pytest.mark.parametrize("target", [".", "..", "~"])
def test_synth_force_never_removes_the_current_folder_or_above(tmp_path, monkeypatch, capsys, kind, target):
    work = tmp_path / "work"
    work.mkdir()
    (work / "thesis.tex").write_text("years of work")
    monkeypatch.chdir(work)
    home = tmp_path / "home"  # "~" must never reach the real home folder, even in a regression
    home.mkdir()
    (home / ".bashrc").write_text("mine")
    monkeypatch.setenv("HOME", str(home))
    target = os.path.expanduser(target)
    before = snapshot(tmp_path)
    code, _, err = run(["synth", kind, target, "--force", "--quiet", *SMALL[kind]], capsys)
    assert code == 2, err
    assert "current folder" in err and "Traceback" not in err
    assert snapshot(tmp_path) == before


def test_synth_force_refuses_a_folder_railcal_did_not_write(tmp_path, capsys):
    folder = tmp_path / "measurements"
    folder.mkdir()
    (folder / "run1.csv").write_text("time\n0\n")
    code, _, err = run(["synth", "in-service", folder, "--force", "--quiet", *SMALL["in-service"]], capsys)
    assert code == 2 and str(folder) in err and SYNTH_MARKER in err and "nothing was removed" in err
    assert (folder / "run1.csv").read_text() == "time\n0\n"


def test_synth_force_refuses_a_truth_file_railcal_did_not_write(tmp_path, capsys):
    (tmp_path / "c.truth.json").write_text("notes")
    code, _, err = run(["synth", "in-service", tmp_path / "c", "--force", "--quiet", *SMALL["in-service"]], capsys)
    assert code == 2 and "c.truth.json" in err and "not a truth file railcal wrote" in err
    assert (tmp_path / "c.truth.json").read_text() == "notes" and not (tmp_path / "c").exists()


# ------------------------------------------------------- outputs are not inputs
@pytest.fixture
def inputs(tmp_path, tiny_campaign):
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({"format": "railcal-calibration/1", "model": "car2d", "parameters": {}}))
    targets = tmp_path / "t.toml"
    targets.write_text(TARGETS)
    priors = tmp_path / "p.toml"
    priors.write_text("[m_v]\nnominal = 38747.0\nlow = 36850.0\nhigh = 40644.0\n")
    track = tmp_path / "track.csv"
    track.write_text("distance,level\n0,0\n1,0\n")
    return {"campaign": tiny_campaign, "cal": cal, "targets": targets, "priors": priors, "track": track}


@pytest.mark.parametrize("command, victim", [
    (["identify", "{campaign}", "--out", "{campaign}/campaign.toml"], "campaign"),
    (["identify", "{campaign}", "--out", "{campaign}/new.json"], "campaign"),
    (["calibrate", "--targets", "{targets}", "--out", "{targets}"], "targets"),
    (["calibrate", "--targets", "{targets}", "--priors", "{priors}", "--out", "{priors}"], "priors"),
    (["calibrate", "{campaign}", "--out", "{campaign}/runs/run_a.csv"], "campaign"),
    (["validate", "{campaign}", "--calibration", "{cal}", "--out", "{cal}"], "cal"),
    (["diagnose", "{campaign}", "--out", "{campaign}/campaign.toml"], "campaign"),
    (["export-fmu", "--calibration", "{cal}", "--out", "{cal}"], "cal"),
    (["export-fmu", "--calibration", "{cal}", "--track", "{track}", "--out", "{track}"], "track"),
    (["crosscheck", "--calibration", "{cal}", "--track", "{track}", "--out", "{track}"], "track"),
    (["crosscheck", "--calibration", "{cal}", "--out", "{cal}"], "cal"),
])
def test_no_command_writes_over_its_own_inputs(inputs, tmp_path, capsys, command, victim):
    before = snapshot(tmp_path)
    code, _, err = run([a.format(**inputs) for a in command], capsys)
    assert code == 2, err
    assert "input of this command" in err and str(inputs[victim]) in err
    assert snapshot(tmp_path) == before


def test_a_derived_plot_path_is_checked_too(inputs, tmp_path, capsys):
    cal = inputs["cal"]
    png = cal.with_suffix(".png")
    png.write_text("a figure I made")
    # validate writes its figure at --out with .png: that figure may not be an input either
    code, _, err = run(["validate", inputs["campaign"], "--calibration", png, "--out", tmp_path / "cal.json2"],
                       capsys)
    assert code == 2
    code, _, err = run(["identify", inputs["campaign"], "--out", tmp_path / "x.json", "--plot", tmp_path / "x.json"],
                       capsys)
    assert code == 2 and "written twice" in err
    assert png.read_text() == "a figure I made"


@pytest.mark.parametrize("command", [
    ["identify", "{campaign}", "--out", "{out}"],
    ["calibrate", "--targets", "{targets}", "--out", "{out}"],
    ["validate", "{campaign}", "--calibration", "{cal}", "--out", "{out}"],
    ["diagnose", "{campaign}", "--out", "{out}"],
    ["export-fmu", "--calibration", "{cal}", "--out", "{out}"],
    ["crosscheck", "--calibration", "{cal}", "--out", "{out}"],
])
def test_a_device_a_fifo_or_a_folder_as_out_is_refused_before_any_work(inputs, tmp_path, capsys, command):
    specials = special_files(tmp_path)
    for out, message in ([(s, "not a regular file") for s in specials]
                         + [(tmp_path, "is a folder"), (inputs["track"] / "x.json", "not a folder")]):
        code, stdout, err = run([a.format(out=out, **inputs) for a in command], capsys)
        assert code == 2, (out, err)
        assert message in err and str(out) in err and "Traceback" not in err
    assert still_special(specials)


# ------------------------------------------------------------------ conventions
def test_version_comes_from_the_package_metadata(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"railcal {version('railcal')}"


def _commands(parser, prefix=()):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _commands(sub, (*prefix, name))
    if parser.get_default("func") is not None:
        yield " ".join(prefix), parser


def test_every_command_has_quiet_help_and_a_stated_default():
    commands = dict(_commands(build_parser()))
    assert {"synth in-service", "synth excitation", "identify", "modes", "calibrate", "validate", "diagnose",
            "export-fmu", "crosscheck", "demo"} <= set(commands)
    for name, parser in commands.items():
        helps = {a.dest: a for a in parser._actions if a.option_strings and a.dest != "help"}
        assert "quiet" in helps, name
        for dest, a in helps.items():
            assert a.help, (name, dest)
            if a.required or isinstance(a, (argparse._StoreTrueAction, argparse._VersionAction)):
                continue
            if "--profile" in a.option_strings:
                continue  # the deprecated alias shares --track's default
            shown = parser.formatter_class(name)._get_help_string(a)
            assert "default" in shown.lower(), (name, dest, shown)


def test_profile_is_a_deprecated_alias_of_track(capsys):
    args = build_parser().parse_args(["crosscheck", "--calibration", "c.json", "--profile", "t.csv", "--out", "o"])
    assert args.track == "t.csv"
    err = capsys.readouterr().err
    assert "--profile is deprecated" in err and "use --track" in err
    args = build_parser().parse_args(["crosscheck", "--calibration", "c.json", "--track", "t.csv", "--out", "o"])
    assert args.track == "t.csv" and capsys.readouterr().err == ""


def test_pso_without_priors_is_refused_and_the_help_says_why(tmp_path, capsys):
    targets = tmp_path / "t.toml"
    targets.write_text(TARGETS)
    code, _, err = run(["calibrate", "--targets", targets, "--method", "pso", "--out", tmp_path / "c.json"], capsys)
    assert code == 2 and "--priors" in err and "no default" in err and "J_v" in err
    assert not (tmp_path / "c.json").exists()
    sub = next(p for n, p in _commands(build_parser()) if n == "calibrate")
    priors_help = next(a.help for a in sub._actions if a.dest == "priors")
    assert "pso needs" in priors_help and "Table 7" in priors_help


def test_a_calibration_carries_its_format_and_readers_refuse_unknown_formats(tmp_path, capsys):
    targets = tmp_path / "t.toml"
    targets.write_text(TARGETS)
    out = tmp_path / "cal.json"
    code, stdout, err = run(["calibrate", "--targets", targets, "--runs", "1", "--out", out], capsys)
    assert code == 0, err
    data = json.loads(out.read_text())
    assert data["format"] == "railcal-calibration/1" and "parameters" in data
    assert str(out) in stdout and "Table 7" in stdout  # the default ranges are named, not silently assumed
    future = tmp_path / "future.json"
    future.write_text(json.dumps({**data, "format": "railcal-calibration/7"}))
    code, _, err = run(["export-fmu", "--calibration", future, "--out", tmp_path / "x.fmu"], capsys)
    assert code == 2 and "future.json" in err and "key 'format'" in err and "railcal-calibration/7" in err
    assert not (tmp_path / "x.fmu").exists()


def test_demo_never_replaces_a_campaign_folder_railcal_did_not_write(tmp_path, capsys):
    mine = tmp_path / "out" / "campaign"
    mine.mkdir(parents=True)
    (mine / "notes.txt").write_text("mine")
    code, _, err = run(["demo", "--out", tmp_path / "out", "--quiet"], capsys)
    assert code == 2 and str(mine) in err and "not a campaign railcal wrote" in err
    assert (mine / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize("command", [
    ["calibrate", "--targets", "{fifo}", "--out", "{out}"],
    ["calibrate", "--targets", "{targets}", "--priors", "{fifo}", "--out", "{out}"],
    ["validate", "{campaign}", "--calibration", "{fifo}", "--out", "{out}"],
    ["export-fmu", "--calibration", "{fifo}", "--out", "{out}"],
    ["crosscheck", "--calibration", "{fifo}", "--out", "{out}"],
])
def test_a_fifo_given_as_an_input_file_is_refused_not_waited_on(inputs, tmp_path, capsys, command):
    import signal

    fifo = tmp_path / "in.fifo"
    os.mkfifo(fifo)

    class Hung(BaseException):  # not an OSError: no reader may turn it into an input error
        pass

    def expire(signum, frame):  # a blocking open() or read() fails the test instead of hanging the suite
        raise Hung("still waiting after 10 s")
    old = signal.signal(signal.SIGALRM, expire)
    signal.alarm(10)
    try:
        code, _, err = run([a.format(fifo=fifo, out=tmp_path / "o.json", **inputs) for a in command], capsys)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    assert code == 2 and "in.fifo" in err and "FIFO" in err, err
    assert not (tmp_path / "o.json").exists()


def test_allow_outside_lets_a_command_read_runs_linked_from_elsewhere(tiny_campaign, tmp_path, capsys):
    """A run linked from outside the campaign is refused by default (exit 2, the file named);
    --allow-outside reads it, so the refusal about the link goes away."""
    outside = tmp_path / "elsewhere.csv"
    (tiny_campaign / "runs" / "run_a.csv").rename(outside)
    (tiny_campaign / "runs" / "run_a.csv").symlink_to(outside)
    out = tmp_path / "ident.json"
    code, _, err = run(["identify", tiny_campaign, "--out", out, "--quiet"], capsys)
    assert code == 2 and "run_a.csv" in err and "outside the campaign folder" in err
    code, _, err = run(["identify", tiny_campaign, "--out", out, "--quiet", "--allow-outside"], capsys)
    assert "outside the campaign folder" not in err


def test_a_campaign_with_priors_is_refused_for_either_model(tiny_campaign, tmp_path, capsys):
    """A campaign brings its own priors: --priors beside it would be silently dropped."""
    priors = tmp_path / "p.toml"
    priors.write_text("[m_v]\nnominal = 38000.0\nlow = 36000.0\nhigh = 40000.0\n")
    for model, method in (("car2d", "ce"), ("box", "pso")):
        code, _, err = run(["calibrate", tiny_campaign, "--model", model, "--method", method, "--priors", priors,
                            "--out", tmp_path / "c.json", "--quiet"], capsys)
        assert code == 2 and "--priors" in err, (model, err)
