"""The registry of model extensions: one per cause in the effects catalogue, each a
physical addition to the 2D car or its sensors with its own parameters and ranges.

``kind`` says which part of the data the extension changes and therefore which error
measures it: ``response`` (bogie and carbody channels predicted from the rail input,
:mod:`.response`), ``wheel`` (the axle-box consistency channel, :mod:`.wheels`) or
``track`` (the axle boxes' spectra over speed, :mod:`.track`). Adding a cause is an entry
of :data:`EXTENSIONS` and the evidence that speaks for it (:func:`.evidence.scores`).
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Callable

import numpy as np

from ...models.car2d import CarExtras, hung_body
from .amplitude import FRICTION
from .records import Layout
from .response import ParamRange, SensorModel

KINDS = ("response", "wheel", "track")
#: The effects catalogue's carbody bending is 6-12 Hz: a carbody soft enough that its first
#: bending sits among the suspension's and bogies' modes. Design practice asks a passenger
#: carbody's first vertical bending to stay above about 10 Hz; every carbody bends somewhere,
#: so a bending found above the catalogue's range is this carbody's property, not a fault.
BENDING_FAULT_HZ = 12.0
#: Largest scale-factor error of a pitch gyro the sensor extension fits: a few per cent is
#: what a rate gyro's data sheet and an in-service calibration leave. Wider (0.6-1.6 before),
#: the gain absorbed what the 2D bogie does not model (a 0.78 gain on every development
#: campaign of the independent truth, whose gyros are within 3 %) and named it an offset.
GYRO_SCALE_ERROR = 0.05
#: Where a carbody's first bending has its nodes, as a fraction of the half-length from the
#: centre: 0.55 for a uniform beam; heavy ends (cabs, end equipment, the bogie pivots)
#: move them inwards, a heavy middle outwards.
BENDING_NODE_RANGE = (0.35, 0.75)
#: A bogie sensor found this close to its declared x is where the drawing puts it (a
#: mounting tolerance; the catalogue's offsets are 0.3-1.5 m): what the extension then gains
#: is its gyro's scale error within GYRO_SCALE_ERROR, the sensor's calibration, not a fault.
SENSOR_PLACED_WITHIN_M = 0.1
#: A carbody's centre of mass found this close to its middle [m] is its design's and its
#: load's (underfloor equipment and tanks are never quite symmetric: the library's intercity
#: car, its powerpack 1.5 m aft, has its centre 0.12 m aft at mid load and 0.06-0.20 m over
#: the seed's load ranges); half the catalogue's smallest fault, COG_FAULT_M. Reported as
#: found, not as a fault.
COG_CENTRED_WITHIN_M = 0.2
#: The effects catalogue's smallest centre-of-mass fault and bogie sensor offset [m]. A size
#: found between a normal vehicle's and these is named with no more than moderate
#: confidence: a mass bolted off centre (890 kg 6.75 m aft moves the centre 0.18 m) or a
#: load set down unevenly gives it as well as a fault does.
COG_FAULT_M = 0.4
SENSOR_FAULT_M = 0.3
#: Underfloor equipment hangs between the bogies: within this distance of the carbody's
#: centre [m] (bogie centres of passenger cars sit 8-9.5 m from it).
UNDERFLOOR_M = 8.0
#: The effects catalogue's track flexibility is a soft to medium track, 20-80 MN/m per
#: wheelset; every track gives, so a stiffer track is reported as found, not as a cause.
SOFT_TRACK_N_PER_M = 80.0e6
#: The one-mass track's stiffness is a dynamic one, fitted at its resonance; a real track's
#: rail pads over ballast have a static stiffness (the catalogue's measure, the two in
#: series) below it. On development campaigns of the independent truth the fit came 1.5 %
#: below to 9 % above the series value: a track found up to this share above the line may
#: be under it.
TRACK_FORM_ALLOWANCE = 0.10
#: A floor accelerometer's scale error the floor-sensor extension fits, as the gyro's: what a
#: data sheet and a calibration leave. The independent truth's sensors are within 3 %.
FLOOR_GAIN_ERROR = 0.05
#: Floor accelerometers found within this of their declared x [m] are where the drawing puts
#: them; from FLOOR_FAULT_M (the smallest misplacement the extension names as a fault: a
#: sensor on the wrong cross-member of a 2-3 m pitch) they are a fault; between, moderate.
FLOOR_PLACED_WITHIN_M = 0.1
FLOOR_FAULT_M = 0.3
#: The largest misplacement searched [m], as for the bogie sensors.
FLOOR_DX_M = 2.5

#: The friction forces searched [N] per bogie's secondary and per wheelset's primary: from
#: what an air spring's own hysteresis gives to what a friction-damped bogie carries.
FRICTION_RANGE_N = (10.0, 5000.0)


@dataclass(frozen=True)
class Extension:
    """One model extension: the cause it stands for, the part of the data it changes and,
    for a response extension, its parameters and how they make the car's additions."""

    name: str  # the cause it stands for (effects catalogue name)
    kind: str  # one of KINDS
    description: str
    params: tuple[ParamRange, ...] = ()
    make: Callable | None = None  # response kind: values -> (CarExtras, SensorModel)
    # (parameter, bound): fitted above the bound, the extension describes what every vehicle
    # or track has (a carbody bends, a track gives), a property of this one, not a fault
    normal_above: tuple[str, float] | None = None
    # (parameter, bound): fitted within +-bound, it describes an installation's tolerance
    # (a sensor placed to within a few centimetres, a gyro's scale within its data sheet's)
    normal_within: tuple[str, float] | None = None
    # what it adds is part of a normal vehicle's design or service at any size (equipment on
    # its mounts, a load that changes between journeys)
    always_normal: bool = False
    # every run carries a load of its own (:func:`.response.loaded`), fitted with the rest
    per_run: bool = False
    # (parameter, size): the catalogue's smallest fault; a size found between normal_within's
    # bound and this is in between, named with moderate confidence at most
    fault_from: tuple[str, float] | None = None
    # the parameters are the campaign's, made from its layout (one pair per floor sensor):
    # :meth:`on` gives the extension with them, ``params`` stays empty here
    per_sensor: Callable[[Layout], tuple[ParamRange, ...]] | None = None
    # sizes derived from the fitted parameters (the worst-placed sensor's |dx|), which
    # normal_within and fault_from may name
    sizes: Callable[[dict], dict] | None = None
    # the share by which the model's form can overstate the normal_above parameter (the
    # fitted range reaches that much further down when tested against the line)
    form_allowance: float = 0.0
    # parameters (log ranges) whose range's low end means the effect is absent there (a
    # friction force of 10 N): fitted at that end, the extension is not standing in for
    # something else (selection._stands_in)
    absent_at_low: tuple[str, ...] = ()

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"Extension {self.name!r}: kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.kind == "response" and (not (self.params or self.per_run or self.per_sensor) or self.make is None):
            raise ValueError(f"Extension {self.name!r}: a response extension needs params (or per_run or "
                             "per_sensor) and make")

    def on(self, lay: Layout) -> Extension | None:
        """The extension for the campaign of layout ``lay``: itself, or with the parameters
        of ``lay``'s sensors (:attr:`per_sensor`); None when it has no sensor to act on."""
        if self.per_sensor is None:
            return self
        params = self.per_sensor(lay)
        return replace(self, params=params, per_sensor=None) if params else None

    def _sized(self, parameters: dict) -> dict:
        return {**parameters, **self.sizes(parameters)} if self.sizes is not None else parameters

    def is_property(self, parameters: dict) -> bool:
        """Do these fitted parameters describe a property of a normal vehicle or track
        (:attr:`normal_above`) rather than the fault the extension is named after?"""
        parameters = self._sized(parameters)
        if self.always_normal:
            return True
        if self.normal_within is not None:
            name, bound = self.normal_within
            if parameters.get(name) is not None and abs(parameters[name]) < bound:
                return True
        if self.normal_above is None:
            return False
        name, bound = self.normal_above
        return parameters.get(name) is not None and parameters[name] > bound

    def straddles(self, parameters: dict, ranges: dict | None) -> str | None:
        """Why the property line (:attr:`normal_above`) cannot tell a fault from a property
        here: the fitted parameter's ``ranges`` (its (low, high) over held-out folds) reach
        across the line. None when they do not, or no range is known."""
        if self.normal_above is None or not ranges or self.normal_above[0] not in ranges:
            return None
        name, bound = self.normal_above
        lo, hi = ranges[name]
        low = lo / (1.0 + self.form_allowance)
        if not low <= bound <= hi:
            return None
        form = f" (less {self.form_allowance:.0%} the model's form may add)" if self.form_allowance else ""
        return (f"{name} {parameters[name]:.3g} ranges {low:.3g}{form} to {hi:.3g} over the folds, across "
                f"{bound:.3g}, the top of the catalogue's fault range: a fault or a normal property")

    def in_between(self, parameters: dict) -> str | None:
        """Why these fitted parameters lie between a normal vehicle's and the catalogue's
        smallest fault (:attr:`fault_from`), or None."""
        if self.fault_from is None or self.is_property(parameters):
            return None
        parameters = self._sized(parameters)
        name, bound = self.fault_from
        size = parameters.get(name)
        if size is None or abs(size) >= bound:
            return None
        return f"|{name}| {abs(size):.3g} lies under the catalogue's smallest fault, {bound:g}"

    def normal_words(self) -> str:
        """When a fitted size is a property, in words."""
        out = ["part of every vehicle's design or service"] if self.always_normal else []
        if self.normal_above is not None:
            out.append(f"{self.normal_above[0]} above {self.normal_above[1]:.4g}, the top of the catalogue's fault "
                       "range")
        if self.normal_within is not None:
            out.append(f"|{self.normal_within[0]}| under {self.normal_within[1]:.4g}, within an installation's "
                       "tolerance")
        return " or ".join(out)

    @property
    def n_params(self) -> int:
        """Parameters the extension fits (a wheel polygon: wavelength, amplitude, wheelset;
        a track: its mass, own frequency and damping and the primary damping; loads per run
        count as one, their spread: a held-out run is judged at loads fitted on its other
        speed bins, so they buy nothing there)."""
        return {"wheel": 3, "track": 4}.get(self.kind, len(self.params) + self.per_run)


def floor_params(lay: Layout) -> tuple[ParamRange, ...]:
    """A position error and a gain per vertical floor accelerometer of ``lay``."""
    return tuple(r for o in lay.responses if o.body == "carbody" and o.kind == "acceleration"
                 for r in (ParamRange(f"dx:{o.name}", -FLOOR_DX_M, FLOOR_DX_M, log=False),
                           ParamRange(f"gain:{o.name}", 1 - FLOOR_GAIN_ERROR, 1 + FLOOR_GAIN_ERROR)))


def floor_sensors(values: dict) -> SensorModel:
    """The floor accelerometers of ``values`` ({"dx:NAME": m, "gain:NAME": -}; a sensor
    with one of the two takes the other's neutral value)."""
    names = sorted({k.split(":", 1)[1] for k in values if k.startswith(("dx:", "gain:"))})
    return SensorModel(floor=tuple((n, float(values.get(f"dx:{n}", 0.0)), float(values.get(f"gain:{n}", 1.0)))
                                   for n in names))


def _worst_dx(values: dict) -> dict:
    """The worst-placed floor sensor's |dx| [m], the size the fault rules read."""
    return {"worst_dx_m": max((abs(x) for k, x in values.items() if k.startswith("dx:")), default=0.0)}


EXTENSIONS: dict[str, Extension] = {e.name: e for e in (
    Extension("sensor_offset", "response",
              "bogie accelerometer off its declared x (dx) and pitch gyro scale error (gyro_gain)",
              (ParamRange("dx", -2.5, 2.5, log=False), ParamRange("gyro_gain", 1 - GYRO_SCALE_ERROR,
                                                                  1 + GYRO_SCALE_ERROR)),
              lambda v: (CarExtras(), SensorModel(v["dx"], v["gyro_gain"])),
              normal_within=("dx", SENSOR_PLACED_WITHIN_M), fault_from=("dx", SENSOR_FAULT_M)),
    Extension("carbody_bending", "response",
              "carbody first vertical bending mode (free-free beam shape, its nodes where the carbody's mass "
              "puts them): frequency, damping, modal mass, node",
              (ParamRange("bending_hz", 4.0, 18.0), ParamRange("bending_damping", 0.005, 0.1),
               ParamRange("bending_mass_ratio", 0.08, 1.0), ParamRange("bending_node", *BENDING_NODE_RANGE)),
              lambda v: (CarExtras(**v), SensorModel()), normal_above=("bending_hz", BENDING_FAULT_HZ)),
    Extension("cog_offset", "response", "carbody centre of mass ahead of its geometric centre",
              (ParamRange("cog_offset", -3.0, 3.0, log=False),),
              lambda v: (CarExtras(**v), SensorModel()), normal_within=("cog_offset", COG_CENTRED_WITHIN_M),
              fault_from=("cog_offset", COG_FAULT_M)),
    Extension("airspring_reservoir", "response",
              "air spring reservoir branch: series stiffness ratio to k_s and orifice corner frequency",
              (ParamRange("reservoir_ratio", 0.05, 5.0), ParamRange("reservoir_corner_hz", 0.3, 10.0)),
              lambda v: (CarExtras(**v), SensorModel())),
    Extension("mounted_equipment", "response",
              "equipment hung resiliently under the carbody (a powerpack, a tank): mass, position, mount frequency "
              "and damping",
              (ParamRange("equipment_mass", 100.0, 5000.0), ParamRange("equipment_x", -UNDERFLOOR_M, UNDERFLOOR_M,
                                                                       log=False),
               ParamRange("mount_hz", 3.0, 25.0), ParamRange("mount_damping", 0.02, 0.3)),
              lambda v: (mounted(v["equipment_mass"], v["equipment_x"], v["mount_hz"], v["mount_damping"]),
                         SensorModel()),
              always_normal=True),
    Extension("journey_load", "response",
              "the load (passengers, luggage, tanks' fill) changing between journeys: the carbody's mass, "
              "inertia and bending mass, and the levelled air springs' stiffness, per journey",
              (), lambda v: (CarExtras(), SensorModel()), always_normal=True, per_run=True),
    Extension("amplitude_dependent_suspension", "response",
              "dry friction in the secondary and primary suspension (each bogie's, each wheelset's): damping "
              "that falls as the amplitude grows, linearised at each cell's relative velocity (sqrt(2/pi) F / sigma)",
              tuple(ParamRange(n, *FRICTION_RANGE_N) for n in FRICTION),
              lambda v: (CarExtras(), SensorModel()), always_normal=True, absent_at_low=FRICTION),
    Extension("floor_sensor_offset", "response",
              "carbody floor accelerometers off their declared x (dx per sensor), their gains within a "
              "calibration's tolerance",
              make=lambda v: (CarExtras(), floor_sensors(v)), per_sensor=floor_params, sizes=_worst_dx,
              normal_within=("worst_dx_m", FLOOR_PLACED_WITHIN_M), fault_from=("worst_dx_m", FLOOR_FAULT_M)),
    Extension("wheel_out_of_round", "wheel",
              "polygonal wheel on one wheelset of the leading bogie: wavelength, radius amplitude, wheelset"),
    Extension("track_flexibility", "track",
              "wheelsets on a flexible track: the track mass under them, its own frequency and damping ratio "
              "(and the primary damping above them)",
              normal_above=("track_stiffness_n_per_m", SOFT_TRACK_N_PER_M), form_allowance=TRACK_FORM_ALLOWANCE),
)}


def mounted(mass: float, x: float, mount_hz: float, damping: float) -> CarExtras:
    """A body of ``mass`` [kg], part of the carbody's m_v, on a spring-damper under the
    carbody at ``x`` [m], its mount frequency [Hz] and damping ratio on a fixed carbody.
    Being part of m_v, it moves nothing at low frequency (where it moves with the carbody):
    it cannot stand in for a centre of mass off the middle."""
    k = mass * (2 * np.pi * mount_hz) ** 2
    body, mount = hung_body("equipment", mass, x, k, 2 * damping * np.sqrt(k * mass))
    return CarExtras(bodies=(body,), elements=(mount,), hung_in_m_v=True)


def combined(first: Extension, then: Extension) -> Extension:
    """Two response extensions as one: ``first``'s parameters and ``then``'s, each making
    its own additions to the car and its sensors (what the second sets taking the place of
    the first's)."""
    if first.kind != "response" or then.kind != "response":
        raise ValueError(f"only response extensions combine, not {first.kind} and {then.kind}")
    names_a = {r.name for r in first.params}

    def make(v):
        ex_a, se_a = first.make({k: x for k, x in v.items() if k in names_a})
        ex_b, se_b = then.make({k: x for k, x in v.items() if k not in names_a})
        return _joined(ex_a, ex_b, CarExtras()), _joined(se_a, se_b, SensorModel())

    return Extension(f"{first.name}+{then.name}", "response", f"{first.description}; {then.description}",
                     first.params + then.params, make, per_run=first.per_run or then.per_run)


def _joined(a, b, default):
    """``a`` with every field ``b`` sets away from ``default`` taken from ``b``."""
    return replace(a, **{f.name: getattr(b, f.name) for f in fields(b)
                         if getattr(b, f.name) != getattr(default, f.name)})
