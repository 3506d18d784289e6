"""Identification of a synthetic in-service campaign against the truth that generated it."""
import json
import shutil
import tomllib

import numpy as np
import pandas as pd
import pytest
import tomli_w

from railcal.cli import main
from calibration.data.campaign import open_campaign
from calibration.identification.fdd import RailInput, derived_channels
from calibration.identification.in_service import RIGID_LABELS, identify_in_service
from calibration.models.vehicles import INTERCITY_TRAILER
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec


@pytest.fixture(scope="module")
def identified(synthetic_campaign, synthetic_identification):
    """(identification, truth) of the synthetic campaign: the one `railcal identify` made
    (``identify_in_service`` at its default settings)."""
    return synthetic_identification[2], synthetic_campaign[1]


def test_rigid_body_modes_are_found_within_tolerance(identified):
    result, truth = identified
    limits = {"carbody_bounce": 0.03, "carbody_pitch": 0.03, "bogie_bounce": 0.02, "bogie_pitch": 0.02}
    for label in RIGID_LABELS:
        m = result.mode(label)
        assert m.frequency_hz == pytest.approx(truth["frequencies_hz"][label], rel=limits[label]), label
        assert m.damping_ratio == pytest.approx(truth["damping_ratios"][label], abs=0.04), label


def assert_noise_floors_match_the_truth(floors: list, truth: dict):
    """Bogie, floor and gyro channels carry nothing but white sensor noise above 25 Hz: their
    floor is that noise's density; the axle boxes carry the rail's short waves too, so
    theirs is an upper bound of their noise."""
    noise = truth["noise_rms_si"]
    expected = {"bogie1_acc_z": noise["bogie1_acc_z"], "bogie1_gyro_pitch": noise["bogie1_gyro_pitch"]}
    expected.update({f["channel"]: noise["carbody"] for f in floors if f["channel"].startswith("carbody")})
    by_channel = {f["channel"]: f for f in floors}
    for name, rms in expected.items():
        asd = rms / np.sqrt(noise["white_up_to_hz"])  # [unit/sqrt(Hz)] of a white noise to fs / 2
        assert by_channel[name]["asd_si_per_sqrt_hz"] == pytest.approx(asd, rel=0.05), name
        assert by_channel[name]["band_hz"][0] >= 25.0 and by_channel[name]["method"] == "psd_percentile"
    axle = [f for f in floors if f["channel"].startswith("axle")]
    assert axle and all(f["asd_si_per_sqrt_hz"] >= 0.95 * noise["axle_boxes"] / np.sqrt(noise["white_up_to_hz"])
                        for f in axle)
    assert by_channel["bogie1_gyro_pitch"]["unit"] == "rad/s" and by_channel["bogie1_acc_z"]["unit"] == "m/s^2"


def test_every_channels_noise_floor_is_its_sensor_noise_through_gaps_and_nan(identified):
    result, truth = identified
    floors = result.to_json()["data"]["noise_floors"]
    assert [f["channel"] for f in floors] == [s.name for s in open_campaign(result.campaign).meta.sensors]
    assert_noise_floors_match_the_truth(floors, truth)


def test_sleepers_are_speed_dependent_at_0_7_m_and_the_gyro_tone_is_not_the_vehicle(identified):
    result, _ = identified
    sleepers = [ln for ln in result.spectral_lines if ln.kind == "speed_dependent"
                and ln.wavelength_m is not None and abs(ln.wavelength_m - 0.70) <= 0.02]
    assert sleepers and sleepers[0].exponent == pytest.approx(1.0, abs=0.05)
    tone = [p for p in result.rejected_peaks if abs(p.frequency_hz - 77.64) < 0.2]
    assert tone and "non-vehicle" in tone[0].reason and "bogie1_gyro_pitch only" in tone[0].reason
    welds = [ln for ln in result.spectral_lines if ln.wavelength_m and abs(ln.wavelength_m - 39.0) < 0.5]
    assert welds, "periodic weld impacts every 39 m"


def test_segments_are_2_km_draws_from_many_journeys(identified):
    result, _ = identified
    used = [o for o in result.fdd.outcomes if o.used]
    assert len({o.segment.run_id for o in used}) == 6
    assert all(o.segment.end - o.segment.start == pytest.approx(2000.0) for o in used)
    assert result.fdd.results["bogie1_pitch"].n_used == 50  # seed Table 3
    assert result.fdd.results["axle1_bounce"].n_used == 20


def test_trailing_rail_is_the_leading_rail_seen_2_L_v_later(synthetic_campaign):
    root, _ = synthetic_campaign
    campaign = open_campaign(root)
    run = campaign.read_run(campaign.run_ids[0])
    d = run.distance.astype(float)
    ch = derived_channels(campaign.meta)
    lead: RailInput = ch["rail_bounce_bogie1"]
    trail: RailInput = ch["rail_bounce_bogie2_from_bogie1"]
    assert trail.delay == pytest.approx(2 * campaign.meta.geometry["bogie_semi_spacing"])
    a, b = run.blocks[0]
    i0, i1 = a + 5000, a + 15000
    x_lead, ok_lead = lead.evaluate(run, a, b, d)
    x_trail, ok = trail.evaluate(run, i0, i1, d)
    # the delayed value at distance s equals the leading value when the bogie was at s - 2 L_v
    target = d[i0:i1] - trail.delay
    expected = np.interp(target, d[a:b], x_lead)
    np.testing.assert_allclose(x_trail[ok], expected[ok], rtol=1e-9, atol=1e-9)


def test_identify_command_writes_modes_and_rejected_peaks(synthetic_identification):
    out, printed, _ = synthetic_identification  # into a folder that did not exist
    data = json.loads(out.read_text())
    assert {m["label"] for m in data["modes"]} == set(RIGID_LABELS)
    assert all({"label", "frequency_hz"} <= set(m) for m in data["modes"])
    assert all({"frequency_hz", "reason"} <= set(p) for p in data["rejected_peaks"])
    assert (out.parent / "ident.png").stat().st_size > 10_000
    assert (out.parent / "ident_spectra.png").stat().st_size > 10_000
    assert not list(out.parent.glob(".*partial*"))
    assert "identified 4 modes" in printed


def test_modes_command_reports_labelled_frequencies(tmp_path, capsys):
    out = tmp_path / "modes.json"
    assert main(["modes", "--model", "car2d", "--param", "J_b=10024", "--out", str(out)]) == 0
    data = json.loads(out.read_text())
    pitch = [m for m in data["modes"] if m["family"] == "bogie_pitch"]
    p = data["parameters"]
    assert pitch[0]["frequency_hz"] == pytest.approx(np.sqrt(2 * p["k_p"] * p["L_b"] ** 2 / 10024) / (2 * np.pi))
    assert all("damping_ratio" in m for m in data["modes"])
    capsys.readouterr()


def test_without_axle_boxes_identification_falls_back_to_fdd_peaks(synthetic_campaign, tmp_path):
    """Output-only, as the seed: the bogie pitch peak of the gyro's FDD, within the few per
    cent the wheelbase filter costs that method (the input-output estimate does 0.01 %)."""
    root, truth = synthetic_campaign
    bogie_only = tmp_path / "bogie_only"
    shutil.copytree(root, bogie_only)
    meta = tomllib.loads((bogie_only / "campaign.toml").read_text())
    meta["sensors"] = [s for s in meta["sensors"] if s["body"] == "bogie1"]
    (bogie_only / "campaign.toml").write_text(tomli_w.dumps(meta))
    for p in (bogie_only / "runs").glob("*.parquet"):
        df = pd.read_parquet(p)
        df[[c for c in df.columns if not c.startswith("axle")]].to_parquet(p)
    result = identify_in_service(open_campaign(bogie_only))
    assert not result.frfs  # no measured rail input, so no input-output estimate
    assert all(m.method == "fdd_peak" for m in result.modes)
    pitch = result.mode("bogie_pitch")  # the gyro's summed singular value peaks at the pitch mode
    assert pitch.frequency_hz == pytest.approx(truth["frequencies_hz"]["bogie_pitch"], rel=0.08)


def test_rail_pitch_follows_the_pitch_convention(identified):
    # a rail lower under the front wheelset pitches the bogie positively (front down):
    # below its resonance the bogie follows the rail, so the pitch FRF is close to +1
    result, _ = identified
    frf = result.frfs["pitch"]
    k = int(np.argmin(np.abs(frf.frequency - 2.0)))
    assert frf.H[k].real == pytest.approx(1.0, abs=0.15)


def test_a_bad_gyro_sample_invalidates_its_neighbours_in_the_centre_acceleration(synthetic_campaign):
    root, _ = synthetic_campaign
    campaign = open_campaign(root)
    run = campaign.read_run(campaign.run_ids[0])
    gyro_ok = run.valid["bogie1_gyro_pitch"].copy()
    run.valid["bogie1_gyro_pitch"][100] = False
    try:
        centre = derived_channels(campaign.meta)["bogie1_centre_acc_z"]
        _, ok = centre.evaluate(run, 0, 200, run.distance)
        assert not ok[99:102].any() and ok[97] and ok[103]
    finally:
        run.valid["bogie1_gyro_pitch"][:] = gyro_ok


@pytest.fixture(scope="module")
def heavily_damped(tmp_path_factory):
    """A campaign of the seed's car at its Table 6 damping (bogie bounce damped about 0.4),
    and a copy whose bogie accelerometer reads 3 % high and gyro 3 % low, as a sensor set's
    calibration may leave them: (campaign, copy, truth)."""
    root = tmp_path_factory.mktemp("damped") / "campaign"
    car = INTERCITY_TRAILER.replace(c_p=29_400.0, c_s=45_000.0)
    settings = InServiceSettings(journeys=6, line=LineSpec(length=10_000.0), vehicle=car)
    truth = synth_in_service(root, seed=23, settings=settings, fmt="parquet")
    copy = root.parent / "gains"
    shutil.copytree(root, copy)
    for path in (copy / "runs").glob("*.parquet"):
        df = pd.read_parquet(path)
        df["bogie1_acc_z"] *= 1.03
        df["bogie1_gyro_pitch"] *= 0.97
        df.to_parquet(path)
    return root, copy, truth


@pytest.mark.spread
def test_sensor_gain_errors_do_not_move_a_heavily_damped_bogie_bounce(heavily_damped):
    # The centre acceleration (accelerometer less the gyro's share) keeps 6 % x 0.45 m of the
    # bogie's pitch acceleration. A gain scales a response and moves no pole; with the rail
    # bounce as its FRF's only input, this pitch read as bounce (it moved the pole 2.0 % here).
    root, copy, truth = heavily_damped
    assert truth["damping_ratios"]["bogie_bounce"] > 0.35
    exact, off = (identify_in_service(open_campaign(r)).mode("bogie_bounce").frequency_hz for r in (root, copy))
    assert exact == pytest.approx(truth["frequencies_hz"]["bogie_bounce"], rel=0.01)
    assert off == pytest.approx(exact, rel=0.002)
