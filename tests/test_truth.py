"""The truth simulator: published irregularity spectrum, sensors as declared, truth beside the campaign."""
import json

import numpy as np
import pytest
import scipy.integrate
import scipy.signal

from calibration.data.campaign import open_campaign
from calibration.models.car2d import build_car, frequencies_by_label, undamped_modes
from calibration.models.parameters import CarParameters
from calibration.models.track_irregularity import german_vertical_psd, synthesise_profile
from calibration.truth.track import Line, LineSpec


def test_synthesised_profile_has_the_variance_of_the_german_spectrum():
    rng = np.random.default_rng(5)
    lo, hi = 2 * np.pi / 100.0, 2 * np.pi / 2.0
    _, z = synthesise_profile(german_vertical_psd, 200_000.0, 0.1, rng, min_wavelength=2.0, max_wavelength=100.0)
    W = np.linspace(lo, 2 * hi, 200_001)
    expected = scipy.integrate.trapezoid(german_vertical_psd(W) / (1 + (W / hi) ** 8), W)
    assert z.var() == pytest.approx(expected, rel=0.03)


def test_line_has_sleepers_welds_and_a_d1_recording():
    spec = LineSpec(length=2_000.0)
    line = Line(spec, np.random.default_rng(1))
    s = np.arange(100.0, 1900.0, 0.01)
    z, dz, d2z = line.level(s)
    # derivatives are consistent with the level
    np.testing.assert_allclose(np.gradient(z, s)[10:-10], dz[10:-10], atol=2e-5)
    # weld dips every 39 m
    assert np.allclose(np.diff(line.weld_positions), spec.panel_length)
    d, level = line.recording(500.0, 1000.0, rng=np.random.default_rng(2))
    assert d[0] >= 500.0 and d[-1] <= 1500.0
    # a D1 record holds nothing at the 0.7 m sleeper wavelength and little beyond 25 m
    nu, P = scipy.signal.welch(level, fs=1 / (d[1] - d[0]), nperseg=1024)  # cycles per metre
    sleeper = P[np.argmin(np.abs(nu - 1 / 0.7))]
    assert sleeper < 1e-6 * P[(nu > 1 / 25) & (nu < 1 / 3)].max()


def test_synthetic_campaign_is_a_valid_campaign_with_its_truth_beside_it(synthetic_campaign):
    root, truth = synthetic_campaign
    assert not any(p.name.endswith("truth.json") for p in root.rglob("*"))
    assert json.loads((root.parent / "campaign.truth.json").read_text()) == json.loads(json.dumps(truth))
    campaign = open_campaign(root)
    assert campaign.meta.kind == "in_service" and len(campaign.run_ids) == 6
    names = {s.name for s in campaign.meta.sensors}
    assert {"bogie1_acc_z", "bogie1_gyro_pitch", "axle1_left_acc_z", "axle2_right_acc_z"} <= names
    gyro = campaign.meta.sensor("bogie1_gyro_pitch")
    assert gyro.unit == "deg/s" and gyro.scale == pytest.approx(23.9)
    acc = campaign.meta.sensor("bogie1_acc_z")
    assert acc.position[0] - campaign.meta.geometry["bogie_semi_spacing"] == pytest.approx(0.45)
    run = campaign.read_run(campaign.run_ids[0])
    assert np.nanmean(run.channels["bogie1_acc_z"]) == pytest.approx(9.80665, rel=1e-3)  # reads +1 g at rest
    assert 20.0 <= np.nanmin(run.speed) and np.nanmax(run.speed) <= 45.0
    # truth frequencies are the model's for the truth parameters, inside the priors
    p = CarParameters(**truth["parameters"])
    assert truth["frequencies_hz"] == pytest.approx(frequencies_by_label(undamped_modes(build_car(p))))
    for name, prior in campaign.meta.priors.items():
        assert prior.low <= truth["parameters"][name] <= prior.high
    assert campaign.tracks()[0].band == "D1"


@pytest.mark.slow
def test_synth_is_reproducible_from_its_seed(tmp_path):
    from calibration.truth.in_service import InServiceSettings, synth_in_service

    settings = InServiceSettings(journeys=1, line=LineSpec(length=6_000.0))
    a = synth_in_service(tmp_path / "a", seed=3, settings=settings)
    b = synth_in_service(tmp_path / "b", seed=3, settings=settings)
    assert a["parameters"] == b["parameters"]
    ra = open_campaign(tmp_path / "a").read_run("journey_001")
    rb = open_campaign(tmp_path / "b").read_run("journey_001")
    np.testing.assert_array_equal(ra.channels["bogie1_acc_z"], rb.channels["bogie1_acc_z"])
