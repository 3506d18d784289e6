"""The floor-sensor extension (issue 31): carbody floor accelerometers off their declared x
and off their calibration, one position error and one gain per sensor. A sensor moved by
dx reads what a sensor declared at x + dx reads; a placement within a drawing's tolerance
is the installation's, not a fault; a calibration file carries the positions on to the FMU."""
from __future__ import annotations

import numpy as np
import pytest

from calibration.diagnosis.in_service.extensions import (EXTENSIONS, FLOOR_FAULT_M, FLOOR_GAIN_ERROR,
                                                         FLOOR_PLACED_WITHIN_M, combined)
from calibration.diagnosis.in_service.records import Layout
from calibration.diagnosis.in_service.response import SensorModel, transfer
from calibration.models.car2d import CarExtras, Output, floor_sensors_from_json, sensor_model_from_json
from calibration.models.parameters import CarParameters

FLOOR = EXTENSIONS["floor_sensor_offset"]


def _layout(carbody_x=(9.0, 0.0, -9.0), extra=()) -> Layout:
    outs = [Output("bogie1_acc_z", "acceleration", "bogie1", 10.0), Output("bogie1_gyro", "pitch_rate", "bogie1")]
    outs += [Output(f"floor_{i}", "acceleration", "carbody", x) for i, x in enumerate(carbody_x)]
    outs += list(extra)
    return Layout(axle={"axle1": ("a1",), "axle2": ("a2",), "axle3": (), "axle4": ()}, responses=tuple(outs),
                  response_sensors=(), L_v=9.5, L_b=1.25, length=23.0)


def test_the_extension_has_a_position_and_a_gain_per_floor_accelerometer_and_none_without_one():
    ext = FLOOR.on(_layout(extra=(Output("carbody_gyro", "pitch_rate", "carbody"),)))
    assert [r.name for r in ext.params] == [f"{k}:floor_{i}" for i in range(3) for k in ("dx", "gain")]
    assert ext.n_params == 6 and ext.on(_layout()) is ext
    gains = [r for r in ext.params if r.name.startswith("gain:")]
    assert all(r.low == pytest.approx(1 - FLOOR_GAIN_ERROR) and r.high == pytest.approx(1 + FLOOR_GAIN_ERROR)
               for r in gains)
    assert FLOOR.on(_layout(carbody_x=())) is None  # the seed's own sensor set: nothing to act on
    assert EXTENSIONS["cog_offset"].on(_layout()) is EXTENSIONS["cog_offset"]


def test_a_moved_floor_sensor_reads_what_a_sensor_declared_there_reads_times_its_gain():
    p = CarParameters(m_v=38_000.0, J_v=1.1e6, m_b=3_000.0, J_b=3_500.0, m_w=1_400.0, k_p=2.8e6, c_p=29_000.0,
                      k_s=0.9e6, c_s=45_000.0, L_v=9.5, L_b=1.25)
    extras = CarExtras(bending_hz=9.0)  # the bending's shape must move with the sensor too
    f = np.linspace(0.5, 20.0, 40)
    lay = _layout()
    ext = FLOOR.on(lay)
    _, sensors = ext.make({"dx:floor_0": 0.8, "gain:floor_0": 1.03, "dx:floor_2": -0.4, "gain:floor_2": 1.0,
                           "dx:floor_1": 0.0, "gain:floor_1": 0.98})
    moved = transfer(p, extras, sensors, lay, f)
    there = transfer(p, extras, SensorModel(), _layout(carbody_x=(9.8, 0.0, -9.4)), f)
    scale = np.array([1.0, 1.0, 1.03, 0.98, 1.0])[None, :, None]
    np.testing.assert_allclose(moved, there * scale, rtol=1e-12, atol=1e-15 * np.abs(there).max())


def test_a_floor_sensor_within_a_drawings_tolerance_is_the_installation_not_a_fault():
    ext = FLOOR.on(_layout())
    placed = {"dx:floor_0": 0.5 * FLOOR_PLACED_WITHIN_M, "dx:floor_1": -0.05, "dx:floor_2": 0.0,
              "gain:floor_0": 1.04, "gain:floor_1": 0.97, "gain:floor_2": 1.0}
    assert ext.is_property(placed) and ext.in_between(placed) is None
    between = {**placed, "dx:floor_2": -0.5 * (FLOOR_PLACED_WITHIN_M + FLOOR_FAULT_M)}
    assert not ext.is_property(between) and "smallest fault" in ext.in_between(between)
    fault = {**placed, "dx:floor_1": 1.01 * FLOOR_FAULT_M}
    assert not ext.is_property(fault) and ext.in_between(fault) is None
    assert "installation's tolerance" in ext.normal_words()


def test_a_floor_finding_and_a_bogie_sensor_finding_combine_without_losing_either():
    lay = _layout()
    both = combined(EXTENSIONS["sensor_offset"], FLOOR.on(lay))
    _, sensors = both.make({"dx": 0.7, "gyro_gain": 1.02, "dx:floor_0": 0.5, "gain:floor_0": 1.0,
                            "dx:floor_1": 0.0, "gain:floor_1": 1.0, "dx:floor_2": 0.0, "gain:floor_2": 1.0})
    assert sensors.dx == 0.7 and sensors.gyro_gain == 1.02
    assert dict((n, (dx, g)) for n, dx, g in sensors.floor)["floor_0"] == (0.5, 1.0)


def test_a_calibration_files_floor_sensors_are_checked_and_read():
    data = {"bogie_dx": 0.0, "gyro_gain": 1.0, "floor": {"floor_0": {"dx_m": 0.6, "gain": 1.02}}}
    assert sensor_model_from_json(data) == (0.0, 1.0)
    assert floor_sensors_from_json(data) == {"floor_0": (0.6, 1.02)}
    assert floor_sensors_from_json(None) == {}
    for bad in ({"floor": [0.6]}, {"floor": {"floor_0": {"dx_m": 0.6}}},
                {"floor": {"floor_0": {"dx_m": float("nan"), "gain": 1.0}}},
                {"floor": {"floor_0": {"dx_m": 0.1, "gain": 0.0}}}):
        with pytest.raises(ValueError, match="sensor_model.floor"):
            sensor_model_from_json(bad)


def test_the_fmus_floor_outputs_sit_where_the_calibration_file_puts_the_sensors():
    from types import SimpleNamespace

    from fmu_src.export import car_sensors

    p = CarParameters(m_v=38_000.0, J_v=1.1e6, m_b=3_000.0, J_b=3_500.0, m_w=1_400.0, k_p=2.8e6, c_p=29_000.0,
                      k_s=0.9e6, c_s=45_000.0, L_v=9.5, L_b=1.25)
    sensor = lambda name, body, x: SimpleNamespace(name=name, body=body, quantity="acceleration",  # noqa: E731
                                                   direction="z", position=(x, 0.0, 0.0))
    campaign = SimpleNamespace(meta=SimpleNamespace(sensors=(sensor("floor_0", "carbody", 9.0),
                                                             sensor("floor_1", "carbody", 0.0),
                                                             sensor("bogie1_acc_z", "bogie1", 10.0))))
    rows = car_sensors(campaign, p, None, bogie_dx=0.2, floor={"floor_0": (0.6, 1.02)})
    assert [r[:2] for r in rows] == [("floor_0", "carbody"), ("floor_1", "carbody"), ("bogie1_acc_z", "bogie1")]
    assert [r[2] for r in rows] == pytest.approx([9.6, 0.0, 0.7], abs=1e-12)
