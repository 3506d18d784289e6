"""Units of the campaign format and their one conversion to SI (applied at read time)."""
from __future__ import annotations

import math

STANDARD_GRAVITY = 9.80665  # [m/s^2] g_n, exact by definition (3rd CGPM, 1901): the g of a sensor unit

# unit -> (quantity family, factor to SI); the factors are the units' exact SI definitions
UNITS: dict[str, tuple[str, float]] = {
    "g": ("acceleration", STANDARD_GRAVITY),
    "m/s^2": ("acceleration", 1.0),
    "deg/s": ("angular_velocity", math.pi / 180.0),
    "rad/s": ("angular_velocity", 1.0),
    "N": ("force", 1.0),
    "kN": ("force", 1000.0),
    "m": ("displacement", 1.0),
    "mm": ("displacement", 1.0e-3),
    "m/s": ("velocity", 1.0),
}
#: Other spellings of a unit in UNITS, read as that unit: loggers and spreadsheets write
#: m/s^2 as "m/s2" (no caret in their character set) or "m/s²" (Unicode superscript). Only
#: spellings that cannot mean anything else are listed.
UNIT_ALIASES: dict[str, str] = {"m/s2": "m/s^2", "m/s²": "m/s^2"}
SI_UNIT = {"acceleration": "m/s^2", "angular_velocity": "rad/s", "force": "N", "displacement": "m",
           "velocity": "m/s"}
QUANTITIES = tuple(SI_UNIT)
TRANSLATIONS = ("x", "y", "z")
ROTATIONS = ("pitch", "roll", "yaw")
BODIES = ("carbody", "bogie1", "bogie2", "axle1", "axle2", "axle3", "axle4", "floor", "roof", "side_left",
          "side_right", "ground")


def canonical_unit(unit: str) -> str:
    """The UNITS spelling of ``unit`` (itself when it is one; an alias's unit otherwise)."""
    return UNIT_ALIASES.get(unit, unit)


def si_factor(unit: str) -> float:
    return UNITS[canonical_unit(unit)][1]
