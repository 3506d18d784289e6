"""The reference floor grid of the box vehicle's stationary excitation test.

The seed's Figure 4 (its measurement points) is not available to us, so this grid is our
assumption, stated once. It is what typed targets are matched against when no campaign
gives sensor positions, and what railcal's synthetic test records. A campaign's own sensors
replace it everywhere else.
"""
from __future__ import annotations

import numpy as np

from ...data.campaign import Sensor
from .shinkansen import Geometry

GEOMETRY = Geometry()

#: Floor accelerometers: vertical, on the floor (z = floor_z), at 9 stations
#: x = +11.2 .. -11.2 m (step 2.8 m; station 01 at the front, the bogie-1 end) on 3 lines
#: y = +1.2 (l, left), 0 (c), -1.2 m (r, right). Named ``acc_f<station>_<line>``, e.g.
#: ``acc_f01_l``, in station-major order; in m/s^2, AC coupled (no gravity).
SENSOR_GRID: tuple[Sensor, ...] = tuple(
    Sensor(f"acc_f{i + 1:02d}_{line}", "acceleration", "m/s^2", "floor", "z",
           (round(11.2 - 2.8 * i, 1), y, GEOMETRY.floor_z))
    for i in range(9) for line, y in (("l", 1.2), ("c", 0.0), ("r", -1.2)))

#: The exciter pushes the floor up from below at a point off every symmetry line, so
#: bending, torsion and breathing modes all respond. Positive force is upward (+z).
EXCITER = Sensor("exciter_force", "force", "N", "floor", "z", (5.6, 0.8, GEOMETRY.floor_z))


def point_record(sensor: Sensor) -> dict:
    """A measurement point as a calibration file stores it (SI, vehicle frame)."""
    return {"name": sensor.name, "body": sensor.body, "direction": sensor.direction,
            "position": [float(x) for x in sensor.position]}


def points_from_calibration(calibration: dict) -> tuple[tuple[Sensor, ...], Sensor]:
    """The sensors and the exciter a box calibration was fitted at (its ``sensors`` and
    ``exciter`` keys). InputError naming the key when they are missing or malformed."""
    from ...data.errors import InputError

    def point(row, key: str, quantity: str, unit: str) -> Sensor:
        try:
            position = tuple(float(x) for x in row["position"])
            if len(position) != 3 or not all(map(np.isfinite, position)):
                raise ValueError("position must be three finite numbers [m]")
            return Sensor(str(row["name"]), quantity, unit, str(row.get("body", "floor")),
                          str(row.get("direction", "z")), position)
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(f"malformed measurement point {row!r}: {e}", key=key) from None

    rows, exciter = calibration.get("sensors"), calibration.get("exciter")
    if not rows or not isinstance(rows, list) or not isinstance(exciter, dict):
        raise InputError("the box calibration names no measurement points (keys 'sensors' and 'exciter'); "
                         "give the campaign (--campaign) to take them from its sensors", key="sensors")
    sensors = tuple(point(r, "sensors", "acceleration", "m/s^2") for r in rows)
    return sensors, point(exciter, "exciter", "force", "N")
