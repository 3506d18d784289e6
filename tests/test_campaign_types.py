"""The campaign's types check themselves when made (a ValueError naming the field), and
campaign.py, the data layer's entry point, still offers every name it did before the split."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import calibration.data.campaign as campaign
from calibration.data.campaign import Excitation, Gap, Prior, Sensor, TrackRecording

from conftest import tiny_meta

GOOD = Sensor("bogie1_acc_z", "acceleration", "g", "bogie1", "z", (8.5, 0.6, 0.7))


@pytest.mark.parametrize("field, value, match", [
    ("name", "bogie 1", r"Sensor\.name: 'bogie 1' must match"),
    ("name", "time", r"Sensor\.name: 'time' is reserved"),
    ("name", "acc_clipped", r"Sensor\.name: 'acc_clipped' is reserved"),
    ("quantity", "jerk", r"Sensor\.quantity: unknown quantity 'jerk'"),
    ("unit", "furlong", r"Sensor\.unit: unknown unit 'furlong'"),
    ("unit", "N", r"Sensor\.unit: 'N' is not a unit of acceleration"),
    ("body", "bogie3", r"Sensor\.body: unknown body 'bogie3'"),
    ("direction", "pitch", r"Sensor\.direction: 'pitch' is not a direction of acceleration"),
    ("position", (1.0, 2.0), r"Sensor\.position: expected \[x, y, z\]"),
    ("position", (1.0, math.nan, 0.0), r"Sensor\.position: expected \[x, y, z\]"),
    ("scale", 0.0, r"Sensor\.scale: 0\.0 times"),
    ("scale", math.inf, r"Sensor\.scale: inf times"),
])
def test_a_sensor_refuses_unknown_names_and_impossible_values(field, value, match):
    with pytest.raises(ValueError, match=match):
        dataclasses.replace(GOOD, **{field: value})


def test_a_sensor_accepts_a_unit_alias_and_converts_it_as_its_unit():
    s = dataclasses.replace(GOOD, unit="m/s2", scale=2.0)
    assert s.si_factor == 2.0
    assert dataclasses.replace(GOOD, quantity="angular_velocity", unit="deg/s",
                               direction="pitch").si_factor == pytest.approx(math.pi / 180)


@pytest.mark.parametrize("nominal, low, high, match", [
    (1.0, 2.0, 0.5, r"Prior\.low: 2\.0 must be below high = 0\.5 \(infeasible bounds\)"),
    (1.0, 1.0, 1.0, r"Prior\.low: 1\.0 must be below high = 1\.0"),
    (3.0, 0.5, 2.0, r"Prior\.nominal: 3\.0 outside \[low, high\] = \[0\.5, 2\.0\]"),
    (math.nan, 0.5, 2.0, r"Prior\.nominal: expected a finite number, got nan"),
    (1.0, 0.5, math.inf, r"Prior\.high: expected a finite number, got inf"),
])
def test_a_prior_refuses_inverted_bounds_and_a_nominal_outside_them(nominal, low, high, match):
    with pytest.raises(ValueError, match=match):
        Prior(nominal, low, high)


def test_a_prior_on_its_bound_is_accepted():
    assert Prior(0.5, 0.5, 2.0).nominal == 0.5


def test_an_excitation_refuses_a_bad_sensor_name_and_position():
    with pytest.raises(ValueError, match=r"Excitation\.sensor: 'exciter force' must match"):
        Excitation("exciter force", (0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match=r"Excitation\.position"):
        Excitation("exciter_force", (0.0, 0.0))


@pytest.mark.parametrize("changes, match", [
    ({"kind": "stationary"}, r"CampaignMeta\.kind: expected one of in_service, stationary_excitation"),
    ({"sensors": ()}, r"CampaignMeta\.sensors: expected at least one Sensor"),
    ({"sensors": (GOOD, GOOD)}, r"CampaignMeta\.sensors: sensor name\(s\) bogie1_acc_z declared twice"),
    ({"sampling_rate": -100.0}, r"CampaignMeta\.sampling_rate: expected a positive number \[Hz\], got -100\.0"),
    ({"sampling_rate": 0.0}, r"CampaignMeta\.sampling_rate"),
    ({"geometry": {"wheelbase": 2.5}}, r"CampaignMeta\.geometry: unknown key 'wheelbase'"),
    ({"geometry": {"length": -23.0}}, r"CampaignMeta\.geometry: length must be a positive length \[m\]"),
    ({"priors": {"m_v": (1.0, 0.5, 2.0)}}, r"CampaignMeta\.priors: 'm_v' is not a Prior"),
    ({"kind": "stationary_excitation"}, r"CampaignMeta\.excitation: a stationary_excitation campaign needs"),
    ({"excitation": Excitation("exciter_force", (0.0, 0.0, 1.0))},
     r"CampaignMeta\.excitation: names sensor 'exciter_force', which is not in sensors"),
])
def test_campaign_meta_refuses_unknown_names_negative_values_and_dangling_references(changes, match):
    with pytest.raises(ValueError, match=match):
        tiny_meta(**changes)


def test_the_written_metadata_round_trips_through_its_own_checks():
    meta = tiny_meta()
    again = campaign.parse_meta(meta.to_toml(), Path("campaign.toml"))
    assert again == meta


def test_a_gap_and_a_track_recording_refuse_inverted_or_unknown_values():
    assert Gap(1.0, 1.5).duration == 0.5
    with pytest.raises(ValueError, match=r"Gap\.before_time: 1\.0 \[s\] must be finite and after after_time = 1\.5"):
        Gap(1.5, 1.0)
    d = np.arange(3.0)
    with pytest.raises(ValueError, match=r"TrackRecording\.band: unknown band 'D3'"):
        TrackRecording("t", Path("t.csv"), d, d, "D3")
    with pytest.raises(ValueError, match=r"TrackRecording\.level: 2 samples for 3 distances"):
        TrackRecording("t", Path("t.csv"), d, d[:2], "raw")


# Every public name campaign.py defined before it was split into modules, as other
# packages import them from there.
BEFORE_THE_SPLIT = (
    "FORMAT KINDS NAME_RE TRACK_BANDS GAP_FACTOR MAX_TOML_BYTES MAX_RUN_BYTES MAX_RUN_CELLS MAX_RUN_LINES "
    "MAX_COLUMNS MAX_SPEED MAX_ABS_DISTANCE MAX_ABS_TIME RATE_RANGE RATE_TOLERANCE MAX_POSITION GEOMETRY_RANGES "
    "Sensor Prior Excitation CampaignMeta parse_meta Gap Run MAX_INPUT_BYTES read_input_file read_run_file "
    "MAX_ABS_LEVEL TrackRecording read_track_file Campaign MAX_TOML_DEPTH open_campaign").split()


def test_campaign_py_still_exports_every_public_name_it_had():
    assert set(BEFORE_THE_SPLIT) <= set(campaign.__all__)
    assert all(hasattr(campaign, n) for n in campaign.__all__)
