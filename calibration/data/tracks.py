"""Track recordings (track/*.csv): measured vertical longitudinal level along the line."""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import CampaignError, quoted
from .limits import MAX_ABS_DISTANCE, MAX_ABS_LEVEL
from .tables import read_csv

#: The wavelength bands a recording may be filtered to, as the campaign format names them
#: (D1 3-25 m, D2 25-70 m: the bands of EN 13848-1), or "raw"; given by the file's optional
#: first line ``# band = "D1"``.
TRACK_BANDS = ("D1", "D2", "raw")
#: [m] The wavelengths of the bands D1 and D2 (EN 13848-1).
BAND_WAVELENGTHS_M = {"D1": (3.0, 25.0), "D2": (25.0, 70.0)}


@dataclass(frozen=True)
class TrackRecording:
    name: str
    path: Path
    distance: np.ndarray  # [m]
    level: np.ndarray  # [m]
    band: str  # D1 | D2 | raw

    def __post_init__(self):
        if self.band not in TRACK_BANDS:
            raise ValueError(f"TrackRecording.band: unknown band {self.band!r}; expected one of "
                             f"{', '.join(TRACK_BANDS)}")
        if np.shape(self.distance) != np.shape(self.level):
            raise ValueError(f"TrackRecording.level: {np.size(self.level)} samples for {np.size(self.distance)} "
                             f"distances")


def read_track_file(path: Path) -> TrackRecording:
    path = Path(path)
    table = read_csv(path)  # checks the file before anything is read
    band = "raw"
    with open(path, "r", encoding="utf-8-sig", errors="replace") as f:  # -sig: a BOM is not part of the line
        first = f.readline(200)
    m = re.match(r'^#\s*band\s*=\s*"?([A-Za-z0-9]+)"?', first.strip())
    if m:
        band = m.group(1)
        if band not in TRACK_BANDS:
            raise CampaignError(f"unknown band {quoted(band)}; expected one of {', '.join(TRACK_BANDS)}", path=path,
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
