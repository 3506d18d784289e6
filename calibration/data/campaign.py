"""Measurement campaigns (shared/spec/campaign-format.md, v1): open a campaign folder.

This module stays the data layer's documented entry point: it re-exports the public names
of the modules that do the work (listed in ``__all__``), so callers import them from here.

Reading is strict: anything malformed raises :class:`CampaignError` naming the file and
the line, column or key. Unit conversion and each sensor's ``scale`` are applied once, at
read time. Runs are read one at a time (:meth:`Campaign.iter_runs`) so a campaign of any
size streams through in the memory of one run. The work is done in

* :mod:`.metadata`: the types of campaign.toml and reading it (:func:`parse_meta`);
* :mod:`.runs`: run files, their checks and gaps (:func:`read_run_file`);
* :mod:`.tracks`: track recordings (:func:`read_track_file`);
* :mod:`.tables`: the strict CSV and Parquet readers under both;
* :mod:`.files`: regular files of bounded size only (:func:`read_input_file`);
* :mod:`.limits`: every plausibility and size limit, with where its value comes from;
* :mod:`.units`: the units and their one conversion to SI.

Hostile or corrupted input is refused before it costs time or memory: only regular files
inside the campaign folder are read (``open_campaign(allow_outside=True)`` lifts the
second condition), sizes are checked before a byte is read, values are held to stated
physical plausibility ranges, and every message quotes at most a short excerpt of a
file's content (:func:`~calibration.data.errors.excerpt`).
"""
from __future__ import annotations

import collections
import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from .errors import CampaignError, excerpt
from .files import check_file, hash_file, read_input_file
from .limits import (GEOMETRY_RANGES, MAX_ABS_DISTANCE, MAX_ABS_LEVEL, MAX_ABS_TIME, MAX_COLUMNS, MAX_INPUT_BYTES,
                     MAX_POSITION, MAX_RUN_BYTES, MAX_RUN_CELLS, MAX_RUN_LINES, MAX_SPEED, MAX_TOML_BYTES,
                     MAX_TOML_DEPTH, RATE_RANGE, RATE_TOLERANCE)
from .metadata import FORMAT, KINDS, NAME_RE, CampaignMeta, Excitation, Prior, Sensor, load_toml, parse_meta
from .runs import GAP_FACTOR, Gap, Run, read_run_axes, read_run_file
from .tracks import TRACK_BANDS, TrackRecording, read_track_file

__all__ = [
    # the campaign folder (this module)
    "Campaign", "open_campaign",
    # campaign.toml (metadata)
    "FORMAT", "KINDS", "NAME_RE", "CampaignMeta", "Excitation", "Prior", "Sensor", "parse_meta",
    # run and track files (runs, tracks, files)
    "GAP_FACTOR", "Gap", "Run", "read_run_file", "TRACK_BANDS", "TrackRecording", "read_track_file",
    "read_input_file",
    # plausibility and size limits (limits)
    "GEOMETRY_RANGES", "MAX_ABS_DISTANCE", "MAX_ABS_LEVEL", "MAX_ABS_TIME", "MAX_COLUMNS", "MAX_INPUT_BYTES",
    "MAX_POSITION", "MAX_RUN_BYTES", "MAX_RUN_CELLS", "MAX_RUN_LINES", "MAX_SPEED", "MAX_TOML_BYTES",
    "MAX_TOML_DEPTH", "RATE_RANGE", "RATE_TOLERANCE",
    # the error every reader raises (errors)
    "CampaignError",
]


@dataclass(frozen=True)
class Campaign:
    """An opened campaign folder: its checked campaign.toml and the run and track files
    found (each checked to be a readable regular file, none read yet)."""

    root: Path
    meta: CampaignMeta
    run_paths: tuple[Path, ...]
    track_paths: tuple[Path, ...]

    @property
    def run_ids(self) -> tuple[str, ...]:
        return tuple(p.stem for p in self.run_paths)

    def fingerprint(self) -> str:
        """SHA-256 of campaign.toml and every run and track file, names and bytes: a result
        made from this campaign carries it, so that one made from another campaign (or from
        this one before its files changed) is refused where it is read back."""
        h = hashlib.sha256()
        for path in (self.root / "campaign.toml", *sorted(self.run_paths), *sorted(self.track_paths)):
            h.update(path.name.encode() + b"\0")
            hash_file(h, path)
            h.update(b"\0")
        return "sha256:" + h.hexdigest()

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
        return read_run_axes(path, self.meta)


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
    meta = parse_meta(load_toml(toml_path, root=inside), toml_path)
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
        check_file(p, MAX_RUN_BYTES, root=inside)
    return Campaign(root, meta, tuple(run_paths), tracks)
