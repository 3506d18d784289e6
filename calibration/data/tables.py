"""Reading the columns of a run or track file, CSV or Parquet, strictly and in bounded memory.

A CSV file may end its lines in LF, CRLF or CR alone (Excel's "CSV (Macintosh)") and may
start with a UTF-8 byte order mark. Parquet columns are integers or floats; a boolean
column is accepted only as a ``<sensor>_clipped`` flag (its natural type there), never as
data. Sizes are checked before the data is parsed (:mod:`calibration.data.limits`), and a
message quotes at most a short excerpt of a file's content.
"""
from __future__ import annotations

import collections
import csv
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from .errors import CampaignError, excerpt
from .files import BOM, check_file, read_bytes
from .limits import MAX_COLUMNS, MAX_RUN_BYTES, MAX_RUN_CELLS, MAX_RUN_LINES


@dataclass(frozen=True)
class Table:
    """Columns as read, and where each data row stands in the file (1-based line numbers;
    None for Parquet, where messages name the row instead)."""

    columns: dict
    lines: np.ndarray | None

    def where(self, row: int) -> dict:
        return {"line": int(self.lines[row])} if self.lines is not None else {}

    def row_word(self, row: int) -> str:
        return "" if self.lines is not None else f" (row {row})"


# a cell the fallback parser accepts: a decimal number, inf or nan, or nothing (missing)
_CELL = re.compile(rb"\s*(?:[+-]?(?:\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?|inf|infinity)|nan)?\s*",
                   re.IGNORECASE)


def read_csv(path: Path) -> Table:
    """Read a CSV run or track file strictly. A comment is a line whose first non-blank
    character is '#'; blank lines are skipped; every other line after the header must have
    the header's number of fields; cells are numbers, empty or nan. Lines end in LF, CRLF
    or CR; a UTF-8 byte order mark is skipped. Time and memory are linear in the size."""
    data = read_bytes(path, MAX_RUN_BYTES)
    if data.startswith(BOM):
        data = data[len(BOM):]
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
        return Table({n: np.empty(0) for n in names}, lines)
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
    return Table(columns, lines)


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


def read_parquet(path: Path, columns=None) -> Table:
    """Read a Parquet run: numeric columns only (integers and floats; booleans only as
    ``<sensor>_clipped`` flags), nulls as NaN; the size is checked from the footer before
    any column is read. ``columns``: read only these (those present), default all."""
    check_file(path, MAX_RUN_BYTES)
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
    return Table({n: np.asarray(v, dtype=float) for n, v in out.items()}, None)
