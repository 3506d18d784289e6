"""MAC of the in-service car calibration: the identified mode shapes (FDD at the response
channels) against the calibrated car's modes at the same channels."""
from __future__ import annotations

import json

import numpy as np
import pytest

from calibration.calibrate import pair_shapes
from calibration.data.campaign import Sensor
from calibration.data.errors import InputError
from calibration.identification.fdd import Analysis, FDDResult
from calibration.identification.in_service import IdentifiedMode
from calibration.identification.shapes import ModeShape, mode_shape
from calibration.models.car2d import build_car
from calibration.models.channel_shapes import model_shapes, response_channels
from calibration.models.vehicles import INTERCITY_TRAILER
from calibration.signals.modal import mac_matrix
from railcal.cli import main

P = INTERCITY_TRAILER
BOGIE = (Sensor("axle1_left_acc_z", "acceleration", "g", "axle1", "z", (P.L_v + P.L_b, 1.0, 0.45)),
         Sensor("bogie1_acc_z", "acceleration", "g", "bogie1", "z", (P.L_v + 0.45, 0.6, 0.7)),
         Sensor("bogie1_gyro_pitch", "angular_velocity", "deg/s", "bogie1", "pitch", (P.L_v + 0.45, 0.6, 0.7)))
FLOOR = tuple(Sensor(f"carbody_{w}_acc_z", "acceleration", "g", "carbody", "z", (x, 0.0, 1.2))
              for w, x in (("front", P.L_v), ("centre", 0.0), ("rear", -P.L_v)))


def test_mac_is_one_for_a_shape_with_itself_zero_for_an_orthogonal_one_and_blind_to_complex_scale():
    rng = np.random.default_rng(5)
    a = rng.normal(size=5) + 1j * rng.normal(size=5)
    b = rng.normal(size=5) + 1j * rng.normal(size=5)
    b_orth = b - (np.vdot(a, b) / np.vdot(a, a)) * a  # orthogonal under the Hermitian product
    assert mac_matrix(a, a)[0, 0] == pytest.approx(1.0, abs=1e-14)
    assert mac_matrix(a, b_orth)[0, 0] == pytest.approx(0.0, abs=1e-14)
    scale = 3.7 * np.exp(1j * 2.1)
    assert mac_matrix(scale * a, b)[0, 0] == pytest.approx(mac_matrix(a, b)[0, 0], rel=1e-12)
    assert mac_matrix(a, -0.2j * b)[0, 0] == pytest.approx(mac_matrix(a, b)[0, 0], rel=1e-12)
    # a real shape and its complex conjugate pair are not alike: phases count
    c = np.array([1.0, 1.0j])
    assert mac_matrix(c, np.conj(c))[0, 0] == pytest.approx(0.0, abs=1e-14)


def test_a_csd_made_by_one_model_mode_gives_back_that_modes_shape():
    """The measured quantities (accelerations, a pitch rate) of one mode at its frequency, as a
    rank-one CSD: the identified shape has MAC 1 with the model's, whatever the unit conversion
    does, and a MAC with the bogie bounce far below it (they differ in the gyro)."""
    channels = response_channels(BOGIE + FLOOR, L_v=P.L_v, L_b=P.L_b)
    assert [c.name for c in channels] == ["bogie1_acc_z", "bogie1_gyro_pitch"] + [s.name for s in FLOOR]
    modes = model_shapes(build_car(P), channels)
    pitch = next((m, v) for m, v in modes if m.name == "bogie_pitch_in_phase")
    bounce = next(v for m, v in modes if m.name == "bogie_bounce_in_phase")
    f = pitch[0].frequency_hz
    iw = 2j * np.pi * f
    # back from displacement entries to what the sensors read: a = (i w)^2 z, rate = i w theta
    measured = np.array([(iw / c.lever if c.output.kind == "pitch_rate" else iw ** 2) * v
                         for c, v in zip(channels, pitch[1])])
    grid = np.array([f - 0.01, f, f + 0.01])
    G = np.repeat(np.outer(measured, np.conj(measured))[None], 3, axis=0)
    result = FDDResult(Analysis("s", tuple(c.name for c in channels), 1, "response_shapes"), grid, np.ones((5, 3)), G,
                       1, np.array([30.0]))
    shape = mode_shape(result, channels, f)
    assert shape.frequency_hz == f and max(abs(np.array(shape.values))) == pytest.approx(1.0)
    assert mac_matrix(np.array(shape.values), pitch[1])[0, 0] == pytest.approx(1.0, abs=1e-12)
    assert mac_matrix(np.array(shape.values), bounce)[0, 0] < 0.3
    assert ModeShape.from_json(json.loads(json.dumps(shape.to_json())), "m") == shape


def test_a_malformed_shape_is_refused_naming_its_key():
    good = {"channels": ["a", "b"], "real": [1.0, 0.5], "imag": [0.0, 0.1], "levers_m": [1.0, 1.25],
            "frequency_hz": 7.0}
    assert ModeShape.from_json(None, "modes[0].shape") is None
    for bad, key in (({"real": [1.0]}, "modes[0].shape"), ({"imag": [0.0, float("nan")]}, "modes[0].shape.imag"),
                     ({"frequency_hz": -1}, "modes[0].shape.frequency_hz")):
        with pytest.raises(InputError) as e:
            ModeShape.from_json({**good, **bad}, "modes[0].shape")
        assert e.value.key == key


def _mode(label, shape_values, channels):
    shape = ModeShape(tuple(c.name for c in channels), tuple(shape_values), tuple(c.lever for c in channels), 1.0)
    return IdentifiedMode(label, 1.0, 0.1, None, "input_output_fit", "x", None, None, None, shape)


def test_a_mac_over_one_moving_channel_is_not_defined_and_says_why():
    """On the bogie alone, a carbody mode moves the bogie accelerometer and not the gyro: its
    MAC would only say how much of the measured shape lies on that channel. With one response
    channel at all, a MAC is 1 for any shape."""
    channels = response_channels(BOGIE, L_v=P.L_v, L_b=P.L_b)
    fit = [{"label": "carbody_bounce"}, {"label": "bogie_pitch"}]
    modes = [_mode("carbody_bounce", [1.0, 0.5j], channels), _mode("bogie_pitch", [-0.39, 1.0], channels)]
    rows, matrix = pair_shapes(fit, modes, P, BOGIE)
    assert rows[0]["mac"] is None and "moves bogie1_acc_z alone" in rows[0]["mac_note"]
    assert rows[1]["mac"] > 0.99 and rows[1]["mac_model_mode"] == "bogie_pitch_in_phase"
    assert matrix["excluded_channels"] == ["axle1_left_acc_z"] and "rail input" in matrix["note"]
    one = BOGIE[:2]
    rows, _ = pair_shapes(fit[1:], [_mode("bogie_pitch", [1.0], response_channels(one, L_v=P.L_v, L_b=P.L_b))],
                          P, one)
    assert rows[0]["mac"] is None and "one response channel (bogie1_acc_z)" in rows[0]["mac_note"]
    rows, matrix = pair_shapes(fit, [], P, BOGIE)
    assert matrix is None and all("no mode shape" in r["mac_note"] for r in rows)


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """A four-journey campaign with floor accelerometers (12 km line), identified and
    calibrated through the commands."""
    from calibration.truth.in_service import InServiceSettings, synth_in_service
    from calibration.truth.track import LineSpec

    out = tmp_path_factory.mktemp("mac")
    root = out / "campaign"
    synth_in_service(root, seed=11, fmt="parquet",
                     settings=InServiceSettings(journeys=4, line=LineSpec(length=12_000.0), carbody_sensors=True))
    ident, cal = out / "ident.json", out / "cal.json"
    assert main(["identify", str(root), "--out", str(ident), "--quiet"]) == 0
    assert main(["calibrate", str(root), "--identification", str(ident), "--refine", "--runs", "2", "--quiet",
                 "--out", str(cal)]) == 0
    return json.loads(ident.read_text()), json.loads(cal.read_text()), cal


@pytest.mark.slow(seconds=25)
def test_the_calibrated_cars_modes_pair_with_the_identified_shapes(calibrated):
    """Expected before the run (read off an exploratory run of the same seed with the truth's
    parameters): carbody bounce 0.99, carbody pitch 0.97, bogie pitch 1.00, each at least 0.8,
    and the other entries among the three pairs at most 0.01, asserted under 0.05 and under
    the pair's own (the bogie pitch's anti-phase
    twin is left out: on one bogie's sensors it is the in-phase member's shape). The bogie bounce has
    no MAC: the in-phase bounce moves only the bogie accelerometer (the gyro not at all, the
    floor by 2 %), and its FDD shape is the bogie pitch's (near v / 4 L_b the wheelbase filter
    takes the rail's bounce out of the bogie's input), MAC 0.13 against the bounce."""
    ident, cal, path = calibrated
    shape = ident["modes"][0]["shape"]
    assert shape["channels"] == ["bogie1_acc_z", "bogie1_gyro_pitch", "carbody_front_acc_z", "carbody_centre_acc_z",
                                 "carbody_rear_acc_z"]
    fit = {r["label"]: r for r in cal["fit"]}
    matrix = cal["mac_matrix"]
    pairs = {"carbody_bounce": "carbody_bounce", "carbody_pitch": "carbody_pitch",
             "bogie_pitch": "bogie_pitch_in_phase"}
    rows = [matrix["identified"].index(lbl) for lbl in pairs]
    cols = [matrix["model"].index(name) for name in pairs.values()]
    M = np.array(matrix["values"])[np.ix_(rows, cols)]
    for k, (lbl, name) in enumerate(pairs.items()):
        assert fit[lbl]["mac"] == pytest.approx(M[k, k]) and fit[lbl]["mac_model_mode"] == name
        assert M[k, k] >= 0.8, (lbl, M[k, k])
        others = np.concatenate([np.delete(M[k], k), np.delete(M[:, k], k)])
        assert np.all(others < M[k, k]) and np.all(others < 0.05), (lbl, M[k], M[:, k])
    assert fit["bogie_bounce"]["mac"] is None and "alone" in fit["bogie_bounce"]["mac_note"]
    assert matrix["excluded_channels"] == [f"axle{a}_{s}_acc_z" for a in (1, 2) for s in ("left", "right")]
    mac_png = path.with_name("cal_mac.png")
    assert cal["plots"] == [mac_png.name] and mac_png.stat().st_size > 0
