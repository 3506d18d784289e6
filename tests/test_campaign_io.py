"""Campaign format v1: what is read, how units are converted, and how bad input is refused.

Every malformed case goes through the real command line: exit code 2, a message naming the
file and the column, line or key, and no output file written.
"""
from __future__ import annotations

import shutil
import tomllib

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import tomli_w

from railcal.cli import main
from calibration.data.campaign import open_campaign
from calibration.data.outputs import CampaignWriter
from calibration.data.errors import CampaignError
from calibration.data.units import STANDARD_GRAVITY

from campaign_edits import identify_rejects, replace_in_toml, rewrite_run, run_cli, set_cell
from conftest import tiny_columns, tiny_meta


# ------------------------------------------------------------------------- reading
def test_units_and_scale_are_applied_once_at_read_time(tiny_campaign):
    run = open_campaign(tiny_campaign).read_run("run_a")
    raw = tiny_columns()
    np.testing.assert_allclose(run.channels["bogie1_acc_z"], raw["bogie1_acc_z"] * STANDARD_GRAVITY)
    # gyro: scale 2.0, then deg/s -> rad/s
    np.testing.assert_allclose(run.channels["bogie1_gyro_pitch"], raw["bogie1_gyro_pitch"] * 2.0 * np.pi / 180)


def test_csv_and_parquet_runs_read_identically(tmp_path):
    cols = tiny_columns()
    for fmt in ("csv", "parquet"):
        with CampaignWriter(tmp_path / fmt, tiny_meta(), fmt=fmt) as w:
            w.write_run("run_a", cols)
            w.commit()
    a = open_campaign(tmp_path / "csv").read_run("run_a")
    b = open_campaign(tmp_path / "parquet").read_run("run_a")
    for name in a.channels:
        np.testing.assert_allclose(a.channels[name], b.channels[name], rtol=1e-8)
    np.testing.assert_allclose(a.time, b.time)


def test_gaps_are_reported_and_split_the_run_never_interpolated(tiny_campaign):
    cols = tiny_columns()
    keep = np.ones(cols["time"].size, bool)
    keep[150:180] = False  # 0.3 s missing
    root = tiny_campaign.parent / "gappy"
    with CampaignWriter(root, tiny_meta()) as w:
        w.write_run("run_a", {k: v[keep] for k, v in cols.items()})
        w.commit()
    run = open_campaign(root).read_run("run_a")
    assert len(run.gaps) == 1
    assert run.gaps[0].after_time == pytest.approx(1.49) and run.gaps[0].before_time == pytest.approx(1.80)
    assert run.blocks == ((0, 150), (150, 370))
    assert len(run) == 370


def test_missing_time_names_the_line(tiny_campaign, tmp_path, capsys):
    set_cell(tiny_campaign, 5, 0, "nan")
    identify_rejects(tiny_campaign, tmp_path, capsys, r"line 6", r"column 'time'", "time is missing")


def test_missing_and_clipped_samples_are_marked_invalid(tiny_campaign):
    cols = tiny_columns()
    cols["bogie1_acc_z"][10] = np.nan
    cols["bogie1_acc_z_clipped"] = np.zeros(cols["time"].size)
    cols["bogie1_acc_z_clipped"][20:23] = 1
    root = tiny_campaign.parent / "clipped"
    with CampaignWriter(root, tiny_meta()) as w:
        w.write_run("run_a", cols)
        w.commit()
    run = open_campaign(root).read_run("run_a")
    assert np.flatnonzero(~run.valid["bogie1_acc_z"]).tolist() == [10, 20, 21, 22]
    assert run.valid["bogie1_gyro_pitch"].all()


def test_comment_lines_anywhere_are_skipped(tiny_campaign):
    rewrite_run(tiny_campaign, lambda lines: ["# logger export", lines[0], "# note", *lines[1:]])
    assert len(open_campaign(tiny_campaign).read_run("run_a")) == 400


# ---------------------------------------------------------------- malformed input
def test_missing_sensor_column(tiny_campaign, tmp_path, capsys):
    rewrite_run(tiny_campaign, lambda lines: [",".join(c for c in ln.split(",")[:-1]) for ln in lines])
    identify_rejects(tiny_campaign, tmp_path, capsys, r"run_a\.csv", r"column 'bogie1_gyro_pitch'", "missing column")


def test_unknown_column_names_the_column_and_the_likely_sensor(tiny_campaign, tmp_path, capsys):
    rewrite_run(tiny_campaign, lambda lines: [lines[0].replace("bogie1_acc_z", "bogie1_acc_Z"), *lines[1:]])
    identify_rejects(tiny_campaign, tmp_path, capsys, r"run_a\.csv", r"column 'bogie1_acc_Z'", "unknown column",
                     "did you mean 'bogie1_acc_z'")


def test_non_increasing_time_names_the_line(tiny_campaign, tmp_path, capsys):
    def swap(lines):
        lines = list(lines)
        lines[6], lines[7] = lines[7], lines[6]  # data rows 6 and 7 (file lines 7 and 8)
        return lines
    rewrite_run(tiny_campaign, swap)
    identify_rejects(tiny_campaign, tmp_path, capsys, r"run_a\.csv", r"line 8", r"column 'time'",
                     "not strictly increasing")


def test_unknown_unit_names_the_key(tiny_campaign, tmp_path, capsys):
    replace_in_toml(tiny_campaign, 'unit = "g"', 'unit = "furlong"')
    identify_rejects(tiny_campaign, tmp_path, capsys, r"campaign\.toml", r"key 'sensors\[0\]\.unit'",
                     "unknown unit 'furlong'")


def test_unit_of_the_wrong_quantity_is_refused(tiny_campaign, tmp_path, capsys):
    replace_in_toml(tiny_campaign, 'unit = "g"', 'unit = "deg/s"')
    identify_rejects(tiny_campaign, tmp_path, capsys, r"key 'sensors\[0\]\.unit'", "not a unit of acceleration")


def test_all_nan_channel_names_the_column(tiny_campaign, tmp_path, capsys):
    rewrite_run(tiny_campaign, lambda lines: [lines[0]] + [",".join(ln.split(",")[:3] + ["", ln.split(",")[4]])
                                                           for ln in lines[1:]])
    identify_rejects(tiny_campaign, tmp_path, capsys, r"run_a\.csv", r"column 'bogie1_acc_z'", "no valid sample")


def test_sensor_declared_twice_is_inconsistent(tiny_campaign, tmp_path, capsys):
    replace_in_toml(tiny_campaign, 'name = "bogie1_gyro_pitch"', 'name = "bogie1_acc_z"')
    identify_rejects(tiny_campaign, tmp_path, capsys, r"campaign\.toml", r"key 'sensors\[1\]\.name'",
                     "declared twice")


def test_non_numeric_cell_names_line_and_column(tiny_campaign, tmp_path, capsys):
    set_cell(tiny_campaign, 11, 3, "abc")
    identify_rejects(tiny_campaign, tmp_path, capsys, r"run_a\.csv", r"line 12", r"column 'bogie1_acc_z'",
                     "'abc' is not a number")


def test_ragged_row_names_the_file_line(tiny_campaign, tmp_path, capsys):
    def spoil(lines):
        lines = ["# comment shifts the numbering", *lines]
        lines[21] = lines[21] + ",1.0"
        return lines
    rewrite_run(tiny_campaign, spoil)
    identify_rejects(tiny_campaign, tmp_path, capsys, r"run_a\.csv", r"line 22", "fields")


def test_malformed_toml_names_the_line(tiny_campaign, tmp_path, capsys):
    replace_in_toml(tiny_campaign, 'kind = "in_service"', 'kind = in_service')
    identify_rejects(tiny_campaign, tmp_path, capsys, r"campaign\.toml", r"line 2", "not valid TOML")


def test_inverted_prior_bounds_are_infeasible(tiny_campaign, tmp_path, capsys):
    replace_in_toml(tiny_campaign, "low = 36850.0", "low = 41000.0")
    identify_rejects(tiny_campaign, tmp_path, capsys, r"key 'priors\.m_v'", "infeasible")


def test_decreasing_distance_names_the_line(tiny_campaign, tmp_path, capsys):
    set_cell(tiny_campaign, 31, 1, "0.5")
    identify_rejects(tiny_campaign, tmp_path, capsys, r"line 32", r"column 'distance'", "decreases")


def test_in_service_run_needs_distance_or_speed(tiny_campaign, tmp_path, capsys):
    rewrite_run(tiny_campaign, lambda lines: [",".join([c for i, c in enumerate(ln.split(",")) if i not in (1, 2)])
                                              for ln in lines])
    identify_rejects(tiny_campaign, tmp_path, capsys, r"run_a\.csv", "needs a 'distance' or a 'speed' column")


def test_parquet_text_column_is_refused(tmp_path, capsys):
    root = tmp_path / "pq"
    with CampaignWriter(root, tiny_meta(), fmt="parquet") as w:
        w.write_run("run_a", tiny_columns())
        w.commit()
    df = pd.read_parquet(root / "runs" / "run_a.parquet")
    df["bogie1_acc_z"] = df["bogie1_acc_z"].astype(str)
    pq.write_table(pa.Table.from_pandas(df), root / "runs" / "run_a.parquet")
    identify_rejects(root, tmp_path, capsys, r"run_a\.parquet", r"column 'bogie1_acc_z'", "not numeric")


def test_missing_campaign_toml_and_missing_folder(tiny_campaign, tmp_path, capsys):
    identify_rejects(tmp_path / "nowhere", tmp_path, capsys, "nowhere", "no such directory")
    (tiny_campaign / "campaign.toml").unlink()
    identify_rejects(tiny_campaign, tmp_path, capsys, "missing campaign.toml")


def test_synth_refuses_to_overwrite_and_leaves_the_folder_intact(tiny_campaign, capsys):
    before = sorted(p.name for p in tiny_campaign.rglob("*"))
    code, _, err = run_cli(["synth", "in-service", tiny_campaign, "--journeys", "1", "--length-km", "5", "--quiet"],
                           capsys)
    assert code == 2 and "already exists" in err and str(tiny_campaign) in err
    assert sorted(p.name for p in tiny_campaign.rglob("*")) == before


def test_synth_with_unknown_effect_writes_nothing(tmp_path, capsys):
    out = tmp_path / "x"
    code, _, err = run_cli(["synth", "in-service", out, "--effect", "gremlins=3", "--quiet"], capsys)
    assert code == 2 and "unknown effect 'gremlins'" in err
    assert not out.exists() and not list(tmp_path.iterdir())


def test_failed_writer_leaves_no_partial_folder(tmp_path):
    root = tmp_path / "half"
    with pytest.raises(RuntimeError):
        with CampaignWriter(root, tiny_meta()) as w:
            w.write_run("run_a", tiny_columns())
            raise RuntimeError("simulated crash mid-write")
    assert not root.exists() and not list(tmp_path.iterdir())


def test_argument_errors_exit_2(capsys):
    code, _, err = run_cli(["modes", "--param", "m_v=heavy"], capsys)
    assert code == 2 and "m_v" in err
    with pytest.raises(SystemExit) as e:
        main(["identify"])
    assert e.value.code == 2
    capsys.readouterr()


# ------------------------------------------------ regressions found in review
def test_short_row_is_refused_not_padded_with_nan(tiny_campaign, tmp_path, capsys):
    rewrite_run(tiny_campaign, lambda lines: [*lines[:4], "0.04,1.2", *lines[5:]])
    identify_rejects(tiny_campaign, tmp_path, capsys, r"line 5", "expected 5 comma-separated fields")


def test_indented_comment_lines_keep_line_numbers_right(tiny_campaign, tmp_path, capsys):
    def spoil(lines):
        lines = [lines[0], "   # indented comment", *lines[1:]]
        cells = lines[3].split(",")
        cells[0] = "nan"  # data row 2 is now file line 4
        lines[3] = ",".join(cells)
        return lines
    rewrite_run(tiny_campaign, spoil)
    identify_rejects(tiny_campaign, tmp_path, capsys, r"line 4", "time is missing")


def test_duplicate_header_is_named_at_its_own_line(tiny_campaign, tmp_path, capsys):
    rewrite_run(tiny_campaign, lambda lines: ["# exported", lines[0] + ",speed", *[ln + ",1" for ln in lines[1:]]])
    identify_rejects(tiny_campaign, tmp_path, capsys, r"line 2", "duplicate column")


def test_non_utf8_bytes_in_a_data_row_are_refused(tiny_campaign, tmp_path, capsys):
    path = tiny_campaign / "runs" / "run_a.csv"
    data = path.read_bytes().split(b"\n")
    data[7] = data[7].replace(b"0", b"\xff", 1)
    path.write_bytes(b"\n".join(data))
    identify_rejects(tiny_campaign, tmp_path, capsys, r"run_a\.csv", r"line 8", "not UTF-8")


def test_infinite_time_is_refused(tiny_campaign, tmp_path, capsys):
    set_cell(tiny_campaign, 400, 0, "inf")
    identify_rejects(tiny_campaign, tmp_path, capsys, r"line 401", r"column 'time'", "not finite")


def test_empty_speed_column_falls_back_to_distance_and_without_distance_is_refused(tiny_campaign, tmp_path,
                                                                                  capsys):
    rewrite_run(tiny_campaign, lambda lines: [lines[0]] + [",".join(c if i != 2 else "" for i, c in
                                                                    enumerate(ln.split(","))) for ln in lines[1:]])
    run = open_campaign(tiny_campaign).read_run("run_a")
    assert run.speed is None and run.distance is not None
    rewrite_run(tiny_campaign, lambda lines: [",".join(c for i, c in enumerate(ln.split(",")) if i != 1)
                                              for ln in lines])
    identify_rejects(tiny_campaign, tmp_path, capsys, r"column 'speed'", "no valid sample")


@pytest.mark.parametrize("edit, key", [
    (lambda d: d.update(priors="x"), r"key 'priors'"),
    (lambda d: d["sensors"][0].update(unit=["g"]), r"key 'sensors\[0\]\.unit'"),
    (lambda d: d["sensors"][1].update(body=3), r"key 'sensors\[1\]\.body'"),
])
def test_values_of_the_wrong_toml_type_are_refused(tiny_campaign, tmp_path, capsys, edit, key):
    toml = tiny_campaign / "campaign.toml"
    doc = tomllib.loads(toml.read_text())
    edit(doc)
    toml.write_text(tomli_w.dumps(doc))
    identify_rejects(tiny_campaign, tmp_path, capsys, r"campaign\.toml", key)


def test_too_slow_sampling_for_the_band_is_an_input_error(tiny_campaign, tmp_path, capsys):
    replace_in_toml(tiny_campaign, "rate = 100.0", "rate = 41.7")
    identify_rejects(tiny_campaign, tmp_path, capsys, r"key 'sampling\.rate'", "too slow")


def test_runs_shorter_than_a_segment_are_an_input_error(tiny_campaign, tmp_path, capsys):
    replace_in_toml(tiny_campaign, "rate = 100.0", "rate = 200.0")
    cols = tiny_columns(4000)
    cols["time"] = np.arange(4000) / 200.0
    cols["distance"] = 30.0 * cols["time"]  # 600 m
    shutil.rmtree(tiny_campaign / "runs")
    (tiny_campaign / "runs").mkdir()
    pd.DataFrame(cols).to_csv(tiny_campaign / "runs" / "run_a.csv", index=False)
    identify_rejects(tiny_campaign, tmp_path, capsys, "no usable 2000 m segment", "longest run 600 m")


def test_campaign_without_usable_sensors_is_an_input_error(tiny_campaign, tmp_path, capsys):
    toml = tiny_campaign / "campaign.toml"
    text = toml.read_text().replace('direction = "z"', 'direction = "y"').replace('direction = "pitch"',
                                                                                   'direction = "yaw"')
    toml.write_text(text)
    identify_rejects(tiny_campaign, tmp_path, capsys, r"key 'sensors'", "nothing the in-service identification")


def test_negative_seed_is_an_argument_error(capsys):
    with pytest.raises(SystemExit) as e:
        main(["synth", "in-service", "x", "--seed", "-1"])
    assert e.value.code == 2 and "seed must be >= 0" in capsys.readouterr().err


def test_track_recording_with_a_single_row_is_refused(tiny_campaign):
    from calibration.data.campaign import read_track_file

    (tiny_campaign / "track").mkdir()
    path = tiny_campaign / "track" / "t.csv"
    path.write_text('# band = "D1"\ndistance,level\n100.0,0.001\n')
    with pytest.raises(CampaignError, match="at least two rows"):
        read_track_file(path)
