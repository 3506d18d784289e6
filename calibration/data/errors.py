"""Errors about user input. The command line turns them into exit code 2."""
from __future__ import annotations

#: At most this many characters of a file's content (a cell, a header, a TOML value) are
#: quoted in a message, so a message never echoes whole lines of an arbitrary file. A
#: choice, not a standard: enough to recognise a cell or a TOML value at a glance.
EXCERPT_CHARS = 60
_SURROGATES = (0xD800, 0xDFFF)  # undecodable bytes of a file name (os.fsdecode)


def excerpt(text, limit: int = EXCERPT_CHARS) -> str:
    """``text`` shortened to ``limit`` characters (an ellipsis marks the cut), with control
    characters, escape sequences and undecodable bytes escaped so that a message prints
    safely on any terminal."""
    s = str(text)
    if len(s) > limit:
        s = s[:limit - 1] + "…"
    return "".join(c if c.isprintable() and not _SURROGATES[0] <= ord(c) <= _SURROGATES[1]
                   else c.encode("unicode_escape", "backslashreplace").decode("ascii") for c in s)


def quoted(value) -> str:
    """A value read from an input file (a TOML value, a band name) as a message quotes it:
    its repr, shortened as :func:`excerpt` does."""
    return excerpt(repr(value))


def _printable(text) -> str:
    """The same escaping without shortening, for file paths (named in full)."""
    return excerpt(text, limit=10 ** 9)


class InputError(ValueError):
    """Bad input: the message names the file and the line, column or key, and what was expected."""

    def __init__(self, message: str, *, path=None, line: int | None = None, column: str | None = None,
                 key: str | None = None):
        where = []
        if path is not None:
            where.append(_printable(path))
        if line is not None:
            where.append(f"line {line}")
        if column is not None:
            where.append(f"column '{excerpt(column)}'")
        if key is not None:
            where.append(f"key '{excerpt(key)}'")
        super().__init__(f"{': '.join([', '.join(where), message]) if where else message}")
        self.message, self.path, self.line, self.column, self.key = message, path, line, column, key

    def located(self, path) -> "InputError":
        """The same error, naming ``path`` as the file it is about (when it names none yet)."""
        if self.path is not None:
            return self
        return type(self)(self.message, path=path, line=self.line, column=self.column, key=self.key)


class CampaignError(InputError):
    """A campaign folder, its campaign.toml or a run/track file is malformed."""
