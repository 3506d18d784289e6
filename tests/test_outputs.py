"""Writing outputs without losing anything (calibration/data/outputs.py): campaign targets,
output-file checks, atomic writes with the umask's permissions, result formats."""
from __future__ import annotations

import json
import os
import stat

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402

from calibration.data.errors import InputError  # noqa: E402
from calibration.data.outputs import (RESULT_FORMATS, SYNTH_MARKER, CampaignWriter, check_campaign_output,  # noqa: E402
                                      check_outputs, read_result, save_figure, write_json_atomic, write_result)
from conftest import tiny_columns, tiny_meta  # noqa: E402


def _write(root, overwrite=False):
    with CampaignWriter(root, tiny_meta(), overwrite=overwrite) as w:
        w.write_run("run_a", tiny_columns(50))
        w.commit()
    return root


def special_files(folder):
    """A FIFO and, where allowed, a character device with /dev/null's numbers, in ``folder``:
    a regression then replaces these, never the system's own /dev/null."""
    fifo = folder / "pipe"
    os.mkfifo(fifo)
    made = [fifo]
    try:
        os.mknod(folder / "null", stat.S_IFCHR | 0o666, os.makedev(1, 3))
        made.append(folder / "null")
    except OSError:  # not root: the FIFO covers the same check
        pass
    return made


def still_special(paths):
    return all(stat.S_ISFIFO(os.stat(p).st_mode) or stat.S_ISCHR(os.stat(p).st_mode) for p in paths)


@pytest.fixture
def umask_022():
    old = os.umask(0o022)
    yield
    os.umask(old)


# ------------------------------------------------------------------ campaign targets
def test_the_current_folder_and_its_parents_are_never_a_campaign_target(tmp_path, monkeypatch):
    work = tmp_path / "work"
    work.mkdir()
    (work / "precious.txt").write_text("keep")
    monkeypatch.chdir(work)
    # a pure check for the root and home, so that a regression here cannot remove them
    for target in (".", "..", str(work), os.sep, os.path.expanduser("~")):
        with pytest.raises(InputError, match="current folder"):
            check_campaign_output(target, overwrite=True)
    with pytest.raises(InputError, match="current folder"):
        CampaignWriter(".", tiny_meta(), overwrite=True)
    assert (work / "precious.txt").read_text() == "keep"
    assert sorted(p.name for p in work.iterdir()) == ["precious.txt"]


def test_force_replaces_only_a_campaign_railcal_wrote(tmp_path):
    foreign = tmp_path / "photos"
    foreign.mkdir()
    (foreign / "a.jpg").write_text("x")
    with pytest.raises(InputError, match=f"no {SYNTH_MARKER} marker.*nothing was removed") as e:
        CampaignWriter(foreign, tiny_meta(), overwrite=True)
    assert str(foreign) in str(e.value)
    assert (foreign / "a.jpg").read_text() == "x"

    ours = _write(tmp_path / "c")
    assert (ours / SYNTH_MARKER).is_file()
    (ours / "runs" / "run_a.csv").write_text("time\n0\n")  # replaced whole, not merged
    _write(ours, overwrite=True)
    assert len((ours / "runs" / "run_a.csv").read_text().splitlines()) == 51
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c", "photos"]  # no partial, no old copy


def test_an_empty_folder_may_be_filled_and_a_file_or_link_is_refused(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    _write(empty, overwrite=True)
    assert (empty / "campaign.toml").is_file()
    (tmp_path / "f").write_text("data")
    with pytest.raises(InputError, match="not a folder"):
        CampaignWriter(tmp_path / "f", tiny_meta(), overwrite=True)
    (tmp_path / "link").symlink_to(empty)
    with pytest.raises(InputError, match="symbolic link"):
        CampaignWriter(tmp_path / "link", tiny_meta(), overwrite=True)
    assert (tmp_path / "f").read_text() == "data" and (empty / "campaign.toml").is_file()


def test_the_truth_file_beside_is_protected_like_the_folder(tmp_path):
    truth = tmp_path / "c.truth.json"
    truth.write_text("my notes")
    with pytest.raises(InputError, match="already exists"):
        check_campaign_output(tmp_path / "c")
    with pytest.raises(InputError, match="not a truth file railcal wrote"):
        check_campaign_output(tmp_path / "c", overwrite=True)
    truth.write_text(json.dumps({"format": "railcal-truth/1", "parameters": {}, "frequencies_hz": {}}))
    check_campaign_output(tmp_path / "c", overwrite=True)
    truth.unlink()
    truth.mkdir()
    with pytest.raises(InputError, match="not a regular file"):
        check_campaign_output(tmp_path / "c", overwrite=True)


def test_stale_partial_folders_of_an_interrupted_writer_are_removed_by_the_next(tmp_path):
    root = tmp_path / "c"
    w = CampaignWriter(root, tiny_meta())
    w.write_run("run_a", tiny_columns(50))  # killed here: no commit, no abort
    stale = w.tmp
    assert stale.name.startswith(".c.partial-")
    other = tmp_path / ".c.partial-notours"  # not railcal's (no marker, not empty): kept
    other.mkdir()
    (other / "x").write_text("x")
    _write(root)
    assert not stale.exists() and other.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [".c.partial-notours", "c"]


def test_a_written_campaign_is_readable_by_others_under_umask_022(tmp_path, umask_022):
    root = _write(tmp_path / "c")
    assert stat.S_IMODE(os.stat(root).st_mode) == 0o755


# -------------------------------------------------------------------- output checks
def test_output_checks_refuse_folders_devices_inputs_and_duplicates(tmp_path):
    campaign = _write(tmp_path / "C")
    cal = tmp_path / "cal.json"
    cal.write_text("{}")
    with pytest.raises(InputError, match="is a folder"):
        check_outputs([tmp_path])
    specials = special_files(tmp_path)
    for special in specials:
        with pytest.raises(InputError, match="not a regular file.*device, FIFO"):
            check_outputs([special])
    with pytest.raises(InputError, match="an input of this command") as e:
        check_outputs([campaign / "campaign.toml"], inputs=[campaign])
    assert "campaign.toml" in str(e.value)
    with pytest.raises(InputError, match="is an input of this command"):
        check_outputs([tmp_path / "sub" / ".." / "cal.json"], inputs=[cal], key="--out")
    with pytest.raises(InputError, match="written twice"):
        check_outputs([tmp_path / "a.json", tmp_path / "./a.json"])
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="not a folder"):
        check_outputs([tmp_path / "file" / "out.json"])
    assert check_outputs([tmp_path / "new" / "deeper" / "out.json", None]) == [tmp_path / "new" / "deeper" / "out.json"]
    assert still_special(specials)


# --------------------------------------------------------------------- atomic files
def test_json_and_figures_get_the_umask_permissions_not_0600(tmp_path, umask_022):
    j = write_json_atomic(tmp_path / "r.json", {"a": 1})
    assert stat.S_IMODE(os.stat(j).st_mode) == 0o644
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    ax.set(xlabel="time [s]", ylabel="level [m]")
    png = save_figure(fig, tmp_path / "p.png")
    assert stat.S_IMODE(os.stat(png).st_mode) == 0o644
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not plt.fignum_exists(fig.number)
    os.chmod(j, 0o640)  # a replaced file keeps the mode its owner gave it
    write_json_atomic(j, {"a": 2})
    assert stat.S_IMODE(os.stat(j).st_mode) == 0o640 and json.loads(j.read_text()) == {"a": 2}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.png", "r.json"]


def test_a_symlink_at_a_predictable_temporary_name_is_not_followed(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("untouched")
    for name in (".p.partial.png", ".p.png.partial", ".r.json.partial"):
        (tmp_path / name).symlink_to(victim)
    fig, _ = plt.subplots()
    save_figure(fig, tmp_path / "p.png")
    write_json_atomic(tmp_path / "r.json", [1])
    assert victim.read_text() == "untouched"
    assert (tmp_path / "p.png").is_file() and not (tmp_path / "p.png").is_symlink()


def test_writers_never_replace_a_device_or_folder(tmp_path):
    (tmp_path / "d").mkdir()
    with pytest.raises(InputError, match="not a regular file"):
        write_json_atomic(tmp_path / "d", {})
    specials = special_files(tmp_path)
    for special in specials:
        with pytest.raises(InputError, match="not a regular file"):
            write_json_atomic(special, {})
    assert still_special(specials)


# ------------------------------------------------------------------- result formats
def test_results_carry_their_format_and_readers_refuse_unknown_ones(tmp_path):
    p = write_result(tmp_path / "c.json", {"model": "car2d", "parameters": {"m_v": 1.0}}, "calibration")
    data = json.loads(p.read_text())
    assert next(iter(data)) == "format" and data["format"] == "railcal-calibration/1"
    assert read_result(p, ["calibration"])["parameters"] == {"m_v": 1.0}
    old = tmp_path / "old.json"
    old.write_text(json.dumps({"parameters": {"m_v": 1.0}}))
    assert read_result(old, ["calibration"])["parameters"] == {"m_v": 1.0}
    new = tmp_path / "new.json"
    new.write_text(json.dumps({"format": "railcal-calibration/2", "parameters": {}}))
    with pytest.raises(InputError, match="format 'railcal-calibration/2' is not one this railcal reads") as e:
        read_result(new, ["calibration", "diagnosis"])
    assert str(new) in str(e.value) and "key 'format'" in str(e.value)
    with pytest.raises(ValueError, match="cannot carry format"):
        write_result(tmp_path / "x.json", {"format": "railcal-modes/1"}, "calibration")
    assert set(RESULT_FORMATS) >= {"identification", "calibration", "validation", "diagnosis", "crosscheck",
                                   "modes", "truth"}


def test_a_campaign_written_before_the_marker_is_known_by_its_truth_file(tmp_path):
    root = _write(tmp_path / "old")
    (root / SYNTH_MARKER).unlink()
    truth = tmp_path / "old.truth.json"
    truth.write_text(json.dumps({"format": "railcal-truth/1", "campaign": "other", "parameters": {},
                                 "frequencies_hz": {}}))
    with pytest.raises(InputError, match="not a campaign railcal wrote"):
        check_campaign_output(root, overwrite=True)  # a truth file naming another campaign proves nothing
    truth.write_text(json.dumps({"format": "railcal-truth/1", "campaign": "old", "parameters": {},
                                 "frequencies_hz": {}}))
    _write(root, overwrite=True)
    assert (root / SYNTH_MARKER).is_file()


def test_importing_the_library_leaves_the_users_backend_alone():
    """Every module of the library (plots included) imported in a notebook-like process that
    chose its own backend: the choice stands."""
    import subprocess
    import sys

    code = ("import importlib, pkgutil, matplotlib; matplotlib.use('svg')\n"
            "import calibration, fmu_src, reference_models\n"
            "names = [m.name for p in (calibration, fmu_src, reference_models)\n"
            "         for m in pkgutil.walk_packages(p.__path__, p.__name__ + '.')]\n"
            "[importlib.import_module(n) for n in names]\n"
            "print(len(names), matplotlib.get_backend())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert int(out[0]) > 50 and out[1] == "svg"


def test_campaign_csv_numbers_are_printfs_nine_digits_and_read_back_exactly():
    """The fast writer's numbers are exactly ``%.9g``'s, over 80 decades, at half-way
    points, and at NaN, infinities and signed zeros; NaN is an empty field."""
    import io

    import numpy as np
    import pandas as pd

    from calibration.data.outputs import round_significant, write_csv

    rng = np.random.default_rng(5)
    x = np.concatenate([rng.standard_normal(20000) * 10.0 ** rng.integers(-40, 40, 20000),
                        np.arange(-2000, 2000) + 0.5, (np.arange(1, 2000) + 0.5) * 1e-12,
                        [5e-324, 1e300, np.nan, np.inf, -np.inf, 0.0, -0.0, 123456789.5]])
    printf = np.array([float(f"{v:.9g}") for v in x])
    assert np.array_equal(round_significant(x), printf, equal_nan=True)
    buf = io.BytesIO()
    write_csv(buf, {"t": x, "k": np.arange(x.size)})
    text = buf.getvalue().decode()
    assert text.startswith("t,k\n") and f"\n,{np.flatnonzero(np.isnan(x))[0]}\n" in text  # NaN: an empty field
    back = pd.read_csv(io.StringIO(text))
    assert np.array_equal(back["t"].to_numpy(), printf, equal_nan=True) and back["k"].dtype.kind == "i"
