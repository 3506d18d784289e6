"""Plausibility and size limits of the campaign reader, each with where its value comes from.

Each keeps a corrupted or hostile value from reaching the analyses, where it would cost
hours or give a wrong answer without a word; input beyond one is refused with a
:class:`~calibration.data.errors.CampaignError` (exit 2). docs/campaign-format.md lists them.
"""
from __future__ import annotations

# ------------------------------------------------------------------------- file sizes
#: campaign.toml is refused above this size before it is parsed: a campaign with hundreds
#: of sensors and priors is tens of kB.
MAX_TOML_BYTES = 1 << 20
#: TOML nesting deeper than this is refused: campaign.toml nests three levels, and the
#: parser recurses once per level (thousands of levels exhaust Python's stack).
MAX_TOML_DEPTH = 32
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
#: A settings or result file a command reads besides a campaign (calibration JSON, targets
#: and priors TOML, a truth file) is refused above this size: such files are kB to a few MB.
MAX_INPUT_BYTES = 64 << 20

# ---------------------------------------------------------------------- campaign.toml
#: [Hz] loggers of vehicle dynamics record between a few Hz (GPS) and tens of kHz (acoustics).
RATE_RANGE = (1.0, 1.0e5)
#: [m] every sensor position coordinate: 1 km bounds any placement on or beside a vehicle.
MAX_POSITION = 1.0e3
#: [m] plausible [vehicle] geometry, (low, high) of each key: bogie_semi_spacing is half
#: the bogie-centre distance, and that distance runs 2-30 m, from short tram sections to
#: 27 m freight wagons; semi_wheelbase is half a bogie wheelbase, and wheelbases run 1-5 m,
#: from tram bogies to three-axle locomotive bogies; length 2-40 m; width 1-5 m (the widest
#: loading gauges are under 4 m); height 1-8 m above the rail (double-stack container cars:
#: 6.1 m).
GEOMETRY_RANGES = {"bogie_semi_spacing": (1.0, 15.0), "semi_wheelbase": (0.5, 2.5), "length": (2.0, 40.0),
                   "width": (1.0, 5.0), "height": (1.0, 8.0), "windowed_length": (1.0, 40.0)}

# -------------------------------------------------------------------------- run files
#: [m/s] 720 km/h, above the wheel-on-rail speed record (574.8 km/h, 2007).
MAX_SPEED = 200.0
#: [m] 100 000 km: a position along any railway line is below 1e7 m.
MAX_ABS_DISTANCE = 1.0e8
#: [s] Unix time in seconds is 1.8e9 today; a time beyond 1e10 s (317 years) is not in seconds.
MAX_ABS_TIME = 1.0e10
#: The median time step of a run must match 1 / [sampling] rate within this fraction: the
#: analyses filter and resample at the nominal rate, so a rate off by more shifts every
#: identified frequency by as much (logger clocks agree with their rate to ppm).
RATE_TOLERANCE = 0.02

# ------------------------------------------------------------------------ track files
#: [m] a level column beyond this is not a longitudinal level (mm to cm) nor even an altitude.
MAX_ABS_LEVEL = 1.0e4
