"""Campaign input that is hostile or corrupted (issue 29): huge or deeply nested TOML values,
overflowing scales, odd Parquet types, implausible geometry and motion, special files, links
from outside, line endings. Each is refused through the real command line with exit code 2,
a message naming where, in bounded time, and nothing written.
"""
from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import shutil

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from campaign_edits import identify_rejects, replace_in_toml, rewrite_run, run_cli, set_cell
from conftest import tiny_columns, tiny_meta

from calibration.data.campaign import open_campaign
from calibration.data.errors import CampaignError
from calibration.data.outputs import CampaignWriter


@contextlib.contextmanager
def deadline(seconds):
    """Fail a test that would hang (a quadratic reader, a blocking read) instead of hanging the suite."""
    def expire(signum, frame):
        raise TimeoutError(f"still running after {seconds} s")
    old = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def write_parquet_run(tmp_path, edit):
    """A Parquet twin of the tiny campaign whose run table went through ``edit(table)``."""
    root = tmp_path / "pq"
    with CampaignWriter(root, tiny_meta(), fmt="parquet") as w:
        w.write_run("run_a", tiny_columns())
        w.commit()
    path = root / "runs" / "run_a.parquet"
    pq.write_table(edit(pq.read_table(path)), path)
    return root


@pytest.mark.parametrize("value", ["1" * 400, "9" * 5000])
def test_huge_toml_integer_is_refused_naming_the_key(tiny_campaign, tmp_path, capsys, value):
    replace_in_toml(tiny_campaign, "rate = 100.0", f"rate = {value}")
    identify_rejects(tiny_campaign, tmp_path, capsys, r"campaign\.toml", r"sampling\.rate|line \d+")


@pytest.mark.parametrize("nested", ["[" * 5000 + "]" * 5000, "{a = " * 3000 + "1" + "}" * 3000])
def test_deeply_nested_toml_is_refused(tiny_campaign, tmp_path, capsys, nested):
    toml = tiny_campaign / "campaign.toml"
    toml.write_text(toml.read_text() + f"\nextra = {nested}\n")
    identify_rejects(tiny_campaign, tmp_path, capsys, r"campaign\.toml", "nest")


def test_scale_that_overflows_the_unit_conversion_is_refused(tiny_campaign, tmp_path, capsys):
    replace_in_toml(tiny_campaign, "scale = 1.0", "scale = 1e308")  # x 9.81 for g: no finite factor
    identify_rejects(tiny_campaign, tmp_path, capsys, r"key 'sensors\[0\]\.scale'", "not finite")


def test_sample_that_overflows_after_scale_names_line_and_column(tiny_campaign, tmp_path, capsys):
    replace_in_toml(tiny_campaign, "scale = 1.0", "scale = 1e300")
    set_cell(tiny_campaign, 17, 3, "1e10")
    identify_rejects(tiny_campaign, tmp_path, capsys, r"line 18", r"column 'bogie1_acc_z'", "not finite")


def test_infinite_sample_is_refused_not_taken_as_missing(tiny_campaign, tmp_path, capsys):
    set_cell(tiny_campaign, 9, 4, "-inf")
    identify_rejects(tiny_campaign, tmp_path, capsys, r"line 10", r"column 'bogie1_gyro_pitch'", "not finite")


def test_fully_clipped_channel_is_refused_like_an_all_nan_one(tiny_campaign, tmp_path, capsys):
    rewrite_run(tiny_campaign, lambda lines: [lines[0] + ",bogie1_acc_z_clipped", *[ln + ",1" for ln in lines[1:]]])
    identify_rejects(tiny_campaign, tmp_path, capsys, r"run_a\.csv", r"column 'bogie1_acc_z'", "no valid sample")


def test_parquet_boolean_column_is_refused(tmp_path, capsys):
    def to_bool(table):
        i = table.column_names.index("bogie1_acc_z")
        return table.set_column(i, "bogie1_acc_z", pa.array(np.arange(table.num_rows) % 2 == 0))
    root = write_parquet_run(tmp_path, to_bool)
    identify_rejects(root, tmp_path, capsys, r"run_a\.parquet", r"column 'bogie1_acc_z'", "bool")


def test_parquet_timestamp_time_column_is_refused(tmp_path, capsys):
    def to_timestamp(table):
        stamps = pa.array((np.arange(table.num_rows) * 10).astype("datetime64[ms]"))
        return table.set_column(table.column_names.index("time"), "time", stamps)
    root = write_parquet_run(tmp_path, to_timestamp)
    identify_rejects(root, tmp_path, capsys, r"run_a\.parquet", r"column 'time'", "timestamp")


@pytest.mark.parametrize("old, new, key", [
    ("bogie_semi_spacing = 8.0", "bogie_semi_spacing = 1e6", "bogie_semi_spacing"),
    ("bogie_semi_spacing = 8.0", "bogie_semi_spacing = -8.0", "bogie_semi_spacing"),
    ("semi_wheelbase = 1.25", "semi_wheelbase = 0.0", "semi_wheelbase"),
    ("semi_wheelbase = 1.25", "semi_wheelbase = 9.0", "semi_wheelbase"),
])
def test_implausible_geometry_is_refused_naming_the_key(tiny_campaign, tmp_path, capsys, old, new, key):
    replace_in_toml(tiny_campaign, old, new)
    identify_rejects(tiny_campaign, tmp_path, capsys, r"campaign\.toml", rf"key 'vehicle\.{key}'")


def test_semi_wheelbase_must_be_shorter_than_the_bogie_semi_spacing(tiny_campaign, tmp_path, capsys):
    replace_in_toml(tiny_campaign, "bogie_semi_spacing = 8.0", "bogie_semi_spacing = 1.2")
    identify_rejects(tiny_campaign, tmp_path, capsys, r"key 'vehicle\.semi_wheelbase'", "below")


def test_the_windowed_middle_must_be_shorter_than_the_carbody(tiny_campaign, tmp_path, capsys):
    replace_in_toml(tiny_campaign, "semi_wheelbase = 1.25",
                    "semi_wheelbase = 1.25\nlength = 20.0\nwindowed_length = 20.0")
    identify_rejects(tiny_campaign, tmp_path, capsys, r"key 'vehicle\.windowed_length'", "below")


@pytest.mark.parametrize("column, value, pattern", [
    (2, "-3.0", "negative"),
    (2, "1e6", "above"),
    (1, "1e300", "distance"),
])
def test_implausible_speed_or_distance_is_refused(tiny_campaign, tmp_path, capsys, column, value, pattern):
    set_cell(tiny_campaign, 50, column, value)
    identify_rejects(tiny_campaign, tmp_path, capsys, r"run_a\.csv", r"line 51", pattern)


def test_missing_speed_without_distance_is_refused(tiny_campaign, tmp_path, capsys):
    rewrite_run(tiny_campaign, lambda lines: [",".join(c for i, c in enumerate(ln.split(",")) if i != 1)
                                              for ln in lines])
    set_cell(tiny_campaign, 60, 1, "")
    identify_rejects(tiny_campaign, tmp_path, capsys, r"line 61", r"column 'speed'", "missing")


def test_time_steps_must_match_the_nominal_rate(tiny_campaign, tmp_path, capsys):
    replace_in_toml(tiny_campaign, "rate = 100.0", "rate = 500.0")
    err = identify_rejects(tiny_campaign, tmp_path, capsys, r"key 'sampling\.rate'", "time step")
    assert "run_a.csv" in err


def test_run_that_is_a_fifo_is_refused_at_once(tiny_campaign, tmp_path, capsys):
    os.mkfifo(tiny_campaign / "runs" / "run_b.csv")
    with deadline(30):  # reading it would block for ever
        identify_rejects(tiny_campaign, tmp_path, capsys, r"run_b\.csv", "not a regular file")


def test_folder_named_like_a_run_is_refused(tiny_campaign, tmp_path, capsys):
    (tiny_campaign / "runs" / "run_b.csv").mkdir()
    identify_rejects(tiny_campaign, tmp_path, capsys, r"run_b\.csv", "not a regular file")


def test_run_linked_from_outside_the_campaign_is_refused_unless_allowed(tiny_campaign, tmp_path, capsys):
    outside = tmp_path / "elsewhere.csv"
    shutil.move(tiny_campaign / "runs" / "run_a.csv", outside)
    (tiny_campaign / "runs" / "run_a.csv").symlink_to(outside)
    identify_rejects(tiny_campaign, tmp_path, capsys, r"run_a\.csv", "outside the campaign folder")
    assert len(open_campaign(tiny_campaign, allow_outside=True).read_run("run_a")) == 400


def test_link_to_a_device_is_refused(tiny_campaign, tmp_path, capsys):
    (tiny_campaign / "runs" / "run_b.csv").symlink_to("/dev/zero")
    with pytest.raises(CampaignError, match="not a regular file"):
        open_campaign(tiny_campaign, allow_outside=True)


def test_file_far_larger_than_a_run_is_refused_without_reading_it(tiny_campaign, tmp_path, capsys):
    with open(tiny_campaign / "runs" / "run_b.csv", "wb") as f:
        f.truncate(20 * 2 ** 30)  # 20 GiB, sparse: costs no disk
    identify_rejects(tiny_campaign, tmp_path, capsys, r"run_b\.csv", "larger than")


def test_cr_only_line_endings_read_like_lf(tiny_campaign):
    path = tiny_campaign / "runs" / "run_a.csv"
    expected = open_campaign(tiny_campaign).read_run("run_a")
    path.write_bytes(path.read_bytes().replace(b"\n", b"\r"))
    run = open_campaign(tiny_campaign).read_run("run_a")
    np.testing.assert_array_equal(run.time, expected.time)
    np.testing.assert_array_equal(run.channels["bogie1_acc_z"], expected.channels["bogie1_acc_z"])


def test_cr_only_file_of_100k_fields_is_refused_at_once(tiny_campaign, tmp_path, capsys):
    """CR-only line endings made the whole file one header line, and the header check was
    quadratic in its fields: a 100k-field header took minutes. Such a header is refused
    at once now (and the checks are linear below the limit)."""
    path = tiny_campaign / "runs" / "run_a.csv"
    path.write_bytes(b",".join(b"c%d" % i for i in range(100_000)) + b"\r" + b",".join([b"1"] * 100_000) + b"\r")
    with deadline(30):  # a quadratic reader would not end
        identify_rejects(tiny_campaign, tmp_path, capsys, r"run_a\.csv", r"line 1\b", "100000 columns")


@pytest.mark.parametrize("unit", ["m/s^2", "m/s2", "m/s²"])
def test_acceleration_unit_spellings_are_accepted_alike(tiny_campaign, unit):
    replace_in_toml(tiny_campaign, 'unit = "g"', f'unit = "{unit}"')
    run = open_campaign(tiny_campaign).read_run("run_a")
    np.testing.assert_allclose(run.channels["bogie1_acc_z"], tiny_columns()["bogie1_acc_z"])


def test_messages_quote_only_a_short_excerpt_of_a_cell(tiny_campaign, tmp_path, capsys):
    set_cell(tiny_campaign, 3, 3, "x" * 5000)
    err = identify_rejects(tiny_campaign, tmp_path, capsys, r"line 4", r"column 'bogie1_acc_z'", "not a number")
    assert "x" * 61 not in err and len(err) < 400


def test_messages_quote_only_a_short_excerpt_of_a_header(tiny_campaign, tmp_path, capsys):
    rewrite_run(tiny_campaign, lambda lines: [lines[0] + ",\x1b[2J" + "y" * 5000, *[ln + ",1" for ln in lines[1:]]])
    err = identify_rejects(tiny_campaign, tmp_path, capsys, r"run_a\.csv", "unknown column")
    assert "y" * 61 not in err and "\x1b" not in err and len(err) < 400


def test_messages_quote_only_a_short_excerpt_of_a_toml_value(tiny_campaign, tmp_path, capsys):
    replace_in_toml(tiny_campaign, 'unit = "g"', f'unit = "{"z" * 5000}"')
    err = identify_rejects(tiny_campaign, tmp_path, capsys, r"key 'sensors\[0\]\.unit'", "unknown unit")
    assert "z" * 61 not in err and len(err) < 400


def test_toml_cut_inside_a_string_names_the_last_line(tiny_campaign, tmp_path, capsys):
    toml = tiny_campaign / "campaign.toml"
    text = toml.read_text()
    toml.write_text(text[:text.index('"railcal-campaign/1"') + 5])  # tomllib: "at end of document"
    identify_rejects(tiny_campaign, tmp_path, capsys, r"campaign\.toml", r"line 1\b", "not valid TOML")


def test_header_of_many_duplicate_names_is_checked_in_linear_time(tiny_campaign, tmp_path, capsys):
    path = tiny_campaign / "runs" / "run_a.csv"
    path.write_bytes(b"time" + b",x" * 9_000 + b"\n")
    with deadline(30):
        err = identify_rejects(tiny_campaign, tmp_path, capsys, r"line 1\b", "duplicate column")
    assert len(err) < 400


@pytest.mark.parametrize("value, pattern", [("0.5", "time not strictly increasing"), ("nan", "time is missing")])
def test_every_command_refuses_a_corrupted_time_column_alike(tmp_path, capsys, value, pattern):
    """identify, calibrate, validate and diagnose all read runs through read_run_file, so
    they refuse the same corrupted axis with the same message (a campaign that each of
    them would otherwise read: axle-box, bogie and track data)."""
    from fuzz_mutants import RUN, calibration_json, write_base

    root = write_base(tmp_path / "c")
    path = root / RUN
    lines = path.read_text().split("\n")
    cells = lines[120].split(",")
    cells[0] = value
    lines[120] = ",".join(cells)
    path.write_text("\n".join(lines))
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps(calibration_json()))
    out = tmp_path / "out.json"
    messages = set()
    for args in (["identify", root], ["calibrate", root, "--runs", "1"], ["validate", root, "--calibration", cal],
                 ["diagnose", root]):
        code, _, err = run_cli([*args, "--out", out, "--quiet"], capsys)
        assert code == 2 and not out.exists(), err
        assert re.search(r"run_a\.csv, line 121, column 'time'", err) and pattern in err, err
        messages.add(err)
    assert len(messages) == 1


def test_parquet_boolean_clipped_flags_and_a_stored_pandas_index_are_read(tmp_path):
    def edit(table):
        clipped = np.zeros(table.num_rows, bool)
        clipped[[3, 4]] = True
        df = table.to_pandas()
        df["bogie1_acc_z_clipped"] = clipped
        df.index = np.arange(table.num_rows) * 7  # not a RangeIndex: stored as a column
        return pa.Table.from_pandas(df)
    run = open_campaign(write_parquet_run(tmp_path, edit)).read_run("run_a")
    assert np.flatnonzero(~run.valid["bogie1_acc_z"]).tolist() == [3, 4]
    assert len(run) == 400


@pytest.mark.parametrize("ending", [b"\r", b"\r\n"])
def test_track_band_is_read_after_a_byte_order_mark_and_any_line_ending(tiny_campaign, ending):
    from calibration.data.campaign import read_track_file

    (tiny_campaign / "track").mkdir()
    path = tiny_campaign / "track" / "t.csv"
    path.write_bytes(b"\xef\xbb\xbf" + ending.join([b'# band = "D1"', b"distance,level", b"0,0.001", b"1,0.002", b""]))
    rec = read_track_file(path)
    assert rec.band == "D1" and rec.distance.tolist() == [0.0, 1.0]


def test_small_input_files_are_checked_before_they_are_read(tmp_path):
    """For the calibration JSON and targets TOML readers (read_input_file): a device, a FIFO
    or an oversized file is refused at once instead of read for ever."""
    from calibration.data.campaign import read_input_file

    os.mkfifo(tmp_path / "cal.json")
    big = tmp_path / "big.json"
    with open(big, "wb") as f:
        f.truncate(20 * 2 ** 30)
    good = tmp_path / "good.json"
    good.write_bytes(b'\xef\xbb\xbf{"parameters": {}}')
    with deadline(30):
        for path, pattern in (("/dev/zero", "character device"), (tmp_path / "cal.json", "FIFO"),
                              (big, "larger than"), (tmp_path, "folder")):
            with pytest.raises(CampaignError, match=pattern):
                read_input_file(path)
    assert json.loads(read_input_file(good)) == {"parameters": {}}
