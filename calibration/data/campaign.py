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
  invalid per channel.
"""
from __future__ import annotations

import difflib
import io
import math
import re
import tomllib
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Mapping

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from .errors import CampaignError
from .units import BODIES, QUANTITIES, ROTATIONS, TRANSLATIONS, UNITS, si_factor

FORMAT = "railcal-campaign/1"
KINDS = ("in_service", "stationary_excitation")
NAME_RE = re.compile(r"^[A-Za-z0-9_]+$")
TRACK_BANDS = ("D1", "D2", "raw")
GAP_FACTOR = 1.5  # a time step longer than this many sampling intervals is a gap
_TOP_KEYS = {"format", "kind", "name", "vehicle", "priors", "sensors", "sampling", "excitation"}
_SENSOR_KEYS = {"name", "quantity", "unit", "body", "direction", "position", "scale"}
_GEOMETRY_KEYS = {"bogie_semi_spacing", "semi_wheelbase", "length", "width", "height"}


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


def _number(value, path, key) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise CampaignError(f"expected a finite number, got {value!r}", path=path, key=key)
    return float(value)


def _position(value, path, key) -> tuple[float, float, float]:
    if not isinstance(value, list) or len(value) != 3:
        raise CampaignError(f"expected [x, y, z] in metres, got {value!r}", path=path, key=key)
    return tuple(_number(v, path, key) for v in value)  # type: ignore[return-value]


def parse_meta(data: dict, path: Path) -> CampaignMeta:
    """Check and convert the parsed campaign.toml; ``path`` is named in every message."""
    for k in sorted(set(data) - _TOP_KEYS):
        warnings.warn(f"{path}: unknown key '{k}' ignored", stacklevel=2)
    fmt = data.get("format")
    if fmt != FORMAT:
        raise CampaignError(f"expected format = \"{FORMAT}\", got {fmt!r}", path=path, key="format")
    kind = data.get("kind")
    if kind not in KINDS:
        raise CampaignError(f"expected one of {', '.join(KINDS)}, got {kind!r}", path=path, key="kind")
    vehicle = data.get("vehicle", {})
    if not isinstance(vehicle, (dict, str)):
        raise CampaignError(f"expected a [vehicle] table or a name, got {vehicle!r}", path=path, key="vehicle")
    vehicle_name = data.get("vehicle") if isinstance(data.get("vehicle"), str) else ""
    geometry: dict[str, float] = {}
    if isinstance(vehicle, dict):
        vehicle_name = str(vehicle.get("name", vehicle_name))
        for k, v in vehicle.items():
            if k in _GEOMETRY_KEYS:
                geometry[k] = _number(v, path, f"vehicle.{k}")
                if geometry[k] <= 0:
                    raise CampaignError(f"must be > 0 m, got {v}", path=path, key=f"vehicle.{k}")
            elif k != "name":
                warnings.warn(f"{path}: unknown key 'vehicle.{k}' ignored", stacklevel=2)
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
            warnings.warn(f"{path}: unknown key '{key}.{k}' ignored", stacklevel=2)
        for k in ("name", "quantity", "unit", "body", "direction", "position"):
            if k not in s:
                raise CampaignError(f"missing '{k}'", path=path, key=key)
            if k != "position" and not isinstance(s[k], str):
                raise CampaignError(f"expected a string, got {s[k]!r}", path=path, key=f"{key}.{k}")
        name = s["name"]
        if not isinstance(name, str) or not NAME_RE.match(name):
            raise CampaignError(f"sensor name {name!r} must match [A-Za-z0-9_]+", path=path, key=f"{key}.name")
        if name in ("time", "distance", "speed") or name.endswith("_clipped"):
            raise CampaignError(f"sensor name {name!r} is reserved", path=path, key=f"{key}.name")
        if name in seen:
            raise CampaignError(f"sensor name '{name}' declared twice (also sensors[{seen[name]}])", path=path,
                                key=f"{key}.name")
        seen[name] = i
        q, unit = s["quantity"], s["unit"]
        if q not in QUANTITIES:
            raise CampaignError(f"unknown quantity {q!r}; expected one of {', '.join(QUANTITIES)}", path=path,
                                key=f"{key}.quantity")
        if unit not in UNITS:
            raise CampaignError(f"unknown unit {unit!r}; expected one of {', '.join(UNITS)}", path=path,
                                key=f"{key}.unit")
        if UNITS[unit][0] != q:
            raise CampaignError(f"unit {unit!r} is not a unit of {q}", path=path, key=f"{key}.unit")
        if s["body"] not in BODIES:
            raise CampaignError(f"unknown body {s['body']!r}; expected one of {', '.join(BODIES)}", path=path,
                                key=f"{key}.body")
        direction = s["direction"]
        allowed = ROTATIONS if q == "angular_velocity" else TRANSLATIONS
        if direction not in allowed:
            raise CampaignError(f"direction {direction!r} not valid for {q}; expected one of {', '.join(allowed)}",
                                path=path, key=f"{key}.direction")
        scale = _number(s.get("scale", 1.0), path, f"{key}.scale")
        if scale == 0:
            raise CampaignError("scale must not be zero", path=path, key=f"{key}.scale")
        sensors.append(Sensor(name, q, unit, s["body"], direction, _position(s["position"], path, f"{key}.position"),
                              scale))
    sampling = data.get("sampling")
    if not isinstance(sampling, dict) or "rate" not in sampling:
        raise CampaignError("expected [sampling] with rate [Hz]", path=path, key="sampling.rate")
    rate = _number(sampling["rate"], path, "sampling.rate")
    if rate <= 0:
        raise CampaignError(f"must be > 0 Hz, got {rate}", path=path, key="sampling.rate")
    excitation = None
    if kind == "stationary_excitation":
        ex = data.get("excitation")
        if not isinstance(ex, dict) or not isinstance(ex.get("sensor"), str):
            raise CampaignError("a stationary_excitation campaign needs [excitation] sensor = ...", path=path,
                                key="excitation")
        if ex["sensor"] not in seen:
            raise CampaignError(f"names sensor {ex['sensor']!r}, which is not declared in [[sensors]]", path=path,
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


def _read_csv(path: Path) -> _Table:
    """Read a CSV run or track file strictly. A comment is a line whose first non-blank
    character is '#'; blank lines are skipped; every other line after the header must have
    the header's number of fields; cells are numbers, empty or nan."""
    try:
        data = path.read_bytes()
    except OSError as e:
        raise CampaignError(f"cannot read: {e.strerror}", path=path) from None
    raw_lines = data.split(b"\n")
    kept, numbers = [], []
    for i, raw in enumerate(raw_lines, start=1):
        stripped = raw.strip()
        if not stripped or stripped.startswith(b"#"):
            continue
        kept.append(raw.rstrip(b"\r"))
        numbers.append(i)
    if not kept:
        raise CampaignError("no header row", path=path)
    header_line = numbers[0]
    try:
        names = [c.strip() for c in kept[0].decode("utf-8").split(",")]
    except UnicodeDecodeError:
        raise CampaignError("header is not UTF-8 text", path=path, line=header_line) from None
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise CampaignError(f"duplicate column(s) {', '.join(dup)} in the header", path=path, line=header_line)
    expected = len(names) - 1
    counts = np.fromiter((ln.count(b",") for ln in kept), int, len(kept))
    bad = np.flatnonzero(counts != expected)
    if bad.size:
        k = int(bad[0])
        raise CampaignError(f"expected {expected + 1} comma-separated fields (as the header), found {counts[k] + 1}",
                            path=path, line=numbers[k])
    lines = np.asarray(numbers[1:])
    body = b"\n".join(kept)
    try:
        body.decode("utf-8")
    except UnicodeDecodeError as e:
        line = numbers[body[:e.start].count(b"\n")]
        raise CampaignError("not UTF-8 text", path=path, line=line) from None
    try:
        # fast path: every cell a number, empty or nan
        df = pd.read_csv(io.BytesIO(body), dtype=np.float64, engine="c", na_values=["", "nan", "NaN", "NAN"],
                         keep_default_na=False, skipinitialspace=True)
    except ValueError:
        # slow path, only to say which cell is not a number
        df = pd.read_csv(io.BytesIO(body), dtype=str, engine="c", keep_default_na=False, na_filter=False)
    df.columns = [c.strip() for c in df.columns]
    return _Table(_to_float_columns(df, path, lines), lines)


def _read_parquet(path: Path, columns=None) -> _Table:
    try:
        if columns is not None:
            names = pq.read_schema(path).names
            columns = [c for c in columns if c in names]
        df = pq.read_table(path, columns=columns).to_pandas()
    except (pa.ArrowInvalid, OSError) as e:
        raise CampaignError(f"cannot read Parquet: {e}", path=path) from None
    return _Table(_to_float_columns(df, path, None), None)


def _to_float_columns(df: pd.DataFrame, path: Path, lines: np.ndarray | None) -> dict[str, np.ndarray]:
    out = {}
    for col in df.columns:
        s = df[col]
        if pd.api.types.is_float_dtype(s):
            out[col] = s.to_numpy(dtype=float)
            continue
        if lines is not None:
            text = s.str.strip()
            empty = (text == "") | (text.str.lower() == "nan")
            vals = pd.to_numeric(text.where(~empty, "nan"), errors="coerce").to_numpy(dtype=float)
            bad = np.isnan(vals) & ~empty.to_numpy()
            if bad.any():
                row = int(np.argmax(bad))
                raise CampaignError(f"'{s.iloc[row]}' is not a number (use an empty cell or nan for a missing "
                                    f"sample)", path=path, line=int(lines[row]), column=col)
        else:
            if not (pd.api.types.is_numeric_dtype(s) or pd.api.types.is_bool_dtype(s)):
                raise CampaignError(f"column type {s.dtype} is not numeric", path=path, column=col)
            vals = s.to_numpy(dtype=float, na_value=np.nan)
        out[col] = vals
    return out


def _check_axes(table: _Table, path: Path, meta: CampaignMeta):
    """Check the time, distance and speed columns; returns (time, distance | None, speed | None)."""
    cols = table.columns
    if "time" not in cols:
        raise CampaignError("missing required column 'time'", path=path, column="time")
    if meta.kind == "in_service" and "distance" not in cols and "speed" not in cols:
        raise CampaignError("an in-service run needs a 'distance' or a 'speed' column", path=path, column="distance")
    t = cols["time"]
    if t.size < 2:
        raise CampaignError("fewer than two samples", path=path, column="time")
    for name in ("time", "distance"):
        x = cols.get(name)
        if x is not None and not np.isfinite(x).all():
            row = int(np.argmax(~np.isfinite(x)))
            raise CampaignError(f"{name} is missing or not finite ({x[row]!r})" + table.row_word(row), path=path,
                                column=name, **table.where(row))
    dt = np.diff(t)
    if (dt <= 0).any():
        row = int(np.argmax(dt <= 0)) + 1
        raise CampaignError(f"time not strictly increasing ({t[row - 1]!r} then {t[row]!r})"
                            + table.row_word(row), path=path, column="time", **table.where(row))
    distance = cols.get("distance")
    if distance is not None:
        dd = np.diff(distance)
        if (dd < 0).any():
            row = int(np.argmax(dd < 0)) + 1
            raise CampaignError(f"distance decreases ({distance[row - 1]!r} then {distance[row]!r})"
                                + table.row_word(row), path=path, column="distance", **table.where(row))
    speed = cols.get("speed")
    if speed is not None:
        finite = np.isfinite(speed)
        if not finite.any():
            if distance is None:
                raise CampaignError("speed column has no valid sample and there is no distance column", path=path,
                                    column="speed")
            speed = None  # an empty optional column: distance alone locates the run
        elif (speed[finite] < 0).any() or np.isinf(speed).any():
            row = int(np.argmax(~finite & ~np.isnan(speed) | (np.nan_to_num(speed) < 0)))
            raise CampaignError(f"negative or infinite speed ({speed[row]!r})" + table.row_word(row), path=path,
                                column="speed", **table.where(row))
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
            near = difflib.get_close_matches(c, sorted(declared), n=1)
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
        ok = np.isfinite(raw)
        if not ok.any():
            raise CampaignError("channel has no valid sample (all NaN or empty)", path=path, column=s.name)
        clip = cols.get(f"{s.name}_clipped")
        if clip is not None:
            bad = ~np.isin(clip[np.isfinite(clip)], (0.0, 1.0))
            if bad.any():
                raise CampaignError("clipped flags must be 0 or 1", path=path, column=f"{s.name}_clipped")
            ok &= ~(clip == 1.0)
        channels[s.name] = raw * s.si_factor
        valid[s.name] = ok

    nominal_dt = 1.0 / meta.sampling_rate
    gap_idx = np.flatnonzero(dt > GAP_FACTOR * nominal_dt)
    gaps = tuple(Gap(float(t[i]), float(t[i + 1])) for i in gap_idx)
    edges = np.concatenate([[0], gap_idx + 1, [t.size]])
    blocks = tuple((int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]))
    return Run(path.stem, path, t, channels, valid, blocks, gaps, distance, speed)


# ------------------------------------------------------------------------------- tracks
@dataclass(frozen=True)
class TrackRecording:
    name: str
    path: Path
    distance: np.ndarray  # [m]
    level: np.ndarray  # [m]
    band: str  # D1 | D2 | raw


def read_track_file(path: Path) -> TrackRecording:
    path = Path(path)
    band = "raw"
    with open(path, "r", encoding="utf-8", errors="replace") as f:
        first = f.readline()
    m = re.match(r'^#\s*band\s*=\s*"?([A-Za-z0-9]+)"?', first.strip())
    if m:
        band = m.group(1)
        if band not in TRACK_BANDS:
            raise CampaignError(f"unknown band {band!r}; expected one of {', '.join(TRACK_BANDS)}", path=path,
                                line=1)
    table = _read_csv(path)
    cols = table.columns
    for c in ("distance", "level"):
        if c not in cols:
            raise CampaignError(f"missing required column '{c}'", path=path, column=c)
    d, z = cols["distance"], cols["level"]
    if d.size < 2:
        raise CampaignError(f"a track recording needs at least two rows, found {d.size}", path=path)
    for c, v in (("distance", d), ("level", z)):
        if not np.isfinite(v).all():
            row = int(np.argmax(~np.isfinite(v)))
            raise CampaignError("missing or non-finite value", path=path, column=c, **table.where(row))
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


def open_campaign(root) -> Campaign:
    """Open a campaign folder: parse and check campaign.toml, list run and track files."""
    root = Path(root)
    if not root.is_dir():
        raise CampaignError("not a campaign folder (no such directory)", path=root)
    toml_path = root / "campaign.toml"
    if not toml_path.is_file():
        raise CampaignError("missing campaign.toml", path=root)
    try:
        with open(toml_path, "rb") as f:
            data = tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        m = re.search(r"line (\d+)", str(e))
        raise CampaignError(f"not valid TOML: {e}", path=toml_path, line=int(m.group(1)) if m else None) from None
    except UnicodeDecodeError:
        raise CampaignError("not UTF-8 text", path=toml_path) from None
    meta = parse_meta(data, toml_path)
    runs_dir = root / "runs"
    if not runs_dir.is_dir():
        raise CampaignError("missing runs/ folder", path=root)
    run_paths = sorted(p for p in runs_dir.iterdir() if p.suffix.lower() in (".csv", ".parquet"))
    if not run_paths:
        raise CampaignError("no run files (*.csv or *.parquet)", path=runs_dir)
    stems = [p.stem for p in run_paths]
    dups = sorted({s for s in stems if stems.count(s) > 1})
    if dups:
        raise CampaignError(f"run id(s) {', '.join(dups)} present as both CSV and Parquet", path=runs_dir)
    track_dir = root / "track"
    tracks = tuple(sorted(track_dir.glob("*.csv"))) if track_dir.is_dir() else ()
    return Campaign(root, meta, tuple(run_paths), tracks)
