"""The in-service diagnosis's baseline is the user's: a calibration when given, else the
campaign's priors; built-in defaults are named, and a campaign with neither is refused."""
from __future__ import annotations

import json

import pytest

from calibration.data.campaign import Prior, open_campaign
from calibration.data.errors import CampaignError, InputError
from calibration.data.outputs import CampaignWriter
from calibration.diagnosis.in_service import DiagnosisSettings
from calibration.diagnosis.in_service.baseline import DEFAULT_CAR, baseline_start
from calibration.diagnosis.in_service.response import FIT_NAMES
from calibration.models.parameters import CAR_PARAMETER_SPECS
from railcal.cli import main

from conftest import tiny_columns, tiny_meta

SPREAD = DiagnosisSettings().prior_spread
#: a user's calibration of another car than the built-in default (every parameter differs)
USER_CAR = {"m_v": 31000.0, "J_v": 1.5e6, "m_b": 2600.0, "J_b": 1500.0, "m_w": 1800.0, "k_p": 1.2e6,
            "c_p": 29400.0, "k_s": 4.1e5, "c_s": 45000.0, "L_v": 9.5, "L_b": 1.28}


def _campaign(tmp_path, **meta):
    root = tmp_path / "c"
    with CampaignWriter(root, tiny_meta(**meta)) as w:
        w.write_run("run_a", tiny_columns())
        w.commit()
    return open_campaign(root)


def test_a_calibration_is_the_start_damping_included_and_priors_bound_the_search(tmp_path):
    campaign = _campaign(tmp_path, priors={"m_v": Prior(30000.0, 28000.0, 34000.0)})
    start = baseline_start(campaign, SPREAD, {"model": "car2d", "parameters": USER_CAR})
    assert start.parameters.as_dict() == USER_CAR and not start.defaults and not start.widened
    assert start.bounds["m_v"] == (28000.0, 34000.0)  # the campaign's prior
    for name in set(FIT_NAMES) - {"m_v"}:  # no prior: a factor around the calibrated value
        assert start.bounds[name] == pytest.approx((USER_CAR[name] / SPREAD, USER_CAR[name] * SPREAD))
    assert "calibration" in start.source


def test_a_calibration_outside_the_priors_widens_the_box_and_says_so(tmp_path):
    campaign = _campaign(tmp_path, priors={"m_v": Prior(38747.0, 36850.0, 40644.0)})
    start = baseline_start(campaign, SPREAD, {"model": "car2d", "parameters": USER_CAR})
    assert start.widened == ("m_v",) and start.bounds["m_v"] == (USER_CAR["m_v"], 40644.0)
    assert any("outside the campaign's prior range of m_v" in line for line in start.describe())


def test_without_a_calibration_the_priors_start_and_every_default_is_named_with_its_value(tmp_path):
    campaign = _campaign(tmp_path)  # priors: m_v only; geometry: L_v, L_b
    start = baseline_start(campaign, SPREAD)
    assert start.parameters.m_v == 38747.0 and start.parameters.L_v == 8.0 and start.parameters.L_b == 1.25
    assert set(start.defaults) == set(CAR_PARAMETER_SPECS) - {"m_v", "L_v", "L_b"}
    line = next(x for x in start.describe() if x.startswith("baseline defaults"))
    for name in start.defaults:
        assert f"{name} = {getattr(DEFAULT_CAR, name):.4g}" in line


def test_a_campaign_without_priors_or_calibration_is_refused(tmp_path):
    campaign = _campaign(tmp_path, priors={})
    with pytest.raises(CampaignError, match="no priors") as e:
        baseline_start(campaign, SPREAD)
    assert e.value.key == "priors"


@pytest.mark.parametrize("calibration,message", [
    ({"model": "box", "parameters": {}}, "needs a car2d calibration"),
    ({"model": "car2d", "parameters": {**USER_CAR, "k_p": -1.0}}, "k_p"),
    ({"model": "car2d", "parameters": {**USER_CAR, "L_b": 20.0}}, "L_b"),
])
def test_a_calibration_that_is_not_a_valid_car_is_an_input_error(tmp_path, calibration, message):
    campaign = _campaign(tmp_path)
    with pytest.raises(InputError, match=message):
        baseline_start(campaign, SPREAD, calibration)


def test_diagnose_without_priors_or_calibration_exits_2_naming_both_and_writes_nothing(tmp_path, capsys):
    root = _campaign(tmp_path, priors={}).root
    out = tmp_path / "d.json"
    assert main(["diagnose", str(root), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "no priors" in err and "--calibration" in err
    assert not out.exists()


def test_diagnose_refuses_a_box_calibration_for_an_in_service_campaign(tmp_path, capsys):
    root = _campaign(tmp_path).root
    cal = tmp_path / "box.json"
    cal.write_text(json.dumps({"format": "railcal-calibration/1", "model": "box", "parameters": {}}))
    out = tmp_path / "d.json"
    assert main(["diagnose", str(root), "--calibration", str(cal), "--out", str(out), "--quiet"]) == 2
    assert "car2d calibration" in capsys.readouterr().err and not out.exists()
