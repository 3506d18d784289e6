"""The box vehicle with an excitation-test diagnosis's extension built in, so that the
extended model a diagnosis names is a vehicle description like the calibrated one: its FRFs,
its reduction for the FMU and its exudyn build all follow from :class:`BoxVehicle` (docs/
methods/diagnosis-excitation.md, "The extended model").

A calibration file's ``extension`` ({``name``, ``parameters``}, as ``railcal diagnose``
writes it) is one of:

* ``underfloor_equipment``: a rigid body of ``equipment_mass_kg`` held to vertical motion on a
  vertical spring-damper (``mounting_frequency_hz``, ``mounting_damping_ratio``) from the floor
  point (``mount_x_m``, ``mount_y_m``), as the diagnosis fits it;
* ``local_panel_softening``: ``panel``'s rigidities divided by ``rigidity_divisor``, which
  is the diagnosis's K(p) - (1 - 1/s) (K0_P + sum_i p_i K_P,i): a panel's energy is linear in
  its rigidities;
* ``force_calibration``: the exciter's load cell reads ``force_gain`` times the applied force;
  the structure is unchanged and a model driven by the reading applies reading / gain
  (:func:`force_gain`).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from ...data.errors import InputError
from .assembly import BoxVehicle, Link, RigidBody

EQUIPMENT, SOFTENING, FORCE = "underfloor_equipment", "local_panel_softening", "force_calibration"
#: each extension's parameters, as the diagnosis names them (numbers unless listed in TEXT)
PARAMETERS = {
    EQUIPMENT: ("equipment_mass_kg", "mounting_frequency_hz", "mounting_damping_ratio", "mount_x_m", "mount_y_m"),
    SOFTENING: ("panel", "rigidity_divisor"),
    FORCE: ("force_gain",),
}
TEXT = ("panel",)
#: what the diagnosis writes beside them for the reader (the equipment's mass over the
#: carbody's), accepted and not used
INFORMATIVE = ("mass_ratio",)
#: the equipment's rotations and horizontal motion are held (the diagnosis's mount is a
#: vertical spring-damper); its inertia only keeps a multibody code's mass matrix regular
EQUIPMENT_HELD = ("x", "y", "roll", "pitch", "yaw")
#: [m] radius of gyration given to the held rotations
EQUIPMENT_GYRATION = 0.5


def extension_of(calibration: Mapping) -> tuple[str, dict] | None:
    """(name, parameters) of a calibration's ``extension``, checked; None without one.
    InputError naming the key for an unknown name, a missing or non-positive number."""
    ext = calibration.get("extension")
    if ext is None:
        return None
    if not isinstance(ext, Mapping) or not isinstance(ext.get("parameters"), Mapping):
        raise InputError("'extension' must have a 'name' and a 'parameters' table", key="extension")
    name, given = ext.get("name"), ext["parameters"]
    if name not in PARAMETERS:
        raise InputError(f"extension {name!r} unknown to the box model; known: {', '.join(PARAMETERS)}",
                         key="extension.name")
    unknown = sorted(set(given) - set(PARAMETERS[name]) - set(INFORMATIVE))
    if unknown:
        raise InputError(f"extension {name}: unknown parameter(s) {', '.join(map(str, unknown))}; known: "
                         f"{', '.join(PARAMETERS[name])}", key=f"extension.{unknown[0]}")
    out = {}
    for key in PARAMETERS[name]:
        v = given.get(key)
        if key in TEXT:
            if not isinstance(v, str):
                raise InputError(f"extension {name}: '{key}' must name a panel, got {v!r}", key=f"extension.{key}")
        elif isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or (
                not key.startswith("mount_") and v <= 0):
            what = "finite" if key.startswith("mount_") else "positive"
            raise InputError(f"extension {name}: '{key}' must be a {what} number, got {v!r}", key=f"extension.{key}")
        out[key] = v if key in TEXT else float(v)
    return name, out


def force_gain(calibration: Mapping) -> float:
    """The exciter load cell's gain the calibration's extension states (1 without one)."""
    ext = extension_of(calibration)
    return ext[1]["force_gain"] if ext is not None and ext[0] == FORCE else 1.0


def floor_host(vehicle: BoxVehicle, point) -> str:
    """The first floor panel (in the vehicle's order) holding ``point``, as a floor sensor
    there is seated."""
    floor = [pn for pn in vehicle.panels if pn.group == "floor"]
    for pn in floor:
        try:
            pn.local(point)
        except ValueError:
            continue
        return pn.name
    x = [pn.centre[0] + s * pn.a / 2 for pn in floor for s in (-1, 1)]
    off = "mount_x_m" if not min(x) <= point[0] <= max(x) else "mount_y_m"
    raise InputError(f"the mount point {tuple(float(c) for c in point[:2])} m is on no floor panel "
                     f"(x {min(x):g} to {max(x):g} m, |y| up to {max(pn.b for pn in floor) / 2:g} m)",
                     key=f"extension.{off}")


def extend_vehicle(vehicle: BoxVehicle, calibration: Mapping) -> BoxVehicle:
    """``vehicle`` with the calibration's extension built in (itself without one, or for a
    load cell's gain, which is not the vehicle's)."""
    ext = extension_of(calibration)
    if ext is None or ext[0] == FORCE:
        return vehicle
    name, p = ext
    if name == SOFTENING:
        panel = p["panel"]
        if panel not in {pn.name for pn in vehicle.panels}:
            raise InputError(f"extension {name}: no panel {panel!r}; have "
                             f"{', '.join(pn.name for pn in vehicle.panels)}", key="extension.panel")
        s = p["rigidity_divisor"]
        return replace(vehicle, panels=tuple(
            replace(pn, rigidity={k: v / s for k, v in pn.rigidity.items()}) if pn.name == panel else pn
            for pn in vehicle.panels))
    z = next(pn.centre[2] for pn in vehicle.panels if pn.name == "floor_middle")
    point = (p["mount_x_m"], p["mount_y_m"], z)
    host = floor_host(vehicle, point)
    m = p["equipment_mass_kg"]
    k = m * (2 * np.pi * p["mounting_frequency_hz"]) ** 2
    c = 2 * p["mounting_damping_ratio"] * np.sqrt(k * m)
    body = RigidBody(EQUIPMENT, m, (m * EQUIPMENT_GYRATION**2,) * 3, point, fixed=EQUIPMENT_HELD)
    mount = Link(f"{EQUIPMENT}_mount", "equipment_mount", host, point, EQUIPMENT, point, (0.0, 0.0, k),
                 (0.0, 0.0, c))
    return replace(vehicle, bodies=vehicle.bodies + (body,), links=vehicle.links + (mount,))
