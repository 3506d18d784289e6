"""The README's tour runs as written.

Every ``sh`` code block of README.md is a command a user will paste. The blocks under one
``###`` heading of the tour build on each other (a campaign, then its identification, ...),
so each section runs in a fresh folder of its own, block after block, line after line, with
the ``railcal`` of this environment first on the PATH. A command that exits non-zero, or
does not write the files its ``--out`` names, fails the test.

A step that the section's ``railcal run`` has already done with the same command line
(its ``--out`` aside) and inputs of the same content is not run a second time: the run ran
it as the railcal command of that name, and the test checks that it succeeded, printed a
summary naming what it wrote, and takes its result under the README's name (the in-service
identification and diagnosis cost half a minute each, the whole section a minute and more).
"""
from __future__ import annotations

import os
import json
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCK = re.compile(r"^```sh\n(.*?)^```", re.S | re.M)


def _sections() -> dict[str, list[str]]:
    """The ``sh`` blocks' command lines, grouped by the ``###`` heading they stand under."""
    text = README.read_text()
    sections: dict[str, list[str]] = {}
    heads = [(m.start(), m.group(1).strip()) for m in re.finditer(r"^###? (.+)$", text, re.M)]
    for m in BLOCK.finditer(text):
        head = [h for pos, h in heads if pos < m.start()][-1]
        lines = [ln.split("  #")[0].strip() for ln in m.group(1).splitlines()]
        sections.setdefault(head, []).extend(ln for ln in lines if ln and not ln.startswith("#"))
    return sections


SECTIONS = _sections()


def test_the_readme_has_a_tour_and_stays_a_guide():
    """A guide of about 200 lines whose tour covers both kinds of campaign."""
    text = README.read_text()
    assert len(text.splitlines()) <= 210
    commands = [c for lines in SECTIONS.values() for c in lines]
    for verb in ("synth in-service", "synth excitation", "identify", "calibrate", "validate", "diagnose",
                 "export-fmu", "crosscheck", "modes"):
        assert any(c.startswith(f"railcal {verb}") for c in commands), verb
    assert not re.search(r"\bcommit [0-9a-f]{7,40}\b", text), "history belongs in docs/CHANGELOG.md"
    assert "in progress" not in text


@pytest.mark.slow(seconds=100)
@pytest.mark.spread
@pytest.mark.parametrize("section", list(SECTIONS))
def test_the_tour_runs_as_written(section, tmp_path):
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    steps: list[dict] = []  # the steps a `railcal run` of this section did
    same: dict[str, str] = {}  # a file the tour wrote -> the run's file of the same content
    for line in SECTIONS[section]:
        argv = shlex.split(line)
        assert argv[0] == "railcal", f"the tour runs railcal commands only: {line!r}"
        step = _done_by_the_run(argv, steps, same)
        if step is not None:
            ran = tmp_path / _out(step["command"])
            assert ran.exists(), f"{line!r}: the run's {step['name']} did not write {ran.name}"
            assert step["summary"] and ran.name in step["summary"], f"{line!r}: the run's summary: {step}"
            shutil.copyfile(ran, tmp_path / _out(argv))
            same[_out(argv)] = _out(step["command"])
            continue
        done = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, f"{line!r} exited {done.returncode}:\n{done.stderr[-3000:]}"
        assert done.stdout.strip(), f"{line!r} printed no summary"
        if "--out" in argv:
            out = tmp_path / _out(argv)
            assert out.exists(), f"{line!r} did not write {out.name}"
            assert out.name in done.stdout, f"{line!r}: the summary does not name {out.name}"
        if argv[1] == "run":
            steps = json.loads((tmp_path / _out(argv) / "run.json").read_text())["steps"]
        else:
            same.update(_alike_results(argv, steps, tmp_path))


def _out(argv) -> str:
    return argv[argv.index("--out") + 1]


def _without_out(argv) -> list[str]:
    i = argv.index("--out")
    return [*argv[:i], *argv[i + 2:]]


def _done_by_the_run(argv, steps, same) -> dict | None:
    """The run's step done with ``argv``'s command but for its ``--out`` and for the tour's
    files of the same content as the run's (``same``)."""
    if "--out" not in argv:
        return None
    wanted = [same.get(a, a) for a in _without_out(argv)]
    return next((s for s in steps if s.get("status") == "done" and "--out" in s.get("command", ())
                 and _without_out(s["command"]) == wanted), None)


def _alike_results(argv, steps, root) -> dict[str, str]:
    """{the JSON ``argv`` wrote: the JSON of the run's step of the same command} when both
    hold the same result (every key but the names of the figures each wrote beside itself)."""
    if "--out" not in argv or not _out(argv).endswith(".json"):
        return {}

    def result(path):
        return {k: v for k, v in json.loads((root / path).read_text()).items() if k not in ("plot", "plots")}

    mine = result(_out(argv))
    return {_out(argv): _out(s["command"]) for s in steps
            if s.get("status") == "done" and "--out" in s.get("command", ()) and s["command"][1] == argv[1]
            and _out(s["command"]).endswith(".json") and result(_out(s["command"])) == mine}
