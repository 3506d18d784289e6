"""The variable list of each FMU: the one source of modelDescription.xml (FMI 2 and 3) and of
the C header with value references, start values and output tables (``build.py``).

Names, units and meanings of the car's variables are those of
``shared/spec/interfaces.md``; parameter names, units and descriptions come from
:data:`calibration.models.parameters.CAR_PARAMETER_SPECS`, so nothing is typed twice.
Value references are assigned in list order and unique across types (FMI 3 requires it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from calibration.models.car2d import RAIL_INPUTS
from calibration.models.parameters import CAR_PARAMETER_SPECS

# units as FMI unit names, with their SI base-unit exponents (kg, m, s, rad)
UNITS = {
    "s": {"s": 1},
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "rad/s": {"rad": 1, "s": -1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "kg": {"kg": 1},
    "kg.m2": {"kg": 1, "m": 2},
    "N/m": {"kg": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1},
    "Hz": {"s": -1},
}
_SPEC_UNIT = {"kg": "kg", "kg m^2": "kg.m2", "N/m": "N/m", "N s/m": "N.s/m", "m": "m"}

# output kinds understood by the models' C code (model_config.h's OutputSpec)
OUT_ACC, OUT_PITCH_RATE, OUT_CONTACT = 0, 1, 2
CAR_BODIES = ("carbody", "bogie1", "bogie2")


@dataclass(frozen=True)
class Variable:
    name: str
    type: str  # "Real" (FMI 3: Float64), "Boolean", "String"
    causality: str  # "independent", "parameter", "input", "output"
    variability: str  # "continuous", "tunable", "fixed"
    description: str
    unit: str | None = None
    start: float | bool | str | None = None
    output: tuple | None = None  # (kind, body index, dx [m], wheel index) for outputs
    input_rate_of: str | None = None  # an input that is the time derivative of another input
    lti_input: bool = False  # part of the model's linear-system input vector u

    def __post_init__(self):
        if self.unit is not None and self.unit not in UNITS:
            raise ValueError(f"{self.name}: unit {self.unit!r} is not defined in UNITS")


@dataclass(frozen=True)
class ModelSpec:
    """What the builder needs of one FMU: its identifier, description, source folder, the
    variable list, the linear system's sizes and the default experiment."""

    identifier: str
    description: str
    folder: str  # fmu_src/<folder>/ holds the model's C
    variables: tuple[Variable, ...]
    n_states: int
    standalone: bool
    defines: dict  # extra #defines for model_config.h (name -> C literal)
    resources: dict  # file name in resources/ -> source path
    default_step: float = 1e-3
    default_stop: float = 10.0
    data_header: str = ""  # model_data.h: the model's data tables (C), if it has any

    @property
    def inputs(self) -> tuple[Variable, ...]:
        return tuple(v for v in self.variables if v.lti_input)

    @property
    def outputs(self) -> tuple[Variable, ...]:
        return tuple(v for v in self.variables if v.causality == "output")

    def value_reference(self, name: str) -> int:
        for k, v in enumerate(self.variables):
            if v.name == name:
                return k
        raise KeyError(f"{self.identifier} has no variable {name!r}")


def _ordered(variables: list[Variable]) -> tuple[Variable, ...]:
    """Reals first, then Booleans, then Strings (the C layer's value-reference ranges)."""
    order = {"Real": 0, "Boolean": 1, "String": 2}
    out = tuple(sorted(variables, key=lambda v: order[v.type]))  # stable: list order within a type
    names = [v.name for v in out]
    if len(set(names)) != len(names):
        raise ValueError(f"duplicate variable names: {sorted({n for n in names if names.count(n) > 1})}")
    return out


def rail_inputs() -> list[Variable]:
    """The rail level under wheelsets 1-4 (1 leads) and its rates: the wheel inputs of every
    vehicle FMU (shared/spec/interfaces.md)."""
    levels = [Variable(rail, "Real", "input", "continuous",
                       f"rail level under wheelset {j} ({'leading' if j % 2 else 'trailing'} wheelset "
                       f"of bogie {(j + 1) // 2})", "m", 0.0, lti_input=True)
              for j, rail in enumerate(RAIL_INPUTS, start=1)]
    return levels + [Variable(f"d{rail}", "Real", "input", "continuous", f"time derivative of {rail}", "m/s", 0.0,
                              input_rate_of=rail, lti_input=True) for rail in RAIL_INPUTS]


class TrackTooShort(ValueError):
    """The track profile to ship cannot hold every wheelset of the vehicle at once."""


def default_track_start(track, wheelset_offsets) -> float:
    """The carbody centre's track distance [m] that puts the rearmost wheelset on the first
    point of the profile ``track`` (a track CSV), every wheelset on the profile.

    ``wheelset_offsets``: [m] ahead of the carbody centre, computed as the FMU's C computes
    them, so that ``start + offset`` lands on the profile in the FMU's own arithmetic.
    :class:`TrackTooShort` when the profile is shorter than the wheelset span."""
    from calibration.data.campaign import read_track_file

    rec = read_track_file(Path(track))
    first, last = float(rec.distance[0]), float(rec.distance[-1])
    rear, front = float(min(wheelset_offsets)), float(max(wheelset_offsets))
    start = first - rear
    while start + rear < first:  # the subtraction may round down by an ulp
        start = math.nextafter(start, math.inf)
    if start + front > last:
        raise TrackTooShort(f"the track profile covers {first:.3f}-{last:.3f} m, shorter than the vehicle's "
                            f"wheelset span of {front - rear:.3f} m")
    return start


def standalone_variables(track_file: str | None, track_start: float = 0.0) -> list[Variable]:
    """Stand-alone running over a track profile: the speed input, the start position, the
    switch (on by default when a track is shipped in resources/) and the profile file.
    ``track_start``: the default start, :func:`default_track_start` of the shipped track."""
    return [
        Variable("speed", "Real", "input", "continuous", "vehicle speed in stand-alone running", "m/s", 0.0),
        Variable("track_start", "Real", "parameter", "fixed",
                 "stand-alone: track distance of the carbody centre at the start time (default: the rearmost "
                 "wheelset on the shipped profile's first point); running off either end of the profile is an "
                 "error", "m", float(track_start)),
        Variable("standalone", "Boolean", "parameter", "fixed",
                 "run over track_file at the input speed instead of taking the rail inputs",
                 start=track_file is not None),
        Variable("track_file", "String", "parameter", "fixed",
                 "stand-alone: track profile CSV (distance, level), a path or a name in resources/",
                 start=track_file or ""),
    ]


def car2d_variables(parameters: dict[str, float], *, track_file: str | None = None,
                    sensors: tuple = (), track_start: float = 0.0, extras: tuple = ()) -> tuple[Variable, ...]:
    """The car FMU's variables: ``parameters`` (calibrated values, SI) become the tunable
    parameters' start values, ``extras`` (:func:`extras_variables`) follow them; ``sensors``
    adds an acceleration output per calibrated sensor position, as (name, body, dx [m] from
    the body centre); ``track_file`` (a name in resources/) makes stand-alone running the
    default, from ``track_start`` [m]."""
    missing = sorted(set(CAR_PARAMETER_SPECS) - set(parameters))
    if missing:
        raise ValueError(f"the calibration lacks car parameter(s) {', '.join(missing)}")
    v: list[Variable] = [Variable("time", "Real", "independent", "continuous", "simulation time", "s")]
    for name, spec in CAR_PARAMETER_SPECS.items():
        v.append(Variable(name, "Real", "parameter", "tunable", spec.description, _SPEC_UNIT[spec.unit],
                          float(parameters[name])))
    v += list(extras)
    v += rail_inputs()
    for b, body in enumerate(CAR_BODIES):
        v.append(Variable(f"{body}_acc_z", "Real", "output", "continuous",
                          f"vertical acceleration of the {body} centre of mass", "m/s2", output=(OUT_ACC, b, 0.0, -1)))
        v.append(Variable(f"{body}_pitch_rate", "Real", "output", "continuous", f"pitch rate of the {body}", "rad/s",
                          output=(OUT_PITCH_RATE, b, 0.0, -1)))
    for j in range(1, 5):
        v.append(Variable(f"contact_force_{j}", "Real", "output", "continuous",
                          f"vertical wheel-rail force at wheelset {j}, static load included", "N",
                          output=(OUT_CONTACT, -1, 0.0, j - 1)))
    for name, body, dx in sensors:
        v.append(Variable(f"sensor_{name}", "Real", "output", "continuous",
                          f"vertical acceleration at the calibrated sensor {name} ({body}, {dx:+.3f} m)", "m/s2",
                          output=(OUT_ACC, CAR_BODIES.index(body), float(dx), -1)))
    v += standalone_variables(track_file, track_start)
    return _ordered(v)


#: The extended model's additions as FMU parameters: (calibration file's extras name, unit,
#: description), by the model_config.h switch that brings them in (car2d/model.c).
EXTRAS_VARIABLES = {
    "CAR_COG": (("cog_offset", "m", "carbody centre of mass ahead (+) of its geometric centre"),),
    "CAR_BENDING": (
        ("bending_hz", "Hz", "carbody first vertical bending, free-free natural frequency"),
        ("bending_damping", None, "carbody bending modal damping ratio"),
        ("bending_mass_ratio", None, "carbody bending generalised mass / m_v (shape 1 at the ends)"),
        ("bending_node", None, "carbody bending nodes at +- this fraction of the half-length"),
        ("carbody_length", "m", "carbody length the bending shape spans")),
    "CAR_RESERVOIR": (
        ("reservoir_ratio", None, "air-spring reservoir branch stiffness / k_s"),
        ("reservoir_corner_hz", "Hz", "reservoir orifice corner frequency k_r / (2 pi c_o)"),
        ("node_mass", "kg", "mass of the node between reservoir stiffness and orifice")),
    "CAR_TRACK": (
        ("track_stiffness", "N/m", "track stiffness under each wheelset"),
        ("track_damping_ratio", None, "track damping / the track mass's critical damping on its stiffness"),
        ("track_mass", "kg", "rail and sleeper mass under each wheelset, below the wheel-rail contact")),
}
HUNG_VARIABLES = (("mass", "kg", "mass"), ("x", "m", "position ahead of the carbody's middle"),
                  ("mount_stiffness", "N/m", "mount stiffness"), ("mount_damping", "N.s/m", "mount damping"))


def extras_variables(extras) -> tuple[list[Variable], dict, int]:
    """The FMU parameters, model_config.h switches and extra coordinates of an extended car
    (:class:`~calibration.models.car2d.CarExtras`): each addition's fields as tunable
    parameters named as in the calibration file's ``extras``; a hung body's as
    ``<name>_mass``, ``<name>_x``, ``<name>_mount_stiffness``, ``<name>_mount_damping``."""
    from calibration.models.assembly import UNIFORM_BEAM_NODE
    from calibration.models.car2d import extras_to_json

    present = {"CAR_COG": extras.cog_offset != 0.0, "CAR_BENDING": extras.bending_hz is not None,
               "CAR_RESERVOIR": extras.reservoir_ratio > 0, "CAR_TRACK": extras.track_stiffness is not None}
    value = {"bending_node": UNIFORM_BEAM_NODE if extras.bending_node is None else extras.bending_node}
    variables, defines = [], {}
    for switch, fields in EXTRAS_VARIABLES.items():
        defines[switch] = "1" if present[switch] else "0"
        if present[switch]:
            variables += [Variable(name, "Real", "parameter", "tunable", description, unit,
                                   float(value.get(name, getattr(extras, name)))) for name, unit, description in fields]
    hung = extras_to_json(extras).get("hung_bodies", [])
    for h in hung:
        variables += [Variable(f"{h['name']}_{key}", "Real", "parameter", "tunable",
                               f"{description} of the body {h['name']} hung under the carbody", unit, float(h[key]))
                      for key, unit, description in HUNG_VARIABLES]
    defines["CAR_N_HUNG"] = str(len(hung))
    defines["CAR_HUNG_IN_M_V"] = "1" if extras.hung_in_m_v else "0"
    if hung:
        defines["CAR_HUNG_VRS"] = "{" + ", ".join(
            "{" + ", ".join(f"VR_{h['name']}_{key}" for key, _, _ in HUNG_VARIABLES) + "}" for h in hung) + "}"
    coordinates = int(present["CAR_BENDING"]) + 2 * int(present["CAR_RESERVOIR"]) + 4 * int(present["CAR_TRACK"]) \
        + len(hung)
    return variables, defines, coordinates


def car_wheelset_offsets(parameters: dict[str, float]) -> tuple[float, ...]:
    """[m] of wheelsets 1..4 ahead of the carbody centre, as car2d/model.c's ``geometry``
    computes them."""
    Lv, Lb = float(parameters["L_v"]), float(parameters["L_b"])
    return (Lv + Lb, Lv - Lb, -Lv + Lb, -Lv - Lb)


def car2d_spec(parameters: dict[str, float], *, track: str | None = None, sensors: tuple = (),
               extras=None) -> ModelSpec:
    """The car FMU; ``track``: a track profile CSV to ship in resources/ for stand-alone runs
    (the default ``track_start`` puts the car on its start); ``extras``: the extended model's
    additions (:class:`~calibration.models.car2d.CarExtras`), None for the seed's car."""
    from calibration.models.car2d import GRAVITY, CarExtras

    resources = {"track.csv": track} if track else {}
    start = default_track_start(track, car_wheelset_offsets(parameters)) if track else 0.0
    added, defines, coordinates = extras_variables(CarExtras() if extras is None else extras)
    variables = car2d_variables(parameters, track_file="track.csv" if track else None, sensors=sensors,
                                track_start=start, extras=added)
    description = "2D railway car (carbody, two bogies, four wheelsets on the rail), calibrated by railcal"
    if added:
        description += f", extended by its diagnosis ({', '.join(v.name for v in added)})"
    return ModelSpec("railcal_car2d", description, "car2d", variables, n_states=2 * (6 + coordinates),
                     standalone=True, defines={"MODEL_GRAVITY": repr(GRAVITY), **defines}, resources=resources)


def trivial_spec(n_outputs: int = 1) -> ModelSpec:
    """A one-state lag, y' = (u - y) / tau, read by ``n_outputs`` outputs y_1..: the yardstick
    for an importer's own cost per step (give it as many outputs as the FMU it is compared with)."""
    v = [Variable("time", "Real", "independent", "continuous", "simulation time", "s"),
         Variable("tau", "Real", "parameter", "fixed", "time constant", "s", 0.1),
         Variable("u", "Real", "input", "continuous", "input", "m", 0.0, lti_input=True)]
    v += [Variable(f"y_{k}", "Real", "output", "continuous", "the lag's state", "m", output=(OUT_ACC, 0, 0.0, -1))
          for k in range(1, n_outputs + 1)]
    return ModelSpec("railcal_trivial", "one-state lag (importer overhead yardstick)", "trivial", _ordered(v),
                     n_states=1, standalone=False, defines={}, resources={})
