"""The hook through which hidden physical effects enter the truth simulator.

``railcal synth ... --effect NAME[=MAGNITUDE]`` looks NAME up in :data:`EFFECTS`. Each
entry says which campaign kinds it applies to and its magnitude range; the simulators
ask the chosen effect to modify what they build (the vehicle model, the sensors, the
track). The catalogue is filled by the diagnosis work (issue 7); until then it is empty
and any --effect is refused with exit code 2.
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
    description: str


@dataclass(frozen=True)
class EffectChoice:
    spec: EffectSpec
    magnitude: float

    def to_json(self) -> dict:
        return {"name": self.spec.name, "magnitude": self.magnitude, "description": self.spec.description}


EFFECTS: dict[str, EffectSpec] = {}


def parse_effect(text: str | None, kind: str) -> EffectChoice | None:
    """Parse ``NAME[=MAGNITUDE]``; raise :class:`InputError` naming what is wrong."""
    if text is None:
        return None
    name, _, mag = text.partition("=")
    name = name.strip()
    spec = EFFECTS.get(name)
    if spec is None or kind not in spec.kinds:
        have = [n for n, s in EFFECTS.items() if kind in s.kinds]
        listing = ", ".join(have) if have else "none are implemented yet"
        raise InputError(f"unknown effect {name!r} for {kind} campaigns; available: {listing}", key="--effect")
    if not mag:
        return EffectChoice(spec, spec.default_magnitude)
    try:
        value = float(mag)
    except ValueError:
        raise InputError(f"magnitude {mag!r} of effect {name} is not a number", key="--effect") from None
    lo, hi = spec.magnitude_range
    if not lo <= value <= hi:
        raise InputError(f"magnitude {value} of effect {name} outside its range [{lo}, {hi}]", key="--effect")
    return EffectChoice(spec, value)
