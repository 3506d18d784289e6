"""Writing railcal's outputs: campaigns (synth), JSON results and figures, each moved into place whole.

Nothing is written half: a campaign is built in a temporary folder beside its target and a
file in a temporary file beside its own (``mkstemp``: an unpredictable name, created
exclusively, never through a symbolic link), then renamed over the target. Every output
path is checked before the work starts (:func:`check_outputs`, :func:`check_campaign_output`),
so a bad ``--out`` is exit 2 at once, never a traceback after minutes, and no command
writes over its own inputs or over anything railcal did not write.
"""
from __future__ import annotations

import json
import os
import shutil
import stat
import tempfile
from pathlib import Path
from typing import BinaryIO, Callable, Iterable, Mapping

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pcsv
import pyarrow.parquet as pq
import tomli_w

from .errors import CampaignError, InputError, quoted
from .files import read_input_file
from .metadata import NAME_RE, CampaignMeta
from .tracks import TRACK_BANDS

#: The ``format`` key of every JSON result, by kind. A reader accepts a file without the key
#: (written before it existed) and refuses one it does not know.
RESULT_FORMATS = {kind: f"railcal-{kind}/1" for kind in (
    "identification", "calibration", "validation", "diagnosis", "crosscheck", "modes", "truth", "fmu-check",
    "track-profile")}

#: Marks a campaign folder written by :class:`CampaignWriter`: ``synth --force`` replaces only
#: such a folder. The campaign format reads nothing but campaign.toml, runs/ and track/, so
#: the marker is invisible to readers.
SYNTH_MARKER = ".railcal-synth"
_MARKER_TEXT = "written by railcal synth; `railcal synth --force` may replace this folder\n"


# ------------------------------------------------------------------------ output checks
def _nearest_existing(path: Path) -> Path:
    p = path
    while not os.path.lexists(p):
        p = p.parent
    return p


def _check_parent(path: Path, key: str) -> None:
    """The folder of ``path`` exists or can be made, and is writable."""
    anc = _nearest_existing(path.parent)
    if not anc.is_dir():
        raise InputError(f"cannot make the folder {path.parent}: {anc} is not a folder", path=path, key=key)
    if not os.access(anc, os.W_OK | os.X_OK):
        raise InputError(f"folder {anc} is not writable", path=path, key=key)


def _inside(child: str, parent: str) -> bool:
    return child == parent or child.startswith(parent.rstrip(os.sep) + os.sep)


def check_outputs(outputs: Iterable, *, inputs: Iterable = (), key: str = "--out") -> list[Path]:
    """Check output files before any work: each one's folder exists or can be made and is
    writable; it is not a folder, device, FIFO or socket; it is none of ``inputs`` and not
    inside an input folder (a campaign); no two outputs are the same file. ``None`` entries
    are skipped. Raises :class:`InputError` naming the path; returns the outputs as Paths."""
    seen: dict[str, Path] = {}
    ins = [(Path(i), os.path.realpath(i)) for i in inputs if i is not None]
    checked = []
    for out in outputs:
        if out is None:
            continue
        path = Path(out)
        if str(out) == "" or path.name in ("", ".", ".."):
            raise InputError("needs a file name", path=path, key=key)
        if os.path.lexists(path):
            try:
                st = os.stat(path)
            except OSError as e:  # e.g. a dangling symbolic link
                raise InputError(f"cannot write here: {e.strerror}", path=path, key=key) from None
            if stat.S_ISDIR(st.st_mode):
                raise InputError(f"is a folder; {key} takes the file to write", path=path, key=key)
            if not stat.S_ISREG(st.st_mode):
                raise InputError("is not a regular file (a device, FIFO or socket); refusing to replace it",
                                 path=path, key=key)
        _check_parent(path, key)
        real = os.path.realpath(path)
        for given, r in ins:
            if real == r:
                raise InputError(f"is an input of this command ({given}); refusing to write over it",
                                 path=path, key=key)
            if os.path.isdir(r) and _inside(real, r):
                raise InputError(f"is inside {given}, an input of this command; write results elsewhere",
                                 path=path, key=key)
        if real in seen:
            raise InputError(f"would be written twice (also as {seen[real]}); give distinct outputs",
                             path=path, key=key)
        seen[real] = path
        checked.append(path)
    return checked


def _protected_folders() -> list[str]:
    """The filesystem root, the home folder, the current folder and every folder above it."""
    cwd = Path(os.path.realpath(os.getcwd()))
    out = {os.path.realpath(os.sep), os.path.realpath(os.path.expanduser("~")), *map(str, (cwd, *cwd.parents))}
    return sorted(out)


def _railcal_truth(path: Path) -> dict | None:
    """The truth file railcal wrote at ``path``, or None."""
    try:
        obj = json.loads(path.read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    ok = isinstance(obj, dict) and (obj.get("format") == RESULT_FORMATS["truth"]
                                    or ("format" not in obj and {"parameters", "frequencies_hz"} <= set(obj)))
    return obj if ok else None


def _written_by_railcal(root: Path) -> bool:
    """The marker, or (a campaign written before the marker existed) a railcal truth file
    beside the folder that names it."""
    if (root / SYNTH_MARKER).is_file():
        return True
    truth = Path(f"{root}.truth.json")
    obj = _railcal_truth(truth) if truth.is_file() and not truth.is_symlink() else None
    return obj is not None and obj.get("campaign") == root.name and (root / "campaign.toml").is_file()


def check_campaign_output(root, *, overwrite: bool = False) -> Path:
    """Check the target of a synthetic campaign and of its ``<root>.truth.json`` before any work.

    Refused: the filesystem root, the home folder, the current folder and its parents; a
    symbolic link or a file; an existing folder without ``overwrite``; with ``overwrite``, a
    non-empty folder railcal did not write (no :data:`SYNTH_MARKER`); a truth file that is not
    a regular railcal truth file, or that exists without ``overwrite``."""
    root = Path(root)
    key = "OUT"
    if str(root) == "":
        raise CampaignError("needs a folder name", path=root, key=key)
    real = os.path.realpath(root)
    if real in _protected_folders():
        raise CampaignError("is the filesystem root, the home folder, the current folder or a folder above "
                            "it; a campaign goes into a new folder of its own", path=root, key=key)
    if os.path.lexists(root):
        if root.is_symlink():
            raise CampaignError("is a symbolic link; give the campaign folder itself", path=root, key=key)
        if not root.is_dir():
            raise CampaignError("exists and is not a folder", path=root, key=key)
        if not overwrite:
            raise CampaignError("already exists; choose another output or remove it (--force replaces a "
                                "campaign railcal wrote)", path=root, key=key)
        if not _written_by_railcal(root) and any(root.iterdir()):
            raise CampaignError(f"is not a campaign railcal wrote (no {SYNTH_MARKER} marker); railcal replaces "
                                "only those, so nothing was removed", path=root, key=key)
    _check_parent(root, key)
    truth = Path(f"{root}.truth.json")
    if os.path.lexists(truth):
        if truth.is_symlink() or not truth.is_file():
            raise CampaignError("is not a regular file; refusing to replace it", path=truth, key=key)
        if not overwrite:
            raise CampaignError("already exists; choose another output or remove it (--force replaces the "
                                "truth of a campaign railcal wrote)", path=truth, key=key)
        if _railcal_truth(truth) is None:
            raise CampaignError("is not a truth file railcal wrote; railcal replaces only those, so nothing "
                                "was removed", path=truth, key=key)
    return root


# ---------------------------------------------------------------------------- campaigns
#: significant digits of a number in a CSV the campaign writer writes (``%.9g``): 1e-9
#: relative, far below any sensor's noise, and half the size of the shortest exact form
CSV_DIGITS = 9


def round_significant(x, digits: int = CSV_DIGITS) -> np.ndarray:
    """``x`` rounded to ``digits`` significant decimal digits: exactly the value that
    ``float(f"{v:.{digits}g}")`` gives, for the whole array at once. NaN and infinities
    stay as they are."""
    x = np.asarray(x, float)
    out = x.copy()
    idx = np.flatnonzero(np.isfinite(x) & (x != 0))
    y = x[idx]
    k = digits - 1 - np.floor(np.log10(np.abs(y))).astype(int)  # decimal places to keep
    # x * 10^k is not exact, so a value within round-off of a half-way point may round the
    # wrong way, and 10^k itself is exact only up to 10^22: such values take printf's path
    up, down = 10.0 ** np.clip(k, 0, 22), 10.0 ** np.clip(-k, 0, 22)
    scaled = y * up / down
    near_half = np.abs(np.abs(scaled - np.trunc(scaled)) - 0.5) < 1e-6
    slow = near_half | (np.abs(k) > 22)
    whole = np.round(scaled)
    r = np.where(k >= 0, whole / up, whole * down)
    r[slow] = [float(f"{v:.{digits}g}") for v in y[slow]]
    out[idx] = r
    return out


def write_csv(f: BinaryIO, columns: Mapping[str, np.ndarray]) -> None:
    """The columns as CSV to the open binary file ``f``: a plain header line, then every
    float with ``CSV_DIGITS`` significant digits (the shortest form of the rounded value,
    which prints no more digits), NaN as an empty field. pyarrow's writer, ten times
    pandas' ``float_format`` (a Python call per number)."""
    f.write((",".join(columns) + "\n").encode())
    table = pa.table({name: pa.array(round_significant(v) if np.asarray(v).dtype.kind == "f" else np.asarray(v),
                                     from_pandas=True) for name, v in columns.items()})
    pcsv.write_csv(table, f, pcsv.WriteOptions(include_header=False))


class CampaignWriter:
    """Writes a campaign into a temporary folder beside ``root`` and moves it into place on
    :meth:`commit`; on failure (or without commit) nothing is left at ``root``. With
    ``overwrite``, only a campaign railcal wrote is replaced (:func:`check_campaign_output`)."""

    def __init__(self, root, meta: CampaignMeta, *, fmt: str = "csv", overwrite: bool = False):
        self.root = Path(root)
        if fmt not in ("csv", "parquet"):
            raise ValueError(f"format must be csv or parquet, not {fmt!r}")
        check_campaign_output(self.root, overwrite=overwrite)
        self.root.parent.mkdir(parents=True, exist_ok=True)
        _remove_stale_partials(self.root)
        self.tmp = Path(tempfile.mkdtemp(prefix=_partial_prefix(self.root), dir=self.root.parent))
        self.fmt, self.meta, self.overwrite = fmt, meta, overwrite
        (self.tmp / SYNTH_MARKER).write_text(_MARKER_TEXT)
        (self.tmp / "runs").mkdir()
        with open(self.tmp / "campaign.toml", "wb") as f:
            tomli_w.dump(meta.to_toml(), f)

    def write_run(self, run_id: str, columns: Mapping[str, np.ndarray]) -> Path:
        """Columns in the sensors' declared (raw) units; NaN for missing samples."""
        if not NAME_RE.match(run_id):
            raise ValueError(f"run id {run_id!r} must match [A-Za-z0-9_]+")
        path = self.tmp / "runs" / f"{run_id}.{self.fmt}"
        if self.fmt == "csv":
            with open(path, "wb") as f:
                write_csv(f, columns)
        else:
            df = pd.DataFrame({k: np.asarray(v) for k, v in columns.items()})
            pq.write_table(pa.Table.from_pandas(df, preserve_index=False), path, compression="zstd")
        return path

    def write_track(self, name: str, distance: np.ndarray, level: np.ndarray, band: str = "raw") -> Path:
        if band not in TRACK_BANDS:
            raise ValueError(f"band must be one of {TRACK_BANDS}")
        (self.tmp / "track").mkdir(exist_ok=True)
        path = self.tmp / "track" / f"{name}.csv"
        with open(path, "wb") as f:
            f.write(f'# band = "{band}"\n'.encode())
            write_csv(f, {"distance": distance, "level": level})
        return path

    def commit(self) -> Path:
        # mkdtemp's 0700 would hide the campaign from other users; give it the umask's mode
        os.chmod(self.tmp, 0o777 & ~_umask())
        if os.path.lexists(self.root):
            check_campaign_output(self.root, overwrite=self.overwrite)  # still a folder railcal wrote
            # move the old campaign aside first, so the target is never missing for long and a
            # failure between the two renames leaves a stale partial for the next writer to remove
            old = Path(tempfile.mkdtemp(prefix=_partial_prefix(self.root), dir=self.root.parent))
            os.replace(self.root, old)
            os.replace(self.tmp, self.root)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(self.tmp, self.root)
        return self.root

    def abort(self) -> None:
        shutil.rmtree(self.tmp, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None:
            self.abort()
        return False


def _partial_prefix(root: Path) -> str:
    return f".{root.name}.partial-"


def _remove_stale_partials(root: Path) -> None:
    """Temporary folders a killed writer left for the same target: only real folders carrying
    the marker (or empty ones, killed before the marker was written) are removed."""
    for p in root.parent.glob(f"{_partial_prefix(root)}*"):
        if p.is_symlink() or not p.is_dir():
            continue
        if (p / SYNTH_MARKER).is_file() or not any(p.iterdir()):
            shutil.rmtree(p, ignore_errors=True)


# ------------------------------------------------------------------------- atomic files
def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_atomic(path, write: Callable[[BinaryIO], None]) -> Path:
    """Call ``write(f)`` on a temporary file beside ``path`` (``mkstemp``), then rename it over
    ``path``. The file gets the mode of the file it replaces, or the umask's for a new one
    (not mkstemp's 0600). A folder, device or FIFO at ``path`` is refused, never replaced."""
    path = Path(path)
    if os.path.lexists(path) and not path.is_file():
        raise InputError("is not a regular file; refusing to replace it", path=path)
    path.parent.mkdir(parents=True, exist_ok=True)
    mode = stat.S_IMODE(os.stat(path).st_mode) if path.is_file() else 0o666 & ~_umask()
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            os.fchmod(f.fileno(), mode)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_json_atomic(path, obj) -> Path:
    """Write JSON via a temporary file and rename, so a failure never leaves half a file."""
    text = json.dumps(obj, indent=2, allow_nan=False, default=_json_default) + "\n"
    return write_atomic(path, lambda f: f.write(text.encode()))


def write_result(path, obj: Mapping, kind: str) -> Path:
    """Write a JSON result with its ``format`` key first (:data:`RESULT_FORMATS`)."""
    fmt = RESULT_FORMATS[kind]
    if obj.get("format", fmt) != fmt:
        raise ValueError(f"a {kind} result cannot carry format {obj['format']!r}")
    return write_json_atomic(path, {"format": fmt, **{k: v for k, v in obj.items() if k != "format"}})


def read_result(path, kinds: Iterable[str]) -> dict:
    """A JSON result of one of ``kinds``: a file without ``format`` (older) is accepted, an
    unknown format refused (:class:`InputError` naming the file and key)."""
    path = Path(path)
    kinds = tuple(kinds)
    text = read_input_file(path)  # a regular file of bounded size: a FIFO or /dev/zero never blocks
    try:
        obj = json.loads(text)
    except ValueError as e:
        raise InputError(f"not a readable JSON result: {e}", path=path) from None
    if not isinstance(obj, dict):
        raise InputError(f"expected a JSON object, got {type(obj).__name__}", path=path)
    fmt = obj.get("format")
    known = [RESULT_FORMATS[k] for k in kinds]
    if fmt is not None and fmt not in known:
        shown = repr(fmt) if len(repr(fmt)) <= 60 else repr(fmt)[:57] + "..."
        raise InputError(f"format {shown} is not one this railcal reads ({', '.join(known)})", path=path,
                         key="format")
    return obj


def result_rows(data: dict, key: str) -> list:
    """``data[key]`` of a JSON result read back, which must be a list, or :class:`InputError`."""
    rows = data.get(key)
    if not isinstance(rows, list):
        raise InputError(f"expected a list, got {quoted(rows)}", key=key)
    return rows


def result_label(row, where: str) -> str:
    """The ``label`` of a row of a JSON result read back, or :class:`InputError` keyed ``where``."""
    if not isinstance(row, dict) or not isinstance(row.get("label"), str):
        raise InputError(f"a row needs a text label, got {quoted(row)}", key=where)
    return row["label"]


def result_number(row: dict, key: str, where: str, *, optional: bool = False, positive: bool = False):
    """``row[key]`` of a JSON result read back, as a finite float (None if ``optional`` and
    absent or null), or :class:`InputError` keyed ``where.key``."""
    value = row.get(key) if isinstance(row, dict) else None
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) \
            or (positive and not value > 0):
        raise InputError(f"expected a finite{' positive' if positive else ''} number, got {quoted(value)}",
                         key=f"{where}.{key}")
    return float(value)


def save_figure(fig, path) -> Path:
    """Save a matplotlib figure atomically (as :func:`write_atomic`; the format from the
    suffix, default PNG) and close it."""
    path = Path(path)
    try:
        write_atomic(path, lambda f: fig.savefig(f, format=path.suffix[1:] or "png", dpi=fig.dpi))
    finally:
        import matplotlib.pyplot as plt  # only to release the figure; the caller chose the backend

        plt.close(fig)
    return path


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
