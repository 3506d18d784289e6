"""Model parameters of the 2D car: one source of truth for names, units and meaning.

Names follow ``shared/spec/interfaces.md`` (and the in-service seed's symbols):
per-wheelset primary (``k_p``, ``c_p``) and per-bogie secondary (``k_s``, ``c_s``)
suspension, so the seed's Tables 7-9 values are used as they stand.

Everything here is SI. A :class:`CarParameters` refuses unknown names, non-finite
values and non-positive masses, inertias, stiffnesses and lengths, naming the culprit.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Mapping


@dataclass(frozen=True)
class ParameterSpec:
    """Metadata of one model parameter."""

    name: str
    unit: str
    description: str
    allow_zero: bool = False  # dampings may be zero; masses and stiffnesses may not


CAR_PARAMETER_SPECS: dict[str, ParameterSpec] = {
    s.name: s
    for s in (
        ParameterSpec("m_v", "kg", "carbody mass"),
        ParameterSpec("J_v", "kg m^2", "carbody pitch inertia about its centre of mass"),
        ParameterSpec("m_b", "kg", "mass of one bogie frame"),
        ParameterSpec("J_b", "kg m^2", "pitch inertia of one bogie frame"),
        ParameterSpec("m_w", "kg", "mass of one wheelset"),
        ParameterSpec("k_p", "N/m", "primary vertical stiffness per wheelset"),
        ParameterSpec("c_p", "N s/m", "primary vertical damping per wheelset", allow_zero=True),
        ParameterSpec("k_s", "N/m", "secondary vertical stiffness per bogie"),
        ParameterSpec("c_s", "N s/m", "secondary vertical damping per bogie", allow_zero=True),
        ParameterSpec("L_v", "m", "half the bogie-centre spacing"),
        ParameterSpec("L_b", "m", "half the wheelbase"),
    )
}


class ParameterError(ValueError):
    """A parameter set is inconsistent (unknown name, non-finite or non-physical value)."""


@dataclass(frozen=True)
class CarParameters:
    """Physical parameters of the 2D car model (SI units, see ``CAR_PARAMETER_SPECS``)."""

    m_v: float
    J_v: float
    m_b: float
    J_b: float
    m_w: float
    k_p: float
    c_p: float
    k_s: float
    c_s: float
    L_v: float
    L_b: float

    def __post_init__(self) -> None:
        for name, spec in CAR_PARAMETER_SPECS.items():
            value = getattr(self, name)
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ParameterError(f"parameter {name} = {value!r} is not a number") from None
            if not math.isfinite(value):
                raise ParameterError(f"parameter {name} = {value} is not finite")
            if value < 0 or (value == 0 and not spec.allow_zero):
                bound = ">= 0" if spec.allow_zero else "> 0"
                raise ParameterError(
                    f"parameter {name} ({spec.description}) = {value} {spec.unit}; must be {bound}"
                )
            object.__setattr__(self, name, value)
        if self.L_b >= self.L_v:
            raise ParameterError(
                f"half wheelbase L_b = {self.L_b} m must be smaller than half the bogie "
                f"spacing L_v = {self.L_v} m"
            )

    @classmethod
    def from_mapping(cls, values: Mapping[str, float], *, base: "CarParameters | None" = None) -> "CarParameters":
        """Build from a name -> value mapping; names missing are taken from ``base``."""
        unknown = sorted(set(values) - set(CAR_PARAMETER_SPECS))
        if unknown:
            raise ParameterError(
                f"unknown parameter name(s) {', '.join(unknown)}; known: {', '.join(CAR_PARAMETER_SPECS)}"
            )
        merged = dict(base.as_dict()) if base is not None else {}
        merged.update(values)
        missing = [n for n in CAR_PARAMETER_SPECS if n not in merged]
        if missing:
            raise ParameterError(f"missing parameter(s) {', '.join(missing)}")
        return cls(**{n: merged[n] for n in CAR_PARAMETER_SPECS})

    def replace(self, **changes: float) -> "CarParameters":
        return CarParameters.from_mapping(changes, base=self)

    def as_dict(self) -> dict[str, float]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
