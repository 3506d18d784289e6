"""How the FMU builder writes its file: through an unpredictable temporary name beside the
target, renamed into place, with the umask's permissions; a planted symlink is not followed
and a failed build leaves nothing behind."""
import os
import zipfile

import pytest

from calibration.data.errors import InputError
from fmu_src.build import BuildError, build_fmu
from fmu_src.variables import trivial_spec


@pytest.fixture
def umask_027():
    old = os.umask(0o027)
    yield 0o027
    os.umask(old)


def test_the_fmu_is_written_beside_the_target_without_following_a_planted_symlink(tmp_path, umask_027):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    out = tmp_path / "lag.fmu"
    for name in (out.name + ".partial", "." + out.name + ".partial"):  # the names a guesser would plant
        (tmp_path / name).symlink_to(victim)
    built = build_fmu(trivial_spec(), 2, out, platforms=("linux64",))
    assert built.path == out and zipfile.ZipFile(out).testzip() is None
    assert "modelDescription.xml" in zipfile.ZipFile(out).namelist()
    assert victim.read_text() == "precious"
    assert oct(out.stat().st_mode & 0o777) == oct(0o666 & ~umask_027)  # not mkstemp's 0600
    leftovers = sorted(p.name for p in tmp_path.iterdir())
    assert leftovers == sorted([out.name, victim.name, out.name + ".partial", "." + out.name + ".partial"])


def test_a_failed_build_leaves_no_file_and_a_folder_is_not_replaced(tmp_path, monkeypatch):
    import fmu_src.build as build

    def failing(*args, **kwargs):
        raise BuildError("compiler failed")

    monkeypatch.setattr(build, "_compile", failing)
    with pytest.raises(BuildError):
        build_fmu(trivial_spec(), 3, tmp_path / "x.fmu", platforms=("linux64",))
    assert list(tmp_path.iterdir()) == []
    monkeypatch.undo()
    (tmp_path / "dir.fmu").mkdir()
    with pytest.raises(InputError, match="dir.fmu.*not a regular file"):
        build_fmu(trivial_spec(), 2, tmp_path / "dir.fmu", platforms=("linux64",))
    assert (tmp_path / "dir.fmu").is_dir()
