"""The package layers (pyproject.toml's import-linter contracts) hold, and every module
stays readable in one sitting."""
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("railcal", "calibration", "fmu_src", "reference_models")
MAX_LINES = 600


def test_the_import_contracts_hold():
    lint = Path(sys.executable).with_name("lint-imports")
    run = subprocess.run([str(lint), "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    assert "0 broken" in run.stdout


def test_a_broken_contract_fails_the_check(tmp_path):
    """The check can fail: a model module importing the truth simulator breaks the leaf rule."""
    config = (ROOT / "pyproject.toml").read_text()
    (tmp_path / "pyproject.toml").write_text(config)
    pkg = tmp_path / "calibration"
    for src in (ROOT / "calibration").rglob("*.py"):
        dst = pkg / src.relative_to(ROOT / "calibration")
        dst.parent.mkdir(parents=True, exist_ok=True)
        dst.write_text(src.read_text())
    for name in ("railcal", "fmu_src", "reference_models"):
        for src in (ROOT / name).rglob("*.py"):
            dst = tmp_path / src.relative_to(ROOT)
            dst.parent.mkdir(parents=True, exist_ok=True)
            dst.write_text(src.read_text())
    bad = pkg / "models" / "leak.py"
    bad.write_text("from ..truth import effects\n")
    lint = Path(sys.executable).with_name("lint-imports")
    run = subprocess.run([str(lint), "--no-cache"], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                         env={"PYTHONPATH": str(tmp_path), "PATH": ""})
    assert run.returncode == 1
    assert "calibration.models.leak -> calibration.truth" in run.stdout


def test_no_module_is_longer_than_a_sitting():
    long = {str(p.relative_to(ROOT)): n for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")
            if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines: {long}"
