"""The catalogue of hidden physical effects the truth simulators can put into a campaign.

``railcal synth ... --effect NAME[=MAGNITUDE]`` looks NAME up in :data:`EFFECTS`. Each
entry says which campaign kinds it applies to, what its magnitude means (with unit) and
the range in which it visibly changes the measurement. Details the magnitude does not fix
(a sign, which wheelset, a transition frequency) are drawn from the campaign's seeded
generator and written to the truth file. The simulators apply the effect physically
(bodies, elements, sensor placement); the diagnosis (:mod:`calibration.diagnosis`) must
find it without reading this file's choices.

In service (2D car, :mod:`calibration.truth.in_service`):

* ``carbody_bending``: the carbody is flexible; its first vertical bending mode (free-free
  beam shape, modal mass a quarter of the carbody's with the shape 1 at the ends, damping
  ratio drawn in 1.5-3 %) at MAGNITUDE Hz.
* ``sensor_offset``: the bogie accelerometer and pitch gyro block sits MAGNITUDE metres
  ahead of or behind (sign drawn) the position campaign.toml declares for it.
* ``cog_offset``: the carbody's centre of mass is MAGNITUDE metres ahead of or behind
  (sign drawn) the carbody centre, so the bogies carry unequal loads and bounce and pitch
  couple.
* ``track_flexibility``: the wheelsets do not sit on a rigid rail but on the track's
  vertical stiffness MAGNITUDE [N/m] per wheelset (soft to medium track: rail pads, sleepers and
  ballast; stiffer track moves the resonance above what 500 Hz logging resolves well; damping
  ratio 0.2 with the wheelset), the rail and sleeper mass taking part (250 kg per
  wheelset) lumped with the wheelset; the line's level is the support's geometry.
* ``wheel_out_of_round``: one wheelset (1 or 2, drawn) has a polygonal wheel pair: radius
  deviation of amplitude MAGNITUDE [m] at polygon order 1, 2 or 3 (drawn) around a
  0.84 m wheel, so it excites at order x speed / circumference.
* ``airspring_reservoir``: each air spring is its area stiffness k_s in parallel with a
  reservoir branch: a stiffness MAGNITUDE x k_s in series with an orifice damper whose
  corner frequency is drawn in 1.5-4 Hz (stiffer and more damped at higher frequency).

Stationary excitation test (box model, :mod:`calibration.truth.excitation`):

* ``underfloor_equipment``: a resiliently mounted underfloor mass of MAGNITUDE x the
  carbody mass whose mounting frequency is tuned near (within +-4 %, drawn) one of the
  carbody's elastic modes in 8-20 Hz, splitting it in two.
* ``local_panel_softening``: one floor or roof panel (drawn) has its rigidities divided by
  MAGNITUDE.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..data.errors import InputError


@dataclass(frozen=True)
class EffectSpec:
    name: str
    kinds: tuple[str, ...]  # campaign kinds it applies to
    magnitude_range: tuple[float, float]
    default_magnitude: float
    unit: str
    description: str


@dataclass(frozen=True)
class EffectChoice:
    spec: EffectSpec
    magnitude: float

    def to_json(self) -> dict:
        return {"name": self.spec.name, "magnitude": self.magnitude, "unit": self.spec.unit,
                "description": self.spec.description}


_IN, _EX = ("in_service",), ("stationary_excitation",)
EFFECTS: dict[str, EffectSpec] = {s.name: s for s in (
    EffectSpec("carbody_bending", _IN, (6.0, 12.0), 8.0, "Hz", "first vertical bending of a flexible carbody"),
    EffectSpec("sensor_offset", _IN, (0.3, 1.5), 0.8, "m",
               "bogie accelerometer and gyro mounted off their declared position along the bogie"),
    EffectSpec("cog_offset", _IN, (0.4, 1.5), 0.8, "m", "carbody centre of mass off its geometric centre"),
    EffectSpec("track_flexibility", _IN, (20.0e6, 80.0e6), 40.0e6, "N/m",
               "wheelsets on rail pads and ballast (track stiffness per wheelset) instead of a rigid rail"),
    EffectSpec("wheel_out_of_round", _IN, (0.05e-3, 0.3e-3), 0.15e-3, "m",
               "polygonal wheel pair: radius deviation amplitude, excitation at order x speed / circumference"),
    EffectSpec("airspring_reservoir", _IN, (0.5, 2.0), 1.0, "-",
               "air spring with reservoir: series stiffness (ratio to k_s) and orifice damping"),
    EffectSpec("underfloor_equipment", _EX, (0.01, 0.05), 0.03, "-",
               "resiliently mounted underfloor mass (ratio to the carbody mass) splitting a carbody mode"),
    EffectSpec("local_panel_softening", _EX, (3.0, 10.0), 5.0, "-",
               "one floor or roof panel softer than the rest (rigidity divisor)"),
    EffectSpec("force_calibration", _EX, (0.9, 1.1), 1.05, "-",
               "the exciter's force sensor reads this times the applied force (a calibration factor off)"),
)}


#: Effects outside the catalogue: the truth simulator can hide them (tests and the
#: diagnosis bench build an :class:`EffectChoice` directly), the CLI does not offer them and
#: the diagnosis has no extension for them, so they must come out as ``unexplained``.
#: ``bogie_equipment`` (in service): equipment of MAGNITUDE kg resiliently mounted on the
#: leading bogie's frame 0.6 m ahead of its centre, mounting frequency drawn in 20-30 Hz,
#: damping 4 %. ``sensor_bracket`` (stationary test): one floor accelerometer (drawn) on a
#: resilient bracket of natural frequency MAGNITUDE Hz, damping ratio drawn in 3-6 %.
UNCATALOGUED: dict[str, EffectSpec] = {s.name: s for s in (
    EffectSpec("bogie_equipment", _IN, (250.0, 600.0), 400.0, "kg",
               "resiliently mounted equipment on the leading bogie frame (outside the catalogue)"),
    EffectSpec("sensor_bracket", _EX, (10.0, 28.0), 20.0, "Hz",
               "one floor accelerometer on a resilient bracket of this natural frequency (outside the catalogue)"),
)}


def effect_spec(name: str) -> EffectSpec:
    """The spec of an effect of the catalogue or outside it (tests and benches hide both)."""
    spec = EFFECTS.get(name) or UNCATALOGUED.get(name)
    if spec is None:
        raise KeyError(f"no effect {name!r} in the catalogue or outside it")
    return spec


def parse_effect(text: str | None, kind: str) -> EffectChoice | None:
    """Parse ``NAME[=MAGNITUDE]``; raise :class:`InputError` naming what is wrong."""
    if text is None:
        return None
    name, _, mag = text.partition("=")
    name = name.strip()
    spec = EFFECTS.get(name)
    if spec is None or kind not in spec.kinds:
        have = [n for n, s in EFFECTS.items() if kind in s.kinds]
        raise InputError(f"unknown effect {name!r} for {kind} campaigns; available: {', '.join(have)}",
                         key="--effect")
    if not mag:
        return EffectChoice(spec, spec.default_magnitude)
    try:
        value = float(mag)
    except ValueError:
        raise InputError(f"magnitude {mag!r} of effect {name} is not a number", key="--effect") from None
    lo, hi = spec.magnitude_range
    if not lo <= value <= hi:
        raise InputError(f"magnitude {value} {spec.unit} of effect {name} outside its range [{lo}, {hi}]",
                         key="--effect")
    return EffectChoice(spec, value)
