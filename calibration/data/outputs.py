"""Writing railcal's outputs: campaigns (synth) and JSON results, each moved into place whole.

Nothing is written half: a campaign is built in a temporary folder beside its target and a
JSON file in a temporary file beside its own, then renamed over the target.
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Mapping

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import tomli_w

from .campaign import NAME_RE, TRACK_BANDS, CampaignMeta
from .errors import CampaignError


class CampaignWriter:
    """Writes a campaign into a temporary folder beside ``root`` and moves it into place on
    :meth:`commit`; on failure (or without commit) nothing is left at ``root``."""

    def __init__(self, root, meta: CampaignMeta, *, fmt: str = "csv", overwrite: bool = False):
        self.root = Path(root)
        if fmt not in ("csv", "parquet"):
            raise ValueError(f"format must be csv or parquet, not {fmt!r}")
        if self.root.exists() and not overwrite:
            raise CampaignError("already exists; choose another output or remove it", path=self.root)
        self.root.parent.mkdir(parents=True, exist_ok=True)
        self.tmp = Path(tempfile.mkdtemp(prefix=f".{self.root.name}.partial-", dir=self.root.parent))
        self.fmt, self.meta, self.overwrite = fmt, meta, overwrite
        (self.tmp / "runs").mkdir()
        with open(self.tmp / "campaign.toml", "wb") as f:
            tomli_w.dump(meta.to_toml(), f)

    def write_run(self, run_id: str, columns: Mapping[str, np.ndarray]) -> Path:
        """Columns in the sensors' declared (raw) units; NaN for missing samples."""
        if not NAME_RE.match(run_id):
            raise ValueError(f"run id {run_id!r} must match [A-Za-z0-9_]+")
        path = self.tmp / "runs" / f"{run_id}.{self.fmt}"
        df = pd.DataFrame({k: np.asarray(v) for k, v in columns.items()})
        if self.fmt == "csv":
            df.to_csv(path, index=False, float_format="%.9g", na_rep="")
        else:
            pq.write_table(pa.Table.from_pandas(df, preserve_index=False), path, compression="zstd")
        return path

    def write_track(self, name: str, distance: np.ndarray, level: np.ndarray, band: str = "raw") -> Path:
        if band not in TRACK_BANDS:
            raise ValueError(f"band must be one of {TRACK_BANDS}")
        (self.tmp / "track").mkdir(exist_ok=True)
        path = self.tmp / "track" / f"{name}.csv"
        with open(path, "w") as f:
            f.write(f'# band = "{band}"\n')
            pd.DataFrame({"distance": distance, "level": level}).to_csv(f, index=False, float_format="%.9g")
        return path

    def commit(self) -> Path:
        if self.root.exists():
            shutil.rmtree(self.root)
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


def write_json_atomic(path, obj) -> Path:
    """Write JSON via a temporary file and rename, so a failure never leaves half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(obj, f, indent=2, allow_nan=False, default=_json_default)
            f.write("\n")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
