"""``railcal demo``'s settings and plumbing, without running the demo (it takes minutes)."""
import json

import numpy as np
import pytest

from railcal import cli, demo
from calibration.models.box.shinkansen import calibrated_box_model
from calibration.data.errors import InputError
from calibration.models.box.shinkansen import shinkansen_model
from conftest import COARSE_BOX_ORDERS


def test_full_keeps_the_published_sizes():
    """--full: 10 journeys over 40 km and the full-order box model, calibrated with
    `railcal calibrate`'s own defaults (the seed's 1000 particles, stopping at 0.5 %)."""
    f = demo.FULL
    assert (f.in_service.journeys, f.in_service.line.length) == (10, 40_000.0)
    assert f.box_order_change == 0 and f.excitation.order_change == 0
    assert f.run_options() == {"calibrate": ("--panel-order-change", "0")}


def test_quick_is_smaller_and_coarse_throughout():
    """The quick demo's excitation test is synthesised and calibrated on the same coarse
    model (the calibration file records it, so every later step rebuilds it)."""
    q = demo.QUICK
    assert q.in_service.journeys * q.in_service.line.length < demo.FULL.in_service.journeys * \
        demo.FULL.in_service.line.length
    assert q.box_order_change < 0 and q.excitation.order_change == q.box_order_change
    options = q.run_options()["calibrate"]
    assert options[:2] == ("--panel-order-change", str(q.box_order_change))
    assert int(options[options.index("--particles") + 1]) < 1000


def test_settings_refuse_a_panel_order_below_one():
    with pytest.raises(ValueError, match="panel order below 1"):
        demo.DemoSettings(demo.QUICK.in_service, box_order_change=-100)


def test_a_missing_result_fails_its_check_and_names_it(tmp_path):
    for kind, name in demo.CAMPAIGNS.items():
        (tmp_path / f"{name}.truth.json").write_text(json.dumps({"frequencies_hz": {"carbody_bounce": 0.9}}))
    checks = demo.demo_checks(tmp_path)
    assert checks and not any(held for _, held in checks)
    assert any("carbody_bounce identified" in text for text, _ in checks)


@pytest.mark.parametrize("flags, full", [([], False), (["--full"], True)])
def test_full_flag_reaches_run_demo(tmp_path, monkeypatch, flags, full):
    seen = {}

    def fake(out, *, progress=None, full=False):
        seen["full"] = full
        return out / "demo.md"

    monkeypatch.setattr(demo, "run_demo", fake)
    assert cli.main(["demo", "--out", str(tmp_path / "d"), "--quiet", *flags]) == 0
    assert seen == {"full": full}


@pytest.mark.parametrize("name", ["campaign", "excitation"])
def test_demo_refuses_a_folder_it_did_not_write(tmp_path, monkeypatch, capsys, name):
    """Both campaigns the demo replaces are checked before any work."""
    monkeypatch.setattr(demo, "run_demo", lambda *a, **k: pytest.fail("ran despite a foreign folder"))
    (tmp_path / name).mkdir()
    (tmp_path / name / "thesis.tex").write_text("mine")
    assert cli.main(["demo", "--out", str(tmp_path), "--quiet"]) == 2
    assert name in capsys.readouterr().err
    assert (tmp_path / name / "thesis.tex").read_text() == "mine"


def test_calibration_file_rebuilds_the_coarse_model_it_was_calibrated_on():
    """A coarse calibration's FRFs and FMU must come from the discretisation it was
    calibrated on: the same mass matrix and, at nominal factors, the same stiffness."""
    model, p = calibrated_box_model({"model": "box", "parameters": {}, "order_change": COARSE_BOX_ORDERS})
    ref = shinkansen_model(COARSE_BOX_ORDERS)
    assert model.n_dof == ref.n_dof < 2709  # the full-order model's degrees of freedom
    K = model.stiffness([p[n] for n in model.names])
    K0 = ref.stiffness(np.ones(len(ref.names)))
    assert abs(model.M - ref.M).max() <= 1e-12 * abs(ref.M).max()
    assert abs(K - K0).max() <= 1e-9 * abs(K0).max()


@pytest.mark.parametrize("bad", [-100, 1.5, True, "-4"])
def test_calibration_file_refuses_a_bad_order_change(bad):
    with pytest.raises(InputError, match="order_change"):
        calibrated_box_model({"model": "box", "parameters": {}, "order_change": bad})
