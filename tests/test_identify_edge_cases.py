"""In-service identification on valid data that once crashed it (issue 29): test rides at
one constant speed, short campaigns and irregularly sampled runs.

What cannot be determined is reported as null with a reason; what is determined is
checked against the truth that generated the data."""
import json
import math

import numpy as np
import pytest

from railcal.cli import main
from calibration.data.campaign import CampaignMeta, Sensor, open_campaign
from calibration.data.outputs import CampaignWriter
from calibration.identification.in_service import RIGID_LABELS, identify_in_service
from calibration.signals.spectral_lines import LineSettings, classify_lines
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec

# the tolerances test_identify holds the identification to on a larger campaign
TOLERANCE = {"carbody_bounce": 0.03, "carbody_pitch": 0.03, "bogie_bounce": 0.02, "bogie_pitch": 0.02}
FS = 500.0  # [Hz] the synthetic logger's rate


def _strict_json(path):
    """The file as JSON, refusing NaN and infinities (which json.loads would accept)."""
    def refuse(name):
        raise AssertionError(f"{path} holds {name}")
    return json.loads(path.read_text(), parse_constant=refuse)


def _campaign(root, seed, *, journeys=3, km=6.0, **settings):
    settings = InServiceSettings(journeys=journeys, line=LineSpec(length=km * 1e3), **settings)
    truth = synth_in_service(root, seed=seed, settings=settings, fmt="parquet")
    return root, truth


def test_a_line_seen_over_too_narrow_a_speed_range_has_an_undetermined_exponent(tmp_path):
    """Three runs at 30.0-30.2 m/s, each with a 40 Hz tone: f ~ v^alpha has no slope to fit,
    so the exponent is None (JSON null), never NaN, and the line is called ambiguous."""
    meta = CampaignMeta(kind="in_service", name="narrow", vehicle="test car", sampling_rate=FS,
                        sensors=(Sensor("bogie1_acc_z", "acceleration", "m/s^2", "bogie1", "z", (8.5, 0.6, 0.7)),))
    rng = np.random.default_rng(3)
    with CampaignWriter(tmp_path / "narrow", meta) as w:
        for k, v in enumerate((30.0, 30.1, 30.2)):
            t = np.arange(int(40 * FS)) / FS
            w.write_run(f"run_{k}", {"time": t, "distance": v * t, "speed": np.full(t.size, v),
                                     "bogie1_acc_z": np.sin(2 * np.pi * 40.0 * t) + rng.normal(0, 0.1, t.size)})
        w.commit()
    lines = classify_lines(open_campaign(tmp_path / "narrow"), settings=LineSettings(windows_per_run=4))
    tone = [ln for ln in lines if abs(ln.frequency_hz - 40.0) < 0.5]
    assert tone and tone[0].kind == "ambiguous"
    assert tone[0].exponent is None and tone[0].exponent_stderr is None
    assert "too narrow a speed range" in tone[0].interpretation
    json.dumps([ln.to_json() for ln in lines], allow_nan=False)


@pytest.fixture(scope="module")
def constant_speed(tmp_path_factory):
    """A test ride: three journeys, each at one constant speed within 29.9-30.1 m/s."""
    return _campaign(tmp_path_factory.mktemp("const") / "campaign", 1, constant_speed=True, speed_range=(29.9, 30.1))


@pytest.mark.slow
def test_constant_speed_campaign_identifies_its_bogie_and_says_why_not_its_carbody(constant_speed, tmp_path):
    """At one speed the trailing bogie's rail is the leading one's delayed copy, so the
    carbody modes (seen only through that difference) are undetermined, not guessed; the
    bogie modes, driven by the bogie's own rail, are still found."""
    root, truth = constant_speed
    out = tmp_path / "ident.json"
    assert main(["identify", str(root), "--out", str(out), "--quiet"]) == 0
    data = _strict_json(out)
    found = {m["label"]: m for m in data["modes"]}
    undetermined = {u["label"]: u for u in data["undetermined_modes"]}
    assert set(found) | set(undetermined) == set(RIGID_LABELS) and not set(found) & set(undetermined)
    for label in ("bogie_bounce", "bogie_pitch"):
        assert found[label]["frequency_hz"] == pytest.approx(truth["frequencies_hz"][label], rel=TOLERANCE[label])
    for label in ("carbody_bounce", "carbody_pitch"):
        if label in found:  # only where the FDD shows a peak, and then it must be right
            assert found[label]["frequency_hz"] == pytest.approx(truth["frequencies_hz"][label], rel=TOLERANCE[label])
        else:
            assert undetermined[label]["frequency_hz"] is None
            assert "cannot be told apart" in undetermined[label]["reason"]
    ambiguous = [ln for ln in data["spectral_lines"] if ln["kind"] == "ambiguous" and ln["exponent"] is None]
    assert ambiguous, "at one speed some lines cannot be classified; their exponent is null"
    # at one speed the track's lines stand still; between them the bogie's channels show their sensor noise
    floors = {f["channel"]: f["asd_si_per_sqrt_hz"] for f in data["data"]["noise_floors"]}
    noise = truth["noise_rms_si"]
    for name in ("bogie1_acc_z", "bogie1_gyro_pitch"):
        assert floors[name] == pytest.approx(noise[name] / math.sqrt(noise["white_up_to_hz"]), rel=0.05), name


@pytest.mark.slow
def test_short_in_service_campaign_identifies_with_exit_0(tmp_path):
    """`railcal synth in-service X --seed 3 --journeys 2 --length-km 5`, then identify: exit 0,
    no NaN in the JSON, every mode found within tolerance or reported undetermined. (Two
    journeys at 27-36 m/s barely tell the two bogies' rails apart: the carbody fit here once
    reported a 3.87 Hz pole as a 0.93 Hz carbody bounce.)"""
    root = tmp_path / "short"
    assert main(["synth", "in-service", str(root), "--seed", "3", "--journeys", "2", "--length-km", "5",
                 "--quiet"]) == 0
    truth = json.loads((tmp_path / "short.truth.json").read_text())
    out = tmp_path / "ident.json"
    assert main(["identify", str(root), "--out", str(out), "--quiet"]) == 0
    data = _strict_json(out)
    labels = [m["label"] for m in data["modes"]] + [u["label"] for u in data["undetermined_modes"]]
    assert sorted(labels) == sorted(RIGID_LABELS)
    for m in data["modes"]:
        assert m["frequency_hz"] == pytest.approx(truth["frequencies_hz"][m["label"]], rel=TOLERANCE[m["label"]])


@pytest.fixture(scope="module")
def jitter_free(tmp_path_factory):
    root, truth = _campaign(tmp_path_factory.mktemp("regular") / "campaign", 1)
    return identify_in_service(open_campaign(root)), truth


@pytest.mark.slow
@pytest.mark.parametrize("jitter_samples", [0.2, 0.24])
def test_irregular_sampling_identifies_as_well_as_regular(jitter_samples, jitter_free, tmp_path):
    """The logger samples at k/fs + u_k, u_k uniform in +-jitter, and records those instants;
    the campaign is otherwise the jitter-free one (same noise, same journeys). Expected
    before running: every mode within the tolerance the jitter-free campaign meets. The
    reader calls a step over 1.5 intervals a gap, so that a missing sample never passes for
    jitter; +-0.24 of an interval is the most jitter whose steps (<= 1.48) all stay sampling.
    +-0.2 crashed the FDD before irregular sampling was resampled."""
    regular, truth = jitter_free
    for label in RIGID_LABELS:  # the reference itself
        assert regular.mode(label).frequency_hz == pytest.approx(truth["frequencies_hz"][label], rel=TOLERANCE[label])
    root, _ = _campaign(tmp_path / "jittered", 1, time_jitter=jitter_samples / FS)
    campaign = open_campaign(root)
    run = campaign.read_run(campaign.run_ids[0])
    steps = np.diff(run.time) * FS
    assert steps.max() - steps.min() > jitter_samples  # the sampling really is irregular
    assert not run.gaps
    result = identify_in_service(campaign)
    for label in RIGID_LABELS:
        f = result.mode(label).frequency_hz
        assert f == pytest.approx(truth["frequencies_hz"][label], rel=TOLERANCE[label]), label
        assert math.isfinite(f)
    assert not result.undetermined
    json.dumps(result.to_json(), allow_nan=False)
