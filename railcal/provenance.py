"""Where a result came from: the software, the machine, the command and every input file's
SHA-256, as a sign-off report must state them."""
from __future__ import annotations

import datetime as _dt
import hashlib
import os
import platform
import re
import subprocess
import sys
from importlib.metadata import PackageNotFoundError, requires, version
from pathlib import Path

from calibration.data.files import hash_file


def file_sha256(path) -> str:
    """SHA-256 of a file's bytes, read in 1 MiB blocks."""
    h = hashlib.sha256()
    hash_file(h, path)
    return h.hexdigest()


def input_hashes(paths, root=None) -> dict[str, str]:
    """{path: SHA-256} of every file in ``paths`` (a folder: every file under it, in sorted
    order); the paths are relative to ``root`` when given."""
    files = []
    for p in map(Path, paths):
        files.extend(sorted(q for q in p.rglob("*") if q.is_file()) if p.is_dir() else [p])
    base = None if root is None else Path(root)
    return {str(f.relative_to(base) if base is not None else f): file_sha256(f) for f in files}


def _commit() -> dict:
    """The git commit of railcal's source and whether it has uncommitted changes; None for
    each when the source is not a git work tree (an installed wheel) or git is absent."""
    src = Path(__file__).resolve().parent
    try:
        head = subprocess.run(["git", "-C", str(src), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=10)
        if head.returncode != 0:
            return {"commit": None, "modified": None}
        status = subprocess.run(["git", "-C", str(src), "status", "--porcelain", "--untracked-files=no"],
                                capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.TimeoutExpired):
        return {"commit": None, "modified": None}
    return {"commit": head.stdout.strip(), "modified": bool(status.stdout.strip()) if status.returncode == 0 else None}


def _package_versions() -> dict[str, str | None]:
    """railcal's own requirements (its install, not the test extras) and their installed versions."""
    try:
        reqs = requires("railcal") or []
    except PackageNotFoundError:
        return {}
    out = {}
    for req in reqs:
        if "extra ==" in req:
            continue
        name = re.split(r"[\s<>=!~;\[]", req, maxsplit=1)[0]
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = None
    return dict(sorted(out.items()))


def provenance(inputs=(), *, root=None, argv=None, seeds=None) -> dict:
    """The provenance block of a result: railcal's version and commit, Python and package
    versions, the machine, the UTC time, the command line (``argv``, default sys.argv), the
    seeds used and the SHA-256 of each input file (:func:`input_hashes`)."""
    try:
        railcal_version = version("railcal")
    except PackageNotFoundError:
        railcal_version = None
    return {"railcal": {"version": railcal_version, **_commit()},
            "python": platform.python_version(), "packages": _package_versions(),
            "machine": {"platform": platform.platform(), "machine": platform.machine(),
                        "processor": platform.processor() or None, "cpus": os.cpu_count()},
            "time_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "command": list(sys.argv if argv is None else argv), "seeds": dict(seeds or {}),
            "inputs_sha256": input_hashes(inputs, root)}
