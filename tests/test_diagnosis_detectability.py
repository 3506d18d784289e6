"""Detectability (issue 31): each catalogue extension's weakest detectable effect, predicted
from the fitted baseline and the measured residual floor. The truth builds the campaigns
only; the assertions are physics: effects that move no channel the sensors have are not
observable, a quieter campaign sees weaker effects unless a model's accuracy, not the noise,
bounds them, and ``none`` says which sizes it rules out.
"""
from __future__ import annotations

from dataclasses import replace

import pytest

from calibration.data.campaign import open_campaign
from calibration.diagnosis.in_service import EXTENSIONS, DiagnosisSettings, diagnose_in_service

#: the extensions that name a cause (the others are what every vehicle has: no limit)
CAUSES = {n for n, e in EXTENSIONS.items() if not e.always_normal}
from calibration.diagnosis.in_service.baseline import baseline_start
from calibration.diagnosis.in_service.detectability import Detectability, _Responses, detectability
from calibration.diagnosis.in_service.diagnose import _data
from calibration.diagnosis.in_service.response import SensorModel, fit_response
from calibration.models.car2d import CarExtras
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec

#: campaign seed, unused by the other diagnosis tests and benches
SEED = 91
SMALL = InServiceSettings(journeys=2, line=LineSpec(length=8_000.0), carbody_sensors=False)
#: the same campaign with every response and axle-box sensor three times quieter
QUIET = dict(bogie_acc_noise=SMALL.bogie_acc_noise / 3, carbody_acc_noise=SMALL.carbody_acc_noise / 3,
             gyro_noise_raw=SMALL.gyro_noise_raw / 3, axle_acc_noise=SMALL.axle_acc_noise / 3)
CARBODY_ONLY = ("carbody_bending",)  # moves the carbody; what it gives back to the bogies is within their noise
BOGIE = ("sensor_offset", "wheel_out_of_round", "track_flexibility")
#: a model-accuracy floor low enough that no channel falls under it
NOISE_ONLY = DiagnosisSettings(systematic_floor=1e-12)


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    root = tmp_path_factory.mktemp("detectability")
    made = {}
    for name, settings in (("bogie", SMALL), ("carbody", replace(SMALL, carbody_sensors=True)),
                           ("carbody_quiet", replace(SMALL, carbody_sensors=True, **QUIET))):
        synth_in_service(root / name, seed=SEED, settings=settings, fmt="parquet")
        made[name] = open_campaign(root / name)
    return made


def _limits(campaign, s: DiagnosisSettings = DiagnosisSettings()) -> Detectability:
    """The detectability at the baseline fit, as the diagnosis computes it."""
    data, _ = _data(campaign, s, baseline_start(campaign, s.prior_spread), lambda msg: None)
    base = fit_response(data.stats, data.layout, data.keys(data.train), data.prior, data.bounds)
    return detectability(data, base)


@pytest.fixture(scope="module")
def limits(campaigns):
    return {name: _limits(c).to_json() for name, c in campaigns.items()}


@pytest.fixture(scope="module")
def noise_limits(campaigns):
    """The limits set by the data's scatter alone: every channel counted, however small the
    model error the effect would leave on it."""
    return {name: _limits(c, NOISE_ONLY).to_json() for name, c in campaigns.items() if name.startswith("carbody")}


def _weaker_or_equal(ext: str, a: float, b: float) -> bool:
    """Is limit ``a`` at an effect as weak as ``b`` or weaker? Bending and track: the limit
    is the highest frequency / stiffness seen, so weaker is higher; others: smaller."""
    return a >= b * (1 - 1e-9) if ext in ("carbody_bending", "track_flexibility") else a <= b * (1 + 1e-9)


@pytest.mark.slow
def test_every_catalogue_extension_has_a_limit_in_its_own_parameter(limits):
    assert CAUSES < set(EXTENSIONS)  # properties at any size (equipment, journey loads) have no limit
    for table in limits.values():
        assert set(table) == CAUSES
        for ext, row in table.items():
            assert set(row) == {"parameter", "unit", "detectable_beyond", "observable", "why"}
            assert row["why"] and row["unit"]
            assert row["detectable_beyond"] is None or row["detectable_beyond"] > 0
    assert limits["carbody"]["carbody_bending"]["parameter"] == "bending_hz"
    assert limits["carbody"]["cog_offset"]["unit"] == "m"


@pytest.mark.slow
def test_carbody_effects_are_not_observable_with_bogie_sensors_only(limits):
    bogie, carbody = limits["bogie"], limits["carbody"]
    for ext in CARBODY_ONLY:
        assert not bogie[ext]["observable"] and bogie[ext]["detectable_beyond"] is None
        assert "carbody" in bogie[ext]["why"]  # says which sensors would see it
        assert carbody[ext]["observable"] and carbody[ext]["detectable_beyond"] is not None
    for ext in BOGIE:
        assert bogie[ext]["observable"] and bogie[ext]["detectable_beyond"] is not None
    # no floor accelerometer, none to be off its place
    assert not bogie["floor_sensor_offset"]["observable"] and carbody["floor_sensor_offset"]["observable"]
    # a CoG offset reaches the bogies only through the secondary suspension: floor sensors see
    # a weaker one than the bogie sensors can (here none within its range)
    assert carbody["cog_offset"]["detectable_beyond"] is not None
    assert bogie["cog_offset"]["detectable_beyond"] is None or \
        bogie["cog_offset"]["detectable_beyond"] > carbody["cog_offset"]["detectable_beyond"]


@pytest.mark.slow
def test_a_quieter_campaign_detects_weaker_effects(noise_limits):
    loud, quiet = noise_limits["carbody"], noise_limits["carbody_quiet"]
    shrunk = []
    # the track's floor is the rail spectra's own scatter over speed, not the sensors' noise
    for ext in CAUSES - {"track_flexibility"}:
        a, b = quiet[ext]["detectable_beyond"], loud[ext]["detectable_beyond"]
        assert b is None or (a is not None and _weaker_or_equal(ext, a, b)), (ext, a, b)
        if a is not None and b is not None and not _weaker_or_equal(ext, b, a):
            shrunk.append(ext)
    # the sensor noise sets these extensions' floors (bending is seen over its whole range in both)
    assert {"sensor_offset", "airspring_reservoir", "wheel_out_of_round"} <= set(shrunk), shrunk


@pytest.mark.slow
def test_a_model_accuracy_floor_only_raises_the_limits(limits, noise_limits):
    """A gain counts only on a channel the effect would leave with a model error, as in the
    decision: the limits are the data's scatter's or the floor's, whichever is weaker. On
    the quiet campaign of railcal's own (exact) car every channel is within a model's
    accuracy, so the floor, not the noise, bounds the reservoir."""
    for name, noise in noise_limits.items():
        for ext in CAUSES - {"track_flexibility", "wheel_out_of_round"}:
            a, b = limits[name][ext]["detectable_beyond"], noise[ext]["detectable_beyond"]
            assert a is None or (b is not None and _weaker_or_equal(ext, b, a)), (name, ext, a, b)
        for ext in ("track_flexibility", "wheel_out_of_round"):  # not response channels: no floor
            assert limits[name][ext] == noise[ext]
    quiet = limits["carbody_quiet"]["airspring_reservoir"]["detectable_beyond"]
    assert quiet > 1.5 * noise_limits["carbody_quiet"]["airspring_reservoir"]["detectable_beyond"]


@pytest.mark.slow
def test_none_lists_every_extension_and_what_it_rules_out(campaigns):
    diag = diagnose_in_service(campaigns["bogie"])
    assert diag.cause == "none", diag.summary
    line = diag.summary[0]
    assert line.startswith("none: no effect above these sizes: ")
    assert all(ext in line for ext in CAUSES)
    assert "carbody_bending: not observable" in line
    written = diag.to_json()["detectability"]
    assert written == diag.detectability.to_json() and set(written) == CAUSES


def test_an_effect_this_sensor_set_cannot_name_at_any_size_says_which_sensors_would():
    from calibration.diagnosis.in_service.detectability import Limit

    blind = Limit("carbody_bending", "bending_hz", "Hz", None, True, "why", "below", needs="carbody sensors")
    assert blind.words() == "carbody_bending: not observable without carbody sensors"
    weak = Limit("airspring_reservoir", "reservoir_ratio", "-", None, True, "why", "above")
    assert weak.words() == "airspring_reservoir: not detectable within its range"


@pytest.mark.slow
def test_an_effect_is_judged_on_top_of_the_model_it_is_added_to(campaigns):
    """On a model with a finding (a bending), the model itself judged as an effect changes
    nothing, and an effect takes the place of the model's own additions of its kind only."""
    s = DiagnosisSettings()
    campaign = campaigns["carbody"]
    data, _ = _data(campaign, s, baseline_start(campaign, s.prior_spread), lambda msg: None)
    bend = EXTENSIONS["carbody_bending"]
    fit = fit_response(data.stats, data.layout, data.keys(data.train), data.prior, data.bounds,
                       ext_params=bend.params, make=bend.make, starts=1)
    assert fit.extras.bending_hz is not None
    r = _Responses(data, fit)
    assert r.judge(fit.extras, fit.sensors) == (0.0, 0.0)
    extras, sensors = r.with_effect(EXTENSIONS["cog_offset"], {"cog_offset": 1.0})
    assert extras == replace(fit.extras, cog_offset=1.0) and sensors == fit.sensors
    assert r.judge(extras, sensors)[1] > 0.0


def test_an_effects_own_parameters_take_the_place_of_the_models_and_the_rest_stays():
    """The bending at the limit's frequency and held shape replaces the one found (its node
    kept); a floor sensor's offset replaces that sensor's, its gain and the other sensors
    stay; a bogie sensor's offset replaces the fit's, its gyro's gain stays."""
    from types import SimpleNamespace

    extras = CarExtras(bending_hz=14.0, bending_damping=0.04, bending_mass_ratio=0.13, bending_node=0.45,
                       reservoir_ratio=0.0)
    sensors = SensorModel(dx=0.05, gyro_gain=1.02, floor=(("a", 0.05, 1.03), ("b", -0.02, 0.98)))
    r = _Responses.__new__(_Responses)
    r.base = SimpleNamespace(extras=extras, sensors=sensors)
    ex, se = r.with_effect(EXTENSIONS["carbody_bending"], {"bending_hz": 9.0, "bending_damping": 0.02,
                                                           "bending_mass_ratio": 0.25})
    assert ex == replace(extras, bending_hz=9.0, bending_damping=0.02, bending_mass_ratio=0.25) and se == sensors
    ex, se = r.with_effect(EXTENSIONS["floor_sensor_offset"], {"dx:a": 0.7})
    assert ex == extras and se == replace(sensors, floor=(("a", 0.7, 1.03), ("b", -0.02, 0.98)))
    ex, se = r.with_effect(EXTENSIONS["sensor_offset"], {"dx": 0.5, "gyro_gain": 1.0})
    assert se == replace(sensors, dx=0.5)
    ex, se = r.with_effect(EXTENSIONS["airspring_reservoir"], {"reservoir_ratio": 0.8, "reservoir_corner_hz": 2.5})
    assert ex == replace(extras, reservoir_ratio=0.8, reservoir_corner_hz=2.5)
