"""The registry of model extensions: one per cause in the effects catalogue, each a
physical addition to the 2D car or its sensors with its own parameters and ranges.

``kind`` says which part of the data the extension changes and therefore which error
measures it: ``response`` (bogie and carbody channels predicted from the rail input,
:mod:`.response`), ``wheel`` (the axle-box consistency channel, :mod:`.wheels`) or
``track`` (the axle boxes' spectra over speed, :mod:`.track`). Adding a cause is an entry
of :data:`EXTENSIONS` and the evidence that speaks for it (:func:`.evidence.scores`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ...models.car2d import CarExtras
from .response import ParamRange, SensorModel

KINDS = ("response", "wheel", "track")


@dataclass(frozen=True)
class Extension:
    """One model extension: the cause it stands for, the part of the data it changes and,
    for a response extension, its parameters and how they make the car's additions."""

    name: str  # the cause it stands for (effects catalogue name)
    kind: str  # one of KINDS
    description: str
    params: tuple[ParamRange, ...] = ()
    make: Callable | None = None  # response kind: values -> (CarExtras, SensorModel)

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"Extension {self.name!r}: kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.kind == "response" and (not self.params or self.make is None):
            raise ValueError(f"Extension {self.name!r}: a response extension needs params and make")

    @property
    def n_params(self) -> int:
        """Parameters the extension fits (a wheel polygon: wavelength, amplitude, wheelset;
        a track: resonance and damping)."""
        return {"wheel": 3, "track": 2}.get(self.kind, len(self.params))


EXTENSIONS: dict[str, Extension] = {e.name: e for e in (
    Extension("sensor_offset", "response",
              "bogie accelerometer off its declared x (dx) and pitch gyro scale error (gyro_gain)",
              (ParamRange("dx", -2.5, 2.5, log=False), ParamRange("gyro_gain", 0.6, 1.6)),
              lambda v: (CarExtras(), SensorModel(v["dx"], v["gyro_gain"]))),
    Extension("carbody_bending", "response",
              "carbody first vertical bending mode (free-free beam shape): frequency, damping, modal mass",
              (ParamRange("bending_hz", 4.0, 18.0), ParamRange("bending_damping", 0.005, 0.1),
               ParamRange("bending_mass_ratio", 0.08, 1.0)),
              lambda v: (CarExtras(**v), SensorModel())),
    Extension("cog_offset", "response", "carbody centre of mass ahead of its geometric centre",
              (ParamRange("cog_offset", -3.0, 3.0, log=False),),
              lambda v: (CarExtras(**v), SensorModel())),
    Extension("airspring_reservoir", "response",
              "air spring reservoir branch: series stiffness ratio to k_s and orifice corner frequency",
              (ParamRange("reservoir_ratio", 0.05, 5.0), ParamRange("reservoir_corner_hz", 0.3, 10.0)),
              lambda v: (CarExtras(**v), SensorModel())),
    Extension("wheel_out_of_round", "wheel",
              "polygonal wheel on one wheelset of the leading bogie: wavelength, radius amplitude, wheelset"),
    Extension("track_flexibility", "track",
              "wheelsets on a flexible track: track resonance frequency and damping ratio"),
)}
