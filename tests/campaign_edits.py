"""Edits and checks the campaign tests share: run the command line, expect a refusal, and
change one cell, one TOML value or one run file of the tiny campaign (tests/conftest.py)."""
from __future__ import annotations

import re

from railcal.cli import main


def run_cli(args, capsys):
    code = main([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def identify_rejects(campaign, tmp_path, capsys, *patterns):
    out = tmp_path / "ident.json"
    code, _, err = run_cli(["identify", campaign, "--out", out, "--quiet"], capsys)
    assert code == 2, err
    for p in patterns:
        assert re.search(p, err), f"{p!r} not in: {err}"
    assert not out.exists()  # nothing written half
    return err


def set_cell(root, data_row, column, value):
    """Replace one cell of run_a.csv; data_row counts from 1 after the header (file line data_row + 1)."""
    def edit(lines):
        lines = list(lines)
        cells = lines[data_row].split(",")
        cells[column] = value
        lines[data_row] = ",".join(cells)
        return lines
    return rewrite_run(root, edit)


def replace_in_toml(root, old, new):
    toml = root / "campaign.toml"
    assert old in toml.read_text()
    toml.write_text(toml.read_text().replace(old, new))


def rewrite_run(root, edit):
    path = root / "runs" / "run_a.csv"
    lines = path.read_text().splitlines()
    path.write_text("\n".join(edit(lines)) + "\n")
    return path
