"""Errors about user input. The command line turns them into exit code 2."""
from __future__ import annotations


class InputError(ValueError):
    """Bad input: the message names the file and the line, column or key, and what was expected."""

    def __init__(self, message: str, *, path=None, line: int | None = None, column: str | None = None,
                 key: str | None = None):
        where = []
        if path is not None:
            where.append(str(path))
        if line is not None:
            where.append(f"line {line}")
        if column is not None:
            where.append(f"column '{column}'")
        if key is not None:
            where.append(f"key '{key}'")
        super().__init__(f"{': '.join([', '.join(where), message]) if where else message}")
        self.path, self.line, self.column, self.key = path, line, column, key


class CampaignError(InputError):
    """A campaign folder, its campaign.toml or a run/track file is malformed."""
