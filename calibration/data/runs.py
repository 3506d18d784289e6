"""Run files (runs/*.csv or *.parquet): read, check and convert to SI units.

* A run-file column that is neither declared in campaign.toml nor a known column
  (``time``, ``distance``, ``speed``, ``<sensor>_clipped``) is an error, not a warning:
  a misspelt sensor column would otherwise silently drop that sensor's data.
* Gaps (a time step over :data:`GAP_FACTOR` sampling intervals) are reported and split the
  run into contiguous blocks; nothing is interpolated. NaN and clipped samples are marked
  invalid per channel; a channel with no valid sample left is an error.
* A NaN speed sample is a missing Doppler fix, accepted where a ``distance`` column
  locates the run; without one it would leave the run's position undefined, so it is an
  error. The time, distance and speed checks live in :func:`check_axes`, which every
  reader of a run goes through.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np

from .errors import CampaignError
from .limits import MAX_ABS_DISTANCE, MAX_ABS_TIME, MAX_SPEED, RATE_TOLERANCE
from .metadata import AXES, CampaignMeta
from .tables import Table, read_csv, read_parquet

#: A time step longer than this many nominal sampling intervals is a gap: halfway between a
#: regular step (1) and a step over one dropped sample (2), so clock jitter of under half
#: an interval is not a gap and a single missing sample is.
GAP_FACTOR = 1.5


@dataclass(frozen=True)
class Gap:
    after_time: float  # [s] last sample before the gap
    before_time: float  # [s] first sample after it

    def __post_init__(self):
        if not (math.isfinite(self.after_time) and math.isfinite(self.before_time)
                and self.after_time < self.before_time):
            raise ValueError(f"Gap.before_time: {self.before_time!r} [s] must be finite and after after_time = "
                             f"{self.after_time!r}")

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


def check_axes(table: Table, path: Path, meta: CampaignMeta):
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
    table = read_csv(path) if path.suffix.lower() == ".csv" else read_parquet(path)
    cols = table.columns
    names = list(cols)
    declared = {s.name for s in meta.sensors}
    known = declared | set(AXES) | {f"{n}_clipped" for n in declared}
    for c in names:
        if c not in known:
            near = difflib.get_close_matches(c, sorted(declared), n=1) if len(c) <= 100 else []
            hint = f"; did you mean '{near[0]}'?" if near else ""
            raise CampaignError(f"unknown column, not declared in campaign.toml [[sensors]]{hint}", path=path,
                                column=c)
    for s in meta.sensors:
        if s.name not in cols:
            raise CampaignError("missing column for sensor declared in campaign.toml", path=path, column=s.name)
    t, distance, speed = check_axes(table, path, meta)
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


def read_run_axes(path: Path, meta: CampaignMeta) -> dict[str, np.ndarray]:
    """Checked time, distance and speed of a run, reading only those columns (for planning
    a streaming pass without holding the sensor data); an absent axis is left out."""
    path = Path(path)
    if path.suffix.lower() == ".parquet":
        table = read_parquet(path, columns=AXES)
    else:
        full = read_csv(path)
        table = Table({k: v for k, v in full.columns.items() if k in AXES}, full.lines)
    t, distance, speed = check_axes(table, path, meta)
    return {k: v for k, v in (("time", t), ("distance", distance), ("speed", speed)) if v is not None}
