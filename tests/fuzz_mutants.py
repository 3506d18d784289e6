"""Mutated campaigns for tests/test_campaign_fuzz.py.

A small valid in-service campaign (:func:`write_base`: six sensors as the truth simulator
lays them out, 7 s at 100 Hz, a D1 track recording) is copied and spoiled in one way per
mutant. The rule: mutant ``i`` belongs to class ``CLASSES[i % len(CLASSES)]`` and draws
every choice it makes (which file, row, column, value) from
``numpy.random.default_rng([SEED, i])``, so a failing mutant is rebuilt from its number.
"""
from __future__ import annotations

import os
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import tomli_w

from calibration.data.campaign import CampaignMeta, Prior, Sensor
from calibration.data.outputs import CampaignWriter
from calibration.models.vehicles import INTERCITY_TRAILER

SEED = 29
RATE = 100.0  # [Hz]
N_ROWS = 700  # 7 s
SPEED = 100.0  # [m/s]: 700 m, enough for validate to compare 200 m over the track
SENSORS = (
    Sensor("axle1_left_acc_z", "acceleration", "g", "axle1", "z", (9.18, 0.75, 0.5)),
    Sensor("axle1_right_acc_z", "acceleration", "g", "axle1", "z", (9.18, -0.75, 0.5)),
    Sensor("axle2_left_acc_z", "acceleration", "g", "axle2", "z", (6.88, 0.75, 0.5)),
    Sensor("axle2_right_acc_z", "acceleration", "m/s^2", "axle2", "z", (6.88, -0.75, 0.5)),
    Sensor("bogie1_acc_z", "acceleration", "g", "bogie1", "z", (8.48, 0.6, 0.7)),
    Sensor("bogie1_gyro_pitch", "angular_velocity", "deg/s", "bogie1", "pitch", (8.48, 0.6, 0.7), 2.0),
)
RUN = "runs/run_a.csv"
TOML = "campaign.toml"
TRACK = "track/level_d1.csv"


def base_meta() -> CampaignMeta:
    return CampaignMeta("in_service", "fuzz base", "test car", SENSORS, RATE,
                        {"bogie_semi_spacing": 8.03, "semi_wheelbase": 1.15, "length": 23.0},
                        {"m_v": Prior(38747.0, 36850.0, 40644.0), "k_s": Prior(720000.0, 540000.0, 900000.0)})


def base_columns(n: int = N_ROWS) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(SEED)
    t = np.arange(n) / RATE
    cols = {"time": t, "distance": 100.0 + SPEED * t, "speed": np.full(n, SPEED)}
    for s in SENSORS:
        cols[s.name] = (1.0 if s.unit == "g" else 0.0) + 0.01 * rng.standard_normal(n)
    cols["bogie1_acc_z_clipped"] = (np.arange(n) % 97 == 5).astype(float)
    return cols


def write_base(root: Path, fmt: str = "csv") -> Path:
    with CampaignWriter(root, base_meta(), fmt=fmt) as w:
        w.write_run("run_a", base_columns())
        w.commit()
    (root / "track").mkdir()
    x = np.arange(0.0, 1000.0, 0.25)
    level = 1e-3 * np.sin(2 * np.pi * x / 12.0)
    rows = "".join(f"{a:.2f},{b:.6e}\n" for a, b in zip(x, level))
    (root / TRACK).write_text('# band = "D1"\ndistance,level\n' + rows)
    return root


def calibration_json() -> dict:
    """A minimal calibration result that `railcal validate` reads."""
    return {"format": "railcal-calibration/1", "model": "car2d", "parameters": INTERCITY_TRAILER.as_dict()}


# ------------------------------------------------------------------ helpers
def _lines(path: Path) -> list[str]:
    return path.read_text().split("\n")


def _write_lines(path: Path, lines: list[str]) -> None:
    path.write_text("\n".join(lines))


def _cell(root: Path, rng, column: int | None = None, value: str = "") -> str:
    """Replace one data cell of the run; returns where."""
    path = root / RUN
    lines = _lines(path)
    n_fields = len(lines[0].split(","))
    row = int(rng.integers(1, len(lines) - 1))
    col = int(rng.integers(0, n_fields)) if column is None else column
    cells = lines[row].split(",")
    cells[col] = value
    lines[row] = ",".join(cells)
    _write_lines(path, lines)
    return f"line {row + 1} column {lines[0].split(',')[col]} = {value[:20]!r}"


def _toml_doc(root: Path) -> dict:
    return tomllib.loads((root / TOML).read_text())


def _write_toml(root: Path, doc: dict) -> None:
    (root / TOML).write_text(tomli_w.dumps(doc))


def _pick(rng, seq):
    return seq[int(rng.integers(len(seq)))]


def _any_file(root: Path, rng) -> Path:
    return root / _pick(rng, [RUN, TOML, TRACK])


# ------------------------------------------------------------------ classes
def truncated(root: Path, rng) -> str:
    path = _any_file(root, rng)
    data = path.read_bytes()
    cut = int(rng.integers(0, len(data)))
    path.write_bytes(data[:cut])
    return f"{path.name} cut at byte {cut} of {len(data)}"


def columns(root: Path, rng) -> str:
    path = root / RUN
    lines = _lines(path)
    header = lines[0].split(",")
    k = int(rng.integers(len(header)))
    how = _pick(rng, ["drop", "duplicate", "rename", "case", "extra", "swap", "no_header", "long_row", "short_row",
                      "empty_name"])
    if how == "drop":
        lines = [",".join(c for i, c in enumerate(ln.split(",")) if i != k) if ln else ln for ln in lines]
    elif how == "duplicate":
        header[k] = header[(k + 1) % len(header)]
        lines[0] = ",".join(header)
    elif how == "rename":
        header[k] = "".join(_pick(rng, list("abcxyz_019")) for _ in range(int(rng.integers(1, 12))))
        lines[0] = ",".join(header)
    elif how == "case":
        header[k] = header[k].upper()
        lines[0] = ",".join(header)
    elif how == "extra":
        lines = [lines[0] + ",extra_sensor"] + [ln + ",1.0" if ln else ln for ln in lines[1:]]
    elif how == "swap":
        j = (k + 1 + int(rng.integers(len(header) - 1))) % len(header)
        header[k], header[j] = header[j], header[k]
        lines[0] = ",".join(header)
    elif how == "no_header":
        lines = lines[1:]
    elif how == "long_row":
        r = int(rng.integers(1, len(lines) - 1))
        lines[r] += ",0.5"
    elif how == "short_row":
        r = int(rng.integers(1, len(lines) - 1))
        lines[r] = lines[r].rsplit(",", 1)[0]
    else:
        header[k] = " "
        lines[0] = ",".join(header)
    _write_lines(path, lines)
    return f"{how} column {k}"


UNIT_SPELLINGS = ("m/s2", "m/s²", "m/s^2", "g", "deg/s", "furlong", "", "G", "m/s**2", "M/S^2", "rad/s", 9.81)
SCALES = (0.0, -1.0, 1e308, 1e-320, 1e300, "x", True, 10 ** 400, 2.5)


def units(root: Path, rng) -> str:
    doc = _toml_doc(root)
    i = int(rng.integers(len(doc["sensors"])))
    if rng.uniform() < 0.6:
        unit = _pick(rng, UNIT_SPELLINGS)
        doc["sensors"][i]["unit"] = unit
        what = f"sensors[{i}].unit = {unit!r}"
    else:
        scale = _pick(rng, SCALES)
        doc["sensors"][i]["scale"] = scale
        what = f"sensors[{i}].scale = {str(scale)[:20]}"
    _write_toml(root, doc)
    return what


NON_FINITE = ("nan", "inf", "-inf", "", "NaN", "1e400", "-1e400", "Infinity", " nan ", "NAN")


def non_finite(root: Path, rng) -> str:
    return "; ".join(_cell(root, rng, value=_pick(rng, NON_FINITE)) for _ in range(int(rng.integers(1, 4))))


def time_order(root: Path, rng) -> str:
    path = root / RUN
    lines = _lines(path)
    data = lines[1:-1]
    how = _pick(rng, ["swap", "repeat", "reverse", "step_back", "shuffle_block", "equal_time"])
    r = int(rng.integers(0, len(data) - 10))
    if how == "swap":
        data[r], data[r + 1] = data[r + 1], data[r]
    elif how == "repeat":
        data.insert(r, data[r])
    elif how == "reverse":
        data.reverse()
    elif how == "step_back":
        cells = data[r + 1].split(",")
        cells[0] = str(float(cells[0]) - 1.0)
        data[r + 1] = ",".join(cells)
    elif how == "shuffle_block":
        block = data[r:r + 10]
        rng.shuffle(block)
        data[r:r + 10] = block
    else:
        cells = data[r + 1].split(",")
        cells[0] = data[r].split(",")[0]
        data[r + 1] = ",".join(cells)
    _write_lines(path, [lines[0], *data, lines[-1]])
    return f"{how} at data row {r}"


HUGE = ("1e300", "-1e308", "1" * 400, "-" + "9" * 400, "1e30", "1.7976931348623157e308", "4e9")


def huge_values(root: Path, rng) -> str:
    if rng.uniform() < 0.5:
        return _cell(root, rng, value=_pick(rng, HUGE))
    doc = _toml_doc(root)
    value = _pick(rng, [1e300, 10 ** 400, -1e300, 1e6, 10 ** 30])
    where = _pick(rng, ["sampling.rate", "vehicle.bogie_semi_spacing", "vehicle.length", "priors.m_v.high",
                        "priors.m_v.nominal", "sensors.position"])
    if where == "sensors.position":
        doc["sensors"][0]["position"][int(rng.integers(3))] = value
    else:
        *parents, leaf = where.split(".")
        d = doc
        for p in parents:
            d = d[p]
        d[leaf] = value
    _write_toml(root, doc)
    return f"{where} = {str(value)[:20]}"


def sampling(root: Path, rng) -> str:
    how = _pick(rng, ["rate", "gaps", "jitter", "decimate", "rate_slightly_off"])
    if how in ("rate", "rate_slightly_off"):
        doc = _toml_doc(root)
        factor = _pick(rng, [0.2, 0.5, 2.0, 5.0, 0.4]) if how == "rate" else float(rng.uniform(0.99, 1.01))
        doc["sampling"]["rate"] = RATE * factor
        _write_toml(root, doc)
        return f"rate x {factor:.4g}"
    path = root / RUN
    lines = _lines(path)
    data = lines[1:-1]
    if how == "gaps":
        keep = rng.uniform(size=len(data)) > float(rng.uniform(0.05, 0.6))
        data = [d for d, k in zip(data, keep) if k]
    elif how == "jitter":
        out = []
        for d in data:
            cells = d.split(",")
            cells[0] = repr(float(cells[0]) + float(rng.uniform(-0.4, 0.4)) / RATE)
            out.append(",".join(cells))
        data = out
    else:
        data = data[::int(rng.integers(2, 6))]
    _write_lines(path, [lines[0], *data, ""])
    return how


def zero_length(root: Path, rng) -> str:
    how = _pick(rng, ["empty_run", "header_only", "one_row", "two_rows", "empty_toml", "no_runs", "empty_track",
                      "comments_only"])
    path = root / RUN
    lines = _lines(path)
    if how == "empty_run":
        path.write_bytes(b"")
    elif how == "header_only":
        _write_lines(path, [lines[0], ""])
    elif how == "one_row":
        _write_lines(path, lines[:2] + [""])
    elif how == "two_rows":
        _write_lines(path, lines[:3] + [""])
    elif how == "empty_toml":
        (root / TOML).write_bytes(b"")
    elif how == "no_runs":
        path.unlink()
    elif how == "empty_track":
        (root / TRACK).write_bytes(b"")
    else:
        _write_lines(path, ["# nothing but comments", "   # here", ""])
    return how


def binary_garbage(root: Path, rng) -> str:
    path = _any_file(root, rng)
    data = path.read_bytes()
    junk = rng.integers(0, 256, size=int(rng.integers(1, 4000)), dtype=np.uint8).tobytes()
    how = _pick(rng, ["replace", "insert", "append", "nul"])
    if how == "replace":
        data = junk
    elif how == "insert":
        at = int(rng.integers(0, len(data)))
        data = data[:at] + junk + data[at:]
    elif how == "append":
        data = data + junk
    else:
        at = int(rng.integers(0, len(data)))
        data = data[:at] + b"\x00" * int(rng.integers(1, 50)) + data[at:]
    path.write_bytes(data)
    return f"{how} {len(junk)} bytes in {path.name}"


def encodings(root: Path, rng) -> str:
    path = _any_file(root, rng)
    text = path.read_text()
    how = _pick(rng, ["bom", "utf16", "utf16_bom_le", "latin1_header", "latin1_toml", "utf32", "bom_twice"])
    if how == "bom":
        path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    elif how == "bom_twice":
        path.write_bytes(b"\xef\xbb\xbf\xef\xbb\xbf" + text.encode())
    elif how == "utf16":
        path.write_bytes(text.encode("utf-16"))
    elif how == "utf16_bom_le":
        path.write_bytes(text.encode("utf-16-le"))
    elif how == "utf32":
        path.write_bytes(text.encode("utf-32"))
    elif how == "latin1_header":
        run = root / RUN
        lines = _lines(run)
        lines[0] = lines[0].replace("bogie1_acc_z,", "bogie1_acc_z_µ,", 1)
        run.write_bytes("\n".join(lines).encode("latin-1"))
        path = run
    else:
        toml = root / TOML
        toml.write_bytes(toml.read_text().replace("fuzz base", "Zürich–München").encode("latin-1", "replace"))
        path = toml
    return f"{how} {path.name}"


def line_endings(root: Path, rng) -> str:
    path = _pick(rng, [root / RUN, root / RUN, root / TOML, root / TRACK])
    data = path.read_bytes()
    how = _pick(rng, ["crlf", "cr", "mixed", "no_final_newline", "blank_lines", "trailing_spaces", "cr_crlf"])
    if how == "crlf":
        data = data.replace(b"\n", b"\r\n")
    elif how == "cr":
        data = data.replace(b"\n", b"\r")
    elif how == "mixed":
        parts = data.split(b"\n")
        data = b"".join(p + _pick(rng, [b"\n", b"\r\n", b"\r"]) for p in parts[:-1]) + parts[-1]
    elif how == "no_final_newline":
        data = data.rstrip(b"\n")
    elif how == "blank_lines":
        data = data.replace(b"\n", b"\n\n")
    elif how == "trailing_spaces":
        data = data.replace(b"\n", b"  \n")
    else:
        data = data.replace(b"\n", b"\r\r\n")
    path.write_bytes(data)
    return f"{how} in {path.name}"


def toml(root: Path, rng) -> str:
    path = root / TOML
    text = path.read_text()
    how = _pick(rng, ["deep_arrays", "deep_tables", "huge_string", "duplicate_key", "no_sampling", "unknown_key",
                      "wrong_type", "format", "kind", "no_sensors", "garbage_line", "huge_int", "dotted_nest"])
    if how == "deep_arrays":
        n = int(rng.integers(100, 5000))
        text += f"\nextra = {'[' * n}{']' * n}\n"
    elif how == "deep_tables":
        n = int(rng.integers(100, 3000))
        text += "\nextra = " + "{a = " * n + "1" + "}" * n + "\n"
    elif how == "huge_string":
        text = text.replace('name = "fuzz base"', f'name = "{"x" * int(rng.integers(1000, 200_000))}"')
    elif how == "duplicate_key":
        text = text.replace("[sampling]\n", "[sampling]\nrate = 100.0\n")
    elif how == "no_sampling":
        doc = tomllib.loads(text)
        del doc["sampling"]
        text = tomli_w.dumps(doc)
    elif how == "unknown_key":
        text = "surprise = 1\n" + text
    elif how == "wrong_type":
        doc = tomllib.loads(text)
        key = _pick(rng, ["kind", "sensors", "sampling", "priors", "vehicle", "name"])
        doc[key] = _pick(rng, [1, [1, 2], {"x": 1}, "text", 1.5, True])
        text = tomli_w.dumps(doc)
    elif how == "format":
        text = text.replace("railcal-campaign/1", _pick(rng, ["railcal-campaign/2", "", "RAILCAL"]))
    elif how == "kind":
        text = text.replace('kind = "in_service"', _pick(rng, ['kind = "stationary"', "kind = 3"]))
    elif how == "no_sensors":
        doc = tomllib.loads(text)
        doc["sensors"] = []
        text = tomli_w.dumps(doc)
    elif how == "garbage_line":
        lines = text.split("\n")
        lines.insert(int(rng.integers(len(lines))), _pick(rng, ["= =", "[[[x]]]", "rate = ", "x = 1 2", '"']))
        text = "\n".join(lines)
    elif how == "huge_int":
        text = text.replace("rate = 100.0", "rate = " + "7" * int(rng.integers(300, 6000)))
    else:
        text += "\n" + ".".join(f"k{i}" for i in range(int(rng.integers(100, 2000)))) + " = 1\n"
    path.write_text(text)
    return how


def path_escapes(root: Path, rng, outside: Path) -> str:
    """``outside`` is a folder beside the campaign (not inside it) that the mutant may use."""
    runs = root / "runs"
    how = _pick(rng, ["symlink_out", "dev_zero", "fifo", "folder", "loop", "runs_out", "toml_out", "sparse",
                      "dangling", "symlink_in"])
    if how == "symlink_out":
        shutil.move(runs / "run_a.csv", outside / "run_a.csv")
        (runs / "run_a.csv").symlink_to(outside / "run_a.csv")
    elif how == "dev_zero":
        (runs / "run_z.csv").symlink_to("/dev/zero")
    elif how == "fifo":
        os.mkfifo(runs / "run_f.csv")
    elif how == "folder":
        (runs / "run_d.csv").mkdir()
    elif how == "loop":
        (runs / "run_l.csv").symlink_to(runs / "run_l.csv")
    elif how == "runs_out":
        shutil.move(runs, outside / "runs")
        runs.symlink_to(outside / "runs")
    elif how == "toml_out":
        shutil.move(root / TOML, outside / TOML)
        (root / TOML).symlink_to(outside / TOML)
    elif how == "sparse":
        with open(runs / "run_s.csv", "wb") as f:
            f.truncate(20 * 2 ** 30)
    elif how == "dangling":
        (runs / "run_g.csv").symlink_to(outside / "nothing.csv")
    else:  # a link that stays inside the folder is an ordinary file
        shutil.move(runs / "run_a.csv", root / "stored_run.csv")
        (runs / "run_a.csv").symlink_to(Path("..") / "stored_run.csv")
    return how


def parquet_types(root: Path, rng) -> str:
    """Mutates the Parquet base."""
    path = root / "runs" / "run_a.parquet"
    table = pq.read_table(path)
    n = table.num_rows
    name = _pick(rng, table.column_names)
    how = _pick(rng, ["bool", "string", "timestamp", "int", "decimal", "nulls", "dictionary", "struct", "list",
                      "duplicate", "truncate", "float32", "bool_clip", "date"])
    if how == "truncate":
        data = path.read_bytes()
        path.write_bytes(data[:int(rng.integers(0, len(data)))])
        return how
    col = table.column(name).to_numpy()
    arrays = {
        "bool": lambda: pa.array(col > np.median(col)),
        "string": lambda: pa.array([repr(v) for v in col]),
        "timestamp": lambda: pa.array((np.arange(n) * 10).astype("datetime64[ms]")),
        "int": lambda: pa.array(np.round(col * 1000).astype(np.int64)),
        "decimal": lambda: pa.array([None] * n, pa.decimal128(10, 3)),
        "nulls": lambda: pa.nulls(n, pa.float64()),
        "dictionary": lambda: pa.array(np.round(col, 1)).dictionary_encode(),
        "struct": lambda: pa.StructArray.from_arrays([pa.array(col)], ["v"]),
        "list": lambda: pa.array([[float(v)] for v in col]),
        "float32": lambda: pa.array(col.astype(np.float32)),
        "date": lambda: pa.array(np.arange(n).astype("datetime64[D]")),
    }
    if how == "duplicate":
        table = table.append_column(name, table.column(name))
    elif how == "bool_clip":
        name = "bogie1_acc_z_clipped"
        table = table.set_column(table.column_names.index(name), name, pa.array(table.column(name).to_numpy() == 1))
    else:
        table = table.set_column(table.column_names.index(name), name, arrays[how]())
    pq.write_table(table, path)
    return f"{how} {name}"


CLASSES = {
    "truncated": truncated, "columns": columns, "units": units, "non_finite": non_finite, "time_order": time_order,
    "huge_values": huge_values, "sampling": sampling, "zero_length": zero_length, "binary_garbage": binary_garbage,
    "encodings_bom": encodings, "line_endings": line_endings, "toml": toml, "path_escapes": path_escapes,
    "parquet_types": parquet_types,
}
