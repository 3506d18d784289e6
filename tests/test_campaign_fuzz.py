"""Fuzzing the campaign reader through the command line (issue 29).

Mutants of a small valid campaign (tests/fuzz_mutants.py: the classes and the seeded rule
that builds them) go through ``railcal identify``; every third also through ``calibrate``
and ``diagnose``, every ninth through ``validate`` (which accepts the base, in 3 s). Each
must be

* accepted: exit 0 with a complete JSON, or read and then refused by the analysis as the
  unmutated campaign is (the same message, numbers aside). The base is 700 m long, too
  short for identify's 2 km segments and diagnose's 80 s records: a full identification of
  even 5 km takes 40 s here, too long for 100 mutants. A mutant may also leave too little
  usable data for an analysis (a shorter run, missing samples): refused as such, naming
  the campaign or file. Or
* refused: exit 2 with a short message naming a file of the campaign and the line, column
  or key (or, for a fault of the whole file, what is wrong with it);

never exit 1, never past the time limit, never changing the input tree, never leaving an
output behind on refusal. Run with ``-s`` to see the count of mutants per class and outcome.
"""
from __future__ import annotations

import collections
import hashlib
import json
import os
import re
import shutil
import signal
import stat
import time
from pathlib import Path

import numpy as np
import pytest

from railcal.cli import main

from fuzz_mutants import CLASSES, SEED, calibration_json, write_base

PER_CLASS = 8  # 14 classes x 8 = 112 mutants
TIME_LIMIT = 60.0  # [s] per command
#: Refusals about a file as a whole, where no line, column or key applies.
WHOLE_FILE = ("not a regular file", "larger than", "outside the campaign folder", "cannot read", "no header row",
              "no run files", "missing runs/ folder", "missing campaign.toml", "UTF-16")
WHERE = re.compile(r"line \d+|column '|key '")
#: Refusals by an analysis of data that is well formed but too little for it.
TOO_LITTLE = ("no usable 2000 m segment", "no run covers at least", "no gap-free stretch")


class MutantTimeout(BaseException):
    """Raised by the alarm; a BaseException so the command line's handler cannot catch it."""


def _alarm(signum, frame):
    raise MutantTimeout()


def tree_state(top: Path) -> dict:
    """Every entry under ``top`` without following links: kind, mode, size and content hash
    (a file over 64 MiB, such as a sparse one, by size and modification time only)."""
    state = {}
    for dirpath, dirnames, filenames in os.walk(top):
        for name in dirnames + filenames:
            p = os.path.join(dirpath, name)
            st = os.lstat(p)
            rel = os.path.relpath(p, top)
            if stat.S_ISLNK(st.st_mode):
                state[rel] = ("link", os.readlink(p))
            elif stat.S_ISREG(st.st_mode) and st.st_size <= 64 << 20:
                state[rel] = ("file", st.st_mode, hashlib.sha256(Path(p).read_bytes()).hexdigest())
            else:
                state[rel] = (stat.S_IFMT(st.st_mode), st.st_mode, st.st_size, st.st_mtime_ns)
    return state


def commands(root: Path, out: Path, calibration: Path) -> dict[str, list[str]]:
    return {
        "identify": ["identify", str(root), "--out", str(out / "ident.json"), "--quiet"],
        "calibrate": ["calibrate", str(root), "--model", "car2d", "--runs", "1", "--out", str(out / "cal.json"),
                      "--quiet"],
        "validate": ["validate", str(root), "--calibration", str(calibration), "--out", str(out / "val.json"),
                     "--quiet"],
        "diagnose": ["diagnose", str(root), "--out", str(out / "diag.json"), "--quiet"],
    }


def run_command(argv, capsys) -> tuple[int | str, str, float]:
    capsys.readouterr()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, TIME_LIMIT)
    t0 = time.perf_counter()
    try:
        code = main(argv)
    except MutantTimeout:
        code = "timeout"
    except SystemExit as e:
        code = e.code
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    return code, capsys.readouterr().err, time.perf_counter() - t0


@pytest.fixture(scope="module")
def bases(tmp_path_factory):
    top = tmp_path_factory.mktemp("fuzz_bases")
    calibration = top / "calibration.json"
    calibration.write_text(json.dumps(calibration_json()))
    return {"csv": write_base(top / "csv"), "parquet": write_base(top / "parquet", "parquet")}, calibration


def _shape(message: str) -> str:
    """A message with its numbers blanked: a shorter run is refused as the base is."""
    return re.sub(r"\d+(\.\d+)?", "#", message)


def judge(code, err: str, base_err: str, root: Path) -> str:
    """The outcome's name, or a failure starting with 'FAIL'."""
    if code == 0:
        return "accepted"
    if code != 2:
        return f"FAIL exit {code}"
    if "\x00" in err or "\x1b" in err or len(err) > 1000:
        return "FAIL message quotes raw or long content"
    if _shape(err.replace(str(root), "<campaign>")) == _shape(base_err):
        return "read, refused by the analysis as the base"
    if str(root) not in err:
        return "FAIL message names no file of the campaign"
    if any(w in err for w in TOO_LITTLE):
        return "read, too little usable data for the analysis"
    if not WHERE.search(err) and not any(w in err for w in WHOLE_FILE):
        return "FAIL message names no line, column or key"
    return "refused, named"


@pytest.mark.slow
def test_mutated_campaigns_are_accepted_or_refused_with_exit_2(bases, tmp_path, capsys):
    paths, calibration = bases
    base_csv, base_parquet = paths["csv"], paths["parquet"]
    base_errs = {}
    for fmt, base in (("csv", base_csv), ("parquet", base_parquet)):
        out = tmp_path / f"base_out_{fmt}"
        for name, argv in commands(base, out, calibration).items():
            code, err, _ = run_command(argv, capsys)
            assert code in (0, 2), f"base {fmt} {name}: exit {code}: {err}"
            base_errs[fmt, name] = err.replace(str(base), "<campaign>")
    names = list(CLASSES)
    table = collections.Counter()
    failures, slowest = [], (0.0, "")
    t_start = time.perf_counter()
    for i in range(PER_CLASS * len(names)):
        cls = names[i % len(names)]
        rng = np.random.default_rng([SEED, i])
        top = tmp_path / f"m{i:03d}"
        root, outside = top / "campaign", top / "outside"
        fmt = "parquet" if cls == "parquet_types" else "csv"
        shutil.copytree(base_parquet if fmt == "parquet" else base_csv, root, symlinks=True)
        outside.mkdir()
        mutate = CLASSES[cls]
        what = mutate(root, rng, outside) if cls == "path_escapes" else mutate(root, rng)
        before = (tree_state(root), tree_state(outside))
        cmds = commands(root, top / "out", calibration)
        chosen = ["identify"] + (["calibrate", "diagnose"] if i % 3 == 0 else []) + (["validate"] if i % 9 == 0 else [])
        for name in chosen:
            out = top / "out"
            out.mkdir()
            code, err, seconds = run_command(cmds[name], capsys)
            slowest = max(slowest, (seconds, f"mutant {i} ({cls}: {what}) {name}"))
            outcome = judge(code, err, base_errs[fmt, name], root)
            left = sorted(p.name for p in out.iterdir())
            if code == 0:
                json.loads((out / Path(cmds[name][cmds[name].index("--out") + 1]).name).read_text())
                if any("partial" in n or n.startswith(".") or n.startswith("tmp") for n in left):
                    outcome = f"FAIL temporary files left: {left}"
            elif left:
                outcome = f"FAIL output left after a refusal: {left}"
            if (tree_state(root), tree_state(outside)) != before:
                outcome = "FAIL the input tree changed"
            table[cls, name, outcome.split(":")[0] if outcome.startswith("FAIL") else outcome] += 1
            if outcome.startswith("FAIL"):
                failures.append(f"mutant {i} ({cls}: {what}) {name}: {outcome}; stderr: {err.strip()[-600:]}")
            shutil.rmtree(out)
        shutil.rmtree(top, ignore_errors=True)
    elapsed = time.perf_counter() - t_start
    summary = {f"{c} / {n} / {o}": k for (c, n, o), k in sorted(table.items())}
    (tmp_path / "fuzz_summary.json").write_text(json.dumps(summary, indent=1))
    print(f"\n{PER_CLASS * len(names)} mutants, {sum(table.values())} commands in {elapsed:.1f} s "
          f"(slowest {slowest[0]:.2f} s: {slowest[1]})")
    for (c, n, o), k in sorted(table.items()):
        print(f"  {c:15s} {n:9s} {k:3d}  {o}")
    assert not failures, f"{len(failures)} failing mutant command(s):\n" + "\n".join(failures)
    assert slowest[0] < TIME_LIMIT
