"""Measurement campaigns (shared/spec/campaign-format.md, v1): read, check, write.

Reading is strict: anything malformed raises :class:`CampaignError` naming the file and
the line, column or key. Unit conversion and each sensor's ``scale`` are applied once,
here. Runs are read one at a time (:meth:`Campaign.iter_runs`) so a campaign of any size
streams through in the memory of one run.

Choices where the spec leaves room:
* A run-file column that is neither declared in campaign.toml nor a known column
  (``time``, ``distance``, ``speed``, ``<sensor>_clipped``) is an error, not a warning:
  a misspelt sensor column would otherwise silently drop that sensor's data.
* Unknown keys in campaign.toml are ignored with a warning, as the spec says.
* Gaps (a time step over 1.5 sampling intervals) are reported and split the run into
  contiguous blocks; nothing is interpolated. NaN and clipped samples are marked
  invalid per channel; a channel with no valid sample left is an error.
* Hostile or corrupted input is refused before it costs time or memory: only regular
  files inside the campaign folder are read (``open_campaign(allow_outside=True)`` lifts
  the second condition), sizes are checked before a byte is read, values are held to
  stated physical plausibility ranges, and every message quotes at most a short excerpt of
  a file's content (:func:`~calibration.data.errors.excerpt`).
* A CSV file may end its lines in LF, CRLF or CR alone (Excel's "CSV (Macintosh)"), and
  may start with a UTF-8 byte order mark.
* Parquet columns are integers or floats; a boolean column is accepted only as a
  ``<sensor>_clipped`` flag (its natural type there), never as data.
* ``m/s2`` and ``m/s²`` are read as ``m/s^2`` (units.UNIT_ALIASES).
* A NaN speed sample is a missing Doppler fix, accepted where a ``distance`` column
  locates the run; without one it would leave the run's position undefined, so it is an
  error. The time, distance and speed checks live in :func:`read_run_file`, so every
  command that reads a run applies them.
"""
from __future__ import annotations

import collections
import csv
import difflib
import io
import math
import os
import re
import stat
import tomllib
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Mapping

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from .errors import CampaignError, excerpt
from .units import BODIES, QUANTITIES, ROTATIONS, TRANSLATIONS, UNIT_ALIASES, UNITS, canonical_unit, si_factor

FORMAT = "railcal-campaign/1"
KINDS = ("in_service", "stationary_excitation")
NAME_RE = re.compile(r"^[A-Za-z0-9_]+$")
TRACK_BANDS = ("D1", "D2", "raw")
GAP_FACTOR = 1.5  # a time step longer than this many sampling intervals is a gap
_TOP_KEYS = {"format", "kind", "name", "vehicle", "priors", "sensors", "sampling", "excitation"}
_SENSOR_KEYS = {"name", "quantity", "unit", "body", "direction", "position", "scale"}

# Plausibility limits. Each keeps a corrupted or hostile value from reaching the analyses,
# where it would cost hours or give a wrong answer without a word.
#: campaign.toml is refused above this size before it is parsed: a campaign with hundreds
#: of sensors and priors is tens of kB.
MAX_TOML_BYTES = 1 << 20
#: A run or track file is refused above this size before it is read. The reader holds a
#: file and its parsed columns in memory (about twice the file); 2 GiB of CSV is about 12 h
#: of the synthetic 9-column 500 Hz format (48 kB/s), longer than any journey.
MAX_RUN_BYTES = 2 << 30
#: ... and a Parquet file above this many cells (rows x columns, from its footer): 2 GiB
#: as float64, so a small compressed file cannot expand without bound.
MAX_RUN_CELLS = 1 << 28
#: ... and a CSV file of more lines than this (12 h at 500 Hz is 21.6 M rows): the reader
#: keeps about 40 bytes per line besides the text, so this bounds that to under 3 GB.
MAX_RUN_LINES = 1 << 26
#: ... or of more columns: a campaign declares tens, at most hundreds, of sensors.
MAX_COLUMNS = 10_000
#: [m/s] 720 km/h, above the wheel-on-rail speed record (574.8 km/h, 2007).
MAX_SPEED = 200.0
#: [m] 100 000 km: a position along any railway line is below 1e7 m.
MAX_ABS_DISTANCE = 1.0e8
#: [s] Unix time in seconds is 1.8e9 today; a time beyond 1e10 s (317 years) is not in seconds.
MAX_ABS_TIME = 1.0e10
#: [Hz] loggers of vehicle dynamics record between a few Hz (GPS) and tens of kHz (acoustics).
RATE_RANGE = (1.0, 1.0e5)
#: The median time step of a run must match 1 / [sampling] rate within this fraction: the
#: analyses filter and resample at the nominal rate, so a rate off by more shifts every
#: identified frequency by as much (logger clocks agree with their rate to ppm).
RATE_TOLERANCE = 0.02
#: [m] every sensor position coordinate: 1 km bounds any placement on or beside a vehicle.
MAX_POSITION = 1.0e3
#: [m] plausible [vehicle] geometry, (low, high):
#: bogie_semi_spacing, half the bogie-centre distance: 2-30 m, from short tram sections to
#: 27 m freight wagons; semi_wheelbase: bogie wheelbases 1-5 m, from tram bogies to
#: three-axle locomotive bogies; length 2-40 m, width 1-5 m (the widest loading gauges are
#: under 4 m), height 1-8 m above the rail (double-stack container cars: 6.1 m).
GEOMETRY_RANGES = {"bogie_semi_spacing": (1.0, 15.0), "semi_wheelbase": (0.5, 2.5), "length": (2.0, 40.0),
                   "width": (1.0, 5.0), "height": (1.0, 8.0)}
_GEOMETRY_KEYS = set(GEOMETRY_RANGES)


# ----------------------------------------------------------------------------- metadata
@dataclass(frozen=True)
class Sensor:
    name: str
    quantity: str
    unit: str
    body: str
    direction: str
    position: tuple[float, float, float]  # [m] vehicle frame
    scale: float = 1.0

    @property
    def si_factor(self) -> float:
        """Multiply the raw column by this to get SI units (scale and unit together)."""
        return self.scale * si_factor(self.unit)

    def to_toml(self) -> dict:
        return {"name": self.name, "quantity": self.quantity, "unit": self.unit, "body": self.body,
                "direction": self.direction, "position": list(self.position), "scale": self.scale}


@dataclass(frozen=True)
class Prior:
    nominal: float
    low: float
    high: float


@dataclass(frozen=True)
class Excitation:
    sensor: str
    position: tuple[float, float, float]


@dataclass(frozen=True)
class CampaignMeta:
    """Everything campaign.toml says."""

    kind: str
    name: str
    vehicle: str
    sensors: tuple[Sensor, ...]
    sampling_rate: float
    geometry: Mapping[str, float] = field(default_factory=dict)
    priors: Mapping[str, Prior] = field(default_factory=dict)
    excitation: Excitation | None = None

    def sensor(self, name: str) -> Sensor:
        for s in self.sensors:
            if s.name == name:
                return s
        raise KeyError(f"no sensor {name!r}; have {', '.join(s.name for s in self.sensors)}")

    def to_toml(self) -> dict:
        d: dict = {"format": FORMAT, "kind": self.kind, "name": self.name}
        vehicle: dict = {"name": self.vehicle, **{k: float(v) for k, v in self.geometry.items()}}
        d["vehicle"] = vehicle
        if self.priors:
            d["priors"] = {k: {"nominal": p.nominal, "low": p.low, "high": p.high} for k, p in self.priors.items()}
        d["sensors"] = [s.to_toml() for s in self.sensors]
        d["sampling"] = {"rate": self.sampling_rate}
        if self.excitation is not None:
            d["excitation"] = {"sensor": self.excitation.sensor, "position": list(self.excitation.position)}
        return d


def _q(value) -> str:
    """A value of campaign.toml as quoted in a message: its repr, shortened."""
    return excerpt(repr(value))


def _number(value, path, key) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CampaignError(f"expected a finite number, got {_q(value)}", path=path, key=key)
    try:
        x = float(value)  # a TOML integer of hundreds of digits has no float
    except OverflowError:
        x = math.inf
    if not math.isfinite(x):
        raise CampaignError(f"expected a finite number, got {_q(value)}", path=path, key=key)
    return x


def _position(value, path, key) -> tuple[float, float, float]:
    if not isinstance(value, list) or len(value) != 3:
        raise CampaignError(f"expected [x, y, z] in metres, got {_q(value)}", path=path, key=key)
    xyz = tuple(_number(v, path, key) for v in value)
    if max(abs(v) for v in xyz) > MAX_POSITION:
        raise CampaignError(f"a coordinate beyond {MAX_POSITION:g} m of the carbody centre: {_q(value)}", path=path,
                            key=key)
    return xyz  # type: ignore[return-value]


def _check_geometry(geometry: Mapping[str, float], path) -> None:
    """The [vehicle] lengths fit together: the axles of a bogie lie between the bogie
    centres, and the bogie centres under the carbody (at its ends on articulated units)."""
    L_v, L_b, length = (geometry.get(k) for k in ("bogie_semi_spacing", "semi_wheelbase", "length"))
    if L_v is not None and L_b is not None and not L_b < L_v:
        raise CampaignError(f"semi_wheelbase {L_b:g} m must be below bogie_semi_spacing {L_v:g} m", path=path,
                            key="vehicle.semi_wheelbase")
    if L_v is not None and length is not None and not L_v <= length / 2:
        raise CampaignError(f"bogie_semi_spacing {L_v:g} m puts the bogies beyond the ends of a {length:g} m "
                            f"carbody", path=path, key="vehicle.bogie_semi_spacing")


def parse_meta(data: dict, path: Path) -> CampaignMeta:
    """Check and convert the parsed campaign.toml; ``path`` is named in every message."""
    for k in sorted(set(data) - _TOP_KEYS):
        warnings.warn(f"{path}: unknown key '{excerpt(k)}' ignored", stacklevel=2)
    fmt = data.get("format")
    if fmt != FORMAT:
        raise CampaignError(f"expected format = \"{FORMAT}\", got {_q(fmt)}", path=path, key="format")
    kind = data.get("kind")
    if kind not in KINDS:
        raise CampaignError(f"expected one of {', '.join(KINDS)}, got {_q(kind)}", path=path, key="kind")
    vehicle = data.get("vehicle", {})
    if not isinstance(vehicle, (dict, str)):
        raise CampaignError(f"expected a [vehicle] table or a name, got {_q(vehicle)}", path=path, key="vehicle")
    vehicle_name = data.get("vehicle") if isinstance(data.get("vehicle"), str) else ""
    geometry: dict[str, float] = {}
    if isinstance(vehicle, dict):
        vehicle_name = str(vehicle.get("name", vehicle_name))
        for k, v in vehicle.items():
            if k in _GEOMETRY_KEYS:
                geometry[k] = _number(v, path, f"vehicle.{k}")
                lo, hi = GEOMETRY_RANGES[k]
                if not lo <= geometry[k] <= hi:
                    raise CampaignError(f"{geometry[k]:g} m is not a plausible {k} (expected {lo:g} to {hi:g} m)",
                                        path=path, key=f"vehicle.{k}")
            elif k != "name":
                warnings.warn(f"{path}: unknown key 'vehicle.{excerpt(k)}' ignored", stacklevel=2)
        _check_geometry(geometry, path)
    priors: dict[str, Prior] = {}
    raw_priors = data.get("priors") or {}
    if not isinstance(raw_priors, dict):
        raise CampaignError("expected tables [priors.NAME] with nominal, low, high", path=path, key="priors")
    for pname, pr in raw_priors.items():
        key = f"priors.{pname}"
        if not isinstance(pr, dict):
            raise CampaignError("expected a table with nominal, low, high", path=path, key=key)
        missing = [k for k in ("nominal", "low", "high") if k not in pr]
        if missing:
            raise CampaignError(f"missing {', '.join(missing)}", path=path, key=key)
        p = Prior(*(_number(pr[k], path, f"{key}.{k}") for k in ("nominal", "low", "high")))
        if not (p.low < p.high):
            raise CampaignError(f"low = {p.low} must be below high = {p.high} (infeasible bounds)", path=path,
                                key=key)
        if not (p.low <= p.nominal <= p.high):
            raise CampaignError(f"nominal = {p.nominal} outside [low, high] = [{p.low}, {p.high}]", path=path,
                                key=key)
        priors[pname] = p
    raw_sensors = data.get("sensors")
    if not isinstance(raw_sensors, list) or not raw_sensors:
        raise CampaignError("expected at least one [[sensors]] table", path=path, key="sensors")
    sensors = []
    seen: dict[str, int] = {}
    for i, s in enumerate(raw_sensors):
        key = f"sensors[{i}]"
        if not isinstance(s, dict):
            raise CampaignError("expected a table", path=path, key=key)
        for k in sorted(set(s) - _SENSOR_KEYS):
            warnings.warn(f"{path}: unknown key '{key}.{excerpt(k)}' ignored", stacklevel=2)
        for k in ("name", "quantity", "unit", "body", "direction", "position"):
            if k not in s:
                raise CampaignError(f"missing '{k}'", path=path, key=key)
            if k != "position" and not isinstance(s[k], str):
                raise CampaignError(f"expected a string, got {_q(s[k])}", path=path, key=f"{key}.{k}")
        name = s["name"]
        if not isinstance(name, str) or not NAME_RE.match(name):
            raise CampaignError(f"sensor name {_q(name)} must match [A-Za-z0-9_]+", path=path, key=f"{key}.name")
        if name in ("time", "distance", "speed") or name.endswith("_clipped"):
            raise CampaignError(f"sensor name {_q(name)} is reserved", path=path, key=f"{key}.name")
        if name in seen:
            raise CampaignError(f"sensor name {_q(name)} declared twice (also sensors[{seen[name]}])", path=path,
                                key=f"{key}.name")
        seen[name] = i
        q, unit = s["quantity"], canonical_unit(s["unit"])
        if q not in QUANTITIES:
            raise CampaignError(f"unknown quantity {_q(q)}; expected one of {', '.join(QUANTITIES)}", path=path,
                                key=f"{key}.quantity")
        if unit not in UNITS:
            raise CampaignError(f"unknown unit {_q(unit)}; expected one of {', '.join(UNITS)} (or "
                                f"{', '.join(UNIT_ALIASES)} for m/s^2)", path=path,
                                key=f"{key}.unit")
        if UNITS[unit][0] != q:
            raise CampaignError(f"unit {_q(unit)} is not a unit of {q}", path=path, key=f"{key}.unit")
        if s["body"] not in BODIES:
            raise CampaignError(f"unknown body {_q(s['body'])}; expected one of {', '.join(BODIES)}", path=path,
                                key=f"{key}.body")
        direction = s["direction"]
        allowed = ROTATIONS if q == "angular_velocity" else TRANSLATIONS
        if direction not in allowed:
            raise CampaignError(f"direction {_q(direction)} not valid for {q}; expected one of {', '.join(allowed)}",
                                path=path, key=f"{key}.direction")
        scale = _number(s.get("scale", 1.0), path, f"{key}.scale")
        if scale == 0:
            raise CampaignError("scale must not be zero", path=path, key=f"{key}.scale")
        factor = scale * si_factor(unit)
        if not math.isfinite(factor) or factor == 0:
            raise CampaignError(f"scale {scale:g} times the {unit} to SI factor {si_factor(unit):g} is not finite "
                                f"and non-zero", path=path, key=f"{key}.scale")
        sensors.append(Sensor(name, q, unit, s["body"], direction, _position(s["position"], path, f"{key}.position"),
                              scale))
    sampling = data.get("sampling")
    if not isinstance(sampling, dict) or "rate" not in sampling:
        raise CampaignError("expected [sampling] with rate [Hz]", path=path, key="sampling.rate")
    rate = _number(sampling["rate"], path, "sampling.rate")
    if not RATE_RANGE[0] <= rate <= RATE_RANGE[1]:
        raise CampaignError(f"{rate:g} Hz is not a plausible sampling rate (expected {RATE_RANGE[0]:g} to "
                            f"{RATE_RANGE[1]:g} Hz)", path=path, key="sampling.rate")
    excitation = None
    if kind == "stationary_excitation":
        ex = data.get("excitation")
        if not isinstance(ex, dict) or not isinstance(ex.get("sensor"), str):
            raise CampaignError("a stationary_excitation campaign needs [excitation] sensor = ...", path=path,
                                key="excitation")
        if ex["sensor"] not in seen:
            raise CampaignError(f"names sensor {_q(ex['sensor'])}, which is not declared in [[sensors]]", path=path,
                                key="excitation.sensor")
        excitation = Excitation(ex["sensor"], _position(ex.get("position", [0, 0, 0]), path, "excitation.position"))
    return CampaignMeta(kind, str(data.get("name", "")), vehicle_name, tuple(sensors), rate, geometry, priors,
                        excitation)


# --------------------------------------------------------------------------------- runs
@dataclass(frozen=True)
class Gap:
    after_time: float  # [s] last sample before the gap
    before_time: float  # [s] first sample after it

    @property
    def duration(self) -> float:
        return self.before_time - self.after_time


@dataclass(frozen=True)
class Run:
    """One run in SI units. ``valid[name]`` is False where a sample is missing or clipped;
    ``blocks`` are [start, stop) index ranges between gaps."""

    run_id: str
    path: Path
    time: np.ndarray
    channels: Mapping[str, np.ndarray]
    valid: Mapping[str, np.ndarray]
    blocks: tuple[tuple[int, int], ...]
    gaps: tuple[Gap, ...]
    distance: np.ndarray | None = None
    speed: np.ndarray | None = None

    def __len__(self) -> int:
        return self.time.size


@dataclass(frozen=True)
class _Table:
    """Columns as read, and where each data row stands in the file (1-based line numbers;
    None for Parquet, where messages name the row instead)."""

    columns: dict
    lines: np.ndarray | None

    def where(self, row: int) -> dict:
        return {"line": int(self.lines[row])} if self.lines is not None else {}

    def row_word(self, row: int) -> str:
        return "" if self.lines is not None else f" (row {row})"


def _kind_of(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a file"


def _check_file(path: Path, limit: int, *, root: Path | None = None) -> None:
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


def _read_bytes(path: Path, limit: int) -> bytes:
    _check_file(path, limit)
    try:
        with open(path, "rb") as f:
            data = f.read(limit + 1)  # never more, even if the file grew since the check
    except OSError as e:
        raise CampaignError(f"cannot read: {e.strerror}", path=path) from None
    if len(data) > limit:
        raise CampaignError(f"larger than the {limit} bytes such a file may be", path=path)
    return data


#: A settings or result file a command reads besides a campaign (calibration JSON, targets
#: and priors TOML, a truth file) is refused above this size: such files are kB to a few MB.
MAX_INPUT_BYTES = 64 << 20


def read_input_file(path, *, limit: int = MAX_INPUT_BYTES) -> str:
    """The UTF-8 text of a small input file (a calibration JSON, a targets TOML), checked
    first to be a regular file of at most ``limit`` bytes: reading ``/dev/zero`` or a FIFO
    would never end. Raises :class:`CampaignError` (an InputError: exit 2) naming the path."""
    path = Path(path)
    data = _read_bytes(path, limit)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise CampaignError("not UTF-8 text", path=path, line=data[:e.start].count(b"\n") + 1) from None


_BOM = b"\xef\xbb\xbf"
# a cell the fallback parser accepts: a decimal number, inf or nan, or nothing (missing)
_CELL = re.compile(rb"\s*(?:[+-]?(?:\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?|inf|infinity)|nan)?\s*",
                   re.IGNORECASE)


def _read_csv(path: Path) -> _Table:
    """Read a CSV run or track file strictly. A comment is a line whose first non-blank
    character is '#'; blank lines are skipped; every other line after the header must have
    the header's number of fields; cells are numbers, empty or nan. Lines end in LF, CRLF
    or CR; a UTF-8 byte order mark is skipped. Time and memory are linear in the size."""
    data = _read_bytes(path, MAX_RUN_BYTES)
    if data.startswith(_BOM):
        data = data[len(_BOM):]
    elif data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise CampaignError("text in UTF-16 or UTF-32; save the file as UTF-8", path=path, line=1)
    n_cr = data.count(b"\r")
    if n_cr and n_cr != data.count(b"\r\n"):  # CR alone ends lines (Excel's "CSV (Macintosh)")
        data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    n_lines = data.count(b"\n") + 1
    if n_lines > MAX_RUN_LINES:
        raise CampaignError(f"{n_lines} lines, more than the {MAX_RUN_LINES} a run file may have", path=path)
    raw_lines = data.split(b"\n")
    del data
    kept, numbers = [], []
    for i, raw in enumerate(raw_lines, start=1):
        stripped = raw.strip()
        if not stripped or stripped.startswith(b"#"):
            continue
        kept.append(raw.rstrip(b"\r"))
        numbers.append(i)
    del raw_lines
    if not kept:
        raise CampaignError("no header row", path=path)
    header_line = numbers[0]
    if kept[0].count(b",") >= MAX_COLUMNS:
        raise CampaignError(f"{kept[0].count(b',') + 1} columns in the header, more than the {MAX_COLUMNS} a run file "
                            f"may have", path=path, line=header_line)
    try:
        names = [c.strip() for c in kept[0].decode("utf-8").split(",")]
    except UnicodeDecodeError:
        raise CampaignError("header is not UTF-8 text", path=path, line=header_line) from None
    dup = [n for n, k in collections.Counter(names).items() if k > 1]
    if dup:
        more = f" and {len(dup) - 3} more" if len(dup) > 3 else ""
        shown = ", ".join(f"'{excerpt(n, 30)}'" for n in dup[:3]) + more
        raise CampaignError(f"duplicate column(s) {shown} in the header", path=path, line=header_line)
    expected = len(names) - 1
    counts = np.fromiter((ln.count(b",") for ln in kept), int, len(kept))
    bad = np.flatnonzero(counts != expected)
    if bad.size:
        k = int(bad[0])
        raise CampaignError(f"expected {expected + 1} comma-separated fields (as the header), found {counts[k] + 1}",
                            path=path, line=numbers[k])
    lines = np.asarray(numbers[1:])
    rows = kept[1:]
    body = b"\n".join(rows)
    try:
        body.decode("utf-8")
    except UnicodeDecodeError as e:
        line = int(lines[body[:e.start].count(b"\n")])
        raise CampaignError("not UTF-8 text", path=path, line=line) from None
    if not rows:
        return _Table({n: np.empty(0) for n in names}, lines)
    try:
        # fast path: every cell a number, empty or nan; quotes are not special, as the
        # field count above does not know them either
        df = pd.read_csv(io.BytesIO(body), header=None, names=list(range(len(names))), dtype=np.float64,
                         engine="c", na_values=["", "nan", "NaN", "NAN"], keep_default_na=False,
                         skipinitialspace=True, quoting=csv.QUOTE_NONE, skip_blank_lines=False)
        if len(df) != len(rows):
            raise ValueError("row count differs")
        columns = {n: df[i].to_numpy(dtype=float) for i, n in enumerate(names)}
    except (ValueError, OverflowError):
        columns = _parse_rows(rows, names, lines, path)  # says which cell is not a number
    return _Table(columns, lines)


def _parse_rows(rows: list[bytes], names: list[str], lines: np.ndarray, path: Path) -> dict[str, np.ndarray]:
    """The slow, plain parse of the data rows, cell by cell, naming the first bad cell."""
    out = np.empty((len(rows), len(names)))
    for r, row in enumerate(rows):
        for c, cell in enumerate(row.split(b",")):
            if not _CELL.fullmatch(cell):
                text = excerpt(cell.decode("utf-8", "replace").strip())
                raise CampaignError(f"'{text}' is not a number (use an empty cell or nan for a missing sample)",
                                    path=path, line=int(lines[r]), column=names[c])
            cell = cell.strip()
            out[r, c] = float(cell) if cell else math.nan
    return {n: out[:, c].copy() for c, n in enumerate(names)}


def _pandas_index_columns(schema: pa.Schema) -> set[str]:
    """Columns a pandas writer stored its index in: not data, not read."""
    try:
        meta = schema.pandas_metadata or {}
        return {c for c in meta.get("index_columns", []) if isinstance(c, str)}
    except (ValueError, TypeError, AttributeError):
        return set()


def _arrow_error(e: Exception) -> str:
    return excerpt(" ".join(str(e).split()), 160)


def _read_parquet(path: Path, columns=None) -> _Table:
    """Read a Parquet run: numeric columns only (integers and floats; booleans only as
    ``<sensor>_clipped`` flags), nulls as NaN; the size is checked from the footer before
    any column is read."""
    _check_file(path, MAX_RUN_BYTES)
    try:
        f = pq.ParquetFile(path)
        schema, n_rows = f.schema_arrow, f.metadata.num_rows
    except (pa.ArrowException, OSError, ValueError, TypeError) as e:
        raise CampaignError(f"cannot read Parquet: {_arrow_error(e)}", path=path) from None
    index = _pandas_index_columns(schema)
    names = [n for n in schema.names if n not in index]
    dup = sorted({n for n, k in collections.Counter(names).items() if k > 1})
    if dup:
        raise CampaignError("duplicate column in the file", path=path, column=dup[0])
    if n_rows * max(1, len(names)) > MAX_RUN_CELLS:
        raise CampaignError(f"{n_rows} rows x {len(names)} columns, more than the {MAX_RUN_CELLS} cells a run may "
                            f"have", path=path)
    wanted = [n for n in names if columns is None or n in columns]
    for n in wanted:
        t = schema.field(n).type
        flag = n.endswith("_clipped") and pa.types.is_boolean(t)
        if not (pa.types.is_integer(t) or pa.types.is_floating(t) or flag):
            what = "boolean (only a <sensor>_clipped flag may be)" if pa.types.is_boolean(t) else excerpt(str(t), 40)
            raise CampaignError(f"column type {what} is not numeric; expected integers or floats", path=path,
                                column=n)
    try:
        table = f.read(columns=wanted, use_pandas_metadata=False)
        out = {n: table.column(n).cast(pa.float64(), safe=False).to_numpy(zero_copy_only=False) for n in wanted}
    except (pa.ArrowException, OSError, ValueError, TypeError) as e:
        raise CampaignError(f"cannot read Parquet: {_arrow_error(e)}", path=path) from None
    return _Table({n: np.asarray(v, dtype=float) for n, v in out.items()}, None)


def _check_axes(table: _Table, path: Path, meta: CampaignMeta):
    """Check the time, distance and speed columns; returns (time, distance | None, speed | None).

    Every command reads runs through here, so they all refuse the same corrupted axes."""
    cols = table.columns
    if "time" not in cols:
        raise CampaignError("missing required column 'time'", path=path, column="time")
    if meta.kind == "in_service" and "distance" not in cols and "speed" not in cols:
        raise CampaignError("an in-service run needs a 'distance' or a 'speed' column", path=path, column="distance")
    t = cols["time"]
    if t.size < 2:
        raise CampaignError("fewer than two samples", path=path, column="time")

    def refuse(message, name, row):
        raise CampaignError(message + table.row_word(row), path=path, column=name, **table.where(row))

    for name, limit, unit in (("time", MAX_ABS_TIME, "s"), ("distance", MAX_ABS_DISTANCE, "m")):
        x = cols.get(name)
        if x is None:
            continue
        if not np.isfinite(x).all():
            row = int(np.argmax(~np.isfinite(x)))
            refuse(f"{name} is missing or not finite ({float(x[row])!r})", name, row)
        if (np.abs(x) > limit).any():
            row = int(np.argmax(np.abs(x) > limit))
            refuse(f"{name} {x[row]:g} {unit} is beyond the plausible +-{limit:g} {unit}", name, row)
    dt = np.diff(t)
    if (dt <= 0).any():
        row = int(np.argmax(dt <= 0)) + 1
        refuse(f"time not strictly increasing ({float(t[row - 1])!r} then {float(t[row])!r})", "time", row)
    distance = cols.get("distance")
    if distance is not None:
        dd = np.diff(distance)
        if (dd < 0).any():
            row = int(np.argmax(dd < 0)) + 1
            refuse(f"distance decreases ({float(distance[row - 1])!r} then {float(distance[row])!r})", "distance", row)
        span, duration = float(distance[-1] - distance[0]), float(t[-1] - t[0])
        if span > MAX_SPEED * duration:
            row = int(np.argmax(dd)) + 1
            refuse(f"distance advances {span:g} m in {duration:g} s, faster than {MAX_SPEED:g} m/s (the largest "
                   f"step ends here)", "distance", row)
    speed = cols.get("speed")
    if speed is not None:
        finite = np.isfinite(speed)
        if not finite.any():
            if distance is None:
                raise CampaignError("speed column has no valid sample and there is no distance column", path=path,
                                    column="speed")
            speed = None  # an empty optional column: distance alone locates the run
        else:
            if np.isinf(speed).any():
                refuse(f"infinite speed ({float(speed[np.argmax(np.isinf(speed))])!r})", "speed",
                       int(np.argmax(np.isinf(speed))))
            if distance is None and not finite.all():
                refuse("speed is missing, and without a distance column the run's position there is unknown",
                       "speed", int(np.argmax(~finite)))
            if (speed[finite] < 0).any():
                row = int(np.argmax(np.nan_to_num(speed) < 0))
                refuse(f"negative speed ({float(speed[row])!r})", "speed", row)
            if (speed[finite] > MAX_SPEED).any():
                row = int(np.argmax(np.nan_to_num(speed) > MAX_SPEED))
                refuse(f"speed {speed[row]:g} m/s is above the plausible {MAX_SPEED:g} m/s", "speed", row)
    step, nominal = float(np.median(dt)), 1.0 / meta.sampling_rate
    if abs(step / nominal - 1.0) > RATE_TOLERANCE:
        raise CampaignError(f"the median time step {step:.6g} s does not match campaign.toml's [sampling] rate = "
                            f"{meta.sampling_rate:g} Hz ({nominal:.6g} s)", path=path, column="time",
                            key="sampling.rate")
    return t, distance, speed


def read_run_file(path: Path, meta: CampaignMeta) -> Run:
    """Read and check one run file (CSV or Parquet) and convert it to SI units."""
    path = Path(path)
    table = _read_csv(path) if path.suffix.lower() == ".csv" else _read_parquet(path)
    cols = table.columns
    names = list(cols)
    declared = {s.name for s in meta.sensors}
    known = declared | {"time", "distance", "speed"} | {f"{n}_clipped" for n in declared}
    for c in names:
        if c not in known:
            near = difflib.get_close_matches(c, sorted(declared), n=1) if len(c) <= 100 else []
            hint = f"; did you mean '{near[0]}'?" if near else ""
            raise CampaignError(f"unknown column, not declared in campaign.toml [[sensors]]{hint}", path=path,
                                column=c)
    for s in meta.sensors:
        if s.name not in cols:
            raise CampaignError("missing column for sensor declared in campaign.toml", path=path, column=s.name)
    t, distance, speed = _check_axes(table, path, meta)
    dt = np.diff(t)
    channels, valid = {}, {}
    for s in meta.sensors:
        raw = cols[s.name]
        if np.isinf(raw).any():
            row = int(np.argmax(np.isinf(raw)))
            raise CampaignError(f"sample is not finite ({float(raw[row])!r}); use an empty cell or nan for a missing "
                                f"sample" + table.row_word(row), path=path, column=s.name, **table.where(row))
        ok = ~np.isnan(raw)
        clip_name = f"{s.name}_clipped"
        clip = cols.get(clip_name)
        if clip is not None:
            bad = ~np.isnan(clip) & (clip != 0.0) & (clip != 1.0)
            if bad.any():
                row = int(np.argmax(bad))
                raise CampaignError(f"clipped flags must be 0 or 1, got {float(clip[row])!r}" + table.row_word(row),
                                    path=path, column=clip_name, **table.where(row))
            ok &= ~(clip == 1.0)
        if not ok.any():  # nothing left to analyse: all missing, or all flagged clipped
            raise CampaignError("channel has no valid sample (all NaN, empty or flagged clipped)", path=path,
                                column=s.name)
        with np.errstate(over="ignore", under="ignore"):
            si = raw * s.si_factor
        lost = np.isinf(si) | ((si == 0) & (raw != 0))  # NaN stays NaN and compares False
        if lost.any():
            row = int(np.argmax(lost))
            raise CampaignError(f"sample {raw[row]:g} times the scale and unit factor {s.si_factor:g} is not finite "
                                f"and non-zero in SI units" + table.row_word(row), path=path, column=s.name,
                                **table.where(row))
        channels[s.name] = si
        valid[s.name] = ok

    nominal_dt = 1.0 / meta.sampling_rate
    gap_idx = np.flatnonzero(dt > GAP_FACTOR * nominal_dt)
    gaps = tuple(Gap(float(t[i]), float(t[i + 1])) for i in gap_idx)
    edges = np.concatenate([[0], gap_idx + 1, [t.size]])
    blocks = tuple((int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]))
    return Run(path.stem, path, t, channels, valid, blocks, gaps, distance, speed)


# ------------------------------------------------------------------------------- tracks
#: [m] a level column beyond this is not a longitudinal level (mm to cm) nor even an altitude.
MAX_ABS_LEVEL = 1.0e4


@dataclass(frozen=True)
class TrackRecording:
    name: str
    path: Path
    distance: np.ndarray  # [m]
    level: np.ndarray  # [m]
    band: str  # D1 | D2 | raw


def read_track_file(path: Path) -> TrackRecording:
    path = Path(path)
    table = _read_csv(path)  # checks the file before anything is read
    band = "raw"
    with open(path, "r", encoding="utf-8-sig", errors="replace") as f:  # -sig: a BOM is not part of the line
        first = f.readline(200)
    m = re.match(r'^#\s*band\s*=\s*"?([A-Za-z0-9]+)"?', first.strip())
    if m:
        band = m.group(1)
        if band not in TRACK_BANDS:
            raise CampaignError(f"unknown band {_q(band)}; expected one of {', '.join(TRACK_BANDS)}", path=path,
                                line=1)
    cols = table.columns
    for c in ("distance", "level"):
        if c not in cols:
            raise CampaignError(f"missing required column '{c}'", path=path, column=c)
    d, z = cols["distance"], cols["level"]
    if d.size < 2:
        raise CampaignError(f"a track recording needs at least two rows, found {d.size}", path=path)
    for c, v, limit in (("distance", d, MAX_ABS_DISTANCE), ("level", z, MAX_ABS_LEVEL)):
        if not np.isfinite(v).all():
            row = int(np.argmax(~np.isfinite(v)))
            raise CampaignError("missing or non-finite value", path=path, column=c, **table.where(row))
        if (np.abs(v) > limit).any():
            row = int(np.argmax(np.abs(v) > limit))
            raise CampaignError(f"{v[row]:g} m is beyond the plausible +-{limit:g} m", path=path, column=c,
                                **table.where(row))
    if (np.diff(d) <= 0).any():
        row = int(np.argmax(np.diff(d) <= 0)) + 1
        raise CampaignError("distance not strictly increasing", path=path, column="distance", **table.where(row))
    return TrackRecording(path.stem, path, d, z, band)


# ----------------------------------------------------------------------------- campaign
@dataclass(frozen=True)
class Campaign:
    root: Path
    meta: CampaignMeta
    run_paths: tuple[Path, ...]
    track_paths: tuple[Path, ...]

    @property
    def run_ids(self) -> tuple[str, ...]:
        return tuple(p.stem for p in self.run_paths)

    def read_run(self, run_id: str) -> Run:
        for p in self.run_paths:
            if p.stem == run_id:
                return read_run_file(p, self.meta)
        raise KeyError(f"no run {run_id!r} in {self.root}")

    def iter_runs(self) -> Iterator[Run]:
        """Runs one at a time, in file-name order (streaming)."""
        for p in self.run_paths:
            yield read_run_file(p, self.meta)

    def tracks(self) -> list[TrackRecording]:
        return [read_track_file(p) for p in self.track_paths]

    def run_summary(self, path: Path) -> dict:
        """Checked time, distance and speed of a run, reading only those columns (for
        planning a streaming pass without holding the sensor data)."""
        path = Path(path)
        axes = ("time", "distance", "speed")
        if path.suffix.lower() == ".parquet":
            table = _read_parquet(path, columns=axes)
        else:
            full = _read_csv(path)
            table = _Table({k: v for k, v in full.columns.items() if k in axes}, full.lines)
        t, distance, speed = _check_axes(table, path, self.meta)
        return {k: v for k, v in (("time", t), ("distance", distance), ("speed", speed)) if v is not None}


#: TOML nesting deeper than this is refused: campaign.toml nests three levels, and the
#: parser recurses once per level (thousands of levels exhaust Python's stack).
MAX_TOML_DEPTH = 32
_DIGITS = re.compile(r"\d{1000,}")


def _toml_line(text: str, pos: int) -> int:
    return text.count("\n", 0, pos) + 1


def _too_deep(text: str) -> int | None:
    """Line where brackets and braces first nest deeper than MAX_TOML_DEPTH, counted
    over the text as a whole (strings included: it only places an error message)."""
    depth = 0
    for m in re.finditer(r"[\[\]{}]", text):
        depth += 1 if m.group() in "[{" else -1
        if depth > MAX_TOML_DEPTH:
            return _toml_line(text, m.start())
    return None


def _load_toml(path: Path, *, root: Path | None) -> dict:
    _check_file(path, MAX_TOML_BYTES, root=root)
    data = _read_bytes(path, MAX_TOML_BYTES)
    if data.startswith(_BOM):
        data = data[len(_BOM):]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise CampaignError("not UTF-8 text", path=path, line=data[:e.start].count(b"\n") + 1) from None
    text = text.replace("\r\n", "\n").replace("\r", "\n")  # CR alone ends lines as in the run files
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        m = re.search(r"line (\d+)", str(e))  # tomllib says "at end of document" for a cut file
        line = int(m.group(1)) if m else text.count("\n") + 1
        raise CampaignError(f"not valid TOML: {excerpt(e, 120)}", path=path, line=line) from None
    except RecursionError:
        raise CampaignError(f"arrays or tables nested deeper than {MAX_TOML_DEPTH} levels", path=path,
                            line=_too_deep(text) or 1) from None
    except ValueError:  # an integer of thousands of digits (Python's int conversion limit)
        m = _DIGITS.search(text)
        raise CampaignError("a number of thousands of digits", path=path,
                            line=_toml_line(text, m.start()) if m else None) from None


def open_campaign(root, *, allow_outside: bool = False) -> Campaign:
    """Open a campaign folder: parse and check campaign.toml, list run and track files.

    Every file listed is checked at once to be a regular file of a plausible size
    (:data:`MAX_RUN_BYTES`) whose real path lies inside ``root``; ``allow_outside=True``
    accepts links to files elsewhere (a shared drive, a read-only archive)."""
    root = Path(root)
    if not root.is_dir():
        raise CampaignError("not a campaign folder (no such directory)", path=root)
    inside = None if allow_outside else root
    toml_path = root / "campaign.toml"
    if not os.path.lexists(toml_path):
        raise CampaignError("missing campaign.toml", path=root)
    meta = parse_meta(_load_toml(toml_path, root=inside), toml_path)
    runs_dir = root / "runs"
    if not runs_dir.is_dir():
        raise CampaignError("missing runs/ folder", path=root)
    run_paths = sorted(p for p in runs_dir.iterdir() if p.suffix.lower() in (".csv", ".parquet"))
    if not run_paths:
        raise CampaignError("no run files (*.csv or *.parquet)", path=runs_dir)
    stems = [p.stem for p in run_paths]
    dups = sorted({s for s, k in collections.Counter(stems).items() if k > 1})
    if dups:
        raise CampaignError(f"run id(s) {excerpt(', '.join(dups))} present as both CSV and Parquet", path=runs_dir)
    track_dir = root / "track"
    tracks = tuple(sorted(track_dir.glob("*.csv"))) if track_dir.is_dir() else ()
    for p in (*run_paths, *tracks):
        _check_file(p, MAX_RUN_BYTES, root=inside)
    return Campaign(root, meta, tuple(run_paths), tracks)
