"""Where the model's rail input comes from when a leading wheelset is out of round: its
axle boxes carry its polygon, which the trailing bogie's wheels do not have, so a trailing
wheelset without axle boxes takes the rail the round wheelset measured."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from calibration.data.runs import Run
from calibration.diagnosis.in_service.records import Layout, Record, RecordSettings, read_records
from calibration.diagnosis.in_service.wheels import fit_polygon, polygon_error
from calibration.models.car2d import Output

L_V, L_B, V, FS = 9.5, 1.25, 30.0, 400.0
RAIL = ((7.3, 1.1e-3, 0.4), (3.1, 0.4e-3, 2.0), (13.7, 2.0e-3, 5.1))  # wavelength [m], amplitude [m], phase
POLYGON = (0.7, 0.5)  # wavelength [m], acceleration amplitude [m/s^2]


def _rail_acc(d: np.ndarray) -> np.ndarray:
    """The rail's vertical acceleration under a wheel at distance d, at the constant speed V."""
    return sum(-a * (2 * np.pi * V / w) ** 2 * np.cos(2 * np.pi * d / w + p) for w, a, p in RAIL)


def _layout(out_of_round=None) -> Layout:
    return Layout(axle={"axle1": ("a1",), "axle2": ("a2",), "axle3": (), "axle4": ()},
                  responses=(Output("b1", "acceleration", "bogie1", L_V),), response_sensors=(),
                  L_v=L_V, L_b=L_B, length=23.0, out_of_round=out_of_round)


def _campaign(polygon_on: int):
    """One 120 s run at constant speed: the leading wheelsets' axle boxes read the rail under
    them, wheelset ``polygon_on`` its polygon on top."""
    t = np.arange(0.0, 120.0, 1 / FS)
    d = V * t
    line = POLYGON[1] * np.cos(2 * np.pi * d / POLYGON[0])
    a1, a2 = _rail_acc(d), _rail_acc(d - 2 * L_B)
    channels = {"a1": a1 + line * (polygon_on == 1), "a2": a2 + line * (polygon_on == 2), "b1": np.zeros_like(t)}
    run = Run("r1", None, t, channels, {k: np.ones(t.size, bool) for k in channels}, ((0, t.size),), (),
              distance=d, speed=np.full(t.size, V))
    return SimpleNamespace(meta=SimpleNamespace(sampling_rate=FS), run_ids=("r1",), read_run=lambda _: run,
                           root=None)


def _polygon_left(rec, row: int, behind: float) -> float:
    """rms of what row ``row`` carries beyond the rail a wheelset ``behind`` metres behind
    wheelset 1 runs on, over the polygon's rms (the ends, where resampling rings, left out)."""
    inner = slice(400, -400)
    rail = _rail_acc(rec.distance - behind)
    err = (rec.z[row] - rec.z[row][inner].mean()) - (rail - rail[inner].mean())
    return float(np.sqrt(np.mean(err[inner] ** 2)) / (POLYGON[1] / np.sqrt(2)))


def test_each_wheelsets_rail_comes_from_a_leading_wheelset_as_far_ahead_as_the_delay():
    behind = {"axle1": 0.0, "axle2": 2 * L_B, "axle3": 2 * L_V, "axle4": 2 * L_V + 2 * L_B}
    for w in (None, 1, 2):
        for k, src, delay in _layout(w).rail_sources():
            assert delay == pytest.approx(behind[k] - behind[src or k])
            assert src != f"axle{w}"  # a trailing wheelset never takes the out-of-round one's axle boxes


@pytest.mark.parametrize("w", [1, 2])
def test_a_polygon_found_on_a_leading_wheelset_stays_out_of_the_trailing_bogies_input(w):
    settings = RecordSettings()
    behind = (0.0, 2 * L_B, 2 * L_V, 2 * L_V + 2 * L_B)
    trailing = {1: 2, 2: 3}[w]  # rows of rail_acc_3, rail_acc_4: the one taken from wheelset w by default
    before = read_records(_campaign(w), _layout(), settings)[0]
    after = read_records(_campaign(w), _layout(out_of_round=w), settings)[0]
    assert _polygon_left(before, trailing, behind[trailing]) > 0.9  # the polygon driven into the trailing bogie
    for row in (2, 3):
        assert _polygon_left(after, row, behind[row]) < 0.02
    # a longer delay (wheelset 4 from wheelset 1) costs the record the wheelbase at its start, no more
    assert 0.0 <= after.distance[0] - before.distance[0] <= 2 * L_B + V / settings.fs


def test_a_polygon_of_several_orders_is_fitted_as_one_wheels_harmonics():
    """A wheel of circumference 2.64 m out of round in orders 2 and 4 (0.2 and 0.08 mm):
    order 4 is the stronger line in curvature (amplitude x order^2), order 2 the larger
    radius deviation. Both are the wheel's, and removing both leaves the noise."""
    rng = np.random.default_rng(4)
    fs, v, c = 200.0, 30.0, 2.64
    t = np.arange(0, 400.0, 1 / fs)
    d = v * t
    orders = {2: 0.2e-3, 4: 0.08e-3}  # radius amplitude [m] per order
    curvature = sum(a * (2 * np.pi * m / c) ** 2 * np.cos(2 * np.pi * m * d / c + m) for m, a in orders.items())
    noise = rng.normal(0, 0.05, (3, t.size))
    z = np.vstack([curvature * v * v + noise[0], noise[1], curvature * v * v + noise[2]])  # carried by wheelset 2
    rows = {"consistency": 0, "axle1_mean": 1, "axle2_mean": 2}
    rec = Record("r1", 0.0, np.full(t.size, v), d, z)
    poly = fit_polygon([rec], rows, {"r1"})
    assert poly.wheelset == 2
    assert poly.wavelength == pytest.approx(c / 4, rel=0.005)  # the strongest line in curvature
    assert poly.circumference == pytest.approx(c, rel=0.005)
    radii = {round(c / w): r["radius_amplitude_m"] for w, r in zip((w for w, _ in poly.lines),
                                                                      poly.to_json()["harmonics"])}
    assert radii[2] == pytest.approx(orders[2], rel=0.05) and radii[4] == pytest.approx(orders[4], rel=0.05)
    assert poly.radius_amplitude == pytest.approx(orders[2], rel=0.05)
    one_line = type(poly)(poly.wavelength, poly.curvature_amplitude, 2, 0.0, 0.0)
    noise_only = np.mean(noise[0] ** 2 / v ** 4)
    assert polygon_error([rec], rows, {"r1"}, poly) < 1.5 * noise_only < polygon_error([rec], rows, {"r1"}, one_line)
