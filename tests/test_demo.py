"""``railcal demo``'s settings and plumbing, without running the demo (it takes minutes)."""
import numpy as np
import pytest

from railcal import cli, demo
from calibration.models.box.shinkansen import calibrated_box_model
from calibration.data.errors import InputError
from calibration.models.box.shinkansen import shinkansen_model
from conftest import COARSE_BOX_ORDERS


def test_full_keeps_the_published_sizes():
    """--full: the seed's 1000 particles stopping at 0.5 %, 10 journeys over 40 km and the
    full-order box model, as the DemoSettings docstring says."""
    f = demo.FULL
    assert (f.in_service.journeys, f.in_service.line.length) == (10, 40_000.0)
    assert (f.box_pso.particles, f.box_pso.target) == (1000, 0.5)
    assert f.box_order_change == 0 and f.excitation.order_change == 0
    assert f.box_refine_tol_pct == 1e-4


def test_quick_is_smaller_and_coarse():
    q = demo.QUICK
    assert q.in_service.journeys * q.in_service.line.length < demo.FULL.in_service.journeys * \
        demo.FULL.in_service.line.length
    assert q.box_pso.particles < demo.FULL.box_pso.particles
    assert q.box_order_change < 0 and q.excitation.order_change == q.box_order_change


def test_settings_refuse_a_panel_order_below_one():
    with pytest.raises(ValueError, match="panel order below 1"):
        demo.DemoSettings(demo.QUICK.in_service, car_runs=1, box_pso=demo.QUICK.box_pso, box_swarms=1,
                          box_order_change=-100)


@pytest.mark.parametrize("flags, full", [([], False), (["--full"], True)])
def test_full_flag_reaches_run_demo(tmp_path, monkeypatch, flags, full):
    seen = {}

    def fake(out, *, progress=None, full=False):
        seen["full"] = full
        return out / "report.md"

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


def test_a_mode_without_damping_gets_a_dash():
    assert demo._damping(None) == "—" and demo._damping(0.0123) == "0.012"


def test_wall_times_are_the_steps_differences():
    text = demo._walls_report({"1/11 synthesising": 100.0, "2/11 identifying": 130.0, "end": 175.5}, demo.QUICK)
    assert "| 1/11 synthesising | 30 |" in text and "| 2/11 identifying | 46 |" in text
    assert "76 s in all" in text and "`railcal demo`" in text
