"""The README's tour runs as written.

Every ``sh`` code block of README.md is a command a user will paste. The blocks under one
``###`` heading of the tour build on each other (a campaign, then its identification, ...),
so each section runs in a fresh folder of its own, block after block, line after line, with
the ``railcal`` of this environment first on the PATH. A command that exits non-zero, or
does not write the files its ``--out`` names, fails the test.

A step that the section's ``railcal run`` has already done with the same options (as
railcal's parser reads them; its ``--out`` aside, and the tour's files taken from the run
for the run's) is not run a second time: the run ran it as the railcal command of that
name, and the test checks that it succeeded, printed a summary naming what it wrote, and
takes its result under the README's name (the in-service identification and diagnosis
cost half a minute each, the whole section a minute and more).
"""
from __future__ import annotations

import json
import os
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
    taken: dict[str, str] = {}  # a file of the tour -> the run's file it was taken from
    for line in SECTIONS[section]:
        argv = shlex.split(line)
        assert argv[0] == "railcal", f"the tour runs railcal commands only: {line!r}"
        step = _done_by_the_run(argv, steps, taken)
        if step is not None:
            ran = tmp_path / _out(step["command"])
            assert ran.exists(), f"{line!r}: the run's {step['name']} did not write {ran.name}"
            assert step["summary"] and ran.name in step["summary"], f"{line!r}: the run's summary: {step}"
            shutil.copyfile(ran, tmp_path / _out(argv))
            taken[_out(argv)] = _out(step["command"])
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


def _out(argv) -> str:
    return argv[argv.index("--out") + 1]


def _options(argv, taken) -> dict:
    """The options railcal's parser reads from the command line ``argv`` with the files in
    ``taken`` replaced by the run's, but for its ``--out``."""
    from railcal.cli import build_parser

    options = vars(build_parser().parse_args([taken.get(a, a) for a in argv[1:]]))
    del options["out"]
    return options


def _done_by_the_run(argv, steps, taken) -> dict | None:
    """The run's step done with ``argv``'s options (:func:`_options`)."""
    if "--out" not in argv:
        return None
    options = _options(argv, taken)
    return next((s for s in steps if s.get("status") == "done" and "--out" in s.get("command", ())
                 and _options(s["command"], {}) == options), None)
