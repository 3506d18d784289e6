"""The reference pages in docs/ tell the truth about the code they describe."""
from __future__ import annotations

import re
import tomllib
import warnings
from pathlib import Path

import pytest

from railcal.cli import build_parser
from calibration.data.campaign import parse_meta

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _blocks(page: str, lang: str) -> list[str]:
    return re.findall(rf"^```{lang}\n(.*?)^```", (DOCS / page).read_text(), re.S | re.M)


@pytest.mark.parametrize("example", _blocks("campaign-format.md", "toml"))
def test_every_campaign_toml_example_is_read_as_written(example):
    """Each example campaign.toml parses and passes railcal's own checks without a warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        meta = parse_meta(tomllib.loads(example), Path("campaign.toml"))
    assert meta.sensors


def test_every_command_of_the_cli_is_documented():
    """docs/cli.md names every railcal command the parser has."""
    text = (DOCS / "cli.md").read_text()
    parser = build_parser()
    commands = next(a for a in parser._actions if a.dest == "command").choices
    for name in commands:
        assert f"railcal {name}" in text, name


def test_the_performance_table_gives_a_command_for_every_row():
    rows = [ln for ln in (DOCS / "performance.md").read_text().splitlines()
            if ln.startswith("| ") and not ln.startswith("| what") and not ln.startswith("|---")]
    assert rows
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert "`" in cells[1], f"no command for: {cells[0]}"
