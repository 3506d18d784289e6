"""Reading input files safely: only regular files of a bounded size, inside a given folder.

A FIFO or a device would block or never end, an oversized file would fill the memory, a
link out of a campaign folder reads what the user did not hand over; each is refused with
a :class:`~calibration.data.errors.CampaignError` naming the path before a byte is read.
"""
from __future__ import annotations

import os
import stat
from pathlib import Path

from .errors import CampaignError
from .limits import MAX_INPUT_BYTES

#: The UTF-8 byte order mark, skipped at the start of a text file.
BOM = b"\xef\xbb\xbf"


def _kind_of(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a file"


def check_file(path: Path, limit: int, *, root: Path | None = None) -> None:
    """Refuse, before opening it, anything but a regular file of at most ``limit`` bytes
    (inside ``root``, resolved, when given): a FIFO or a device would block or never end,
    an oversized file would fill the memory, a link out of the folder reads what the user
    did not hand over."""
    try:
        st = os.stat(path)  # follows links: the target is what would be read
    except OSError as e:
        raise CampaignError(f"cannot read: {e.strerror}", path=path) from None
    if not stat.S_ISREG(st.st_mode):
        raise CampaignError(f"not a regular file ({_kind_of(st.st_mode)})", path=path)
    if st.st_size > limit:
        raise CampaignError(f"{st.st_size} bytes, larger than the {limit} bytes such a file may be", path=path)
    if root is not None:
        real, top = os.path.realpath(path), os.path.realpath(root)
        if os.path.commonpath([real, top]) != top:
            raise CampaignError(f"resolves to {real}, outside the campaign folder {top}; it is read only when "
                                f"outside files are allowed (open_campaign(..., allow_outside=True))", path=path)


def read_bytes(path: Path, limit: int) -> bytes:
    """The content of ``path`` after :func:`check_file`; never more than ``limit`` bytes."""
    check_file(path, limit)
    try:
        with open(path, "rb") as f:
            data = f.read(limit + 1)  # never more, even if the file grew since the check
    except OSError as e:
        raise CampaignError(f"cannot read: {e.strerror}", path=path) from None
    if len(data) > limit:
        raise CampaignError(f"larger than the {limit} bytes such a file may be", path=path)
    return data


def read_input_file(path, *, limit: int = MAX_INPUT_BYTES) -> str:
    """The UTF-8 text of a small input file (a calibration JSON, a targets TOML), checked
    first to be a regular file of at most ``limit`` bytes: reading ``/dev/zero`` or a FIFO
    would never end. Raises :class:`CampaignError` (an InputError: exit 2) naming the path."""
    path = Path(path)
    data = read_bytes(path, limit)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise CampaignError("not UTF-8 text", path=path, line=data[:e.start].count(b"\n") + 1) from None


def hash_file(h, path) -> None:
    """Feed the bytes of the file at ``path`` into the hashlib object ``h``, 1 MiB at a time."""
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
